"""Analyses of a fitted GPLVM material manifold (Soler et al. 2018 §4, Figs. 7–10).

Everything here starts from the store, the centred Gram matrix of
:func:`brdfpipe.manifold.gram.gram_matrix` and the saved fits; the figures are drawn
by :mod:`brdfpipe.manifold.figures` from the files written by :func:`analyze_manifold`.

Albedo (§4.2, Fig. 7)
---------------------
The albedo of a BRDF is the ratio of the radiance it reflects under a
uniform incident distribution to that distribution's irradiance:
``A = (1/π) ∫∫ f(ωi, ωo) cos θi cos θo dωi dωo`` (the white-sky albedo).
With the directional albedo ``a(θi) = ∫ f cos θo dωo``
(:func:`brdfpipe.data.merl.directional_albedo`) and ``u = sin²θi``,
``A = ∫₀¹ a(θi(u)) du``; :func:`brdfpipe.manifold.albedo.material_albedo` takes the midpoint rule with
:data:`~brdfpipe.manifold.albedo.ALBEDO_NODES` nodes in ``u``.  A is linear in f, so the albedo of the
interpolated BRDF at a latent point is ``Σ wᵢ Aᵢ`` with the blend weights of
:func:`brdfpipe.manifold.gplvm.blend_weights` (each material's albedo is computed once,
over its own measured cells; the clamping of negative interpolated values,
which makes the map slightly non-linear, is ignored).

Paths (§4.3, Fig. 9) and the bound of eq. 7
-------------------------------------------
A path from material A to material B is the straight latent segment
``x(t) = (1 − t)x_A + t x_B`` at ``t = k/steps``.  At each point the
interpolated BRDF is formed (as :func:`brdfpipe.manifold.gplvm.interpolate_tables`
forms it) and its perceptual distance to both ends is measured with
:mod:`brdfpipe.manifold.perceptual`; all points of all paths are blended and measured
in one pass over the store, a block of cells at a time
(:func:`brdfpipe.manifold.blendpass.measure_blends`, :func:`paths_analysis`).  The actual deviation from the nearest training
material ``j`` (in latent space) is exact from the Gram matrix:
``z* − z_j = Σ (wᵢ − δᵢⱼ) zᵢ`` with weights summing to 0, so
``‖z* − z_j‖² = (w − e_j)ᵀ G_c (w − e_j)``.  Eq. 7 bounds it by
``e^{−1/2} √(2N)/ℓ · κ(K) · ‖Z‖_F · ‖x* − x_j‖`` with ``‖Z‖_F = √tr(G_c)``
(the centred data the GP interpolates) and κ the 2-norm condition number
of K.  Both are in the data units of the Gram file (the fit's ``gram_scale``
cancels: the bound is homogeneous in Z).

Reproduction (Fig. 8)
---------------------
The GPLVM reproduces every training material exactly: ``b(xᵢ) = eᵢ``;
its relative error ``‖ẑᵢ − zᵢ‖/‖zᵢ‖`` is computed the same exact way as the
deviation above.  A PCA with k components reproduces row i with the
residual ``Σ_{j>k} λⱼ Vᵢⱼ²`` (eigen-decomposition ``G_c = VΛVᵀ``; the mean is
kept exactly), relative to ``‖zᵢ‖ = √(ZZᵀ)ᵢᵢ`` of the un-centred data.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.filenames import path_name
from brdfpipe.registry.manifold import SOLER_PATHS, check_paths, default_paths
from brdfpipe.registry import tables
from brdfpipe.data import merl
from brdfpipe.data.store import BrdfStore, open_store
from brdfpipe.manifold import blendpass, derivation, gplvm, latent
from brdfpipe.manifold.albedo import material_albedos, read_material_albedos
from brdfpipe.manifold.gram import check_gram_store, load_gram

__all__ = [
    "SOLER_PATHS",
    "default_paths",
    "check_paths",
    "path_name",
    "latent_grid",
    "albedo_map",
    "eq7_bound",
    "deviation",
    "reproduction_errors",
    "LatentPath",
    "latent_path",
    "paths_analysis",
    "analyze_manifold",
    "path_points_to_files",
]

logger = logging.getLogger("brdfpipe.manifold.analysis")

_LUMA: Final = np.array([0.2126, 0.7152, 0.0722])


# --------------------------------------------------------------------------
# Latent-space helpers
# --------------------------------------------------------------------------


def latent_grid(
    X: ArrayLike, dims: tuple[int, int] = (0, 1), n: int = 96, margin: float = 0.15
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Grid coordinates ``(x, y)`` covering the latent points along ``dims`` plus a margin."""
    x = np.asarray(X, dtype=np.float64)
    lo, hi = x[:, list(dims)].min(axis=0), x[:, list(dims)].max(axis=0)
    pad = margin * np.maximum(hi - lo, 1e-12)
    return np.linspace(lo[0] - pad[0], hi[0] + pad[0], n), np.linspace(lo[1] - pad[1], hi[1] + pad[1], n)


def _blend_weights_at(model: gplvm.GplvmModel, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Blend weights ``w`` (P × N) at many latent points in one triangular solve (δ term dropped)."""
    d2 = ((points[:, None, :] - model.X[None, :, :]) ** 2).sum(axis=2)
    k = np.exp(-d2 / (2.0 * model.ell * model.ell))
    b = scipy.linalg.cho_solve((model.chol, True), k.T).T
    return b + (1.0 - b.sum(axis=1, keepdims=True)) / model.X.shape[0]


def albedo_map(
    model: gplvm.GplvmModel, albedos: ArrayLike, *, dims: tuple[int, int] = (0, 1), n: int = 96
) -> dict[str, Any]:
    """Albedo ``Σ wᵢ(x) Aᵢ`` of the interpolated BRDF over a latent plane (a slice through the mean of X).

    Returns the arrays of an ``albedo-map-q{q}.npz``: ``x``, ``y``, ``albedo``
    (H, W, 3), ``luminance`` (H, W), ``dims``, ``fixed`` (q,), ``q``,
    ``inside_hull`` (H, W: the grid point lies inside the convex hull of the
    q-dimensional training points, :func:`brdfpipe.manifold.latent.hull_contains`),
    ``bad_inside`` / ``bad_outside`` (share of grid points inside / outside
    the hull whose albedo leaves [0, 1] in some channel) and
    ``training_gap_median`` / ``_max`` (luminance |A_map(xᵢ) − Aᵢ| of the map's
    interpolant at the training points).

    The map is the smooth interpolant: ``k`` without the μδ term, since no
    grid point coincides with a training point.  At a training point itself
    the model's δ convention gives its own albedo exactly; the training gap
    measures how far the smooth map is from that there (the jump of
    ``μK⁻¹eᵢ``).
    """
    A = np.asarray(albedos, dtype=np.float64)
    q = model.X.shape[1]
    if A.shape != (model.X.shape[0], 3):
        raise ValueError(f"albedos must have shape ({model.X.shape[0]}, 3), got {A.shape}")
    if q < 2 or len(set(dims)) != 2 or max(dims) >= q or min(dims) < 0:
        raise ValueError(f"dims {dims} is not a pair of distinct latent axes of a q = {q} model")
    xs, ys = latent_grid(model.X, dims, n)
    fixed = model.X.mean(axis=0)
    XX, YY = np.meshgrid(xs, ys)  # row j ↔ y[j], column i ↔ x[i]
    pts = np.tile(fixed, (XX.size, 1))
    pts[:, dims[0]], pts[:, dims[1]] = XX.ravel(), YY.ravel()
    alb = (_blend_weights_at(model, pts) @ A).reshape(n, n, 3)
    inside = latent.hull_contains(model.X, pts).reshape(n, n)
    bad = ((alb < 0.0) | (alb > 1.0)).any(axis=2)
    # the map's interpolant at the training points themselves (a hair off: the δ term dropped)
    at_train = _blend_weights_at(model, model.X) @ A
    gap = np.abs((at_train - A) @ _LUMA)
    return {
        "x": xs, "y": ys, "albedo": alb, "luminance": alb @ _LUMA,
        "dims": np.array(dims), "fixed": fixed, "q": np.array(q),
        "inside_hull": inside,
        "bad_inside": np.array(float(bad[inside].mean()) if inside.any() else float("nan")),
        "bad_outside": np.array(float(bad[~inside].mean()) if (~inside).any() else float("nan")),
        "training_gap_median": np.array(float(np.median(gap))),
        "training_gap_max": np.array(float(gap.max())),
    }


def deviation(gram: ArrayLike, w: ArrayLike, j: int) -> float:
    """``‖Σ wᵢ zᵢ − z_j‖`` exactly from the centred Gram matrix (Σw = 1), see the module docstring."""
    g = np.asarray(gram, dtype=np.float64)
    v = np.asarray(w, dtype=np.float64).copy()
    v[j] -= 1.0
    return float(np.sqrt(max(float(v @ g @ v), 0.0)))


def eq7_bound(model: gplvm.GplvmModel, gram: ArrayLike, x_star: ArrayLike, j: int) -> float:
    """Right-hand side of eq. 7: ``e^{−1/2}√(2N)/ℓ · κ(K) · ‖Z‖_F · ‖x* − x_j‖`` (‖Z‖_F = √tr G_c)."""
    g = np.asarray(gram, dtype=np.float64)
    n = model.X.shape[0]
    kappa = float(np.linalg.cond(model.chol @ model.chol.T))
    znorm = float(np.sqrt(max(np.trace(g), 0.0)))
    dist = float(np.linalg.norm(np.asarray(x_star, dtype=np.float64) - model.X[j]))
    return float(np.exp(-0.5) * np.sqrt(2.0 * n) / model.ell * kappa * znorm * dist)


# --------------------------------------------------------------------------
# Reproduction of the training materials (Fig. 8)
# --------------------------------------------------------------------------


def reproduction_errors(
    gram: ArrayLike, raw_gram: ArrayLike, models: Mapping[int, gplvm.GplvmModel], ks: Sequence[int] = (20, 40)
) -> list[tuple[str, int, NDArray[np.float64]]]:
    """Relative reproduction error of every material: ``[(method, k, errors (N,)), …]``.

    ``("pca", k, …)`` for each k in ``ks`` (capped at N − 1) and for each
    model's q; ``("gplvm", q, …)`` for each model.  See the module docstring.
    """
    g = np.asarray(gram, dtype=np.float64)
    norms = np.sqrt(np.maximum(np.diag(np.asarray(raw_gram, dtype=np.float64)), 0.0))
    norms[norms == 0] = 1.0
    n = g.shape[0]
    lam, V = np.linalg.eigh(0.5 * (g + g.T))
    lam, V = np.clip(lam[::-1], 0.0, None), V[:, ::-1]
    contrib = V * V * lam  # (N, N): row i's squared residual per dropped component
    out: list[tuple[str, int, NDArray[np.float64]]] = []
    for k in sorted({min(int(k), n - 1) for k in ks} | {int(q) for q in models}):
        out.append(("pca", k, np.sqrt(contrib[:, k:].sum(axis=1)) / norms))
    for q, model in sorted(models.items()):
        errs = np.empty(n)
        for i in range(n):
            w = gplvm.blend_weights(gplvm.weights(model, model.X[i]))
            errs[i] = deviation(g, w, i) / norms[i]
        out.append(("gplvm", int(q), errs))
    return out


# --------------------------------------------------------------------------
# Paths (Fig. 9) and eq. 7
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class LatentPath:
    """The points ``x(t) = (1 − t)x_A + t x_B``, ``t = k/steps``, of one latent path and their blend weights."""

    a: str
    b: str
    ts: NDArray[np.float64]
    points: NDArray[np.float64]
    #: Blend weights ``(steps + 1, N)`` with the model's δ convention (the ends are A and B exactly).
    weights: NDArray[np.float64]

    def pairs(self, offset: int = 0) -> list[tuple[int, int]]:
        """The PR12 distances :meth:`rows` needs, as pairs of blend rows (this path's rows from ``offset``).

        Every point to A, every point to B, then A to B.
        """
        n = self.ts.size
        first, last = offset, offset + n - 1
        return ([(offset + k, first) for k in range(n)] + [(offset + k, last) for k in range(n)]
                + [(first, last)])

    def rows(self, model: gplvm.GplvmModel, gram: ArrayLike, distances: ArrayLike) -> list[dict[str, Any]]:
        """One row per point (:data:`~brdfpipe.registry.tables.LATENT_PATHS` without database, space, q); ``distances`` of :meth:`pairs`."""
        n = self.ts.size
        d = np.asarray(distances, dtype=np.float64)
        to_a, to_b, d_ab = d[:n], d[n : 2 * n], float(d[2 * n])
        names = list(model.names)
        g = np.asarray(gram, dtype=np.float64)
        xa, xb = model.X[names.index(self.a)], model.X[names.index(self.b)]
        out = []
        for k, (t, x) in enumerate(zip(self.ts, self.points)):
            j = int(np.argmin(((model.X - x) ** 2).sum(axis=1)))
            out.append({
                "path": path_name(self.a, self.b), "material_a": self.a, "material_b": self.b, "step": k,
                "t": float(t),
                "latent_distance": float(t * np.linalg.norm(xb - xa)),
                "perceptual_a": float(to_a[k]),
                "perceptual_b": float(to_b[k]),
                "perceptual_ab": d_ab,
                "nearest": names[j],
                "deviation": deviation(g, self.weights[k], j),
                "bound": eq7_bound(model, g, x, j),
            })
        logger.info("path %s: %d points, perceptual distance A-B %.4g", path_name(self.a, self.b), n, d_ab)
        return out


def latent_path(model: gplvm.GplvmModel, a: str, b: str, steps: int = 20) -> LatentPath:
    """The points and blend weights of the latent path from ``a`` to ``b`` (materials of ``model``)."""
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    names = list(model.names)
    check_paths([(a, b)], names, what="path")
    xa, xb = model.X[names.index(a)], model.X[names.index(b)]
    ts = np.arange(steps + 1) / steps
    pts = (1.0 - ts)[:, None] * xa + ts[:, None] * xb
    W = np.stack([gplvm.blend_weights(gplvm.weights(model, x)) for x in pts])
    return LatentPath(a, b, ts, pts, W)


def paths_analysis(
    store: BrdfStore | str | os.PathLike[str],
    model: gplvm.GplvmModel,
    gram: ArrayLike,
    pairs: Sequence[tuple[str, str]],
    steps: int = 20,
) -> list[dict[str, Any]]:
    """One row per point of every latent path of ``pairs``, in order, all blended in one pass over the store.

    The rows: see the module docstring and tables.LATENT_PATHS.  The interpolated tables are never
    formed whole: their perceptual distances are summed a block of cells at a time
    (:func:`brdfpipe.manifold.blendpass.measure_blends`), so memory does not grow with ``steps``.
    """
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    check_paths(pairs, list(model.names), what="path")
    paths = [latent_path(model, a, b, steps) for a, b in pairs]
    if not paths:
        return []
    offsets = np.cumsum([0] + [p.ts.size for p in paths])
    wanted = [pair for p, o in zip(paths, offsets) for pair in p.pairs(int(o))]
    measured = blendpass.measure_blends(store, np.vstack([p.weights for p in paths]), model=model, pairs=wanted)
    rows: list[dict[str, Any]] = []
    at = 0
    for p in paths:
        n = len(p.pairs())
        rows += p.rows(model, gram, measured.distances[at : at + n])
        at += n
    return rows


# --------------------------------------------------------------------------
# The workflow entry point
# --------------------------------------------------------------------------


def _fmt(v: Any) -> str:
    if isinstance(v, (float, np.floating)):
        return format(float(v), ".10g")
    return str(v)


def _write_csv(path: Path, columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_fmt(r[c]) for c in columns])
    integrity.write_csv(path, buf.getvalue())


def analyze_manifold(
    *,
    store: str | os.PathLike[str],
    gram: str | os.PathLike[str],
    models: Mapping[int, str | os.PathLike[str]],
    paths: Sequence[Sequence[str]] | None,
    path_q: int,
    seed: int,
    steps: int = 20,
    albedo_grid: int = 96,
    pca_ks: Sequence[int] = (20, 40),
    albedos: str | os.PathLike[str] | None = None,
    albedo_out: str | os.PathLike[str],
    albedo_maps_out: Mapping[int, str | os.PathLike[str]],
    paths_out: str | os.PathLike[str],
    reproduction_out: str | os.PathLike[str],
) -> None:
    """The workflow's ``analyze_manifold`` job: albedos, albedo maps, paths, reproduction.

    Writes ``albedo_out`` (CSV), one albedo map per entry of
    ``albedo_maps_out`` (q → npz; q must have a model and be ≥ 2),
    ``paths_out`` (CSV: paths of the ``path_q`` model; ``paths=None``:
    :func:`default_paths`) and ``reproduction_out`` (CSV).  ValueError for an
    unknown material in a path or a ``path_q`` without a model.  ``albedos``:
    the materials' albedos (:func:`brdfpipe.manifold.albedo.write_material_albedos`,
    checked against the store); None computes them here.
    """
    st = open_store(store)
    G, d, info = load_gram(gram)
    check_gram_store(info, st, gram)
    fits = {int(q): gplvm.load_model(p) for q, p in models.items()}
    names = list(info.materials)
    for q, m in fits.items():
        if list(m.names) != names:
            raise ValueError(f"{models[q]}: its materials differ from those of {gram}")
        gplvm.check_store(m, st)
    if int(path_q) not in fits:
        raise ValueError(f"path_q = {path_q} has no fitted model (fitted: {sorted(fits)})")
    pairs = check_paths(paths, names) if paths else default_paths(names, seed)
    database = st.database

    A = material_albedos(st, names) if albedos is None else read_material_albedos(albedos, st, names)
    for q in albedo_maps_out:
        if int(q) not in fits:
            raise ValueError(f"albedo map for q = {q} requested, but there is no q = {q} model")
        if int(q) < 2:
            raise ValueError(f"albedo map for q = {q} requested: a latent plane needs q ≥ 2")
    _write_csv(Path(albedo_out), tables.MATERIAL_ALBEDO, [
        {"database": database, "material": m, "r": A[i, 0], "g": A[i, 1], "b": A[i, 2], "luminance": float(A[i] @ _LUMA)}
        for i, m in enumerate(names)
    ])
    for q, target in sorted(albedo_maps_out.items()):
        amap = albedo_map(fits[int(q)], A, n=albedo_grid)
        amap["database"] = np.array(database)
        integrity.save_npz(target, amap)

    rows = [{"database": database, "space": info.space, "q": int(path_q), **r}
            for r in paths_analysis(st, fits[int(path_q)], G, pairs, steps)]
    _write_csv(Path(paths_out), tables.LATENT_PATHS, rows)

    rep = []
    for method, k, errs in reproduction_errors(G, info.raw_gram, fits, pca_ks):
        rep += [{"database": database, "space": info.space, "material": m, "method": method, "k": k,
                 "relative_error": float(errs[i])} for i, m in enumerate(names)]
    _write_csv(Path(reproduction_out), tables.REPRODUCTION, rep)
    logger.info("manifold analyses of %d materials (%s database) -> %s", len(names), database, reproduction_out)


def path_points_to_files(
    *,
    model: str | os.PathLike[str],
    store: str | os.PathLike[str],
    points: Sequence[tuple[str, str, float]],
    merl_outs: Sequence[str | os.PathLike[str]],
    weights_outs: Sequence[str | os.PathLike[str]],
) -> NDArray[np.float64]:
    """Interpolated materials at points ``(a, b, t)`` of latent paths ``a → b``: MERL files and weights JSONs.

    The workflow's ``interpolate_path_points`` job (the rendering track blends
    pre-rendered images with the same weights).  All points are blended in one
    pass over the store (:func:`brdfpipe.manifold.gplvm.interpolate_tables`): the store
    is read once, not once per point.  ``merl_outs[k]`` and
    ``weights_outs[k]`` belong to ``points[k]``.  Each JSON holds ``path``,
    ``t``, ``q``, the latent point ``x``, ``clamped`` (values of measured cells
    that came out negative and were clamped to 0), ``measured_values`` (the
    table's values in measured cells) and ``weights`` {material: wᵢ} (blend
    weights, Σw = 1), written atomically.  Each MERL file carries a
    ``derived`` provenance mark (operation ``path-point``, :mod:`brdfpipe.manifold.derivation`).
    Returns the weights ``(P, N)``.
    """

    if not (len(points) == len(merl_outs) == len(weights_outs)) or not points:
        raise ValueError(f"need one MERL and one weights output per path point, got {len(points)} points, "
                         f"{len(merl_outs)} MERL and {len(weights_outs)} weights outputs")
    m = gplvm.load_model(model)
    check_paths(sorted({(a, b) for a, b, _ in points}), m.names, what=f"path of {model}")
    st = open_store(store)
    source = derivation.BlendSource.of(model, m, st)
    names = list(m.names)
    xs, ws = [], []
    for a, b, t in points:
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        x = (1.0 - t) * m.X[names.index(a)] + t * m.X[names.index(b)]
        xs.append(x)
        ws.append(gplvm.blend_weights(gplvm.weights(m, x)))
    W = np.stack(ws)
    tables, clamped = gplvm.interpolate_tables(st, W, materials=names, space=m.space, model=m)
    for k, (a, b, t) in enumerate(points):
        mark = source.mark(out=merl_outs[k], operation="path-point", point=xs[k],
                           weights=W[k], path=[a, b], t=float(t))
        merl.write_merl(merl_outs[k], tables[k], mark=mark)
        doc = {"path": path_name(a, b), "material_a": a, "material_b": b, "t": float(t), "q": int(m.X.shape[1]),
               "x": [float(v) for v in xs[k]], "clamped": int(clamped[k]),
               "measured_values": int(np.count_nonzero(tables[k] >= 0.0)),
               "weights": {n: float(v) for n, v in zip(names, W[k])}}
        integrity.write_json(weights_outs[k], doc)
        logger.info("path %s at t = %g: %d clamped values -> %s", path_name(a, b), t, clamped[k], merl_outs[k])
    return W
