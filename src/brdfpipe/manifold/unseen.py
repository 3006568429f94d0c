"""Materials outside the training set on a fitted GPLVM manifold: their latent position x* and reproduction.

A GPLVM (:mod:`brdfpipe.manifold.gplvm`) places the N materials it was
fitted to at latent points X; a material outside that set (config
``unseen``: e.g. RGL or Nielsen materials when the model is of MERL's) has
no latent point.  Two ways to give it one, both in the model's data space
(the new material ``o`` mapped with the training materials' maps and
centred by their mean, ``y = o − μ̄``; :func:`brdfpipe.manifold.gram.cross_gram`):

* **least squares** — the x* whose interpolant ``ẑ(x) = μ̄ + Σ bᵢ(x)(zᵢ − μ̄)``
  (``b = K⁻¹k(x)``, Soler eq. 4) is closest to the material:
  ``R(x) = ‖y − Yᵀb(x)‖² = ‖y‖² − 2bᵀc + bᵀG_c b`` with ``c = Y y`` (the
  cross products) and G_c the centred Gram matrix;
* **likelihood** — the x* that maximises the GP likelihood of the new
  material given the fitted model (X, ℓ, μ fixed): each of the d data
  columns is Gaussian given the training columns, with mean ``bᵀY`` and
  variance ``σ²(x) = 1 + μ − k(x)ᵀK⁻¹k(x)`` (the new material is an
  observation of a point distinct from the training points, noise μ
  included), so ``log p(y | x) = −(d/2) log σ²(x) − R(x)/(2sσ²(x))`` + const,
  with ``s`` the model's ``gram_scale`` (the fit is of ``G/s``).  This is
  the increase of the fit's objective (Soler eq. 6) when the material is
  added with its point at x and every other point held: the standard way
  of placing new data in a GPLVM.  It trades closeness (R) against the
  model's confidence (σ², smallest near the training points).

Both are found by L-BFGS (analytic gradients; k without the μδ term, so
the objectives are smooth) from the :data:`STARTS` training points where
the objective is best (and, for the likelihood, from the least-squares
point).  For least squares the training points themselves are candidates
with the model's own interpolant (b(xᵢ) = eᵢ, the δ convention of
:func:`brdfpipe.manifold.gplvm.weights`), so a material of the training set
is placed exactly at its own xᵢ (R = 0); a refined point replaces the
best candidate only if it lowers R by more than rounding.

Reproduction: ``‖o − ẑ(x*)‖ / ‖o‖`` (the interpolant of
:func:`brdfpipe.manifold.gplvm.weights`, in the data space, relative to the
un-centred material as in ``reproduction.csv``), next to the projection of
y on the first k principal components of the same training materials
(``G_c = VΛVᵀ``: residual ``‖y‖² − Σ_{j≤k} (V_jᵀc)²/λ_j``), for k = each
latent dimension q and each of ``pca_components``.

``unseen.csv`` (:data:`~brdfpipe.registry.tables.MANIFOLD_UNSEEN`): one row per unseen material and
method — ``gplvm-likelihood`` and ``gplvm-least-squares`` (k = q, with the
conditional log-likelihood at x*, the nearest training material in latent
space and x* itself, coordinates separated by spaces) and ``pca`` (k) —
``database`` the material's, ``model_database`` the training store's.
"""

from __future__ import annotations

import io
import csv
import logging
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data.store import open_store
from brdfpipe.manifold import gplvm
from brdfpipe.manifold.gram import CrossGram, cross_gram, load_gram
from brdfpipe.registry import tables

__all__ = [
    "METHODS",
    "STARTS",
    "Position",
    "Objective",
    "locate",
    "pca_residuals",
    "unseen_rows",
    "write_unseen",
]

logger = logging.getLogger("brdfpipe.manifold.unseen")

F64 = NDArray[np.float64]

#: How x* is found: the GP likelihood of the material, or least squares of the interpolant against it.
METHODS: Final = ("likelihood", "least-squares")
#: Training points the local searches start from (those where the objective is best).
STARTS: Final = 8
#: A Gram file and the store recomputed in the same space must agree to this (relative, largest entry).
GRAM_RTOL: Final = 1e-8


class Objective:
    """R(x), σ²(x) and the conditional log-likelihood of one new material under a fitted model (module docstring).

    ``gram``: the centred Gram matrix the model was fitted to (unscaled);
    ``cross``: ``c = Y y``; ``yy`` = ``‖y‖²``; ``d`` columns.
    """

    def __init__(self, model: gplvm.GplvmModel, gram: ArrayLike, cross: ArrayLike, yy: float, d: float) -> None:
        self.model = model
        self.X = np.asarray(model.X, dtype=np.float64)
        self.G = np.asarray(gram, dtype=np.float64)
        self.c = np.asarray(cross, dtype=np.float64)
        self.yy = float(yy)
        self.d = float(d)
        self.s = float(model.gram_scale)
        self.cf = (np.asarray(model.chol, dtype=np.float64), True)
        n = self.X.shape[0]
        if self.G.shape != (n, n) or self.c.shape != (n,):
            raise ValueError(f"gram {self.G.shape} and cross {self.c.shape} do not fit a model of {n} materials")
        self.scale = max(self.yy, np.finfo(np.float64).tiny)
        # K⁻¹, K⁻¹c and K⁻¹G_cK⁻¹ once: then R and σ² cost two N × N products per x
        kinv = scipy.linalg.cho_solve(self.cf, np.eye(n))
        self.kinv = 0.5 * (kinv + kinv.T)
        self.v = self.kinv @ self.c
        a = self.kinv @ self.G @ self.kinv
        self.a = 0.5 * (a + a.T)

    def _k(self, x: F64) -> tuple[F64, F64]:
        diff = x - self.X
        k = np.exp(-np.einsum("ij,ij->i", diff, diff) / (2.0 * self.model.ell ** 2))
        return k, diff

    def residual(self, b: ArrayLike) -> float:
        """R = ‖y − Yᵀb‖² for weights b (clamped at 0)."""
        bb = np.asarray(b, dtype=np.float64)
        return max(self.yy - 2.0 * float(bb @ self.c) + float(bb @ self.G @ bb), 0.0)

    def residual_at(self, x: ArrayLike) -> float:
        """R at x with the model's own interpolant (:func:`brdfpipe.manifold.gplvm.weights`: b(xᵢ) = eᵢ)."""
        return self.residual(gplvm.weights(self.model, np.asarray(x, dtype=np.float64)))

    def _parts(self, x: F64) -> tuple[float, float, F64, F64]:
        """R, σ² and their gradients at x (smooth kernel: no μδ term)."""
        k, diff = self._k(x)
        ak = self.a @ k
        b = self.kinv @ k
        r = self.yy - 2.0 * float(k @ self.v) + float(k @ ak)
        var = 1.0 + self.model.mu - float(k @ b)
        J = -(k[:, None] * diff) / self.model.ell ** 2  # ∂k/∂x (N × q)
        dr = 2.0 * J.T @ (ak - self.v)
        dvar = -2.0 * J.T @ b
        return r, var, dr, dvar

    def log_likelihood(self, x: ArrayLike) -> float:
        """log p(y | x) up to a constant: −(d/2) log σ² − R/(2sσ²) (σ² floored at the smallest positive float)."""
        r, var, _, _ = self._parts(np.asarray(x, dtype=np.float64))
        var = max(var, np.finfo(np.float64).tiny)
        return -0.5 * self.d * math.log(var) - max(r, 0.0) / (2.0 * self.s * var)

    def _ls(self, x: F64) -> tuple[float, F64]:
        r, _, dr, _ = self._parts(x)
        return r / self.scale, dr / self.scale

    def _nll(self, x: F64) -> tuple[float, F64]:
        r, var, dr, dvar = self._parts(x)
        var = max(var, np.finfo(np.float64).tiny)
        r = max(r, 0.0)
        f = 0.5 * self.d * math.log(var) + r / (2.0 * self.s * var)
        g = 0.5 * self.d * dvar / var + dr / (2.0 * self.s * var) - r * dvar / (2.0 * self.s * var * var)
        return f / self.d, g / self.d


@dataclass(frozen=True)
class Position:
    """A latent position x* of a new material: how it was found, R(x*), its relative error and likelihood."""

    method: str
    x: F64
    residual: float
    relative_error: float
    log_likelihood: float
    nearest: str


def _minimise(fun: Any, starts: Sequence[F64]) -> tuple[F64, float]:
    best_x, best_f = starts[0], math.inf
    for x0 in starts:
        res = scipy.optimize.minimize(fun, x0, jac=True, method="L-BFGS-B",
                                      options={"maxiter": 500, "ftol": 1e-15, "gtol": 1e-10})
        f = float(res.fun)
        if math.isfinite(f) and f < best_f:
            best_x, best_f = np.asarray(res.x, dtype=np.float64), f
    return best_x, best_f


def locate(obj: Objective, method: str, *, norm: float, starts: int = STARTS) -> Position:
    """x* of the material of ``obj`` by ``method`` (:data:`METHODS`); ``norm`` = ‖o‖ (un-centred) for the relative error."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    X = obj.X
    n = X.shape[0]
    # the model's own interpolant at each training point: b = e_i, R_i = ‖y − y_i‖²
    r_train = np.maximum(obj.yy - 2.0 * obj.c + np.diag(obj.G), 0.0)
    if method == "least-squares":
        order = np.argsort(r_train, kind="stable")[: max(1, min(starts, n))]
        x_ls, f = _minimise(obj._ls, [X[i] for i in order])
        best = int(order[0])
        x = x_ls if f * obj.scale < r_train[best] - 1e-12 * obj.scale else X[best].copy()
    else:
        ll = np.array([obj.log_likelihood(X[i]) for i in range(n)])
        order = np.argsort(-ll, kind="stable")[: max(1, min(starts, n))]
        first = [X[i] for i in order]
        ls = locate(obj, "least-squares", norm=norm, starts=starts).x
        x, _ = _minimise(obj._nll, first + [ls])
    r = obj.residual_at(x)
    j = int(np.argmin(((X - x) ** 2).sum(axis=1)))
    return Position(method, x, r, math.sqrt(r) / norm if norm > 0 else math.inf, obj.log_likelihood(x),
                    obj.model.names[j])


def pca_residuals(gram: ArrayLike, cross: ArrayLike, yy: ArrayLike, ks: Sequence[int]) -> dict[int, F64]:
    """Squared residual of each new material projected on the first k principal components of the training set.

    ``gram`` (N × N, centred), ``cross`` (N × M), ``yy`` (M,): k → (M,)
    residuals ``‖y‖² − Σ_{j≤k} (V_jᵀc)²/λ_j`` (components with λ ≤ 0 carry
    nothing; k capped at N − 1, the rank of centred data).
    """
    g = np.asarray(gram, dtype=np.float64)
    c = np.asarray(cross, dtype=np.float64)
    if c.ndim == 1:
        c = c[:, None]
    lam, V = np.linalg.eigh(0.5 * (g + g.T))
    lam, V = lam[::-1], V[:, ::-1]
    tol = max(float(lam[0]), 0.0) * g.shape[0] * np.finfo(np.float64).eps
    proj = V.T @ c  # (N, M)
    energy = np.where(lam[:, None] > tol, proj * proj / np.where(lam[:, None] > tol, lam[:, None], 1.0), 0.0)
    out = {}
    for k in ks:
        kk = min(int(k), g.shape[0] - 1)
        out[int(k)] = np.maximum(np.asarray(yy, dtype=np.float64) - energy[:kk].sum(axis=0), 0.0)
    return out


def unseen_rows(
    cross: CrossGram,
    models: Mapping[int, gplvm.GplvmModel],
    *,
    gram: ArrayLike,
    model_database: str,
    pca_ks: Sequence[int] = (20, 40),
    starts: int = STARTS,
) -> list[dict[str, Any]]:
    """Rows of ``unseen.csv`` (:data:`~brdfpipe.registry.tables.MANIFOLD_UNSEEN`) for every outside material of ``cross``.

    ``gram``: the centred Gram matrix the models were fitted to (compared with
    ``cross.gram`` to :data:`GRAM_RTOL`: the outside materials must have been
    mapped to the models' own data space; ValueError otherwise).
    """
    g = np.asarray(gram, dtype=np.float64)
    scale = max(float(np.abs(g).max()), np.finfo(np.float64).tiny)
    diff = float(np.abs(cross.gram - g).max()) / scale
    if g.shape != cross.gram.shape or not diff <= GRAM_RTOL:
        raise ValueError(f"the Gram matrix recomputed from the store in the {cross.space} space differs from the "
                         f"models' by {diff:.3g} (relative): the models were fitted to other data")
    for q, m in models.items():
        if tuple(m.names) != tuple(cross.materials):
            raise ValueError(f"the q = {q} model's materials differ from the store's")
        if m.space != cross.space:
            raise ValueError(f"the q = {q} model is of the {m.space} space, the cross products of {cross.space}")
    ks = sorted({int(k) for k in pca_ks} | {int(q) for q in models})
    pca = pca_residuals(g, cross.cross, cross.norms2, ks)
    rows: list[dict[str, Any]] = []
    for j, (database, material) in enumerate(cross.others):
        norm = math.sqrt(max(float(cross.raw_norms2[j]), 0.0))
        base = {"database": database, "model_database": model_database, "space": cross.space, "material": material}
        for q, model in sorted(models.items()):
            obj = Objective(model, g, cross.cross[:, j], float(cross.norms2[j]), cross.d)
            for method in METHODS:
                pos = locate(obj, method, norm=norm, starts=starts)
                rows.append({**base, "method": f"gplvm-{method}", "k": int(q), "relative_error": pos.relative_error,
                             "log_likelihood": pos.log_likelihood, "nearest": pos.nearest,
                             "latent": " ".join(repr(float(v)) for v in pos.x)})
        for k in ks:
            rel = math.sqrt(float(pca[k][j])) / norm if norm > 0 else math.inf
            rows.append({**base, "method": "pca", "k": min(k, len(cross.materials) - 1), "relative_error": rel,
                         "log_likelihood": "", "nearest": "", "latent": ""})
    return rows


def _csv(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else str(v) for v in (r[c] for c in columns)])
    return buf.getvalue()


def write_unseen(
    out: str | os.PathLike[str],
    *,
    store: str | os.PathLike[str],
    gram: str | os.PathLike[str],
    models: Mapping[int, str | os.PathLike[str]],
    unseen_stores: Sequence[str | os.PathLike[str]],
    pca_ks: Sequence[int] = (20, 40),
    threads: int | None = 1,
) -> Path:
    """The workflow's ``locate_unseen`` job: every material of ``unseen_stores`` placed on each model (CSV ``out``).

    ``store``, ``gram``, ``models`` (q → file): the training store, the Gram
    matrix the models were fitted to and the fits (all of one data space);
    one streamed pass over the store and the unseen stores
    (:func:`brdfpipe.manifold.gram.cross_gram`), then :func:`unseen_rows`.
    ``threads``: BLAS threads (the searches' small products are slowed
    several-fold by idle BLAS threads spinning on a loaded machine).
    """
    t0 = time.perf_counter()
    G, d, info = load_gram(gram)
    fits = {int(q): gplvm.load_model(p) for q, p in models.items()}
    st = open_store(store)
    for fit in fits.values():
        gplvm.check_store(fit, st)  # fitted on these very rows (their digests), not on a store of the same names
    with blas_threads(threads):
        cross = cross_gram(st, list(unseen_stores), space=info.space, materials=list(info.materials))
        if cross.d != d:
            raise ValueError(f"{gram}: {d} columns, the store {store} has {cross.d} valid ones")
        rows = unseen_rows(cross, fits, gram=G, model_database=st.database, pca_ks=pca_ks)
    path = Path(out)
    integrity.write_csv(path, _csv(tables.MANIFOLD_UNSEEN, rows))
    logger.info("%d unseen materials on %d model(s) of %d %s materials (%s space) in %.1f s -> %s",
                len(cross.others), len(fits), len(cross.materials), st.database, cross.space,
                time.perf_counter() - t0, path)
    return path
