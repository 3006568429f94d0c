"""Figures of the rendering track (Soler et al. 2018 §5.2).

The pre-render grid of every material (Fig. 1 analogue), the interpolation
strip of the rendered latent-path points (Fig. 12) and their error panel
(Fig. 13), written by :func:`make_render_figures` (stems
:data:`RENDER_FIGURE_STEMS`), and the noise-floor check of the GPLVM
candidates (:func:`plot_floor_check`, from
:func:`brdfpipe.rendering.blend.floor_check`'s table).  Style, determinism
and atomic writing are :mod:`brdfpipe.core.plot`'s.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core import integrity
from brdfpipe.core.filenames import RENDER_FIGURE_STEMS, format_t
from brdfpipe.data.databases import title as database_label
from brdfpipe.core.plot import (
    FigureInputError,
    FigureOutput,
    Warnings,
    check_keys,
    figure_stem,
    finish,
    new_figure,
    style,
)

__all__ = [
    "RENDER_FIGURE_STEMS",
    "RenderPoint",
    "render_fig01_prerenders",
    "render_fig12_interpolation",
    "render_fig13_errors",
    "make_render_figures",
    "FLOOR_RATIO_TARGET",
    "plot_floor_check",
]

logger = logging.getLogger("brdfpipe.rendering.figures")

@dataclass(frozen=True)
class RenderPoint:
    """One rendered point of a latent path (from its weights JSON and the error-map folder)."""

    path: str
    material_a: str
    material_b: str
    t: float
    reference: Path
    blended: Path
    error: Path


def _read_exr_checked(path: Path) -> NDArray[np.float64]:
    from brdfpipe.core.exr import ExrError, read_exr

    try:
        return read_exr(path).astype(np.float64)
    except ExrError as err:
        raise FigureInputError(str(err)) from None


def _read_summary(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    rows = _read_csv_rows(path, ("database", "path", "t", "rmse_blend", "rmse_noise", "ratio", "rmse_blend_seed2"))
    return {(r["path"], r["t"]): r for r in rows}


def _read_csv_rows(path: Path, need: Sequence[str]) -> list[dict[str, str]]:
    """The rows of a verified CSV (:func:`brdfpipe.core.integrity.read_csv_rows`); FigureInputError naming it."""
    if not path.is_file():
        raise FigureInputError(f"{path}: no such file")
    return integrity.read_csv_rows(path, required=need, error=FigureInputError)[1]


def _exposure(images: Sequence[NDArray[np.float64]]) -> float:
    """One exposure for a set of images: their pooled median luminance maps to 0.18 (middle grey)."""
    lum = np.concatenate([(im @ np.array([0.2126, 0.7152, 0.0722])).ravel() for im in images])
    med = float(np.median(lum[lum > 0])) if np.any(lum > 0) else 1.0
    return float(np.log2(0.18 / med)) if med > 0 else 0.0


def _image_axes(ax: Any, img: NDArray[np.uint8], title: str, fontsize: float = 6.0) -> None:
    ax.imshow(img, interpolation="nearest")
    ax.set_title(title, fontsize=fontsize)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)
    for s in ax.spines.values():
        s.set_visible(False)


def render_fig01_prerenders(prerenders: Mapping[str, Path], stem: Path, database: str) -> FigureOutput:
    """Grid of every pre-rendered material (Soler Fig. 1 analogue), one common exposure."""
    from brdfpipe.rendering.blend import tonemap

    warn = Warnings(stem.name)
    names = sorted(prerenders)
    images = [_read_exr_checked(Path(prerenders[m])) for m in names]
    ev = _exposure(images)
    cols = min(10, max(1, math.ceil(math.sqrt(len(names)))))
    rows = math.ceil(len(names) / cols)
    h, w = images[0].shape[:2]
    cell_w = 1.25
    fig = new_figure(cols * cell_w, rows * cell_w * h / w + rows * 0.18 + 0.5)
    for k, (m, im) in enumerate(zip(names, images)):
        ax = fig.add_subplot(rows, cols, k + 1)
        _image_axes(ax, tonemap(im, ev), m, fontsize=4.5)
    title = f"Pre-rendered materials, global illumination (Soler Fig. 1 analogue) — {database_label(database)}"
    return finish(fig, stem, title, f"{len(names)} materials, one exposure ({ev:+.2f} EV)", database, warn)


def render_fig12_interpolation(prerenders: Mapping[str, Path], points: Sequence[RenderPoint], stem: Path,
                               database: str) -> FigureOutput:
    """Per path: A, blended images at each t, B (top); references at each t (bottom) (Soler Fig. 12)."""
    from brdfpipe.rendering.blend import tonemap

    warn = Warnings(stem.name)
    paths = list(dict.fromkeys(p.path for p in points))
    by_path = {p: sorted((q for q in points if q.path == p), key=lambda q: q.t) for p in paths}
    ends = {p: (by_path[p][0].material_a, by_path[p][0].material_b) for p in paths}
    imgs: dict[Path, NDArray[np.float64]] = {}
    for p in paths:
        for f in [Path(prerenders[ends[p][0]]), Path(prerenders[ends[p][1]])] + [
                x for q in by_path[p] for x in (q.blended, q.reference)]:
            imgs.setdefault(f, _read_exr_checked(f))
    ev = _exposure(list(imgs.values()))
    ncol = 2 + max(len(v) for v in by_path.values())
    h, w = next(iter(imgs.values())).shape[:2]
    cell = 1.35
    fig = new_figure(ncol * cell, len(paths) * 2 * (cell * h / w + 0.25) + 0.6)
    gs = fig.add_gridspec(2 * len(paths), ncol)
    for r, p in enumerate(paths):
        a, b = ends[p]
        _image_axes(fig.add_subplot(gs[2 * r, 0]), tonemap(imgs[Path(prerenders[a])], ev), f"A: {a}", 5.0)
        for c, q in enumerate(by_path[p]):
            _image_axes(fig.add_subplot(gs[2 * r, c + 1]), tonemap(imgs[q.blended], ev), f"blend t = {q.t:g}", 5.5)
            _image_axes(fig.add_subplot(gs[2 * r + 1, c + 1]), tonemap(imgs[q.reference], ev),
                        f"reference t = {q.t:g}", 5.5)
        _image_axes(fig.add_subplot(gs[2 * r, ncol - 1]), tonemap(imgs[Path(prerenders[b])], ev), f"B: {b}", 5.0)
    title = f"Interpolation along latent paths: blended pre-renders vs renders (Soler Fig. 12) — {database_label(database)}"
    return finish(fig, stem, title, "top: Σ wᵢ Iᵢ of the pre-renders; bottom: the interpolated material rendered",
                   database, warn)


def render_fig13_errors(points: Sequence[RenderPoint], summary: Mapping[tuple[str, str], Mapping[str, str]],
                        stem: Path, database: str) -> FigureOutput:
    """Per path point: reference, blend and |blend − reference| with the relative RMSEs (Soler Fig. 13)."""
    from brdfpipe.rendering.blend import tonemap

    warn = Warnings(stem.name)
    refs = [_read_exr_checked(q.reference) for q in points]
    blends = [_read_exr_checked(q.blended) for q in points]
    errs = [_read_exr_checked(q.error)[..., 0] for q in points]
    ev = _exposure(refs)
    vmax = max(float(np.percentile(e, 99.0)) for e in errs) or 1.0
    h, w = refs[0].shape[:2]
    cell = 1.6
    fig = new_figure(3 * cell + 0.6, len(points) * (cell * h / w + 0.35) + 0.6)
    gs = fig.add_gridspec(len(points), 3)
    im = None
    for r, (q, ref, bl, er) in enumerate(zip(points, refs, blends, errs)):
        row = summary.get((q.path, format_t(q.t)))
        if row is None:
            warn(f"no summary row for {q.path} t = {format_t(q.t)}")
            note = ""
        else:
            note = (f"RMSE {float(row['rmse_blend']):.3g}, vs 2nd seed {float(row['rmse_blend_seed2']):.3g} "
                    f"(noise {float(row['rmse_noise']):.3g})")
            if row.get("rmse_blend_one_seed2"):  # the I¹⁻ part (paths with ≤ 1 bounce on the material)
                note += (f"\nI¹⁻ only: vs 2nd seed {float(row['rmse_blend_one_seed2']):.3g} "
                         f"(noise {float(row['rmse_noise_one']):.3g})")
        _image_axes(fig.add_subplot(gs[r, 0]), tonemap(ref, ev), f"{q.path}\nreference t = {q.t:g}", 5.0)
        _image_axes(fig.add_subplot(gs[r, 1]), tonemap(bl, ev), "blended pre-renders", 5.5)
        ax = fig.add_subplot(gs[r, 2])
        im = ax.imshow(er, cmap="magma", vmin=0.0, vmax=vmax, interpolation="nearest")
        ax.set_title(f"|blend − ref|, {note}", fontsize=5.0)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    if im is not None:
        fig.colorbar(im, ax=fig.axes[2::3], fraction=0.04, pad=0.01, extend="max").set_label(
            "mean over RGB of |blend − ref| (radiance)", fontsize=6)
    title = f"Blended vs reference renders of interpolated materials (Soler Fig. 13) — {database_label(database)}"
    return finish(fig, stem, title, "relative RMSE over pixels and channels, divided by the reference mean; "
                   "noise = the same between two seeds of the reference; I¹⁻: light paths with at most one "
                   "bounce on the material (blending is exact for them)", database, warn)


def make_render_figures(*, prerenders: Mapping[str, str | os.PathLike[str]],
                        weights: Sequence[str | os.PathLike[str]], references: Sequence[str | os.PathLike[str]],
                        blended: Sequence[str | os.PathLike[str]], errors: Sequence[str | os.PathLike[str]],
                        summary: str | os.PathLike[str] | None,
                        figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                        database: str) -> list[Path]:
    """Write the requested rendering-track figures (keys of :data:`RENDER_FIGURE_STEMS`), PNG + PDF each.

    Per path point ``k``: ``weights[k]`` (its weights JSON,
    :func:`brdfpipe.manifold.analysis.path_points_to_files`), ``references[k]`` (its
    reference render), ``blended[k]`` and ``errors[k]`` (the blend and the
    error EXR of :func:`brdfpipe.rendering.blend.error_maps`); ``summary``: the error
    maps' ``summary.csv`` (needed for ``fig13``).  ``figures``: key → its PNG
    and PDF paths.  A missing or corrupt input raises
    :class:`FigureInputError` naming it.
    """
    check_keys(figures, RENDER_FIGURE_STEMS, "make_render_figures")
    stems = {k: figure_stem(v) for k, v in figures.items()}
    if not (len(weights) == len(references) == len(blended) == len(errors)):
        raise ValueError("weights, references, blended and errors must list the same path points")
    points = []
    for wf, ref, bl, er in zip(weights, references, blended, errors):
        doc = integrity.read_json(wf, kind="path-point weights file", error=FigureInputError)
        try:
            name, t = str(doc["path"]), float(doc["t"])
            a, b = str(doc["material_a"]), str(doc["material_b"])
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise FigureInputError(f"{wf}: not a path-point weights file ({type(err).__name__}: {err})") from None
        points.append(RenderPoint(name, a, b, t, Path(ref), Path(bl), Path(er)))
    pre = {m: Path(p) for m, p in prerenders.items()}
    for q in points:
        for m in (q.material_a, q.material_b):
            if m not in pre:
                raise FigureInputError(f"path {q.path}: no pre-render of {m}")
    if ("fig12" in stems or "fig13" in stems) and not points:
        raise ValueError("figures fig12 and fig13 need at least one path point")
    summary_rows = _read_summary(Path(summary)) if "fig13" in stems and summary is not None else {}
    if "fig13" in stems and summary is None:
        raise ValueError("fig13 needs the error maps' summary.csv")
    draw = {
        "fig01": lambda st: render_fig01_prerenders(pre, st, database),
        "fig12": lambda st: render_fig12_interpolation(pre, points, st, database),
        "fig13": lambda st: render_fig13_errors(points, summary_rows, st, database),
    }
    with style():
        results = [draw[k](stems[k]) for k in RENDER_FIGURE_STEMS if k in stems]
    return [p for r in results for p in r.files]




# ---------------------------------------------------------------------------
# The noise-floor check of every candidate (render.floor_check)
# ---------------------------------------------------------------------------

#: Blends are "at the noise floor" up to this ratio (issue target for the I¹⁻ part).
FLOOR_RATIO_TARGET = 1.2


def plot_floor_check(*, table: str | os.PathLike[str], files: Sequence[str | os.PathLike[str]],
                     database: str) -> FigureOutput:
    """Blend error / noise floor of every candidate at every path point, whole image and I¹⁻ (PNG + PDF).

    ``table`` is :func:`brdfpipe.rendering.blend.floor_check_table`'s CSV.  Left: the
    whole image, right: its I¹⁻ part; one row of markers per candidate, one
    marker per path point, against the independent-seed reference
    (``ratio_seed2``, ``ratio_one_seed2``) with ± 2 standard errors of the
    floor's own estimate (``*_se``); lines at 1 (no error beyond the
    noise) and :data:`FLOOR_RATIO_TARGET`.  The subtitle gives the renders'
    size, spp and the floor's range.  :class:`FigureInputError` for a
    missing table, a missing column or another database.
    """
    from brdfpipe.rendering.blend import FLOOR_CHECK_COLUMNS

    stem = figure_stem(files)
    rows = _read_csv_rows(Path(table), FLOOR_CHECK_COLUMNS)
    if not rows:
        raise FigureInputError(f"{table}: no rows")
    other = sorted({r["database"] for r in rows} - {database})
    if other:
        raise FigureInputError(f"{table}: rows of database(s) {other}, this run's is {database!r}")
    warn = Warnings(stem.name)
    labels = list(dict.fromkeys(r["candidate"] for r in rows))
    default = next((r["candidate"] for r in rows if r["default"] == "1"), "")
    points = list(dict.fromkeys((r["path"], r["t"]) for r in rows))
    with style():
        from matplotlib.ticker import FuncFormatter, LogLocator

        fig = new_figure(7.2, 2.0 + 0.34 * len(labels))
        axes = fig.subplots(1, 2, sharey=True)
        panels = ((axes[0], "ratio_seed2", "whole image I"), (axes[1], "ratio_one_seed2", "I¹⁻ part (≤ 1 bounce)"))
        for ax, col, name in panels:
            for y, c in enumerate(labels):
                vals = np.array([float(r[col]) for r in rows if r["candidate"] == c], dtype=np.float64)
                se = np.array([float(r[f"{col}_se"]) for r in rows if r["candidate"] == c], dtype=np.float64)
                # ± 2 standard errors of the floor's own estimate (one pair of seeds), clipped to the log axis
                lo = np.where(np.isfinite(se), np.minimum(2 * se, 0.9 * vals), 0.0)
                hi = np.where(np.isfinite(se), 2 * se, 0.0)
                ax.errorbar(vals, np.full(vals.size, y), xerr=np.vstack([lo, hi]), fmt="none", lw=0.6,
                            color="C3" if c == default else "C0", alpha=0.6, zorder=2)
                ax.scatter(vals, np.full(vals.size, y), s=14, marker="o" if c == default else "x",
                           color="C3" if c == default else "C0", zorder=3)
                worst = np.nanmax(vals) if np.isfinite(vals).any() else math.nan
                ax.annotate(f"max {worst:.3g}", (1.0, y), xycoords=("axes fraction", "data"), fontsize=5.5,
                            ha="right", va="bottom", xytext=(0, 2), textcoords="offset points")
            ax.axvline(1.0, color="0.5", lw=0.8, ls="--")
            ax.axvline(FLOOR_RATIO_TARGET, color="C2", lw=0.8, ls=":")
            ax.set_xscale("log")
            ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
            ax.set_ylim(len(labels) - 0.5, -0.7)
            ax.set_title(name)
            ax.set_xlabel("RMSE(blend, ref.) / RMSE(two seeds)")
        axes[0].set_yticks(range(len(labels)), [c + (" (default)" if c == default else "") for c in labels])
        first = rows[0]
        floors = np.array([float(r["rmse_noise"]) for r in rows], dtype=np.float64)
        subtitle = (f"{len(points)} path points per candidate, {first['width']}×{first['height']} px, "
                    f"{first['spp']} spp; noise floor (two seeds) {floors.min():.3g}–{floors.max():.3g} "
                    f"relative; bars: ± 2 s.e. of the floor's estimate; dotted: {FLOOR_RATIO_TARGET}×")
        title = f"Blended pre-renders vs renders at the noise floor, every data space — {database_label(database)}"
        return finish(fig, stem, title, subtitle, database, warn)
