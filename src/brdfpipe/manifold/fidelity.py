"""How faithful a GPLVM material manifold is, measured per data space (Soler et al. 2018 §3–§5).

A fitted model (:class:`brdfpipe.manifold.gplvm.GplvmModel`) is judged here on what a
user of the manifold relies on, with the same numbers for every candidate data
space (:data:`brdfpipe.registry.manifold.SPACE_NAMES` × μ), so the default can be chosen by
measurement (rule ``compare_spaces``, CSV :data:`~brdfpipe.registry.tables.SPACES`):

Weights
-------
``w(x) = blend_weights(K⁻¹k(x))`` with ``k`` **without** the μδ term
(:func:`smooth_weights`): the interpolant a hair away from a training point.
At a training point exactly, the model's own convention adds μ to ``k`` and
gives ``w = eᵢ`` (:func:`brdfpipe.manifold.gplvm.weights`).  The gap between the two,
``μ K⁻¹ eᵢ``, is what makes the interpolant jump at the training points.

Measures
--------
* ``albedo_clamped_bad_hull``: share of latent points, drawn uniformly inside
  the convex hull of the training points (:func:`brdfpipe.manifold.latent.sample_in_hull`;
  the first ``manifold.clamped_hull_points`` of them, default
  :data:`CLAMPED_HULL_POINTS`, ``albedo_clamped_points``),
  whose interpolated table *as a renderer receives it* — negative values
  clamped to 0, exactly the table :func:`brdfpipe.manifold.gplvm.interpolate_tables`
  and ``brdfpipe interpolate`` write — has a white-sky albedo (Soler §4.2's
  albedo, :func:`brdfpipe.manifold.albedo.material_albedo`) outside [0, 1] in
  some channel; ``albedo_clamped_bad_map`` the same over the plotted albedo
  map (q = 2: every :data:`CLAMPED_MAP_STRIDE`-th row and column of the grid of
  :func:`brdfpipe.manifold.analysis.latent_grid`, 15 % past the data).  Measured
  in one pass over the store for every q of a candidate, over the cells the
  albedo reads (:func:`brdfpipe.manifold.blendpass.measure_blends`).  Clamping
  only raises a table, so it turns albedos below 0 into albedos ≥ 0 and can
  push one above 1.
* ``albedo_bad_hull`` / ``albedo_bad_map``: the same over all
  :data:`HULL_POINTS` hull points and the whole map for the *unclamped* table
  ``Σ wᵢ zᵢ``, whose albedo is ``w·A`` exactly in the linear spaces (albedo is
  linear in the BRDF): a diagnostic of negative lobes, not what is rendered.
  In the ``log`` space the blend is not linear and every table is clamped:
  there both columns are the clamped table's (the map is not computed).
* ``sum_abs_w_*``: ``Σ|wᵢ|`` over the hull points and along the paths
  (median and max): 1 for a convex blend; large values mean cancelling
  weights, noise amplification in image blends and negative BRDF values.
* ``kappa``: the 2-norm condition number of K; ``log_likelihood``: L of the
  fit (of G/s when the fit was normalised); ``log_likelihood_eq6``: Soler's
  eq. 6 at the fitted points with the space's Gram matrix as it is (no
  normalisation), so fits of one space compare whatever their normalisation.
* ``jump_nn_*_1e-6`` (:func:`nearest_neighbour_points`): next to each material,
  towards its nearest neighbour in latent space (``x = (1 − t) xᵢ + t xⱼ``,
  t = :data:`NN_STEP`, the point ``brdfpipe interpolate --between i j --t 1e-6``
  takes), the distance of the interpolated table *as that command writes it*
  (negative values clamped) from the material's, ``‖z(x) − zᵢ‖ / ‖zᵢ‖`` in
  raw BRDF units over the valid cells, measured in a pass over the store (any
  data space); median, 90th percentile, max and the worst pair.  With the
  kernel's noise term μ the weights a hair away from a training point are
  not its own (``μ K⁻¹ eᵢ`` off), so the interpolant jumps there.  The
  unclamped table can be much farther (its negative lobes): on merl-nbrdf's
  blue-fabric → green-fabric, 159 % against the 48 % written.
* ``reproduction_max``: at the training points themselves (the model's own
  weights, δ term included), the largest ``‖z(xᵢ) − zᵢ‖ / ‖zᵢ‖`` in raw units:
  rounding, amplified by κ(K).
* stability (:func:`stability`): relative change of the interpolated
  material ``‖z(xᵢ + εu) − zᵢ‖ / ‖zᵢ‖`` for a random unit direction ``u`` per
  material and ε in :data:`EPSILONS` (ℓ units), exactly from Gram matrices
  (``‖Σ vⱼ zⱼ‖² = vᵀ G v``, ``v = w − eᵢ``), in raw BRDF units
  (``norm = "raw"``) and in the space the model was fitted in
  (``norm = "space"``); median, 90th percentile and max over the materials.
  For ε → 0 it tends to the reproduction error of the smooth interpolant (the
  jump above, in a random direction rather than towards a neighbour).
* nearest-neighbour spread: distance from each latent point to its nearest
  neighbour (median, min, in ℓ), and the number of pairs closer than
  ``√(2μ)`` (where the kernel's δ term outweighs their distance) and 1e-5.
* ``perceptual_*`` (:func:`path_uniformity`): along each latent path, the
  perceptual distance from A of the interpolated material divided by that of
  B, compared with ``t`` (Soler Fig. 9: a perceptually uniform manifold has
  ``d(A, x(t)) / d(A, B) ≈ t``): the largest deviation, and the number of
  steps where the distance from A decreases.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.manifold import analysis, blendpass, gplvm, latent
from brdfpipe.manifold.gram import check_gram_store, load_gram
from brdfpipe.manifold.likelihood import log_likelihood
from brdfpipe.manifold.albedo import material_albedos, read_material_albedos
from brdfpipe.registry.manifold import LINEAR_SPACES, candidate_label
from brdfpipe.registry import tables

__all__ = [
    "EPSILONS",
    "NN_STEP",
    "CLAMPED_HULL_POINTS",
    "CLAMPED_MAP_STRIDE",
    "candidate_label",
    "smooth_weights",
    "albedo_outside",
    "clamped_albedos",
    "stability",
    "reproduction_at_points",
    "nearest_neighbour_spread",
    "path_uniformity",
    "hull_sample",
    "measure_model",
    "measure_candidate",
    "combine_candidates",
]

logger = logging.getLogger("brdfpipe.manifold.fidelity")

#: Offsets from the training points (ℓ units) of the stability measure.
EPSILONS: Final = (1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
#: The step towards the nearest neighbour (a fraction of the way) of the continuity measure.
NN_STEP: Final = 1e-6
#: Hull points drawn per model for the albedo and weight statistics.
HULL_POINTS: Final = 20000
#: The hull points (the first drawn) whose clamped tables' albedo is measured: each costs a blend of every
#: material over the albedo's cells (~0.9 M values); 2,000 give a share to ±0.5 % (one standard error at 5 %).
CLAMPED_HULL_POINTS: Final = 2000
#: Every this-th row and column of the albedo map grid whose clamped tables' albedo is measured (q = 2).
CLAMPED_MAP_STRIDE: Final = 3


# --------------------------------------------------------------------------
# Weights
# --------------------------------------------------------------------------


def smooth_weights(model: gplvm.GplvmModel, points: ArrayLike) -> NDArray[np.float64]:
    """Blend weights ``(P, N)`` at latent points with ``k`` free of the μδ term (one triangular solve)."""
    P = np.atleast_2d(np.asarray(points, dtype=np.float64))
    if P.shape[1] != model.X.shape[1]:
        raise ValueError(f"points must have {model.X.shape[1]} coordinates, got shape {P.shape}")
    d2 = ((P[:, None, :] - model.X[None, :, :]) ** 2).sum(axis=2)
    k = np.exp(-d2 / (2.0 * model.ell * model.ell))
    b = scipy.linalg.cho_solve((model.chol, True), k.T).T
    return b + (1.0 - b.sum(axis=1, keepdims=True)) / model.X.shape[0]


def _outside(albedo: NDArray[np.float64]) -> NDArray[np.bool_]:
    return ((albedo < 0.0) | (albedo > 1.0)).any(axis=1)


def albedo_outside(model: gplvm.GplvmModel, points: ArrayLike, albedos: ArrayLike) -> NDArray[np.bool_]:
    """For each latent point: is the albedo ``w·A`` of its (unclamped) interpolated material outside [0, 1]?

    ``A``: the materials' albedos (N, 3); a linear data space only (the blend of the tables is the blend of
    their albedos), ValueError for another.
    """
    if model.space not in LINEAR_SPACES:
        raise ValueError(f"albedo w·A in the {model.space!r} space: the blend is not linear")
    return _outside(smooth_weights(model, points) @ np.asarray(albedos, dtype=np.float64))


def clamped_albedos(
    store: Any, fits: Mapping[int, gplvm.GplvmModel], points: Mapping[int, NDArray[np.float64]]
) -> dict[int, NDArray[np.float64]]:
    """White-sky albedo ``(P, 3)`` of the clamped interpolated table at each latent point, per q.

    The tables ``brdfpipe interpolate`` writes (negative values in valid
    cells set to 0): the fits of one candidate (same materials and space)
    blended together in one pass over the store, over the cells the albedo
    reads (:func:`brdfpipe.manifold.blendpass.measure_blends`, ``albedo_only``).
    """
    first = next(iter(fits.values()))
    blocks = [smooth_weights(fits[q], points[q]) for q in fits]
    got = blendpass.measure_blends(store, np.vstack(blocks), model=first, albedo_only=True)
    ends = np.cumsum([0] + [b.shape[0] for b in blocks])
    return {q: got.albedo[a:b] for q, a, b in zip(fits, ends[:-1], ends[1:])}


# --------------------------------------------------------------------------
# Stability near the training points
# --------------------------------------------------------------------------


def stability(
    model: gplvm.GplvmModel,
    gram: ArrayLike,
    *,
    epsilons: Sequence[float] = EPSILONS,
    rng: np.random.Generator,
) -> dict[float, NDArray[np.float64]]:
    """Relative change ``‖z(xᵢ + εuᵢ) − zᵢ‖/‖zᵢ‖`` per material (N,) for each ε.

    ``gram`` is an *un-centred* Gram matrix ``Z Zᵀ`` of the materials (in
    model order) in the units the change is measured in; ``uᵢ`` are random
    unit directions (one per material, from ``rng``).  Linear spaces only
    (the blend of the ``log`` space is not a linear combination of rows).
    """
    G = np.asarray(gram, dtype=np.float64)
    n, q = model.X.shape
    if G.shape != (n, n):
        raise ValueError(f"gram must be {n} x {n}, got {G.shape}")
    u = rng.standard_normal((n, q))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return {float(eps): _relative_distances(smooth_weights(model, model.X + float(eps) * u), G) for eps in epsilons}


def _relative_distances(W: NDArray[np.float64], G: NDArray[np.float64]) -> NDArray[np.float64]:
    """``‖Σⱼ Wᵢⱼ zⱼ − zᵢ‖ / ‖zᵢ‖`` per row i, from the un-centred Gram matrix ``G = Z Zᵀ``."""
    V = W - np.eye(W.shape[0])
    norms = np.sqrt(np.maximum(np.diag(G), 0.0))
    norms[norms == 0] = 1.0
    return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", V, G, V), 0.0)) / norms


def nearest_neighbour_points(model: gplvm.GplvmModel) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Blend weights ``(N, N)`` at ``(1 − t) xᵢ + t xⱼ`` next to each material i, j its nearest latent neighbour; and j.

    ``t`` = :data:`NN_STEP`.  The point and its weights are those of ``brdfpipe interpolate --between i j --t 1e-6``
    (:func:`brdfpipe.manifold.gplvm.interpolate_to_file`: the model's own weights, δ term where the point is a
    training point bitwise).
    """
    t = NN_STEP
    X = model.X
    D = ((X[:, None, :] - X[None, :, :]) ** 2).sum(axis=2)
    np.fill_diagonal(D, np.inf)
    nn = D.argmin(axis=1)
    W = np.stack([gplvm.blend_weights(gplvm.weights(model, (1.0 - t) * X[i] + t * X[nn[i]])) for i in range(len(nn))])
    return W, nn


def reproduction_at_points(model: gplvm.GplvmModel, raw_gram: ArrayLike) -> NDArray[np.float64]:
    """``‖z(xᵢ) − zᵢ‖ / ‖zᵢ‖`` per material at its own latent point (the model's weights, δ term included)."""
    W = np.stack([gplvm.blend_weights(gplvm.weights(model, x)) for x in model.X])
    return _relative_distances(W, np.asarray(raw_gram, dtype=np.float64))


def nearest_neighbour_spread(model: gplvm.GplvmModel) -> dict[str, float]:
    """Nearest-neighbour distances of the latent points (ℓ units) and counts of near-coincident pairs."""
    X = model.X / model.ell
    D = np.sqrt(np.maximum(((X[:, None, :] - X[None, :, :]) ** 2).sum(axis=2), 0.0))
    iu = np.triu_indices(X.shape[0], 1)
    pairs = D[iu]
    np.fill_diagonal(D, np.inf)
    nn = D.min(axis=1)
    return {
        "nn_median": float(np.median(nn)),
        "nn_min": float(nn.min()),
        "pairs_within_sqrt2mu": int((pairs < np.sqrt(2.0 * model.mu)).sum()),
        "pairs_within_1e-5": int((pairs < 1e-5).sum()),
    }


# --------------------------------------------------------------------------
# Perceptual uniformity along paths (Soler Fig. 9)
# --------------------------------------------------------------------------


def path_uniformity(path_rows: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """From :func:`brdfpipe.manifold.analysis.paths_analysis` rows: largest ``|d(A, x)/d(A, B) − t|``, decreasing steps."""
    by_path: dict[str, list[Mapping[str, Any]]] = {}
    for r in path_rows:
        by_path.setdefault(str(r["path"]), []).append(r)
    dev, dec = 0.0, 0
    for rows in by_path.values():
        rows = sorted(rows, key=lambda r: float(r["t"]))
        d_ab = float(rows[-1]["perceptual_a"]) or 1.0
        da = np.array([float(r["perceptual_a"]) for r in rows])
        t = np.array([float(r["t"]) for r in rows])
        dev = max(dev, float(np.max(np.abs(da / d_ab - t))))
        dec += int((np.diff(da) < 0).sum())
    return {"perceptual_max_deviation": dev, "perceptual_decreasing_steps": dec}


# --------------------------------------------------------------------------
# One model, all measures
# --------------------------------------------------------------------------


def hull_sample(model: gplvm.GplvmModel, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """``n`` latent points uniform in the convex hull of the model's training points (drawn from ``rng``)."""
    return latent.sample_in_hull(model.X, n, rng)


def measure_model(
    model: gplvm.GplvmModel,
    *,
    albedos: ArrayLike,
    raw_gram: ArrayLike,
    space_gram: ArrayLike | None,
    centred_gram: ArrayLike,
    paths: Sequence[tuple[str, str]],
    steps: int,
    rng: np.random.Generator,
    clamped_albedo: ArrayLike,
    jump: tuple[NDArray[np.float64], NDArray[np.intp]],
    hull: ArrayLike,
    clamped_map_albedo: ArrayLike | None = None,
    albedo_grid: int = 96,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Every measure of the module docstring for one fit: a :data:`~brdfpipe.registry.tables.SPACES` row (partial) and stability rows.

    ``raw_gram`` / ``space_gram``: un-centred Gram matrices of the model's
    materials in raw units and in the model's space (``space_gram`` may be
    None for the ``log`` space, whose stability is not a Gram quantity and
    is left empty); ``centred_gram``: the centred Gram matrix of the model's
    space (eq. 6 without normalisation).  ``paths``: latent paths (material
    pairs) for ``Σ|w|``.  ``clamped_albedo`` / ``clamped_map_albedo``: the
    albedos ``(P, 3)`` of the clamped tables at the first hull points and at
    the map's sub-grid (q = 2; :func:`clamped_albedos`, measured by the caller
    in one pass for every q); ``jump``: the table's distance from each
    material next to it, and the neighbour it was taken towards
    (:func:`nearest_neighbour_points`).

    ``hull``: the hull points, already drawn from ``rng`` (:func:`hull_sample`;
    ``rng`` then in the state after the draw).
    """
    A = np.asarray(albedos, dtype=np.float64)
    n, q = model.X.shape
    row: dict[str, Any] = {"q": q, "log_likelihood": model.log_likelihood}
    row["log_likelihood_eq6"] = log_likelihood(model.X, centred_gram, model.d, model.ell, model.mu)
    K = model.chol @ model.chol.T
    row["kappa"] = float(np.linalg.cond(K))
    linear = model.space in LINEAR_SPACES
    H = np.asarray(hull, dtype=np.float64)
    bad = _outside(np.asarray(clamped_albedo, dtype=np.float64))
    row["albedo_clamped_bad_hull"], row["albedo_clamped_points"] = float(bad.mean()), int(bad.size)
    row["albedo_clamped_bad_map"] = (float("nan") if clamped_map_albedo is None else
                                     float(_outside(np.asarray(clamped_map_albedo, dtype=np.float64)).mean()))
    if linear:  # the unclamped table's albedo w·A, every hull point and the whole map
        row["albedo_bad_hull"], row["hull_points"] = float(albedo_outside(model, H, A).mean()), int(H.shape[0])
        row["albedo_bad_map"] = (float(albedo_outside(model, _map_points(model.X, albedo_grid), A).mean())
                                 if q == 2 else float("nan"))
    else:  # every table of the log space is clamped
        row["albedo_bad_hull"], row["hull_points"] = row["albedo_clamped_bad_hull"], row["albedo_clamped_points"]
        row["albedo_bad_map"] = float("nan")
    sw = np.abs(smooth_weights(model, H)).sum(axis=1)
    row["sum_abs_w_hull_median"], row["sum_abs_w_hull_max"] = float(np.median(sw)), float(sw.max())
    names = list(model.names)
    ts = np.arange(steps + 1) / steps
    sp = []
    for a, b in paths:
        xa, xb = model.X[names.index(a)], model.X[names.index(b)]
        sp.append(np.abs(smooth_weights(model, (1.0 - ts)[:, None] * xa + ts[:, None] * xb)).sum(axis=1))
    spa = np.concatenate(sp) if sp else np.array([np.nan])
    row["sum_abs_w_path_median"], row["sum_abs_w_path_max"] = float(np.median(spa)), float(np.max(spa))
    row.update(nearest_neighbour_spread(model))
    row.update(_continuity(model, *jump, raw_gram if linear else None))

    stab_rows: list[dict[str, Any]] = []
    for norm, G in (("raw", raw_gram), ("space", space_gram)):
        key = f"stability_{norm}"
        if G is None or not linear:
            row[f"{key}_median_1e-6"] = row[f"{key}_p90_1e-6"] = float("nan")
            continue
        res = stability(model, G, rng=np.random.default_rng(rng.integers(2**63)))
        for eps, rel in res.items():
            stab_rows.append({"q": q, "norm": norm, "epsilon": eps, "median": float(np.median(rel)),
                              "p90": float(np.percentile(rel, 90)), "max": float(rel.max())})
        row[f"{key}_median_1e-6"] = float(np.median(res[1e-6]))
        row[f"{key}_p90_1e-6"] = float(np.percentile(res[1e-6], 90))
    return row, stab_rows


def _map_points(X: NDArray[np.float64], grid: int, stride: int = 1) -> NDArray[np.float64]:
    """The albedo map's latent points (q = 2), every ``stride``-th row and column of its grid."""
    xs, ys = analysis.latent_grid(X, (0, 1), grid)
    XX, YY = np.meshgrid(xs[::stride], ys[::stride])
    return np.c_[XX.ravel(), YY.ravel()]


def _continuity(model: gplvm.GplvmModel, jump: NDArray[np.float64], nn: NDArray[np.intp],
                raw_gram: ArrayLike | None) -> dict[str, Any]:
    """The ``jump_nn_*`` and ``reproduction_max`` columns (the latter NaN without a raw Gram: the log space)."""
    i = int(jump.argmax())
    return {"jump_nn_median_1e-6": float(np.median(jump)), "jump_nn_p90_1e-6": float(np.percentile(jump, 90)),
            "jump_nn_max_1e-6": float(jump[i]), "jump_nn_worst": f"{model.names[i]}>{model.names[int(nn[i])]}",
            "reproduction_max": (float(reproduction_at_points(model, raw_gram).max()) if raw_gram is not None
                                 else float("nan"))}


def _table_pass(
    st: Any, fits: Mapping[int, gplvm.GplvmModel], paths: Sequence[analysis.LatentPath]
) -> tuple[list[NDArray[np.float64]], dict[int, tuple[NDArray[np.float64], NDArray[np.intp]]]]:
    """One pass over the store (every valid cell) for the measures of whole tables.

    The perceptual distances of the latent paths' points (:meth:`LatentPath.pairs`, of the paths' fit) and,
    for every q, the jump next to each material (:func:`nearest_neighbour_points`, measured as the distance of
    the table written there from the material's: :func:`brdfpipe.manifold.blendpass.measure_blends` with ``targets``).
    """
    first = next(iter(fits.values()))
    blocks: list[NDArray[np.float64]] = []
    pairs: list[tuple[int, int]] = []
    targets: list[int] = []
    counts = []
    for p in paths:
        pairs += p.pairs(len(targets))
        counts.append(len(p.pairs()))
        blocks.append(p.weights)
        targets += [-1] * p.weights.shape[0]
    near = {q: nearest_neighbour_points(m) for q, m in fits.items()}
    rows = {}
    for q, (W, _) in near.items():
        rows[q] = slice(len(targets), len(targets) + W.shape[0])
        blocks.append(W)
        targets += list(range(W.shape[0]))
    got = blendpass.measure_blends(st, np.vstack(blocks), materials=first.names, space=first.space, pairs=pairs,
                                   targets=targets)
    ends = np.cumsum([0] + counts)
    return ([got.distances[a:b] for a, b in zip(ends[:-1], ends[1:])],
            {q: (got.to_target[rows[q]], near[q][1]) for q in fits})


def _fmt(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (float, np.floating)):
        return format(float(v), ".10g")
    return str(v)


def _write_csv(path: str | os.PathLike[str], columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_fmt(r[c]) for c in columns])
    integrity.write_csv(Path(path), buf.getvalue())


def measure_candidate(
    *,
    store: str | os.PathLike[str],
    grams: Mapping[str, str | os.PathLike[str]],
    models: Mapping[int, str | os.PathLike[str]],
    candidate: str,
    default: str,
    paths: Sequence[Sequence[str]] | None,
    path_q: int,
    seed: int,
    steps: int = 20,
    albedo_grid: int = 96,
    clamped_hull_points: int = CLAMPED_HULL_POINTS,
    albedos: str | os.PathLike[str] | None = None,
    spaces_out: str | os.PathLike[str],
    stability_out: str | os.PathLike[str],
) -> list[dict[str, Any]]:
    """The workflow's ``measure_gplvm_candidate`` job: every measure for one candidate's fits.

    ``grams``: data space → Gram file (:func:`brdfpipe.manifold.gram.save_gram`):
    the ``raw`` one (raw-unit stability and continuity) and the candidate's own space;
    ``models``: {q: model file} of the candidate (:func:`candidate_label` of
    its space, μ, normalisation, optimiser and start must give ``candidate``;
    the row records the last three); ``default``: the label of the configured
    default.  Writes ``spaces_out`` (:data:`~brdfpipe.registry.tables.SPACES`, one row per q)
    and ``stability_out`` (:data:`~brdfpipe.registry.tables.STABILITY`).  ``albedos``: the
    materials' albedos (:func:`brdfpipe.manifold.albedo.write_material_albedos`,
    checked against the store); None computes them here.  The random hull
    points and directions are seeded by (``seed``, q, ``candidate``);
    ``clamped_hull_points``: how many of the :data:`HULL_POINTS` hull points
    (the first drawn) have their clamped table's albedo measured
    (config ``manifold.clamped_hull_points``).
    The clamped tables' albedos of every q are measured in one pass over the
    store (:func:`clamped_albedos`), the latent paths' points and the tables
    next to each material of every q in another (:func:`_table_pass`).
    """
    from brdfpipe.registry.manifold import check_paths, default_paths
    from brdfpipe.data.store import open_store

    if "raw" not in grams:
        raise ValueError("measure_candidate needs the raw Gram matrix (stability in raw units)")
    if not 1 <= clamped_hull_points <= HULL_POINTS:
        raise ValueError(f"clamped_hull_points must be in [1, {HULL_POINTS}], got {clamped_hull_points}")
    st = open_store(store)
    loaded = {s: load_gram(p) for s, p in grams.items()}
    for s, (_, _, info) in loaded.items():
        check_gram_store(info, st, grams[s])
    names = list(loaded["raw"][2].materials)
    raw_gram = loaded["raw"][2].raw_gram
    pairs = check_paths(paths, names) if paths else default_paths(names, seed)
    A = material_albedos(st, names) if albedos is None else read_material_albedos(albedos, st, names)
    fits: dict[int, gplvm.GplvmModel] = {}
    for q, path in sorted(models.items()):
        model = gplvm.load_model(path)
        if list(model.names) != names:
            raise ValueError(f"{path}: its materials differ from those of {grams['raw']}")
        label = candidate_label(model.space, model.mu, model.normalised, model.method, model.init)
        if label != candidate:
            raise ValueError(f"{path}: a {label} fit, expected {candidate}")
        if model.space not in loaded:
            raise ValueError(f"{path}: a fit in the {model.space} space, but no Gram matrix of that space is given")
        gplvm.check_store(model, st)
        fits[int(q)] = model
    rngs = {q: np.random.default_rng([seed, int(q), *candidate.encode()]) for q in fits}
    hulls = {q: hull_sample(m, HULL_POINTS, rngs[q]) for q, m in fits.items()}
    lp = [analysis.latent_path(fits[int(path_q)], a, b, steps) for a, b in pairs] if int(path_q) in fits else []
    # the clamped tables at the first hull points of every q, and at the map's sub-grid (q = 2): one pass
    maps = {q: _map_points(m.X, albedo_grid, CLAMPED_MAP_STRIDE) for q, m in fits.items() if q == 2}
    picks = {q: np.vstack([hulls[q][:clamped_hull_points], maps.get(q, np.empty((0, q)))]) for q in fits}
    clamped = clamped_albedos(st, fits, picks)
    distances, jumps = _table_pass(st, fits, lp)
    rows: list[dict[str, Any]] = []
    stab: list[dict[str, Any]] = []
    for q, model in fits.items():
        centred, _, info = loaded[model.space]
        k = min(clamped_hull_points, hulls[q].shape[0])
        row, srows = measure_model(model, albedos=A, raw_gram=raw_gram, space_gram=info.raw_gram,
                                   centred_gram=centred, paths=pairs, steps=steps, rng=rngs[q],
                                   clamped_albedo=clamped[q][:k], clamped_map_albedo=clamped[q][k:] if q in maps
                                   else None, jump=jumps[q], albedo_grid=albedo_grid, hull=hulls[q])
        if lp and q == int(path_q):
            prow = [r for p, d in zip(lp, distances) for r in p.rows(model, centred, d)]
            row.update(path_uniformity(prow))
        else:
            row.update({"perceptual_max_deviation": float("nan"), "perceptual_decreasing_steps": -1})
        meta = {"database": st.database, "candidate": candidate, "space": model.space, "mu": model.mu,
                "normalise": model.normalised, "method": model.method, "init": model.init}
        rows.append({**meta, "default": candidate == default, **row})
        stab += [{**meta, **r} for r in srows]
        logger.info("%s q = %d: clamped table's albedo outside [0, 1] on %.2f %% of the hull (unclamped %.2f %%); "
                    "kappa %.3g; next to a material the table jumps by %.3g (median, max %.3g)", candidate, q,
                    100 * row["albedo_clamped_bad_hull"], 100 * row["albedo_bad_hull"], row["kappa"],
                    row["jump_nn_median_1e-6"], row["jump_nn_max_1e-6"])
    _write_csv(spaces_out, tables.SPACES, rows)
    _write_csv(stability_out, tables.STABILITY, stab)
    return rows


def _read_rows(path: str | os.PathLike[str], columns: Sequence[str]) -> list[list[str]]:
    r = list(csv.reader(io.StringIO(integrity.read_csv_text(path), newline="")))  # its digest checked
    if not r or tuple(r[0]) != tuple(columns):
        raise ValueError(f"{path}: not a table with columns {', '.join(columns)}")
    return r[1:]


def combine_candidates(
    *,
    spaces: Sequence[str | os.PathLike[str]],
    stability: Sequence[str | os.PathLike[str]],
    spaces_out: str | os.PathLike[str],
    stability_out: str | os.PathLike[str],
) -> None:
    """The workflow's ``compare_spaces`` job: the candidates' tables, one after another, in one table each.

    ValueError naming a file whose header is not :data:`~brdfpipe.registry.tables.SPACES` /
    :data:`~brdfpipe.registry.tables.STABILITY` or that repeats a row (candidate, q[, norm, ε]),
    or when not exactly one candidate is the default.
    """
    texts: list[tuple[str | os.PathLike[str], str]] = []
    for files, columns, out in ((spaces, tables.SPACES, spaces_out), (stability, tables.STABILITY, stability_out)):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(columns)
        defaults = set()
        seen: set[tuple[str, ...]] = set()
        key = [columns.index(c) for c in ("candidate", "q") + (("norm", "epsilon") if columns is tables.STABILITY else ())]
        for f in files:
            rows = _read_rows(f, columns)
            for r in rows:
                k = tuple(r[i] for i in key)
                if k in seen:
                    raise ValueError(f"{f}: a second row for {', '.join(k)}")
                seen.add(k)
            if columns is tables.SPACES:
                defaults |= {r[1] for r in rows if r[columns.index("default")] == "true"}
            w.writerows(rows)
        if columns is tables.SPACES and len(defaults) != 1:
            raise ValueError(f"expected exactly one default candidate among {len(files)} tables, found {sorted(defaults)}")
        texts.append((out, buf.getvalue()))
    for out, text in texts:  # both checked before either is written
        integrity.write_csv(Path(out), text)
