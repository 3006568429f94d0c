"""The GPLVM's kernel and likelihood (Soler et al. 2018, eqs. 5–6), their derivatives and the data scale.

Model
-----
Kernel (eq. 5) ``c(x, x′) = μ·δ(x, x′) + exp(−‖x − x′‖²/2ℓ²)``, so
``K = exp(−D²/2ℓ²) + μI``; objective (eq. 6)
``L(X) = −(d/2)·log|K| − ½·tr(K⁻¹ Gc)``, with ``Gc`` the centred Gram matrix
of the materials' data (:func:`brdfpipe.manifold.gram.gram_matrix`) and ``d``
its column count.  :func:`log_likelihood` and :func:`log_likelihood_grad`
check their arguments; :func:`loglik` and :func:`loglik_grad` are the same
without the checks, given the Gram matrix's square root (:class:`GramRoot`),
and :func:`loglik_grad_hess` adds the Hessian: the inner loops of the
optimisers (:mod:`brdfpipe.manifold.fitting`).

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
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import scipy.linalg
import scipy.linalg.blas
import scipy.linalg.lapack
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "check_hyper",
    "check_q",
    "check_gram",
    "check_latents",
    "check_point",
    "gram_scale",
    "sqdist",
    "kernel_matrix",
    "kernel_vector",
    "log_likelihood",
    "log_likelihood_grad",
    "GramRoot",
    "loglik",
    "loglik_grad",
    "loglik_grad_hess",
]


# --------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------


def check_hyper(ell: float, mu: float) -> tuple[float, float]:
    """``(ell, mu)`` as floats; ValueError unless ℓ > 0 and μ ≥ 0 are finite."""
    ell_f, mu_f = float(ell), float(mu)
    if not np.isfinite(ell_f) or ell_f <= 0:
        raise ValueError(f"length scale ell must be a finite number > 0, got {ell!r}")
    if not np.isfinite(mu_f) or mu_f < 0:
        raise ValueError(f"noise parameter mu must be a finite number >= 0, got {mu!r}")
    return ell_f, mu_f


def check_q(q: Any) -> int:
    """The latent dimension as an int; ValueError unless it is an integer ≥ 1."""
    if isinstance(q, bool) or not isinstance(q, (int, np.integer)) or int(q) < 1:
        raise ValueError(f"latent dimension q must be an integer >= 1, got {q!r}")
    return int(q)


def check_gram(gram: ArrayLike, d: Any) -> tuple[NDArray[np.float64], float]:
    """The Gram matrix symmetrised (float64) and ``d`` as a float; ValueError for a bad shape, entry or ``d``."""
    g = np.asarray(gram, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] != g.shape[1] or g.shape[0] < 2:
        raise ValueError(f"gram must be a square N x N matrix with N >= 2, got shape {g.shape}")
    if not np.isfinite(g).all():
        raise ValueError("gram has non-finite entries")
    d_f = float(d)
    if not np.isfinite(d_f) or d_f <= 0:
        raise ValueError(f"column count d must be > 0, got {d!r}")
    return 0.5 * (g + g.T), d_f


def check_latents(X: ArrayLike) -> NDArray[np.float64]:
    """The latent points as a float64 N × q matrix; ValueError for another shape or a non-finite entry."""
    x = np.asarray(X, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise ValueError(f"X must be an N x q matrix, got shape {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("X has non-finite entries")
    return x


def gram_scale(gram: ArrayLike, d: float) -> float:
    """``s = tr(G)/(N·d)``: the mean variance per data entry of the centred data.

    Fitting to ``G/s`` puts the data on the kernel's unit amplitude; it is the
    same as giving the kernel a fixed signal variance ``s`` (``K → sK``
    changes L by a constant and ``b = K⁻¹k`` not at all).  See the module
    docstring, "Data scale".
    """
    g, d_f = check_gram(gram, d)
    tr = float(np.trace(g))
    if not tr > 0:
        raise ValueError("gram has a non-positive trace: the centred data are all zero")
    return tr / (g.shape[0] * d_f)


# --------------------------------------------------------------------------
# Kernel and likelihood
# --------------------------------------------------------------------------


def sqdist(X: NDArray[np.float64]) -> NDArray[np.float64]:
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
    ell, mu = check_hyper(ell, mu)
    x = check_latents(X)
    K = np.exp(-sqdist(x) / (2.0 * ell * ell))
    K[np.diag_indices_from(K)] = 1.0 + mu
    return K


def kernel_vector(X: ArrayLike, x_star: ArrayLike, ell: float = 1.0, mu: float = 1e-4) -> NDArray[np.float64]:
    """``k(x*)_j = c(x_j, x*)`` including μ where ``x*`` equals ``x_j`` exactly
    (:mod:`brdfpipe.manifold.gplvm`, "Interpolation")."""
    ell, mu = check_hyper(ell, mu)
    x = check_latents(X)
    xs = check_point(x_star, x.shape[1])
    diff = x - xs
    d2 = np.einsum("ij,ij->i", diff, diff)
    k = np.exp(-d2 / (2.0 * ell * ell))
    k[(diff == 0).all(axis=1)] += mu
    return k


def check_point(x_star: ArrayLike, q: int) -> NDArray[np.float64]:
    """A latent point as a float64 vector of length ``q``; ValueError for another shape or a non-finite entry."""
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
    g, d_f = check_gram(gram, d)
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
    of G (:class:`GramRoot`; ≈ 4N³ flops in all) and O(N²q) for the kernel
    and the contraction — no N × N × q array.  Used by the L-BFGS stage
    of :func:`brdfpipe.manifold.fitting.fit` (``hybrid``) and checked against finite differences in the tests.
    """
    g, d_f = check_gram(gram, d)
    ell, mu = check_hyper(ell, mu)
    x = check_latents(X)
    if x.shape[0] != g.shape[0]:
        raise ValueError(f"X has {x.shape[0]} rows but gram is {g.shape[0]} x {g.shape[0]}")
    return loglik_grad(x, GramRoot(g), d_f, ell, mu)


class GramRoot:
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


def _factor(x: NDArray[np.float64], ell: float, mu: float) -> tuple[float, NDArray[np.float64], NDArray[np.float64],
                                                                 float, NDArray[np.float64]]:
    """The kernel of ``x`` factorised: ``(s, E, c, log det K, K⁻¹)`` with ``s = 1/ℓ²``, ``E = exp(−s d²/2)``,
    ``K = E + μI`` (diagonal 1 + μ), ``c`` its lower Cholesky factor and K⁻¹ in its lower triangle only
    (LAPACK's dpotri: the strict upper triangle is zero).  LinAlgError if K is not positive definite."""
    lapack = scipy.linalg.lapack
    s = 1.0 / (ell * ell)
    E = np.exp(sqdist(x) * (-0.5 * s))
    K = E.copy()
    np.fill_diagonal(K, 1.0 + mu)
    c, info = lapack.dpotrf(K, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("K is not positive definite")
    logdet = 2.0 * float(np.log(np.diag(c)).sum())
    Kinv_l, info = lapack.dpotri(c, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("K could not be inverted")
    return s, E, c, logdet, Kinv_l


def _root_solves(c: NDArray[np.float64], root: GramRoot) -> Iterator[tuple[float, NDArray[np.float64],
                                                                            NDArray[np.float64]]]:
    """Per part of the Gram matrix's root (G = R₊R₊ᵀ − R₋R₋ᵀ): its sign, L⁻¹R and K⁻¹R, with ``c`` = L."""
    blas = scipy.linalg.blas
    for R, sign in ((root.plus, 1.0), (root.minus, -1.0)):
        if R is None or R.shape[1] == 0:
            continue
        S = blas.dtrsm(1.0, c, R, lower=1)  # L⁻¹R
        yield sign, S, blas.dtrsm(1.0, c, S, lower=1, trans_a=1)  # K⁻¹R


def loglik_grad(
    x: NDArray[np.float64], root: GramRoot, d: float, ell: float, mu: float
) -> tuple[float, NDArray[np.float64]]:
    """:func:`log_likelihood_grad` without validation (the L-BFGS stage's inner loop)."""
    blas = scipy.linalg.blas
    s, E, c, logdet, Kinv_l = _factor(x, ell, mu)
    # Lower triangles only (dpotri and dsyrk leave the strict upper triangle zero), mirrored once.
    Wl = Kinv_l
    Wl *= -0.5 * d
    tr = 0.0
    for sign, S, T in _root_solves(c, root):
        tr += sign * float(np.einsum("ij,ij->", S, S))
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


def loglik(x: NDArray[np.float64], root: GramRoot, d: float, ell: float, mu: float) -> float:
    """L alone (one Cholesky and one triangular solve): the trial points of the Newton stage."""
    blas, lapack = scipy.linalg.blas, scipy.linalg.lapack
    K = np.exp(sqdist(x) * (-0.5 / (ell * ell)))
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


def loglik_grad_hess(
    x: NDArray[np.float64], root: GramRoot, d: float, ell: float, mu: float
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """``L`` (eq. 6), ``∂L/∂X`` (N × q) and the Hessian ``∂²L/∂x∂x`` (Nq × Nq, in the order of ``x.ravel()``).

    Arguments unchecked (see :func:`log_likelihood_grad`).  With ``P = K⁻¹``, ``Q = K⁻¹GK⁻¹`` and
    ``W = −(d/2)P + ½Q`` (= ∂L/∂K),
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
    ``newton`` method (:mod:`brdfpipe.manifold.newton`); checked against finite differences of
    the gradient in the tests.
    """
    blas = scipy.linalg.blas
    n, q = x.shape
    s, E, c, logdet, P = _factor(x, ell, mu)
    P = np.tril(P)
    P += np.tril(P, -1).T
    Q = np.zeros((n, n))
    tr = 0.0
    for sign, S, T in _root_solves(c, root):
        tr += sign * float(np.einsum("ij,ij->", S, S))
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

