"""The direction optimiser of minimal BRDF sampling (Xu et al. 2016 §5.1,
after Nielsen et al. 2015) and its directions files.

:func:`optimize` runs the greedy few-to-many search with local moves over the
configurations of a setup of :mod:`brdfpipe.acquisition.geometry`, minimising
a metric of :mod:`brdfpipe.acquisition.metrics` (E(S) of eq. 15, the
condition number of eq. 6, or Nielsen et al. 2015's first-n variant of it); :func:`write_directions` and
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
from brdfpipe.spec import acquisition as acquisition_spec
from brdfpipe.acquisition.geometry import (
    CONFIG_DIMS,
    Config,
    Setup,
    cell_config,
    centre_cells,
    config_from_dict,
    config_to_dict,
    observation_cells,
)
from brdfpipe.acquisition.metrics import (
    DEFAULT_ETA,
    DOWNDATE_TOL,
    ErrorModel,
    FactoredSelection,
    RowBlock,
    block_stats,
    check_eta,
    condition_number,
    condition_number_first_n,
    empty_stats,
    expected_error,
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
# factorisation (rebuilt from the blocks once per n and every
# _MAX_UPDATE_DEPTH updates).  A point candidate then costs O(k² + km)
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
# κ of every set are recomputed from scratch (summarise).  Deterministic for a
# seed (numpy Generator; single-threaded choice, fixed reduction order).

logger = logging.getLogger("brdfpipe.acquisition.optimize")

_REL_IMPROVE: float = 1e-12
_CELL_CACHE_MAX: int = 10_000 * 1024  # observed cells cached over all configurations (int32: ≤ ~40 MB at any grid)
_EVAL_CHUNK_ROWS: int = 4096  # distinct candidate rows gathered from Q at a time (≤ ~9 MB as float64)
_MAX_UPDATE_DEPTH: int = 32  # the current set's statistics are rebuilt after this many derivations
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


@dataclass
class _Block:
    """One configuration of the current set and its observation rows."""

    config: Config
    idx: NDArray[np.intp]  # (n_i,) model rows observed, with repeats
    rows: NDArray[np.float32]  # (n_i, k) = Q[idx]
    G: F64
    qsum: F64

    @property
    def n(self) -> int:
        return int(self.rows.shape[0])


def _emit(log: Callable[[str], Any] | logging.Logger | None, msg: str) -> None:
    if log is None:
        logger.info(msg)
    elif isinstance(log, logging.Logger):
        log.info(msg)
    else:
        log(msg)


def _better(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
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


def _load_q(Q: Any) -> NDArray[np.float32]:
    """The whole (p, k) matrix as a C-contiguous float32 array (read in row blocks)."""
    if isinstance(Q, np.ndarray):
        return np.ascontiguousarray(Q, dtype=np.float32)
    shape = tuple(int(s) for s in Q.shape)
    if len(shape) != 2:
        raise ValueError(f"model Q must be 2-D, got shape {shape}")
    out = np.empty(shape, dtype=np.float32)
    chunk = getattr(Q, "chunks", None)
    rows = max(int(chunk[0]), 1) if chunk else 1
    step = rows * max(_Q_READ_ROWS // rows, 1)  # whole chunks at a time
    for a in range(0, shape[0], step):
        b = min(a + step, shape[0])
        out[a:b] = np.asarray(Q[a:b], dtype=np.float32)
    return out


class _Optimizer:
    """State shared by the greedy add and the local search of one run."""

    def __init__(
        self,
        model: ModelLike,
        setup: Setup,
        metric: str,
        eta: float,
        beta: float,
        rng: np.random.Generator,
        log: Callable[[str], Any] | logging.Logger | None,
        evaluation: Literal["fast", "direct"] = "fast",
    ) -> None:
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
        self.setup = setup
        self.metric = metric
        self.rng = rng
        self.log = log
        self.em = ErrorModel(sigma, U, eta=eta, beta=beta)  # validates σ, U, η, β
        self.k = int(sigma.size)
        self.cells = cells
        self.lookup = np.full(merl.N_CELLS, -1, dtype=np.int32)
        self.lookup[cells] = np.arange(cells.size, dtype=np.int32)
        self.valid = self.lookup >= 0
        self.Q = _load_q(model.Q)
        self.fixed = bool(setup.spec.shared)
        self.axes: tuple[int, ...] = setup.spec.moves
        self.pinned: tuple[tuple[int, int], ...] = setup.spec.pinned
        if self.pinned and not self.fixed:
            raise ValueError(f"set-up {setup.kind}: pinned axes need a shared direction "
                             "(candidates drawn on the grid)")
        self.wrap = (False, False, setup.spec.wrap_phi)
        self._cache: dict[Config, NDArray[np.int32] | None] = {}
        self._cached_cells = 0
        self.evaluations = 0
        # "fast": candidates by low-rank updates where cheaper; "direct": each one afresh (reference).
        self.method: Literal["auto", "direct"] = "direct" if evaluation == "direct" else "auto"
        # The current set's configurations and factored statistics (see current()).
        self._current: tuple[tuple[Config, ...], FactoredSelection] | None = None
        # The last summarised set's fresh factorisation (see summarise).
        self._fresh: tuple[tuple[Config, ...], FactoredSelection] | None = None

    # -- configurations --------------------------------------------------

    def obs(self, config: Config) -> NDArray[np.int32] | None:
        """Observed cells of a configuration, or None if it is not valid for this model."""
        hit = self._cache.get(config, False)
        if hit is not False:
            return hit  # type: ignore[return-value]
        result: NDArray[np.int32] | None = None
        centre = int(centre_cells(self.setup, np.asarray([config]))[0])
        if self.valid[centre]:
            cells = observation_cells(self.setup, config, self.valid)
            if cells.size:
                result = cells.astype(np.int32)
        size = 1 if result is None else int(result.size)
        if self._cached_cells + size > _CELL_CACHE_MAX:
            self._cache.clear()
            self._cached_cells = 0
        self._cache[config] = result
        self._cached_cells += size
        return result

    def rows_of(self, cells: NDArray[np.int32]) -> NDArray[np.intp]:
        """Model rows (indices into Q) of observed cells."""
        return self.lookup[cells].astype(np.intp)

    def block(self, config: Config, idx: NDArray[np.intp]) -> _Block:
        rows = self.Q[idx]
        G, qsum = selection_stats(rows)
        return _Block(config, idx, rows, G, qsum)

    def row_block(self, idx: NDArray[np.intp], stats: tuple[F64, F64] | None = None) -> RowBlock:
        """The distinct rows of Q observed (``idx``, with repeats) and their counts."""
        if idx.size > 1:
            u, counts = np.unique(idx, return_counts=True)
            if u.size < idx.size:
                return RowBlock(self.Q[u], counts.astype(np.float64), stats)
        return RowBlock(self.Q[idx], None, stats)

    def shift(self, config: Config, axis: int, delta: int) -> Config | None:
        c = list(config)
        v = c[axis] + delta
        dim = CONFIG_DIMS[axis]
        if self.wrap[axis]:
            v %= dim
        elif not 0 <= v < dim:
            return None
        c[axis] = v
        if self.fixed and c[1] == 0:
            c[2] = 0  # the zenith has no azimuth (see the geometry section)
        return (c[0], c[1], c[2])

    def sample(self, t: int, exclude: set[Config], shared: int | None) -> list[Config]:
        """Up to ``t`` distinct random configurations with a model-column centre cell, not in ``exclude``."""
        out: list[Config] = []
        if not self.fixed:
            p = self.cells.size
            idx = self.rng.choice(p, size=min(p, t + len(exclude)), replace=False)
            for cell in self.cells[idx]:
                c = cell_config(int(cell))
                if c not in exclude:
                    out.append(c)
                    if len(out) == t:
                        break
            return out
        seen = set(exclude)
        for _ in range(64):
            batch = 4 * t
            ish = (self.rng.integers(0, CONFIG_DIMS[0], batch) if shared is None
                   else np.full(batch, shared, dtype=np.int64))
            it = self.rng.integers(0, CONFIG_DIMS[1], batch)
            ip = self.rng.integers(0, CONFIG_DIMS[2], batch)
            configs = np.stack([ish, it, ip], axis=1)
            for axis, value in self.pinned:
                configs[:, axis] = value
            ok = self.valid[centre_cells(self.setup, configs)] & ((it != 0) | (ip == 0))
            for row in configs[ok]:
                c = (int(row[0]), int(row[1]), int(row[2]))
                if c not in seen:
                    seen.add(c)
                    out.append(c)
                    if len(out) == t:
                        return out
        return out

    # -- metric ------------------------------------------------------------

    def key(self, G: F64, qsum: F64, nrows: int, parts: Callable[[], list[NDArray[np.float32]]]) -> tuple[float, ...]:
        """The metric of one selection evaluated afresh from its statistics (and rows, for κ)."""
        self.evaluations += 1
        E = expected_error(self.em, G, qsum)
        if self.metric == "error":
            return (E,)
        return (self.kappa(G, nrows, parts), E)

    def kappa(self, G: Callable[[], F64] | F64, nrows: int, parts: Callable[[], list[NDArray[np.float32]]]) -> float:
        """κ(Q̃) of the metric: from the rows when there are at most k, else from the Gram matrix ``G``."""
        if nrows <= self.k:
            rows = np.concatenate(parts(), axis=0)
            return condition_number_first_n(rows) if self.metric == "condition_nielsen" else condition_number(rows)
        return condition_number(G() if callable(G) else G, nrows)

    def evaluate(
        self, base: FactoredSelection, n0: int, base_parts: list[NDArray[np.float32]],
        cands: Sequence[NDArray[np.intp]], remove: _Block | None = None,
    ) -> list[tuple[float, ...]]:
        """Metric keys of ``base`` (less the block ``remove``) plus each candidate (model rows ``idx``).

        E(S) of all candidates at once by :meth:`FactoredSelection.candidate_errors`
        (low-rank updates of the base's factorisation where cheaper, the
        direct form otherwise), in chunks of ≤ _EVAL_CHUNK_ROWS distinct rows
        so that memory stays bounded; κ as in :meth:`kappa`.  ``n0`` and
        ``base_parts`` are the row count and rows without ``remove``.
        """
        self.evaluations += len(cands)
        rem = None if remove is None else self.row_block(remove.idx, (remove.G, remove.qsum))
        if self.metric == "error" and cands and all(idx.size == 1 for idx in cands):
            # Point candidates: one row each, passed as one (t, k) array (no per-candidate blocks).
            rows = self.Q[np.concatenate(cands)]
            out: list[tuple[float, ...]] = []
            for a in range(0, len(cands), _EVAL_CHUNK_ROWS):
                out += [(float(E),) for E in base.candidate_errors(rows[a:a + _EVAL_CHUNK_ROWS], remove=rem,
                                                                   method=self.method)]
            return out
        keys: list[tuple[float, ...]] = []
        start = 0
        while start < len(cands):
            blocks: list[RowBlock] = []
            rows = 0
            while start + len(blocks) < len(cands) and (not blocks or rows < _EVAL_CHUNK_ROWS):
                idx = cands[start + len(blocks)]
                b = self.row_block(idx)
                if self.metric != "error" and n0 + idx.size > self.k:
                    # κ needs the candidate's Gram matrix: computed once, also used for E when direct.
                    b = b._replace(stats=block_stats(b, self.k))
                blocks.append(b)
                rows += len(b.rows)
            errors = base.candidate_errors(blocks, remove=rem, method=self.method)
            for i, E in enumerate(errors):
                if self.metric == "error":
                    keys.append((float(E),))
                    continue
                idx, b = cands[start + i], blocks[i]

                def gram(b: RowBlock = b) -> F64:
                    assert b.stats is not None
                    G = base.G + b.stats[0]
                    return G if remove is None else G - remove.G

                kappa = self.kappa(gram, n0 + idx.size, lambda idx=idx: base_parts + [self.Q[idx]])
                keys.append((kappa, float(E)))
            start += len(blocks)
        return keys

    def current(self, blocks: Sequence[_Block]) -> FactoredSelection:
        """The current set's factored statistics: kept across steps, rebuilt from the blocks when stale."""
        configs = tuple(b.config for b in blocks)
        if self._current is None or self._current[0] != configs or self._current[1].depth >= _MAX_UPDATE_DEPTH:
            G, qsum, _ = self.totals(blocks)
            self._current = (configs, FactoredSelection(self.em, G, qsum))
        return self._current[1]

    def totals(self, blocks: Sequence[_Block]) -> tuple[F64, F64, int]:
        G, qsum = empty_stats(self.k)
        n = 0
        for b in blocks:
            G += b.G
            qsum += b.qsum
            n += b.n
        return G, qsum, n

    def fmt(self, key: tuple[float, ...]) -> str:
        if self.metric == "error":
            return f"E = {key[0]:.6g}"
        return f"κ = {key[0]:.6g} (E = {key[1]:.6g})"

    def describe(self, config: Config) -> str:
        names = self.setup.spec.axes
        inner = ", ".join(f"{n}={v}" for n, v in zip(names, config))
        if self.fixed:
            return f"({inner}; cell {int(centre_cells(self.setup, np.asarray([config]))[0])})"
        return f"({inner})"

    # -- search steps --------------------------------------------------------

    def greedy_add(self, blocks: list[_Block], t: int) -> tuple[tuple[float, ...], int]:
        # rebuilt from the blocks once per n (summarise's fresh factorisation): no rounding carried over
        configs_now = tuple(b.config for b in blocks)
        self._current = self._fresh if self._fresh is not None and self._fresh[0] == configs_now else None
        self._fresh = None
        base = self.current(blocks)
        n0 = sum(b.n for b in blocks)
        exclude = {b.config for b in blocks}
        shared = blocks[0].config[0] if (self.fixed and blocks) else None
        configs: list[Config] = []
        cands: list[NDArray[np.intp]] = []
        for cfg in self.sample(t, exclude, shared):
            cells = self.obs(cfg)
            if cells is not None:
                configs.append(cfg)
                cands.append(self.rows_of(cells))
        if not cands:
            raise ValueError(
                f"no valid {self.setup.kind} configuration left to add to a set of {len(blocks)} "
                "(the model's columns leave none)"
            )
        keys = self.evaluate(base, n0, [b.rows for b in blocks], cands)
        best = 0
        for i in range(1, len(keys)):
            if keys[i] < keys[best]:
                best = i
        new = self.block(configs[best], cands[best])
        blocks.append(new)
        self._current = (tuple(b.config for b in blocks),
                         base.updated(add=self.row_block(new.idx, (new.G, new.qsum))))
        return keys[best], len(cands)

    def move_single(
        self, blocks: list[_Block], j: int, s: int, current: tuple[float, ...]
    ) -> tuple[tuple[float, ...], list[_Block], str] | None:
        """Best improving move of configuration ``j`` by ±s (or the combined move), or None.

        All moves are evaluated against one base: the current set's
        factorisation, less block j by a downdate, when block j is weak
        enough for that to be accurate (``tr G_j ≤ η/DOWNDATE_TOL``: every
        point row of the default models), else the set without j built
        afresh from the other blocks (near-field images, strong rows).
        """
        old = blocks[j]
        remove: _Block | None = old
        if float(np.trace(old.G)) * DOWNDATE_TOL <= self.em.eta:
            base = self.current(blocks)
        else:
            G, qsum, _ = self.totals([b for i, b in enumerate(blocks) if i != j])
            base, remove = FactoredSelection(self.em, G, qsum), None
        n0 = sum(b.n for b in blocks) - old.n
        parts = [b.rows for i, b in enumerate(blocks) if i != j]
        taken = {b.config for i, b in enumerate(blocks) if i != j}
        cfg = old.config

        def valid(new: Config | None) -> NDArray[np.intp] | None:
            if new is None or new == cfg or new in taken:
                return None
            cells = self.obs(new)
            return None if cells is None else self.rows_of(cells)

        moves: list[tuple[tuple[int, int], Config, NDArray[np.intp]]] = []
        for axis in self.axes:
            for d in (1, -1):
                new = self.shift(cfg, axis, d * s)
                idx = valid(new)
                if idx is not None:
                    moves.append(((axis, d), new, idx))  # type: ignore[arg-type]
        keys = self.evaluate(base, n0, parts, [mv[2] for mv in moves], remove)
        results = {mv[0]: (key, mv[1], mv[2]) for mv, key in zip(moves, keys)}
        candidates = list(results.values())
        # The paper's gradient step: move along every axis that improves, at once.
        dirs: dict[int, int] = {}
        for axis in self.axes:
            opts = [(results[(axis, d)][0], d) for d in (1, -1) if (axis, d) in results]
            if opts:
                k_best, d_best = min(opts)
                if _better(k_best, current):
                    dirs[axis] = d_best
        if len(dirs) >= 2:
            new_c: Config | None = cfg
            for axis, d in dirs.items():
                new_c = self.shift(new_c, axis, d * s) if new_c is not None else None
            idx = valid(new_c)
            if idx is not None:
                key_c = self.evaluate(base, n0, parts, [idx], remove)[0]
                candidates.append((key_c, new_c, idx))  # type: ignore[arg-type]
        if not candidates:
            return None
        key, new_cfg, idx = min(candidates, key=lambda r: r[0])
        if not _better(key, current):
            return None
        new_blocks = list(blocks)
        new_blocks[j] = self.block(new_cfg, idx)
        nb = new_blocks[j]
        self._current = (tuple(b.config for b in new_blocks),
                         base.updated(add=self.row_block(nb.idx, (nb.G, nb.qsum)),
                                      remove=None if remove is None else self.row_block(old.idx, (old.G, old.qsum))))
        unit = self.setup.spec.unit
        return key, new_blocks, f"{unit} {j + 1} {self.describe(cfg)} -> {self.describe(new_cfg)}"

    def move_shared(
        self, blocks: list[_Block], s: int, current: tuple[float, ...]
    ) -> tuple[tuple[float, ...], list[_Block], str] | None:
        """Best improving ±s move of the shared elevation (fixed_*), or None."""
        best: tuple[tuple[float, ...], list[Config], list[NDArray[np.intp]]] | None = None
        for d in (1, -1):
            news = [self.shift(b.config, 0, d * s) for b in blocks]
            if any(c is None for c in news):
                continue
            idxs: list[NDArray[np.intp]] = []
            for c in news:
                cells = self.obs(c)  # type: ignore[arg-type]
                if cells is None:
                    break
                idxs.append(self.rows_of(cells))
            else:
                # Every image changes: evaluated afresh.
                parts = [self.Q[i] for i in idxs]
                G, q = selection_stats(np.concatenate(parts, axis=0))
                nrows = sum(p_.shape[0] for p_ in parts)
                key = self.key(G, q, nrows, lambda: parts)
                if best is None or key < best[0]:
                    best = (key, news, idxs)  # type: ignore[assignment]
        if best is None or not _better(best[0], current):
            return None
        new_blocks = [self.block(c, i) for c, i in zip(best[1], best[2])]
        name = self.setup.spec.axes[0]
        return best[0], new_blocks, f"shared {name} {blocks[0].config[0]} -> {best[1][0][0]}"

    def local_search(
        self, blocks: list[_Block], key: tuple[float, ...], steps: Sequence[int], n: int, held: int = 0
    ) -> tuple[list[_Block], tuple[float, ...], int]:
        """Moves of every configuration but the first ``held`` ones (and of the shared elevation when none is held)."""
        moves = 0
        for si, s in enumerate(steps):
            if si > 0:
                _emit(self.log, f"n={n} step {steps[si - 1]} -> {s}: {self.fmt(key)}")
            while True:
                units: list[int | None] = list(range(held, len(blocks))) + ([None] if self.fixed and not held else [])
                changed = False
                for ui in self.rng.permutation(len(units)):
                    unit = units[int(ui)]
                    res = (self.move_shared(blocks, s, key) if unit is None
                           else self.move_single(blocks, unit, s, key))
                    if res is None:
                        continue
                    key, blocks, what = res
                    moves += 1
                    changed = True
                    _emit(self.log, f"n={n} step {s}: move {what}: {self.fmt(key)}")
                if not changed:
                    break
        return blocks, key, moves

    def summarise(self, blocks: Sequence[_Block], greedy: tuple[float, ...], final: tuple[float, ...],
                  moves: int) -> DirectionSet:
        rows = np.concatenate([b.rows for b in blocks], axis=0)
        G, qsum = selection_stats(rows)
        configs = tuple(b.config for b in blocks)
        # E(S) from scratch (Cholesky of G + ηI, solve); the same fresh factorisation is the next
        # greedy add's base (no rounding carried over, one factorisation per n instead of two).
        fresh = FactoredSelection(self.em, G, qsum)
        self._fresh = (configs, fresh)
        return DirectionSet(
            n=len(blocks),
            configurations=configs,
            records=tuple(config_to_dict(self.setup, c) for c in configs),
            expected_error=fresh.error(),
            condition_number=condition_number(rows),
            n_observations=int(rows.shape[0]),
            greedy_value=float(greedy[0]),
            metric_value=float(final[0]),
            moves=moves,
        )


def _check_steps(steps: Sequence[int]) -> tuple[int, ...]:
    try:
        out = tuple(steps)
    except TypeError:
        raise ValueError(f"steps must be a sequence of positive integers, got {steps!r}") from None
    if not out or any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 1 for s in out):
        raise ValueError(f"steps must be a non-empty sequence of positive integers, got {steps!r}")
    return tuple(int(s) for s in out)


def _held_blocks(opt: _Optimizer, held: Sequence[Config]) -> list[_Block]:
    """The blocks of the configurations :func:`optimize` holds; ValueError for one it cannot hold."""
    blocks: list[_Block] = []
    for c in held:
        config_to_dict(opt.setup, c)  # checks it: three in-range grid indices
        config = (int(c[0]), int(c[1]), int(c[2]))
        if config in {b.config for b in blocks}:
            raise ValueError(f"held configuration {config} is given twice")
        off = [axis for axis, value in opt.pinned if config[axis] != value]
        if off:
            raise ValueError(f"held {opt.setup.kind} configuration {config} leaves its pinned axes {off}")
        if opt.fixed and blocks and config[0] != blocks[0].config[0]:
            raise ValueError(f"held {opt.setup.kind} configurations must share the elevation: {config} vs "
                             f"{blocks[0].config}")
        cells = opt.obs(config)
        if cells is None:
            raise ValueError(f"held configuration {config} observes no model column")
        blocks.append(opt.block(config, opt.rows_of(cells)))
    return blocks


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
    ErrorModel(np.ones(1), np.zeros((1, 1)), eta=eta, beta=beta)  # checks η and β before the model is read
    held = tuple(held)
    if len(held) >= int(n_max):
        raise ValueError(f"n_max = {n_max} leaves nothing to add to {len(held)} held configuration(s)")
    opt = _Optimizer(model, setup, metric, eta, beta, np.random.default_rng(seed), log, evaluation)
    blocks = _held_blocks(opt, held)
    _emit(log, f"optimise {setup.kind} fov {setup.fov_deg:g}° grid {setup.grid}, metric {metric}, "
               f"n = {len(held) + 1}..{n_max}, t = {candidates}, steps {step_list}, η = {opt.em.eta:g}, "
               f"β = {opt.em.beta:g}, seed {seed}; model p = {opt.cells.size}, k = {opt.k}, m = {opt.em.m}"
               + "".join(f"; held {opt.describe(b.config)}" for b in blocks))
    sets: list[DirectionSet] = []
    for n in range(len(held) + 1, int(n_max) + 1):
        t0 = time.perf_counter()
        evals0 = opt.evaluations
        greedy, tried = opt.greedy_add(blocks, int(candidates))
        _emit(log, f"n={n} greedy add: best of {tried} candidates {opt.describe(blocks[-1].config)}, "
                   f"{sum(b.n for b in blocks)} rows: {opt.fmt(greedy)} ({time.perf_counter() - t0:.1f} s)")
        blocks, final, moves = opt.local_search(blocks, greedy, step_list, n, len(held))
        result = opt.summarise(blocks, greedy, final, moves)
        sets.append(result)
        kappa = result.condition_number
        _emit(log, f"n={n} converged after {moves} moves: {opt.fmt(final)} (greedy {opt.fmt(greedy)}); "
                   f"E = {result.expected_error:.6g}, κ = {kappa:.6g}, {result.n_observations} rows, "
                   f"{time.perf_counter() - t0:.1f} s, {opt.evaluations - evals0} metric evaluations")
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
#              infinite), "n_observations": rows}, …]}


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
) -> Path:
    """Write :func:`optimize`'s sets as the directions JSON (format above), atomically.

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
) -> Path:
    """Optimise the direction sets of one setup on a PCA model and write them as JSON.

    The workflow's ``optimize_directions`` job: opens the model written by
    :func:`brdfpipe.acquisition.svd.write_model`, runs :func:`optimize` (one log line per
    step) and writes :func:`write_directions`'s JSON to ``out``; the split
    and database recorded are the model's.  ``threads``: the BLAS threads
    to use (the rule's declared threads; None leaves them as they are).
    """
    from brdfpipe.acquisition.svd import open_model

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
            eta=eta, beta=beta, seed=seed, log=log,
        )
    return write_directions(
        out, sets, setup=kind_setup, metric=metric, split=model.split,
        model_path=model_path, seed=seed, eta=eta, beta=beta, database=model.database,
    )
