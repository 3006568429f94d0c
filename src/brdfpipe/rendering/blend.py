"""Blended images and their error maps (Soler et al. 2018 §5.2, Figs. 12, 13).

A material on the manifold is ``z* = Σᵢ wᵢ zᵢ`` with the blend weights of
:func:`brdfpipe.manifold.gplvm.blend_weights` (Σ wᵢ = 1; some wᵢ may be negative).
Light paths that bounce at most once on the material are linear in it, so the
image of ``z*`` is approximated by blending the pre-rendered images of the
``zᵢ`` with the same weights, ``I* ≈ Σᵢ wᵢ Iᵢ`` (eq. 13; the error comes from
paths with two or more bounces on the material).  Fig. 13 compares such a
blend with a reference render of ``z*`` and with the noise between two
references rendered with different seeds.

Conventions
-----------
* Blends are accumulated in float64, one image at a time (the pre-renders
  are never stacked in memory), and weights are used as given: negative
  weights are not clipped and the blend is not clamped.
* :func:`rmse` is the root of the mean over **all pixels and channels** of
  the squared difference; :func:`relative_rmse` divides it by the mean of the
  reference over all pixels and channels.
* :func:`error_map` is the per-pixel absolute difference averaged over the
  three channels, ``mean_c |a − b|``, in the images' radiance units.
* Output files are written atomically (temporary sibling, then
  :func:`os.replace`).

Importing this module does not import Mitsuba.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_write, check_not_input
from brdfpipe.core.exr import ExrError, read_exr, tonemap, write_exr
from brdfpipe.core.filenames import format_t
from brdfpipe.core.version import full_version
from brdfpipe.registry import tables

__all__ = [
    "BlendError",
    "format_t",
    "rmse",
    "relative_rmse",
    "error_map",
    "write_error_map_exr",
    "write_error_map_png",
    "tonemap",
    "error_maps",
    "error_maps_from_files",
    "ratio_standard_error",
    "bounce_shares",
    "floor_check_table",
]

logger = logging.getLogger("brdfpipe.rendering.blend")


#: Characters allowed in a path name (it becomes part of file names).
_NAME_RE: Final = re.compile(r"^[A-Za-z0-9_.+-]+$")


class BlendError(ValueError):
    """Images cannot be blended or compared (shape mismatch, bad weights); the message names the files."""


def _say(progress: Callable[[str], None] | None, msg: str) -> None:
    (progress if progress is not None else logger.info)(msg)


# --------------------------------------------------------------------------
# Blending
# --------------------------------------------------------------------------


def _check_weights(weights: ArrayLike, n: int, what: str) -> NDArray[np.float64]:
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1:
        raise BlendError(f"{what} must be a vector, got shape {w.shape}")
    if w.size != n:
        raise BlendError(f"{what} has {w.size} entries but there are {n} images")
    if not np.isfinite(w).all():
        raise BlendError(f"{what} has non-finite entries: {w.tolist()}")
    return w


def _blend_many(
    paths: Sequence[str | os.PathLike[str]],
    W: NDArray[np.float64],
    progress: Callable[[str], None] | None = None,
) -> NDArray[np.float64]:
    """``(P, H, W, 3)`` blends ``Σᵢ W[p, i] Iᵢ`` for P weight vectors, reading each image once."""
    if not paths:
        raise BlendError("no images to blend")
    for p in paths:  # fail before any work if a file is missing
        if not Path(p).is_file():
            raise ExrError(f"{p}: no such file")
    first_path: Path | None = None
    out: NDArray[np.float64] | None = None
    for i, p in enumerate(paths):
        p = Path(p)
        img = read_exr(p)
        if out is None:
            first_path = p
            out = np.zeros((W.shape[0],) + img.shape, dtype=np.float64)
        elif img.shape != out.shape[1:]:
            raise BlendError(
                f"{p}: image has shape {img.shape}, but the first image {first_path} has {out.shape[1:]}"
            )
        img64 = img.astype(np.float64)
        for k in range(W.shape[0]):
            out[k] += W[k, i] * img64
        del img, img64
        _say(progress, f"blend: read {i + 1}/{len(paths)} {p}")
    assert out is not None
    return out


# --------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------


def _pair(a: ArrayLike, b: ArrayLike, what: str = "images") -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a64 = np.asarray(a, dtype=np.float64)
    b64 = np.asarray(b, dtype=np.float64)
    if a64.shape != b64.shape:
        raise BlendError(f"{what} differ in shape: {a64.shape} vs {b64.shape}")
    if a64.size == 0:
        raise BlendError(f"{what} are empty")
    return a64, b64


def rmse(a: ArrayLike, b: ArrayLike) -> float:
    """Root mean squared difference of two same-shape images over all pixels and channels."""
    a64, b64 = _pair(a, b)
    return float(np.sqrt(np.mean(np.square(a64 - b64))))


def ratio_standard_error(
    blend: ArrayLike, reference: ArrayLike, reference_seed2: ArrayLike, compared_with: ArrayLike | None = None
) -> float:
    """Standard error of ``rmse(blend, reference_seed2) / rmse(reference, reference_seed2)``, from the pixels.

    The noise floor is measured from one pair of seeds: its own estimate is
    uncertain, and so is the ratio a verdict compares with 1.  With per-pixel
    squared differences (summed over the channels) uᵢ = |blend − ref₂|² and
    vᵢ = |ref − ref₂|², the ratio is R = √(ū / v̄); pixels of a Monte Carlo
    render carry independent noise, so (delta method, a paired comparison of
    uᵢ and vᵢ over the n pixels) SE(R²) = sd(uᵢ − R² vᵢ) / (√n · v̄) and
    SE(R) = SE(R²) / (2R).  Heavy-tailed noise (fireflies) widens it, as it
    should.  ``nan`` when the ratio is not finite and positive or there is a
    single pixel.  ``compared_with``: the image the blend is compared with
    in the numerator, when it is not ``reference_seed2`` (the isolated
    reference of :func:`error_maps`); the floor stays the two references'.
    """
    b64, r2 = _pair(blend, reference_seed2)
    r64, _ = _pair(reference, r2)
    c64 = r2 if compared_with is None else _pair(compared_with, r2)[0]
    if b64.ndim == 3:
        u = np.square(b64 - c64).sum(axis=2).ravel()
        v = np.square(r64 - r2).sum(axis=2).ravel()
    else:
        u, v = np.square(b64 - c64).ravel(), np.square(r64 - r2).ravel()
    n = u.size
    vbar = float(v.mean()) if n else 0.0
    if n < 2 or not vbar > 0.0:
        return math.nan
    ratio2 = float(u.mean()) / vbar
    if not (math.isfinite(ratio2) and ratio2 > 0.0):
        return math.nan
    se2 = float(np.std(u - ratio2 * v, ddof=1)) / (math.sqrt(n) * vbar)
    return se2 / (2.0 * math.sqrt(ratio2))


def relative_rmse(a: ArrayLike, b: ArrayLike, reference: ArrayLike) -> float:
    """``rmse(a, b) / mean(reference)``, the mean taken over all pixels and channels.

    ValueError (:class:`BlendError`) if the reference's mean is not positive.
    """
    ref = np.asarray(reference, dtype=np.float64)
    a64, _ = _pair(a, ref, "image and reference")
    mean = float(ref.mean())
    if not mean > 0.0:
        raise BlendError(f"reference has mean {mean}; relative RMSE needs a positive mean")
    return rmse(a64, b) / mean


def error_map(blended: ArrayLike, reference: ArrayLike) -> NDArray[np.float64]:
    """Per-pixel ``mean over R, G, B of |blended − reference|``, an ``(H, W)`` float64 array."""
    a64, b64 = _pair(blended, reference)
    if a64.ndim != 3 or a64.shape[2] != 3:
        raise BlendError(f"images must have shape (H, W, 3), got {a64.shape}")
    return np.abs(a64 - b64).mean(axis=2)


def _check_err(err: ArrayLike) -> NDArray[np.float64]:
    e = np.asarray(err, dtype=np.float64)
    if e.ndim != 2 or e.size == 0:
        raise BlendError(f"an error map must be a non-empty (H, W) array, got shape {e.shape}")
    if not np.isfinite(e).all():
        raise BlendError("error map has non-finite values")
    return e


def write_error_map_exr(
    path: str | os.PathLike[str],
    err: ArrayLike,
    *,
    attrs: Mapping[str, str] | None = None,
) -> None:
    """Write an ``(H, W)`` error map as a float32 EXR, the value repeated in R, G and B (atomic)."""
    e = _check_err(err)
    write_exr(path, np.repeat(e[..., None], 3, axis=2).astype(np.float32), attrs=attrs)


def write_error_map_png(
    path: str | os.PathLike[str],
    err: ArrayLike,
    *,
    vmax: float | None = None,
    title: str = "|blended − reference|",
    database: str | None = None,
) -> None:
    """A false-colour PNG of an error map with a labelled colour bar (atomic).

    Colours run from 0 (black) to ``vmax`` (default: the map's 99th
    percentile, or its maximum if that is 0 … or 1 for an all-zero map);
    larger values saturate (perceptual colormap ``magma``).
    The title is ``"{database}: {title}"`` (just ``title`` without a
    database).  Built on :class:`matplotlib.figure.Figure` with the Agg canvas
    (pyplot is not used) and written without a timestamp, so the same input
    gives the same bytes.
    """
    import matplotlib as mpl
    import matplotlib.style
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    e = _check_err(err)
    if vmax is None:
        vmax = float(np.percentile(e, 99.0)) or float(e.max()) or 1.0
    if not (math.isfinite(vmax) and vmax > 0.0):
        raise ValueError(f"{path}: vmax must be finite and > 0, got {vmax}")
    full_title = f"{database}: {title}" if database else title
    h, w = e.shape
    with mpl.rc_context():
        mpl.style.use("default")
        mpl.rcParams.update({"font.family": "DejaVu Sans", "font.size": 8.0, "svg.hashsalt": "brdfpipe-blend"})
        width_in = 4.8
        img_h = width_in * 0.82 * h / w
        fig = Figure(figsize=(width_in, img_h + 0.6), dpi=150, layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        im = ax.imshow(e, cmap="magma", vmin=0.0, vmax=vmax, interpolation="nearest")
        ax.set_axis_off()
        ax.set_title(full_title, fontsize=8.5)
        bar = fig.colorbar(im, ax=ax, fraction=0.05, pad=0.02, extend="max")
        bar.set_label("radiance units (mean over RGB of |Δ|)")
        software = f"brdfpipe {full_version()} (matplotlib {mpl.__version__})"
        atomic_write(path, lambda fh: fig.savefig(fh, format="png", metadata={"Title": full_title,
                                                                               "Software": software}))


# --------------------------------------------------------------------------
# Error maps along manifold paths (the workflow's entry point)
# --------------------------------------------------------------------------


def _fmt(x: float) -> str:
    return f"{x:.9g}"


def _ratio(err: float, noise: float) -> float:
    if noise > 0.0:
        return err / noise
    return math.inf if err > 0.0 else math.nan


def _one_row(blend: NDArray[np.float64], ref_path: Path, ref2_path: Path,
             whole: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]) -> dict[str, float]:
    """The ``_one`` and ``ratio_isolated`` columns of a summary row, from the I¹⁻ blend and references.

    ``whole``: the whole images' blend and two references.  The isolated
    reference of the second seed is ``Σ wᵢ I¹⁻ᵢ + (ref₂ − ref₂¹⁻)``: the I¹⁻
    part of the *unclamped* interpolated table (exact by linearity: I¹⁻ is
    affine in the table, negative values included) plus the reference's own
    I²⁺ part.  The blend differs from it by ``Σ wᵢ I²⁺ᵢ − I²⁺_ref`` alone —
    the L²⁺ approximation (Soler eq. 13) and its noise — and not by the
    clamping of the reference's table, which enters the I²⁺ paths only.
    """
    ref = read_exr(ref_path).astype(np.float64)
    ref2 = read_exr(ref2_path).astype(np.float64)
    for p, img in ((ref_path, ref), (ref2_path, ref2)):
        if img.shape != blend.shape:
            raise BlendError(f"{p}: image has shape {img.shape}, but the I1- pre-renders have {blend.shape}")
    rmse_blend = relative_rmse(blend, ref, ref)
    rmse_noise = relative_rmse(ref, ref2, ref)
    rmse_blend2 = relative_rmse(blend, ref2, ref)
    w_blend, w_ref, w_ref2 = whole
    isolated2 = blend + (w_ref2 - ref2)
    return {"rmse_blend_one": rmse_blend, "rmse_noise_one": rmse_noise,
            "ratio_one": _ratio(rmse_blend, rmse_noise), "rmse_blend_one_seed2": rmse_blend2,
            "ratio_one_seed2": _ratio(rmse_blend2, rmse_noise), "mean_reference_one": float(ref.mean()),
            "ratio_one_seed2_se": ratio_standard_error(blend, ref, ref2),
            "ratio_isolated_seed2": _ratio(rmse(w_blend, isolated2), rmse(w_ref, w_ref2)),
            "ratio_isolated_seed2_se": ratio_standard_error(w_blend, w_ref, w_ref2, isolated2)}


def error_maps(
    *,
    prerenders: Mapping[str, str | os.PathLike[str]],
    paths: Sequence[Mapping[str, Any]],
    summary: str | os.PathLike[str],
    database: str,
    prerenders_one: Mapping[str, str | os.PathLike[str]] | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Blend the pre-renders at points along manifold paths and compare with references (Fig. 13).

    ``prerenders`` maps each material to its pre-rendered EXR.  Each entry
    of ``paths`` is one point: ``{"path": name, "t": t, "weights":
    {material: wᵢ}, "reference": EXR, "reference_seed2": EXR, "blended": EXR,
    "error_exr": EXR, "error_png": PNG}``, where the references are renders
    of the interpolated material with two seeds and the last three are the
    point's output files.  The
    weights are dense GP weights: every material with a weight must have a
    pre-render and every pre-render must have a weight (BlendError listing
    the differences otherwise).

    For every point writes ``blended`` (the blend, float32), ``error_exr``
    (:func:`error_map` of blend vs reference) and ``error_png`` (false
    colour; one ``vmax`` — the largest 99th
    percentile over the points — shared by all maps of the call so colours
    compare), and computes a row

    * ``rmse_blend`` = :func:`relative_rmse` (blend, reference, reference);
    * ``rmse_noise`` = :func:`relative_rmse` (reference, reference_seed2, reference);
    * ``ratio`` = rmse_blend / rmse_noise (``inf`` if the noise is 0 and the
      blend error is not, ``nan`` if both are 0): below 1, the blend is
      closer to the reference than two references are to each other;
    * ``rmse_blend_seed2`` = :func:`relative_rmse` (blend, reference_seed2,
      reference) and ``ratio_seed2`` = rmse_blend_seed2 / rmse_noise: the
      same against the second-seed render.  When the pre-renders and the
      first reference share a sampler seed their Monte Carlo noise is
      correlated (same camera rays and light samples), which makes
      ``rmse_blend`` optimistic; against the independent second seed, a
      blend without bias gives ``ratio_seed2`` ≈ 1 (both sides noisy) and
      a visible blending bias gives more;
    * ``mean_reference`` = mean of the reference over pixels and channels;
    * ``ratio_seed2_se`` = :func:`ratio_standard_error`: the uncertainty of
      ``ratio_seed2`` that comes from measuring the noise floor from one
      pair of seeds (a verdict "blend within the floor" compares
      ``ratio_seed2`` with 1 within a few of these);
    * ``sum_abs_w`` = Σ|wᵢ| (1 for a convex blend; the pre-renders' noise and
      any bias enter the blend amplified) and ``clamped_fraction``: the share
      of the interpolated table's measured values the reference's table has
      clamped at 0 (the point's optional ``clamped_fraction``; empty without),
      which no blend of images can do.

    With ``prerenders_one`` (each material's ``I¹⁻`` pre-render: light paths
    with at most one scattering on the material, :mod:`brdfpipe.rendering.bounce`;
    same materials as ``prerenders``), every point also needs
    ``reference_one`` and ``reference_one_seed2`` (the references' ``I¹⁻``
    images), the ``I¹⁻`` pre-renders are blended with the same weights, and
    the row gets the same seven numbers for them, suffixed ``_one``
    (``rmse_blend_one``, ``rmse_noise_one``, ``ratio_one``,
    ``rmse_blend_one_seed2``, ``ratio_one_seed2``, ``mean_reference_one``,
    ``ratio_one_seed2_se``;
    relative to the ``I¹⁻`` reference's mean).  ``I¹⁻`` is exactly affine in
    the material, so its blend has no bias from ``I²⁺``: ``ratio_one_seed2``
    ≈ 1 apart from the material interpolation's own error.  And the
    blend against a reference that isolates the paper's question, the L²⁺
    approximation, from the clamping of the reference's table:
    ``ratio_isolated_seed2`` = RMSE(blend, Σ wᵢ I¹⁻ᵢ + I²⁺ of the second
    reference) / RMSE(the two references), with its standard error
    ``ratio_isolated_seed2_se`` (see :func:`_one_row`).  The renderer cannot
    take the unclamped table itself (its MERL plugin reads negative values
    as unmeasured, and sampling needs a non-negative BRDF); its I¹⁻ part
    needs no render, being affine in the table.  Without ``prerenders_one``
    those cells are empty.

    Then writes ``summary`` (CSV, columns :data:`~brdfpipe.registry.tables.ERROR_MAP_SUMMARY`, one line
    per point in input order, numbers as ``%.9g``, ``t`` as ``format_t``)
    atomically, and returns the rows (floats unrounded).  Each pre-render is
    read once for all points.  Any missing or corrupt pre-render or
    reference raises (:class:`~brdfpipe.core.exr.ExrError` naming the file) and
    no ``summary`` is left (a stale one is removed first).
    """
    summary = Path(summary)
    summary.parent.mkdir(parents=True, exist_ok=True)
    summary.unlink(missing_ok=True)  # never leave a stale summary next to a failed run's outputs

    materials = list(prerenders)
    if not materials:
        raise BlendError("no pre-renders given")
    if not paths:
        raise BlendError("no path points given")
    with_one = prerenders_one is not None
    if prerenders_one is not None:
        _check_same_materials(prerenders_one, materials)
    ref_keys = ("reference", "reference_seed2") + (("reference_one", "reference_one_seed2") if with_one else ())
    # validate the points and every input file up front, before any work
    points, W = _check_points(paths, materials, ref_keys)
    inputs = [Path(prerenders[m]) for m in materials]
    if prerenders_one is not None:
        inputs += [Path(prerenders_one[m]) for m in materials]
    inputs += [Path(pt[key]) for pt in paths for key in ref_keys]
    _check_files(inputs, [Path(pt[key]) for pt in paths for key in ("blended", "error_exr", "error_png")] + [summary])

    blends = _blend_many([Path(prerenders[m]) for m in materials], W, progress)
    blends_one = (_blend_many([Path(prerenders_one[m]) for m in materials], W, progress)
                  if prerenders_one is not None else None)

    rows: list[dict[str, Any]] = []
    errs: list[NDArray[np.float64]] = []
    for k, ((name, t, s), pt) in enumerate(zip(points, paths)):
        row, err = _point_row(blends[k], None if blends_one is None else blends_one[k], W[k], pt, name, t, s,
                              database)
        rows.append(row)
        errs.append(err)
        msg = (f"{name} t={s}: relative RMSE blend {row['rmse_blend']:.4g}, noise {row['rmse_noise']:.4g}, "
               f"ratio {row['ratio']:.3g}, vs seed 2 {row['ratio_seed2']:.3g}")
        if blends_one is not None:
            msg += f"; I1- ratio {row['ratio_one']:.3g}, vs seed 2 {row['ratio_one_seed2']:.3g}"
        _say(progress, msg)
    _write_error_pngs(points, errs, rows, paths, database)
    _write_summary(summary, database, points, rows)
    return rows


def _check_same_materials(prerenders_one: Mapping[str, Any], materials: Sequence[str]) -> None:
    """BlendError unless the I¹⁻ pre-renders name exactly the pre-renders' materials (listing the differences)."""
    if set(prerenders_one) == set(materials):
        return
    extra = sorted(set(prerenders_one) - set(materials))
    lacking = sorted(set(materials) - set(prerenders_one))
    raise BlendError(
        "I1- pre-renders and pre-renders name different materials"
        + (f"; I1- only: {', '.join(extra)}" if extra else "")
        + (f"; without an I1- pre-render: {', '.join(lacking)}" if lacking else "")
    )


def _write_error_pngs(points: Sequence[tuple[str, float, str]], errs: Sequence[NDArray[np.float64]],
                      rows: Sequence[Mapping[str, Any]], paths: Sequence[Mapping[str, Any]], database: str) -> None:
    """Every point's false-colour error map, on one scale: the largest 99th percentile over the points."""
    vmax = max(float(np.percentile(e, 99.0)) for e in errs) or max(float(e.max()) for e in errs) or 1.0
    for (name, _, s), err, row, pt in zip(points, errs, rows, paths):
        write_error_map_png(
            Path(pt["error_png"]), err, vmax=vmax, database=database,
            title=f"path {name}, t = {s}: |blended − reference|\n"
                  f"relative RMSE {row['rmse_blend']:.3g} (noise between seeds {row['rmse_noise']:.3g})",
        )


def _check_points(
    paths: Sequence[Mapping[str, Any]], materials: Sequence[str], ref_keys: tuple[str, ...]
) -> tuple[list[tuple[str, float, str]], NDArray[np.float64]]:
    """``(path, t, format_t(t))`` of each point and the weights ``(points, materials)``; BlendError naming a bad point."""
    points: list[tuple[str, float, str]] = []
    W = np.empty((len(paths), len(materials)), dtype=np.float64)
    seen: dict[tuple[str, str], int] = {}
    for k, pt in enumerate(paths):
        missing_keys = [key for key in ("path", "t", "weights", *ref_keys, "blended",
                                        "error_exr", "error_png") if key not in pt]
        if missing_keys:
            raise BlendError(f"path point {k}: missing key(s) {', '.join(missing_keys)}")
        name = str(pt["path"])
        if not _NAME_RE.match(name):
            raise BlendError(f"path point {k}: path name {name!r} must match {_NAME_RE.pattern}")
        t = float(pt["t"])
        s = format_t(t)
        if (name, s) in seen:
            raise BlendError(f"path points {seen[(name, s)]} and {k} are both {name} at t = {s}")
        seen[(name, s)] = k
        weights = pt["weights"]
        extra = sorted(set(weights) - set(materials))
        lacking = sorted(set(materials) - set(weights))
        if extra or lacking:
            raise BlendError(
                f"path {name} t={s}: weights and pre-renders name different materials"
                + (f"; weights without a pre-render: {', '.join(extra)}" if extra else "")
                + (f"; pre-renders without a weight: {', '.join(lacking)}" if lacking else "")
            )
        W[k] = _check_weights([weights[m] for m in materials], len(materials), f"path {name} t={s} weights")
        points.append((name, t, s))
    return points, W


def _check_files(inputs: Sequence[Path], outputs: Sequence[Path]) -> None:
    """Every input is a file (ExrError naming it); no output is named twice or is an input (BlendError)."""
    for f in inputs:
        if not f.is_file():
            raise ExrError(f"{f}: no such file")
    resolved = [o.resolve() for o in outputs]
    clash = sorted({str(o) for o, r in zip(outputs, resolved) if resolved.count(r) > 1})
    if clash:
        raise BlendError(f"output paths given more than once: {', '.join(clash)}")
    for o in outputs:
        check_not_input(o, inputs, what="output")


def _point_row(
    blend: NDArray[np.float64], blend_one: NDArray[np.float64] | None, weights: NDArray[np.float64],
    pt: Mapping[str, Any], name: str, t: float, s: str, database: str,
) -> tuple[dict[str, Any], NDArray[np.float64]]:
    """One point of :func:`error_maps`: its blend and error-map EXRs written, its summary row and error map."""
    ref_path, ref2_path = Path(pt["reference"]), Path(pt["reference_seed2"])
    ref = read_exr(ref_path).astype(np.float64)
    ref2 = read_exr(ref2_path).astype(np.float64)
    for p, img in ((ref_path, ref), (ref2_path, ref2)):
        if img.shape != blend.shape:
            raise BlendError(
                f"{p}: image has shape {img.shape}, but the pre-renders have {blend.shape}"
            )
    mean_ref = float(ref.mean())
    rmse_blend = relative_rmse(blend, ref, ref)
    rmse_noise = relative_rmse(ref, ref2, ref)
    rmse_blend2 = relative_rmse(blend, ref2, ref)
    ratio, ratio2 = (_ratio(e, rmse_noise) for e in (rmse_blend, rmse_blend2))
    attrs = {"database": database, "path": name, "t": s}
    write_exr(Path(pt["blended"]), blend.astype(np.float32),
              attrs={**attrs, "image": "blend of pre-renders"})
    err = error_map(blend, ref)
    write_error_map_exr(Path(pt["error_exr"]), err,
                        attrs={**attrs, "image": "mean over RGB of |blended - reference|",
                               "reference": ref_path.name})
    row = {"path": name, "t": t, "rmse_blend": rmse_blend, "rmse_noise": rmse_noise,
           "ratio": ratio, "rmse_blend_seed2": rmse_blend2, "ratio_seed2": ratio2,
           "mean_reference": mean_ref, "ratio_seed2_se": ratio_standard_error(blend, ref, ref2),
           "sum_abs_w": float(np.abs(weights).sum())}
    if "clamped_fraction" in pt:
        row["clamped_fraction"] = float(pt["clamped_fraction"])
    if blend_one is not None:
        row.update(_one_row(blend_one, Path(pt["reference_one"]), Path(pt["reference_one_seed2"]), (blend, ref, ref2)))
    return row, err


def _write_summary(summary: Path, database: str, points: Sequence[tuple[str, float, str]],
                   rows: Sequence[Mapping[str, Any]]) -> None:
    """The summary CSV of :func:`error_maps` (:data:`~brdfpipe.registry.tables.ERROR_MAP_SUMMARY`), atomically with its digest."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(tables.ERROR_MAP_SUMMARY)
    for (_, _, s), row in zip(points, rows):
        writer.writerow([database, row["path"], s] + [_fmt(row[c]) if c in row else "" for c in tables.ERROR_MAP_SUMMARY[3:]])
    integrity.write_csv(summary, buf.getvalue())


def error_maps_from_files(
    *,
    prerenders: Mapping[str, str | os.PathLike[str]],
    weights: Sequence[str | os.PathLike[str]],
    references: Sequence[str | os.PathLike[str]],
    references_noise: Sequence[str | os.PathLike[str]],
    blended: Sequence[str | os.PathLike[str]],
    error_exrs: Sequence[str | os.PathLike[str]],
    error_pngs: Sequence[str | os.PathLike[str]],
    summary: str | os.PathLike[str],
    database: str,
    prerenders_one: Mapping[str, str | os.PathLike[str]] | None = None,
    references_one: Sequence[str | os.PathLike[str]] | None = None,
    references_one_noise: Sequence[str | os.PathLike[str]] | None = None,
) -> list[dict[str, Any]]:
    """:func:`error_maps` with each path point given by its weights JSON and two reference renders.

    The workflow's ``error_maps`` job.  ``weights[k]`` is the JSON written
    by :func:`brdfpipe.manifold.analysis.path_points_to_files` (``path``, ``t``,
    ``weights``); ``references[k]`` / ``references_noise[k]`` the renders of
    that interpolated material with the main and the second seed;
    ``blended[k]``, ``error_exrs[k]``, ``error_pngs[k]`` its output files.
    ``prerenders_one``, ``references_one`` and ``references_one_noise``
    (all three or none): the ``I¹⁻`` images of the pre-renders and of the
    two references (see :func:`error_maps`).
    BlendError naming the file for an unreadable or malformed JSON.
    """

    ones = (prerenders_one, references_one, references_one_noise)
    if any(x is None for x in ones) and not all(x is None for x in ones):
        raise BlendError("give all of prerenders_one, references_one and references_one_noise, or none")
    lists = [weights, references, references_noise, blended, error_exrs, error_pngs]
    if references_one is not None and references_one_noise is not None:
        lists += [references_one, references_one_noise]
    if len({len(x) for x in lists}) != 1:
        raise BlendError("weights, references, references_noise (references_one, references_one_noise) and the "
                         "output lists must have the same length")
    points = []
    for wf, ref, ref2, bl, ee, ep, *one in zip(*lists):
        doc = integrity.read_json(wf, kind="path-point weights file", error=BlendError)  # its digest checked
        try:
            points.append({"path": doc["path"], "t": float(doc["t"]), "weights": dict(doc["weights"]),
                           "reference": ref, "reference_seed2": ref2, "blended": bl, "error_exr": ee,
                           "error_png": ep, "clamped_fraction": _clamped_fraction(doc)})
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise BlendError(f"{wf}: not a path-point weights file ({type(err).__name__}: {err})") from None
        if one:
            points[-1].update(reference_one=one[0], reference_one_seed2=one[1])
    return error_maps(prerenders=prerenders, paths=points, summary=summary, database=database,
                      prerenders_one=prerenders_one, progress=lambda msg: logger.info("%s", msg))


def _clamped_fraction(doc: Mapping[str, Any]) -> float:
    """The share of a path point's measured values clamped at 0 (ValueError unless 0 ≤ clamped ≤ measured > 0)."""
    clamped, measured = int(doc["clamped"]), int(doc["measured_values"])
    if measured <= 0 or not 0 <= clamped <= measured:
        raise ValueError(f"clamped = {clamped} of measured_values = {measured}: need 0 <= clamped <= measured > 0")
    return clamped / measured


def bounce_shares(
    *,
    images: Mapping[str, str | os.PathLike[str]],
    ones: Mapping[str, str | os.PathLike[str]],
    mask: str | os.PathLike[str],
    out: str | os.PathLike[str],
    database: str,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """The share of ``I²⁺`` (≥ 2 scatterings on the material) in each material's pre-render.

    The workflow's ``bounce_shares`` job.  ``images[m]`` is material ``m``'s
    whole pre-render ``I``, ``ones[m]`` its ``I¹⁻`` part (same render,
    :func:`brdfpipe.rendering.scene.render_material`), ``mask`` the object mask EXR
    (:func:`brdfpipe.rendering.scene.render_object_mask`; a pixel is the object's when
    its mask is ≥ 0.5).  Writes ``out`` (CSV, columns :data:`~brdfpipe.registry.tables.BOUNCE_SHARES`,
    one row per material in the order of ``images``, numbers ``%.9g``)
    atomically and returns the rows:

    * ``mean_image``, ``mean_one``: means of ``I`` and ``I¹⁻`` over all
      pixels and channels; ``share_image`` = 1 − mean_one / mean_image
      (= mean ``I²⁺`` / mean ``I``);
    * ``mean_image_object``, ``mean_one_object``, ``share_object``: the same
      over the object's pixels; ``object_pixels``: how many there are.

    The share is ``nan`` where the mean of ``I`` is 0.  BlendError if the
    two mappings name different materials, a shape differs (naming the file)
    or the mask has no object pixel; ExrError naming a missing or corrupt
    file.
    """
    out = Path(out)
    materials = list(images)
    if not materials:
        raise BlendError("no pre-renders given")
    if set(ones) != set(materials):
        raise BlendError(f"images and I1- images name different materials: "
                         f"{sorted(set(materials) ^ set(ones))}")
    inputs = [Path(mask)] + [Path(images[m]) for m in materials] + [Path(ones[m]) for m in materials]
    for f in inputs:
        if not f.is_file():
            raise ExrError(f"{f}: no such file")
    check_not_input(out, inputs, what="output")
    m_img = read_exr(mask)
    obj = m_img[..., 0] >= 0.5
    if not obj.any():
        raise BlendError(f"{mask}: the object mask has no pixel >= 0.5")
    rows: list[dict[str, Any]] = []
    for m in materials:
        whole = read_exr(images[m]).astype(np.float64)
        one = read_exr(ones[m]).astype(np.float64)
        for p, img in ((Path(images[m]), whole), (Path(ones[m]), one)):
            if img.shape != m_img.shape:
                raise BlendError(f"{p}: image has shape {img.shape}, but the mask {mask} has {m_img.shape}")
        mi_, mo = float(whole.mean()), float(one.mean())
        mi_obj, mo_obj = float(whole[obj].mean()), float(one[obj].mean())
        row = {"material": m, "mean_image": mi_, "mean_one": mo,
               "share_image": 1.0 - mo / mi_ if mi_ > 0 else math.nan,
               "mean_image_object": mi_obj, "mean_one_object": mo_obj,
               "share_object": 1.0 - mo_obj / mi_obj if mi_obj > 0 else math.nan,
               "object_pixels": int(obj.sum())}
        rows.append(row)
        _say(progress, f"{m}: I2+ share {row['share_image']:.4g} of the image, {row['share_object']:.4g} "
                       f"of the object")
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(tables.BOUNCE_SHARES)
    for row in rows:
        writer.writerow([database, row["material"]]
                        + [_fmt(row[c]) if isinstance(row[c], float) else str(row[c]) for c in tables.BOUNCE_SHARES[2:]])
    integrity.write_csv(out, buf.getvalue())
    return rows


# --------------------------------------------------------------------------
# Blends against the noise floor, every GPLVM candidate (render.floor_check)
# --------------------------------------------------------------------------



def _read_summary_rows(path: Path, database: str) -> list[dict[str, str]]:
    if not path.is_file():
        raise BlendError(f"{path}: no such file")
    _, rows = integrity.read_csv_rows(path, required=tables.ERROR_MAP_SUMMARY, kind="error-map summary", error=BlendError)
    for k, row in enumerate(rows):
        if row["database"] != database:
            raise BlendError(f"{path}: row {k + 1} is from database {row['database']!r}, this run's is {database!r}")
    return rows


def _weights_doc(path: Path) -> dict[str, Any]:
    doc = integrity.read_json(path, kind="path-point weights file", error=BlendError)  # its digest checked
    try:
        w = np.array([float(v) for v in dict(doc["weights"]).values()], dtype=np.float64)
        out = {"path": str(doc["path"]), "t": format_t(float(doc["t"])), "w": w,
               "clamped": int(doc["clamped"]), "measured": int(doc["measured_values"])}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise BlendError(f"{path}: not a path-point weights file ({type(err).__name__}: {err})") from None
    if w.size == 0 or not np.isfinite(w).all() or out["measured"] <= 0 or not 0 <= out["clamped"] <= out["measured"]:
        raise BlendError(f"{path}: weights must be finite and non-empty, 0 <= clamped <= measured_values > 0")
    return out


def floor_check_table(
    *,
    candidates: Mapping[str, tuple[str, float]],
    default: str,
    summaries: Mapping[str, str | os.PathLike[str]],
    weights: Mapping[str, Sequence[str | os.PathLike[str]]],
    references: Mapping[str, Sequence[str | os.PathLike[str]]],
    out: str | os.PathLike[str],
    database: str,
) -> list[dict[str, Any]]:
    """Every candidate's blends against the Monte Carlo noise floor, one row per path point (a CSV).

    The workflow's ``summarize_floor_check`` job.  For each candidate label
    in ``candidates`` (label → (space, μ); ``default`` is the workflow's
    default candidate): ``summaries[c]`` is its :func:`error_maps` summary
    (rendered at the check's spp), ``weights[c]`` the weights JSONs of its
    path points (:func:`brdfpipe.manifold.analysis.path_points_to_files`) and
    ``references[c]`` the reference renders, both in the summary's row order.
    Each row carries the candidate, its space and μ, the renders' size and
    spp (read from the reference EXR, which must agree across the check),
    Σ|wᵢ| and ‖w‖₂ (noise of the pre-renders enters the blend with ‖w‖₂),
    the share of the interpolated table's measured values clamped at 0
    (a clamp the linear blend of images cannot know), the noise floor and
    the ratios of the summary with their standard errors (whole image,
    I¹⁻, and against the reference that differs only by the L²⁺ paths).  Writes ``out``
    (columns :data:`~brdfpipe.registry.tables.FLOOR_CHECK`, numbers ``%.9g``) atomically.
    :class:`BlendError` naming the file when a summary is of another
    database, its rows and the weights disagree on the points, or the renders
    differ in size or spp.
    """
    from brdfpipe.core.exr import read_exr_attrs

    out = Path(out)
    labels = list(candidates)
    if default not in candidates:
        raise BlendError(f"default candidate {default!r} is not among the candidates {labels}")
    for name, mapping in (("summaries", summaries), ("weights", weights), ("references", references)):
        if set(mapping) != set(labels):
            raise BlendError(f"{name} name candidates {sorted(mapping)}, expected {sorted(labels)}")
    inputs = [Path(summaries[c]) for c in labels] + [Path(f) for c in labels for f in (*weights[c], *references[c])]
    check_not_input(out, inputs, what="output")
    rows: list[dict[str, Any]] = []
    size: tuple[tuple[int, int, int], Path] | None = None
    for c in labels:
        summary = Path(summaries[c])
        srows = _read_summary_rows(summary, database)
        if not (len(srows) == len(weights[c]) == len(references[c])):
            raise BlendError(f"{summary}: {len(srows)} rows, but {len(weights[c])} weights files and "
                             f"{len(references[c])} references for candidate {c}")
        for srow, wf, rf in zip(srows, weights[c], references[c]):
            doc = _weights_doc(Path(wf))
            if (doc["path"], doc["t"]) != (srow["path"], srow["t"]):
                raise BlendError(f"{summary}: row {srow['path']} t={srow['t']} does not match {wf} "
                                 f"({doc['path']} t={doc['t']})")
            img = read_exr(rf)
            attrs = read_exr_attrs(rf)
            try:
                this = (int(img.shape[1]), int(img.shape[0]), int(attrs["spp"]))
            except (KeyError, ValueError):
                raise BlendError(f"{rf}: the render records no spp") from None
            if size is None:
                size = (this, Path(rf))
            elif this != size[0]:
                raise BlendError(f"{rf}: {this[0]}x{this[1]} at {this[2]} spp, but {size[1]} is "
                                 f"{size[0][0]}x{size[0][1]} at {size[0][2]} spp")
            space, mu = candidates[c]
            w = doc["w"]
            row: dict[str, Any] = {
                "candidate": c, "space": space, "mu": float(mu), "default": int(c == default),
                "path": srow["path"], "t": srow["t"], "width": this[0], "height": this[1], "spp": this[2],
                "sum_abs_w": float(np.abs(w).sum()), "norm2_w": float(np.linalg.norm(w)),
                "clamped_fraction": doc["clamped"] / doc["measured"],
            }
            for col in ("rmse_noise", "ratio", "ratio_seed2", "rmse_noise_one", "ratio_one", "ratio_one_seed2",
                        "ratio_seed2_se", "ratio_one_seed2_se", "ratio_isolated_seed2", "ratio_isolated_seed2_se"):
                row[col] = float(srow[col]) if srow[col] != "" else math.nan
            rows.append(row)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(tables.FLOOR_CHECK)
    for row in rows:
        writer.writerow([database] + [_fmt(row[c]) if isinstance(row[c], float) else str(row[c])
                                      for c in tables.FLOOR_CHECK[1:]])
    integrity.write_csv(out, buf.getvalue())
    for c in labels:
        mine = [r["ratio_one_seed2"] for r in rows if r["candidate"] == c]
        logger.info("%s: I1- blend / noise floor (independent seed) %.3g-%.3g over %d points",
                    c, min(mine), max(mine), len(mine))
    return rows
