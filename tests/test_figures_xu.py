"""Xu 2016 Figs. 2, 3, 9, 14 and 15: what each shows, checked against the run that drew it.

The tiny config's run (tests/shared_runs.py, shared with tests/test_workflow.py)
holds every figure.  Fig. 2 / 15: each reconstruction panel is a render of the
table the evaluation reconstructs (its log-space error is errors.csv's), made
exactly as the pre-renders (a fresh render of the table gives the same pixels),
next to the material's own pre-render; the inputs are the observed pixels.
Fig. 3: E_recon is eq. 12 computed from the model and the store, E_deviation
errors.csv's floor.  Figs. 9 / 14: the angles are the directions files'.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from brdfpipe import plan
from brdfpipe.acquisition import figures, geometry, reconstruct
from brdfpipe.acquisition.figure_inputs import read_errors
from brdfpipe.acquisition.optimize import read_directions
from brdfpipe.acquisition.svd import open_model
from brdfpipe.core import filenames as fn
from brdfpipe.core import integrity
from brdfpipe.core.exr import read_exr
from brdfpipe.core.plot import Warnings
from brdfpipe.data import logmap, merl, provenance
from brdfpipe.data.store import material_indices, open_store
from brdfpipe.registry import figures as fig_spec
from brdfpipe.registry import tables
from shared_runs import shared_run

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "config" / "tiny.yaml"
CONFIG = yaml.safe_load(TINY.read_text())


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return shared_run(tmp_path_factory, TINY)


def _rows(path: Path) -> list[dict[str, str]]:
    return integrity.read_csv_rows(path)[1]


def _held_out(run: Path) -> list[str]:
    """The run's held-out materials (sorted: the tiny config's are listed so)."""
    return sorted(json.loads((run / fn.splits()).read_text())["test"])


# ---------------------------------------------------------------------------
# What the planner asks for
# ---------------------------------------------------------------------------


def test_figure_materials_are_xus_seven_when_held_out() -> None:
    xu9 = ("black-soft-plastic", "blue-acrylic", "green-fabric", "light-red-paint", "pink-jasper",
           "silver-metallic-paint", "specular-violet-phenolic", "two-layer-silver", "white-fabric")
    held = sorted((*xu9, "alum-bronze"))  # merl-nbrdf's default held-out list
    assert plan.figure_materials(held) == list(fig_spec.FIG02_MATERIALS)
    assert set(fig_spec.FIG02_MATERIALS) == set(xu9) - {"green-fabric", "silver-metallic-paint"}
    assert plan.figure_materials(["a", "b", "c", "d", "e", "f"]) == ["a", "b", "c", "d"]  # another database


def test_fig02_columns_are_the_papers() -> None:
    acq = {"setups": ["point", "nearfield", "fixed_camera", "fixed_light"], "metrics": ["error", "condition_nielsen"],
           "fovs": [15, 25, 35], "fixed_fov": 30, "n_max_images": 5, "n_max_point": 20}
    cols = plan.reconstruction_columns(acq)
    metric = fig_spec.PREVIOUS_WORK_METRIC
    assert cols["fig02"] == [("1 image", ("nearfield", 25.0, "error", 1)), ("5 points", ("point", 0.0, metric, 5)),
                             ("2 images", ("nearfield", 25.0, "error", 2)), ("20 points", ("point", 0.0, metric, 20))]
    assert cols["fig15"] == [("2 images, fixed camera", ("fixed_camera", 30.0, "error", 2)),
                             ("2 images, near-field", ("nearfield", 25.0, "error", 2))]
    assert len(plan.reconstruction_sets(acq)) == 5  # the near-field pair once
    # without the previous work's metric the point columns go; point samples capped at n_max_point
    assert [c for c, _ in plan.reconstruction_columns({**acq, "metrics": ["error"]})["fig02"]] == ["1 image",
                                                                                                 "2 images"]
    assert plan.reconstruction_columns({**acq, "n_max_point": 3})["fig02"][3] == ("3 points", ("point", 0.0, metric, 3))
    assert plan.reconstruction_columns({**acq, "setups": ["point"]}) == {}


def test_e_recon_is_the_orthogonal_complement_of_the_deviation(tmp_path: Path) -> None:
    """rms_log² = E_deviation² + E_recon² per channel: 0.5 and 0.3 give 0.4 (3-4-5), channel means after."""
    lines = [",".join(tables.ERRORS)]
    for c, (rms, dev) in zip("RGB", ((0.5, 0.3), (1.3, 0.5), (0.25, 0.25))):
        lines.append(f"db,train,nearfield,25,error,2,m1,{c},rms_log,{rms}")
        lines.append(f"db,train,all,0,none,0,m1,{c},deviation,{dev}")
    lines.append("db,train,nearfield,25,error,2,m2,R,rms_log,0.5")  # m2: no deviation rows
    integrity.write_csv(tmp_path / "errors.csv", "\n".join(lines) + "\n")
    table = read_errors(tmp_path / "errors.csv")
    warn = Warnings("t")
    out = figures.recon_vs_deviation(table, ["m1", "m2"], split="train", setup="nearfield", fov=25.0, metric="error",
                                     n=2, warn=warn)
    assert [r["material"] for r in out] == ["m1"] and "m2" in warn.items[0]
    assert out[0]["e_recon"] == pytest.approx((0.4 + 1.2 + 0.0) / 3, rel=1e-15)
    assert out[0]["e_deviation"] == pytest.approx((0.3 + 0.5 + 0.25) / 3, rel=1e-15)


# ---------------------------------------------------------------------------
# The tiny run's figures
# ---------------------------------------------------------------------------


def _recon_panels(run: Path, key: str) -> list[dict[str, str]]:
    stem = fig_spec.figure(f"xu-{key}").stem
    assert (run / fn.FIGURES / f"{stem}.png").stat().st_size > 10_000
    return _rows(run / fn.FIGURES / f"{stem}.csv")


def test_fig02_and_fig15_lay_out_the_papers_rows(run: Path) -> None:
    mats = plan.figure_materials(_held_out(run))
    columns = plan.reconstruction_columns(CONFIG["acquisition"])
    for key, expect in (("fig02", ["input", "1 image", "3 points", "input 1", "input 2", "2 images", "3 points",
                                   "reference"]),
                        ("fig15", ["input 1", "input 2", "2 images, fixed camera", "2 images, near-field",
                                   "reference"])):
        rows = _recon_panels(run, key)
        assert [r["material"] for r in rows] == [m for m in mats for _ in expect]
        assert [r["column"] for r in rows] == expect * len(mats)
        sets = dict(columns[key])
        for r in rows:
            if r["kind"] == "reference":
                assert r["file"] == fn.prerender("preview", r["material"])  # exactly the material's pre-render
            elif r["kind"] == "reconstruction":
                s = sets[r["column"]]
                assert (r["setup"], float(r["fov"]), r["metric"], int(r["n"])) == s
                assert r["file"] == fn.reconstruction_render("preview", r["material"], *s)
            else:
                assert r["file"] == fn.reconstruction_input(r["material"], r["setup"], r["fov"], r["metric"], r["n"],
                                                            r["image"])


def test_a_reconstruction_panel_is_the_evaluated_table_rendered_as_the_prerenders(run: Path, tmp_path: Path) -> None:
    rows = [r for r in _recon_panels(run, "fig02") if r["kind"] == "reconstruction"]
    errors = read_errors(run / fn.errors())
    mdl = open_model(run / fn.svd_model("train"))
    st = open_store(run / fn.store())
    checked = set()
    for r in rows:
        setup, fov, metric, n = r["setup"], float(r["fov"]), r["metric"], int(r["n"])
        table_path = run / fn.reconstruction(r["material"], setup, fov, metric, n)
        # the figure's numbers: errors.csv's rms_log; the render's difference from the reference
        assert float(r["rms_log"]) == errors.material_value("train", setup, fov, metric, n, "rms_log", r["material"])
        image, ref = read_exr(run / r["file"]).astype(np.float64), read_exr(run / fn.prerender("preview", r["material"]))
        diff = np.sqrt(np.mean((image - ref) ** 2)) / np.sqrt(np.mean(ref.astype(np.float64) ** 2))
        assert float(r["render_relative_rmse"]) == pytest.approx(diff, rel=1e-12)
        if (setup, r["material"]) in checked:
            continue
        checked.add((setup, r["material"]))
        # the table: eq. 4 from the store's values at the set's observation cells (the evaluation's), marked derived
        d = read_directions(run / fn.directions("train", setup, fov, metric))
        configs = next(s for s in d.sets if s.n == n).configurations
        valid = np.zeros(merl.N_CELLS, dtype=bool)
        valid[mdl.cells] = True
        cells = np.concatenate([geometry.observation_cells(d.setup, c, valid) for c in configs])
        row = np.asarray(st.brdf[int(material_indices(st, [r["material"]], "m")[0])], dtype=np.float64)
        rgb = row.reshape(3, merl.N_CELLS)[:, cells].T
        xhat, _, _ = reconstruct.reconstruct_log(mdl, cells, rgb)
        written = merl.read_merl(table_path).reshape(3, merl.N_CELLS)
        want = reconstruct.reconstruct_brdf(mdl, cells, rgb).reshape(3, merl.N_CELLS)
        # at the model's cells (the others are unmeasured, negative, and hold the mark): the file stores ρ / scale
        # and reads it back × scale, 2 roundings of 2⁻⁵³ each
        np.testing.assert_allclose(written[:, mdl.cells], want[:, mdl.cells], rtol=4.5e-16, atol=0)
        assert (written[:, ~valid] < 0).all()
        truth = logmap.forward(row.reshape(3, merl.N_CELLS)[:, mdl.cells], mdl.reference, mdl.weight, mdl.epsilon)
        for c, ch in enumerate("RGB"):  # its log-space error is errors.csv's (a Gram identity there: ≤ 1e-9 apart)
            rms = math.sqrt(float(np.mean((xhat[c] - truth[c]) ** 2)))
            assert rms == pytest.approx(errors.values[("train", setup, fov, metric, n, r["material"], ch, "rms_log")],
                                        rel=1e-9)
        mark = provenance.read_mark(table_path)
        assert mark.kind == "derived" and mark.fields["operation"] == "reconstruct"
        assert mark.fields["inputs"]["material"] == r["material"] and mark.fields["inputs"]["directions"]["n"] == n
    # one render again, alone, with the pre-renders' settings: the same pixels
    from brdfpipe.rendering import scene

    r = rows[0]
    out = tmp_path / "again.exr"
    render = CONFIG["render"]
    scene.render_material(run / fn.reconstruction(r["material"], r["setup"], float(r["fov"]), r["metric"], int(r["n"])),
                          out, envmap=run / fn.envmap("preview"), variant=render["variant"],
                          resolution=tuple(render["resolution"]), spp=render["spp"], max_depth=render["max_depth"],
                          seed=render["seed"], threads=2)
    assert np.array_equal(read_exr(out), read_exr(run / r["file"]))


def test_an_input_panel_holds_the_observed_values(run: Path) -> None:
    rows = [r for r in _recon_panels(run, "fig15") if r["kind"] == "input"]
    mdl = open_model(run / fn.svd_model("train"))
    st = open_store(run / fn.store())
    valid = np.zeros(merl.N_CELLS, dtype=bool)
    valid[mdl.cells] = True
    for r in rows[:2]:
        d = read_directions(run / fn.directions("train", r["setup"], r["fov"], r["metric"]))
        config = next(s for s in d.sets if s.n == int(r["n"])).configurations[int(r["image"]) - 1]
        cells = geometry.observation_cells(d.setup, config, valid)
        wi, _ = geometry.centre_directions(d.setup, config)
        row = np.asarray(st.brdf[int(material_indices(st, [r["material"]], "m")[0])], dtype=np.float64)
        want = np.sort((row.reshape(3, merl.N_CELLS)[:, cells] * wi[2]).astype(np.float32), axis=1)
        image = read_exr(run / r["file"])
        assert image.shape == (d.setup.grid + 1 - d.setup.grid % 2,) * 2 + (3,)
        seen = image.reshape(-1, 3)[np.any(image.reshape(-1, 3) > 0, axis=1)]
        assert seen.shape[0] == cells.size  # one pixel per observation
        assert np.allclose(np.sort(seen.T, axis=1), want, rtol=1e-6, atol=0)


def test_fig03_bars_are_eq12_and_eq9(run: Path) -> None:
    rows = _rows(run / fn.FIGURES / f"{fig_spec.figure('xu-fig03').stem}.csv")
    errors = read_errors(run / fn.errors())
    assert sorted({r["material"] for r in rows}) == plan.figure_materials(_held_out(run))
    assert sorted({int(r["n"]) for r in rows}) == [1, 2]
    for r in rows:
        key = ("train", "nearfield", 25.0, "error", int(r["n"]), r["material"])
        rms = [errors.values[(*key, c, "rms_log")] for c in "RGB"]
        dev = [errors.values[("train", "all", 0.0, "none", 0, r["material"], c, "deviation")] for c in "RGB"]
        assert float(r["e_deviation"]) == pytest.approx(np.mean(dev), rel=1e-15)
        assert float(r["e_recon"]) == pytest.approx(np.mean([math.sqrt(a * a - b * b) for a, b in zip(rms, dev)]),
                                                    rel=1e-15)
        assert float(r["e_recon"]) > float(r["e_deviation"])  # the paper's "E_recon dominates", here too
    # eq. 12 literally for one material-channel: ‖Q(Q⁺ − (SQ)⁺_η S) y‖ / √p, Q⁺ = (QᵀQ)⁻¹Qᵀ
    r = rows[0]
    mdl = open_model(run / fn.svd_model("train"))
    st = open_store(run / fn.store())
    d = read_directions(run / fn.directions("train", "nearfield", 25, "error"))
    valid = np.zeros(merl.N_CELLS, dtype=bool)
    valid[mdl.cells] = True
    cells = np.concatenate([geometry.observation_cells(d.setup, c, valid)
                            for c in next(s for s in d.sets if s.n == int(r["n"])).configurations])
    row = np.asarray(st.brdf[int(material_indices(st, [r["material"]], "m")[0])], dtype=np.float64)
    _, coef, _ = reconstruct.reconstruct_log(mdl, cells, row.reshape(3, merl.N_CELLS)[:, cells].T)
    y = logmap.forward(row.reshape(3, merl.N_CELLS)[:, mdl.cells], mdl.reference, mdl.weight, mdl.epsilon)[0] - mdl.mean
    q = np.asarray(mdl.Q[:], dtype=np.float64)
    gram = q.T @ q
    c_all = np.linalg.solve(gram, q.T @ y)
    e_recon = math.sqrt(float((c_all - coef[:, 0]) @ gram @ (c_all - coef[:, 0])) / mdl.p)
    rms, dev = (errors.values[k] for k in (("train", "nearfield", 25.0, "error", int(r["n"]), r["material"], "R",
                                            "rms_log"),
                                           ("train", "all", 0.0, "none", 0, r["material"], "R", "deviation")))
    assert e_recon == pytest.approx(math.sqrt(rms * rms - dev * dev), rel=1e-8)


@pytest.mark.parametrize("key, sets", [("fig09", [("nearfield", 1), ("nearfield", 2)]),
                                       ("fig14", [("fixed_camera", 2), ("fixed_light", 2)])])
def test_fig09_and_fig14_angles_are_the_directions_files(run: Path, key: str, sets: list[tuple[str, int]]) -> None:
    rows = _rows(run / fn.FIGURES / f"{fig_spec.figure(f'xu-{key}').stem}.csv")
    expect = []
    for setup, n in sets:
        d = read_directions(run / fn.directions("train", setup, 25, "error"))
        for j, rec in enumerate(next(s for s in d.sets if s.n == n).records, start=1):
            sph = []
            for v in (rec["light"], rec["camera"]):
                theta = math.degrees(math.acos(v[2]))
                phi = math.degrees(math.atan2(v[1], v[0])) % 360.0 if math.hypot(v[0], v[1]) > 1e-9 else 0.0
                sph += [theta, phi]
            expect.append((setup, n, j, *sph, rec["theta_h_deg"], rec["theta_d_deg"], rec["phi_d_deg"]))
    got = [(r["setup"], int(r["n_images"]), int(r["image"]),
            *(float(r[c]) for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "theta_h_deg",
                                    "theta_d_deg", "phi_d_deg"))) for r in rows]
    assert [g[:3] for g in got] == [e[:3] for e in expect]
    for g, e in zip(got, expect):
        assert np.allclose(g[3:], e[3:], rtol=0, atol=5e-7)  # the table's six decimals
    if key == "fig14":  # the shared direction: one camera (fixed camera), one light (fixed light) per set
        assert len({(g[5], g[6]) for g in got if g[0] == "fixed_camera"}) == 1
        assert len({(g[3], g[4]) for g in got if g[0] == "fixed_light"}) == 1
