"""Exploring a fitted GPLVM latent space: the hull of the materials, neighbours, extrapolation, sampling.

Soler et al. 2018 (§4) navigate the latent space of a fitted GPLVM
(:mod:`brdfpipe.manifold.gplvm`): every latent point ``x`` gives a material
``Σ wᵢ(x) zᵢ`` (:func:`brdfpipe.manifold.gplvm.blend_weights`).  Inside the convex hull
of the training points the interpolant is backed by data; outside it the
weights drift towards the mean and can go strongly negative, and the
material can stop being physically plausible.  This module gives:

* :func:`hull_contains` / :func:`sample_in_hull`: the convex hull of the
  latent points (any ``q``, degenerate point sets included);
* :func:`nearest_materials`: the training materials nearest a latent point;
* :func:`extrapolate`: walk along a latent line until the white-sky albedo
  of the material leaves [0, 1] in some channel (energy conservation, or a
  negative material);
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
``method`` ("qhull", "lp"; "auto" = qhull with the LP fallback).  The half-space
test is the default: it is the fastest of the three by far (measured:
``docs/results/manifold.md``).

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
(:func:`brdfpipe.manifold.albedo.material_albedos`); the clamping of negative
interpolated values to 0 by :func:`brdfpipe.manifold.gplvm.interpolate_table` is
ignored (as in :func:`brdfpipe.manifold.analysis.albedo_map`).  That is exact only
where no interpolated value is negative: far from the data or between
dissimilar materials the weights go negative and the clamping can change
the albedo by ten percent or more (measured: 0.169 by w·A vs 0.193 of the
clamped table, red channel, 1.0 M clamped values, in
``tests/test_latent.py``); ``exact=True`` forms the table in every space.
In the ``log`` space
the blend is of log-mapped values, so the table itself is formed
(:func:`brdfpipe.manifold.gplvm.interpolate_tables`) and its albedo computed
(:func:`brdfpipe.manifold.albedo.material_albedo`) — exact, one pass over the store per 4 points.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.spatial
from numpy.typing import ArrayLike, NDArray

from brdfpipe.data.store import BrdfStore
from brdfpipe.data import merl
from brdfpipe.manifold import derivation, gplvm
from brdfpipe.registry.manifold import LINEAR_SPACES
from brdfpipe.manifold.albedo import material_albedo, material_albedos

__all__ = [
    "MIN_ACCEPTANCE",
    "HULL_METHODS",
    "STOP_REASONS",
    "hull_contains",
    "sample_in_hull",
    "nearest_materials",
    "blend_weights_at",
    "Extrapolation",
    "extrapolate",
    "MAX_WALK_WEIGHTS",
    "MaterialSamples",
    "sample_material",
    "write_blends",
]

logger = logging.getLogger("brdfpipe.manifold.latent")

#: Below this acceptance rate (hull volume / box volume) :func:`sample_in_hull` samples cones of the hull.
MIN_ACCEPTANCE: Final = 0.05
#: Methods of :func:`hull_contains`.
HULL_METHODS: Final = ("auto", "qhull", "lp")
#: Relative rank tolerance of the affine hull (singular values below this × the largest are dropped).
_RANK_TOL: Final = 1e-10
#: Containment tolerance relative to the size (largest singular value / √N) of the point set.
_CONTAIN_TOL: Final = 1e-9
_BATCH: Final = 4096
#: Why :func:`extrapolate` stopped.
STOP_REASONS: Final = ("albedo above 1", "albedo below 0", "max_s reached")
#: Interpolated tables formed at once for the albedo in the log space (35 MB each).
_LOG_BATCH: Final = 4
#: Most blend weights :func:`extrapolate` holds (steps × materials): its walk solves every step at
#: once in the linear spaces.  Measured peak RSS (``ru_maxrss``, 100 materials, q = 5, 2-core AMD EPYC)
#: grows by 7.5-8.4 kB per step (10,001 and 99,991 steps: +80 and +720 MB), about ten float64 arrays of
#: N weights; 10⁷ weights are then about 0.8 GB.
MAX_WALK_WEIGHTS: Final = 10**7
_CHANNELS: Final = ("r", "g", "b")


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
    program per point: exact but far slower).  ValueError for bad shapes or
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


# --------------------------------------------------------------------------
# Materials at latent points
# --------------------------------------------------------------------------


def _is_linear(space: str) -> bool:
    """Whether the interpolated table is the plain blend Σ wᵢ zᵢ of the stored values (albedo = w·A)."""
    return space in LINEAR_SPACES


def _point(model: gplvm.GplvmModel, x: ArrayLike | str, what: str) -> NDArray[np.float64]:
    """A latent point given as coordinates or as the name of a training material."""
    if isinstance(x, str):
        if x not in model.names:
            raise ValueError(f"{what}: unknown material {x!r} (not in the model)")
        return np.array(model.X[model.names.index(x)], dtype=np.float64)
    v = np.asarray(x, dtype=np.float64)
    q = model.X.shape[1]
    if v.shape != (q,):
        raise ValueError(f"{what} must be a latent point of q = {q} coordinates, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError(f"{what} has non-finite coordinates")
    return v


def nearest_materials(
    model: gplvm.GplvmModel, x: ArrayLike | str, k: int = 5, *, exclude: Sequence[str] = ()
) -> list[tuple[str, float]]:
    """The ``k`` training materials nearest a latent point: ``[(name, distance / ℓ), …]``, nearest first.

    ``x``: q coordinates or a material name (its latent point).  Distances
    are Euclidean in units of the kernel length scale ℓ; ties are broken by
    name.  ``exclude``: names left out (e.g. the material ``x`` itself).
    Fewer than ``k`` when the model has fewer materials.  ValueError for
    ``k < 1``, a point of the wrong length or an unknown material.
    """
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    xs = _point(model, x, "x")
    d = np.linalg.norm(model.X - xs, axis=1) / model.ell
    skip = set(exclude)
    ranked = sorted((float(d[i]), n) for i, n in enumerate(model.names) if n not in skip)
    return [(n, dist) for dist, n in ranked[: int(k)]]


def blend_weights_at(model: gplvm.GplvmModel, points: ArrayLike) -> NDArray[np.float64]:
    """Blend weights ``w`` ``(P, N)`` at many latent points (one triangular solve; Σw = 1 per row).

    The same as :func:`brdfpipe.manifold.gplvm.blend_weights` of :func:`brdfpipe.manifold.gplvm.weights`
    row by row, δ convention included: a point equal (bitwise) to a training
    point gets that material's weight 1.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 1:
        p = p[None, :]
    p = _as_points(p, "points", model.X.shape[1]) if p.shape[0] else np.zeros((0, model.X.shape[1]))
    diff = p[:, None, :] - model.X[None, :, :]
    d2 = np.einsum("pnq,pnq->pn", diff, diff)
    kv = np.exp(-d2 / (2.0 * model.ell * model.ell))
    kv[(diff == 0).all(axis=2)] += model.mu
    b = scipy.linalg.cho_solve((model.chol, True), kv.T).T
    return b + (1.0 - b.sum(axis=1, keepdims=True)) / model.X.shape[0]


AlbedoSource = ArrayLike | BrdfStore | str | os.PathLike[str]


@dataclass
class _Albedo:
    """Evaluates the albedo at latent points for one model: w·A (linear spaces) or the exact table (log)."""

    model: gplvm.GplvmModel
    A: NDArray[np.float64] | None
    store: BrdfStore | None

    @classmethod
    def of(cls, model: gplvm.GplvmModel, source: AlbedoSource, exact: bool) -> _Albedo:
        """The albedo of ``model``'s interpolated material from ``source`` (see :func:`extrapolate`)."""
        if isinstance(source, (BrdfStore, str, os.PathLike)):
            st = gplvm.check_store(model, source)  # the store holds the rows the model was fitted on
            if _is_linear(model.space) and not exact:
                return cls(model, material_albedos(st, list(model.names)), None)
            unknown = [m for m in model.names if m not in st.materials]
            if unknown:
                raise ValueError(f"{st.path}: unknown material(s) {', '.join(unknown)} of the model")
            return cls(model, None, st)
        if exact:
            raise ValueError("the exact albedo (of the clamped interpolated table) needs the store, not albedos")
        if not _is_linear(model.space):
            raise ValueError(
                f"the model's data space is {model.space!r} (not linear): the albedo needs the store, "
                "not the materials' albedos"
            )
        A = np.asarray(source, dtype=np.float64)
        if A.shape != (len(model.names), 3) or not np.isfinite(A).all():
            raise ValueError(f"albedos must be a finite ({len(model.names)}, 3) array, got shape {A.shape}")
        return cls(model, A, None)

    def __call__(self, points: NDArray[np.float64], W: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        W = blend_weights_at(self.model, points) if W is None else W
        if self.A is not None:
            return W @ self.A
        assert self.store is not None
        out = np.empty((W.shape[0], 3))
        for a in range(0, W.shape[0], _LOG_BATCH):
            tables, _ = gplvm.interpolate_tables(self.store, W[a : a + _LOG_BATCH], materials=self.model.names,
                                                 space=self.model.space, model=self.model)
            for j, t in enumerate(tables):
                out[a + j] = material_albedo(t)
        return out


# --------------------------------------------------------------------------
# Extrapolation
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class Extrapolation:
    """What :func:`extrapolate` found along ``x(s) = start + s·direction``."""

    start: NDArray[np.float64]
    direction: NDArray[np.float64]
    #: The steps evaluated, ``0, step, 2·step, …`` up to and including the one that stopped the walk.
    s: NDArray[np.float64]
    #: Albedo ``(len(s), 3)`` at each step.
    albedos: NDArray[np.float64] = field(repr=False)
    #: The last step whose albedo is in [0, 1] in every channel (None: not even the start).
    last_valid_s: float | None
    #: The step that stopped the walk (None when max_s was reached with every step valid).
    stop_s: float | None
    #: One of :data:`STOP_REASONS`.
    reason: str
    #: The channel ("r", "g", "b") that left [0, 1] at stop_s (None when max_s was reached).
    channel: str | None

    def point(self, s: float) -> NDArray[np.float64]:
        """The latent point at ``s``."""
        return self.start + s * self.direction

    @property
    def last_valid_point(self) -> NDArray[np.float64] | None:
        return None if self.last_valid_s is None else self.point(self.last_valid_s)


def extrapolate(
    model: gplvm.GplvmModel,
    source: AlbedoSource,
    start: ArrayLike | str,
    direction: ArrayLike | str,
    *,
    step: float = 0.05,
    max_s: float = 3.0,
    exact: bool = False,
) -> Extrapolation:
    """Walk ``x(s) = x_start + s·d`` for ``s = 0, step, 2·step, … ≤ max_s`` until the albedo leaves [0, 1].

    ``start``: a latent point or a material name.  ``direction``: a latent
    vector ``d``, or a material name B, meaning ``d = x_B − x_start`` (so
    ``s = 1`` is B and ``s > 1`` goes beyond it).  ``source``: the materials'
    albedos ``(N, 3)`` in model order (:func:`brdfpipe.manifold.albedo.material_albedos`;
    linear data spaces only) or the store (any space; in the log space the tables are
    formed, one store pass per 4 points).  ``exact``: form the table in every space
    (needs the store), so the clamping of negative interpolated values counts (module
    docstring, "Albedo at a latent point").  At each step the
    albedo of the interpolated material is computed per channel; the walk
    stops at the first step where a channel exceeds 1 (the material would
    reflect more energy than it receives) or goes below 0.  ValueError for a
    non-positive step, a negative ``max_s``, a zero direction or unknown
    materials.
    """
    step_f, max_f = float(step), float(max_s)
    if not (np.isfinite(step_f) and step_f > 0):
        raise ValueError(f"step must be a finite number > 0, got {step!r}")
    if not (np.isfinite(max_f) and max_f >= 0):
        raise ValueError(f"max_s must be a finite number >= 0, got {max_s!r}")
    x0 = _point(model, start, "start")
    if isinstance(direction, str):
        d = _point(model, direction, "direction") - x0
    else:
        d = _point(model, direction, "direction")
    if not np.any(d):
        raise ValueError("the direction is zero (the start and the target coincide)")
    count = int(math.floor(max_f / step_f + 1e-9)) + 1 if max_f / step_f < 1e18 else 10**18
    n_mat = len(model.names)
    most = max(1, MAX_WALK_WEIGHTS // max(1, n_mat))
    if count > most:
        raise ValueError(f"max_s {max_s!r} / step {step!r} is {count:.3g} steps; at most {most} for {n_mat} "
                         f"materials (each step holds the {n_mat} blend weights: at most {MAX_WALK_WEIGHTS:.0e} "
                         "weights in memory); raise step or lower max_s")
    s_all = np.arange(count) * step_f
    albedo = _Albedo.of(model, source, exact)
    chunk = count if albedo.A is not None else _LOG_BATCH
    vals: list[NDArray[np.float64]] = []
    stop: int | None = None
    for a in range(0, count, chunk):
        pts = x0 + s_all[a : a + chunk, None] * d
        v = albedo(pts)
        bad = ((v > 1.0) | (v < 0.0)).any(axis=1)
        vals.append(v)
        if bad.any():
            stop = a + int(np.argmax(bad))
            break
    A = np.concatenate(vals)
    if stop is None:
        return Extrapolation(x0, d, s_all, A, float(s_all[-1]), None, STOP_REASONS[2], None)
    row = A[stop]
    # the channel that left [0, 1] (the farthest out when several did)
    excess = np.maximum(row - 1.0, -row)
    ch = int(np.argmax(excess))
    reason = STOP_REASONS[0] if row[ch] > 1.0 else STOP_REASONS[1]
    last = float(s_all[stop - 1]) if stop > 0 else None
    return Extrapolation(x0, d, s_all[: stop + 1], A[: stop + 1], last, float(s_all[stop]), reason, _CHANNELS[ch])


# --------------------------------------------------------------------------
# Sampling plausible materials
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class MaterialSamples:
    """What :func:`sample_material` drew."""

    #: Latent points ``(n, q)``.
    points: NDArray[np.float64]
    #: Blend weights ``(n, N)`` over ``names`` (Σw = 1 per row).
    weights: NDArray[np.float64] = field(repr=False)
    #: Albedo ``(n, 3)`` of each sampled material (all in [0, 1]).
    albedos: NDArray[np.float64]
    names: tuple[str, ...]
    #: Candidates drawn (uniform in the hull) to get the n accepted.
    tries: int


def sample_material(
    model: gplvm.GplvmModel,
    source: AlbedoSource,
    rng: np.random.Generator,
    n: int = 1,
    *,
    max_tries: int | None = None,
    exact: bool = False,
) -> MaterialSamples:
    """Sample ``n`` plausible new materials: latent points uniform in the hull of the training points whose
    interpolated material has albedo in [0, 1] in every channel.

    Candidates come from :func:`sample_in_hull` in batches and are kept in
    the order drawn, so the result is deterministic given ``rng``.
    ``source``, ``exact``: see :func:`extrapolate`.  ``max_tries``: most candidates
    drawn (default ``max(1000, 100·n)``); ValueError when fewer than ``n``
    are accepted within it (naming how many were).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    limit = max(1000, 100 * int(n)) if max_tries is None else int(max_tries)
    if limit < 1:
        raise ValueError(f"max_tries must be >= 1, got {max_tries!r}")
    albedo = _Albedo.of(model, source, exact)
    batch = max(2 * int(n), 64) if albedo.A is not None else max(int(n), _LOG_BATCH)
    pts: list[NDArray[np.float64]] = []
    ws: list[NDArray[np.float64]] = []
    als: list[NDArray[np.float64]] = []
    have = tries = 0
    while have < n and tries < limit:
        m = min(batch, limit - tries)
        cand = sample_in_hull(model.X, m, rng)
        W = blend_weights_at(model, cand)
        v = albedo(cand, W)
        ok = ((v >= 0.0) & (v <= 1.0)).all(axis=1)
        take = np.flatnonzero(ok)[: n - have]
        # count the tries up to the last accepted candidate when the batch finished the job
        tries += m if have + int(ok.sum()) < n else int(take[-1]) + 1
        pts.append(cand[take])
        ws.append(W[take])
        als.append(v[take])
        have += take.size
    if have < n:
        raise ValueError(
            f"only {have} of {n} sampled materials had albedo in [0, 1] within {limit} tries; raise max_tries"
        )
    return MaterialSamples(np.concatenate(pts), np.concatenate(ws), np.concatenate(als), model.names, tries)


# --------------------------------------------------------------------------
# Writing blended materials
# --------------------------------------------------------------------------


def write_blends(
    model_path: str | os.PathLike[str],
    model: gplvm.GplvmModel,
    store: BrdfStore | str | os.PathLike[str],
    points: ArrayLike,
    outs: Sequence[str | os.PathLike[str]],
    *,
    operation: str,
    details: Sequence[Mapping[str, Any]] | None = None,
    batch: int = _LOG_BATCH,
) -> NDArray[np.int64]:
    """Write the materials at latent ``points`` ``(P, q)`` of ``model`` as MERL files ``outs``; returns clamp counts.

    Each is the blend of :func:`blend_weights_at` (:func:`brdfpipe.manifold.gplvm.interpolate_tables`,
    ``batch`` tables at a time, one pass over the store per batch) written
    with its ``derived`` provenance mark (:class:`brdfpipe.manifold.derivation.BlendSource`:
    ``operation`` — ``sample``, ``extrapolate`` … — the model's and the
    store's digests, the point, the weights and ``details[k]``).  The store is
    opened (and verified) once.
    """
    P = _as_points(points, "points", model.X.shape[1])
    if len(outs) != P.shape[0] or (details is not None and len(details) != P.shape[0]):
        raise ValueError(f"need one output (and one details entry) per point, got {P.shape[0]} points, "
                         f"{len(outs)} outputs")
    st = gplvm.check_store(model, store)  # the store holds the rows the model was fitted on
    source = derivation.BlendSource.of(model_path, model, st)
    W = blend_weights_at(model, P)
    clamped = np.zeros(P.shape[0], dtype=np.int64)
    for a in range(0, P.shape[0], max(1, int(batch))):
        b = min(a + max(1, int(batch)), P.shape[0])
        tables, clamped[a:b] = gplvm.interpolate_tables(st, W[a:b], materials=model.names, space=model.space,
                                                        model=model)
        for k in range(a, b):
            mark = source.mark(out=outs[k], operation=operation, point=P[k], weights=W[k],
                               **(details[k] if details is not None else {}))
            merl.write_merl(outs[k], tables[k - a], mark=mark)
    return clamped
