"""How a database of MERL tables compares with another: the statistics of issue 22, item 5.

The synthetic database (:mod:`brdfpipe.data.synth`) stands in for the measured
materials in the tests and as a fallback; this module measures how far it is
from them.  Every statistic is computed from a folder of MERL ``.binary``
files (read with :func:`brdfpipe.data.merl.read_merl`), the same way for
every database:

* **PCA spectrum of the log-mapped data** (:func:`pca_spectrum`) – the rows
  (material-channels, row ``3·i + c``) and columns (the cells measured, ≥ 0
  in all three channels, in *every* material: the store's ``valid``) of the
  pipeline's log-map, mapped exactly as :mod:`brdfpipe.data.logmap` maps them
  (:func:`~brdfpipe.data.logmap.forward`, ρ_ref the per-cell median over the
  rows by :func:`~brdfpipe.data.logmap.median_rows`, w from
  :func:`~brdfpipe.data.logmap.cell_weights`, default ``product``), with every
  material a training material (split ``all``; the pipeline's model uses the
  ``train`` split).  The singular values come from the row-centred Gram
  matrix by :func:`brdfpipe.acquisition.svd.decompose`, as the pipeline's
  model does.  Reported: σ_k/σ₁ and the cumulative explained variance
  EV(k) = Σ_{i≤k} σ_i² / Σ_i σ_i² at k = 1, 2, 5, 10, 20, 50 (:data:`KS`), and
  the total variance per entry Σσ²/(m·p) (the mean squared centred log value:
  how far the materials spread).
* **PCA-k reconstruction error of held-out materials** (:func:`holdout_errors`)
  – the materials are split into ``folds`` groups by a seeded permutation;
  each group in turn is held out, ρ_ref, μ and the components are computed
  from the others (ρ_ref the median over their rows, as the ``train`` split of
  the pipeline), and each held-out row x is projected on the first k
  components: ``rms_log(k) = ‖x − μ − V_k V_kᵀ(x − μ)‖ / √p`` (the pipeline's
  ``rms_log`` with every cell observed; k = 0 is the mean alone).  Reported:
  the mean of ``rms_log`` over all rows (every material is held out once) and
  the relative error ``√(Σ‖r‖² / Σ‖x − μ‖²)``.
* **Directional albedo at normal incidence** (:func:`normal_albedo`) –
  :func:`brdfpipe.data.merl.directional_albedo` at θi = 0, the mean of the
  three channels; quantiles 10 / 50 / 90 % over the materials.
* **Specular width** (:func:`specular_width`) – defined on the θd bin
  nearest 0 (θd ∈ [0°, 1°), centre 0.5°: light and view both near the
  mirror configuration of the half vector), where the BRDF is a function of
  θh alone: the profile f(θh) is the mean over φd and over the three
  channels of the measured (≥ 0) values of each θh bin (bin centres
  θh = ((i + ½)/90)²·90°).  The *peak* is f at the first θh bin (θh ≈ 0),
  the *floor* the smallest f over the bins with θh ≤ 80°
  (:data:`WIDTH_MAX_THETA_H`).  The width is the θh at which f first falls to
  floor + ½·(peak − floor), interpolated linearly in θh between bin centres:
  the half width at half maximum of the specular lobe over its diffuse
  floor, in degrees.  A material whose peak is below
  :data:`PEAK_CONTRAST` × floor has no specular peak there (a velvet, a
  matte diffuser): its width is NaN, counted apart and left out of the
  quantiles.  For a lobe exp(−tan²θh/α²) over a constant floor it is
  atan(α·√ln 2).
* **Largest value** – each material's largest measured value (sr⁻¹, over
  every measured cell and channel): quantiles 10 / 50 / 90 % and the
  largest of all.  The dynamic range the store, the Gram matrices and a
  renderer see: a narrow analytic lobe times 1/(cos θi · cos θo) peaks far
  higher at grazing angles than a measured (or fitted) material does.

Memory: the rows are held once, float32, only the valid cells
(3 × 100 materials × ≈ 1.1 M cells: 1.3 GB for 100 materials; a table is
read in float64 one file at a time); the Gram matrices are accumulated over
blocks of 8,192 columns mapped in float64 (20 MB each), so no m × p float64
matrix is ever held.  One pass over the rows computes the Gram matrices of
the spectrum and of every fold.

Command line (measure a folder, then tabulate)::

    python -m brdfpipe.acquisition.realism measure FOLDER --out stats.json [--note TEXT]
    python -m brdfpipe.acquisition.realism table a.json b.json ...

``table`` prints one Markdown table, one column per database.  A column is
headed by the database's label, which ``measure`` reads from the files'
provenance marks (:func:`brdfpipe.data.database.database_from_folder`: a
folder that mixes kinds of files is refused), never by what the caller
believes it to be; ``--note`` only adds a remark after it (``synthetic,
before (c461497)``) and may not name another database.  Both commands keep
the project's error contract (:mod:`brdfpipe.core.command`): one line naming
the file or option on bad input, an ``--out`` that is one of the inputs
refused before any work, the output written atomically.  Measured:
``docs/results/synthetic-vs-merl-nbrdf.md``.
"""

from __future__ import annotations

import json
import logging
import math
import re
import sys
import time
from argparse import ArgumentTypeError, Namespace
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.acquisition.svd import decompose
from brdfpipe.core import atomic
from brdfpipe.core.command import OneLineParser, run
from brdfpipe.core.logutil import setup_console_logging
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import logmap, merl, provenance
from brdfpipe.data.database import Database, database_from_folder

__all__ = [
    "KS",
    "HOLDOUT_KS",
    "QUANTILES",
    "PEAK_CONTRAST",
    "WIDTH_MAX_THETA_H",
    "DEFAULT_FOLDS",
    "DEFAULT_SEED",
    "Rows",
    "Spectrum",
    "Holdout",
    "Realism",
    "normal_albedo",
    "specular_width",
    "theta_h_centres",
    "rows_from_tables",
    "read_database",
    "gram_matrices",
    "pca_spectrum",
    "holdout_errors",
    "quantiles",
    "measure",
    "comparison_table",
    "read_realism",
    "check_label",
    "build_parser",
    "main",
]

logger = logging.getLogger("brdfpipe.acquisition.realism")

F64 = NDArray[np.float64]

#: Components at which the spectrum is reported.
KS: Final = (1, 2, 5, 10, 20, 50)
#: Components at which the held-out reconstruction error is reported (0: the mean alone).
HOLDOUT_KS: Final = (0, 1, 2, 5, 10, 20, 50)
#: Quantiles of the per-material distributions.
QUANTILES: Final = (0.1, 0.5, 0.9)
#: A specular peak must exceed the diffuse floor by this factor to have a width.
PEAK_CONTRAST: Final = 1.2
#: The diffuse floor of the width is the smallest profile value at θh ≤ this (degrees).
WIDTH_MAX_THETA_H: Final = 80.0
#: Held-out groups of :func:`holdout_errors` (every material is held out once).
DEFAULT_FOLDS: Final = 5
#: Seed of the held-out groups.
DEFAULT_SEED: Final = 2016
#: Columns per float64 working block of the Gram pass.
_BLOCK: Final = 8192


# --------------------------------------------------------------------------
# Per-material statistics
# --------------------------------------------------------------------------


def _table(table: ArrayLike) -> F64:
    arr = np.asarray(table, dtype=np.float64)
    if arr.shape != merl.SHAPE:
        raise ValueError(f"table has shape {arr.shape}, expected {merl.SHAPE}")
    return arr


def theta_h_centres() -> F64:
    """θh of the 90 bin centres in degrees: ((i + ½)/90)² · 90°."""
    u = (np.arange(merl.N_THETA_H) + 0.5) / merl.N_THETA_H
    return u * u * 90.0


def normal_albedo(table: ArrayLike) -> F64:
    """Directional albedo at normal incidence of a ``(3, 90, 90, 180)`` table, per channel ``(3,)``."""
    return merl.directional_albedo(_table(table), [0.0])[0]


def _width_profile(table: F64) -> F64:
    """f(θh) on the θd bin nearest 0: mean over φd and channels of the measured values (NaN: none)."""
    sl = table[:, :, 0, :]  # (3, θh, φd)
    ok = sl >= 0.0
    n = ok.sum(axis=(0, 2))
    total = np.where(ok, sl, 0.0).sum(axis=(0, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def specular_width(table: ArrayLike) -> float:
    """Half width at half maximum (degrees of θh) of the specular peak over its diffuse floor.

    On the θd bin nearest 0: f(θh) = mean over φd and channels of the
    measured values; peak = f at the first θh bin, floor = min f over
    θh ≤ :data:`WIDTH_MAX_THETA_H`; the width is the first θh where
    f ≤ floor + ½(peak − floor), linearly interpolated between bin centres.
    NaN when the peak is below :data:`PEAK_CONTRAST` × floor (no specular
    peak) or the first bin is not measured.  See the module docstring.
    """
    f = _width_profile(_table(table))
    th = theta_h_centres()
    use = (th <= WIDTH_MAX_THETA_H) & np.isfinite(f)
    if not use[0]:
        return math.nan
    peak = float(f[0])
    floor = float(np.min(f[use]))
    if not peak > PEAK_CONTRAST * max(floor, 0.0) or peak <= 0.0:
        return math.nan
    half = floor + 0.5 * (peak - floor)
    idx = np.flatnonzero(use)
    below = idx[f[idx] <= half]
    j = int(below[0])  # exists: the floor itself is ≤ half
    i = int(idx[idx < j][-1])  # the previous used bin (f > half there)
    t = (f[i] - half) / (f[i] - f[j])
    return float(th[i] + t * (th[j] - th[i]))


# --------------------------------------------------------------------------
# Rows of a database
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class Rows:
    """The materials of a database as the log-map sees them, and their per-material statistics.

    ``data`` is float32 ``(3·n, p)``, row ``3·i + c`` = channel c of
    material i (physical units), columns = ``cells`` (the cells measured in
    every material, increasing); ``albedo`` ``(n, 3)`` at normal incidence,
    ``width`` ``(n,)`` degrees (NaN: no specular peak), ``peak`` ``(n,)`` the
    largest measured value of each material (sr⁻¹).
    """

    names: tuple[str, ...]
    cells: NDArray[np.int64]
    data: NDArray[np.float32]
    albedo: F64
    width: F64
    peak: F64


def rows_from_tables(names: Sequence[str], tables: Iterable[ArrayLike]) -> Rows:
    """:class:`Rows` of materials given as ``(3, 90, 90, 180)`` tables (physical units), in order.

    Holds every table's full float32 copy until the valid cells are known,
    then compacts them in place; ValueError for no table, a count that does
    not match ``names`` or no cell measured in every material.
    """
    names = tuple(names)
    n = len(names)
    if n == 0:
        raise ValueError("no materials")
    data = np.empty((3 * n, merl.N_CELLS), dtype=np.float32)
    valid = np.ones(merl.N_CELLS, dtype=bool)
    albedo = np.empty((n, 3))
    width = np.empty(n)
    peak = np.empty(n)
    count = 0
    for i, table in enumerate(tables):
        if i >= n:
            raise ValueError(f"more tables than the {n} names")
        t = _table(table)
        flat = t.reshape(3, merl.N_CELLS)
        valid &= (flat >= 0.0).all(axis=0)
        data[3 * i: 3 * i + 3] = flat
        albedo[i] = normal_albedo(t)
        width[i] = specular_width(t)
        peak[i] = float(flat.max())  # unmeasured cells are negative
        count += 1
    if count != n:
        raise ValueError(f"{count} tables for {n} names")
    cells = np.flatnonzero(valid).astype(np.int64)
    if cells.size == 0:
        raise ValueError("no cell is measured in every material")
    p = cells.size
    for r in range(3 * n):  # compact each row to the valid cells, in place
        data[r, :p] = data[r, cells]
    return Rows(names, cells, data[:, :p], albedo, width, peak)


def read_database(db: Database) -> Rows:
    """:class:`Rows` of the materials of ``db`` (sorted by name), as labelled by :func:`database_from_folder`.

    Files are read one at a time (:func:`brdfpipe.data.merl.read_merl`, float64,
    :class:`~brdfpipe.data.merl.MerlFormatError` naming a bad file) and kept
    as float32.
    """
    names = db.materials

    def tables() -> Iterable[F64]:
        for k, name in enumerate(names):
            yield merl.read_merl(db.sources[name])
            if (k + 1) % 20 == 0:
                logger.info("read %d of %d materials", k + 1, len(names))

    return rows_from_tables(names, tables())


# --------------------------------------------------------------------------
# Gram matrices of the log-map
# --------------------------------------------------------------------------


def gram_matrices(
    rows: Rows, references: Sequence[NDArray[np.bool_]], weighting: str = "product"
) -> list[tuple[F64, F64]]:
    """``(G, colsum)`` of the log-map of all rows for each reference set, in one pass.

    ``references[j]`` is a boolean mask over the rows: ρ_ref is the per-cell
    median of those rows (:func:`brdfpipe.data.logmap.median_rows`), and every
    row is mapped with it (:func:`brdfpipe.data.logmap.forward`, weights of
    ``weighting``).  G = X Xᵀ (m × m) and colsum = X·1, float64, accumulated
    over float64 blocks of 8,192 columns, with one BLAS thread (the products
    are small: on a busy 2-core machine OpenBLAS's threads made the pass 20×
    slower).
    """
    m, p = rows.data.shape
    masks = [np.asarray(r, dtype=bool) for r in references]
    for mask in masks:
        if mask.shape != (m,) or not mask.any():
            raise ValueError(f"a reference set must be a non-empty boolean mask of the {m} rows")
    w = logmap.cell_weights(rows.cells, weighting)
    out = [(np.zeros((m, m)), np.zeros(m)) for _ in masks]
    with blas_threads(1):
        for a in range(0, p, _BLOCK):
            b = min(a + _BLOCK, p)
            block = rows.data[:, a:b]
            for (g, s), mask in zip(out, masks):
                ref = logmap.median_rows(block[mask])
                x = logmap.forward(block, ref, w[a:b])
                g += x @ x.T
                s += x.sum(axis=1)
    return out


def _centred_trace(g: F64) -> float:
    """trace(C G C) = Σσ² of the row-centred matrix (C = I − 11ᵀ/m)."""
    m = g.shape[0]
    return float(np.trace(g) - g.sum() / m)


# --------------------------------------------------------------------------
# Spectrum and held-out error
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class Spectrum:
    """PCA spectrum of a log-map: σ_k/σ₁ and cumulative explained variance at ``ks``."""

    ks: tuple[int, ...]
    sigma_ratio: tuple[float, ...]
    explained: tuple[float, ...]
    components: int
    variance_per_entry: float


def _spectrum(g: F64, colsum: F64, p: int, ks: Sequence[int]) -> Spectrum:
    _, sigma = decompose(g, colsum, p)
    total = _centred_trace(g)
    cum = np.cumsum(sigma**2) / total
    ratio = sigma / sigma[0]
    at = [min(k, sigma.size) - 1 for k in ks]
    return Spectrum(
        tuple(int(k) for k in ks),
        tuple(float(ratio[i]) if k <= sigma.size else 0.0 for i, k in zip(at, ks)),
        tuple(float(min(cum[i], 1.0)) for i in at),
        int(sigma.size),
        total / (g.shape[0] * p),
    )


def pca_spectrum(rows: Rows, ks: Sequence[int] = KS, weighting: str = "product") -> Spectrum:
    """PCA spectrum of the log-map of every row (ρ_ref: median over all rows).

    σ from :func:`brdfpipe.acquisition.svd.decompose` (components below its
    tolerance dropped: σ_k/σ₁ is 0 and EV(k) = 1 past them).  ValueError when
    all rows are identical (no component).
    """
    g, s = gram_matrices(rows, [np.ones(rows.data.shape[0], dtype=bool)], weighting)[0]
    return _spectrum(g, s, rows.data.shape[1], ks)


@dataclass(frozen=True)
class Holdout:
    """Held-out reconstruction error in log space at ``ks`` components (over every row)."""

    ks: tuple[int, ...]
    rms_log: tuple[float, ...]
    relative: tuple[float, ...]
    folds: int
    seed: int


def _folds(n: int, folds: int, seed: int) -> list[NDArray[np.intp]]:
    if not 2 <= folds <= n:
        raise ValueError(f"folds must lie in [2, {n}], got {folds}")
    order = np.random.default_rng(seed).permutation(n)
    return [np.sort(part) for part in np.array_split(order, folds)]


def _fold_residuals(g: F64, colsum: F64, p: int, test: NDArray[np.bool_], ks: Sequence[int]) -> tuple[F64, F64]:
    """Squared residuals (len(ks), held-out rows) and squared centred norms of the held-out rows."""
    tr = np.flatnonzero(~test)
    te = np.flatnonzero(test)
    gtt = g[np.ix_(tr, tr)]
    gts = g[np.ix_(tr, te)]
    u, sigma = decompose(gtt, colsum[tr], p)
    mt = tr.size
    xt_mu = gtt.sum(axis=1) / mt  # X_T μ
    mu_mu = gtt.sum() / mt**2
    norm2 = np.diag(g)[te] - 2.0 * gts.sum(axis=0) / mt + mu_mu  # ‖x − μ‖²
    coef = (u.T @ (gts - xt_mu[:, None])) / sigma[:, None]  # V_kᵀ(x − μ), (k, test)
    cum = np.vstack([np.zeros(te.size), np.cumsum(coef**2, axis=0)])
    res = np.array([np.maximum(norm2 - cum[min(k, sigma.size)], 0.0) for k in ks])
    return res, norm2


def holdout_errors(
    rows: Rows, ks: Sequence[int] = HOLDOUT_KS, folds: int = DEFAULT_FOLDS, seed: int = DEFAULT_SEED,
    weighting: str = "product",
) -> Holdout:
    """PCA-k reconstruction error of held-out materials (leave-one-group-out, seeded groups).

    The n materials are permuted with ``default_rng(seed)`` and split into
    ``folds`` groups; each group is held out once, mapped with the median of
    the other rows, and projected on the first k components of the others
    (k past the available components: all of them).  ``rms_log[j]`` is the
    mean over all rows of ‖r‖/√p at ``ks[j]``, ``relative[j]`` is
    √(Σ‖r‖²/Σ‖x − μ‖²).  Deterministic for a seed.
    """
    n = len(rows.names)
    groups = _folds(n, folds, seed)
    m, p = rows.data.shape
    tests = []
    for grp in groups:
        t = np.zeros(m, dtype=bool)
        for i in grp:
            t[3 * i: 3 * i + 3] = True
        tests.append(t)
    grams = gram_matrices(rows, [~t for t in tests], weighting)
    res_all, norm_all = [], []
    for (g, s), t in zip(grams, tests):
        res, norm2 = _fold_residuals(g, s, p, t, ks)
        res_all.append(res)
        norm_all.append(norm2)
    res = np.hstack(res_all)
    norm = np.concatenate(norm_all)
    return Holdout(
        tuple(int(k) for k in ks),
        tuple(float(x) for x in np.sqrt(res / p).mean(axis=1)),
        tuple(float(x) for x in np.sqrt(res.sum(axis=1) / norm.sum())),
        folds,
        seed,
    )


# --------------------------------------------------------------------------
# Summary
# --------------------------------------------------------------------------


def quantiles(values: ArrayLike, qs: Sequence[float] = QUANTILES) -> tuple[float, ...]:
    """Quantiles ``qs`` of the finite values (linear interpolation); NaN for each when there is none."""
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return tuple(math.nan for _ in qs)
    return tuple(float(x) for x in np.quantile(v, list(qs)))


def check_label(database: str, note: str = "") -> None:
    """ValueError unless ``database`` is a database label and ``note`` may be shown after it.

    ``database``: one of :func:`brdfpipe.data.provenance.database_labels`.
    ``note``: one line that names no other database label (as a whole word,
    any case) than ``database`` or a part of it: ``--note MERL`` cannot head
    a synthetic database's column, but may head ``merl-nbrdf``'s.
    """
    if database not in provenance.database_labels():
        raise ValueError(f"database {database!r}: not a database label ({', '.join(provenance.database_labels())})")
    if note != " ".join(note.split()):
        raise ValueError(f"--note {note!r}: one line of text, without leading, trailing or repeated spaces")
    for label in provenance.database_labels():
        if label not in (database, *database.split("-")) and re.search(
                rf"(?<![\w-]){re.escape(label)}(?![\w-])", note, re.IGNORECASE):
            raise ValueError(f"--note {note!r}: names the database {label!r}, but the files are {database!r} "
                             "(their provenance marks say so); the column is headed by that label")


@dataclass(frozen=True)
class Realism:
    """Every statistic of one database (JSON-serialisable with :func:`dataclasses.asdict`).

    ``database`` is the label of its files' provenance marks
    (:func:`brdfpipe.data.provenance.database_labels`), ``note`` a remark
    shown after it; both are checked on construction (:func:`check_label`).
    """

    database: str
    note: str
    materials: int
    cells: int
    weighting: str
    spectrum: Spectrum
    holdout: Holdout
    albedo_quantiles: tuple[float, ...]
    width_quantiles: tuple[float, ...]
    no_peak: int
    peak_quantiles: tuple[float, ...]
    peak_max: float
    quantile_levels: tuple[float, ...] = QUANTILES

    def __post_init__(self) -> None:
        check_label(self.database, self.note)

    @property
    def label(self) -> str:
        """The column's heading: the database's label, then the note."""
        return f"{self.database}, {self.note}" if self.note else self.database

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, doc: Any) -> Realism:
        """The statistics :meth:`to_json` wrote; ValueError for anything else (missing keys, other ``ks``)."""

        def floats(v: Any) -> tuple[float, ...]:
            if not isinstance(v, list):
                raise TypeError(f"expected a list, got {type(v).__name__}")
            return tuple(float(x) for x in v)

        if not isinstance(doc, dict):
            raise ValueError(f"not the statistics `realism measure` writes (a JSON {type(doc).__name__}, not an object)")
        try:
            s, h = doc["spectrum"], doc["holdout"]
            r = cls(
                str(doc["database"]), str(doc["note"]), int(doc["materials"]), int(doc["cells"]), str(doc["weighting"]),
                Spectrum(tuple(int(k) for k in floats(s["ks"])), floats(s["sigma_ratio"]), floats(s["explained"]),
                         int(s["components"]), float(s["variance_per_entry"])),
                Holdout(tuple(int(k) for k in floats(h["ks"])), floats(h["rms_log"]), floats(h["relative"]),
                        int(h["folds"]), int(h["seed"])),
                floats(doc["albedo_quantiles"]), floats(doc["width_quantiles"]), int(doc["no_peak"]),
                floats(doc["peak_quantiles"]), float(doc["peak_max"]), floats(doc["quantile_levels"]),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            what = f"no {err}" if isinstance(err, KeyError) else str(err)
            raise ValueError(f"not the statistics `realism measure` writes ({what})") from None
        shapes = {"spectrum.ks": (r.spectrum.ks, KS, r.spectrum.sigma_ratio, r.spectrum.explained),
                  "holdout.ks": (r.holdout.ks, HOLDOUT_KS, r.holdout.rms_log, r.holdout.relative),
                  "quantile_levels": (r.quantile_levels, QUANTILES, r.albedo_quantiles, r.width_quantiles,
                                      r.peak_quantiles)}
        for key, (have, want, *values) in shapes.items():
            if have != tuple(want) or any(len(v) != len(want) for v in values):
                raise ValueError(f"{key} is {list(have)}, this version measures {list(want)} (with a value each): "
                                 "measure the database again")
        return r


def read_realism(path: str | Path) -> Realism:
    """The statistics in a JSON file written by ``measure``; ValueError (or OSError) naming ``path``."""
    what = "not the statistics `realism measure` writes"
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError as err:
        raise ValueError(f"{path}: {what} (not UTF-8 text: {err.reason} at byte {err.start})") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: {what} (not JSON: {err})") from None
    try:
        return Realism.from_json(doc)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None


def measure(
    rows: Rows, database: str, *, note: str = "", weighting: str = "product", folds: int = DEFAULT_FOLDS,
    seed: int = DEFAULT_SEED,
) -> Realism:
    """Every statistic of a database (spectrum, held-out error, albedo, width and largest-value quantiles).

    ``database`` is the label of the files the rows come from (the ``kind``
    of :func:`brdfpipe.data.database.database_from_folder`), ``note`` a
    remark shown after it (:func:`check_label`, checked first).
    """
    check_label(database, note)
    albedo = rows.albedo.mean(axis=1)
    return Realism(
        database, note, len(rows.names), int(rows.cells.size), weighting,
        pca_spectrum(rows, KS, weighting),
        holdout_errors(rows, HOLDOUT_KS, folds, seed, weighting),
        quantiles(albedo), quantiles(rows.width), int(np.isnan(rows.width).sum()),
        quantiles(rows.peak), float(rows.peak.max()),
    )


def _fmt(x: float) -> str:
    if not math.isfinite(x):
        return "–"
    return f"{x:.3g}" if abs(x) >= 1e-3 or x == 0.0 else f"{x:.2e}"


def comparison_table(results: Sequence[Realism]) -> str:
    """One Markdown table: a row per statistic, a column per database (in the given order)."""
    if not results:
        raise ValueError("no databases to compare")
    head = "| statistic | " + " | ".join(r.label for r in results) + " |"
    lines = [head, "|---|" + "---|" * len(results)]

    def row(name: str, values: Iterable[str]) -> None:
        lines.append(f"| {name} | " + " | ".join(values) + " |")

    row("materials / valid cells", (f"{r.materials} / {r.cells:,}" for r in results))
    row("log-map variance per entry Σσ²/(m·p)", (_fmt(r.spectrum.variance_per_entry) for r in results))
    for j, k in enumerate(results[0].spectrum.ks):
        row(f"σ_{k}/σ_1", (_fmt(r.spectrum.sigma_ratio[j]) for r in results))
    for j, k in enumerate(results[0].spectrum.ks):
        row(f"explained variance, k = {k}", (_fmt(r.spectrum.explained[j]) for r in results))
    for j, k in enumerate(results[0].holdout.ks):
        row(f"held-out rms_log, k = {k}", (_fmt(r.holdout.rms_log[j]) for r in results))
    for j, k in enumerate(results[0].holdout.ks):
        if k:
            row(f"held-out relative error, k = {k}", (_fmt(r.holdout.relative[j]) for r in results))
    levels = "/".join(f"{round(100 * q)}" for q in results[0].quantile_levels)
    row(f"albedo at θi = 0 (channel mean), quantiles {levels} %",
        (" / ".join(_fmt(x) for x in r.albedo_quantiles) for r in results))
    row(f"specular width (°θh, HWHM at θd ≈ 0.5°), quantiles {levels} %",
        (" / ".join(_fmt(x) for x in r.width_quantiles) for r in results))
    row(f"materials without a specular peak (peak < {PEAK_CONTRAST} × floor)",
        (str(r.no_peak) for r in results))
    row(f"largest value (sr⁻¹), quantiles {levels} % / largest",
        (" / ".join(_fmt(x) for x in (*r.peak_quantiles, r.peak_max)) for r in results))
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------


#: The command's name in its messages.
PROG: Final = "python -m brdfpipe.acquisition.realism"


def _at_least(minimum: int) -> Any:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise ArgumentTypeError(f"expected a whole number ≥ {minimum}, got {text!r}") from None
        if value < minimum:
            raise ArgumentTypeError(f"expected a whole number ≥ {minimum}, got {text!r}")
        return value

    return parse


def build_parser() -> OneLineParser:
    """The argument parser of ``python -m brdfpipe.acquisition.realism`` (subcommands ``measure``, ``table``)."""
    parser = OneLineParser(prog=PROG, description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("measure", help="measure a folder of MERL .binary files")
    p.add_argument("folder", help="folder of .binary files of one kind (labelled from their provenance marks)")
    p.add_argument("--out", required=True, help="JSON file of the statistics")
    p.add_argument("--note", default="", help="a remark shown after the database's label in the table (e.g. the "
                   "commit measured); it may not name another database")
    p.add_argument("--weighting", default="product", choices=logmap.WEIGHTINGS)
    p.add_argument("--folds", type=_at_least(2), default=None,
                   help=f"held-out groups, 2 to the number of materials (default {DEFAULT_FOLDS}, or fewer if there "
                   "are fewer materials)")
    p.add_argument("--seed", type=_at_least(0), default=DEFAULT_SEED, help="seed of the held-out groups")
    t = sub.add_parser("table", help="print the Markdown table of measured databases")
    t.add_argument("stats", nargs="+", help="JSON files written by measure, one column each")
    return parser


def _measure_command(args: Namespace) -> int:
    """``measure``: every check before the work (the folder's files and label, --out, --folds, --note)."""
    db = database_from_folder(args.folder, key="folder")
    atomic.check_not_input(args.out, [args.folder, *db.sources.values()])
    if Path(args.out).is_dir():
        raise atomic.OutputError(f"--out {args.out}: is a folder; give the JSON file to write")
    atomic.check_writable(args.out)
    n = len(db.sources)
    folds = min(DEFAULT_FOLDS, n) if args.folds is None else args.folds
    if not 2 <= folds <= n:
        raise ValueError(f"--folds {folds}: must lie in [2, {n}], the number of materials in {args.folder} "
                         "(each group holds at least one, and one is held out against the others)")
    check_label(db.kind, args.note)
    setup_console_logging()
    start = time.perf_counter()
    rows = read_database(db)
    logger.info("read %d materials (%s), %d cells: %.1f s", n, db.kind, rows.cells.size, time.perf_counter() - start)
    try:
        result = measure(rows, db.kind, note=args.note, weighting=args.weighting, folds=folds, seed=args.seed)
    except ValueError as err:
        raise ValueError(f"folder {args.folder}: {err}") from None
    atomic.write_text(args.out, json.dumps(result.to_json(), indent=1) + "\n")
    logger.info("measured %s in %.1f s: %s", args.folder, time.perf_counter() - start, args.out)
    return 0


def _table_command(args: Namespace) -> int:
    """``table``: every file read and checked before anything is printed."""
    docs = [read_realism(f) for f in args.stats]
    sys.stdout.write(comparison_table(docs))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``measure FOLDER --out JSON [--note TEXT]`` or ``table JSON ...`` (prints Markdown); the exit status.

    Errors: one line ``python -m brdfpipe.acquisition.realism CMD: error: ...``
    naming the file or option (:func:`brdfpipe.core.command.run`).
    """
    args = build_parser().parse_args(argv)
    work = _measure_command if args.command == "measure" else _table_command
    return run(f"{PROG} {args.command}", lambda: work(args))


if __name__ == "__main__":
    raise SystemExit(main())
