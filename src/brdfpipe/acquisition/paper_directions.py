"""The near-field directions Xu et al. 2016 state in words (§6, Figs. 8, 9), evaluated with E(S) on this run's model.

"For one image, we capture a slightly offspecular direction (θh = 3°) at an
angle of incidence of about 50°." and "for two images, the first direction
for 15° field of view is an exact specular reflection at 60°" (§6).  A
sentence fixes the first image's θh and its light's incidence, not a
configuration.  Here it is the set of near-field configurations — the
centre cell (iθh, iθd, iφd) of the MERL grid with φh = 0, as the optimiser's
(:mod:`brdfpipe.acquisition.geometry`) — that match it
(:data:`brdfpipe.registry.acquisition.PAPER_DIRECTIONS`,
:func:`matching_configurations`):

* one image (FOV 25°, Fig. 9's, which draws it): the θh cell whose centre is
  nearest 3° (centres θh = ((i + ½)/90)² · 90°: i = 16, 3.03°), the light's
  incidence at the sample's centre within 50 ± 5° ("about 50°"), any φd;
* two images (FOV 15°): the first image's θh cell centre at most 0.5°
  ("exact specular": i = 0 … 6) at 60 ± 2.5° incidence, any φd; the second
  image is not stated.

What the sentence leaves free is given its best value: the paper's direction
is the matching configuration of least E(S) (eq. 15 with the run's η and β,
the near-field image of ``acquisition.grid`` pixels a side; a configuration
observing no model column does not count).  Of two images, the first is the
matching configuration of least E(S) alone, and the second is the one the
optimiser adds to it: its greedy add of t random candidates and its local
search, with the first image held (:func:`brdfpipe.acquisition.optimize.optimize`,
``held``), as it grows its own sets.  So the E(S) reported is what the
paper's direction reaches at best by this project's search; a number above
the optimiser's own optimum is a finding about the direction, not the search.

Cost.  One configuration costs one near-field image's cells and one E(S)
from its distinct rows (≈ 0.04 s at 256 px, k = 299).  The sentences match
1,800 (one image) and 6,300 (two images) configurations, so φd is
sub-sampled on the optimiser's coarsest local-search step (every 3rd cell,
:data:`PHI_STEP`) and the best of those is refined along φd at the smaller
steps (±1, ±2 cells), as the optimiser's steps 3 → 2 → 1: the table says how
many were evaluated of how many match.

:func:`evaluate_paper_directions` evaluates them, :func:`write_paper_directions`
writes the table (columns :data:`brdfpipe.registry.tables.PAPER_DIRECTIONS`, one
row per image), :func:`paper_directions_to_file` is the workflow's
``evaluate_paper_directions`` job.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brdfpipe.acquisition.candidates import Screen
from brdfpipe.acquisition.geometry import CONFIG_DIMS, Config, Setup, config_to_dict, observation_cells
from brdfpipe.acquisition.metrics import ErrorModel, RowBlock, block_stats, expected_error
from brdfpipe.acquisition.optimize import ModelLike, optimize
from brdfpipe.core import integrity
from brdfpipe.core.atomic import check_not_input
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import merl
from brdfpipe.registry import tables
from brdfpipe.registry.acquisition import PaperDirection, paper_direction

__all__ = [
    "PHI_STEP",
    "PaperSet",
    "matching_configurations",
    "evaluate_paper_directions",
    "write_paper_directions",
    "paper_directions_to_file",
]

logger = logging.getLogger("brdfpipe.acquisition.paper_directions")

#: φd sub-sampling of the matching configurations: the optimiser's coarsest local-search step (grid cells).
PHI_STEP: int = 3
_TIE_DEG: float = 1e-9  # an incidence on the interval's edge (60 − 2.5 = 57.5°, a θd cell centre at θh ≈ 0) is in


@dataclass(frozen=True)
class PaperSet:
    """A paper's direction as evaluated: ``configurations[0]`` matches the sentence, the rest the optimiser added.

    ``expected_error``: E(S) of the whole set; ``matching``: the configurations
    matching the sentence (centre cell a model column), ``evaluated``: how
    many of them were evaluated (:data:`PHI_STEP` and the refinement).
    """

    direction: PaperDirection
    configurations: tuple[Config, ...]
    expected_error: float
    matching: int
    evaluated: int


@dataclass(frozen=True)
class _InMemory:
    """A :class:`~brdfpipe.acquisition.optimize.ModelLike` whose Q is read once (the optimiser does not copy it)."""

    Q: NDArray[np.float32]
    sigma: NDArray[np.float64]
    U: NDArray[np.float64]
    cells: NDArray[np.int64]


def matching_configurations(direction: PaperDirection, valid: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
    """The (n, 3) configurations (iθh, iθd, iφd) whose centre matches ``direction``'s sentence, in grid order.

    θh by the record's rule on the cell centres (θh = ((i + ½)/90)² · 90°),
    the light's incidence (its angle from the normal at the centre, φh = 0)
    within the record's interval.  ``valid``: a boolean mask of all MERL
    cells the centre must lie in (the model's columns); default every cell.
    """
    theta_h = np.degrees(merl.cell_centres()[0][:, 0, 0])
    if direction.theta_h_rule == "nearest":
        ih = np.array([int(np.argmin(np.abs(theta_h - direction.theta_h_deg)))])
    elif direction.theta_h_rule == "at_most":
        ih = np.flatnonzero(theta_h <= direction.theta_h_deg)
    else:
        raise ValueError(f"unknown θh rule {direction.theta_h_rule!r} of paper direction {direction.key!r}")
    per_h = merl.N_THETA_D * merl.N_PHI_D
    cells = (ih[:, None] * per_h + np.arange(per_h)[None, :]).ravel()
    wi, _ = merl.cell_directions(cells)
    incidence = np.degrees(np.arccos(np.clip(wi[:, 2], -1.0, 1.0)))
    keep = np.abs(incidence - direction.incidence_deg) <= direction.incidence_tol_deg + _TIE_DEG
    if valid is not None:
        keep &= np.asarray(valid, dtype=bool).reshape(-1)[cells]
    ih_, rest = np.divmod(cells[keep], per_h)
    idd, ip = np.divmod(rest, merl.N_PHI_D)
    return np.stack([ih_, idd, ip], axis=1).astype(np.intp)


def _best_matching(direction: PaperDirection, setup: Setup, Q: NDArray[np.float32], lookup: NDArray[np.int64],
                   em: ErrorModel, phi_step: int) -> tuple[Config, float, int, int]:
    """(configuration, E(S) alone, matching, evaluated): the best on the φd sub-grid, refined along φd."""
    valid = lookup >= 0
    configs = matching_configurations(direction, valid)
    if not len(configs):
        raise ValueError(f"no configuration of the model matches the paper's {direction.key} direction")
    known = {(int(a), int(b), int(c)) for a, b, c in configs}
    errors: dict[Config, float] = {}

    def error(c: Config) -> float:
        if c not in errors:
            idx = lookup[observation_cells(setup, c, valid)]
            if idx.size == 0:
                errors[c] = math.inf
            else:
                rows, counts = np.unique(idx, return_counts=True)
                G, qsum = block_stats(RowBlock(Q[rows], counts.astype(np.float64), None), em.k)
                errors[c] = expected_error(em, G, qsum)
        return errors[c]

    coarse = [c for c in sorted(known) if c[2] % phi_step == 0] or sorted(known)
    best = min(coarse, key=lambda c: (error(c), c))
    for d in range(1 - phi_step, phi_step):  # the smaller steps about the best, as the optimiser's 3 → 2 → 1
        c = (best[0], best[1], best[2] + d)
        if c in known and 0 <= c[2] < CONFIG_DIMS[2]:
            error(c)
    best = min(errors, key=lambda c: (errors[c], c))
    if not math.isfinite(errors[best]):
        raise ValueError(f"no configuration matching the paper's {direction.key} direction observes a model column")
    return best, errors[best], len(known), len(errors)


def evaluate_paper_directions(
    model: ModelLike,
    directions: Sequence[PaperDirection],
    *,
    grid: int,
    eta: float,
    beta: float,
    candidates: int,
    seed: int,
    phi_step: int = PHI_STEP,
    log: Callable[[str], Any] | logging.Logger | None = None,
    screen: Screen | None = None,
) -> list[PaperSet]:
    """E(S) of each paper direction on ``model`` (see the module docstring), in the order given.

    ``grid``: pixels a side of the near-field images; ``eta``, ``beta``: E(S)'s
    η and β; ``candidates`` and ``seed``: the optimiser's t and seed, for the
    images after the first (``screen``: its greedy add's :class:`Screen`, as
    :func:`~brdfpipe.acquisition.optimize.optimize`'s); ``phi_step``: the φd sub-sampling (1: every
    matching configuration).  ValueError when none of a direction's
    configurations observes a model column.
    """
    if isinstance(phi_step, bool) or not isinstance(phi_step, int) or phi_step < 1:
        raise ValueError(f"phi_step must be a positive integer, got {phi_step!r}")
    em = ErrorModel(np.asarray(model.sigma, dtype=np.float64), np.asarray(model.U, dtype=np.float64), eta=eta,
                    beta=beta)
    Q = model.Q if isinstance(model.Q, np.ndarray) else np.asarray(model.Q[:], dtype=np.float32)
    cells = np.asarray(model.cells, dtype=np.int64)
    loaded = _InMemory(np.ascontiguousarray(Q, dtype=np.float32), em.sigma, em.U, cells)
    lookup = np.full(merl.N_CELLS, -1, dtype=np.int64)
    lookup[cells] = np.arange(cells.size)
    emit = log.info if isinstance(log, logging.Logger) else log or logger.info
    out = []
    for d in directions:
        setup = Setup("nearfield", d.fov_deg, grid)
        first, E, matching, evaluated = _best_matching(d, setup, loaded.Q, lookup, em, phi_step)
        emit(f"{d.key} (FOV {d.fov_deg:g}°): best of {evaluated} of the {matching} configurations matching the "
             f"sentence {first}: E = {E:.6g} alone")
        configs: tuple[Config, ...] = (first,)
        if d.n_images > 1:
            sets = optimize(loaded, setup, metric="error", n_max=d.n_images, candidates=candidates, eta=eta,
                            beta=beta, seed=seed, log=log, held=configs, screen=screen)
            configs, E = sets[-1].configurations, sets[-1].expected_error
            emit(f"{d.key}: with the optimiser's {d.n_images - 1} more image(s) {configs[1:]}: E = {E:.6g}")
        out.append(PaperSet(d, configs, float(E), matching, evaluated))
    return out


def write_paper_directions(path: str | os.PathLike[str], sets: Sequence[PaperSet], *, grid: int, split: str,
                           database: str) -> Path:
    """Write the table (columns :data:`brdfpipe.registry.tables.PAPER_DIRECTIONS`, one row per image), atomically.

    ``chosen_by``: ``sentence`` for the image the paper states, ``optimiser``
    for those the optimiser added; angles are the centre's (the light's θ
    from the normal); ``expected_error`` is the whole set's.
    """
    rows: list[list[str]] = [list(tables.PAPER_DIRECTIONS)]
    for s in sets:
        setup = Setup("nearfield", s.direction.fov_deg, grid)
        for i, c in enumerate(s.configurations):
            r = config_to_dict(setup, c)
            light = math.degrees(math.acos(max(-1.0, min(1.0, r["light"][2]))))
            rows.append([database, split, s.direction.key, f"{s.direction.fov_deg:g}", str(grid),
                         str(len(s.configurations)), str(i + 1), "sentence" if i == 0 else "optimiser",
                         f"{r['theta_h_deg']:.6f}", f"{r['theta_d_deg']:.6f}", f"{r['phi_d_deg']:.6f}",
                         f"{light:.6f}", f"{s.expected_error:.10g}", str(s.matching), str(s.evaluated)])
    path = Path(path)
    integrity.write_csv(path, rows)  # with its digest line
    return path


def paper_directions_to_file(
    model_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    directions: Sequence[str],
    grid: int,
    eta: float,
    beta: float,
    candidates: int,
    seed: int,
    threads: int | None = None,
    screen_grid: int = 0,
    screen_keep: int = 10,
) -> Path:
    """The workflow's ``evaluate_paper_directions`` job: the named paper directions on a model, as the table.

    ``directions``: keys of :data:`brdfpipe.registry.acquisition.PAPER_DIRECTIONS`;
    the model written by :func:`brdfpipe.acquisition.svd.write_model` (the
    table records its split and database); ``threads``: the BLAS threads to
    use (the rule's; None leaves them as they are); ``screen_grid`` > 0, ``screen_keep``: the
    optimiser's :class:`Screen` (as :func:`~brdfpipe.acquisition.optimize.optimize_to_file`'s).
    """
    from brdfpipe.acquisition.svd import open_model

    records = [paper_direction(k) for k in directions]
    check_not_input(out, [model_path], what="output")
    model = open_model(model_path)
    with blas_threads(threads):
        sets = evaluate_paper_directions(model, records, grid=grid, eta=eta, beta=beta, candidates=candidates,
                                         seed=seed, log=logger,
                                         screen=Screen(int(screen_grid), int(screen_keep)) if screen_grid else None)
    return write_paper_directions(out, sets, grid=grid, split=model.split, database=model.database)
