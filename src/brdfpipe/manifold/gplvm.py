"""The core of Soler et al. 2018's GPLVM over measured materials (§2.1–§3).

Data
----
``Z`` has one row per material (``d`` columns: the R, G, B values of the
cells valid in every material of the store, mapped to a data space).  The
mean BRDF (column mean over the materials) is subtracted (Soler §3), so far
from the data the interpolant tends to the mean.  The optimisation needs
only the N × N Gram matrix ``(Z − 1μ̄ᵀ)(Z − 1μ̄ᵀ)ᵀ``: how it is streamed from
the store, the data spaces, and why the blend weights of every space but
``log`` apply to the raw BRDFs are in :mod:`brdfpipe.manifold.gram`
(:func:`~brdfpipe.manifold.gram.gram_matrix`).

Model
-----
Kernel (eq. 5) ``c(x, x′) = μ·δ(x, x′) + exp(−‖x − x′‖²/2ℓ²)``, so
``K = exp(−D²/2ℓ²) + μI``; objective (eq. 6)
``L(X) = −(d/2)·log|K| − ½·tr(K⁻¹ Gc)``, with ``Gc`` the centred Gram.

Hooke–Jeeves (``method="hooke-jeeves"``, ``"hybrid"``): direct search over the latent points.
Moving point ``i`` changes row and column ``i`` of ``K`` (its diagonal stays
1 + μ): ``K′ = K + u e_iᵀ + e_i uᵀ`` with ``u = k′_i − k_i`` (``u_i = 0``),
i.e. a symmetric rank-2 update ``K′ = K + U C Uᵀ``, ``U = [u, e_i]``,
``C = [[0, 1], [1, 0]]``.  With ``A = K⁻¹U`` and the 2 × 2 capacitance
``M = C⁻¹ + UᵀK⁻¹U`` (``C⁻¹ = C``):

* Woodbury (= Sherman–Morrison applied twice): ``K′⁻¹ = K⁻¹ − A M⁻¹ Aᵀ``;
* determinant lemma (applied twice): ``|K′| = |K|·|C|·|M| = −|K|·|M|``, so
  ``log|K′| = log|K| + log(−det M)``;
* trace: ``tr(K′⁻¹Gc) = tr(K⁻¹Gc) − ⟨M⁻¹, Aᵀ Gc A⟩``.

A candidate move is therefore scored in O(N²) (``K⁻¹u`` and ``Gc A``) without
forming ``K′⁻¹``; ``K⁻¹`` is updated (O(N²)) only when the move is accepted,
and refactorised from scratch (Cholesky) every ``refactor_every`` accepted
moves and at the end, which bounds the drift of the bookkeeping.

Data scale
----------
The paper's kernel has no signal variance: its amplitude is 1.  In raw
units the centred synthetic store has tr(G)/(N·d) ≈ 1.8e8 (sr⁻²; the mean
variance per data entry), so the likelihood can only explain the data by
making K nearly singular: the fitted points collapse to ~1e-7 ℓ of each
other, K ≈ 11ᵀ + μI, κ(K) ≈ N/μ and the eq. 7 bound is useless.  The
workflow therefore fits to ``G/s`` with ``s = tr(G)/(N·d)``
(:func:`gram_scale`, config ``manifold.normalise``, default on): the data
then have unit mean variance per entry, the kernel's amplitude.  This is the
same as a fixed signal variance ``s`` in the kernel — ``K → sK`` shifts L by
the constant ``−(dN/2)·log s`` and leaves the interpolation weights
``b = K⁻¹k`` unchanged — so the model and its weights are those of the
paper's objective with one extra, data-determined hyperparameter.  The
scale is saved in the model (``gram_scale``); the saved L is that of
``G/s``.  (Dividing G by tr(G)/N instead — unit variance per material —
makes the log-determinant term dominate by d ≈ 3e6 and the maximum is the
degenerate "all points coincide"; measured in ``benches/bench_gplvm.py``.)

Optimisation
------------
``method="newton"`` (the default since issue 23, in this form since issue 31;
:func:`_newton_stages`):

1. start: :func:`pca_init` scaled by the rules ``rms`` and ``unit``
   (:data:`NEWTON_TRIAL_SCALES`; below); steps 2 to 4 from each, the higher
   final L is kept;
2. Newton steps with the exact Hessian (:func:`log_likelihood_hessian`,
   ≈ 20 gradients' worth at q = 5) in Levenberg–Marquardt form: the shift λ
   on a ladder of powers of two, raised until L gains, lowered after good
   steps; where L curves up along some direction by more than λ/2, λ is
   raised up to 8-fold, and beyond that the step is taken with the Hessian's
   absolute value (its eigenvalues' signs dropped: saddle-free Newton), which
   moves uphill along such a direction at the gradient's pace instead of
   letting it set λ for every other direction; until no step can gain above
   the rounding level of L;
3. where the Hessian shows the stationary point to be a saddle (L curving up
   by more than :data:`SADDLE_CURVATURE` of its typical curvature), a step
   along its direction of positive curvature and back to 2;
4. a few Newton steps judged by the gradient, where the gains are below the
   rounding level of L.  The result is a local maximum: gradient at rounding
   level, Hessian negative semi-definite up to the rigid motions.

It has no random element (``seed`` is not used).  The objective is
multimodal (several maxima within a few per cent of each other, and on
merl-nbrdf at q = 2 up to 20 % apart), and a different path from the same
start can end in a different one, either way; no optimiser here is global.

Reproducibility.  The path must not depend on the BLAS kernel: the L of one X
differs between kernels (and thread counts) by up to ~4e-13 relative, the
Gram matrix computed from the same store by ~1e-15 of its largest entry.  The
optimiser before issue 31 (L-BFGS trials, Hessian-preconditioned L-BFGS,
Newton) amplified these differences ~10× every ten L-BFGS iterations (the
curvature pairs of L-BFGS are differences of nearly equal gradients), and
ended at different maxima on different kernels: on merl-nbrdf, default space,
q = 2, four maxima among five kernels (L 1.529e8 to 1.548e8).  So:

* no quasi-Newton memory: every step is a function of the current point alone;
* each step's component along the rigid motions (under which L is invariant:
  rounding noise divided by the shift) is removed, and the rest is rounded to
  :data:`STEP_BITS` bits of its largest entry (:func:`_snap`, exact and the
  same on every machine), the start to :data:`POINT_BITS` bits: two machines
  whose steps differ by rounding take bit for bit the same step, so their
  paths do not drift apart (a rounded step is an inexact Newton step with
  relative error ≤ 2^-8, which converges all the same);
* the discrete decisions are taken on a ladder (λ = unit·2^k, k an integer)
  or with margins (a step predicted to gain less than :data:`GAIN_RESOLUTION`
  of |L| is not tried; of two starts the later wins only by more than that).

Measured (docs/design/reproducibility.md): 17 fits under five OpenBLAS
kernels and two thread counts take the same steps and end at the same
maximum, the latent points at most 4e-10 ℓ apart; the fits before issue 31
ended at up to four maxima.  The other two methods below are not
reproducible across kernels.

``method="hooke-jeeves"`` is the paper's direct search alone (below).
``method="hybrid"`` (the default before issue 23): the initial scale is chosen by short
Hooke–Jeeves trials (below), then scipy's L-BFGS-B on the analytic gradient
(:func:`log_likelihood_grad`) runs from that start to a stationary point,
then the Hooke–Jeeves search continues from there (its finite steps can
leave a stationary point that is not a maximum; every move it accepts is
followed by a final L-BFGS polish).  Why not Hooke–Jeeves alone: measured on
the default synthetic store (normalised, N = 100, one thread), the direct
search stops 3–6 % below the L of a stationary point (q = 2: 9.24e8 vs
9.87e8; q = 5: 1.119e9 vs 1.147e9) — moving one point at a time crawls along
the narrow curved valleys of this ill-conditioned objective (L-BFGS needs
1,000–3,000 iterations), and shrinking its steps only buys 0.5 % more in 10×
the time; L-BFGS run after Hooke–Jeeves reaches a different, 0.1 % lower
optimum than L-BFGS from the start.  The trace CSV records every stage.

Initial scale
-------------
The initial points are the truncated PCA of the centred data (the top ``q``
eigenvectors of ``Gc`` times the square roots of their eigenvalues), then
scaled by one factor.  Since ``ℓ`` and the scale of ``X`` are interchangeable
(Soler §3), only the scale relative to ``ℓ`` matters, and the raw PCA
coordinates of BRDF data (units of sr⁻¹·√d) can be anything from 1e-2 to
1e4 × ℓ: far too small and ``K`` ≈ 11ᵀ + μI is nearly singular, far too large
and ``K`` ≈ (1 + μ)I carries no structure, and in both cases a local search
with fixed steps crawls (``init_scale="pca"`` keeps the scores as they are,
the paper's start).  Rules tried (:data:`INIT_SCALES`):

* ``"nn"``: median nearest-neighbour distance = ℓ;
* ``"rms"``: RMS pairwise distance = ℓ·√(2q) (unit variance per latent axis
  summed over q axes: the spread of a standard-normal prior, the usual GPLVM
  convention of unit-variance latents);
* ``"unit"``: the first PCA coordinate has unit standard deviation.

No rule wins everywhere (measured with N = 100 on the synthetic 100-material
store ``results/merl.zarr`` in the three spaces and on a random structured
Gram matrix, d = 4e6; final L after convergence, single-threaded):

========  =====  ===============  ===============  ===============
case      q      ``nn``           ``rms``          ``unit``
========  =====  ===============  ===============  ===============
raw       2      −2.54e16         **−1.69e16**     −1.80e16
raw       5      −2.49e16         **−6.57e15**     −7.10e15
cosine    2      **−4.49e9**      −1.50e10         −1.80e10
cosine    5      −4.81e9          −1.61e9          **−1.50e9**
log       2      **−5.01e7**      −1.08e8          −1.27e10
log       5      9.48e7           **1.46e8**       1.01e8
random    2      **1.91e8**       1.66e8           1.61e8
random    5      3.37e8           3.76e8           **4.05e8**
========  =====  ===============  ===============  ===============

so ``init_scale="best"`` (the default) runs every rule for ``trial_sweeps``
sweeps (10) and continues the search from the one with the highest L (that
is ``hybrid`` and ``hooke-jeeves``; ``newton`` runs from ``rms`` and ``unit``
to convergence and keeps the better: under L-BFGS to convergence, on the 18
default fits, ``nn`` never ended best — its final L was 0.43–0.97 of the
best rule's); on the
eight cases above it ends within 2 % of the best single rule or above it
(raw q = 2: −1.36e16), for about 30 % more time.  The tendencies: ``nn``
(points spread so neighbours sit at ℓ) wins at q = 2 when the data are on
the kernel's scale; when the data variance per column (tr Gc / (N·d)) is far
above the kernel's unit amplitude, as in raw units, the likelihood wants the
points much closer together than ℓ (strongly correlated K), which ``rms`` /
``unit`` give (factors 100× smaller than ``nn``'s on the raw store).

Files and their data
--------------------
:func:`save_gram` / :func:`save_model` write npz files that carry their own
digest (:func:`brdfpipe.core.integrity.save_npz`; :func:`load_gram` /
:func:`load_model` check it, so a truncated, corrupt or edited file is one
:class:`GplvmFileError` naming it) and the digests of the store rows they
were computed from (the store's name-bound CRC-32C per row,
:func:`brdfpipe.data.store.shard_digest`): the Gram file records them
(``row_digests``) and the fit carries them into the model
(``data_digests``).  Every use of a model with a store checks them
(:func:`check_store`: :func:`interpolate_tables` given the model,
:func:`interpolate_to_file`, :mod:`brdfpipe.manifold.latent`,
:mod:`brdfpipe.manifold.analysis`, :mod:`brdfpipe.manifold.fidelity`, the
workflow's path points, the command line), so a store of the same names
whose rows differ — ingested from other files, rows swapped — is a
:class:`DataMismatchError` naming the model, the store and the material,
never another material's BRDF under a name.

Interpolation
-------------
``b(x*) = K⁻¹ k(x*)`` (eq. 4) and the interpolated BRDF is
``z* = μ̄ + bᵀ(Z − 1μ̄ᵀ) = Σ w_i z_i`` with ``w_i = b_i + (1 − Σb)/N``
(:func:`blend_weights`; Σw = 1), so images rendered from the materials blend
with the same ``w``.  "Exact reproduction": ``k(x*)`` includes the μδ term
when ``x*`` coincides (bitwise) with a training point ``x_i``, so ``k(x_i)``
is column ``i`` of ``K`` and ``b(x_i) = e_i`` (to rounding); an ``x*`` a hair
away from ``x_i`` drops the δ term and gives ``b ≈ e_i·1/(1+μ)``-like
weights (the "negligible discontinuity" of Soler §3).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
import scipy.linalg.blas
import scipy.linalg.lapack
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import logmap, merl
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import (
    DIGEST_ALGORITHM as STORE_DIGEST_ALGORITHM,
    BrdfStore,
    iter_column_blocks,
    material_indices,
    open_store,
)
from brdfpipe.manifold import derivation, spaces
from brdfpipe.manifold.gram import MEAN_HANDLING, GramInfo, check_space, gram_matrix, select_materials
from brdfpipe.spec import tables

__all__ = [
    "INIT_SCALES",
    "NEWTON_TRIAL_SCALES",
    "GplvmFileError",
    "DataMismatchError",
    "FitResult",
    "GplvmModel",
    "save_gram",
    "load_gram",
    "kernel_matrix",
    "kernel_vector",
    "log_likelihood",
    "log_likelihood_grad",
    "log_likelihood_hessian",
    "METHODS",
    "gram_scale",
    "pca_init",
    "rank2_update",
    "fit",
    "weights",
    "blend_weights",
    "interpolate_table",
    "interpolate_tables",
    "save_model",
    "load_model",
    "store_digests",
    "check_store",
    "check_gram_store",
    "write_gram",
    "fit_to_files",
    "write_trace",
    "interpolate_to_file",
]

logger = logging.getLogger("brdfpipe.manifold.gplvm")

#: Initial-scale rules of :func:`fit` (plus ``"best"``: try all, keep the best L).
INIT_SCALES: Final = ("nn", "rms", "unit")
#: The rules ``init_scale="best"`` tries with ``method="newton"`` (module docstring, "Optimisation").
NEWTON_TRIAL_SCALES: Final = ("rms", "unit")
#: Optimisers of :func:`fit` (see the module docstring, "Optimisation").
METHODS: Final = ("newton", "hybrid", "hooke-jeeves")
#: ``newton``: each step is rounded to this many bits of its largest entry, and the start point
#: likewise to :data:`POINT_BITS` (module docstring, "Reproducibility").
STEP_BITS: Final = 8
POINT_BITS: Final = 10
#: ``newton``: a step predicted to gain less than this × |L| is not tried (2^-40 ≈ 9.1e-13: twice
#: the largest difference between the L of one X computed with different BLAS kernels, measured
#: in docs/design/reproducibility.md).
GAIN_RESOLUTION: Final = 2.0**-40
#: ``newton``: a stationary point where L curves up by more than this × the mean |diagonal| of −∇²L along
#: some direction is a saddle point, and is left.
SADDLE_CURVATURE: Final = 1e-6
#: ``newton``: the exponents k of the Levenberg–Marquardt shift ``λ = unit·2^k``.
_MIN_SHIFT_EXPONENT: Final = -30
_MAX_SHIFT_EXPONENT: Final = 60
#: ``newton``: λ is raised at most 2^this-fold for a direction along which L curves up; beyond, the step
#: is taken with |∇²L| instead.
_MAX_RAISE: Final = 3
#: /3: how it was fitted (``normalised``, ``init``) besides the digests of the store rows it was fitted on.
MODEL_FORMAT: Final = "brdfpipe.gplvm/3"
#: /2: the digests of the store rows (``row_digests``) and the file's digest.
GRAM_FORMAT: Final = "brdfpipe.manifold.gplvm.gram/2"
#: Earlier formats: refused with (why, what to do).
RETIRED_FORMATS: Final = {
    "brdfpipe.gplvm/1": ("it records no digests of the store rows it was fitted on", "refit it"),
    "brdfpipe.gplvm/2": ("it records neither its normalisation nor its initialisation", "refit it"),
    "brdfpipe.manifold.gplvm.gram/1": ("it records no digests of the store rows it was computed from",
                                       "compute it again"),
}


class GplvmFileError(ValueError):
    """A GPLVM model or Gram file is missing, damaged, of another format or inconsistent; names the file."""


class DataMismatchError(ValueError):
    """A model (or Gram file) used with a store whose rows are not the data it was fitted on (computed from)."""


# --------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------


def _check_hyper(ell: float, mu: float) -> tuple[float, float]:
    ell_f, mu_f = float(ell), float(mu)
    if not np.isfinite(ell_f) or ell_f <= 0:
        raise ValueError(f"length scale ell must be a finite number > 0, got {ell!r}")
    if not np.isfinite(mu_f) or mu_f < 0:
        raise ValueError(f"noise parameter mu must be a finite number >= 0, got {mu!r}")
    return ell_f, mu_f


def _check_q(q: Any) -> int:
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or int(q) < 1:
        raise ValueError(f"latent dimension q must be an integer >= 1, got {q!r}")
    return int(q)


def _check_gram(gram: ArrayLike, d: Any) -> tuple[NDArray[np.float64], float]:
    g = np.asarray(gram, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] != g.shape[1] or g.shape[0] < 2:
        raise ValueError(f"gram must be a square N x N matrix with N >= 2, got shape {g.shape}")
    if not np.isfinite(g).all():
        raise ValueError("gram has non-finite entries")
    d_f = float(d)
    if not np.isfinite(d_f) or d_f <= 0:
        raise ValueError(f"column count d must be > 0, got {d!r}")
    return 0.5 * (g + g.T), d_f


def _check_X(X: ArrayLike, what: str = "X") -> NDArray[np.float64]:
    x = np.asarray(X, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise ValueError(f"{what} must be an N x q matrix, got shape {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"{what} has non-finite entries")
    return x


# --------------------------------------------------------------------------
# The Gram matrix's scale and file (the matrix itself: brdfpipe.manifold.gram)
# --------------------------------------------------------------------------


def gram_scale(gram: ArrayLike, d: float) -> float:
    """``s = tr(G)/(N·d)``: the mean variance per data entry of the centred data.

    Fitting to ``G/s`` puts the data on the kernel's unit amplitude; it is the
    same as giving the kernel a fixed signal variance ``s`` (``K → sK``
    changes L by a constant and ``b = K⁻¹k`` not at all).  See the module
    docstring, "Data scale".
    """
    g, d_f = _check_gram(gram, d)
    tr = float(np.trace(g))
    if not tr > 0:
        raise ValueError("gram has a non-positive trace: the centred data are all zero")
    return tr / (g.shape[0] * d_f)


def _atomic_savez(path: Path, **arrays: Any) -> None:
    integrity.save_npz(path, arrays)


def _digest_array(path: str | os.PathLike[str], digests: Sequence[int], n: int, what: str) -> NDArray[np.uint32]:
    d = np.asarray(list(digests), dtype=np.int64)
    if d.size and (d.shape != (n,) or d.min() < 0 or d.max() >= 2**32):
        raise ValueError(f"{path}: {what} must give one 32-bit digest per material ({n}), got shape {d.shape}")
    return d.astype(np.uint32)


def _load(path: str | os.PathLike[str], fmt: str, kind: str) -> dict[str, NDArray[Any]]:
    """The arrays of a model / Gram npz, its digest and format checked; :class:`GplvmFileError` naming it."""
    z = integrity.load_npz(path, kind=kind, error=GplvmFileError)
    found = str(z["format"]) if "format" in z and z["format"].shape == () else None
    if found in RETIRED_FORMATS:
        why, todo = RETIRED_FORMATS[found]
        raise GplvmFileError(f"{path}: {kind} format {found!r} is no longer supported: {why}; {todo} "
                             f"({integrity.rerun_hint(path)})")
    if found != fmt:
        raise GplvmFileError(f"{path}: not a brdfpipe {kind} (format {found!r}, expected {fmt!r})")
    return z


def save_gram(path: str | os.PathLike[str], gram: ArrayLike, d: int, info: GramInfo) -> None:
    """Write a Gram matrix, ``d`` and its :class:`GramInfo` (with the store rows' digests) to an npz, atomically.

    The file carries its own digest (:func:`brdfpipe.core.integrity.save_npz`).
    """
    _atomic_savez(
        Path(path),
        format=np.array(GRAM_FORMAT),
        gram=np.asarray(gram, dtype=np.float64),
        d=np.array(int(d)),
        materials=np.array(info.materials, dtype=str),
        space=np.array(info.space),
        mean_handling=np.array(info.mean_handling),
        row_sums=info.row_sums,
        raw_gram=info.raw_gram,
        row_digests=_digest_array(path, info.digests, len(info.materials), "the row digests"),
        digest_algorithm=np.array(STORE_DIGEST_ALGORITHM),
    )


def load_gram(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], int, GramInfo]:
    """Read what :func:`save_gram` wrote, its digest checked.

    :class:`GplvmFileError` (a ValueError) naming the file and what to rerun
    for a missing, truncated, corrupt, unverifiable or edited file, another
    format or inconsistent arrays.
    """
    z = _load(path, GRAM_FORMAT, "GPLVM Gram file")
    try:
        materials = tuple(str(m) for m in z["materials"])
        digests = tuple(int(v) for v in z["row_digests"])
        if str(z["digest_algorithm"]) != STORE_DIGEST_ALGORITHM or (digests and len(digests) != len(materials)):
            raise ValueError("row digests of another kind or count")
        info = GramInfo(materials, str(z["space"]), z["row_sums"], z["raw_gram"], str(z["mean_handling"]),
                        digests=digests)
        gram, d = z["gram"], int(z["d"])
    except (KeyError, TypeError, ValueError) as exc:
        raise GplvmFileError(f"{path}: inconsistent GPLVM Gram file ({type(exc).__name__}: {exc})") from None
    if gram.shape != (len(materials), len(materials)):
        raise GplvmFileError(f"{path}: Gram matrix of shape {gram.shape} for {len(materials)} materials")
    return gram, d, info


# --------------------------------------------------------------------------
# Kernel and likelihood
# --------------------------------------------------------------------------


def _sqdist(X: NDArray[np.float64]) -> NDArray[np.float64]:
    """Squared distances ``‖x_i − x_j‖²`` (N × N), one latent axis at a time: O(N²q) time, O(N²) memory.

    Differences, not ``‖x_i‖² + ‖x_j‖² − 2x_i·x_j`` (which cancels for close
    points); exactly symmetric with a zero diagonal.
    """
    n, q = X.shape
    out = np.zeros((n, n))
    diff = np.empty((n, n))
    for k in range(q):
        col = X[:, k]
        np.subtract(col[:, None], col[None, :], out=diff)
        diff *= diff
        out += diff
    return out


def kernel_matrix(X: ArrayLike, ell: float = 1.0, mu: float = 1e-4) -> NDArray[np.float64]:
    """``K_ij = μ δ_ij + exp(−‖x_i − x_j‖²/2ℓ²)`` (eq. 5) for the rows of ``X`` (N × q)."""
    ell, mu = _check_hyper(ell, mu)
    x = _check_X(X)
    K = np.exp(-_sqdist(x) / (2.0 * ell * ell))
    K[np.diag_indices_from(K)] = 1.0 + mu
    return K


def kernel_vector(X: ArrayLike, x_star: ArrayLike, ell: float = 1.0, mu: float = 1e-4) -> NDArray[np.float64]:
    """``k(x*)_j = c(x_j, x*)`` including μ where ``x*`` equals ``x_j`` exactly (see module docstring)."""
    ell, mu = _check_hyper(ell, mu)
    x = _check_X(X)
    xs = _check_xstar(x_star, x.shape[1])
    diff = x - xs
    d2 = np.einsum("ij,ij->i", diff, diff)
    k = np.exp(-d2 / (2.0 * ell * ell))
    k[(diff == 0).all(axis=1)] += mu
    return k


def _check_xstar(x_star: ArrayLike, q: int) -> NDArray[np.float64]:
    xs = np.asarray(x_star, dtype=np.float64)
    if xs.ndim != 1 or xs.shape[0] != q:
        raise ValueError(f"x_star must be a vector of length q = {q}, got shape {xs.shape}")
    if not np.isfinite(xs).all():
        raise ValueError("x_star has non-finite entries")
    return xs


def _loglik_from_chol(
    cf: tuple[NDArray[np.float64], bool], gram: NDArray[np.float64], d: float
) -> tuple[float, float, float]:
    """(L, log|K|, tr(K⁻¹G)) from a Cholesky factor of K."""
    logdet = 2.0 * float(np.log(np.diag(cf[0])).sum())
    tr = float(np.trace(scipy.linalg.cho_solve(cf, gram)))
    return -0.5 * d * logdet - 0.5 * tr, logdet, tr


def log_likelihood(
    X: ArrayLike, gram: ArrayLike, d: float, ell: float = 1.0, mu: float = 1e-4
) -> float:
    """``L = −(d/2) log|K| − ½ tr(K⁻¹ G)`` (eq. 6), computed directly with a Cholesky factor of K."""
    g, d_f = _check_gram(gram, d)
    K = kernel_matrix(X, ell, mu)
    if K.shape[0] != g.shape[0]:
        raise ValueError(f"X has {K.shape[0]} rows but gram is {g.shape[0]} x {g.shape[0]}")
    cf = scipy.linalg.cho_factor(K, lower=True)
    return _loglik_from_chol(cf, g, d_f)[0]


def log_likelihood_grad(
    X: ArrayLike, gram: ArrayLike, d: float, ell: float = 1.0, mu: float = 1e-4
) -> tuple[float, NDArray[np.float64]]:
    """``L`` (eq. 6) and its analytic gradient ``∂L/∂X`` (N × q).

    ``∂L/∂K = W = −(d/2)K⁻¹ + ½K⁻¹GK⁻¹``; off the diagonal ``∂K_ij/∂x_i =
    −K_ij (x_i − x_j)/ℓ²`` (the diagonal 1 + μ does not move), and K_ij and
    K_ji move together, so ``∂L/∂x_i = −(2/ℓ²) Σ_j W_ij E_ij (x_i − x_j)``
    with ``E = exp(−D²/2ℓ²)``.  Cost: one Cholesky of K, its inverse
    (``dpotri``), two triangular solves and one ``dsyrk`` with a square root
    of G (:class:`_GramRoot`; ≈ 4N³ flops in all) and O(N²q) for the kernel
    and the contraction — no N × N × q array.  Used by the quasi-Newton
    stage of :func:`fit` and checked against finite differences in the tests.
    """
    g, d_f = _check_gram(gram, d)
    ell, mu = _check_hyper(ell, mu)
    x = _check_X(X)
    if x.shape[0] != g.shape[0]:
        raise ValueError(f"X has {x.shape[0]} rows but gram is {g.shape[0]} x {g.shape[0]}")
    return _loglik_grad(x, _GramRoot(g), d_f, ell, mu)


class _GramRoot:
    """``G = R₊R₊ᵀ − R₋R₋ᵀ`` from the eigendecomposition of the (symmetric) Gram matrix, computed once per fit.

    With ``K = LLᵀ``: ``tr(K⁻¹G) = ‖L⁻¹R₊‖² − ‖L⁻¹R₋‖²`` and
    ``K⁻¹GK⁻¹ = T₊T₊ᵀ − T₋T₋ᵀ``, ``T = L⁻ᵀL⁻¹R`` — triangular solves and
    ``dsyrk`` instead of general products with G.  (R₋ holds the eigenvalues
    of a centred Gram matrix that rounding made negative: ~1e-16 of ‖G‖.)
    """

    def __init__(self, gram: NDArray[np.float64]) -> None:
        lam, V = np.linalg.eigh(gram)
        pos = lam > 0
        self.plus = np.asfortranarray(V[:, pos] * np.sqrt(lam[pos]))
        self.minus = np.asfortranarray(V[:, ~pos] * np.sqrt(-lam[~pos])) if (~pos).any() else None


def _loglik_grad(
    x: NDArray[np.float64], root: _GramRoot, d: float, ell: float, mu: float
) -> tuple[float, NDArray[np.float64]]:
    """:func:`log_likelihood_grad` without validation (the quasi-Newton stage's inner loop)."""
    blas, lapack = scipy.linalg.blas, scipy.linalg.lapack
    s = 1.0 / (ell * ell)
    E = np.exp(_sqdist(x) * (-0.5 * s))
    K = E.copy()
    np.fill_diagonal(K, 1.0 + mu)
    c, info = lapack.dpotrf(K, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("K is not positive definite")
    logdet = 2.0 * float(np.log(np.diag(c)).sum())
    Kinv_l, info = lapack.dpotri(c, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("K could not be inverted")
    # Lower triangles only (dpotri and dsyrk leave the strict upper triangle zero), mirrored once.
    Wl = Kinv_l
    Wl *= -0.5 * d
    tr = 0.0
    for R, sign in ((root.plus, 1.0), (root.minus, -1.0)):
        if R is None or R.shape[1] == 0:
            continue
        S = blas.dtrsm(1.0, c, R, lower=1)  # L⁻¹R
        tr += sign * float(np.einsum("ij,ij->", S, S))
        T = blas.dtrsm(1.0, c, S, lower=1, trans_a=1)  # K⁻¹R
        Wl = blas.dsyrk(0.5 * sign, T, beta=1.0, c=Wl, lower=1, overwrite_c=1)  # + ½ K⁻¹GK⁻¹
    L = -0.5 * d * logdet - 0.5 * tr
    np.fill_diagonal(Wl, 0.0)  # the diagonal of A is zero anyway
    A = Wl + Wl.T  # W off the diagonal
    A *= E
    np.fill_diagonal(A, 0.0)
    grad = A @ x
    grad -= A.sum(axis=1)[:, None] * x
    grad *= 2.0 * s
    return L, grad


def log_likelihood_hessian(
    X: ArrayLike, gram: ArrayLike, d: float, ell: float = 1.0, mu: float = 1e-4
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """``L`` (eq. 6), ``∂L/∂X`` (N × q) and the Hessian ``∂²L/∂x∂x`` (Nq × Nq, in the order of ``X.ravel()``).

    With ``P = K⁻¹``, ``Q = K⁻¹GK⁻¹`` and ``W = −(d/2)P + ½Q`` (= ∂L/∂K),
    the second differential is ``d²L = tr(W d²K) + (d/2)·tr(P dK₁ P dK₂) −
    tr(P dK₁ Q dK₂)``.  Moving coordinate k of point i changes only row and
    column i of K: ``∂K/∂x_ik = e_i aᵀ + a e_iᵀ`` with ``a`` row i of
    ``A_k = −E ∘ Δ_k / ℓ²`` (``Δ_k[i, j] = x_ik − x_jk``, antisymmetric), so
    for any symmetric P, Q
    ``tr(P dK₁ Q dK₂) = (A_kQ)_ij (A_lP)_ji + (A_kP)_ij (A_lQ)_ji + P_ij (A_kQA_lᵀ)_ij + Q_ij (A_kPA_lᵀ)_ij``
    for the pair (x_ik, x_jl).  The block (k, l) over all point pairs is
    therefore a few element-wise products of N × N matrices and the two
    products ``(dA_kP − A_kQ)A_lᵀ`` and ``A_kPA_lᵀ``; the ``tr(W d²K)`` term
    is ``−2F_ij(Δ_kΔ_l/ℓ⁴ − δ_kl/ℓ²)`` off the diagonal (``F = W ∘ E``) and
    minus its row sum on it (L is invariant under translations).  Cost:
    ``2q + q(q + 1)`` products of N × N matrices (≈ 80N³ flops for q = 5,
    20 gradients' worth) on top of the gradient's factorisations; memory
    ``(Nq)²`` doubles.  The Hessian is singular along the rigid motions of the
    latent points (q translations, q(q − 1)/2 rotations).  Used by the
    ``newton`` method of :func:`fit`; checked against finite differences of
    the gradient in the tests.
    """
    g, d_f = _check_gram(gram, d)
    ell, mu = _check_hyper(ell, mu)
    x = _check_X(X)
    if x.shape[0] != g.shape[0]:
        raise ValueError(f"X has {x.shape[0]} rows but gram is {g.shape[0]} x {g.shape[0]}")
    return _loglik_grad_hess(x, _GramRoot(g), d_f, ell, mu)


def _loglik_only(x: NDArray[np.float64], root: _GramRoot, d: float, ell: float, mu: float) -> float:
    """L alone (one Cholesky and one triangular solve): the trial points of the Newton stage."""
    blas, lapack = scipy.linalg.blas, scipy.linalg.lapack
    K = np.exp(_sqdist(x) * (-0.5 / (ell * ell)))
    np.fill_diagonal(K, 1.0 + mu)
    c, info = lapack.dpotrf(K, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("K is not positive definite")
    logdet = 2.0 * float(np.log(np.diag(c)).sum())
    tr = 0.0
    for R, sign in ((root.plus, 1.0), (root.minus, -1.0)):
        if R is None or R.shape[1] == 0:
            continue
        S = blas.dtrsm(1.0, c, R, lower=1)
        tr += sign * float(np.einsum("ij,ij->", S, S))
    return -0.5 * d * logdet - 0.5 * tr


def _loglik_grad_hess(
    x: NDArray[np.float64], root: _GramRoot, d: float, ell: float, mu: float
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """:func:`log_likelihood_hessian` without validation."""
    blas, lapack = scipy.linalg.blas, scipy.linalg.lapack
    n, q = x.shape
    s = 1.0 / (ell * ell)
    E = np.exp(_sqdist(x) * (-0.5 * s))
    K = E.copy()
    np.fill_diagonal(K, 1.0 + mu)
    c, info = lapack.dpotrf(K, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("K is not positive definite")
    logdet = 2.0 * float(np.log(np.diag(c)).sum())
    P, info = lapack.dpotri(c, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("K could not be inverted")
    P = np.tril(P)
    P += np.tril(P, -1).T
    Q = np.zeros((n, n))
    tr = 0.0
    for R, sign in ((root.plus, 1.0), (root.minus, -1.0)):
        if R is None or R.shape[1] == 0:
            continue
        S = blas.dtrsm(1.0, c, R, lower=1)  # L⁻¹R
        tr += sign * float(np.einsum("ij,ij->", S, S))
        T = blas.dtrsm(1.0, c, S, lower=1, trans_a=1)  # K⁻¹R
        Q = blas.dsyrk(sign, T, beta=1.0, c=Q, lower=1, overwrite_c=1)
    Q = np.tril(Q)
    Q += np.tril(Q, -1).T
    L = -0.5 * d * logdet - 0.5 * tr
    F = (-0.5 * d) * P
    F += 0.5 * Q
    F *= E  # F = W ∘ E
    np.fill_diagonal(F, 0.0)
    grad = F @ x
    grad -= F.sum(axis=1)[:, None] * x
    grad *= 2.0 * s
    Dl = x.T[:, :, None] - x.T[:, None, :]  # (q, N, N): Δ_k[i, j] = x_ik − x_jk
    A = Dl * E[None]
    A *= -s  # A_k = ∂K/∂x_ik along row i; zero diagonal
    AP = (A.reshape(q * n, n) @ P).reshape(q, n, n)
    AQ = (A.reshape(q * n, n) @ Q).reshape(q, n, n)
    B = d * AP
    B -= AQ  # A_k(dP − Q)
    H = np.empty((n, q, n, q))
    m2F = -2.0 * F
    diag = np.diag_indices(n)
    for l_ in range(q):
        AlT = A[l_].T
        BA = (B[: l_ + 1].reshape(-1, n) @ AlT).reshape(l_ + 1, n, n)
        PA = (AP[: l_ + 1].reshape(-1, n) @ AlT).reshape(l_ + 1, n, n)
        APlT, AQlT = AP[l_].T, AQ[l_].T
        dAPlT = d * APlT - AQlT
        for k in range(l_ + 1):
            blk = AP[k] * dAPlT
            blk -= AQ[k] * APlT
            blk += P * BA[k]
            blk -= Q * PA[k]
            t2 = m2F * Dl[k]
            t2 *= Dl[l_]
            t2 *= s * s
            if k == l_:
                t2 -= s * m2F
            t2[diag] = 0.0
            blk += t2
            blk[diag] -= t2.sum(axis=1)
            if k == l_:
                blk += blk.T
                blk *= 0.5  # symmetric to the last bit (it is, up to rounding)
            H[:, k, :, l_] = blk
            if k != l_:
                H[:, l_, :, k] = blk.T
    return L, grad, H.reshape(n * q, n * q)


# --------------------------------------------------------------------------
# The incremental (rank-2) update
# --------------------------------------------------------------------------


@dataclass
class _State:
    X: NDArray[np.float64]
    K: NDArray[np.float64]
    Kinv: NDArray[np.float64]
    logdet: float
    tr: float


def _full_state(X: NDArray[np.float64], gram: NDArray[np.float64], ell: float, mu: float) -> _State:
    K = kernel_matrix(X, ell, mu)
    cf = scipy.linalg.cho_factor(K, lower=True)
    Kinv = scipy.linalg.cho_solve(cf, np.eye(K.shape[0]))
    Kinv = 0.5 * (Kinv + Kinv.T)
    logdet = 2.0 * float(np.log(np.diag(cf[0])).sum())
    tr = float(np.einsum("ij,ji->", Kinv, gram))
    return _State(X.copy(), K, Kinv, logdet, tr)


def _candidates(
    st: _State, gram: NDArray[np.float64], i: int, xs: NDArray[np.float64], inv2l2: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
           NDArray[np.bool_]]:
    """Score moving point ``i`` to each row of ``xs`` (c × q) at once, by the rank-2 formulas.

    Returns ``(Δlog|K|, Δtr, columns (N × c), a = K⁻¹u (N × c), M⁻¹ (c × 2 × 2), ok)``; ``ok`` is
    False where K′ would not be positive definite (its other entries are then meaningless).  The
    products with K⁻¹ and G of all candidates are two matrix products (2·2N²c flops), the rest
    O(Nc): ``U = [u, e_i]``, ``A = K⁻¹U``, ``M = C + UᵀK⁻¹U`` (module docstring).
    """
    n = st.X.shape[0]
    d2 = np.zeros((n, xs.shape[0]))
    for k in range(st.X.shape[1]):
        diff = st.X[:, k, None] - xs[None, :, k]
        d2 += diff * diff
    cols = np.exp(d2 * -inv2l2)
    cols[i] = st.K[i, i]
    u = cols - st.K[i][:, None]  # K is symmetric: row i = column i
    u[i] = 0.0
    a = st.Kinv @ u  # (N, c)
    ki = st.Kinv[i]
    gki = gram @ ki
    m00 = np.einsum("nc,nc->c", u, a)
    m01 = a[i] + 1.0
    m11 = ki[i]
    det = m00 * m11 - m01 * m01
    ratio = -det  # |K′|/|K| (determinant lemma, twice)
    ok = ratio > 0.0
    safe = np.where(ok, det, -1.0)
    Minv = np.empty((xs.shape[0], 2, 2))
    Minv[:, 0, 0] = m11 / safe
    Minv[:, 0, 1] = Minv[:, 1, 0] = -m01 / safe
    Minv[:, 1, 1] = m00 / safe
    ga = gram @ a
    aga00 = np.einsum("nc,nc->c", a, ga)
    aga01 = a.T @ gki
    aga11 = float(ki @ gki)
    dtr = -(Minv[:, 0, 0] * aga00 + 2.0 * Minv[:, 0, 1] * aga01 + Minv[:, 1, 1] * aga11)
    dlogdet = np.log(np.where(ok, ratio, 1.0))
    return dlogdet, dtr, cols, a, Minv, ok


def _candidate(
    st: _State, gram: NDArray[np.float64], i: int, xi: NDArray[np.float64], inv2l2: float
) -> tuple[float, float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """Score moving point ``i`` to ``xi``: (Δlog|K|, Δtr, new column, Aᵀ (2 × N), M⁻¹); None if K′ is not PD.

    One candidate of :func:`_candidates`.
    """
    dlogdet, dtr, cols, a, Minv, ok = _candidates(st, gram, i, xi[None, :], inv2l2)
    if not ok[0]:
        return None
    At = np.stack([a[:, 0], st.Kinv[i]])
    return float(dlogdet[0]), float(dtr[0]), cols[:, 0], At, Minv[0]


def _accept(st: _State, i: int, xi: NDArray[np.float64], col: NDArray[np.float64],
            At: NDArray[np.float64], Minv: NDArray[np.float64], dlogdet: float, dtr: float) -> None:
    """Apply a scored move: Woodbury ``K′⁻¹ = K⁻¹ − A M⁻¹ Aᵀ`` (Sherman–Morrison twice), K, X, log|K|, tr."""
    st.Kinv -= At.T @ (Minv @ At)
    st.K[:, i] = col
    st.K[i, :] = col
    st.X[i] = xi
    st.logdet += dlogdet
    st.tr += dtr


def rank2_update(
    Kinv: ArrayLike, logdet: float, X: ArrayLike, i: int, x_new: ArrayLike, ell: float = 1.0, mu: float = 1e-4
) -> tuple[NDArray[np.float64], float]:
    """K⁻¹ and log|K| after moving latent point ``i`` of ``X`` to ``x_new`` (Woodbury 2 × 2 + determinant lemma).

    ``Kinv`` / ``logdet`` must belong to ``kernel_matrix(X, ell, mu)``.  O(N²).
    Exposed for tests; :func:`fit` uses the same code.  ValueError if the
    updated K is not positive definite.
    """
    ell, mu = _check_hyper(ell, mu)
    x = _check_X(X)
    K = kernel_matrix(x, ell, mu)
    st = _State(x.copy(), K, np.array(Kinv, dtype=np.float64), float(logdet), 0.0)
    xi = _check_xstar(x_new, x.shape[1])
    res = _candidate(st, np.zeros_like(K), int(i), xi, 1.0 / (2.0 * ell * ell))
    if res is None:
        raise ValueError("the updated kernel matrix is not positive definite")
    dlogdet, dtr, col, A, Minv = res
    _accept(st, int(i), xi, col, A, Minv, dlogdet, dtr)
    return st.Kinv, st.logdet


# --------------------------------------------------------------------------
# Initialisation and fit
# --------------------------------------------------------------------------


def pca_init(gram: ArrayLike, q: int) -> NDArray[np.float64]:
    """Truncated PCA scores of the centred data from its Gram matrix: ``V_q Λ_q^{1/2}`` (N × q), unscaled.

    Signs are fixed (largest-magnitude entry of each column positive) so the
    result is deterministic.
    """
    q = _check_q(q)
    g = np.asarray(gram, dtype=np.float64)
    n = g.shape[0]
    if q > n:
        raise ValueError(f"latent dimension q = {q} exceeds the number of materials N = {n}")
    lam, V = np.linalg.eigh(0.5 * (g + g.T))
    top = np.argsort(lam)[::-1][:q]
    lam, V = np.clip(lam[top], 0.0, None), V[:, top]
    sign = np.sign(V[np.abs(V).argmax(axis=0), np.arange(q)])
    sign[sign == 0] = 1.0
    return V * sign * np.sqrt(lam)


def _scale_factor(Y: NDArray[np.float64], rule: str, ell: float) -> float:
    """Factor turning PCA scores ``Y`` into initial latents under ``rule`` (see module docstring)."""
    n, q = Y.shape
    if rule == "pca":  # the truncated PCA as it is (Soler §3)
        return 1.0
    if rule == "unit":
        sd = float(Y[:, 0].std())
        return 1.0 / sd if sd > 0 else 1.0
    D = np.sqrt(_sqdist(Y))
    if rule == "nn":
        np.fill_diagonal(D, np.inf)
        nn = np.median(D.min(axis=1))
        return ell / nn if np.isfinite(nn) and nn > 0 else 1.0
    if rule == "rms":
        rms = float(np.sqrt((D**2).sum() / (n * (n - 1))))
        return ell * np.sqrt(2.0 * q) / rms if rms > 0 else 1.0
    raise ValueError(f"unknown init_scale {rule!r}; expected a number or one of best, pca, {', '.join(INIT_SCALES)}")


@dataclass
class FitResult:
    """Outcome of :func:`fit`."""

    X: NDArray[np.float64]
    log_likelihood: float
    #: ``(sweep, L)`` after each sweep; sweep 0 is the initial point.
    trace: list[tuple[int, float]]
    ell: float
    mu: float
    d: float
    init_scale: str
    init_factor: float
    initial_log_likelihood: float
    sweeps: int
    accepted_moves: int
    evaluations: int
    final_step: float
    #: Largest |L_incremental − L_refactored| seen at a refactorisation (relative to |L|).
    max_drift: float
    seconds: float
    #: The best L reached from each initial-scale rule tried (``init_scale="best"``).
    scale_trials: dict[str, float] = field(default_factory=dict)
    #: ``"newton"``, ``"hybrid"`` or ``"hooke-jeeves"`` (:data:`METHODS`).
    method: str = "hooke-jeeves"
    #: Stage of each trace entry: ``start``, ``hooke-jeeves`` (a sweep), ``lbfgs`` (an iteration) or
    #: ``newton`` (a Newton step, or a step out of a saddle point).
    stages: list[str] = field(default_factory=list)
    #: L when the Hooke–Jeeves stage ended.
    hj_log_likelihood: float = float("nan")
    #: ``"hybrid"``: L-BFGS iterations of the polish (0 for the other methods).
    polish_iterations: int = 0
    #: ``"newton"``: Newton steps from the start scales that were not kept.
    trial_iterations: int = 0
    #: ``"newton"``: Newton steps (and steps out of saddle points) from the start that was kept.
    newton_iterations: int = 0
    #: ``"newton"``: evaluations of L alone (the trial points of the steps) and of L with its gradient and
    #: Hessian, every start included.
    gradient_evaluations: int = 0
    hessian_evaluations: int = 0


def _hooke_jeeves(
    st: _State, gram: NDArray[np.float64], d: float, ell: float, mu: float, *,
    rng: np.random.Generator, max_sweeps: int, step: float, min_step: float, refactor_every: int,
    tol: float, ftol: float,
) -> tuple[list[tuple[int, float]], int, int, float, float, int]:
    n, q = st.X.shape
    inv2l2 = 1.0 / (2.0 * ell * ell)

    def L() -> float:
        return -0.5 * d * st.logdet - 0.5 * st.tr

    trace = [(0, L())]
    accepted = evals = since = 0
    max_drift = 0.0
    sweep = 0

    def refactor() -> None:
        nonlocal max_drift
        before = L()
        fresh = _full_state(st.X, gram, ell, mu)
        st.K, st.Kinv, st.logdet, st.tr = fresh.K, fresh.Kinv, fresh.logdet, fresh.tr
        max_drift = max(max_drift, abs(before - L()) / max(abs(L()), 1.0))

    def try_moves(i: int, xs: NDArray[np.float64]) -> int:
        """Score the moves of point i to the rows of ``xs`` in one batch; accept the first that
        improves L (in row order) and return its row, or −1.  The same choice as trying them one
        by one and stopping at the first improvement."""
        nonlocal accepted, evals, since
        evals += xs.shape[0]
        dlogdet, dtr, cols, a, Minv, ok = _candidates(st, gram, i, xs, inv2l2)
        dL = -0.5 * d * dlogdet - 0.5 * dtr
        good = np.flatnonzero(ok & (dL > tol * max(abs(L()), 1.0)))
        if good.size == 0:
            return -1
        c = int(good[0])
        At = np.stack([a[:, c], st.Kinv[i]])
        _accept(st, i, xs[c].copy(), cols[:, c].copy(), At, Minv[c], float(dlogdet[c]), float(dtr[c]))
        accepted += 1
        since += 1
        if since >= refactor_every:
            refactor()
            since = 0
        return c

    def try_move(i: int, xi: NDArray[np.float64]) -> bool:
        return try_moves(i, xi[None, :]) == 0

    steps = np.full(n, step)
    stalled = 0
    patience = 5
    while sweep < max_sweeps and steps.max() >= min_step:
        sweep += 1
        L_before = L()
        for i in rng.permutation(n):
            if steps[i] < min_step:
                continue
            h = steps[i]
            base = st.X[i].copy()
            # exploratory moves: ±h on each coordinate in a random order, first improvement taken
            # (then the next coordinate from the new point); the remaining moves are scored in one batch
            order = rng.permutation(q)
            j = 0
            while j < q:
                ks = order[j:]
                xs = np.repeat(st.X[i][None, :], 2 * ks.size, axis=0)
                xs[np.arange(0, 2 * ks.size, 2), ks] += h
                xs[np.arange(1, 2 * ks.size, 2), ks] -= h
                c = try_moves(int(i), xs)
                if c < 0:
                    break
                j += c // 2 + 1
            delta = st.X[i] - base
            if delta.any():
                # pattern moves: keep going in the direction that improved, doubling
                for _ in range(8):
                    if not try_move(int(i), st.X[i] + delta):
                        break
                    delta = 2.0 * delta
            else:
                steps[i] = 0.5 * h
        trace.append((sweep, L()))
        # converged: no significant gain for `patience` sweeps in a row (the steps shrink meanwhile)
        stalled = stalled + 1 if L() - L_before <= ftol * max(abs(L()), 1.0) else 0
        if stalled >= patience:
            break
    step = float(steps.max())
    refactor()
    trace[-1] = (trace[-1][0], L())
    return trace, accepted, evals, step, max_drift, sweep


def _lbfgs_polish(
    X0: NDArray[np.float64], gram: NDArray[np.float64], d: float, ell: float, mu: float, *,
    max_iter: int, ftol: float, gtol: float,
) -> tuple[NDArray[np.float64], list[float], int]:
    """Quasi-Newton polish: scipy L-BFGS-B on −L/|L(X₀)| with :func:`log_likelihood_grad`.

    Returns the final X, L after every iteration, and the iteration count.
    The objective is divided by a constant so that ``ftol`` / ``gtol`` are
    relative; a trial point where K is not positive definite scores +∞.
    """
    import scipy.optimize

    n, q = X0.shape
    scale = max(abs(log_likelihood(X0, gram, d, ell, mu)), 1.0)
    root = _GramRoot(gram)

    last: dict[bytes, float] = {}

    def f(x: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        try:
            L, g = _loglik_grad(x.reshape(n, q), root, d, ell, mu)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(x)
        last.clear()
        last[x.tobytes()] = L
        return -L / scale, -g.ravel() / scale

    def record(xk: NDArray[np.float64]) -> None:
        # the accepted iterate is normally the last point evaluated
        history.append(last[xk.tobytes()] if xk.tobytes() in last else log_likelihood(xk.reshape(n, q), gram, d, ell, mu))

    history: list[float] = []
    res = scipy.optimize.minimize(
        f, X0.ravel(), jac=True, method="L-BFGS-B", callback=record,
        options={"maxiter": int(max_iter), "maxfun": 4 * int(max_iter), "ftol": ftol, "gtol": gtol, "maxcor": 20},
    )
    X = res.x.reshape(n, q)
    if log_likelihood(X, gram, d, ell, mu) < log_likelihood(X0, gram, d, ell, mu):
        return X0.copy(), history, int(res.nit)  # never hand back a worse point
    return X, history, int(res.nit)


@dataclass
class _Counts:
    """Work of the ``newton`` method: evaluations of L alone, of L with its gradient and Hessian, factorisations."""

    evaluations: int = 0
    hessians: int = 0
    factorisations: int = 0
    newton_iterations: int = 0


def _snap(x: NDArray[np.float64], bits: int) -> NDArray[np.float64]:
    """``x`` rounded to the grid of spacing ``2^(e − bits)``, where ``2^(e−1) ≤ max|x| < 2^e``.

    ``frexp``, scaling by a power of two and rounding to an integer (round half to even) are exact,
    so the result is a function of the bits of ``x`` alone, the same on every machine; two ``x``
    that differ by δ land on the same grid point unless an entry lies within δ of a midpoint
    (chance ≈ δ / spacing per entry).  See the module docstring, "Reproducibility".
    """
    top = float(np.abs(x).max()) if x.size else 0.0
    if not top > 0 or not np.isfinite(top):
        return x.copy()
    spacing = np.ldexp(1.0, int(np.frexp(top)[1]) - int(bits))
    return np.round(x / spacing) * spacing


def _rigid_motions(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Orthonormal basis (Nq × ≤ q(q+1)/2) of the infinitesimal translations and rotations of the latent points.

    L is invariant under them (the Hessian is singular along them), so a Newton step has no
    business there: its component along them is rounding noise divided by the shift.
    """
    n, q = x.shape
    cols = []
    for a in range(q):
        t = np.zeros((n, q))
        t[:, a] = 1.0
        cols.append(t.ravel())
        for b in range(a + 1, q):
            r = np.zeros((n, q))
            r[:, a], r[:, b] = -x[:, b], x[:, a]
            cols.append(r.ravel())
    U, s, _ = np.linalg.svd(np.stack(cols, axis=1), full_matrices=False)
    return U[:, s > 1e-12 * s[0]]


def _positive_definite(B: NDArray[np.float64], shift: float, counts: _Counts) -> bool:
    """Whether ``B + shift·I`` is positive definite (its Cholesky factorisation succeeds)."""
    diag = np.diag_indices_from(B)
    base = B[diag].copy()
    B[diag] = base + shift
    counts.factorisations += 1
    ok = scipy.linalg.lapack.dpotrf(B, lower=1, clean=0)[1] == 0
    B[diag] = base
    return bool(ok)


def _lm_step(
    x: NDArray[np.float64], L: float, M: NDArray[np.float64], B: NDArray[np.float64], gf: NDArray[np.float64],
    unit: float, k: int, root: _GramRoot, d: float, ell: float, mu: float, *, scale: float, counts: _Counts,
) -> tuple[tuple[NDArray[np.float64], float] | None, int]:
    """One Levenberg–Marquardt step from ``x`` (:func:`_lm_newton`): ``(step, gain / prediction)``, or None where no
    step is predicted to gain more than :data:`GAIN_RESOLUTION`; and the last ``k``.

    ``p = −(M + λI)⁻¹gf`` with ``λ = unit·2^k`` (``M``: ``B = −∇²L/scale`` or its absolute value,
    ``gf = −∇L/scale``); its rigid-motion component removed and the rest rounded to :data:`STEP_BITS` bits of
    its largest entry; the prediction is the quadratic model's (``B``); ``k`` +2 (λ ×4) until L gains at least
    1e-4 of it.
    """
    lapack = scipy.linalg.lapack
    n, q = x.shape
    Q = _rigid_motions(x)
    diag = np.diag_indices_from(M)
    base = M[diag].copy()
    while k <= _MAX_SHIFT_EXPONENT:
        M[diag] = base + unit * 2.0**k
        c, info = lapack.dpotrf(M, lower=1, clean=1)
        M[diag] = base
        counts.factorisations += 1
        if info != 0:  # M is positive semi-definite: only a shift lost to rounding
            k += 1
            continue
        p = -lapack.dpotrs(c, gf, lower=1)[0]
        p = _snap(p - Q @ (Q.T @ p), STEP_BITS)
        pred = -float(gf @ p + 0.5 * p @ (B @ p))
        if not pred > GAIN_RESOLUTION:
            return None, k
        counts.evaluations += 1
        try:
            L_new = _loglik_only(x + p.reshape(n, q), root, d, ell, mu)
        except np.linalg.LinAlgError:
            L_new = -np.inf
        gain = (L_new - L) / scale
        if gain > 1e-4 * pred:
            return (p, gain / pred), k
        k += 2
    return None, k


def _lm_newton(
    x: NDArray[np.float64], root: _GramRoot, d: float, ell: float, mu: float, *, scale: float, steps_left: int,
    gtol: float, hist: list[tuple[str, float]], counts: _Counts,
) -> tuple[NDArray[np.float64], float, NDArray[np.float64], NDArray[np.float64], int]:
    """Stage 1 of :func:`_newton_stages` from ``x``: Newton steps (:func:`_lm_step`) until none gains.

    Appends ``("newton", L)`` per step to ``hist``; returns the final X, its L, gradient and Hessian, and
    the steps left.  ``λ = unit·2^k``, ``unit`` the mean |diagonal| of ``B = −∇²L/scale``, ``k`` an integer
    in [−30, 60]: −2 after a step that gained more than 3/4 of its prediction, +1 after one that gained less
    than 1/4.  Where ``B + λ/2`` is not positive definite (L curves up along some direction by more than
    λ/2), λ is raised up to 2^3-fold until it is; beyond, the step is taken with ``|B|`` (its eigenvalues'
    signs dropped, ``dsyevd``: saddle-free Newton), which moves along such a direction uphill at the
    gradient's pace instead of letting it set λ for every other direction.
    """
    n, q = x.shape
    L, g, H = _loglik_grad_hess(x, root, d, ell, mu)
    counts.hessians += 1
    k = 0
    while steps_left > 0 and np.abs(g).max() > gtol * max(abs(L), 1.0):
        B = H * (-1.0 / scale)
        gf = g.ravel() * (-1.0 / scale)
        unit = float(np.abs(np.diag(B)).mean())
        unit = unit if unit > 0 else 1.0  # a zero Hessian: every point far from all others
        raised = next((j for j in range(k, k + _MAX_RAISE + 1) if _positive_definite(B, unit * 2.0 ** (j - 1), counts)),
                      None)
        if raised is not None:
            M, k = B.copy(), raised
        else:
            b, V = np.linalg.eigh(B)
            M = (V * np.abs(b)) @ V.T
        step, k = _lm_step(x, L, M, B, gf, unit, k, root, d, ell, mu, scale=scale, counts=counts)
        if step is None:
            break
        p, rho = step
        x = x + p.reshape(n, q)
        L, g, H = _loglik_grad_hess(x, root, d, ell, mu)
        counts.hessians += 1
        counts.newton_iterations += 1
        steps_left -= 1
        hist.append(("newton", L))
        k = max(k - 2, _MIN_SHIFT_EXPONENT) if rho > 0.75 else (k + 1 if rho < 0.25 else k)
    return x, L, g, H, steps_left


def _polish_gradient(
    x: NDArray[np.float64], L: float, g: NDArray[np.float64], H: NDArray[np.float64], root: _GramRoot, d: float,
    ell: float, mu: float, *, scale: float, steps_left: int, gtol: float, hist: list[tuple[str, float]],
    counts: _Counts,
) -> NDArray[np.float64]:
    """Newton steps past the resolution of L (stage 3 of :func:`_newton_stages`), judged by the gradient.

    At a maximum along which L curves down steeply (nearly coincident points make K nearly singular), the
    last steps gain less than the rounding level of L and :func:`_lm_step` cannot tell them from losses;
    the gradient still can.  Levenberg–Marquardt steps as in :func:`_lm_step` (the shift from 2^-30 of the
    mean |diagonal| up, ×4 while a step does not shrink the largest gradient entry or loses more than the
    rounding level of L), until that entry is ≤ ``gtol``·|L| or ``steps_left`` steps.
    """
    n, q = x.shape
    lapack = scipy.linalg.lapack
    k = _MIN_SHIFT_EXPONENT
    while steps_left > 0 and np.abs(g).max() > gtol * max(abs(L), 1.0):
        B = H * (-1.0 / scale)
        gf = g.ravel() * (-1.0 / scale)
        unit = float(np.abs(np.diag(B)).mean()) or 1.0
        Q = _rigid_motions(x)
        diag = np.diag_indices_from(B)
        base = B[diag].copy()
        step = None
        while step is None and k <= 0:
            B[diag] = base + unit * 2.0**k
            c, info = lapack.dpotrf(B, lower=1, clean=1)
            counts.factorisations += 1
            k += 2
            if info != 0:
                continue
            p = -lapack.dpotrs(c, gf, lower=1)[0]
            p = _snap(p - Q @ (Q.T @ p), STEP_BITS)
            try:
                new = _loglik_grad_hess(x + p.reshape(n, q), root, d, ell, mu)
            except np.linalg.LinAlgError:
                continue
            counts.hessians += 1
            if np.abs(new[1]).max() < np.abs(g).max() and new[0] >= L - GAIN_RESOLUTION * abs(L):
                step = p, new
        if step is None:
            break
        k = max(k - 4, _MIN_SHIFT_EXPONENT)  # back to the shift before the one that worked, less 2
        x = x + step[0].reshape(n, q)
        L, g, H = step[1]
        counts.newton_iterations += 1
        steps_left -= 1
        hist.append(("newton", L))
    return x


def _newton_stages(
    X0: NDArray[np.float64], root: _GramRoot, d: float, ell: float, mu: float, *, newton_iterations: int,
    gtol: float, max_escapes: int, counts: _Counts,
) -> tuple[NDArray[np.float64], float, list[tuple[str, float]]]:
    """The ``newton`` method from X₀; returns the final X, the L of its start and ``(stage, L)`` per step.

    0. The start X₀ is rounded to :data:`POINT_BITS` bits of its largest entry (:func:`_snap`).
    1. Newton steps with the exact Hessian in Levenberg–Marquardt form (:func:`_lm_newton`,
       :func:`_lm_step`): ``p = (M + λI)⁻¹∇L/s`` with ``M = −∇²L/s`` (``s`` the power of two
       just above |L(X₀)|), or its absolute value where L curves up by more than λ/2 along some
       direction (saddle-free Newton); λ on the ladder ``unit·2^k``; the step's rigid-motion
       component removed and the rest rounded to :data:`STEP_BITS` bits of its largest entry;
       accepted when L gains at least 1e-4 of the quadratic model's prediction.  Until the
       largest gradient entry is ≤ ``gtol``·|L|, or no step is predicted to gain more than
       :data:`GAIN_RESOLUTION`·s (the rounding level of L), or ``newton_iterations`` steps.
    2. Saddle points: a stationary point where M is not positive semi-definite (its smallest
       eigenvalue below −:data:`SADDLE_CURVATURE` × its mean |diagonal|, LAPACK's ``dsyevr``) is
       left along that eigenvector (:func:`_escape_saddle`), and stage 1 resumes; at most
       ``max_escapes`` times.
    3. :func:`_polish_gradient`: Newton steps judged by the gradient, where L can no longer judge
       them.  The result is a local maximum: gradient at rounding level, Hessian negative
       semi-definite up to the rigid motions.

    Why this form: see the module docstring, "Reproducibility".
    """
    x = _snap(X0, POINT_BITS)
    L_start = _loglik_only(x, root, d, ell, mu)
    counts.evaluations += 1
    scale = float(np.ldexp(1.0, int(np.frexp(max(abs(L_start), 1.0))[1])))
    hist: list[tuple[str, float]] = []
    steps_left = int(newton_iterations)
    for round_ in range(int(max_escapes) + 1):
        x, L, g, H, steps_left = _lm_newton(x, root, d, ell, mu, scale=scale, steps_left=steps_left, gtol=gtol,
                                            hist=hist, counts=counts)
        v = _ascent_curvature(H, scale, counts) if round_ < int(max_escapes) and steps_left > 0 else None
        escaped = None if v is None else _escape_saddle(x, v, L, root, d, ell, mu, scale=scale, counts=counts)
        if escaped is None:
            break
        x, L_esc = escaped
        counts.newton_iterations += 1
        steps_left -= 1
        hist.append(("newton", L_esc))
    x = _polish_gradient(x, L, g, H, root, d, ell, mu, scale=scale, steps_left=min(steps_left, 10), gtol=gtol,
                         hist=hist, counts=counts)
    return x, L_start, hist


def _ascent_curvature(H: NDArray[np.float64], scale: float, counts: _Counts) -> NDArray[np.float64] | None:
    """At a stationary point: the eigenvector of the most positive curvature of L where it is a saddle
    (smallest eigenvalue of ``M = −H/scale`` below −:data:`SADDLE_CURVATURE` × its mean |diagonal|), else None.  Its sign
    is fixed (largest-magnitude entry positive)."""
    lapack = scipy.linalg.lapack
    B = H * (-1.0 / scale)
    dB = float(np.abs(np.diag(B)).mean())
    diag = np.diag_indices_from(B)
    B[diag] += SADDLE_CURVATURE * dB
    counts.factorisations += 1
    if lapack.dpotrf(B, lower=1, clean=0)[1] == 0:
        return None  # negative semi-definite up to SADDLE_CURVATURE of its scale: a maximum
    B[diag] -= SADDLE_CURVATURE * dB
    w, v = scipy.linalg.eigh(B, subset_by_index=[0, 0], driver="evr")
    if not w[0] < -SADDLE_CURVATURE * dB:
        return None
    u = v[:, 0]
    return u if u[np.abs(u).argmax()] > 0 else -u


def _escape_saddle(
    x: NDArray[np.float64], v: NDArray[np.float64], L: float, root: _GramRoot, d: float, ell: float, mu: float, *,
    scale: float, counts: _Counts,
) -> tuple[NDArray[np.float64], float] | None:
    """Move from a saddle point along ``±v`` (a direction of positive curvature of L), the length doubled or
    halved from 0.01ℓ while L increases, the step rounded like a Newton step; returns the new X and its L,
    or None.  ``−v`` is taken only where it gains more than ``+v`` by more than the rounding level of L."""
    n, q = x.shape
    best: tuple[float, NDArray[np.float64]] | None = None
    for sign in (1.0, -1.0):
        u = (sign * v).reshape(n, q)

        def point(a: float) -> NDArray[np.float64]:
            return x + _snap(a * u, STEP_BITS)

        def value(a: float) -> float:
            counts.evaluations += 1
            try:
                return _loglik_only(point(a), root, d, ell, mu)
            except np.linalg.LinAlgError:
                return -np.inf

        a = 0.01 * ell
        La = value(a)
        if La > L:
            while a <= 1e3 * ell:
                Lb = value(2.0 * a)
                if not Lb > La:
                    break
                a, La = 2.0 * a, Lb
        else:
            for _ in range(30):
                a *= 0.5
                La = value(a)
                if La > L:
                    break
        if La > L and (best is None or La > best[0] + GAIN_RESOLUTION * scale):
            best = (La, point(a))
    return None if best is None else (best[1], best[0])


def _start_rule(Y: NDArray[np.float64], init_scale: str | float, ell: float) -> tuple[str, float]:
    """The label and factor of one start scale ``init_scale`` (a rule of :data:`INIT_SCALES` or a factor > 0)."""
    if isinstance(init_scale, str):
        return init_scale, _scale_factor(Y, init_scale, ell)
    factor = float(init_scale)
    if not np.isfinite(factor) or factor <= 0:
        raise ValueError(f"init_scale factor must be > 0, got {init_scale!r}")
    return "factor", factor


def _fit_newton(
    g: NDArray[np.float64], d: float, Y: NDArray[np.float64], *, ell: float, mu: float, init_scale: str | float,
    newton_iterations: int, gtol: float, max_escapes: int,
) -> FitResult:
    """:func:`fit` with ``method="newton"``: :func:`_newton_stages` from each start scale, the best L kept.

    ``init_scale="best"``: from each rule of :data:`NEWTON_TRIAL_SCALES`, to convergence; a later
    rule is kept only where its L exceeds the earlier one's by more than :data:`GAIN_RESOLUTION`
    (a tie within rounding goes to the first rule, on every machine).
    """
    root = _GramRoot(g)
    counts = _Counts()
    if isinstance(init_scale, str) and init_scale == "best":
        rules: list[tuple[str, float]] = [(r, _scale_factor(Y, r, ell)) for r in NEWTON_TRIAL_SCALES]
    else:
        rules = [_start_rule(Y, init_scale, ell)]
    runs = []
    for label, factor in rules:
        before = counts.newton_iterations
        X, L_start, hist = _newton_stages(Y * factor, root, d, ell, mu, newton_iterations=newton_iterations,
                                          gtol=gtol, max_escapes=max_escapes, counts=counts)
        L = log_likelihood(X, g, d, ell, mu)
        runs.append((L, label, factor, X, L_start, hist, counts.newton_iterations - before))
    best = runs[0]
    for run in runs[1:]:
        if run[0] > best[0] + GAIN_RESOLUTION * abs(best[0]):
            best = run
    L_fin, label, factor, X_fin, L_init, hist, steps = best
    stages = ["start"] + [st for st, _ in hist]
    trace = list(enumerate([L_init] + [v for _, v in hist]))
    trace[-1] = (trace[-1][0], L_fin)
    res = FitResult(X_fin, L_fin, trace, ell, mu, d, label, factor, L_init, 0, 0, 0, float("nan"), 0.0, 0.0)
    res.scale_trials = {run[1]: run[0] for run in runs} if len(runs) > 1 else {}
    res.method, res.stages, res.hj_log_likelihood = "newton", stages, float("nan")
    res.newton_iterations = steps
    res.trial_iterations = counts.newton_iterations - steps
    res.gradient_evaluations = counts.evaluations
    res.hessian_evaluations = counts.hessians
    return res


@dataclass(frozen=True, eq=False)
class _HJSettings:
    """The data and fixed settings of :func:`fit`'s Hooke–Jeeves runs (methods ``hybrid``, ``hooke-jeeves``)."""

    gram: NDArray[np.float64]
    d: float
    ell: float
    mu: float
    seed: int
    step: float
    min_step: float
    refactor_every: int
    tol: float
    ftol: float


def _hj_run(
    s: _HJSettings, X0: NDArray[np.float64], sweeps: int, sweep0: int = 0
) -> tuple[_State, list[tuple[int, float]], tuple[int, int, float, float, int]]:
    """At most ``sweeps`` Hooke–Jeeves sweeps from X₀, seeded by ``(seed, sweep0)`` and numbered from ``sweep0``.

    Returns the final state, the ``(sweep, L)`` trace and ``(accepted
    moves, evaluations, final step, max drift, sweeps)``.
    """
    st = _full_state(X0, s.gram, s.ell, s.mu)
    rng = np.random.default_rng([s.seed, sweep0])
    trace, acc, ev, stp, drift, nsw = _hooke_jeeves(
        st, s.gram, s.d, s.ell, s.mu, rng=rng, max_sweeps=sweeps, step=s.step, min_step=s.min_step,
        refactor_every=s.refactor_every, tol=s.tol, ftol=s.ftol,
    )
    return st, [(k + sweep0, v) for k, v in trace], (acc, ev, stp, drift, nsw)


@dataclass
class _HJStart:
    """Where :func:`fit`'s Hooke–Jeeves search starts: the scale rule and, after trials of every rule, their work."""

    label: str
    factor: float
    X: NDArray[np.float64]
    sweep0: int
    remaining: int
    #: L at the start (None: not computed yet).
    L_init: float | None
    #: The chosen trial's ``(sweep, L)`` trace (empty without trials).
    trace: list[tuple[int, float]] = field(default_factory=list)
    trials: dict[str, float] = field(default_factory=dict)
    accepted: int = 0
    evaluations: int = 0
    drift: float = 0.0


def _hj_start(
    s: _HJSettings, Y: NDArray[np.float64], init_scale: str | float, trial_sweeps: int, max_sweeps: int
) -> _HJStart:
    """The search's start: one rule, or (``init_scale="best"``) the best of :data:`INIT_SCALES` after trial sweeps."""
    if not (isinstance(init_scale, str) and init_scale == "best"):
        label, factor = _start_rule(Y, init_scale, s.ell)
        return _HJStart(label, factor, Y * factor, 0, int(max_sweeps), None)
    trials: dict[str, float] = {}
    acc = ev = 0
    drift = 0.0
    best: tuple[float, str, float, _State, list[tuple[int, float]]] | None = None
    n_trial = min(int(trial_sweeps), int(max_sweeps))
    for rule in INIT_SCALES:
        factor = _scale_factor(Y, rule, s.ell)
        st_t, tr_t, (a_t, e_t, _, dr_t, _) = _hj_run(s, Y * factor, n_trial)
        acc, ev, drift = acc + a_t, ev + e_t, max(drift, dr_t)
        L_t = tr_t[-1][1]
        trials[rule] = L_t
        if best is None or L_t > best[0]:
            best = (L_t, rule, factor, st_t, tr_t)
    assert best is not None
    _, label, factor, st_b, trace = best
    sweep0 = trace[-1][0]
    return _HJStart(label, factor, st_b.X, sweep0, int(max_sweeps) - sweep0, trace[0][1], trace, trials, acc, ev,
                    drift)


@dataclass
class _HJEnd:
    """The outcome of :func:`fit`'s stages after the start (methods ``hybrid``, ``hooke-jeeves``)."""

    X: NDArray[np.float64]
    trace: list[tuple[int, float]]
    stages: list[str]
    L_init: float
    #: L when the Hooke–Jeeves stage ended.
    L_hj: float
    #: L-BFGS iterations.
    nit: int
    #: Accepted moves, evaluations, final step and max drift of the search after the start.
    accepted: int
    evaluations: int
    step: float
    drift: float


def _hooke_jeeves_stage(s: _HJSettings, start: _HJStart) -> _HJEnd:
    """Method ``hooke-jeeves``: the search continues from the start for the sweeps left."""
    st, tr2, (a2, e2, stp, dr2, _) = _hj_run(s, start.X, max(start.remaining, 0), start.sweep0)
    trace = start.trace + (tr2[1:] if start.trace else tr2)
    L_init = trace[0][1] if start.L_init is None else start.L_init
    stages = ["hooke-jeeves"] * len(trace)
    return _HJEnd(st.X, trace, stages, L_init, trace[-1][1], 0, a2, e2, stp, dr2)


def _hybrid_stages(
    s: _HJSettings, start: _HJStart, Y: NDArray[np.float64], *, max_iter: int, ftol: float, gtol: float
) -> _HJEnd:
    """Method ``hybrid``: L-BFGS from the chosen start, Hooke–Jeeves from its optimum, L-BFGS again if that moved.

    (The search's finite steps can leave a stationary point.)
    """
    g, d_f, ell, mu = s.gram, s.d, s.ell, s.mu
    X_start = Y * start.factor
    L_init = log_likelihood(X_start, g, d_f, ell, mu)
    X1, hist1, nit = _lbfgs_polish(X_start, g, d_f, ell, mu, max_iter=max_iter, ftol=ftol, gtol=gtol)
    trace = [(0, L_init)] + [(k + 1, v) for k, v in enumerate(hist1)]
    stages = ["start"] + ["lbfgs"] * len(hist1)
    st, tr2, (a2, e2, stp, dr2, _) = _hj_run(s, X1, max(start.remaining, 0), len(trace) - 1)
    trace[-1] = (trace[-1][0], tr2[0][1])
    trace += tr2[1:]
    stages += ["hooke-jeeves"] * (len(tr2) - 1)
    X_fin, L_hj = st.X, trace[-1][1]
    if a2 > 0:
        X_fin, hist3, nit3 = _lbfgs_polish(st.X, g, d_f, ell, mu, max_iter=max_iter, ftol=ftol, gtol=gtol)
        last = trace[-1][0]
        trace += [(last + k + 1, v) for k, v in enumerate(hist3)]
        stages += ["lbfgs"] * len(hist3)
        nit += nit3
    trace[-1] = (trace[-1][0], log_likelihood(X_fin, g, d_f, ell, mu))
    return _HJEnd(X_fin, trace, stages, L_init, L_hj, nit, a2, e2, stp, dr2)


def _hj_result(s: _HJSettings, start: _HJStart, end: _HJEnd, method: str) -> FitResult:
    """The :class:`FitResult` of a ``hybrid`` / ``hooke-jeeves`` fit (``seconds`` left at 0)."""
    res = FitResult(
        end.X, end.trace[-1][1], end.trace, s.ell, s.mu, s.d, start.label, start.factor, end.L_init,
        sum(st_ == "hooke-jeeves" for st_ in end.stages), start.accepted + end.accepted,
        start.evaluations + end.evaluations, end.step, max(start.drift, end.drift), 0.0,
    )
    res.scale_trials = start.trials
    res.method, res.stages, res.hj_log_likelihood, res.polish_iterations = method, end.stages, end.L_hj, end.nit
    return res


def _fit_hooke_jeeves(
    s: _HJSettings, Y: NDArray[np.float64], method: str, *, init_scale: str | float, trial_sweeps: int,
    max_sweeps: int, polish_iterations: int, polish_ftol: float, polish_gtol: float,
) -> FitResult:
    """:func:`fit` with ``method="hybrid"`` or ``"hooke-jeeves"``: the start, the stages, the result."""
    start = _hj_start(s, Y, init_scale, trial_sweeps, max_sweeps)
    if method == "hooke-jeeves":
        end = _hooke_jeeves_stage(s, start)
    else:
        end = _hybrid_stages(s, start, Y, max_iter=polish_iterations, ftol=polish_ftol, gtol=polish_gtol)
    return _hj_result(s, start, end, method)


def _check_fit_options(
    *, method: str, max_sweeps: int, refactor_every: int, step: float | None, min_step: float | None, ell: float,
    newton_iterations: int, max_escapes: int, newton_gtol: float,
) -> tuple[float, float]:
    """Check :func:`fit`'s options (ValueError naming the first bad one); returns the search's step and min_step."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    if isinstance(max_sweeps, bool) or int(max_sweeps) < 0:
        raise ValueError(f"max_sweeps must be >= 0, got {max_sweeps!r}")
    if int(refactor_every) < 1:
        raise ValueError(f"refactor_every must be >= 1, got {refactor_every!r}")
    step0 = ell / 4.0 if step is None else float(step)
    min_step_f = ell * 1e-3 if min_step is None else float(min_step)
    if not step0 > 0 or not min_step_f > 0:
        raise ValueError("step and min_step must be > 0")
    for name, value, low in (("newton_iterations", newton_iterations, 0), ("max_escapes", max_escapes, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if not np.isfinite(float(newton_gtol)) or not float(newton_gtol) > 0:
        raise ValueError(f"newton_gtol must be a finite number > 0, got {newton_gtol!r}")
    return step0, min_step_f


def fit(
    gram: ArrayLike,
    d: float,
    *,
    q: int,
    ell: float = 1.0,
    mu: float = 1e-4,
    seed: int = 0,
    max_sweeps: int = 200,
    init_scale: str | float = "best",
    refactor_every: int = 200,
    step: float | None = None,
    min_step: float | None = None,
    trial_sweeps: int = 10,
    tol: float = 1e-15,
    ftol: float = 1e-9,
    method: str = "newton",
    polish_iterations: int = 5000,
    polish_ftol: float = 1e-12,
    polish_gtol: float = 1e-8,
    newton_iterations: int = 2000,
    newton_gtol: float = 1e-10,
    max_escapes: int = 10,
) -> FitResult:
    """Maximise eq. 6 over the latent points (``method``: see the module docstring, "Optimisation").

    ``gram``: centred Gram matrix (N × N); ``d``: column count (enters only
    as a number).

    ``method="newton"`` (the default; :func:`_newton_stages`): the start is
    :func:`pca_init` scaled by ``init_scale`` (``"best"``: from each rule of
    :data:`NEWTON_TRIAL_SCALES`, and the highest L is kept); from it, at most
    ``newton_iterations`` Newton (Levenberg–Marquardt) steps with the exact
    Hessian, until the largest gradient entry is ≤ ``newton_gtol``·|L| or no
    step can gain above the rounding level of L, leaving at most
    ``max_escapes`` saddle points.  The Hooke–Jeeves parameters
    (``max_sweeps``, ``seed``, …) are not used: the method has no random
    element, and its result is the same local maximum on every BLAS kernel
    (module docstring, "Reproducibility").

    ``method="hybrid"`` / ``"hooke-jeeves"``: ``polish_*`` are L-BFGS-B's
    iteration cap and relative tolerances (hybrid only).  Initialisation: :func:`pca_init` scaled by ``init_scale``
    (a rule of :data:`INIT_SCALES`, a number = the factor itself, ``"pca"`` = the
    scores as they are (factor 1, Soler §3), or ``"best"``: every rule is run for ``trial_sweeps`` sweeps and the one with
    the highest L continues).  Search: a global step (default ``ℓ/4``) for
    every coordinate; each sweep visits the points in a seeded random order,
    tries ±step on each coordinate of the point (first improvement taken),
    then pattern moves along the point's displacement (doubling while L
    improves); a sweep without any accepted move halves the step; stop after
    ``max_sweeps`` sweeps or when the step falls below ``min_step`` (default
    ``ℓ·1e-3``).  Only strictly improving moves (ΔL > tol·|L|) are accepted, so
    the trace never decreases (up to the refactorisation drift, recorded in
    ``max_drift``).  ``K⁻¹`` and log|K| are updated by the rank-2 formulas
    and refactorised every ``refactor_every`` accepted moves and at the end.
    """
    q = _check_q(q)
    ell, mu = _check_hyper(ell, mu)
    g, d_f = _check_gram(gram, d)
    step0, min_step_f = _check_fit_options(
        method=method, max_sweeps=max_sweeps, refactor_every=refactor_every, step=step, min_step=min_step, ell=ell,
        newton_iterations=newton_iterations, max_escapes=max_escapes, newton_gtol=newton_gtol,
    )
    t0 = time.perf_counter()
    Y = pca_init(g, q)
    if method == "newton":
        res = _fit_newton(
            g, d_f, Y, ell=ell, mu=mu, init_scale=init_scale, newton_iterations=int(newton_iterations),
            gtol=float(newton_gtol), max_escapes=int(max_escapes),
        )
        res.seconds = time.perf_counter() - t0
        logger.info(
            "GPLVM fit N=%d q=%d (newton): start %s x%.3g, L %.6g -> %.6g after %d Newton steps (%d from the other "
            "starts: %s), %d Hessians, %d evaluations of L, %.2f s",
            g.shape[0], q, res.init_scale, res.init_factor, res.initial_log_likelihood, res.log_likelihood,
            res.newton_iterations, res.trial_iterations,
            ", ".join(f"{k} {v:.6g}" for k, v in res.scale_trials.items()) or "none",
            res.hessian_evaluations, res.gradient_evaluations, res.seconds,
        )
        return res

    res = _fit_hooke_jeeves(
        _HJSettings(g, d_f, ell, mu, seed, step0, min_step_f, int(refactor_every), tol, ftol), Y, method,
        init_scale=init_scale, trial_sweeps=trial_sweeps, max_sweeps=max_sweeps,
        polish_iterations=polish_iterations, polish_ftol=polish_ftol, polish_gtol=polish_gtol,
    )
    res.seconds = time.perf_counter() - t0
    logger.info(
        "GPLVM fit N=%d q=%d (%s): L %.6g -> %.6g after %d Hooke-Jeeves sweeps (%d moves, %d evaluations, "
        "init %s x%.3g) -> %.6g after %d L-BFGS iterations, %.2f s",
        g.shape[0], q, method, res.initial_log_likelihood, res.hj_log_likelihood, res.sweeps, res.accepted_moves,
        res.evaluations, res.init_scale, res.init_factor, res.log_likelihood, res.polish_iterations, res.seconds,
    )
    return res


# --------------------------------------------------------------------------
# Interpolation
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class GplvmModel:
    """A saved fit (:func:`save_model` / :func:`load_model`)."""

    names: tuple[str, ...]
    X: NDArray[np.float64]
    ell: float
    mu: float
    space: str
    mean_handling: str
    #: Lower Cholesky factor of K (for b = K⁻¹k).
    chol: NDArray[np.float64] = field(repr=False)
    log_likelihood: float
    d: float
    trace: NDArray[np.float64] = field(repr=False)
    #: The Gram matrix was divided by this before fitting (1.0: not normalised); L is of ``G/gram_scale``.
    gram_scale: float = 1.0
    method: str = "hooke-jeeves"
    #: Whether the Gram matrix was normalised (divided by :func:`gram_scale`) before fitting.
    normalised: bool = True
    #: The start asked for (``init_scale`` of :func:`fit`: ``best``, ``pca`` or a scale rule).
    init: str = "best"
    #: Digest of the store row each material was fitted on (:func:`brdfpipe.data.store.shard_digest`, in
    #: ``names`` order); empty: not tied to a store (it cannot be used with one, see :func:`check_store`).
    data_digests: tuple[int, ...] = field(default=(), repr=False)
    #: The file it was loaded from (for messages), if any.
    path: Path | None = field(default=None, repr=False, compare=False)


def weights(
    fit_or_X: FitResult | GplvmModel | ArrayLike,
    x_star: ArrayLike,
    ell: float | None = None,
    mu: float | None = None,
) -> NDArray[np.float64]:
    """``b = K⁻¹ k(x*)`` (N,) (eq. 4), with the δ convention of the module docstring (b(x_i) = e_i).

    ``fit_or_X``: a :class:`FitResult`, a :class:`GplvmModel` (ℓ, μ default to
    theirs) or an N × q latent matrix (ℓ, μ default to 1, 1e-4).  ValueError if
    ``x_star`` is not a length-q vector.
    """
    chol = None
    if isinstance(fit_or_X, (FitResult, GplvmModel)):
        X = fit_or_X.X
        ell = fit_or_X.ell if ell is None else ell
        mu = fit_or_X.mu if mu is None else mu
        if isinstance(fit_or_X, GplvmModel) and ell == fit_or_X.ell and mu == fit_or_X.mu:
            chol = fit_or_X.chol
    else:
        X = _check_X(fit_or_X)
        ell = 1.0 if ell is None else ell
        mu = 1e-4 if mu is None else mu
    k = kernel_vector(X, x_star, ell, mu)
    if chol is None:
        chol = np.linalg.cholesky(kernel_matrix(X, ell, mu))
    return scipy.linalg.cho_solve((chol, True), k)


def blend_weights(b: ArrayLike) -> NDArray[np.float64]:
    """``w_i = b_i + (1 − Σb)/N``: weights of the un-centred material rows, Σw = 1.

    ``z* = μ̄ + bᵀ(Z − 1μ̄ᵀ) = Σ_i w_i z_i``, so images of the materials blend
    with the same ``w``.
    """
    b64 = np.asarray(b, dtype=np.float64)
    if b64.ndim != 1 or b64.size == 0:
        raise ValueError(f"b must be a non-empty vector, got shape {b64.shape}")
    return b64 + (1.0 - b64.sum()) / b64.size


def interpolate_table(
    store_path: str | os.PathLike[str] | BrdfStore,
    weights: ArrayLike,
    *,
    materials: Sequence[str] | None = None,
    space: str = "raw",
    model: GplvmModel | None = None,
) -> tuple[NDArray[np.float64], int]:
    """``Σ_i w_i z_i`` as a MERL table ``(3, 90, 90, 180)`` float64 and the number of clamped values.

    ``weights``: blend weights (:func:`blend_weights`) of ``materials`` (in
    that order; default all of the store).  See :func:`interpolate_tables`
    (also for ``model``).
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1:
        raise ValueError(f"weights must be a vector (one per material), got shape {w.shape}")
    tables, clamped = interpolate_tables(store_path, w[None, :], materials=materials, space=space, model=model)
    return tables[0], int(clamped[0])


def interpolate_tables(
    store_path: str | os.PathLike[str] | BrdfStore,
    weights: ArrayLike,
    *,
    materials: Sequence[str] | None = None,
    space: str = "raw",
    model: GplvmModel | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Several blends ``W Z`` in one pass over the store: tables ``(P, 3, 90, 90, 180)`` and clamp counts ``(P,)``.

    ``model``: the model whose weights these are; the store is then checked
    to hold the rows it was fitted on (:func:`check_store`), ``materials``
    defaults to its materials and must be them, and ``space`` must be its
    space.

    ``weights`` is ``(P, N)``: one row of blend weights per output table,
    over ``materials`` (in that order; default all of the store).  In the
    :data:`~brdfpipe.manifold.gram.LINEAR_SPACES` the blend is of the stored values (their factor is
    per value, so blending before or after it is the same).
    In the ``log`` space the blend is taken of the log-mapped values, with the
    same ρ_ref (median of ``materials``) and weights as :func:`~brdfpipe.manifold.gram.gram_matrix`,
    and mapped back with :func:`brdfpipe.data.logmap.inverse`.  Cells not valid in
    every material of the store are written as −1 (unmeasured, like MERL);
    values that come out negative in valid cells are clamped to 0 and
    counted (logged as a warning).  Streamed by column blocks of the store;
    the P output tables (8·4.37M bytes each) are the memory cost.
    """
    check_space(space)
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    if model is not None:
        check_store(model, st)
        materials = model.names if materials is None else materials
        if list(materials) != list(model.names) or space != model.space:
            raise ValueError(f"{model.path or 'the model'}: interpolate over its materials in its space "
                             f"({model.space!r}), got {len(list(materials))} materials in space {space!r}")
    spaces.check_blendable(space)
    idx = select_materials(st, materials)
    W = np.asarray(weights, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != idx.size:
        raise ValueError(f"weights must have shape (P, {idx.size}) (one per material), got {W.shape}")
    if not np.isfinite(W).all():
        raise ValueError("weights have non-finite entries")
    order = np.argsort(idx, kind="stable")
    rows, W_sorted = idx[order], W[:, order]
    valid = np.asarray(st.valid[:], dtype=bool)
    if space == "log":
        cells = np.flatnonzero(valid).astype(np.int64)
        ref_all = logmap.median_reference(st, [st.materials[i] for i in idx], cells)
        wt_all = logmap.cell_weights(cells, "product")
    P = W.shape[0]
    out = np.full((P, 3 * N_CELLS), -1.0)
    clamped = np.zeros(P, dtype=np.int64)
    for start, stop, block in iter_column_blocks(st, rows=rows):
        cell = np.arange(start, stop) % N_CELLS
        keep = valid[cell]
        if not keep.any():
            continue
        if space == "log":
            pos = np.searchsorted(cells, cell[keep])
            ref, wt = ref_all[pos], wt_all[pos]
            vals = logmap.inverse(W_sorted @ logmap.forward(block[:, keep], ref, wt), ref, wt)
        else:
            vals = W_sorted @ block[:, keep].astype(np.float64)
        neg = vals < 0
        clamped += neg.sum(axis=1)
        vals[neg] = 0.0
        seg = out[:, start:stop]
        seg[:, keep] = vals
    if clamped.any():
        logger.warning("interpolated tables: %s negative values in measured cells clamped to 0", clamped.tolist())
    return out.reshape((P, *merl.SHAPE)), clamped


# --------------------------------------------------------------------------
# Saving a fit
# --------------------------------------------------------------------------


def save_model(
    path: str | os.PathLike[str],
    result: FitResult,
    names: Sequence[str],
    *,
    space: str = "raw",
    mean_handling: str = MEAN_HANDLING,
    gram_scale: float = 1.0,
    normalised: bool = True,
    init: str = "best",
    data_digests: Sequence[int] = (),
) -> None:
    """Write a fit to an npz file atomically, with its digest (:func:`brdfpipe.core.integrity.save_npz`).

    Arrays: names, X, ℓ, μ, space, mean handling, chol(K) (the factor that
    interpolation needs: ``b = K⁻¹k``), L, d, trace, gram scale, method,
    ``normalised`` (the Gram matrix divided by the gram scale), ``init`` (the
    start asked for) and ``data_digests``: the digests of the store rows the materials were fitted
    on (from the Gram file, :attr:`brdfpipe.manifold.gram.GramInfo.digests`; empty for a fit that
    did not come from a store), which every use with a store checks
    (:func:`check_store`).
    """
    check_space(space)
    names = [str(n) for n in names]
    if len(names) != result.X.shape[0]:
        raise ValueError(f"{len(names)} names for {result.X.shape[0]} latent points")
    chol = np.linalg.cholesky(kernel_matrix(result.X, result.ell, result.mu))
    _atomic_savez(
        Path(path),
        format=np.array(MODEL_FORMAT),
        names=np.array(names, dtype=str),
        X=result.X,
        ell=np.array(result.ell),
        mu=np.array(result.mu),
        space=np.array(space),
        mean_handling=np.array(mean_handling),
        chol=chol,
        log_likelihood=np.array(result.log_likelihood),
        d=np.array(result.d),
        trace=np.array(result.trace, dtype=np.float64).reshape(-1, 2),
        gram_scale=np.array(float(gram_scale)),
        method=np.array(result.method),
        normalised=np.array(bool(normalised)),
        init=np.array(str(init)),
        data_digests=_digest_array(path, data_digests, len(names), "data_digests"),
        digest_algorithm=np.array(STORE_DIGEST_ALGORITHM),
    )


def load_model(path: str | os.PathLike[str]) -> GplvmModel:
    """Read what :func:`save_model` wrote, its digest checked.

    :class:`GplvmFileError` (a ValueError) naming the file and what to rerun
    for a missing, truncated, corrupt, unverifiable or edited file, a retired
    or other format, or inconsistent arrays.
    """
    z = _load(path, MODEL_FORMAT, "GPLVM model")
    try:
        names = tuple(str(n) for n in z["names"])
        X = np.asarray(z["X"], dtype=np.float64)
        digests = tuple(int(v) for v in z["data_digests"])
        if str(z["digest_algorithm"]) != STORE_DIGEST_ALGORITHM:
            raise ValueError(f"data digests of another kind ({str(z['digest_algorithm'])!r})")
        model = GplvmModel(
            names, X, float(z["ell"]), float(z["mu"]), str(z["space"]),
            str(z["mean_handling"]), z["chol"], float(z["log_likelihood"]), float(z["d"]), z["trace"],
            float(z["gram_scale"]), str(z["method"]), bool(z["normalised"]), str(z["init"]),
            data_digests=digests, path=Path(path),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise GplvmFileError(f"{path}: inconsistent GPLVM model ({type(exc).__name__}: {exc})") from None
    n = len(names)
    if X.ndim != 2 or X.shape[0] != n or model.chol.shape != (n, n) or (digests and len(digests) != n):
        raise GplvmFileError(f"{path}: inconsistent GPLVM model (X {X.shape}, chol {model.chol.shape} for "
                             f"{n} materials, {len(digests)} data digests)")
    return model


def store_digests(store: BrdfStore | str | os.PathLike[str], names: Sequence[str]) -> tuple[int, ...]:
    """The digests of the store rows of ``names`` (what :func:`save_model` records for a fit on that store)."""
    st = store if isinstance(store, BrdfStore) else open_store(store)
    idx = material_indices(st, names, "materials")
    return tuple(int(st.digests[i]) for i in idx)


def _check_rows(label: str, kind: str, names: Sequence[str], digests: Sequence[int], st: BrdfStore,
                hint: str) -> None:
    if not digests:
        raise DataMismatchError(
            f"{label}: the {kind} records no digests of the store rows it was fitted on, so it cannot be checked "
            f"against the store {st.path}; {hint}"
        )
    index = {m: i for i, m in enumerate(st.materials)}
    missing = [m for m in names if m not in index]
    if missing:
        raise DataMismatchError(
            f"{label}: material(s) {', '.join(missing[:5])}{' …' if len(missing) > 5 else ''} of the {kind} "
            f"are not in the store {st.path}; use the store it was fitted on, or {hint}"
        )
    for name, digest in zip(names, digests):
        if int(st.digests[index[name]]) != int(digest):
            raise DataMismatchError(
                f"{label}: material {name!r} of the store {st.path} is not the data the {kind} was fitted on "
                f"(the row's digest differs: the store was ingested from other files, or its rows were "
                f"swapped); use the store it was fitted on, or {hint}"
            )


def check_store(model: GplvmModel, store: BrdfStore | str | os.PathLike[str]) -> BrdfStore:
    """Check that ``store`` holds the rows ``model`` was fitted on; returns the opened store.

    Every material of the model must be in the store with the row digest the
    model recorded (:attr:`GplvmModel.data_digests`), so a store of the same
    names whose rows differ (re-ingested from other files, rows swapped) is
    refused with a :class:`DataMismatchError` naming the model, the store and
    the material, as is a model that records no digests.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    label = str(model.path) if model.path is not None else "the GPLVM model"
    hint = (f"refit the model ({integrity.rerun_hint(model.path)})" if model.path is not None
            else "refit the model on this store")
    _check_rows(label, "model", model.names, model.data_digests, st, hint)
    return st


def check_gram_store(info: GramInfo, store: BrdfStore | str | os.PathLike[str],
                     path: str | os.PathLike[str] | None = None) -> BrdfStore:
    """:func:`check_store` for a Gram file's :class:`GramInfo` (``path`` names it in messages)."""
    st = store if isinstance(store, BrdfStore) else open_store(store)
    label = str(path) if path is not None else "the Gram matrix"
    hint = (f"compute it again ({integrity.rerun_hint(path)})" if path is not None
            else "compute it again from this store")
    _check_rows(label, "Gram matrix", info.materials, info.digests, st, hint)
    return st


# --------------------------------------------------------------------------
# Workflow and command-line entry points
# --------------------------------------------------------------------------


def write_gram(store_path: str | os.PathLike[str], out: str | os.PathLike[str], *, space: str = "raw") -> None:
    """Stream the centred Gram matrix of every material of a store and save it (one pass, float64).

    The workflow's ``compute_gram`` job: every GPLVM fit of that data space
    shares this one file.
    """
    gram, d, info = gram_matrix(store_path, space=space)
    save_gram(out, gram, d, info)
    logger.info("Gram matrix of %d materials over %d columns (%s space) -> %s", gram.shape[0], d, space, out)


def fit_to_files(
    gram_path: str | os.PathLike[str],
    model_out: str | os.PathLike[str],
    trace_out: str | os.PathLike[str],
    *,
    q: int,
    ell: float = 1.0,
    mu: float = 1e-4,
    seed: int = 0,
    max_sweeps: int = 200,
    normalise: bool = True,
    method: str = "newton",
    init: str = "best",
    threads: int | None = None,
) -> FitResult:
    """Fit a q-dimensional latent space to a saved Gram matrix; write the model and its trace.

    ``threads``: the BLAS threads to use (the rule's declared threads; None
    leaves them as they are).

    The workflow's ``fit_gplvm`` job.  ``normalise``: fit to ``G/s`` with
    ``s`` = :func:`gram_scale` (stored in the model, with ``normalise``);
    ``init``: the start (``init_scale`` of :func:`fit`, recorded in the model).  ``trace_out`` is a CSV
    ``step,stage,log_likelihood`` (Soler Fig. 5; stage ``hooke-jeeves`` for
    the sweeps, ``lbfgs`` for L-BFGS iterations, ``newton`` for Newton
    steps), written atomically like the model.
    """
    gram, d, info = load_gram(gram_path)
    scale = gram_scale(gram, d) if normalise else 1.0
    with blas_threads(threads):
        result = fit(gram / scale, d, q=q, ell=ell, mu=mu, seed=seed, max_sweeps=max_sweeps, method=method,
                     init_scale=init)
    logger.info(
        "q = %d: Gram divided by %.6g; L %.6g -> %.6g in %d sweeps + %d L-BFGS iterations + %d Newton steps, "
        "%.2f s (start scale %s)",
        q, scale, result.initial_log_likelihood, result.log_likelihood, result.sweeps,
        result.polish_iterations, result.newton_iterations, result.seconds, result.init_scale,
    )
    save_model(model_out, result, info.materials, space=info.space, mean_handling=info.mean_handling,
               gram_scale=scale, normalised=normalise, init=init, data_digests=info.digests)
    write_trace(trace_out, result)
    return result


def write_trace(path: str | os.PathLike[str], result: FitResult) -> None:
    """The log-likelihood trace of a fit as CSV ``step,stage,log_likelihood`` (atomic, with its digest line)."""
    path = Path(path)
    lines = [",".join(tables.GPLVM_TRACE)]
    stages = result.stages or ["hooke-jeeves"] * len(result.trace)
    for (step, value), stage in zip(result.trace, stages):
        lines.append(f"{int(step)},{stage},{float(value)!r}")
    integrity.write_csv(path, "\n".join(lines) + "\n")


def interpolate_to_file(
    model_path: str | os.PathLike[str],
    store_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    at: Sequence[float] | None = None,
    between: tuple[str, str] | None = None,
    t: float = 0.5,
) -> int:
    """Write the BRDF at a latent point as a MERL file; returns the number of clamped values.

    The point is ``at`` (q coordinates) or the point a fraction ``t`` of the
    way from material A to material B of ``between`` (linear in the latent
    space).  The blend is Σ w_i z_i of the store's materials with the weights
    of :func:`blend_weights`, taken in the model's data space
    (:func:`interpolate_table`).  The file carries a ``derived`` provenance
    mark (:mod:`brdfpipe.manifold.derivation`: model and store digests, the
    latent point, ``between`` and ``t``).  ValueError for a point of the wrong
    length, an unknown material, both or neither of ``at`` / ``between``, a
    damaged model file (:class:`GplvmFileError`), or a store that does not
    hold the rows the model was fitted on (:class:`DataMismatchError`, naming
    the model, the store and the material: :func:`check_store`).
    """
    model = load_model(model_path)
    st = check_store(model, store_path)
    if (at is None) == (between is None):
        raise ValueError("give exactly one of a latent point (at) or two materials (between)")
    if between is not None:
        missing = [m for m in between if m not in model.names]
        if missing:
            raise ValueError(f"{model_path}: unknown material(s) {', '.join(missing)}")
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        a, b = (model.X[model.names.index(m)] for m in between)
        with np.errstate(over="ignore", invalid="ignore"):  # an overflowing point is refused below
            x_star = (1.0 - t) * a + t * b
        where = f"t = {t:g}"
    else:
        x_star = np.asarray(at, dtype=np.float64)
        where = "at = " + ",".join(f"{v:g}" for v in np.ravel(x_star))
    with np.errstate(over="ignore", invalid="ignore"):
        far = not np.isfinite(x_star).all() or (
            x_star.shape == model.X.shape[1:] and not np.isfinite(((model.X - x_star) ** 2).sum(axis=1)).all())
    if far:
        raise ValueError(f"{where}: the latent distances overflow (beyond 1.8e308 in units of ℓ = {model.ell:.6g}); "
                         "give a point nearer the materials")
    w = blend_weights(weights(model, x_star))
    table, clamped = interpolate_table(st, w, materials=model.names, space=model.space, model=model)
    details: dict[str, Any] = {"between": list(between), "t": float(t)} if between is not None else {}
    mark = derivation.BlendSource.of(model_path, model, st).mark(
        out=out, operation="interpolate", point=x_star, weights=w, **details)
    merl.write_merl(out, table, mark=mark)
    logger.info("interpolated BRDF at x* = %s -> %s (%d clamped values)", np.round(x_star, 4).tolist(), out, clamped)
    return clamped
