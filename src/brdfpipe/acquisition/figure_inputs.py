"""The evaluation's tables as the Xu 2016 figures read them: ``errors.csv`` and ``training_size.csv``.

Shared by the figure modules of the acquisition track
(:mod:`brdfpipe.acquisition.figures`, :mod:`brdfpipe.acquisition.figures_configs`,
:mod:`brdfpipe.acquisition.figures_recon`).  ``errors.csv`` (tidy):
``database, split, setup, fov, metric, n, material, channel, kind, value``
(:data:`brdfpipe.registry.tables.ERRORS`); ``training_size.csv``: ``database,
n_train, order_seed, material, channel, kind, value``.  A missing, empty or
malformed file raises :class:`~brdfpipe.core.plot.FigureInputError` naming it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from brdfpipe.core.plot import FigureInputError, parse_float, parse_int, read_csv, single_database
from brdfpipe.registry import tables

__all__ = [
    "FOV_TOL",
    "AcquisitionFigureInputs",
    "ErrorTable",
    "TrainingTable",
    "read_errors",
    "read_training_size",
]

#: Two fields of view closer than this (degrees) are the same.
FOV_TOL = 1e-6


@dataclass(frozen=True)
class AcquisitionFigureInputs:
    """What the Xu figures of ``plot_acquisition_figures`` read: each figure's function takes it and its stem.

    ``errors_csv``: the evaluation's ``errors.csv``; ``training_csv``: the
    training-size table (Fig. 7); ``directions``: the direction files to
    tabulate (Figs. 8, 9, 14); ``fovs``: the near-field FOVs of Figs. 5, 6
    and 8 (None: every near-field FOV in the table); ``n_point``: the point
    samples of Fig. 18; ``fov_fixed``: the FOV of Figs. 7 (label), 13 and
    14; ``figure_fov``: the near-field FOV of Figs. 3 and 9 (Xu's 25°);
    ``figure_materials``: the materials of Fig. 3 (Fig. 2's; None: every
    held-out material); ``split``: the split whose rows are plotted;
    ``kind``: the error plotted; ``database``: the label of the
    configuration figures' titles (the errors table's).
    """

    errors_csv: str | os.PathLike[str] = ""
    training_csv: str | os.PathLike[str] | None = None
    directions: Sequence[str | os.PathLike[str]] = ()
    fovs: Sequence[float] | None = None
    n_point: int = 5
    fov_fixed: float = 25.0
    figure_fov: float = 25.0
    figure_materials: Sequence[str] | None = None
    split: str = "train"
    kind: str = "rms_log"
    database: str = ""


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
                     if k[0] == split and k[1] == setup and abs(k[2] - fov) < FOV_TOL and k[3] == metric
                     and k[5] == material and k[6] == channel and k[7] == kind and math.isfinite(v))
        return (np.array([p[0] for p in pts], dtype=np.int64), np.array([p[1] for p in pts], dtype=np.float64))

    def materials(self, split: str, setup: str, fov: float, metric: str, n: int, kind: str) -> list[str]:
        return sorted({k[5] for k in self.values
                       if k[0] == split and k[1] == setup and abs(k[2] - fov) < FOV_TOL and k[3] == metric
                       and k[4] == n and k[7] == kind and k[5] != "mean"})

    def material_value(self, split: str, setup: str, fov: float, metric: str, n: int, kind: str,
                       material: str) -> float:
        """A material's value averaged over channels: its ``all`` row, else the mean of its channel rows."""
        vals = {k[6]: v for k, v in self.values.items()
                if k[0] == split and k[1] == setup and abs(k[2] - fov) < FOV_TOL and k[3] == metric
                and k[4] == n and k[7] == kind and k[5] == material}
        if "all" in vals and math.isfinite(vals["all"]):
            return vals["all"]
        chans = [v for c, v in sorted(vals.items()) if c != "all" and math.isfinite(v)]
        return float(np.mean(chans)) if chans else math.nan


def read_errors(path: str | os.PathLike[str]) -> ErrorTable:
    """Read and check ``errors.csv`` (:class:`FigureInputError` naming the file if it is malformed)."""
    p, rows = read_csv(path, tables.ERRORS)
    values: dict[tuple[str, str, float, str, int, str, str, str], float] = {}
    for r in rows:
        i = int(r["__line__"])
        for c in ("split", "setup", "metric", "material", "channel", "kind"):
            if not r[c]:
                raise FigureInputError(f"{p}: line {i}: empty {c!r}")
        key = (r["split"], r["setup"], parse_float(p, i, "fov", r["fov"]), r["metric"],
               parse_int(p, i, "n", r["n"]), r["material"], r["channel"], r["kind"])
        if key in values:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {dict(zip(tables.ERRORS[1:9], key))}")
        values[key] = parse_float(p, i, "value", r["value"])
    return ErrorTable(p, single_database(p, (r["database"] for r in rows)), values)


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
    p, rows = read_csv(path, tables.TRAINING_SIZE)
    values: dict[tuple[int, str, str, str, str], float] = {}
    for r in rows:
        i = int(r["__line__"])
        for c in ("order_seed", "material", "channel", "kind"):
            if not r[c]:
                raise FigureInputError(f"{p}: line {i}: empty {c!r}")
        key = (parse_int(p, i, "n_train", r["n_train"]), r["order_seed"], r["material"], r["channel"], r["kind"])
        if key in values:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {dict(zip(tables.TRAINING_SIZE[1:6], key))}")
        values[key] = parse_float(p, i, "value", r["value"])
    return TrainingTable(p, single_database(p, (r["database"] for r in rows)), values)
