"""The candidates of the direction search of :mod:`brdfpipe.acquisition.optimize`: where they lie, how they score.

:class:`CandidateSpace` is a set-up's configurations over a model's cells:
the model rows a configuration observes, its moves along the grid axes and
random draws of new ones.  :class:`Scorer` gives candidates' metric keys
against the current set, whose factorisation it carries from one accepted
move to the next by low-rank updates (:class:`FactoredSelection`).  The
search, its metrics and its cost are described in the section comment of
:mod:`~brdfpipe.acquisition.optimize`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from brdfpipe.data import merl
from brdfpipe.acquisition.geometry import CONFIG_DIMS, Config, Setup, cell_config, centre_cells, observation_cells
from brdfpipe.acquisition.metrics import (ErrorModel, FactoredSelection, RowBlock, block_stats, condition_number,
                                          condition_number_first_n, empty_stats, expected_error, selection_stats)

__all__ = ["Key", "Screen", "Block", "CandidateSpace", "Scorer"]

F64 = NDArray[np.float64]
#: A metric key: (E,) for the "error" metric, (κ, E) for the κ metrics (E breaks ties); smaller is better.
Key = tuple[float, ...]

_CELL_CACHE_MAX: int = 10_000 * 1024  # observed rows cached over all configurations (int32: ≤ ~40 MB at any grid)
_EVAL_CHUNK_ROWS: int = 4096  # distinct candidate rows gathered from Q at a time (≤ ~9 MB as float64)
_MAX_UPDATE_DEPTH: int = 32  # the current set's statistics are rebuilt after this many derivations


@dataclass(frozen=True)
class Screen:
    """Screening of the greedy add on a coarse lattice (ours, not the paper's: Xu §5.1 scores every candidate).

    The t random candidates are scored with the cells of a ``grid`` × ``grid``
    lattice, each row counted (full grid / ``grid``)² times so that E(S) is
    on the full lattice's scale; only the ``keep`` best are then scored at the
    full lattice, and the best of those is added.  Same draws, same local
    search.  For image set-ups and the E(S) metric, at a ``grid`` below the
    set-up's.  Not exact; measured against the exhaustive add on merl-nbrdf
    (docs/results/run-cost.md): the same sets in 12 of 12 runs at 128 and
    256 px, at 0.63× and 0.46× the CPU, and in 9 of a default run's 10
    optimisations (the tenth: its 5-image set, E(S) 0.066 % higher).
    """

    grid: int
    keep: int = 10

    def __post_init__(self) -> None:
        for name in ("grid", "keep"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"screen {name} must be a positive integer, got {v!r}")

    def applies(self, setup: Setup, metric: str) -> bool:
        """Whether it screens the greedy add of ``setup`` under ``metric`` (images, E(S), a coarser grid)."""
        return bool(setup.spec.images) and metric == "error" and self.grid < setup.grid


@dataclass
class Block:
    """One configuration of the current set and its observation rows."""

    config: Config
    idx: NDArray[np.intp]  # (n_i,) model rows observed, with repeats
    rows: NDArray[np.float32]  # (n_i, k) = Q[idx]
    G: F64
    qsum: F64

    @property
    def n(self) -> int:
        return int(self.rows.shape[0])


class CandidateSpace:
    """A set-up's configurations over a model's cells: the rows each observes, its moves, random draws.

    ``cells`` (p,) are the model's distinct MERL cells, one a row of Q; ``rng``
    draws the candidates (and the search's sweep orders).  A configuration is
    valid when its centre cell is a model column and it observes one.
    """

    def __init__(self, setup: Setup, cells: NDArray[np.int64], rng: np.random.Generator) -> None:
        self.setup = setup
        self.cells = cells
        self.rng = rng
        self.fixed = bool(setup.spec.shared)
        self.axes: tuple[int, ...] = setup.spec.moves
        self.pinned: tuple[tuple[int, int], ...] = setup.spec.pinned
        if self.pinned and not self.fixed:
            raise ValueError(f"set-up {setup.kind}: pinned axes need a shared direction "
                             "(candidates drawn on the grid)")
        self._wrap = (False, False, setup.spec.wrap_phi)
        self._lookup = np.full(merl.N_CELLS, -1, dtype=np.int32)
        self._lookup[cells] = np.arange(cells.size, dtype=np.int32)
        self._valid = self._lookup >= 0
        self._cache: dict[Config, NDArray[np.int32] | None] = {}
        self._cached = 0

    def rows(self, config: Config) -> NDArray[np.intp] | None:
        """Model rows (indices into Q, with repeats) a configuration observes, or None if it is not valid."""
        if config not in self._cache:
            found: NDArray[np.int32] | None = None
            if self._valid[int(centre_cells(self.setup, np.asarray([config]))[0])]:
                cells = observation_cells(self.setup, config, self._valid)
                if cells.size:
                    found = self._lookup[cells]
            size = 1 if found is None else int(found.size)
            if self._cached + size > _CELL_CACHE_MAX:
                self._cache.clear()
                self._cached = 0
            self._cache[config] = found
            self._cached += size
        hit = self._cache[config]
        return None if hit is None else hit.astype(np.intp)

    def shift(self, config: Config, axis: int, delta: int) -> Config | None:
        """``config`` moved by ``delta`` grid units along ``axis``, or None off a bounded axis."""
        c = list(config)
        v = c[axis] + delta
        dim = CONFIG_DIMS[axis]
        if self._wrap[axis]:
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
            ok = self._valid[centre_cells(self.setup, configs)] & ((it != 0) | (ip == 0))
            for row in configs[ok]:
                c = (int(row[0]), int(row[1]), int(row[2]))
                if c not in seen:
                    seen.add(c)
                    out.append(c)
                    if len(out) == t:
                        return out
        return out

    def describe(self, config: Config) -> str:
        """A configuration as the log shows it: its named axes (and centre cell, for fixed_*)."""
        inner = ", ".join(f"{n}={v}" for n, v in zip(self.setup.spec.axes, config))
        if self.fixed:
            return f"({inner}; cell {int(centre_cells(self.setup, np.asarray([config]))[0])})"
        return f"({inner})"


class Scorer:
    """Metric keys of candidate sets, scored against the current set's factorisation.

    ``metric`` is one of the optimiser's; ``Q`` the model's (p, k) rows;
    ``evaluation`` "fast" (low-rank updates where cheaper) or "direct" (each
    candidate afresh, the reference).  ``evaluations`` counts the keys computed.
    """

    def __init__(self, em: ErrorModel, metric: str, Q: NDArray[np.float32],
                 evaluation: Literal["fast", "direct"]) -> None:
        self.em = em
        self.metric = metric
        self.Q = Q
        self.k = em.k
        self.evaluations = 0
        self._method: Literal["auto", "direct"] = "direct" if evaluation == "direct" else "auto"
        # The current set's configurations and factored statistics (see current()).
        self._current: tuple[tuple[Config, ...], FactoredSelection] | None = None

    def block(self, config: Config, idx: NDArray[np.intp]) -> Block:
        """The block of ``config``, which observes the model rows ``idx``."""
        rows = self.Q[idx]
        G, qsum = selection_stats(rows)
        return Block(config, idx, rows, G, qsum)

    def afresh(self, blocks: Sequence[Block]) -> FactoredSelection:
        """The set of ``blocks`` factored from their summed statistics."""
        G, qsum = empty_stats(self.k)
        for b in blocks:
            G += b.G
            qsum += b.qsum
        return FactoredSelection(self.em, G, qsum)

    def current(self, blocks: Sequence[Block]) -> FactoredSelection:
        """The current set's factorisation: kept across steps, rebuilt from the blocks when stale."""
        configs = tuple(b.config for b in blocks)
        if self._current is None or self._current[0] != configs or self._current[1].depth >= _MAX_UPDATE_DEPTH:
            self._current = (configs, self.afresh(blocks))
        return self._current[1]

    def set_current(self, blocks: Sequence[Block], selection: FactoredSelection) -> None:
        """Make ``selection`` the factorisation of the current set ``blocks``."""
        self._current = (tuple(b.config for b in blocks), selection)

    def accept(self, blocks: Sequence[Block], base: FactoredSelection, add: Block, remove: Block | None = None) -> None:
        """Make ``blocks`` the current set: ``base`` with ``add`` added (and ``remove`` removed), updated."""
        rem = None if remove is None else self._rows(remove)
        self.set_current(blocks, base.updated(add=self._rows(add), remove=rem))

    def key(self, idxs: Sequence[NDArray[np.intp]]) -> Key:
        """The key of the set observing the model rows ``idxs`` (one array a configuration), afresh."""
        parts = [self.Q[i] for i in idxs]
        G, qsum = selection_stats(np.concatenate(parts, axis=0))
        self.evaluations += 1
        E = expected_error(self.em, G, qsum)
        if self.metric == "error":
            return (E,)
        return (self._kappa(G, sum(p.shape[0] for p in parts), lambda: parts), E)

    def evaluate(self, base: FactoredSelection, others: Sequence[Block], cands: Sequence[NDArray[np.intp]],
                 remove: Block | None = None, weight: float = 1.0) -> list[Key]:
        """Keys of the set ``others`` plus each candidate (model rows ``idx``).

        ``weight``: each candidate row counts this many times (a coarse
        lattice's rows standing for a full lattice's pixels, :class:`Screen`).

        ``base`` is the factorisation of ``others`` (and of ``remove``, when
        given, which is downdated).  E(S) of all candidates at once by
        :meth:`FactoredSelection.candidate_errors`, in chunks of ≤
        _EVAL_CHUNK_ROWS distinct rows so that memory stays bounded; κ from
        the rows while there are at most k, else from the Gram matrix.
        """
        self.evaluations += len(cands)
        rem = None if remove is None else self._rows(remove)
        if self.metric == "error" and cands and all(idx.size == 1 for idx in cands):
            # Point candidates: one row each, passed as one (t, k) array (no per-candidate blocks).
            rows = self.Q[np.concatenate(cands)]
            return [(float(E),) for a in range(0, len(cands), _EVAL_CHUNK_ROWS)
                    for E in base.candidate_errors(rows[a:a + _EVAL_CHUNK_ROWS], remove=rem, method=self._method)]
        n0 = sum(o.n for o in others)
        parts = [o.rows for o in others]
        keys: list[Key] = []
        start = 0
        while start < len(cands):
            blocks: list[RowBlock] = []
            nrows = 0
            while start + len(blocks) < len(cands) and (not blocks or nrows < _EVAL_CHUNK_ROWS):
                idx = cands[start + len(blocks)]
                b = self._row_block(idx, weight=weight)
                if self.metric != "error" and n0 + idx.size > self.k:
                    # κ needs the candidate's Gram matrix: computed once, also used for E when direct.
                    b = b._replace(stats=block_stats(b, self.k))
                blocks.append(b)
                nrows += len(b.rows)
            errors = base.candidate_errors(blocks, remove=rem, method=self._method)
            for i, E in enumerate(errors):
                if self.metric == "error":
                    keys.append((float(E),))
                    continue
                idx, b = cands[start + i], blocks[i]

                def gram(b: RowBlock = b) -> F64:
                    assert b.stats is not None
                    G = base.G + b.stats[0]
                    return G if remove is None else G - remove.G

                kappa = self._kappa(gram, n0 + idx.size, lambda idx=idx: parts + [self.Q[idx]])
                keys.append((kappa, float(E)))
            start += len(blocks)
        return keys

    def fmt(self, key: Key) -> str:
        """A key as the log shows it."""
        if self.metric == "error":
            return f"E = {key[0]:.6g}"
        return f"κ = {key[0]:.6g} (E = {key[1]:.6g})"

    def _kappa(self, G: Callable[[], F64] | F64, nrows: int, parts: Callable[[], list[NDArray[np.float32]]]) -> float:
        """κ(Q̃) of the metric: from the rows when there are at most k, else from the Gram matrix ``G``."""
        if nrows <= self.k:
            rows = np.concatenate(parts(), axis=0)
            return condition_number_first_n(rows) if self.metric == "condition_nielsen" else condition_number(rows)
        return condition_number(G() if callable(G) else G, nrows)

    def _rows(self, b: Block) -> RowBlock:
        return self._row_block(b.idx, (b.G, b.qsum))

    def _row_block(self, idx: NDArray[np.intp], stats: tuple[F64, F64] | None = None,
                   weight: float = 1.0) -> RowBlock:
        """The distinct rows of Q observed (``idx``, with repeats) and their counts (× ``weight``)."""
        if idx.size > 1:
            u, counts = np.unique(idx, return_counts=True)
            if u.size < idx.size or weight != 1.0:
                return RowBlock(self.Q[u], counts.astype(np.float64) * weight, stats)
        return RowBlock(self.Q[idx], None if weight == 1.0 else np.full(idx.size, float(weight)), stats)
