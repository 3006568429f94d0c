"""The GPLVM's ``newton`` optimiser: exact-Hessian Newton steps to a local maximum, the same on every BLAS kernel.

``method="newton"`` of :func:`brdfpipe.manifold.fitting.fit` (the default
since issue 23, in this form since issue 31; :func:`newton_stages` from one
start):

1. start: :func:`~brdfpipe.manifold.fitting.pca_init` scaled by the rules
   ``rms`` and ``unit`` (:data:`~brdfpipe.manifold.fitting.NEWTON_TRIAL_SCALES`);
   steps 2 to 4 from each, the higher final L is kept;
2. Newton steps with the exact Hessian
   (:func:`~brdfpipe.manifold.likelihood.loglik_grad_hess`,
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

Reproducibility
---------------
The path must not depend on the BLAS kernel: the L of one X
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
ended at up to four maxima.  The other two methods
(:mod:`brdfpipe.manifold.hookejeeves`) are not reproducible across kernels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
import scipy.linalg
import scipy.linalg.lapack
from numpy.typing import NDArray

from brdfpipe.manifold.likelihood import GramRoot, loglik, loglik_grad_hess

__all__ = ["STEP_BITS", "POINT_BITS", "GAIN_RESOLUTION", "SADDLE_CURVATURE", "Counts", "newton_stages"]

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


@dataclass
class Counts:
    """Work of the ``newton`` method: evaluations of L alone, of L with its gradient and Hessian, Newton steps."""

    evaluations: int = 0
    hessians: int = 0
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


def _positive_definite(B: NDArray[np.float64], shift: float) -> bool:
    """Whether ``B + shift·I`` is positive definite (its Cholesky factorisation succeeds)."""
    diag = np.diag_indices_from(B)
    base = B[diag].copy()
    B[diag] = base + shift
    ok = scipy.linalg.lapack.dpotrf(B, lower=1, clean=0)[1] == 0
    B[diag] = base
    return bool(ok)


def _lm_step(
    x: NDArray[np.float64], L: float, M: NDArray[np.float64], B: NDArray[np.float64], gf: NDArray[np.float64],
    unit: float, k: int, root: GramRoot, d: float, ell: float, mu: float, *, scale: float, counts: Counts,
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
            L_new = loglik(x + p.reshape(n, q), root, d, ell, mu)
        except np.linalg.LinAlgError:
            L_new = -np.inf
        gain = (L_new - L) / scale
        if gain > 1e-4 * pred:
            return (p, gain / pred), k
        k += 2
    return None, k


def _lm_newton(
    x: NDArray[np.float64], root: GramRoot, d: float, ell: float, mu: float, *, scale: float, steps_left: int,
    gtol: float, hist: list[tuple[str, float]], counts: Counts,
) -> tuple[NDArray[np.float64], float, NDArray[np.float64], NDArray[np.float64], int]:
    """Stage 1 of :func:`newton_stages` from ``x``: Newton steps (:func:`_lm_step`) until none gains.

    Appends ``("newton", L)`` per step to ``hist``; returns the final X, its L, gradient and Hessian, and
    the steps left.  ``λ = unit·2^k``, ``unit`` the mean |diagonal| of ``B = −∇²L/scale``, ``k`` an integer
    in [−30, 60]: −2 after a step that gained more than 3/4 of its prediction, +1 after one that gained less
    than 1/4.  Where ``B + λ/2`` is not positive definite (L curves up along some direction by more than
    λ/2), λ is raised up to 2^3-fold until it is; beyond, the step is taken with ``|B|`` (its eigenvalues'
    signs dropped, ``dsyevd``: saddle-free Newton), which moves along such a direction uphill at the
    gradient's pace instead of letting it set λ for every other direction.
    """
    n, q = x.shape
    L, g, H = loglik_grad_hess(x, root, d, ell, mu)
    counts.hessians += 1
    k = 0
    while steps_left > 0 and np.abs(g).max() > gtol * max(abs(L), 1.0):
        B = H * (-1.0 / scale)
        gf = g.ravel() * (-1.0 / scale)
        unit = float(np.abs(np.diag(B)).mean())
        unit = unit if unit > 0 else 1.0  # a zero Hessian: every point far from all others
        raised = next((j for j in range(k, k + _MAX_RAISE + 1) if _positive_definite(B, unit * 2.0 ** (j - 1))), None)
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
        L, g, H = loglik_grad_hess(x, root, d, ell, mu)
        counts.hessians += 1
        counts.newton_iterations += 1
        steps_left -= 1
        hist.append(("newton", L))
        k = max(k - 2, _MIN_SHIFT_EXPONENT) if rho > 0.75 else (k + 1 if rho < 0.25 else k)
    return x, L, g, H, steps_left


def _polish_gradient(
    x: NDArray[np.float64], L: float, g: NDArray[np.float64], H: NDArray[np.float64], root: GramRoot, d: float,
    ell: float, mu: float, *, scale: float, steps_left: int, gtol: float, hist: list[tuple[str, float]],
    counts: Counts,
) -> NDArray[np.float64]:
    """Newton steps past the resolution of L (stage 3 of :func:`newton_stages`), judged by the gradient.

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
            k += 2
            if info != 0:
                continue
            p = -lapack.dpotrs(c, gf, lower=1)[0]
            p = _snap(p - Q @ (Q.T @ p), STEP_BITS)
            try:
                new = loglik_grad_hess(x + p.reshape(n, q), root, d, ell, mu)
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


def newton_stages(
    X0: NDArray[np.float64], root: GramRoot, d: float, ell: float, mu: float, *, newton_iterations: int,
    gtol: float, max_escapes: int, counts: Counts,
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
    L_start = loglik(x, root, d, ell, mu)
    counts.evaluations += 1
    scale = float(np.ldexp(1.0, int(np.frexp(max(abs(L_start), 1.0))[1])))
    hist: list[tuple[str, float]] = []
    steps_left = int(newton_iterations)
    for round_ in range(int(max_escapes) + 1):
        x, L, g, H, steps_left = _lm_newton(x, root, d, ell, mu, scale=scale, steps_left=steps_left, gtol=gtol,
                                            hist=hist, counts=counts)
        v = _ascent_curvature(H, scale) if round_ < int(max_escapes) and steps_left > 0 else None
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


def _ascent_curvature(H: NDArray[np.float64], scale: float) -> NDArray[np.float64] | None:
    """At a stationary point: the eigenvector of the most positive curvature of L where it is a saddle
    (smallest eigenvalue of ``M = −H/scale`` below −:data:`SADDLE_CURVATURE` × its mean |diagonal|), else None.  Its sign
    is fixed (largest-magnitude entry positive)."""
    lapack = scipy.linalg.lapack
    B = H * (-1.0 / scale)
    dB = float(np.abs(np.diag(B)).mean())
    diag = np.diag_indices_from(B)
    B[diag] += SADDLE_CURVATURE * dB
    if lapack.dpotrf(B, lower=1, clean=0)[1] == 0:
        return None  # negative semi-definite up to SADDLE_CURVATURE of its scale: a maximum
    B[diag] -= SADDLE_CURVATURE * dB
    w, v = scipy.linalg.eigh(B, subset_by_index=[0, 0], driver="evr")
    if not w[0] < -SADDLE_CURVATURE * dB:
        return None
    u = v[:, 0]
    return u if u[np.abs(u).argmax()] > 0 else -u


def _escape_saddle(
    x: NDArray[np.float64], v: NDArray[np.float64], L: float, root: GramRoot, d: float, ell: float, mu: float, *,
    scale: float, counts: Counts,
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
                return loglik(point(a), root, d, ell, mu)
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

