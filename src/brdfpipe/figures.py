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
``fixed_light``; metrics ``error`` (E(S), eq. 15) and ``condition`` (κ).

``training_size.csv``: ``database, n_train, order_seed, material, channel,
kind, value`` (+ mean rows).

Directions files ``{directions_dir}/{split}/{setup}-fov{fov}-{metric}.json``
(:func:`brdfpipe.acquisition.optimize.read_directions`).

Outputs
-------
One public function per figure; each takes its input path(s) and an output
*stem* and writes ``<stem>.png`` and ``<stem>.pdf`` (Fig. 8 also
``<stem>.csv`` and ``<stem>.md``), each atomically (temporary sibling, then
:func:`os.replace`), and returns a :class:`FigureOutput`.
:func:`make_acquisition_figures` writes them all.

=============================  ================================================
``fig05-error-vs-images``      near-field error vs n, one panel per FOV,
                               E(S) vs condition-number directions
``fig06-fov-vs-point``         near-field (each FOV) vs point sampling
``fig07-training-size``        error vs number of training materials
``fig08-optimal-configurations``  table + 3-D sketch of the 1-/2-image
                               near-field configurations per FOV (Figs. 8, 9)
``fig13-fixed-camera-light``   fixed camera / fixed light / near-field / point
``fig18-per-material``         per-material error of n point samples, with
                               the E_deviation floor
``fig19-error-vs-n``           point sampling error vs n, with the floor
=============================  ================================================

Every title names the database, read from the input (the CSV's ``database``
column, the JSON's ``database`` key).  Missing combinations (a FOV, a metric,
a set size) are skipped with a logged warning (a panel with no data says
so); a missing, empty or malformed input *file* raises
:class:`FigureInputError` (or :class:`FileNotFoundError`) naming the file.

Determinism: figures are built on :class:`matplotlib.figure.Figure` with the
Agg canvas (pyplot and the global backend are never touched), under
matplotlib's default rcParams plus the fixed overrides in :data:`RC_PARAMS`
(``svg.hashsalt`` included); PDFs are written with ``CreationDate`` None and
PNGs without a timestamp, so the same inputs give the same bytes with the
same matplotlib and FreeType.

Manifold track
--------------
The second half of the module draws the Soler et al. 2018 analogues (Figs.
5, 7, 8, 9, 10 and eq. 7) from the GPLVM fits and ``brdfpipe.manifold.analysis``'s
tables: :func:`make_manifold_figures` (stems :data:`MANIFOLD_FIGURE_STEMS`),
with the same style, atomic writing and determinism; there every input is
read and checked first, and a missing file too raises
:class:`FigureInputError` naming it.
"""

from __future__ import annotations

import csv
import logging
import math
import os
import textwrap
import zipfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib as mpl
import matplotlib.style
import numpy as np
from numpy.typing import NDArray
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import Rectangle
from matplotlib.ticker import LogFormatter, MaxNLocator

from brdfpipe.core.filenames import FIGURE_STEMS, MANIFOLD_FIGURE_STEMS, RENDER_FIGURE_STEMS, format_t
from brdfpipe.core.version import full_version
from brdfpipe.core.atomic import atomic_write as _atomic_write

__all__ = [
    "ERRORS_COLUMNS",
    "TRAINING_COLUMNS",
    "RC_PARAMS",
    "DPI",
    "FIGURE_STEMS",
    "figure_stem",
    "FigureInputError",
    "FigureOutput",
    "ErrorTable",
    "TrainingTable",
    "read_errors",
    "read_training_size",
    "database_label",
    "fig05_error_vs_images",
    "fig06_fov_vs_point",
    "fig07_training_size",
    "fig08_optimal_configurations",
    "fig13_fixed_camera_light",
    "fig18_per_material",
    "fig19_error_vs_n",
    "make_acquisition_figures",
]

logger = logging.getLogger("brdfpipe.figures")

#: Required columns of ``errors.csv`` (extra columns are ignored).
ERRORS_COLUMNS: tuple[str, ...] = (
    "database", "split", "setup", "fov", "metric", "n", "material", "channel", "kind", "value",
)
#: Required columns of ``training_size.csv``.
TRAINING_COLUMNS: tuple[str, ...] = ("database", "n_train", "order_seed", "material", "channel", "kind", "value")

#: Resolution of the PNGs (pixels per inch); the figure sizes are fixed, so a
#: PNG is ``round(w·DPI) × round(h·DPI)`` pixels (see FigureOutput.size_px).
DPI: int = 150

#: rcParams applied on top of matplotlib's defaults (never the user's matplotlibrc).
RC_PARAMS: dict[str, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 9.0,
    "axes.titlesize": 9.5,
    "axes.labelsize": 9.0,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "legend.fontsize": 7.5,
    "legend.framealpha": 0.85,
    "figure.titlesize": 10.5,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.6,
    "lines.linewidth": 1.6,
    "lines.markersize": 4.5,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "savefig.dpi": DPI,
    "savefig.facecolor": "white",
    "figure.facecolor": "white",
    "svg.hashsalt": "brdfpipe-figures",
    "pdf.fonttype": 42,
    "pdf.compression": 6,
    "path.simplify": False,
    "text.usetex": False,
    "axes.unicode_minus": True,
}

# A fixed colour cycle (matplotlib's tab10), so colours never depend on rcParams.
_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
            "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
_FOV_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd", "#17becf", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")
_IMAGE_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")
_METRIC_STYLE = {
    "error": dict(label="min E(S) (eq. 15)", linestyle="-", marker="o"),
    "condition": dict(label="min condition number κ", linestyle="--", marker="s"),
}
_KIND_LABEL = {
    "rms_log": "RMS error (log-mapped BRDF)",
    "relrms_linear": "relative RMS error (cosine-weighted BRDF)",
    "deviation": "E_deviation (log-mapped BRDF)",
}
_SETUP_LABEL = {
    "point": "point samples",
    "nearfield": "near-field",
    "fixed_camera": "fixed camera, moving light",
    "fixed_light": "fixed light, moving camera",
}
_FOV_TOL = 1e-6


class FigureInputError(ValueError):
    """An input file of a figure is empty, malformed or lacks required columns (the message names it)."""


@dataclass(frozen=True)
class FigureOutput:
    """What one figure function wrote.

    ``files``: the paths written (PNG, PDF, then any table files);
    ``title``: the figure's title (it names the database; it is also the
    PNG's and PDF's ``Title`` metadata); ``panel_titles``: the axes' titles;
    ``database``: the database name read from the input ("" if none was
    readable); ``size_px``: (height, width) of the PNG; ``warnings``: the
    skipped combinations, as logged.
    """

    files: tuple[Path, ...]
    title: str
    panel_titles: tuple[str, ...]
    database: str
    size_px: tuple[int, int]
    warnings: tuple[str, ...] = ()


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------


def _read_csv(path: str | os.PathLike[str], required: Sequence[str]) -> tuple[Path, list[dict[str, str]]]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: input file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FigureInputError(f"{path}: not a UTF-8 text file ({exc})") from exc
    if not text.strip():
        raise FigureInputError(f"{path}: empty file (expected a CSV header with columns {', '.join(required)})")
    reader = csv.DictReader(text.splitlines())
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in required if c not in header]
    if missing:
        raise FigureInputError(
            f"{path}: missing column(s) {', '.join(missing)} (header: {', '.join(header) or 'none'}; "
            f"required: {', '.join(required)})"
        )
    rows: list[dict[str, str]] = []
    for raw in reader:
        row = {(k or "").strip(): (v or "").strip() if isinstance(v, str) else v for k, v in raw.items()}
        if None in raw or any(row.get(c) is None for c in required):
            raise FigureInputError(f"{path}: line {reader.line_num}: wrong number of fields")
        row["__line__"] = str(reader.line_num)
        rows.append(row)
    if not rows:
        raise FigureInputError(f"{path}: no data rows (only a header)")
    return path, rows


def _parse_float(path: Path, line: int, column: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise FigureInputError(f"{path}: line {line}: column {column!r} is not a number: {text!r}") from None


def _parse_int(path: Path, line: int, column: str, text: str) -> int:
    x = _parse_float(path, line, column, text)
    if not math.isfinite(x) or x != int(x):
        raise FigureInputError(f"{path}: line {line}: column {column!r} is not an integer: {text!r}")
    return int(x)


def _single_database(path: Path, values: Iterable[str]) -> str:
    names = sorted(set(values))
    if any(not v for v in names):
        raise FigureInputError(f"{path}: empty 'database' value")
    if len(names) != 1:
        raise FigureInputError(f"{path}: rows from more than one database ({', '.join(names)}); expected one")
    return names[0]


def database_label(name: str) -> str:
    """How a title names a database: ``merl`` → "MERL database", ``synthetic`` → "synthetic database"."""
    name = str(name).strip()
    if not name:
        return "unknown database"
    shown = "MERL" if name.lower() == "merl" else name
    return shown if shown.lower().endswith("database") else f"{shown} database"


@dataclass(frozen=True)
class ErrorTable:
    """``errors.csv``, parsed: one value per (split, setup, fov, metric, n, material, channel, kind)."""

    path: Path
    database: str
    values: dict[tuple[str, str, float, str, int, str, str, str], float]

    def splits(self) -> list[str]:
        return sorted({k[0] for k in self.values})

    def fovs(self, split: str, setup: str, metric: str | None = None, kind: str | None = None) -> list[float]:
        return sorted({k[2] for k in self.values if k[0] == split and k[1] == setup
                       and (metric is None or k[3] == metric) and (kind is None or k[7] == kind)})

    def series(self, split: str, setup: str, fov: float, metric: str, kind: str,
               material: str = "mean", channel: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """(n, value) sorted by n, finite values only (empty arrays if none)."""
        pts = sorted((k[4], v) for k, v in self.values.items()
                     if k[0] == split and k[1] == setup and abs(k[2] - fov) < _FOV_TOL and k[3] == metric
                     and k[5] == material and k[6] == channel and k[7] == kind and math.isfinite(v))
        return (np.array([p[0] for p in pts], dtype=np.int64), np.array([p[1] for p in pts], dtype=np.float64))

    def materials(self, split: str, setup: str, fov: float, metric: str, n: int, kind: str) -> list[str]:
        return sorted({k[5] for k in self.values
                       if k[0] == split and k[1] == setup and abs(k[2] - fov) < _FOV_TOL and k[3] == metric
                       and k[4] == n and k[7] == kind and k[5] != "mean"})

    def material_value(self, split: str, setup: str, fov: float, metric: str, n: int, kind: str,
                       material: str) -> float:
        """A material's value averaged over channels: its ``all`` row, else the mean of its channel rows."""
        vals = {k[6]: v for k, v in self.values.items()
                if k[0] == split and k[1] == setup and abs(k[2] - fov) < _FOV_TOL and k[3] == metric
                and k[4] == n and k[7] == kind and k[5] == material}
        if "all" in vals and math.isfinite(vals["all"]):
            return vals["all"]
        chans = [v for c, v in sorted(vals.items()) if c != "all" and math.isfinite(v)]
        return float(np.mean(chans)) if chans else math.nan


def read_errors(path: str | os.PathLike[str]) -> ErrorTable:
    """Read and check ``errors.csv`` (:class:`FigureInputError` naming the file if it is malformed)."""
    p, rows = _read_csv(path, ERRORS_COLUMNS)
    values: dict[tuple[str, str, float, str, int, str, str, str], float] = {}
    for r in rows:
        i = int(r["__line__"])
        for c in ("split", "setup", "metric", "material", "channel", "kind"):
            if not r[c]:
                raise FigureInputError(f"{p}: line {i}: empty {c!r}")
        key = (r["split"], r["setup"], _parse_float(p, i, "fov", r["fov"]), r["metric"],
               _parse_int(p, i, "n", r["n"]), r["material"], r["channel"], r["kind"])
        if key in values:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {dict(zip(ERRORS_COLUMNS[1:9], key))}")
        values[key] = _parse_float(p, i, "value", r["value"])
    return ErrorTable(p, _single_database(p, (r["database"] for r in rows)), values)


@dataclass(frozen=True)
class TrainingTable:
    """``training_size.csv``, parsed: value per (n_train, order_seed, material, channel, kind)."""

    path: Path
    database: str
    values: dict[tuple[int, str, str, str, str], float]

    def seeds(self, kind: str) -> list[str]:
        return sorted({k[1] for k in self.values if k[4] == kind},
                      key=lambda s: (0, int(s), s) if s.lstrip("-").isdigit() else (1, 0, s))

    def series(self, seed: str, kind: str, material: str = "mean", channel: str = "all") -> tuple[np.ndarray, np.ndarray]:
        pts = sorted((k[0], v) for k, v in self.values.items()
                     if k[1] == seed and k[2] == material and k[3] == channel and k[4] == kind and math.isfinite(v))
        return (np.array([p[0] for p in pts], dtype=np.int64), np.array([p[1] for p in pts], dtype=np.float64))


def read_training_size(path: str | os.PathLike[str]) -> TrainingTable:
    """Read and check ``training_size.csv`` (:class:`FigureInputError` naming the file if it is malformed)."""
    p, rows = _read_csv(path, TRAINING_COLUMNS)
    values: dict[tuple[int, str, str, str, str], float] = {}
    for r in rows:
        i = int(r["__line__"])
        for c in ("order_seed", "material", "channel", "kind"):
            if not r[c]:
                raise FigureInputError(f"{p}: line {i}: empty {c!r}")
        key = (_parse_int(p, i, "n_train", r["n_train"]), r["order_seed"], r["material"], r["channel"], r["kind"])
        if key in values:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {dict(zip(TRAINING_COLUMNS[1:6], key))}")
        values[key] = _parse_float(p, i, "value", r["value"])
    return TrainingTable(p, _single_database(p, (r["database"] for r in rows)), values)


# ---------------------------------------------------------------------------
# Drawing helpers
# ---------------------------------------------------------------------------


class _Warnings:
    """Collects (and logs) the skipped combinations of one figure."""

    def __init__(self, figure: str) -> None:
        self.figure = figure
        self.items: list[str] = []

    def __call__(self, msg: str) -> None:
        text = f"{self.figure}: {msg}"
        logger.warning(text)
        self.items.append(text)


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


@contextmanager
def _style() -> Iterator[None]:
    """matplotlib's default style plus :data:`RC_PARAMS`, whatever the user's matplotlibrc; restored on exit."""
    with mpl.rc_context():
        mpl.style.use("default")
        mpl.rcParams.update(RC_PARAMS)
        yield


def _fov_text(fov: float) -> str:
    return f"{fov:g}°"


def _split_text(split: str) -> str:
    if split == "train":
        return "held-out materials (model and directions from the training split)"
    if split == "all":
        return "all materials (model and directions from every material: in-sample)"
    return f"split '{split}'"


def _choose_split(table: ErrorTable, split: str, warn: _Warnings) -> str:
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


def _no_data(ax: Any, what: str) -> None:
    ax.text(0.5, 0.5, f"no data\n({what})", ha="center", va="center", transform=ax.transAxes,
            fontsize=9, color="#666666")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)
    for spine in ax.spines.values():
        spine.set_visible(False)


def _save(fig: Figure, stem: str | os.PathLike[str], title: str) -> tuple[tuple[Path, Path], tuple[int, int]]:
    stem = Path(stem)
    png = stem.with_name(stem.name + ".png")
    pdf = stem.with_name(stem.name + ".pdf")
    software = f"brdfpipe {full_version()} (matplotlib {mpl.__version__})"
    _atomic_write(png, lambda fh: fig.savefig(fh, format="png", dpi=DPI,
                                              metadata={"Title": title, "Software": software}))
    _atomic_write(pdf, lambda fh: fig.savefig(fh, format="pdf", dpi=DPI,
                                              metadata={"Title": title, "Creator": software,
                                                        "CreationDate": None, "ModDate": None}))
    w, h = fig.get_size_inches()
    return (png, pdf), (int(round(h * DPI)), int(round(w * DPI)))


def _finish(fig: Figure, stem: str | os.PathLike[str], title: str, subtitle: str, database: str,
            warn: _Warnings, extra: Sequence[Path] = ()) -> FigureOutput:
    """Title the figure (``title``, then ``subtitle``, each wrapped to its width) and save it."""
    chars = max(30, int(float(fig.get_size_inches()[0]) * 72.0 / (0.6 * 10.5)))
    lines = textwrap.wrap(title, chars) + (textwrap.wrap(subtitle, chars) if subtitle else [])
    fig.suptitle("\n".join(lines))
    panel_titles = tuple(ax.get_title() for ax in fig.axes if ax.get_title())
    files, size = _save(fig, stem, title)
    return FigureOutput(files=files + tuple(extra), title=title, panel_titles=panel_titles,
                        database=database, size_px=size, warnings=tuple(warn.items))


def _plot_series(ax: Any, n: np.ndarray, v: np.ndarray, **style: Any) -> None:
    ax.plot(n, v, **style)


# ---------------------------------------------------------------------------
# Figures from errors.csv
# ---------------------------------------------------------------------------


def fig05_error_vs_images(errors_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                          fovs: Sequence[float] | None = None, split: str = "train",
                          kind: str = "rms_log") -> FigureOutput:
    """Xu Fig. 5: mean error over the held-out materials vs number of near-field images.

    One panel per FOV (``fovs``, default every near-field FOV in the table);
    curves for directions optimised with E(S) (eq. 15) and with the condition
    number.  Absent FOVs / metrics are skipped with a warning.
    """
    table = read_errors(errors_csv)
    warn = _Warnings("fig05")
    split = _choose_split(table, split, warn)
    fov_list = list(fovs) if fovs is not None else table.fovs(split, "nearfield", kind=kind)
    present = []
    for fov in fov_list:
        if any(abs(fov - f) < _FOV_TOL for f in table.fovs(split, "nearfield", kind=kind)):
            present.append(float(fov))
        else:
            warn(f"no near-field rows for FOV {_fov_text(fov)} (split {split}, kind {kind}); panel skipped")
    with _style():
        ncols = max(1, min(len(present), 4))
        nrows = max(1, math.ceil(len(present) / ncols))
        fig = _new_figure(2.9 * ncols + 0.4, 2.7 * nrows + 0.7)
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
                _plot_series(ax, n, v, color=_COLOURS[0] if metric == "error" else _COLOURS[3], **st)
                allv.extend(v.tolist())
            ax.set_xlabel("number of images n")
            _integer_x(ax)
            used.append(ax)
        for ax in axes[len(present):]:
            if not present and ax is axes[0]:
                _no_data(ax, "no near-field rows for the requested FOVs")
            else:
                ax.set_visible(False)
        if used:
            _auto_log_y(used, allv)
            for ax in axes[::ncols]:
                ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            if used[0].get_legend_handles_labels()[0]:
                used[0].legend(loc="best")
        title = f"Near-field error vs number of images ({database_label(table.database)})"
        return _finish(fig, stem, title, "Xu 2016 Fig. 5 analogue: directions optimised with E(S) vs with the "
                       f"condition number; mean over {_split_text(split)}", table.database, warn)


def _nearfield_and_point(ax: Any, table: ErrorTable, split: str, kind: str, fovs: Sequence[float],
                         warn: _Warnings, allv: list[float]) -> None:
    for i, fov in enumerate(fovs):
        n, v = table.series(split, "nearfield", fov, "error", kind)
        if n.size == 0:
            warn(f"no mean {kind} rows for near-field FOV {_fov_text(fov)}, metric error; curve skipped")
            continue
        _plot_series(ax, n, v, color=_FOV_COLOURS[i % len(_FOV_COLOURS)], marker="o",
                     label=f"near-field images, FOV {_fov_text(fov)}, min E(S)")
        allv.extend(v.tolist())


def _point_curves(ax: Any, table: ErrorTable, split: str, kind: str, warn: _Warnings, allv: list[float]) -> None:
    for metric, colour, label in (("error", _COLOURS[1], "point samples, min E(S)"),
                                  ("condition", _COLOURS[3], "point samples, min κ (Xu eq. 6)")):
        n, v = table.series(split, "point", 0.0, metric, kind)
        if n.size == 0:
            warn(f"no mean {kind} rows for point sampling, metric {metric}; curve skipped")
            continue
        _plot_series(ax, n, v, color=colour, marker="^" if metric == "error" else "v",
                     linestyle="-" if metric == "error" else "--", label=label)
        allv.extend(v.tolist())


def fig06_fov_vs_point(errors_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                       fovs: Sequence[float] | None = None, split: str = "train",
                       kind: str = "rms_log") -> FigureOutput:
    """Xu Fig. 6: near-field error vs n for each FOV (E(S) directions) against point sampling vs n."""
    table = read_errors(errors_csv)
    warn = _Warnings("fig06")
    split = _choose_split(table, split, warn)
    fov_list = [float(f) for f in fovs] if fovs is not None else table.fovs(split, "nearfield", "error", kind)
    with _style():
        fig = _new_figure(8.2, 4.3)
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
            _no_data(ax, "no near-field or point rows")
        ax.set_title("near-field images vs point samples")
        title = f"Near-field acquisition per field of view vs point sampling ({database_label(table.database)})"
        return _finish(fig, stem, title, f"Xu 2016 Fig. 6 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def fig13_fixed_camera_light(errors_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                             fov: float = 25.0, split: str = "train", kind: str = "rms_log",
                             include_condition: bool = True) -> FigureOutput:
    """Xu Fig. 13: error vs n for fixed camera, fixed light and near-field (at ``fov``) and point sampling.

    Solid: directions optimised with E(S); dashed (``include_condition``): with κ.
    """
    table = read_errors(errors_csv)
    warn = _Warnings("fig13")
    split = _choose_split(table, split, warn)
    curves = (("fixed_camera", fov, _COLOURS[0]), ("fixed_light", fov, _COLOURS[4]),
              ("nearfield", fov, _COLOURS[2]), ("point", 0.0, _COLOURS[1]))
    metrics = ("error", "condition") if include_condition else ("error",)
    with _style():
        fig = _new_figure(8.8, 4.5)
        ax = fig.subplots()
        allv: list[float] = []
        for setup, f, colour in curves:
            for metric in metrics:
                n, v = table.series(split, setup, f, metric, kind)
                where = f"{setup}" + ("" if setup == "point" else f" FOV {_fov_text(f)}")
                if n.size == 0:
                    warn(f"no mean {kind} rows for {where}, metric {metric}; curve skipped")
                    continue
                label = _SETUP_LABEL[setup] + ("" if setup == "point" else f" ({_fov_text(f)})")
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
            _no_data(ax, f"no fixed-camera/light, near-field or point rows at {_fov_text(fov)}")
        ax.set_title(f"image setups at FOV {_fov_text(fov)}; solid: min E(S), dashed: min κ")
        title = (f"Fixed camera / fixed light vs near-field and point sampling "
                 f"({database_label(table.database)})")
        return _finish(fig, stem, title, f"Xu 2016 Fig. 13 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def _deviation_split(table: ErrorTable, split: str) -> str | None:
    for s in (split, *table.splits()):
        if any(k[0] == s and k[1] == "all" and k[7] == "deviation" for k in table.values):
            return s
    return None


def _mean_deviation(table: ErrorTable, split: str, warn: _Warnings) -> float | None:
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


def fig19_error_vs_n(errors_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                     split: str = "train", kind: str = "rms_log") -> FigureOutput:
    """Xu Fig. 19: point sampling error vs number of samples n (E(S) and κ directions), with the E_deviation floor."""
    table = read_errors(errors_csv)
    warn = _Warnings("fig19")
    split = _choose_split(table, split, warn)
    with _style():
        fig = _new_figure(6.0, 4.0)
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
            _no_data(ax, "no point-sampling rows")
        ax.set_title("point sampling")
        title = f"Point-sampling error vs number of samples ({database_label(table.database)})"
        return _finish(fig, stem, title, f"Xu 2016 Fig. 19 analogue; mean over {_split_text(split)}",
                       table.database, warn)


def fig18_per_material(errors_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                       n: int = 5, split: str = "train", kind: str = "rms_log") -> FigureOutput:
    """Xu Fig. 18: per-material error of ``n`` point samples (E(S) and κ directions), with E_deviation markers.

    Each material's value is its channel ``all`` row, else the mean of its
    channel rows; materials are the held-out ones present in the table, in
    name order.
    """
    table = read_errors(errors_csv)
    warn = _Warnings("fig18")
    split = _choose_split(table, split, warn)
    mats = sorted(set(table.materials(split, "point", 0.0, "error", n, kind))
                  | set(table.materials(split, "point", 0.0, "condition", n, kind)))
    dev_split = _deviation_split(table, split) if kind == "rms_log" else None
    width = max(7.0, min(16.0, 1.4 + 0.45 * len(mats)))
    with _style():
        fig = _new_figure(width, 4.6)
        ax = fig.subplots()
        if not mats:
            warn(f"no per-material point rows at n = {n} (split {split}, kind {kind})")
            _no_data(ax, f"no per-material point-sampling rows at n = {n}")
        else:
            x = np.arange(len(mats), dtype=np.float64)
            bw = 0.38
            bars = (("error", _COLOURS[2], "directions: min E(S)"),
                    ("condition", _COLOURS[0], "directions: min κ (Xu eq. 6)"))
            for j, (metric, colour, label) in enumerate(bars):
                vals = np.array([table.material_value(split, "point", 0.0, metric, n, kind, m) for m in mats])
                if not np.isfinite(vals).any():
                    warn(f"no per-material point rows at n = {n} for metric {metric}; bars skipped")
                    continue
                ax.bar(x + (j - 0.5) * bw, np.where(np.isfinite(vals), vals, 0.0), width=bw, color=colour,
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
        title = f"Per-material error of {n} point samples ({database_label(table.database)})"
        return _finish(fig, stem, title, f"Xu 2016 Fig. 18 analogue, with the E_deviation floor; {_split_text(split)}",
                       table.database, warn)


# ---------------------------------------------------------------------------
# Fig. 7 (training_size.csv)
# ---------------------------------------------------------------------------


def fig07_training_size(training_csv: str | os.PathLike[str], stem: str | os.PathLike[str], *,
                        kind: str = "rms_log", fov: float = 25.0, n_images: int = 2) -> FigureOutput:
    """Xu Fig. 7: mean error over the held-out materials vs number of training materials.

    One thin curve per material order (``order_seed``) and, when there are
    several (or a ``mean`` order row exists), their average in bold.
    ``fov`` and ``n_images`` only label the figure (the table has no such
    columns; the evaluation stage computes it for 2-image near-field at 25°).
    """
    table = read_training_size(training_csv)
    warn = _Warnings("fig07")
    seeds = table.seeds(kind)
    with _style():
        fig = _new_figure(6.0, 4.0)
        ax = fig.subplots()
        curves = [(s, *table.series(s, kind)) for s in seeds]
        curves = [c for c in curves if c[1].size]
        if not curves:
            warn(f"no mean {kind} rows (material mean, channel all) in {table.path}")
            _no_data(ax, f"no mean {kind} rows")
        else:
            explicit = [c for c in curves if c[0] == "mean"]
            orders = [c for c in curves if c[0] != "mean"]
            many = len(orders) > 1
            for i, (s, n, v) in enumerate(orders):
                ax.plot(n, v, color=_COLOURS[0] if not many else "#9ab7d3",
                        linewidth=1.6 if not many else 0.9, marker="o" if not many else None,
                        label=(f"material order {s}" if not many else ("individual material orders" if i == 0 else None)))
            if explicit:
                _, n, v = explicit[0]
                ax.plot(n, v, color=_COLOURS[0], linewidth=2.2, marker="o", label="average over material orders")
            elif many:
                ns = sorted(set.intersection(*(set(c[1].tolist()) for c in orders)))
                if ns:
                    avg = [np.mean([c[2][list(c[1]).index(k)] for c in orders]) for k in ns]
                    ax.plot(ns, avg, color=_COLOURS[0], linewidth=2.2, marker="o",
                            label=f"average over {len(orders)} material orders")
            ax.set_xlabel("number of training materials in the database")
            ax.set_ylabel(f"mean {_KIND_LABEL.get(kind, kind)}")
            _integer_x(ax)
            ax.legend(loc="best")
        ax.set_title(f"{n_images}-image near-field acquisition, FOV {_fov_text(fov)}")
        title = f"Error vs number of training materials ({database_label(table.database)})"
        return _finish(fig, stem, title, "Xu 2016 Fig. 7 analogue; mean over the held-out materials; "
                       "training materials added in random order", table.database, warn)


# ---------------------------------------------------------------------------
# Fig. 8 / 9 (directions files)
# ---------------------------------------------------------------------------

#: Columns of the Fig. 8 table (CSV and Markdown).
FIG08_COLUMNS: tuple[str, ...] = (
    "fov_deg", "n_images", "image", "theta_h_deg", "theta_d_deg", "phi_d_deg",
    "light_theta_deg", "light_phi_deg", "camera_theta_deg", "camera_phi_deg",
    "expected_error", "split", "database",
)


def _spherical_deg(v: Sequence[float]) -> tuple[float, float]:
    x, y, z = (float(c) for c in v)
    theta = math.degrees(math.acos(max(-1.0, min(1.0, z))))
    phi = math.degrees(math.atan2(y, x)) % 360.0 if math.hypot(x, y) > 1e-9 else 0.0
    if phi >= 360.0 - 1e-9:
        phi = 0.0
    return theta, phi


@dataclass
class _ConfigRow:
    fov: float
    n_images: int
    image: int
    theta_h: float
    theta_d: float
    phi_d: float
    light: tuple[float, float, float]
    camera: tuple[float, float, float]
    expected_error: float
    split: str
    database: str
    light_sph: tuple[float, float] = field(init=False)
    camera_sph: tuple[float, float] = field(init=False)

    def __post_init__(self) -> None:
        self.light_sph = _spherical_deg(self.light)
        self.camera_sph = _spherical_deg(self.camera)

    def csv_values(self) -> list[str]:
        return [f"{self.fov:g}", str(self.n_images), str(self.image),
                f"{self.theta_h:.6f}", f"{self.theta_d:.6f}", f"{self.phi_d:.6f}",
                f"{self.light_sph[0]:.6f}", f"{self.light_sph[1]:.6f}",
                f"{self.camera_sph[0]:.6f}", f"{self.camera_sph[1]:.6f}",
                f"{self.expected_error:.10g}", self.split, self.database]


def _load_configurations(directions: Sequence[str | os.PathLike[str]], fovs: Sequence[float],
                         n_images: Sequence[int], setup: str, metric: str, splits: Sequence[str],
                         warn: _Warnings) -> tuple[list[_ConfigRow], str]:
    from brdfpipe.acquisition.optimize import read_directions  # noqa: PLC0415 (heavy import, only needed here)

    loaded = []
    for p in directions:
        path = Path(p)
        if not path.is_file():
            raise FigureInputError(f"{path}: directions file not found")
        loaded.append((path, read_directions(path)))  # ValueError naming the file if malformed
    rows: list[_ConfigRow] = []
    databases: dict[str, Path] = {}
    for fov in fovs:
        found = None
        for split in splits:
            found = next(((p, d) for p, d in loaded if d.split == split and d.setup.kind == setup
                          and d.metric == metric and abs(d.setup.fov_deg - float(fov)) <= _FOV_TOL), None)
            if found is not None:
                break
        if found is None:
            warn(f"no {setup} {metric} directions file for FOV {_fov_text(fov)} among the inputs "
                 f"(splits tried: {', '.join(splits)}); skipped")
            continue
        path, d = found
        if not d.database:
            raise FigureInputError(f"{path}: empty 'database'")
        databases.setdefault(d.database, path)
        by_n = {s.n: s for s in d.sets}
        for n in n_images:
            s = by_n.get(n)
            if s is None:
                warn(f"{path}: no set of {n} image(s); skipped")
                continue
            for i, rec in enumerate(s.records, start=1):
                rows.append(_ConfigRow(
                    fov=float(fov), n_images=n, image=i,
                    theta_h=float(rec["theta_h_deg"]), theta_d=float(rec["theta_d_deg"]),
                    phi_d=float(rec["phi_d_deg"]),
                    light=tuple(float(c) for c in rec["light"]),  # type: ignore[arg-type]
                    camera=tuple(float(c) for c in rec["camera"]),  # type: ignore[arg-type]
                    expected_error=s.expected_error, split=d.split, database=d.database))
    if len(databases) > 1:
        raise FigureInputError("directions files from different databases: "
                               + "; ".join(f"{db!r} ({p})" for db, p in sorted(databases.items())))
    return rows, next(iter(databases), "")


def _markdown(rows: Sequence[_ConfigRow], database: str, setup: str, metric: str) -> str:
    lines = [
        f"# Optimal {'- and '.join(sorted({str(r.n_images) for r in rows})) or '1- and 2'}-image "
        f"{_SETUP_LABEL.get(setup, setup)} configurations (Xu 2016 Fig. 8 analogue), {database_label(database)}",
        "",
        f"Directions optimised with {'E(S) (eq. 15)' if metric == 'error' else 'the condition number'}; "
        "angles in degrees at the centre of the sample (θh, θd, φd: Rusinkiewicz half/difference angles; "
        "light and camera as (θ, φ) spherical angles from the sample normal). "
        "E(S) is the expected error of the whole set.",
        "",
    ]
    if not rows:
        lines.append("No directions files were found for the requested fields of view.")
        return "\n".join(lines) + "\n"
    lines += [
        "| FOV | images | image | θh | θd | φd | light (θ, φ) | camera (θ, φ) | E(S) | split |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.fov:g}° | {r.n_images} | {r.image} | {r.theta_h:.1f} | {r.theta_d:.1f} | {r.phi_d:.1f} "
            f"| ({r.light_sph[0]:.1f}, {r.light_sph[1]:.1f}) | ({r.camera_sph[0]:.1f}, {r.camera_sph[1]:.1f}) "
            f"| {r.expected_error:.4g} | {r.split} |"
        )
    return "\n".join(lines) + "\n"


def _draw_configuration(ax: Any, rows: Sequence[_ConfigRow], fov: float) -> None:
    """3-D sketch: hemisphere, sample disk (radius tan(fov/2)), light arrows and camera positions."""
    t = np.linspace(0.0, 2.0 * np.pi, 73)
    for el in (0.0, 30.0, 60.0):  # parallels
        r, z = math.cos(math.radians(el)), math.sin(math.radians(el))
        ax.plot(r * np.cos(t), r * np.sin(t), np.full_like(t, z), color="#c8c8c8", linewidth=0.6)
    s = np.linspace(0.0, 0.5 * np.pi, 25)
    for az in range(0, 360, 45):  # meridians
        a = math.radians(az)
        ax.plot(np.cos(s) * math.cos(a), np.cos(s) * math.sin(a), np.sin(s), color="#dddddd", linewidth=0.5)
    nu = math.tan(math.radians(fov) / 2.0)
    ax.plot_trisurf(np.concatenate([[0.0], nu * np.cos(t)]), np.concatenate([[0.0], nu * np.sin(t)]),
                    np.zeros(t.size + 1), color="#9e9e9e", alpha=0.55, linewidth=0, shade=False)
    ax.plot(nu * np.cos(t), nu * np.sin(t), np.zeros_like(t), color="#555555", linewidth=0.8)
    ax.plot([0, 0], [0, 0], [0, 1.05], color="#888888", linewidth=0.7, linestyle=":")
    rim = np.stack([nu * np.cos(t[::9]), nu * np.sin(t[::9]), np.zeros(t[::9].size)], axis=1)
    for r in rows:
        colour = _IMAGE_COLOURS[(r.image - 1) % len(_IMAGE_COLOURS)]
        li = np.asarray(r.light, dtype=np.float64)
        ca = np.asarray(r.camera, dtype=np.float64)
        start = 1.25 * li
        ax.quiver(start[0], start[1], start[2], -start[0] * 0.88, -start[1] * 0.88, -start[2] * 0.88,
                  color=colour, linewidth=1.8, arrow_length_ratio=0.18)
        ax.text(*(1.34 * li), f"L{r.image}", color=colour, fontsize=8.5, fontweight="bold",
                ha="center", va="center")
        for p in rim:  # viewing cone to the disk rim
            ax.plot([ca[0], p[0]], [ca[1], p[1]], [ca[2], p[2]], color=colour, linewidth=0.5, alpha=0.6)
        ax.scatter([ca[0]], [ca[1]], [ca[2]], color=colour, marker="s", s=30, depthshade=False,
                   label=(f"image {r.image}: L ({r.light_sph[0]:.0f}, {r.light_sph[1]:.0f}), "
                          f"C ({r.camera_sph[0]:.0f}, {r.camera_sph[1]:.0f}); θh {r.theta_h:.0f}, "
                          f"θd {r.theta_d:.0f}, φd {r.phi_d:.0f}"))
        ax.text(*(1.14 * ca), f"C{r.image}", color=colour, fontsize=8.5, fontweight="bold",
                ha="center", va="center")
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_zlim(0.0, 1.1)
    ax.set_box_aspect((1.0, 1.0, 0.55), zoom=1.3)
    ax.view_init(elev=24, azim=-62)
    ax.set_axis_off()


def fig08_optimal_configurations(directions: Sequence[str | os.PathLike[str]], stem: str | os.PathLike[str], *,
                                 fovs: Sequence[float], n_images: Sequence[int] = (1, 2),
                                 setup: str = "nearfield", metric: str = "error",
                                 splits: Sequence[str] = ("all", "train")) -> FigureOutput:
    """Xu Figs. 8 and 9: table and sketch of the optimal 1- and 2-image configurations per FOV.

    ``directions``: the direction files to choose from; for each FOV the
    first of ``splits`` with a ``setup``/``metric`` file at that FOV is used
    (``all``, the full database, as Xu's Fig. 8; else ``train``).  Writes
    ``<stem>.csv`` (columns :data:`FIG08_COLUMNS`, one row per image),
    ``<stem>.md`` and the sketch ``<stem>.png``/``.pdf`` (one 3-D panel per
    FOV and set size: the hemisphere, the sample disk, light arrows L and
    camera positions C with their viewing cones).
    """
    warn = _Warnings("fig08")
    rows, database = _load_configurations(directions, [float(f) for f in fovs], list(n_images), setup,
                                          metric, list(splits), warn)
    stem = Path(stem)
    csv_path = stem.with_name(stem.name + ".csv")
    md_path = stem.with_name(stem.name + ".md")

    def write_csv(fh: Any) -> None:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(FIG08_COLUMNS)
        for r in rows:
            w.writerow(r.csv_values())

    _atomic_write(csv_path, write_csv, binary=False)
    md = _markdown(rows, database, setup, metric)
    _atomic_write(md_path, lambda fh: fh.write(md), binary=False)

    present = sorted({r.fov for r in rows})
    sizes = [n for n in n_images if any(r.n_images == n for r in rows)]
    with _style():
        ncols = max(1, len(sizes))
        nrows = max(1, len(present))
        fig = _new_figure(4.2 * ncols + 0.2, 3.9 * nrows + 0.9)
        if not rows:
            ax = fig.subplots()
            _no_data(ax, "no directions files for the requested FOVs")
        else:
            # per FOV: a row of 3-D sketches and, under each, a strip holding its legend
            gs = fig.add_gridspec(2 * nrows, ncols, height_ratios=[6.0, 1.0] * nrows)
            for i, fov in enumerate(present):
                for j, n in enumerate(sizes):
                    ax = fig.add_subplot(gs[2 * i, j], projection="3d")
                    key = fig.add_subplot(gs[2 * i + 1, j])
                    key.set_axis_off()
                    sel = [r for r in rows if r.fov == fov and r.n_images == n]
                    if not sel:
                        ax.set_axis_off()
                        ax.set_title(f"FOV {_fov_text(fov)}, {n} image{'s' if n > 1 else ''}: no set")
                        continue
                    _draw_configuration(ax, sel, fov)
                    ax.set_title(f"FOV {_fov_text(fov)}, {n} image{'s' if n > 1 else ''}, "
                                 f"E(S) = {sel[0].expected_error:.3g}")
                    handles, labels = ax.get_legend_handles_labels()
                    key.legend(handles, labels, loc="upper center", fontsize=7.5, frameon=False,
                               handletextpad=0.3, borderaxespad=0.0,
                               title="L: light, C: camera as (θ, φ); angles in degrees", title_fontsize=7.5)
        title = (f"Optimal {_SETUP_LABEL.get(setup, setup)} configurations per field of view "
                 f"({database_label(database) if database else 'no directions files found'})")
        splits_used = sorted({r.split for r in rows})
        subtitle = ("Xu 2016 Figs. 8-9 analogue; arrows L: light, squares C: camera with its view cone "
                    f"to the sample disk; directions from split {', '.join(splits_used) or '-'}")
        return _finish(fig, stem, title, subtitle, database, warn, extra=(csv_path, md_path))


# ---------------------------------------------------------------------------
# All figures
# ---------------------------------------------------------------------------


def figure_stem(files: Sequence[str | os.PathLike[str]], *, table: bool = False) -> Path:
    """The common stem of one figure's output files, checked: ``[X.png, X.pdf]`` (``+ [X.csv, X.md]`` for a table).

    The workflow passes every output path explicitly; this only checks that
    the list names the files a figure function writes, so none is missing or
    written under a name the caller did not declare.
    """
    paths = [Path(f) for f in files]
    exts = [".png", ".pdf", ".csv", ".md"] if table else [".png", ".pdf"]
    if len(paths) != len(exts) or [p.suffix for p in paths] != exts:
        raise ValueError(f"figure outputs {[str(p) for p in paths]}: expected files ending in {exts}, in that order")
    stems = {p.with_suffix("") for p in paths}
    if len(stems) != 1:
        raise ValueError(f"figure outputs {[str(p) for p in paths]}: must share one stem")
    return stems.pop()


def _check_keys(figures: Mapping[str, Any], known: Mapping[str, str], what: str) -> None:
    unknown = sorted(set(figures) - set(known))
    if unknown:
        raise ValueError(f"{what}: unknown figure key(s) {unknown}; known: {sorted(known)}")


def make_acquisition_figures(*, errors_csv: str | os.PathLike[str],
                             training_csv: str | os.PathLike[str] | None,
                             directions: Sequence[str | os.PathLike[str]],
                             figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                             fovs: Sequence[float], n_point: int, fov_fixed: float = 25.0,
                             split: str = "train", kind: str = "rms_log") -> list[Path]:
    """Write the requested Xu 2016 figure analogues; return the files written.

    ``figures``: figure key (of :data:`FIGURE_STEMS`) → its output files
    (PNG, PDF; Fig. 8 also CSV and Markdown), exactly as the workflow
    declares them; only these figures are drawn.  ``training_csv`` is needed
    for ``fig07``, ``directions`` (the direction files to tabulate) for
    ``fig08``.  ``fovs``: near-field FOVs of Figs. 5, 6 and 8; ``n_point``:
    number of point samples of Fig. 18; ``fov_fixed``: the FOV of Figs. 7
    (label) and 13; ``split``: the errors.csv split whose rows are plotted
    (``train``: directions from the training split, evaluated on the
    held-out materials).
    """
    _check_keys(figures, FIGURE_STEMS, "make_acquisition_figures")
    stems = {k: figure_stem(v, table=(k == "fig08")) for k, v in figures.items()}
    # Check every input before writing anything: a bad file stops the run with no partial output.
    read_errors(errors_csv)
    if "fig07" in stems:
        if training_csv is None:
            raise ValueError("fig07 needs the training-size table (training_csv)")
        read_training_size(training_csv)
    fovs = [float(f) for f in fovs]
    draw = {
        "fig05": lambda st: fig05_error_vs_images(errors_csv, st, fovs=fovs, split=split, kind=kind),
        "fig06": lambda st: fig06_fov_vs_point(errors_csv, st, fovs=fovs, split=split, kind=kind),
        "fig07": lambda st: fig07_training_size(training_csv, st, kind=kind, fov=fov_fixed),  # type: ignore[arg-type]
        "fig08": lambda st: fig08_optimal_configurations(directions, st, fovs=fovs),
        "fig13": lambda st: fig13_fixed_camera_light(errors_csv, st, fov=fov_fixed, split=split, kind=kind),
        "fig18": lambda st: fig18_per_material(errors_csv, st, n=n_point, split=split, kind=kind),
        "fig19": lambda st: fig19_error_vs_n(errors_csv, st, split=split, kind=kind),
    }
    results = [draw[k](stems[k]) for k in FIGURE_STEMS if k in stems]
    dbs = {r.database for r in results if r.database}
    if len(dbs) > 1:
        logger.warning("figures: inputs name different databases: %s", ", ".join(sorted(dbs)))
    return [p for r in results for p in r.files]


# ===========================================================================
# Manifold track: Soler et al. 2018 figure analogues
# ===========================================================================
#
# Inputs (written by brdfpipe.manifold.analysis and the fit_gplvm jobs):
#
# * models ``gplvm/q{q}.npz`` (:func:`brdfpipe.manifold.gplvm.load_model`) and traces
#   ``gplvm/q{q}-trace.csv`` (``step,stage,log_likelihood``; stage
#   ``hooke-jeeves``, then ``lbfgs`` for the polish);
# * ``manifold/albedo.csv`` (``database,material,r,g,b,luminance``);
# * albedo maps ``manifold/albedo-map-q{q}.npz`` (arrays x (W,), y (H,),
#   dims (2,), albedo (H, W, 3), luminance (H, W), fixed (q,), q, database);
# * ``manifold/paths.csv`` (:data:`PATHS_COLUMNS`, one row per step of each
#   latent path) and ``manifold/reproduction.csv``
#   (:data:`REPRODUCTION_COLUMNS`).
#
# :func:`make_manifold_figures` reads and checks every input first (a
# missing or malformed file raises FigureInputError naming it, before any
# figure is written), then writes the figures of MANIFOLD_FIGURE_STEMS, each
# PNG + PDF, atomically and deterministically like the acquisition figures.

#: Columns of a GPLVM trace CSV (gplvm.write_trace).
TRACE_COLUMNS: tuple[str, ...] = ("step", "stage", "log_likelihood")
#: Trace stages: the start point, Hooke–Jeeves sweeps, L-BFGS iterations (in any order).
TRACE_STAGES: tuple[str, ...] = ("start", "hooke-jeeves", "lbfgs")
#: Columns of ``albedo.csv``.
ALBEDO_COLUMNS: tuple[str, ...] = ("database", "material", "r", "g", "b", "luminance")
#: Columns of ``paths.csv``.
PATHS_COLUMNS: tuple[str, ...] = (
    "database", "space", "q", "path", "material_a", "material_b", "step", "t", "latent_distance",
    "perceptual_a", "perceptual_b", "perceptual_ab", "nearest", "deviation", "bound",
)
#: Columns of ``reproduction.csv``.
REPRODUCTION_COLUMNS: tuple[str, ...] = ("database", "space", "material", "method", "k", "relative_error")
#: Arrays of an albedo map npz.
ALBEDO_MAP_KEYS: tuple[str, ...] = (
    "x", "y", "dims", "albedo", "luminance", "fixed", "q", "database", "inside_hull", "bad_inside", "bad_outside",
    "training_gap_median", "training_gap_max",
)

#: Most path panels drawn in Figs. 9 and eq. 7 (the first paths of paths.csv, in file order).
MAX_PATH_PANELS: int = 6
#: GPLVM reproduction errors at or below this are drawn at it ("exact").
REPRODUCTION_FLOOR: float = 1e-16
#: Font size (points) of the material names on the latent maps.
LATENT_LABEL_SIZE: float = 4.8

_PATH_A_COLOUR = "#1f5fbf"
_PATH_B_COLOUR = "#d62728"


def _input_file(path: str | os.PathLike[str], what: str) -> Path:
    path = Path(path)
    if not path.is_file():
        raise FigureInputError(f"{path}: {what} not found")
    return path


def _read_manifold_csv(path: str | os.PathLike[str], required: Sequence[str], what: str
                       ) -> tuple[Path, list[dict[str, str]]]:
    """:func:`_read_csv`, with a missing file a FigureInputError naming it."""
    return _read_csv(_input_file(path, what), required)


def _finite(path: Path, line: int, column: str, text: str) -> float:
    x = _parse_float(path, line, column, text)
    if not math.isfinite(x):
        raise FigureInputError(f"{path}: line {line}: column {column!r} is not a finite number: {text!r}")
    return x


def _nonempty(path: Path, line: int, column: str, text: str) -> str:
    if not text:
        raise FigureInputError(f"{path}: line {line}: empty {column!r}")
    return text


@dataclass(frozen=True)
class TraceTable:
    """A GPLVM fit's log-likelihood trace: ``step``, ``stage`` of each row, ``log_likelihood``."""

    path: Path
    step: np.ndarray
    stage: np.ndarray
    log_likelihood: np.ndarray

    @property
    def switches(self) -> list[int]:
        """Indices of the rows where the stage changes (the first row excluded; a ``start`` row never counts)."""
        return [i for i in range(1, len(self.stage))
                if self.stage[i] != self.stage[i - 1] and self.stage[i - 1] != "start"]


def read_trace(path: str | os.PathLike[str]) -> TraceTable:
    """Read and check a ``q{q}-trace.csv`` (FigureInputError naming the file if it is missing or malformed)."""
    p, rows = _read_manifold_csv(path, TRACE_COLUMNS, "trace file")
    steps, stages, values = [], [], []
    for r in rows:
        i = int(r["__line__"])
        steps.append(_parse_int(p, i, "step", r["step"]))
        if r["stage"] not in TRACE_STAGES:
            raise FigureInputError(f"{p}: line {i}: unknown stage {r['stage']!r} "
                                   f"(expected {' or '.join(TRACE_STAGES)})")
        if stages and r["stage"] == "start":
            raise FigureInputError(f"{p}: line {i}: a start row after the first row")
        if len(steps) > 1 and steps[-1] <= steps[-2]:
            raise FigureInputError(f"{p}: line {i}: steps not increasing ({steps[-2]} then {steps[-1]})")
        stages.append(r["stage"])
        values.append(_finite(p, i, "log_likelihood", r["log_likelihood"]))
    return TraceTable(p, np.array(steps, dtype=np.int64), np.array(stages, dtype=str),
                      np.array(values, dtype=np.float64))


@dataclass(frozen=True)
class AlbedoTable:
    """``albedo.csv``: hemispherical albedo (R, G, B) and luminance of each material."""

    path: Path
    database: str
    materials: tuple[str, ...]
    rgb: np.ndarray
    luminance: np.ndarray

    def display_colours(self, names: Sequence[str]) -> np.ndarray:
        """Marker colours of ``names``: RGB / (brightest channel over all materials), clipped to [0, 1], ^(1/2.2)."""
        top = float(self.rgb.max()) if self.rgb.size else 0.0
        scale = top if top > 0 else 1.0
        index = {m: k for k, m in enumerate(self.materials)}
        rgb = np.array([self.rgb[index[n]] for n in names], dtype=np.float64).reshape(-1, 3)
        return np.clip(rgb / scale, 0.0, 1.0) ** (1.0 / 2.2)


def read_albedo(path: str | os.PathLike[str]) -> AlbedoTable:
    """Read and check ``albedo.csv``."""
    p, rows = _read_manifold_csv(path, ALBEDO_COLUMNS, "albedo table")
    mats: list[str] = []
    rgb, lum = [], []
    seen: set[str] = set()
    for r in rows:
        i = int(r["__line__"])
        m = _nonempty(p, i, "material", r["material"])
        if m in seen:
            raise FigureInputError(f"{p}: line {i}: duplicate material {m!r}")
        seen.add(m)
        mats.append(m)
        rgb.append([_finite(p, i, c, r[c]) for c in ("r", "g", "b")])
        lum.append(_finite(p, i, "luminance", r["luminance"]))
    return AlbedoTable(p, _single_database(p, (r["database"] for r in rows)), tuple(mats),
                       np.array(rgb, dtype=np.float64), np.array(lum, dtype=np.float64))


@dataclass(frozen=True)
class AlbedoMap:
    """An albedo map over a 2-D slice of a q-dimensional latent space."""

    path: Path
    database: str
    q: int
    dims: tuple[int, int]
    x: np.ndarray
    y: np.ndarray
    albedo: np.ndarray
    luminance: np.ndarray
    fixed: np.ndarray
    #: (H, W): grid point inside the convex hull of the q-dimensional training points.
    inside_hull: np.ndarray
    #: Share of grid points inside / outside the hull with albedo outside [0, 1] (NaN: no such point).
    bad_inside: float
    bad_outside: float
    #: Luminance |A_map(xᵢ) − Aᵢ| of the smooth map at the training points: median, max.
    training_gap: tuple[float, float]


def read_albedo_map(path: str | os.PathLike[str]) -> AlbedoMap:
    """Read and check an ``albedo-map-q{q}.npz``."""
    p = _input_file(path, "albedo map")
    if not zipfile.is_zipfile(p):
        raise FigureInputError(f"{p}: not an npz (zip) file")
    try:
        with np.load(p, allow_pickle=False) as z:
            missing = [k for k in ALBEDO_MAP_KEYS if k not in z]
            if missing:
                raise FigureInputError(f"{p}: missing array(s) {', '.join(missing)} "
                                       f"(required: {', '.join(ALBEDO_MAP_KEYS)})")
            arrays = {k: np.asarray(z[k]) for k in ALBEDO_MAP_KEYS}
    except FigureInputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise FigureInputError(f"{p}: not a readable npz file ({exc})") from exc
    try:
        x = arrays["x"].astype(np.float64)
        y = arrays["y"].astype(np.float64)
        albedo = arrays["albedo"].astype(np.float64)
        lum = arrays["luminance"].astype(np.float64)
        fixed = arrays["fixed"].astype(np.float64).reshape(-1)
        dims_arr = arrays["dims"].reshape(-1)
        q_arr = arrays["q"]
    except (TypeError, ValueError) as exc:
        raise FigureInputError(f"{p}: non-numeric array ({exc})") from exc
    if q_arr.size != 1 or not np.issubdtype(q_arr.dtype, np.integer):
        raise FigureInputError(f"{p}: 'q' must be one integer, got {q_arr!r}")
    q = int(q_arr.reshape(()))
    if dims_arr.size != 2 or not np.issubdtype(dims_arr.dtype, np.integer):
        raise FigureInputError(f"{p}: 'dims' must be 2 integers, got {dims_arr.tolist()!r}")
    dims = (int(dims_arr[0]), int(dims_arr[1]))
    if q < 2 or not all(0 <= d < q for d in dims) or dims[0] == dims[1]:
        raise FigureInputError(f"{p}: dims {dims} are not two different latent dimensions of q = {q}")
    if x.ndim != 1 or y.ndim != 1 or x.size < 2 or y.size < 2:
        raise FigureInputError(f"{p}: 'x' and 'y' must be 1-D with >= 2 points, got shapes {x.shape}, {y.shape}")
    H, W = y.size, x.size
    if lum.shape != (H, W):
        raise FigureInputError(f"{p}: 'luminance' has shape {lum.shape}, expected (len(y), len(x)) = {(H, W)}")
    if albedo.shape != (H, W, 3):
        raise FigureInputError(f"{p}: 'albedo' has shape {albedo.shape}, expected {(H, W, 3)}")
    if fixed.shape != (q,):
        raise FigureInputError(f"{p}: 'fixed' has {fixed.size} coordinates, expected q = {q}")
    for name, a in (("x", x), ("y", y), ("albedo", albedo), ("luminance", lum), ("fixed", fixed)):
        if not np.all(np.isfinite(a)):
            raise FigureInputError(f"{p}: {name!r} holds NaN or infinite values")
    if np.any(np.diff(x) <= 0) or np.any(np.diff(y) <= 0):
        raise FigureInputError(f"{p}: 'x' and 'y' must be strictly increasing")
    db = str(arrays["database"].reshape(()) if arrays["database"].size == 1 else "").strip()
    if not db:
        raise FigureInputError(f"{p}: empty or missing 'database'")
    inside = arrays["inside_hull"]
    if inside.shape != (H, W) or inside.dtype != bool:
        raise FigureInputError(f"{p}: 'inside_hull' must be a boolean {(H, W)} array, got {inside.dtype} {inside.shape}")
    try:
        stats = [float(arrays[k].reshape(())) for k in ("bad_inside", "bad_outside", "training_gap_median",
                                                         "training_gap_max")]
    except (TypeError, ValueError) as exc:
        raise FigureInputError(f"{p}: the hull statistics must be single numbers ({exc})") from exc
    return AlbedoMap(p, db, q, dims, x, y, albedo, lum, fixed, inside, stats[0], stats[1], (stats[2], stats[3]))


@dataclass(frozen=True)
class LatentPath:
    """One latent path of ``paths.csv``, rows sorted by step."""

    name: str
    space: str
    q: int
    material_a: str
    material_b: str
    step: np.ndarray
    t: np.ndarray
    latent_distance: np.ndarray
    perceptual_a: np.ndarray
    perceptual_b: np.ndarray
    perceptual_ab: float
    nearest: tuple[str, ...]
    deviation: np.ndarray
    bound: np.ndarray

    @property
    def title(self) -> str:
        return f"{self.material_a} → {self.material_b} (q = {self.q})"


@dataclass(frozen=True)
class PathTable:
    path: Path
    database: str
    paths: tuple[LatentPath, ...]


_PATH_NUMERIC = ("t", "latent_distance", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound")


def read_paths(path: str | os.PathLike[str]) -> PathTable:
    """Read and check ``paths.csv``: rows grouped by (space, q, path), in order of first appearance."""
    p, rows = _read_manifold_csv(path, PATHS_COLUMNS, "paths table")
    groups: dict[tuple[str, int, str], list[dict[str, Any]]] = {}
    for r in rows:
        i = int(r["__line__"])
        for c in ("space", "path", "material_a", "material_b", "nearest"):
            _nonempty(p, i, c, r[c])
        rec: dict[str, Any] = {c: _finite(p, i, c, r[c]) for c in _PATH_NUMERIC}
        rec.update(line=i, step=_parse_int(p, i, "step", r["step"]), a=r["material_a"], b=r["material_b"],
                   nearest=r["nearest"])
        q = _parse_int(p, i, "q", r["q"])
        if q < 1:
            raise FigureInputError(f"{p}: line {i}: q must be >= 1, got {q}")
        for c in ("latent_distance", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound"):
            if rec[c] < 0:
                raise FigureInputError(f"{p}: line {i}: negative {c!r} ({rec[c]!r})")
        groups.setdefault((r["space"], q, r["path"]), []).append(rec)
    out = []
    for (space, q, name), recs in groups.items():
        where = f"{p}: path {name!r} (space {space}, q = {q})"
        recs.sort(key=lambda d: d["step"])
        steps = [d["step"] for d in recs]
        if len(set(steps)) != len(steps):
            raise FigureInputError(f"{where}: duplicate steps")
        if len(recs) < 2:
            raise FigureInputError(f"{where}: fewer than 2 points")
        if len({(d["a"], d["b"]) for d in recs}) != 1:
            raise FigureInputError(f"{where}: material_a / material_b change along the path")
        pab = np.array([d["perceptual_ab"] for d in recs])
        if not pab[0] > 0 or np.ptp(pab) > 1e-9 * pab[0]:
            raise FigureInputError(f"{where}: perceptual_ab must be one positive value per path, "
                                   f"got {pab.min():g}..{pab.max():g}")
        if not recs[-1]["latent_distance"] > 0:
            raise FigureInputError(f"{where}: latent_distance at the last step is {recs[-1]['latent_distance']!r} "
                                   "(must be > 0 to normalise)")
        arr = {c: np.array([d[c] for d in recs], dtype=np.float64) for c in _PATH_NUMERIC}
        out.append(LatentPath(name, space, q, recs[0]["a"], recs[0]["b"], np.array(steps, dtype=np.int64),
                              arr["t"], arr["latent_distance"], arr["perceptual_a"], arr["perceptual_b"],
                              float(pab[0]), tuple(d["nearest"] for d in recs), arr["deviation"], arr["bound"]))
    return PathTable(p, _single_database(p, (r["database"] for r in rows)), tuple(out))


@dataclass(frozen=True)
class ReproductionTable:
    """``reproduction.csv``: relative error per (space, method, k) and material."""

    path: Path
    database: str
    values: dict[tuple[str, str, int], dict[str, float]]

    def spaces(self) -> list[str]:
        return sorted({k[0] for k in self.values})

    def ks(self, space: str, method: str) -> list[int]:
        return sorted(k[2] for k in self.values if k[0] == space and k[1] == method)


def read_reproduction(path: str | os.PathLike[str]) -> ReproductionTable:
    """Read and check ``reproduction.csv`` (methods ``pca`` and ``gplvm``)."""
    p, rows = _read_manifold_csv(path, REPRODUCTION_COLUMNS, "reproduction table")
    values: dict[tuple[str, str, int], dict[str, float]] = {}
    for r in rows:
        i = int(r["__line__"])
        space = _nonempty(p, i, "space", r["space"])
        mat = _nonempty(p, i, "material", r["material"])
        method = r["method"].lower()
        if method not in ("pca", "gplvm"):
            raise FigureInputError(f"{p}: line {i}: unknown method {r['method']!r} (expected pca or gplvm)")
        k = _parse_int(p, i, "k", r["k"])
        if k < 1:
            raise FigureInputError(f"{p}: line {i}: k must be >= 1, got {k}")
        v = _finite(p, i, "relative_error", r["relative_error"])
        if v < 0:
            raise FigureInputError(f"{p}: line {i}: negative relative_error {v!r}")
        per = values.setdefault((space, method, k), {})
        if mat in per:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {method} k = {k}, material {mat!r}")
        per[mat] = v
    return ReproductionTable(p, _single_database(p, (r["database"] for r in rows)), values)


def _read_model(path: str | os.PathLike[str], q: int) -> Any:
    from brdfpipe.manifold import gplvm  # noqa: PLC0415 (scipy import, only needed here)

    p = _input_file(path, "GPLVM model")
    if not zipfile.is_zipfile(p):
        raise FigureInputError(f"{p}: not a GPLVM model (not an npz file)")
    try:
        model = gplvm.load_model(p)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        msg = str(exc)
        raise FigureInputError(msg if msg.startswith(str(p)) else f"{p}: not a readable GPLVM model ({msg})") from exc
    X = np.asarray(model.X, dtype=np.float64)
    if X.ndim != 2 or X.shape[0] != len(model.names) or X.shape[0] < 1:
        raise FigureInputError(f"{p}: latent points of shape {X.shape} for {len(model.names)} materials")
    if X.shape[1] != q:
        raise FigureInputError(f"{p}: latent dimension {X.shape[1]}, but it is given as the q = {q} model")
    if not np.all(np.isfinite(X)):
        raise FigureInputError(f"{p}: latent points hold NaN or infinite values")
    return model


SPACES_FIGURE_COLUMNS: tuple[str, ...] = (
    "database", "candidate", "space", "mu", "q", "default", "kappa", "albedo_bad_hull", "albedo_bad_map",
    "sum_abs_w_hull_median", "sum_abs_w_path_max", "nn_median",
)
STABILITY_FIGURE_COLUMNS: tuple[str, ...] = ("database", "candidate", "q", "norm", "epsilon", "median", "p90")


@dataclass(frozen=True)
class SpacesTable:
    """``spaces.csv`` and ``spaces-stability.csv`` of :mod:`brdfpipe.manifold.fidelity`."""

    path: Path
    database: str
    default: str
    #: (candidate, q) → the row's numbers (NaN where the measure does not apply).
    rows: dict[tuple[str, int], dict[str, float]]
    #: (candidate, q, norm) → (ε, median, p90) arrays sorted by ε.
    stability: dict[tuple[str, int, str], tuple[np.ndarray, np.ndarray, np.ndarray]]

    @property
    def candidates(self) -> list[str]:
        return sorted({c for c, _ in self.rows}, key=lambda c: (c != self.default, c))

    @property
    def dims(self) -> list[int]:
        return sorted({q for _, q in self.rows})


def read_spaces(spaces_csv: str | os.PathLike[str], stability_csv: str | os.PathLike[str]) -> SpacesTable:
    """Read and check the data-space comparison of ``compare_spaces`` (one default candidate, one database)."""
    p, rows = _read_manifold_csv(spaces_csv, SPACES_FIGURE_COLUMNS, "data-space comparison")
    if not rows:
        raise FigureInputError(f"{p}: no rows")
    out: dict[tuple[str, int], dict[str, float]] = {}
    defaults = set()
    for r in rows:
        i = int(r["__line__"])
        c = _nonempty(p, i, "candidate", r["candidate"])
        q = _parse_int(p, i, "q", r["q"])
        if (c, q) in out:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {c} q = {q}")
        if r["default"] == "true":
            defaults.add(c)
        out[(c, q)] = {k: _parse_float(p, i, k, r[k]) for k in SPACES_FIGURE_COLUMNS[3:] if k != "default"}
    if len(defaults) != 1:
        raise FigureInputError(f"{p}: expected exactly one default candidate, found {sorted(defaults)}")
    database = _single_database(p, (r["database"] for r in rows))
    sp = _input_file(stability_csv, "stability table")
    with sp.open(encoding="utf-8") as fh:
        lines = [line for line in fh.read().splitlines() if line.strip()]
    header_only = len(lines) == 1
    if header_only and not set(STABILITY_FIGURE_COLUMNS) <= set(lines[0].split(",")):
        raise FigureInputError(f"{sp}: missing column(s) of a stability table (required: {', '.join(STABILITY_FIGURE_COLUMNS)})")
    # the log space has no Gram-based stability: a header alone is a valid (empty) table
    srows = [] if header_only else _read_manifold_csv(sp, STABILITY_FIGURE_COLUMNS, "stability table")[1]
    acc: dict[tuple[str, int, str], list[tuple[float, float, float]]] = {}
    for r in srows:
        i = int(r["__line__"])
        key = (r["candidate"], _parse_int(sp, i, "q", r["q"]), r["norm"])
        acc.setdefault(key, []).append((_finite(sp, i, "epsilon", r["epsilon"]), _finite(sp, i, "median", r["median"]),
                                        _finite(sp, i, "p90", r["p90"])))
    if srows and _single_database(sp, (r["database"] for r in srows)) != database:
        raise FigureInputError(f"{sp}: another database than {p}")
    stab = {k: tuple(np.array(col) for col in zip(*sorted(v))) for k, v in acc.items()}
    return SpacesTable(p, database, defaults.pop(), out, stab)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ManifoldInputs:
    """Everything :func:`make_manifold_figures` draws, read and cross-checked."""

    database: str
    models: dict[int, Any]
    model_paths: dict[int, Path]
    traces: dict[int, TraceTable]
    albedo: AlbedoTable
    maps: dict[int, AlbedoMap]
    paths: PathTable
    reproduction: ReproductionTable
    #: The data-space comparison (``spaces.csv``), when given.
    spaces: SpacesTable | None = None


def _q_key(q: Any, what: str) -> int:
    try:
        k = int(q)
    except (TypeError, ValueError):
        raise FigureInputError(f"{what}: latent dimension {q!r} is not an integer") from None
    if k < 1 or str(k) != str(q).strip():
        raise FigureInputError(f"{what}: latent dimension {q!r} is not a positive integer")
    return k


def read_manifold_inputs(*, models: Mapping[int, str | os.PathLike[str]],
                         traces: Mapping[int, str | os.PathLike[str]], albedo_csv: str | os.PathLike[str],
                         albedo_maps: Mapping[int, str | os.PathLike[str]], paths_csv: str | os.PathLike[str],
                         reproduction_csv: str | os.PathLike[str], database: str | None = None,
                         spaces_csv: str | os.PathLike[str] | None = None,
                         stability_csv: str | os.PathLike[str] | None = None) -> ManifoldInputs:
    """Read every input of the manifold figures and check them against each other.

    FigureInputError (naming the file) for a missing or malformed file, a
    model or map whose q disagrees with its key, a path or map whose q has no
    model, a material of a path or model missing from its model / the albedo
    table, or inputs naming different databases (or another database than
    ``database``, when given).
    """
    model_paths = {_q_key(q, "models"): Path(p) for q, p in models.items()}
    if not model_paths:
        raise FigureInputError("models: no GPLVM model given")
    loaded = {q: _read_model(p, q) for q, p in sorted(model_paths.items())}
    trace_tables = {_q_key(q, "traces"): read_trace(p) for q, p in traces.items()}
    albedo = read_albedo(albedo_csv)
    maps: dict[int, AlbedoMap] = {}
    for q, p in albedo_maps.items():
        key = _q_key(q, "albedo_maps")
        m = read_albedo_map(p)
        if m.q != key:
            raise FigureInputError(f"{m.path}: holds a q = {m.q} map, but it is given as the q = {key} map")
        if key not in loaded:
            raise FigureInputError(f"{m.path}: no GPLVM model for its q = {key} (models given: "
                                   f"{', '.join(map(str, sorted(loaded)))})")
        maps[key] = m
    paths = read_paths(paths_csv)
    for lp in paths.paths:
        if lp.q not in loaded:
            raise FigureInputError(f"{paths.path}: path {lp.name!r} has q = {lp.q}, but no GPLVM model has that q "
                                   f"(models given: {', '.join(map(str, sorted(loaded)))})")
        names = loaded[lp.q].names
        absent = [m for m in (lp.material_a, lp.material_b) if m not in names]
        if absent:
            raise FigureInputError(f"{paths.path}: path {lp.name!r}: material(s) {', '.join(absent)} not in "
                                   f"the q = {lp.q} model ({model_paths[lp.q]})")
    reproduction = read_reproduction(reproduction_csv)
    have = set(albedo.materials)
    for q, model in loaded.items():
        absent = [n for n in model.names if n not in have]
        if absent:
            raise FigureInputError(f"{albedo.path}: no albedo row for {len(absent)} material(s) of the q = {q} "
                                   f"model ({', '.join(absent[:5])}{', …' if len(absent) > 5 else ''})")
    spaces = None
    if (spaces_csv is None) != (stability_csv is None):
        raise FigureInputError("give both spaces_csv and stability_csv, or neither")
    if spaces_csv is not None and stability_csv is not None:
        spaces = read_spaces(spaces_csv, stability_csv)
    sources = [(albedo.database, albedo.path), (paths.database, paths.path),
               (reproduction.database, reproduction.path)] + [(m.database, m.path) for m in maps.values()]
    if spaces is not None:
        sources.append((spaces.database, spaces.path))
    names = sorted({db for db, _ in sources})
    if len(names) > 1:
        raise FigureInputError("inputs from different databases: "
                               + "; ".join(f"{db!r} ({p})" for db, p in sources))
    if database is not None and str(database).strip() and names[0] != str(database).strip():
        raise FigureInputError(f"{sources[0][1]}: database {names[0]!r}, but the figures are for database "
                               f"{str(database).strip()!r}")
    return ManifoldInputs(names[0], loaded, model_paths, trace_tables, albedo, maps, paths, reproduction, spaces)


# ---------------------------------------------------------------------------
# Manifold drawing helpers
# ---------------------------------------------------------------------------


def _set_title(fig: Figure, title: str, subtitle: str) -> None:
    """The suptitle exactly as :func:`_finish` writes it (so layout-dependent steps can run before saving)."""
    chars = max(30, int(float(fig.get_size_inches()[0]) * 72.0 / (0.6 * 10.5)))
    lines = textwrap.wrap(title, chars) + (textwrap.wrap(subtitle, chars) if subtitle else [])
    fig.suptitle("\n".join(lines))


# label directions (x, y) around a point and distances (points), in order of preference
_LABEL_DIRS = ((1, 0), (1, 1), (1, -1), (-1, 0), (-1, 1), (-1, -1), (0, 1), (0, -1))
_LABEL_RADII = (3.2, 7.0, 12.0, 18.0)


def _overlap(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Total overlap area of each of ``boxes`` (C × 4: x0, y0, x1, y1) with all of ``others`` (M × 4)."""
    if others.size == 0:
        return np.zeros(len(boxes))
    ox = np.minimum(boxes[:, None, 2], others[None, :, 2]) - np.maximum(boxes[:, None, 0], others[None, :, 0])
    oy = np.minimum(boxes[:, None, 3], others[None, :, 3]) - np.maximum(boxes[:, None, 1], others[None, :, 1])
    return (np.clip(ox, 0.0, None) * np.clip(oy, 0.0, None)).sum(axis=1)


def _label_panel(ax: Any, renderer: Any, x: np.ndarray, y: np.ndarray, names: Sequence[str], label: np.ndarray,
                 visible: np.ndarray, *, fontsize: float, marker_radius: float, colour: str = "#1a1a1a") -> None:
    """Name the points ``label`` (mask) of a panel, each on the side that overlaps least.

    Greedy and deterministic: crowded points first; each label goes to the
    candidate position (8 directions × 4 distances) of least cost: its
    overlap with the labels already placed, the ``visible`` markers and the
    area outside the axes.  A label that would still overlap the accepted
    ones by more than 8 % of its area goes instead to a column of
    call-outs at the emptier side of the panel, with a leader line.  The
    layout must be final (run after the title is set and a layout pass);
    labels are left out of the layout so saving does not move the axes.
    """
    px = ax.figure.dpi / 72.0
    P = ax.transData.transform(np.column_stack([x, y]))
    prop = FontProperties(family=RC_PARAMS["font.family"], size=fontsize)
    ab = ax.get_window_extent(renderer)
    rm = marker_radius * px
    markers = np.column_stack([P - rm, P + rm])
    cands = []
    for r in _LABEL_RADII:
        for cx, cy in _LABEL_DIRS:
            n = math.hypot(cx, cy)
            cands.append((r, cx, cy, r * px * cx / n, r * px * cy / n))
    c_off = np.array([[c[3], c[4]] for c in cands])
    c_dir = np.array([[c[1], c[2]] for c in cands], dtype=np.float64)
    pref = np.arange(len(cands), dtype=np.float64)
    vis = np.flatnonzero(visible)
    d2 = ((P[:, None, :] - P[None, vis, :]) ** 2).sum(-1)
    crowd = (d2 < (30.0 * px) ** 2).sum(1)
    order = sorted(np.flatnonzero(label).tolist(), key=lambda i: (-int(crowd[i]), i))
    sizes = {i: renderer.get_text_width_height_descent(names[i], prop, ismath=False)[:2] for i in order}
    placed = np.zeros((0, 4))
    accepted = np.zeros((0, 4))
    chosen: list[tuple[int, int]] = []
    failed: list[int] = []
    for i in order:
        w, h = sizes[i]
        anchor = P[i] + c_off
        x0 = np.where(c_dir[:, 0] > 0, anchor[:, 0], np.where(c_dir[:, 0] < 0, anchor[:, 0] - w, anchor[:, 0] - w / 2))
        y0 = np.where(c_dir[:, 1] > 0, anchor[:, 1], np.where(c_dir[:, 1] < 0, anchor[:, 1] - h, anchor[:, 1] - h / 2))
        boxes = np.column_stack([x0, y0, x0 + w, y0 + h])
        inside_w = np.clip(np.minimum(boxes[:, 2], ab.x1) - np.maximum(boxes[:, 0], ab.x0), 0.0, None)
        inside_h = np.clip(np.minimum(boxes[:, 3], ab.y1) - np.maximum(boxes[:, 1], ab.y0), 0.0, None)
        outside = w * h - inside_w * inside_h
        others = markers[vis[vis != i]]
        cost = (_overlap(boxes, placed) + 0.6 * _overlap(boxes, others) + 2.0 * outside
                + 1e-3 * w * h * pref)
        k = int(np.argmin(cost))
        placed = np.vstack([placed, boxes[k]])
        if _overlap(boxes[k : k + 1], accepted)[0] > 0.08 * w * h:
            failed.append(i)
            continue
        accepted = np.vstack([accepted, boxes[k]])
        chosen.append((i, k))
    for i, k in sorted(chosen):
        r, cx, cy, _, _ = cands[k]
        n = math.hypot(cx, cy)
        ann = ax.annotate(
            names[i], xy=(float(x[i]), float(y[i])), xytext=(r * cx / n, r * cy / n), textcoords="offset points",
            ha="left" if cx > 0 else "right" if cx < 0 else "center",
            va="bottom" if cy > 0 else "top" if cy < 0 else "center",
            fontsize=fontsize, color=colour, parse_math=False, annotation_clip=False, zorder=5,
            arrowprops=(dict(arrowstyle="-", linewidth=0.3, color="#777777", shrinkA=0.0, shrinkB=marker_radius)
                        if r > _LABEL_RADII[0] else None),
        )
        ann.set_in_layout(False)
    if not failed:
        return
    # Call-outs: columns at the side of the panel farther from these points, ordered by height.
    failed.sort(key=lambda i: (-P[i, 1], i))
    mean_x = float(np.mean(P[failed, 0]))
    right = (ab.x1 - mean_x) >= (mean_x - ab.x0)
    lh = 1.25 * max(sizes[i][1] for i in failed)
    cap = max(1, int((ab.height - 4.0 * px) // lh))
    cols = [failed[c : c + cap] for c in range(0, len(failed), cap)]
    inv = ax.transData.inverted()
    for c, col in enumerate(cols):
        cw = max(sizes[i][0] for i in col) + 3.0 * px
        tx = ab.x1 - 2.0 * px - (c + 1) * cw if right else ab.x0 + 2.0 * px + c * cw
        centre = float(np.mean(P[col, 1]))
        top = min(ab.y1 - 2.0 * px - lh / 2, max(ab.y0 + 2.0 * px + lh / 2 + (len(col) - 1) * lh,
                                                 centre + (len(col) - 1) * lh / 2))
        for j, i in enumerate(col):
            tdata = inv.transform((tx, top - j * lh))
            ann = ax.annotate(
                names[i], xy=(float(x[i]), float(y[i])), xytext=(float(tdata[0]), float(tdata[1])),
                textcoords="data", ha="left", va="center", fontsize=fontsize, color=colour, parse_math=False,
                annotation_clip=False, zorder=5,
                arrowprops=dict(arrowstyle="-", linewidth=0.3, color="#8a8a8a", shrinkA=0.5, shrinkB=marker_radius),
            )
            ann.set_in_layout(False)


#: Crowding on the latent maps: a point with at least _CROWD_K other points within _CROWD_R inches (at the
#: panel's scale) is crowded; the largest cluster of crowded points gets a zoomed panel (nested, at most _MAX_ZOOMS).
_CROWD_R = 0.2
_CROWD_K = 3
_MAX_ZOOMS = 3

_Box = tuple[float, float, float, float]  # x0, x1, y0, y1


def _bbox(P: np.ndarray, pad: float, min_span: float = 0.0) -> _Box:
    lo, hi = P.min(axis=0), P.max(axis=0)
    span = np.maximum(hi - lo, max(min_span, 1e-12 * max(1.0, float(np.abs(P).max()))))
    centre = (lo + hi) / 2.0
    half = span * (0.5 + pad)
    return (float(centre[0] - half[0]), float(centre[0] + half[0]), float(centre[1] - half[1]),
            float(centre[1] + half[1]))


def _inside(P: np.ndarray, box: _Box) -> np.ndarray:
    return (P[:, 0] >= box[0]) & (P[:, 0] <= box[1]) & (P[:, 1] >= box[2]) & (P[:, 1] <= box[3])


def _components(adj: np.ndarray) -> list[list[int]]:
    """Connected components of a boolean adjacency matrix, each sorted, in order of their smallest member."""
    seen = np.zeros(len(adj), dtype=bool)
    comps = []
    for s in range(len(adj)):
        if seen[s]:
            continue
        stack, comp = [s], []
        seen[s] = True
        while stack:
            v = stack.pop()
            comp.append(v)
            for u in np.flatnonzero(adj[v] & ~seen):
                seen[u] = True
                stack.append(int(u))
        comps.append(sorted(comp))
    return comps


def _zoom_chain(P: np.ndarray, panel_in: tuple[float, float]) -> list[_Box]:
    """Views of a latent map: the whole (with a margin), then nested zooms on the most crowded cluster.

    At each level the points are scaled as the panel would show them (equal
    aspect, ``panel_in`` inches); if some are crowded (see :data:`_CROWD_R`),
    the next view is the box around the largest connected group of crowded
    points (linked within 2·_CROWD_R), unless it would not zoom in by at
    least 2×.  Deterministic.
    """
    views = [_bbox(P, 0.08)]
    for _ in range(_MAX_ZOOMS):
        view = views[-1]
        idx = np.flatnonzero(_inside(P, view))
        dx, dy = view[1] - view[0], view[3] - view[2]
        scale = min(panel_in[0] / dx, panel_in[1] / dy)  # inches per latent unit
        Q = P[idx] * scale
        d = np.sqrt(((Q[:, None, :] - Q[None, :, :]) ** 2).sum(-1))
        crowded = ((d < _CROWD_R).sum(axis=1) - 1) >= _CROWD_K
        if crowded.sum() <= _CROWD_K:
            break
        ci = np.flatnonzero(crowded)
        comps = _components(d[np.ix_(ci, ci)] < 2.0 * _CROWD_R)
        best = max(comps, key=lambda c: (len(c), -c[0]))
        members = idx[ci[best]]
        box = _bbox(P[members], 0.12, min_span=1e-6 * max(dx, dy))
        if (box[1] - box[0]) > dx / 2.0 and (box[3] - box[2]) > dy / 2.0:
            break
        views.append(box)
    return views


def _latent_row(axes: Sequence[Any], P: np.ndarray, colours: np.ndarray, views: Sequence[_Box],
                labels: tuple[str, str], name: str, *, size: float) -> None:
    """Draw the points in each of ``axes`` (one per view), equal aspect, titled."""
    for k, (ax, view) in enumerate(zip(axes, views)):
        ax.scatter(P[:, 0], P[:, 1], s=size, c=colours, edgecolors="#202020", linewidths=0.4, zorder=3)
        ax.set_xlim(view[0], view[1])
        ax.set_ylim(view[2], view[3])
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        if k == 0:
            ax.set_title(f"{name}: all materials" if len(views) > 1 else name)
        else:
            z = (views[0][1] - views[0][0]) / (view[1] - view[0])
            ax.set_title(f"{name}: zoom ×{z:.3g} on the dashed box of the previous panel")


class _DropFixedLimits(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Ignoring fixed")


@contextmanager
def _quiet_fixed_limits() -> Iterator[None]:
    """Silence matplotlib's "Ignoring fixed x limits to fulfill fixed data aspect" during the first layout.

    The latent panels set both limits (the view) and ask for equal aspect
    with adjustable data limits: the first draw widens one of them, as
    intended; the widened limits are then fixed and later draws keep them.
    """
    log = logging.getLogger("matplotlib.axes._base")
    f = _DropFixedLimits()
    log.addFilter(f)
    try:
        yield
    finally:
        log.removeFilter(f)


def _label_rows(fig: Figure, rows: Sequence[tuple[Sequence[Any], np.ndarray]], names: Sequence[str], *,
                fontsize: float, marker_radius: float) -> None:
    """After the layout: freeze each panel's limits, outline the next zoom, and name each point once per row.

    A point is named in the deepest view of its row that shows it (the
    whole view names only the points outside its zoom).
    """
    with _quiet_fixed_limits():
        fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    for axes, P in rows:
        lims = []
        for ax in axes:
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            ax.set_xlim(x0, x1)  # the aspect-adjusted limits, fixed
            ax.set_ylim(y0, y1)
            lims.append((x0, x1, y0, y1))
        for k, ax in enumerate(axes):
            visible = _inside(P, lims[k])
            if k + 1 < len(axes):
                nxt = lims[k + 1]
                ax.add_patch(Rectangle((nxt[0], nxt[2]), nxt[1] - nxt[0], nxt[3] - nxt[2], fill=False,
                                                   edgecolor="#555555", linestyle="--", linewidth=0.8, zorder=2))
                tag = ax.annotate("zoom: next panel", xy=(nxt[0], nxt[3]), xytext=(-4.0, 8.0),
                                  textcoords="offset points", ha="right", va="bottom", fontsize=5.5,
                                  color="#444444", zorder=6, annotation_clip=False,
                                  arrowprops=dict(arrowstyle="-", linewidth=0.4, color="#555555", shrinkA=0.0,
                                                  shrinkB=0.0))
                tag.set_in_layout(False)
                label = visible & ~_inside(P, nxt)
            else:
                label = visible
            _label_panel(ax, renderer, P[:, 0], P[:, 1], names, label, visible, fontsize=fontsize,
                         marker_radius=marker_radius)


def _grid_shape(n: int, max_cols: int) -> tuple[int, int]:
    ncols = max(1, min(n, max_cols))
    return max(1, math.ceil(n / ncols)), ncols


def _fit_note(inp: ManifoldInputs) -> str:
    """"standardised space, mu 1e-06" for the titles: which data space and noise term the fits use (ASCII: PDF metadata)."""
    fits = sorted({(str(m.space), float(m.mu)) for m in inp.models.values()})
    return "; ".join(f"{s} space, mu {mu:g}" for s, mu in fits) or "no model"


def _space_note(spaces: Iterable[str]) -> str:
    s = sorted(set(spaces))
    return f"data space {', '.join(s)}" if s else ""


# ---------------------------------------------------------------------------
# The manifold figures
# ---------------------------------------------------------------------------


def manifold_fig05_likelihood(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 5: log-likelihood vs optimisation step, one line per q; right: gap to the best L (log y)."""
    warn = _Warnings("manifold-fig05")
    with _style():
        fig = _new_figure(10.0, 4.2)
        ax, gap = fig.subplots(1, 2)
        if not inp.traces:
            warn("no trace files given")
            _no_data(ax, "no trace files")
            gap.set_visible(False)
        else:
            allL = np.concatenate([t.log_likelihood for t in inp.traces.values()])
            switch_drawn = False
            for i, (q, tr) in enumerate(sorted(inp.traces.items())):
                colour = _COLOURS[i % len(_COLOURS)]
                ax.plot(tr.step, tr.log_likelihood, color=colour, linewidth=1.3, label=f"q = {q}")
                best = float(tr.log_likelihood.max())
                g = best - tr.log_likelihood
                ok = g > 0
                gap.plot(tr.step[ok], g[ok], color=colour, linewidth=1.3, label=f"q = {q}")
                for s in tr.switches:
                    for a, v in ((ax, tr.log_likelihood[s]), (gap, g[s] if g[s] > 0 else np.nan)):
                        a.axvline(tr.step[s], color=colour, linestyle=":", linewidth=1.0)
                        if math.isfinite(v):
                            a.plot([tr.step[s]], [v], marker="o", markersize=4.5, color=colour,
                                   markerfacecolor="white", linestyle="none")
                    ax.annotate(str(tr.stage[s]), (tr.step[s], tr.log_likelihood[s]), fontsize=6, color=colour,
                                xytext=(3, -10), textcoords="offset points")
                    switch_drawn = True
                model = inp.models.get(q)
                if model is not None:
                    L_model = float(model.log_likelihood)
                    if abs(L_model - float(tr.log_likelihood[-1])) > 1e-6 * max(1.0, abs(L_model)):
                        warn(f"q = {q}: the trace ends at L = {tr.log_likelihood[-1]:.10g} but the model "
                             f"({inp.model_paths[q]}) has L = {L_model:.10g}")
            if switch_drawn:
                ax.plot([], [], color="#444444", linestyle=":", marker="o", markerfacecolor="white",
                        label="stage changes (label: the new stage)")
            # One sign and a wide range: |L| on a log scale (symlog, linear part below every value);
            # values of both signs: linear (the right panel shows the convergence on a log scale).
            a = np.abs(allL)
            if (allL.min() > 0 or allL.max() < 0) and a.max() / a.min() > 30.0:
                ax.set_yscale("symlog", linthresh=10.0 ** math.floor(math.log10(a.min())))
            last = max(int(t.step[-1]) for t in inp.traces.values())
            for a_ in (ax, gap):  # sweeps (tens) and L-BFGS iterations (thousands) both visible
                if last > 200:
                    a_.set_xscale("symlog", linthresh=10.0, linscale=0.6)
                a_.set_xlim(left=0.0)
            ax.set_xlabel("step (an L-BFGS iteration or a Hooke–Jeeves sweep; stage changes marked)")
            ax.set_ylabel("log-likelihood L (eq. 6)")
            ax.set_title("log-likelihood")
            ax.legend(loc="lower right")
            gap.set_yscale("log")
            gap.set_xlabel("step")
            gap.set_ylabel("max L − L")
            gap.set_title("distance to the best log-likelihood")
            if not gap.get_lines():
                _no_data(gap, "no improvement")
        title = f"GPLVM log-likelihood during the fit ({database_label(inp.database)}, {_fit_note(inp)})"
        methods = sorted({str(m.method) for m in inp.models.values()})
        scales = sorted({f"{float(m.gram_scale):.4g}" for m in inp.models.values()})
        subtitle = (f"Soler 2018 Fig. 5 analogue; method {', '.join(methods)}; Gram matrix divided by "
                    f"{', '.join(scales)} before fitting")
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def _latent_names(names: Sequence[str]) -> list[str]:
    return [str(n) for n in names]


def manifold_fig10_latent_q2(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 (latent map): the 2-D latent points, each named, coloured by its albedo.

    Where the points crowd (names would overlap), zoomed panels on the most
    crowded cluster follow (at most two, nested); every material is named
    once, in the deepest panel that shows it.
    """
    warn = _Warnings("manifold-fig10-q2")
    q = 2 if 2 in inp.models else min(inp.models)
    if q != 2:
        warn(f"no q = 2 model; drawing {'dims 0, 1' if q > 2 else 'dim 0 against the material index'} "
             f"of the q = {q} model")
    model = inp.models[q]
    X = np.asarray(model.X, dtype=np.float64)
    if q < 2:
        P = np.column_stack([X[:, 0], np.arange(len(X), dtype=np.float64)])
        labels = ("latent dim 0", "material index")
    else:
        P = X[:, :2]
        labels = ("latent dim 0", "latent dim 1")
    names = _latent_names(model.names)
    single = _zoom_chain(P, (7.6, 6.6))
    views = single if len(single) == 1 else _zoom_chain(P, (5.4, 4.9))
    with _style():
        if len(views) == 1:
            fig = _new_figure(9.0, 8.4)
            axes = [fig.subplots()]
        else:
            nrows, ncols = _grid_shape(len(views), 2 if len(views) == 4 else 3)
            fig = _new_figure(6.1 * ncols + 0.3, 6.0 * nrows + 1.0)
            grid = fig.subplots(nrows, ncols, squeeze=False).ravel()
            axes = list(grid[: len(views)])
            for ax in grid[len(views):]:
                ax.set_visible(False)
        _latent_row(axes, P, inp.albedo.display_colours(model.names), views, labels,
                    f"q = {q}, {len(names)} materials", size=22.0)
        title = f"The {'2-D ' if q == 2 else ''}latent space of the materials ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = (f"Soler 2018 Fig. 10 analogue; colour: hemispherical albedo (RGB / brightest channel, "
                    f"gamma 1/2.2); ℓ = {model.ell:g}, μ = {model.mu:g}; {_space_note([model.space])}"
                    + ("; each material named once, in the deepest panel showing it" if len(views) > 1 else ""))
        _set_title(fig, title, subtitle)
        _label_rows(fig, [(axes, P)], names, fontsize=LATENT_LABEL_SIZE, marker_radius=2.6)
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig10_latent_q5(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 for q = 5: the latent points projected onto dims (0,1), (1,2), (2,3), (3,4), named.

    The q = 5 model, else the largest q (its consecutive pairs, at most 4).
    One row per pair; crowded projections get zoomed panels to the right
    (as :func:`manifold_fig10_latent_q2`).
    """
    warn = _Warnings("manifold-fig10-q5")
    q = 5 if 5 in inp.models else max(inp.models)
    if q != 5:
        warn(f"no q = 5 model; drawing the q = {q} model")
    model = inp.models[q]
    X = np.asarray(model.X, dtype=np.float64)
    names = _latent_names(model.names)
    pairs = [(k, k + 1) for k in range(min(q, 5) - 1)]
    chains = [_zoom_chain(X[:, list(dims)], (4.4, 4.2)) for dims in pairs]
    with _style():
        ncols = max([len(c) for c in chains] + [1])
        if len(chains) == 4 and ncols == 1:  # nothing crowded: a 2 × 2 grid
            fig = _new_figure(2 * 5.4 + 0.3, 2 * 5.0 + 0.8)
            grid = fig.subplots(2, 2, squeeze=False).ravel()
            rows_axes = [[ax] for ax in grid]
        else:
            nrows = max(1, len(pairs))
            fig = _new_figure(5.0 * ncols + 0.3, 4.8 * nrows + 0.8)
            grid = fig.subplots(nrows, ncols, squeeze=False)
            rows_axes = [list(grid[r, : len(chains[r])]) for r in range(len(chains))]
            for r in range(nrows):
                for c in range(len(chains[r]) if r < len(chains) else 0, ncols):
                    grid[r, c].set_visible(False)
        colours = inp.albedo.display_colours(model.names)
        if not pairs:
            warn(f"the q = {q} model has one latent dimension: no 2-D projection")
            ax0 = grid.ravel()[0]
            ax0.set_visible(True)
            _no_data(ax0, f"q = {q}: no pair of latent dimensions")
        rows = []
        for axes, dims, views in zip(rows_axes, pairs, chains):
            P = X[:, list(dims)]
            _latent_row(axes, P, colours, views, (f"latent dim {dims[0]}", f"latent dim {dims[1]}"),
                        f"dims {dims[0]}, {dims[1]}", size=16.0)
            rows.append((axes, P))
        title = f"Projections of the q = {q} latent space ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = (f"Soler 2018 Fig. 10 analogue; latent points projected onto pairs of latent dimensions; "
                    f"colour: hemispherical albedo (gamma 1/2.2); {_space_note([model.space])}"
                    + ("; each material named once per row, in the deepest panel showing it"
                       if ncols > 1 else ""))
        _set_title(fig, title, subtitle)
        _label_rows(fig, rows, names, fontsize=4.5, marker_radius=2.2)
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig07_albedo(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 7: luminance albedo of the interpolated BRDFs over the latent plane, with iso-lines."""
    warn = _Warnings("manifold-fig07")
    maps = [inp.maps[q] for q in sorted(inp.maps)]
    with _style():
        nrows, ncols = _grid_shape(max(1, len(maps)), 2)
        fig = _new_figure(5.6 * ncols + 0.3, 4.9 * nrows + 0.8)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        if not maps:
            warn("no albedo maps given")
            _no_data(axes[0], "no albedo maps")
        for ax, m in zip(axes, maps):
            L = m.luminance
            dx, dy = np.diff(m.x), np.diff(m.y)
            uniform = np.allclose(dx, dx[0], rtol=1e-6) and np.allclose(dy, dy[0], rtol=1e-6)
            if uniform:
                extent = (m.x[0] - dx[0] / 2, m.x[-1] + dx[0] / 2, m.y[0] - dy[0] / 2, m.y[-1] + dy[0] / 2)
                im = ax.imshow(L, origin="lower", extent=extent, cmap="viridis", interpolation="nearest",
                               aspect="equal")
            else:
                im = ax.pcolormesh(m.x, m.y, L, cmap="viridis", shading="nearest")
                ax.set_aspect("equal")
            lo, hi = float(L.min()), float(L.max())
            if hi - lo > 1e-12 * max(1.0, abs(hi)):
                levels = [v for v in MaxNLocator(nbins=8).tick_values(lo, hi) if lo < v < hi]
                if levels:
                    cs = ax.contour(m.x, m.y, L, levels=levels, colors="#111111", linewidths=0.6, alpha=0.8)
                    ax.clabel(cs, fmt="%.3g", fontsize=6.0, inline=True)
                phys = [v for v in (0.0, 1.0) if lo < v < hi]
                if phys:  # where the albedo leaves the physical range [0, 1]
                    ax.contour(m.x, m.y, L, levels=phys, colors="#ff3030", linewidths=1.3, linestyles="solid")
            else:
                warn(f"{m.path}: constant luminance {lo:.4g}; no iso-lines")
            model = inp.models[m.q]
            X = np.asarray(model.X, dtype=np.float64)
            if m.inside_hull.any() and not m.inside_hull.all():
                ax.contour(m.x, m.y, m.inside_hull.astype(float), levels=[0.5], colors="white", linewidths=1.2,
                           linestyles="dashed", zorder=3)
            ax.scatter(X[:, m.dims[0]], X[:, m.dims[1]], s=7.0, c="white", edgecolors="#222222",
                       linewidths=0.35, zorder=4)
            ax.text(0.01, 0.01, f"albedo outside [0, 1]: {100 * m.bad_inside:.2f} % of the grid inside the hull, "
                    f"{100 * m.bad_outside:.1f} % outside\nsmooth map vs own albedo at the training points: "
                    f"median {m.training_gap[0]:.2g}, max {m.training_gap[1]:.2g}",
                    transform=ax.transAxes, fontsize=6.0, color="white", va="bottom", zorder=5,
                    bbox={"facecolor": "#000000", "alpha": 0.45, "edgecolor": "none", "pad": 1.5})
            if uniform:
                ax.set_xlim(extent[0], extent[1])
                ax.set_ylim(extent[2], extent[3])
            else:
                ax.set_xlim(m.x[0], m.x[-1])
                ax.set_ylim(m.y[0], m.y[-1])
            ax.set_xlabel(f"latent dim {m.dims[0]}")
            ax.set_ylabel(f"latent dim {m.dims[1]}")
            ax.grid(False)
            if m.q > 2:
                others = [k for k in range(m.q) if k not in m.dims]
                held = ", ".join(f"x{k} = {m.fixed[k]:.3g}" for k in others)
                ax.set_title(f"q = {m.q}: slice through dims {m.dims[0]}, {m.dims[1]} ({held})")
            else:
                ax.set_title(f"q = {m.q}: latent plane")
            if lo < 0.0 or hi > 1.0:
                ax.set_title(ax.get_title() + "\nred iso-lines: albedo 0 and 1 (limits of the physical range)",
                             fontsize=8.0)
            cax = ax.inset_axes((1.04, 0.0, 0.045, 1.0))  # follows the (equal-aspect) image's height
            cb = fig.colorbar(im, cax=cax)
            cb.set_label("albedo (luminance)")
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            off = ~((X[:, m.dims[0]] >= x0) & (X[:, m.dims[0]] <= x1) & (X[:, m.dims[1]] >= y0) & (X[:, m.dims[1]] <= y1))
            if off.any():
                warn(f"{m.path}: {int(off.sum())} of {len(off)} training points lie outside the map "
                     f"(is it the map of {inp.model_paths[m.q]}?)")
            if lo < 0.0 or hi > 1.0:
                warn(f"{m.path}: luminance albedo outside [0, 1] ({lo:.4g}..{hi:.4g})")
        for ax in axes[max(1, len(maps)):]:
            ax.set_visible(False)
        title = f"Albedo of the interpolated BRDFs over the latent space ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 7 analogue; luminance 0.2126 R + 0.7152 G + 0.0722 B of the hemispherical "
                    "albedo, iso-lines labelled; white dashed line: the convex hull of the training points "
                    "(for q > 2, where the slice cuts the q-dimensional hull); white dots: training materials "
                    "(for q > 2 their projection onto the slice, so their albedo need not match the map). "
                    "The map is the smooth interpolant (kernel without the μδ term): no grid point is a "
                    "training point, where the δ term would give the material's own albedo exactly")
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def _selected_paths(inp: ManifoldInputs, warn: _Warnings) -> list[LatentPath]:
    paths = list(inp.paths.paths)
    if len(paths) > MAX_PATH_PANELS:
        warn(f"{inp.paths.path}: {len(paths)} paths; drawing the first {MAX_PATH_PANELS}")
    return paths[:MAX_PATH_PANELS]


def manifold_fig09_paths(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 9: perceptual distance to A and to B along latent paths (normalised axes)."""
    warn = _Warnings("manifold-fig09")
    paths = _selected_paths(inp, warn)
    with _style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = _new_figure(3.7 * ncols + 0.3, 3.5 * nrows + 0.9)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        line = np.array([0.0, 1.0])
        for ax, lp in zip(axes, paths):
            u = lp.latent_distance / lp.latent_distance[-1]
            ax.plot(line, line, color=_PATH_A_COLOUR, linestyle="--", linewidth=0.9, alpha=0.7)
            ax.plot(line, 1.0 - line, color=_PATH_B_COLOUR, linestyle="--", linewidth=0.9, alpha=0.7)
            ax.plot(u, lp.perceptual_a / lp.perceptual_ab, color=_PATH_A_COLOUR, marker="o", markersize=3.0,
                    linewidth=1.2, label=f"to A: {lp.material_a}")
            ax.plot(u, lp.perceptual_b / lp.perceptual_ab, color=_PATH_B_COLOUR, marker="s", markersize=3.0,
                    linewidth=1.2, label=f"to B: {lp.material_b}")
            ax.set_title(lp.title, fontsize=8.0)
            ax.set_xlim(-0.03, 1.03)
            ax.set_xlabel("latent distance from A / distance A–B")
            ax.set_ylabel("perceptual distance / d(A, B)")
            ax.legend(loc="best", fontsize=6.5)
        _hide_unused_path_panels(axes, len(paths))
        title = f"Perceptual distances along latent paths ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 9 analogue; blue: distance of the interpolated BRDF to A, red: to B, "
                    "both divided by the distance between A and B; dashed: perceptually uniform; "
                    f"{_space_note(p.space for p in paths)}")
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def _hide_unused_path_panels(axes: Sequence[Any], n_paths: int) -> None:
    """Hide the panels after the last path; with no path at all, say so in the first."""
    for ax in axes[n_paths:]:
        if not n_paths and ax is axes[0]:
            _no_data(ax, "no paths")
        else:
            ax.set_visible(False)


def manifold_fig08_reproduction(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 8: relative error reproducing each training material, PCA (k components) vs GPLVM (q)."""
    warn = _Warnings("manifold-fig08")
    tab = inp.reproduction
    spaces = tab.spaces()
    model_spaces = sorted({str(m.space) for m in inp.models.values()})
    if len(spaces) == 1:
        space = spaces[0]
    else:
        common = [s for s in model_spaces if s in spaces]
        if not common:
            raise FigureInputError(f"{tab.path}: rows for data spaces {', '.join(spaces)}; none is the models' "
                                   f"({', '.join(model_spaces)})")
        space = common[0]
        warn(f"{tab.path}: several data spaces ({', '.join(spaces)}); drawing {space}")
    pca_k = tab.ks(space, "pca")
    gp_q = tab.ks(space, "gplvm")
    sort_k = 20 if 20 in pca_k else (min(pca_k, key=lambda k: (abs(k - 20), k)) if pca_k else None)
    if sort_k is not None and sort_k != 20:
        warn(f"no PCA-20 rows; materials sorted by PCA-{sort_k}")
    mats = sorted({m for (s, _, _), per in tab.values.items() if s == space for m in per})
    if sort_k is not None:
        key_vals = tab.values[(space, "pca", sort_k)]
        mats.sort(key=lambda m: (0, key_vals[m], m) if m in key_vals else (1, 0.0, m))
    xs = np.arange(len(mats), dtype=np.float64)
    with _style():
        fig = _new_figure(10.0, 4.8)
        ax = fig.subplots()
        for i, k in enumerate(pca_k):
            per = tab.values[(space, "pca", k)]
            v = np.array([per.get(m, np.nan) for m in mats])
            ok = np.isfinite(v) & (v > 0)
            ax.plot(xs[ok], v[ok], color=_COLOURS[i % len(_COLOURS)], marker="o", markersize=2.6,
                    linewidth=1.0, label=f"PCA, {k} components")
        exact_any = False
        gp_markers = ("v", "^", "D", "s", "P", "X")
        for j, q in enumerate(gp_q):
            per = tab.values[(space, "gplvm", q)]
            v = np.array([per.get(m, np.nan) for m in mats])
            ok = np.isfinite(v)
            exact = ok & (v <= REPRODUCTION_FLOOR)
            exact_any |= bool(exact.any())
            drawn = np.where(exact, REPRODUCTION_FLOOR, v)
            ax.plot(xs[ok], drawn[ok], linestyle="none", marker=gp_markers[j % len(gp_markers)],
                    markersize=3.4 + 1.2 * j, color="#111111" if j == 0 else "#555555",
                    markerfacecolor="#111111" if j == 0 else "none", markeredgewidth=0.7,
                    label=f"GPLVM, q = {q} (max {np.nanmax(v):.2g})")
        if exact_any:
            ax.axhline(REPRODUCTION_FLOOR, color="#999999", linewidth=0.7, linestyle=":")
            ax.annotate("exact (≤1e-16)", xy=(0.995, REPRODUCTION_FLOOR), xycoords=("axes fraction", "data"),
                        xytext=(0.0, 7.0), textcoords="offset points", ha="right", va="bottom", fontsize=7.0,
                        color="#333333")
        for q_model in sorted(inp.models):
            if q_model not in gp_q:
                warn(f"{tab.path}: no gplvm rows for q = {q_model}")
        if not ax.get_lines():
            _no_data(ax, f"no rows for data space {space}")
        else:
            ax.set_yscale("log")
            lo = min([REPRODUCTION_FLOOR] + [float(np.nanmin(line.get_ydata())) for line in ax.get_lines()
                                             if len(line.get_ydata())])
            ax.set_ylim(bottom=lo / 8.0)
            ax.set_xlim(-1.0, max(len(mats), 1))
            ax.set_xlabel("materials (sorted)" + (f" by PCA-{sort_k} error" if sort_k is not None else ""))
            ax.set_ylabel("relative error ‖ẑ − z‖ / ‖z‖")
            ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), borderaxespad=0.0)
        ax.set_title(f"reproduction of the {len(mats)} training materials ({space} space)")
        title = f"Reproducing the training materials: PCA vs GPLVM ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 8 analogue; PCA truncated to k components vs the GPLVM interpolant at "
                    "each material's latent point (exact in exact arithmetic: b(x_i) = e_i)")
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_eq7_bound(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Eq. 7: actual deviation from the nearest training material vs the bound, along each path."""
    warn = _Warnings("manifold-eq7")
    paths = _selected_paths(inp, warn)
    with _style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = _new_figure(3.7 * ncols + 0.3, 3.3 * nrows + 0.9)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        for ax, lp in zip(axes, paths):
            dv, bd, t = lp.deviation, lp.bound, lp.t
            # Omitted: points with a zero bound (x* on a training point: the ends) whose deviation is
            # zero or rounding noise (≤ 1e-9 of the path's largest); a real deviation there stays.
            noise = 1e-9 * float(dv.max())
            keep = ~((bd == 0) & (dv <= noise))
            okd, okb = keep & (dv > 0), keep & (bd > 0)
            ax.plot(t[okd], dv[okd], color=_COLOURS[0], marker="o", markersize=2.8, linewidth=1.2,
                    label="deviation ‖z* − z_nearest‖")
            ax.plot(t[okb], bd[okb], color=_COLOURS[3], linestyle="--", marker="s", markersize=2.4,
                    linewidth=1.2, label="eq. 7 bound")
            over = keep & (dv > bd * (1.0 + 1e-9)) & (dv > noise)
            if over.any():
                ax.plot(t[over], dv[over], linestyle="none", marker="x", markersize=6.0, markeredgewidth=1.2,
                        color="black", label="deviation above the bound")
                warn(f"path {lp.name!r}: the deviation exceeds the eq. 7 bound at {int(over.sum())} point(s)")
            ax.set_title(lp.title, fontsize=8.0)
            ax.set_xlim(0.0, 1.0)
            ax.set_xlabel("t (fraction of the path A → B)")
            ax.set_ylabel("distance in data space")
            if okd.any() or okb.any():
                ax.set_yscale("log")
                ax.legend(loc="best", fontsize=6.5)
            else:
                warn(f"path {lp.name!r}: deviation and bound are zero at every point")
                _no_data(ax, "deviation and bound are 0")
                ax.set_title(lp.title, fontsize=8.0)
        _hide_unused_path_panels(axes, len(paths))
        title = f"Deviation from the nearest training material vs the eq. 7 bound ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 eq. 7: ‖z* − z_j‖ ≤ e^(−1/2)·√(2N)/ℓ·κ(K)·‖Z‖·‖x* − x_j‖, j the nearest "
                    "training point in latent space; the path ends (bound 0, deviation 0 up to rounding) omitted; "
                    f"{_space_note(p.space for p in paths)}")
        return _finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_spaces(table: SpacesTable, stem: str | os.PathLike[str]) -> FigureOutput:
    """The data spaces compared: albedo outside [0, 1], stability near the training points, κ(K) and Σ|w|."""
    warn = _Warnings("manifold-spaces")
    cands = table.candidates
    dims = table.dims
    with _style():
        fig = _new_figure(12.0, 8.6)
        (ax_a, ax_s), (ax_k, ax_w) = fig.subplots(2, 2)
        x = np.arange(len(cands))
        width = 0.8 / max(1, len(dims))
        for j, q in enumerate(dims):
            colour = _COLOURS[j % len(_COLOURS)]
            off = (j - (len(dims) - 1) / 2) * width
            hull = [100 * table.rows.get((c, q), {}).get("albedo_bad_hull", np.nan) for c in cands]
            ax_a.bar(x + off, hull, width * 0.9, color=colour, label=f"q = {q}: inside the hull")
            if q == 2:
                mp = [100 * table.rows.get((c, q), {}).get("albedo_bad_map", np.nan) for c in cands]
                ax_a.plot(x + off, mp, "v", color="#222222", markersize=5, label="q = 2: plotted map (box 15 % past the data)")
            kap = [table.rows.get((c, q), {}).get("kappa", np.nan) for c in cands]
            ax_k.bar(x + off, kap, width * 0.9, color=colour, label=f"q = {q}")
            ws = [table.rows.get((c, q), {}).get("sum_abs_w_path_max", np.nan) for c in cands]
            wh = [table.rows.get((c, q), {}).get("sum_abs_w_hull_median", np.nan) for c in cands]
            ax_w.bar(x + off, ws, width * 0.9, color=colour, label=f"q = {q}: max along the paths")
            ax_w.plot(x + off, wh, "o", color="#222222", markersize=4, label="median over the hull" if j == 0 else None)
        ax_a.axhline(1.0, color="#aa0000", linestyle=":", linewidth=1.0, label="target: ≤ 1 %")
        ax_a.set_ylabel("albedo outside [0, 1] (% of points)")
        ax_a.set_title("(a) physically implausible albedo")
        ax_k.set_yscale("log")
        ax_k.set_ylabel("κ(K) (2-norm)")
        ax_k.set_title("(c) condition number of K")
        ax_w.set_yscale("log")
        ax_w.axhline(1.0, color="#777777", linestyle=":", linewidth=1.0)
        ax_w.set_ylabel("Σ|wᵢ| (1 = convex blend)")
        ax_w.set_title("(d) cancelling blend weights")
        for ax in (ax_a, ax_k, ax_w):
            ax.set_xticks(x)
            ax.set_xticklabels([c + (" (default)" if c == table.default else "") for c in cands], rotation=30,
                               ha="right", fontsize=7)
            ax.legend(fontsize=6.5)
        qs = max(dims)
        for i, c in enumerate(cands):
            colour = _COLOURS[i % len(_COLOURS)]
            for norm, style in (("space", "-"), ("raw", ":")):
                v = table.stability.get((c, qs, norm))
                if v is None:
                    continue
                eps, med, _ = v
                ok = med > 0
                ax_s.plot(eps[ok], med[ok], style, color=colour, marker="o", markersize=2.5, linewidth=1.4 if c == table.default else 0.9,
                          label=f"{c}" if norm == "space" else None)
        ax_s.axhline(0.01, color="#aa0000", linestyle=":", linewidth=1.0)
        ax_s.set_xscale("log")
        ax_s.set_yscale("log")
        ax_s.set_xlabel("offset ε from the training point (ℓ)")
        ax_s.set_ylabel("median ‖z(xᵢ+εu) − zᵢ‖ / ‖zᵢ‖")
        ax_s.set_title(f"(b) stability near the training points, q = {qs}\nsolid: the fit's own space; dotted: raw BRDF units; red: 1 %")
        ax_s.legend(fontsize=6.5)
        title = f"GPLVM data spaces compared ({database_label(table.database)})"
        subtitle = (f"candidates: data space and kernel noise μ; default: {table.default}. (a) albedo outside [0, 1] "
                    "of the interpolated material (linear blend, before clamping); (b) change of the interpolated "
                    "material a distance ε from a training point; (c) κ(K); (d) Σ|w|")
        return _finish(fig, stem, title, subtitle, table.database, warn)


def make_manifold_figures(*, models: Mapping[int, str | os.PathLike[str]],
                          traces: Mapping[int, str | os.PathLike[str]], albedo_csv: str | os.PathLike[str],
                          albedo_maps: Mapping[int, str | os.PathLike[str]], paths_csv: str | os.PathLike[str],
                          reproduction_csv: str | os.PathLike[str],
                          figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                          database: str | None = None,
                          spaces_csv: str | os.PathLike[str] | None = None,
                          stability_csv: str | os.PathLike[str] | None = None) -> list[Path]:
    """Write the requested Soler 2018 figure analogues (keys of :data:`MANIFOLD_FIGURE_STEMS`).

    ``models``, ``traces``, ``albedo_maps``: q → path.  ``figures``: key →
    its PNG and PDF paths, as the workflow declares them; only these are
    drawn.  Every input is read and checked first
    (:func:`read_manifold_inputs`): a missing or malformed file raises
    :class:`FigureInputError` naming it and nothing is written.  Returns the
    files written (PNG then PDF of each figure, in key order).

    ==============================  ===========================================
    ``fig05`` likelihood             L vs step per q, L-BFGS switch marked;
                                     gap to the best L on a log axis
    ``fig10_q2`` latent q = 2        q = 2 latent points, named, albedo colours
    ``fig10_q5`` latent q = 5        q = 5 projections on dims (0,1)…(3,4)
    ``fig07`` albedo                 luminance albedo maps with iso-lines
    ``fig09`` paths                  perceptual distance to A / B along paths
    ``fig08`` reproduction           per-material reproduction error, PCA vs GPLVM
    ``eq7`` bound                    deviation vs eq. 7 bound along paths
    ``spaces`` data spaces           the candidates of ``compare_spaces``
                                     (``spaces_csv``, ``stability_csv``)
    ==============================  ===========================================
    """
    _check_keys(figures, MANIFOLD_FIGURE_STEMS, "make_manifold_figures")
    stems = {k: figure_stem(v) for k, v in figures.items()}
    if "spaces" in stems and (spaces_csv is None or stability_csv is None):
        raise FigureInputError("the 'spaces' figure needs spaces_csv and stability_csv")
    inp = read_manifold_inputs(models=models, traces=traces, albedo_csv=albedo_csv, albedo_maps=albedo_maps,
                               paths_csv=paths_csv, reproduction_csv=reproduction_csv, database=database,
                               spaces_csv=spaces_csv, stability_csv=stability_csv)
    draw = {
        "fig05": manifold_fig05_likelihood,
        "fig10_q2": manifold_fig10_latent_q2,
        "fig10_q5": manifold_fig10_latent_q5,
        "fig07": manifold_fig07_albedo,
        "fig09": manifold_fig09_paths,
        "fig08": manifold_fig08_reproduction,
        "eq7": manifold_eq7_bound,
    }
    results = [draw[k](inp, stems[k]) for k in MANIFOLD_FIGURE_STEMS if k in stems and k != "spaces"]
    if "spaces" in stems and inp.spaces is not None:
        results.append(manifold_spaces(inp.spaces, stems["spaces"]))
    return [p for r in results for p in r.files]


__all__ += [
    "TRACE_COLUMNS", "ALBEDO_COLUMNS", "PATHS_COLUMNS", "REPRODUCTION_COLUMNS", "ALBEDO_MAP_KEYS",
    "MANIFOLD_FIGURE_STEMS", "TraceTable", "AlbedoTable", "AlbedoMap", "LatentPath", "PathTable",
    "ReproductionTable", "ManifoldInputs", "read_trace", "read_albedo", "read_albedo_map", "read_paths",
    "read_reproduction", "read_manifold_inputs", "manifold_fig05_likelihood", "manifold_fig10_latent_q2",
    "manifold_fig10_latent_q5", "manifold_fig07_albedo", "manifold_fig09_paths", "manifold_fig08_reproduction",
    "manifold_eq7_bound", "make_manifold_figures", "SpacesTable", "read_spaces", "manifold_spaces",
]


# ==========================================================================
# Rendering track (Soler 2018 §5.2): pre-render grid, interpolation strip, error panel
# ==========================================================================

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
    if not path.is_file():
        raise FigureInputError(f"{path}: no such file")
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in need if c not in (reader.fieldnames or [])]
        if missing:
            raise FigureInputError(f"{path}: missing column(s) {', '.join(missing)}")
        return list(reader)


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

    warn = _Warnings(stem.name)
    names = sorted(prerenders)
    images = [_read_exr_checked(Path(prerenders[m])) for m in names]
    ev = _exposure(images)
    cols = min(10, max(1, math.ceil(math.sqrt(len(names)))))
    rows = math.ceil(len(names) / cols)
    h, w = images[0].shape[:2]
    cell_w = 1.25
    fig = _new_figure(cols * cell_w, rows * cell_w * h / w + rows * 0.18 + 0.5)
    for k, (m, im) in enumerate(zip(names, images)):
        ax = fig.add_subplot(rows, cols, k + 1)
        _image_axes(ax, tonemap(im, ev), m, fontsize=4.5)
    title = f"Pre-rendered materials, global illumination (Soler Fig. 1 analogue) — {database_label(database)}"
    return _finish(fig, stem, title, f"{len(names)} materials, one exposure ({ev:+.2f} EV)", database, warn)


def render_fig12_interpolation(prerenders: Mapping[str, Path], points: Sequence[RenderPoint], stem: Path,
                               database: str) -> FigureOutput:
    """Per path: A, blended images at each t, B (top); references at each t (bottom) (Soler Fig. 12)."""
    from brdfpipe.rendering.blend import tonemap

    warn = _Warnings(stem.name)
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
    fig = _new_figure(ncol * cell, len(paths) * 2 * (cell * h / w + 0.25) + 0.6)
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
    return _finish(fig, stem, title, "top: Σ wᵢ Iᵢ of the pre-renders; bottom: the interpolated material rendered",
                   database, warn)


def render_fig13_errors(points: Sequence[RenderPoint], summary: Mapping[tuple[str, str], Mapping[str, str]],
                        stem: Path, database: str) -> FigureOutput:
    """Per path point: reference, blend and |blend − reference| with the relative RMSEs (Soler Fig. 13)."""
    from brdfpipe.rendering.blend import tonemap

    warn = _Warnings(stem.name)
    refs = [_read_exr_checked(q.reference) for q in points]
    blends = [_read_exr_checked(q.blended) for q in points]
    errs = [_read_exr_checked(q.error)[..., 0] for q in points]
    ev = _exposure(refs)
    vmax = max(float(np.percentile(e, 99.0)) for e in errs) or 1.0
    h, w = refs[0].shape[:2]
    cell = 1.6
    fig = _new_figure(3 * cell + 0.6, len(points) * (cell * h / w + 0.35) + 0.6)
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
    return _finish(fig, stem, title, "relative RMSE over pixels and channels, divided by the reference mean; "
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
    import json

    _check_keys(figures, RENDER_FIGURE_STEMS, "make_render_figures")
    stems = {k: figure_stem(v) for k, v in figures.items()}
    if not (len(weights) == len(references) == len(blended) == len(errors)):
        raise ValueError("weights, references, blended and errors must list the same path points")
    points = []
    for wf, ref, bl, er in zip(weights, references, blended, errors):
        try:
            doc = json.loads(Path(wf).read_text(encoding="utf-8"))
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
    with _style():
        results = [draw[k](stems[k]) for k in RENDER_FIGURE_STEMS if k in stems]
    return [p for r in results for p in r.files]


__all__ += ["RENDER_FIGURE_STEMS", "RenderPoint", "render_fig01_prerenders", "render_fig12_interpolation",
            "render_fig13_errors", "make_render_figures"]


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
    (``ratio_seed2``, ``ratio_one_seed2``); lines at 1 (no error beyond the
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
    warn = _Warnings(stem.name)
    labels = list(dict.fromkeys(r["candidate"] for r in rows))
    default = next((r["candidate"] for r in rows if r["default"] == "1"), "")
    points = list(dict.fromkeys((r["path"], r["t"]) for r in rows))
    with _style():
        from matplotlib.ticker import FuncFormatter, LogLocator

        fig = _new_figure(7.2, 2.0 + 0.34 * len(labels))
        axes = fig.subplots(1, 2, sharey=True)
        panels = ((axes[0], "ratio_seed2", "whole image I"), (axes[1], "ratio_one_seed2", "I¹⁻ part (≤ 1 bounce)"))
        for ax, col, name in panels:
            for y, c in enumerate(labels):
                vals = np.array([float(r[col]) for r in rows if r["candidate"] == c], dtype=np.float64)
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
                    f"relative; dotted: {FLOOR_RATIO_TARGET}×")
        title = f"Blended pre-renders vs renders at the noise floor, every data space — {database_label(database)}"
        return _finish(fig, stem, title, subtitle, database, warn)


__all__ += ["FLOOR_RATIO_TARGET", "plot_floor_check"]
