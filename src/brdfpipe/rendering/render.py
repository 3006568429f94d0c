"""A ``merl`` BSDF for Mitsuba 3: measured (MERL-format) BRDFs in a path tracer.

The plugin renders any table of :mod:`brdfpipe.data.merl` (a ``.binary`` file read
with :func:`brdfpipe.data.merl.read_merl`) in Mitsuba 3's JIT variants
(:data:`VARIANTS`)::

    from brdfpipe.rendering import render
    render.use_variant("llvm_ad_rgb")      # or "cuda_ad_rgb" on a GPU
    render.register_merl_bsdf()
    scene = mi.load_dict({..., "shape": {"type": "sphere",
                                         "bsdf": render.merl_bsdf("gold.binary")}})

Evaluation
----------
The table lives on the device as one flat ``Float`` array of 3 × 1,458,000
values in physical units (sr⁻¹), *cell-major* (the three channels of a cell
are adjacent, so one :func:`drjit.gather` of a ``Color3f`` fetches them);
unmeasured (negative) cells are stored as 0, so they evaluate to black.
The lookup reproduces :func:`brdfpipe.data.merl.lookup` exactly (nearest cell;
half vector, rotation of the incident direction into the half-vector frame,
square-root binning of θh, φd folded to [0, π), clamped indices); θh and θd
are computed with ``atan2`` rather than ``acos``, which keeps single
precision accurate near θ = 0, where MERL's first θh bin is only 0.011° wide.
Mitsuba's ``si.wi`` plays MERL's light direction; the table is reciprocal
by construction (swapping the directions maps φd to φd + π, which folds onto
the same cell), so the choice does not matter.  The back side (cos θi ≤ 0
or cos θo ≤ 0) is black; wrap the BSDF in ``twosided`` for open surfaces.
``eval`` returns f · cos θo, as Mitsuba expects.

Importance sampling
-------------------
Each material gets, once at load time (numpy/scipy, deterministic), a mixture of cosine-hemisphere sampling and one or two GGX
lobes sampled through their visible normals
(:class:`mitsuba.MicrofacetDistribution`)::

    p(wo) = w_cos · cos θo / π + Σ_k w_k · G1(wi; α_k) D(h; α_k) / (4 cos θi)

``sample`` picks the component with ``sample1`` and the direction with
``sample2``; ``pdf`` returns exactly this mixture density (χ²-tested at
10°, 45° and 75° on five materials).  The parameters minimise what sampling
should make small, measured on the table itself: the relative variance
``Var[f cos θo / p] / E[f cos θo / p]²`` of the one-sample estimator of the
directional albedo, averaged over six incident angles (5°, 20°, …, 80°) and
computed by quadrature over half vectors (MERL's square-root θh grid × 64 φh
steps).  One lobe: grid search over α (48 log-spaced values in [0.004, 1])
and w_cos (≥ 2 %, so ``f cos θo / p`` stays bounded where the lobe misses),
refined by Nelder–Mead; then a second lobe (Nelder–Mead over both α and the
three weights, four starts), kept only if it lowers the variance by more than
5 % (:data:`TWO_LOBE_GAIN`).  A pure diffuse table fits w_cos = 1 (cosine
sampling only); an all-zero table falls back to it.

Measured relative variance (mean over the six angles; 0 is perfect
importance sampling; printed by ``benches/bench_render.py`` [4]; tabulated
Mitsuba BSDFs and ``brdfpipe.data.synth.plan_database(100, 0)`` materials):

==============================  =======  ========  ==========  ===========  ========================
table                           cosine   best GGX  fit 1 lobe  fit 2 lobes  used
==============================  =======  ========  ==========  ===========  ========================
roughconductor GGX α 0.1 Au     61.3     0.022     0.024       0.024        α 0.097, w_cos 0.02
roughconductor Beckmann 0.1 Au  109      0.229     0.251       0.251        α 0.083
roughplastic GGX α 0.2          2.79     0.523     0.065       0.065        α 0.169, w_cos 0.75
diffuse 0.5                     1e-5     0.595     1e-5        1e-5         cosine only
synth metal-nickel-006 (haze)   358      0.115     0.091       0.031        α 0.031 + 0.101
synth metallic-paint-blue-055   119      0.747     0.101       0.088        α 0.056 + 0.135
synth phenolic-black-085        802      1.31      0.122       0.080        α 0.025 + 0.108
synth paint-red-plastic-040     74.7     1.03      0.142       0.142        α 0.089, w_cos 0.43
synth fabric-green-velvet-070   0.29     0.889     0.290       0.290        w_cos 0.97
==============================  =======  ========  ==========  ===========  ========================

The mixture is within 10 % of the best pure GGX lobe on metals (the 2 %
cosine share costs ≈ 0.02) and 3–11× better on everything with a diffuse
part (exact for a Lambertian table); the second lobe divides the variance of
hazy metals and layered materials by up to 3 and changes nothing elsewhere.  In a path tracer
(bench, 160 × 120, two spheres on a floor, ``max_depth`` 4) the tabulated
GGX gold renders with 1.01× the RMSE of Mitsuba's own ``roughconductor``
at 16 spp, and runs at 0.78–0.82× the throughput of ``roughplastic`` (2 shared
cores; the gap is the cell index — three ``atan2`` — and cache misses in
the 17.5 MB table, which a built-in BSDF's closed form does not have).

The plugin class, ``brdfpipe.rendering.render.MerlBSDF`` (a subclass of the current
variant's ``mi.BSDF``), is created on first access after :func:`use_variant`,
so importing this module never touches a Mitsuba backend; it is therefore
not in ``__all__``.

Tabulation
----------
:func:`tabulate_bsdf` evaluates any Mitsuba BSDF at the cell centres
(:func:`brdfpipe.data.merl.cell_directions`) and divides out cos θo, giving a MERL
table of it (cells with a direction below the horizon are negative, like
MERL's unmeasured cells); :func:`lambertian_table` is an exact Lambertian
table (a/π in every cell) for furnace tests.
"""

from __future__ import annotations

import math
import os
import threading
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.data import merl

__all__ = [
    "VARIANTS",
    "RenderError",
    "use_variant",
    "current_variant",
    "set_cpu_threads",
    "register_merl_bsdf",
    "merl_bsdf",
    "SamplingFit",
    "fit_sampling",
    "sampling_report",
    "tabulate_bsdf",
    "lambertian_table",
]

#: The Mitsuba variants the plugin supports (JIT, RGB).
VARIANTS: Final = ("llvm_ad_rgb", "cuda_ad_rgb")

PLUGIN_NAME: Final = "merl"

# Sampling fit: incident angles, φh steps, candidate α and cosine weights.
FIT_THETA_I_DEG: Final = (5.0, 20.0, 35.0, 50.0, 65.0, 80.0)
_FIT_N_PHI: Final = 64
_ALPHA_GRID: Final = np.geomspace(0.004, 1.0, 48)
_W_COS_MIN: Final = 0.02
_W_COS_GRID: Final = np.concatenate(
    [np.linspace(_W_COS_MIN, 0.2, 10), np.linspace(0.25, 1.0, 16)]
)
#: A second GGX lobe is kept only if it lowers the fitted variance by more than this fraction.
TWO_LOBE_GAIN: Final = 0.05
_ALPHA_FALLBACK: Final = 0.5  # α of the (unused) lobe of an all-zero or pure diffuse table

_CACHE_SIZE: Final = 4  # tables kept in memory (path, mtime, size) → (table, fit)
_HALF_PI: Final = 0.5 * math.pi


class RenderError(RuntimeError):
    """A rendering set-up problem (variant, plugin, file); the message says which."""


# --------------------------------------------------------------------------
# Variant and registration
# --------------------------------------------------------------------------

_registered: set[str] = set()
_lock = threading.Lock()


def set_cpu_threads(threads: int) -> None:
    """Limit Dr.Jit's CPU (LLVM backend) thread pool to ``threads`` (≥ 1).

    Without it a render job uses every core of its node, whatever the
    workflow declared; the CUDA backend is unaffected.  With ``threads = 1``
    (Dr.Jit then has no worker thread) scenes must be loaded with
    :func:`load_scene`: Mitsuba's environment-map emitter never finishes
    loading without a worker (Mitsuba 3.9 / Dr.Jit 1.5, LLVM backend).
    """
    import drjit as dr

    if int(threads) < 1:
        raise ValueError(f"threads must be ≥ 1, got {threads}")
    dr.set_thread_count(int(threads))


def load_scene(scene: Mapping[str, Any]) -> Any:
    """``mitsuba.load_dict(scene)`` with at least one Dr.Jit worker thread while it loads.

    Loading an ``envmap`` emitter with Dr.Jit's worker pool disabled
    (``set_cpu_threads(1)``, as Snakemake sets for a rule's job on one core)
    hangs forever in Mitsuba 3.9; rendering with one thread works.  So the
    pool is raised to 2 threads (the caller plus one worker) for the load only
    and put back before rendering.
    """
    import drjit as dr
    import mitsuba as mi

    before = dr.thread_count()
    if before < 2:
        dr.set_thread_count(2)
    try:
        return mi.load_dict(dict(scene))
    finally:
        if before < 2:
            dr.set_thread_count(before)


def use_variant(variant: str) -> None:
    """Set Mitsuba's variant to ``variant`` (one of :data:`VARIANTS`).

    Raises :class:`RenderError` naming the variant and the allowed ones if it
    is not supported here, or if its backend is not available on this machine
    (e.g. ``cuda_ad_rgb`` without a CUDA GPU, ``llvm_ad_rgb`` without
    libLLVM).  The previous variant stays set on failure.
    """
    if variant not in VARIANTS:
        raise RenderError(
            f"unsupported Mitsuba variant {variant!r}; the merl plugin supports {', '.join(VARIANTS)}"
        )
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - mitsuba is a dependency
        raise RenderError(f"cannot use variant {variant!r}: Mitsuba is not importable ({exc})") from exc
    backend = dr.JitBackend.CUDA if variant.startswith("cuda") else dr.JitBackend.LLVM
    if not dr.has_backend(backend):
        raise RenderError(
            f"Mitsuba variant {variant!r} is not available on this machine: the "
            f"{backend.name} backend of Dr.Jit could not be initialised "
            f"({'no CUDA GPU/driver' if backend == dr.JitBackend.CUDA else 'libLLVM not found'}); "
            f"supported variants: {', '.join(VARIANTS)}"
        )
    try:
        mi.set_variant(variant)
    except (ImportError, AttributeError, RuntimeError) as exc:
        raise RenderError(
            f"Mitsuba variant {variant!r} could not be set ({exc}); supported variants: "
            f"{', '.join(VARIANTS)}"
        ) from exc


class _NoVariantError(RenderError, AttributeError):
    """No supported variant is set (an AttributeError too, for ``render.MerlBSDF``)."""


def current_variant() -> str:
    """The Mitsuba variant now set, if it is one of :data:`VARIANTS`; otherwise an error saying to call :func:`use_variant`."""
    import mitsuba as mi

    variant = mi.variant()
    if variant not in VARIANTS:
        now = "no Mitsuba variant is set" if variant is None else f"the current Mitsuba variant is {variant!r}"
        raise _NoVariantError(
            f"{now}; call brdfpipe.rendering.render.use_variant() with one of {', '.join(VARIANTS)} first"
        )
    return variant


def register_merl_bsdf() -> None:
    """Register the ``merl`` plugin with Mitsuba for the current variant.

    Call after :func:`use_variant`.  Idempotent: registering twice for the
    same variant does nothing; after a variant change it registers the class
    of the new variant.
    """
    import mitsuba as mi

    variant = current_variant()
    with _lock:
        if variant in _registered:
            return
        cls = _merl_class(variant)
        mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
        _registered.add(variant)


def merl_bsdf(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The :func:`mitsuba.load_dict` entry of a ``merl`` BSDF reading ``path``."""
    return {"type": PLUGIN_NAME, "filename": str(Path(path))}


def __getattr__(name: str) -> Any:
    # ``MerlBSDF`` subclasses the current variant's ``mi.BSDF``, so it is
    # created on first access (after use_variant), not at import.
    if name == "MerlBSDF":
        return _merl_class(current_variant())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# --------------------------------------------------------------------------
# Loading tables (cached) and fitting the sampling mixture
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class SamplingFit:
    """The importance-sampling mixture of one material.

    ``p(wo) = w_cos · cos θo / π + Σ_k weights[k] · p_GGX(wo; alphas[k])`` with
    ``w_cos + Σ weights = 1``.  ``rel_variance`` is the fitted objective (mean
    relative variance of ``f cos θo / p`` over :data:`FIT_THETA_I_DEG`).
    """

    w_cos: float
    alphas: tuple[float, ...]
    weights: tuple[float, ...]
    rel_variance: float

    def describe(self) -> str:
        """One-line summary, e.g. ``w_cos=0.04 GGX(α=0.102, w=0.96) var=0.058``."""
        lobes = " ".join(f"GGX(α={a:.3g}, w={w:.3g})" for a, w in zip(self.alphas, self.weights))
        return f"w_cos={self.w_cos:.3g} {lobes} var={self.rel_variance:.3g}"


@dataclass(frozen=True)
class _FitGeometry:
    """Quadrature over half vectors for each fit incident angle (table-independent)."""

    cells: NDArray[np.intp]  # (n,) cell index of each node
    angle: NDArray[np.intp]  # (n,) which incident angle
    cos_o: NDArray[np.float64]  # (n,)
    d_omega: NDArray[np.float64]  # (n,) solid angle of wo per node
    cos_h: NDArray[np.float64]  # (n,)
    theta_i: NDArray[np.float64]  # (n_angles,)


@lru_cache(maxsize=4)
def _fit_geometry(theta_i_deg: tuple[float, ...] = FIT_THETA_I_DEG) -> _FitGeometry:
    n_h = merl.N_THETA_H
    u = (np.arange(n_h) + 0.5) / n_h
    th = u * u * _HALF_PI
    w_th = np.pi * u / n_h * np.sin(th)  # dθh sin θh on the square-root grid
    ph = (np.arange(_FIT_N_PHI) + 0.5) / _FIT_N_PHI * 2.0 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    dwh = np.broadcast_to(w_th[:, None] * (2.0 * np.pi / _FIT_N_PHI), TH.shape).ravel()
    h = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    parts: list[tuple[NDArray[Any], ...]] = []
    theta_i = np.radians(np.asarray(theta_i_deg, dtype=np.float64))
    for k, t in enumerate(theta_i):
        wi = np.array([np.sin(t), 0.0, np.cos(t)])
        cih = h @ wi
        wo = 2.0 * cih[:, None] * h - wi
        ok = (cih > 0.0) & (wo[:, 2] > 0.0)
        cells = merl.cell_index(np.broadcast_to(wi, (int(ok.sum()), 3)), wo[ok])
        parts.append(
            (cells, np.full(cells.size, k), wo[ok, 2], 4.0 * cih[ok] * dwh[ok], h[ok, 2])
        )
    cat = [np.concatenate(p) for p in zip(*parts)]
    return _FitGeometry(cat[0], cat[1], cat[2], cat[3], cat[4], theta_i)


def _ggx_pdf(
    cos_h: NDArray[np.float64], cos_i: NDArray[np.float64], alpha: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Density over wo of GGX visible-normal sampling, (len(alpha), n) (Mitsuba's convention).

    ``p(wo) = G1(wi) D(h) / (4 cos θi)`` with the Smith G1 of GGX; ``cos_h``
    and ``cos_i`` are per node.
    """
    a2 = np.asarray(alpha, dtype=np.float64)[:, None] ** 2
    d = a2 / (np.pi * ((a2 - 1.0) * (cos_h * cos_h)[None, :] + 1.0) ** 2)
    tan2 = ((1.0 - cos_i * cos_i) / (cos_i * cos_i))[None, :]
    g1 = 2.0 / (1.0 + np.sqrt(1.0 + a2 * tan2))
    return d * g1 / (4.0 * cos_i[None, :])


def _scalar_brdf(table: NDArray[np.floating]) -> NDArray[np.float64]:
    """Channel mean of a (3, N_CELLS) table with negative cells as 0, (N_CELLS,)."""
    return np.maximum(np.asarray(table, dtype=np.float64), 0.0).reshape(3, merl.N_CELLS).mean(axis=0)


class _FitProblem:
    """The variance objective of one table on the fit quadrature (nodes with f > 0 only)."""

    def __init__(self, table: NDArray[np.floating]) -> None:
        geo = _fit_geometry()
        g = _scalar_brdf(table)[geo.cells] * geo.cos_o
        self.n_angles = geo.theta_i.size
        self.albedo = np.bincount(geo.angle, weights=g * geo.d_omega, minlength=self.n_angles)
        keep = g > 0.0
        self.g2 = g[keep] ** 2 * geo.d_omega[keep]
        self.angle = geo.angle[keep]
        self.p_cos = geo.cos_o[keep] / np.pi
        self.cos_h = geo.cos_h[keep]
        self.cos_i = np.cos(geo.theta_i)[self.angle]
        self.theta_i = geo.theta_i
        self._groups, self._starts = np.unique(self.angle, return_index=True)

    @property
    def empty(self) -> bool:
        return not bool((self.albedo > 0.0).any())

    def p_ggx(self, alpha: ArrayLike) -> NDArray[np.float64]:
        return _ggx_pdf(self.cos_h, self.cos_i, np.atleast_1d(np.asarray(alpha, dtype=np.float64)))

    def rel_variance(self, pdf: NDArray[np.float64]) -> NDArray[np.float64]:
        """Relative variance per angle for candidate densities ``pdf`` (m, n) → (m, n_angles)."""
        with np.errstate(divide="ignore"):
            ratio = self.g2 / np.atleast_2d(pdf)
        second = np.zeros((ratio.shape[0], self.n_angles))
        # nodes are grouped by angle (contiguous), so one reduceat sums every group
        second[:, self._groups] = np.add.reduceat(ratio, self._starts, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.albedo > 0.0, second / self.albedo**2 - 1.0, 0.0)

    def mixture(self, w_cos: float, alphas: tuple[float, ...], weights: tuple[float, ...]) -> NDArray[np.float64]:
        pdf = w_cos * self.p_cos
        if alphas:
            pdf = pdf + np.asarray(weights, dtype=np.float64) @ self.p_ggx(alphas)
        return pdf

    def objective(self, w_cos: float, alphas: tuple[float, ...], weights: tuple[float, ...]) -> float:
        return float(self.rel_variance(self.mixture(w_cos, alphas, weights)[None, :])[0].mean())


def _sigmoid(t: float) -> float:
    return 1.0 / (1.0 + math.exp(-t)) if t >= 0 else math.exp(t) / (1.0 + math.exp(t))


def _logit(p: float) -> float:
    p = min(max(p, 1e-6), 1.0 - 1e-6)
    return math.log(p / (1.0 - p))


def _softmax(t: NDArray[np.float64]) -> NDArray[np.float64]:
    e = np.exp(t - t.max())
    return e / e.sum()


def _clip_alpha(log_alpha: float) -> float:
    return float(np.clip(math.exp(log_alpha), _ALPHA_GRID[0], _ALPHA_GRID[-1]))


def _fit_one_lobe(prob: _FitProblem) -> SamplingFit:
    """Grid over (α, w_cos), then Nelder–Mead refinement of (log α, logit w_cos)."""
    p_ggx = prob.p_ggx(_ALPHA_GRID)
    wc = _W_COS_GRID[:, None]
    best = (math.inf, 1.0, _ALPHA_FALLBACK)
    for j, alpha in enumerate(_ALPHA_GRID):
        v = prob.rel_variance(wc * prob.p_cos[None, :] + (1.0 - wc) * p_ggx[j][None, :]).mean(axis=1)
        i = int(np.argmin(v))
        if v[i] < best[0] - 1e-12:
            best = (float(v[i]), float(_W_COS_GRID[i]), float(alpha))
    var, w_cos, alpha = best
    if w_cos >= 1.0:  # pure diffuse: no lobe needed
        return SamplingFit(1.0, (_ALPHA_FALLBACK,), (0.0,), var)
    from scipy.optimize import minimize

    def unpack(x: NDArray[np.float64]) -> tuple[float, float]:
        return _W_COS_MIN + (1.0 - _W_COS_MIN) * _sigmoid(float(x[1])), _clip_alpha(float(x[0]))

    def f(x: NDArray[np.float64]) -> float:
        c, a = unpack(x)
        return prob.objective(c, (a,), (1.0 - c,))

    x0 = np.array([math.log(alpha), _logit((w_cos - _W_COS_MIN) / (1.0 - _W_COS_MIN))])
    res = minimize(f, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-5, "maxiter": 200})
    if float(res.fun) < var:
        w_cos, alpha = unpack(res.x)
        var = float(res.fun)
    return SamplingFit(w_cos, (alpha,), (1.0 - w_cos,), var)


def _fit_two_lobes(prob: _FitProblem, one: SamplingFit) -> SamplingFit:
    """Nelder–Mead over (log α1, log α2, two softmax logits) from a few starts."""
    from scipy.optimize import minimize

    def unpack(x: NDArray[np.float64]) -> tuple[float, tuple[float, float], tuple[float, float]]:
        s = _softmax(np.array([x[2], x[3], 0.0]))
        c = _W_COS_MIN + (1.0 - _W_COS_MIN) * float(s[0])
        rest = 1.0 - c
        w = float(s[1]) / max(float(s[1] + s[2]), 1e-300)
        return c, (_clip_alpha(float(x[0])), _clip_alpha(float(x[1]))), (rest * w, rest * (1.0 - w))

    def f(x: NDArray[np.float64]) -> float:
        return prob.objective(*unpack(x))

    best = one
    a1 = one.alphas[0]
    for a2, w2 in ((3.0 * a1, 0.1), (6.0 * a1, 0.1), (a1 / 3.0, 0.3), (3.0 * a1, 0.3)):
        c = max(one.w_cos, _W_COS_MIN + 1e-3)
        s0 = (c - _W_COS_MIN) / (1.0 - _W_COS_MIN)
        s1 = (1.0 - s0) * (1.0 - w2)
        s2 = (1.0 - s0) * w2
        x0 = np.array([math.log(a1), math.log(a2), math.log(s0 / s2), math.log(s1 / s2)])
        res = minimize(f, x0, method="Nelder-Mead", options={"xatol": 1e-2, "fatol": 1e-4, "maxiter": 400})
        if float(res.fun) < best.rel_variance:
            c, alphas, weights = unpack(res.x)
            best = SamplingFit(c, alphas, weights, float(res.fun))
    return best


def fit_sampling(table: ArrayLike, n_lobes: int = 2) -> SamplingFit:
    """Fit the cosine + GGX sampling mixture of a ``(3, 90, 90, 180)`` table.

    Minimises the mean relative variance of ``f cos θo / p`` (see the module
    docstring) over α and the cosine weight (≥ 2 %): a grid search, refined
    by Nelder–Mead; with ``n_lobes=2`` (the default) a second GGX lobe is
    then fitted (Nelder–Mead over both α and the three weights, from four
    starts) and kept only if it lowers the objective by more than
    :data:`TWO_LOBE_GAIN`.  Deterministic.  A pure diffuse table gives
    ``w_cos = 1``; an all-zero table pure cosine sampling.
    """
    if n_lobes not in (1, 2):
        raise ValueError(f"n_lobes must be 1 or 2, got {n_lobes}")
    arr = np.asarray(table)
    if arr.shape != merl.SHAPE:
        raise ValueError(f"table has shape {arr.shape}, expected {merl.SHAPE}")
    prob = _FitProblem(arr)
    if prob.empty:
        return SamplingFit(1.0, (_ALPHA_FALLBACK,), (0.0,), 0.0)
    one = _fit_one_lobe(prob)
    if n_lobes == 1 or one.w_cos >= 1.0:
        return one
    two = _fit_two_lobes(prob, one)
    return two if two.rel_variance < (1.0 - TWO_LOBE_GAIN) * one.rel_variance else one


def sampling_report(table: ArrayLike) -> dict[str, float]:
    """Mean relative variance of the strategies compared in the module docstring.

    Keys: ``cosine``, ``ggx_only`` (best pure GGX α on the grid), ``fitted``
    (the one-lobe mixture), ``two_lobes`` (the two-lobe fit, before the
    :data:`TWO_LOBE_GAIN` test of :func:`fit_sampling`) and the one-lobe
    ``alpha`` / ``w_cos``.
    """
    arr = np.asarray(table)
    prob = _FitProblem(arr)
    if prob.empty:
        return {"cosine": 0.0, "ggx_only": 0.0, "fitted": 0.0, "two_lobes": 0.0,
                "alpha": _ALPHA_FALLBACK, "w_cos": 1.0}
    one = _fit_one_lobe(prob)
    two = _fit_two_lobes(prob, one) if one.w_cos < 1.0 else one
    ggx = float(prob.rel_variance(prob.p_ggx(_ALPHA_GRID)).mean(axis=1).min())
    return {
        "cosine": prob.objective(1.0, (), ()),
        "ggx_only": ggx,
        "fitted": one.rel_variance,
        "two_lobes": two.rel_variance,
        "alpha": one.alphas[0],
        "w_cos": one.w_cos,
    }


def _device_layout(table: NDArray[np.floating]) -> NDArray[np.float32]:
    """Cell-major float32 copy of a physical table, negative cells → 0, (3 · N_CELLS,)."""
    flat = np.asarray(table, dtype=np.float64).reshape(3, merl.N_CELLS)
    return np.ascontiguousarray(np.maximum(flat, 0.0).T, dtype=np.float32).ravel()


def _fit_of_device_table(values: Any) -> SamplingFit:
    """The sampling fit of a device table (the flat cell-major ``Float`` of :func:`_device_layout`).

    RenderError unless it holds 3 · N_CELLS values (a ``table`` parameter set through ``traverse``).
    """
    table = np.asarray(values.numpy(), dtype=np.float64)
    if table.size != 3 * merl.N_CELLS:
        raise RenderError(
            f"merl: parameter 'table' must hold {3 * merl.N_CELLS} values, got {table.size}"
        )
    return fit_sampling(table.reshape(merl.N_CELLS, 3).T.reshape(merl.SHAPE))


_table_cache: OrderedDict[tuple[str, int, int], tuple[NDArray[np.float32], SamplingFit]] = OrderedDict()


def _load(path: Path) -> tuple[NDArray[np.float32], SamplingFit]:
    """Device layout and sampling fit of a MERL file (small LRU cache on path/mtime/size)."""
    try:
        st = path.stat()
    except OSError as exc:
        raise RenderError(f"merl: cannot read MERL file {path}: {exc.strerror or exc}") from exc
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    with _lock:
        hit = _table_cache.get(key)
        if hit is not None:
            _table_cache.move_to_end(key)
            return hit
    try:
        table = merl.read_merl(path)
    except (OSError, ValueError) as exc:
        why = str(exc) if str(path) in str(exc) else f"{path}: {exc}"
        raise RenderError(f"merl: cannot load MERL file {why}") from exc
    entry = (_device_layout(table), fit_sampling(table))
    with _lock:
        _table_cache[key] = entry
        while len(_table_cache) > _CACHE_SIZE:
            _table_cache.popitem(last=False)
    return entry


def _resolve(filename: str) -> Path:
    """Resolve a relative file name with Mitsuba's file resolver (scene folder), if any."""
    path = Path(filename)
    if path.is_absolute() or path.exists():
        return path
    try:
        import mitsuba as mi

        resolved = Path(str(mi.file_resolver().resolve(str(path))))
        return resolved if resolved.exists() else path
    except Exception:  # noqa: BLE001 - resolver missing in this build: keep the name
        return path


# --------------------------------------------------------------------------
# The plugin (Dr.Jit, traced: no Python loops over rays, no numpy)
# --------------------------------------------------------------------------


def _cell_index_jit(mi: Any, dr: Any, wi: Any, wo: Any) -> Any:
    """Flat MERL cell index (UInt32) of direction pairs, as :func:`brdfpipe.data.merl.cell_index`."""
    h = dr.normalize(wi + wo)
    sin_h = dr.sqrt(dr.fma(h.x, h.x, h.y * h.y))
    theta_h = dr.atan2(sin_h, h.z)
    nz = sin_h > 0.0
    inv = dr.rcp(dr.select(nz, sin_h, 1.0))
    cp = dr.select(nz, h.x * inv, 1.0)  # cos φh, sin φh (φh = 0 at the pole, like atan2(0, 0))
    sp = dr.select(nz, h.y * inv, 0.0)
    x1 = dr.fma(wi.x, cp, wi.y * sp)
    y1 = dr.fma(-wi.x, sp, wi.y * cp)
    dx = dr.fma(x1, h.z, -wi.z * sin_h)
    dz = dr.fma(x1, sin_h, wi.z * h.z)
    theta_d = dr.atan2(dr.sqrt(dr.fma(dx, dx, y1 * y1)), dz)
    phi_d = dr.atan2(y1, dx)
    phi_d = dr.select(phi_d < 0.0, phi_d + dr.pi, phi_d)
    fh = dr.sqrt(dr.maximum(theta_h, 0.0) * (1.0 / _HALF_PI)) * merl.N_THETA_H
    fd = theta_d * (merl.N_THETA_D / _HALF_PI)
    fp = phi_d * (merl.N_PHI_D / math.pi)
    ih = mi.UInt32(dr.clip(dr.floor(fh), 0.0, merl.N_THETA_H - 1.0))
    idd = mi.UInt32(dr.clip(dr.floor(fd), 0.0, merl.N_THETA_D - 1.0))
    ip = mi.UInt32(dr.clip(dr.floor(fp), 0.0, merl.N_PHI_D - 1.0))
    return (ih * merl.N_THETA_D + idd) * merl.N_PHI_D + ip


@dataclass(frozen=True)
class _DeviceMixture:
    """A :class:`SamplingFit` as the traced code of the plugin reads it (:func:`_device_mixture`).

    ``has_lobe`` and ``two_lobes`` are traced (Python-level) branches:
    pure-cosine and one-lobe tables skip the unused code.  The weights and αs
    are opaque ``Float`` (one compiled kernel serves every material of one
    lobe count); lobe 1 is chosen when ``sample1 < w_cos + w_1``.
    """

    has_lobe: bool
    two_lobes: bool
    w_cos: Any
    w_1: Any
    w_2: Any
    alpha_1: Any
    alpha_2: Any


def _device_mixture(dr: Any, mi: Any, fit: SamplingFit) -> _DeviceMixture:
    """``fit`` on the device: a missing second lobe gets weight 0, αs are at least 1e-4."""
    has_lobe = fit.w_cos < 1.0
    two_lobes = has_lobe and len(fit.alphas) == 2 and fit.weights[1] > 0.0
    weights = tuple(fit.weights) + (0.0,) * (2 - len(fit.weights))
    alphas = tuple(fit.alphas) + (fit.alphas[0],) * (2 - len(fit.alphas))
    return _DeviceMixture(
        has_lobe=has_lobe,
        two_lobes=two_lobes,
        w_cos=dr.opaque(mi.Float, fit.w_cos),
        w_1=dr.opaque(mi.Float, weights[0]),
        w_2=dr.opaque(mi.Float, weights[1]),
        alpha_1=dr.opaque(mi.Float, max(alphas[0], 1e-4)),
        alpha_2=dr.opaque(mi.Float, max(alphas[1], 1e-4)),
    )


def _mixture_pdf(dr: Any, mi: Any, mix: _DeviceMixture, wi: Any, wo: Any, active: Any) -> Any:
    """The sampling density ``p(wo)`` of the mixture (module docstring), 0 where not ``active``."""
    p_cos = mix.w_cos * mi.Frame3f.cos_theta(wo) * dr.inv_pi
    if not mix.has_lobe:
        return dr.select(active, p_cos, 0.0)
    h = dr.normalize(wi + wo)
    d1 = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, mix.alpha_1, True)
    p_ggx = mix.w_1 * d1.pdf(wi, h)
    if mix.two_lobes:
        d2 = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, mix.alpha_2, True)
        p_ggx += mix.w_2 * d2.pdf(wi, h)
    p = dr.fma(p_ggx, dr.rcp(4.0 * dr.dot(wo, h)), p_cos)
    return dr.select(active, p, 0.0)


def _table_value(dr: Any, mi: Any, table: Any, wi: Any, wo: Any, active: Any) -> Any:
    """``f(wi, wo) · cos θo`` looked up in the device ``table`` (nearest cell), 0 where not ``active``."""
    idx = _cell_index_jit(mi, dr, wi, wo)
    f = dr.gather(mi.Color3f, table, idx, active)
    return dr.select(active, f * mi.Frame3f.cos_theta(wo), 0.0)


def _sample_direction(dr: Any, mi: Any, mix: _DeviceMixture, wi: Any, sample1: Any, sample2: Any) -> Any:
    """A direction ``wo`` from the mixture: ``sample1`` picks the component, ``sample2`` the direction."""
    wo = mi.warp.square_to_cosine_hemisphere(sample2)
    if mix.has_lobe:
        alpha = mix.alpha_1
        if mix.two_lobes:
            alpha = dr.select(sample1 < mix.w_cos + mix.w_1, mix.alpha_1, mix.alpha_2)
        distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True)
        m, _ = distr.sample(wi, sample2)
        wo = dr.select(sample1 < mix.w_cos, wo, mi.reflect(wi, m))
    return wo


def _sample_mixture(dr: Any, mi: Any, mix: _DeviceMixture, table: Any, si: Any, sample1: Any,
                    sample2: Any, active: Any) -> tuple[Any, Any]:
    """``MerlBSDF.sample`` (component enabled): the ``BSDFSample3f`` and the weight ``f cos θo / p``."""
    bs = dr.zeros(mi.BSDFSample3f)
    active = mi.Bool(active) & (mi.Frame3f.cos_theta(si.wi) > 0.0)
    wo = _sample_direction(dr, mi, mix, si.wi, sample1, sample2)
    active &= mi.Frame3f.cos_theta(wo) > 0.0
    pdf = _mixture_pdf(dr, mi, mix, si.wi, wo, active)
    active &= pdf > 0.0
    value = _table_value(dr, mi, table, si.wi, wo, active)
    bs.wo = wo
    bs.pdf = dr.select(active, pdf, 0.0)
    bs.eta = 1.0
    bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
    bs.sampled_component = mi.UInt32(0)
    weight = dr.select(active, value / dr.select(active, pdf, 1.0), 0.0)
    return bs, weight


@lru_cache(maxsize=None)
def _merl_class(variant: str) -> type:
    """The ``MerlBSDF`` class for ``variant`` (the variant must be the current one).

    The class only wires the module's functions into Mitsuba's interface:
    :func:`_device_mixture` (the sampling fit on the device), :func:`_table_value`
    (the lookup), :func:`_mixture_pdf` and :func:`_sample_mixture` (sampling),
    :func:`_fit_of_device_table` (a changed ``table`` parameter).
    """
    import drjit as dr
    import mitsuba as mi

    if mi.variant() != variant:
        raise RenderError(f"variant {variant!r} is not the current Mitsuba variant ({mi.variant()!r})")

    class MerlBSDF(mi.BSDF):
        """Mitsuba BSDF ``merl``: a measured MERL-format BRDF (see :mod:`brdfpipe.rendering.render`).

        Properties: ``filename`` (string) – a MERL ``.binary`` file.  Parameters
        exposed by ``traverse``: ``table`` (flat cell-major RGB Float, physical
        units); changing it refits the sampling mixture.
        """

        def __init__(self, props: Any) -> None:
            super().__init__(props)
            if "filename" not in props:
                raise RenderError("merl: the 'filename' property (a MERL .binary file) is required")
            self.filename = str(props["filename"])
            data, fit = _load(_resolve(self.filename))
            self.m_table = mi.Float(data)
            self._set_fit(fit)
            flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        def _set_fit(self, fit: SamplingFit) -> None:
            self.fit = fit
            self.m_mix = _device_mixture(dr, mi, fit)

        def _pdf(self, wi: Any, wo: Any, active: Any) -> Any:
            return _mixture_pdf(dr, mi, self.m_mix, wi, wo, active)

        def _value(self, wi: Any, wo: Any, active: Any) -> Any:
            return _table_value(dr, mi, self.m_table, wi, wo, active)

        @staticmethod
        def _front(si: Any, wo: Any, active: Any) -> Any:
            return active & (mi.Frame3f.cos_theta(si.wi) > 0.0) & (mi.Frame3f.cos_theta(wo) > 0.0)

        # -- BSDF interface ----------------------------------------------------
        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True) -> Any:
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return dr.zeros(mi.BSDFSample3f), mi.Color3f(0.0)
            return _sample_mixture(dr, mi, self.m_mix, self.m_table, si, sample1, sample2, active)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0)
            return self._value(si.wi, wo, self._front(si, wo, mi.Bool(active)))

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Float(0.0)
            return self._pdf(si.wi, wo, self._front(si, wo, mi.Bool(active)))

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0), mi.Float(0.0)
            active = self._front(si, wo, mi.Bool(active))
            return self._value(si.wi, wo, active), self._pdf(si.wi, wo, active)

        def traverse(self, callback: Any) -> None:
            callback.put("table", self.m_table, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys: Any) -> None:
            if not keys or "table" in keys:
                self._set_fit(_fit_of_device_table(self.m_table))

        def to_string(self) -> str:
            return f"MerlBSDF[filename={self.filename!r}, sampling: {self.fit.describe()}]"

    MerlBSDF.__qualname__ = "MerlBSDF"
    MerlBSDF.__module__ = __name__
    return MerlBSDF


# --------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------


def lambertian_table(albedo: float | ArrayLike) -> NDArray[np.float64]:
    """A Lambertian MERL table: ``albedo/π`` (per channel) in *every* cell, (3, 90, 90, 180).

    No cell is negative, so nothing is lost near the horizon (for white-furnace
    tests).  ``albedo`` is a scalar or three channel values in [0, 1].
    """
    a = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (3,))
    if not np.isfinite(a).all() or (a < 0).any() or (a > 1).any():
        raise ValueError(f"albedo must lie in [0, 1], got {albedo!r}")
    return np.broadcast_to((a / np.pi)[:, None, None, None], merl.SHAPE).copy()


def tabulate_bsdf(bsdf: Any, chunk: int = 1 << 18) -> NDArray[np.float64]:
    """Tabulate a Mitsuba BSDF into a MERL table ``(3, 90, 90, 180)``, physical units.

    ``bsdf`` is a :func:`mitsuba.load_dict` dictionary or a ``mi.BSDF``
    instance (the current variant must be one of :data:`VARIANTS`).  Each cell
    holds ``eval(wi, wo) / cos θo`` at its centre directions
    (:func:`brdfpipe.data.merl.cell_directions`, ``si.wi`` = MERL's light direction);
    cells with a direction at or below the horizon hold ``-SCALES[c]``
    (raw −1, like MERL's unmeasured cells).
    """
    import drjit as dr
    import mitsuba as mi

    current_variant()
    obj = mi.load_dict(dict(bsdf)) if isinstance(bsdf, dict) else bsdf
    if not isinstance(obj, mi.BSDF):
        raise TypeError(f"expected a BSDF dictionary or instance, got {type(obj).__name__}")
    wi_all, wo_all = merl.cell_directions()
    ok = (wi_all[:, 2] > 0.0) & (wo_all[:, 2] > 0.0)
    out = np.empty((3, merl.N_CELLS))
    out[:] = -merl.SCALES[:, None]
    ctx = mi.BSDFContext()
    cells = np.flatnonzero(ok)
    for a in range(0, cells.size, chunk):
        sel = cells[a : a + chunk]
        wi, wo = wi_all[sel], wo_all[sel]
        si = dr.zeros(mi.SurfaceInteraction3f, sel.size)
        si.wi = mi.Vector3f(wi.T.astype(np.float32))
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        si.n = mi.Vector3f(0.0, 0.0, 1.0)
        value = obj.eval(ctx, si, mi.Vector3f(wo.T.astype(np.float32)))
        out[:, sel] = np.asarray(value.numpy(), dtype=np.float64).reshape(3, -1) / wo[:, 2][None, :]
    return out.reshape(merl.SHAPE)
