"""A synthetic, physically based database of MERL-format BRDFs.

The real MERL database (100 measured isotropic BRDFs, Matusik et al. 2003)
cannot be downloaded everywhere, so the pipeline can run on a synthetic
stand-in with the same format, the same family mix and measured-data-like
behaviour.  Every material is

1. an analytic, reciprocal, (approximately) energy-conserving model of one of five
   families (below), evaluated at the MERL cell centres
   (:func:`brdfpipe.data.synthmodel.evaluate`);
2. times a seeded, smooth, low-frequency multiplicative deviation
   ``exp(g(θh, θd, φd))`` over the whole (θh, θd, φd) cube, so the set is not a
   handful of analytic families (``g`` is centred to zero mean over the
   measured cells, then gains, not losses, are soft-limited:
   ``g → L·tanh(g/L)`` for ``g > 0``, ``L = 0.25``);
3. rescaled uniformly if its directional albedo
   (:func:`brdfpipe.data.merl.directional_albedo`, 46 incident angles 0 … 89.5°,
   before noise) exceeds :data:`ALBEDO_BOUND`; the scale is the record's
   ``energy_scale`` (:func:`generate_material`);
4. times log-normal measurement noise ``exp(noise·z − noise²/2)``, z ~ N(0, 1)
   independent per cell and channel (relative standard deviation ≈ ``noise``,
   mean 1);

and every cell outside :func:`brdfpipe.data.merl.measured_mask` holds
``-SCALES[c]`` (raw value −1 in the file), like MERL's unmeasured cells, except
the eight watermark cells (:data:`WATERMARK_CELLS`), which hold other negative
values that mark the file as synthetic (:func:`is_synthetic_file`).  A file
written by :func:`write_material` also carries a ``synthetic`` provenance mark
(:mod:`brdfpipe.data.provenance`: the material's name, the plan's count and
seed, the noise, …) in other unmeasurable cells of the red channel, which
binds the file to its name and configuration.

Watermark
---------
A synthetic file must never be mistaken for a measured one, even when it is
copied without its ``manifest.json``.  Cells ``iθh = 89, iθd = 89, iφd = 0 … 7``
(the first eight cells of the last θh/θd row, in every channel) are
geometrically unmeasurable: every direction pair that maps to them has its
light or its view direction below the horizon (at least 80° below, z ≤ −0.98,
when the half vector is above it; a half vector below the horizon already
means a direction below it).  Every
reader treats their negative values as unmeasured, as for any other negative
cell, so the data's meaning is unchanged.  They hold the raw values
``−(1 + b/2²⁰)`` for the bytes ``b`` of :data:`WATERMARK_MAGIC` (``b"brdfsyn1"``);
:func:`is_synthetic_file` reads just those 64 bytes of the red channel.

Families and counts
-------------------
Counts mirror MERL's mix: for 100 materials 25 ``metal``, 30 ``paint``
(paints and plastics), 12 ``metallic-paint``, 12 ``fabric`` and 21
``phenolic`` (phenolics and acrylics); other counts are apportioned in the same
proportions (largest remainder), every family present once ``count ≥ 5``.
Materials are laid out in family blocks in :data:`FAMILIES` order; names are
``<family>-<colour or metal>[-<variant>]-<index>``, e.g. ``metal-gold-005``,
``paint-red-plastic-026``, ``fabric-blue-velvet-067``.

Models: :mod:`brdfpipe.data.synthmodel`.

Parameter ranges (U: uniform, logU: log-uniform; colours are linear RGB drawn
in HSV: hue U(0, 1), saturation s, value v = largest channel; every lobe's
GGX weight t is 1 (50 %), 0 (10 %) or U(0, 1) (40 %) unless stated; ranges
tuned towards merl-nbrdf, docs/results/synthetic-vs-merl-nbrdf.md)

==================  =========================================================
metal               metal round-robin over :data:`METALS`; (n, k) × exp(N(0,
                    0.03)) each (alloy / oxide spread); α logU(0.02, 0.5); haze
                    with p = 0.5: α_haze = min(0.8, α·U(2, 5)), h U(0.05, 0.4);
                    the whole lobe × ``scale`` logU(0.05, 0.35) (merl-nbrdf's
                    metals reflect 3 to 20 % at normal incidence, not Fresnel's
                    50 to 95 %)
paint (paint /      η U(1.4, 1.6); ks U(0.5, 1); s U(0, 0.95), v logU(0.01,
plastic alternate)  0.6); σ U(0, 0.5); paint: α1 logU(0.1, 0.6), second lobe
                    with p = 0.3: α2 U(0.3, 0.6), w2 U(0.1, 0.4); plastic: α1
                    logU(0.015, 0.12), α2 logU(0.15, 0.45), w2 U(0.05, 0.5);
                    w1 = 1 − w2
metallic-paint      η U(1.45, 1.6), α_coat logU(0.015, 0.06) (GGX); c: s U(0,
                    0.9), v U(0.1, 0.7); kd U(0.02, 0.25), k1 U(0.15, 0.45), k2
                    U(0.05, 0.25), scaled so kd + k1 + k2 ≤ 0.9; α1 logU(0.06,
                    0.2), α_flake U(0.3, 0.6); c_flake = mix(c, v, U(0, 0.5))
fabric (velvet,     s U(0, 0.9), v logU(0.01, 0.45); velvet: σ U(0.2, 0.5), r
felt, satin         U(0.3, 0.7), sheen U(0.3, 0.8); felt: σ U(0.35, 0.6), r
alternate)          U(0.6, 1), sheen U(0.05, 0.3); satin: σ U(0.1, 0.3), r U(0.2,
                    0.45), sheen U(0.2, 0.6), ks U(0.1, 0.4), α U(0.15, 0.35)
                    (GGX), η 1.5; sheen ≤ 0.95 − v (the sheen lobe's albedo
                    reaches ≈ 0.96 at grazing); sheen colour = sheen·mix(ρ/v,
                    1, U(0.2, 0.8))
phenolic (phenolic  η U(1.48, 1.6) (acrylic U(1.48, 1.5)); α_coat logU(0.015,
/ acrylic           0.06) (GGX); haze with p = 0.5: α_haze U(0.05, 0.15), h
alternate)          U(0.05, 0.3); ρ: s U(0.2, 1), v logU(0.01, 0.5); kb U(0,
                    0.3) (acrylic U(0.05, 0.4)), α_b U(0.1, 0.3)
deviation           g = Σ c_abc·cos(aπu)·cos(2bθd)·cos(2cφd), u = sqrt(θh/(π/2))
                    (MERL's θh binning), shared by the channels: a, b < 5,
                    c < 3 (74 terms, no constant), c_abc ~ N(0, σ²/(1+a+b+c)²),
                    σ U(0.05, 0.2); plus per channel a, b < 3, c < 2 (17 terms)
                    with σ_ch = σ·U(0.1, 0.4)
==================  =========================================================

The smallest roughness is 0.015 for the coats and the plastics' first lobe
(0.02 for the metals), although merl-nbrdf's sharpest lobes are narrower (a
specular half width of 0.09° in θh at the 10 % quantile against 0.76° here).
Narrower analytic lobes were tried and measured
(docs/results/synthetic-vs-merl-nbrdf.md): evaluated at the cell centres,
a lobe times 1/(cos θi · cos θo) peaks at the grazing θd ≈ 89.5° cells at
values far above any fitted (or measured) material's: the median material's
largest value went from 4·10⁴ to 4·10⁵ sr⁻¹ (merl-nbrdf: 337), a dynamic
range that broke the exactness of PCA through the Gram matrix and of the
GPLVM's blends on small test databases.  Below about α = 0.012 the
nearest-cell albedo quadrature of a MERL table also overshoots at grazing
incidence (the cell centre's cosθo differs from the true one inside the 1°
θd bins), so such a material would be darkened by the energy rescaling
(step 3) for an artefact.

The cos(2cφd) terms have period π in φd, so the deviations keep Helmholtz
reciprocity (swapping the directions maps φd → φd + π) and isotropy.

Complex refractive indices of :data:`METALS` (R, G, B ≈ 650, 550, 450 nm)
are typical literature values rounded to three decimals: Au, Ag, Cu (Johnson &
Christy 1972), Al (Rakić 1995), Cr, Fe (steel), Pt, Ni, Ti, Co, W (Johnson &
Christy 1974; Palik) as tabulated for RGB rendering (e.g. Chaos Group,
"Understanding metalness"; the 3Delight metal table at 642/529/464 nm for Ni,
Ti, Co, W), brass (Cu–Zn, Querry 1985).  Sources differ by up to ~10 %; the
per-material perturbation covers that.

Determinism: material ``i`` of ``plan_database(count, seed)`` draws all its
parameters from its own seed ``SeedSequence(seed, spawn_key=(i,))``; the noise
uses a stream derived from that seed.  The same ``(count, seed, noise)``
gives byte-identical files, materials can be generated independently and in
any order.
"""

from __future__ import annotations

import colorsys
import json
import logging
import math
import numbers
import os
import time
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core import atomic
from brdfpipe.core.version import full_version
from brdfpipe.data import databases, merl, provenance
from brdfpipe.data.provenance import WATERMARK_CELLS, WATERMARK_MAGIC, WATERMARK_RAW
from brdfpipe.data.synthmodel import DEV_CHANNEL, DEV_SHARED, Grid, cell_grid, model_values
from brdfpipe.registry import layouts

__all__ = [
    "FAMILIES",
    "FAMILY_WEIGHTS",
    "METALS",
    "DEFAULT_NOISE",
    "ALBEDO_BOUND",
    "ALBEDO_THETA_I",
    "WATERMARK_MAGIC",
    "WATERMARK_CELLS",
    "WATERMARK_RAW",
    "MaterialSpec",
    "plan_database",
    "family_counts",
    "default_test_materials",
    "default_test_count",
    "generate_table",
    "generate_material",
    "material_mark",
    "write_material",
    "write_named_material",
    "write_manifest",
    "write_database_manifest",
    "is_synthetic_file",
    "check_output_folder",
    "synthesize",
]

log = logging.getLogger("brdfpipe.data.synth")

#: Material families, in the order of their blocks in a planned database.
FAMILIES: Final[tuple[str, ...]] = ("metal", "paint", "metallic-paint", "fabric", "phenolic")
#: Share of each family (per 100 materials), after MERL's mix.
FAMILY_WEIGHTS: Final[Mapping[str, int]] = {
    "metal": 25,
    "paint": 30,
    "metallic-paint": 12,
    "fabric": 12,
    "phenolic": 21,
}
#: Default relative standard deviation of the measurement noise.
DEFAULT_NOISE: Final = 0.01
#: A material whose directional albedo exceeds this anywhere is rescaled to it.
ALBEDO_BOUND: Final = 0.97
#: Incident angles (radians) at which the albedo bound is checked: 0 … 89.5°.
ALBEDO_THETA_I: Final = np.radians(np.linspace(0.0, 89.5, 46))

# The watermark of synthetic files (its home is brdfpipe.data.provenance, with the marks).
_WATERMARK_BYTES: Final = WATERMARK_RAW.tobytes()
_WATERMARK_OFFSET: Final = merl.HEADER_BYTES + int(WATERMARK_CELLS[0]) * 8

#: Complex refractive index (n, k) of metals at R, G, B ≈ 650, 550, 450 nm.
METALS: Final[Mapping[str, tuple[tuple[float, float, float], tuple[float, float, float]]]] = {
    #             n (R, G, B)             k (R, G, B)
    "aluminium": ((1.346, 0.965, 0.617), (7.475, 6.400, 5.303)),
    "brass": ((0.444, 0.527, 1.094), (3.695, 2.765, 1.829)),
    "chrome": ((3.107, 3.181, 2.323), (3.331, 3.329, 3.135)),
    "cobalt": ((2.870, 2.191, 1.809), (4.342, 3.880, 3.492)),
    "copper": ((0.271, 0.677, 1.316), (3.609, 2.625, 2.292)),
    "gold": ((0.183, 0.421, 1.373), (3.424, 2.346, 1.770)),
    "nickel": ((1.994, 1.732, 1.645), (3.768, 3.132, 2.737)),
    "platinum": ((2.376, 2.085, 1.845), (4.266, 3.715, 3.137)),
    "silver": ((0.159, 0.145, 0.135), (3.929, 3.190, 2.381)),
    "steel": ((2.911, 2.950, 2.585), (3.089, 2.932, 2.767)),  # iron
    "titanium": ((2.184, 1.836, 1.721), (2.955, 2.519, 2.303)),
    "tungsten": ((3.668, 3.482, 3.316), (2.927, 2.720, 2.572)),
}

_NOISE_STREAM: Final = 0x6E6F6973  # "nois": the noise's sub-stream of a material seed
# The deviation's coefficients (basis sizes: brdfpipe.data.synthmodel.DEV_SHARED, DEV_CHANNEL).
_DEV_DECAY: Final = 1.0  # coefficient std ∝ (1 + a + b + c)^-decay
_DEV_SIGMA: Final = (0.05, 0.2)  # range of the per-material deviation scale σ
_DEV_CHANNEL_SIGMA: Final = (0.1, 0.4)  # per-channel σ as a fraction of σ
# Ranges tuned towards merl-nbrdf (docs/results/synthetic-vs-merl-nbrdf.md): roughness and
# reflectance scale of the metals, colour value v of the paints, metallic paints and fabrics.
_METAL_ALPHA: Final = (0.02, 0.5)
_METAL_SCALE: Final = (0.05, 0.35)
_PAINT_VALUE: Final = (0.01, 0.6)
_METALLIC_PAINT_VALUE: Final = (0.1, 0.7)
_FABRIC_VALUE: Final = (0.01, 0.45)
_COAT_ALPHA: Final = (0.015, 0.06)  # clear coats of phenolics, acrylics and metallic paints
_PLASTIC_ALPHA: Final = (0.015, 0.12)
_PAINT_ALPHA: Final = (0.1, 0.6)


# --------------------------------------------------------------------------
# Plan
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class MaterialSpec:
    """Everything needed to generate one material.

    ``params`` is JSON-serialisable (floats, lists, strings); it holds the
    family model's parameters (with ``family`` and ``variant``) and the
    deviation coefficients (``deviation``).
    """

    name: str
    family: str
    index: int
    seed: int
    params: dict = field(compare=True, hash=False)

    def to_json(self) -> dict[str, Any]:
        """The manifest entry of this material."""
        return {
            "name": self.name,
            "family": self.family,
            "index": self.index,
            "seed": self.seed,
            "params": self.params,
        }


def _check_int(value: Any, what: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{what} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{what} must be ≥ {minimum}, got {value}")
    return int(value)


def _check_noise(noise: Any) -> float:
    if isinstance(noise, bool) or not isinstance(noise, numbers.Real):
        raise ValueError(f"noise must be a number, got {noise!r}")
    value = float(noise)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"noise must be a finite number ≥ 0, got {noise!r}")
    return value


def family_counts(count: int) -> dict[str, int]:
    """Materials per family for a database of ``count`` (MERL's proportions).

    Largest-remainder apportionment of :data:`FAMILY_WEIGHTS`; every family
    gets at least one material when ``count ≥ 5`` (for fewer, the families
    with the largest shares come first).
    """
    count = _check_int(count, "count", 1)
    total = sum(FAMILY_WEIGHTS.values())
    quota = {f: FAMILY_WEIGHTS[f] * count / total for f in FAMILIES}
    if count >= len(FAMILIES):
        base = {f: max(1, math.floor(quota[f])) for f in FAMILIES}
    else:
        base = {f: 0 for f in FAMILIES}
    order = {f: i for i, f in enumerate(FAMILIES)}
    while sum(base.values()) > count:  # only possible because of the minimum of one
        f = max(
            (f for f in FAMILIES if base[f] > 1), key=lambda f: (base[f] - quota[f], -order[f])
        )
        base[f] -= 1
    while sum(base.values()) < count:
        f = max(FAMILIES, key=lambda f: (quota[f] - base[f], -order[f]))
        base[f] += 1
    return base


def _r(x: float) -> float:
    """Round a drawn parameter to 6 significant digits (readable manifests)."""
    return float(f"{float(x):.6g}")


def _rl(xs: Iterable[float]) -> list[float]:
    return [_r(x) for x in xs]


def _logu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(math.log(lo), math.log(hi))))


def _colour(
    rng: np.random.Generator, s_range: tuple[float, float], v_range: tuple[float, float],
    log_v: bool,
) -> tuple[list[float], float, float, float]:
    """A linear-RGB colour drawn in HSV; returns (rgb, hue, saturation, value)."""
    h = float(rng.uniform(0.0, 1.0))
    s = float(rng.uniform(*s_range))
    v = _logu(rng, *v_range) if log_v else float(rng.uniform(*v_range))
    rgb = _rl(colorsys.hsv_to_rgb(h, s, v))
    return rgb, h, s, v


def _colour_name(h: float, s: float, v: float, *, metallic: bool = False) -> str:
    """A short colour word for HSV (hue in [0, 1), value = linear max channel)."""
    if s < 0.15:
        if metallic:
            return "silver" if v >= 0.35 else "gunmetal"
        if v < 0.04:
            return "black"
        return "white" if v >= 0.45 else "grey"
    if v < 0.025:
        return "black"
    deg = h * 360.0
    if deg < 15 or deg >= 345:
        name = "red"
    elif deg < 45:
        name = "orange"
    elif deg < 70:
        name = "yellow"
    elif deg < 160:
        name = "green"
    elif deg < 200:
        name = "cyan"
    elif deg < 255:
        name = "blue"
    elif deg < 290:
        name = "purple"
    else:
        name = "pink"
    if name in ("orange", "red", "yellow") and v < 0.12 and s > 0.3 and metallic is False:
        name = "brown" if name != "red" else "maroon"
    if metallic and name in ("orange", "yellow") and v >= 0.35:
        name = "gold"
    return name


def _tail(rng: np.random.Generator) -> float:
    """GGX weight of a lobe: pure GGX (50 %), pure Beckmann (10 %) or a U(0, 1) mix."""
    r = float(rng.uniform())
    return 1.0 if r < 0.5 else (0.0 if r < 0.6 else float(rng.uniform()))


def _plan_metal(rng: np.random.Generator, j: int) -> tuple[str, dict]:
    metal = sorted(METALS)[j % len(METALS)]
    n0, k0 = METALS[metal]
    n = [x * math.exp(0.03 * rng.standard_normal()) for x in n0]
    k = [x * math.exp(0.03 * rng.standard_normal()) for x in k0]
    ggx = _tail(rng)
    alpha = _logu(rng, *_METAL_ALPHA)
    if rng.uniform() < 0.5:
        alpha_haze = min(0.8, alpha * float(rng.uniform(2.0, 5.0)))
        haze = float(rng.uniform(0.05, 0.4))
    else:
        alpha_haze, haze = alpha, 0.0
    params = {
        "metal": metal, "n": _rl(n), "k": _rl(k), "ggx": _r(ggx), "alpha": _r(alpha),
        "alpha_haze": _r(alpha_haze), "haze": _r(haze), "scale": _r(_logu(rng, *_METAL_SCALE)),
    }
    return metal, params


def _plan_paint(rng: np.random.Generator, j: int) -> tuple[str, dict]:
    variant = ("paint", "plastic")[j % 2]
    eta = float(rng.uniform(1.4, 1.6))
    ks = float(rng.uniform(0.5, 1.0))
    rgb, h, s, v = _colour(rng, (0.0, 0.95), _PAINT_VALUE, log_v=True)
    if variant == "paint":
        a1 = _logu(rng, *_PAINT_ALPHA)
        if rng.uniform() < 0.3:
            a2, w2 = float(rng.uniform(0.3, 0.6)), float(rng.uniform(0.1, 0.4))
        else:
            a2, w2 = a1, 0.0
    else:
        a1 = _logu(rng, *_PLASTIC_ALPHA)
        a2 = _logu(rng, 0.15, 0.45)
        w2 = float(rng.uniform(0.05, 0.5))
    params = {
        "eta": _r(eta), "ks": _r(ks), "diffuse": rgb,
        "sigma": _r(rng.uniform(0.0, 0.5)), "ggx": _r(_tail(rng)),
        "lobes": [[_r(a1), _r(1.0 - w2)], [_r(a2), _r(w2)]],
    }
    colour = _colour_name(h, s, v)
    return (colour if variant == "paint" else f"{colour}-plastic"), params | {"variant": variant}


def _plan_metallic_paint(rng: np.random.Generator, j: int) -> tuple[str, dict]:
    rgb, h, s, v = _colour(rng, (0.0, 0.9), _METALLIC_PAINT_VALUE, log_v=False)
    kd = float(rng.uniform(0.02, 0.25))
    k1 = float(rng.uniform(0.15, 0.45))
    k2 = float(rng.uniform(0.05, 0.25))
    total = kd + k1 + k2
    if total > 0.9:
        kd, k1, k2 = (x * 0.9 / total for x in (kd, k1, k2))
    t = float(rng.uniform(0.0, 0.5))
    params = {
        "coat_eta": _r(rng.uniform(1.45, 1.6)),
        "coat_alpha": _r(_logu(rng, *_COAT_ALPHA)),
        "base": rgb,
        "kd": _r(kd),
        "k1": _r(k1), "alpha1": _r(_logu(rng, 0.06, 0.2)),
        "k2": _r(k2), "alpha_flake": _r(rng.uniform(0.3, 0.6)),
        "ggx": _r(_tail(rng)),
        "flake_colour": _rl((1.0 - t) * c + t * v for c in rgb),
    }
    return _colour_name(h, s, v, metallic=True), params


def _plan_fabric(rng: np.random.Generator, j: int) -> tuple[str, dict]:
    variant = ("velvet", "felt", "satin")[j % 3]
    rgb, h, s, v = _colour(rng, (0.0, 0.9), _FABRIC_VALUE, log_v=True)
    if variant == "velvet":
        sigma, r, sheen = rng.uniform(0.2, 0.5), rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.8)
        ks, alpha = 0.0, 0.25
    elif variant == "felt":
        sigma, r, sheen = rng.uniform(0.35, 0.6), rng.uniform(0.6, 1.0), rng.uniform(0.05, 0.3)
        ks, alpha = 0.0, 0.25
    else:
        sigma, r, sheen = rng.uniform(0.1, 0.3), rng.uniform(0.2, 0.45), rng.uniform(0.2, 0.6)
        alpha, ks = rng.uniform(0.15, 0.35), rng.uniform(0.1, 0.4)
    # the Charlie sheen's albedo reaches ~0.96 at grazing: keep diffuse + sheen ≤ 0.95
    sheen = min(float(sheen), 0.95 - v)
    t = float(rng.uniform(0.2, 0.8))
    sheen_rgb = [sheen * ((1.0 - t) * c / v + t) for c in rgb]
    params = {
        "variant": variant, "diffuse": rgb, "sigma": _r(sigma),
        "sheen": _rl(sheen_rgb), "sheen_roughness": _r(r),
        "ks": _r(ks), "alpha": _r(alpha), "eta": 1.5,
    }
    return f"{_colour_name(h, s, v)}-{variant}", params


def _plan_phenolic(rng: np.random.Generator, j: int) -> tuple[str, dict]:
    variant = ("phenolic", "acrylic")[j % 2]
    eta = float(rng.uniform(1.48, 1.6) if variant == "phenolic" else rng.uniform(1.48, 1.5))
    a_coat = _logu(rng, *_COAT_ALPHA)
    if rng.uniform() < 0.5:
        a_haze, haze = float(rng.uniform(0.05, 0.15)), float(rng.uniform(0.05, 0.3))
    else:
        a_haze, haze = a_coat, 0.0
    rgb, h, s, v = _colour(rng, (0.2, 1.0), (0.01, 0.5), log_v=True)
    kb = float(rng.uniform(0.0, 0.3) if variant == "phenolic" else rng.uniform(0.05, 0.4))
    params = {
        "variant": variant, "eta": _r(eta), "coat_alpha": _r(a_coat),
        "alpha_haze": _r(a_haze), "haze": _r(haze), "diffuse": rgb,
        "kb": _r(kb), "alpha_base": _r(rng.uniform(0.1, 0.3)),
        "ggx": _r(_tail(rng)),
    }
    colour = _colour_name(h, s, v)
    return (colour if variant == "phenolic" else f"{colour}-acrylic"), params


_PLANNERS: Final = {
    "metal": _plan_metal,
    "paint": _plan_paint,
    "metallic-paint": _plan_metallic_paint,
    "fabric": _plan_fabric,
    "phenolic": _plan_phenolic,
}


def _plan_deviation(rng: np.random.Generator) -> dict:
    sigma = float(rng.uniform(*_DEV_SIGMA))
    a, b, c = np.meshgrid(*(np.arange(n) for n in DEV_SHARED), indexing="ij")
    shared = rng.standard_normal(DEV_SHARED) * sigma / (1.0 + a + b + c) ** _DEV_DECAY
    shared[0, 0, 0] = 0.0
    a, b, c = np.meshgrid(*(np.arange(n) for n in DEV_CHANNEL), indexing="ij")
    sig_ch = sigma * float(rng.uniform(*_DEV_CHANNEL_SIGMA))
    channel = rng.standard_normal((3, *DEV_CHANNEL)) * sig_ch / (1.0 + a + b + c) ** _DEV_DECAY
    channel[:, 0, 0, 0] = 0.0
    return {
        "sigma": _r(sigma),
        "shared": _rl(shared.ravel()),
        "channel": [_rl(ch.ravel()) for ch in channel],
    }


def _material_seed(seed: int, index: int) -> int:
    ss = np.random.SeedSequence(seed, spawn_key=(index,))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(11))  # 53 bits: exact in JSON


def plan_database(count: int, seed: int) -> list[MaterialSpec]:
    """The materials of a synthetic database of ``count`` materials (pure, fast).

    Families in blocks (:data:`FAMILIES` order, :func:`family_counts`);
    inside a family, named metals and variants go round-robin; every other
    parameter is drawn from the material's own seed, derived from
    ``(seed, index)``.  Names are ``<family>-<descriptor>-<NNN>`` with the
    index as running number, each checked by the material-name rule
    (:func:`brdfpipe.data.databases.check_material_name`, whose
    :class:`~brdfpipe.data.databases.DatabaseError` names the plan) before any
    caller writes a file.  Raises :class:`ValueError` for ``count < 1`` or
    ``seed < 0``.
    """
    count = _check_int(count, "count", 1)
    seed = _check_int(seed, "seed", 0)
    width = max(3, len(str(count - 1)))
    specs: list[MaterialSpec] = []
    index = 0
    for family, n in family_counts(count).items():
        for j in range(n):
            mseed = _material_seed(seed, index)
            rng = np.random.default_rng(mseed)
            descriptor, params = _PLANNERS[family](rng, j)
            params = {"family": family, "variant": params.pop("variant", family), **params}
            params["deviation"] = _plan_deviation(rng)
            name = databases.check_material_name(f"{family}-{descriptor}-{index:0{width}d}",
                                       f"synthetic database (count {count}, seed {seed})")
            specs.append(MaterialSpec(name, family, index, mseed, params))
            index += 1
    return specs


def default_test_materials(specs: Sequence[MaterialSpec], n: int = 10) -> list[str]:
    """``n`` held-out material names spanning every family (deterministic).

    Round-robin over the families (in :data:`FAMILIES` order); inside a family
    the materials are taken in the order of their seeds (a pseudo-random but
    fixed order).  Returned in database order.  Raises :class:`ValueError` if
    ``n`` is negative or larger than the database.
    """
    n = _check_int(n, "n", 0)
    if n > len(specs):
        raise ValueError(f"n = {n} test materials requested from a database of {len(specs)}")
    groups: dict[str, list[MaterialSpec]] = {}
    for s in specs:
        groups.setdefault(s.family, []).append(s)
    order = [f for f in FAMILIES if f in groups] + sorted(set(groups) - set(FAMILIES))
    queues = [sorted(groups[f], key=lambda s: (s.seed, s.index)) for f in order]
    picked: list[MaterialSpec] = []
    depth = 0
    while len(picked) < n:
        for q in queues:
            if depth < len(q) and len(picked) < n:
                picked.append(q[depth])
        depth += 1
    return [s.name for s in sorted(picked, key=lambda s: s.index)]

# --------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _watermark_table_values() -> NDArray[np.float64]:
    """Physical values ``(3, 8)`` of the watermark cells that write back as exactly :data:`WATERMARK_RAW`.

    :func:`brdfpipe.data.merl.write_merl` divides by the channel scale; ``raw ·
    scale`` does not always divide back to ``raw`` exactly, so the nearest
    float that does is taken (one exists for every value of
    :data:`WATERMARK_RAW` in every channel; not for every float).
    """
    out = np.empty((3, WATERMARK_RAW.size))
    for c, scale in enumerate(merl.SCALES):
        for k, raw in enumerate(WATERMARK_RAW):
            t = raw * scale
            for _ in range(64):
                back = t / scale
                if back == raw:
                    break
                t = np.nextafter(t, -np.inf if back > raw else np.inf)
            else:  # pragma: no cover - checked for these values and scales
                raise AssertionError(f"no float64 maps to the watermark value {raw} in channel {c}")
            out[c, k] = t
    return out


def _table(values: NDArray[np.float64], grid: Grid) -> NDArray[np.float64]:
    table = np.empty(merl.SHAPE)
    table[...] = -merl.SCALES[:, None, None, None]
    flat = table.reshape(3, -1)
    flat[:, grid.cells] = values
    flat[:, WATERMARK_CELLS] = _watermark_table_values()
    return table


def is_synthetic_file(path: str | os.PathLike[str]) -> bool:
    """True if ``path`` carries the synthetic watermark (was written by this generator).

    Reads only the 64 watermark bytes of the red channel (a few microseconds;
    no validation of the rest of the file).  A file too short to hold them is
    not synthetic.  Raises :class:`OSError` if the file cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY)
    try:
        return os.pread(fd, len(_WATERMARK_BYTES), _WATERMARK_OFFSET) == _WATERMARK_BYTES
    finally:
        os.close(fd)


def generate_material(
    spec: MaterialSpec, noise: float = DEFAULT_NOISE
) -> tuple[NDArray[np.float64], dict[str, float]]:
    """:func:`generate_table` plus the generation record.

    The record is ``{"energy_scale": s, "max_albedo": a}``: ``a`` is the
    largest directional albedo (any channel, 46 θi from 0 to 89.5°) of the
    model with deviations before rescaling, ``s = min(1, ALBEDO_BOUND / a)``
    the uniform scale applied.
    """
    noise = _check_noise(noise)
    grid = cell_grid()
    values = model_values(spec)
    albedo = float(merl.directional_albedo(_table(values, grid), ALBEDO_THETA_I).max())
    scale = 1.0 if albedo <= ALBEDO_BOUND else ALBEDO_BOUND / albedo
    if scale != 1.0:
        values *= scale
    if noise > 0.0:
        rng = np.random.default_rng([spec.seed, _NOISE_STREAM])
        z = rng.standard_normal(values.shape)
        values *= np.exp(noise * z - 0.5 * noise * noise)
    return _table(values, grid), {"energy_scale": scale, "max_albedo": albedo}


def generate_table(spec: MaterialSpec, noise: float = DEFAULT_NOISE) -> NDArray[np.float64]:
    """The material's MERL table, ``(3, 90, 90, 180)`` in physical units.

    Measured cells (:func:`brdfpipe.data.merl.measured_mask`) hold model ×
    deviation × energy scale × noise (finite, ≥ 0); the others ``-SCALES[c]``,
    except the watermark cells (:data:`WATERMARK_CELLS`, raw values
    :data:`WATERMARK_RAW`, also negative).
    Deterministic: the same spec and noise give identical arrays.
    """
    return generate_material(spec, noise)[0]


def material_mark(spec: MaterialSpec, noise: float, plan: tuple[int, int] | None = None) -> provenance.Mark:
    """The provenance mark of a material's file: its name and how it was made.

    ``plan``: ``(count, seed)`` of :func:`plan_database` that planned ``spec``
    (recorded as null when not given).
    """
    count, seed = (_check_int(plan[0], "count", 1), _check_int(plan[1], "seed", 0)) if plan else (None, None)
    return provenance.synthetic_mark(name=spec.name, count=count, seed=seed, noise=_check_noise(noise),
                                     family=spec.family, index=spec.index, material_seed=spec.seed)


def write_material(
    spec: MaterialSpec,
    path: str | os.PathLike[str],
    noise: float = DEFAULT_NOISE,
    *,
    plan: tuple[int, int] | None = None,
) -> dict[str, float]:
    """Generate a material and write it as a MERL file (atomically) with its mark (:func:`material_mark`).

    ``plan``: ``(count, seed)`` of the plan the spec comes from (the
    workflow checks it at ingest).  Returns the generation record of
    :func:`generate_material`.
    """
    table, record = generate_material(spec, noise)
    merl.write_merl(path, table, mark=material_mark(spec, noise, plan))
    return record


def _find_spec(specs: Sequence[MaterialSpec], name: str) -> MaterialSpec:
    for s in specs:
        if s.name == name:
            return s
    raise ValueError(
        f"no material named {name!r} in this synthetic database "
        f"({len(specs)} materials, e.g. {specs[0].name!r})"
    )


def write_named_material(
    *,
    name: str,
    count: int,
    seed: int,
    noise: float,
    path: str | os.PathLike[str],
    record_path: str | os.PathLike[str] | None = None,
) -> dict[str, float]:
    """Generate material ``name`` of ``plan_database(count, seed)`` into ``path``.

    One workflow job per material.  Logs one line; returns the record of
    :func:`generate_material` and, with ``record_path``, also writes it there
    as JSON (for :func:`write_database_manifest`).  Raises :class:`ValueError`
    for an unknown name.
    """
    noise = _check_noise(noise)
    spec = _find_spec(plan_database(count, seed), name)
    t0 = time.perf_counter()
    record = write_material(spec, path, noise, plan=(count, seed))
    log.info(
        "%s (%s): %.2f s, energy_scale %.4f, max albedo %.4f -> %s",
        spec.name, spec.family, time.perf_counter() - t0, record["energy_scale"],
        record["max_albedo"], path,
    )
    if record_path is not None:
        atomic.write_text(record_path, json.dumps({"name": spec.name, **record}) + "\n")
    return record


# --------------------------------------------------------------------------
# Manifest and database
# --------------------------------------------------------------------------


def write_manifest(
    specs: Sequence[MaterialSpec],
    path: str | os.PathLike[str],
    *,
    seed: int,
    noise: float,
    test_materials: Sequence[str],
    records: Mapping[str, Mapping[str, float]] | None = None,
    count: int | None = None,
) -> None:
    """Write the database's ``manifest.json`` (atomically: temporary file + rename).

    ``records`` (optional) maps material names to their generation records
    (:func:`generate_material`); they are stored in the materials' params.
    ``count``: the size of the planned database (``plan_database(count,
    seed)``) when ``specs`` are only the part of it that was generated;
    default ``len(specs)``.
    Raises :class:`ValueError` for duplicate names or unknown test materials.
    """
    seed = _check_int(seed, "seed", 0)
    noise = _check_noise(noise)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise ValueError("material names in a manifest must be unique")
    known = set(names)
    unknown = [t for t in test_materials if t not in known]
    if unknown:
        raise ValueError(f"test materials not in the database: {', '.join(unknown)}")
    records = records or {}
    materials = []
    for s in specs:
        entry = s.to_json()
        if s.name in records:
            entry["params"] = {**s.params, **{k: float(v) for k, v in records[s.name].items()}}
        materials.append(entry)
    doc = {
        "kind": "synthetic",
        "generator": "brdfpipe.data.synth",
        "version": full_version(),
        "seed": seed,
        "count": len(specs) if count is None else _check_int(count, "count", len(specs)),
        "noise": noise,
        "materials": materials,
        "test_materials": list(test_materials),
    }
    atomic.write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")


def write_database_manifest(
    path: str | os.PathLike[str],
    *,
    count: int,
    seed: int,
    noise: float,
    test_materials: Sequence[str],
    record_files: Sequence[str | os.PathLike[str]],
    materials: Sequence[str] | None = None,
) -> None:
    """Write the manifest of ``plan_database(count, seed)`` with the records of its jobs.

    ``record_files`` are the JSON records that :func:`write_named_material`
    wrote, one per material; a missing or foreign record is an error naming
    the file.  ``materials``: the names generated when the run uses a part
    of the database (the workflow's ``materials`` key); the manifest then
    lists those only (its ``count`` stays the planned database's).
    """
    specs = plan_database(count, seed)
    if materials is not None:
        planned = {s.name for s in specs}
        unknown = sorted(set(materials) - planned)
        if unknown:
            raise ValueError(f"not materials of this synthetic database: {', '.join(unknown)}")
        keep = set(materials)
        specs = [s for s in specs if s.name in keep]
    names = {s.name for s in specs}
    records: dict[str, dict[str, float]] = {}
    for f in record_files:
        doc = json.loads(Path(f).read_text(encoding="utf-8"))
        name = doc.pop("name", None)
        if name not in names:
            raise ValueError(f"{f}: record of {name!r}, not a material of this database")
        records[name] = doc
    missing = sorted(names - set(records))
    if missing:
        raise ValueError(f"no generation record for: {', '.join(missing)}")
    write_manifest(
        specs, path, seed=seed, noise=noise, test_materials=test_materials, records=records, count=count
    )


def default_test_count(count: int) -> int:
    """Held-out materials for a synthetic database of ``count`` materials.

    Ten, as in the papers' leave-10-out protocol, once there are at least 40
    materials; smaller (test) databases hold out a quarter (at least one).
    """
    return 10 if count >= 40 else max(1, count // 4)


def _is_synthetic_manifest(path: Path) -> bool:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(doc, dict) and doc.get("kind") == "synthetic"


def check_output_folder(out: str | os.PathLike[str], specs: Sequence[MaterialSpec]) -> None:
    """Refuse an output folder where :func:`synthesize` would touch files it did not write.

    ``out`` may be absent, empty (hidden entries aside) or a folder that this
    generator wrote before (a synthetic ``manifest.json``), whose ``*.binary``
    files are all watermarked materials of ``specs`` (regenerated in place);
    a folder of watermarked materials of ``specs`` alone (a run interrupted
    before it wrote its manifest) is completed the same way.
    Anything else — a file, a folder of other data, a real MERL file or a
    material of another plan — raises :class:`brdfpipe.core.atomic.OutputError`
    naming the path, before anything is written.  Nothing is ever deleted.
    """
    out = Path(out)
    if out.is_symlink() and not out.exists():
        raise atomic.OutputError(f"--out {out}: a broken link; refusing to write through it")
    if out.exists() and not out.is_dir():
        raise atomic.OutputError(f"--out {out}: exists and is not a folder")
    if not out.exists():
        return
    entries = sorted(e for e in out.iterdir() if not e.name.startswith("."))
    if not entries:
        return
    planned = {layouts.merl_file(s.name) for s in specs}
    interrupted = all(e.name in planned and e.is_file() and not e.is_symlink() and is_synthetic_file(e)
                      for e in entries)  # an earlier run of this plan stopped before its manifest
    if not interrupted and not _is_synthetic_manifest(out / layouts.SYNTHETIC_MANIFEST):
        raise atomic.OutputError(
            f"--out {out}: folder is not empty and holds no synthetic manifest.json (not written by "
            "`brdfpipe synth`); refusing to write into it: choose a new or empty folder"
        )
    foreign: list[str] = []
    other_plan: list[str] = []
    for e in entries:
        if not e.name.lower().endswith(layouts.MERL_SUFFIX):
            continue
        if e.name not in planned:
            other_plan.append(e.name)
        elif e.is_symlink() or not e.is_file() or not is_synthetic_file(e):
            foreign.append(e.name)
    if foreign:
        raise atomic.OutputError(
            f"--out {out}: {', '.join(foreign)} not written by `brdfpipe synth` (no synthetic "
            "watermark, or not a plain file); refusing to overwrite: choose a new or empty folder"
        )
    if other_plan:
        shown = ", ".join(other_plan[:5]) + (f" and {len(other_plan) - 5} more" if len(other_plan) > 5 else "")
        raise atomic.OutputError(
            f"--out {out}: holds {len(other_plan)} file(s) that are not materials of this "
            f"database ({shown}); the folder would mix two databases: choose a new or empty folder"
        )


def _synth_one(args: tuple[MaterialSpec, str, float, tuple[int, int]]) -> tuple[dict[str, float], float]:
    spec, path, noise, plan = args
    t0 = time.perf_counter()
    record = write_material(spec, path, noise, plan=plan)
    return record, time.perf_counter() - t0


def synthesize(
    out_dir: str | os.PathLike[str],
    count: int,
    seed: int,
    noise: float = DEFAULT_NOISE,
    jobs: int = 1,
    progress: bool = True,
) -> Path:
    """Generate a whole synthetic database into ``out_dir``.

    Writes ``<name>.binary`` for every material of ``plan_database(count,
    seed)`` and then ``manifest.json`` (with each material's generation
    record and the default test materials); returns the manifest's path.
    ``jobs > 1`` generates in a process pool.  An existing ``out_dir`` is
    checked first (:func:`check_output_folder`): only an empty folder or an
    earlier output of this generator for the same plan is written into.  One log line per material
    (logger ``brdfpipe.data.synth``; INFO if ``progress`` else DEBUG).
    """
    count = _check_int(count, "count", 1)
    seed = _check_int(seed, "seed", 0)
    noise = _check_noise(noise)
    jobs = _check_int(jobs, "jobs", 1)
    out = Path(out_dir)
    specs = plan_database(count, seed)
    check_output_folder(out, specs)
    out.mkdir(parents=True, exist_ok=True)
    tasks = [(s, str(out / layouts.merl_file(s.name)), noise, (count, seed)) for s in specs]
    level = logging.INFO if progress else logging.DEBUG
    records: dict[str, dict[str, float]] = {}
    t_start = time.perf_counter()

    def done(i: int, spec: MaterialSpec, record: dict[str, float], seconds: float) -> None:
        records[spec.name] = record
        log.log(
            level, "[%d/%d] %s (%s): %.2f s, energy_scale %.4f", i + 1, count, spec.name,
            spec.family, seconds, record["energy_scale"],
        )

    if jobs == 1 or count == 1:
        for i, task in enumerate(tasks):
            done(i, task[0], *_synth_one(task))
    else:
        with ProcessPoolExecutor(max_workers=min(jobs, count)) as pool:
            for i, (task, result) in enumerate(zip(tasks, pool.map(_synth_one, tasks))):
                done(i, task[0], *result)
    test = default_test_materials(specs, default_test_count(count))
    manifest = out / layouts.SYNTHETIC_MANIFEST
    write_manifest(specs, manifest, seed=seed, noise=noise, test_materials=test, records=records)
    log.log(level, "%d materials in %.1f s -> %s", count, time.perf_counter() - t_start, manifest)
    return manifest
