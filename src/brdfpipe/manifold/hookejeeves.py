"""The paper's direct search over the latent points (Hooke–Jeeves), scored by rank-2 updates of K⁻¹.

Methods ``hooke-jeeves`` and ``hybrid`` of :func:`brdfpipe.manifold.fitting.fit`
(which chooses the start and, for ``hybrid``, runs L-BFGS around the search).
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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from brdfpipe.manifold.likelihood import kernel_matrix

__all__ = ["State", "full_state", "Settings", "run"]


@dataclass
class State:
    """The search's latent points and the bookkeeping of their kernel: K, K⁻¹, log|K| and tr(K⁻¹G)."""

    X: NDArray[np.float64]
    K: NDArray[np.float64]
    Kinv: NDArray[np.float64]
    logdet: float
    tr: float


def full_state(X: NDArray[np.float64], gram: NDArray[np.float64], ell: float, mu: float) -> State:
    """The :class:`State` of ``X`` computed afresh (Cholesky of K): the start, and every refactorisation."""
    K = kernel_matrix(X, ell, mu)
    cf = scipy.linalg.cho_factor(K, lower=True)
    Kinv = scipy.linalg.cho_solve(cf, np.eye(K.shape[0]))
    Kinv = 0.5 * (Kinv + Kinv.T)
    logdet = 2.0 * float(np.log(np.diag(cf[0])).sum())
    tr = float(np.einsum("ij,ji->", Kinv, gram))
    return State(X.copy(), K, Kinv, logdet, tr)


def _candidates(
    st: State, gram: NDArray[np.float64], i: int, xs: NDArray[np.float64], inv2l2: float
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


def _accept(st: State, i: int, xi: NDArray[np.float64], col: NDArray[np.float64],
            a: NDArray[np.float64], Minv: NDArray[np.float64], dlogdet: float, dtr: float) -> None:
    """Apply a move scored by :func:`_candidates` (its column, ``a = K⁻¹u``, M⁻¹, Δlog|K|, Δtr).

    Woodbury ``K′⁻¹ = K⁻¹ − A M⁻¹ Aᵀ`` (Sherman–Morrison twice, ``A = [a, K⁻¹e_i]``), then K, X, log|K|, tr.
    """
    At = np.stack([a, st.Kinv[i]])
    st.Kinv -= At.T @ (Minv @ At)
    st.K[:, i] = col
    st.K[i, :] = col
    st.X[i] = xi
    st.logdet += dlogdet
    st.tr += dtr


def _hooke_jeeves(
    st: State, gram: NDArray[np.float64], d: float, ell: float, mu: float, *,
    rng: np.random.Generator, max_sweeps: int, step: float, min_step: float, refactor_every: int,
    tol: float, ftol: float,
) -> tuple[list[tuple[int, float]], int, int, float]:
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
        fresh = full_state(st.X, gram, ell, mu)
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
        _accept(st, i, xs[c].copy(), cols[:, c].copy(), a[:, c], Minv[c], float(dlogdet[c]), float(dtr[c]))
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
    refactor()
    trace[-1] = (trace[-1][0], L())
    return trace, accepted, evals, max_drift



@dataclass(frozen=True, eq=False)
class Settings:
    """The data and fixed settings of the Hooke–Jeeves runs (:func:`run`) of a fit (``hybrid``, ``hooke-jeeves``)."""

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


def run(
    s: Settings, X0: NDArray[np.float64], sweeps: int, sweep0: int = 0
) -> tuple[State, list[tuple[int, float]], tuple[int, int, float]]:
    """At most ``sweeps`` Hooke–Jeeves sweeps from X₀, seeded by ``(seed, sweep0)`` and numbered from ``sweep0``.

    Returns the final state, the ``(sweep, L)`` trace and ``(accepted
    moves, evaluations, max drift)``.
    """
    st = full_state(X0, s.gram, s.ell, s.mu)
    rng = np.random.default_rng([s.seed, sweep0])
    trace, acc, ev, drift = _hooke_jeeves(
        st, s.gram, s.d, s.ell, s.mu, rng=rng, max_sweeps=sweeps, step=s.step, min_step=s.min_step,
        refactor_every=s.refactor_every, tol=s.tol, ftol=s.ftol,
    )
    return st, [(k + sweep0, v) for k, v in trace], (acc, ev, drift)
