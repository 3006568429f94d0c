"""Figure analogues of Soler et al. 2018 ("A Versatile Parameterization for
Measured Material Manifolds") for the manifold track.

Figs. 5, 7, 8, 9, 10 and eq. 7 from the GPLVM fits and
:mod:`brdfpipe.manifold.analysis`'s tables, Fig. 6 from
:mod:`brdfpipe.manifold.lengthscale`'s (drawn by
:mod:`brdfpipe.manifold.lengthscale_figure`), and the comparison of data
spaces: :func:`make_manifold_figures` (stems :data:`MANIFOLD_FIGURE_STEMS`)
and :func:`manifold_spaces`.  Every input is read and checked first; a
missing or malformed file raises :class:`~brdfpipe.core.plot.FigureInputError`
naming it, before any figure is written.  Style, determinism and atomic
writing are :mod:`brdfpipe.core.plot`'s.
"""

from __future__ import annotations

import logging
import math
import os
import textwrap
import zipfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import Rectangle
from matplotlib.ticker import MaxNLocator

from brdfpipe.core import integrity
from brdfpipe.core.filenames import MANIFOLD_FIGURE_STEMS
from brdfpipe.data.databases import title as database_label
from brdfpipe.manifold.lengthscale_figure import LengthscaleTable, manifold_fig06_lengthscale, read_lengthscales
from brdfpipe.spec import figures as figure_specs
from brdfpipe.spec import tables
from brdfpipe.core.plot import (
    COLOURS,
    RC_PARAMS,
    FigureInputError,
    FigureOutput,
    Warnings,
    check_keys,
    figure_stem,
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
    "TRACE_COLUMNS",
    "ALBEDO_COLUMNS",
    "PATHS_COLUMNS",
    "REPRODUCTION_COLUMNS",
    "ALBEDO_MAP_KEYS",
    "MANIFOLD_FIGURE_STEMS",
    "TraceTable",
    "AlbedoTable",
    "AlbedoMap",
    "LatentPath",
    "PathTable",
    "ReproductionTable",
    "ManifoldInputs",
    "read_trace",
    "read_albedo",
    "read_albedo_map",
    "read_paths",
    "read_reproduction",
    "read_manifold_inputs",
    "manifold_fig05_likelihood",
    "manifold_fig10_latent_q2",
    "manifold_fig10_latent_q5",
    "manifold_fig07_albedo",
    "manifold_fig09_paths",
    "manifold_fig08_reproduction",
    "manifold_eq7_bound",
    "manifold_fig06_lengthscale",
    "make_manifold_figures",
    "SpacesTable",
    "read_spaces",
    "manifold_spaces",
    "UNSEEN_COLUMNS",
    "UnseenTable",
    "read_unseen",
    "manifold_unseen",
]

logger = logging.getLogger("brdfpipe.manifold.figures")

# Inputs (written by brdfpipe.manifold.analysis and the fit_gplvm jobs):
#
# * models ``gplvm/q{q}.npz`` (:func:`brdfpipe.manifold.gplvm.load_model`) and traces
#   ``gplvm/q{q}-trace.csv`` (``step,stage,log_likelihood``; stages
#   ``start``, ``lbfgs``, ``newton``, ``hooke-jeeves``: :data:`TRACE_STAGES`);
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
TRACE_COLUMNS: tuple[str, ...] = tables.GPLVM_TRACE
#: Trace stages: the start point, Hooke–Jeeves sweeps, L-BFGS iterations, Newton steps (in any order).
TRACE_STAGES: tuple[str, ...] = ("start", "hooke-jeeves", "lbfgs", "newton")
#: Columns of ``albedo.csv``.
ALBEDO_COLUMNS: tuple[str, ...] = tables.MATERIAL_ALBEDO
#: Columns of ``paths.csv``.
PATHS_COLUMNS: tuple[str, ...] = tables.LATENT_PATHS
#: Columns of ``reproduction.csv``.
REPRODUCTION_COLUMNS: tuple[str, ...] = tables.REPRODUCTION
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
    """:func:`read_csv`, with a missing file a FigureInputError naming it."""
    return read_csv(_input_file(path, what), required)


def _finite(path: Path, line: int, column: str, text: str) -> float:
    x = parse_float(path, line, column, text)
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
        steps.append(parse_int(p, i, "step", r["step"]))
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
    return AlbedoTable(p, single_database(p, (r["database"] for r in rows)), tuple(mats),
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
    """Read and check an ``albedo-map-q{q}.npz`` (its digest first: :func:`brdfpipe.core.integrity.load_npz`)."""
    p = _input_file(path, "albedo map")
    z = integrity.load_npz(p, kind="albedo map", error=FigureInputError)
    missing = [k for k in ALBEDO_MAP_KEYS if k not in z]
    if missing:
        raise FigureInputError(f"{p}: missing array(s) {', '.join(missing)} "
                               f"(required: {', '.join(ALBEDO_MAP_KEYS)})")
    arrays = {k: np.asarray(z[k]) for k in ALBEDO_MAP_KEYS}
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
        rec.update(line=i, step=parse_int(p, i, "step", r["step"]), a=r["material_a"], b=r["material_b"],
                   nearest=r["nearest"])
        q = parse_int(p, i, "q", r["q"])
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
    return PathTable(p, single_database(p, (r["database"] for r in rows)), tuple(out))


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
        k = parse_int(p, i, "k", r["k"])
        if k < 1:
            raise FigureInputError(f"{p}: line {i}: k must be >= 1, got {k}")
        v = _finite(p, i, "relative_error", r["relative_error"])
        if v < 0:
            raise FigureInputError(f"{p}: line {i}: negative relative_error {v!r}")
        per = values.setdefault((space, method, k), {})
        if mat in per:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {method} k = {k}, material {mat!r}")
        per[mat] = v
    return ReproductionTable(p, single_database(p, (r["database"] for r in rows)), values)


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


#: The columns of ``spaces.csv`` and ``stability.csv`` (:data:`brdfpipe.spec.tables.SPACES`, ``STABILITY``) the figure reads.
SPACES_FIGURE_COLUMNS: tuple[str, ...] = tables.columns(
    tables.SPACES, "database", "candidate", "space", "mu", "q", "default", "kappa", "albedo_clamped_bad_hull",
    "albedo_clamped_bad_map", "albedo_bad_hull", "albedo_bad_map", "sum_abs_w_hull_median", "sum_abs_w_path_max", "nn_median",
)
STABILITY_FIGURE_COLUMNS: tuple[str, ...] = tables.columns(
    tables.STABILITY, "database", "candidate", "q", "norm", "epsilon", "median", "p90")


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
        q = parse_int(p, i, "q", r["q"])
        if (c, q) in out:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {c} q = {q}")
        if r["default"] == "true":
            defaults.add(c)
        out[(c, q)] = {k: parse_float(p, i, k, r[k]) for k in SPACES_FIGURE_COLUMNS[3:] if k != "default"}
    if len(defaults) != 1:
        raise FigureInputError(f"{p}: expected exactly one default candidate, found {sorted(defaults)}")
    database = single_database(p, (r["database"] for r in rows))
    sp = _input_file(stability_csv, "stability table")
    text = integrity.read_csv_text(sp, kind="stability table", error=FigureInputError)  # its digest checked
    lines = [line for line in text.splitlines() if line.strip()]
    header_only = len(lines) == 1
    if header_only and not set(STABILITY_FIGURE_COLUMNS) <= set(lines[0].split(",")):
        raise FigureInputError(f"{sp}: missing column(s) of a stability table (required: {', '.join(STABILITY_FIGURE_COLUMNS)})")
    # the log space has no Gram-based stability: a header alone is a valid (empty) table
    srows = [] if header_only else _read_manifold_csv(sp, STABILITY_FIGURE_COLUMNS, "stability table")[1]
    acc: dict[tuple[str, int, str], list[tuple[float, float, float]]] = {}
    for r in srows:
        i = int(r["__line__"])
        key = (r["candidate"], parse_int(sp, i, "q", r["q"]), r["norm"])
        acc.setdefault(key, []).append((_finite(sp, i, "epsilon", r["epsilon"]), _finite(sp, i, "median", r["median"]),
                                        _finite(sp, i, "p90", r["p90"])))
    if srows and single_database(sp, (r["database"] for r in srows)) != database:
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
    #: Fig. 6's table (``lengthscales.csv``), when given.
    lengthscales: LengthscaleTable | None = None


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
                         stability_csv: str | os.PathLike[str] | None = None,
                         lengthscales_csv: str | os.PathLike[str] | None = None) -> ManifoldInputs:
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
    scales = read_lengthscales(lengthscales_csv) if lengthscales_csv is not None else None
    if scales is not None:
        sources.append((scales.database, scales.path))
    names = sorted({db for db, _ in sources})
    if len(names) > 1:
        raise FigureInputError("inputs from different databases: "
                               + "; ".join(f"{db!r} ({p})" for db, p in sources))
    if database is not None and str(database).strip() and names[0] != str(database).strip():
        raise FigureInputError(f"{sources[0][1]}: database {names[0]!r}, but the figures are for database "
                               f"{str(database).strip()!r}")
    return ManifoldInputs(names[0], loaded, model_paths, trace_tables, albedo, maps, paths, reproduction, spaces,
                          scales)


# ---------------------------------------------------------------------------
# Manifold drawing helpers
# ---------------------------------------------------------------------------


def _set_title(fig: Figure, title: str, subtitle: str) -> None:
    """The suptitle exactly as :func:`finish` writes it (so layout-dependent steps can run before saving)."""
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
    warn = Warnings("manifold-fig05")
    with style():
        fig = new_figure(10.0, 4.2)
        ax, gap = fig.subplots(1, 2)
        if not inp.traces:
            warn("no trace files given")
            no_data(ax, "no trace files")
            gap.set_visible(False)
        else:
            allL = np.concatenate([t.log_likelihood for t in inp.traces.values()])
            switch_drawn = False
            for i, (q, tr) in enumerate(sorted(inp.traces.items())):
                colour = COLOURS[i % len(COLOURS)]
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
            ax.set_xlabel("step (L-BFGS iteration, Newton step or Hooke–Jeeves sweep; stage changes marked)")
            ax.set_ylabel("log-likelihood L (eq. 6)")
            ax.set_title("log-likelihood")
            ax.legend(loc="lower right")
            gap.set_yscale("log")
            gap.set_xlabel("step")
            gap.set_ylabel("max L − L")
            gap.set_title("distance to the best log-likelihood")
            if not gap.get_lines():
                no_data(gap, "no improvement")
        title = f"GPLVM log-likelihood during the fit ({database_label(inp.database)}, {_fit_note(inp)})"
        methods = sorted({str(m.method) for m in inp.models.values()})
        scales = sorted({f"{float(m.gram_scale):.4g}" for m in inp.models.values()})
        subtitle = (f"Soler 2018 Fig. 5 analogue; method {', '.join(methods)}; Gram matrix divided by "
                    f"{', '.join(scales)} before fitting")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _latent_names(names: Sequence[str]) -> list[str]:
    return [str(n) for n in names]


def manifold_fig10_latent_q2(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 (latent map): the 2-D latent points, each named, coloured by its albedo.

    Where the points crowd (names would overlap), zoomed panels on the most
    crowded cluster follow (at most two, nested); every material is named
    once, in the deepest panel that shows it.
    """
    warn = Warnings("manifold-fig10-q2")
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
    with style():
        if len(views) == 1:
            fig = new_figure(9.0, 8.4)
            axes = [fig.subplots()]
        else:
            nrows, ncols = _grid_shape(len(views), 2 if len(views) == 4 else 3)
            fig = new_figure(6.1 * ncols + 0.3, 6.0 * nrows + 1.0)
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
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig10_latent_q5(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 for q = 5: the latent points projected onto dims (0,1), (1,2), (2,3), (3,4), named.

    The q = 5 model, else the largest q (its consecutive pairs, at most 4).
    One row per pair; crowded projections get zoomed panels to the right
    (as :func:`manifold_fig10_latent_q2`).
    """
    warn = Warnings("manifold-fig10-q5")
    q = 5 if 5 in inp.models else max(inp.models)
    if q != 5:
        warn(f"no q = 5 model; drawing the q = {q} model")
    model = inp.models[q]
    X = np.asarray(model.X, dtype=np.float64)
    names = _latent_names(model.names)
    pairs = [(k, k + 1) for k in range(min(q, 5) - 1)]
    chains = [_zoom_chain(X[:, list(dims)], (4.4, 4.2)) for dims in pairs]
    with style():
        ncols = max([len(c) for c in chains] + [1])
        if len(chains) == 4 and ncols == 1:  # nothing crowded: a 2 × 2 grid
            fig = new_figure(2 * 5.4 + 0.3, 2 * 5.0 + 0.8)
            grid = fig.subplots(2, 2, squeeze=False).ravel()
            rows_axes = [[ax] for ax in grid]
        else:
            nrows = max(1, len(pairs))
            fig = new_figure(5.0 * ncols + 0.3, 4.8 * nrows + 0.8)
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
            no_data(ax0, f"q = {q}: no pair of latent dimensions")
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
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig07_albedo(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 7: luminance albedo of the interpolated BRDFs over the latent plane, with iso-lines."""
    warn = Warnings("manifold-fig07")
    maps = [inp.maps[q] for q in sorted(inp.maps)]
    with style():
        nrows, ncols = _grid_shape(max(1, len(maps)), 2)
        fig = new_figure(5.6 * ncols + 0.3, 4.9 * nrows + 0.8)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        if not maps:
            warn("no albedo maps given")
            no_data(axes[0], "no albedo maps")
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
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _selected_paths(inp: ManifoldInputs, warn: Warnings) -> list[LatentPath]:
    paths = list(inp.paths.paths)
    if len(paths) > MAX_PATH_PANELS:
        warn(f"{inp.paths.path}: {len(paths)} paths; drawing the first {MAX_PATH_PANELS}")
    return paths[:MAX_PATH_PANELS]


def manifold_fig09_paths(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 9: perceptual distance to A and to B along latent paths (normalised axes)."""
    warn = Warnings("manifold-fig09")
    paths = _selected_paths(inp, warn)
    with style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = new_figure(3.7 * ncols + 0.3, 3.5 * nrows + 0.9)
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
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _hide_unused_path_panels(axes: Sequence[Any], n_paths: int) -> None:
    """Hide the panels after the last path; with no path at all, say so in the first."""
    for ax in axes[n_paths:]:
        if not n_paths and ax is axes[0]:
            no_data(ax, "no paths")
        else:
            ax.set_visible(False)


def manifold_fig08_reproduction(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 8: relative error reproducing each training material, PCA (k components) vs GPLVM (q)."""
    warn = Warnings("manifold-fig08")
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
    with style():
        fig = new_figure(10.0, 4.8)
        ax = fig.subplots()
        for i, k in enumerate(pca_k):
            per = tab.values[(space, "pca", k)]
            v = np.array([per.get(m, np.nan) for m in mats])
            ok = np.isfinite(v) & (v > 0)
            ax.plot(xs[ok], v[ok], color=COLOURS[i % len(COLOURS)], marker="o", markersize=2.6,
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
            no_data(ax, f"no rows for data space {space}")
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
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_eq7_bound(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Eq. 7: actual deviation from the nearest training material vs the bound, along each path."""
    warn = Warnings("manifold-eq7")
    paths = _selected_paths(inp, warn)
    with style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = new_figure(3.7 * ncols + 0.3, 3.3 * nrows + 0.9)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        for ax, lp in zip(axes, paths):
            dv, bd, t = lp.deviation, lp.bound, lp.t
            # Omitted: points with a zero bound (x* on a training point: the ends) whose deviation is
            # zero or rounding noise (≤ 1e-9 of the path's largest); a real deviation there stays.
            noise = 1e-9 * float(dv.max())
            keep = ~((bd == 0) & (dv <= noise))
            okd, okb = keep & (dv > 0), keep & (bd > 0)
            ax.plot(t[okd], dv[okd], color=COLOURS[0], marker="o", markersize=2.8, linewidth=1.2,
                    label="deviation ‖z* − z_nearest‖")
            ax.plot(t[okb], bd[okb], color=COLOURS[3], linestyle="--", marker="s", markersize=2.4,
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
                no_data(ax, "deviation and bound are 0")
                ax.set_title(lp.title, fontsize=8.0)
        _hide_unused_path_panels(axes, len(paths))
        title = f"Deviation from the nearest training material vs the eq. 7 bound ({database_label(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 eq. 7: ‖z* − z_j‖ ≤ e^(−1/2)·√(2N)/ℓ·κ(K)·‖Z‖·‖x* − x_j‖, j the nearest "
                    "training point in latent space; the path ends (bound 0, deviation 0 up to rounding) omitted; "
                    f"{_space_note(p.space for p in paths)}")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_spaces(table: SpacesTable, stem: str | os.PathLike[str]) -> FigureOutput:
    """The data spaces compared: albedo outside [0, 1], stability near the training points, κ(K) and Σ|w|."""
    warn = Warnings("manifold-spaces")
    cands = table.candidates
    dims = table.dims
    with style():
        fig = new_figure(12.0, 8.6)
        (ax_a, ax_s), (ax_k, ax_w) = fig.subplots(2, 2)
        x = np.arange(len(cands))
        width = 0.8 / max(1, len(dims))
        for j, q in enumerate(dims):
            colour = COLOURS[j % len(COLOURS)]
            off = (j - (len(dims) - 1) / 2) * width
            hull = [100 * table.rows.get((c, q), {}).get("albedo_clamped_bad_hull", np.nan) for c in cands]
            ax_a.bar(x + off, hull, width * 0.9, color=colour, label=f"q = {q}: inside the hull")
            unclamped = [100 * table.rows.get((c, q), {}).get("albedo_bad_hull", np.nan) for c in cands]
            ax_a.plot(x + off, unclamped, "x", color="#222222", markersize=4,
                      label="unclamped table (Σ wᵢ Aᵢ: negative lobes)" if j == 0 else None)
            if q == 2:
                mp = [100 * table.rows.get((c, q), {}).get("albedo_clamped_bad_map", np.nan) for c in cands]
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
            colour = COLOURS[i % len(COLOURS)]
            for norm, linestyle in (("space", "-"), ("raw", ":")):
                v = table.stability.get((c, qs, norm))
                if v is None:
                    continue
                eps, med, _ = v
                ok = med > 0
                ax_s.plot(eps[ok], med[ok], linestyle, color=colour, marker="o", markersize=2.5, linewidth=1.4 if c == table.default else 0.9,
                          label=f"{c}" if norm == "space" else None)
        ax_s.axhline(0.01, color="#aa0000", linestyle=":", linewidth=1.0)
        ax_s.set_xscale("log")
        ax_s.set_yscale("log")
        ax_s.set_xlabel("offset ε from the training point (ℓ)")
        ax_s.set_ylabel("median ‖z(xᵢ+εu) − zᵢ‖ / ‖zᵢ‖")
        ax_s.set_title(f"(b) stability near the training points, q = {qs}\nsolid: the fit's own space; dotted: raw BRDF units; red: 1 %")
        ax_s.legend(fontsize=6.5)
        title = f"GPLVM data spaces compared ({database_label(table.database)})"
        subtitle = (f"candidates: data space and kernel noise μ (and how fitted, when not the standard fit); default: "
                    f"{table.default}. (a) albedo outside [0, 1] of the interpolated table as rendered (negative "
                    "values clamped to 0; ×: before clamping); (b) change of the interpolated "
                    "material a distance ε from a training point; (c) κ(K); (d) Σ|w|")
        return finish(fig, stem, title, subtitle, table.database, warn)


def make_manifold_figures(*, models: Mapping[int, str | os.PathLike[str]],
                          traces: Mapping[int, str | os.PathLike[str]], albedo_csv: str | os.PathLike[str],
                          albedo_maps: Mapping[int, str | os.PathLike[str]], paths_csv: str | os.PathLike[str],
                          reproduction_csv: str | os.PathLike[str],
                          figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                          database: str | None = None,
                          spaces_csv: str | os.PathLike[str] | None = None,
                          stability_csv: str | os.PathLike[str] | None = None,
                          lengthscales_csv: str | os.PathLike[str] | None = None) -> list[Path]:
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
    ``fig06`` length scale           eq. 7 as ℓ shrinks (``lengthscales_csv``),
                                     PNG, PDF and its note
    ``spaces`` data spaces           the candidates of ``compare_spaces``
                                     (``spaces_csv``, ``stability_csv``)
    ==============================  ===========================================
    """
    check_keys(figures, MANIFOLD_FIGURE_STEMS, "make_manifold_figures")
    notes = {f.key for f in figure_specs.track_figures("manifold", "plot_manifold_figures") if f.note}
    stems = {k: figure_stem(v, note=k in notes) for k, v in figures.items()}
    if "spaces" in stems and (spaces_csv is None or stability_csv is None):
        raise FigureInputError("the 'spaces' figure needs spaces_csv and stability_csv")
    if "fig06" in stems and lengthscales_csv is None:
        raise FigureInputError("the 'fig06' figure needs lengthscales_csv")
    inp = read_manifold_inputs(models=models, traces=traces, albedo_csv=albedo_csv, albedo_maps=albedo_maps,
                               paths_csv=paths_csv, reproduction_csv=reproduction_csv, database=database,
                               spaces_csv=spaces_csv, stability_csv=stability_csv, lengthscales_csv=lengthscales_csv)
    draw = {
        "fig05": manifold_fig05_likelihood,
        "fig10_q2": manifold_fig10_latent_q2,
        "fig10_q5": manifold_fig10_latent_q5,
        "fig07": manifold_fig07_albedo,
        "fig09": manifold_fig09_paths,
        "fig08": manifold_fig08_reproduction,
        "eq7": manifold_eq7_bound,
    }
    results = [draw[k](inp, stems[k]) for k in MANIFOLD_FIGURE_STEMS if k in stems and k not in ("spaces", "fig06")]
    if "fig06" in stems and inp.lengthscales is not None:
        results.append(manifold_fig06_lengthscale(inp.lengthscales, stems["fig06"], inp.database))
    if "spaces" in stems and inp.spaces is not None:
        results.append(manifold_spaces(inp.spaces, stems["spaces"]))
    return [p for r in results for p in r.files]


# ---------------------------------------------------------------------------
# Materials outside the training set (config unseen)
# ---------------------------------------------------------------------------

#: Columns of the manifold's ``unseen.csv`` (:mod:`brdfpipe.manifold.unseen`).
UNSEEN_COLUMNS: tuple[str, ...] = tables.MANIFOLD_UNSEEN
_UNSEEN_COLOURS = ("#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b")


@dataclass(frozen=True)
class UnseenTable:
    """The manifold's ``unseen.csv``: per (database, material, method, k) the error and, for the GPLVM, x*."""

    path: Path
    model_database: str
    space: str
    errors: dict[tuple[str, str, str, int], float]
    latent: dict[tuple[str, str, str, int], tuple[float, ...]]

    def databases(self) -> list[str]:
        return sorted({k[0] for k in self.errors})


def read_unseen(path: str | os.PathLike[str]) -> UnseenTable:
    """Read and check the manifold's ``unseen.csv`` (:class:`FigureInputError` naming the file)."""
    p, rows = read_csv(path, UNSEEN_COLUMNS)
    model_db = single_database(p, (r["model_database"] for r in rows))
    space = single_database(p, (r["space"] for r in rows))
    errors: dict[tuple[str, str, str, int], float] = {}
    latent: dict[tuple[str, str, str, int], tuple[float, ...]] = {}
    for r in rows:
        i = int(r["__line__"])
        if not r["database"] or r["database"] == model_db:
            raise FigureInputError(f"{p}: line {i}: database {r['database']!r} is not outside the model's {model_db}")
        key = (r["database"], r["material"], r["method"], int(_finite(p, i, "k", r["k"])))
        if key in errors:
            raise FigureInputError(f"{p}: line {i}: duplicate row for {key}")
        errors[key] = _finite(p, i, "relative_error", r["relative_error"])
        if r["latent"]:
            latent[key] = tuple(_finite(p, i, "latent", t) for t in r["latent"].split())
    return UnseenTable(p, model_db, space, errors, latent)


def manifold_unseen(model_path: str | os.PathLike[str], q: int, unseen_csv: str | os.PathLike[str],
                    files: Sequence[str | os.PathLike[str]]) -> FigureOutput:
    """The unseen materials on the latent map of the q model, and their reproduction by the GPLVM and PCA.

    Left: the training materials' latent points (grey) and each unseen
    material's x* by the GP likelihood (filled, named) and by least squares
    (open), joined, coloured by database (q = 2: the plane; q > 2: dims 0, 1;
    q = 1: dim 0 against the material index).  Right: relative reproduction
    error of each unseen material by b(x*) (both ways, each q) and by the
    projection on k principal components of the same training materials.
    """
    stem = figure_stem(files)
    model = _read_model(model_path, q)
    table = read_unseen(unseen_csv)
    warn = Warnings("manifold-unseen")
    X = np.asarray(model.X, dtype=np.float64)
    if q < 2:
        warn(f"the q = {q} model has one latent dimension: drawn against the material index")
    dbs = table.databases()
    colours = {db: _UNSEEN_COLOURS[i % len(_UNSEEN_COLOURS)] for i, db in enumerate(dbs)}

    def plane(x: Sequence[float], index: float) -> tuple[float, float]:
        return (x[0], x[1]) if q >= 2 else (x[0], index)

    with style():
        fig = new_figure(13.0, 6.2)
        left, right = fig.subplots(1, 2, width_ratios=[1.25, 1.0])
        P = np.array([plane(x, i) for i, x in enumerate(X)])
        left.scatter(P[:, 0], P[:, 1], s=10, color="#b0b0b0", label=f"training materials ({table.model_database})",
                     zorder=1)
        drawn = 0
        for db in dbs:
            mats = sorted({k[1] for k in table.latent if k[0] == db and k[3] == q})
            for j, mat in enumerate(mats):
                gp = table.latent.get((db, mat, "gplvm-likelihood", q))
                ls = table.latent.get((db, mat, "gplvm-least-squares", q))
                idx = len(X) + j
                if gp is not None and ls is not None:
                    a, b = plane(gp, idx), plane(ls, idx)
                    left.plot([a[0], b[0]], [a[1], b[1]], color=colours[db], lw=0.6, alpha=0.6, zorder=2)
                if ls is not None:
                    b = plane(ls, idx)
                    left.scatter([b[0]], [b[1]], s=22, facecolors="none", edgecolors=colours[db], zorder=3)
                if gp is not None:
                    a = plane(gp, idx)
                    left.scatter([a[0]], [a[1]], s=22, color=colours[db], zorder=4)
                    left.annotate(mat, a, fontsize=LATENT_LABEL_SIZE, color=colours[db], xytext=(3, 2),
                                  textcoords="offset points")
                    drawn += 1
            left.scatter([], [], s=22, color=colours[db], label=f"{db}: x* by likelihood (named)")
            left.scatter([], [], s=22, facecolors="none", edgecolors=colours[db], label=f"{db}: x* by least squares")
        if not drawn:
            warn(f"no unseen latent position for q = {q}")
        left.set_xlabel("latent dim 0")
        left.set_ylabel("latent dim 1" if q >= 2 else "material index")
        left.set_title(f"latent map, q = {q}, {len(X)} training materials")
        left.legend(loc="best", fontsize=6)
        methods = sorted({(k[2], k[3]) for k in table.errors},
                         key=lambda mk: (mk[0] != "pca", mk[1], mk[0]))
        labels = [("PCA" if m == "pca" else "GPLVM, " + m.removeprefix("gplvm-")) + f", k = {k}" for m, k in methods]
        allv: list[float] = []
        for xi, (m, k) in enumerate(methods):
            for off, db in enumerate(dbs):
                vals = [v for key, v in sorted(table.errors.items()) if key[0] == db and key[2] == m and key[3] == k]
                if not vals:
                    continue
                xs = xi + (off - (len(dbs) - 1) / 2) * 0.18 + np.zeros(len(vals))
                right.scatter(xs, vals, s=10, color=colours[db], alpha=0.7, label=db if xi == 0 else None)
                right.plot([xi - 0.3, xi + 0.3], [float(np.median(vals))] * 2, color=colours[db], lw=1.5)
                allv += vals
        right.set_xticks(np.arange(len(methods)), labels, rotation=35, ha="right", fontsize=7)
        right.set_ylabel(f"relative reproduction error ({table.space} space)")
        right.set_title("reproduction of each unseen material (bar: median)")
        if allv and min(allv) > 0 and max(allv) / min(allv) > 8:
            right.set_yscale("log")
        if allv:
            right.legend(loc="best", fontsize=7)
        else:
            no_data(right, "no reproduction rows")
        title = (f"Materials outside the training set on the GPLVM manifold "
                 f"(model: {database_label(table.model_database)})")
        subtitle = (f"Soler 2018 Fig. 10 / Fig. 8 analogue for unseen materials ({'; '.join(database_label(d) for d in dbs)}); "
                    "x* maximises the "
                    f"GP likelihood of the material or minimises ‖z − Σ bᵢ(x) zᵢ‖ in the {table.space} space")
        return finish(fig, stem, title, subtitle, table.model_database, warn)
