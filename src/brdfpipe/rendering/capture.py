"""Closed-loop capture (Xu et al. 2016 §7, simulated): photograph a flat sample, read the BRDF off the image.

For a material (a MERL-format ``.binary`` file) and one acquisition
configuration (light and camera unit vectors, as in a directions file of
:mod:`brdfpipe.acquisition.optimize`), :func:`render_capture` renders with
Mitsuba 3 what the near-field camera of that configuration sees:

* the sample: a flat ``rectangle`` in z = 0 (half-size 2ν, larger than the
  disk of radius ν = tan(α/2) the set-up uses) with the project's ``merl``
  BSDF (:mod:`brdfpipe.rendering.render`);
* the camera: a pinhole at C = wo (R = 1) looking at the origin, ``up`` the
  frame's e_u, square film of the set-up's frame
  (:func:`brdfpipe.registry.nearfield.image_frame`: the grid × grid lattice of
  the acquisition geometry inside the smallest odd image centred on the
  optical axis, pitch :func:`brdfpipe.registry.nearfield.pixel_pitch`, which
  frames the whole disk from every direction); box pixel filter, ``spp``
  uniformly jittered samples per pixel (the pixel *footprint* is averaged);
* the light: a ``point`` emitter at L = D·wi (D = ``light_distance``, in units
  of R) of intensity D² (irradiance ≈ 1 at the disk centre under normal
  incidence); ``light_distance`` = ``inf`` gives a ``directional`` emitter of
  irradiance 1 (Xu's distant light);
* the ``direct`` integrator (one emitter sample, no BSDF sample: a point or
  directional light is a delta, only emitter sampling reaches it), so the
  render has no Monte Carlo noise except the footprint average.

A sensor (:class:`Sensor`) then turns radiance into a photograph: exposures
of relative length ``brackets`` (one for a single shot, several for Xu §7's
HDR bracketing), scaled so that the brightest disk pixel collects
``peak_level`` of the full well in the *shortest* exposure; per exposure
Poisson photon noise, Gaussian read noise, saturation at the full well and
an ADC of ``bits``; the HDR merge Σ eₖ / Σ tₖ over each pixel's unsaturated
exposures; pixels saturated in every exposure are masked.  ``enabled:
false`` keeps the render as is.

:func:`observations_from_image` turns an image into the observation table
of :func:`brdfpipe.acquisition.reconstruct.load_observations` (NPZ with
``wi``, ``wo``, ``rgb``): for every lattice pixel whose centre ray hits the
disk, wo = normalize(C − P), wi = normalize(L − P) (or wi for a distant
light) and the BRDF value pixel / E with E = I·cos θi/d² (point) or cos θi
(directional), averaged over the pixel's footprint; pixels with a direction
below the horizon, a non-positive value in any channel, an SNR below
``min_snr`` or saturated everywhere are masked, and counted.  Unmeasured cells are the reconstruction's to drop
(cells that are not model columns).

:func:`capture_to_files` is the workflow's call: for one material and the
given directions files and set sizes n, the EXR of every image (noiseless
render and sensor photograph) and two observation tables per (file, n),
read off each.  The cells a lattice pixel predicts (the optimiser's geometry, distant light)
are :func:`brdfpipe.acquisition.geometry.observation_cells`; the tests check
that a render of a cell-index table decodes to them.
"""

from __future__ import annotations

import json
import logging
import math
import os
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.data import provenance
from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.registry import nearfield
from brdfpipe.core.exr import write_exr

__all__ = [
    "Sensor",
    "CaptureSettings",
    "PixelGeometry",
    "pixel_geometry",
    "render_capture",
    "expose",
    "observations_from_image",
    "read_configurations",
    "capture_to_files",
    "capture_materials_to_file",
    "MANY_FORMAT",
    "output_layout",
    "OBSERVATION_KEYS",
    "MAX_FULL_WELL",
    "MAX_BRACKET",
    "MAX_BRACKETS",
]

logger = logging.getLogger("brdfpipe.rendering.capture")

F64 = NDArray[np.float64]

#: Arrays of an observation table (NPZ) written by :func:`capture_to_files`.
OBSERVATION_KEYS: Final = ("wi", "wo", "rgb", "image", "row", "col")
#: Largest full well (electrons) and relative exposure time of a bracket: a pixel's expected photon count,
#: up to full_well × bracket ≤ 1e15, must stay within NumPy's Poisson sampler (it refuses λ above ~9.2e18,
#: "lam value too large").  The config schema's closed_loop.sensor maxima are these (a test keeps them equal).
MAX_FULL_WELL: Final = 1.0e9
MAX_BRACKET: Final = 1.0e6
#: Most brackets (each is one more exposure of every image; the schema's maxItems).
MAX_BRACKETS: Final = 16
_SAMPLE_HALF_SIZE: Final = 2.0  # the rectangle's half-size, in units of ν
_FOOTPRINT_SUB: Final = 8  # sub × sub rays per pixel average the irradiance over its footprint


@dataclass(frozen=True)
class Sensor:
    """The camera's sensor (see the module docstring); ``enabled = False``: the render as is."""

    enabled: bool = True
    full_well: float = 20000.0  # electrons at saturation
    read_noise: float = 5.0  # electrons RMS per exposure
    bits: int = 12  # ADC
    peak_level: float = 0.8  # brightest disk pixel of the shortest exposure, fraction of the full well
    brackets: tuple[float, ...] = (1.0,)  # relative exposure times (≥ 1 each; the shortest is 1)

    def __post_init__(self) -> None:
        object.__setattr__(self, "brackets", tuple(float(b) for b in self.brackets))
        checks = {
            "full_well": 0 < self.full_well <= MAX_FULL_WELL,
            "read_noise": self.read_noise >= 0,
            "bits": 1 <= int(self.bits) <= 32,
            "peak_level": 0 < self.peak_level <= 1,
            "brackets": 1 <= len(self.brackets) <= MAX_BRACKETS and all(1.0 <= b <= MAX_BRACKET for b in self.brackets)
            and min(self.brackets) == 1.0,
        }
        for key, ok in checks.items():
            if not ok:
                raise ValueError(f"sensor.{key}: invalid value {getattr(self, key)!r}")


@dataclass(frozen=True)
class CaptureSettings:
    """The set-up (fov, grid) and the capture's render and sensor settings."""

    fov_deg: float
    grid: int
    spp: int = 64
    seed: int = 0
    light_distance: float = 20.0  # in units of the camera distance R; inf: directional light
    min_snr: float = 3.0
    sensor: Sensor = field(default_factory=Sensor)

    def __post_init__(self) -> None:
        nearfield.image_half_width(self.fov_deg)  # 0 < fov < 90
        if int(self.grid) < 1 or int(self.spp) < 1 or int(self.seed) < 0:
            raise ValueError(f"grid and spp must be ≥ 1 and seed ≥ 0, got {self.grid}, {self.spp}, {self.seed}")
        if not (self.light_distance > 1.0):
            raise ValueError(f"light_distance must exceed the camera distance 1 (or be inf), got {self.light_distance}")
        if not (math.isfinite(self.min_snr) and self.min_snr >= 0):
            raise ValueError(f"min_snr must be finite and ≥ 0, got {self.min_snr}")

    @property
    def nu(self) -> float:
        return nearfield.nu(self.fov_deg)

    @property
    def distant(self) -> bool:
        return math.isinf(self.light_distance)


def _unit(v: ArrayLike, name: str) -> F64:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all() or abs(np.linalg.norm(a) - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a unit 3-vector, got {v!r}")
    return a / np.linalg.norm(a)


@dataclass(frozen=True)
class PixelGeometry:
    """Per lattice pixel (grid × grid, lattice order a-major): where it sits in the image and what it sees.

    ``row``, ``col``: the pixel in the rendered (size × size) image;
    ``inside``: the centre ray hits the disk; ``wi``, ``wo``: light and view
    directions at the hit point P (wi per pixel for a point light);
    ``irradiance``: E = I·cos θi/d² (point) or cos θi (directional),
    averaged over the pixel's footprint (8 × 8 rays), as the render averages
    f·E over it (exact for a Lambertian sample).
    """

    size: int
    row: NDArray[np.intp]
    col: NDArray[np.intp]
    inside: NDArray[np.bool_]
    wi: F64
    wo: F64
    irradiance: F64


def _light_at(settings: CaptureSettings, wi_c: F64, P: F64) -> tuple[F64, F64]:
    """Light direction and irradiance (normal incidence 1 at the origin) at points P (n, 3) of the plane."""
    if settings.distant:
        wi = np.broadcast_to(wi_c, P.shape).copy()
        return wi, np.maximum(wi[:, 2], 0.0)
    D = float(settings.light_distance)
    to_light = D * wi_c - P
    d = np.linalg.norm(to_light, axis=1)
    wi = to_light / d[:, None]
    return wi, D * D * np.maximum(wi[:, 2], 0.0) / (d * d)


def pixel_geometry(settings: CaptureSettings, light: ArrayLike, camera: ArrayLike) -> PixelGeometry:
    """The :class:`PixelGeometry` of the camera at ``camera`` with the light towards ``light``."""
    wi_c, wo = _unit(light, "light"), _unit(camera, "camera")
    grid = int(settings.grid)
    size, offset = nearfield.image_frame(grid)
    step = nearfield.pixel_pitch(settings.fov_deg, grid)
    j = np.arange(grid)
    a, b = (x.ravel() for x in np.meshgrid(j, j, indexing="ij"))
    u = (a - grid // 2) * step
    v = (b - grid // 2) * step
    f, e_r, e_u = nearfield.camera_basis(wo)
    ray = f + u[:, None] * e_r + v[:, None] * e_u
    dz = ray[:, 2]
    hit = dz < 0.0
    t = np.where(hit, -wo[2] / np.where(hit, dz, -1.0), 0.0)
    P = wo + t[:, None] * ray
    P[:, 2] = 0.0
    inside = hit & (np.hypot(P[:, 0], P[:, 1]) <= settings.nu * (1.0 + 1e-12)) & (wo[2] > 0.0)
    view = wo - P
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    wi, _ = _light_at(settings, wi_c, P)
    # E averaged over each pixel's footprint (sub × sub rays), as the render averages f·E over it.
    sub = (np.arange(_FOOTPRINT_SUB) + 0.5) / _FOOTPRINT_SUB - 0.5
    du, dv = (x.ravel() * step for x in np.meshgrid(sub, sub, indexing="ij"))
    uu = u[:, None] + du[None, :]
    vv = v[:, None] + dv[None, :]
    rays = f + uu[..., None] * e_r + vv[..., None] * e_u  # (grid², sub², 3)
    rz = rays[..., 2]
    ok = rz < 0.0
    tt = np.where(ok, -wo[2] / np.where(ok, rz, -1.0), 0.0)
    Ps = wo + tt[..., None] * rays
    Ps[..., 2] = 0.0
    _, e_sub = _light_at(settings, wi_c, Ps.reshape(-1, 3))
    e_sub = np.where(ok.ravel(), e_sub, 0.0).reshape(ok.shape)
    irr = e_sub.mean(axis=1)
    return PixelGeometry(
        size=size,
        row=(size - 1 - offset - b).astype(np.intp),
        col=(offset + a).astype(np.intp),
        inside=inside,
        wi=wi,
        wo=view,
        irradiance=irr,
    )


def _scene(
    material: str | os.PathLike[str], settings: CaptureSettings, light: F64, camera: F64, centre_only: bool = False
) -> dict[str, Any]:
    import mitsuba as mi

    from brdfpipe.rendering import render

    T = mi.ScalarTransform4f
    size, _ = nearfield.image_frame(settings.grid)
    step = nearfield.pixel_pitch(settings.fov_deg, settings.grid)
    fov = math.degrees(2.0 * math.atan(0.5 * size * step))
    _, _, e_u = nearfield.camera_basis(camera)
    half = _SAMPLE_HALF_SIZE * settings.nu
    if settings.distant:
        emitter: dict[str, Any] = {"type": "directional", "direction": [float(-x) for x in light], "irradiance": 1.0}
    else:
        D = float(settings.light_distance)
        emitter = {"type": "point", "position": [float(D * x) for x in light], "intensity": D * D}
    return {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective",
            "fov": fov,
            "fov_axis": "x",
            "near_clip": 1e-3,
            "far_clip": 10.0,
            "to_world": T().look_at(origin=[float(x) for x in camera], target=[0.0, 0.0, 0.0],
                                    up=[float(x) for x in e_u]),
            "sampler": (
                {"type": "stratified", "sample_count": 1, "jitter": False}  # one ray through each pixel centre
                if centre_only
                else {"type": "independent", "sample_count": int(settings.spp)}
            ),
            "film": {
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "pixel_format": "rgb",
                "component_format": "float32",
                "rfilter": {"type": "box"},
            },
        },
        "sample": {
            "type": "rectangle",
            "to_world": T().scale([half, half, 1.0]),
            "bsdf": render.merl_bsdf(material),
        },
        "light": emitter,
    }


def render_capture(
    material: str | os.PathLike[str],
    settings: CaptureSettings,
    light: ArrayLike,
    camera: ArrayLike,
    *,
    seed: int,
    centre_only: bool = False,
) -> F64:
    """The noiseless render (size × size × 3, float64 radiance) of the sample seen by the configuration's camera.

    ``settings.spp`` samples spread over each pixel's footprint, or with
    ``centre_only`` one ray through each pixel centre (what the acquisition
    geometry models; for checking it).
    The Mitsuba variant must be set and the ``merl`` plugin registered
    (:func:`brdfpipe.rendering.render.use_variant`,
    :func:`~brdfpipe.rendering.render.register_merl_bsdf`).  A camera below
    the horizon gives a black image.
    """
    import mitsuba as mi

    from brdfpipe.rendering import render

    wi, wo = _unit(light, "light"), _unit(camera, "camera")
    size, _ = nearfield.image_frame(settings.grid)
    if wo[2] <= 0.0:
        return np.zeros((size, size, 3))
    scene = render.load_scene(_scene(material, settings, wi, wo, centre_only))
    spp = 1 if centre_only else int(settings.spp)
    img = np.array(mi.render(scene, seed=int(seed), spp=spp), dtype=np.float64)[..., :3]
    if not np.isfinite(img).all():
        raise RuntimeError(f"{material}: the capture render has non-finite pixels")
    return img


def expose(image: ArrayLike, inside: ArrayLike, sensor: Sensor, rng: np.random.Generator) -> tuple[F64, F64, NDArray[np.bool_]]:
    """The sensor's photograph of a radiance image: ``(hdr, snr, saturated)``, each per pixel (and channel).

    ``hdr`` is in the render's units (radiance), ``snr`` its estimated
    signal-to-noise ratio (inf when the sensor is disabled), ``saturated``
    true where every exposure saturated.  ``inside`` (H, W) marks the disk's
    pixels, whose brightest value sets the exposure.
    """
    img = np.asarray(image, dtype=np.float64)
    if not sensor.enabled:
        return img.copy(), np.full(img.shape, np.inf), np.zeros(img.shape, dtype=bool)
    mask = np.asarray(inside, dtype=bool)
    peak = float(img[mask].max()) if mask.any() else 0.0
    if peak <= 0.0:
        return np.zeros_like(img), np.zeros(img.shape), np.zeros(img.shape, dtype=bool)
    gain = sensor.peak_level * sensor.full_well / peak  # electrons per unit radiance in the shortest exposure
    levels = (1 << int(sensor.bits)) - 1
    lsb = sensor.full_well / levels
    total_e = np.zeros_like(img)
    total_t = np.zeros_like(img)
    frames = np.zeros_like(img)
    for t in sorted(sensor.brackets):
        electrons = rng.poisson(img * gain * t).astype(np.float64)
        electrons += rng.normal(0.0, sensor.read_noise, size=img.shape)
        sat = electrons >= sensor.full_well
        digital = np.clip(np.round(electrons / lsb), 0, levels) * lsb
        ok = ~sat
        total_e += np.where(ok, digital, 0.0)
        total_t += np.where(ok, t, 0.0)
        frames += ok
    saturated = frames == 0
    with np.errstate(invalid="ignore", divide="ignore"):
        hdr = np.where(saturated, 0.0, total_e / np.where(saturated, 1.0, total_t)) / gain
        noise = np.sqrt(np.maximum(total_e, 0.0) + frames * sensor.read_noise**2 + frames * lsb**2 / 12.0)
        snr = np.where(saturated | (noise <= 0), 0.0, total_e / np.where(noise > 0, noise, 1.0))
    return np.maximum(hdr, 0.0), snr, saturated


def observations_from_image(
    hdr: ArrayLike, snr: ArrayLike, saturated: ArrayLike, geom: PixelGeometry, min_snr: float
) -> tuple[dict[str, F64], dict[str, int]]:
    """The observation table of one image and the counts of kept and masked lattice pixels.

    Table: ``wi``, ``wo`` (n, 3), ``rgb`` (n, 3) BRDF values (pixel / E),
    ``row``, ``col`` of each kept pixel.  Counts: ``pixels`` (on the disk),
    ``kept``, ``masked_horizon``, ``masked_saturated``, ``masked_low`` (a
    channel ≤ 0 or below ``min_snr``).
    """
    img = np.asarray(hdr, dtype=np.float64)
    s = np.asarray(snr, dtype=np.float64)
    sat = np.asarray(saturated, dtype=bool)
    pix = img[geom.row, geom.col]  # (grid², 3)
    pix_snr = s[geom.row, geom.col]
    pix_sat = sat[geom.row, geom.col].any(axis=1)
    on_disk = geom.inside
    horizon = on_disk & ((geom.wi[:, 2] <= 0.0) | (geom.wo[:, 2] <= 0.0) | (geom.irradiance <= 0.0))
    cand = on_disk & ~horizon
    saturated_px = cand & pix_sat
    low = cand & ~pix_sat & ((pix <= 0.0).any(axis=1) | (pix_snr < min_snr).any(axis=1))
    keep = cand & ~pix_sat & ~low
    rgb = pix[keep] / geom.irradiance[keep, None]
    table = {
        "wi": geom.wi[keep],
        "wo": geom.wo[keep],
        "rgb": rgb,
        "row": geom.row[keep].astype(np.int64),
        "col": geom.col[keep].astype(np.int64),
    }
    counts = {
        "pixels": int(on_disk.sum()),
        "kept": int(keep.sum()),
        "masked_horizon": int(horizon.sum()),
        "masked_saturated": int(saturated_px.sum()),
        "masked_low": int(low.sum()),
    }
    return table, counts


def read_configurations(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The parts of a directions file a capture needs: setup, fov, grid and each set's (light, camera) pairs.

    ``{"setup", "fov", "grid", "sets": {n: [(light, camera), ...]}}``;
    :class:`ValueError` naming the file for another format.  (The format is
    :mod:`brdfpipe.acquisition.optimize`'s; the tracks meet in this file.)
    """
    path = Path(path)
    doc = integrity.read_json(path, kind="directions file")  # its digest checked, as by the optimizer's reader
    try:
        if doc.get("format") != acquisition_spec.DIRECTIONS_FORMAT:
            raise ValueError(f"format {doc.get('format')!r}")
        sets = {
            int(s["n"]): [(_unit(c["light"], "light"), _unit(c["camera"], "camera")) for c in s["configurations"]]
            for s in doc["sets"]
        }
        return {"setup": str(doc["setup"]), "fov": float(doc["fov"]), "grid": int(doc["grid"]), "sets": sets}
    except (OSError, KeyError, TypeError, AttributeError, ValueError) as exc:
        raise ValueError(f"{path}: not a directions file a capture can use ({exc})") from exc


def _write_npz(out: Path, arrays: Mapping[str, NDArray[Any]], counts: Mapping[str, int]) -> None:
    """An observation table, with its digest (:func:`brdfpipe.core.integrity.save_npz`)."""
    integrity.save_npz(out, {**arrays, "counts_keys": np.array(list(counts)),
                             "counts": np.array(list(counts.values()), dtype=np.int64)})


def _image_seed(seed: int, material: str, light: F64, camera: F64) -> int:
    key = f"{material}|{np.round(light, 12).tolist()}|{np.round(camera, 12).tolist()}".encode()
    return (int(seed) * 0x9E3779B1 + zlib.crc32(key)) % (1 << 31)


def output_layout(n_directions: int, n_images: Sequence[int]) -> tuple[list[tuple[int, int, int]], list[tuple[int, int]]]:
    """The order of :func:`capture_to_files`' output lists: image keys (d, n, j) and table keys (d, n)."""
    images = [(d, int(n), j) for d in range(n_directions) for n in n_images for j in range(int(n))]
    tables = [(d, int(n)) for d in range(n_directions) for n in n_images]
    return images, tables


def _capture_material(
    mat: Path,
    name: str,
    docs: Sequence[Mapping[str, Any]],
    directions: Sequence[str | os.PathLike[str]],
    n_images: Sequence[int],
    *,
    spp: int,
    seed: int,
    light_distance: float,
    min_snr: float,
    sens: Sensor,
    on_image: Callable[[int, int, int, F64, F64, dict[str, str]], None] | None = None,
) -> dict[tuple[int, int], dict[str, tuple[dict[str, NDArray[Any]], dict[str, int]]]]:
    """Every set of size ``n_images`` of each directions file (``docs``: :func:`read_configurations`) of one material.

    Returns per (d, n) and source (``noiseless``, ``sensor``) the merged
    observation table (:data:`OBSERVATION_KEYS`) and its counts summed over
    the images.  ``on_image(d, n, j, render, photograph, attrs)`` is called
    for every image (the EXR writer of :func:`capture_to_files`).  A
    configuration shared by two sets is rendered once (same seed: same
    photograph).  Mitsuba's variant must be set and the ``merl`` plugin
    registered.
    """
    cache: dict[tuple[Any, ...], tuple[F64, F64, F64, NDArray[np.bool_], PixelGeometry]] = {}
    result: dict[tuple[int, int], dict[str, tuple[dict[str, NDArray[Any]], dict[str, int]]]] = {}
    for d, (dpath, doc) in enumerate(zip(directions, docs)):
        kind = acquisition_spec.SETUPS.get(doc["setup"])
        if kind is None or not kind.images:
            raise ValueError(f"{dpath}: a {doc['setup']} setup has no image to capture")
        settings = CaptureSettings(fov_deg=doc["fov"], grid=doc["grid"], spp=spp, seed=seed,
                                   light_distance=light_distance, min_snr=min_snr, sensor=sens)
        for n in n_images:
            if n not in doc["sets"]:
                raise ValueError(f"{dpath}: no set of n = {n} images")
            parts: dict[str, list[dict[str, F64]]] = {"noiseless": [], "sensor": []}
            totals: dict[str, dict[str, int]] = {"noiseless": {}, "sensor": {}}
            for j, (light, camera) in enumerate(doc["sets"][n]):
                key = (doc["fov"], doc["grid"], tuple(np.round(light, 12)), tuple(np.round(camera, 12)))
                if key not in cache:
                    geom = pixel_geometry(settings, light, camera)
                    img_seed = _image_seed(seed, name, light, camera)
                    raw = render_capture(mat, settings, light, camera, seed=img_seed)
                    inside = np.zeros(raw.shape[:2], dtype=bool)
                    inside[geom.row[geom.inside], geom.col[geom.inside]] = True
                    hdr, snr, sat = expose(raw, inside, sens, np.random.default_rng(img_seed))
                    cache[key] = (raw, hdr, snr, sat, geom)
                    logger.info("%s: rendered light %s camera %s (%d × %d, %d spp)", name,
                                np.round(light, 4).tolist(), np.round(camera, 4).tolist(), raw.shape[0], raw.shape[1], spp)
                raw, hdr, snr, sat, geom = cache[key]
                if on_image is not None:
                    attrs = {"material": name, "directions": str(dpath), "n": str(n), "image": str(j),
                             "light": json.dumps(light.tolist()), "camera": json.dumps(camera.tolist()),
                             "spp": str(spp), "light_distance": str(light_distance)}
                    on_image(d, n, j, raw, hdr, attrs)
                no_noise = (raw, np.full(raw.shape, np.inf), np.zeros(raw.shape, dtype=bool), 0.0)
                for source, (im, sn, st, thr) in (("noiseless", no_noise), ("sensor", (hdr, snr, sat, min_snr))):
                    table, counts = observations_from_image(im, sn, st, geom, thr)
                    table["image"] = np.full(table["row"].shape, j, dtype=np.int64)
                    parts[source].append(table)
                    for k, v in counts.items():
                        totals[source][k] = totals[source].get(k, 0) + v
            result[(d, int(n))] = {
                source: ({k: np.concatenate([p[k] for p in parts[source]]) for k in OBSERVATION_KEYS}, totals[source])
                for source in ("noiseless", "sensor")
            }
            logger.info("%s: %s n = %d: sensor %s", name, Path(dpath).name, n, totals["sensor"])
    return result


def _start_mitsuba(variant: str, threads: int | None) -> None:
    from brdfpipe.rendering import render

    render.use_variant(variant)
    if threads is not None:
        render.set_cpu_threads(threads)
    render.register_merl_bsdf()


def capture_to_files(
    *,
    material: str | os.PathLike[str],
    directions: Sequence[str | os.PathLike[str]],
    n_images: Sequence[int],
    renders: Sequence[str | os.PathLike[str]],
    photographs: Sequence[str | os.PathLike[str]],
    noiseless: Sequence[str | os.PathLike[str]],
    observations: Sequence[str | os.PathLike[str]],
    spp: int,
    seed: int,
    light_distance: float | None,
    min_snr: float,
    sensor: Sensor | Mapping[str, Any],
    variant: str = "llvm_ad_rgb",
    threads: int | None = None,
    name: str | None = None,
    database: str | None = None,
) -> dict[tuple[int, int], dict[str, int]]:
    """Capture one material under every set of size ``n_images`` of each directions file; write the files.

    In the order of :func:`output_layout`: ``renders`` / ``photographs`` are
    the EXRs (noiseless render, sensor image) of image j of the n-set of
    ``directions[d]``; ``noiseless`` / ``observations`` its NPZ
    observation tables (:data:`OBSERVATION_KEYS`, ``image`` = j, plus
    ``counts_keys`` / ``counts``: pixels, kept, masked_horizon,
    masked_saturated, masked_low summed over the images) read off the
    noiseless render and off the sensor's photograph.  A configuration
    shared by two sets is rendered once (same seed: same photograph).  Noise
    is seeded from ``seed``, the material and the configuration.
    ``light_distance`` None (or inf): a distant light.  With ``name`` (the
    workflow's material), the file is first checked to be that material, of
    ``database`` when given (its provenance mark,
    :func:`brdfpipe.data.provenance.check_sources`).  Returns the counts per
    (d, n).
    """
    light_distance = math.inf if light_distance is None else float(light_distance)
    image_keys, table_keys = output_layout(len(directions), n_images)
    if not len(renders) == len(photographs) == len(image_keys) or not len(noiseless) == len(observations) == len(table_keys):
        raise ValueError(f"capture outputs: need {len(image_keys)} images and {len(table_keys)} tables of each kind, "
                         f"got {len(renders)}, {len(photographs)}, {len(noiseless)}, {len(observations)}")
    images = {k: (r, p) for k, r, p in zip(image_keys, renders, photographs)}
    tables = {k: (a, b) for k, a, b in zip(table_keys, noiseless, observations)}
    mat = Path(material)
    if name is not None:
        provenance.check_sources([(name, mat)], database=database)
    elif not mat.is_file():
        raise FileNotFoundError(f"{mat}: material file not found")
    sens = sensor if isinstance(sensor, Sensor) else Sensor(**dict(sensor))
    _start_mitsuba(variant, threads)
    docs = [read_configurations(p) for p in directions]

    def write_images(d: int, n: int, j: int, raw: F64, hdr: F64, attrs: dict[str, str]) -> None:
        raw_path, img_path = images[(d, n, j)]
        write_exr(raw_path, raw, attrs={**attrs, "kind": "render"})
        write_exr(img_path, hdr, attrs={**attrs, "kind": "sensor"})

    captured = _capture_material(mat, mat.stem, docs, directions, n_images, spp=spp, seed=seed,
                                 light_distance=light_distance, min_snr=min_snr, sens=sens, on_image=write_images)
    result: dict[tuple[int, int], dict[str, int]] = {}
    for (d, n), by_source in captured.items():
        for source, out in zip(("noiseless", "sensor"), tables[(d, n)]):
            merged, totals = by_source[source]
            _write_npz(Path(out), merged, totals)
        result[(d, n)] = by_source["sensor"][1]
    return result


#: Format of the one observations file of many materials (:func:`capture_materials_to_file`).
MANY_FORMAT: Final = "brdfpipe.capture.observations-many/1"


def capture_materials_to_file(
    *,
    materials: Mapping[str, str | os.PathLike[str]],
    database: str,
    directions: Sequence[str | os.PathLike[str]],
    n_images: Sequence[int],
    out: str | os.PathLike[str],
    spp: int,
    seed: int,
    light_distance: float | None,
    min_snr: float,
    sensor: Sensor | Mapping[str, Any],
    variant: str = "llvm_ad_rgb",
    threads: int | None = None,
) -> dict[tuple[str, int, int], dict[str, int]]:
    """:func:`capture_to_files` for many materials in one process, every observation table in one NPZ.

    The workflow's ``capture_unseen_closedloop`` job (one per database of
    materials outside the training database): Mitsuba starts once, not once
    per material (its start-up costs more than a capture).  ``materials``
    maps each material to its MERL file (``database``: their label, recorded
    in the file; each file is checked to be its material of ``database``
    first, :func:`brdfpipe.data.provenance.check_sources`).  Same renders, seeds and observation tables as
    :func:`capture_to_files` (no EXR is written).  ``out`` (NPZ, written
    atomically) holds ``format`` (:data:`MANY_FORMAT`), ``database``,
    ``index`` (JSON: one entry per table with ``material``, ``directions``
    (file name), ``setup``, ``fov``, ``metric``, ``n``, ``source``
    (``noiseless`` / ``sensor``) and ``counts``) and the arrays
    ``<key>_<i>`` (:data:`OBSERVATION_KEYS`) of table i.  Returns the sensor
    counts per (material, d, n).
    """
    light_distance = math.inf if light_distance is None else float(light_distance)
    sens = sensor if isinstance(sensor, Sensor) else Sensor(**dict(sensor))
    paths = {str(m): Path(p) for m, p in materials.items()}
    provenance.check_sources(paths, database=database)
    docs = [read_configurations(p) for p in directions]
    metrics = [_directions_metric(p) for p in directions]
    _start_mitsuba(variant, threads)
    index: list[dict[str, Any]] = []
    arrays: dict[str, NDArray[Any]] = {}
    result: dict[tuple[str, int, int], dict[str, int]] = {}
    for name, mat in paths.items():
        captured = _capture_material(mat, name, docs, directions, n_images, spp=spp, seed=seed,
                                     light_distance=light_distance, min_snr=min_snr, sens=sens)
        for (d, n), by_source in captured.items():
            for source in ("noiseless", "sensor"):
                merged, totals = by_source[source]
                i = len(index)
                index.append({"material": name, "directions": Path(directions[d]).name, "setup": docs[d]["setup"],
                              "fov": docs[d]["fov"], "metric": metrics[d], "n": int(n), "source": source,
                              "counts": {k: int(v) for k, v in totals.items()}})
                for k in OBSERVATION_KEYS:
                    arrays[f"{k}_{i}"] = merged[k]
            result[(name, d, n)] = by_source["sensor"][1]
    integrity.save_npz(out, {"format": np.array(MANY_FORMAT), "database": np.array(str(database)),
                          "index": np.array(json.dumps(index, sort_keys=True)), **arrays})
    logger.info("%d materials of %s captured: %d observation tables -> %s", len(paths), database, len(index), out)
    return result


def _directions_metric(path: str | os.PathLike[str]) -> str:
    """The optimisation metric recorded in a directions file (its digest checked)."""
    doc = integrity.read_json(path, kind="directions file")
    if not isinstance(doc.get("metric"), str):
        raise ValueError(f"{path}: not a directions file a capture can use (no metric)")
    return str(doc["metric"])
