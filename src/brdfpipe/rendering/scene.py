"""A material-preview scene built from Mitsuba 3's own shapes, and its renders.

The scene is the set-up of Soler et al. 2018 §5.2 (Figs. 12, 13): one
preview object whose material changes, in a fixed environment, rendered with
multi-bounce global illumination, so that images of measured materials can be
pre-rendered once and blended (:mod:`brdfpipe.rendering.blend`).

Coordinates
-----------
World space is **+Y up**, the ground is the plane ``y = 0`` and the camera
looks from ``+Z`` towards ``-Z`` (image right is world ``+X``).

Environment map convention (verified)
-------------------------------------
Mitsuba's ``envmap`` emitter (``src/emitters/envmap.cpp``, default
``to_world`` = identity) maps a world direction ``d = (x, y, z)`` to the
texture coordinate ``u = atan2(x, −z) / 2π (mod 1)``, ``v = acos(y) / π``, i.e.
``d = (sin φ sin θ, cos θ, −cos φ sin θ)`` with ``φ = 2πu``, ``θ = πv``.  It
pads the image with a copy of column 0 and interpolates bilinearly with

* column ``c`` exactly at ``u = (c + ½) / W`` (a half-texel shift), and
* row ``r`` exactly at ``v = r / (H − 1)``: **row 0 is the zenith (+Y)**,
  row ``H − 1`` the nadir (−Y).

Columns: ``u = 0`` looks along ``−Z`` (away from the camera), ``u = ¼`` along
``+X``, ``u = ½`` along ``+Z`` (towards the camera), ``u = ¾`` along ``−X``.
This was checked numerically against Mitsuba 3.9.1 (``Emitter.eval`` of an
``envmap`` holding single bright pixels peaks exactly at those directions);
:func:`envmap_pixel_directions` gives the direction of every pixel and is what
:func:`make_envmap` evaluates the sky at, so "up" in the map is "up" in the
scene (tests render a diffuse sphere: its top is brighter than its bottom, and
the side facing the sun is brighter than the other).

Sun direction: elevation ``e`` above the horizon and azimuth ``a`` in the same
convention as ``u`` (``a = 0`` → ``−Z``, ``a = 90°`` → ``+X``, ``a = 180°`` →
``+Z``): ``(sin a cos e, sin e, −cos a cos e)`` (:func:`sun_direction`).  The
default ``a = 135°`` puts the sun to the right of and in front of the object
(behind the camera's right shoulder), so the lit side faces the camera and
shadows fall back-left.

Scene layout (:func:`scene_dict`)
---------------------------------
* ground: a 50 × 50 ``rectangle`` at ``y = 0`` with a ``diffuse`` bsdf whose
  reflectance is a ``checkerboard`` (0.5-unit checks, greys 0.7 / 0.3);
* preview object, every part carrying the material under study (the same
  bsdf instance, referenced by id ``material``): a unit ``sphere`` resting on
  the ground at the origin, a small ``cube`` (0.7 wide, turned 30°) in front
  on the left, and a capped ``cylinder`` (radius 0.32, height 0.9; cap is a
  ``disk``) in front on the right — concave corners between them give the
  inter-reflections on the material that a teapot's handle and spout give;
* light: the ``envmap`` emitter (sky + sun) and, if ``emitters``, a 1.5 × 1.5
  ``rectangle`` ``area`` light up-left-front of the object;
* ``path`` integrator (``max_depth``), ``perspective`` camera (40° horizontal
  field of view), ``hdrfilm`` (rgb, ``box`` filter), ``independent`` sampler.

Rendering (:func:`render_to_exr`) needs a Mitsuba variant set first
(:func:`set_variant`); Mitsuba is imported lazily inside the functions, so
importing this module (and :func:`make_envmap`) does not need it.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core.exr import read_exr, write_exr
from brdfpipe.data import provenance

__all__ = [
    "VARIANTS",
    "DEFAULT_PASS_SPP",
    "PASS_SAMPLES",
    "auto_pass_spp",
    "SUN_AZIMUTH_DEG",
    "SceneError",
    "set_variant",
    "envmap_pixel_directions",
    "sun_direction",
    "make_envmap",
    "scene_dict",
    "pass_seeds",
    "MITSUBA_UINT32_MAX",
    "MAX_SPP",
    "MAX_SEED",
    "MAX_DEPTH",
    "RENDER_BASE_BYTES",
    "RENDER_BYTES_PER_PIXEL",
    "render_memory",
    "check_render_settings",
    "render_to_exr",
    "render_split_to_exr",
    "render_material",
    "render_material_seeds",
    "render_object_mask",
]

logger = logging.getLogger("brdfpipe.rendering.scene")

#: Mitsuba variants this module renders with.
VARIANTS: Final = ("llvm_ad_rgb", "cuda_ad_rgb", "scalar_rgb")
#: Largest number of samples per pixel rendered in one pass by :func:`render_to_exr`.
DEFAULT_PASS_SPP: Final = 32
#: Samples (pixels × spp) a pass of :func:`render_material` may hold: a 256 × 192 image's 32 spp.
#: Smaller images render in fewer, larger passes (:func:`auto_pass_spp`), so a 48 × 36 render of
#: 4,096 spp takes 8 passes instead of 128: each pass costs a trace of the integrator and a kernel
#: launch (measured: docs/results/whole-run-2026-11-28-cpu.md).
PASS_SAMPLES: Final = 256 * 192 * 32
#: Default sun azimuth (degrees, :func:`sun_direction` convention): right of and in front of the object.
SUN_AZIMUTH_DEG: Final = 135.0
#: At most this many passes per render, so pass seeds ``seed*1000 + p`` never collide.
_MAX_PASSES: Final = 1000
#: Mitsuba's sampler ``seed`` and ``sample_count``, ``mi.render(seed=, spp=)`` and the path depth are
#: 32-bit unsigned integers (Mitsuba 3.9: "value 4294967296 is out of bounds, must be in the range
#: [0, 4294967295]"; a larger ``mi.render`` seed is a TypeError).
MITSUBA_UINT32_MAX: Final = 2**32 - 1
#: Largest ``spp`` of :func:`render_to_exr` with the default passes: 1000 passes of 32 samples.
MAX_SPP: Final = _MAX_PASSES * DEFAULT_PASS_SPP
#: Largest render seed: the pass seeds ``seed·1000 + p`` (p < 1000) must fit Mitsuba's 32-bit seed.
MAX_SEED: Final = (MITSUBA_UINT32_MAX - (_MAX_PASSES - 1)) // _MAX_PASSES
#: Largest ``max_depth`` (Mitsuba's path depth is 32-bit unsigned; the largest means unbounded).
MAX_DEPTH: Final = MITSUBA_UINT32_MAX
#: Peak memory of one render (``brdfpipe render``, a pre-render): a base plus a cost per pixel,
#: independent of spp (passes of at most 32 samples per pixel, or of :data:`PASS_SAMPLES` samples for
#: small images, which is no more than a 256 × 192 pass; Mitsuba's loops are evaluated in one kernel).
#: Measured with ``/usr/bin/time`` (max RSS) on Mitsuba 3.9.1 ``llvm_ad_rgb``, 2-core AMD EPYC:
#: 1024 × 768 at 1 spp 400 MB, 2048 × 1536 at 1 and 4 spp 1,006 and 984 MB, 32 × 24 to 512 × 384 at
#: 32 spp 242-249 MB: 257 bytes per pixel above 198 MB, rounded up.
RENDER_BASE_BYTES: Final = 250_000_000
RENDER_BYTES_PER_PIXEL: Final = 300


class SceneError(RuntimeError):
    """Mitsuba could not be set up, load a scene or render it; the message says why."""


# --------------------------------------------------------------------------
# Mitsuba variant
# --------------------------------------------------------------------------


def set_variant(variant: str) -> None:
    """Select the Mitsuba variant used by :func:`scene_dict` and :func:`render_to_exr`.

    ``variant`` must be one of :data:`VARIANTS` (``ValueError`` naming it and
    the allowed set otherwise).  The backend is exercised with a tiny
    computation, so an unusable one (no CUDA device or driver, no LLVM
    library) fails here with a :class:`SceneError` naming the variant and the
    cause, not later in the middle of a render.
    """
    if variant not in VARIANTS:
        raise ValueError(f"unknown Mitsuba variant {variant!r}; allowed: {', '.join(VARIANTS)}")
    try:
        import drjit as dr
        import mitsuba as mi

        mi.set_variant(variant)
        probe = mi.Float(1.0) + mi.Float(2.0)
        dr.eval(probe)
        if np.asarray(probe, dtype=np.float64).ravel().tolist() != [3.0]:
            raise RuntimeError("backend returned a wrong result for 1 + 2")
    except Exception as exc:
        raise SceneError(f"Mitsuba variant {variant!r} is not usable on this machine: {exc}") from exc


def _mitsuba() -> Any:
    """The mitsuba module, with a variant of :data:`VARIANTS` set (SceneError otherwise)."""
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise SceneError(
            "no Mitsuba variant is set; call brdfpipe.rendering.scene.set_variant(...) with one of "
            + ", ".join(VARIANTS)
        )
    if variant not in VARIANTS:
        raise SceneError(f"Mitsuba variant {variant!r} is set; use one of {', '.join(VARIANTS)}")
    return mi


# --------------------------------------------------------------------------
# Environment map
# --------------------------------------------------------------------------


def envmap_pixel_directions(width: int, height: int) -> NDArray[np.float64]:
    """World directions ``(H, W, 3)`` at which Mitsuba's ``envmap`` samples each pixel exactly.

    Row ``r`` is at polar angle ``θ = π r / (H − 1)`` from +Y (row 0 =
    zenith), column ``c`` at ``φ = 2π (c + ½) / W``; the direction is
    ``(sin φ sin θ, cos θ, −cos φ sin θ)`` (see the module docstring).
    """
    if width < 2 or height < 3:
        raise ValueError(f"an environment map needs at least 2 × 3 pixels, got {width} × {height}")
    theta = np.pi * np.arange(height) / (height - 1)
    phi = 2.0 * np.pi * (np.arange(width) + 0.5) / width
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    sp, cp = np.sin(phi)[None, :], np.cos(phi)[None, :]
    return np.stack(np.broadcast_arrays(sp * st, ct + 0.0 * sp, -cp * st), axis=-1)


def sun_direction(elevation_deg: float, azimuth_deg: float) -> NDArray[np.float64]:
    """Unit vector towards the sun: ``(sin a cos e, sin e, −cos a cos e)`` (+Y up, ``a = 0`` → −Z)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.sin(a) * math.cos(e), math.sin(e), -math.cos(a) * math.cos(e)])


def _sky(d: NDArray[np.float64], zenith: NDArray[np.float64], horizon: NDArray[np.float64],
         ground: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sky radiance for unit directions ``d`` (..., 3): zenith→horizon gradient above, darker ground below."""
    y = d[..., 1:2]
    up = np.clip(y, 0.0, 1.0)
    t = (1.0 - up) ** 3  # 0 at the zenith, 1 at the horizon, horizon colour dominates low down
    sky = zenith + (horizon - zenith) * t
    # below the horizon: ground colour, blended with a dimmed horizon over the first ~7°
    down = np.clip(-y * 8.0, 0.0, 1.0)
    below = 0.5 * horizon + (ground - 0.5 * horizon) * down
    return np.where(y >= 0.0, sky, below)


def make_envmap(
    path: str | os.PathLike[str],
    *,
    width: int = 256,
    height: int = 128,
    sun_elevation_deg: float = 35.0,
    sun_azimuth_deg: float = SUN_AZIMUTH_DEG,
    sun_radius_deg: float = 2.5,
    sun_intensity: float = 800.0,
    zenith_rgb: tuple[float, float, float] = (0.20, 0.35, 0.80),
    horizon_rgb: tuple[float, float, float] = (0.80, 0.85, 0.95),
    ground_rgb: tuple[float, float, float] = (0.12, 0.11, 0.10),
    sun_rgb: tuple[float, float, float] = (1.0, 0.95, 0.85),
    attrs: Mapping[str, str] | None = None,
) -> None:
    """Write a lat-long sky environment map for Mitsuba's ``envmap`` emitter (EXR, float32).

    Sky: ``zenith_rgb`` at the zenith fading to ``horizon_rgb`` at the horizon
    (radiance, linear RGB); below the horizon ``ground_rgb`` (darker).  Sun:
    a disk of angular radius ``sun_radius_deg`` centred on
    :func:`sun_direction` ``(sun_elevation_deg, sun_azimuth_deg)`` with
    radiance ``sun_intensity · sun_rgb`` added to the sky; each pixel's sun
    coverage is the fraction of a 4 × 4 grid of sub-pixel directions inside
    the disk, so the disk is antialiased and its brightest pixel is the one
    nearest the sun direction.  Pixel directions follow Mitsuba's convention
    (:func:`envmap_pixel_directions`), so with the emitter's default
    ``to_world`` the map's up is the scene's +Y.  Deterministic: the same
    arguments give the same bytes.  ``attrs`` are extra EXR header strings;
    the sun parameters are recorded too.
    """
    if not (-90.0 <= sun_elevation_deg <= 90.0):
        raise ValueError(f"sun_elevation_deg must be in [-90, 90], got {sun_elevation_deg}")
    if not (0.0 < sun_radius_deg < 90.0):
        raise ValueError(f"sun_radius_deg must be in (0, 90), got {sun_radius_deg}")
    if not (sun_intensity >= 0.0 and math.isfinite(sun_intensity)):
        raise ValueError(f"sun_intensity must be finite and >= 0, got {sun_intensity}")
    zen, hor, gnd, sun_c = (np.asarray(c, dtype=np.float64) for c in
                            (zenith_rgb, horizon_rgb, ground_rgb, sun_rgb))
    for name, c in (("zenith_rgb", zen), ("horizon_rgb", hor), ("ground_rgb", gnd), ("sun_rgb", sun_c)):
        if c.shape != (3,) or not np.isfinite(c).all() or (c < 0).any():
            raise ValueError(f"{name} must be three finite non-negative numbers, got {c.tolist()}")

    d = envmap_pixel_directions(width, height)
    image = _sky(d, zen, hor, gnd)

    # sun coverage: 4 × 4 sub-pixel directions over each pixel's footprint
    # (rows span ±½ row around θ_r, columns ±½ column around φ_c)
    n_sub = 4
    offs = (np.arange(n_sub) + 0.5) / n_sub - 0.5
    s = sun_direction(sun_elevation_deg, sun_azimuth_deg)
    cos_r = math.cos(math.radians(sun_radius_deg))
    rows = np.arange(height)[:, None] + offs[None, :]  # (H, n_sub)
    cols = np.arange(width)[:, None] + 0.5 + offs[None, :]  # (W, n_sub)
    theta = np.clip(np.pi * rows / (height - 1), 0.0, np.pi)
    phi = 2.0 * np.pi * cols / width
    st, ct = np.sin(theta), np.cos(theta)  # (H, n)
    sp, cp = np.sin(phi), np.cos(phi)  # (W, n)
    # dot(d, s) for every (row, sub-row, column, sub-column)
    dot = (sp[None, None, :, :] * st[:, :, None, None] * s[0]
           + ct[:, :, None, None] * s[1]
           - cp[None, None, :, :] * st[:, :, None, None] * s[2])
    coverage = (dot >= cos_r).mean(axis=(1, 3))  # (H, W)
    image = image + coverage[..., None] * (sun_intensity * sun_c)

    info = {
        "envmap_kind": "brdfpipe sky (lat-long, Mitsuba envmap convention, +Y up)",
        "sun_elevation_deg": f"{sun_elevation_deg:g}",
        "sun_azimuth_deg": f"{sun_azimuth_deg:g}",
        "sun_radius_deg": f"{sun_radius_deg:g}",
        "sun_intensity": f"{sun_intensity:g}",
    }
    write_exr(path, image.astype(np.float32), attrs={**info, **dict(attrs or {})})


# --------------------------------------------------------------------------
# Scene
# --------------------------------------------------------------------------


def scene_dict(
    bsdf: Mapping[str, Any],
    *,
    envmap: str | os.PathLike[str],
    resolution: tuple[int, int] = (256, 192),
    max_depth: int = 6,
    spp: int = 64,
    seed: int = 0,
    emitters: bool = True,
) -> dict[str, Any]:
    """The preview scene as a dictionary for ``mi.load_dict`` (layout in the module docstring).

    ``bsdf`` is the material of the preview object (a Mitsuba bsdf
    dictionary, e.g. ``{"type": "roughplastic"}`` or the ``merl`` plugin's);
    it is the only thing that differs between materials.  ``resolution`` is
    ``(width, height)`` in pixels; ``envmap`` the lat-long EXR
    (:func:`make_envmap`); ``emitters`` adds the area light.  ``spp`` and
    ``seed`` set the ``independent`` sampler (:func:`render_to_exr`
    overrides both per pass).  Needs a Mitsuba variant (:func:`set_variant`)
    because transforms are Mitsuba objects.
    """
    width, height = (int(v) for v in resolution)
    if width < 1 or height < 1:
        raise ValueError(f"resolution must be two positive integers, got {resolution}")
    if max_depth < 1 and max_depth != -1:
        raise ValueError(f"max_depth must be >= 1 (or -1 for unlimited), got {max_depth}")
    if spp < 1:
        raise ValueError(f"spp must be >= 1, got {spp}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if not isinstance(bsdf, Mapping) or "type" not in bsdf:
        raise ValueError(f"bsdf must be a Mitsuba bsdf dictionary with a 'type', got {bsdf!r}")
    envmap = Path(envmap)
    if not envmap.is_file():
        raise FileNotFoundError(f"{envmap}: environment map not found")
    # Mitsuba reads the file itself: a map made by make_envmap is checked against its digest first
    # (a damaged one is an ExrError naming it); a user's own HDRI carries none and is taken as it is
    read_exr(envmap, require=False)
    mi = _mitsuba()
    T = mi.ScalarTransform4f

    material = {"type": "ref", "id": "material"}
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(max_depth)},
        "sensor": {
            "type": "perspective",
            "fov": 40.0,
            "fov_axis": "x",
            "near_clip": 0.01,
            "far_clip": 100.0,
            "to_world": T().look_at(origin=[0.0, 2.3, 6.0], target=[0.0, 0.75, 0.0], up=[0.0, 1.0, 0.0]),
            "sampler": {"type": "independent", "sample_count": int(spp), "seed": int(seed)},
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "pixel_format": "rgb",
                "component_format": "float32",
                "rfilter": {"type": "box"},
            },
        },
        "material": dict(bsdf, id="material"),
        "ground": {
            "type": "rectangle",
            "to_world": T().rotate([1.0, 0.0, 0.0], -90.0).scale([25.0, 25.0, 1.0]),
            "bsdf": {
                "type": "diffuse",
                "reflectance": {
                    "type": "checkerboard",
                    "color0": {"type": "rgb", "value": [0.7, 0.7, 0.7]},
                    "color1": {"type": "rgb", "value": [0.3, 0.3, 0.3]},
                    "to_uv": T().scale([50.0, 50.0, 1.0]),
                },
            },
        },
        "object_sphere": {"type": "sphere", "center": [0.0, 1.0, 0.0], "radius": 1.0, "bsdf": material},
        "object_cube": {
            "type": "cube",
            "to_world": T().translate([-1.55, 0.35, 0.75]).rotate([0.0, 1.0, 0.0], 30.0).scale(0.35),
            "bsdf": material,
        },
        "object_cylinder": {
            "type": "cylinder",
            "p0": [1.45, 0.0, 0.6],
            "p1": [1.45, 0.9, 0.6],
            "radius": 0.32,
            "bsdf": material,
        },
        "object_cylinder_cap": {
            "type": "disk",
            "to_world": T().translate([1.45, 0.9, 0.6]).rotate([1.0, 0.0, 0.0], -90.0).scale(0.32),
            "bsdf": material,
        },
        "sky": {"type": "envmap", "filename": str(envmap)},
    }
    if emitters:
        scene["area_light"] = {
            "type": "rectangle",
            "to_world": T().look_at(origin=[-3.5, 4.5, 3.0], target=[0.0, 0.8, 0.0], up=[0.0, 1.0, 0.0])
            .scale([0.75, 0.75, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [20.0, 19.0, 17.0]}},
        }
    return scene


# --------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------


def pass_seeds(spp: int, seed: int, pass_spp: int = DEFAULT_PASS_SPP) -> list[tuple[int, int]]:
    """``(seed, spp)`` of each pass of a render of ``spp`` samples: pass ``p`` uses seed ``seed·1000 + p``.

    Passes have ``pass_spp`` samples except possibly the last (the
    remainder).  At most 1000 passes (ValueError otherwise), so two renders
    with different seeds never share a pass seed; every pass seed fits
    Mitsuba's 32-bit seed (``seed`` ≤ :data:`MAX_SEED`, ValueError otherwise).
    """
    if spp < 1 or pass_spp < 1:
        raise ValueError(f"spp and pass_spp must be >= 1, got {spp}, {pass_spp}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    n = -(-spp // pass_spp)
    if n > _MAX_PASSES:
        raise ValueError(f"{spp} spp in passes of {pass_spp} is {n} passes; at most {_MAX_PASSES} "
                         f"(spp ≤ {_MAX_PASSES * pass_spp})")
    if seed * _MAX_PASSES + n - 1 > MITSUBA_UINT32_MAX:
        raise ValueError(f"seed {seed}: the pass seeds seed·{_MAX_PASSES} + p would exceed Mitsuba's 32-bit "
                         f"sampler seed; at most {MAX_SEED}")
    return [(seed * _MAX_PASSES + p, min(pass_spp, spp - p * pass_spp)) for p in range(n)]


def auto_pass_spp(width: int, height: int, spp: int) -> int:
    """Samples per pixel of each pass of :func:`render_material`: :data:`DEFAULT_PASS_SPP`, or, where an
    image smaller than 256 × 192 then needs fewer passes, the largest power of two whose pass holds
    at most :data:`PASS_SAMPLES` samples (never more than ``spp``).

    A pass's memory and work grow with its samples, so a small image's pass is no larger than the
    default image's; fewer passes save the per-pass trace and launch.  The pass size is recorded in
    each EXR (``pass_spp``) and changes the sample stream, so it is part of what a render means.
    """
    pixels, spp = max(1, int(width) * int(height)), max(1, int(spp))
    p = DEFAULT_PASS_SPP
    while pixels * p * 2 <= PASS_SAMPLES:
        p *= 2
    if -(-spp // p) == -(-spp // DEFAULT_PASS_SPP):  # no pass saved: the default passes, as always
        return DEFAULT_PASS_SPP
    return min(p, spp)


def render_memory(width: int, height: int) -> int:
    """Peak bytes of one render of ``width`` × ``height`` pixels (:data:`RENDER_BYTES_PER_PIXEL`)."""
    return RENDER_BASE_BYTES + RENDER_BYTES_PER_PIXEL * int(width) * int(height)


def check_render_settings(
    resolution: tuple[int, int], spp: int, seed: int, max_depth: int, *, memory: int | None = None,
    names: Mapping[str, str] | None = None,
) -> None:
    """ValueError naming the setting unless Mitsuba and this machine can render it.

    ``spp`` ≤ :data:`MAX_SPP`, ``0 ≤ seed`` ≤ :data:`MAX_SEED`, ``1 ≤
    max_depth`` ≤ :data:`MAX_DEPTH`, and the render's memory
    (:func:`render_memory`) within the machine's physical memory
    (``memory`` overrides it).  ``names`` maps ``resolution``, ``spp``,
    ``seed``, ``max_depth`` to the names the message uses (CLI options,
    config keys).
    """
    from brdfpipe.core import resources

    nm = {"resolution": "resolution", "spp": "spp", "seed": "seed", "max_depth": "max_depth", **(names or {})}
    w, h = (int(v) for v in resolution)
    if w < 1 or h < 1:
        raise ValueError(f"{nm['resolution']} {w} {h}: width and height must be ≥ 1")
    if not 1 <= int(spp) <= MAX_SPP:
        raise ValueError(f"{nm['spp']} {spp}: at most {MAX_SPP} samples per pixel ({_MAX_PASSES} passes of "
                         f"{DEFAULT_PASS_SPP}, each with its own seed)")
    if not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"{nm['seed']} {seed}: must be in [0, {MAX_SEED}] (pass p renders with seed "
                         f"seed·{_MAX_PASSES} + p, and Mitsuba's seed is a 32-bit unsigned integer)")
    if not 1 <= int(max_depth) <= MAX_DEPTH:
        raise ValueError(f"{nm['max_depth']} {max_depth}: must be in [1, {MAX_DEPTH}] (Mitsuba's path depth "
                         "is a 32-bit unsigned integer)")
    resources.check_memory(
        render_memory(w, h), what=f"{nm['resolution']} {w} {h}", memory=memory,
        how=f"{resources.format_bytes(RENDER_BASE_BYTES)} + {RENDER_BYTES_PER_PIXEL} B per pixel × {w * h} pixels",
    )


def _check_attrs(out: Path, attrs: Mapping[str, str] | None, auto: Mapping[str, str]) -> None:
    clash = sorted(set(auto) & set(attrs or {}))
    if clash:
        raise ValueError(f"{out}: attrs may not set {', '.join(clash)} (render_to_exr records them)")


def _render_passes(
    scene: Mapping[str, Any],
    out: Path,
    passes: list[tuple[int, int]],
    say: Callable[[str], None],
) -> NDArray[np.float64]:
    """Load ``scene`` and render it in ``passes``; the sample-weighted mean, ``(H, W, C)`` float64.

    ``C`` is every channel ``mi.render`` returns (R, G, B, then the
    integrator's AOVs).  Non-finite values raise :class:`SceneError` naming ``out``.
    """
    from brdfpipe.rendering import render

    mi = _mitsuba()
    spp = sum(n for _, n in passes)
    try:
        loaded = render.load_scene(scene)
    except Exception as exc:
        raise SceneError(f"{out}: Mitsuba could not load the scene: {exc}") from exc
    total: NDArray[np.float64] | None = None
    for p, (pass_seed, n) in enumerate(passes):
        try:
            img = np.array(mi.render(loaded, seed=pass_seed, spp=n), dtype=np.float64)
        except Exception as exc:
            cause = exc.__cause__ if exc.__cause__ is not None else exc  # mi.render wraps Python errors
            raise SceneError(f"{out}: Mitsuba render pass {p + 1}/{len(passes)} failed: {cause}") from exc
        if img.ndim != 3 or img.shape[2] < 3:
            raise SceneError(f"{out}: render returned an image of shape {img.shape}, expected (H, W, 3)")
        total = img * n if total is None else total + img * n
        say(f"{out.name}: pass {p + 1}/{len(passes)} done ({n} spp, seed {pass_seed}, "
            f"{sum(k for _, k in passes[: p + 1])}/{spp} spp)")
    assert total is not None
    mean = total / spp
    bad = ~np.isfinite(mean.astype(np.float32))
    if bad.any():
        raise SceneError(f"{out}: render produced {int(bad.sum())} non-finite value(s) (NaN or Inf); not written")
    return mean


def _auto_attrs(spp: int, seed: int, pass_spp: int) -> dict[str, str]:
    mi = _mitsuba()
    return {
        "spp": str(spp),
        "seed": str(seed),
        "pass_spp": str(pass_spp),
        "mitsuba_variant": str(mi.variant()),
        "mitsuba_version": str(mi.__version__),
    }


def render_to_exr(
    scene: Mapping[str, Any],
    out: str | os.PathLike[str],
    *,
    spp: int,
    seed: int,
    attrs: Mapping[str, str] | None = None,
    progress: Callable[[str], None] | None = None,
    pass_spp: int = DEFAULT_PASS_SPP,
) -> NDArray[np.float32]:
    """Render a scene dictionary and write the image to ``out`` as a float32 EXR (atomically).

    The variant must already be set (:func:`set_variant`).  The render is
    split into passes of at most ``pass_spp`` samples per pixel; pass ``p``
    uses sampler seed ``seed·1000 + p`` (:func:`pass_seeds`); the image is
    the sample-weighted mean of the passes (accumulated in float64, stored as
    float32), so it is an ``spp``-sample estimate.  One line per pass goes to
    ``progress`` (or the ``brdfpipe.rendering.scene`` logger).  The EXR header records
    ``spp``, ``seed``, ``pass_spp``, ``mitsuba_variant`` and
    ``mitsuba_version`` plus ``attrs`` (which may not override those).  The
    same scene, ``spp``, ``seed`` and ``pass_spp`` on the same variant give
    the same bytes.  Returns the ``(H, W, 3)`` float32 image (R, G, B; AOVs
    are dropped).  A scene that fails to load or render raises
    :class:`SceneError`; a render with NaN/Inf pixels raises
    :class:`SceneError` naming ``out`` (nothing is written).
    """
    out = Path(out)
    passes = pass_seeds(spp, seed, pass_spp)
    auto = _auto_attrs(spp, seed, pass_spp)
    _check_attrs(out, attrs, auto)
    say = progress if progress is not None else logger.info
    image = _render_passes(scene, out, passes, say)[..., :3].astype(np.float32)
    write_exr(out, image, attrs={**dict(attrs or {}), **auto})
    return image


def render_split_to_exr(
    scene: Mapping[str, Any],
    out: str | os.PathLike[str] | None,
    *,
    out_one: str | os.PathLike[str] | None = None,
    out_mask: str | os.PathLike[str] | None = None,
    spp: int,
    seed: int,
    attrs: Mapping[str, str] | None = None,
    progress: Callable[[str], None] | None = None,
    pass_spp: int = DEFAULT_PASS_SPP,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """:func:`render_to_exr` for a scene with the ``bouncesplit`` integrator: one render, up to three EXRs.

    Writes the whole image ``I`` to ``out``, its ``I¹⁻`` part (light paths
    with at most one scattering on the material, :mod:`brdfpipe.rendering.bounce`) to
    ``out_one`` and the object mask (coverage of the material's first hits,
    repeated in R, G, B) to ``out_mask``, each if given (at least one must
    be), from the **same** passes (one render).  Headers as :func:`render_to_exr`, plus ``image``
    saying which part the file holds.  Returns ``(I, I¹⁻)`` as ``(H, W, 3)``
    float32.  :class:`SceneError` if the scene's integrator gives no split
    (not ``bouncesplit``).
    """
    from brdfpipe.rendering import bounce

    given = [Path(p) for p in (out, out_one, out_mask) if p is not None]
    if not given:
        raise ValueError("render_split_to_exr: give at least one of out, out_one, out_mask")
    label = given[0]
    passes = pass_seeds(spp, seed, pass_spp)
    auto = _auto_attrs(spp, seed, pass_spp)
    _check_attrs(label, attrs, auto)
    say = progress if progress is not None else logger.info
    img = _render_passes(scene, label, passes, say)
    if img.shape[2] != 3 + len(bounce.AOV_NAMES):
        raise SceneError(f"{label}: the render has {img.shape[2]} channels, expected "
                         f"{3 + len(bounce.AOV_NAMES)}: the scene's integrator must be "
                         f"{bounce.PLUGIN_NAME!r} (brdfpipe.rendering.bounce)")
    whole = img[..., :3].astype(np.float32)
    one = img[..., 3:6].astype(np.float32)
    base = {**dict(attrs or {}), **auto}
    if out is not None:
        write_exr(out, whole, attrs={**base, "image": "I (every light path)"})
    if out_one is not None:
        write_exr(out_one, one, attrs={**base, "image": "I1- (light paths with at most one scattering "
                                                           "on the material)"})
    if out_mask is not None:
        mask = np.repeat(img[..., 6:7], 3, axis=2).astype(np.float32)
        write_exr(out_mask, mask, attrs={**base, "image": "object mask (fraction of camera rays whose "
                                                            "first hit is on the material)"})
    return whole, one


def render_material(
    merl_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    out_one: str | os.PathLike[str] | None = None,
    envmap: str | os.PathLike[str],
    variant: str,
    resolution: tuple[int, int],
    spp: int,
    max_depth: int,
    seed: int,
    attrs: Mapping[str, str] | None = None,
    progress: Callable[[str], None] | None = None,
    threads: int | None = None,
) -> NDArray[np.float32]:
    """Render the preview scene with a MERL material (the ``merl`` plugin) to an EXR.

    One render of the workflow's ``prerender_materials`` jobs (:func:`render_materials`) and path points' jobs (:func:`render_points`).
    The integrator is ``bouncesplit`` (:mod:`brdfpipe.rendering.bounce`: Mitsuba's
    ``path`` with the same ``max_depth``, Russian roulette and sampler draws,
    so the whole image is ``path``'s), so one render gives the whole image
    ``I`` (written to ``out``) and its ``I¹⁻`` part (paths with at most one
    scattering on the material; written to ``out_one`` if given) — see
    :func:`render_split_to_exr`.  ``variant`` is validated by
    :func:`brdfpipe.rendering.render.use_variant` (RenderError for an unknown or
    unavailable one); a missing or corrupt MERL file raises an error naming
    it before anything is rendered.  ``threads``: CPU threads of Dr.Jit's
    LLVM backend (the job's declared threads; ``None`` leaves Dr.Jit's
    default, every core of the machine).  Passes of :func:`auto_pass_spp` samples
    per pixel.  Returns the whole image.
    """
    from brdfpipe.rendering import bounce, render

    render.use_variant(variant)
    if threads is not None:
        render.set_cpu_threads(threads)
    render.register_merl_bsdf()
    bounce.register_bounce_integrator()
    scene = scene_dict(
        render.merl_bsdf(merl_path), envmap=envmap, resolution=tuple(resolution),  # type: ignore[arg-type]
        max_depth=max_depth, spp=spp, seed=seed,
    )
    scene["integrator"] = bounce.bounce_integrator(max_depth)
    meta = {"material_file": Path(merl_path).name, "integrator": bounce.PLUGIN_NAME, **(attrs or {})}
    logger.info("rendering %s: %dx%d, %d spp, max_depth %d, seed %d, %s",
                Path(merl_path).name, resolution[0], resolution[1], spp, max_depth, seed, variant)
    whole, _ = render_split_to_exr(scene, out, out_one=out_one, spp=spp, seed=seed, attrs=meta,
                                   progress=progress, pass_spp=auto_pass_spp(resolution[0], resolution[1], spp))
    return whole


def render_materials(
    merl_paths: Sequence[str | os.PathLike[str]],
    outs: Sequence[Sequence[str | os.PathLike[str]]],
    *,
    outs_one: Sequence[Sequence[str | os.PathLike[str]]],
    materials: Sequence[str],
    settings: Sequence[tuple[Sequence[int], int]],
    database: str | None = None,
    attrs: Mapping[str, str] | None = None,
    progress: Callable[[str], None] | None = None,
    **kwargs: Any,
) -> None:
    """:func:`render_material` for many materials and render settings in one process (the ``prerender_materials`` jobs).

    ``settings[s]`` is ``(resolution, spp)`` of scene folder ``s``;
    ``merl_paths[k]`` is rendered with each of them to ``outs[s][k]`` (whole
    image) and ``outs_one[s][k]`` (its ``I¹⁻`` part), with ``material =
    materials[k]`` added to ``attrs`` in the headers; every other keyword
    argument is :func:`render_material`'s, the same for all.  Mitsuba, its
    variant, the plugins and the compiled kernels are set up once, and a
    material's table is loaded and its sampling fitted once for all its
    settings (materials in the outer loop): only the material changes between
    renders (what that saves: ``benches/bench_render_batch.py``).  Each image is exactly
    the one :func:`render_material` gives alone (same bytes).  Before the
    first render every source is checked to be the material it is rendered
    as, of ``database`` when given (recorded in the headers too): its
    provenance mark (:func:`brdfpipe.data.provenance.check_sources`), so a
    table renamed over another material's file is refused, naming it; a
    source that fails to load stops the batch with the error naming it.
    """
    n = len(merl_paths)
    if len(materials) != n:
        raise ValueError(f"render_materials: {len(materials)} materials for {n} MERL files")
    if len(set(materials)) != n:
        raise ValueError("render_materials: materials repeat an entry")
    for name, table in (("outs", outs), ("outs_one", outs_one)):
        if len(table) != len(settings) or any(len(row) != n for row in table):
            raise ValueError(f"render_materials: {name} needs one list of {n} files per setting "
                             f"({len(settings)} settings)")
    files = [str(f) for table in (outs, outs_one) for row in table for f in row]
    if len(set(files)) != len(files):
        raise ValueError("render_materials: an output file is named twice")
    provenance.check_sources(list(zip(materials, merl_paths)), database=database, what="MERL file")
    if database is not None:
        attrs = {**(attrs or {}), "database": database}
    say = progress if progress is not None else logger.info
    start = time.perf_counter()
    for k, (src, material) in enumerate(zip(merl_paths, materials)):
        for s, (resolution, spp) in enumerate(settings):
            render_material(src, outs[s][k], out_one=outs_one[s][k], resolution=tuple(resolution), spp=int(spp),
                            attrs={**(attrs or {}), "material": material}, progress=progress, **kwargs)
        say(f"material {k + 1}/{n} rendered: {material} ({time.perf_counter() - start:.1f} s so far)")


def render_material_seeds(
    merl_path: str | os.PathLike[str],
    outs: list[str | os.PathLike[str]],
    *,
    seeds: list[int],
    outs_one: list[str | os.PathLike[str]] | None = None,
    attrs: Mapping[str, str] | None = None,
    **kwargs: Any,
) -> None:
    """:func:`render_material` once per seed (``outs[k]``, ``outs_one[k]`` with ``seeds[k]``), in one process (one JIT warm-up)."""
    if len(outs) != len(seeds) or len(set(seeds)) != len(seeds):
        raise ValueError(f"need one distinct seed per output, got seeds {seeds} for {len(outs)} outputs")
    if outs_one is not None and len(outs_one) != len(outs):
        raise ValueError(f"need one I1- output per output, got {len(outs_one)} for {len(outs)}")
    ones = list(outs_one) if outs_one is not None else [None] * len(outs)
    for out, one, seed in zip(outs, ones, seeds):
        render_material(merl_path, out, out_one=one, seed=seed,
                        attrs={**(attrs or {}), "seed_role": f"seed {seed}"}, **kwargs)


def render_points(
    merl_paths: Sequence[str | os.PathLike[str]],
    *,
    outs: Sequence[Sequence[str | os.PathLike[str]]],
    outs_one: Sequence[Sequence[str | os.PathLike[str]]] | None,
    seeds: list[int],
    labels: Sequence[str],
    derived: bool = False,
    label_key: str = "path_point",
    attrs: Mapping[str, str] | None = None,
    progress: Callable[[str], None] | None = None,
    **kwargs: Any,
) -> None:
    """:func:`render_material_seeds` for many derived materials in one process (path points, reconstructions).

    ``merl_paths[k]`` is rendered once per seed, ``outs[k][s]`` and
    ``outs_one[k][s]`` (None: no I¹⁻ files) with ``seeds[s]``, and
    ``label_key = labels[k]`` in the headers; the other keywords are
    :func:`render_material`'s.  One Mitsuba start for all of them (the
    points of a path come from one interpolation job, so they change
    together); each image is the one the table gives alone.  Every source is
    checked to exist before the first render and, with ``derived`` (the
    workflow's interpolated and reconstructed tables), to be the derived
    table its file name says (its provenance mark).
    """
    n = len(merl_paths)
    for name, values in (("outs", outs), ("outs_one", outs_one), ("labels", labels)):
        if values is not None and len(values) != n:
            raise ValueError(f"render_points: {len(values)} {name} for {n} MERL files")
    if any(len(o) != len(seeds) for o in list(outs) + list(outs_one or [])):
        raise ValueError(f"render_points: every point needs one output per seed ({len(seeds)})")
    if len(set(labels)) != len(labels):
        raise ValueError("render_points: labels repeat an entry")
    provenance.check_sources([(provenance.output_name(p), p) for p in merl_paths],
                             database="derived" if derived else None, what="derived MERL file")
    say = progress if progress is not None else logger.info
    start = time.perf_counter()
    for k, (src, label) in enumerate(zip(merl_paths, labels)):
        render_material_seeds(src, list(outs[k]), outs_one=list(outs_one[k]) if outs_one is not None else None,
                              seeds=seeds, attrs={**(attrs or {}), label_key: label}, progress=progress, **kwargs)
        say(f"{k + 1}/{n} rendered: {label} ({time.perf_counter() - start:.1f} s so far)")


def render_object_mask(
    out: str | os.PathLike[str],
    *,
    envmap: str | os.PathLike[str],
    variant: str,
    resolution: tuple[int, int],
    spp: int,
    seed: int,
    attrs: Mapping[str, str] | None = None,
    threads: int | None = None,
) -> NDArray[np.float32]:
    """The preview object's mask: per pixel, the fraction of camera rays whose first hit is the object.

    The workflow's ``object_mask`` job (the pixels over which
    :func:`brdfpipe.rendering.blend.bounce_shares` measures the object's ``I²⁺``
    share).  Rendered with the ``bouncesplit`` integrator (``max_depth`` 1)
    and the same camera sampling as the pre-renders (``spp``, ``seed``); the
    material is irrelevant (a grey ``diffuse``).  Written to ``out`` as an
    EXR with the mask in R, G and B; returns it, ``(H, W)``.
    """
    from brdfpipe.rendering import bounce, render

    render.use_variant(variant)
    if threads is not None:
        render.set_cpu_threads(threads)
    bounce.register_bounce_integrator()
    grey = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
    scene = scene_dict(grey, envmap=envmap, resolution=tuple(resolution),  # type: ignore[arg-type]
                       max_depth=1, spp=spp, seed=seed)
    scene["integrator"] = bounce.bounce_integrator(1)
    render_split_to_exr(scene, None, out_mask=out, spp=spp, seed=seed,
                        attrs={"integrator": bounce.PLUGIN_NAME, **(attrs or {})})

    return read_exr(out)[..., 0]
