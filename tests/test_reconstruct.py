"""Tests of :mod:`brdfpipe.acquisition.reconstruct`: reconstruction of a full BRDF from observations.

The small pipeline (store, log-map, PCA model, directions files) is built once
per module by tests/acquisition_fixture.py.
"""

from __future__ import annotations

import csv
import logging
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from acquisition_fixture import Data, dense_coef
from brdfpipe.acquisition import reconstruct
from brdfpipe.acquisition.reconstruct import ObservationError
from brdfpipe.cli import main as cli_main
from brdfpipe.data import logmap, merl, provenance, store
from brdfpipe.data.database import database_from_folder


# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Data:
    return Data(tmp_path_factory.mktemp("reconstruct"))


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
    c = dense_coef(data.Q, y, eta)
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
    source = database_from_folder(data.dir / "db", key="folder").sources[data.test[0]]
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
