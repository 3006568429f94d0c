"""Figure helpers shared by the figures of every track (acquisition, manifold, rendering).

The style (:data:`RC_PARAMS`, :data:`DPI`, :data:`COLOURS`), the result of a
figure function (:class:`FigureOutput`) and its input error
(:class:`FigureInputError`), CSV input checking (:func:`read_csv`,
:func:`parse_float`, :func:`parse_int`, :func:`single_database`), the collected warnings of
one figure (:class:`Warnings`), and creating, titling and atomically saving a
figure (:func:`new_figure`, :func:`style`, :func:`no_data`, :func:`finish`)
with its declared output files (:func:`figure_stem`).

Determinism: figures are built on :class:`matplotlib.figure.Figure` with the
Agg canvas (pyplot and the global backend are never touched), under
matplotlib's default rcParams plus the fixed overrides in :data:`RC_PARAMS`
(``svg.hashsalt`` included); PDFs are written with ``CreationDate`` None and
PNGs without a timestamp, so the same inputs give the same bytes with the
same matplotlib and FreeType.  Each figure is written as ``<stem>.png`` and
``<stem>.pdf``, each atomically (temporary sibling, then :func:`os.replace`).
"""

from __future__ import annotations

import csv
import logging
import math
import os
import textwrap
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import matplotlib as mpl
import matplotlib.style
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_write
from brdfpipe.core.notes import write_note
from brdfpipe.core.version import full_version
from brdfpipe.registry import figures as figure_specs

__all__ = [
    "DPI",
    "RC_PARAMS",
    "COLOURS",
    "FigureInputError",
    "FigureOutput",
    "read_csv",
    "parse_float",
    "parse_int",
    "single_database",
    "Warnings",
    "new_figure",
    "style",
    "no_data",
    "finish",
    "figure_stem",
    "figure_stems",
    "draw_figures",
]

logger = logging.getLogger("brdfpipe.core.plot")

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

#: A fixed colour cycle (matplotlib's tab10), so colours never depend on rcParams.
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
            "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")

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
    skipped combinations, as logged; ``note``: the note written next to it
    (``<stem>.json``, "" for none).
    """

    files: tuple[Path, ...]
    title: str
    panel_titles: tuple[str, ...]
    database: str
    size_px: tuple[int, int]
    warnings: tuple[str, ...] = ()
    note: str = ""


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------


def read_csv(path: str | os.PathLike[str], required: Sequence[str]) -> tuple[Path, list[dict[str, str]]]:
    """Read a figure's input CSV: ``(path, rows)``, each row with the stripped ``required`` columns and ``__line__``.

    A missing file raises :class:`FileNotFoundError`; a file without its
    digest line or that does not match it (:func:`brdfpipe.core.integrity.read_csv_text`),
    an empty, non-UTF-8 or header-only file, missing columns or a short row
    raise :class:`FigureInputError` naming the file (and line, counted in the
    file as written).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: input file not found")
    text = integrity.read_csv_text(path, error=FigureInputError)
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
            raise FigureInputError(f"{path}: line {reader.line_num + 1}: wrong number of fields")
        row["__line__"] = str(reader.line_num + 1)  # + the digest line
        rows.append(row)
    if not rows:
        raise FigureInputError(f"{path}: no data rows (only a header)")
    return path, rows


def parse_float(path: Path, line: int, column: str, text: str) -> float:
    """``float(text)``, or :class:`FigureInputError` naming the file, line and column."""
    try:
        return float(text)
    except ValueError:
        raise FigureInputError(f"{path}: line {line}: column {column!r} is not a number: {text!r}") from None


def parse_int(path: Path, line: int, column: str, text: str) -> int:
    """An integer written as ``3`` or ``3.0``, or :class:`FigureInputError` naming the file, line and column."""
    x = parse_float(path, line, column, text)
    if not math.isfinite(x) or x != int(x):
        raise FigureInputError(f"{path}: line {line}: column {column!r} is not an integer: {text!r}")
    return int(x)


def single_database(path: Path, values: Iterable[str]) -> str:
    """The one database named by a file's ``database`` values; empty or several raise :class:`FigureInputError`."""
    names = sorted(set(values))
    if any(not v for v in names):
        raise FigureInputError(f"{path}: empty 'database' value")
    if len(names) != 1:
        raise FigureInputError(f"{path}: rows from more than one database ({', '.join(names)}); expected one")
    return names[0]


# ---------------------------------------------------------------------------
# Drawing helpers
# ---------------------------------------------------------------------------


class Warnings:
    """Collects (and logs) the skipped combinations of one figure."""

    def __init__(self, figure: str) -> None:
        self.figure = figure
        self.items: list[str] = []

    def __call__(self, msg: str) -> None:
        text = f"{self.figure}: {msg}"
        logger.warning(text)
        self.items.append(text)


def new_figure(width: float, height: float) -> Figure:
    """A ``width`` × ``height`` inch figure on the Agg canvas, constrained layout, at :data:`DPI` (no pyplot)."""
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


@contextmanager
def style() -> Iterator[None]:
    """matplotlib's default style plus :data:`RC_PARAMS`, whatever the user's matplotlibrc; restored on exit."""
    with mpl.rc_context():
        mpl.style.use("default")
        mpl.rcParams.update(RC_PARAMS)
        yield


def no_data(ax: Any, what: str) -> None:
    """Mark an empty panel: "no data (``what``)" in its centre, no ticks, grid or spines."""
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
    atomic_write(png, lambda fh: fig.savefig(fh, format="png", dpi=DPI,
                                              metadata={"Title": title, "Software": software}))
    # The PNG's save laid the figure out (constrained layout); the PDF keeps that layout rather than
    # computing it again (about a tenth of a figure job's CPU)
    engine = fig.get_layout_engine()
    fig.set_layout_engine("none")
    try:
        atomic_write(pdf, lambda fh: fig.savefig(fh, format="pdf", dpi=DPI,
                                                  metadata={"Title": title, "Creator": software,
                                                            "CreationDate": None, "ModDate": None}))
    finally:
        fig.set_layout_engine(engine)
    w, h = fig.get_size_inches()
    return (png, pdf), (int(round(h * DPI)), int(round(w * DPI)))


def finish(fig: Figure, stem: str | os.PathLike[str], title: str, subtitle: str, database: str,
            warn: Warnings, extra: Sequence[Path] = (), note: str | None = None) -> FigureOutput:
    """Title the figure (``title``, then ``subtitle``, each wrapped to its width) and save it.

    ``note``: the figure's note (one paragraph of the run's numbers, quoted
    by its report caption), written to ``<stem>.json``
    (:func:`brdfpipe.core.notes.write_note`) after the PNG and PDF.
    """
    chars = max(30, int(float(fig.get_size_inches()[0]) * 72.0 / (0.6 * 10.5)))
    lines = textwrap.wrap(title, chars) + (textwrap.wrap(subtitle, chars) if subtitle else [])
    fig.suptitle("\n".join(lines))
    panel_titles = tuple(ax.get_title() for ax in fig.axes if ax.get_title())
    files, size = _save(fig, stem, title)
    if note is not None:
        extra = (*extra, write_note(stem, title, note))
    return FigureOutput(files=files + tuple(extra), title=title, panel_titles=panel_titles,
                        database=database, size_px=size, warnings=tuple(warn.items), note=note or "")


# ---------------------------------------------------------------------------
# Output files
# ---------------------------------------------------------------------------


def figure_stem(files: Sequence[str | os.PathLike[str]], *, table: bool = False, note: bool = False) -> Path:
    """The common stem of one figure's output files, checked: ``[X.png, X.pdf]`` (``+ [X.csv, X.md]`` for a table,
    ``+ [X.json]`` for a note: :func:`brdfpipe.core.filenames.figure_files`).

    The workflow passes every output path explicitly; this only checks that
    the list names the files a figure function writes, so none is missing or
    written under a name the caller did not declare.
    """
    paths = [Path(f) for f in files]
    exts = ([".png", ".pdf", ".csv", ".md"] if table else [".png", ".pdf"]) + ([".json"] if note else [])
    if len(paths) != len(exts) or [p.suffix for p in paths] != exts:
        raise ValueError(f"figure outputs {[str(p) for p in paths]}: expected files ending in {exts}, in that order")
    stems = {p.with_suffix("") for p in paths}
    if len(stems) != 1:
        raise ValueError(f"figure outputs {[str(p) for p in paths]}: must share one stem")
    return stems.pop()


def figure_stems(track: str, rule: str, figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                 what: str) -> dict[str, Path]:
    """Key → output stem of each figure of ``rule`` asked for (``figures``: key → its declared files), checked.

    The keys and what each figure writes (a table, a note) are its record's
    (:func:`brdfpipe.registry.figures.track_figures`); :class:`ValueError`
    naming ``what`` for a key that is not a figure of the rule, or files that
    are not the figure's (:func:`figure_stem`).
    """
    records = {f.key: f for f in figure_specs.track_figures(track, rule)}
    unknown = sorted(set(figures) - set(records))
    if unknown:
        raise ValueError(f"{what}: unknown figure key(s) {unknown}; known: {sorted(records)}")
    return {k: figure_stem(figures[k], table=f.table, note=f.note) for k, f in records.items() if k in figures}


def draw_figures(module: ModuleType, track: str, rule: str, stems: Mapping[str, Path],
                 inputs: Any) -> list[FigureOutput]:
    """Draw the figures of ``stems`` (:func:`figure_stems`), each by the function its record names.

    The record (:class:`brdfpipe.registry.figures.Figure`) is the dispatcher:
    its ``draw`` is the name of a function of ``module`` called as
    ``draw(inputs, stem)``, where ``inputs`` holds everything the rule's
    figures read; nothing else maps a figure to its function.  In the
    records' order.
    """
    return [getattr(module, f.draw)(inputs, stems[f.key])
            for f in figure_specs.track_figures(track, rule) if f.key in stems]
