"""Tests of :mod:`brdfpipe.acquisition.evaluation`: leave-out evaluation, consistency check, training-size curve.

The small pipeline (store, log-map, PCA model, directions files) is built once
per module by tests/acquisition_fixture.py.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from acquisition_fixture import Data, dense_coef
from pspace_reference import direct_training_error
from brdfpipe.acquisition import evaluation as acq_evaluation
from brdfpipe.acquisition import metrics, optimize, svd
from brdfpipe.acquisition.evaluation import (
    CONSISTENCY_COLUMNS,
    ConsistencyError,
)
from brdfpipe.acquisition.geometry import Setup
from brdfpipe.core import integrity
from brdfpipe.data import logmap, merl
from brdfpipe.registry import tables


# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Data:
    return Data(tmp_path_factory.mktemp("evaluation"))


@pytest.fixture(scope="module")
def evaluation(data: Data) -> list[dict[str, Any]]:
    return acq_evaluation.evaluate(data.store, data.model_path, [data.dirs["point"], data.dirs["nearfield"]],
                                   test_materials=data.test)


def _value(rows: list[dict[str, Any]], **key: Any) -> float:
    got = [r["value"] for r in rows if all(r[k] == v for k, v in key.items())]
    assert len(got) == 1, (key, len(got))
    return float(got[0])


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
            c = dense_coef(data.Q[rows], Y[:, rows].T, 40.0)
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
    rows = acq_evaluation.evaluate_selections(data.store, data.model_path, [(label, m.cells)],
                                              test_materials=data.test, eta=1e-6, linear=False)
    assert not any(r["kind"] == "relrms_linear" for r in rows)
    for mat in [*data.test, "mean"]:
        for ch in ("RGB" if mat != "mean" else ["all"]):
            floor = _value(evaluation, kind="deviation", material=mat, channel=ch)
            got = _value(rows, kind="rms_log", setup="everything", material=mat, channel=ch)
            assert got == pytest.approx(floor, rel=1e-6)
    # A selection that misses the model reconstructs the mean: rms_log = ‖y‖/√p.
    unmeasured = int(np.flatnonzero(~merl.measured_mask().ravel())[0])
    rows = acq_evaluation.evaluate_selections(data.store, data.model_path, [(label, [unmeasured])],
                                              test_materials=data.test, linear=False)
    y0 = np.linalg.norm(data.X_test[0] - m.mean) / np.sqrt(m.p)
    assert _value(rows, kind="rms_log", setup="everything", material=data.test[0], channel="R") == pytest.approx(y0)


def test_evaluation_rows_are_tidy(data: Data, evaluation: list[dict[str, Any]], tmp_path: Path) -> None:
    path = acq_evaluation.write_errors(tmp_path / "evaluation" / "errors.csv", evaluation)
    with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == tables.ERRORS
    body = [dict(zip(tables.ERRORS, r)) for r in rows[1:]]
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
        acq_evaluation.write_errors(tmp_path / "bad.csv", [{"database": "x"}])


def test_evaluation_refuses_bad_inputs(data: Data, tmp_path: Path) -> None:
    dirs = [data.dirs["point"]]
    with pytest.raises(ValueError, match="training materials"):
        acq_evaluation.evaluate(data.store, data.model_path, dirs, test_materials=[data.train[0]])
    with pytest.raises(ValueError, match="unknown material"):
        acq_evaluation.evaluate(data.store, data.model_path, dirs, test_materials=["no-such-material"])
    doc = integrity.read_json(data.dirs["point"])
    doc["split"] = "all"
    other = tmp_path / "point-all.json"
    integrity.write_json(other, doc)
    with pytest.raises(ValueError, match="split"):
        acq_evaluation.evaluate(data.store, data.model_path, [other], test_materials=data.test)
    with pytest.raises(ValueError, match="also comes from"):
        acq_evaluation.evaluate(data.store, data.model_path, dirs * 2, test_materials=data.test)


# --------------------------------------------------------------------------
# Consistency check
# --------------------------------------------------------------------------


def test_consistency_check_passes(data: Data, tmp_path: Path) -> None:
    out = tmp_path / "consistency.csv"
    rows = acq_evaluation.check_consistency(data.logmap, data.model_path, list(data.dirs.values()), out=out)
    assert len(rows) == 3 + 2
    assert max(r["rel_diff"] for r in rows) <= 1e-6
    with io.StringIO(integrity.read_csv_text(out), newline="") as fh:
        back = list(csv.reader(fh))
    assert tuple(back[0]) == CONSISTENCY_COLUMNS and len(back) == 1 + len(rows)
    # The Gram-style direct value equals direct_training_error in p-space.
    m = data.model
    for r in rows:
        path = data.dirs[r["setup"]]
        direct = direct_training_error(data.Q, m.U, m.sigma, m.mean, data.X, data.rows_of(path, r["n"]))
        assert r["direct"] == pytest.approx(direct, rel=1e-9)
        assert r["predicted"] == pytest.approx(direct, rel=1e-6)
    # With noise β > 0 the recorded E includes β‖Q(Q̃ᵀQ̃ + ηI)⁻¹Q̃ᵀ1‖, and so does the direct value.
    setup = Setup("point")
    sets = optimize.optimize(m, setup, metric="error", n_max=2, candidates=4, steps=(1,), seed=1, beta=0.5,
                             log=lambda line: None)
    noisy = optimize.write_directions(tmp_path / "noisy" / "point-fov0-error.json", sets, setup=setup,
                                      metric="error", split="train", model_path=data.model_path, seed=1, eta=40.0,
                                      beta=0.5, database=m.database)
    noisy_rows = acq_evaluation.check_consistency(data.logmap, data.model_path, [noisy])
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
        acq_evaluation.check_consistency(data.logmap, data.model_path, [data.dirs["point"], bad])
    raw.pop(integrity.DIGEST_KEY)
    integrity.write_json(bad, raw)  # a sealed tamper: the E(S) check catches it
    out = tmp_path / "consistency.csv"
    with pytest.raises(ConsistencyError, match=r"n = 2 .*relative difference") as exc:
        acq_evaluation.check_consistency(data.logmap, data.model_path, [data.dirs["point"], bad], out=out)
    assert str(bad) in str(exc.value)
    assert out.exists()  # written before raising, for inspection
    # A model of another log-map is refused.
    other = tmp_path / "all.zarr"
    logmap.write_logmap(data.store, other, split="all", materials_train=data.materials)
    with pytest.raises(ValueError, match="log-map ids differ"):
        acq_evaluation.check_consistency(other, data.model_path, [data.dirs["point"]])


# --------------------------------------------------------------------------
# Error vs number of training materials
# --------------------------------------------------------------------------


def test_training_size_curve(data: Data, evaluation: list[dict[str, Any]], tmp_path: Path) -> None:
    rows = acq_evaluation.training_size_curve(data.store, data.logmap, data.dirs["nearfield"],
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
    c = dense_coef(Q[obs], Y[:, obs].T, 40.0)
    rms = np.linalg.norm(Y - (Q @ c).T, axis=1) / np.sqrt(data.model.p)
    got = [_value(rows, n_train=3, material=mat, channel=ch) for mat in data.test for ch in "RGB"]
    np.testing.assert_allclose(got, rms, rtol=1e-7)
    assert _value(rows, n_train=3, material="mean") == pytest.approx(rms.mean(), rel=1e-7)
    # Tidy CSV.
    path = acq_evaluation.write_errors(tmp_path / "training_size.csv", rows, tables.TRAINING_SIZE)
    with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
        back = list(csv.reader(fh))
    assert tuple(back[0]) == tables.TRAINING_SIZE and len(back) == 1 + 2 * (3 * len(data.test) + 1)
    assert {r[2] for r in back[1:]} == {"5"} and {r[5] for r in back[1:]} == {"rms_log"}


def test_training_size_over_several_orders_is_each_orders_curve(data: Data, tmp_path: Path) -> None:
    """orders = 3: the curves of seeds 5, 6 and 7, one after the other, each equal to its single-order curve."""
    out = acq_evaluation.write_training_size(data.store, data.logmap, data.dirs["nearfield"], tmp_path / "t.csv",
                                             test_materials=data.test, sizes=(3, 6), order_seed=5, orders=3)
    _, rows = integrity.read_csv_rows(out, required=tables.TRAINING_SIZE)
    assert [r["order_seed"] for r in rows][:: len(rows) // 3] == ["5", "6", "7"]
    for seed in (5, 6, 7):
        single = acq_evaluation.training_size_curve(data.store, data.logmap, data.dirs["nearfield"],
                                                    test_materials=data.test, sizes=(3, 6), order_seed=seed)
        mine = [r for r in rows if r["order_seed"] == str(seed)]
        assert [(r["n_train"], r["material"], r["channel"]) for r in mine] == [
            (str(r["n_train"]), r["material"], r["channel"]) for r in single]
        np.testing.assert_allclose([float(r["value"]) for r in mine], [r["value"] for r in single], rtol=1e-8)
    # the three orders pick different first materials here: their curves differ at N = 3
    assert len({r["value"] for r in rows if r["n_train"] == "3" and r["material"] == "mean"}) > 1
    with pytest.raises(ValueError, match="orders must be in"):
        acq_evaluation.write_training_size(data.store, data.logmap, data.dirs["nearfield"], tmp_path / "u.csv",
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
    assert acq_evaluation.write_evaluation(data.store, data.model_path, dirs, errors_out,
                                           test_materials=data.test) == errors_out
    consistency = acq_evaluation.check_consistency(data.logmap, data.model_path, dirs, out=consistency_out)
    assert acq_evaluation.write_training_size(data.store, data.logmap, data.dirs["nearfield"], curve_out,
                                              test_materials=data.test, sizes=(2, 6)) == curve_out
    # Exactly the three files given, no temporary or other file left anywhere under out.
    assert sorted(p for p in out.rglob("*") if p.is_file()) == sorted([errors_out, consistency_out, curve_out])
    read_back = {}
    for path, cols in ((errors_out, tables.ERRORS), (consistency_out, CONSISTENCY_COLUMNS),
                       (curve_out, tables.TRAINING_SIZE)):
        with io.StringIO(integrity.read_csv_text(path), newline="") as fh:
            read_back[path] = list(csv.reader(fh))
        assert tuple(read_back[path][0]) == cols
    # The errors CSV is the evaluation, written by write_errors.
    ref = acq_evaluation.write_errors(tmp_path / "ref" / "errors.csv", evaluation)
    assert errors_out.read_text() == ref.read_text()
    assert len(read_back[consistency_out]) == 1 + len(consistency)
    # The curve uses the given directions file and sizes: N = 2 and N = 6 (all training materials).
    curve = read_back[curve_out]
    n_col = tables.TRAINING_SIZE.index("n_train")
    assert sorted({int(r[n_col]) for r in curve[1:]}) == [2, 6]
    assert len(curve) == 1 + 2 * (3 * len(data.test) + 1)
