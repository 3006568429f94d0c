"""The interpolant and the bound of eq. 7 as the kernel's length scale shrinks (Soler et al. 2018 §4.1, Fig. 6).

Eq. 7 bounds how far the interpolant ``z* = Σ wᵢ(x*) zᵢ`` strays from the
training material ``z_j`` nearest ``x*`` in latent space::

    ‖z* − z_j‖ ≤ e^{−1/2} √(2N)/ℓ · κ(K) · ‖Z‖ · ‖x* − x_j‖

and the paper reads it at both ends of ℓ: "choosing ℓ to be very small or
very large causes the maximum deviation to worsen", and as ℓ → 0 "the
interpolated BRDF is the average of all measurements everywhere in the
domain except very close to the xᵢ (See Fig. 6)".  Only the ratio of the
latent spacing to ℓ matters (§3: scaling ℓ and the xᵢ together changes
nothing), so :func:`lengthscale_rows` keeps a fitted model's latent points
and scales its ℓ by the factors :data:`LENGTH_SCALE_FACTORS`; for each it
forms ``K(ℓ) = μI + exp(−‖xᵢ − xⱼ‖²/2ℓ²)`` (eq. 5, the model's μ), the
weights ``w = b + (1 − Σb)/N`` with ``b = K⁻¹k(x*)`` (the δ convention of
:func:`brdfpipe.manifold.likelihood.kernel_vector`: at a training point itself
the weights are that material's) at :data:`PROFILE_STEPS` + 1 points of a
latent path, and from the centred Gram matrix ``G_c`` of the data (exact, no
table formed):

* ``deviation`` = ‖z* − z_j‖ = √((w − e_j)ᵀ G_c (w − e_j))
  (:func:`brdfpipe.manifold.analysis.deviation`), j the nearest training
  point in latent space (the paper's β(x*) "most of the time");
* ``bound`` = the right-hand side of eq. 7 with κ the 2-norm condition
  number of K(ℓ) and ‖Z‖ = √tr G_c (the centred data the GP interpolates,
  as :func:`brdfpipe.manifold.analysis.eq7_bound`);
* ``from_mean`` = ‖z* − z̄‖ = √(wᵀ G_c w) (Σw = 1): 0 where the interpolant
  is the mean of the materials.

The values are in the data units of the Gram file (the default candidate's
data space); the figure divides them by ‖Z‖.  Written to
``results/manifold/lengthscales.csv`` (:data:`brdfpipe.registry.tables.LENGTHSCALES`)
by the workflow's ``measure_lengthscales`` job (:func:`measure_lengthscales`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from typing import Any, Final

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.manifold import gplvm
from brdfpipe.manifold.analysis import deviation
from brdfpipe.manifold.gram import load_gram
from brdfpipe.manifold.likelihood import kernel_matrix, kernel_vector
from brdfpipe.registry import tables
from brdfpipe.registry.manifold import check_paths, path_name

__all__ = [
    "LENGTH_SCALE_FACTORS",
    "PROFILE_STEPS",
    "lengthscale_rows",
    "measure_lengthscales",
]

logger = logging.getLogger("brdfpipe.manifold.lengthscale")

#: ℓ / ℓ_fit of the kernels compared: from 1/32 of the fitted length scale (the paper's ℓ → 0) to 4 times it.
LENGTH_SCALE_FACTORS: Final[tuple[float, ...]] = (1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0)
#: Equal steps along the path (the profile is exact from the Gram matrix: no table is formed).
PROFILE_STEPS: Final = 100


def _kernel_factor(X: NDArray[np.float64], ell: float, mu: float) -> tuple[tuple[NDArray[np.float64], bool], float]:
    """Cholesky factor of K(ℓ) (eq. 5) and its 2-norm condition number."""
    K = kernel_matrix(X, ell, mu)
    lam = np.linalg.eigvalsh(K)
    return scipy.linalg.cho_factor(K, lower=True), float(lam[-1] / lam[0])


def lengthscale_rows(
    model: gplvm.GplvmModel,
    gram: ArrayLike,
    a: str,
    b: str,
    *,
    factors: Sequence[float] = LENGTH_SCALE_FACTORS,
    steps: int = PROFILE_STEPS,
) -> list[dict[str, Any]]:
    """One row per factor of ℓ and point of the latent path ``a → b`` (see the module docstring).

    ``gram``: the centred Gram matrix of the data the model was fitted on
    (its materials in the model's order).  Row keys: the columns of
    :data:`~brdfpipe.registry.tables.LENGTHSCALES` but ``database``, ``space`` and ``q``.
    """
    names = list(model.names)
    check_paths([(a, b)], names, what="path")
    g = np.asarray(gram, dtype=np.float64)
    n = len(names)
    if g.shape != (n, n):
        raise ValueError(f"gram has shape {g.shape}, expected ({n}, {n}) for the model's materials")
    if steps < 1 or not factors or any(not np.isfinite(f) or f <= 0 for f in factors):
        raise ValueError(f"need steps >= 1 and positive finite factors, got {steps}, {list(factors)}")
    X = np.asarray(model.X, dtype=np.float64)
    xa, xb = X[names.index(a)], X[names.index(b)]
    z_norm = float(np.sqrt(max(np.trace(g), 0.0)))
    ts = np.arange(steps + 1) / steps
    pts = (1.0 - ts)[:, None] * xa + ts[:, None] * xb
    pts[0], pts[-1] = xa, xb  # bitwise the materials' points: the δ convention holds at the ends
    nearest = [int(np.argmin(((X - x) ** 2).sum(axis=1))) for x in pts]
    rows: list[dict[str, Any]] = []
    for f in factors:
        ell = float(f) * float(model.ell)
        cf, kappa = _kernel_factor(X, ell, float(model.mu))
        for t, x, j in zip(ts, pts, nearest):
            bvec = scipy.linalg.cho_solve(cf, kernel_vector(X, x, ell, float(model.mu)))
            w = gplvm.blend_weights(bvec)
            dist = float(np.linalg.norm(x - X[j]))
            rows.append({
                "path": path_name(a, b), "material_a": a, "material_b": b, "ell_factor": float(f), "ell": ell,
                "kappa": kappa, "t": float(t), "nearest": names[j], "latent_distance_nearest": dist,
                "deviation": deviation(g, w, j),
                "bound": float(np.exp(-0.5) * np.sqrt(2.0 * n) / ell * kappa * z_norm * dist),
                "from_mean": float(np.sqrt(max(float(w @ g @ w), 0.0))),
                "sum_abs_w": float(np.abs(w).sum()), "z_norm": z_norm,
            })
        logger.info("ℓ = %.4g (× %g): κ(K) = %.4g", ell, f, kappa)
    return rows


def measure_lengthscales(
    *,
    model: str | os.PathLike[str],
    gram: str | os.PathLike[str],
    path: Sequence[str],
    out: str | os.PathLike[str],
    database: str,
) -> list[dict[str, Any]]:
    """The workflow's ``measure_lengthscales`` job: :func:`lengthscale_rows` of ``path`` written to ``out``.

    ``model``: the default candidate's fit at the rendering track's q;
    ``gram``: the Gram file of its data space (its materials must be the
    model's, in order: ValueError naming both otherwise); ``database``: the
    run's database label (a column of the CSV).  Returns the rows.
    """
    m = gplvm.load_model(model)
    G, _, info = load_gram(gram)
    if tuple(info.materials) != tuple(m.names) or info.space != m.space:
        raise ValueError(f"{gram}: its materials or data space ({info.space}) differ from those of {model} "
                         f"({m.space})")
    if len(path) != 2:
        raise ValueError(f"path must be a pair of materials, got {list(path)!r}")
    rows = [{"database": database, "space": m.space, "q": int(m.X.shape[1]), **r}
            for r in lengthscale_rows(m, G, str(path[0]), str(path[1]))]
    integrity.write_csv(out, [tables.LENGTHSCALES, *([_fmt(r[c]) for c in tables.LENGTHSCALES] for r in rows)])
    logger.info("eq. 7 against ℓ along %s: %d rows -> %s", path_name(str(path[0]), str(path[1])), len(rows), out)
    return rows


def _fmt(v: Any) -> str:
    return format(float(v), ".10g") if isinstance(v, (float, np.floating)) else str(v)
