"""Tests of :mod:`brdfpipe.rendering.blend` on tiny synthetic EXR images written with write_exr."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Any

import matplotlib.image
import numpy as np
import pytest

from brdfpipe.core import filenames, integrity
from brdfpipe.rendering import blend
from brdfpipe.rendering.blend import (
    BlendError,
    error_map,
    error_maps,
    format_t,
    relative_rmse,
    rmse,
    tonemap,
)
from brdfpipe.core.exr import ExrError, read_exr, read_exr_attrs, write_exr
from brdfpipe.core.notes import read_note
from brdfpipe.registry import tables

H, W = 6, 8
MATERIALS = ("alum-bronze", "chrome", "silver-paint")


def _images(tmp_path: Path, n: int = 3, seed: int = 0, shape: tuple[int, int] = (H, W)) -> list[Path]:
    rng = np.random.default_rng(seed)
    paths = []
    for i in range(n):
        p = tmp_path / f"img{i}.exr"
        write_exr(p, rng.uniform(0.0, 2.0, shape + (3,)).astype(np.float32))
        paths.append(p)
    return paths


# --------------------------------------------------------------------------
# Blending: error_maps' weights check and blend of the pre-renders
# --------------------------------------------------------------------------


def blend_exr(paths: list[Path], weights: Any, progress: Any = None) -> np.ndarray:
    """``Σᵢ wᵢ Iᵢ`` of the EXR images at ``paths``, checked and blended as :func:`error_maps` does."""
    return blend._blend_many(paths, blend._check_weights(weights, len(paths), "weights")[None, :], progress)[0]


def test_blend_of_constant_images_is_the_weighted_sum(tmp_path: Path) -> None:
    consts = [0.25, 1.5, 3.0]  # exactly representable
    paths = []
    for i, c in enumerate(consts):
        paths.append(tmp_path / f"c{i}.exr")
        write_exr(paths[-1], np.full((H, W, 3), c, dtype=np.float32))
    w = [0.7, -0.2, 0.5]  # a negative GP weight is kept, not clipped
    out = blend_exr(paths, w)
    assert out.dtype == np.float64 and out.shape == (H, W, 3)
    expected = 0.7 * 0.25 + (-0.2) * 1.5 + 0.5 * 3.0
    assert np.all(out == expected)


def test_blend_is_linear_in_the_weights(tmp_path: Path) -> None:
    paths = _images(tmp_path)
    w = np.array([0.2, 0.5, 0.3])
    base = blend_exr(paths, w)
    assert np.allclose(blend_exr(paths, 3.0 * w), 3.0 * base, rtol=1e-14, atol=0)
    v = np.array([-1.0, 0.25, 2.0])
    assert np.allclose(blend_exr(paths, w + v), base + blend_exr(paths, v), rtol=1e-13, atol=1e-15)
    # against a direct float64 computation
    direct = sum(wi * read_exr(p).astype(np.float64) for wi, p in zip(w, paths))
    assert np.allclose(base, direct, rtol=1e-15, atol=0)


def test_blend_reads_each_file_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    paths = _images(tmp_path, n=4)
    calls: list[Path] = []
    real = blend.read_exr

    def counting(p: Any) -> np.ndarray:
        calls.append(Path(p))
        return real(p)

    monkeypatch.setattr(blend, "read_exr", counting)
    lines: list[str] = []
    blend_exr(paths, [0.25] * 4, progress=lines.append)
    assert calls == paths
    assert len(lines) == 4


def test_blend_checks_lengths_shapes_and_files(tmp_path: Path) -> None:
    paths = _images(tmp_path)
    with pytest.raises(BlendError, match="2 entries but there are 3 images"):
        blend_exr(paths, [0.5, 0.5])
    with pytest.raises(BlendError, match="non-finite"):
        blend_exr(paths, [0.5, np.nan, 0.5])
    odd = tmp_path / "odd.exr"
    write_exr(odd, np.zeros((H + 1, W, 3), dtype=np.float32))
    with pytest.raises(BlendError, match=rf"odd\.exr: image has shape \({H + 1}, {W}, 3\).*img0\.exr has \({H}, {W}, 3\)"):
        blend_exr(paths + [odd], [0.25] * 4)
    with pytest.raises(ExrError, match=r"gone\.exr: no such file"):
        blend_exr(paths + [tmp_path / "gone.exr"], [0.25] * 4)
    (tmp_path / "junk.exr").write_bytes(b"not an exr at all")
    with pytest.raises(ExrError, match=r"junk\.exr: not an OpenEXR file"):
        blend_exr([tmp_path / "junk.exr"] + paths, [0.25] * 4)


# --------------------------------------------------------------------------
# metrics, maps
# --------------------------------------------------------------------------


def test_rmse_and_relative_rmse_analytic() -> None:
    ref = np.full((4, 5, 3), 2.0)
    a = ref + 0.5  # every pixel and channel off by 0.5
    assert rmse(a, ref) == pytest.approx(0.5)
    assert relative_rmse(a, ref, ref) == pytest.approx(0.25)
    # half the values off by 1, half exact: RMSE = sqrt(1/2); reference mean (1 + 3)/2 = 2
    ref2 = np.zeros((2, 2, 3))
    ref2[0] = 1.0
    ref2[1] = 3.0
    b = ref2.copy()
    b[0] += 1.0
    assert relative_rmse(b, ref2, ref2) == pytest.approx(np.sqrt(0.5) / 2.0)
    with pytest.raises(BlendError, match="positive mean"):
        relative_rmse(a, ref, np.zeros_like(ref))
    with pytest.raises(BlendError, match="differ in shape"):
        rmse(a, ref[:, :4])


def test_error_map_is_mean_abs_over_rgb() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(H, W, 3))
    assert np.array_equal(error_map(a, a), np.zeros((H, W)))
    b = a.copy()
    b[..., 0] += 0.3
    b[..., 2] -= 0.6
    assert np.allclose(error_map(b, a), 0.3)
    assert error_map(b, a).shape == (H, W)


def test_tonemap() -> None:
    img = np.array([[[0.0, 0.5, 1.0], [2.0, -1.0, 0.0031308]]])
    out = tonemap(img)
    assert out.dtype == np.uint8 and out.shape == (1, 2, 3)
    assert out[0, 0].tolist() == [0, 188, 255]
    assert out[0, 1].tolist() == [255, 0, 10]
    assert tonemap(img, exposure=1.0)[0, 0, 1] == 255  # 0.5 · 2 = 1


def test_error_map_png_and_exr(tmp_path: Path) -> None:
    err = np.linspace(0.0, 1.0, H * W).reshape(H, W)
    blend.write_error_map_png(tmp_path / "e.png", err, database="synthetic", title="t")
    blend.write_error_map_png(tmp_path / "f.png", err, database="synthetic", title="t")
    assert (tmp_path / "e.png").read_bytes() == (tmp_path / "f.png").read_bytes()
    png = matplotlib.image.imread(tmp_path / "e.png")
    assert png.ndim == 3 and png.shape[1] > png.shape[0] > 50
    blend.write_error_map_exr(tmp_path / "e.exr", err, attrs={"database": "synthetic"})
    back = read_exr(tmp_path / "e.exr")
    assert np.allclose(back, err[..., None].astype(np.float32))
    assert read_exr_attrs(tmp_path / "e.exr") == {"database": "synthetic"}
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_format_t() -> None:
    assert [format_t(t) for t in (0.25, 0.5, 1.0, 0.0, -0.0, 0.125)] == ["0.25", "0.5", "1", "0", "0", "0.125"]
    with pytest.raises(ValueError):
        format_t(float("nan"))
    assert format_t is filenames.format_t  # one definition, shared by the workflow's file names


# --------------------------------------------------------------------------
# error_maps (the workflow entry point)
# --------------------------------------------------------------------------


def _setup(tmp_path: Path) -> tuple[dict[str, Path], list[dict[str, Any]], dict[str, np.ndarray]]:
    rng = np.random.default_rng(7)
    src = tmp_path / "in"
    src.mkdir(parents=True)
    images: dict[str, np.ndarray] = {}
    prerenders = {}
    for m in MATERIALS:
        images[m] = rng.uniform(0.1, 2.0, (H, W, 3)).astype(np.float32)
        prerenders[m] = src / f"{m}.exr"
        write_exr(prerenders[m], images[m], attrs={"material": m})
    points = []
    for t, w in ((0.25, [0.75, 0.25, 0.0]), (0.5, [0.6, 0.6, -0.2])):
        exact = sum(wi * images[m].astype(np.float64) for wi, m in zip(w, MATERIALS))
        ref = (exact + rng.normal(0.0, 0.05, exact.shape)).astype(np.float32)
        ref2 = (exact + rng.normal(0.0, 0.05, exact.shape)).astype(np.float32)
        name = f"ref-{t}"
        write_exr(src / f"{name}.exr", ref)
        write_exr(src / f"{name}-2.exr", ref2)
        images[name], images[name + "-2"] = ref, ref2
        points.append({"path": "chrome-to-silver", "t": t, "weights": dict(zip(MATERIALS, w)),
                       "reference": str(src / f"{name}.exr"), "reference_seed2": str(src / f"{name}-2.exr")})
    return prerenders, points, images


def _outputs(points: list[dict[str, Any]], out: Path) -> list[dict[str, Any]]:
    """The points with their output files under ``out`` (names the library never chose itself)."""
    return [{**pt, "blended": out / f"point{k}-blend.exr", "error_exr": out / f"point{k}-err.exr",
             "error_png": out / f"point{k}-err.png"} for k, pt in enumerate(points)]


def _output_files(points: list[dict[str, Any]]) -> list[Path]:
    return [Path(pt[k]) for pt in points for k in ("blended", "error_exr", "error_png")]


def test_error_maps_end_to_end(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    prerenders, points, images = _setup(tmp_path)
    out = tmp_path / "out"
    calls: list[Path] = []
    real = blend.read_exr
    monkeypatch.setattr(blend, "read_exr", lambda p: (calls.append(Path(p)), real(p))[1])
    points = _outputs(points, out)
    summary = out / "my-summary.csv"
    rows = error_maps(prerenders=prerenders, paths=points, summary=summary, database="synthetic")
    # each pre-render read once for all points; each reference once
    assert sorted(calls) == sorted([Path(p) for p in prerenders.values()]
                                   + [Path(pt[k]) for pt in points for k in ("reference", "reference_seed2")])
    assert len(rows) == 2
    for row, pt in zip(rows, points):
        w = pt["weights"]
        direct = sum(w[m] * images[m].astype(np.float64) for m in MATERIALS)
        ref = images[f"ref-{pt['t']}"].astype(np.float64)
        ref2 = images[f"ref-{pt['t']}-2"].astype(np.float64)
        rb = np.sqrt(np.mean((direct - ref) ** 2)) / ref.mean()
        rn = np.sqrt(np.mean((ref - ref2) ** 2)) / ref.mean()
        assert row["path"] == "chrome-to-silver" and row["t"] == pt["t"]
        assert row["rmse_blend"] == pytest.approx(rb, rel=1e-12)
        assert row["rmse_noise"] == pytest.approx(rn, rel=1e-12)
        assert row["ratio"] == pytest.approx(rb / rn, rel=1e-12)
        rb2 = np.sqrt(np.mean((direct - ref2) ** 2)) / ref.mean()
        assert row["rmse_blend_seed2"] == pytest.approx(rb2, rel=1e-12)
        assert row["ratio_seed2"] == pytest.approx(rb2 / rn, rel=1e-12)
        assert row["mean_reference"] == pytest.approx(ref.mean(), rel=1e-12)
        assert np.array_equal(read_exr(pt["blended"]), direct.astype(np.float32))
        assert np.allclose(read_exr(pt["error_exr"])[..., 0], np.abs(direct - ref).mean(axis=2), rtol=1e-6)
        assert Path(pt["error_png"]).stat().st_size > 0
        attrs = read_exr_attrs(pt["blended"])
        assert attrs["database"] == "synthetic" and attrs["t"] == format_t(pt["t"])
    # exactly the files passed in, nothing else (no temporary, no name of the library's own)
    assert sorted(out.iterdir()) == sorted([summary, *_output_files(points)])
    with io.StringIO(integrity.read_csv_text(summary), newline="") as fh:
        table = list(csv.reader(fh))
    assert tuple(table[0]) == tables.ERROR_MAP_SUMMARY
    assert [r[:3] for r in table[1:]] == [["synthetic", "chrome-to-silver", "0.25"], ["synthetic", "chrome-to-silver", "0.5"]]
    assert float(table[2][3]) == pytest.approx(rows[1]["rmse_blend"], rel=1e-8)
    # reruns give the same bytes
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    error_maps(prerenders=prerenders, paths=points, summary=summary, database="synthetic")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == first
    # a point without its output files is refused before anything is read
    with pytest.raises(BlendError, match="path point 1: missing key.*blended, error_exr, error_png"):
        error_maps(prerenders=prerenders, paths=[points[0], {k: v for k, v in points[1].items()
                                                              if k not in ("blended", "error_exr", "error_png")}],
                   summary=summary, database="synthetic")
    assert not summary.exists()


@pytest.mark.parametrize("what", ["missing-prerender", "corrupt-prerender", "missing-reference", "corrupt-seed2"])
def test_error_maps_bad_input_names_the_file_and_writes_no_summary(tmp_path: Path, what: str) -> None:
    prerenders, points, _ = _setup(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    points = _outputs(points, out)
    summary = out / "summary.csv"
    summary.write_text("stale\n")  # from an earlier run: must not survive a failed one
    if what == "missing-prerender":
        bad = prerenders["chrome"]
        bad.unlink()
    elif what == "corrupt-prerender":
        bad = prerenders["chrome"]
        bad.write_bytes(bad.read_bytes()[:200])
    elif what == "missing-reference":
        bad = Path(points[1]["reference"])
        bad.unlink()
    else:
        bad = Path(points[0]["reference_seed2"])
        bad.write_bytes(bad.read_bytes()[:-40])
    with pytest.raises(ExrError, match=str(bad).replace(".", r"\.")):
        error_maps(prerenders=prerenders, paths=points, summary=summary, database="synthetic")
    assert not summary.exists()
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


def test_error_maps_shape_mismatch_and_weight_mismatch(tmp_path: Path) -> None:
    prerenders, points, _ = _setup(tmp_path)
    write_exr(Path(points[0]["reference"]), np.ones((H, W + 2, 3), dtype=np.float32))
    with pytest.raises(BlendError, match=r"ref-0\.25\.exr: image has shape"):
        error_maps(prerenders=prerenders, paths=_outputs(points, tmp_path / "out"),
                   summary=tmp_path / "out" / "summary.csv", database="synthetic")
    assert not (tmp_path / "out" / "summary.csv").exists()

    prerenders, points, _ = _setup(tmp_path / "again")
    points[1]["weights"] = {"chrome": 1.0, "gold": 0.0}
    with pytest.raises(BlendError, match="without a pre-render: gold; pre-renders without a weight: alum-bronze"):
        error_maps(prerenders=prerenders, paths=_outputs(points, tmp_path / "out2"),
                   summary=tmp_path / "out2" / "summary.csv", database="synthetic")


def test_error_maps_refuses_clashing_outputs_before_writing(tmp_path: Path) -> None:
    prerenders, points, _ = _setup(tmp_path)
    ref_bytes = Path(points[0]["reference"]).read_bytes()
    out = tmp_path / "out"
    clash = _outputs(points, out)
    clash[1]["blended"] = clash[0]["blended"]  # two points, one file
    with pytest.raises(BlendError, match="more than once"):
        error_maps(prerenders=prerenders, paths=clash, summary=out / "summary.csv", database="synthetic")
    over = _outputs(points, out)
    over[0]["error_exr"] = points[0]["reference"]  # an output naming an input
    with pytest.raises(ValueError, match="would write over the input"):
        error_maps(prerenders=prerenders, paths=over, summary=out / "summary.csv", database="synthetic")
    assert Path(points[0]["reference"]).read_bytes() == ref_bytes
    assert not out.exists() or not any(out.iterdir())


def test_error_maps_from_weight_files_and_render_figures(tmp_path: Path) -> None:
    """The workflow's entry points: weights JSON files → summary, then the three render figures."""

    from brdfpipe.core.plot import FigureInputError
    from brdfpipe.rendering import figures
    from brdfpipe.rendering.blend import error_maps_from_files

    prerenders, points, _ = _setup(tmp_path)
    wfiles = []
    for k, pt in enumerate(points):
        wf = tmp_path / f"w{k}.json"
        integrity.write_json(wf, ({"path": pt["path"], "t": pt["t"], "weights": pt["weights"],
                                  "material_a": MATERIALS[0], "material_b": MATERIALS[1],
                                  "clamped": 30 * k, "measured_values": 1000}))
        wfiles.append(wf)
    out = tmp_path / "maps"
    mapped = _outputs(points, out)
    summary = out / "table.csv"
    rows = error_maps_from_files(prerenders=prerenders, weights=wfiles,
                                 references=[p["reference"] for p in points],
                                 references_noise=[p["reference_seed2"] for p in points],
                                 blended=[p["blended"] for p in mapped], error_exrs=[p["error_exr"] for p in mapped],
                                 error_pngs=[p["error_png"] for p in mapped], summary=summary, database="synthetic")
    assert sorted(out.iterdir()) == sorted([summary, *_output_files(mapped)])
    direct_dir = tmp_path / "direct"
    direct = error_maps(prerenders=prerenders, paths=_outputs(points, direct_dir),
                        summary=direct_dir / "summary.csv", database="synthetic")
    assert [r["rmse_blend"] for r in rows] == [r["rmse_blend"] for r in direct]
    # the share of the table the reference clamps comes from the point's weights file
    assert [r["clamped_fraction"] for r in rows] == [0.0, 0.03] and "clamped_fraction" not in direct[0]
    assert [r["sum_abs_w"] for r in rows] == [r["sum_abs_w"] for r in direct] == pytest.approx([1.0, 1.4])
    figs = tmp_path / "figs"

    def figure_map(folder: Path) -> dict[str, list[Path]]:  # the path figures write their note too
        return {k: [folder / f"my-{k}.{e}" for e in ("png", "pdf") + (("json",) if k != "prerenders" else ())]
                for k in ("prerenders", "fig12", "fig13")}

    figure_files = figure_map(figs)
    files = figures.make_render_figures(prerenders=prerenders, weights=wfiles,
                                        references=[p["reference"] for p in points],
                                        references_noise=[p["reference_seed2"] for p in points],
                                        blended=[p["blended"] for p in mapped],
                                        errors=[p["error_exr"] for p in mapped], summary=summary,
                                        figures=figure_files, database="synthetic")
    assert len(files) == 8 and all(f.stat().st_size > 200 for f in files)
    assert sorted(files) == sorted(p for v in figure_files.values() for p in v) == sorted(figs.iterdir())
    # Fig. 13 at the midpoint of the (only) path, its numbers those of the summary and the weights
    note = read_note(figs / "my-fig13.json")
    ratio = next(r["ratio_seed2"] for r in rows if r["t"] == 0.5)
    assert "t = 0.5" in note and f"ratio {ratio:.3g}" in note and "Σ|w| = 1.4," in note  # |0.6| + |0.6| + |−0.2|
    assert "is not rendered here" in note  # not Soler's chrome → silver-paint: the figure says so
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(BlendError, match="bad.json"):
        error_maps_from_files(prerenders=prerenders, weights=[tmp_path / "bad.json"], references=["x"],
                              references_noise=["y"], blended=["b"], error_exrs=["e"], error_pngs=["p"],
                              summary=summary, database="synthetic")
    with pytest.raises(BlendError, match="same length"):
        error_maps_from_files(prerenders=prerenders, weights=wfiles,
                              references=[p["reference"] for p in points],
                              references_noise=[p["reference_seed2"] for p in points],
                              blended=[p["blended"] for p in mapped], error_exrs=[p["error_exr"] for p in mapped],
                              error_pngs=[mapped[0]["error_png"]], summary=summary, database="synthetic")
    summary.unlink(missing_ok=True)
    with pytest.raises(FigureInputError, match="table.csv"):
        figures.make_render_figures(prerenders=prerenders, weights=wfiles,
                                    references=[p["reference"] for p in points],
                                    blended=[p["blended"] for p in mapped],
                                    errors=[p["error_exr"] for p in mapped], summary=summary,
                                    figures=figure_map(tmp_path / "figs2"), database="synthetic")
    assert not (tmp_path / "figs2").exists() or not list((tmp_path / "figs2").iterdir())


def test_error_maps_of_the_one_bounce_part(tmp_path: Path) -> None:
    """With I¹⁻ pre-renders, the same weights blend them and six ``_one`` columns compare them."""
    prerenders, points, images = _setup(tmp_path)
    rng = np.random.default_rng(8)
    src = tmp_path / "in"
    ones = {}
    for m in MATERIALS:
        images[m + "-one"] = (0.8 * images[m]).astype(np.float32)
        ones[m] = src / f"{m}-one.exr"
        write_exr(ones[m], images[m + "-one"])
    for k, pt in enumerate(points):
        exact = sum(pt["weights"][m] * images[m + "-one"].astype(np.float64) for m in MATERIALS)
        for key, name in (("reference_one", f"one-{k}.exr"), ("reference_one_seed2", f"one-{k}-2.exr")):
            img = (exact + rng.normal(0.0, 0.04, exact.shape)).astype(np.float32)
            write_exr(src / name, img)
            pt[key] = str(src / name)
            images[name] = img
    out = tmp_path / "out"
    rows = error_maps(prerenders=prerenders, paths=_outputs(points, out), summary=out / "s.csv",
                      database="synthetic", prerenders_one=ones)
    for k, (row, pt) in enumerate(zip(rows, points)):
        direct = sum(pt["weights"][m] * images[m + "-one"].astype(np.float64) for m in MATERIALS)
        ref, ref2 = (images[n].astype(np.float64) for n in (f"one-{k}.exr", f"one-{k}-2.exr"))
        rb, rn = (np.sqrt(np.mean((a - b) ** 2)) / ref.mean() for a, b in ((direct, ref), (ref, ref2)))
        rb2 = np.sqrt(np.mean((direct - ref2) ** 2)) / ref.mean()
        assert row["rmse_blend_one"] == pytest.approx(rb, rel=1e-12)
        assert row["rmse_noise_one"] == pytest.approx(rn, rel=1e-12)
        assert row["ratio_one"] == pytest.approx(rb / rn, rel=1e-12)
        assert row["ratio_one_seed2"] == pytest.approx(rb2 / rn, rel=1e-12)
        assert row["mean_reference_one"] == pytest.approx(ref.mean(), rel=1e-12)
        assert row["ratio_one_seed2_se"] == pytest.approx(blend.ratio_standard_error(direct, ref, ref2), rel=1e-12)
        assert 0 < row["ratio_one_seed2_se"] < np.inf and 0 < row["ratio_seed2_se"] < np.inf
    with io.StringIO(integrity.read_csv_text(out / "s.csv"), newline="") as fh:
        table = list(csv.DictReader(fh))
    assert float(table[1]["ratio_one_seed2"]) == pytest.approx(rows[1]["ratio_one_seed2"], rel=1e-8)
    assert float(table[1]["ratio_seed2_se"]) == pytest.approx(rows[1]["ratio_seed2_se"], rel=1e-8)
    # without I¹⁻ images the columns are empty; a point lacking its I¹⁻ reference is named
    error_maps(prerenders=prerenders, paths=_outputs(points, out), summary=out / "s.csv", database="synthetic")
    with io.StringIO(integrity.read_csv_text(out / "s.csv"), newline="") as fh:
        assert all(r["ratio_one"] == "" for r in csv.DictReader(fh))
    lacking = [{k: v for k, v in pt.items() if k != "reference_one"} for pt in points]
    with pytest.raises(BlendError, match="reference_one"):
        error_maps(prerenders=prerenders, paths=_outputs(lacking, out), summary=out / "s.csv",
                   database="synthetic", prerenders_one=ones)
    with pytest.raises(BlendError, match="different materials"):
        error_maps(prerenders=prerenders, paths=_outputs(points, out), summary=out / "s.csv",
                   database="synthetic", prerenders_one={MATERIALS[0]: ones[MATERIALS[0]]})


@pytest.mark.parametrize("l2_error", [0.0, 1.0])
def test_isolated_reference_differs_from_the_blend_by_the_l2_paths_alone(tmp_path: Path, l2_error: float) -> None:
    """ratio_isolated_seed2: the blend against Σ wᵢ I¹⁻ᵢ + the second reference's I²⁺.  The reference's table is
    clamped — its I¹⁻ is not the blend of the pre-renders' I¹⁻ — which the clamped reference's ratio reads as a
    large excess; the isolated reference does not, and reads an L²⁺ error (the reference's I²⁺ off the blend of
    the pre-renders' I²⁺) when there is one."""
    prerenders, points, images = _setup(tmp_path)
    rng = np.random.default_rng(9)
    src = tmp_path / "in"
    ones = {}
    for m in MATERIALS:  # I = I¹⁻ + I²⁺ with I²⁺ a tenth of the image
        images[m + "-one"] = (0.9 * images[m]).astype(np.float32)
        ones[m] = src / f"{m}-one.exr"
        write_exr(ones[m], images[m + "-one"])
    for k, pt in enumerate(points):
        w = pt["weights"]
        one = sum(w[m] * images[m + "-one"].astype(np.float64) for m in MATERIALS)
        two = sum(w[m] * (images[m] - images[m + "-one"]).astype(np.float64) for m in MATERIALS)
        clamp = 0.5 * np.abs(one).mean() * (rng.random(one.shape) < 0.3)  # the clamped table's brighter I¹⁻
        for key, seed in (("", ""), ("_seed2", "-2")):
            ref_one = one + clamp + rng.normal(0.0, 0.01, one.shape)
            ref = ref_one + (1.0 + l2_error) * two + rng.normal(0.0, 0.01, one.shape)
            for kind, img in (("reference" + key, ref), ("reference_one" + key, ref_one)):
                name = f"{kind}-{k}.exr"
                write_exr(src / name, img.astype(np.float32))
                images[name] = img.astype(np.float32).astype(np.float64)
                pt[kind] = str(src / name)
    out = tmp_path / "out"
    rows = error_maps(prerenders=prerenders, paths=_outputs(points, out), summary=out / "s.csv",
                      database="synthetic", prerenders_one=ones)
    for k, (row, pt) in enumerate(zip(rows, points)):
        w = pt["weights"]
        bl = sum(w[m] * images[m].astype(np.float64) for m in MATERIALS)
        bl_one = sum(w[m] * images[m + "-one"].astype(np.float64) for m in MATERIALS)
        ref, ref2, ref2_one = (images[f"{n}-{k}.exr"] for n in ("reference", "reference_seed2", "reference_one_seed2"))
        isolated = bl_one + ref2 - ref2_one
        want = np.sqrt(np.mean((bl - isolated) ** 2) / np.mean((ref - ref2) ** 2))
        assert row["ratio_isolated_seed2"] == pytest.approx(want, rel=1e-9)
        assert row["ratio_isolated_seed2_se"] == pytest.approx(
            blend.ratio_standard_error(bl, ref, ref2, isolated), rel=1e-9)
        assert row["ratio_seed2"] > 5.0  # the clamped reference: the clamp, not the L²⁺ paths
        assert row["sum_abs_w"] == pytest.approx(sum(abs(v) for v in w.values()))
        if l2_error == 0.0:  # only the I²⁺ noise left: below the whole images' floor
            assert row["ratio_isolated_seed2"] < 1.0
        else:
            assert row["ratio_isolated_seed2"] > 2.0
    with io.StringIO(integrity.read_csv_text(out / "s.csv"), newline="") as fh:
        table = list(csv.DictReader(fh))
    assert float(table[1]["ratio_isolated_seed2"]) == pytest.approx(rows[1]["ratio_isolated_seed2"], rel=1e-8)
    assert table[0]["clamped_fraction"] == ""  # not given with the point


def test_bounce_shares(tmp_path: Path) -> None:
    from brdfpipe.rendering.blend import bounce_shares

    rng = np.random.default_rng(3)
    mask = np.zeros((H, W, 3), np.float32)
    mask[: H // 2] = 1.0
    write_exr(tmp_path / "mask.exr", mask)
    images, ones = {}, {}
    for k, m in enumerate(MATERIALS):
        whole = rng.uniform(0.5, 1.0, (H, W, 3)).astype(np.float32)
        one = whole.copy()
        one[: H // 2] *= np.float32(1.0 - 0.1 * k)  # I²⁺ only on the object, 10 k %
        images[m], ones[m] = tmp_path / f"{m}.exr", tmp_path / f"{m}-one.exr"
        write_exr(images[m], whole)
        write_exr(ones[m], one)
    rows = bounce_shares(images=images, ones=ones, mask=tmp_path / "mask.exr", out=tmp_path / "s.csv",
                         database="synthetic")
    for k, row in enumerate(rows):
        whole, one = read_exr(images[row["material"]]).astype(np.float64), read_exr(ones[row["material"]])
        assert row["share_object"] == pytest.approx(0.1 * k, abs=1e-6)
        assert row["share_image"] == pytest.approx(1.0 - one.astype(np.float64).mean() / whole.mean(), abs=1e-9)
        assert row["object_pixels"] == (H // 2) * W
    with io.StringIO(integrity.read_csv_text(tmp_path / "s.csv"), newline="") as fh:
        table = list(csv.reader(fh))
    assert tuple(table[0]) == tables.BOUNCE_SHARES and [r[1] for r in table[1:]] == list(MATERIALS)
    write_exr(tmp_path / "empty.exr", np.zeros((H, W, 3), np.float32))
    with pytest.raises(BlendError, match="empty.exr"):
        bounce_shares(images=images, ones=ones, mask=tmp_path / "empty.exr", out=tmp_path / "s.csv",
                      database="synthetic")


# -- the noise-floor check of every candidate ---------------------------------


def _floor_inputs(tmp_path: Path, spp: tuple[int, int] = (4096, 4096)) -> dict[str, Any]:
    """Two candidates with two path points each: summaries from error_maps, weights JSONs, references."""

    rng = np.random.default_rng(3)
    pre = {m: p for m, p in zip(MATERIALS, _images(tmp_path, 3, seed=4))}
    out: dict[str, Any] = {"summaries": {}, "weights": {}, "references": {}}
    for c, sp in zip(("standardised-mu1e-06", "raw-mu0.0001"), spp):
        d = tmp_path / c
        d.mkdir()
        points, wfiles, refs = [], [], []
        for k, t in enumerate((0.25, 0.5)):
            w = rng.normal(size=3)
            w += (1.0 - w.sum()) / 3
            wf = d / f"p-t{t}-weights.json"
            integrity.write_json(wf, ({"path": "a--b", "t": t, "clamped": 10 * k, "measured_values": 1000,
                                      "weights": dict(zip(MATERIALS, w.tolist()))}))
            ref, ref2 = d / f"p-t{t}.exr", d / f"p-t{t}-noise.exr"
            for f, s in ((ref, 10 + k), (ref2, 20 + k)):
                write_exr(f, rng.uniform(0.5, 1.5, (H, W, 3)).astype(np.float32), attrs={"spp": str(sp)})
            points.append({"path": "a--b", "t": t, "weights": dict(zip(MATERIALS, w)), "reference": ref,
                           "reference_seed2": ref2, "blended": d / f"b{k}.exr", "error_exr": d / f"e{k}.exr",
                           "error_png": d / f"e{k}.png"})
            wfiles.append(wf)
            refs.append(ref)
        out["summaries"][c] = d / "summary.csv"
        error_maps(prerenders=pre, paths=points, summary=out["summaries"][c], database="synthetic")
        out["weights"][c], out["references"][c] = wfiles, refs
    out["candidates"] = {"standardised-mu1e-06": ("standardised", 1e-6), "raw-mu0.0001": ("raw", 1e-4)}
    return out


def test_floor_check_table_joins_every_candidate(tmp_path: Path) -> None:

    inp = _floor_inputs(tmp_path)
    out = tmp_path / "floor-check.csv"
    rows = blend.floor_check_table(**inp, default="standardised-mu1e-06", out=out, database="synthetic")
    with io.StringIO(integrity.read_csv_text(out), newline="") as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == list(tables.FLOOR_CHECK) and len(table) == len(rows) == 4
    assert [(r["candidate"], r["default"], r["t"]) for r in table] == [
        ("standardised-mu1e-06", "1", "0.25"), ("standardised-mu1e-06", "1", "0.5"),
        ("raw-mu0.0001", "0", "0.25"), ("raw-mu0.0001", "0", "0.5")]
    for r in table:
        doc = integrity.read_json(inp["weights"][r["candidate"]][0 if r["t"] == "0.25" else 1])
        w = np.array(list(doc["weights"].values()))
        assert float(r["sum_abs_w"]) == pytest.approx(np.abs(w).sum())
        assert float(r["norm2_w"]) == pytest.approx(np.sqrt((w * w).sum()))
        assert float(r["clamped_fraction"]) == pytest.approx(doc["clamped"] / 1000)
        assert (r["width"], r["height"], r["spp"]) == (str(W), str(H), "4096")
    # the ratios are the summary's, against the independent seed
    with io.StringIO(integrity.read_csv_text(inp["summaries"]["raw-mu0.0001"]), newline="") as fh:
        summary = list(csv.DictReader(fh))
    assert [r["ratio_seed2"] for r in table[2:]] == [s["ratio_seed2"] for s in summary]


def test_floor_check_table_refuses_mixed_renders_and_other_databases(tmp_path: Path) -> None:
    inp = _floor_inputs(tmp_path, spp=(4096, 64))
    out = tmp_path / "floor-check.csv"
    with pytest.raises(BlendError, match=r"at 64 spp, but .* at 4096 spp"):
        blend.floor_check_table(**inp, default="standardised-mu1e-06", out=out, database="synthetic")
    with pytest.raises(BlendError, match="this run's is 'merl'"):
        blend.floor_check_table(**inp, default="standardised-mu1e-06", out=out, database="merl")
    with pytest.raises(BlendError, match="not among the candidates"):
        blend.floor_check_table(**inp, default="log-mu0.0001", out=out, database="synthetic")
    inp["weights"]["raw-mu0.0001"] = inp["weights"]["raw-mu0.0001"][::-1]
    with pytest.raises(BlendError, match="does not match"):
        blend.floor_check_table(**{**inp, "references": {c: r for c, r in inp["references"].items()}},
                                default="standardised-mu1e-06", out=out, database="synthetic")
    assert not out.exists()


def test_floor_check_figure(tmp_path: Path) -> None:
    from brdfpipe.core.plot import FigureInputError
    from brdfpipe.rendering import figures

    inp = _floor_inputs(tmp_path)
    table = tmp_path / "floor-check.csv"
    blend.floor_check_table(**inp, default="standardised-mu1e-06", out=table, database="synthetic")
    res = figures.plot_floor_check(table=table, files=[tmp_path / "f.png", tmp_path / "f.pdf"], database="synthetic")
    assert (tmp_path / "f.png").stat().st_size > 0 and "synthetic MERL-format database" in res.title
    assert any("I¹⁻" in t for t in res.panel_titles)
    with pytest.raises(FigureInputError, match="this run's is 'merl'"):
        figures.plot_floor_check(table=table, files=[tmp_path / "g.png", tmp_path / "g.pdf"], database="merl")


# --------------------------------------------------------------------------
# Integrity (issue 21): a changed pixel of an input is refused, not blended
# --------------------------------------------------------------------------


def _rewrite_pixel(path: Path, value: float, channel: str = "G") -> None:
    """Rewrite an EXR with one pixel changed, its header (attributes included) kept: an edit by another tool."""
    import OpenEXR

    f = OpenEXR.File(str(path), separate_channels=True)
    header, planes = dict(f.header()), {c: np.array(p.pixels) for c, p in f.channels().items()}
    planes[channel][3, 4] = value
    with OpenEXR.File(header, planes) as g:
        g.write(str(path))


@pytest.mark.parametrize("which", ["prerender", "reference"])
def test_one_changed_pixel_of_an_input_stops_the_error_maps(tmp_path: Path, which: str) -> None:
    """The tester's case: one 1e6 pixel in a pre-render made an error map's RMSE 3,600x worse with exit 0.
    Now the job stops, naming the file and the rule to rerun, and writes no summary."""
    prerenders, points, _ = _setup(tmp_path / "results" / "renders")
    if which == "prerender":
        bad = prerenders["chrome"]
        rule = "prerender_materials"
        moved = tmp_path / "results" / "renders" / "preview" / "materials" / "chrome.exr"
    else:
        bad = Path(points[1]["reference"])
        rule = "render_path_points"
        moved = tmp_path / "results" / "renders" / "preview" / "paths" / "chrome--silver-t0.5.exr"
    moved.parent.mkdir(parents=True, exist_ok=True)
    bad.rename(moved)
    if which == "prerender":
        prerenders["chrome"] = moved
    else:
        points[1]["reference"] = str(moved)
    _rewrite_pixel(moved, 1e6)
    out = tmp_path / "out"
    summary = out / "summary.csv"
    hint = (f"delete it and rerun the workflow (a {rule}_* job writes it again)" if which == "prerender"
            else f"rerun its rule: snakemake --forcerun {rule}")
    with pytest.raises(ExrError, match=re.escape(f"{moved}: its pixels or attributes do not match their recorded "
                                                 f"digest (damaged or edited); {hint}")):
        error_maps(prerenders=prerenders, paths=_outputs(points, out), summary=summary, database="synthetic")
    assert not summary.exists()


def test_a_relabelled_image_is_refused(tmp_path: Path) -> None:
    """The digest covers the header's attributes too: a pre-render relabelled as another material fails."""
    import OpenEXR

    prerenders, _, _ = _setup(tmp_path)
    f = OpenEXR.File(str(prerenders["chrome"]), separate_channels=True)
    header, planes = dict(f.header()), {c: p.pixels for c, p in f.channels().items()}
    header["material"] = "silver"
    with OpenEXR.File(header, planes) as g:
        g.write(str(prerenders["chrome"]))
    with pytest.raises(ExrError, match="chrome.exr: its pixels or attributes do not match"):
        read_exr(prerenders["chrome"])


def test_ratio_standard_error_is_the_spread_of_the_ratio_over_seeds() -> None:
    """The standard error of blend / floor from one pair of seeds equals the spread of that ratio over many pairs.

    A blend without bias (its own noise like a reference's) against a floor between two references: over
    400 independent noise draws the ratio's standard deviation is what :func:`blend.ratio_standard_error`
    estimates from each single draw's pixels (here 1.5 %); a heavy-tailed noise (a few fireflies) widens both.
    """
    rng = np.random.default_rng(7)
    truth = rng.uniform(0.2, 1.0, size=(24, 32, 3))

    def draws(noise) -> tuple[float, float]:
        ratios, ses = [], []
        for _ in range(400):
            ref, ref2, bl = (truth + noise() for _ in range(3))
            ratios.append(blend.rmse(bl, ref2) / blend.rmse(ref, ref2))
            ses.append(blend.ratio_standard_error(bl, ref, ref2))
        return float(np.std(ratios, ddof=1)), float(np.median(ses))

    spread, se = draws(lambda: 0.05 * rng.normal(size=truth.shape))
    assert se == pytest.approx(spread, rel=0.15) and 0.01 < se < 0.03
    fireflies = lambda: 0.05 * rng.normal(size=truth.shape) * np.where(rng.random(truth.shape) < 0.003, 20.0, 1.0)  # noqa: E731
    spread_ff, se_ff = draws(fireflies)
    assert se_ff > 2 * se and se_ff == pytest.approx(spread_ff, rel=0.35)
    # degenerate: identical references (no floor) or a single pixel give no error estimate
    assert np.isnan(blend.ratio_standard_error(truth, truth, truth))
    assert np.isnan(blend.ratio_standard_error(truth[:1, :1], truth[:1, :1] + 1, truth[:1, :1]))

