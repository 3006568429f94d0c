"""Soler et al. 2018 Figs. 1, 6, 12 and 13 as the paper draws them (issue 32, item 7).

Unit tests of the choices each figure makes (the paper's path, the measured
materials of Fig. 1 and their places, the notes the captions quote), then the
content of the four figures in a shared run of ``tests/config/tiny-nbrdf.yaml``
(13 MERL materials through their fits: Soler's Fig. 9 and Figs. 12/13 paths'
ends among them), each checked against an independent computation from the
run's own inputs.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import cli, plan
from brdfpipe.core import filenames, integrity
from brdfpipe.core.notes import read_note, write_note
from brdfpipe.report import captions
from brdfpipe.registry import manifold as man_spec

CONFIG = Path(__file__).resolve().parent / "config" / "tiny-nbrdf.yaml"


# -- the choices ---------------------------------------------------------------------------------------


def test_the_paper_path_is_rendered_beside_the_configured_ones_where_the_database_has_it() -> None:
    fig9 = list(man_spec.SOLER_PATHS)
    names = [m for p in fig9 for m in p]  # silver-paint among them (teflon → silver-paint), chrome not
    assert man_spec.rendered_paths(fig9, names) == fig9
    names.append("chrome")
    assert man_spec.rendered_paths(fig9, names) == [*fig9, ("chrome", "silver-paint")]
    assert man_spec.rendered_paths([("chrome", "silver-paint")], names) == [("chrome", "silver-paint")]
    assert man_spec.rendered_paths([("a", "b")], ["a", "b", "chrome"]) == [("a", "b")]


def test_fig01_puts_soler_s_measured_materials_at_his_places_and_draws_the_missing() -> None:
    from brdfpipe.rendering.figures import FIG01_COLUMNS, fig01_layout

    full = ["two-layer-silver", "chrome-steel", "gold-paint", "brass", "teflon", "red-plastic"]
    cells, how = fig01_layout(11, full, 2018)
    assert len(cells) == 15 and sum(k == "sample" for k, _ in cells) == 11
    for m, (r, c) in man_spec.SOLER_FIG1_MATERIALS:  # §4.3: row 1 column 4 two-layer silver, …
        assert cells[r * FIG01_COLUMNS + c] == ("measured", m)
    assert [n for k, n in cells if k == "sample"] == [str(i) for i in range(11)]
    assert "drawn" not in how
    some = ["gold-paint", "a", "b", "c", "d", "e"]
    cells, how = fig01_layout(11, some, 7)
    measured = [n for k, n in cells if k == "measured"]
    assert len(measured) == 4 and cells[1 * FIG01_COLUMNS + 2] == ("measured", "gold-paint")
    assert set(measured) - {"gold-paint"} <= set(some) and "in place of" in how
    assert fig01_layout(11, some, 7) == (cells, how)  # seeded
    cells, _ = fig01_layout(2, full, 1)  # fewer cells than the paper's places
    assert len(cells) == 6 and sum(k == "measured" for k, _ in cells) == 4


def test_figs_12_and_13_take_soler_s_path_and_its_midpoint_or_say_why_not(tmp_path: Path) -> None:
    from brdfpipe.rendering import figures

    def pt(path: str, t: float) -> figures.RenderPoint:
        a, b = path.split("--")
        return figures.RenderPoint(path, a, b, t, tmp_path, tmp_path, tmp_path, q=5)

    soler = man_spec.path_name(*man_spec.SOLER_FIG12_PATH)
    pts = [pt("teflon--silver-paint", 0.5), pt(soler, 0.25), pt(soler, 0.5), pt(soler, 0.75)]
    assert figures.paper_path(pts) == (soler, "")
    assert figures._midpoint(pts) == (pts[2], "")
    name, why = figures.paper_path(pts[:1])
    assert name == "teflon--silver-paint" and "chrome → silver-paint is not rendered" in why
    q, why = figures._midpoint([pt(soler, 0.25), pt(soler, 0.75)])
    assert q.t == 0.25 and "t = 0.5 is not rendered" in why


def test_render_figures_are_planned_with_their_notes() -> None:
    figs = plan.render_figures(3, 11)
    assert list(figs) == ["fig01", "prerenders", "fig12", "fig13"]
    assert figs["fig01"] == filenames.figure_files("render-fig01-latent-samples", note=True)
    assert figs["fig01"][-1].endswith(".json") and len(figs["prerenders"]) == 2
    assert list(plan.render_figures(0, 0)) == ["prerenders"]
    notes = plan.figure_notes(acquisition_figures={}, manifold_figures=plan.manifold_figures({"latent_dims": [2, 5]}),
                              render_figures=figs)
    assert notes == {"soler-fig06": filenames.figure_files("manifold-fig06-lengthscale", note=True)[-1],
                     **{f"render-{k}": figs[k][-1] for k in ("fig01", "fig12", "fig13")}}


def test_a_caption_quotes_its_figure_s_note_literally(tmp_path: Path) -> None:
    path = write_note(tmp_path / "f", "t", "Σ|w| = 1.87, *clamped* `share` 3 %\nsecond line")
    note = read_note(path)
    assert note == "Σ|w| = 1.87, *clamped* `share` 3 % second line"
    text = captions.caption_rst("render-fig13", [], database="merl-nbrdf", note=note)
    assert "This run: " in text and "\\*clamped\\*" in text and "\\`share\\`" in text
    assert "This run" not in captions.caption_rst("render-fig13", [], database="merl-nbrdf")
    path.write_text(path.read_text().replace("1.87", "1.88"))
    with pytest.raises(integrity.IntegrityError, match="f.json"):
        read_note(path)


# -- the four figures of a tiny-nbrdf run ---------------------------------------------------------------


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from shared_runs import shared_run

    return shared_run(tmp_path_factory, CONFIG)


def _config() -> dict:
    import yaml

    return yaml.safe_load(CONFIG.read_text())


def _default_model(work: Path, q: int) -> Path:
    """The model file of the config's own fit (its label names how it is fitted: tiny-nbrdf fits with hybrid)."""
    from brdfpipe.registry.manifold import candidate_label

    m = _config()["manifold"]
    label = candidate_label(m["space"], m["mu"], m.get("normalise", True), m.get("method", "newton"),
                            m.get("init", "best"))
    return work / filenames.gplvm_model(label, q)


@pytest.mark.slow
def test_fig01_samples_are_brdfpipe_sample_s_rendered_like_the_pre_renders(work: Path, tmp_path: Path) -> None:
    from brdfpipe.core.exr import read_exr, read_exr_attrs
    from brdfpipe.data import provenance
    from brdfpipe.manifold import gplvm, latent

    cfg = _config()
    scene, res = cfg["render"]["scene"], work / "results"
    doc = json.loads((work / filenames.latent_samples_json(scene)).read_text())
    count, seed = doc["count"], doc["seed"]
    assert (count, seed) == (11, 2018)  # the schema's defaults: Soler's eleven
    model_file = _default_model(work, 5)
    # drawn exactly as `brdfpipe sample` draws them: its tables are the same bytes
    out = tmp_path / "cli"
    assert cli.main(["-q", "sample", "--model", str(model_file), "--store", str(res / "merl.zarr"), "--seed",
                     str(seed), "--count", str(count), "--out-dir", str(out)]) == 0
    by_cli = json.loads((out / "samples.json").read_text())
    model = gplvm.load_model(model_file)
    points = np.array([s["latent"] for s in doc["samples"]])
    assert points.tolist() == [s["latent"] for s in by_cli["samples"]]
    assert latent.hull_contains(model.X, points).all()
    for k, s in enumerate(doc["samples"]):
        table = work / filenames.latent_sample(scene, k, "binary")
        assert table.read_bytes() == (out / f"sample-{k:03d}.binary").read_bytes()
        mark = provenance.read_mark(table)
        assert mark is not None and (mark.kind, mark.name) == ("derived", f"sample-{k:03d}")
        assert mark.fields["operation"] == "sample" and mark.fields["inputs"]["latent"] == s["latent"]
        assert all(0.0 <= a <= 1.0 for a in s["albedo"])
        assert s["sum_abs_w"] == pytest.approx(sum(abs(v) for v in s["weights"].values()))
        # rendered in the pre-renders' scene and settings
        image = work / filenames.latent_sample(scene, k, "image")
        attrs, pre = read_exr_attrs(image), read_exr_attrs(work / filenames.prerender(scene, "chrome"))
        assert attrs["material_file"] == table.name
        for key in ("spp", "pass_spp", "seed", "integrator", "mitsuba_variant", "database"):
            assert attrs[key] == pre[key], key
        assert read_exr(image).shape == (*cfg["render"]["resolution"][::-1], 3)
    note = read_note(work / filenames.figure_files("render-fig01-latent-samples", note=True)[-1])
    sums = [s["sum_abs_w"] for s in doc["samples"]]
    assert f"--seed {seed} --count {count}" in note and f"Σ|w| from {min(sums):.3g} to {max(sums):.3g}" in note
    assert "pre-renders of Soler's measured gold-paint; " in note  # the only one of his four in this config


@pytest.mark.slow
def test_fig06_follows_the_paper_s_path_and_its_limit(work: Path) -> None:
    from brdfpipe.manifold import gplvm, gram
    from brdfpipe.manifold.lengthscale_figure import read_lengthscales

    tab = read_lengthscales(work / filenames.lengthscales_csv())
    assert (tab.material_a, tab.material_b, tab.q, tab.space) == ("chrome", "silver-paint", 5, "standardised")
    G, _, info = gram.load_gram(work / filenames.gram("standardised"))
    model = gplvm.load_model(_default_model(work, 5))
    names = list(model.names)
    z = math.sqrt(np.trace(G))
    fit = int(np.argmin(np.abs(np.log(tab.factors))))
    mid = int(np.argmin(np.abs(tab.t - 0.5)))
    x = 0.5 * (model.X[names.index("chrome")] + model.X[names.index("silver-paint")])
    # at the fitted ℓ: the weights of the model itself (its own Cholesky factor)
    w = gplvm.blend_weights(gplvm.weights(model, x))
    j = int(np.argmin(np.linalg.norm(model.X - x, axis=1)))
    v = w.copy()
    v[j] -= 1
    assert tab.deviation[fit, mid] == pytest.approx(math.sqrt(v @ G @ v) / z, rel=1e-6)
    assert tab.from_mean[fit, mid] == pytest.approx(math.sqrt(w @ G @ w) / z, rel=1e-6)
    inner = (tab.t > 0) & (tab.t < 1)
    assert (tab.deviation[:, inner] <= tab.bound[:, inner]).all()
    # as ℓ shrinks the midpoint becomes the mean of the materials: ‖z* − z_j‖ → ‖z̄ − z_j‖ = √(G_c)ⱼⱼ
    assert tab.from_mean[0, mid] < 1e-3 * tab.from_mean[fit, mid]
    assert tab.deviation[0, mid] == pytest.approx(math.sqrt(G[j, j]) / z, rel=1e-3)
    note = read_note(work / filenames.figure_files("manifold-fig06-lengthscale", note=True)[-1])
    assert note.startswith("Along chrome → silver-paint (q = 5")


@pytest.mark.slow
def test_figs_12_and_13_show_chrome_to_silver_paint_and_its_midpoint(work: Path) -> None:
    from brdfpipe.core.exr import read_exr
    from brdfpipe.rendering.blend import relative_rmse

    scene, path = _config()["render"]["scene"], "chrome--silver-paint"
    wdoc = integrity.read_json(work / filenames.path_point(scene, path, 0.5, "weights"))
    assert (wdoc["material_a"], wdoc["material_b"], wdoc["q"]) == ("chrome", "silver-paint", 5)
    # the blend of Fig. 12/13 is Σ wᵢ Iᵢ of the pre-renders, formed here from the weights and the images
    blend = sum(w * read_exr(work / filenames.prerender(scene, m)).astype(np.float64)
                for m, w in wdoc["weights"].items())
    shown = read_exr(work / filenames.errormap(scene, path, 0.5, "blended.exr")).astype(np.float64)
    np.testing.assert_allclose(shown, blend, rtol=1e-6, atol=1e-6 * float(np.abs(blend).max()))
    ref = read_exr(work / filenames.path_point(scene, path, 0.5, "image")).astype(np.float64)
    ref2 = read_exr(work / filenames.path_point(scene, path, 0.5, "noise")).astype(np.float64)
    _, rows = integrity.read_csv_rows(work / filenames.errormap_summary(scene), required=("path", "t", "ratio_seed2"))
    row = next(r for r in rows if (r["path"], r["t"]) == (path, "0.5"))
    ratio = relative_rmse(blend, ref2, ref) / relative_rmse(ref, ref2, ref)
    assert float(row["ratio_seed2"]) == pytest.approx(ratio, rel=1e-5)
    sum_abs = sum(abs(v) for v in wdoc["weights"].values())
    share = wdoc["clamped"] / wdoc["measured_values"]
    for stem in ("render-fig12-interpolation", "render-fig13-errors"):
        note = read_note(work / filenames.figure_files(stem, note=True)[-1])
        assert note.startswith("chrome → silver-paint") and "q = 5" in note and "(Soler's" in note
        assert f"Σ|w| = {sum_abs:.3g}" in note and f"ratio {ratio:.3g}" in note
        assert f"clamped share {100 * share:.3g} %" in note
    # the report's captions quote the notes
    cap = (work / filenames.caption("render-fig13")).read_text()
    assert "This run: chrome \\→ silver\\-paint" in cap
