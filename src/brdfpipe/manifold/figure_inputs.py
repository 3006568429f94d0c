"""The inputs of the manifold track's figures (:mod:`brdfpipe.manifold.figures`), read and checked.

The GPLVM fits and their traces, the tables of :mod:`brdfpipe.manifold.analysis`,
the albedo maps, the data-space comparison of :mod:`brdfpipe.manifold.fidelity`,
Fig. 6's length-scale table and the unseen materials' table: each reader
returns a record of checked values, and raises
:class:`~brdfpipe.core.plot.FigureInputError` naming the file (and line) for
a missing or malformed one, so no figure is drawn from a bad input.
"""

from __future__ import annotations

import math
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from brdfpipe.core import integrity
from brdfpipe.core.plot import FigureInputError, parse_float, parse_int, read_csv, single_database
from brdfpipe.manifold.lengthscale_figure import LengthscaleTable, read_lengthscales
from brdfpipe.registry import tables

__all__ = [
    "TRACE_STAGES",
    "ALBEDO_MAP_KEYS",
    "SPACES_FIGURE_COLUMNS",
    "STABILITY_FIGURE_COLUMNS",
    "TraceTable",
    "AlbedoTable",
    "AlbedoMap",
    "LatentPath",
    "PathTable",
    "ReproductionTable",
    "SpacesTable",
    "UnseenTable",
    "ManifoldInputs",
    "read_trace",
    "read_albedo",
    "read_albedo_map",
    "read_paths",
    "read_reproduction",
    "read_model",
    "read_spaces",
    "read_unseen",
    "read_manifold_inputs",
]

# Inputs (written by brdfpipe.manifold.analysis and the fit_gplvm jobs):
#
# * models ``gplvm/q{q}.npz`` (:func:`brdfpipe.manifold.gplvm.load_model`) and traces
#   ``gplvm/q{q}-trace.csv`` (``step,stage,log_likelihood``; stages
#   ``start``, ``lbfgs``, ``newton``, ``hooke-jeeves``: :data:`TRACE_STAGES`);
# * ``manifold/albedo.csv`` (``database,material,r,g,b,luminance``);
# * albedo maps ``manifold/albedo-map-q{q}.npz`` (arrays x (W,), y (H,),
#   dims (2,), albedo (H, W, 3), luminance (H, W), fixed (q,), q, database);
# * ``manifold/paths.csv`` (:data:`~brdfpipe.registry.tables.LATENT_PATHS`, one row per step of each
#   latent path) and ``manifold/reproduction.csv``
#   (:data:`~brdfpipe.registry.tables.REPRODUCTION`).
#
# :func:`brdfpipe.manifold.figures.make_manifold_figures` reads and checks every input first (a
# missing or malformed file raises FigureInputError naming it, before any
# figure is written), then writes the figures of MANIFOLD_FIGURE_STEMS, each
# PNG + PDF, atomically and deterministically like the acquisition figures.

#: Trace stages: the start point, Hooke–Jeeves sweeps, L-BFGS iterations, Newton steps (in any order).
TRACE_STAGES: tuple[str, ...] = ("start", "hooke-jeeves", "lbfgs", "newton")
#: Arrays of an albedo map npz.
ALBEDO_MAP_KEYS: tuple[str, ...] = (
    "x", "y", "dims", "albedo", "luminance", "fixed", "q", "database", "inside_hull", "bad_inside", "bad_outside",
    "training_gap_median", "training_gap_max",
)


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
    p, rows = _read_manifold_csv(path, tables.GPLVM_TRACE, "trace file")
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
    p, rows = _read_manifold_csv(path, tables.MATERIAL_ALBEDO, "albedo table")
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
    """The latent paths of ``paths.csv`` (:func:`read_paths`), in file order."""

    path: Path
    database: str
    paths: tuple[LatentPath, ...]


_PATH_NUMERIC = ("t", "latent_distance", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound")


def read_paths(path: str | os.PathLike[str]) -> PathTable:
    """Read and check ``paths.csv``: rows grouped by (space, q, path), in order of first appearance."""
    p, rows = _read_manifold_csv(path, tables.LATENT_PATHS, "paths table")
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
    p, rows = _read_manifold_csv(path, tables.REPRODUCTION, "reproduction table")
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


def read_model(path: str | os.PathLike[str], q: int) -> Any:
    """The GPLVM model of latent dimension ``q`` at ``path`` (:func:`brdfpipe.manifold.gplvm.load_model`).

    :class:`~brdfpipe.core.plot.FigureInputError` naming the file for a missing or unreadable model or another q.
    """
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


#: The columns of ``spaces.csv`` and ``stability.csv`` (:data:`brdfpipe.registry.tables.SPACES`, ``STABILITY``) the figure reads.
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
    """Everything :func:`~brdfpipe.manifold.figures.make_manifold_figures` draws, read and cross-checked."""

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
    loaded = {q: read_model(p, q) for q, p in sorted(model_paths.items())}
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
    p, rows = read_csv(path, tables.MANIFOLD_UNSEEN)
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
