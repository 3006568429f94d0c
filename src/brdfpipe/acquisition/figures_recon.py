"""Xu 2016's figures of rendered reconstructions: Fig. 2 (near-field images vs point samples) and Fig. 15 (fixed camera).

Each row is one held-out material: the input images of an image set (the
observed pixels, :func:`brdfpipe.acquisition.reconstruct.reconstruct_sets`),
the renders of the tables reconstructed from each set, and rightmost the
reference, the material's own pre-render.  Every render is the pre-renders'
scene with their settings and seed (:func:`brdfpipe.rendering.scene.render_points`),
so a reconstruction's render differs from the reference only by its table.
The panels of a row share one exposure (the reference's median luminance
at middle grey); each input image has its own (its 95th-percentile
luminance at 0.8).

Each figure writes ``<stem>.png``/``.pdf`` and a table of its panels
(``<stem>.csv`` with its digest line, ``<stem>.md``; columns
:data:`~brdfpipe.registry.tables.RECONSTRUCTION_PANELS`): per reconstruction the RMS log error of its table
(``errors.csv``'s ``rms_log``, mean over R, G, B) and the relative RMS
difference of its render from the reference.  A missing or corrupt input
raises :class:`~brdfpipe.core.plot.FigureInputError` naming it.
"""

from __future__ import annotations

import math
import os
import sys
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brdfpipe.acquisition.figure_inputs import ErrorTable, read_errors
from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_write
from brdfpipe.core.exr import ExrError, read_exr, tonemap
from brdfpipe.core.plot import (
    FigureInputError,
    FigureOutput,
    Warnings,
    draw_figures,
    figure_stems,
    finish,
    new_figure,
    no_data,
    style,
)
from brdfpipe.data import databases
from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.registry.figures import ReconSet
from brdfpipe.registry import tables

__all__ = [
    "Panel",
    "render_difference",
    "reconstruction_panels",
    "ReconFigureInputs",
    "fig02_reconstructions",
    "fig15_fixed_camera_reconstructions",
    "make_reconstruction_figures",
]


_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
_INPUT_PERCENTILE = 95.0
_INPUT_LEVEL = 0.8


@dataclass(frozen=True)
class Panel:
    """One image of a row: ``kind`` ``input`` (image ``image`` of ``recon``), ``reconstruction`` or ``reference``."""

    material: str
    column: str
    kind: str
    file: Path
    recon: ReconSet | None = None
    image: int = 0


def _read(path: Path) -> NDArray[np.float64]:
    if not path.is_file():
        raise FigureInputError(f"{path}: no such file")
    try:
        return read_exr(path).astype(np.float64)
    except ExrError as err:
        raise FigureInputError(str(err)) from None


def render_difference(image: NDArray[np.float64], reference: NDArray[np.float64]) -> float:
    """Relative RMS difference ‖I − R‖ / ‖R‖ over every pixel and channel (NaN for a black reference)."""
    if image.shape != reference.shape:
        raise FigureInputError(f"a render of shape {image.shape} against a reference of shape {reference.shape}")
    norm = float(np.sqrt(np.mean(reference * reference)))
    return float(np.sqrt(np.mean((image - reference) ** 2))) / norm if norm > 0 else math.nan


def _exposure(image: NDArray[np.float64], quantile: float, level: float) -> float:
    lum = (image @ _LUMINANCE).ravel()
    lum = lum[lum > 0]
    value = float(np.percentile(lum, quantile)) if lum.size else 0.0
    return float(np.log2(level / value)) if value > 0 else 0.0


def _set_text(s: ReconSet) -> str:
    setup, fov, metric, n = s
    where = f"FOV {fov:g}°, " if setup != "point" else ""
    return f"{setup} {where}{metric} n = {n}"


def reconstruction_panels(materials: Sequence[str], columns: Sequence[tuple[str, ReconSet]], *,
                          prerenders: Mapping[str, str | os.PathLike[str]],
                          renders: Mapping[tuple[str, ReconSet], str | os.PathLike[str]],
                          inputs: Mapping[tuple[str, ReconSet], Sequence[str | os.PathLike[str]]],
                          show_inputs: Sequence[ReconSet] = ()) -> list[list[Panel]]:
    """The rows of a figure: per material the inputs of each set of ``show_inputs``, each column's render, the reference.

    ``columns``: (label, set) in order; the inputs of a set of
    ``show_inputs`` come just before its render.  KeyError-free:
    :class:`FigureInputError` naming what is missing.
    """
    rows = []
    for m in materials:
        if m not in prerenders:
            raise FigureInputError(f"no pre-render of {m} (the reference)")
        row = []
        for label, s in columns:
            if s in show_inputs:
                files = inputs.get((m, s))
                if not files:
                    raise FigureInputError(f"no input images of {m}, {_set_text(s)}")
                row += [Panel(m, f"input {j}" if len(files) > 1 else "input", "input", Path(f), s, j)
                        for j, f in enumerate(files, start=1)]
            if (m, s) not in renders:
                raise FigureInputError(f"no render of {m} reconstructed from {_set_text(s)}")
            row.append(Panel(m, label, "reconstruction", Path(renders[(m, s)]), s))
        row.append(Panel(m, "reference", "reference", Path(prerenders[m])))
        rows.append(row)
    return rows


def _table_rows(rows: Sequence[Sequence[Panel]], images: Mapping[Path, NDArray[np.float64]], errors: ErrorTable,
                split: str, warn: Warnings) -> list[dict[str, Any]]:
    out = []
    for row in rows:
        ref = images[row[-1].file]
        for p in row:
            rms = diff = math.nan
            if p.kind == "reconstruction" and p.recon is not None:
                setup, fov, metric, n = p.recon
                rms = errors.material_value(split, setup, float(fov), metric, int(n), "rms_log", p.material)
                if not math.isfinite(rms):
                    warn(f"no rms_log rows for {p.material}, {_set_text(p.recon)} in {errors.path}")
                diff = render_difference(images[p.file], ref)
            setup, fov, metric, n = p.recon if p.recon is not None else ("", 0.0, "", 0)
            out.append({"database": errors.database, "material": p.material, "column": p.column, "kind": p.kind,
                        "setup": setup, "fov": f"{float(fov):g}" if p.recon else "", "metric": metric,
                        "n": str(n) if p.recon else "", "image": str(p.image) if p.kind == "input" else "",
                        "file": str(p.file), "rms_log": "" if math.isnan(rms) else f"{rms:.17g}",
                        "render_relative_rmse": "" if math.isnan(diff) else f"{diff:.17g}"})
    return out


def _write_tables(stem: Path, table: Sequence[Mapping[str, str]], title: str) -> tuple[Path, Path]:
    csv_path, md_path = stem.with_name(stem.name + ".csv"), stem.with_name(stem.name + ".md")
    cols = tables.RECONSTRUCTION_PANELS
    integrity.write_csv(csv_path, [cols, *([r[c] for c in cols] for r in table)])
    lines = [f"# {title}", "", "Every panel, row by row. rms_log: RMS error of the reconstructed table in the "
             "log-mapped space (errors.csv, mean over R, G, B); render Δ: ‖render − reference‖ / ‖reference‖ over "
             "the image (same scene, settings and seed).", "",
             "| material | column | set | file | rms_log | render Δ |", "|:---|:---|:---|:---|---:|---:|"]
    for r in table:
        what = f"{r['setup']} {r['fov']}° {r['metric']} n = {r['n']}".replace(" 0° ", " ") if r["setup"] else ""
        rms = f"{float(r['rms_log']):.4g}" if r["rms_log"] else ""
        diff = f"{100.0 * float(r['render_relative_rmse']):.1f} %" if r["render_relative_rmse"] else ""
        lines.append(f"| {r['material']} | {r['column']} | {what} | {Path(r['file']).name} | {rms} | {diff} |")
    md = "\n".join(lines) + "\n"
    atomic_write(md_path, lambda fh: fh.write(md), binary=False)
    return csv_path, md_path


def _draw_rows(fig: Any, rows: Sequence[Sequence[Panel]], images: Mapping[Path, NDArray[np.float64]],
               table: Sequence[Mapping[str, str]]) -> None:
    h, w = images[rows[0][-1].file].shape[:2]
    ratios = [1.0 if p.kind == "input" else w / h for p in rows[0]]
    gs = fig.add_gridspec(len(rows), len(rows[0]), width_ratios=ratios, wspace=0.04, hspace=0.28)
    by_file = {(r["material"], r["column"]): r for r in table}
    for i, row in enumerate(rows):
        ev = _exposure(images[row[-1].file], 50.0, 0.18)
        for j, p in enumerate(row):
            ax = fig.add_subplot(gs[i, j])
            img = images[p.file]
            shown = tonemap(img, _exposure(img, _INPUT_PERCENTILE, _INPUT_LEVEL) if p.kind == "input" else ev)
            ax.imshow(shown, interpolation="nearest")
            r = by_file[(p.material, p.column)]
            title = p.column
            if p.kind == "reconstruction":
                rms = f"{float(r['rms_log']):.3f}" if r["rms_log"] else "–"
                title += f"\nrms log {rms}, Δ {100.0 * float(r['render_relative_rmse']):.0f} %"
            ax.set_title(title, fontsize=6.5)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.grid(False)
            for spine in ax.spines.values():
                spine.set_visible(False)
            if j == 0:
                ax.set_ylabel(textwrap.fill(p.material, 14), fontsize=7, rotation=0, ha="right", va="center")


def _reconstruction_figure(errors_csv: str | os.PathLike[str], stem: Path, rows: Sequence[Sequence[Panel]], *,
                           title: str, subtitle: str, split: str) -> FigureOutput:
    warn = Warnings(stem.name)
    errors = read_errors(errors_csv)
    images = {p.file: _read(p.file) for row in rows for p in row}
    table = _table_rows(rows, images, errors, split, warn)
    title = f"{title} ({databases.title(errors.database)})"
    extra = _write_tables(stem, table, title)
    with style():
        if not rows:
            fig = new_figure(6.0, 2.0)
            no_data(fig.subplots(), "no held-out material to show")
        else:
            fig = new_figure(1.25 * sum(1.0 if p.kind == "input" else 1.33 for p in rows[0]) + 0.6,
                             1.3 * len(rows) + 1.1)
            _draw_rows(fig, rows, images, table)
        return finish(fig, stem, title, subtitle, errors.database, warn, extra=extra)


def _image_sets(columns: Sequence[tuple[str, ReconSet]]) -> list[ReconSet]:
    return [s for _, s in columns if s[0] != "point"]


@dataclass(frozen=True)
class ReconFigureInputs:
    """Everything the figures of ``plot_reconstruction_figures`` read, checked by :func:`make_reconstruction_figures`.

    ``columns``: figure key → its (label, set) columns
    (:func:`brdfpipe.plan.outputs.reconstruction_columns`); ``prerenders``:
    material → its pre-render; ``renders``: (material, set) → the render of
    its reconstruction; ``inputs``: (material, set) → the set's input images.
    """

    errors_csv: str | os.PathLike[str]
    materials: Sequence[str]
    columns: Mapping[str, Sequence[tuple[str, ReconSet]]]
    prerenders: Mapping[str, str | os.PathLike[str]]
    renders: Mapping[tuple[str, ReconSet], str | os.PathLike[str]]
    inputs: Mapping[tuple[str, ReconSet], Sequence[str | os.PathLike[str]]]
    split: str = "train"


def fig02_reconstructions(inp: ReconFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 2: per material the 1-image input, its reconstruction, 5 points; the 2 inputs, theirs, 20 points; the reference.

    Its columns are ``inp.columns["fig02"]`` (label, set); every image set's
    inputs come before its render.
    """
    columns = inp.columns["fig02"]
    rows = reconstruction_panels(inp.materials, columns, prerenders=inp.prerenders, renders=inp.renders,
                                 inputs=inp.inputs, show_inputs=_image_sets(columns))
    points = sorted({acquisition_spec.METRIC_KINDS[s[2]].label for _, s in columns if s[0] == "point"})
    return _reconstruction_figure(
        inp.errors_csv, Path(stem), rows, split=inp.split,
        title="Held-out materials reconstructed from near-field images and from point samples",
        subtitle=("Xu 2016 Fig. 2 analogue; the renders of the reconstructed tables in the pre-renders' scene (same "
                  "settings and seed) next to the material's pre-render; near-field sets min E(S), point sets of "
                  f"previous work {', '.join(points) or '(none)'}; inputs: the observed pixels of each image"))


def fig15_fixed_camera_reconstructions(inp: ReconFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 15: per material the fixed-camera set's 2 inputs and reconstruction, the near-field one's, the reference."""
    columns = inp.columns["fig15"]
    rows = reconstruction_panels(inp.materials, columns, prerenders=inp.prerenders, renders=inp.renders,
                                 inputs=inp.inputs, show_inputs=[s for _, s in columns if s[0] == "fixed_camera"])
    return _reconstruction_figure(
        inp.errors_csv, Path(stem), rows, split=inp.split,
        title="Held-out materials reconstructed from two images with a fixed camera",
        subtitle=("Xu 2016 Fig. 15 analogue; renders of the reconstructed tables in the pre-renders' scene next to "
                  "the 2-image near-field reconstruction and the material's pre-render; directions min E(S); "
                  "inputs: the observed pixels of each image"))


def _by_set(materials: Sequence[str], sets: Sequence[ReconSet], files: Sequence[str | os.PathLike[str]],
            counts: Sequence[int], what: str) -> dict[tuple[str, ReconSet], list[str | os.PathLike[str]]]:
    """Files listed material by material, set by set (``counts[k]`` for set k), keyed by (material, set)."""
    need = len(materials) * sum(counts)
    if len(files) != need:
        raise ValueError(f"make_reconstruction_figures: {len(files)} {what} for {len(materials)} materials × "
                         f"{sum(counts)} per material")
    out, it = {}, iter(files)
    for m in materials:
        for s, c in zip(sets, counts):
            out[(m, s)] = [next(it) for _ in range(c)]
    return out


def make_reconstruction_figures(*, errors_csv: str | os.PathLike[str], materials: Sequence[str],
                                sets: Sequence[Sequence[Any]],
                                columns: Mapping[str, Sequence[tuple[str, Sequence[Any]]]],
                                prerenders: Sequence[str | os.PathLike[str]],
                                renders: Sequence[str | os.PathLike[str]],
                                inputs: Sequence[str | os.PathLike[str]],
                                figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                                split: str = "train") -> list[Path]:
    """Write the requested figures of rendered reconstructions, each by the function its record names.

    ``sets``: every reconstructed (setup, fov, metric, n)
    (:func:`brdfpipe.plan.outputs.reconstruction_sets`); ``columns[key]``:
    each figure's (label, set) columns (:func:`brdfpipe.plan.outputs.reconstruction_columns`);
    ``prerenders``: one per material; ``renders``: one per material and set,
    material by material; ``inputs``: the input images of each material's
    image sets (n each; none for point samples), in the same order;
    ``figures``: key → its PNG, PDF, CSV and Markdown paths.  Every input
    is read before anything is written.
    """
    stems = figure_stems("acquisition", "plot_reconstruction_figures", figures, "make_reconstruction_figures")
    missing = sorted(set(stems) - set(columns))
    if missing:
        raise ValueError(f"make_reconstruction_figures: no columns for {', '.join(missing)}")
    recon = [(str(a), float(b), str(c), int(d)) for a, b, c, d in sets]
    cols = {k: [(str(label), (str(a), float(b), str(c), int(d))) for label, (a, b, c, d) in v]
            for k, v in columns.items()}
    if len(prerenders) != len(materials):
        raise ValueError(f"make_reconstruction_figures: {len(prerenders)} pre-renders for {len(materials)} materials")
    pre = dict(zip(materials, prerenders))
    shots = _by_set(materials, recon, inputs, [s[3] if s[0] != "point" else 0 for s in recon], "input images")
    images = {k: v[0] for k, v in _by_set(materials, recon, renders, [1] * len(recon), "renders").items()}
    read_errors(errors_csv)
    for f in [*prerenders, *renders, *inputs]:
        _read(Path(f))
    inp = ReconFigureInputs(errors_csv, materials, cols, pre, images, shots, split)
    results = draw_figures(sys.modules[__name__], "acquisition", "plot_reconstruction_figures", stems, inp)
    return [p for r in results for p in r.files]
