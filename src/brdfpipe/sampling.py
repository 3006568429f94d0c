"""Minimal BRDF sampling (Xu et al. 2016, "Minimal BRDF Sampling for Two-Shot
Near-Field Reflectance Acquisition"): error metrics, acquisition geometry and
the direction optimiser.

This module holds the whole sampling stage, in three sections:

* **Metrics**: the expected error of a selection of cells (the paper's
  eq. 15), its fast sufficient-statistics form, the literal p-space formula
  it is checked against, the condition-number baseline of Nielsen et al.
  2015 (eq. 6), and the regularised reconstruction of eq. 4.
* **Acquisition geometry**: setups (:class:`Setup`: point, nearfield,
  fixed_camera, fixed_light) and which MERL cells one configuration — a
  point sample or a near-field image — observes (:func:`observation_cells`).
* **Optimiser**: the greedy few-to-many search of §5 (:func:`optimize`) and
  the directions files (:func:`write_directions`, :func:`read_directions`).

The later sections build on the names of the metrics section, which are
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
:class:`FactoredSelection` — many candidates evaluated against one
factorisation by low-rank updates, for the optimiser — likewise keeps
its k-sized products in scipy (``cho_solve``, ``dgemm``, ``dgemv``); numpy
does only element-wise work and the small r × r systems of a batch.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NamedTuple, Protocol

import numpy as np
import scipy.linalg
import scipy.linalg.blas
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import atomic
from brdfpipe.data import merl
from brdfpipe.core.version import full_version

__all__ = [
    "DEFAULT_ETA",
    "ErrorModel",
    "add_rows",
    "condition_number",
    "direct_training_error",
    "empty_stats",
    "expected_error",
    "FactoredSelection",
    "RowBlock",
    "expected_error_literal",
    "expected_error_terms",
    "reconstruct_coefficients",
    "remove_rows",
    "selection_stats",
    # acquisition geometry
    "SETUP_KINDS",
    "DEFAULT_GRID",
    "Config",
    "Setup",
    "centre_directions",
    "pixel_directions",
    "observation_cells",
    "config_to_dict",
    "config_from_dict",
    # optimiser
    "DIRECTIONS_FORMAT",
    "DirectionSet",
    "Directions",
    "optimize",
    "write_directions",
    "read_directions",
    "optimize_to_file",
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
# is below _DOWNDATE_TOL the base minus the block is factored afresh instead
# (one Cholesky per batch).  (3) Blocks with so many rows that the low-rank
# form costs more flops than a fresh evaluation (r ≳ 100 at k = m = 270:
# near-field images) are evaluated fresh (:func:`expected_error`).  Rows
# observed c times are passed once with count c (weight √c), which makes both
# forms cheaper.  The result agrees with expected_error to ~1e-13 relative.
#
# A selection derived from another (:meth:`FactoredSelection.updated`: a
# block added and/or removed, as an optimiser's set changes) gets a fresh
# Cholesky factor but its solve from the parent's by the exact identity
#   M_new⁻¹ = M_old⁻¹ − M_new⁻¹ VᵀDV M_old⁻¹,   i.e. W_new = W_old − Y D (V W_old), Y = M_new⁻¹Vᵀ
# (2k²r + 2krm flops instead of 2k²m).  Such chains are counted (``depth``)
# so that a caller can rebuild from scratch now and then, bounding the
# rounding they accumulate.

#: A squared norm updated by the expansion above is recomputed from its vector
#: when it is below this fraction of the magnitude of its terms.
_CANCEL_TOL: float = 1e-3
#: A removed block is downdated by the Woodbury form only if the smallest
#: eigenvalue of I − R_j M0⁻¹R_jᵀ (= (I + R_j M_{−j}⁻¹R_jᵀ)⁻¹) is at least this.
_DOWNDATE_TOL: float = 1e-3
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
        self._W: F64 | None = None  # M⁻¹Uᵀ (k, m)
        self._w: F64 | None = None  # M⁻¹qsum (k,), only when β > 0
        self._nnW: F64 | None = None  # NᵀN W (k, m)
        self._a2: F64 | None = None  # ‖N W_i‖² (m,)

    # -- factorisation and solve, on first use ----------------------------------

    def _factor(self) -> tuple[F64, bool]:
        if self._cf is None:
            self._cf = _cho_M(self.G, self.model.eta)
        return self._cf

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

    def _prepared(self) -> tuple[F64, F64, F64]:
        """``(W, NᵀN W, ‖N W_i‖²)``: the per-base quantities of the low-rank form."""
        W, _ = self._solve()
        if self._nnW is None or self._a2 is None:
            self._nnW = self._nn(W)
            self._a2 = np.einsum("ki,ki->i", W, self._nnW)
        return W, self._nnW, self._a2

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
            V = np.concatenate([blk.Rw for blk, _ in parts], axis=0)
            d = np.concatenate([np.full(blk.r, sign) for blk, sign in parts])
            s = np.concatenate([blk.s for blk, _ in parts])
            Y = scipy.linalg.cho_solve(new._factor(), np.asfortranarray(V.T), check_finite=False)  # M_new⁻¹Vᵀ
            VW = scipy.linalg.blas.dgemm(1.0, V, self._W)  # (r, m)
            new._W = scipy.linalg.blas.dgemm(-1.0, Y, d[:, None] * VW, 1.0, self._W)  # W − Y D V W
            if self._w is not None:
                Vw = scipy.linalg.blas.dgemv(1.0, V, self._w)
                new._w = scipy.linalg.blas.dgemv(-1.0, Y, d * (Vw - s), 1.0, self._w)
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
                    base = self._updated([(rem, -1.0)])
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
        W, nnW, a2 = self._prepared()
        _, w0 = self._solve()
        k, m = em.k, em.m
        t, rc = len(cands), cands[0].r
        rj = 0 if rem is None else rem.r
        r, n = rc + rj, t * rc
        # All update rows stacked: the candidates' (n) then the removed block's (rj).
        X = np.concatenate([c.Rw for c in cands] + ([rem.Rw] if rem is not None else []), axis=0)
        Z = scipy.linalg.cho_solve(self._factor(), np.asfortranarray(X.T), check_finite=False)  # M0⁻¹Xᵀ
        Y = self._nn(Z)
        if rem is not None:
            K = np.eye(rj) - scipy.linalg.blas.dgemm(1.0, X[n:], Z[:, n:])
            lam = float(K[0, 0]) if rj == 1 else float(scipy.linalg.eigvalsh(0.5 * (K + K.T), check_finite=False)[0])
            if not lam >= _DOWNDATE_TOL:
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
    directions; the figures label this baseline "min κ (Xu eq. 6)".)

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
    eta = check_eta(eta)
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
    eta = check_eta(eta)
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
# Acquisition geometry
# ===========================================================================
#
# Which MERL cells one acquisition *configuration* observes.  Four setups:
#
# point (Nielsen et al. 2015)
#     One BRDF sample per configuration.  A configuration is a MERL cell
#     (iθh, iθd, iφd); its observation is that cell.  Centre directions: the
#     cell centre (merl.cell_centres) with φh = 0.
#
# nearfield (Xu et al. 2016 §5.2, Fig. 4)
#     A pinhole camera at C = R·wo (R = 1: only ν = r/R matters) looks at the
#     centre of a flat disk of radius r = ν = tan(α/2) (α = fov); the light is
#     distant, direction wi for every point of the disk.  A configuration is a
#     MERL cell (iθh, iθd, iφd): the cell of the *centre pixel*; wi and wo are
#     the cell centre's directions (φh = 0).  Every other pixel sees the disk
#     point P its ray hits and the view direction normalize(C − P), hence its
#     own (θh, θd, φd) cell.
#
# fixed_camera / fixed_light (Xu §8)
#     n images share the camera (resp. light) direction.  The BRDF is
#     isotropic and the disk rotationally symmetric, so only the shared
#     direction's elevation and each image's other direction *relative to it*
#     matter: the shared direction is put at azimuth 0 and a configuration is
#     three grid indices (i_shared, i_theta, i_phi):
#
#         shared direction  (θ = i_shared · 1°,  φ = 0)             i_shared ∈ [0, 90)
#         other direction   (θ = i_theta · 1°,   φ = i_phi · 2°)     i_theta ∈ [0, 90), i_phi ∈ [0, 180)
#
#     (fixed_camera: camera = shared, light = other; fixed_light: the
#     reverse).  All images of one set carry the same i_shared.  An other
#     direction at the zenith (i_theta = 0) has no azimuth: only i_phi = 0 is
#     a valid configuration there.  (With the shared direction at the zenith,
#     configurations differing in i_phi only are rotations of one another
#     about z: the same cells up to the pixel lattice's orientation.)  Each image is rendered with the near-field
#     pixel model above at the configured fov; its "cell" (reported like the
#     other setups') is that of its centre pixel.  Integer-degree directions
#     often sit on a MERL bin edge (θd and φd bins are 1° wide), so which of
#     two neighbouring cells a pixel falls in is decided by rounding — the
#     same way every time.
#
# The near-field pixel model
# --------------------------
# The image is square with half-angle α/2: tangent-plane coordinates
# (u, v) ∈ [−ν, ν]², so at the zenith the disk exactly fills it.  Pixel centres
# lie on a grid × grid lattice of pitch Δ = 2ν/grid *centred on the optical
# axis*: u = (i − ⌊grid/2⌋)·Δ, i = 0 … grid − 1 (for an even grid the lattice
# has one more column on the negative side, which lies on the image border) —
# so there always is a centre pixel, looking exactly along −wo.  Camera frame:
# forward f = −wo, right e_r = (−sin φo, cos φo, 0) (horizontal, normal to the
# camera's plane of incidence; φo = atan2(wo_y, wo_x), 0 at the zenith), up
# e_u = e_r × f.  The ray f + u·e_r + v·e_u from C meets the plane z = 0 at P
# (rays with non-negative z component never do and are dropped); a pixel is
# kept iff |P| ≤ r.  At the zenith ≈ π/4·grid² pixels are kept (795 of 1024 for
# grid 32).  Oblique cameras see the disk foreshortened into an ellipse and
# keep fewer pixels (708 at 30°, 420 at 60°, 154 at 80° for 25°/32).
#
# Angles: at the zenith every kept ray is within α/2 of the optical axis.  An
# oblique camera's disk image is not exactly inside the cone of half-angle
# α/2: the disk lies inside the ball of radius ν about the origin, which
# subtends asin(ν) from C, and points on the near side of the disk reach up
# to that bound (12.81° against α/2 = 12.5° at 25°); the square image still
# clips them at |u|, |v| ≤ ν.
#
# The observed cells are cell_index(wi, view) of the kept pixels, in lattice
# order, with repeats (neighbouring pixels often share a cell; every pixel is
# one observation row).  Cells outside the *valid* set are dropped: by default
# the geometrically measured cells (merl.measured_mask: both directions of the
# cell centre above the horizon); the optimiser passes the model's columns.


#: The acquisition setups.
SETUP_KINDS: tuple[str, ...] = ("point", "nearfield", "fixed_camera", "fixed_light")
#: Default pixel lattice (grid × grid) of an image setup.
DEFAULT_GRID: int = 32
_MAX_GRID: int = 4096

#: A configuration: three non-negative grid indices (see the section comment):
#: (iθh, iθd, iφd) of the centre cell for point / nearfield,
#: (i_shared, i_theta, i_phi) for fixed_camera / fixed_light.
Config = tuple[int, int, int]

_CONFIG_DIMS: tuple[int, int, int] = (merl.N_THETA_H, merl.N_THETA_D, merl.N_PHI_D)  # (90, 90, 180) for all setups
_FIXED_THETA_DEG: float = 1.0  # elevation steps of fixed_* (shared and per image)
_FIXED_PHI_DEG: float = 2.0  # azimuth steps of fixed_* (per image)
_IMAGE_KINDS = frozenset({"nearfield", "fixed_camera", "fixed_light"})
_FIXED_KINDS = frozenset({"fixed_camera", "fixed_light"})


@dataclass(frozen=True)
class Setup:
    """An acquisition setup: kind, field of view (degrees) and pixel lattice.

    ``kind`` ∈ :data:`SETUP_KINDS`.  Image setups (``nearfield``,
    ``fixed_camera``, ``fixed_light``) need ``0 < fov_deg < 180`` and a
    ``grid`` ≥ 1 (the image is a ``grid × grid`` lattice); ``point`` needs
    ``fov_deg == 0`` and its ``grid`` is normalised to 1 (one sample per
    configuration).  :class:`ValueError` otherwise.
    """

    kind: str
    fov_deg: float = 0.0
    grid: int = DEFAULT_GRID

    def __post_init__(self) -> None:
        if self.kind not in SETUP_KINDS:
            raise ValueError(f"setup kind must be one of {SETUP_KINDS}, got {self.kind!r}")
        if isinstance(self.fov_deg, (bool, np.bool_)) or not isinstance(
            self.fov_deg, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"fov_deg must be a number, got {self.fov_deg!r}")
        fov = float(self.fov_deg)
        if isinstance(self.grid, bool) or not isinstance(self.grid, (int, np.integer)):
            raise ValueError(f"grid must be an integer, got {self.grid!r}")
        grid = int(self.grid)
        if self.kind == "point":
            if fov != 0.0:
                raise ValueError(f"a point setup has no field of view: fov_deg must be 0, got {self.fov_deg!r}")
            if grid < 1:
                raise ValueError(f"grid must be ≥ 1, got {grid}")
            grid = 1
        else:
            if not (np.isfinite(fov) and 0.0 < fov < 180.0):
                raise ValueError(f"{self.kind} needs 0 < fov_deg < 180, got {self.fov_deg!r}")
            if not 1 <= grid <= _MAX_GRID:
                raise ValueError(f"grid must lie in [1, {_MAX_GRID}], got {grid}")
        object.__setattr__(self, "fov_deg", fov)
        object.__setattr__(self, "grid", grid)

    @property
    def is_image(self) -> bool:
        """True for the image (near-field) setups."""
        return self.kind in _IMAGE_KINDS

    @property
    def nu(self) -> float:
        """ν = r/R = tan(α/2) (0 for point)."""
        return math.tan(math.radians(self.fov_deg) / 2.0) if self.is_image else 0.0


def _check_config(setup: Setup, config: ArrayLike) -> Config:
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be a Setup, got {type(setup).__name__}")
    try:
        items = tuple(config)  # type: ignore[arg-type]
    except TypeError:
        raise ValueError(f"a configuration is three integer grid indices, got {config!r}") from None
    if len(items) != 3 or any(isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)) for x in items):
        raise ValueError(f"a configuration is three integer grid indices, got {config!r}")
    c = (int(items[0]), int(items[1]), int(items[2]))
    for value, dim in zip(c, _CONFIG_DIMS):
        if not 0 <= value < dim:
            raise ValueError(f"configuration {c} out of range: indices must lie in [0, {_CONFIG_DIMS})")
    if setup.kind in _FIXED_KINDS and c[1] == 0 and c[2] != 0:
        raise ValueError(f"configuration {c}: a direction at the zenith (i_theta = 0) needs i_phi = 0")
    return c


def _flat_cell(c: Config) -> int:
    return (c[0] * merl.N_THETA_D + c[1]) * merl.N_PHI_D + c[2]


def _cell_config(cell: int) -> Config:
    ih, rest = divmod(int(cell), merl.N_THETA_D * merl.N_PHI_D)
    idd, ip = divmod(rest, merl.N_PHI_D)
    return (ih, idd, ip)


def _centre_angles(c: Config) -> tuple[float, float, float]:
    """(θh, θd, φd) in radians of the centre of cell ``c`` (as merl.cell_centres)."""
    th = ((c[0] + 0.5) / merl.N_THETA_H) ** 2 * (0.5 * np.pi)
    td = (c[1] + 0.5) / merl.N_THETA_D * (0.5 * np.pi)
    pd = (c[2] + 0.5) / merl.N_PHI_D * np.pi
    return th, td, pd


def _unit_vectors(theta_deg: ArrayLike, phi_deg: ArrayLike) -> F64:
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    p = np.radians(np.asarray(phi_deg, dtype=np.float64))
    st = np.sin(t)
    return np.stack([st * np.cos(p), st * np.sin(p), np.cos(t)], axis=-1)


def _fixed_directions(kind: str, configs: NDArray[np.intp]) -> tuple[F64, F64]:
    """(wi, wo), each (n, 3), of (n, 3) fixed_* configurations."""
    shared = _unit_vectors(configs[:, 0] * _FIXED_THETA_DEG, 0.0)
    other = _unit_vectors(configs[:, 1] * _FIXED_THETA_DEG, configs[:, 2] * _FIXED_PHI_DEG)
    return (other, shared) if kind == "fixed_camera" else (shared, other)


def _centre_cells(setup: Setup, configs: NDArray[np.intp]) -> NDArray[np.intp]:
    """Centre cells of an (n, 3) array of in-range configurations (vectorised)."""
    configs = np.asarray(configs, dtype=np.intp).reshape(-1, 3)
    if setup.kind in _FIXED_KINDS:
        wi, wo = _fixed_directions(setup.kind, configs)
        return merl.cell_index(wi, wo)
    return (configs[:, 0] * merl.N_THETA_D + configs[:, 1]) * merl.N_PHI_D + configs[:, 2]


def centre_directions(setup: Setup, config: ArrayLike) -> tuple[F64, F64]:
    """Light and camera unit vectors ``(wi, wo)``, each (3,), of a configuration's centre.

    point / nearfield: the centre of cell (iθh, iθd, iφd) with φh = 0
    (:func:`brdfpipe.data.merl.directions_from_half_diff`); fixed_*: the shared
    direction at (i_shared°, azimuth 0) and the other one at
    (i_theta°, 2·i_phi°).  For nearfield and fixed_* ``wo`` is the direction
    from the disk centre to the camera.
    """
    c = _check_config(setup, config)
    if setup.kind in _FIXED_KINDS:
        wi, wo = _fixed_directions(setup.kind, np.asarray([c], dtype=np.intp))
    else:
        wi, wo = merl.directions_from_half_diff(*_centre_angles(c))
    return wi[0], wo[0]


@functools.lru_cache(maxsize=16)
def _lattice(fov_deg: float, grid: int) -> tuple[F64, F64, int]:
    """Tangent-plane pixel coordinates (u, v) of the axis-centred lattice and the centre pixel's index."""
    nu = math.tan(math.radians(fov_deg) / 2.0)
    step = 2.0 * nu / grid
    j = np.arange(grid) - grid // 2
    a, b = np.meshgrid(j, j, indexing="ij")
    u = a.ravel() * step
    v = b.ravel() * step
    for arr in (u, v):
        arr.setflags(write=False)
    return u, v, (grid // 2) * grid + grid // 2


def _pixel_views(setup: Setup, wo: F64) -> F64:
    """View directions (n, 3) of the kept pixels of a camera at ``wo`` (see the section comment)."""
    if wo[2] <= 0.0:
        return np.zeros((0, 3))
    u, v, centre = _lattice(setup.fov_deg, setup.grid)
    nu = setup.nu
    phi = math.atan2(wo[1], wo[0]) if (wo[0] != 0.0 or wo[1] != 0.0) else 0.0
    e_r = np.array([-math.sin(phi), math.cos(phi), 0.0])
    f = -wo
    e_u = np.cross(e_r, f)
    ray = f + u[:, None] * e_r + v[:, None] * e_u
    dz = ray[:, 2]
    hit = dz < 0.0
    t = np.where(hit, -wo[2] / np.where(hit, dz, -1.0), 0.0)
    px = wo[0] + t * ray[:, 0]
    py = wo[1] + t * ray[:, 1]
    keep = hit & (px * px + py * py <= nu * nu * (1.0 + 1e-12))
    view = np.stack([wo[0] - px, wo[1] - py, np.full(px.shape, wo[2])], axis=1)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    view[centre] = wo  # the centre pixel looks exactly along −wo (P = 0)
    return view[keep]


def pixel_directions(setup: Setup, config: ArrayLike) -> tuple[F64, F64]:
    """Light and view directions ``(wi, wo)``, each (n, 3), of every sample of a configuration.

    point: the centre directions (n = 1).  Image setups: one row per kept
    pixel of the near-field pixel model (lattice order; the light is the same
    for every pixel) — before any cell filtering.  Empty (0, 3) arrays when
    the camera is not above the horizon.
    """
    wi, wo = centre_directions(setup, config)
    if not setup.is_image:
        return wi[None, :], wo[None, :]
    view = _pixel_views(setup, wo)
    return np.broadcast_to(wi, view.shape).copy(), view


@functools.lru_cache(maxsize=1)
def _measured_flat() -> NDArray[np.bool_]:
    mask = merl.measured_mask().ravel()
    mask.setflags(write=False)
    return mask


def _as_valid(valid: ArrayLike | None) -> NDArray[np.bool_]:
    if valid is None:
        return _measured_flat()
    mask = np.asarray(valid)
    if mask.dtype != np.bool_ or mask.size != merl.N_CELLS:
        raise ValueError(f"valid must be a boolean mask of all {merl.N_CELLS} cells, got {mask.dtype} {mask.shape}")
    return mask.reshape(-1)


def observation_cells(setup: Setup, config: ArrayLike, valid: ArrayLike | None = None) -> NDArray[np.intp]:
    """MERL cells observed by one configuration, with repeats (one entry per observation).

    point: the configuration's cell.  Image setups: the cell of every kept
    pixel (see the section comment), in lattice order; the centre pixel's
    cell is the configuration's centre cell.  Cells not in ``valid`` — a
    boolean mask over all ``merl.N_CELLS`` cells, default
    :func:`brdfpipe.data.merl.measured_mask` (both directions of the cell centre
    above the horizon) — are dropped; so are all pixels when the light is
    not above the horizon.
    """
    mask = _as_valid(valid)
    c = _check_config(setup, config)
    if not setup.is_image:
        cell = _flat_cell(c)
        return np.array([cell] if mask[cell] else [], dtype=np.intp)
    wi, view = pixel_directions(setup, c)
    if view.shape[0] == 0 or wi[0, 2] <= 0.0:
        return np.zeros(0, dtype=np.intp)
    cells = merl.cell_index(wi, view)
    return cells[mask[cells]]


def _half_diff_deg(wi: F64, wo: F64) -> tuple[float, float, float]:
    th, td, pd = merl.half_diff(wi, wo)
    phi = float(pd[0]) + (np.pi if pd[0] < 0.0 else 0.0)
    return float(np.degrees(th[0])), float(np.degrees(td[0])), float(np.degrees(phi))


def config_to_dict(setup: Setup, config: ArrayLike) -> dict[str, Any]:
    """A JSON-friendly record of a configuration's centre.

    Keys: ``cell`` (flat MERL cell index of the centre pixel / point),
    ``theta_h_deg``, ``theta_d_deg``, ``phi_d_deg`` (the centre's half/difference
    angles in degrees, φd folded into [0, 180]: the cell centre for point and
    nearfield, the exact angles of the centre directions for fixed_*),
    ``light`` and ``camera`` (the centre directions ``wi`` and ``wo`` as
    [x, y, z] unit vectors).
    """
    c = _check_config(setup, config)
    wi, wo = centre_directions(setup, c)
    if setup.kind in _FIXED_KINDS:
        cell = int(merl.cell_index(wi, wo)[0])
        th, td, pd = _half_diff_deg(wi[None, :], wo[None, :])
    else:
        cell = _flat_cell(c)
        th, td, pd = (float(np.degrees(a)) for a in _centre_angles(c))
    return {
        "cell": cell,
        "theta_h_deg": th,
        "theta_d_deg": td,
        "phi_d_deg": pd,
        "light": [float(x) for x in wi],
        "camera": [float(x) for x in wo],
    }


def _vector(record: dict[str, Any], key: str) -> F64:
    v = np.asarray(record.get(key), dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or abs(float(np.linalg.norm(v)) - 1.0) > 1e-6:
        raise ValueError(f"configuration record: {key!r} must be a unit 3-vector, got {record.get(key)!r}")
    return v


def config_from_dict(setup: Setup, record: dict[str, Any]) -> Config:
    """Inverse of :func:`config_to_dict`.

    point / nearfield: from ``cell``.  fixed_*: from the ``light`` and
    ``camera`` vectors (any common rotation about z is allowed): the shared
    direction's elevation and the other direction's elevation and azimuth
    relative to it, rounded to the grid; :class:`ValueError` if the vectors
    are more than 1e-6 off the grid or the record's ``cell`` disagrees.
    """
    if not isinstance(record, dict):
        raise ValueError(f"configuration record must be a dict, got {type(record).__name__}")
    cell = record.get("cell")
    if isinstance(cell, bool) or not isinstance(cell, (int, np.integer)) or not 0 <= int(cell) < merl.N_CELLS:
        raise ValueError(f"configuration record: 'cell' must be a MERL cell index, got {cell!r}")
    if setup.kind not in _FIXED_KINDS:
        return _check_config(setup, _cell_config(int(cell)))
    light, camera = _vector(record, "light"), _vector(record, "camera")
    shared, other = (camera, light) if setup.kind == "fixed_camera" else (light, camera)
    ts = math.degrees(math.acos(min(1.0, max(-1.0, shared[2]))))
    to = math.degrees(math.acos(min(1.0, max(-1.0, other[2]))))
    phi_s = math.degrees(math.atan2(shared[1], shared[0])) if np.hypot(shared[0], shared[1]) > 1e-12 else 0.0
    phi_o = math.degrees(math.atan2(other[1], other[0])) if np.hypot(other[0], other[1]) > 1e-12 else phi_s
    c = (
        int(round(ts / _FIXED_THETA_DEG)),
        int(round(to / _FIXED_THETA_DEG)),
        int(round(((phi_o - phi_s) % 360.0) / _FIXED_PHI_DEG)) % merl.N_PHI_D,
    )
    c = _check_config(setup, c)
    wi, wo = centre_directions(setup, c)
    rot = math.radians(phi_s)
    rz = np.array([[math.cos(rot), -math.sin(rot), 0.0], [math.sin(rot), math.cos(rot), 0.0], [0.0, 0.0, 1.0]])
    if max(np.abs(rz @ wi - light).max(), np.abs(rz @ wo - camera).max()) > 1e-6:
        raise ValueError(f"configuration record is not on the {setup.kind} grid: {record!r}")
    if int(merl.cell_index(wi, wo)[0]) != int(cell):
        raise ValueError(f"configuration record: 'cell' {cell} disagrees with its directions")
    return c


# ===========================================================================
# Optimiser
# ===========================================================================
#
# Greedy few-to-many search of Xu et al. §5.1 (after Nielsen et al. 2015),
# for every setup of the geometry section:
#
# for n = 1 … n_max:
#   1. greedy add: draw t = ``candidates`` distinct random configurations not
#      in the set, uniformly over the valid ones (centre cell a model column,
#      ≥ 1 observation row; for fixed_* with n > 1 the shared elevation is the
#      set's); evaluate each from the current statistics (G, qsum) +
#      add_rows(its observation rows) and add the best;
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
# point (§3.1, Fig. 5) and is left as it is.  Improvements must exceed a
# relative 1e-12, so rounding noise never counts as one (and the search
# cannot cycle).
#
# Cost.  Candidates are evaluated in batches sharing one base
# (FactoredSelection, "Many candidates against one factored base selection"
# in the metrics section): the greedy add's t candidates are the current set
# + their block; a configuration's ≤ 7 moves are the current set − its block
# + the moved block.  The current set's M = G + ηI is factored and solved
# once and carried along as the set changes (fresh Cholesky, solve by the
# update identity; rebuilt from the blocks once per n and every
# _MAX_UPDATE_DEPTH updates).  A point candidate then costs O(k² + km)
# flops — a few stacked triangular solves and dgemm rows — instead of a
# fresh Cholesky + solve with m right-hand sides, O(k³/3 + 2k²m).  Near-field
# images (hundreds of distinct cells, the low-rank form would cost more) are
# still evaluated afresh: their distinct rows (counted, not repeated) in one
# dsyrk, one Cholesky + solve (E), one eigvalsh (κ, more than k rows) — and
# a configuration whose block is too strong to downdate accurately
# (tr G_j > η/_DOWNDATE_TOL) has its moves evaluated against the set without
# it, summed afresh from the other blocks.  scipy's BLAS/LAPACK only for
# k-sized work, see the performance note at the top.  The reported E(S) and
# κ of every set are recomputed from scratch (summarise).  Deterministic for a
# seed (numpy Generator; single-threaded choice, fixed reduction order).

logger = logging.getLogger("brdfpipe.sampling")

#: Format tag of the directions JSON file.
DIRECTIONS_FORMAT: str = "brdfpipe.directions/1"
_METRICS = ("error", "condition")
_REL_IMPROVE: float = 1e-12
_CELL_CACHE_MAX: int = 10_000  # configurations whose observed cells are cached (≤ ~40 MB)
_EVAL_CHUNK_ROWS: int = 4096  # distinct candidate rows gathered from Q at a time (≤ ~9 MB as float64)
_MAX_UPDATE_DEPTH: int = 32  # the current set's statistics are rebuilt after this many derivations
_Q_READ_ROWS: int = 36_450 * 4
_AXIS_NAMES = {
    "point": ("iθh", "iθd", "iφd"),
    "nearfield": ("iθh", "iθd", "iφd"),
    "fixed_camera": ("θcam", "θlight", "φlight"),
    "fixed_light": ("θlight", "θcam", "φcam"),
}


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
        self.fixed = setup.kind in _FIXED_KINDS
        self.axes: tuple[int, ...] = (1, 2) if self.fixed else (0, 1, 2)
        self.wrap = (False, False, setup.kind != "nearfield")
        self._cache: dict[Config, NDArray[np.int32] | None] = {}
        self.evaluations = 0
        # "fast": candidates by low-rank updates where cheaper; "direct": each one afresh (reference).
        self.method: Literal["auto", "direct"] = "direct" if evaluation == "direct" else "auto"
        # The current set's configurations and factored statistics (see current()).
        self._current: tuple[tuple[Config, ...], FactoredSelection] | None = None

    # -- configurations --------------------------------------------------

    def obs(self, config: Config) -> NDArray[np.int32] | None:
        """Observed cells of a configuration, or None if it is not valid for this model."""
        hit = self._cache.get(config, False)
        if hit is not False:
            return hit  # type: ignore[return-value]
        result: NDArray[np.int32] | None = None
        centre = int(_centre_cells(self.setup, np.asarray([config]))[0])
        if self.valid[centre]:
            cells = observation_cells(self.setup, config, self.valid)
            if cells.size:
                result = cells.astype(np.int32)
        if len(self._cache) >= _CELL_CACHE_MAX:
            self._cache.clear()
        self._cache[config] = result
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
        dim = _CONFIG_DIMS[axis]
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
                c = _cell_config(int(cell))
                if c not in exclude:
                    out.append(c)
                    if len(out) == t:
                        break
            return out
        seen = set(exclude)
        for _ in range(64):
            batch = 4 * t
            ish = (self.rng.integers(0, _CONFIG_DIMS[0], batch) if shared is None
                   else np.full(batch, shared, dtype=np.int64))
            it = self.rng.integers(0, _CONFIG_DIMS[1], batch)
            ip = self.rng.integers(0, _CONFIG_DIMS[2], batch)
            configs = np.stack([ish, it, ip], axis=1)
            ok = self.valid[_centre_cells(self.setup, configs)] & ((it != 0) | (ip == 0))
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
        """κ(Q̃): from the rows when there are at most k, else from the Gram matrix ``G``."""
        if nrows <= self.k:
            return condition_number(np.concatenate(parts(), axis=0))
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
        keys: list[tuple[float, ...]] = []
        start = 0
        while start < len(cands):
            blocks: list[RowBlock] = []
            rows = 0
            while start + len(blocks) < len(cands) and (not blocks or rows < _EVAL_CHUNK_ROWS):
                idx = cands[start + len(blocks)]
                b = self.row_block(idx)
                if self.metric == "condition" and n0 + idx.size > self.k:
                    # κ needs the candidate's Gram matrix: computed once, also used for E when direct.
                    b = b._replace(stats=_as_block(b, self.k, "block").gram())
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
        names = _AXIS_NAMES[self.setup.kind]
        inner = ", ".join(f"{n}={v}" for n, v in zip(names, config))
        if self.fixed:
            return f"({inner}; cell {int(_centre_cells(self.setup, np.asarray([config]))[0])})"
        return f"({inner})"

    # -- search steps --------------------------------------------------------

    def greedy_add(self, blocks: list[_Block], t: int) -> tuple[tuple[float, ...], int]:
        self._current = None  # rebuilt from the blocks once per n: no rounding carried over
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
        enough for that to be accurate (``tr G_j ≤ η/_DOWNDATE_TOL``: every
        point row of the default models), else the set without j built
        afresh from the other blocks (near-field images, strong rows).
        """
        old = blocks[j]
        remove: _Block | None = old
        if float(np.trace(old.G)) * _DOWNDATE_TOL <= self.em.eta:
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
        unit = "direction" if self.setup.kind == "point" else "image"
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
        name = _AXIS_NAMES[self.setup.kind][0]
        return best[0], new_blocks, f"shared {name} {blocks[0].config[0]} -> {best[1][0][0]}"

    def local_search(
        self, blocks: list[_Block], key: tuple[float, ...], steps: Sequence[int], n: int
    ) -> tuple[list[_Block], tuple[float, ...], int]:
        moves = 0
        for si, s in enumerate(steps):
            if si > 0:
                _emit(self.log, f"n={n} step {steps[si - 1]} -> {s}: {self.fmt(key)}")
            while True:
                units: list[int | None] = list(range(len(blocks))) + ([None] if self.fixed else [])
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
        return DirectionSet(
            n=len(blocks),
            configurations=configs,
            records=tuple(config_to_dict(self.setup, c) for c in configs),
            expected_error=expected_error(self.em, G, qsum),
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


def optimize(
    model: ModelLike,
    setup: Setup,
    *,
    metric: Literal["error", "condition"] = "error",
    n_max: int,
    candidates: int = 500,
    steps: Sequence[int] = (3, 2, 1),
    eta: float = DEFAULT_ETA,
    beta: float = 0.0,
    seed: int | None = 0,
    log: Callable[[str], Any] | logging.Logger | None = None,
    evaluation: Literal["fast", "direct"] = "fast",
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
        ``"error"`` (E(S), eq. 15) or ``"condition"`` (κ(Q̃), eq. 6, ties and
        inf broken by E(S)).
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
        ``brdfpipe.sampling`` logger, INFO): one line per greedy add, accepted
        move, step change and convergence, with the metric value.
    evaluation:
        How candidates' E(S) is computed: ``"fast"`` (default) by low-rank
        updates of a factorisation shared by a batch of candidates where
        that is cheaper (:class:`FactoredSelection`), ``"direct"`` each
        candidate afresh (:func:`expected_error`; the reference the fast
        path is tested against, many times slower for point sampling).  Both
        are exact; they differ by rounding (≈ 1e-13 relative), which can only
        change which of two candidates tied to that precision wins.

    Returns
    -------
    list[DirectionSet]
        The sets for n = 1 … n_max, each grown from the previous one.

    Raises
    ------
    ValueError
        Bad parameters or model, or no valid configuration left to add.
    """
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be a Setup, got {type(setup).__name__}")
    if metric not in _METRICS:
        raise ValueError(f"metric must be one of {_METRICS}, got {metric!r}")
    if isinstance(n_max, bool) or not isinstance(n_max, (int, np.integer)) or n_max < 1:
        raise ValueError(f"n_max must be a positive integer, got {n_max!r}")
    if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) or candidates < 1:
        raise ValueError(f"candidates must be a positive integer, got {candidates!r}")
    step_list = _check_steps(steps)
    if evaluation not in ("fast", "direct"):
        raise ValueError(f"evaluation must be 'fast' or 'direct', got {evaluation!r}")
    ErrorModel(np.ones(1), np.zeros((1, 1)), eta=eta, beta=beta)  # checks η and β before the model is read
    opt = _Optimizer(model, setup, metric, eta, beta, np.random.default_rng(seed), log, evaluation)
    _emit(log, f"optimise {setup.kind} fov {setup.fov_deg:g}° grid {setup.grid}, metric {metric}, "
               f"n = 1..{n_max}, t = {candidates}, steps {step_list}, η = {opt.em.eta:g}, β = {opt.em.beta:g}, "
               f"seed {seed}; model p = {opt.cells.size}, k = {opt.k}, m = {opt.em.m}")
    blocks: list[_Block] = []
    sets: list[DirectionSet] = []
    for n in range(1, int(n_max) + 1):
        t0 = time.perf_counter()
        evals0 = opt.evaluations
        greedy, tried = opt.greedy_add(blocks, int(candidates))
        _emit(log, f"n={n} greedy add: best of {tried} candidates {opt.describe(blocks[-1].config)}, "
                   f"{sum(b.n for b in blocks)} rows: {opt.fmt(greedy)} ({time.perf_counter() - t0:.1f} s)")
        blocks, final, moves = opt.local_search(blocks, greedy, step_list, n)
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
#    point), "grid": g, "metric": "error" | "condition", "split": …, "eta": η,
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
    if metric not in _METRICS:
        raise ValueError(f"metric must be one of {_METRICS}, got {metric!r}")
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
        "format": DIRECTIONS_FORMAT,
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
    atomic.write_text(path, json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return path


def read_directions(path: str | os.PathLike[str]) -> Directions:
    """Read a directions file written by :func:`write_directions`.

    Configurations are rebuilt from their records (:func:`config_from_dict`);
    a null κ reads as inf.  :class:`ValueError` naming the file for a wrong
    format or inconsistent content.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from exc
    if not isinstance(doc, dict) or doc.get("format") != DIRECTIONS_FORMAT:
        raise ValueError(f"{path}: not a directions file (format {doc.get('format') if isinstance(doc, dict) else None!r})")
    try:
        setup = Setup(doc["setup"], doc["fov"], doc["grid"])
        metric = doc["metric"]
        if metric not in _METRICS:
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
) -> Path:
    """Optimise the direction sets of one setup on a PCA model and write them as JSON.

    The workflow's ``optimize_directions`` job: opens the model written by
    :func:`brdfpipe.acquisition.svd.write_model`, runs :func:`optimize` (one log line per
    step) and writes :func:`write_directions`'s JSON to ``out``; the split
    and database recorded are the model's.
    """
    from brdfpipe.acquisition.svd import open_model

    model = open_model(model_path)
    kind_setup = Setup(setup, fov_deg=0.0 if setup == "point" else float(fov), grid=int(grid))
    log = logging.getLogger("brdfpipe.sampling")
    log.info(
        "optimising %s fov %g (%s metric) on %s: n_max %d, %d candidates, seed %d",
        setup, kind_setup.fov_deg, metric, model_path, n_max, candidates, seed,
    )
    sets = optimize(
        model, kind_setup, metric=metric, n_max=n_max, candidates=candidates,
        eta=eta, beta=beta, seed=seed, log=log,
    )
    return write_directions(
        out, sets, setup=kind_setup, metric=metric, split=model.split,
        model_path=model_path, seed=seed, eta=eta, beta=beta, database=model.database,
    )
