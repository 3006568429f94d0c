"""Error metrics of minimal BRDF sampling (Xu et al. 2016, "Minimal BRDF
Sampling for Two-Shot Near-Field Reflectance Acquisition").

How good a selection of MERL cells is for reconstructing a BRDF from the
principal components of :mod:`brdfpipe.acquisition.svd`: the expected error
of a selection (the paper's eq. 15) in its fast sufficient-statistics form
(the tests check it against the literal p-space formula), the
condition-number baseline of eq. 6 and Nielsen et al. 2015's released variant
of it, many candidate selections evaluated against one factored base
selection (:class:`FactoredSelection`, for the optimiser), and the
regularised reconstruction of eq. 4.  Which cells an acquisition
configuration observes is :mod:`brdfpipe.acquisition.geometry`; the search
over configurations is :mod:`brdfpipe.acquisition.optimize`.

Notation (paper §3)
-------------------
``X`` (m × p): log-mapped training BRDFs, one row per material-channel, one
column per cell; ``μ`` its column mean.  ``X − μ̂ = U Σ Vᵀ`` (thin SVD, ``k``
components kept), ``Q = V Σ`` (p × k), so ``QᵀQ = Σ²`` and the training
residuals are ``y_i = x_i − μ = Q u_i`` with ``u_i`` row *i* of ``U``
(exactly so when ``k`` is the rank of the centred ``X``; for a truncated
``k`` the training rows' own reconstruction error also holds the part of
``x_i`` outside the column space of ``Q``).

A *selection* ``S`` (n × p) picks ``n`` rows of ``Q`` – observations, a cell
may be observed more than once – giving ``Q̃ = S Q`` (n × k).  Its regularised
inverse is ``(SQ)⁺_η = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ`` (eq. 5), ``η = 40`` by default.

Everything a metric needs from a selection is its pair of **sufficient
statistics** (:func:`selection_stats`)::

    G    = Q̃ᵀQ̃  = Σ_rows q qᵀ     (k × k Gram matrix)
    qsum = Q̃ᵀ 1  = Σ_rows q        (k,)

Both are sums over the selected rows, so adding or removing a block of rows
(one near-field image, one point direction) is an O(n_block·k²) update; the
optimiser evaluates its candidates against its current selection
(:class:`FactoredSelection`).

Conventions: all arithmetic is float64 whatever the input dtype (the model
stores ``Q`` as float32); functions never modify their arguments; invalid
shapes or parameters raise :class:`ValueError`.

Performance note: the numpy and scipy wheels each bundle their *own*
OpenBLAS, each with its own thread pool.  Alternating calls into the two
(e.g. a numpy ``Bᵀ @ B`` then a scipy Cholesky, as an optimiser loop would)
makes the idle pool's spinning threads compete with the active one (each
evaluation is slower; measured: ``docs/results/acquisition.md``).  The
per-candidate functions here (:func:`selection_stats`,
:func:`expected_error`, :func:`condition_number`)
therefore use scipy's BLAS/LAPACK only (``dsyrk``, ``dgemm``,
``cho_factor``/``cho_solve``, ``eigvalsh``, ``svdvals``).  Multithreaded
OpenBLAS is also erratic on a loaded machine; an optimiser there is better
run with ``OPENBLAS_NUM_THREADS=1``, parallel over candidates if at all
(single-threaded evaluations take a stable time).
:class:`FactoredSelection` — many candidates evaluated against one
factorisation by low-rank updates, for the optimiser — likewise keeps
its k-sized products in scipy (``cho_solve``, ``dgemm``, ``dgemv``); numpy
does only element-wise work and the small r × r systems of a batch.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
import scipy.linalg
import scipy.linalg.blas
import scipy.linalg.lapack
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DEFAULT_ETA",
    "ErrorModel",
    "condition_number",
    "condition_number_first_n",
    "empty_stats",
    "expected_error",
    "FactoredSelection",
    "RowBlock",
    "expected_error_terms",
    "reconstruct_coefficients",
    "selection_stats",
    "DOWNDATE_TOL",
    "block_stats",
]

F64 = NDArray[np.float64]

#: The paper's Tikhonov regularisation weight (§3, eq. 4): "we set η = 40".
DEFAULT_ETA: float = 40.0

@dataclass(frozen=True, eq=False)
class ErrorModel:
    """The training set and parameters of the expected error E(S) (eq. 15).

    E(S) = (1/m) Σ_i ‖Q (Q⁺ − (SQ)⁺_η S) y_i‖ + β ‖Q (SQ)⁺_η S O‖

    with ``y_i = Q u_i`` the training residuals and ``O`` the all-ones
    p-vector (constant-magnitude noise of level ``β``, §4 "Final Error
    Metric").  With ``G = Q̃ᵀQ̃``, ``qsum = Q̃ᵀ1`` and ``M = G + ηI``:

    * ``Q⁺ y_i = u_i`` (as ``Q⁺ = Σ⁻¹Vᵀ`` and ``Q = VΣ``);
    * ``(SQ)⁺_η S y_i = M⁻¹ Q̃ᵀ Q̃ u_i = M⁻¹ G u_i``;
    * so the coefficient error is ``(I − M⁻¹G) u_i = M⁻¹(M − G) u_i = η M⁻¹ u_i``;
    * and ``‖Q w‖ = ‖Σ w‖`` for every k-vector ``w`` (``QᵀQ = Σ²``);

    giving the reconstruction term ``(η/m) Σ_i ‖Σ M⁻¹ u_i‖`` and, since
    ``S O = 1``, the noise term ``β ‖Σ M⁻¹ qsum‖`` — both evaluated in
    O(k³ + k²m) from the selection's sufficient statistics, never touching a
    p-vector (:func:`expected_error`).  Zero singular values (the direction
    removed by centring when ``k = m``) are handled by the same formula.

    Parameters
    ----------
    sigma:
        (k,) singular values Σ (≥ 0, finite), in the column order of ``Q``.
    U:
        (m, k) coefficients of the materials the error is averaged over, in
        the basis ``Q``: ``y_i = Q u_i``.  For the paper's metric these are
        the training coefficients (left singular vectors), but any set of
        coefficient vectors works (e.g. held-out materials projected on ``Q``).
    eta:
        Tikhonov weight η > 0 of eq. 4 (default 40).
    beta:
        Noise level β ≥ 0 of eq. 15 (default 0: reconstruction error only,
        as in the paper's main results).
    qtq:
        Optional (k, k) Gram matrix ``QᵀQ`` of the *stored* ``Q``.  By default
        ``QᵀQ = diag(σ²)`` is assumed, which holds only to the precision ``Q``
        is stored in: for float32 (relative rounding ~6e-8 per entry, largely
        averaging out over p rows) E moved by 2e-11 – 1e-10 relative on a
        p = 50,000 synthetic model.  Passing the Gram matrix actually
        computed from the stored ``Q`` makes the fast formula agree with the
        p-space formulas to float64 rounding instead (costs one extra k × k
        by k × m product per evaluation).  It must be symmetric positive
        semi-definite.

    Raises
    ------
    ValueError
        On wrong shapes, non-finite values, negative σ, η ≤ 0 or β < 0.
    """

    sigma: F64
    U: F64
    eta: float = DEFAULT_ETA
    beta: float = 0.0
    qtq: F64 | None = None
    # (k, m) contiguous Uᵀ, the right-hand sides of every evaluation.
    _ut: F64 = field(init=False, repr=False)
    # (k, k) factor R with RᵀR = QᵀQ, or None for diag(σ) (norms ‖R w‖).
    _r: F64 | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        sigma = np.array(self.sigma, dtype=np.float64)  # copies
        U = np.array(self.U, dtype=np.float64)
        if sigma.ndim != 1 or sigma.size == 0:
            raise ValueError(f"sigma must be a non-empty 1-D array, got shape {sigma.shape}")
        k = sigma.size
        if U.ndim != 2 or U.shape[1] != k or U.shape[0] == 0:
            raise ValueError(f"U must have shape (m, k) = (m ≥ 1, {k}) to match sigma, got {U.shape}")
        if not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
            raise ValueError("sigma must be finite and non-negative")
        if not np.all(np.isfinite(U)):
            raise ValueError("U must be finite")
        eta = check_eta(self.eta)
        beta = float(self.beta)
        if not np.isfinite(beta) or beta < 0:
            raise ValueError(f"beta must be finite and ≥ 0, got {self.beta!r}")
        r: F64 | None = None
        qtq: F64 | None = None
        if self.qtq is not None:
            qtq = np.array(self.qtq, dtype=np.float64)
            if qtq.shape != (k, k) or not np.all(np.isfinite(qtq)):
                raise ValueError(f"qtq must be a finite ({k}, {k}) matrix, got shape {qtq.shape}")
            scale = max(float(np.max(np.abs(qtq))), np.finfo(np.float64).tiny)
            if np.max(np.abs(qtq - qtq.T)) > 1e-10 * scale:
                raise ValueError("qtq must be symmetric")
            w, z = np.linalg.eigh(qtq)
            if w[0] < -1e-10 * max(w[-1], 0.0):
                raise ValueError("qtq must be positive semi-definite")
            r = np.asfortranarray(np.sqrt(np.clip(w, 0.0, None))[:, None] * z.T)
            qtq.setflags(write=False)
            r.setflags(write=False)
        ut = np.ascontiguousarray(U.T)
        for a in (sigma, U, ut):
            a.setflags(write=False)
        object.__setattr__(self, "sigma", sigma)
        object.__setattr__(self, "U", U)
        object.__setattr__(self, "eta", eta)
        object.__setattr__(self, "beta", beta)
        object.__setattr__(self, "qtq", qtq)
        object.__setattr__(self, "_ut", ut)
        object.__setattr__(self, "_r", r)

    @property
    def k(self) -> int:
        """Number of principal components."""
        return int(self.sigma.size)

    @property
    def m(self) -> int:
        """Number of materials (rows of ``U``) the error is averaged over."""
        return int(self.U.shape[0])

    def _weighted_col_norms(self, w: F64) -> F64:
        """``‖Q w_j‖`` for each column ``w_j`` of the (k, r) array ``w``."""
        if self._r is None:
            return np.linalg.norm(self.sigma[:, None] * w, axis=0)
        return np.linalg.norm(scipy.linalg.blas.dgemm(1.0, self._r, w), axis=0)


def check_eta(eta: float) -> float:
    eta = float(eta)
    if not np.isfinite(eta) or eta <= 0:
        raise ValueError(f"eta must be finite and > 0, got {eta!r}")
    return eta


def _as_rows(Qrows: ArrayLike) -> F64:
    """A 2-D float64 (n, k) view/copy of a block of Q rows (1-D = one row)."""
    B = np.asarray(Qrows, dtype=np.float64)
    if B.ndim == 1:
        B = B[None, :]
    if B.ndim != 2:
        raise ValueError(f"Qrows must be an (n, k) array of Q rows, got shape {B.shape}")
    if B.shape[1] == 0:
        raise ValueError("Qrows must have k ≥ 1 columns")
    if not np.all(np.isfinite(B)):
        raise ValueError("Qrows must be finite")
    return B


def _check_stats(G: ArrayLike, qsum: ArrayLike, k: int | None = None) -> tuple[F64, F64]:
    G = np.asarray(G, dtype=np.float64)
    qsum = np.asarray(qsum, dtype=np.float64)
    if G.ndim != 2 or G.shape[0] != G.shape[1]:
        raise ValueError(f"G must be a square (k, k) matrix, got shape {G.shape}")
    kk = G.shape[0] if k is None else k
    if G.shape != (kk, kk):
        raise ValueError(f"G has shape {G.shape}, expected ({kk}, {kk})")
    if qsum.shape != (kk,):
        raise ValueError(f"qsum has shape {qsum.shape}, expected ({kk},)")
    return G, qsum


def _gram(B: F64) -> F64:
    """``BᵀB`` (k × k, exactly symmetric) for an (n, k) float64 block, via scipy's ``dsyrk``."""
    k = B.shape[1]
    if B.shape[0] == 0:
        return np.zeros((k, k))
    # dsyrk(trans=0) computes a·aᵀ for a (k, n) Fortran array: a = Bᵀ (no copy
    # when B is C-contiguous).  Only the lower triangle is written.
    c = scipy.linalg.blas.dsyrk(1.0, np.asfortranarray(B.T), trans=0, lower=1)
    out = c + c.T  # the strict upper triangle of c is zero: the lower one mirrored (one pass, no masks)
    np.fill_diagonal(out, np.diagonal(c))
    return out


def empty_stats(k: int) -> tuple[F64, F64]:
    """Sufficient statistics ``(G, qsum)`` of the empty selection: zeros."""
    if int(k) < 1:
        raise ValueError(f"k must be ≥ 1, got {k!r}")
    return np.zeros((int(k), int(k))), np.zeros(int(k))


def selection_stats(Qrows: ArrayLike) -> tuple[F64, F64]:
    """Sufficient statistics of a selection from its block of ``Q`` rows.

    Parameters
    ----------
    Qrows:
        (n, k) selected rows ``Q̃ = S Q`` (a cell observed twice appears
        twice); a 1-D array is one row.  ``n = 0`` gives zeros.

    Returns
    -------
    (G, qsum):
        ``G = Q̃ᵀQ̃`` (k, k) and ``qsum = Q̃ᵀ1`` (k,), float64.
    """
    B = _as_rows(Qrows)
    return _gram(B), B.sum(axis=0)


def _cho_M(G: F64, eta: float) -> tuple[F64, bool]:
    """Cholesky factor of ``M = G + ηI`` (ValueError if not positive definite)."""
    M = G + eta * np.eye(G.shape[0])
    try:
        return scipy.linalg.cho_factor(M, lower=True, overwrite_a=True, check_finite=True)
    except np.linalg.LinAlgError as exc:
        raise ValueError(
            "G + ηI is not positive definite: G is not a Gram matrix Q̃ᵀQ̃ "
            "(too many rows removed, or not symmetric positive semi-definite)"
        ) from exc


def expected_error_terms(model: ErrorModel, G: ArrayLike, qsum: ArrayLike) -> tuple[float, float]:
    """The two terms of eq. 15 separately: ``(E_recon, E_noise / β)``.

    ``E_recon = (η/m) Σ_i ‖Σ M⁻¹ u_i‖`` (mean reconstruction error over the
    materials of ``model``) and ``E_noise/β = ‖Σ M⁻¹ qsum‖`` (the noise term
    for unit β), with ``M = G + ηI``; see :class:`ErrorModel`.  Then
    ``expected_error = E_recon + β · (E_noise/β)``.
    """
    G, qsum = _check_stats(G, qsum, model.k)
    cf = _cho_M(G, model.eta)
    rhs = np.concatenate([model._ut, qsum[:, None]], axis=1)  # (k, m + 1)
    W = scipy.linalg.cho_solve(cf, rhs, check_finite=False)
    norms = model._weighted_col_norms(W)
    return float(model.eta * np.mean(norms[:-1])), float(norms[-1])


def expected_error(model: ErrorModel, G: ArrayLike, qsum: ArrayLike) -> float:
    """Expected error E(S) of eq. 15 from a selection's sufficient statistics.

    Parameters
    ----------
    model:
        Training coefficients, Σ, η and β (:class:`ErrorModel`).
    G, qsum:
        ``Q̃ᵀQ̃`` (k, k) and ``Q̃ᵀ1`` (k,) of the selection
        (:func:`selection_stats`); ``qsum`` is only used
        when ``β > 0``.

    Returns
    -------
    float
        ``(η/m) Σ_i ‖Σ M⁻¹ u_i‖ + β ‖Σ M⁻¹ qsum‖`` with ``M = G + ηI``, equal
        to the literal p-space formula of eq. 15 in exact arithmetic.  Cost O(k³/3 + 2k²m): one Cholesky factorisation of ``M``
        (``scipy.linalg.cho_factor``) and one solve with m (+1) right-hand
        sides; about a millisecond at k = m = 270.  For many selections that
        differ from one base by a few rows (an optimiser's candidates),
        :class:`FactoredSelection` gives the same values in O(k² + km) each.

    Raises
    ------
    ValueError
        Shapes inconsistent with ``model``, non-finite ``G``, or ``G + ηI``
        not positive definite.
    """
    G, qsum = _check_stats(G, qsum, model.k)
    if model.beta == 0.0:
        cf = _cho_M(G, model.eta)
        W = scipy.linalg.cho_solve(cf, model._ut, check_finite=False)
        return float(model.eta * np.mean(model._weighted_col_norms(W)))
    recon, noise = expected_error_terms(model, G, qsum)
    return recon + model.beta * noise


# ---------------------------------------------------------------------------
# Many candidates against one factored base selection (low-rank updates)
# ---------------------------------------------------------------------------
#
# An optimiser evaluates batches of candidates that share a *base* selection
# and differ from it by a few rows: adding a configuration to the current set
# (greedy add: base = the set, + its block R), or moving configuration j
# (local search: base = the set, − block R_j + the moved block R).  Write
# every candidate as M = M0 + VᵀDV with M0 = G0 + ηI the base's, V (r × k) the
# rows added and removed and D = diag(±1).  With M0 factored once and
# W0 = M0⁻¹Uᵀ, w0 = M0⁻¹qsum0 solved once per base, the Woodbury identity
#
#   M⁻¹ = M0⁻¹ − Z C⁻¹ Zᵀ,   Z = M0⁻¹Vᵀ (k × r),   C = D + V Z (r × r)
#
# gives M⁻¹Uᵀ = W0 − Z c with c = C⁻¹P, P = V W0 (r × m), and, writing N for
# the norm's weight (Σ, or the factor of the stored QᵀQ), A = N W0, B = N Z:
#
#   ‖N M⁻¹u_i‖² = ‖A_i‖² − 2 c_iᵀF_i + c_iᵀH c_i,
#                 F = BᵀA = Zᵀ(NᵀN W0) (r × m),   H = BᵀB = ZᵀNᵀN Z (r × r);
#
# and for the noise term (qsum = qsum0 + VᵀD s, s the rows' √counts)
#
#   M⁻¹qsum = w0 − Z C⁻¹(V w0 − s).
#
# ‖A_i‖² and NᵀN W0 are computed once per base.  Per candidate the cost is a
# solve with r right-hand sides (2k²r), the products P and F (4krm) and the
# r × r work (2kr² + r³/3 + 2r²m) — against k³/3 + 2k²m (+ k²r for G) for a
# fresh evaluation: ~1 Mflop against ~46 Mflop for a point move at
# k = m = 270.  All candidates of a batch share the big operations (their rows
# are stacked into one cho_solve and two dgemm; a removed block's products are
# computed once); small r × r systems are solved batched (numpy), larger
# ones one candidate at a time (scipy).
#
# Accuracy.  (1) The expanded squared norm cancels when ‖N M⁻¹u_i‖² is much
# smaller than its terms: a candidate for which any material's value is below
# _CANCEL_TOL times the sum of the terms' magnitudes has its norms recomputed
# from the vectors N(W0 − Z c) (O(kmr), still no factorisation), so no value
# loses more than 3 of its ~16 digits.  (2) Removing a block R_j is the
# downdate C_jj = −(I − R_j M0⁻¹R_jᵀ) = −(I + R_j M_{−j}⁻¹ R_jᵀ)⁻¹, which
# cancels when the block is strong (‖q‖²/η ≫ 1): when its smallest eigenvalue
# is below DOWNDATE_TOL the base minus the block is factored afresh instead
# (one Cholesky per batch).  (3) Blocks with so many rows that the low-rank
# form costs more flops than a fresh evaluation (r ≳ 100 at k = m = 270:
# near-field images) are evaluated fresh (:func:`expected_error`).  Rows
# observed c times are passed once with count c (weight √c), which makes both
# forms cheaper.  The result agrees with expected_error to ~1e-13 relative.
#
# A selection derived from another (:meth:`FactoredSelection.updated`: a
# block added and/or removed, as an optimiser's set changes) gets M⁻¹ and its
# solve from the parent's by the same identity, with no factorisation:
#   Z = M_old⁻¹Vᵀ, C = D + VZ,  M_new⁻¹ = M_old⁻¹ − Z C⁻¹ Zᵀ,  W_new = W_old − Z C⁻¹ (V W_old)
# (2k²r + 2krm flops instead of the k³/3 + 2k²m of a fresh Cholesky and
# solve).  M⁻¹ is kept explicitly (from ``dpotri`` of a fresh selection), so
# every product with it — the candidates' Z = M⁻¹Xᵀ included — is one dgemm.
# A derived selection whose removed block is too strong to downdate
# accurately (DOWNDATE_TOL) is factored afresh instead.  Such chains are
# counted (``depth``) so that a caller can rebuild from scratch now and then,
# bounding the rounding they accumulate.  With this, an optimiser's cost per
# accepted move and per candidate is O(k² + km): quadratic in the number of
# training materials (k, m ≈ 3 × materials), the one cubic step being the
# rebuild.

#: A squared norm updated by the expansion above is recomputed from its vector
#: when it is below this fraction of the magnitude of its terms.
_CANCEL_TOL: float = 1e-3
#: A removed block is downdated by the Woodbury form only if the smallest
#: eigenvalue of I − R_j M0⁻¹R_jᵀ (= (I + R_j M_{−j}⁻¹R_jᵀ)⁻¹) is at least this.
DOWNDATE_TOL: float = 1e-3
#: Candidate rows stacked into one batched low-rank step (bounds memory to a
#: few (rows × max(k, m)) float64 arrays: 4 MB each at 2048 × 270).
_LOWRANK_CHUNK_ROWS: int = 2048
#: Candidates with at most this many update rows are solved batched (numpy),
#: larger ones one at a time.
_BATCH_MAX_R: int = 8
#: Up to this many stacked update rows, C and H of all candidates are taken
#: from the full products XZ and ZᵀNᵀNZ (one dgemm each) rather than per block.
_FULL_GRAM_MAX: int = 64


def _lowrank_flops(r: int, k: int, m: int) -> float:
    """Flops of one candidate with r update rows by the low-rank form (see the section comment)."""
    return 2.0 * k * k * r + 4.0 * k * r * m + 2.0 * k * r * r + r**3 / 3.0 + 2.0 * r * r * m


def _direct_flops(r: int, k: int, m: int) -> float:
    """Flops of one candidate adding r rows evaluated fresh: dsyrk, Cholesky, solve with m RHS."""
    return k * k * r + k**3 / 3.0 + 2.0 * k * k * m


class RowBlock(NamedTuple):
    """A block of rows of ``Q``, e.g. the observations of one configuration.

    ``rows`` (r, k): its distinct rows; ``counts`` (r,): how many times each
    is observed (None: once each) — the block contributes ``Σ c_i q_iᵀq_i`` to
    ``G`` and ``Σ c_i q_i`` to ``qsum``; ``stats``: that contribution
    ``(G_b, qsum_b)`` when already known (saves a dsyrk; it is not checked).
    A plain (r, k) array means ``RowBlock(rows)``.
    """

    rows: ArrayLike
    counts: ArrayLike | None = None
    stats: tuple[ArrayLike, ArrayLike] | None = None


@dataclass(frozen=True)
class _Weighted:
    """A validated block: ``Rw = √c·R`` and ``s = √c``, so ``RwᵀRw = Σ c qᵀq`` and ``Rwᵀs = Σ c q``."""

    Rw: F64
    s: F64
    stats: tuple[F64, F64] | None

    @property
    def r(self) -> int:
        return int(self.Rw.shape[0])

    def gram(self) -> tuple[F64, F64]:
        """The block's contribution ``(G_b, qsum_b)``."""
        if self.stats is not None:
            return self.stats
        return _gram(self.Rw), scipy.linalg.blas.dgemv(1.0, self.Rw, self.s, trans=1)


def block_stats(block: RowBlock | ArrayLike, k: int) -> tuple[F64, F64]:
    """A block's contribution ``(G_b, qsum_b) = (Σ c q qᵀ, Σ c q)`` to a selection's statistics.

    ``block`` as for :class:`FactoredSelection` (a :class:`RowBlock` or a
    plain (r, k) array of ``Q`` rows), validated the same way; its ``stats``
    are returned as given when present.  The optimiser computes it once for a
    candidate whose Gram matrix both κ and E(S) need.
    """
    return _as_block(block, k, "block").gram()


def _as_block(block: RowBlock | ArrayLike, k: int, name: str) -> _Weighted:
    """Validate a block and weight its rows (float64, one pass over the rows)."""
    b = block if isinstance(block, RowBlock) else RowBlock(block)
    R = np.asarray(b.rows)
    if R.ndim == 1:
        R = R[None, :]
    if R.ndim != 2 or R.shape[1] != k or R.shape[0] == 0 or not np.issubdtype(R.dtype, np.number):
        raise ValueError(f"{name} must be a non-empty (r, {k}) array of Q rows, got shape {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError(f"{name} must be finite")
    stats = None if b.stats is None else _check_stats(b.stats[0], b.stats[1], k)
    if b.counts is None:
        return _Weighted(np.asarray(R, dtype=np.float64), np.ones(R.shape[0]), stats)
    c = np.asarray(b.counts, dtype=np.float64)
    if c.shape != (R.shape[0],) or not np.all(np.isfinite(c)) or np.any(c <= 0):
        raise ValueError(f"{name}: counts must be {R.shape[0]} finite positive multiplicities, got shape {c.shape}")
    s = np.sqrt(c)
    return _Weighted(np.multiply(s[:, None], R, dtype=np.float64), s, stats)


class FactoredSelection:
    """A selection's ``M = G + ηI`` factored once, to evaluate many modifications of it exactly.

    :meth:`candidate_errors` gives E(S) (eq. 15) of ``base (− a removed
    block) + block`` for many blocks at once — equal to
    ``expected_error(model, G − G_removed + G_b, qsum − qsum_removed + qsum_b)``
    up to rounding (≈ 1e-13 relative) — through the Woodbury identity where
    the blocks are small and a fresh evaluation where they are not (by flop
    count; see the section comment above).  :meth:`updated` gives the
    selection with a block added and/or removed, re-using this one's solve.

    Parameters
    ----------
    model:
        The :class:`ErrorModel` (Σ, U, η, β).
    G, qsum:
        The selection's statistics (:func:`selection_stats`); copied.

    Attributes: ``G``, ``qsum`` (read-only); ``depth``, the number of
    :meth:`updated` steps since a selection built from its statistics (0),
    so that a caller can rebuild from scratch now and then; ``recomputed``,
    the number of candidates whose norms were recomputed from their vectors
    because the expanded form would have cancelled.  The factorisation and
    the solve with m right-hand sides are done on first use; not thread-safe.
    """

    def __init__(self, model: ErrorModel, G: ArrayLike, qsum: ArrayLike) -> None:
        if not isinstance(model, ErrorModel):
            raise ValueError(f"model must be an ErrorModel, got {type(model).__name__}")
        G, qsum = _check_stats(G, qsum, model.k)
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(qsum))):
            raise ValueError("G and qsum must be finite")
        self.model = model
        self.G: F64 = np.array(G, dtype=np.float64)
        self.qsum: F64 = np.array(qsum, dtype=np.float64)
        self.G.setflags(write=False)
        self.qsum.setflags(write=False)
        self.depth = 0
        self.recomputed = 0
        self._cf: tuple[F64, bool] | None = None
        self._Minv: F64 | None = None  # M⁻¹ (k, k), explicit: products with it are one dgemm
        self._W: F64 | None = None  # M⁻¹Uᵀ (k, m)
        self._w: F64 | None = None  # M⁻¹qsum (k,), only when β > 0
        self._a2: F64 | None = None  # ‖N W_i‖² (m,)

    # -- factorisation and solve, on first use ----------------------------------

    def _factor(self) -> tuple[F64, bool]:
        if self._cf is None:
            self._cf = _cho_M(self.G, self.model.eta)
        return self._cf

    def _inverse(self) -> F64:
        """``M⁻¹`` (k, k): from the Cholesky factor (``dpotri``), or carried over by :meth:`updated`."""
        if self._Minv is None:
            c, _ = self._factor()
            inv, info = scipy.linalg.lapack.dpotri(c, lower=1)
            if info != 0:
                raise ValueError(f"G + ηI could not be inverted (dpotri info {info})")
            inv = np.tril(inv)
            inv += np.tril(inv, -1).T
            self._Minv = np.asfortranarray(inv)
        return self._Minv

    def _apply_inv(self, B: F64) -> F64:
        """``M⁻¹ B`` for a (k, r) array: one dgemm with the explicit inverse (O(k²r))."""
        return scipy.linalg.blas.dgemm(1.0, self._inverse(), B)

    def _solve(self) -> tuple[F64, F64 | None]:
        """``(W, w) = (M⁻¹Uᵀ, M⁻¹qsum)`` (w None when β = 0)."""
        if self._W is None:
            cf = self._factor()
            em = self.model
            if em.beta > 0.0:
                rhs = np.concatenate([em._ut, self.qsum[:, None]], axis=1)
                sol = scipy.linalg.cho_solve(cf, rhs, check_finite=False)
                self._W, self._w = sol[:, :-1], np.ascontiguousarray(sol[:, -1])
            else:
                self._W = scipy.linalg.cho_solve(cf, em._ut, check_finite=False)
        return self._W, self._w

    def _nn(self, x: F64) -> F64:
        """``NᵀN x`` for a (k, r) array (N = diag(Σ), or the factor of the model's QᵀQ)."""
        em = self.model
        if em.qtq is None:
            return (em.sigma**2)[:, None] * x
        return scipy.linalg.blas.dgemm(1.0, em.qtq, x)

    def _prepared(self) -> tuple[F64, F64]:
        """``(W, ‖N W_i‖²)``: the per-base quantities of the low-rank form."""
        W, _ = self._solve()
        if self._a2 is None:
            self._a2 = np.einsum("ki,ki->i", W, self._nn(W))
        return W, self._a2

    def error(self) -> float:
        """E(S) of this selection (from its solve)."""
        W, w = self._solve()
        em = self.model
        recon = em.eta * float(np.mean(em._weighted_col_norms(W)))
        if w is None:
            return recon
        return recon + em.beta * float(em._weighted_col_norms(w[:, None])[0])

    # -- derived selections ----------------------------------------------------

    def updated(self, add: RowBlock | ArrayLike | None = None,
                remove: RowBlock | ArrayLike | None = None) -> FactoredSelection:
        """This selection with the block ``add`` added and the block ``remove`` removed (either may be None).

        The removed rows must have been added before (not checked: ``G + ηI``
        may even stay positive definite).  Removing subtracts the block's
        Gram matrix, which costs accuracy of order ε·‖G_b‖/η relative; for
        a strong block (‖G_b‖ ≫ 1e3·η) build the selection afresh from the
        remaining rows instead.  The result has ``depth + 1``; its solve is
        derived from this one's (identity of the section comment) when that
        is computed and the blocks are small, else done afresh on first use.
        """
        k = self.model.k
        return self._updated([(_as_block(b, k, name), sign)
                              for b, name, sign in ((add, "add", 1.0), (remove, "remove", -1.0)) if b is not None])

    def _updated(self, parts: list[tuple[_Weighted, float]]) -> FactoredSelection:
        k, m = self.model.k, self.model.m
        G, qsum = self.G.copy(), self.qsum.copy()
        for blk, sign in parts:
            Gb, qb = blk.gram()
            G += sign * Gb
            qsum += sign * qb
        new = FactoredSelection(self.model, G, qsum)
        new.depth = self.depth + 1
        r = sum(blk.r for blk, _ in parts)
        if self._W is not None and r and 2.0 * k * k * r + 2.0 * k * r * m < 2.0 * k * k * m:
            # Woodbury with the explicit inverse (section comment): Z = M_old⁻¹Vᵀ, C = D + VZ,
            # M_new⁻¹ = M_old⁻¹ − Z C⁻¹ Zᵀ, W_new = W_old − Z C⁻¹ (V W_old): O(k²r + krm), no factorisation.
            V = np.concatenate([blk.Rw for blk, _ in parts], axis=0)
            d = np.concatenate([np.full(blk.r, sign) for blk, sign in parts])
            s = np.concatenate([blk.s for blk, _ in parts])
            Z = self._apply_inv(np.asfortranarray(V.T))  # (k, r)
            C = scipy.linalg.blas.dgemm(1.0, V, Z)
            C = 0.5 * (C + C.T)
            C[np.diag_indices(r)] += d
            neg = d < 0
            if neg.any():
                # Downdating a strong block cancels (section comment, accuracy (2)): then the new
                # selection is factored afresh on first use instead.
                Kr = -C[np.ix_(neg, neg)]
                if not float(scipy.linalg.eigvalsh(Kr, check_finite=False)[0]) >= DOWNDATE_TOL:
                    return new
            VW = scipy.linalg.blas.dgemm(1.0, V, self._W)  # (r, m)
            rhs = VW if self._w is None else np.concatenate(
                [VW, (scipy.linalg.blas.dgemv(1.0, V, self._w) - s)[:, None]], axis=1)
            sol = np.linalg.solve(C, rhs) if r > 1 else rhs / C[0, 0]
            ZCinv = np.linalg.solve(C, Z.T).T if r > 1 else Z / C[0, 0]  # Z C⁻¹ (C symmetric)
            # (Fortran order from dgemm; symmetric to rounding, which the rebuilds every few updates reset)
            new._Minv = scipy.linalg.blas.dgemm(-1.0, ZCinv, Z, 1.0, self._inverse(), trans_b=1)
            new._W = scipy.linalg.blas.dgemm(-1.0, Z, sol[:, :m], 1.0, self._W)
            if self._w is not None:
                new._w = scipy.linalg.blas.dgemv(-1.0, Z, sol[:, m], 1.0, self._w)
        return new

    # -- candidates ----------------------------------------------------------

    def candidate_errors(
        self,
        blocks: Sequence[RowBlock | ArrayLike],
        *,
        remove: RowBlock | ArrayLike | None = None,
        method: Literal["auto", "lowrank", "direct"] = "auto",
    ) -> F64:
        """E(S) of this selection, less ``remove``, plus each block.

        Parameters
        ----------
        blocks:
            Candidate blocks: :class:`RowBlock` or (r, k) arrays of rows
            (r ≥ 1 may differ between blocks; a 1-D array is one row).
        remove:
            A block (previously added) removed from every candidate, or None.
            As for :meth:`updated`, results lose accuracy of order
            ε·‖G_remove‖/η relative: for strong blocks use a selection built
            without them.
        method:
            ``"auto"``: per block the cheaper of the low-rank form and a fresh
            evaluation (by flop count); ``"lowrank"`` / ``"direct"`` force one
            (tests, reference runs).

        Returns
        -------
        (len(blocks),) float64 array: ``expected_error(model, G − G_remove +
        G_b, qsum − qsum_remove + qsum_b)`` for each block ``b``, in order.
        """
        if method not in ("auto", "lowrank", "direct"):
            raise ValueError(f"method must be 'auto', 'lowrank' or 'direct', got {method!r}")
        k, m = self.model.k, self.model.m
        if isinstance(blocks, np.ndarray) and blocks.ndim == 2:
            # t single-row candidates (a 2-D array is a sequence of rows): validated at once.
            R = np.asarray(blocks, dtype=np.float64)
            if R.shape[1] != k or not np.issubdtype(blocks.dtype, np.number) or not np.all(np.isfinite(R)):
                raise ValueError(f"blocks must be finite rows of length {k}, got shape {R.shape}")
            one = np.ones(1)
            cands = [_Weighted(R[i:i + 1], one, None) for i in range(R.shape[0])]
        else:
            cands = [_as_block(b, k, f"blocks[{i}]") for i, b in enumerate(blocks)]
        rem = None if remove is None else _as_block(remove, k, "remove")
        rj = 0 if rem is None else rem.r
        out = np.empty(len(cands))
        lowrank: list[int] = []
        G0: F64 | None = None
        for i, c in enumerate(cands):
            if method == "lowrank" or (
                method == "auto" and _lowrank_flops(c.r + rj, k, m) < _direct_flops(c.r, k, m)
            ):
                lowrank.append(i)
                continue
            if G0 is None:
                G0, q0 = self.G, self.qsum
                if rem is not None:
                    Gr, qr = rem.gram()
                    G0, q0 = G0 - Gr, q0 - qr
            Gc, qc = c.gram()
            out[i] = expected_error(self.model, G0 + Gc, q0 + qc)
        if not lowrank:
            return out
        # Batches of equal r (stable order), ≤ _LOWRANK_CHUNK_ROWS stacked rows each.
        by_r: dict[int, list[int]] = {}
        for i in lowrank:
            by_r.setdefault(cands[i].r, []).append(i)
        base: FactoredSelection = self
        for r, idx in sorted(by_r.items()):
            step = max(1, _LOWRANK_CHUNK_ROWS // r)
            for a in range(0, len(idx), step):
                chunk = [cands[i] for i in idx[a:a + step]]
                res = base._lowrank(chunk, rem if base is self else None)
                if res is None:  # downdating rem would lose accuracy: factor the base without it instead
                    assert rem is not None
                    Gr, qr = rem.gram()
                    base = FactoredSelection(self.model, self.G - Gr, self.qsum - qr)
                    res = base._lowrank(chunk, None)
                out[idx[a:a + step]] = res
        if base is not self:
            self.recomputed += base.recomputed
        return out

    def _lowrank(self, cands: list[_Weighted], rem: _Weighted | None) -> F64 | None:
        """E(S) of this selection (− ``rem``) + each block (all of one size rc) by the Woodbury form.

        None when ``rem``'s downdate is too ill-conditioned (see the section comment).
        """
        em = self.model
        W, a2 = self._prepared()
        _, w0 = self._solve()
        k, m = em.k, em.m
        t, rc = len(cands), cands[0].r
        rj = 0 if rem is None else rem.r
        r, n = rc + rj, t * rc
        # All update rows stacked: the candidates' (n) then the removed block's (rj).
        X = np.concatenate([c.Rw for c in cands] + ([rem.Rw] if rem is not None else []), axis=0)
        Z = self._apply_inv(np.asfortranarray(X.T))  # M0⁻¹Xᵀ
        Y = self._nn(Z)
        if rem is not None:
            K = np.eye(rj) - scipy.linalg.blas.dgemm(1.0, X[n:], Z[:, n:])
            lam = float(K[0, 0]) if rj == 1 else float(scipy.linalg.eigvalsh(0.5 * (K + K.T), check_finite=False)[0])
            if not lam >= DOWNDATE_TOL:
                return None
        PF = scipy.linalg.blas.dgemm(1.0, np.concatenate([X, Y.T], axis=0), W)
        P, F = PF[: n + rj], PF[n + rj:]  # X W0 and Zᵀ NᵀN W0
        # Candidate i's update rows within X: its own rc, then the removed block's rj.
        ix = np.concatenate([np.arange(n).reshape(t, rc), np.broadcast_to(np.arange(n, n + rj), (t, rj))], axis=1)
        if n + rj <= _FULL_GRAM_MAX:
            XZ = scipy.linalg.blas.dgemm(1.0, X, Z)
            ZY = scipy.linalg.blas.dgemm(1.0, Z, Y, trans_a=1)
            C = XZ[ix[:, :, None], ix[:, None, :]]
            H = ZY[ix[:, :, None], ix[:, None, :]]
        else:
            C = np.empty((t, r, r))
            H = np.empty((t, r, r))
            Z3 = Z[:, :n].T.reshape(t, rc, k)
            C[:, :rc, :rc] = np.einsum("tak,tbk->tab", X[:n].reshape(t, rc, k), Z3)
            H[:, :rc, :rc] = np.einsum("tak,tbk->tab", Z3, Y[:, :n].T.reshape(t, rc, k))
            if rj:
                XZj = scipy.linalg.blas.dgemm(1.0, X, Z[:, n:])  # (n + rj, rj)
                ZYj = scipy.linalg.blas.dgemm(1.0, Z, Y[:, n:], trans_a=1)
                for A, Aj in ((C, XZj), (H, ZYj)):
                    A[:, :rc, rc:] = Aj[:n].reshape(t, rc, rj)
                    A[:, rc:, :rc] = A[:, :rc, rc:].transpose(0, 2, 1)
                    A[:, rc:, rc:] = Aj[n:]
        C += np.diag(np.concatenate([np.ones(rc), -np.ones(rj)]))  # C = D + VZ
        rhs = P[ix]  # (t, r, m)
        if w0 is not None:  # the noise term's right-hand side V w0 − s as one more column
            s = np.concatenate([c.s for c in cands] + ([rem.s] if rem is not None else []))
            rhs = np.concatenate([rhs, (scipy.linalg.blas.dgemv(1.0, X, w0) - s)[ix][:, :, None]], axis=2)
        sol = _solve_small(C, rhs)
        c = sol[:, :, :m]
        Fc = F[ix]
        cF = np.einsum("tai,tai->ti", c, Fc)
        cHc = np.einsum("tai,tai->ti", c, np.einsum("tab,tbi->tai", H, c))
        d2 = a2[None, :] - 2.0 * cF + cHc
        out = em.eta * np.mean(np.sqrt(np.maximum(d2, 0.0)), axis=1)
        bad = np.flatnonzero(np.any(d2 < _CANCEL_TOL * (a2[None, :] + 2.0 * np.abs(cF) + np.abs(cHc)), axis=1))
        self.recomputed += int(bad.size)
        for i in bad:  # the norms from the vectors N(W0 − Z c)
            vecs = scipy.linalg.blas.dgemm(-1.0, Z[:, ix[i]], c[i], 1.0, W)  # W0 − Z c
            out[i] = em.eta * float(np.mean(em._weighted_col_norms(vecs)))
        if w0 is not None:
            h = sol[:, :, m]  # C⁻¹(V w0 − s); M⁻¹qsum = w0 − Z h
            v = w0[:, None] - np.einsum("kta,ta->kt", Z[:, :n].reshape(k, t, rc), h[:, :rc])
            if rj:
                v -= scipy.linalg.blas.dgemm(1.0, Z[:, n:], h[:, rc:], trans_b=1)
            out = out + em.beta * em._weighted_col_norms(v)
        return out


def _solve_small(C: F64, rhs: F64) -> F64:
    """Solve the (t, r, r) symmetric systems ``C x = rhs`` for (t, r, n) right-hand sides.

    r = 1, 2 in closed form (Cramer's rule is forward stable for 2 × 2 systems,
    Higham, *Accuracy and Stability of Numerical Algorithms*, §1.10.1), up to
    _BATCH_MAX_R batched by numpy, larger ones one at a time (LDLᵀ).
    """
    t, r = C.shape[0], C.shape[1]
    if r == 1:
        return rhs / C
    if r == 2:
        a, b, d = C[:, 0, 0, None], C[:, 0, 1, None], C[:, 1, 1, None]
        det = a * d - b * b
        x0 = (d * rhs[:, 0] - b * rhs[:, 1]) / det
        x1 = (a * rhs[:, 1] - b * rhs[:, 0]) / det
        return np.stack([x0, x1], axis=1)
    if r <= _BATCH_MAX_R:
        return np.linalg.solve(C, rhs)
    return np.stack([scipy.linalg.solve(C[i], rhs[i], assume_a="sym", check_finite=False) for i in range(t)])


def reconstruct_coefficients(Qrows: ArrayLike, y_obs: ArrayLike, eta: float = DEFAULT_ETA) -> F64:
    """Regularised coefficients ``c̄ = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ ỹ`` (eq. 4).

    Parameters
    ----------
    Qrows:
        (n, k) selected rows ``Q̃``.
    y_obs:
        (n,) observations ``ỹ = x̃ − μ̃`` at those rows, or (n, r): one
        observation vector per column.
    eta:
        Tikhonov weight η > 0.

    Returns
    -------
    (k,) or (k, r) float64 coefficients; the reconstruction is ``Q c̄ + μ``.
    """
    eta = check_eta(eta)
    B = _as_rows(Qrows)
    y = np.asarray(y_obs, dtype=np.float64)
    if y.ndim not in (1, 2) or y.shape[0] != B.shape[0]:
        raise ValueError(f"y_obs must have shape (n,) or (n, r) with n = {B.shape[0]}, got {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("y_obs must be finite")
    cf = _cho_M(_gram(B), eta)
    return scipy.linalg.cho_solve(cf, B.T @ y, check_finite=False)


def condition_number(
    Qrows_or_G: ArrayLike,
    n: int | None = None,
    *,
    method: Literal["gram", "svd"] = "gram",
    rtol: float | None = None,
) -> float:
    """The condition-number baseline κ(Q̃) = σ_max(Q̃) / σ_min(Q̃) of Xu et al.'s eq. 6.

    Over all k components of Q̃, as Xu write it.  (Nielsen et al. 2015's
    released code conditions only the first n components and picks other
    directions: :func:`condition_number_first_n`.)

    The singular values are the ``min(n, k)`` singular values of the n × k
    matrix ``Q̃`` — for ``n < k`` the ``n`` (generically non-zero) ones, so a
    handful of point directions has a finite κ even though ``Q̃ᵀQ̃`` is
    singular.  (Eq. 6 prints σ_max(Q); the ratio meant, and used here, is
    that of ``Q̃``.)

    Parameters
    ----------
    Qrows_or_G:
        Either the (n, k) block of selected rows ``Q̃`` (``n`` omitted), or the
        (k, k) Gram matrix ``G = Q̃ᵀQ̃`` of a selection together with its row
        count ``n`` (as kept incrementally by an optimiser).
    n:
        Number of selected rows when a Gram matrix is passed; must be None
        when rows are passed.
    method:
        ``"gram"`` (default): eigenvalues λ = σ² of the smaller of
        ``Q̃Q̃ᵀ`` (n × n) and ``Q̃ᵀQ̃`` (k × k) — cheap, and the same numbers
        whether rows or ``G`` are passed.  ``"svd"``: singular values of
        ``Q̃`` itself (rows only; slower, accurate up to κ ≈ 1/ε).
    rtol:
        Rank tolerance.  ``Q̃`` counts as rank deficient, and κ = inf, when
        ``σ_min ≤ rtol · σ_max``.  Default: ``sqrt(max(n, k) · ε)`` for
        ``"gram"`` (a Gram matrix's eigenvalues carry absolute errors
        ≈ max(n, k)·ε·λ_max, so smaller σ ratios, κ ≳ 1/sqrt(max(n,k)·ε) ≈ 5e6
        at n = 1600, are not resolvable), and ``max(n, k) · ε`` for ``"svd"``
        (``numpy.linalg.matrix_rank``'s default).

    Returns
    -------
    float
        κ ≥ 1, or ``inf`` for rank-deficient ``Q̃`` (including the empty
        selection and an all-zero ``Q̃``).

    Notes
    -----
    This is why κ suits point sampling but not near-field images (paper
    §3.1): a repeated cell, or two nearly identical rows (neighbouring pixels
    of one image see almost the same (θh, θd, φd)), make ``Q̃`` exactly or
    nearly rank deficient whenever ``n ≤ k``, driving κ to inf or to a huge
    value, although the extra observation can only add information — the
    expected error :func:`expected_error` does not have this defect.  For
    ``n > k`` duplicates no longer force rank deficiency, but near-duplicate
    blocks still leave ``σ_min`` tiny, so κ cannot rank such selections.
    """
    A = np.asarray(Qrows_or_G, dtype=np.float64)
    if A.ndim != 2:
        raise ValueError(f"condition_number needs a 2-D array, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("condition_number: input must be finite")
    if method not in ("gram", "svd"):
        raise ValueError(f"method must be 'gram' or 'svd', got {method!r}")
    eps = np.finfo(np.float64).eps
    if n is not None:
        if method != "gram":
            raise ValueError("method='svd' needs the rows Q̃, not a Gram matrix")
        n = int(n)
        if n < 0:
            raise ValueError(f"n must be ≥ 0, got {n}")
        if A.shape[0] != A.shape[1]:
            raise ValueError(f"with n given the input must be a (k, k) Gram matrix, got shape {A.shape}")
        k = A.shape[0]
        if n == 0:
            return float("inf")
        lam = scipy.linalg.eigvalsh(A, check_finite=False)[::-1][: min(n, k)]  # the min(n, k) largest
    else:
        n, k = A.shape
        if k == 0:
            raise ValueError("Q̃ must have k ≥ 1 columns")
        if n == 0:
            return float("inf")
        if method == "svd":
            s = scipy.linalg.svdvals(A, check_finite=False)
            tol = (max(n, k) * eps) if rtol is None else float(rtol)
            if s[0] <= 0 or s[-1] <= tol * s[0]:
                return float("inf")
            return float(s[0] / s[-1])
        small = _gram(A.T) if n <= k else _gram(A)  # the smaller of Q̃Q̃ᵀ and Q̃ᵀQ̃
        lam = scipy.linalg.eigvalsh(small, check_finite=False)[::-1]
    tol = np.sqrt(max(n, k) * eps) if rtol is None else float(rtol)
    lam_max, lam_min = float(lam[0]), float(lam[-1])
    if lam_max <= 0 or lam_min <= (tol**2) * lam_max:
        return float("inf")
    return float(np.sqrt(lam_max / lam_min))


def condition_number_first_n(Qrows: ArrayLike) -> float:
    """Nielsen et al. 2015's κ as their released code computes it: the first n components only.

    For the n selected rows ``Q̃`` (n × k) the code's ``CondNum`` conditions
    the n × n matrix of those rows and the first ``n`` columns of ``Q``
    (``usePrimaryColumnsOnly``), so the i-th sample is paired with the i-th
    principal component; with more rows than components (n > k) it is the
    all-k κ of :func:`condition_number`.  A single sample gives a 1 × 1
    matrix, whose ``CondNum`` is ``1 / |q₁₁|`` (the code's rule for one
    value; it then favours the row of largest first component).  κ of the
    square matrix from its singular values (rank tolerance ``n · ε``, as
    :func:`condition_number`'s ``"svd"``); ``inf`` when singular or empty.

    Unlike eq. 6 over all k, it ignores what the rows say about components
    n + 1 … k: two rows equal in their first n components give ``inf`` even
    when they differ beyond, and rows that differ only there do not help.
    """
    A = np.asarray(Qrows, dtype=np.float64)
    if A.ndim != 2 or A.shape[1] == 0:
        raise ValueError(f"condition_number_first_n needs an (n, k) array with k ≥ 1, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("condition_number_first_n: input must be finite")
    n, k = A.shape
    if n == 0:
        return float("inf")
    if n > k:
        return condition_number(A, method="svd")
    if n == 1:
        return float("inf") if A[0, 0] == 0 else float(1.0 / abs(A[0, 0]))
    return condition_number(A[:, :n], method="svd")
