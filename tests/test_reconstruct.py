"""Tests of :mod:`brdfpipe.acquisition.reconstruct`: reconstruction from observations and the leave-out evaluation.

One small real pipeline is built once per module: eight synthetic materials
(``synth.synthesize``) → store → ``train`` log-map holding out two materials
(m = 18 rows, p ≈ 1.1 M) → PCA model (k = 17) → two optimised directions
files (point n ≤ 3 and near-field 25° n ≤ 2, few candidates).  The dense
references hold Q (p × k float64, 150 MB) and the log-mapped rows in memory.
"""

from __future__ import annotations

import csv
import io
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from brdfpipe.acquisition import geometry, metrics, optimize, reconstruct, svd
from brdfpipe.cli import main as cli_main
from brdfpipe.core import filenames, integrity
from brdfpipe.data import logmap, merl, provenance, store, synth
from brdfpipe.data.database import folder_database
from brdfpipe.acquisition.reconstruct import (
    CONSISTENCY_COLUMNS,
    ERROR_COLUMNS,
    TRAINING_SIZE_COLUMNS,
    ConsistencyError,
    ObservationError,
)
from brdfpipe.acquisition.geometry import Setup

# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


class Data:
    """Paths and dense arrays of the small pipeline."""

    def __init__(self, d: Path) -> None:
        synth.synthesize(d / "db", count=8, seed=11, noise=0.01, jobs=1, progress=False)
        db = folder_database(d / "db")
        self.dir = d
        self.store = d / "merl.zarr"
        store.ingest(db.sources, self.store, database=db.kind, jobs=1)
        st = store.open_store(self.store)
        self.materials = list(st.materials)
        self.test = [self.materials[1], self.materials[6]]
        self.train = [m for m in self.materials if m not in self.test]
        self.logmap = d / "logmap" / "train.zarr"
        logmap.write_logmap(self.store, self.logmap, split="train", materials_train=self.train)
        self.model_path = d / "svd" / "train.zarr"
        svd.fit(self.logmap, self.model_path)
        self.model = svd.open_model(self.model_path)
        m = self.model
        self.Q = np.asarray(m.Q[:], dtype=np.float64)
        self.X = np.asarray(logmap.open_logmap(self.logmap).X[:], dtype=np.float64)
        # Held-out rows: physical values at the model's columns and their log-map (train reference).
        rows = [self.materials.index(n) for n in self.test]
        self.rho_test = np.stack([np.asarray(st.brdf[r], dtype=np.float64).reshape(3, merl.N_CELLS)[:, m.cells]
                                  for r in rows]).reshape(-1, m.p)  # (6, p), row 3i + c
        self.X_test = logmap.forward(self.rho_test, m.reference, m.weight, m.epsilon)
        # Two optimised directions files.
        self.dirs: dict[str, Path] = {}
        for kind, fov, n_max in (("point", 0.0, 3), ("nearfield", 25.0, 2)):
            setup = Setup(kind, fov, 16)
            sets = optimize.optimize(m, setup, metric="error", n_max=n_max, candidates=6, steps=(1,), seed=3,
                                     log=lambda line: None)
            self.dirs[kind] = optimize.write_directions(
                d / filenames.directions("train", kind, fov, "error"), sets, setup=setup, metric="error",
                split="train", model_path=self.model_path, seed=3, eta=40.0, beta=0.0, database=m.database)

    def rows_of(self, path: Path, n: int) -> NDArray[np.intp]:
        """Model columns observed by set n of a directions file (recomputed independently)."""
        d = optimize.read_directions(path)
        lut = np.full(merl.N_CELLS, -1, dtype=np.intp)
        lut[self.model.cells] = np.arange(self.model.p)
        (s,) = [s for s in d.sets if s.n == n]
        cells = np.concatenate([geometry.observation_cells(d.setup, c, lut >= 0) for c in s.configurations])
        return lut[cells]


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Data:
    return Data(tmp_path_factory.mktemp("reconstruct"))


@pytest.fixture(scope="module")
def evaluation(data: Data) -> list[dict[str, Any]]:
    return reconstruct.evaluate(data.store, data.model_path, [data.dirs["point"], data.dirs["nearfield"]],
                                test_materials=data.test)


def _dense_coef(Q: NDArray[np.float64], y: NDArray[np.float64], eta: float) -> NDArray[np.float64]:
    """(QᵀQ + ηI)⁻¹ Qᵀ y for y (n, r)."""
    return np.linalg.solve(Q.T @ Q + eta * np.eye(Q.shape[1]), Q.T @ y)


def _value(rows: list[dict[str, Any]], **key: Any) -> float:
    got = [r["value"] for r in rows if all(r[k] == v for k, v in key.items())]
    assert len(got) == 1, (key, len(got))
    return float(got[0])


# --------------------------------------------------------------------------
# Reconstruction
# --------------------------------------------------------------------------


@pytest.mark.parametrize("eta", [40.0, 1e-6])
def test_heldout_from_all_cells_is_the_regularised_projection(data: Data, eta: float) -> None:
    m = data.model
    rgb = data.rho_test[0:3].T  # first held-out material, (p, 3)
    xhat, coef, n_used = reconstruct.reconstruct_log(m, m.cells, rgb, eta)
    assert n_used == m.p and xhat.shape == (3, m.p) and coef.shape == (m.k, 3)
    y = (data.X_test[0:3] - m.mean).T
    c = _dense_coef(data.Q, y, eta)
    np.testing.assert_allclose(coef, c, rtol=1e-7, atol=1e-10 * np.abs(c).max())
    expect = m.mean + (data.Q @ c).T
    np.testing.assert_allclose(xhat, expect, rtol=0, atol=1e-9 * np.abs(expect).max())
    if eta < 1:  # the orthogonal projection Q Q⁺ y: residual orthogonal to the columns of Q
        r = (data.X_test[0:3] - xhat).T
        assert np.abs(data.Q.T @ r).max() < 1e-6 * np.abs(data.Q.T @ y).max()


def test_training_material_from_all_cells_returns_itself(data: Data) -> None:
    m = data.model
    st = store.open_store(data.store)
    i = data.materials.index(data.train[2])
    rgb = np.asarray(st.brdf[i], dtype=np.float64).reshape(3, merl.N_CELLS)[:, m.cells].T
    xhat, _, _ = reconstruct.reconstruct_log(m, m.cells, rgb, eta=1e-6)
    x = data.X[6:9]  # rows of train[2]
    assert np.abs(xhat - x).max() <= 8 * np.finfo(np.float32).eps * np.abs(x).max()
    table = reconstruct.reconstruct_brdf(m, m.cells, rgb, eta=1e-6)
    flat = table.reshape(3, merl.N_CELLS)
    np.testing.assert_allclose(flat[:, m.cells], rgb.T, rtol=1e-5, atol=1e-6)


def test_table_layout_and_clamping(data: Data, caplog: pytest.LogCaptureFixture) -> None:
    m = data.model
    rows = data.rows_of(data.dirs["point"], 3)
    cells = m.cells[rows]
    rgb = data.rho_test[3:6][:, rows].T
    with caplog.at_level(logging.INFO, logger="brdfpipe.acquisition.reconstruct"):
        table = reconstruct.reconstruct_brdf(m, cells, rgb)
    assert table.shape == merl.SHAPE
    flat = table.reshape(3, merl.N_CELLS)
    xhat, _, _ = reconstruct.reconstruct_log(m, cells, rgb)
    rho = logmap.inverse(xhat, m.reference, m.weight, m.epsilon)
    np.testing.assert_array_equal(flat[:, m.cells], np.maximum(rho, 0.0))
    off = np.ones(merl.N_CELLS, dtype=bool)
    off[m.cells] = False
    assert off.any()
    np.testing.assert_array_equal(flat[:, off], np.broadcast_to(-merl.SCALES[:, None], (3, int(off.sum()))))
    if (rho < 0).any():
        assert any("clamped" in r.getMessage() for r in caplog.records)


def _observation_files(data: Data, tmp: Path) -> tuple[dict[str, Path], NDArray[np.intp], NDArray[np.float64]]:
    """The same 400 observations (random model cells, some repeated) in the four formats."""
    m = data.model
    rng = np.random.default_rng(7)
    idx = rng.choice(m.p, 300, replace=False)
    idx = np.concatenate([idx, idx[:100]])  # repeated observations
    cells = m.cells[idx].astype(np.intp)
    rgb = data.rho_test[0:3][:, idx].T.copy()
    wi, wo = merl.cell_directions(cells)
    phi = rng.uniform(0, 2 * np.pi, cells.size)  # any rotation about the normal: same cell
    rot = np.stack([np.cos(phi), -np.sin(phi), np.sin(phi), np.cos(phi)], axis=1).reshape(-1, 2, 2)
    wi[:, :2] = np.einsum("nij,nj->ni", rot, wi[:, :2])
    wo[:, :2] = np.einsum("nij,nj->ni", rot, wo[:, :2])
    wi *= rng.uniform(0.5, 2.0, (cells.size, 1))  # not unit: normalised on reading
    th, td, pd = (np.degrees(a.ravel()[cells]) for a in merl.cell_centres())
    pd = pd - 180.0 * (rng.random(cells.size) < 0.5)  # φd − 180° is the same cell (reciprocity)
    files = {
        "csv-dirs": tmp / "obs-dirs.csv",
        "csv-angles": tmp / "obs-angles.csv",
        "npz-dirs": tmp / "obs-dirs.npz",
        "npz-angles": tmp / "obs-angles.npz",
    }
    with open(files["csv-dirs"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z", "r", "g", "b"])
        for a, b, c in zip(wi, wo, rgb):
            w.writerow([repr(float(v)) for v in (*a, *b, *c)])
    with open(files["csv-angles"], "w", newline="") as fh:
        fh.write("# reconstructed from cell centres\n")
        w = csv.writer(fh)
        w.writerow(["B", "G", "R", "note", "Phi_D", "theta_d", "theta_h"])  # any order, any case, extra column
        for a, b, c, col in zip(th, td, pd, rgb):
            w.writerow([repr(float(col[2])), repr(float(col[1])), repr(float(col[0])), "x", repr(float(c)),
                        repr(float(b)), repr(float(a))])
    np.savez(files["npz-dirs"], wi=wi, wo=wo, rgb=rgb)
    np.savez(files["npz-angles"], theta_h=th, theta_d=td, phi_d=pd, rgb=rgb)
    return files, cells, rgb


def test_observation_formats_agree(data: Data, tmp_path: Path) -> None:
    files, cells, rgb = _observation_files(data, tmp_path)
    tables = {}
    for name, path in files.items():
        got_cells, got_rgb = reconstruct.load_observations(path)
        np.testing.assert_array_equal(got_cells, cells, err_msg=name)
        np.testing.assert_array_equal(got_rgb, rgb, err_msg=name)
        tables[name] = reconstruct.reconstruct_brdf(data.model, got_cells, got_rgb)
    for name, t in tables.items():
        np.testing.assert_array_equal(t, tables["csv-dirs"], err_msg=name)


def test_write_reconstruction_and_cli(data: Data, tmp_path: Path) -> None:
    files, cells, rgb = _observation_files(data, tmp_path)
    out = tmp_path / "out" / "rec.binary"
    assert reconstruct.write_reconstruction(data.model_path, files["npz-angles"], out) == out
    back = merl.read_merl(out)
    table = reconstruct.reconstruct_brdf(data.model, cells, rgb)
    unmarked = np.ones((3, merl.N_CELLS), dtype=bool)
    unmarked[0, provenance.MARK_CELLS] = False  # the provenance mark (unmeasurable cells, negative)
    np.testing.assert_allclose(back.reshape(3, -1)[unmarked], table.reshape(3, -1)[unmarked], rtol=1e-14, atol=0)
    flat = back.reshape(3, merl.N_CELLS)
    measured = np.zeros(merl.N_CELLS, dtype=bool)
    measured[data.model.cells] = True
    assert (flat[:, ~measured] < 0).all() and (flat[:, measured] >= 0).all()
    raw = merl.read_merl_raw(out).reshape(3, -1)
    np.testing.assert_array_equal(raw[:, ~measured][unmarked[:, ~measured]], -1.0)
    mark = provenance.read_mark(out)
    assert mark is not None and mark.kind == "derived" and mark.fields["operation"] == "reconstruct"
    assert mark.fields["source_database"] == data.model.database and mark.fields["name"] == "rec"
    assert mark.fields["inputs"]["model"]["id"] == data.model.id
    assert mark.fields["inputs"]["observations"]["sha256"] == provenance.file_sha256(files["npz-angles"])
    out2 = tmp_path / "cli.binary"
    assert cli_main(["-q", "reconstruct", str(files["csv-dirs"]), "--model", str(data.model_path),
                     "--out", str(out2), "--eta", "40"]) == 0
    np.testing.assert_array_equal(merl.read_merl(out2).reshape(3, -1)[unmarked], back.reshape(3, -1)[unmarked])
    assert provenance.read_mark(out2).fields["inputs"]["observations"]["sha256"] == provenance.file_sha256(
        files["csv-dirs"])
    bad = _write(tmp_path / "bad.csv", "theta_h,theta_d,r,g,b\n1,2,3,4,5\n")
    assert cli_main(["-q", "reconstruct", str(bad), "--model", str(data.model_path), "--out", str(out2)]) == 1


def test_reconstructions_are_derived_and_ingest_as_derived(data: Data, tmp_path: Path) -> None:
    """A reconstruction (and that of a capture) is marked derived; a folder of them is never 'merl'."""
    files, _, _ = _observation_files(data, tmp_path)
    folder = tmp_path / "recs"
    reconstruct.write_reconstruction(data.model_path, files["npz-dirs"], folder / "rec.binary")
    source = folder_database(data.dir / "db").sources[data.test[0]]
    reconstruct.write_reconstruction(data.model_path, files["csv-angles"], folder / "captured.binary", material=source)
    mark = provenance.read_mark(folder / "captured.binary")
    assert mark.fields["operation"] == "capture-reconstruct"
    assert mark.fields["inputs"]["material"] == {"sha256": provenance.file_sha256(source), "database": "synthetic"}
    assert provenance.read_mark(folder / "rec.binary").fields["operation"] == "reconstruct"
    assert cli_main(["-q", "ingest", str(folder), "--out", str(tmp_path / "recs.zarr"), "--jobs", "1"]) == 0
    assert store.open_store(tmp_path / "recs.zarr").database == "derived"


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


BAD_CSV = {
    "missing-column": ("wi_x,wi_y,wi_z,wo_x,wo_y,r,g,b\n0,0,1,0,0,1,1,1\n", "missing columns"),
    "missing-rgb": ("theta_h,theta_d,phi_d,r,g\n1,2,3,1,1\n", "missing columns: b"),
    "nan": ("theta_h,theta_d,phi_d,r,g,b\n1,2,3,0.1,nan,0.1\n", "NaN"),
    "negative": ("theta_h,theta_d,phi_d,r,g,b\n1,2,3,0.1,-0.2,0.1\n", "negative"),
    "below-horizon": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b\n0,0,1,0,0,1,1,1,1\n0.5,0,-0.2,0,0,1,1,1,1\n",
                      "below the horizon"),
    "angles-below-horizon": ("theta_h,theta_d,phi_d,r,g,b\n80,60,0,1,1,1\n", "below the horizon"),
    "angle-range": ("theta_h,theta_d,phi_d,r,g,b\n10,95,0,1,1,1\n", "[0, 90]"),
    "zero-vector": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b\n0,0,0,0,0,1,1,1,1\n", "zero-length"),
    "not-a-number": ("theta_h,theta_d,phi_d,r,g,b\n1,2,x,1,1,1\n", "malformed"),
    "header-only": ("theta_h,theta_d,phi_d,r,g,b\n", "no observations"),
    "empty": ("", "empty"),
    "both-formats": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,theta_h,theta_d,phi_d,r,g,b\n", "both"),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV))
def test_bad_csv_raises_naming_the_file(tmp_path: Path, case: str) -> None:
    text, what = BAD_CSV[case]
    path = _write(tmp_path / f"{case}.csv", text)
    with pytest.raises(ObservationError) as exc:
        reconstruct.load_observations(path)
    assert str(path) in str(exc.value) and what in str(exc.value), str(exc.value)


def test_bad_npz_and_missing_files(tmp_path: Path, data: Data) -> None:
    cases = {
        "no-rgb.npz": ({"wi": np.ones((2, 3)), "wo": np.ones((2, 3))}, "'rgb'"),
        "no-wo.npz": ({"wi": np.ones((2, 3)), "rgb": np.ones((2, 3))}, "wo"),
        "shape.npz": ({"wi": np.ones((2, 3)), "wo": np.ones((2, 3)), "rgb": np.ones((3, 3))}, "disagree"),
        "angles.npz": ({"theta_h": np.ones(2), "theta_d": np.ones(2), "phi_d": np.ones(3), "rgb": np.ones((2, 3))},
                       "phi_d"),
        "nan.npz": ({"wi": [[0, 0, 1]], "wo": [[0, 0, 1]], "rgb": [[np.inf, 0, 0]]}, "NaN"),
    }
    for name, (arrays, what) in cases.items():
        path = tmp_path / name
        np.savez(path, **arrays)
        with pytest.raises(ObservationError) as exc:
            reconstruct.load_observations(path)
        assert str(path) in str(exc.value) and what in str(exc.value), str(exc.value)
    for missing in (tmp_path / "nope.csv", tmp_path / "nope.npz"):
        with pytest.raises(ObservationError, match="no such"):
            reconstruct.load_observations(missing)
    garbage = _write(tmp_path / "garbage.npz", "not a zip")
    with pytest.raises(ObservationError, match="garbage.npz"):
        reconstruct.load_observations(garbage)
    # Observations that all miss the model's columns: the error names the file.
    unmeasured = int(np.flatnonzero(~merl.measured_mask().ravel())[0])
    with pytest.raises(ValueError, match="no observation falls on a model column"):
        reconstruct.reconstruct_brdf(data.model, [unmeasured], [[0.1, 0.1, 0.1]])


# --------------------------------------------------------------------------
# Leave-out evaluation
# --------------------------------------------------------------------------


def test_gram_trick_equals_dense_p_space(data: Data, evaluation: list[dict[str, Any]]) -> None:
    m = data.model
    Y = data.X_test - m.mean  # (6, p)
    wi, wo = merl.cell_directions(m.cells)
    cc = wi[:, 2] * wo[:, 2]
    for kind, path in data.dirs.items():
        setup = "point" if kind == "point" else "nearfield"
        fov = 0 if kind == "point" else 25
        for s in optimize.read_directions(path).sets:
            rows = data.rows_of(path, s.n)
            c = _dense_coef(data.Q[rows], Y[:, rows].T, 40.0)
            R = Y - (data.Q @ c).T
            rms = np.linalg.norm(R, axis=1) / np.sqrt(m.p)
            rho_hat = np.maximum(logmap.inverse(m.mean + (data.Q @ c).T, m.reference, m.weight, m.epsilon), 0)
            rel = np.linalg.norm((rho_hat - data.rho_test) * cc, axis=1) / np.linalg.norm(data.rho_test * cc, axis=1)
            for i, (mat, ch) in enumerate((mat, ch) for mat in data.test for ch in "RGB"):
                key = {"setup": setup, "fov": fov, "metric": "error", "n": s.n, "material": mat, "channel": ch}
                assert _value(evaluation, kind="rms_log", **key) == pytest.approx(rms[i], rel=1e-6)
                assert _value(evaluation, kind="relrms_linear", **key) == pytest.approx(rel[i], rel=1e-5)
            key = {"setup": setup, "fov": fov, "metric": "error", "n": s.n, "material": "mean", "channel": "all"}
            assert _value(evaluation, kind="rms_log", **key) == pytest.approx(rms.mean(), rel=1e-6)
            assert _value(evaluation, kind="relrms_linear", **key) == pytest.approx(rel.mean(), rel=1e-5)
    # The deviation floor: least-squares projection on the stored Q.
    coef, *_ = np.linalg.lstsq(data.Q, Y.T, rcond=None)
    dev = np.linalg.norm(Y - (data.Q @ coef).T, axis=1) / np.sqrt(m.p)
    for i, (mat, ch) in enumerate((mat, ch) for mat in data.test for ch in "RGB"):
        got = _value(evaluation, kind="deviation", setup="all", material=mat, channel=ch)
        assert got == pytest.approx(dev[i], rel=1e-6)
    assert dev.min() > 0  # held-out materials are not in the training subspace


def test_all_cells_tiny_eta_equals_deviation(data: Data, evaluation: list[dict[str, Any]]) -> None:
    m = data.model
    label = {"setup": "everything", "fov": 0, "metric": "none", "n": 1}
    rows = reconstruct.evaluate_selections(data.store, data.model_path, [(label, m.cells)],
                                           test_materials=data.test, eta=1e-6, linear=False)
    assert not any(r["kind"] == "relrms_linear" for r in rows)
    for mat in [*data.test, "mean"]:
        for ch in ("RGB" if mat != "mean" else ["all"]):
            floor = _value(evaluation, kind="deviation", material=mat, channel=ch)
            got = _value(rows, kind="rms_log", setup="everything", material=mat, channel=ch)
            assert got == pytest.approx(floor, rel=1e-6)
    # A selection that misses the model reconstructs the mean: rms_log = ‖y‖/√p.
    unmeasured = int(np.flatnonzero(~merl.measured_mask().ravel())[0])
    rows = reconstruct.evaluate_selections(data.store, data.model_path, [(label, [unmeasured])],
                                           test_materials=data.test, linear=False)
    y0 = np.linalg.norm(data.X_test[0] - m.mean) / np.sqrt(m.p)
    assert _value(rows, kind="rms_log", setup="everything", material=data.test[0], channel="R") == pytest.approx(y0)


def test_evaluation_rows_are_tidy(data: Data, evaluation: list[dict[str, Any]], tmp_path: Path) -> None:
    path = reconstruct.write_errors(tmp_path / "evaluation" / "errors.csv", evaluation)
    with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == ERROR_COLUMNS
    body = [dict(zip(ERROR_COLUMNS, r)) for r in rows[1:]]
    n_sets = 3 + 2
    per = len(data.test) * 3 + 1
    assert len(body) == (1 + 2 * n_sets) * per
    assert {r["database"] for r in body} == {"synthetic"} and {r["split"] for r in body} == {"train"}
    dev = [r for r in body if r["kind"] == "deviation"]
    assert len(dev) == per and all((r["setup"], r["fov"], r["metric"], r["n"]) == ("all", "0", "none", "0")
                                   for r in dev)
    assert {(r["setup"], r["fov"]) for r in body} == {("all", "0"), ("point", "0"), ("nearfield", "25")}
    means = [r for r in body if r["material"] == "mean"]
    assert len(means) == 1 + 2 * n_sets and {r["channel"] for r in means} == {"all"}
    assert {r["channel"] for r in body if r["material"] != "mean"} == {"R", "G", "B"}
    values = np.array([float(r["value"]) for r in body])
    assert np.isfinite(values).all() and (values >= 0).all()
    # More images help on average (n = 2 vs n = 1 near-field).
    e1 = _value(evaluation, kind="rms_log", setup="nearfield", n=1, material="mean")
    e2 = _value(evaluation, kind="rms_log", setup="nearfield", n=2, material="mean")
    assert e2 < e1
    # Round trip of the floats.
    assert float(body[0]["value"]) == evaluation[0]["value"]
    with pytest.raises(ValueError, match="lacks column"):
        reconstruct.write_errors(tmp_path / "bad.csv", [{"database": "x"}])


def test_evaluation_refuses_bad_inputs(data: Data, tmp_path: Path) -> None:
    dirs = [data.dirs["point"]]
    with pytest.raises(ValueError, match="training materials"):
        reconstruct.evaluate(data.store, data.model_path, dirs, test_materials=[data.train[0]])
    with pytest.raises(ValueError, match="unknown material"):
        reconstruct.evaluate(data.store, data.model_path, dirs, test_materials=["no-such-material"])
    doc = integrity.read_json(data.dirs["point"])
    doc["split"] = "all"
    other = tmp_path / "point-all.json"
    integrity.write_json(other, doc)
    with pytest.raises(ValueError, match="split"):
        reconstruct.evaluate(data.store, data.model_path, [other], test_materials=data.test)
    with pytest.raises(ValueError, match="also comes from"):
        reconstruct.evaluate(data.store, data.model_path, dirs * 2, test_materials=data.test)


# --------------------------------------------------------------------------
# Consistency check
# --------------------------------------------------------------------------


def test_consistency_check_passes(data: Data, tmp_path: Path) -> None:
    out = tmp_path / "consistency.csv"
    rows = reconstruct.check_consistency(data.logmap, data.model_path, list(data.dirs.values()), out=out)
    assert len(rows) == 3 + 2
    assert max(r["rel_diff"] for r in rows) <= 1e-6
    with io.StringIO(integrity.read_csv_text(out), newline="") as fh:
        back = list(csv.reader(fh))
    assert tuple(back[0]) == CONSISTENCY_COLUMNS and len(back) == 1 + len(rows)
    # The Gram-style direct value equals metrics.direct_training_error in p-space.
    m = data.model
    for r in rows:
        path = data.dirs[r["setup"]]
        direct = metrics.direct_training_error(data.Q, m.U, m.sigma, m.mean, data.X, data.rows_of(path, r["n"]))
        assert r["direct"] == pytest.approx(direct, rel=1e-9)
        assert r["predicted"] == pytest.approx(direct, rel=1e-6)
    # With noise β > 0 the recorded E includes β‖Q(Q̃ᵀQ̃ + ηI)⁻¹Q̃ᵀ1‖, and so does the direct value.
    setup = Setup("point")
    sets = optimize.optimize(m, setup, metric="error", n_max=2, candidates=4, steps=(1,), seed=1, beta=0.5,
                             log=lambda line: None)
    noisy = optimize.write_directions(tmp_path / "noisy" / "point-fov0-error.json", sets, setup=setup,
                                      metric="error", split="train", model_path=data.model_path, seed=1, eta=40.0,
                                      beta=0.5, database=m.database)
    noisy_rows = reconstruct.check_consistency(data.logmap, data.model_path, [noisy])
    assert len(noisy_rows) == 2 and max(r["rel_diff"] for r in noisy_rows) <= 1e-6
    em0 = metrics.ErrorModel(m.sigma, m.U, eta=40.0)  # β = 0
    for r in noisy_rows:
        G, qsum = metrics.selection_stats(data.Q[data.rows_of(noisy, r["n"])])
        assert r["direct"] > 1.001 * metrics.expected_error(em0, G, qsum)  # the noise term counts


def test_consistency_check_detects_tampering(data: Data, tmp_path: Path) -> None:
    raw = json.loads(data.dirs["nearfield"].read_text())
    raw["sets"][1]["expected_error"] *= 1 + 1e-5
    bad = tmp_path / "nearfield-fov25-error.json"
    bad.write_text(json.dumps(raw))  # edited by hand (its recorded digest kept): no longer matches
    with pytest.raises(ValueError, match=r"nearfield-fov25-error\.json: its content does not match its recorded "
                                         r"digest \(damaged or edited\)"):
        reconstruct.check_consistency(data.logmap, data.model_path, [data.dirs["point"], bad])
    raw.pop(integrity.DIGEST_KEY)
    integrity.write_json(bad, raw)  # a sealed tamper: the E(S) check catches it
    out = tmp_path / "consistency.csv"
    with pytest.raises(ConsistencyError, match=r"n = 2 .*relative difference") as exc:
        reconstruct.check_consistency(data.logmap, data.model_path, [data.dirs["point"], bad], out=out)
    assert str(bad) in str(exc.value)
    assert out.exists()  # written before raising, for inspection
    # A model of another log-map is refused.
    other = tmp_path / "all.zarr"
    logmap.write_logmap(data.store, other, split="all", materials_train=data.materials)
    with pytest.raises(ValueError, match="log-map ids differ"):
        reconstruct.check_consistency(other, data.model_path, [data.dirs["point"]])


# --------------------------------------------------------------------------
# Error vs number of training materials
# --------------------------------------------------------------------------


def test_training_size_curve(data: Data, evaluation: list[dict[str, Any]], tmp_path: Path) -> None:
    rows = reconstruct.training_size_curve(data.store, data.logmap, data.dirs["nearfield"],
                                           test_materials=data.test, sizes=(3, 6, 100), order_seed=5)
    assert sorted({r["n_train"] for r in rows}) == [3, 6]  # capped at 6 training materials
    # N = all equals the main evaluation of the same directions (float32 Q there, exact here).
    for mat in [*data.test, "mean"]:
        for ch in ("RGB" if mat != "mean" else ["all"]):
            main = _value(evaluation, kind="rms_log", setup="nearfield", n=2, material=mat, channel=ch)
            got = _value(rows, n_train=6, material=mat, channel=ch)
            assert got == pytest.approx(main, rel=1e-5)
    # N = 3 against a dense PCA of the first three materials of the seeded order.
    order = np.random.default_rng(5).permutation(len(data.train))
    sel = np.sort((3 * order[:3, None] + np.arange(3)).ravel())
    Xn = data.X[sel]
    mu = Xn.mean(axis=0)
    _, s, vt = np.linalg.svd(Xn - mu, full_matrices=False)
    k = int((s > svd.TOL * s[0]).sum())
    Q = vt[:k].T * s[:k]
    obs = data.rows_of(data.dirs["nearfield"], 2)
    Y = data.X_test - mu
    c = _dense_coef(Q[obs], Y[:, obs].T, 40.0)
    rms = np.linalg.norm(Y - (Q @ c).T, axis=1) / np.sqrt(data.model.p)
    got = [_value(rows, n_train=3, material=mat, channel=ch) for mat in data.test for ch in "RGB"]
    np.testing.assert_allclose(got, rms, rtol=1e-7)
    assert _value(rows, n_train=3, material="mean") == pytest.approx(rms.mean(), rel=1e-7)
    # Tidy CSV.
    path = reconstruct.write_errors(tmp_path / "training_size.csv", rows, TRAINING_SIZE_COLUMNS)
    with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
        back = list(csv.reader(fh))
    assert tuple(back[0]) == TRAINING_SIZE_COLUMNS and len(back) == 1 + 2 * (3 * len(data.test) + 1)
    assert {r[2] for r in back[1:]} == {"5"} and {r[5] for r in back[1:]} == {"rms_log"}


def test_training_size_over_several_orders_is_each_orders_curve(data: Data, tmp_path: Path) -> None:
    """orders = 3: the curves of seeds 5, 6 and 7, one after the other, each equal to its single-order curve."""
    out = reconstruct.write_training_size(data.store, data.logmap, data.dirs["nearfield"], tmp_path / "t.csv",
                                          test_materials=data.test, sizes=(3, 6), order_seed=5, orders=3)
    _, rows = integrity.read_csv_rows(out, required=TRAINING_SIZE_COLUMNS)
    assert [r["order_seed"] for r in rows][:: len(rows) // 3] == ["5", "6", "7"]
    for seed in (5, 6, 7):
        single = reconstruct.training_size_curve(data.store, data.logmap, data.dirs["nearfield"],
                                                 test_materials=data.test, sizes=(3, 6), order_seed=seed)
        mine = [r for r in rows if r["order_seed"] == str(seed)]
        assert [(r["n_train"], r["material"], r["channel"]) for r in mine] == [
            (str(r["n_train"]), r["material"], r["channel"]) for r in single]
        np.testing.assert_allclose([float(r["value"]) for r in mine], [r["value"] for r in single], rtol=1e-8)
    # the three orders pick different first materials here: their curves differ at N = 3
    assert len({r["value"] for r in rows if r["n_train"] == "3" and r["material"] == "mean"}) > 1
    with pytest.raises(ValueError, match="orders must be in"):
        reconstruct.write_training_size(data.store, data.logmap, data.dirs["nearfield"], tmp_path / "u.csv",
                                        test_materials=data.test, orders=0)


def test_evaluation_functions_write_one_file_each(data: Data, evaluation: list[dict[str, Any]],
                                                 tmp_path: Path) -> None:
    """write_evaluation, check_consistency and write_training_size each write exactly the path given."""
    out = tmp_path / "evaluation"
    # Names the library never chose, to show it writes where it is told.
    errors_out = out / "my-errors.csv"
    consistency_out = out / "check" / "my-consistency.csv"
    curve_out = out / "my-curve.csv"
    dirs = [data.dirs["point"], data.dirs["nearfield"]]
    assert reconstruct.write_evaluation(data.store, data.model_path, dirs, errors_out,
                                        test_materials=data.test) == errors_out
    consistency = reconstruct.check_consistency(data.logmap, data.model_path, dirs, out=consistency_out)
    assert reconstruct.write_training_size(data.store, data.logmap, data.dirs["nearfield"], curve_out,
                                           test_materials=data.test, sizes=(2, 6)) == curve_out
    # Exactly the three files given, no temporary or other file left anywhere under out.
    assert sorted(p for p in out.rglob("*") if p.is_file()) == sorted([errors_out, consistency_out, curve_out])
    tables = {}
    for path, cols in ((errors_out, ERROR_COLUMNS), (consistency_out, CONSISTENCY_COLUMNS),
                       (curve_out, TRAINING_SIZE_COLUMNS)):
        with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
            tables[path] = list(csv.reader(fh))
        assert tuple(tables[path][0]) == cols
    # The errors CSV is the evaluation, written by write_errors.
    ref = reconstruct.write_errors(tmp_path / "ref" / "errors.csv", evaluation)
    assert errors_out.read_text() == ref.read_text()
    assert len(tables[consistency_out]) == 1 + len(consistency)
    # The curve uses the given directions file and sizes: N = 2 and N = 6 (all training materials).
    curve = tables[curve_out]
    n_col = TRAINING_SIZE_COLUMNS.index("n_train")
    assert sorted({int(r[n_col]) for r in curve[1:]}) == [2, 6]
    assert len(curve) == 1 + 2 * (3 * len(data.test) + 1)
