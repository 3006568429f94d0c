"""Tests of :mod:`brdfpipe.acquisition.optimize`, the direction optimiser (Xu et al. 2016 §5).

The model is a fake, built with numpy in a few seconds: m = 24 "material
channels" that are random mixtures of r = 16 smooth functions of the cell
angles (specular-like lobes in θh of several widths, a Fresnel-like term in
θd, low-frequency Fourier modes) over every geometrically measured MERL cell
(p = 1,096,216, as the real model) or a subset of them.  The centred matrix has
rank 15 = k, so E(S) must equal the direct reconstruction error of the
training rows.  Q is stored as float32, as the real model does.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.typing import NDArray

from brdfpipe.core import integrity
from pspace_reference import direct_training_error
from brdfpipe.acquisition.geometry import config_to_dict, observation_cells, Setup
from brdfpipe.acquisition.metrics import (ErrorModel, condition_number, condition_number_first_n, expected_error,
                                          selection_stats)
from brdfpipe.acquisition.candidates import Scorer, Screen
from brdfpipe.acquisition.optimize import DirectionSet, optimize, read_directions, write_directions
from brdfpipe.core import filenames
from brdfpipe.data import merl
from brdfpipe.registry.acquisition import DIRECTIONS_FORMAT

T = 40  # candidates per greedy add (the paper's 500 is the default; small here for speed)


@dataclass
class FakeModel:
    """What optimize() needs (Q, sigma, U, cells), plus mean and X for the direct check."""

    Q: NDArray[np.float32]
    sigma: NDArray[np.float64]
    U: NDArray[np.float64]
    cells: NDArray[np.int64]
    mean: NDArray[np.float64]
    X: NDArray[np.float64]


def make_model(cells: NDArray[np.int64], m: int = 24, r: int = 16, seed: int = 0) -> FakeModel:
    rng = np.random.default_rng(seed)
    th, td, pd = (a.ravel()[cells] for a in merl.cell_centres())
    feats = [np.exp(-((th / w) ** 2)) for w in (0.03, 0.08, 0.2, 0.5)]
    feats += [(1.0 - np.cos(td)) ** 5, np.cos(td), np.sin(td) * np.cos(pd)]
    while len(feats) < r:
        om = rng.normal(0.0, 2.0, 3)
        feats.append(np.cos(2 * om[0] * th + om[1] * td + om[2] * pd + rng.uniform(0, 2 * np.pi)))
    F = np.array(feats)
    X = 1.0 + (rng.standard_normal((m, r)) * np.arange(1, r + 1) ** -0.7) @ F
    mean = X.mean(axis=0)
    Y = X - mean
    lam, V = np.linalg.eigh(Y @ Y.T)
    keep = lam > 1e-9 * lam[-1]
    lam, V = lam[keep][::-1], V[:, keep][:, ::-1]
    Q = (Y.T @ V).astype(np.float32)
    return FakeModel(Q=Q, sigma=np.sqrt(lam), U=V, cells=cells, mean=mean, X=X)


@functools.lru_cache(maxsize=None)
def full_model() -> FakeModel:
    return make_model(np.flatnonzero(merl.measured_mask().ravel()))


@functools.lru_cache(maxsize=None)
def partial_model() -> FakeModel:
    """Only part of the measured region: θh < 50°-ish, θd < 60°, φd < 150°."""
    ih, idd, ip = np.meshgrid(*(np.arange(d) for d in merl.DIMS), indexing="ij")
    mask = merl.measured_mask() & (ih < 67) & (idd < 60) & (ip < 150)
    return make_model(np.flatnonzero(mask.ravel()), seed=1)


def setup_of(kind: str, grid: int = 16) -> Setup:
    return Setup(kind, 0.0 if kind == "point" else 25.0, grid)


def lookup_of(model: FakeModel) -> NDArray[np.int64]:
    lut = np.full(merl.N_CELLS, -1, dtype=np.int64)
    lut[model.cells] = np.arange(model.cells.size)
    return lut


def rows_of(model: FakeModel, setup: Setup, configs: tuple) -> NDArray[np.int64]:
    """Model rows observed by a set, recomputed independently of the optimiser."""
    lut = lookup_of(model)
    cells = np.concatenate([observation_cells(setup, c, lut >= 0) for c in configs])
    return lut[cells]


@functools.lru_cache(maxsize=None)
def run(kind: str, metric: str = "error", seed: int = 0, n_max: int = 3, partial: bool = False,
        beta: float = 0.0) -> tuple[DirectionSet, ...]:
    model = partial_model() if partial else full_model()
    n = 5 if kind == "point" and n_max == 3 else n_max
    return tuple(optimize(model, setup_of(kind), metric=metric, n_max=n, candidates=T, seed=seed, beta=beta,
                          log=lambda line: None))


KINDS = ("point", "nearfield", "fixed_camera", "fixed_light")


# ---------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_deterministic_with_a_seed(kind: str) -> None:
    a = run(kind, seed=3)
    b = optimize(full_model(), setup_of(kind), metric="error", n_max=len(a), candidates=T, seed=3,
                 log=lambda line: None)
    assert [s.configurations for s in a] == [s.configurations for s in b]
    assert [s.expected_error for s in a] == [s.expected_error for s in b]
    c = run(kind, seed=4)
    assert [s.configurations for s in a] != [s.configurations for s in c]


@pytest.mark.parametrize("kind", KINDS)
def test_nested_sets(kind: str) -> None:
    sets = run(kind)
    setup = setup_of(kind)
    assert [s.n for s in sets] == list(range(1, len(sets) + 1))
    for s in sets:
        assert len(s.configurations) == s.n == len(s.records)
        assert len(set(s.configurations)) == s.n
        assert list(s.records) == [config_to_dict(setup, c) for c in s.configurations]
        assert s.n_observations == rows_of(full_model(), setup, s.configurations).size
        assert s.moves is not None and s.moves >= 0
        if kind in ("fixed_camera", "fixed_light"):
            assert len({c[0] for c in s.configurations}) == 1  # one shared elevation per set
    if kind == "point":
        assert [s.n_observations for s in sets] == [s.n for s in sets]
    else:
        assert all(s.n_observations > 20 * s.n for s in sets)


@pytest.mark.parametrize("kind,beta", [(k, 0.0) for k in KINDS] + [("nearfield", 0.5)])
def test_reported_metrics_recomputed_from_scratch(kind: str, beta: float) -> None:
    model = full_model()
    em = ErrorModel(model.sigma, model.U, eta=40.0, beta=beta)
    for s in run(kind, beta=beta):
        rows = model.Q[rows_of(model, setup_of(kind), s.configurations)]
        G, qsum = selection_stats(rows)
        assert s.expected_error == pytest.approx(expected_error(em, G, qsum), rel=1e-12)
        assert s.condition_number == pytest.approx(condition_number(rows), rel=1e-9)
        assert math.isfinite(s.expected_error) and s.expected_error > 0


@pytest.mark.parametrize(
    "kind,metric,beta,grid",
    [
        ("point", "error", 0.0, 16),
        ("point", "error", 0.5, 16),
        ("point", "condition", 0.0, 16),
        ("nearfield", "error", 0.0, 2),  # a 2 × 2 lattice: blocks of 1-4 rows, low-rank and direct
        ("nearfield", "error", 0.5, 16),
        ("nearfield", "condition", 0.0, 2),
        ("fixed_camera", "error", 0.0, 2),
        ("fixed_light", "error", 0.5, 16),
    ],
)
def test_fast_evaluation_selects_as_direct(kind: str, metric: str, beta: float, grid: int) -> None:
    """The low-rank candidate evaluation makes the same choices as evaluating every candidate afresh."""
    model = full_model()
    setup = setup_of(kind, grid)
    n_max = 6 if kind == "point" else 3
    kw = dict(metric=metric, n_max=n_max, candidates=T, seed=5, beta=beta, log=lambda line: None)
    fast = optimize(model, setup, evaluation="fast", **kw)  # type: ignore[arg-type]
    direct = optimize(model, setup, evaluation="direct", **kw)  # type: ignore[arg-type]
    assert [s.configurations for s in fast] == [s.configurations for s in direct]
    assert [s.moves for s in fast] == [s.moves for s in direct]
    for a, b in zip(fast, direct):
        assert a.expected_error == b.expected_error  # recomputed from scratch for both
        assert a.greedy_value == pytest.approx(b.greedy_value, rel=1e-10)
        assert a.metric_value == pytest.approx(b.metric_value, rel=1e-10)
        if metric == "error":
            assert a.metric_value == pytest.approx(a.expected_error, rel=1e-10)


def test_bad_evaluation_raises() -> None:
    with pytest.raises(ValueError):
        optimize(full_model(), setup_of("point"), n_max=1, candidates=5,
                 evaluation="woodbury")  # type: ignore[arg-type]


def test_point_error_equals_direct_training_error() -> None:
    """The issue's acceptance check: predicted E(S) = mean reconstruction error of the training rows."""
    model = full_model()
    for s in run("point"):
        rows = rows_of(model, setup_of("point"), s.configurations)
        direct = direct_training_error(model.Q, model.U, model.sigma, model.mean, model.X, rows)
        assert s.expected_error == pytest.approx(direct, rel=1e-6)


@pytest.mark.parametrize("kind", KINDS)
def test_centre_cells_are_model_columns(kind: str) -> None:
    model = partial_model()
    in_model = np.zeros(merl.N_CELLS, dtype=bool)
    in_model[model.cells] = True
    for metric in ("error", "condition"):
        for s in run(kind, metric=metric, partial=True):
            for c, rec in zip(s.configurations, s.records):
                assert in_model[rec["cell"]], (c, rec)
            # every observation row is a model row
            assert s.n_observations == rows_of(model, setup_of(kind), s.configurations).size


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("metric", ["error", "condition"])
def test_local_search_never_worsens_greedy(kind: str, metric: str) -> None:
    for s in run(kind, metric=metric):
        assert s.greedy_value is not None and s.metric_value is not None
        assert s.metric_value <= s.greedy_value or s.metric_value == s.greedy_value == math.inf
        if metric == "error":
            assert s.expected_error <= s.greedy_value * (1 + 1e-9)
            assert s.expected_error == pytest.approx(s.metric_value, rel=1e-9)


def test_point_result_is_a_local_minimum() -> None:
    """Converged: no ±1 move of any direction (valid, not in the set) lowers E(S)."""
    model = full_model()
    em = ErrorModel(model.sigma, model.U)
    lut = lookup_of(model)
    s = run("point")[-1]
    configs = list(s.configurations)
    for j, c in enumerate(configs):
        for axis in range(3):
            for d in (1, -1):
                new = list(c)
                new[axis] += d
                if axis == 2:
                    new[axis] %= merl.N_PHI_D
                if not 0 <= new[axis] < merl.DIMS[axis] or tuple(new) in configs:
                    continue
                cell = int(np.ravel_multi_index(new, merl.DIMS))
                if lut[cell] < 0:
                    continue
                trial = configs[:j] + [tuple(new)] + configs[j + 1:]
                rows = model.Q[rows_of(model, setup_of("point"), tuple(trial))]
                assert expected_error(em, *selection_stats(rows)) >= s.expected_error * (1 - 1e-9)


def test_error_metric_beats_condition_metric_near_field() -> None:
    """Paper Fig. 5: minimising κ is a poor proxy for near-field images (soft: mean over seeds)."""
    e_err = [run("nearfield", "error", seed)[-1].expected_error for seed in (0, 1, 2)]
    e_cond = [run("nearfield", "condition", seed)[-1].expected_error for seed in (0, 1, 2)]
    assert np.mean(e_err) < np.mean(e_cond)
    # ... and each metric wins at its own game on average
    k_err = [run("nearfield", "error", seed)[-1].condition_number for seed in (0, 1, 2)]
    k_cond = [run("nearfield", "condition", seed)[-1].condition_number for seed in (0, 1, 2)]
    assert np.mean(np.log(k_cond)) < np.mean(np.log(k_err))


def test_more_images_help() -> None:
    for kind in KINDS:
        errs = [s.expected_error for s in run(kind)]
        assert errs[-1] < errs[0]


# ---------------------------------------------------------------------------
# Parameters and logging
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {"metric": "rmse"},
        {"n_max": 0},
        {"n_max": 1.5},
        {"candidates": 0},
        {"steps": ()},
        {"steps": (3, 0, 1)},
        {"steps": (2.5,)},
        {"eta": 0.0},
        {"beta": -1.0},
    ],
)
def test_bad_parameters_raise(kwargs: dict) -> None:
    args = {"metric": "error", "n_max": 1, "candidates": 5, "seed": 0, "log": lambda line: None} | kwargs
    with pytest.raises(ValueError):
        optimize(full_model(), setup_of("point"), **args)


def test_bad_models_raise() -> None:
    good = full_model()
    bad_cells = FakeModel(good.Q[:10], good.sigma, good.U, np.array([5] * 10), good.mean, good.X)
    with pytest.raises(ValueError):
        optimize(bad_cells, setup_of("point"), n_max=1, candidates=5, seed=0)
    bad_shape = FakeModel(good.Q[:10], good.sigma, good.U, good.cells[:11], good.mean, good.X)
    with pytest.raises(ValueError):
        optimize(bad_shape, setup_of("point"), n_max=1, candidates=5, seed=0)
    with pytest.raises(ValueError):
        optimize(good, "nearfield", n_max=1, candidates=5, seed=0)  # type: ignore[arg-type]


@pytest.mark.parametrize("kind", ["nearfield", "fixed_camera"])
def test_held_configurations_start_every_set_and_never_move(kind: str) -> None:
    """A set that must hold a stated image (the paper's directions): only the others are added and moved."""
    model, setup = full_model(), setup_of(kind)
    held = run(kind, n_max=1)[0].configurations
    sets = optimize(model, setup, n_max=3, candidates=T, seed=5, log=lambda line: None, held=held)
    assert [s.n for s in sets] == [2, 3]
    em = ErrorModel(model.sigma, model.U, eta=40.0, beta=0.0)
    for s in sets:
        assert s.configurations[0] == held[0]
        if kind == "fixed_camera":  # the shared elevation is the held image's
            assert {c[0] for c in s.configurations} == {held[0][0]}
        G, qsum = selection_stats(model.Q[rows_of(model, setup, s.configurations)])
        assert s.expected_error == pytest.approx(expected_error(em, G, qsum), rel=1e-12)


@pytest.mark.parametrize(
    "held,n_max,match",
    [
        (((40, 40, 40),), 1, "leaves nothing to add"),
        (((40, 40, 40), (40, 40, 40)), 3, "given twice"),
        (((90, 0, 0),), 2, "out of range"),
        (((80, 10, 10),), 2, "observes no model column"),  # outside the partial model's cells
    ],
)
def test_bad_held_configurations_raise(held: tuple, n_max: int, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        optimize(partial_model(), setup_of("nearfield"), n_max=n_max, candidates=5, seed=0, log=lambda line: None,
                 held=held)


def test_runs_out_of_configurations() -> None:
    good = full_model()
    tiny = FakeModel(good.Q[:2], good.sigma, good.U, good.cells[:2], good.mean, good.X)
    with pytest.raises(ValueError, match="no valid"):
        optimize(tiny, setup_of("point"), n_max=3, candidates=5, seed=0, log=lambda line: None)


def test_log_lines(caplog: pytest.LogCaptureFixture) -> None:
    lines: list[str] = []
    sets = optimize(full_model(), setup_of("nearfield"), n_max=2, candidates=10, seed=0, log=lines.append)
    assert sum("greedy add" in line for line in lines) == 2
    assert sum("converged" in line for line in lines) == 2
    moves = [line for line in lines if ": move " in line]
    assert len(moves) == sum(s.moves for s in sets)  # type: ignore[misc]
    assert all("E = " in line for line in lines[1:])
    assert sum("step 3 -> 2" in line for line in lines) == 2
    with caplog.at_level(logging.INFO, logger="brdfpipe.acquisition.optimize"):
        optimize(full_model(), setup_of("point"), n_max=1, candidates=5, seed=0)
    assert any("greedy add" in r.getMessage() for r in caplog.records)
    condition_lines: list[str] = []
    optimize(full_model(), setup_of("point"), metric="condition", n_max=1, candidates=5, seed=0,
             log=condition_lines.append)
    assert all("κ = " in line for line in condition_lines[1:])


# ---------------------------------------------------------------------------
# Directions files
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_write_read_directions(tmp_path, kind: str) -> None:  # type: ignore[no-untyped-def]
    setup = setup_of(kind)
    sets = run(kind)
    path = tmp_path / filenames.directions("train", kind, setup.fov_deg, "error")
    fov = "0" if kind == "point" else "25"
    assert path == tmp_path / "results" / "directions" / "train" / f"{kind}-fov{fov}-error.json"
    out = write_directions(path, sets, setup=setup, metric="error", split="train", model_path="/tmp/m.zarr",
                           seed=0, eta=40.0, beta=0.0, database="synthetic")
    assert out == path and path.is_file()
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporary left
    doc = json.loads(path.read_text())
    assert doc["format"] == DIRECTIONS_FORMAT
    assert {k: doc[k] for k in ("setup", "fov", "grid", "metric", "split", "eta", "beta", "seed", "database",
                                "model")} == {
        "setup": kind, "fov": 0 if kind == "point" else 25, "grid": setup.grid, "metric": "error",
        "split": "train", "eta": 40.0, "beta": 0.0, "seed": 0, "database": "synthetic", "model": "/tmp/m.zarr"}
    assert [set(s) for s in doc["sets"]] == [
        {"n", "configurations", "expected_error", "condition_number", "n_observations"}] * len(sets)
    back = read_directions(path)
    assert back.setup == setup and back.metric == "error" and back.seed == 0
    for a, b in zip(sets, back.sets):
        assert a.configurations == b.configurations
        assert list(a.records) == list(b.records)
        assert (a.expected_error, a.condition_number, a.n_observations) == (
            b.expected_error, b.condition_number, b.n_observations)


def test_infinite_condition_number_is_null(tmp_path) -> None:  # type: ignore[no-untyped-def]
    s = run("point")[0]
    inf = DirectionSet(s.n, s.configurations, s.records, s.expected_error, math.inf, s.n_observations)
    path = tmp_path / "d.json"
    write_directions(path, [inf], setup=setup_of("point"), metric="condition", split="all", model_path="m",
                     seed=None, eta=40, beta=0, database="merl")
    assert json.loads(path.read_text())["sets"][0]["condition_number"] is None
    assert read_directions(path).sets[0].condition_number == math.inf


def test_bad_directions_files(tmp_path) -> None:  # type: ignore[no-untyped-def]
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(ValueError, match=r"x\.json: truncated or corrupt directions file \(not JSON"):
        read_directions(p)
    p.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match=r"x\.json: directions file carries no brdfpipe digest"):
        read_directions(p)
    integrity.write_json(p, {"format": "something else"})
    with pytest.raises(ValueError, match=r"x\.json: not a directions file"):
        read_directions(p)
    sets = run("nearfield")
    write_directions(p, sets, setup=setup_of("nearfield"), metric="error", split="train", model_path="m",
                     seed=0, eta=40, beta=0, database="merl")
    doc = json.loads(p.read_text())
    doc["sets"][0]["n"] = 7
    p.write_text(json.dumps(doc))  # an edit by hand
    with pytest.raises(ValueError, match=r"x\.json: its content does not match its recorded digest"):
        read_directions(p)
    doc.pop(integrity.DIGEST_KEY)
    integrity.write_json(p, doc)  # sealed again: the content check still refuses it
    with pytest.raises(ValueError, match=r"x\.json: invalid directions file: set n = 7 holds 1"):
        read_directions(p)
    with pytest.raises(ValueError):
        write_directions(p, sets, setup=setup_of("nearfield"), metric="kappa", split="train", model_path="m",
                         seed=0, eta=40, beta=0, database="merl")


def test_each_kappa_metric_picks_the_sets_a_brute_force_greedy_search_picks() -> None:
    """A tiny candidate set (8 point cells, k = 4): every step adds what an exhaustive search over the cells adds.

    The cells are 5 φd cells apart, so no local move (≤ 3 cells) lands on
    another: the optimiser is the paper's greedy few-to-many search with
    every candidate tried (t = p).  The brute force evaluates each metric's
    key (κ, then E(S)) on every remaining cell, independently of the
    optimiser.  On this basis the two κ pick different sets, so a swapped
    metric fails.
    """
    @dataclass
    class Tiny:
        Q: NDArray[np.float32]
        sigma: NDArray[np.float64]
        U: NDArray[np.float64]
        cells: NDArray[np.int64]

    rng = np.random.default_rng(1)
    p, k, n_max = 8, 4, 4
    cells = np.ravel_multi_index((np.full(p, 40), np.full(p, 40), 5 * np.arange(p)), merl.DIMS).astype(np.int64)
    model = Tiny((rng.standard_normal((p, k)) * [4.0, 2.0, 1.0, 0.5]).astype(np.float32), np.array([4.0, 2.0, 1.0, 0.5]),
                 np.linalg.qr(rng.standard_normal((6, k)))[0], cells)
    em = ErrorModel(model.sigma, model.U)
    Q = model.Q.astype(np.float64)

    def brute_force(kappa) -> list[int]:  # type: ignore[no-untyped-def]
        chosen: list[int] = []
        for _ in range(n_max):
            def key(c: int) -> tuple[float, float]:
                rows = Q[chosen + [c]]
                return kappa(rows), expected_error(em, *selection_stats(rows))
            chosen.append(min((c for c in range(p) if c not in chosen), key=key))
        return chosen

    picked = {}
    for metric, kappa in (("condition_nielsen", condition_number_first_n), ("condition", condition_number)):
        sets = optimize(model, Setup("point", 0.0, 8), metric=metric, n_max=n_max, candidates=p, seed=0,
                        log=lambda line: None)
        order = [int(np.flatnonzero(cells == np.ravel_multi_index(c, merl.DIMS))[0]) for c in sets[-1].configurations]
        want = brute_force(kappa)
        assert order == want, (metric, order, want)
        assert [sorted(s.configurations) for s in sets] == [
            sorted(sets[-1].configurations[:n]) for n in range(1, n_max + 1)]  # each set grows from the previous
        picked[metric] = want
    assert picked["condition_nielsen"] != picked["condition"]


def test_a_ring_of_cameras_is_a_record(monkeypatch: pytest.MonkeyPatch) -> None:
    """The extending page's ring (docs/design/extending.md): one record, its geometry the fixed light's.

    One light shared by the set and cameras on a ring at 45° elevation: the
    record pins the camera's elevation (axis 1) and moves only its azimuth;
    nothing else is edited.  Every set the optimiser returns keeps the ring,
    shares the light's elevation, and its reported E(S) is its rows' own.
    """
    from brdfpipe.registry import acquisition as acq_spec

    ring = acq_spec.SetupKind("ring", "camera ring at 45°, fixed light", images=True, fov="fixed", shared="light",
                              axes=("θlight", "θcam", "φcam"), wrap_phi=True, n_max_key="n_max_images",
                              moves=(2,), pinned=((1, 45),))
    monkeypatch.setitem(acq_spec.SETUPS, "ring", ring)
    model, setup = full_model(), Setup("ring", 25.0, 8)
    sets = optimize(model, setup, metric="error", n_max=3, candidates=T, seed=0, log=lambda line: None)
    assert [s.n for s in sets] == [1, 2, 3]
    for s in sets:
        assert all(c[1] == 45 for c in s.configurations), s.configurations
        assert len({c[0] for c in s.configurations}) == 1  # the shared light's elevation
        em = ErrorModel(model.sigma, model.U, eta=40.0)
        rows = model.Q[rows_of(model, setup, s.configurations)]
        assert math.isclose(s.expected_error, expected_error(em, *selection_stats(rows)), rel_tol=1e-9)
    assert sets[-1].expected_error < sets[0].expected_error
    light = optimize(model, Setup("fixed_light", 25.0, 8), metric="error", n_max=3, candidates=T, seed=0,
                     log=lambda line: None)
    assert any(c[1] != 45 for c in light[-1].configurations)  # without the pin the cameras leave the ring


def test_a_pinned_axis_is_refused_where_it_cannot_hold(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pinned axes need candidates drawn on the grid (a shared direction); a held set must keep them."""
    from brdfpipe.registry import acquisition as acq_spec

    base = acq_spec.SETUPS["fixed_light"]
    monkeypatch.setitem(acq_spec.SETUPS, "ring", dataclasses.replace(base, name="ring", moves=(2,), pinned=((1, 45),)))
    monkeypatch.setitem(acq_spec.SETUPS, "pinned_nearfield",
                        dataclasses.replace(acq_spec.SETUPS["nearfield"], name="pinned_nearfield", pinned=((1, 45),)))
    model = full_model()
    with pytest.raises(ValueError, match="set-up pinned_nearfield: pinned axes need a shared direction"):
        optimize(model, Setup("pinned_nearfield", 25.0, 8), n_max=1, candidates=T, seed=0, log=lambda line: None)
    with pytest.raises(ValueError, match=r"held ring configuration \(20, 30, 10\) leaves its pinned axes \[1\]"):
        optimize(model, Setup("ring", 25.0, 8), n_max=2, candidates=T, seed=0, held=[(20, 30, 10)],
                 log=lambda line: None)


# ---------------------------------------------------------------------------
# Screening the greedy add on a coarse lattice (ours, acquisition.screen_grid)
# ---------------------------------------------------------------------------


def _sets(kind: str, screen: Screen | None, metric: str = "error", grid: int = 16) -> list[tuple]:
    sets = optimize(full_model(), setup_of(kind, grid), metric=metric, n_max=3, candidates=T, seed=3,
                    log=lambda line: None, screen=screen)
    return [(s.configurations, s.expected_error, s.greedy_value, s.metric_value, s.moves) for s in sets]


@pytest.mark.parametrize("kind", ["nearfield", "fixed_camera", "fixed_light"])
def test_screening_that_keeps_every_candidate_adds_what_the_exhaustive_add_adds(kind: str) -> None:
    """All t candidates kept and scored in full: the exhaustive search, bit for bit."""
    assert _sets(kind, Screen(grid=4, keep=T)) == _sets(kind, None)


@pytest.mark.parametrize("kind", ["nearfield", "fixed_camera"])
def test_screening_scores_in_full_only_the_kept_candidates(kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The full lattice's cells are computed for the ``keep`` best coarse candidates only (and the local search)."""
    import brdfpipe.acquisition.candidates as candidates

    full = setup_of(kind, 16)
    counted: list[tuple] = []
    real = candidates.observation_cells

    def counting(setup: Setup, config: tuple, valid: NDArray[np.bool_]) -> NDArray[np.int64]:
        if setup == full:
            counted.append(tuple(config))
        return real(setup, config, valid)

    monkeypatch.setattr(candidates, "observation_cells", counting)
    logs: list[str] = []
    sets = optimize(full_model(), full, metric="error", n_max=1, candidates=T, seed=3, steps=(1,),
                    log=logs.append, screen=Screen(grid=4, keep=3))
    moves = 2 * len(full.spec.moves) + 1  # ± one step along each axis and the combined move, per sweep
    assert len(set(counted)) <= 3 + moves * (sets[0].moves + 1), (len(set(counted)), sets[0].moves)
    assert f"best of {T} candidates" in logs[1] and "screened at 4 px, best 3 scored in full" in logs[0]


def test_screening_applies_to_images_and_the_error_metric_at_a_coarser_grid(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Elsewhere it changes nothing, and the directions file records it only where it screened."""
    screen = Screen(grid=4, keep=2)
    assert _sets("point", screen) == _sets("point", None)
    assert _sets("nearfield", screen, metric="condition") == _sets("nearfield", None, metric="condition")
    assert _sets("nearfield", Screen(grid=16, keep=2)) == _sets("nearfield", None)
    assert not screen.applies(setup_of("point"), "error") and screen.applies(setup_of("nearfield"), "error")
    kw = dict(split="all", model_path="m.zarr", seed=3, eta=40.0, beta=0.0, database="synthetic")
    for kind, metric, recorded in [("nearfield", "error", {"grid": 4, "keep": 2}), ("nearfield", "condition", None),
                                   ("point", "error", None)]:
        sets = optimize(full_model(), setup_of(kind), metric=metric, n_max=1, candidates=T, seed=3,
                        log=lambda line: None, screen=screen)
        path = write_directions(tmp_path / f"{kind}-{metric}.json", sets, setup=setup_of(kind), metric=metric,
                                screen=screen, **kw)
        assert json.loads(path.read_text()).get("screen") == recorded
        assert read_directions(path).sets[0].configurations == sets[0].configurations
    with pytest.raises(ValueError, match="screen grid must be a positive integer"):
        Screen(grid=0)
    with pytest.raises(ValueError, match="screen must be a Screen"):
        optimize(full_model(), setup_of("nearfield"), n_max=1, candidates=T, screen=(4, 2))  # type: ignore[arg-type]


def test_a_weighted_candidate_counts_as_its_rows_repeated() -> None:
    """A coarse candidate's rows count (full / coarse)² times each: exactly its rows repeated that often."""
    model = full_model()
    em = ErrorModel(model.sigma, model.U, eta=40.0)
    scorer = Scorer(em, "error", model.Q, "direct")
    setup = setup_of("nearfield", 6)
    lut = lookup_of(model)
    first = lut[observation_cells(setup, (10, 30, 40), lut >= 0)]
    block = scorer.block((10, 30, 40), first)
    base = scorer.afresh([block])
    cands = [lut[observation_cells(setup, c, lut >= 0)] for c in [(20, 40, 60), (5, 70, 90), (30, 20, 10)]]
    weighted = scorer.evaluate(base, [block], cands, weight=4.0)
    repeated = scorer.evaluate(base, [block], [np.repeat(c, 4) for c in cands])
    np.testing.assert_allclose(np.asarray(weighted), np.asarray(repeated), rtol=1e-9)
    assert scorer.evaluate(base, [block], cands) != weighted
