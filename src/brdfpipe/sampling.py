"""Minimal BRDF sampling (Xu et al. 2016, "Minimal BRDF Sampling for Two-Shot
Near-Field Reflectance Acquisition"): error metrics.

This module will hold the whole sampling stage.  The part here is the
**metrics** section: the expected error of a selection of cells (the paper's
eq. 15), its fast sufficient-statistics form, the literal p-space formula it
is checked against, the condition-number baseline of Nielsen et al. 2015
(eq. 6), and the regularised reconstruction of eq. 4.  The acquisition
geometry (which cells one near-field image observes) and the optimiser are
added in later sections; they build on the names defined here, which are
therefore kept stable.

Notation (paper §3)
-------------------
``X`` (m × p): log-mapped training BRDFs, one row per material-channel, one
column per cell; ``μ`` its column mean.  ``X − μ̂ = U Σ Vᵀ`` (thin SVD, ``k``
components kept), ``Q = V Σ`` (p × k), so ``QᵀQ = Σ²`` and the training
residuals are ``y_i = x_i − μ = Q u_i`` with ``u_i`` row *i* of ``U``
(exactly so when ``k`` is the rank of the centred ``X``; see
:func:`direct_training_error` for a truncated ``k``).

A *selection* ``S`` (n × p) picks ``n`` rows of ``Q`` – observations, a cell
may be observed more than once – giving ``Q̃ = S Q`` (n × k).  Its regularised
inverse is ``(SQ)⁺_η = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ`` (eq. 5), ``η = 40`` by default.

Everything a metric needs from a selection is its pair of **sufficient
statistics** (:func:`selection_stats`)::

    G    = Q̃ᵀQ̃  = Σ_rows q qᵀ     (k × k Gram matrix)
    qsum = Q̃ᵀ 1  = Σ_rows q        (k,)

Both are sums over the selected rows, so adding or removing a block of rows
(one near-field image, one point direction) is an O(n_block·k²) update
(:func:`add_rows`, :func:`remove_rows`); an optimiser keeps ``(G, qsum)`` for
its current selection and evaluates candidates from them.

Conventions: all arithmetic is float64 whatever the input dtype (the model
stores ``Q`` as float32); functions never modify their arguments; invalid
shapes or parameters raise :class:`ValueError`.

Performance note: the numpy and scipy wheels each bundle their *own*
OpenBLAS, each with its own thread pool.  Alternating calls into the two
(e.g. a numpy ``Bᵀ @ B`` then a scipy Cholesky, as an optimiser loop would)
makes the idle pool's spinning threads compete with the active one: on the
shared 2-core development machine, "add an 800-row block, then evaluate E"
at k = m = 270 took 8.0 ms that way against 3.2 ms with scipy only.  The
per-candidate functions here (:func:`selection_stats`, :func:`add_rows`,
:func:`remove_rows`, :func:`expected_error`, :func:`condition_number`)
therefore use scipy's BLAS/LAPACK only (``dsyrk``, ``dgemm``,
``cho_factor``/``cho_solve``, ``eigvalsh``, ``svdvals``).  Multithreaded
OpenBLAS is also erratic on a loaded machine (single evaluations from 1 ms
to > 100 ms were seen while another job ran); an optimiser there is better
run with ``OPENBLAS_NUM_THREADS=1``, parallel over candidates if at all
(single-threaded: ~1.3–1.8 ms per evaluation at k = m = 270, stable).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg
import scipy.linalg.blas
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DEFAULT_ETA",
    "ErrorModel",
    "add_rows",
    "condition_number",
    "direct_training_error",
    "empty_stats",
    "expected_error",
    "expected_error_literal",
    "expected_error_terms",
    "reconstruct_coefficients",
    "remove_rows",
    "selection_stats",
]

F64 = NDArray[np.float64]

#: The paper's Tikhonov regularisation weight (§3, eq. 4): "we set η = 40".
DEFAULT_ETA: float = 40.0

#: Rows of ``Q`` processed at a time by the p-space functions (bounds memory to
#: a few × block·max(k, m) float64 values).
_P_BLOCK: int = 32_768


# ===========================================================================
# Metrics
# ===========================================================================
#
# Derivation of the fast form of eq. 15 (also in ErrorModel's docstring)
# ----------------------------------------------------------------------
# Let Q = VΣ with VᵀV = I, so QᵀQ = Σ² and Q⁺ = Σ⁻¹Vᵀ (Σ⁺ where σ = 0), and
# let y_i = Q u_i.  With Q̃ = SQ, G = Q̃ᵀQ̃, M = G + ηI (symmetric positive
# definite for η > 0):
#
#   Q⁺ y_i             = Σ⁻¹VᵀVΣ u_i           = u_i        (σ > 0)
#   (SQ)⁺_η S y_i      = M⁻¹ Q̃ᵀ (S Q u_i)      = M⁻¹ G u_i
#   (Q⁺ − (SQ)⁺_η S) y_i = (I − M⁻¹G) u_i = M⁻¹(M − G) u_i = η M⁻¹ u_i
#
# and, for any k-vector w, ‖Q w‖² = wᵀQᵀQw = wᵀΣ²w = ‖Σ w‖², so
#
#   ‖Q (Q⁺ − (SQ)⁺_η S) y_i‖ = η ‖Σ M⁻¹ u_i‖.
#
# Noise term: S O = 1 (n ones), so (SQ)⁺_η S O = M⁻¹ Q̃ᵀ 1 = M⁻¹ qsum and
#
#   ‖Q (SQ)⁺_η S O‖ = ‖Σ M⁻¹ qsum‖.
#
# Hence E(S) = (η/m) Σ_i ‖Σ M⁻¹ u_i‖ + β ‖Σ M⁻¹ qsum‖, which depends on S only
# through (G, qsum) and costs one Cholesky factorisation of M (k³/3) plus a
# solve with m + 1 right-hand sides (2k²(m + 1)): no p-dimensional vector.
# Components with σ_j = 0 (the direction removed by centring when k = m) need
# no special case: column j of Q is zero, so G has a zero row/column j, and
# the factor σ_j = 0 removes it from both norms – the same as Q⁺ = Σ⁺Vᵀ.


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
        eta = _check_eta(self.eta)
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


def _check_eta(eta: float) -> float:
    eta = float(eta)
    if not np.isfinite(eta) or eta <= 0:
        raise ValueError(f"eta must be finite and > 0, got {eta!r}")
    return eta


def _as_rows(Qrows: ArrayLike, k: int | None = None, name: str = "Qrows") -> F64:
    """A 2-D float64 (n, k) view/copy of a block of Q rows (1-D = one row)."""
    B = np.asarray(Qrows, dtype=np.float64)
    if B.ndim == 1:
        B = B[None, :]
    if B.ndim != 2:
        raise ValueError(f"{name} must be an (n, k) array of Q rows, got shape {B.shape}")
    if k is not None and B.shape[1] != k:
        raise ValueError(f"{name} has {B.shape[1]} columns, expected k = {k}")
    if B.shape[1] == 0:
        raise ValueError(f"{name} must have k ≥ 1 columns")
    if not np.all(np.isfinite(B)):
        raise ValueError(f"{name} must be finite")
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
    return np.tril(c) + np.tril(c, -1).T


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


def add_rows(G: ArrayLike, qsum: ArrayLike, Qrows: ArrayLike) -> tuple[F64, F64]:
    """Statistics after adding a block of rows: ``(G + BᵀB, qsum + Bᵀ1)``.

    Returns new arrays; ``G`` and ``qsum`` are not modified.  Adding a row
    that is already selected counts it twice (a repeated observation).
    """
    G, qsum = _check_stats(G, qsum)
    B = _as_rows(Qrows, G.shape[0])
    return G + _gram(B), qsum + B.sum(axis=0)


def remove_rows(G: ArrayLike, qsum: ArrayLike, Qrows: ArrayLike) -> tuple[F64, F64]:
    """Statistics after removing a block of rows: ``(G − BᵀB, qsum − Bᵀ1)``.

    The rows must have been added before (this is not checked: ``(G, qsum)``
    do not remember which rows they came from).  Long add/remove sequences
    accumulate rounding error of order ε·‖G‖ per update; an optimiser should
    recompute :func:`selection_stats` from its current rows now and then.
    """
    G, qsum = _check_stats(G, qsum)
    B = _as_rows(Qrows, G.shape[0])
    return G - _gram(B), qsum - B.sum(axis=0)


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
        (:func:`selection_stats`, :func:`add_rows`); ``qsum`` is only used
        when ``β > 0``.

    Returns
    -------
    float
        ``(η/m) Σ_i ‖Σ M⁻¹ u_i‖ + β ‖Σ M⁻¹ qsum‖`` with ``M = G + ηI``, equal
        to the p-space formula (:func:`expected_error_literal`) in exact
        arithmetic.  Cost O(k³/3 + 2k²m): one Cholesky factorisation of ``M``
        (``scipy.linalg.cho_factor``) and one solve with m (+1) right-hand
        sides; about a millisecond at k = m = 270.

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
    eta = _check_eta(eta)
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
    """Nielsen et al.'s baseline metric κ(Q̃) = σ_max(Q̃) / σ_min(Q̃) (eq. 6).

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


# ---------------------------------------------------------------------------
# p-space reference computations (tests, benches, acceptance checks)
# ---------------------------------------------------------------------------


def _as_q(Q: ArrayLike) -> NDArray[np.floating]:
    Qa = np.asarray(Q)
    if Qa.ndim != 2 or Qa.shape[0] == 0 or Qa.shape[1] == 0:
        raise ValueError(f"Q must be a non-empty (p, k) array, got shape {Qa.shape}")
    if not np.issubdtype(Qa.dtype, np.floating):
        Qa = Qa.astype(np.float64)
    return Qa


def _as_selection(S_rows: ArrayLike, p: int) -> NDArray[np.intp]:
    idx = np.asarray(S_rows)
    if idx.ndim != 1:
        raise ValueError(f"S_rows must be a 1-D array of row (cell column) indices, got shape {idx.shape}")
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"S_rows must hold integers, got dtype {idx.dtype}")
    idx = idx.astype(np.intp)
    if idx.size and (idx.min() < 0 or idx.max() >= p):
        raise ValueError(f"S_rows out of range [0, {p})")
    return idx


def _blocks(p: int, block: int) -> range:
    if block < 1:
        raise ValueError(f"block must be ≥ 1, got {block}")
    return range(0, p, block)


def expected_error_literal(
    Q: ArrayLike,
    U_or_Y: ArrayLike,
    S_rows: ArrayLike,
    eta: float = DEFAULT_ETA,
    beta: float = 0.0,
    mean: ArrayLike | None = None,
    *,
    kind: Literal["auto", "coefficients", "residuals"] = "auto",
    block: int = _P_BLOCK,
    return_terms: bool = False,
) -> float | tuple[float, float]:
    """E(S) of eq. 15 evaluated literally, with p-dimensional vectors.

    For tests and benchmarks only: cost O(m·p·k + p·k²) time — ≈ 8e10 flops
    at p = 1.1M, k = m = 270 — where :func:`expected_error` needs O(k³).
    Memory is bounded by processing ``block`` rows of ``Q`` at a time.

    The steps follow the formula as written, in p-space:

    1. ``Q⁺ = (QᵀQ)⁺ Qᵀ`` — the Moore–Penrose pseudo-inverse of ``Q``
       (``= Σ⁻¹Vᵀ`` for ``Q = VΣ``), with ``QᵀQ`` accumulated from the rows of
       ``Q`` and pseudo-inverted by ``numpy.linalg.pinv`` (so zero singular
       values are dropped, as in a pseudo-inverse);
    2. ``(SQ)⁺_η = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ`` with ``Q̃ = Q[S_rows]`` (``numpy.linalg.solve``);
    3. for every material, the p-vector ``r_i = Q (Q⁺ y_i − (SQ)⁺_η (S y_i))``,
       ``S y_i = y_i[S_rows]``, and its Euclidean norm;
    4. the p-vector ``Q (SQ)⁺_η 1`` (``S O = 1``) and its norm;

    and returns ``mean_i ‖r_i‖ + β ‖Q (SQ)⁺_η 1‖``.

    Parameters
    ----------
    Q:
        (p, k) principal components ``VΣ`` (float32 or float64).
    U_or_Y:
        Either (m, k) coefficients ``u_i`` (then ``y_i = Q u_i`` is formed in
        p-space), or (m, p) residuals ``y_i`` — or raw rows ``x_i`` when
        ``mean`` is given (``y_i = x_i − mean``).
    S_rows:
        (n,) integer row indices into ``Q`` (cells; repeats allowed, n ≥ 0).
    eta, beta:
        η > 0 and β ≥ 0 of eq. 15.
    mean:
        (p,) mean ``μ`` to subtract from (m, p) rows; only with residual input.
    kind:
        How to read ``U_or_Y``: ``"coefficients"`` (m, k), ``"residuals"``
        (m, p), or ``"auto"`` (by its width; ambiguous, hence an error, when
        p = k).
    block:
        Rows of ``Q`` per block.
    return_terms:
        Return ``(E_recon, E_noise/β)`` — the reconstruction term and the
        noise term for unit β, as :func:`expected_error_terms` — instead of
        ``E_recon + β·E_noise/β`` (one pass gives E for every β).

    Notes
    -----
    With coefficient input this equals :func:`expected_error` in exact
    arithmetic for any ``Q``.  With residual input it does so only if every
    ``y_i`` lies in the column space of ``Q`` (``k`` = rank of the centred
    training matrix); for a truncated ``k`` the out-of-subspace part of
    ``y_i`` enters ``S y_i`` and the two differ.
    """
    eta = _check_eta(eta)
    beta = float(beta)
    if not np.isfinite(beta) or beta < 0:
        raise ValueError(f"beta must be finite and ≥ 0, got {beta!r}")
    Qa = _as_q(Q)
    p, k = Qa.shape
    Z = np.asarray(U_or_Y)
    if Z.ndim != 2 or Z.shape[0] == 0:
        raise ValueError(f"U_or_Y must be a non-empty 2-D array, got shape {Z.shape}")
    if kind == "auto":
        if p == k:
            raise ValueError("U_or_Y is ambiguous when p == k: pass kind='coefficients' or 'residuals'")
        if Z.shape[1] == k:
            kind = "coefficients"
        elif Z.shape[1] == p:
            kind = "residuals"
        else:
            raise ValueError(f"U_or_Y must have k = {k} or p = {p} columns, got {Z.shape}")
    if kind == "coefficients":
        if Z.shape[1] != k:
            raise ValueError(f"coefficients must have shape (m, {k}), got {Z.shape}")
        if mean is not None:
            raise ValueError("mean applies to (m, p) rows, not to coefficients")
    elif kind == "residuals":
        if Z.shape[1] != p:
            raise ValueError(f"residuals must have shape (m, {p}), got {Z.shape}")
    else:
        raise ValueError(f"kind must be 'auto', 'coefficients' or 'residuals', got {kind!r}")
    mu: F64 | None = None
    if mean is not None:
        mu = np.asarray(mean, dtype=np.float64)
        if mu.shape != (p,):
            raise ValueError(f"mean must have shape ({p},), got {mu.shape}")
    idx = _as_selection(S_rows, p)
    m = Z.shape[0]
    Zc = np.asarray(Z, dtype=np.float64) if kind == "coefficients" else None

    def y_block(a: int, b: int) -> F64:
        """Residuals y_i over rows a:b of Q, as an (m, b − a) array."""
        if Zc is not None:
            return Zc @ np.asarray(Qa[a:b], dtype=np.float64).T
        yb = np.asarray(Z[:, a:b], dtype=np.float64)
        return yb - mu[a:b] if mu is not None else yb

    # 1. Q⁺ = (QᵀQ)⁺ Qᵀ.
    qtq = np.zeros((k, k))
    for a in _blocks(p, block):
        Qb = np.asarray(Qa[a : a + block], dtype=np.float64)
        qtq += Qb.T @ Qb
    qtq_pinv = np.linalg.pinv(qtq, hermitian=True)
    # 2. (SQ)⁺_η.
    Qt = np.asarray(Qa[idx], dtype=np.float64).reshape(idx.size, k)
    reg_inv = np.linalg.solve(Qt.T @ Qt + eta * np.eye(k), Qt.T)  # (k, n)
    # 3. coefficients Q⁺ y_i (a p-space product) and (SQ)⁺_η S y_i, per material.
    c_full = np.zeros((k, m))
    for a in _blocks(p, block):
        b = min(a + block, p)
        q_pinv_block = qtq_pinv @ np.asarray(Qa[a:b], dtype=np.float64).T  # columns a:b of Q⁺
        c_full += q_pinv_block @ y_block(a, b).T
    if Zc is not None:
        s_y = Zc @ Qt.T  # (m, n): y_i at the selected rows
    else:
        s_y = np.asarray(Z[:, idx], dtype=np.float64).reshape(m, idx.size)
        if mu is not None:
            s_y = s_y - mu[idx]
    c_bar = reg_inv @ s_y.T
    diff = c_full - c_bar
    noise_c = reg_inv @ np.ones(idx.size)
    # 4. p-space error vectors and their norms.
    sq = np.zeros(m)
    noise_sq = 0.0
    for a in _blocks(p, block):
        Qb = np.asarray(Qa[a : a + block], dtype=np.float64)
        r = Qb @ diff  # (block, m): rows a:b of every r_i
        sq += np.einsum("ij,ij->j", r, r)
        v = Qb @ noise_c
        noise_sq += float(v @ v)
    recon, noise = float(np.mean(np.sqrt(sq))), float(np.sqrt(noise_sq))
    if return_terms:
        return recon, noise
    return recon + beta * noise


def direct_training_error(
    Q: ArrayLike,
    U: ArrayLike,
    sigma: ArrayLike,
    mean: ArrayLike,
    X_train: ArrayLike,
    S_rows: ArrayLike,
    eta: float = DEFAULT_ETA,
    *,
    block: int = _P_BLOCK,
) -> float:
    """Mean reconstruction error of the training rows, recomputed directly in p-space.

    Each training row ``x_i`` is reconstructed from its own observations at
    the selected cells exactly as an acquisition would: ``ỹ = S(x_i − μ)``,
    ``c̄_i = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ ỹ`` (eq. 4, :func:`reconstruct_coefficients`),
    and the result is ``(1/m) Σ_i ‖y_i − Q c̄_i‖`` with ``y_i = x_i − μ``.
    Nothing of the SVD but ``Q`` enters the computation: it is the acceptance
    check of :func:`expected_error`, which it equals (β = 0) when the
    training rows lie in the column space of ``Q`` — i.e. ``k`` is the rank of
    the centred training matrix, up to the precision ``Q``, ``μ`` and
    ``X_train`` are stored in.  With a truncated ``k`` it is larger in
    general: it also contains the deviation error of eq. 9 and the effect of
    the out-of-subspace part of ``x_i`` on its observations.

    Parameters
    ----------
    Q:
        (p, k) principal components.
    U, sigma:
        (m, k) and (k,) of the same SVD; only checked for consistent shapes
        (``m`` rows of ``X_train``, ``k`` columns of ``Q``).
    mean:
        (p,) column mean ``μ`` of the training matrix.
    X_train:
        (m, p) log-mapped training rows ``x_i`` (float32 or float64).
    S_rows:
        (n,) selected row (cell column) indices, repeats allowed.
    eta:
        Tikhonov weight η > 0.
    block:
        Columns processed at a time (memory bound).

    Cost O(m·p·k); memory O(block·(m + k)) beyond the inputs.
    """
    eta = _check_eta(eta)
    Qa = _as_q(Q)
    p, k = Qa.shape
    Ua = np.asarray(U)
    sa = np.asarray(sigma)
    X = np.asarray(X_train)
    if sa.shape != (k,):
        raise ValueError(f"sigma must have shape ({k},) to match Q, got {sa.shape}")
    if X.ndim != 2 or X.shape[1] != p or X.shape[0] == 0:
        raise ValueError(f"X_train must have shape (m, {p}), got {X.shape}")
    m = X.shape[0]
    if Ua.shape != (m, k):
        raise ValueError(f"U must have shape ({m}, {k}) to match X_train and Q, got {Ua.shape}")
    mu = np.asarray(mean, dtype=np.float64)
    if mu.shape != (p,):
        raise ValueError(f"mean must have shape ({p},), got {mu.shape}")
    idx = _as_selection(S_rows, p)
    Qt = np.asarray(Qa[idx], dtype=np.float64).reshape(idx.size, k)
    y_obs = (np.asarray(X[:, idx], dtype=np.float64).reshape(m, idx.size) - mu[idx]).T  # (n, m)
    if idx.size == 0:
        c_bar = np.zeros((k, m))
    else:
        c_bar = reconstruct_coefficients(Qt, y_obs, eta)  # (k, m)
    sq = np.zeros(m)
    for a in _blocks(p, block):
        b = min(a + block, p)
        yb = np.asarray(X[:, a:b], dtype=np.float64) - mu[a:b]  # (m, b − a)
        r = yb - (np.asarray(Qa[a:b], dtype=np.float64) @ c_bar).T
        sq += np.einsum("ij,ij->i", r, r)
    return float(np.mean(np.sqrt(sq)))


# ===========================================================================
# Acquisition geometry (to come)
# ===========================================================================

# ===========================================================================
# Optimiser (to come)
# ===========================================================================
