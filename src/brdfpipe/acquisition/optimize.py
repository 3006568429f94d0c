"""The direction optimiser of minimal BRDF sampling (Xu et al. 2016 §5.1,
after Nielsen et al. 2015) and its directions files.

:func:`optimize` runs the greedy few-to-many search with local moves over the
configurations of a setup of :mod:`brdfpipe.acquisition.geometry`, minimising
a metric of :mod:`brdfpipe.acquisition.metrics` (E(S) of eq. 15, the
condition number of eq. 6, or Nielsen et al. 2015's first-n variant of it;
candidates drawn, moved and scored by :mod:`brdfpipe.acquisition.candidates`); :func:`write_directions` and
:func:`read_directions` write and read the direction sets as JSON, and
:func:`optimize_to_file` is the workflow's ``optimize_directions`` job.  The
comment below the imports describes the search, its moves, metrics and cost.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core import integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.core.version import full_version
from brdfpipe.data import merl
from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.acquisition.candidates import Block, CandidateSpace, Key, Scorer, Screen
from brdfpipe.acquisition.geometry import Config, Setup, config_from_dict, config_to_dict
from brdfpipe.acquisition.metrics import (
    DEFAULT_ETA,
    DOWNDATE_TOL,
    ErrorModel,
    FactoredSelection,
    check_eta,
    condition_number,
    selection_stats,
)

__all__ = [
    "DirectionSet",
    "Directions",
    "optimize",
    "write_directions",
    "read_directions",
    "optimize_to_file",
]

F64 = NDArray[np.float64]

# Greedy few-to-many search of Xu et al. §5.1 (after Nielsen et al. 2015),
# for every setup of the geometry section:
#
# for n = 1 … n_max:
#   1. greedy add: draw t = ``candidates`` distinct random configurations not
#      in the set, uniformly over the valid ones (centre cell a model column,
#      ≥ 1 observation row; for fixed_* with n > 1 the shared elevation is the
#      set's); evaluate each from the current statistics (G, qsum) +
#      its observation rows (selection_stats) and add the best;
#   2. local search: for step s in ``steps`` (3, 2, 1): sweep over the
#      configurations in a random order (seeded); for each, evaluate the
#      moves by ±s grid units along each of its axes and the combined
#      "gradient" move (every axis whose better ± move improves, moved
#      together — the paper's step along ∇E); take the best if it improves
#      the metric; repeat sweeps until one changes nothing, then go to the
#      next step.  Converged when a sweep at the last step changes nothing.
#      fixed_* sets also have the shared elevation as a unit of the sweep: its
#      ±s moves re-render every image.
#
# Held configurations (``held``: a set that must contain them, e.g. an image a
# paper states) start every set: n runs from len(held) + 1, and the local
# search moves only the others (fixed_*: nor the shared elevation).
#
# Moves stay in the measured region: a move whose centre cell is not a model
# column (or which observes nothing, or lands on a configuration already in
# the set, or leaves the index range) is not evaluated.  Axis ranges: point:
# iθh, iθd bounded, iφd periodic (φd and φd + π are one cell: reciprocity);
# nearfield: all bounded (across iφd = 179 → 0 light and camera would trade
# places); fixed_*: elevations bounded, the azimuth index periodic (360°).
#
# Metrics: "error" minimises E(S) (eq. 15, η and β as given).  "condition"
# minimises κ(Q̃) (eq. 6) — computed from the Gram matrix G when the set has
# more rows than k, from the rows otherwise — with ties (in particular κ = inf
# for both, rank-deficient Q̃, which the κ metric of near-field images often
# gives) broken by the smaller E(S): finite κ always wins, among equal κ the
# smaller E.  That the κ search is poor for near-field images is the paper's
# point (§3.1, Fig. 5) and is left as it is.  "condition_nielsen" minimises
# Nielsen et al. 2015's κ as released (the n × n matrix of the n rows and the
# first n components, condition_number_first_n; all k columns once there are
# more rows than k), with the same tie-break; its cost per candidate is one
# n × n SVD, as κ's.  (Their code also starts from the row of largest norm and
# runs no local search at n = 1; here n = 1 is searched like any n, on the
# code's 1 / |q₁₁|.)  Improvements must exceed a
# relative 1e-12, so rounding noise never counts as one (and the search
# cannot cycle).
#
# Cost.  Candidates are evaluated in batches sharing one base
# (FactoredSelection, "Many candidates against one factored base selection"
# in the metrics section): the greedy add's t candidates are the current set
# + their block; a configuration's ≤ 7 moves are the current set − its block
# + the moved block.  The current set's M⁻¹ = (G + ηI)⁻¹ and solve
# W = M⁻¹Uᵀ are computed once (Cholesky, dpotri) and carried along as the
# set changes by Woodbury updates, O(k²r + krm) per accepted move and no
# factorisation (rebuilt from the blocks once per n and every 32 updates;
# candidates.Scorer keeps it).  A point candidate then costs O(k² + km)
# flops — dgemm columns, all candidates of a step stacked into one product,
# point candidates passed as one (t, k) array — instead of a fresh
# Cholesky + solve with m right-hand sides, O(k³/3 + 2k²m); per run the
# cost grows with k² (≈ N², N training materials) but for the 2·n_max
# rebuilds and recomputations of each set (k³).  Near-field
# images (hundreds of distinct cells, the low-rank form would cost more) are
# still evaluated afresh: their distinct rows (counted, not repeated) in one
# dsyrk, one Cholesky + solve (E), one eigvalsh (κ, more than k rows) — and
# a configuration whose block is too strong to downdate accurately
# (tr G_j > η/DOWNDATE_TOL) has its moves evaluated against the set without
# it, summed afresh from the other blocks.  scipy's BLAS/LAPACK only for
# k-sized work, see the performance note at the top.  The reported E(S) and
# κ of every set are recomputed from scratch (_summarise).  Deterministic for a
# seed (numpy Generator; single-threaded choice, fixed reduction order).

logger = logging.getLogger("brdfpipe.acquisition.optimize")

_REL_IMPROVE: float = 1e-12
_Q_READ_ROWS: int = 36_450 * 4


class ModelLike(Protocol):
    """What :func:`optimize` needs of a model (:class:`brdfpipe.acquisition.svd.Model` has it)."""

    Q: Any  # (p, k) array-like (zarr or numpy), rows in ``cells`` order
    sigma: Any  # (k,)
    U: Any  # (m, k)
    cells: Any  # (p,) MERL cell of each row of Q


@dataclass(frozen=True)
class DirectionSet:
    """The optimised set of ``n`` configurations (one entry of :func:`optimize`'s result).

    ``records`` are :func:`config_to_dict` of ``configurations``;
    ``expected_error`` (E(S), eq. 15, with the run's η and β) and
    ``condition_number`` (κ(Q̃), eq. 6; inf when rank deficient) are always
    computed, from scratch, from the ``n_observations`` observation rows.
    ``greedy_value`` and ``metric_value`` are the optimised metric (E or κ)
    after the greedy add and after the local search, and ``moves`` the number
    of accepted moves (None when read from a file).
    """

    n: int
    configurations: tuple[Config, ...]
    records: tuple[dict[str, Any], ...]
    expected_error: float
    condition_number: float
    n_observations: int
    greedy_value: float | None = None
    metric_value: float | None = None
    moves: int | None = None


@dataclass(frozen=True)
class Directions:
    """A directions file as read by :func:`read_directions`."""

    setup: Setup
    metric: str
    split: str
    eta: float
    beta: float
    seed: int | None
    database: str
    model: str
    sets: tuple[DirectionSet, ...]


def _emit(log: Callable[[str], Any] | logging.Logger | None, msg: str) -> None:
    if log is None:
        logger.info(msg)
    elif isinstance(log, logging.Logger):
        log.info(msg)
    else:
        log(msg)


def _better(a: Key, b: Key) -> bool:
    """Lexicographic ``a < b`` where differences within a relative 1e-12 are ties (inf == inf)."""
    for x, y in zip(a, b):
        if x == y:
            continue
        if math.isinf(x) or math.isinf(y):
            return y > x
        tol = _REL_IMPROVE * max(abs(x), abs(y))
        if x < y - tol:
            return True
        if x > y + tol:
            return False
    return False


def _model_arrays(model: ModelLike) -> tuple[F64, F64, NDArray[np.int64]]:
    """A model's σ, U and cells as arrays, the cells and Q's shape checked (σ and U: by :class:`ErrorModel`)."""
    sigma = np.asarray(model.sigma, dtype=np.float64)
    U = np.asarray(model.U, dtype=np.float64)
    cells = np.asarray(model.cells)
    if cells.ndim != 1 or cells.size == 0 or not np.issubdtype(cells.dtype, np.integer):
        raise ValueError(f"model cells must be a non-empty 1-D integer array, got {cells.dtype} {cells.shape}")
    cells = cells.astype(np.int64)
    if cells.min() < 0 or cells.max() >= merl.N_CELLS:
        raise ValueError(f"model cells must lie in [0, {merl.N_CELLS})")
    if not np.all(np.diff(cells) > 0) and np.unique(cells).size != cells.size:
        raise ValueError("model cells must be distinct")
    q_shape = tuple(int(s) for s in model.Q.shape)
    if q_shape != (cells.size, sigma.size):
        raise ValueError(f"model Q has shape {q_shape}, expected (p, k) = ({cells.size}, {sigma.size})")
    return sigma, U, cells


def _load_q(Q: Any) -> NDArray[np.float32]:
    """The whole (p, k) matrix (shape checked by _model_arrays) as a C-contiguous float32 array, read in row blocks."""
    if isinstance(Q, np.ndarray):
        return np.ascontiguousarray(Q, dtype=np.float32)
    out = np.empty(tuple(int(s) for s in Q.shape), dtype=np.float32)
    chunk = getattr(Q, "chunks", None)
    rows = max(int(chunk[0]), 1) if chunk else 1
    step = rows * max(_Q_READ_ROWS // rows, 1)  # whole chunks at a time
    for a in range(0, out.shape[0], step):
        b = min(a + step, out.shape[0])
        out[a:b] = np.asarray(Q[a:b], dtype=np.float32)
    return out


def _check_steps(steps: Sequence[int]) -> tuple[int, ...]:
    try:
        out = tuple(steps)
    except TypeError:
        raise ValueError(f"steps must be a sequence of positive integers, got {steps!r}") from None
    if not out or any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 1 for s in out):
        raise ValueError(f"steps must be a non-empty sequence of positive integers, got {steps!r}")
    return tuple(int(s) for s in out)


def _held_blocks(space: CandidateSpace, scorer: Scorer, held: Sequence[Config]) -> list[Block]:
    """The blocks of the configurations :func:`optimize` holds; ValueError for one it cannot hold."""
    blocks: list[Block] = []
    kind = space.setup.kind
    for c in held:
        config_to_dict(space.setup, c)  # checks it: three in-range grid indices
        config = (int(c[0]), int(c[1]), int(c[2]))
        if config in {b.config for b in blocks}:
            raise ValueError(f"held configuration {config} is given twice")
        off = [axis for axis, value in space.pinned if config[axis] != value]
        if off:
            raise ValueError(f"held {kind} configuration {config} leaves its pinned axes {off}")
        if space.fixed and blocks and config[0] != blocks[0].config[0]:
            raise ValueError(f"held {kind} configurations must share the elevation: {config} vs {blocks[0].config}")
        idx = space.rows(config)
        if idx is None:
            raise ValueError(f"held configuration {config} observes no model column")
        blocks.append(scorer.block(config, idx))
    return blocks


def _greedy_add(space: CandidateSpace, scorer: Scorer, blocks: list[Block], t: int,
                coarse: CandidateSpace | None = None, keep: int = 0) -> tuple[Key, int]:
    """Add the best of ``t`` random candidates to ``blocks``; its key and how many were scored.

    ``coarse``: the same set-up on a coarse lattice (:class:`Screen`): the
    candidates are ranked by their coarse keys and the ``keep`` best (a
    candidate the coarse lattice cannot score ranks last) scored at the full
    lattice, in the order they were drawn, so that keeping every candidate
    adds what the exhaustive add does.
    """
    base = scorer.current(blocks)
    exclude = {b.config for b in blocks}
    shared = blocks[0].config[0] if (space.fixed and blocks) else None
    drawn = space.sample(t, exclude, shared)
    if coarse is not None:
        rows = [coarse.rows(cfg) for cfg in drawn]
        scored = [i for i, r in enumerate(rows) if r is not None]
        found = scorer.evaluate(base, blocks, [rows[i] for i in scored],
                                weight=(space.setup.grid / coarse.setup.grid) ** 2)
        coarse_key: list[Key] = [(math.inf,)] * len(drawn)
        for i, key in zip(scored, found):
            coarse_key[i] = key
        ranked = sorted(range(len(drawn)), key=coarse_key.__getitem__)
        kept: list[int] = []
        for i in ranked:
            if space.rows(drawn[i]) is not None:
                kept.append(i)
                if len(kept) == keep:
                    break
        drawn = [drawn[i] for i in sorted(kept)]
    configs: list[Config] = []
    cands: list[NDArray[np.intp]] = []
    for cfg in drawn:
        idx = space.rows(cfg)
        if idx is not None:
            configs.append(cfg)
            cands.append(idx)
    if not cands:
        raise ValueError(f"no valid {space.setup.kind} configuration left to add to a set of {len(blocks)} "
                         "(the model's columns leave none)")
    keys = scorer.evaluate(base, blocks, cands)
    best = min(range(len(keys)), key=keys.__getitem__)  # the first of equal keys
    new = scorer.block(configs[best], cands[best])
    blocks.append(new)
    scorer.accept(blocks, base, new)
    return keys[best], len(cands) if coarse is None else len(scored)


def _move_single(
    space: CandidateSpace, scorer: Scorer, blocks: list[Block], j: int, s: int, current: Key
) -> tuple[Key, list[Block], str] | None:
    """Best improving move of configuration ``j`` by ±s (or the combined move), or None.

    All moves are evaluated against one base: the current set's
    factorisation, less block j by a downdate, when block j is weak
    enough for that to be accurate (``tr G_j ≤ η/DOWNDATE_TOL``: every
    point row of the default models), else the set without j built
    afresh from the other blocks (near-field images, strong rows).
    """
    old = blocks[j]
    others = blocks[:j] + blocks[j + 1:]
    remove: Block | None = old
    if float(np.trace(old.G)) * DOWNDATE_TOL <= scorer.em.eta:
        base = scorer.current(blocks)
    else:
        base, remove = scorer.afresh(others), None
    taken = {b.config for b in others}
    cfg = old.config

    def valid(new: Config | None) -> NDArray[np.intp] | None:
        return None if new is None or new == cfg or new in taken else space.rows(new)

    moves: list[tuple[tuple[int, int], Config, NDArray[np.intp]]] = []
    for axis in space.axes:
        for d in (1, -1):
            new = space.shift(cfg, axis, d * s)
            idx = valid(new)
            if idx is not None:
                moves.append(((axis, d), new, idx))  # type: ignore[arg-type]
    keys = scorer.evaluate(base, others, [mv[2] for mv in moves], remove)
    results = {mv[0]: (key, mv[1], mv[2]) for mv, key in zip(moves, keys)}
    candidates = list(results.values())
    # The paper's gradient step: move along every axis that improves, at once.
    dirs: dict[int, int] = {}
    for axis in space.axes:
        opts = [(results[(axis, d)][0], d) for d in (1, -1) if (axis, d) in results]
        if opts:
            k_best, d_best = min(opts)
            if _better(k_best, current):
                dirs[axis] = d_best
    if len(dirs) >= 2:
        new_c: Config | None = cfg
        for axis, d in dirs.items():
            new_c = space.shift(new_c, axis, d * s) if new_c is not None else None
        idx = valid(new_c)
        if idx is not None:
            candidates.append((scorer.evaluate(base, others, [idx], remove)[0], new_c, idx))  # type: ignore[arg-type]
    if not candidates:
        return None
    key, new_cfg, idx = min(candidates, key=lambda r: r[0])
    if not _better(key, current):
        return None
    new_blocks = list(blocks)
    new_blocks[j] = scorer.block(new_cfg, idx)
    scorer.accept(new_blocks, base, new_blocks[j], remove)
    unit = space.setup.spec.unit
    return key, new_blocks, f"{unit} {j + 1} {space.describe(cfg)} -> {space.describe(new_cfg)}"


def _move_shared(
    space: CandidateSpace, scorer: Scorer, blocks: list[Block], s: int, current: Key
) -> tuple[Key, list[Block], str] | None:
    """Best improving ±s move of the shared elevation (fixed_*), or None."""
    best: tuple[Key, list[Config], list[NDArray[np.intp]]] | None = None
    for d in (1, -1):
        news = [space.shift(b.config, 0, d * s) for b in blocks]
        if any(c is None for c in news):
            continue
        idxs: list[NDArray[np.intp]] = []
        for c in news:
            idx = space.rows(c)  # type: ignore[arg-type]
            if idx is None:
                break
            idxs.append(idx)
        else:
            key = scorer.key(idxs)  # every image changes: evaluated afresh
            if best is None or key < best[0]:
                best = (key, news, idxs)  # type: ignore[assignment]
    if best is None or not _better(best[0], current):
        return None
    new_blocks = [scorer.block(c, i) for c, i in zip(best[1], best[2])]
    name = space.setup.spec.axes[0]
    return best[0], new_blocks, f"shared {name} {blocks[0].config[0]} -> {best[1][0][0]}"


def _local_search(
    space: CandidateSpace, scorer: Scorer, blocks: list[Block], key: Key, steps: Sequence[int], n: int, held: int,
    log: Callable[[str], Any] | logging.Logger | None,
) -> tuple[list[Block], Key, int]:
    """Moves of every configuration but the first ``held`` ones (and of the shared elevation when none is held)."""
    moves = 0
    for si, s in enumerate(steps):
        if si > 0:
            _emit(log, f"n={n} step {steps[si - 1]} -> {s}: {scorer.fmt(key)}")
        while True:
            units: list[int | None] = list(range(held, len(blocks))) + ([None] if space.fixed and not held else [])
            changed = False
            for ui in space.rng.permutation(len(units)):
                unit = units[int(ui)]
                res = (_move_shared(space, scorer, blocks, s, key) if unit is None
                       else _move_single(space, scorer, blocks, unit, s, key))
                if res is None:
                    continue
                key, blocks, what = res
                moves += 1
                changed = True
                _emit(log, f"n={n} step {s}: move {what}: {scorer.fmt(key)}")
            if not changed:
                break
    return blocks, key, moves


def _summarise(space: CandidateSpace, scorer: Scorer, blocks: Sequence[Block], greedy: Key, final: Key,
               moves: int) -> DirectionSet:
    """The set of ``blocks`` with its E(S) and κ computed from scratch."""
    rows = np.concatenate([b.rows for b in blocks], axis=0)
    configs = tuple(b.config for b in blocks)
    # E(S) from scratch (Cholesky of G + ηI, solve); the same fresh factorisation is the next
    # greedy add's base (no rounding carried over, one factorisation per n instead of two).
    fresh = FactoredSelection(scorer.em, *selection_stats(rows))
    scorer.set_current(blocks, fresh)
    return DirectionSet(
        n=len(blocks),
        configurations=configs,
        records=tuple(config_to_dict(space.setup, c) for c in configs),
        expected_error=fresh.error(),
        condition_number=condition_number(rows),
        n_observations=int(rows.shape[0]),
        greedy_value=float(greedy[0]),
        metric_value=float(final[0]),
        moves=moves,
    )


def optimize(
    model: ModelLike,
    setup: Setup,
    *,
    metric: Literal["error", "condition", "condition_nielsen"] = "error",
    n_max: int,
    candidates: int = 500,
    steps: Sequence[int] = (3, 2, 1),
    eta: float = DEFAULT_ETA,
    beta: float = 0.0,
    seed: int | None = 0,
    log: Callable[[str], Any] | logging.Logger | None = None,
    evaluation: Literal["fast", "direct"] = "fast",
    held: Sequence[Config] = (),
    screen: Screen | None = None,
) -> list[DirectionSet]:
    """Optimal acquisition configurations for n = 1 … ``n_max`` (Xu et al. §5; see the section comment).

    Parameters
    ----------
    model:
        The PCA model (:func:`brdfpipe.acquisition.svd.open_model`, or anything with
        ``Q`` (p, k), ``sigma`` (k,), ``U`` (m, k) and ``cells`` (p,)).  ``Q``
        is read into memory as float32 (1.2 GB at p = 1.1 M, k = 270); E(S)
        averages over the m rows of ``U``.
    setup:
        The acquisition :class:`Setup`.
    metric:
        ``"error"`` (E(S), eq. 15), ``"condition"`` (κ(Q̃), eq. 6, ties and
        inf broken by E(S)) or ``"condition_nielsen"`` (κ of the first n
        components, Nielsen et al. 2015 as released; ties likewise).
    n_max:
        Largest set size (≥ 1).
    candidates:
        t, random candidates per greedy add (paper: 500).
    steps:
        Local-search step lengths in grid units, largest first (paper: 3, 2, 1).
    eta, beta:
        η > 0 and β ≥ 0 of E(S) (used for the "error" metric, the tie-break
        and the reported E(S) alike).
    seed:
        Seed of the ``numpy.random.Generator`` (candidates, sweep order).
    log:
        A callable taking one line, a :class:`logging.Logger`, or None (the
        ``brdfpipe.acquisition.optimize`` logger, INFO): one line per greedy add, accepted
        move, step change and convergence, with the metric value.
    evaluation:
        How candidates' E(S) is computed: ``"fast"`` (default) by low-rank
        updates of a factorisation shared by a batch of candidates where
        that is cheaper (:class:`FactoredSelection`), ``"direct"`` each
        candidate afresh (:func:`expected_error`; the reference the fast
        path is tested against, many times slower for point sampling).  Both
        are exact; they differ by rounding (≈ 1e-13 relative), which can only
        change which of two candidates tied to that precision wins.
    held:
        Configurations held fixed as the first ones of every set (default
        none): the search adds the others to them and never moves them
        (nor, for fixed_*, their shared elevation).  Each must observe a
        model column; fixed_* ones must share the elevation.
    screen:
        The greedy add screened on a coarse lattice (:class:`Screen`, ours), for image set-ups and the
        "error" metric at a grid below the set-up's (ignored otherwise); None: every candidate scored at
        the full lattice, the paper's search.

    Returns
    -------
    list[DirectionSet]
        The sets for n = len(held) + 1 … n_max, each grown from the previous one.

    Raises
    ------
    ValueError
        Bad parameters or model, or no valid configuration left to add.
    """
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be a Setup, got {type(setup).__name__}")
    if metric not in acquisition_spec.METRICS:
        raise ValueError(f"metric must be one of {acquisition_spec.METRICS}, got {metric!r}")
    if isinstance(n_max, bool) or not isinstance(n_max, (int, np.integer)) or n_max < 1:
        raise ValueError(f"n_max must be a positive integer, got {n_max!r}")
    if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) or candidates < 1:
        raise ValueError(f"candidates must be a positive integer, got {candidates!r}")
    step_list = _check_steps(steps)
    if evaluation not in ("fast", "direct"):
        raise ValueError(f"evaluation must be 'fast' or 'direct', got {evaluation!r}")
    if screen is not None and not isinstance(screen, Screen):
        raise ValueError(f"screen must be a Screen or None, got {type(screen).__name__}")
    ErrorModel(np.ones(1), np.zeros((1, 1)), eta=eta, beta=beta)  # checks η and β before the model is read
    held = tuple(held)
    if len(held) >= int(n_max):
        raise ValueError(f"n_max = {n_max} leaves nothing to add to {len(held)} held configuration(s)")
    sigma, U, cells = _model_arrays(model)
    space = CandidateSpace(setup, cells, np.random.default_rng(seed))
    em = ErrorModel(sigma, U, eta=eta, beta=beta)  # validates σ and U
    scorer = Scorer(em, metric, _load_q(model.Q), evaluation)
    blocks = _held_blocks(space, scorer, held)
    coarse, keep = None, 0
    if screen is not None and screen.applies(setup, metric):
        coarse, keep = CandidateSpace(Setup(setup.kind, setup.fov_deg, screen.grid), cells, space.rng), screen.keep
    _emit(log, f"optimise {setup.kind} fov {setup.fov_deg:g}° grid {setup.grid}, metric {metric}, "
               f"n = {len(held) + 1}..{n_max}, t = {candidates}, steps {step_list}, η = {em.eta:g}, "
               f"β = {em.beta:g}, seed {seed}; model p = {cells.size}, k = {em.k}, m = {em.m}"
               + (f"; greedy add screened at {screen.grid} px, best {keep} scored in full" if coarse else "")
               + "".join(f"; held {space.describe(b.config)}" for b in blocks))
    sets: list[DirectionSet] = []
    for n in range(len(held) + 1, int(n_max) + 1):
        t0 = time.perf_counter()
        evals0 = scorer.evaluations
        greedy, tried = _greedy_add(space, scorer, blocks, int(candidates), coarse, keep)
        _emit(log, f"n={n} greedy add: best of {tried} candidates {space.describe(blocks[-1].config)}, "
                   f"{sum(b.n for b in blocks)} rows: {scorer.fmt(greedy)} ({time.perf_counter() - t0:.1f} s)")
        blocks, final, moves = _local_search(space, scorer, blocks, greedy, step_list, n, len(held), log)
        result = _summarise(space, scorer, blocks, greedy, final, moves)
        sets.append(result)
        kappa = result.condition_number
        _emit(log, f"n={n} converged after {moves} moves: {scorer.fmt(final)} (greedy {scorer.fmt(greedy)}); "
                   f"E = {result.expected_error:.6g}, κ = {kappa:.6g}, {result.n_observations} rows, "
                   f"{time.perf_counter() - t0:.1f} s, {scorer.evaluations - evals0} metric evaluations")
    return sets


# ---------------------------------------------------------------------------
# Directions files
# ---------------------------------------------------------------------------
#
# JSON, written atomically (temporary sibling + rename):
#
#   {"format": "brdfpipe.directions/1", "setup": kind, "fov": degrees (0 for
#    point), "grid": g, "metric": "error" | "condition" | "condition_nielsen", "split": …, "eta": η,
#    "beta": β, "seed": …, "database": …, "model": path, "brdfpipe_version": …,
#    "sets": [{"n": n, "configurations": [config_to_dict records],
#              "expected_error": E, "condition_number": κ (null when
#              infinite), "n_observations": rows}, …],
#    "screen": {"grid": g, "keep": n} only where the greedy add was screened (ours)}


def _json_number(x: float) -> float | int:
    return int(x) if float(x).is_integer() else float(x)


def write_directions(
    path: str | os.PathLike[str],
    sets: Sequence[DirectionSet],
    *,
    setup: Setup,
    metric: str,
    split: str,
    model_path: str | os.PathLike[str],
    seed: int | None,
    eta: float,
    beta: float,
    database: str,
    screen: Screen | None = None,
) -> Path:
    """Write :func:`optimize`'s sets as the directions JSON (format above), atomically.

    ``screen``: the :class:`Screen` the search used, recorded where it applied.

    The configuration records are regenerated from the configurations and
    ``setup``.  Parent folders are created.  Returns the path.
    """
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be a Setup, got {type(setup).__name__}")
    if metric not in acquisition_spec.METRICS:
        raise ValueError(f"metric must be one of {acquisition_spec.METRICS}, got {metric!r}")
    eta = check_eta(eta)
    beta = float(beta)
    if not np.isfinite(beta) or beta < 0:
        raise ValueError(f"beta must be finite and ≥ 0, got {beta!r}")
    out_sets = []
    for s in sets:
        if s.n != len(s.configurations):
            raise ValueError(f"set n = {s.n} holds {len(s.configurations)} configurations")
        kappa = float(s.condition_number)
        out_sets.append({
            "n": int(s.n),
            "configurations": [config_to_dict(setup, c) for c in s.configurations],
            "expected_error": float(s.expected_error),
            "condition_number": kappa if math.isfinite(kappa) else None,
            "n_observations": int(s.n_observations),
        })
    doc = {
        "format": acquisition_spec.DIRECTIONS_FORMAT,
        "setup": setup.kind,
        "fov": _json_number(setup.fov_deg),
        "grid": setup.grid,
        "metric": metric,
        "split": str(split),
        "eta": eta,
        "beta": beta,
        "seed": None if seed is None else int(seed),
        "database": str(database),
        "model": str(model_path),
        "brdfpipe_version": full_version(),
        "sets": out_sets,
    }
    if screen is not None and screen.applies(setup, metric):
        doc["screen"] = {"grid": int(screen.grid), "keep": int(screen.keep)}
    path = Path(path)
    integrity.write_json(path, doc, indent=1, allow_nan=False)  # with its digest
    return path


def read_directions(path: str | os.PathLike[str]) -> Directions:
    """Read a directions file written by :func:`write_directions`.

    Configurations are rebuilt from their records (:func:`config_from_dict`);
    a null κ reads as inf.  :class:`ValueError` naming the file for a
    missing, truncated or edited file (its digest is checked,
    :func:`brdfpipe.core.integrity.read_json`), a wrong format or inconsistent
    content.
    """
    path = Path(path)
    doc = integrity.read_json(path, kind="directions file")  # its digest checked
    if doc.get("format") != acquisition_spec.DIRECTIONS_FORMAT:
        raise ValueError(f"{path}: not a directions file (format {doc.get('format')!r})")
    try:
        setup = Setup(doc["setup"], doc["fov"], doc["grid"])
        metric = doc["metric"]
        if metric not in acquisition_spec.METRICS:
            raise ValueError(f"unknown metric {metric!r}")
        sets = []
        for entry in doc["sets"]:
            configs = tuple(config_from_dict(setup, r) for r in entry["configurations"])
            if int(entry["n"]) != len(configs):
                raise ValueError(f"set n = {entry['n']} holds {len(configs)} configurations")
            kappa = entry["condition_number"]
            sets.append(DirectionSet(
                n=int(entry["n"]),
                configurations=configs,
                records=tuple(entry["configurations"]),
                expected_error=float(entry["expected_error"]),
                condition_number=float("inf") if kappa is None else float(kappa),
                n_observations=int(entry["n_observations"]),
            ))
        return Directions(
            setup=setup,
            metric=metric,
            split=str(doc["split"]),
            eta=float(doc["eta"]),
            beta=float(doc["beta"]),
            seed=None if doc.get("seed") is None else int(doc["seed"]),
            database=str(doc["database"]),
            model=str(doc["model"]),
            sets=tuple(sets),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: invalid directions file: {exc}") from exc


def optimize_to_file(
    model_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    setup: str,
    fov: float,
    grid: int,
    metric: str,
    n_max: int,
    candidates: int,
    eta: float,
    beta: float,
    seed: int,
    threads: int | None = None,
    screen_grid: int = 0,
    screen_keep: int = 10,
) -> Path:
    """Optimise the direction sets of one setup on a PCA model and write them as JSON.

    The workflow's ``optimize_directions`` job: opens the model written by
    :func:`brdfpipe.acquisition.svd.write_model`, runs :func:`optimize` (one log line per
    step) and writes :func:`write_directions`'s JSON to ``out``; the split
    and database recorded are the model's.  ``threads``: the BLAS threads
    to use (the rule's declared threads; None leaves them as they are).
    ``screen_grid`` > 0: the greedy add screened on that lattice, its
    ``screen_keep`` best scored in full (:class:`Screen`, ours); 0: the paper's search.
    """
    from brdfpipe.acquisition.svd import open_model

    screen = Screen(int(screen_grid), int(screen_keep)) if screen_grid else None

    model = open_model(model_path)
    known = acquisition_spec.SETUPS.get(setup)  # an unknown name: Setup says which exist
    kind_setup = Setup(setup, fov_deg=0.0 if known is not None and not known.images else float(fov), grid=int(grid))
    log = logging.getLogger("brdfpipe.acquisition.optimize")
    log.info(
        "optimising %s fov %g (%s metric) on %s: n_max %d, %d candidates, seed %d",
        setup, kind_setup.fov_deg, metric, model_path, n_max, candidates, seed,
    )
    with blas_threads(threads):
        sets = optimize(
            model, kind_setup, metric=metric, n_max=n_max, candidates=candidates,
            eta=eta, beta=beta, seed=seed, log=log, screen=screen,
        )
    return write_directions(
        out, sets, setup=kind_setup, metric=metric, split=model.split,
        model_path=model_path, seed=seed, eta=eta, beta=beta, database=model.database, screen=screen,
    )
