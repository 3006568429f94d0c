"""Figure analogues of Xu et al. 2016 ("Minimal BRDF Sampling for Two-Shot
Near-Field Reflectance Acquisition"), drawn from the evaluation stage's tables
and the optimiser's directions files.

Inputs
------
``errors.csv`` (tidy): ``database, split, setup, fov, metric, n, material,
channel, kind, value``.  ``kind`` is ``rms_log`` (RMS error in log-mapped
space, the papers' measure), ``relrms_linear`` or ``deviation`` (the
E_deviation floor: rows with setup ``all``, fov 0, metric ``none``, n 0).
Averages over the held-out materials are the rows with material ``mean`` and
channel ``all``.  Setups: ``point`` (fov 0), ``nearfield``, ``fixed_camera``,
``fixed_light``; metrics ``error`` (E(S), eq. 15), ``condition`` (κ over all
k components, Xu eq. 6) and ``condition_nielsen`` (κ of the first n
components, Nielsen 2015's released code: the papers' "previous work", drawn
red in Figs. 6, 18 and 19).

``training_size.csv``: ``database, n_train, order_seed, material, channel,
kind, value`` (+ mean rows).

Directions files ``{directions_dir}/{split}/{setup}-fov{fov}-{metric}.json``
(:func:`brdfpipe.acquisition.optimize.read_directions`).

The readers of the two tables are :mod:`brdfpipe.acquisition.figure_inputs`'s;
the figures of configurations (Figs. 8, 9, 14) are
:mod:`brdfpipe.acquisition.figures_configs`', those of rendered
reconstructions (Figs. 2, 15) :mod:`brdfpipe.acquisition.figures_recon`'s;
this module re-exports their public names.

Outputs
-------
One public function per figure, the one its record in
:mod:`brdfpipe.registry.figures` names; each takes the rule's inputs
(:class:`~brdfpipe.acquisition.figure_inputs.AcquisitionFigureInputs`) and an
output *stem* and writes ``<stem>.png`` and ``<stem>.pdf`` (a figure with a
table, :attr:`brdfpipe.registry.figures.Figure.table`, also ``<stem>.csv`` and
``<stem>.md``), each atomically (temporary sibling, then
:func:`os.replace`), and returns a :class:`FigureOutput`.
:func:`make_acquisition_figures` draws those a rule asks for, each through
its record (:func:`brdfpipe.core.plot.draw_figures`).

=============================  ================================================
``fig03-recon-vs-deviation``   E_recon vs E_deviation of the Fig. 2 materials
``fig05-error-vs-images``      near-field error vs n, one panel per FOV,
                               E(S) vs condition-number directions
``fig06-fov-vs-point``         near-field (each FOV) vs point sampling
``fig07-training-size``        error vs number of training materials
``fig08-optimal-configurations``  table + 3-D sketch of the 1-/2-image
                               near-field configurations per FOV
``fig09-configurations-fov25``  the 1- and 2-shot pairs at one FOV, with angles
``fig13-fixed-camera-light``   fixed camera / fixed light / near-field / point
``fig14-fixed-configurations``  the 2-image fixed camera / fixed light sets
``fig18-per-material``         per-material error of n point samples, with
                               the E_deviation floor
``fig19-error-vs-n``           point sampling error vs n, with the floor
=============================  ================================================

Every title names the database, read from the input (the CSV's ``database``
column, the JSON's ``database`` key).  Missing combinations (a FOV, a metric,
a set size) are skipped with a logged warning (a panel with no data says
so); a missing, empty or malformed input *file* raises
:class:`FigureInputError` (or :class:`FileNotFoundError`) naming the file.

Style, determinism and atomic writing are :mod:`brdfpipe.core.plot`'s.  The
manifold track's figures are :mod:`brdfpipe.manifold.figures`, the rendering
track's :mod:`brdfpipe.rendering.figures`.
"""

from __future__ import annotations

import logging
import math
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.ticker import LogFormatter, MaxNLocator

from brdfpipe.acquisition.figure_inputs import (
    FOV_TOL,
    AcquisitionFigureInputs,
    ErrorTable,
    TrainingTable,
    read_errors,
    read_training_size,
)
from brdfpipe.acquisition.figures_recon import (
    fig02_reconstructions,
    fig15_fixed_camera_reconstructions,
    make_reconstruction_figures,
)
from brdfpipe.acquisition.figures_configs import (
    fig08_optimal_configurations,
    fig09_configurations,
    fig14_fixed_configurations,
)
from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_write
from brdfpipe.data import databases
from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.registry import tables
from brdfpipe.core.plot import (
    COLOURS,
    FigureInputError,
    FigureOutput,
    Warnings,
    draw_figures,
    figure_stem,
    figure_stems,
    finish,
    new_figure,
    no_data,
    parse_float,
    parse_int,
    read_csv,
    single_database,
    style,
)

__all__ = [
    "AcquisitionFigureInputs",
    "ErrorTable",
    "TrainingTable",
    "read_errors",
    "read_training_size",
    "fig02_reconstructions",
    "fig15_fixed_camera_reconstructions",
    "make_reconstruction_figures",
    "recon_vs_deviation",
    "fig03_recon_vs_deviation",
    "fig05_error_vs_images",
    "fig06_fov_vs_point",
    "fig07_training_size",
    "fig08_optimal_configurations",
    "fig09_configurations",
    "fig13_fixed_camera_light",
    "fig14_fixed_configurations",
    "fig18_per_material",
    "fig19_error_vs_n",
    "make_acquisition_figures",
    "read_unseen",
    "plot_unseen",
]

logger = logging.getLogger("brdfpipe.acquisition.figures")

_FOV_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd", "#17becf", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")
_METRIC_STYLE = {
    "error": dict(label="min E(S) (eq. 15)", linestyle="-", marker="o"),
    "condition": dict(label="min condition number κ", linestyle="--", marker="s"),
}
_KIND_LABEL = {
    "rms_log": "RMS error (log-mapped BRDF)",
    "relrms_linear": "relative RMS error (cosine-weighted BRDF)",
    "deviation": "E_deviation (log-mapped BRDF)",
}


# ---------------------------------------------------------------------------
# Drawing helpers
# ---------------------------------------------------------------------------


def _fov_text(fov: float) -> str:
    return f"{fov:g}°"


def _split_text(split: str) -> str:
    if split == "train":
        return "held-out materials (model and directions from the training split)"
    if split == "all":
        return "all materials (model and directions from every material: in-sample)"
    return f"split '{split}'"


def _choose_split(table: ErrorTable, split: str, warn: Warnings) -> str:
    have = table.splits()
    if split in have:
        return split
    other = [s for s in have if s != "all"] or have
    warn(f"no rows for split {split!r} in {table.path}; using split {other[0]!r}")
    return other[0]


def _integer_x(ax: Any) -> None:
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


class _PlainLogFormatter(LogFormatter):
    """LogFormatter's choice of which ticks to label, written as plain numbers (0.3, 1, 20)."""

    def __call__(self, x: float, pos: int | None = None) -> str:
        return f"{x:.3g}" if super().__call__(x, pos) else ""


def _auto_log_y(axes: Sequence[Any], values: Iterable[float]) -> None:
    """Log y on all ``axes`` when the positive values span more than a factor of 8."""
    v = np.array([x for x in values if math.isfinite(x)], dtype=np.float64)
    if v.size and np.all(v > 0) and v.max() / v.min() > 8.0:
        for ax in axes:
            ax.set_yscale("log")
            # plain numbers (0.3, 1, 2) rather than 3×10⁻¹; minor ticks labelled while the range is short
            ax.yaxis.set_major_formatter(_PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.6)))
            ax.yaxis.set_minor_formatter(_PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.6)))


def _plot_series(ax: Any, n: np.ndarray, v: np.ndarray, **style: Any) -> None:
    ax.plot(n, v, **style)


# ---------------------------------------------------------------------------
# Figures from errors.csv
# ---------------------------------------------------------------------------


def fig05_error_vs_images(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 5: mean error over the held-out materials vs number of near-field images.

    One panel per FOV (``inp.fovs``, default every near-field FOV in the
    table); curves for directions optimised with E(S) (eq. 15) and with the
    condition number.  Absent FOVs / metrics are skipped with a warning.
    """
    fovs, split, kind = inp.fovs, inp.split, inp.kind
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig05")
    split = _choose_split(table, split, warn)
    fov_list = list(fovs) if fovs is not None else table.fovs(split, "nearfield", kind=kind)
    present = []
    for fov in fov_list:
        if any(abs(fov - f) < FOV_TOL for f in table.fovs(split, "nearfield", kind=kind)):
            present.append(float(fov))
        else:
            warn(f"no near-field rows for FOV {_fov_text(fov)} (split {split}, kind {kind}); panel skipped")
    with style():
        ncols = max(1, min(len(present), 4))
        nrows = max(1, math.ceil(len(present) / ncols))
        fig = new_figure(2.9 * ncols + 0.4, 2.7 * nrows + 0.7)
        axes = fig.subplots(nrows, ncols, sharey=True, squeeze=False).ravel()
        used, allv = [], []
        for ax, fov in zip(axes, present):
            ax.set_title(f"near-field, FOV {_fov_text(fov)}")
            for metric in ("error", "condition"):
                n, v = table.series(split, "nearfield", fov, metric, kind)
                if n.size == 0:
                    warn(f"no mean {kind} rows for near-field FOV {_fov_text(fov)}, metric {metric}")
                    continue
                st = _METRIC_STYLE[metric]
                _plot_series(ax, n, v, color=COLOURS[0] if metric == "error" else COLOURS[3], **st)
                allv.extend(v.tolist())
            ax.set_xlabel("number of images n")
            _integer_x(ax)
            used.append(ax)
        for ax in axes[len(present):]:
            if not present and ax is axes[0]:
                no_data(ax, "no near-field rows for the requested FOVs")
            else:
                ax.set_visible(False)
        if used:
            _auto_log_y(used, allv)
            for ax in axes[::ncols]:
                ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            if used[0].get_legend_handles_labels()[0]:
                used[0].legend(loc="best")
        title = f"Near-field error vs number of images ({databases.title(table.database)})"
        return finish(fig, stem, title, "Xu 2016 Fig. 5 analogue: directions optimised with E(S) vs with the "
                       f"condition number; mean over {_split_text(split)}", table.database, warn)


def _nearfield_and_point(ax: Any, table: ErrorTable, split: str, kind: str, fovs: Sequence[float],
                         warn: Warnings, allv: list[float]) -> None:
    for i, fov in enumerate(fovs):
        n, v = table.series(split, "nearfield", fov, "error", kind)
        if n.size == 0:
            warn(f"no mean {kind} rows for near-field FOV {_fov_text(fov)}, metric error; curve skipped")
            continue
        _plot_series(ax, n, v, color=_FOV_COLOURS[i % len(_FOV_COLOURS)], marker="o",
                     label=f"near-field images, FOV {_fov_text(fov)}, min E(S)")
        allv.extend(v.tolist())


#: The point-sampling curves of Xu Figs. 6, 18 and 19: metric → colour, marker, line style, legend.  Red is the
#: papers' "previous work" (Nielsen 2015's κ as released); eq. 6's κ over all k components is a curve of its own.
_POINT_CURVES: dict[str, tuple[str, str, str, str]] = {
    "error": (COLOURS[1], "^", "-", "point samples, min E(S) (eq. 15)"),
    "condition_nielsen": (COLOURS[3], "v", "--", "previous work: point samples, "
                          + acquisition_spec.METRIC_KINDS["condition_nielsen"].label),
    "condition": (COLOURS[7], "s", ":", "point samples, " + acquisition_spec.METRIC_KINDS["condition"].label),
}


def _point_curves(ax: Any, table: ErrorTable, split: str, kind: str, warn: Warnings, allv: list[float]) -> None:
    for metric, (colour, marker, linestyle, label) in _POINT_CURVES.items():
        n, v = table.series(split, "point", 0.0, metric, kind)
        if n.size == 0:
            warn(f"no mean {kind} rows for point sampling, metric {metric}; curve skipped")
            continue
        _plot_series(ax, n, v, color=colour, marker=marker, linestyle=linestyle, label=label)
        allv.extend(v.tolist())


def fig06_fov_vs_point(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 6: near-field error vs n for each FOV (E(S) directions) against point sampling vs n."""
    fovs, split, kind = inp.fovs, inp.split, inp.kind
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig06")
    split = _choose_split(table, split, warn)
    fov_list = [float(f) for f in fovs] if fovs is not None else table.fovs(split, "nearfield", "error", kind)
    with style():
        fig = new_figure(8.2, 4.3)
        ax = fig.subplots()
        allv: list[float] = []
        _nearfield_and_point(ax, table, split, kind, fov_list, warn, allv)
        _point_curves(ax, table, split, kind, warn, allv)
        if allv:
            _auto_log_y([ax], allv)
            ax.set_xlabel("number of images (near-field) / point samples n")
            ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            _integer_x(ax)
            ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
        else:
            no_data(ax, "no near-field or point rows")
        ax.set_title("near-field images vs point samples")
        title = f"Near-field acquisition per field of view vs point sampling ({databases.title(table.database)})"
        return finish(fig, stem, title, f"Xu 2016 Fig. 6 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def fig13_fixed_camera_light(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 13: error vs n for fixed camera, fixed light and near-field (at ``inp.fov_fixed``) and point sampling.

    Solid: directions optimised with E(S); dashed: with κ.
    """
    fov, split, kind = inp.fov_fixed, inp.split, inp.kind
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig13")
    split = _choose_split(table, split, warn)
    # every set-up: those with a shared direction, the other image set-ups, then point samples
    records = sorted(acquisition_spec.SETUPS.values(), key=lambda r: (not r.shared, not r.images))
    curves = [(r.name, fov if r.images else 0.0, COLOURS[r.colour % len(COLOURS)]) for r in records]
    metrics = ("error", "condition")
    with style():
        fig = new_figure(8.8, 4.5)
        ax = fig.subplots()
        allv: list[float] = []
        for setup, f, colour in curves:
            for metric in metrics:
                n, v = table.series(split, setup, f, metric, kind)
                where = f"{setup}" + (f" FOV {_fov_text(f)}" if f else "")
                if n.size == 0:
                    warn(f"no mean {kind} rows for {where}, metric {metric}; curve skipped")
                    continue
                label = acquisition_spec.setup(setup).label + (f" ({_fov_text(f)})" if f else "")
                label += ", min E(S)" if metric == "error" else ", min κ"
                _plot_series(ax, n, v, color=colour, marker="o" if metric == "error" else "s",
                             linestyle="-" if metric == "error" else "--",
                             alpha=1.0 if metric == "error" else 0.6, label=label)
                allv.extend(v.tolist())
        if allv:
            _auto_log_y([ax], allv)
            ax.set_xlabel("number of images / point samples n")
            ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            _integer_x(ax)
            ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
        else:
            no_data(ax, f"no fixed-camera/light, near-field or point rows at {_fov_text(fov)}")
        ax.set_title(f"image setups at FOV {_fov_text(fov)}; solid: min E(S), dashed: min κ")
        title = (f"Fixed camera / fixed light vs near-field and point sampling "
                 f"({databases.title(table.database)})")
        return finish(fig, stem, title, f"Xu 2016 Fig. 13 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def _deviation_split(table: ErrorTable, split: str) -> str | None:
    for s in (split, *table.splits()):
        if any(k[0] == s and k[1] == "all" and k[7] == "deviation" for k in table.values):
            return s
    return None


def _mean_deviation(table: ErrorTable, split: str, warn: Warnings) -> float | None:
    s = _deviation_split(table, split)
    if s is None:
        warn(f"no deviation rows (setup all, kind deviation) in {table.path}; E_deviation floor omitted")
        return None
    if s != split:
        warn(f"deviation rows only for split {s!r}; using them")
    n, v = table.series(s, "all", 0.0, "none", "deviation")
    if v.size:
        return float(v[0])
    mats = table.materials(s, "all", 0.0, "none", 0, "deviation")
    vals = [table.material_value(s, "all", 0.0, "none", 0, "deviation", m) for m in mats]
    vals = [x for x in vals if math.isfinite(x)]
    if not vals:
        warn("no finite deviation values; E_deviation floor omitted")
        return None
    warn("no mean deviation row; using the average of the per-material deviations")
    return float(np.mean(vals))


def fig19_error_vs_n(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 19: point sampling error vs number of samples n (E(S) and κ directions), with the E_deviation floor."""
    split, kind = inp.split, inp.kind
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig19")
    split = _choose_split(table, split, warn)
    with style():
        fig = new_figure(6.0, 4.0)
        ax = fig.subplots()
        allv: list[float] = []
        _point_curves(ax, table, split, kind, warn, allv)
        floor = _mean_deviation(table, split, warn) if kind == "rms_log" else None
        if allv:
            if floor is not None:
                ax.axhline(floor, color="black", linestyle=":", linewidth=1.4,
                           label=f"E_deviation floor (mean, {floor:.3g})")
                allv.append(floor)
            _auto_log_y([ax], allv)
            ax.set_xlabel("number of point samples n")
            ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            _integer_x(ax)
            ax.legend(loc="best")
        else:
            no_data(ax, "no point-sampling rows")
        ax.set_title("point sampling")
        title = f"Point-sampling error vs number of samples ({databases.title(table.database)})"
        return finish(fig, stem, title, f"Xu 2016 Fig. 19 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def fig18_per_material(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 18: per-material error of ``inp.n_point`` point samples (E(S), κ directions), E_deviation markers.

    Each material's value is its channel ``all`` row, else the mean of its
    channel rows; materials are the held-out ones present in the table, in
    name order.
    """
    n, split, kind = inp.n_point, inp.split, inp.kind
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig18")
    split = _choose_split(table, split, warn)
    mats = sorted({m for metric in _POINT_CURVES for m in table.materials(split, "point", 0.0, metric, n, kind)})
    dev_split = _deviation_split(table, split) if kind == "rms_log" else None
    width = max(7.0, min(16.0, 1.4 + 0.45 * len(mats)))
    with style():
        fig = new_figure(width, 4.6)
        ax = fig.subplots()
        if not mats:
            warn(f"no per-material point rows at n = {n} (split {split}, kind {kind})")
            no_data(ax, f"no per-material point-sampling rows at n = {n}")
        else:
            x = np.arange(len(mats), dtype=np.float64)
            bars = [(metric, _POINT_CURVES[metric][0], _POINT_CURVES[metric][3].replace("point samples, ", "directions: "))
                    for metric in _POINT_CURVES if table.materials(split, "point", 0.0, metric, n, kind)]
            bw = 0.76 / max(len(bars), 1)
            for j, (metric, colour, label) in enumerate(bars):
                vals = np.array([table.material_value(split, "point", 0.0, metric, n, kind, m) for m in mats])
                if not np.isfinite(vals).any():
                    warn(f"no per-material point rows at n = {n} for metric {metric}; bars skipped")
                    continue
                ax.bar(x + (j - (len(bars) - 1) / 2) * bw, np.where(np.isfinite(vals), vals, 0.0), width=bw, color=colour,
                       label=label, zorder=2)
            if dev_split is not None:
                dev = np.array([table.material_value(dev_split, "all", 0.0, "none", 0, "deviation", m) for m in mats])
                ok = np.isfinite(dev)
                if ok.any():
                    ax.plot(x[ok], dev[ok], linestyle="none", marker="_", markersize=16, markeredgewidth=2.2,
                            color="black", label="E_deviation floor", zorder=3)
                if not ok.all():
                    warn(f"no deviation rows for {', '.join(m for m, o in zip(mats, ok) if not o)}")
            elif kind == "rms_log":
                warn(f"no deviation rows in {table.path}; E_deviation markers omitted")
            ax.set_xticks(x, mats, rotation=45, ha="right", rotation_mode="anchor")
            ax.set_xlim(-0.6, len(mats) - 0.4)
            ax.set_xlabel("held-out material" if split == "train" else "material")
            ax.set_ylabel(f"{_KIND_LABEL.get(kind, kind)}\n(average over colour channels)")
            ax.grid(axis="x", visible=False)
            fig.legend(loc="outside lower center", ncols=3)  # under the plot, clear of the bars
        ax.set_title(f"point sampling, n = {n}, per material")
        title = f"Per-material error of {n} point samples ({databases.title(table.database)})"
        return finish(fig, stem, title, f"Xu 2016 Fig. 18 analogue, with the E_deviation floor; {_split_text(split)}",
                       table.database, warn)


# ---------------------------------------------------------------------------
# Fig. 3 (E_recon vs E_deviation)
# ---------------------------------------------------------------------------



def recon_vs_deviation(table: ErrorTable, materials: Sequence[str], *, split: str, setup: str, fov: float,
                       metric: str, n: int, warn: Warnings) -> list[dict[str, Any]]:
    """Per material: E_recon (Xu eq. 12) and E_deviation (eq. 9) of one direction set, from ``errors.csv``.

    E_deviation = ‖y − Qc‖ with c the least-squares coefficients (every cell
    observed) is the table's ``deviation``; the set's reconstruction x̂ =
    μ + Qc̄ lies in the span of Q, and y − Qc is orthogonal to it, so
    ``rms_log``² = ‖y − Qc̄‖²/p = E_deviation² + E_recon² (eq. 14 holds with
    equality in squares): E_recon = √(rms_log² − deviation²) per channel
    (RMS over the p cells, like both columns), clamped at 0 where rounding
    makes the difference negative.  A material's values are the means over
    its channel rows (R, G, B); a material without rows of the same
    channels of both kinds is skipped with a warning.
    """
    dev_split = _deviation_split(table, split)
    out = []
    for m in materials:
        rms = {k[6]: v for k, v in table.values.items() if k[:6] == (split, setup, fov, metric, n, m)
               and k[7] == "rms_log" and k[6] != "all"}
        dev = {k[6]: v for k, v in table.values.items() if k[:6] == (dev_split, "all", 0.0, "none", 0, m)
               and k[7] == "deviation" and k[6] != "all"}
        channels = sorted(set(rms) & set(dev))
        if not channels or set(rms) != set(dev) or not all(math.isfinite(rms[c] + dev[c]) for c in channels):
            warn(f"no rms_log and deviation rows of the same channels for {m} ({setup} FOV {_fov_text(fov)}, "
                 f"{metric}, n = {n}); skipped")
            continue
        recon = [math.sqrt(max(rms[c] ** 2 - dev[c] ** 2, 0.0)) for c in channels]
        out.append({"database": table.database, "material": m, "setup": setup, "fov": fov, "metric": metric, "n": n,
                    "e_recon": float(np.mean(recon)), "e_deviation": float(np.mean([dev[c] for c in channels])),
                    "rms_log": float(np.mean([rms[c] for c in channels]))})
    return out


def fig03_recon_vs_deviation(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 3: E_recon of the 1- and 2-image near-field E(S) sets at ``inp.figure_fov`` next to E_deviation.

    Per material of ``inp.figure_materials``: those of Fig. 2 (None: every
    held-out material with rows).  The values are :func:`recon_vs_deviation`'s; writes them to
    ``<stem>.csv`` (:data:`~brdfpipe.registry.tables.RECON_VS_DEVIATION`, one row per material
    and set size) and ``<stem>.md``.
    """
    materials, fov, split = inp.figure_materials, inp.figure_fov, inp.split
    n_images, metric = (1, 2), "error"
    table = read_errors(inp.errors_csv)
    warn = Warnings("fig03")
    split = _choose_split(table, split, warn)
    fov = float(fov)
    sizes = [int(n) for n in n_images]
    mats = list(materials) if materials is not None else table.materials(split, "nearfield", fov, metric, sizes[0],
                                                                          "rms_log")
    rows = [r for n in sizes for r in recon_vs_deviation(table, mats, split=split, setup="nearfield", fov=fov,
                                                         metric=metric, n=n, warn=warn)]
    stem = Path(stem)
    csv_path, md_path = stem.with_name(stem.name + ".csv"), stem.with_name(stem.name + ".md")
    integrity.write_csv(csv_path, [tables.RECON_VS_DEVIATION,
                                   *([f"{r[c]:.17g}" if isinstance(r[c], float) else str(r[c])
                                      for c in tables.RECON_VS_DEVIATION] for r in rows)])
    shown = [m for m in mats if any(r["material"] == m for r in rows)]
    dominant = {n: sum(r["e_recon"] > r["e_deviation"] for r in rows if r["n"] == n) for n in sizes}
    lines = [f"# E_recon vs E_deviation (Xu 2016 Fig. 3 analogue), {databases.title(table.database)}", "",
             f"Near-field FOV {_fov_text(fov)}, directions min E(S); RMS over the model's cells of the log-mapped "
             "BRDF, mean over R, G, B. E_recon = √(rms_log² − E_deviation²).", "",
             "| material | images | E_recon | E_deviation | rms_log |", "|:---|---:|---:|---:|---:|"]
    lines += [f"| {r['material']} | {r['n']} | {r['e_recon']:.4g} | {r['e_deviation']:.4g} | {r['rms_log']:.4g} |"
              for r in rows]
    md = "\n".join(lines) + "\n"
    atomic_write(md_path, lambda fh: fh.write(md), binary=False)
    with style():
        fig = new_figure(max(6.5, 1.6 + 0.9 * len(shown)), 4.6)
        ax = fig.subplots()
        if not shown:
            no_data(ax, f"no rows for the near-field sets at FOV {_fov_text(fov)}")
        else:
            x = np.arange(len(shown), dtype=np.float64)
            width = 0.8 / (1 + len(sizes))
            value = {(r["material"], r["n"]): r for r in rows}
            dev = [next(r["e_deviation"] for r in rows if r["material"] == m) for m in shown]
            ax.bar(x - 0.4 + 0.5 * width, dev, width, color="#444444", label="E_deviation (eq. 9)", zorder=2)
            for i, n in enumerate(sizes):
                vals = [value[(m, n)]["e_recon"] if (m, n) in value else math.nan for m in shown]
                ax.bar(x - 0.4 + (i + 1.5) * width, np.nan_to_num(vals), width, color=_FOV_COLOURS[i],
                       label=f"E_recon (eq. 12), {n} image{'s' if n > 1 else ''}", zorder=2)
            ax.set_xticks(x, shown, rotation=30, ha="right", rotation_mode="anchor")
            ax.set_ylabel("RMS error over the cells (log-mapped BRDF)")
            ax.grid(axis="x", visible=False)
            ax.legend(loc="best")
        ax.set_title(f"near-field, FOV {_fov_text(fov)}, min E(S): E_recon > E_deviation for "
                     + ", ".join(f"{dominant[n]} of {len(shown)} ({n} image{'s' if n > 1 else ''})" for n in sizes))
        title = f"Reconstruction vs deviation error per material ({databases.title(table.database)})"
        return finish(fig, stem, title, f"Xu 2016 Fig. 3 analogue; {_split_text(split)}", table.database, warn,
                      extra=(csv_path, md_path))


# ---------------------------------------------------------------------------
# Fig. 7 (training_size.csv)
# ---------------------------------------------------------------------------


def fig07_training_size(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 7: mean error over the held-out materials vs number of training materials (``inp.training_csv``).

    One thin curve per material order (``order_seed``) and, when there are
    several (or a ``mean`` order row exists), their average in bold.
    ``inp.fov_fixed`` and the 2 images only label the figure (the table has
    no such columns; the evaluation stage computes it for 2-image near-field).
    """
    kind, fov, n_images = inp.kind, inp.fov_fixed, 2
    if inp.training_csv is None:
        raise ValueError("fig07 needs the training-size table (training_csv)")
    table = read_training_size(inp.training_csv)
    warn = Warnings("fig07")
    seeds = table.seeds(kind)
    with style():
        fig = new_figure(6.0, 4.0)
        ax = fig.subplots()
        curves = [(s, *table.series(s, kind)) for s in seeds]
        curves = [c for c in curves if c[1].size]
        if not curves:
            warn(f"no mean {kind} rows (material mean, channel all) in {table.path}")
            no_data(ax, f"no mean {kind} rows")
        else:
            explicit = [c for c in curves if c[0] == "mean"]
            orders = [c for c in curves if c[0] != "mean"]
            many = len(orders) > 1
            for i, (s, n, v) in enumerate(orders):
                ax.plot(n, v, color=COLOURS[0] if not many else "#9ab7d3",
                        linewidth=1.6 if not many else 0.9, marker="o" if not many else None,
                        label=(f"material order {s}" if not many else ("individual material orders" if i == 0 else None)))
            if explicit:
                _, n, v = explicit[0]
                ax.plot(n, v, color=COLOURS[0], linewidth=2.2, marker="o", label="average over material orders")
            elif many:
                ns = sorted(set.intersection(*(set(c[1].tolist()) for c in orders)))
                if ns:
                    avg = [np.mean([c[2][list(c[1]).index(k)] for c in orders]) for k in ns]
                    ax.plot(ns, avg, color=COLOURS[0], linewidth=2.2, marker="o",
                            label=f"average over {len(orders)} material orders")
            ax.set_xlabel("number of training materials in the database")
            ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            _integer_x(ax)
            ax.legend(loc="best")
        ax.set_title(f"{n_images}-image near-field acquisition, FOV {_fov_text(fov)}")
        title = f"Error vs number of training materials ({databases.title(table.database)})"
        return finish(fig, stem, title, "Xu 2016 Fig. 7 analogue; mean over the held-out materials; "
                       "training materials added in random order", table.database, warn)


# ---------------------------------------------------------------------------
# All figures
# ---------------------------------------------------------------------------


def make_acquisition_figures(*, errors_csv: str | os.PathLike[str],
                             training_csv: str | os.PathLike[str] | None,
                             directions: Sequence[str | os.PathLike[str]],
                             figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                             fovs: Sequence[float], n_point: int, fov_fixed: float = 25.0,
                             figure_fov: float = 25.0, figure_materials: Sequence[str] | None = None,
                             split: str = "train", kind: str = "rms_log") -> list[Path]:
    """Write the requested Xu 2016 figure analogues; return the files written.

    ``figures``: figure key (of the rule's records in :mod:`brdfpipe.registry.figures`) → its output files
    (PNG, PDF; a figure with a table, :attr:`brdfpipe.registry.figures.Figure.table`,
    also CSV and Markdown), exactly as the workflow declares them; only
    these figures are drawn.  ``training_csv`` is needed for ``fig07``,
    ``directions`` (the direction files to tabulate) for ``fig08``, ``fig09``
    and ``fig14``.  ``fovs``: near-field FOVs of Figs. 5, 6 and 8;
    ``n_point``: number of point samples of Fig. 18; ``fov_fixed``: the FOV
    of Figs. 7 (label), 13 and 14; ``figure_fov``: the near-field FOV of
    Figs. 3 and 9 (Xu's 25°); ``figure_materials``: the materials of Fig. 3
    (Fig. 2's; None: every held-out material); ``split``: the errors.csv
    split whose rows are plotted (``train``: directions from the training
    split, evaluated on the held-out materials).
    """
    stems = figure_stems("acquisition", "plot_acquisition_figures", figures, "make_acquisition_figures")
    # Check every input before writing anything: a bad file stops the run with no partial output.
    database = read_errors(errors_csv).database
    if "fig07" in stems:
        if training_csv is None:
            raise ValueError("fig07 needs the training-size table (training_csv)")
        read_training_size(training_csv)
    inp = AcquisitionFigureInputs(errors_csv, training_csv, directions, [float(f) for f in fovs], n_point, fov_fixed,
                                  figure_fov, figure_materials, split, kind, database)
    results = draw_figures(sys.modules[__name__], "acquisition", "plot_acquisition_figures", stems, inp)
    dbs = {r.database for r in results if r.database}
    if len(dbs) > 1:
        logger.warning("figures: inputs name different databases: %s", ", ".join(sorted(dbs)))
    return [p for r in results for p in r.files]


# ---------------------------------------------------------------------------
# Closed-loop acquisition (issue 13)
# ---------------------------------------------------------------------------

_CLOSEDLOOP_SERIES = (
    ("rms_log", "table lookup", COLOURS[0]),
    ("closedloop_noiseless_rms_log", "closed loop, noiseless render", COLOURS[1]),
    ("closedloop_rms_log", "closed loop, sensor", COLOURS[3]),
)


def plot_closedloop(closedloop_csv: str | os.PathLike[str], files: Sequence[str | os.PathLike[str]]) -> FigureOutput:
    """Table-lookup vs closed-loop error (``closedloop.csv``): mean RMS log error per set, and per material.

    Left: for every captured direction set (setup, FOV, n) the mean
    ``rms_log`` over the held-out materials of the table lookup, the
    closed loop from the noiseless render and from the sensor's photograph.
    Right: each material's closed-loop (sensor) error over its table-lookup
    error, and the share of the disk's pixels the closed loop could not use.
    """
    stem = figure_stem(files)
    table = read_errors(closedloop_csv)
    warn = Warnings("closedloop")
    split = _choose_split(table, "train", warn)
    sets = sorted({(k[1], k[2], k[3], k[4]) for k in table.values if k[0] == split and k[7] == "rms_log"})
    with style():
        fig = new_figure(max(6.0, 1.0 + 1.1 * len(sets)) + 3.5, 3.6)
        left, right = fig.subplots(1, 2, width_ratios=[max(1.0, len(sets) / 3.0), 1.0])
        if not sets:
            no_data(left, "no closed-loop rows")
            no_data(right, "no closed-loop rows")
        labels = [f"{'near-field' if s == 'nearfield' else s.replace('_', ' ')} {_fov_text(f)}\n"
                  f"n = {n}" + ("" if m == "error" else f" ({m})") for s, f, m, n in sets]
        x = np.arange(len(sets), dtype=np.float64)
        width = 0.8 / len(_CLOSEDLOOP_SERIES)
        allv: list[float] = []
        for i, (kind, label, colour) in enumerate(_CLOSEDLOOP_SERIES):
            vals = []
            for s, f, m, n in sets:
                v = table.values.get((split, s, f, m, n, "mean", "all", kind), math.nan)
                if not math.isfinite(v):
                    warn(f"no mean {kind} for {s} FOV {_fov_text(f)} n = {n}")
                vals.append(v)
            left.bar(x + (i - 1) * width, vals, width, label=label, color=colour)
            allv += [v for v in vals if math.isfinite(v)]
        if sets:
            left.set_xticks(x, labels, fontsize=8)
            left.set_ylabel(f"mean {_KIND_LABEL.get('rms_log', 'rms_log')}")
            left.set_title("held-out mean per direction set")
            if allv:
                left.set_ylim(0.0, 1.25 * max(allv))  # headroom for the legend
            left.legend(loc="upper center", ncol=3, fontsize=8)
            markers = {1: "o", 2: "s", 3: "^", 4: "D", 5: "v"}
            for (s, f, m, n), xi in zip(sets, x):
                for mat in table.materials(split, s, f, m, n, "rms_log"):
                    t = table.material_value(split, s, f, m, n, "rms_log", mat)
                    c = table.material_value(split, s, f, m, n, "closedloop_rms_log", mat)
                    masked = table.material_value(split, s, f, m, n, "closedloop_masked", mat)
                    if math.isfinite(t) and math.isfinite(c) and t > 0:
                        right.scatter([c / t], [masked * 100.0 if math.isfinite(masked) else math.nan],
                                      marker=markers.get(n, "x"), color=COLOURS[int(xi) % len(COLOURS)],
                                      s=18, alpha=0.8)
            for xi, lab in zip(x, labels):
                right.scatter([], [], marker="o", color=COLOURS[int(xi) % len(COLOURS)],
                              label=lab.replace("\n", ", "))
            right.axvline(1.0, color="#666666", lw=0.8, ls="--")
            right.set_xlabel("closed-loop (sensor) / table-lookup RMS log error")
            right.set_ylabel("disk pixels not used (%)")
            right.set_title("per material")
            right.legend(loc="best", fontsize=6)
        title = f"Closed-loop vs table-lookup reconstruction ({databases.title(table.database)})"
        return finish(fig, stem, title, f"{_split_text(split)}, photographed by the optimised set-ups (Mitsuba 3, "
                      "merl BSDF, point light, sensor model) and reconstructed from the images", table.database, warn)


# ---------------------------------------------------------------------------
# Materials outside the training database (config unseen)
# ---------------------------------------------------------------------------

_UNSEEN_COLOURS = ("#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b")


def read_unseen(path: str | os.PathLike[str]) -> tuple[str, dict[str, ErrorTable]]:
    """``unseen.csv``: (the model's database, {unseen database: its rows as an :class:`ErrorTable`}).

    :class:`FigureInputError` naming the file for rows of several model
    databases, an empty label, a duplicate row or a bad number.
    """
    p, rows = read_csv(path, tables.UNSEEN_ERRORS)
    model_db = single_database(p, (r["model_database"] for r in rows))
    by_db: dict[str, dict[tuple[str, str, float, str, int, str, str, str], float]] = {}
    for r in rows:
        i = int(r["__line__"])
        if not r["database"]:
            raise FigureInputError(f"{p}: line {i}: empty 'database'")
        if r["database"] == model_db:
            raise FigureInputError(f"{p}: line {i}: a material of the model's own database {model_db} is not unseen")
        key = (r["split"], r["setup"], parse_float(p, i, "fov", r["fov"]), r["metric"],
               parse_int(p, i, "n", r["n"]), r["material"], r["channel"], r["kind"])
        values = by_db.setdefault(r["database"], {})
        if key in values:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {r['database']} "
                                   f"{dict(zip(tables.ERRORS[1:9], key))}")
        values[key] = parse_float(p, i, "value", r["value"])
    return model_db, {db: ErrorTable(p, db, v) for db, v in sorted(by_db.items())}


def _floor(table: ErrorTable, split: str) -> float | None:
    n, v = table.series(split, "all", 0.0, "none", "deviation")
    return float(v[0]) if v.size else None


def plot_unseen(errors_csv: str | os.PathLike[str], unseen_csv: str | os.PathLike[str],
                files: Sequence[str | os.PathLike[str]], *,
                closedloop_csv: str | os.PathLike[str] | None = None, split: str = "train") -> FigureOutput:
    """Materials outside the training database next to the held-out ones (Xu Figs. 5/6 layout).

    Left: mean RMS log error of point sampling (min E(S)) vs n: the held-out
    materials (``errors.csv``) and each unseen database (``unseen.csv``; thin
    lines: its materials), the deviation floors dotted.  Then one panel per
    near-field set size n (1 and 2 images when evaluated): error vs FOV by
    table lookup (solid) and, where captured, by the closed loop from the
    sensor's photographs (dashed; held-out from ``closedloop.csv``).
    """
    stem = figure_stem(files)
    held = read_errors(errors_csv)
    model_db, unseen = read_unseen(unseen_csv)
    if held.database != model_db:
        raise FigureInputError(f"{unseen_csv}: model of {model_db}, but {errors_csv} is of {held.database}")
    loop = read_errors(closedloop_csv) if closedloop_csv is not None else None
    if loop is not None and loop.database != model_db:
        raise FigureInputError(f"{closedloop_csv}: database {loop.database}, the model's is {model_db}")
    warn = Warnings("unseen")
    split = _choose_split(held, split, warn)
    sizes = sorted({k[4] for t in unseen.values() for k in t.values if k[1] == "nearfield" and k[4] in (1, 2)
                    and k[0] == split})
    colours = {db: _UNSEEN_COLOURS[i % len(_UNSEEN_COLOURS)] for i, db in enumerate(unseen)}
    with style():
        fig = new_figure(3.6 * (1 + max(1, len(sizes))) + 2.6, 4.2)
        axes = fig.subplots(1, 1 + max(1, len(sizes)), squeeze=False).ravel()
        ax = axes[0]
        allv: list[float] = []
        n, v = held.series(split, "point", 0.0, "error", "rms_log")
        if n.size:
            ax.plot(n, v, color="#000000", marker="o", label=f"held-out ({model_db})")
            allv += v.tolist()
        else:
            warn("no held-out point rows (min E(S))")
        fl = _floor(held, split)
        if fl is not None:
            ax.axhline(fl, color="#000000", lw=0.8, ls=":")
        for db, t in unseen.items():
            ns = sorted({k[4] for k in t.values if k[0] == split and k[1] == "point" and k[3] == "error"
                         and k[7] == "rms_log"})
            for mat in t.materials(split, "point", 0.0, "error", ns[0], "rms_log") if ns else []:
                mv = [t.material_value(split, "point", 0.0, "error", k, "rms_log", mat) for k in ns]
                ax.plot(ns, mv, color=colours[db], lw=0.5, alpha=0.3)
            un, uv = t.series(split, "point", 0.0, "error", "rms_log")
            if un.size:
                ax.plot(un, uv, color=colours[db], marker="s", lw=2.0, label=f"unseen: {db}")
                allv += uv.tolist()
            uf = _floor(t, split)
            if uf is not None:
                ax.axhline(uf, color=colours[db], lw=0.8, ls=":")
        if allv:
            ax.set_xlabel("number of point samples n")
            ax.set_ylabel(f"mean {_KIND_LABEL['rms_log']}")
            _integer_x(ax)
            ax.legend(loc="best", fontsize=7)
        else:
            no_data(ax, "no point rows")
        ax.set_title("point samples, min E(S) (dotted: floors)")
        for ax, size in zip(axes[1:], sizes or [None]):
            if size is None:
                no_data(ax, "no near-field rows of 1 or 2 images")
                continue
            series = [(f"held-out ({model_db})", "#000000", held, "rms_log", "-"),
                      *[(f"unseen: {db}", colours[db], t, "rms_log", "-") for db, t in unseen.items()]]
            if loop is not None:
                series.append(("held-out, closed loop (sensor)", "#000000", loop, "closedloop_rms_log", "--"))
            series += [(f"{db}, closed loop (sensor)", colours[db], t, "closedloop_rms_log", "--")
                       for db, t in unseen.items()]
            for label, colour, t, kind, ls in series:
                fovs = [f for f in t.fovs(split, "nearfield", "error", kind)]
                pts = [(f, t.values.get((split, "nearfield", f, "error", size, "mean", "all", kind), math.nan))
                       for f in fovs]
                pts = [(f, val) for f, val in pts if math.isfinite(val)]
                if pts:
                    ax.plot([f for f, _ in pts], [val for _, val in pts], color=colour, ls=ls,
                            marker="o" if ls == "-" else "^", label=label)
                    allv += [val for _, val in pts]
            ax.set_xlabel("field of view (°)")
            ax.set_title(f"near-field, {size} image{'s' if size > 1 else ''}, min E(S)")
            if ax.get_legend_handles_labels()[0]:
                ax.legend(loc="best", fontsize=6)
        used = [a for a in axes if a.lines]
        if used and allv:
            _auto_log_y(used, allv)
        names = ", ".join(f"{databases.title(db)}" for db in unseen)
        title = (f"Materials never seen by the model vs held-out materials (model: {databases.title(model_db)})")
        subtitle = (f"Xu 2016 Figs. 5/6 layout; unseen: {names}; model and directions from the {model_db} training "
                    "split; means over each database's materials")
        return finish(fig, stem, title, subtitle, model_db, warn)
