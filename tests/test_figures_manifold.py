"""Tests of the :mod:`brdfpipe.manifold.figures` (Soler 2018 analogues).

The fixtures are small synthetic files in the formats ``brdfpipe.manifold.analysis``
writes: GPLVM models (q = 2 and 5) fitted to a random Gram matrix of
N = 24 materials and saved with :func:`brdfpipe.manifold.gplvm.save_model`, their
traces (:func:`brdfpipe.manifold.gplvm.write_trace`: Hooke–Jeeves sweeps, then an
L-BFGS polish), ``albedo.csv``, albedo maps for q = 2 and a q = 5 slice,
``paths.csv`` (three q = 5 paths and one q = 2 path, 21 points each) and
``reproduction.csv`` (PCA k = 2, 5, 20, 40; GPLVM q = 2, 5 at ~1e-16).
"""

from __future__ import annotations

import csv
import io
import logging
import math
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from brdfpipe.core import integrity
from brdfpipe.core.filenames import MANIFOLD_FIGURE_STEMS
from brdfpipe.core.notes import read_note
from brdfpipe.core.plot import FigureInputError
from brdfpipe.manifold import fitting, gplvm, gram, latent_map, lengthscale
from brdfpipe.manifold.figure_inputs import (
    read_albedo_map,
    read_manifold_inputs,
    read_paths,
    read_trace,
)
from brdfpipe.manifold.figures import (
    make_manifold_figures,
    manifold_eq7_bound,
    manifold_fig10_latent_q2,
    manifold_fig10_latent_q5,
)
from brdfpipe.registry import tables

DB = "synthetic"
N = 24
D = 60
QS = (2, 5)
STEPS = 20
BASE_NAMES = ("alum-bronze", "blue-metallic-paint", "dark-blue-paint", "teflon", "silver-paint",
              "black-oxidized-steel", "color-changing-paint3", "gold-metallic-paint", "chrome-steel",
              "white-fabric", "red-plastic", "two-layer-silver")
NAMES = tuple(BASE_NAMES[i % len(BASE_NAMES)] + ("" if i < len(BASE_NAMES) else f"-{i}") for i in range(N))
# (path id, q, material A, material B)
PATHS = (("p0", 5, "blue-metallic-paint", "dark-blue-paint"), ("p1", 5, "teflon", "silver-paint"),
         ("p2", 5, "black-oxidized-steel", "color-changing-paint3"), ("p3", 2, "teflon", "silver-paint"))
PCA_K = (2, 5, 20, 40)


def _write_csv(path: Path, header: tuple[str, ...] | list[str], rows: list[list[object]]) -> Path:
    """A table as the workflow writes it: with its digest line (brdfpipe.core.integrity)."""
    integrity.write_csv(path, [header, *rows])
    return path


def _directions(n: int) -> np.ndarray:
    a = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([np.cos(a), np.sin(a)])


def _albedo(rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(0.02, 0.8, size=(N, 3))


def write_inputs(root: Path, *, database: str = DB) -> dict[str, object]:
    """Every input of make_manifold_figures under ``root``; returns its keyword arguments (less figures)."""
    rng = np.random.default_rng(2018)
    Z = rng.normal(size=(N, D)) * np.linspace(2.0, 0.2, D)
    Z -= Z.mean(axis=0)
    G = Z @ Z.T
    (root / "gplvm").mkdir(parents=True, exist_ok=True)
    (root / "manifold").mkdir(parents=True, exist_ok=True)
    models, traces, fits = {}, {}, {}
    for q in QS:
        res = fitting.fit(G, D, q=q, max_sweeps=5, polish_iterations=60)
        if q == 2:  # crowd 16 of the points into a tight cluster: the latent map must zoom on it
            res.X = np.concatenate([0.02 * rng.normal(size=(16, 2)),
                                    rng.uniform(3.0, 6.0, size=(N - 16, 1)) * _directions(N - 16)])
        models[q] = root / "gplvm" / f"q{q}.npz"
        traces[q] = root / "gplvm" / f"q{q}-trace.csv"
        gplvm.save_model(models[q], res, NAMES)
        gplvm.write_trace(traces[q], res)
        fits[q] = res

    rgb = _albedo(rng)
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    albedo_csv = _write_csv(root / "manifold" / "albedo.csv", tables.MATERIAL_ALBEDO,
                            [[database, n, *map(repr, c.tolist()), repr(float(v))] for n, c, v in zip(NAMES, rgb, lum)])

    maps = {}
    for q in QS:
        X = fits[q].X
        dims = np.array([0, 1])
        fixed = X.mean(axis=0)
        lo, hi = X[:, :2].min(axis=0) - 0.5, X[:, :2].max(axis=0) + 0.5
        x = np.linspace(lo[0], hi[0], 23)
        y = np.linspace(lo[1], hi[1], 19)
        gx, gy = np.meshgrid(x, y)  # (H, W)
        w = np.exp(-((gx[..., None] - X[:, 0]) ** 2 + (gy[..., None] - X[:, 1]) ** 2) / 2.0)
        w = w / (w.sum(-1, keepdims=True) + 1e-3)
        alb = np.einsum("hwn,nc->hwc", w, rgb) + 1e-3 * rgb.mean(axis=0)
        maps[q] = root / "manifold" / f"albedo-map-q{q}.npz"
        inside = (gx - X[:, 0].mean()) ** 2 + (gy - X[:, 1].mean()) ** 2 < (0.3 * (hi[0] - lo[0])) ** 2
        integrity.save_npz(maps[q], dict(
            x=x, y=y, dims=dims, albedo=alb, luminance=alb @ np.array([0.2126, 0.7152, 0.0722]),
            fixed=fixed, q=np.array(q), database=np.array(database), inside_hull=inside,
            bad_inside=np.array(0.0), bad_outside=np.array(0.25), training_gap_median=np.array(1e-4),
            training_gap_max=np.array(3e-3)))

    rows = []
    for pid, q, a, b in PATHS:
        pab = 0.3 + 0.1 * len(a) / 10
        dist = float(np.linalg.norm(fits[q].X[NAMES.index(a)] - fits[q].X[NAMES.index(b)]))
        for s in range(STEPS + 1):
            t = s / STEPS
            dev = 0.0 if s in (0, STEPS) else 0.4 * math.sin(math.pi * t) + 0.01 * s
            bound = 0.0 if s in (0, STEPS) else 30.0 * min(t, 1 - t) + 1.0
            if s == STEPS:
                dev = 1e-12  # rounding at the end point: omitted like an exact 0
            if pid == "p1" and s == 10:
                dev = 2.0 * bound  # a violation of the bound: marked and warned about
            nearest = a if t < 0.5 else b
            rows.append([database, "raw", q, pid, a, b, s, repr(t), repr(t * dist), repr(pab * t ** 0.8),
                         repr(pab * (1 - t) ** 1.2), repr(pab), nearest, repr(dev), repr(bound)])
    paths_csv = _write_csv(root / "manifold" / "paths.csv", tables.LATENT_PATHS, rows)

    rows = []
    for i, n in enumerate(NAMES):
        base = 0.05 + 0.4 * ((i * 7) % N) / N
        for k in PCA_K:
            rows.append([database, "raw", n, "pca", k, repr(base * (40.0 / (k + 2)) ** 0.6 / 10)])
        for q in QS:
            rows.append([database, "raw", n, "gplvm", q, repr(0.0 if i % 3 == 0 else (i % 5 + 1) * 1e-16)])
    repro_csv = _write_csv(root / "manifold" / "reproduction.csv", tables.REPRODUCTION, rows)
    rows, srows = [], []
    for c, (space, mu) in {"standardised-mu1e-06": ("standardised", 1e-6), "raw-mu0.0001": ("raw", 1e-4)}.items():
        for q in QS:
            r = {k: 0.5 for k in tables.SPACES}
            r.update(database=database, candidate=c, space=space, mu=mu, q=q, default=str(space != "raw").lower(),
                     kappa=1e4 if space != "raw" else 1e6, albedo_bad_hull=0.001 if space != "raw" else 0.2,
                     albedo_bad_map=0.01 if q == 2 else float("nan"))
            rows.append([r[k] for k in tables.SPACES])
            for norm in ("raw", "space"):
                for eps in (1e-9, 1e-6, 1e-3):
                    med = (1e-5 if space != "raw" else 0.08) + eps
                    srows.append([database, c, space, mu, q, norm, eps, med, 2 * med, 3 * med])
    spaces_csv = _write_csv(root / "manifold" / "spaces.csv", tables.SPACES, rows)
    stability_csv = _write_csv(root / "manifold" / "spaces-stability.csv", tables.STABILITY, srows)
    gram_path = root / "gplvm" / "gram-raw.npz"
    gram.save_gram(gram_path, G, D, gram.GramInfo(NAMES, "raw", Z.sum(axis=1), G, "mean subtracted"))
    lengthscales_csv = root / "manifold" / "lengthscales.csv"
    lengthscale.measure_lengthscales(model=models[5], gram=gram_path, path=["teflon", "silver-paint"],
                                     out=lengthscales_csv, database=database)
    return dict(models=models, traces=traces, albedo_csv=albedo_csv, albedo_maps=maps, paths_csv=paths_csv,
                reproduction_csv=repro_csv, spaces_csv=spaces_csv, stability_csv=stability_csv,
                lengthscales_csv=lengthscales_csv)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    return write_inputs(tmp_path_factory.mktemp("manifold-inputs"))


def figure_map(out: Path, keys: tuple[str, ...] | None = None) -> dict[str, list[Path]]:
    """The workflow's figure files (stems :data:`MANIFOLD_FIGURE_STEMS`, PNG + PDF, Fig. 6's note) under ``out``."""
    return {k: [out / f"{stem}.png", out / f"{stem}.pdf"] + ([out / f"{stem}.json"] if k == "fig06" else [])
            for k, stem in MANIFOLD_FIGURE_STEMS.items() if keys is None or k in keys}


def files_under(folder: Path) -> list[Path]:
    """Every file under ``folder`` (none when it does not exist)."""
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


@pytest.fixture(scope="module")
def outputs(inputs: dict[str, object], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    out = tmp_path_factory.mktemp("manifold-figs")
    return out, make_manifold_figures(**inputs, figures=figure_map(out))


def test_writes_every_figure(outputs: tuple[Path, list[Path]]) -> None:
    out, files = outputs
    expected = [out / f"{stem}.{ext}" for k, stem in MANIFOLD_FIGURE_STEMS.items()
                for ext in ("png", "pdf") + (("json",) if k == "fig06" else ())]
    assert files == expected and len(files) == 2 * len(MANIFOLD_FIGURE_STEMS) + 1
    assert files == [p for v in figure_map(out).values() for p in v]
    for p in files:
        assert p.is_file() and p.stat().st_size > (1000 if p.suffix != ".json" else 100), p
    assert read_note(out / f"{MANIFOLD_FIGURE_STEMS['fig06']}.json").startswith("Along teflon → silver-paint (q = 5")
    assert files_under(out) == sorted(files)  # exactly the files passed in: no temporary files left
    for stem in MANIFOLD_FIGURE_STEMS.values():
        img = matplotlib.image.imread(out / f"{stem}.png")
        assert img.ndim == 3 and img.shape[2] in (3, 4) and min(img.shape[:2]) > 400, stem
        assert float(img[..., :3].std()) > 0.02, f"{stem}.png looks blank"
        assert (out / f"{stem}.pdf").read_bytes().startswith(b"%PDF-")


def test_database_named_in_every_figure(outputs: tuple[Path, list[Path]]) -> None:
    out, _ = outputs
    for stem in MANIFOLD_FIGURE_STEMS.values():
        for ext in ("png", "pdf"):  # the title (naming the database) is the PNG's and the PDF's Title
            assert b"synthetic MERL-format database" in (out / f"{stem}.{ext}").read_bytes(), f"{stem}.{ext}"


def test_deterministic(inputs: dict[str, object], outputs: tuple[Path, list[Path]], tmp_path: Path) -> None:
    _, files_a = outputs
    files_b = make_manifold_figures(**inputs, figures=figure_map(tmp_path))
    assert [p.name for p in files_a] == [p.name for p in files_b]
    for a, b in zip(files_a, files_b):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_subset_of_figures_writes_exactly_those_files(inputs: dict[str, object], outputs: tuple[Path, list[Path]],
                                                      tmp_path: Path) -> None:
    out_a, _ = outputs
    out = tmp_path / "some"
    # Names the library never chose; only the keys given are drawn, in MANIFOLD_FIGURE_STEMS order.
    wanted = {"eq7": [out / "bound.png", out / "bound.pdf"], "fig05": [out / "sub" / "lik.png", out / "sub" / "lik.pdf"]}
    files = make_manifold_figures(**inputs, figures=wanted)
    assert files == [*wanted["fig05"], *wanted["eq7"]]
    assert files_under(out) == sorted(files)
    for key, (png, pdf) in wanted.items():
        stem = MANIFOLD_FIGURE_STEMS[key]
        assert png.read_bytes() == (out_a / f"{stem}.png").read_bytes(), png.name
        assert pdf.read_bytes() == (out_a / f"{stem}.pdf").read_bytes(), pdf.name
    assert make_manifold_figures(**inputs, figures={}) == []


@pytest.mark.parametrize("bad", ["unknown-key", "suffix-order", "with-table", "two-stems"])
def test_bad_figures_mapping_is_refused_before_writing(inputs: dict[str, object], tmp_path: Path, bad: str) -> None:
    out = tmp_path / "figs"
    mapping: dict[str, list[Path]] = figure_map(out)
    if bad == "unknown-key":
        mapping["fig99"] = [out / "fig99.png", out / "fig99.pdf"]
    elif bad == "suffix-order":
        mapping["fig09"] = mapping["fig09"][::-1]
    elif bad == "with-table":
        mapping["fig08"] = [*mapping["fig08"], out / "x.csv", out / "x.md"]
    else:
        mapping["eq7"] = [out / "eq7-a.png", out / "eq7-b.pdf"]
    with pytest.raises(ValueError, match="fig99" if bad == "unknown-key" else "figure outputs"):
        make_manifold_figures(**inputs, figures=mapping)
    assert files_under(tmp_path) == []


def test_database_argument_must_match(inputs: dict[str, object], tmp_path: Path) -> None:
    assert read_manifold_inputs(**inputs, database=DB).database == DB
    _expect_error(inputs, tmp_path, r"albedo\.csv.*'synthetic'.*'other'", database="other")


def test_readers(inputs: dict[str, object]) -> None:
    inp = read_manifold_inputs(**inputs)
    assert inp.database == DB and sorted(inp.models) == list(QS)
    tr = read_trace(inputs["traces"][2])  # type: ignore[index]
    st = list(tr.stage)
    assert st[0] == "start" and "newton" in st
    assert tr.switches == [k for k in range(1, len(st)) if st[k] != st[k - 1] and st[k - 1] != "start"]
    m = read_albedo_map(inputs["albedo_maps"][5])  # type: ignore[index]
    assert m.q == 5 and m.dims == (0, 1) and m.luminance.shape == (19, 23) and m.fixed.shape == (5,)
    pt = read_paths(inputs["paths_csv"])  # type: ignore[arg-type]
    assert [(p.name, p.q, p.material_a, p.material_b) for p in pt.paths] == list(PATHS)
    assert all(list(p.step) == list(range(STEPS + 1)) for p in pt.paths)
    colours = inp.albedo.display_colours(NAMES)
    assert colours.shape == (N, 3) and colours.max() == pytest.approx(1.0) and colours.min() >= 0.0


def _expect_error(inputs: dict[str, object], tmp_path: Path, pattern: str, **override: object) -> None:
    out = tmp_path / "out"
    with pytest.raises(FigureInputError, match=pattern):
        make_manifold_figures(**{**inputs, **override}, figures=figure_map(out))
    # every input is checked before anything is written (nor the folder itself: below)
    assert files_under(out) == []


def test_bad_input_creates_no_output_folder(inputs: dict[str, object], tmp_path: Path) -> None:
    out = tmp_path / "out"
    with pytest.raises(FigureInputError, match=r"absent-albedo\.csv"):
        make_manifold_figures(**{**inputs, "albedo_csv": tmp_path / "absent-albedo.csv"}, figures=figure_map(out))
    assert not out.exists()


def test_missing_files(inputs: dict[str, object], tmp_path: Path) -> None:
    _expect_error(inputs, tmp_path, r"absent-albedo\.csv.*not found", albedo_csv=tmp_path / "absent-albedo.csv")
    _expect_error(inputs, tmp_path, r"q9\.npz.*not found", models={**inputs["models"], 5: tmp_path / "q9.npz"})  # type: ignore[dict-item]
    _expect_error(inputs, tmp_path, r"nomap\.npz.*not found", albedo_maps={2: tmp_path / "nomap.npz"})
    _expect_error(inputs, tmp_path, r"notrace\.csv.*not found", traces={2: tmp_path / "notrace.csv"})


def test_bad_headers(inputs: dict[str, object], tmp_path: Path) -> None:
    src = integrity.read_csv_text(inputs["paths_csv"])  # type: ignore[arg-type]
    bad = tmp_path / "bad-paths.csv"
    integrity.write_csv(bad, src.replace("perceptual_ab", "perceptual_AB", 1))
    _expect_error(inputs, tmp_path, r"bad-paths\.csv.*perceptual_ab", paths_csv=bad)
    trace = tmp_path / "bad-trace.csv"
    integrity.write_csv(trace, "step,log_likelihood\n0,-3.0\n")
    _expect_error(inputs, tmp_path, r"bad-trace\.csv.*stage", traces={2: trace})
    repro = tmp_path / "bad-repro.csv"
    integrity.write_csv(repro, "database,space,material,method,relative_error\nsynthetic,raw,a,pca,0.1\n")
    _expect_error(inputs, tmp_path, r"bad-repro\.csv.*'?k'?", reproduction_csv=repro)
    empty = tmp_path / "empty-albedo.csv"
    integrity.write_csv(empty, "")
    _expect_error(inputs, tmp_path, r"empty-albedo\.csv.*empty", albedo_csv=empty)
    assert tables.GPLVM_TRACE == ("step", "stage", "log_likelihood")


def test_nan_and_bad_values(inputs: dict[str, object], tmp_path: Path) -> None:
    rows = integrity.read_csv_text(inputs["reproduction_csv"]).splitlines()  # type: ignore[arg-type]
    rows[3] = ",".join(rows[3].split(",")[:-1] + ["nan"])
    nan_repro = tmp_path / "nan-repro.csv"
    integrity.write_csv(nan_repro, "\n".join(rows) + "\n")
    _expect_error(inputs, tmp_path, r"nan-repro\.csv: line 5.*relative_error", reproduction_csv=nan_repro)

    with io.StringIO(integrity.read_csv_text(inputs["paths_csv"]), newline="") as fh:  # type: ignore[arg-type]
        recs = list(csv.DictReader(fh))
    recs[5]["perceptual_a"] = "NaN"
    nan_paths = _write_csv(tmp_path / "nan-paths.csv", tables.LATENT_PATHS, [[r[c] for c in tables.LATENT_PATHS] for r in recs])
    _expect_error(inputs, tmp_path, r"nan-paths\.csv: line 8.*perceptual_a", paths_csv=nan_paths)

    arrays = integrity.load_npz(inputs["albedo_maps"][2])  # type: ignore[index]
    arrays["luminance"] = arrays["luminance"].copy()
    arrays["luminance"][3, 4] = np.nan
    nan_map = tmp_path / "nan-map.npz"
    integrity.save_npz(nan_map, arrays)
    _expect_error(inputs, tmp_path, r"nan-map\.npz.*luminance.*NaN", albedo_maps={2: nan_map})

    lines = integrity.read_csv_text(inputs["traces"][5]).splitlines()  # type: ignore[index]
    lines[2] = lines[2].rsplit(",", 1)[0] + ",nan"
    nan_trace = tmp_path / "nan-trace.csv"
    integrity.write_csv(nan_trace, "\n".join(lines) + "\n")
    _expect_error(inputs, tmp_path, r"nan-trace\.csv: line 4.*log_likelihood", traces={5: nan_trace})

    text = integrity.read_csv_text(inputs["albedo_csv"])  # type: ignore[arg-type]
    bad_alb = tmp_path / "short-albedo.csv"
    integrity.write_csv(bad_alb, "\n".join(text.splitlines()[:-2]) + "\n")  # two materials missing
    _expect_error(inputs, tmp_path, r"short-albedo\.csv.*no albedo row", albedo_csv=bad_alb)


def test_inconsistent_inputs(inputs: dict[str, object], tmp_path: Path) -> None:
    # a path whose q has no model
    _expect_error(inputs, tmp_path, r"paths\.csv.*q = 5.*no GPLVM model", models={2: inputs["models"][2]},  # type: ignore[index]
                  traces={}, albedo_maps={2: inputs["albedo_maps"][2]})  # type: ignore[index]
    # a map given under the wrong q, a model under the wrong q
    _expect_error(inputs, tmp_path, r"albedo-map-q5\.npz.*q = 5 map.*q = 2", albedo_maps={2: inputs["albedo_maps"][5]})  # type: ignore[index]
    _expect_error(inputs, tmp_path, r"q2\.npz.*latent dimension 2.*q = 5",
                  models={2: inputs["models"][2], 5: inputs["models"][2]})  # type: ignore[index]
    # a model file that is not one
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file")
    _expect_error(inputs, tmp_path, r"junk\.npz", models={**inputs["models"], 2: junk})  # type: ignore[dict-item]
    # files from different databases
    rows = integrity.read_csv_text(inputs["reproduction_csv"]).replace("synthetic,", "merl,")  # type: ignore[arg-type]
    other = tmp_path / "other-db.csv"
    integrity.write_csv(other, rows)
    _expect_error(inputs, tmp_path, r"different databases.*other-db\.csv", reproduction_csv=other)
    # a trace with a second start row, and one with an unknown stage
    back = tmp_path / "back-trace.csv"
    integrity.write_csv(back, "step,stage,log_likelihood\n0,start,-5\n1,lbfgs,-4\n2,start,-3\n")
    _expect_error(inputs, tmp_path, r"back-trace\.csv: line 5", traces={2: back})
    odd = tmp_path / "odd-trace.csv"
    integrity.write_csv(odd, "step,stage,log_likelihood\n0,start,-5\n1,simplex,-4\n")
    _expect_error(inputs, tmp_path, r"odd-trace\.csv: line 4.*unknown stage", traces={2: odd})


def test_merl_and_optional_parts(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Database from the inputs (merl → "MERL (Matusik et al. 2003)"); no traces, no maps, only the q = 2 model: still
    16 files (the empty panels say so; warnings logged)."""
    kw = write_inputs(tmp_path / "in", database="merl")
    with io.StringIO(integrity.read_csv_text(kw["paths_csv"]), newline="") as fh:  # type: ignore[arg-type]
        recs = [r for r in csv.DictReader(fh) if r["q"] == "2"]
    paths = _write_csv(tmp_path / "paths-q2.csv", tables.LATENT_PATHS, [[r[c] for c in tables.LATENT_PATHS] for r in recs])
    with caplog.at_level(logging.WARNING, logger="brdfpipe"):
        files = make_manifold_figures(**{**kw, "models": {2: kw["models"][2]}, "traces": {}, "albedo_maps": {},  # type: ignore[index]
                                         "paths_csv": paths}, figures=figure_map(tmp_path / "out"))
    assert len(files) == 2 * len(MANIFOLD_FIGURE_STEMS) + 1 and all(p.is_file() for p in files)
    assert files_under(tmp_path / "out") == sorted(files)
    for p in files:
        assert b"Matusik et al. 2003" in p.read_bytes(), p.name  # the title ("MERL (Matusik et al. 2003)"), also in the PDF
    assert "no trace files" in caplog.text and "no albedo maps" in caplog.text and "no q = 5 model" in caplog.text
    assert "no gplvm rows for q = 5" not in caplog.text


def test_latent_maps_zoom_on_crowded_points(inputs: dict[str, object], tmp_path: Path) -> None:
    inp = read_manifold_inputs(**inputs)
    res = manifold_fig10_latent_q2(inp, tmp_path / "q2")
    # the 16 clustered points get a zoomed panel; the 8 spread ones do not need one
    assert len(res.panel_titles) == 2 and "zoom" in res.panel_titles[1] and "zoom" not in res.panel_titles[0]
    img = matplotlib.image.imread(res.files[0])
    assert img.shape[:2] == res.size_px
    res5 = manifold_fig10_latent_q5(inp, tmp_path / "q5")  # spread points: one panel per pair, no zoom
    assert res5.panel_titles == ("dims 0, 1", "dims 1, 2", "dims 2, 3", "dims 3, 4")
    assert "synthetic MERL-format database" in res.title and "synthetic MERL-format database" in res5.title


def test_zoom_chain() -> None:
    rng = np.random.default_rng(1)
    spread = rng.uniform(-5, 5, size=(30, 2))
    assert len(latent_map.zoom_chain(spread, (5.0, 5.0))) == 1
    cluster = np.concatenate([spread, 1e-3 * rng.normal(size=(20, 2))])
    views = latent_map.zoom_chain(cluster, (5.0, 5.0))
    assert len(views) >= 2
    x0, x1, y0, y1 = views[1]
    inside = (cluster[:, 0] >= x0) & (cluster[:, 0] <= x1) & (cluster[:, 1] >= y0) & (cluster[:, 1] <= y1)
    assert inside[30:].all() and (x1 - x0) < 0.1


def test_eq7_bound_end_points_and_violations(inputs: dict[str, object], tmp_path: Path) -> None:
    res = manifold_eq7_bound(read_manifold_inputs(**inputs), tmp_path / "eq7")
    assert res.panel_titles == tuple(f"{a} → {b} (q = {q})" for _, q, a, b in PATHS)
    assert len(res.warnings) == 1 and "'p1'" in res.warnings[0] and "exceeds the eq. 7 bound at 1 point" in res.warnings[0]
