"""The near-field directions Xu §6 states in words, evaluated (brdfpipe.acquisition.paper_directions).

The model is test_optimize's fake (smooth functions of the cell angles, m = 24
rows), over a block of cells that holds both sentences' configurations and
few enough others that every configuration can be evaluated by brute force:
θh cells < 18 (3.4°), θd cells 42–62, φd cells < 12.  Images of 12 pixels a
side, as the tiny config's.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from test_optimize import FakeModel, make_model

from brdfpipe.acquisition.geometry import Setup, centre_directions, config_to_dict, observation_cells
from brdfpipe.acquisition.metrics import ErrorModel, expected_error, selection_stats
from brdfpipe.acquisition.optimize import optimize
from brdfpipe.acquisition.paper_directions import (PHI_STEP, evaluate_paper_directions, matching_configurations,
                                                   write_paper_directions)
from brdfpipe.core import integrity
from brdfpipe.data import merl
from brdfpipe.registry import tables
from brdfpipe.registry.acquisition import PAPER_DIRECTIONS, paper_direction

GRID = 12
ONE, TWO = paper_direction("one-shot"), paper_direction("two-shot")


@functools.lru_cache(maxsize=None)
def block_model() -> FakeModel:
    ih, idd, ip = np.meshgrid(*(np.arange(d) for d in merl.DIMS), indexing="ij")
    mask = merl.measured_mask() & (ih < 18) & (idd >= 42) & (idd < 63) & (ip < 12)
    return make_model(np.flatnonzero(mask.ravel()), seed=2)


_LOOKUPS: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def lookup_of(model: FakeModel) -> tuple[np.ndarray, np.ndarray]:
    """Model row of every MERL cell (−1: not a column) and the mask of the columns, once per model."""
    if id(model) not in _LOOKUPS:
        lut = np.full(merl.N_CELLS, -1, dtype=np.int64)
        lut[model.cells] = np.arange(model.cells.size)
        _LOOKUPS[id(model)] = (lut, lut >= 0)
    return _LOOKUPS[id(model)]


def valid_of(model: FakeModel) -> np.ndarray:
    return lookup_of(model)[1]


def direct_error(model: FakeModel, setup: Setup, configs: tuple) -> float:
    """E(S) of a set from its observation rows, with repeats (test_optimize's route, not the module's)."""
    lut, valid = lookup_of(model)
    rows = lut[np.concatenate([observation_cells(setup, c, valid) for c in configs])]
    if rows.size == 0:
        return math.inf
    G, qsum = selection_stats(model.Q[rows])
    return expected_error(ErrorModel(model.sigma, model.U, eta=40.0, beta=0.0), G, qsum)


def incidence(setup: Setup, c: tuple) -> float:
    wi, _ = centre_directions(setup, c)
    return math.degrees(math.acos(wi[2]))


def matches(d, c: tuple) -> bool:  # type: ignore[no-untyped-def]
    """The sentence's reading, from geometry's records: θh of the cell centre and the light's incidence."""
    setup = Setup("nearfield", d.fov_deg, GRID)
    centres = [((i + 0.5) / 90) ** 2 * 90 for i in range(90)]
    th = config_to_dict(setup, c)["theta_h_deg"]
    if d.theta_h_rule == "nearest":
        ok = abs(th - d.theta_h_deg) == min(abs(x - d.theta_h_deg) for x in centres)
    else:
        ok = th <= d.theta_h_deg
    return ok and abs(incidence(setup, c) - d.incidence_deg) <= d.incidence_tol_deg + 1e-9


@pytest.mark.parametrize("key", [d.key for d in PAPER_DIRECTIONS])
def test_matching_configurations_are_the_sentences(key: str) -> None:
    """Exactly the configurations the sentence describes, in a window about them (φd every 7th cell)."""
    d = paper_direction(key)
    got = {tuple(int(x) for x in c) for c in matching_configurations(d)}
    assert got and all(matches(d, c) for c in got)
    window = range(12, 20) if d.theta_h_rule == "nearest" else range(0, 10)
    for ih in window:
        for idd in range(38, 68):
            for ip in range(0, 180, 7):
                assert ((ih, idd, ip) in got) == matches(d, (ih, idd, ip)), (ih, idd, ip)
    if key == "one-shot":
        assert {c[0] for c in got} == {16}  # 3.025°, the centre nearest 3°
    else:
        assert {c[0] for c in got} == set(range(7))  # centres up to 0.469°


def test_one_shot_is_the_best_configuration_matching_the_sentence() -> None:
    model = block_model()
    setup = Setup("nearfield", ONE.fov_deg, GRID)
    configs = [tuple(int(x) for x in c) for c in matching_configurations(ONE, valid_of(model))]
    brute = {c: direct_error(model, setup, (c,)) for c in configs}
    best = min(brute.values())
    for step in (1, PHI_STEP):
        [s] = evaluate_paper_directions(model, [ONE], grid=GRID, eta=40.0, beta=0.0, candidates=5, seed=0,
                                        phi_step=step, log=lambda line: None)
        [c] = s.configurations
        assert matches(ONE, c) and c in brute and s.matching == len(configs)
        # its E(S) is that configuration's, from its rows (rounding of sums over ≤ 144 rows: far below 1e-9)
        assert s.expected_error == pytest.approx(direct_error(model, setup, (c,)), rel=1e-9)
        # never below the best matching configuration; equal to it when every one is evaluated
        assert s.expected_error >= best * (1 - 1e-9)
        if step == 1:
            assert s.evaluated == len(configs) and s.expected_error == pytest.approx(best, rel=1e-9)
        else:  # the sub-grid's best, refined: no worse than it, fewer evaluated
            coarse = min(v for c, v in brute.items() if c[2] % step == 0)
            assert s.expected_error <= coarse * (1 + 1e-9) and s.evaluated < len(configs)


def test_two_shot_holds_the_sentences_image_and_adds_the_best_second() -> None:
    """With a greedy add that sees every configuration, the second image is the best one by brute force."""
    model = block_model()
    setup = Setup("nearfield", TWO.fov_deg, GRID)
    [s] = evaluate_paper_directions(model, [TWO], grid=GRID, eta=40.0, beta=0.0, candidates=model.cells.size,
                                    seed=0, phi_step=1, log=lambda line: None)
    first, second = s.configurations
    configs = [tuple(int(x) for x in c) for c in matching_configurations(TWO, valid_of(model))]
    alone = {c: direct_error(model, setup, (c,)) for c in configs}
    assert matches(TWO, first) and alone[first] == pytest.approx(min(alone.values()), rel=1e-9)
    assert s.expected_error == pytest.approx(direct_error(model, setup, (first, second)), rel=1e-9)
    lut, valid = lookup_of(model)
    em = ErrorModel(model.sigma, model.U, eta=40.0, beta=0.0)
    G1, q1 = selection_stats(model.Q[lut[observation_cells(setup, first, valid)]])
    pairs = math.inf
    for cell in model.cells:  # every second image: its statistics added to the first's
        c = tuple(int(x) for x in np.unravel_index(cell, merl.DIMS))
        rows = lut[observation_cells(setup, c, valid)]
        if c != first and rows.size:
            G2, q2 = selection_stats(model.Q[rows])
            pairs = min(pairs, expected_error(em, G1 + G2, q1 + q2))
    assert s.expected_error == pytest.approx(pairs, rel=1e-9)


def test_table_has_the_declared_columns_and_one_row_per_image(tmp_path) -> None:  # type: ignore[no-untyped-def]
    model = block_model()
    sets = evaluate_paper_directions(model, [ONE, TWO], grid=GRID, eta=40.0, beta=0.0, candidates=20, seed=1,
                                     log=lambda line: None)
    path = write_paper_directions(tmp_path / "paper.csv", sets, grid=GRID, split="all", database="synthetic")
    header, rows = integrity.read_csv_rows(path)
    assert tuple(header) == tables.PAPER_DIRECTIONS
    assert [(r["direction"], r["image"], r["chosen_by"]) for r in rows] == [
        ("one-shot", "1", "sentence"), ("two-shot", "1", "sentence"), ("two-shot", "2", "optimiser")]
    for r, (d, c) in zip(rows, [(ONE, sets[0].configurations[0]), (TWO, sets[1].configurations[0]),
                                (TWO, sets[1].configurations[1])]):
        setup = Setup("nearfield", d.fov_deg, GRID)
        assert float(r["light_theta_deg"]) == pytest.approx(incidence(setup, c), abs=1e-6)
        assert float(r["theta_h_deg"]) == pytest.approx(config_to_dict(setup, c)["theta_h_deg"], abs=1e-6)
        assert r["database"] == "synthetic" and r["split"] == "all" and r["grid"] == str(GRID)


def test_a_model_without_matching_configurations_is_refused() -> None:
    full = block_model()
    keep = np.flatnonzero(np.unravel_index(full.cells, merl.DIMS)[0] != 16)  # no θh cell at 3°
    model = FakeModel(full.Q[keep], full.sigma, full.U, full.cells[keep], full.mean, full.X)
    with pytest.raises(ValueError, match="no configuration of the model matches the paper's one-shot"):
        evaluate_paper_directions(model, [ONE], grid=GRID, eta=40.0, beta=0.0, candidates=5, seed=0)
