"""Eq. 15 and the training error computed literally, with p-dimensional vectors: the reference of the fast forms.

The library's metrics (:mod:`brdfpipe.acquisition.metrics`) never touch a
p-vector; these do, as the formulas are written, so that the tests (and
``benches/bench_error_metric.py``) can check the fast forms against them:
:func:`expected_error_literal` (E(S) of eq. 15) and
:func:`direct_training_error` (the training rows reconstructed from their own
observations, eq. 4).  Cost O(m·p·k): tests and benchmarks only.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.acquisition.metrics import DEFAULT_ETA, check_eta, reconstruct_coefficients

F64 = NDArray[np.float64]

#: Rows of ``Q`` processed at a time (bounds memory to a few × block·max(k, m) float64 values).
P_BLOCK: int = 32_768


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
    block: int = P_BLOCK,
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
    kind = _literal_kind(Z, p, k, kind, mean is not None)
    mu: F64 | None = None
    if mean is not None:
        mu = np.asarray(mean, dtype=np.float64)
        if mu.shape != (p,):
            raise ValueError(f"mean must have shape ({p},), got {mu.shape}")
    idx = _as_selection(S_rows, p)
    Zc = np.asarray(Z, dtype=np.float64) if kind == "coefficients" else None

    # 1. Q⁺ = (QᵀQ)⁺ Qᵀ.
    qtq_pinv = _literal_qtq_pinv(Qa, block)
    # 2. (SQ)⁺_η.
    Qt = np.asarray(Qa[idx], dtype=np.float64).reshape(idx.size, k)
    reg_inv = np.linalg.solve(Qt.T @ Qt + eta * np.eye(k), Qt.T)  # (k, n)
    # 3. coefficients Q⁺ y_i (a p-space product) and (SQ)⁺_η S y_i, per material.
    diff = _literal_coefficient_gap(Qa, Z, Zc, mu, idx, Qt, qtq_pinv, reg_inv, block)
    noise_c = reg_inv @ np.ones(idx.size)
    # 4. p-space error vectors and their norms.
    recon, noise = _literal_norms(Qa, diff, noise_c, block)
    if return_terms:
        return recon, noise
    return recon + beta * noise


def _literal_kind(
    Z: NDArray[np.generic], p: int, k: int, kind: str, has_mean: bool
) -> Literal["coefficients", "residuals"]:
    """How :func:`expected_error_literal` reads ``U_or_Y`` (resolving ``"auto"``), its width checked."""
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
        if has_mean:
            raise ValueError("mean applies to (m, p) rows, not to coefficients")
        return "coefficients"
    if kind == "residuals":
        if Z.shape[1] != p:
            raise ValueError(f"residuals must have shape (m, {p}), got {Z.shape}")
        return "residuals"
    raise ValueError(f"kind must be 'auto', 'coefficients' or 'residuals', got {kind!r}")


def _literal_y_block(
    Qa: NDArray[np.floating], Z: NDArray[np.generic], Zc: F64 | None, mu: F64 | None, a: int, b: int
) -> F64:
    """Residuals y_i over rows a:b of Q, as an (m, b − a) array (from coefficients ``Zc`` or rows ``Z``)."""
    if Zc is not None:
        return Zc @ np.asarray(Qa[a:b], dtype=np.float64).T
    yb = np.asarray(Z[:, a:b], dtype=np.float64)
    return yb - mu[a:b] if mu is not None else yb


def _literal_qtq_pinv(Qa: NDArray[np.floating], block: int) -> F64:
    """Step 1 of :func:`expected_error_literal`: ``(QᵀQ)⁺``, ``QᵀQ`` accumulated ``block`` rows at a time."""
    p, k = Qa.shape
    qtq = np.zeros((k, k))
    for a in _blocks(p, block):
        Qb = np.asarray(Qa[a : a + block], dtype=np.float64)
        qtq += Qb.T @ Qb
    return np.linalg.pinv(qtq, hermitian=True)


def _literal_coefficient_gap(
    Qa: NDArray[np.floating],
    Z: NDArray[np.generic],
    Zc: F64 | None,
    mu: F64 | None,
    idx: NDArray[np.intp],
    Qt: F64,
    qtq_pinv: F64,
    reg_inv: F64,
    block: int,
) -> F64:
    """Step 3 of :func:`expected_error_literal`: ``Q⁺ y_i − (SQ)⁺_η S y_i`` for every material, as (k, m)."""
    p, k = Qa.shape
    m = Z.shape[0]
    c_full = np.zeros((k, m))
    for a in _blocks(p, block):
        b = min(a + block, p)
        q_pinv_block = qtq_pinv @ np.asarray(Qa[a:b], dtype=np.float64).T  # columns a:b of Q⁺
        c_full += q_pinv_block @ _literal_y_block(Qa, Z, Zc, mu, a, b).T
    if Zc is not None:
        s_y = Zc @ Qt.T  # (m, n): y_i at the selected rows
    else:
        s_y = np.asarray(Z[:, idx], dtype=np.float64).reshape(m, idx.size)
        if mu is not None:
            s_y = s_y - mu[idx]
    c_bar = reg_inv @ s_y.T
    return c_full - c_bar


def _literal_norms(Qa: NDArray[np.floating], diff: F64, noise_c: F64, block: int) -> tuple[float, float]:
    """Step 4 of :func:`expected_error_literal`: ``mean_i ‖Q diff_i‖`` and ``‖Q noise_c‖``, block by block."""
    p = Qa.shape[0]
    sq = np.zeros(diff.shape[1])
    noise_sq = 0.0
    for a in _blocks(p, block):
        Qb = np.asarray(Qa[a : a + block], dtype=np.float64)
        r = Qb @ diff  # (block, m): rows a:b of every r_i
        sq += np.einsum("ij,ij->j", r, r)
        v = Qb @ noise_c
        noise_sq += float(v @ v)
    return float(np.mean(np.sqrt(sq))), float(np.sqrt(noise_sq))


def direct_training_error(
    Q: ArrayLike,
    U: ArrayLike,
    sigma: ArrayLike,
    mean: ArrayLike,
    X_train: ArrayLike,
    S_rows: ArrayLike,
    eta: float = DEFAULT_ETA,
    *,
    block: int = P_BLOCK,
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
