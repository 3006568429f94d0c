"""Exploring a fitted GPLVM latent space: the hull of the materials, neighbours, extrapolation, sampling.

Soler et al. 2018 (§4) navigate the latent space of a fitted GPLVM
(:mod:`brdfpipe.gplvm`): every latent point ``x`` gives a material
``Σ wᵢ(x) zᵢ`` (:func:`brdfpipe.gplvm.blend_weights`).  Inside the convex hull
of the training points the interpolant is backed by data; outside it the
weights drift towards the mean and can go strongly negative, and the
material can stop being physically plausible.  This module gives:

* :func:`hull_contains` / :func:`sample_in_hull`: the convex hull of the
  latent points (any ``q``, degenerate point sets included);
* :func:`nearest_materials`: the training materials nearest a latent point;
* :func:`latent_albedos`: the white-sky albedo of the material at many
  latent points;
* :func:`extrapolate`: walk along a latent line until the albedo leaves
  [0, 1] in some channel (energy conservation, or a negative material);
* :func:`sample_material`: plausible new materials, uniform in the hull and
  with albedo in [0, 1].

Hull geometry
-------------
The points are first reduced to their affine hull: centred on their mean,
the right singular vectors whose singular values exceed ``1e-10`` × the
largest span a rank-``r`` subspace (``r < q`` when ``N ≤ q`` or the points
lie on a lower-dimensional flat).  A query point is outside if its residual
off that flat exceeds the tolerance; otherwise its ``r`` coordinates are
tested against the hull in ``r`` dimensions — an interval for ``r = 1``, the
facet half-spaces of Qhull's convex hull (``scipy.spatial.ConvexHull``:
inside iff ``a·y + b ≤ tol`` for every facet) for ``r ≥ 2``.  Should Qhull
fail on a nearly degenerate set, the exact LP feasibility test is used
instead: ``y`` is inside iff ``λ ≥ 0, Σλ = 1, Yᵀλ = y`` is feasible
(``scipy.optimize.linprog``, HiGHS).  Both are available through
``method`` ("qhull", "lp"; "auto" = qhull with the LP fallback).  Measured
for P = 20,000 points, q = 5, N = 100 standard-normal points (2 shared
cores): the half-space test 0.19 s including the hull, the LP 1.9 ms per
point (≈ 39 s), ``scipy.spatial.Delaunay`` + ``find_simplex`` 14.5 s (the
5-D triangulation) — so the half-space test is the default.  Qhull's hull of
N = 1,000 points at q = 6 takes 0.07 s (14,815 facets).

Uniform sampling (:func:`sample_in_hull`) is rejection sampling in the
bounding box of the (reduced) points, in batches, when the hull fills at
least :data:`MIN_ACCEPTANCE` of that box (the acceptance rate, known exactly
from Qhull's volume); otherwise (a thin hull, or high ``q``: 2 % for 100
Gaussian points at q = 6) the hull is cut into cones from an interior point
(the mean of the hull's vertices) over its triangulated facets; a cone is
drawn with probability proportional to its volume and a point inside it
with Dirichlet(1) barycentric weights, which is exactly uniform.  Both are
deterministic given the generator.

Albedo at a latent point
------------------------
In the linear data spaces (anything but ``log``) the interpolated table is
``Σ wᵢ zᵢ`` and the albedo is linear in the table, so the albedo at ``x``
is ``w(x)·A`` with ``A`` the materials' albedos
(:func:`brdfpipe.manifold.material_albedos`); the clamping of negative
interpolated values to 0 by :func:`brdfpipe.gplvm.interpolate_table` is
ignored (as in :func:`brdfpipe.manifold.albedo_map`).  In the ``log`` space
the blend is of log-mapped values, so the table itself is formed
(:func:`brdfpipe.gplvm.interpolate_tables`) and its albedo computed
(:func:`brdfpipe.manifold.material_albedo`) — exact, and ~1 s per point.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.spatial
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MIN_ACCEPTANCE",
    "HULL_METHODS",
    "hull_contains",
    "sample_in_hull",
]

logger = logging.getLogger("brdfpipe.latent")

#: Below this acceptance rate (hull volume / box volume) :func:`sample_in_hull` samples cones of the hull.
MIN_ACCEPTANCE: Final = 0.05
#: Methods of :func:`hull_contains`.
HULL_METHODS: Final = ("auto", "qhull", "lp")
#: Relative rank tolerance of the affine hull (singular values below this × the largest are dropped).
_RANK_TOL: Final = 1e-10
#: Containment tolerance relative to the size (largest singular value / √N) of the point set.
_CONTAIN_TOL: Final = 1e-9
_BATCH: Final = 4096


# --------------------------------------------------------------------------
# Convex hull
# --------------------------------------------------------------------------


def _as_points(X: ArrayLike, what: str, q: int | None = None) -> NDArray[np.float64]:
    x = np.asarray(X, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] < 1 or (q is None and x.shape[0] < 1):
        raise ValueError(f"{what} must be a 2-D array (rows of coordinates), got shape {x.shape}")
    if q is not None and x.shape[1] != q:
        raise ValueError(f"{what} must have {q} columns (the latent dimension), got shape {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"{what} has non-finite entries")
    return x


@dataclass(frozen=True)
class _Flat:
    """The affine hull of a point set: ``x = centre + y @ basis`` with ``y`` in ``r`` dimensions."""

    centre: NDArray[np.float64]
    basis: NDArray[np.float64]  # (r, q), orthonormal rows
    Y: NDArray[np.float64]  # (N, r) reduced coordinates of the points
    tol: float  # absolute containment tolerance

    @property
    def rank(self) -> int:
        return int(self.basis.shape[0])

    def reduce(self, points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Reduced coordinates of points and whether each lies on the flat (within tol)."""
        d = points - self.centre
        y = d @ self.basis.T
        resid = np.linalg.norm(d - y @ self.basis, axis=1)
        return y, resid <= self.tol

    def lift(self, y: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.centre + y @ self.basis


def _flat(X: NDArray[np.float64]) -> _Flat:
    centre = X.mean(axis=0)
    d = X - centre
    if X.shape[0] == 1 or not np.any(d):
        return _Flat(centre, np.zeros((0, X.shape[1])), np.zeros((X.shape[0], 0)),
                     _CONTAIN_TOL * max(1.0, float(np.abs(centre).max())))
    _, s, vt = np.linalg.svd(d, full_matrices=False)
    r = int((s > _RANK_TOL * s[0]).sum())
    basis = vt[:r]
    size = max(float(s[0]) / math.sqrt(X.shape[0]), float(np.abs(centre).max()) * 1e-3)
    return _Flat(centre, basis, d @ basis.T, _CONTAIN_TOL * size)


def _hull_qhull(Y: NDArray[np.float64]) -> scipy.spatial.ConvexHull:
    return scipy.spatial.ConvexHull(Y)


def _contains_halfspaces(hull: scipy.spatial.ConvexHull, y: NDArray[np.float64], tol: float) -> NDArray[np.bool_]:
    eq = hull.equations  # (F, r + 1): unit outward normal, offset; inside iff n·y + b <= 0
    out = np.empty(y.shape[0], dtype=bool)
    for a in range(0, y.shape[0], _BATCH):
        yb = y[a : a + _BATCH]
        out[a : a + _BATCH] = (yb @ eq[:, :-1].T + eq[:, -1]).max(axis=1) <= tol
    return out


def _contains_lp(Y: NDArray[np.float64], y: NDArray[np.float64], tol: float) -> NDArray[np.bool_]:
    """LP feasibility per point: ∃ λ ≥ 0, Σλ = 1, Yᵀλ = y (equality relaxed by tol in each coordinate)."""
    n, r = Y.shape
    # |Yᵀλ − y| ≤ tol as two inequalities; Σλ = 1 as an equality.
    A_ub = np.vstack([Y.T, -Y.T])
    A_eq = np.ones((1, n))
    c = np.zeros(n)
    out = np.empty(y.shape[0], dtype=bool)
    for i, p in enumerate(y):
        b_ub = np.concatenate([p + tol, -p + tol])
        res = scipy.optimize.linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=[1.0], bounds=(0, None),
                                     method="highs")
        if res.status not in (0, 2):
            raise RuntimeError(f"linprog failed on a hull-membership test: {res.message}")
        out[i] = res.status == 0
    return out


def hull_contains(X: ArrayLike, points: ArrayLike, *, method: str = "auto") -> NDArray[np.bool_]:
    """Whether each point lies in the convex hull of the rows of ``X``: bool ``(P,)``.

    ``X`` is ``(N, q)``, ``points`` ``(P, q)`` (a single ``(q,)`` point is
    taken as one row).  Any ``q`` and ``N``, degenerate sets included (``N ≤ q``,
    repeated points, points on a lower-dimensional flat): see the module
    docstring, "Hull geometry".  Points on the boundary count as inside
    (tolerance ``1e-9`` × the size of the set).  ``method``: "auto" (Qhull
    half-spaces, the LP test if Qhull fails), "qhull" or "lp" (one linear
    program per point: exact but ~1 ms each).  ValueError for bad shapes or
    non-finite values.
    """
    if method not in HULL_METHODS:
        raise ValueError(f"unknown hull method {method!r}; expected one of {', '.join(HULL_METHODS)}")
    x = _as_points(X, "X")
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 1:
        p = p[None, :]
    p = _as_points(p, "points", x.shape[1]) if p.shape[0] else np.zeros((0, x.shape[1]))
    fl = _flat(x)
    y, on = fl.reduce(p)
    out = np.zeros(p.shape[0], dtype=bool)
    if not on.any():
        return out
    r, yo = fl.rank, y[on]
    if r == 0:
        out[on] = True
        return out
    if r == 1:
        lo, hi = fl.Y[:, 0].min(), fl.Y[:, 0].max()
        out[on] = (yo[:, 0] >= lo - fl.tol) & (yo[:, 0] <= hi + fl.tol)
        return out
    if method == "lp":
        out[on] = _contains_lp(fl.Y, yo, fl.tol)
        return out
    try:
        hull = _hull_qhull(fl.Y)
    except scipy.spatial.QhullError:
        if method == "qhull":
            raise
        logger.info("Qhull failed on %d points in %d dimensions; LP membership test", *fl.Y.shape)
        out[on] = _contains_lp(fl.Y, yo, fl.tol)
        return out
    out[on] = _contains_halfspaces(hull, yo, fl.tol)
    return out


# --------------------------------------------------------------------------
# Uniform sampling
# --------------------------------------------------------------------------


def _cone_sampler(Y: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Simplices ``(S, r + 1, r)`` cutting the hull of Y (cones from an interior point) and their volumes."""
    hull = _hull_qhull(Y)
    apex = Y[hull.vertices].mean(axis=0)
    facets = Y[hull.simplices]  # (S, r, r): triangulated facets (Qhull option Qt)
    simplices = np.concatenate([facets, np.broadcast_to(apex, (facets.shape[0], 1, Y.shape[1]))], axis=1)
    r = Y.shape[1]
    vol = np.abs(np.linalg.det(facets - apex[None, None, :])) / math.factorial(r)
    return simplices, vol


def _sample_cones(Y: NDArray[np.float64], n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    simplices, vol = _cone_sampler(Y)
    pick = rng.choice(vol.size, size=n, p=vol / vol.sum())
    lam = rng.dirichlet(np.ones(Y.shape[1] + 1), size=n)  # (n, r + 1)
    return np.einsum("nk,nkr->nr", lam, simplices[pick])


def sample_in_hull(
    X: ArrayLike, n: int, rng: np.random.Generator, *, method: str = "auto"
) -> NDArray[np.float64]:
    """``n`` points ``(n, q)`` uniformly distributed in the convex hull of the rows of ``X``.

    Uniform with respect to the volume of the hull's own dimension (a
    degenerate set — points on a plane in 3-D — gives points uniform on that
    polygon).  ``method``: "rejection" (bounding box + :func:`hull_contains`,
    in batches), "cones" (exact cone decomposition), or "auto": rejection
    unless the hull fills less than :data:`MIN_ACCEPTANCE` of its bounding box.  See the
    module docstring.  Deterministic given ``rng``.
    """
    if method not in ("auto", "rejection", "cones"):
        raise ValueError(f"unknown sampling method {method!r}; expected auto, rejection or cones")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n must be an integer >= 0, got {n!r}")
    x = _as_points(X, "X")
    fl = _flat(x)
    r = fl.rank
    if n == 0:
        return np.zeros((0, x.shape[1]))
    if r == 0:
        return np.tile(fl.centre, (n, 1))
    lo, hi = fl.Y.min(axis=0), fl.Y.max(axis=0)
    if r == 1:
        return fl.lift(rng.uniform(lo, hi, size=(n, 1)))
    hull = None
    if method != "cones":
        try:
            hull = _hull_qhull(fl.Y)
        except scipy.spatial.QhullError:
            hull = None
    if method == "cones" or hull is None:
        return fl.lift(_sample_cones(fl.Y, n, rng))
    frac = float(hull.volume / np.prod(hi - lo))
    if method == "auto" and frac < MIN_ACCEPTANCE:
        logger.info("hull fills %.3g of its box: sampling cones of the hull", frac)
        return fl.lift(_sample_cones(fl.Y, n, rng))
    got: list[NDArray[np.float64]] = []
    have = 0
    batch = int(min(max(2 * n / max(frac, 1e-6), 256), 1_000_000))
    while have < n:
        cand = rng.uniform(lo, hi, size=(batch, r))
        keep = cand[_contains_halfspaces(hull, cand, fl.tol)]
        got.append(keep)
        have += keep.shape[0]
    return fl.lift(np.concatenate(got)[:n])
