"""Figures of the rendering track (Soler et al. 2018 §4.3, §5.2).

Soler Fig. 1 (materials at random latent points among measured ones:
:func:`render_fig01_latent_samples`), the pre-render grid of every material
(:func:`render_prerenders`), Fig. 12 (the blends of pre-renders along the
paper's path, chrome → silver-paint, next to the renders of the
interpolated materials, then the other rendered paths:
:func:`render_fig12_interpolation`) and Fig. 13 (the paper's check at that
path's midpoint: :func:`render_fig13_errors`), written by
:func:`make_render_figures` (each by the function its record names), and the
noise-floor check of the GPLVM candidates (:func:`plot_floor_check`, from
:func:`brdfpipe.rendering.blend.floor_check`'s table).  Figs. 1, 12 and 13
write a note next to them (the run's numbers their report captions quote).
Style, determinism and atomic writing are :mod:`brdfpipe.core.plot`'s.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core import integrity
from brdfpipe.core.filenames import format_t
from brdfpipe.data import databases
from brdfpipe.core.plot import (
    FigureInputError,
    FigureOutput,
    Warnings,
    draw_figures,
    figure_stem,
    figure_stems,
    finish,
    new_figure,
    style,
)
from brdfpipe.registry.manifold import SOLER_FIG1_MATERIALS, SOLER_FIG12_PATH, path_name
from brdfpipe.registry import tables

__all__ = [
    "RenderPoint",
    "RenderFigureInputs",
    "paper_path",
    "fig01_layout",
    "render_fig01_latent_samples",
    "render_prerenders",
    "render_fig12_interpolation",
    "render_fig13_errors",
    "make_render_figures",
    "FLOOR_RATIO_TARGET",
    "plot_floor_check",
]

logger = logging.getLogger("brdfpipe.rendering.figures")

#: Columns per row of Fig. 1's grid (the paper's 3 × 5).
FIG01_COLUMNS = 5


@dataclass(frozen=True)
class RenderPoint:
    """One rendered point of a latent path (from its weights JSON and the error-map folder).

    ``weights``: its blend weights {material: wᵢ}; ``clamped`` / ``measured``:
    the interpolated table's negative values written as 0 and its measured
    values; ``reference_noise``: the reference's second-seed render (Fig. 13).
    """

    path: str
    material_a: str
    material_b: str
    t: float
    reference: Path
    blended: Path
    error: Path
    q: int = 0
    weights: Mapping[str, float] = field(default_factory=dict, repr=False)
    clamped: int = 0
    measured: int = 0
    reference_noise: Path | None = None

    @property
    def sum_abs_w(self) -> float:
        """Σ|wᵢ| of the blend (1 for a convex combination)."""
        return float(sum(abs(v) for v in self.weights.values()))

    @property
    def clamped_share(self) -> float:
        """The share of the interpolated table's measured values that came out negative (written as 0)."""
        return self.clamped / self.measured if self.measured > 0 else math.nan


def _read_exr_checked(path: Path) -> NDArray[np.float64]:
    from brdfpipe.core.exr import ExrError, read_exr

    try:
        return read_exr(path).astype(np.float64)
    except ExrError as err:
        raise FigureInputError(str(err)) from None


def _read_summary(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    rows = _read_csv_rows(path, ("database", "path", "t", "rmse_blend", "rmse_noise", "ratio", "rmse_blend_seed2",
                                 "ratio_seed2", "ratio_seed2_se"))
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


def _pct(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{100.0 * x:.3g} %"


# ---------------------------------------------------------------------------
# Soler Fig. 1: materials at random latent points among measured ones
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RenderFigureInputs:
    """Everything the figures of ``plot_render_figures`` read, read and checked by :func:`make_render_figures`.

    Each figure's function (its record's ``draw``) takes it and the figure's
    stem: ``prerenders`` (material → EXR), the path ``points``, the error
    maps' ``summary`` rows ((path, t) → row), the ``database`` and, for
    Fig. 1, the latent ``samples``' document and their renders.
    """

    prerenders: Mapping[str, Path]
    points: Sequence[RenderPoint]
    summary: Mapping[tuple[str, str], Mapping[str, str]]
    database: str
    samples: Mapping[str, Any] | None = None
    sample_images: Sequence[Path] = ()


def fig01_layout(n_samples: int, materials: Sequence[str], seed: int) -> tuple[list[tuple[str, str]], str]:
    """The cells of Fig. 1, row by row (:data:`FIG01_COLUMNS` a row), ``[(kind, name), …]``, and how the measured
    materials were chosen.

    ``kind`` is ``measured`` (a material's pre-render) or ``sample`` (the
    k-th latent sample, name ``"k"``).  Four measured materials (fewer when
    the database has fewer): Soler's four (:data:`~brdfpipe.registry.manifold.SOLER_FIG1_MATERIALS`)
    where ``materials`` has them, at the paper's places, the rest drawn from
    the other materials with ``seed``; a place past the last cell moves to
    the last free cell.  The samples fill the other cells in order.
    """
    names = sorted(materials)
    paper = [(m, rc) for m, rc in SOLER_FIG1_MATERIALS if m in names]
    spots = [rc for _, rc in SOLER_FIG1_MATERIALS]
    others = [m for m in names if m not in {m for m, _ in paper}]
    want = min(len(SOLER_FIG1_MATERIALS), len(names))
    drawn = ([others[i] for i in np.random.default_rng(seed).choice(len(others), want - len(paper), replace=False)]
             if want > len(paper) else [])
    free = [rc for rc in spots if rc not in {rc for _, rc in paper}]
    measured = paper + list(zip(drawn, free))
    total = n_samples + len(measured)
    cells: list[tuple[str, str] | None] = [None] * total
    for m, (r, c) in measured:
        k = r * FIG01_COLUMNS + c
        if k >= total or cells[k] is not None:
            k = max(i for i in range(total) if cells[i] is None)
        cells[k] = ("measured", m)
    it = iter(range(n_samples))
    out = [cell if cell is not None else ("sample", str(next(it))) for cell in cells]
    lacking = [m for m, _ in SOLER_FIG1_MATERIALS if m not in names]
    how = "; ".join(part for part in (
        f"Soler's measured {', '.join(m for m, _ in paper)}" if paper else "",
        f"{', '.join(drawn)} (drawn with seed {seed} in place of {', '.join(lacking[:len(drawn)])}, which the "
        "database lacks)" if drawn else "") if part)
    return out, how


def render_fig01_latent_samples(inp: RenderFigureInputs, stem: Path) -> FigureOutput:
    """Soler Fig. 1: renders of the latent samples among measured materials' pre-renders, one exposure."""
    from brdfpipe.rendering.blend import tonemap

    samples, images, prerenders, database = inp.samples or {}, inp.sample_images, inp.prerenders, inp.database

    warn = Warnings(stem.name)
    entries = list(samples["samples"])
    if len(entries) != len(images):
        raise FigureInputError(f"{len(images)} sample renders for {len(entries)} samples")
    cells, how = fig01_layout(len(entries), list(prerenders), int(samples["seed"]))
    files = {("sample", str(k)): Path(f) for k, f in enumerate(images)}
    files.update({("measured", m): Path(prerenders[m]) for kind, m in cells if kind == "measured"})
    imgs = {key: _read_exr_checked(f) for key, f in files.items()}
    ev = _exposure(list(imgs.values()))
    rows = math.ceil(len(cells) / FIG01_COLUMNS)
    h, w = next(iter(imgs.values())).shape[:2]
    cell_w = 1.5
    fig = new_figure(FIG01_COLUMNS * cell_w, rows * (cell_w * h / w + 0.3) + 0.8)
    for k, (kind, name) in enumerate(cells):
        ax = fig.add_subplot(rows, FIG01_COLUMNS, k + 1)
        label = f"measured: {name}" if kind == "measured" else f"latent sample {int(name) + 1}"
        _image_axes(ax, tonemap(imgs[(kind, name)], ev), label, fontsize=5.5)
    sums = [float(s["sum_abs_w"]) for s in entries]
    shares = [s["clamped"] / s["measured_values"] for s in entries if s.get("measured_values")]
    q, space = int(samples["q"]), str(samples["space"])
    note = (f"{len(entries)} materials at random latent points of the default candidate's q = {q} manifold "
            f"({space} space), drawn as brdfpipe sample --seed {samples['seed']} --count {samples['count']} draws "
            f"them ({samples['candidates_drawn']} candidates drawn uniformly in the hull of the materials' latent "
            f"points for {len(entries)} with albedo in [0, 1]); their blend weights have Σ|w| from "
            f"{min(sums):.3g} to {max(sums):.3g} (median {statistics.median(sums):.3g})"
            + (f", and the renderer clamps a median {_pct(statistics.median(shares))} (at most {_pct(max(shares))}) "
               "of each table's measured values, which came out negative" if shares else "")
            + f"; among them the pre-renders of {how}, at the paper's places; one exposure ({ev:+.2f} EV).")
    title = (f"Materials at random points of the latent space among measured ones (Soler Fig. 1) — "
             f"{databases.title(database)}")
    subtitle = (f"{len(entries)} latent samples (q = {q}, seed {samples['seed']}) and {len(cells) - len(entries)} "
                "measured materials, all rendered in the pre-renders' scene and settings")
    return finish(fig, stem, title, subtitle, database, warn, note=note)


def render_prerenders(inp: RenderFigureInputs, stem: Path) -> FigureOutput:
    """Grid of every pre-rendered material (the images the blends of Soler §5.2 are made of), one common exposure."""
    from brdfpipe.rendering.blend import tonemap

    prerenders, database = inp.prerenders, inp.database

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
    title = f"Pre-rendered materials, global illumination (Soler §5.2) — {databases.title(database)}"
    return finish(fig, stem, title, f"{len(names)} materials, one exposure ({ev:+.2f} EV)", database, warn)


# ---------------------------------------------------------------------------
# Soler Figs. 12 and 13: the paper's path and its midpoint
# ---------------------------------------------------------------------------


def paper_path(points: Sequence[RenderPoint]) -> tuple[str, str]:
    """The path of Figs. 12/13 among the rendered ``points``: Soler's chrome → silver-paint, else the first; and why.

    Returns ``(path name, reason)``; the reason is "" for Soler's path.
    """
    if not points:
        raise ValueError("no rendered path point")
    names = list(dict.fromkeys(p.path for p in points))
    soler = path_name(*SOLER_FIG12_PATH)
    if soler in names:
        return soler, ""
    return names[0], (f"Soler's path {SOLER_FIG12_PATH[0]} → {SOLER_FIG12_PATH[1]} is not rendered here, the "
                      "database lacking one of them: the first rendered path instead")


def _point_numbers(q: RenderPoint, row: Mapping[str, str] | None) -> str:
    """A rendered point's numbers: blend vs reference against the floor, Σ|w| and the clamped share."""
    out = f"Σ|w| = {q.sum_abs_w:.3g}, clamped share {_pct(q.clamped_share)}"
    if row is not None:
        se = float(row["ratio_seed2_se"]) if row.get("ratio_seed2_se") else math.nan
        out = (f"relative RMSE of the blend against the second-seed reference {float(row['rmse_blend_seed2']):.3g}, "
               f"noise floor between the two seeds {float(row['rmse_noise']):.3g}, ratio "
               f"{float(row['ratio_seed2']):.3g}" + (f" ± {se:.2g}" if math.isfinite(se) else "")
               + (f" (I¹⁻ part: {float(row['ratio_one_seed2']):.3g})" if row.get("ratio_one_seed2") else "")
               + f"; {out}")
    return out


def render_fig12_interpolation(inp: RenderFigureInputs, stem: Path) -> FigureOutput:
    """Per path (the paper's first): A, blends at each t, B (top); references at each t (bottom) (Soler Fig. 12)."""
    from brdfpipe.rendering.blend import tonemap

    prerenders, points, summary, database = inp.prerenders, inp.points, inp.summary, inp.database

    warn = Warnings(stem.name)
    main, why = paper_path(points)
    if why:
        warn(why)
    paths = [main] + [p for p in dict.fromkeys(q.path for q in points) if p != main]
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
    fig = new_figure(ncol * cell, len(paths) * 2 * (cell * h / w + 0.3) + 0.7)
    gs = fig.add_gridspec(2 * len(paths), ncol)
    for r, p in enumerate(paths):
        a, b = ends[p]
        lead = "Soler Fig. 12: " if r == 0 and not why else ""
        _image_axes(fig.add_subplot(gs[2 * r, 0]), tonemap(imgs[Path(prerenders[a])], ev),
                    f"{lead}A: {a}\n(pre-rendered)", 5.0)
        for c, q in enumerate(by_path[p]):
            _image_axes(fig.add_subplot(gs[2 * r, c + 1]), tonemap(imgs[q.blended], ev),
                        f"blend t = {q.t:g}\nΣ|w| {q.sum_abs_w:.3g}", 5.5)
            _image_axes(fig.add_subplot(gs[2 * r + 1, c + 1]), tonemap(imgs[q.reference], ev),
                        f"rendered t = {q.t:g}\nclamped {_pct(q.clamped_share)}", 5.5)
        _image_axes(fig.add_subplot(gs[2 * r, ncol - 1]), tonemap(imgs[Path(prerenders[b])], ev),
                    f"B: {b}\n(pre-rendered)", 5.0)
    first = by_path[main]
    a, b = ends[main]
    note = (f"{a} → {b} in the q = {first[0].q} latent space" + (f" — {why}" if why else " (Soler's path)")
            + ", rendered at t = " + ", ".join(f"{q.t:g}" for q in first) + ": "
            + "; ".join(f"t = {q.t:g}: {_point_numbers(q, summary.get((q.path, format_t(q.t))))}" for q in first)
            + (f". {len(paths) - 1} other rendered path(s) below it." if len(paths) > 1 else "."))
    title = f"Blended pre-renders vs renders along latent paths (Soler Fig. 12) — {databases.title(database)}"
    return finish(fig, stem, title, "top: the pre-rendered ends and Σ wᵢ Iᵢ of the pre-renders between them; "
                  "bottom: the interpolated material rendered; first row pair: "
                  + (f"{a} → {b} (Soler's path)" if not why else why), database, warn, note=note)


def _midpoint(points: Sequence[RenderPoint]) -> tuple[RenderPoint, str]:
    """The paper's point of Fig. 13: the rendered point of :func:`paper_path` nearest t = 0.5, and why (or "")."""
    main, why = paper_path(points)
    q = min((p for p in points if p.path == main), key=lambda p: (abs(p.t - 0.5), p.t))
    if q.t != 0.5:
        why = "; ".join(x for x in (why, f"t = 0.5 is not rendered: the nearest rendered point, t = {q.t:g}") if x)
    return q, why


def render_fig13_errors(inp: RenderFigureInputs, stem: Path) -> FigureOutput:
    """Soler Fig. 13 at the paper's point: blend, reference, |blend − second-seed reference| and the noise floor."""
    from brdfpipe.rendering.blend import error_map, tonemap

    points, summary, database = inp.points, inp.summary, inp.database

    warn = Warnings(stem.name)
    q, why = _midpoint(points)
    if why:
        warn(why)
    if q.reference_noise is None:
        raise FigureInputError(f"{q.path} t = {format_t(q.t)}: no second-seed reference render given")
    ref, ref2, bl = (_read_exr_checked(f) for f in (q.reference, q.reference_noise, q.blended))
    if not ref.shape == ref2.shape == bl.shape:
        raise FigureInputError(f"{q.path} t = {format_t(q.t)}: the blend and the references differ in shape")
    errs = (error_map(bl, ref2), error_map(ref, ref2))
    ev = _exposure([ref])
    vmax = max(float(np.percentile(e, 99.0)) for e in errs) or 1.0
    h, w = ref.shape[:2]
    cell = 2.2
    fig = new_figure(4 * cell + 0.7, cell * h / w + 1.5)
    axes = fig.subplots(1, 4)
    _image_axes(axes[0], tonemap(bl, ev), "blend of pre-renders Σ wᵢ Iᵢ", 7.0)
    _image_axes(axes[1], tonemap(ref, ev), "reference: the interpolated\nmaterial rendered", 7.0)
    im = None
    for ax, e, name in ((axes[2], errs[0], "|blend − reference (seed 2)|"),
                        (axes[3], errs[1], "noise floor:\n|reference − reference (seed 2)|")):
        im = ax.imshow(e, cmap="magma", vmin=0.0, vmax=vmax, interpolation="nearest")
        ax.set_title(f"{name}\nmean {float(e.mean()):.3g}", fontsize=7.0)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.grid(False)
    fig.colorbar(im, ax=list(axes[2:]), fraction=0.04, pad=0.01, extend="max").set_label(
        "mean over RGB (radiance)", fontsize=6)
    row = summary.get((q.path, format_t(q.t)))
    if row is None:
        warn(f"no summary row for {q.path} t = {format_t(q.t)}")
    note = (f"{q.material_a} → {q.material_b} at t = {q.t:g} in the q = {q.q} latent space"
            + (f" — {why} —" if why else " (Soler's point)") + f": {_point_numbers(q, row)}.")
    title = (f"Blended pre-renders vs the render of the interpolated material at the path's midpoint (Soler Fig. 13)"
             f" — {databases.title(database)}")
    subtitle = (f"{q.material_a} → {q.material_b}, t = {q.t:g}, q = {q.q}"
                + (f"; {why}" if why else "") + "; error maps on one scale, against the reference's second seed "
                "(the pre-renders share the first seed's samples)")
    return finish(fig, stem, title, subtitle, database, warn, note=note)


def _read_points(weights: Sequence[str | os.PathLike[str]], references: Sequence[str | os.PathLike[str]],
                 references_noise: Sequence[str | os.PathLike[str]] | None,
                 blended: Sequence[str | os.PathLike[str]], errors: Sequence[str | os.PathLike[str]]
                 ) -> list[RenderPoint]:
    """The rendered path points from their weights JSONs (:func:`brdfpipe.manifold.analysis.path_points_to_files`)."""
    noises = list(references_noise) if references_noise is not None else [None] * len(weights)
    if not (len(weights) == len(references) == len(noises) == len(blended) == len(errors)):
        raise ValueError("weights, references, references_noise, blended and errors must list the same path points")
    points = []
    for wf, ref, ref2, bl, er in zip(weights, references, noises, blended, errors):
        doc = integrity.read_json(wf, kind="path-point weights file", error=FigureInputError)
        try:
            name, t = str(doc["path"]), float(doc["t"])
            a, b = str(doc["material_a"]), str(doc["material_b"])
            w = {str(k): float(v) for k, v in doc["weights"].items()}
            extra = (int(doc.get("q", 0)), int(doc.get("clamped", 0)), int(doc.get("measured_values", 0)))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
            raise FigureInputError(f"{wf}: not a path-point weights file ({type(err).__name__}: {err})") from None
        points.append(RenderPoint(name, a, b, t, Path(ref), Path(bl), Path(er), q=extra[0], weights=w,
                                  clamped=extra[1], measured=extra[2],
                                  reference_noise=None if ref2 is None else Path(ref2)))
    return points


def make_render_figures(*, prerenders: Mapping[str, str | os.PathLike[str]],
                        weights: Sequence[str | os.PathLike[str]], references: Sequence[str | os.PathLike[str]],
                        blended: Sequence[str | os.PathLike[str]], errors: Sequence[str | os.PathLike[str]],
                        summary: str | os.PathLike[str] | None,
                        figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                        database: str,
                        references_noise: Sequence[str | os.PathLike[str]] | None = None,
                        samples: str | os.PathLike[str] | None = None,
                        sample_images: Sequence[str | os.PathLike[str]] = ()) -> list[Path]:
    """Write the requested rendering-track figures (keys of the rule's records), PNG + PDF (+ note) each.

    Per path point ``k``: ``weights[k]`` (its weights JSON,
    :func:`brdfpipe.manifold.analysis.path_points_to_files`), ``references[k]`` and
    ``references_noise[k]`` (its reference renders, two seeds), ``blended[k]``
    and ``errors[k]`` (the blend and the error EXR of
    :func:`brdfpipe.rendering.blend.error_maps`); ``summary``: the error maps'
    ``summary.csv`` (needed for ``fig12`` and ``fig13``; ``fig13`` also needs
    ``references_noise``).  ``samples``, ``sample_images``: the latent
    samples' JSON (:func:`brdfpipe.manifold.samples.sample_to_files`) and
    their renders (``fig01``).  ``figures``: key → its files.  A missing or
    corrupt input raises :class:`FigureInputError` naming it.
    """
    stems = figure_stems("rendering", "plot_render_figures", figures, "make_render_figures")
    points = _read_points(weights, references, references_noise, blended, errors)
    pre = {m: Path(p) for m, p in prerenders.items()}
    for q in points:
        for m in (q.material_a, q.material_b):
            if m not in pre:
                raise FigureInputError(f"path {q.path}: no pre-render of {m}")
    if ("fig12" in stems or "fig13" in stems) and not points:
        raise ValueError("figures fig12 and fig13 need at least one path point")
    if ("fig12" in stems or "fig13" in stems) and summary is None:
        raise ValueError("fig12 and fig13 need the error maps' summary.csv")
    summary_rows = _read_summary(Path(summary)) if ("fig12" in stems or "fig13" in stems) and summary else {}
    samples_doc = None
    if "fig01" in stems:
        if samples is None:
            raise ValueError("fig01 needs the latent samples' JSON")
        from brdfpipe.manifold.samples import read_samples

        samples_doc = read_samples(samples, error=FigureInputError)
    inp = RenderFigureInputs(pre, points, summary_rows, database, samples_doc, [Path(f) for f in sample_images])
    with style():
        results = draw_figures(sys.modules[__name__], "rendering", "plot_render_figures", stems, inp)
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

    stem = figure_stem(files)
    rows = _read_csv_rows(Path(table), tables.FLOOR_CHECK)
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
        title = f"Blended pre-renders vs renders at the noise floor, every data space — {databases.title(database)}"
        return finish(fig, stem, title, subtitle, database, warn)
