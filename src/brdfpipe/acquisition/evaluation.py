"""Leave-out evaluation of direction sets on held-out materials (Xu et al. 2016, issue §6).

The workflow's evaluation stage (rules ``evaluate_directions``,
``check_directions`` and ``evaluate_training_size``), built on a PCA model
(:func:`brdfpipe.acquisition.svd.open_model`: ``Q = VΣ`` (p × k), mean μ,
and the log-relative mapping's reference ρ_ref and weight w at the model's p
columns = MERL cells) and reconstructing by eq. 4 as
:mod:`brdfpipe.acquisition.reconstruct` does for one material.  The closed
loop (:mod:`brdfpipe.acquisition.closedloop`) and the unseen materials
(:mod:`brdfpipe.acquisition.unseen`) write their tables (the columns of
``errors.csv``; ``unseen.csv`` adds ``model_database``) with
:func:`write_errors` and name the channels by :data:`CHANNELS`.

Leave-out evaluation
--------------------
:func:`evaluate` reconstructs the held-out material-channels (rows of the
store, log-mapped with the *train* model's ρ_ref and w) from simulated
acquisitions: for every directions file (setup, fov, metric; optimised on the
``train`` split) and every n, the observations are the values at
:func:`brdfpipe.acquisition.geometry.observation_cells` of the set's configurations
(pixels on cells that are not model columns dropped, repeated cells
repeated), c̄ by eq. 4 and x̂ = μ + Q c̄.  Reported per material-channel and as
the mean over them (material ``mean``, channel ``all``):

* ``rms_log`` = ‖x − x̂‖/√p, the RMS error in log-mapped space (the papers'
  measure);
* ``relrms_linear`` = ‖(ρ̂ − ρ)·cos θi·cos θo‖ / ‖ρ·cos θi·cos θo‖ over the
  model's columns (cell-centre cosines; ρ̂ clamped ≥ 0), the relative RMS of
  the cosine-weighted BRDF in linear space;
* ``deviation`` = ‖(I − VVᵀ) y‖/√p (eq. 9): the floor with every cell
  observed (y = x − μ); rows with setup ``all``, fov 0, metric ``none``, n 0.

How it is computed (no p-vector per (set, material) is ever formed at once):

1. one streamed pass over the model's columns (Q chunk by chunk, the store's
   held-out rows block by block, each decoded once, read ahead in a thread)
   accumulates QᵀQ (k × k), QᵀY (k × m_t), ‖y_i‖² and keeps Y and Q at the
   union of all observed columns;
2. c̄ for every (set, row) from the kept columns (k × k solves), and the
   log-space errors by the Gram identity
   ‖y − Qc̄‖² = ‖y‖² − 2c̄ᵀQᵀy + c̄ᵀ(QᵀQ)c̄; the deviation floor is
   ‖y‖² − (Qᵀy)ᵀ(QᵀQ)⁻¹(Qᵀy) (the stored Q's own Gram matrix is used, so the
   numbers are those of an explicit least-squares projection on the stored Q);
3. a second pass for the linear error: per row block of Q, x̂ for all
   (set × row) coefficient columns at once (one GEMM), mapped back and
   compared in place, in sub-blocks of :data:`_SUB_ROWS` rows.  The product
   Q c̄ is taken in float32 (sgemm, ~2.5× faster than dgemm here), the rest
   in float64: this moves ``relrms_linear`` by < 1e-6 relative (7.5e-7 at
   most on the default store against an all-float64 pass); the log-space
   numbers are all float64.

Precision: on the default synthetic store (k = 269) the Gram identity agrees
with explicitly formed float64 residuals to 6e-13 (``rms_log``) and 3e-11
(``deviation``) relative.

Cost: ``docs/results/acquisition.md`` (measured on the default synthetic store).

Consistency check (:func:`check_consistency`): for every directions set the
expected error E(S) recorded in the JSON is recomputed directly from the
training log-map rows: each row is reconstructed from its own observations
(eq. 4, the file's η) and ‖y_i − Q c̄_i‖ measured, by the same Gram identity
with QᵀY of the training rows from one streamed pass (nothing assumes
y_i = Q u_i); plus β‖Q(Q̃ᵀQ̃ + ηI)⁻¹Q̃ᵀ1‖ if the file's β > 0.  Writes
``consistency.csv`` and raises :class:`ConsistencyError` if any relative
difference exceeds 1e-6.

Error vs number of training materials (:func:`training_size_curve`, Xu Fig. 7):
the training materials in a seeded random order; for each size N the PCA of
the first N materials' 3N rows, and the held-out rows reconstructed from one
directions set (default: the 2-image near-field 25° error-metric set).  One
streamed pass accumulates X Xᵀ and X Y_testᵀ of the training and test rows,
the row sums, and both at the observed columns (the *cross-Gram trick*); then
for each N, with G_N the rows' Gram block, (U, σ) = svd.decompose(G_N)
(exactly as :func:`brdfpipe.acquisition.svd.fit` does), A = C U, Q_N = X_Nᵀ A and
μ_N = X_Nᵀ 1/m: Q̃_N, μ̃_N come from the observed columns, QᵀQ = AᵀG_N A,
Qᵀy = Aᵀ(X_N x − G_N 1/m) and ‖y‖² = ‖x‖² − 2·1ᵀX_N x/m + 1ᵀG_N 1/m² — no
p-space pass per N.  Two documented approximations: every N uses the
``train`` log-mapping (ρ_ref = median of *all* training materials, not of the
first N), and the directions optimised for the full ``train`` model (not
re-optimised per N).

Output files (tidy CSV, written atomically; one workflow job each)
------------------------------------------------------------------
:func:`write_evaluation`, :func:`check_consistency` and
:func:`write_training_size` each write one file, at the path the caller gives:

* ``errors.csv``: ``database,split,setup,fov,metric,n,material,channel,kind,value``
  (channel R, G, B; ``mean`` / ``all`` rows average the material-channels);
* ``consistency-{split}.csv``: ``setup,fov,metric,n,predicted,direct,rel_diff``;
* ``training_size.csv``: ``database,n_train,order_seed,material,channel,kind,value``
  (kind ``rms_log``, plus ``mean`` / ``all`` rows).

Floats are written with Python's shortest round-trip repr.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import os
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from brdfpipe.acquisition import geometry, metrics, svd
from brdfpipe.acquisition.metrics import DEFAULT_ETA, reconstruct_coefficients
from brdfpipe.acquisition.optimize import Directions, read_directions
from brdfpipe.acquisition.reconstruct import as_model, column_lookup, q_chunks
from brdfpipe.acquisition.svd import Model
from brdfpipe.core import integrity
from brdfpipe.data import logmap, merl
from brdfpipe.data.logmap import Logmap, open_logmap
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import BrdfStore, material_indices, open_store, read_ahead, row_runs
from brdfpipe.data.store import CHUNK_COLS
from brdfpipe.registry import tables

__all__ = [
    "CHANNELS",
    "CONSISTENCY_COLUMNS",
    "DEFAULT_SIZES",
    "CONSISTENCY_RTOL",
    "ConsistencyError",
    "evaluate",
    "evaluate_selections",
    "RowStatistics",
    "row_statistics",
    "check_consistency",
    "training_size_curve",
    "write_errors",
    "write_evaluation",
    "write_training_size",
]

logger = logging.getLogger("brdfpipe.acquisition.evaluation")

F64 = NDArray[np.float64]

#: Channel names of the rows 3·i + c.
CHANNELS: Final = ("R", "G", "B")
#: Columns of ``consistency.csv``.
CONSISTENCY_COLUMNS: Final = ("setup", "fov", "metric", "n", "predicted", "direct", "rel_diff")
#: Default training-set sizes of the training-size curve (capped at the number of training materials).
DEFAULT_SIZES: Final = (10, 20, 30, 40, 50, 60, 70, 80, 90)
#: Largest accepted relative difference between recorded and recomputed E(S).
CONSISTENCY_RTOL: Final = 1e-6

#: Rows of Q per sub-block in the linear-error pass (bounds the (rows × sets·materials) work array).
_SUB_ROWS: Final = 1024
#: Seconds between progress lines in the streamed passes.
_PROGRESS_S: Final = 10.0


class ConsistencyError(ValueError):
    """A directions file's recorded E(S) disagrees with the direct recomputation."""


# ==========================================================================
# Streaming helpers
# ==========================================================================


class _StoreColumns:
    """Values of some store rows at the model's columns, served by column range in increasing order.

    Each 145,800-cell store chunk is decoded once (the latest is cached).
    ``get(a, b)`` returns float32 ``(len(rows), 3, b − a)`` in the order of
    ``rows`` given.
    """

    def __init__(self, st: BrdfStore, rows: ArrayLike, cells: NDArray[np.integer[Any]]) -> None:
        idx = np.asarray(rows, dtype=np.intp)
        self.st = st
        self.order = np.argsort(idx, kind="stable")
        self.sorted = idx[self.order]
        self.inverse = np.empty_like(self.order)
        self.inverse[self.order] = np.arange(idx.size)
        self.identity = bool(np.array_equal(self.order, np.arange(idx.size)))
        self.runs = row_runs(self.sorted)
        self.cells = np.asarray(cells, dtype=np.int64)
        self._start = -1
        self._data: NDArray[np.float32] | None = None

    def _block(self, start: int) -> NDArray[np.float32]:
        if start != self._start or self._data is None:
            stop = min(start + CHUNK_COLS, N_CELLS)
            raw = np.empty((self.sorted.size, 3, stop - start), dtype=np.float32)
            for c in range(3):
                k = 0
                for r0, r1 in self.runs:
                    raw[k : k + r1 - r0, c] = self.st.brdf[r0:r1, c * N_CELLS + start : c * N_CELLS + stop]
                    k += r1 - r0
            self._start, self._data = start, raw
        return self._data

    def get(self, a: int, b: int) -> NDArray[np.float32]:
        cells = self.cells[a:b]
        out = np.empty((self.sorted.size, 3, b - a), dtype=np.float32)
        j = 0
        while j < cells.size:
            start = int(cells[j]) // CHUNK_COLS * CHUNK_COLS
            j1 = int(np.searchsorted(cells, start + CHUNK_COLS))
            out[:, :, j:j1] = self._block(start)[:, :, cells[j:j1] - start]
            j = j1
        return out if self.identity else out[self.inverse]


class _Progress:
    """A progress line every :data:`_PROGRESS_S` seconds (and at the end) of a pass over p columns."""

    def __init__(self, what: str, p: int) -> None:
        self.what, self.p = what, p
        self.t0 = self.last = time.perf_counter()

    def step(self, done: int) -> None:
        now = time.perf_counter()
        if done >= self.p or now - self.last >= _PROGRESS_S:
            self.last = now
            logger.info("%s: %d/%d columns (%.0f%%), %.1f s", self.what, done, self.p, 100.0 * done / self.p,
                        now - self.t0)


def _material_rows(st: BrdfStore, names: Sequence[str], what: str) -> NDArray[np.intp]:
    return material_indices(st, names, what)


def _check_columns(st: BrdfStore, mdl: Model) -> None:
    valid = np.asarray(st.valid[:], dtype=bool)
    if not valid[mdl.cells].all():
        n = int((~valid[mdl.cells]).sum())
        raise ValueError(f"{mdl.path}: {n} model column(s) are cells not measured in every material of {st.path}; "
                         f"the model was fitted to another store")


def _test_materials(st: BrdfStore, train: Sequence[str], test_materials: Sequence[str] | None) -> list[str]:
    if test_materials is None:
        names = [m for m in st.materials if m not in set(train)]
        if not names:
            raise ValueError(f"{st.path}: every material is a training material; nothing is held out")
        return names
    names = list(test_materials)
    clash = [m for m in names if m in set(train)]
    if clash:
        raise ValueError(f"test material(s) {', '.join(clash)} are training materials of the model; "
                         f"the evaluation needs held-out materials")
    _material_rows(st, names, "test_materials")  # unknown / duplicate names
    return names


def _fov(value: float) -> float | int:
    return int(value) if float(value).is_integer() else float(value)


# ==========================================================================
# Direction sets
# ==========================================================================


@dataclass(frozen=True, eq=False)
class _Combo:
    """One direction set of one file: its tags, its observed model columns (with repeats) and its recorded E."""

    path: Path
    setup: str
    fov: float | int
    metric: str
    n: int
    rows: NDArray[np.intp]
    predicted: float
    eta: float
    beta: float


def _check_directions(path: Path, d: Directions, mdl: Model) -> None:
    if d.split != mdl.split:
        raise ValueError(f"{path}: directions were optimised on split {d.split!r}, the model {mdl.path} is of "
                         f"split {mdl.split!r}")
    if d.database != mdl.database:
        raise ValueError(f"{path}: directions are of database {d.database!r}, the model {mdl.path} of "
                         f"{mdl.database!r}")
    if d.model and Path(d.model).resolve() != Path(mdl.path).resolve():
        logger.warning("%s: directions were optimised with model %s, evaluated with %s", path, d.model, mdl.path)


def _combos(paths: Sequence[str | os.PathLike[str]], mdl: Model) -> list[_Combo]:
    """Every set of every directions file, with its observed model columns (cells off the model dropped)."""
    lut = column_lookup(mdl.cells)
    valid = lut >= 0
    out: list[_Combo] = []
    seen: dict[tuple[str, float, str, int], Path] = {}
    for p in paths:
        path = Path(p)
        d = read_directions(path)
        _check_directions(path, d, mdl)
        fov = _fov(d.setup.fov_deg)
        for s in d.sets:
            key = (d.setup.kind, float(fov), d.metric, s.n)
            if key in seen:
                raise ValueError(f"{path}: set {key} also comes from {seen[key]}; give each (setup, fov, metric) once")
            seen[key] = path
            parts = [geometry.observation_cells(d.setup, c, valid) for c in s.configurations]
            cells = np.concatenate(parts) if parts else np.zeros(0, dtype=np.intp)
            out.append(_Combo(path, d.setup.kind, fov, d.metric, s.n, lut[cells], s.expected_error, d.eta, d.beta))
    return out


class _Gathered:
    """Columns of a matrix kept at a set of model columns while streaming (sorted unique ``cols``)."""

    def __init__(self, cols: NDArray[np.intp]) -> None:
        self.cols = np.unique(cols)

    def take(self, a: int, b: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """(positions in ``cols``, offsets in [0, b − a)) of the kept columns inside [a, b)."""
        i0, i1 = np.searchsorted(self.cols, [a, b])
        return np.arange(i0, i1), self.cols[i0:i1] - a

    def pos(self, rows: NDArray[np.intp]) -> NDArray[np.intp]:
        return np.searchsorted(self.cols, rows)


def _sq_err(yy: F64, qty: F64, qtq: F64, coef: F64) -> F64:
    """‖y − Q c̄‖² of each column: ‖y‖² − 2c̄ᵀQᵀy + c̄ᵀ(QᵀQ)c̄, clamped at 0."""
    e = yy - 2.0 * np.einsum("kj,kj->j", coef, qty) + np.einsum("kj,kj->j", coef, qtq @ coef)
    return np.maximum(e, 0.0)


# ==========================================================================
# Leave-out evaluation
# ==========================================================================


def _gram_pass(
    mdl: Model,
    keep: _Gathered,
    residuals: Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float64]]],
    m: int,
    label: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """One streamed pass over Q with the residual rows y (m × block) of every column block.

    Returns QᵀQ (k × k, symmetrised), QᵀY (k × m), ‖y‖² per row, and Q and Y
    at the observed columns ``keep`` — everything the Gram identity
    ‖y − Qc‖² = ‖y‖² − 2cᵀQᵀy + cᵀQᵀQc needs.  Blocks are produced one ahead
    in a thread (:func:`brdfpipe.data.store.read_ahead`).
    """
    k = mdl.k
    qtq = np.zeros((k, k))
    qty = np.zeros((k, m))
    yy = np.zeros(m)
    q_obs = np.empty((keep.cols.size, k))
    y_obs = np.empty((m, keep.cols.size))
    prog = _Progress(label, mdl.p)
    for a, b, q32, y in read_ahead(residuals):
        q = q32.astype(np.float64)
        qtq += q.T @ q
        qty += q.T @ y.T
        yy += np.einsum("ij,ij->i", y, y)
        pos, off = keep.take(a, b)
        q_obs[pos] = q[off]
        y_obs[:, pos] = y[:, off]
        prog.step(b)
    return 0.5 * (qtq + qtq.T), qty, yy, q_obs, y_obs


def evaluate(
    store_path: BrdfStore | str | os.PathLike[str],
    model_path: Model | str | os.PathLike[str],
    directions_paths: Sequence[str | os.PathLike[str]],
    *,
    test_materials: Sequence[str] | None,
    eta: float = DEFAULT_ETA,
    linear: bool = True,
) -> list[dict[str, Any]]:
    """Reconstruction errors of the held-out material-channels for every set of every directions file.

    Parameters
    ----------
    store_path:
        The store holding the held-out materials (the one the model's log-map was made from).
    model_path:
        The PCA model of the training split (ρ_ref, w, μ, Q).
    directions_paths:
        Directions files (:func:`brdfpipe.acquisition.optimize.write_directions`) of the
        model's split and database; each (setup, fov, metric) once.  The
        observations of a set are :func:`brdfpipe.acquisition.geometry.observation_cells`
        of its configurations with the model's columns as the valid cells.
    test_materials:
        The held-out materials (None: the store's materials that are not
        training materials of the model).  Must not be training materials.
    eta:
        η of eq. 4 for the reconstructions.
    linear:
        Also compute ``relrms_linear`` (the second pass over Q); False skips it.

    Returns
    -------
    list of dict
        Rows with keys :data:`~brdfpipe.registry.tables.ERRORS` (see the module docstring),
        ready for :func:`write_errors`.
    """
    mdl = as_model(model_path)
    combos = _combos(directions_paths, mdl)
    logger.info("%d direction sets from %d files", len(combos), len(directions_paths))
    return _evaluate(store_path, mdl, combos, test_materials, eta, linear)


def evaluate_selections(
    store_path: BrdfStore | str | os.PathLike[str],
    model_path: Model | str | os.PathLike[str],
    selections: Sequence[tuple[dict[str, Any], ArrayLike]],
    *,
    test_materials: Sequence[str] | None,
    eta: float = DEFAULT_ETA,
    linear: bool = True,
) -> list[dict[str, Any]]:
    """:func:`evaluate` for explicit selections: ``(label, cells)`` pairs.

    ``label`` holds the ``setup``, ``fov``, ``metric`` and ``n`` written to
    the rows; ``cells`` are the observed MERL cells (repeats = repeated
    observations; cells that are not model columns are dropped).
    """
    mdl = as_model(model_path)
    lut = column_lookup(mdl.cells)
    combos = []
    for label, cells in selections:
        c = np.asarray(cells, dtype=np.intp).ravel()
        if c.size and (c.min() < 0 or c.max() >= N_CELLS):
            raise ValueError(f"selection {label}: cells must lie in [0, {N_CELLS})")
        r = lut[c]
        combos.append(_Combo(Path("."), str(label["setup"]), _fov(label["fov"]), str(label["metric"]),
                             int(label["n"]), r[r >= 0], math.nan, DEFAULT_ETA, 0.0))
    return _evaluate(store_path, mdl, combos, test_materials, eta, linear)


def _evaluate(
    store_path: BrdfStore | str | os.PathLike[str],
    mdl: Model,
    combos: Sequence[_Combo],
    test_materials: Sequence[str] | None,
    eta: float,
    linear: bool,
) -> list[dict[str, Any]]:
    eta = metrics.check_eta(eta)
    t0 = time.perf_counter()
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    if st.database != mdl.database:
        raise ValueError(f"{st.path} is database {st.database!r}, the model {mdl.path} {mdl.database!r}")
    _check_columns(st, mdl)
    names = _test_materials(st, mdl.train_materials, test_materials)
    if not combos:
        raise ValueError("no direction sets to evaluate")
    n_combo = len(combos)
    p, k, m_t = mdl.p, mdl.k, 3 * len(names)
    logger.info("evaluating %d selections on %d held-out rows (%d materials); p = %d, k = %d, η = %g",
                n_combo, m_t, len(names), p, k, eta)
    reader = _StoreColumns(st, _material_rows(st, names, "test_materials"), mdl.cells)
    keep = _Gathered(np.concatenate([c.rows for c in combos]))

    # Pass 1: QᵀQ, QᵀY, ‖y‖², and Y, Q at the observed columns.
    def residuals() -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float64]]]:
        for a, b in q_chunks(mdl):
            rho = reader.get(a, b).reshape(m_t, b - a)
            y = logmap.forward(rho, mdl.reference[a:b], mdl.weight[a:b], mdl.epsilon)
            yield a, b, np.asarray(mdl.Q[a:b], dtype=np.float32), y - mdl.mean[a:b]

    qtq, qty, yy, q_obs, y_obs = _gram_pass(mdl, keep, residuals(), m_t, "evaluation pass 1 (Gram statistics)")

    # Coefficients of every (selection, row); log-space errors by the Gram identity.
    coefs = np.zeros((k, n_combo * m_t))
    for ci, c in enumerate(combos):
        pos = keep.pos(c.rows)
        if pos.size:
            coefs[:, ci * m_t : (ci + 1) * m_t] = reconstruct_coefficients(q_obs[pos], y_obs[:, pos].T, eta)
        else:
            logger.warning("%s %g %s n=%d observes no model column: reconstruction = mean",
                           c.setup, c.fov, c.metric, c.n)
    sq = _sq_err(np.tile(yy, n_combo), np.tile(qty, (1, n_combo)), qtq, coefs)
    rms_log = np.sqrt(sq / p).reshape(n_combo, m_t)
    proj = scipy.linalg.solve(qtq, qty, assume_a="pos")
    deviation = np.sqrt(np.maximum(yy - np.einsum("kj,kj->j", qty, proj), 0.0) / p)

    # Pass 2: the linear-space error, all (selection × row) columns per block of Q.
    rel_lin = _linear_errors(mdl, reader, coefs, n_combo, m_t) if linear else None

    rows: list[dict[str, Any]] = []
    base = {"database": mdl.database, "split": mdl.split}
    labels = [(mat, CHANNELS[ch]) for mat in names for ch in range(3)]

    def emit(setup: str, fov: float | int, metric: str, n: int, kind: str, values: F64) -> None:
        for (mat, ch), v in zip(labels, values):
            rows.append({**base, "setup": setup, "fov": fov, "metric": metric, "n": n, "material": mat,
                         "channel": ch, "kind": kind, "value": float(v)})
        rows.append({**base, "setup": setup, "fov": fov, "metric": metric, "n": n, "material": "mean",
                     "channel": "all", "kind": kind, "value": float(np.mean(values))})

    emit("all", 0, "none", 0, "deviation", deviation)
    for ci, c in enumerate(combos):
        emit(c.setup, c.fov, c.metric, c.n, "rms_log", rms_log[ci])
        if rel_lin is not None:
            emit(c.setup, c.fov, c.metric, c.n, "relrms_linear", rel_lin[ci])
    logger.info("evaluation done in %.1f s: %d rows; mean deviation floor (rms_log) %.4g",
                time.perf_counter() - t0, len(rows), float(deviation.mean()))
    return rows


def _linear_errors(mdl: Model, reader: _StoreColumns, coefs: F64, n_combo: int, m_t: int) -> F64:
    """relrms_linear (n_combo, m_t): ‖(ρ̂ − ρ)·cc‖/‖ρ·cc‖ with ρ̂ = max(inverse(μ + Q c̄), 0)."""
    wi, wo = merl.cell_directions(mdl.cells)
    cc = wi[:, 2] * wo[:, 2]
    # With e = exp(x̂)·(ρ_ref·w + ε) and s = cc/w:  ρ̂·cc = max(e − ε, 0)·s = max(e·s, ε·s) − ε·s, and
    # e·s = exp(Q c̄ + μ + ln(ρ_ref·w + ε) + ln s).  So per value: one exp, one max, one subtraction
    # of K = ε·s + ρ·cc, one square-sum.
    scale = cc / mdl.weight
    offset = mdl.mean + np.log(mdl.reference * mdl.weight + mdl.epsilon) + np.log(scale)
    floor = mdl.epsilon * scale
    num = np.zeros(n_combo * m_t)
    den = np.zeros(m_t)
    clamped = 0
    coefs32 = np.ascontiguousarray(coefs, dtype=np.float32)

    def blocks() -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float32]]]:
        for a, b in q_chunks(mdl):
            yield a, b, np.asarray(mdl.Q[a:b], dtype=np.float32), reader.get(a, b)

    prog = _Progress("evaluation pass 2 (linear-space error)", mdl.p)
    for a, b, q32, rho32 in read_ahead(blocks()):
        rho_cc = rho32.reshape(m_t, b - a).T.astype(np.float64) * cc[a:b, None]  # (b − a, m_t)
        den += np.einsum("ij,ij->j", rho_cc, rho_cc)
        kk = rho_cc + floor[a:b, None]
        for s0 in range(0, b - a, _SUB_ROWS):
            s1 = min(s0 + _SUB_ROWS, b - a)
            lo = floor[a + s0 : a + s1, None]
            # Q c̄ in float32 (sgemm, see the module docstring), everything after it in float64.
            z = np.add(q32[s0:s1] @ coefs32, offset[a + s0 : a + s1, None], dtype=np.float64)
            np.exp(z, out=z)
            clamped += int(np.count_nonzero(z < lo))
            np.maximum(z, lo, out=z)
            z3 = z.reshape(s1 - s0, n_combo, m_t)
            z3 -= kk[s0:s1, None, :]
            num += np.einsum("ij,ij->j", z, z)
        prog.step(b)
    if clamped:
        logger.info("linear-space error: %d of %d reconstructed values clamped at 0 (%.3g%%)",
                    clamped, mdl.p * n_combo * m_t, 100.0 * clamped / (mdl.p * n_combo * m_t))
    den_all = np.tile(den, n_combo)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(den_all > 0, np.sqrt(num / den_all), np.where(num > 0, np.inf, 0.0))
    return rel.reshape(n_combo, m_t)


# ==========================================================================
# Materials of another database (config unseen)
# ==========================================================================


@dataclass(frozen=True, eq=False)
class RowStatistics:
    """What the Gram identity needs about some material-channels of a store, from one streamed pass.

    Rows are ``3·i + c`` for material ``materials[i]`` and channel c, log-mapped
    with the model's ρ_ref and w; ``y = x − μ``.  ``qtq`` = QᵀQ (k × k),
    ``qty`` = QᵀY (k × m), ``yy`` = ‖y‖² per row, and Q and Y at the kept
    model columns ``cols`` (sorted, unique).  :meth:`rms_log` and
    :meth:`deviation` are then exact for any coefficient columns (as
    :func:`evaluate`'s ``rms_log`` and ``deviation``), at O(k²) each.
    """

    model: Model
    database: str
    materials: tuple[str, ...]
    qtq: F64
    qty: F64
    yy: F64
    cols: NDArray[np.intp]
    q_obs: F64
    y_obs: F64

    def _pos(self, cols: ArrayLike) -> NDArray[np.intp]:
        c = np.asarray(cols, dtype=np.intp).ravel()
        pos = np.searchsorted(self.cols, c)
        if c.size and (pos.max() >= self.cols.size or not np.array_equal(self.cols[pos], c)):
            raise ValueError("columns that the streamed pass did not keep")
        return pos

    def q_at(self, cols: ArrayLike) -> F64:
        """Rows of Q (float64) at model columns ``cols`` (repeats allowed; each must be kept)."""
        return self.q_obs[self._pos(cols)]

    def y_at(self, cols: ArrayLike) -> F64:
        """``y`` of every row at model columns ``cols``: (m, len(cols))."""
        return self.y_obs[:, self._pos(cols)]

    def rms_log(self, coefs: ArrayLike, owners: ArrayLike) -> F64:
        """‖y − Qc‖/√p of each coefficient column ``coefs[:, j]`` against row ``owners[j]``."""
        c = np.asarray(coefs, dtype=np.float64)
        o = np.asarray(owners, dtype=np.intp)
        if c.ndim != 2 or c.shape[0] != self.model.k or o.shape != (c.shape[1],):
            raise ValueError(f"coefs must be (k = {self.model.k}, r) with one owner row per column")
        return np.sqrt(_sq_err(self.yy[o], self.qty[:, o], self.qtq, c) / self.model.p)

    def deviation(self) -> F64:
        """The floor ‖(I − VVᵀ) y‖/√p of every row (all cells observed; eq. 9)."""
        proj = scipy.linalg.solve(self.qtq, self.qty, assume_a="pos")
        return np.sqrt(np.maximum(self.yy - np.einsum("kj,kj->j", self.qty, proj), 0.0) / self.model.p)


def row_statistics(
    store_path: BrdfStore | str | os.PathLike[str],
    model_path: Model | str | os.PathLike[str],
    materials: Sequence[str],
    columns: ArrayLike,
    *,
    database: str | None = None,
) -> RowStatistics:
    """One streamed pass over Q and the rows of ``materials``: :class:`RowStatistics`, keeping ``columns``.

    ``database`` None: the store must be of the model's database and the
    materials held out (not training materials of the model), as in
    :func:`evaluate`; a label: the store must be of that database (materials
    from outside the training database, which the model has never seen),
    named in any error.  Either way every model column must be a cell
    measured in every material of the store.
    """
    mdl = as_model(model_path)
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    if database is None:
        if st.database != mdl.database:
            raise ValueError(f"{st.path} is database {st.database!r}, the model {mdl.path} {mdl.database!r}")
        names = _test_materials(st, mdl.train_materials, materials)
    else:
        if st.database != database:
            raise ValueError(f"{st.path} is database {st.database!r}, expected {database!r}")
        names = list(materials)
    _check_columns(st, mdl)
    rows = _material_rows(st, names, "materials")
    cols = np.asarray(columns, dtype=np.intp).ravel()
    if cols.size and (cols.min() < 0 or cols.max() >= mdl.p):
        raise ValueError(f"columns must lie in [0, {mdl.p}) (model columns of {mdl.path})")
    keep = _Gathered(cols)
    reader = _StoreColumns(st, rows, mdl.cells)
    m = 3 * len(names)

    def residuals() -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float64]]]:
        for a, b in q_chunks(mdl):
            rho = reader.get(a, b).reshape(m, b - a)
            y = logmap.forward(rho, mdl.reference[a:b], mdl.weight[a:b], mdl.epsilon)
            yield a, b, np.asarray(mdl.Q[a:b], dtype=np.float32), y - mdl.mean[a:b]

    qtq, qty, yy, q_obs, y_obs = _gram_pass(mdl, keep, residuals(), m, f"row statistics of {st.path.name}")
    return RowStatistics(mdl, st.database, tuple(names), qtq, qty, yy, keep.cols, q_obs, y_obs)


# ==========================================================================
# Consistency check
# ==========================================================================


def check_consistency(
    logmap_path: Logmap | str | os.PathLike[str],
    model_path: Model | str | os.PathLike[str],
    directions_paths: Sequence[str | os.PathLike[str]],
    *,
    out: str | os.PathLike[str] | None = None,
    rtol: float = CONSISTENCY_RTOL,
) -> list[dict[str, Any]]:
    """Recompute E(S) of every directions set directly from the training rows and compare.

    For each set, every training row ``x_i`` of the log-map (the rows the
    model was fitted to; its id must match the model's) is reconstructed
    from its own observations, ``c̄_i = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ S(x_i − μ)`` with the
    file's η, and ``direct = mean_i ‖x_i − μ − Q c̄_i‖ (+ β‖Q(Q̃ᵀQ̃ + ηI)⁻¹Q̃ᵀ1‖
    when the file's β > 0)``, by the Gram identity with QᵀQ, QᵀY and ‖y_i‖²
    from one streamed pass over the log-map and Q (the p-space error, without
    assuming y_i = Q u_i; the tests check it against a literal p-space
    computation).  ``rel_diff = |direct − predicted|/|predicted|`` with
    ``predicted`` the file's ``expected_error``.

    Writes the rows (:data:`CONSISTENCY_COLUMNS`) to ``out`` when given —
    also when the check fails — and raises :class:`ConsistencyError` naming
    the worst set if any ``rel_diff`` > ``rtol``.  Returns the rows.
    """
    t0 = time.perf_counter()
    lm = logmap_path if isinstance(logmap_path, Logmap) else open_logmap(logmap_path)
    mdl = as_model(model_path)
    if lm.id != mdl.logmap_id:
        raise ValueError(f"{mdl.path} was not fitted to the log-map {lm.path} (log-map ids differ)")
    if lm.p != mdl.p or not np.array_equal(lm.cells, mdl.cells):
        raise ValueError(f"{lm.path} and {mdl.path} disagree in their columns")
    combos = _combos(directions_paths, mdl)
    if not combos:
        raise ValueError("no direction sets to check")
    k, m = mdl.k, lm.m
    keep = _Gathered(np.concatenate([c.rows for c in combos]))
    logger.info("consistency check of %d direction sets against %d training rows of %s", len(combos), m, lm.path)

    def residuals() -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float64]]]:
        for a, b in q_chunks(mdl):
            x = lm.read_columns(a, b).astype(np.float64)
            yield a, b, np.asarray(mdl.Q[a:b], dtype=np.float32), x - mdl.mean[a:b]

    qtq, qty, yy, q_obs, y_obs = _gram_pass(mdl, keep, residuals(), m, "consistency pass")

    rows: list[dict[str, Any]] = []
    worst: tuple[float, _Combo, float] | None = None
    for c in combos:
        pos = keep.pos(c.rows)
        qt = q_obs[pos]
        coef = reconstruct_coefficients(qt, y_obs[:, pos].T, c.eta) if pos.size else np.zeros((k, m))
        direct = float(np.mean(np.sqrt(_sq_err(yy, qty, qtq, coef))))
        if c.beta > 0.0:
            w = reconstruct_coefficients(qt, np.ones(pos.size), c.eta) if pos.size else np.zeros(k)
            direct += c.beta * math.sqrt(max(float(w @ qtq @ w), 0.0))
        rel = abs(direct - c.predicted) / max(abs(c.predicted), np.finfo(np.float64).tiny)
        if not math.isfinite(rel):
            rel = math.inf  # a NaN must fail the check, not slip past the comparison
        rows.append({"setup": c.setup, "fov": c.fov, "metric": c.metric, "n": c.n, "predicted": c.predicted,
                     "direct": direct, "rel_diff": rel})
        if worst is None or rel > worst[0]:
            worst = (rel, c, direct)
    if out is not None:
        write_errors(out, rows, CONSISTENCY_COLUMNS)
    assert worst is not None
    logger.info("consistency check: %d sets, largest relative difference %.3g (%s %g° %s n=%d) in %.1f s",
                len(rows), worst[0], worst[1].setup, worst[1].fov, worst[1].metric, worst[1].n,
                time.perf_counter() - t0)
    if not worst[0] <= rtol:
        bad = sum(1 for r in rows if not r["rel_diff"] <= rtol)
        c = worst[1]
        raise ConsistencyError(
            f"{c.path}: recorded E(S) of the set n = {c.n} ({c.setup}, fov {c.fov}, metric {c.metric}) is "
            f"{c.predicted:.10g}, the direct recomputation from {lm.path} gives "
            f"{worst[2]:.10g}: relative difference {worst[0]:.3g} > {rtol:g} "
            f"({bad} of {len(rows)} set(s) fail the check)"
        )
    return rows


# ==========================================================================
# Error vs number of training materials
# ==========================================================================


def training_size_curve(
    store_path: BrdfStore | str | os.PathLike[str],
    logmap_path: Logmap | str | os.PathLike[str],
    directions_path: str | os.PathLike[str],
    *,
    test_materials: Sequence[str] | None,
    sizes: Sequence[int] = DEFAULT_SIZES,
    order_seed: int = 0,
    n_images: int = 2,
    eta: float = DEFAULT_ETA,
    tol: float = svd.TOL,
) -> list[dict[str, Any]]:
    """Mean log-space RMS error of the held-out rows vs the number N of training materials (Xu Fig. 7).

    The training materials of ``logmap_path`` (the ``train`` log-map) are
    put in the order ``numpy.random.default_rng(order_seed).permutation``;
    for each N in ``sizes`` (capped at their number, duplicates dropped) the
    PCA of the first N materials' rows (channels as rows; k ≤ 3N − 1, the
    tolerance ``tol`` as :func:`brdfpipe.acquisition.svd.fit`) reconstructs the held-out
    rows from the set with ``n_images`` configurations of
    ``directions_path`` (normally the near-field 25° error-metric file of
    the ``train`` optimisation).  Approximations (see the module docstring):
    the ``train`` log-mapping's ρ_ref and the ``train`` directions for every N.

    Returns rows with keys :data:`~brdfpipe.registry.tables.TRAINING_SIZE` (kind ``rms_log``,
    per material-channel and ``mean``/``all``).
    """
    eta = metrics.check_eta(eta)
    t0 = time.perf_counter()
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    lm = logmap_path if isinstance(logmap_path, Logmap) else open_logmap(logmap_path)
    if st.database != lm.database:
        raise ValueError(f"{st.path} is database {st.database!r}, the log-map {lm.path} {lm.database!r}")
    if set(lm.materials) != set(lm.train_materials):
        raise ValueError(f"{lm.path}: rows are not the training materials of its split")
    valid = np.asarray(st.valid[:], dtype=bool)
    if not valid[lm.cells].all():
        raise ValueError(f"{lm.path}: columns are not measured in every material of {st.path}")
    names = _test_materials(st, lm.train_materials, test_materials)
    d = read_directions(directions_path)
    if d.split != lm.split or d.database != lm.database:
        raise ValueError(f"{directions_path}: directions of split {d.split!r} / database {d.database!r}, the log-map "
                         f"{lm.path} is {lm.split!r} / {lm.database!r}")
    chosen = [s for s in d.sets if s.n == n_images]
    if not chosen:
        raise ValueError(f"{directions_path}: no set with n = {n_images}")
    lut = column_lookup(lm.cells)
    cells = np.concatenate([geometry.observation_cells(d.setup, c, lut >= 0) for c in chosen[0].configurations])
    obs_rows = lut[cells]
    mats = list(lm.materials)
    n_mat = len(mats)
    want = sorted({min(int(s), n_mat) for s in sizes})
    if not want or want[0] < 1:
        raise ValueError(f"sizes must be positive integers, got {list(sizes)}")
    order = np.random.default_rng(order_seed).permutation(n_mat)
    p, m, m_t = lm.p, lm.m, 3 * len(names)
    logger.info("training-size curve: N = %s of %d training materials (order seed %d), %s fov %g n = %d "
                "(%d observations), %d held-out rows", want, n_mat, order_seed, d.setup.kind, d.setup.fov_deg,
                n_images, obs_rows.size, m_t)

    reader = _StoreColumns(st, _material_rows(st, names, "test_materials"), lm.cells)
    keep = _Gathered(obs_rows)
    g_tt = np.zeros((m, m))
    g_ts = np.zeros((m, m_t))
    s_tr = np.zeros(m)
    xx_t = np.zeros(m_t)
    xo_tr = np.empty((m, keep.cols.size))
    xo_te = np.empty((m_t, keep.cols.size))

    def blocks() -> Iterator[tuple[int, int, NDArray[np.float32], NDArray[np.float32]]]:
        width = lm.chunk_cols
        for a in range(0, p, width):
            b = min(a + width, p)
            yield a, b, lm.read_columns(a, b), reader.get(a, b)

    prog = _Progress("training-size pass (cross-Gram)", p)
    for a, b, x32, rho in read_ahead(blocks()):
        x = x32.astype(np.float64)
        xt = logmap.forward(rho.reshape(m_t, b - a), lm.reference[a:b], lm.weight[a:b], lm.epsilon)
        g_tt += x @ x.T
        g_ts += x @ xt.T
        s_tr += x.sum(axis=1)
        xx_t += np.einsum("ij,ij->i", xt, xt)
        pos, off = keep.take(a, b)
        xo_tr[:, pos] = x[:, off]
        xo_te[:, pos] = xt[:, off]
        prog.step(b)
    g_tt = 0.5 * (g_tt + g_tt.T)
    pos = keep.pos(obs_rows)
    xo_tr, xo_te = xo_tr[:, pos], xo_te[:, pos]  # (m, n_obs), (m_t, n_obs), repeats expanded

    rows: list[dict[str, Any]] = []
    labels = [(mat, CHANNELS[ch]) for mat in names for ch in range(3)]
    for n_train in want:
        sel = np.sort((3 * order[:n_train, None] + np.arange(3)[None, :]).ravel())
        g = g_tt[np.ix_(sel, sel)]
        u, sigma = svd.decompose(g, s_tr[sel], p, tol)
        mn = sel.size
        amat = u - u.mean(axis=0)  # C U
        avec = np.full(mn, 1.0 / mn)
        q_obs = xo_tr[sel].T @ amat  # (n_obs, k)
        y_obs = xo_te.T - (xo_tr[sel].T @ avec)[:, None]  # (n_obs, m_t)
        coef = reconstruct_coefficients(q_obs, y_obs, eta) if obs_rows.size else np.zeros((sigma.size, m_t))
        ga = g @ avec
        xg = g_ts[sel]  # X_N x_t
        yy = xx_t - 2.0 * (avec @ xg) + float(avec @ ga)
        qty = amat.T @ (xg - ga[:, None])
        qtq = amat.T @ g @ amat
        rms = np.sqrt(_sq_err(yy, qty, 0.5 * (qtq + qtq.T), coef) / p)
        for (mat, ch), v in zip(labels, rms):
            rows.append({"database": lm.database, "n_train": n_train, "order_seed": order_seed, "material": mat,
                         "channel": ch, "kind": "rms_log", "value": float(v)})
        rows.append({"database": lm.database, "n_train": n_train, "order_seed": order_seed, "material": "mean",
                     "channel": "all", "kind": "rms_log", "value": float(rms.mean())})
        logger.info("N = %d materials (m = %d rows, k = %d): mean rms_log %.5g", n_train, mn, sigma.size,
                    float(rms.mean()))
    logger.info("training-size curve done in %.1f s", time.perf_counter() - t0)
    return rows


# ==========================================================================
# Output
# ==========================================================================


def _fmt(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf" if v < 0 else "nan")
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def write_errors(
    path: str | os.PathLike[str], rows: Sequence[dict[str, Any]], columns: Sequence[str] = tables.ERRORS
) -> Path:
    """Write ``rows`` (dicts with at least ``columns``) as a CSV with a header line, atomically.

    Parent folders are created; the file is written under a temporary name
    and renamed into place, with its digest line first
    (:func:`brdfpipe.core.integrity.write_csv`).  ValueError if a row lacks a
    column.  Returns the path.
    """
    path = Path(path)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for i, r in enumerate(rows):
        missing = [c for c in columns if c not in r]
        if missing:
            raise ValueError(f"row {i} lacks column(s) {', '.join(missing)}")
        w.writerow([_fmt(r[c]) for c in columns])
    integrity.write_csv(path, buf.getvalue())
    return path


def write_evaluation(
    store_path: str | os.PathLike[str],
    model_path: str | os.PathLike[str],
    directions_paths: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    test_materials: Sequence[str] | None = None,
    eta: float = DEFAULT_ETA,
) -> Path:
    """Leave-out evaluation of every direction set (:func:`evaluate`), written to ``out`` (errors CSV)."""
    rows = evaluate(store_path, model_path, directions_paths, test_materials=test_materials, eta=eta)
    return write_errors(out, rows)


def write_training_size(
    store_path: str | os.PathLike[str],
    logmap_path: str | os.PathLike[str],
    directions_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    test_materials: Sequence[str] | None = None,
    sizes: Sequence[int] = DEFAULT_SIZES,
    order_seed: int = 0,
    orders: int = 1,
    eta: float = DEFAULT_ETA,
) -> Path:
    """Error vs number of training materials (Xu Fig. 7, :func:`training_size_curve`), written to ``out``.

    One curve per material order, seeds ``order_seed``, ``order_seed + 1``, …
    (``orders`` of them), their rows one after the other (column
    ``order_seed``): one order's curve can rise by less than the spread
    between orders, so the figure and the claim use their mean.
    """
    if not 1 <= int(orders) <= 64:
        raise ValueError(f"orders must be in [1, 64], got {orders}")
    curve = [row for k in range(int(orders))
             for row in training_size_curve(store_path, logmap_path, directions_path, test_materials=test_materials,
                                            sizes=sizes, order_seed=order_seed + k, eta=eta)]
    return write_errors(out, curve, tables.TRAINING_SIZE)
