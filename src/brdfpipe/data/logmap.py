"""The log-relative mapping of the MERL matrix (Xu et al. 2016 §3, Nielsen et al. 2015).

Every BRDF value ρ of a cell is mapped to

    x = ln((ρ·w + ε) / (ρ_ref·w + ε)),        ε = 0.001,

and back with ρ = (exp(x)·(ρ_ref·w + ε) − ε) / w (:func:`forward`,
:func:`inverse`).  ``ρ_ref`` is the per-cell median over the *training rows*
(every channel of every training material; :func:`median_reference`) and ``w``
a per-cell weight computed from the light and view directions of the cell
centre (:func:`cell_weights`, with θi / θo the zenith angles of
``merl.cell_directions``):

* ``"product"`` (default): ``w = max(cos θi · cos θo, 0.01)``, as in the code
  released with Nielsen et al. 2015;
* ``"max"``: ``w = max(cos θi, cos θo)``, as written in Xu et al. 2016 §3.

Rows and columns
----------------
Rows are *material-channels*: row ``r = 3·i + c`` is channel ``c`` (0 = R,
1 = G, 2 = B) of material ``i`` of the given material list, so m = 3 × the
number of materials.  Columns are the cells valid (measured) in every material
of the *store* (``store.valid``), in increasing cell order (p ≈ 1.1 M); column
``j`` is MERL cell ``cells[j]`` (flat index ``iθh·16200 + iθd·180 + iφd``).
Whatever materials a log-map holds, its columns are the same for one store, so
log-maps of the training and the test materials line up column for column.

Splits
------
``split`` names the training set and is checked against it: ``"all"`` = every
material of the store, ``"train"`` = the store's materials minus the held-out
test materials (a non-empty proper subset).  The rows written
(``materials_out``) default to the training materials; the test materials'
rows are written by giving them as ``materials_out`` with the same training
set (so they are mapped relative to the *training* median).

On-disk format (:func:`write_logmap`, read with :func:`open_logmap`)
-------------------------------------------------------------------
A Zarr v3 group holding

* ``X`` – float32 ``(m_out, p)``, dimensions ``("row", "column")``: the mapped
  rows of ``materials_out``; chunks ``(m_out, 36_450)`` (:data:`CHUNK_COLS`,
  a quarter of the store's 145,800-column chunks), Blosc lz4 + byte shuffle,
  fill value NaN.  Chunks span all rows, so a column block is one chunk read;
  36,450 columns keep a chunk at 39 MB for m = 270 (its float64 working copy
  79 MB) and give 31 chunks, i.e. up to 31 chunk-aligned column ranges for
  the distributed SVD (:mod:`brdfpipe.acquisition.svd`).
* ``reference`` – float64 ``(p,)``: ρ_ref, the per-cell median of the training
  rows (sr⁻¹).
* ``weight`` – float64 ``(p,)``: w.
* ``cells`` – int32 ``(p,)``: column → MERL cell index, strictly increasing.

Group attributes: ``format`` (``"brdfpipe.logmap/1"``), ``split``,
``weighting``, ``epsilon``, ``materials`` (of the rows, in order), ``rows``
(``[material, channel]`` for every row), ``train_materials`` (in store order),
``database`` (copied from the store), ``brdfpipe_version`` and, written last,
the completion marker ``brdfpipe_complete`` = ``{"rows": m_out, "columns": p,
"id": <hex digest>}``; the ``id`` is a sha256 digest of the attributes, the
store's source digests and ρ_ref, so it identifies this log-map's content
(the SVD refuses Gram partials computed from another one) while the same
inputs still give the same bytes.  The marker is written together with the
integrity record ``brdfpipe_digests`` (CRC-32C of every file, digest of the
attributes; :mod:`brdfpipe.core.integrity`): :func:`open_logmap` checks it,
and every chunk of ``X`` is checked before it is read.

The output is built in a temporary sibling directory and swapped into place
(:func:`brdfpipe.core.atomic.atomic_dir`): after any error or interrupt an earlier
log-map at ``out`` is left exactly as it was, and an ``out`` that holds
anything but a log-map (a store, another Zarr group, a folder) is refused
before any work.  The store is opened with :func:`brdfpipe.data.store.open_store`,
which verifies every shard against its digest, so a damaged or missing shard
is a :class:`~brdfpipe.data.store.StoreError` naming the material, never NaN in X.

Memory: the store is read in blocks of 145,800 cells (all three channels of
the needed materials, float32: 175 MB for 100 materials) and mapped in float64
sub-blocks of 8,192 columns; the m × p matrix is never held, and at most one
X chunk of output is buffered.  Time, peak memory and size on disk:
``docs/results/acquisition.md``.
"""

from __future__ import annotations

import hashlib

import json
import logging
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import zarr
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core.atomic import atomic_dir, check_replaceable
from brdfpipe.core.version import full_version
from brdfpipe.core.integrity import GroupDigests
from brdfpipe.core.zgroup import COMPLETE_ATTR, create_array, finish_group, format_predicate, open_sealed_group
from brdfpipe.data import merl, store
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import BrdfStore, iter_cell_blocks, material_indices, open_store

__all__ = [
    "EPS",
    "WEIGHTINGS",
    "SPLITS",
    "PRODUCT_FLOOR",
    "CHUNK_COLS",
    "LOGMAP_FORMAT",
    "COMPLETE_ATTR",
    "LogmapError",
    "Logmap",
    "is_logmap",
    "cell_weights",
    "forward",
    "inverse",
    "median_rows",
    "median_reference",
    "write_logmap",
    "open_logmap",
    "iter_columns",
]

logger = logging.getLogger("brdfpipe.data.logmap")

#: ε of the mapping (Xu et al. 2016 §3).
EPS: Final = 1e-3
#: Weightings w of a cell: ``product`` = max(cos θi·cos θo, 0.01) (Nielsen 2015 code),
#: ``max`` = max(cos θi, cos θo) (Xu 2016 text).
WEIGHTINGS: Final = ("product", "max")
#: Floor of the ``product`` weighting.
PRODUCT_FLOOR: Final = 0.01
#: Splits: ``all`` = every material is a training material; ``train`` = all minus the test materials.
SPLITS: Final = ("all", "train")
#: Columns per chunk of ``X`` (a quarter of the store's chunk width).
CHUNK_COLS: Final = store.CHUNK_COLS // 4  # 36,450
LOGMAP_FORMAT: Final = "brdfpipe.logmap/1"
#: Columns per float64 working sub-block while mapping.
_SUB_COLS: Final = 8192
#: ``replaceable`` predicate of :func:`brdfpipe.core.atomic.atomic_dir`: an earlier log-map (and nothing else).
is_logmap: Final = format_predicate((LOGMAP_FORMAT,))


class LogmapError(ValueError):
    """A log-map is missing, incomplete or inconsistent; the message names the path."""


# --------------------------------------------------------------------------
# The mapping
# --------------------------------------------------------------------------


def _check_weighting(kind: str) -> str:
    if kind not in WEIGHTINGS:
        raise ValueError(f"unknown weighting {kind!r}; expected one of {', '.join(WEIGHTINGS)}")
    return kind


def cell_weights(cells: ArrayLike, kind: str = "product") -> NDArray[np.float64]:
    """Weights w of MERL cells, shape ``(p,)`` float64, from their centre's light/view directions.

    ``cells`` are flat cell indices (0 … 1,457,999); θi and θo are the zenith
    angles of ``merl.cell_directions(cells)`` (cell centre, φh = 0).
    ``kind="product"``: ``max(cos θi · cos θo, 0.01)``; ``kind="max"``:
    ``max(cos θi, cos θo)``.  Raises ValueError for an unknown kind or a cell
    index out of range.  (For cells with both directions below the horizon
    ``max`` can be ≤ 0; such cells are never measured.)
    """
    _check_weighting(kind)
    idx = np.asarray(cells, dtype=np.int64).ravel()
    wi, wo = merl.cell_directions(idx)
    cos_i, cos_o = wi[:, 2], wo[:, 2]
    if kind == "product":
        return np.maximum(cos_i * cos_o, PRODUCT_FLOOR)
    return np.maximum(cos_i, cos_o)


def forward(rho: ArrayLike, ref: ArrayLike, w: ArrayLike, eps: float = EPS) -> NDArray[np.float64]:
    """Log-relative map ``ln((ρ·w + ε)/(ρ_ref·w + ε))`` in float64.

    ``rho`` has shape ``(..., p)`` (e.g. ``(rows, p)``); ``ref`` and ``w``
    broadcast against it (normally ``(p,)``).  Pure and vectorised.
    """
    r = np.asarray(rho, dtype=np.float64)
    ref64 = np.asarray(ref, dtype=np.float64)
    w64 = np.asarray(w, dtype=np.float64)
    return np.log((r * w64 + eps) / (ref64 * w64 + eps))


def inverse(x: ArrayLike, ref: ArrayLike, w: ArrayLike, eps: float = EPS) -> NDArray[np.float64]:
    """Inverse of :func:`forward`: ``ρ = (exp(x)·(ρ_ref·w + ε) − ε)/w`` in float64 (broadcasting)."""
    x64 = np.asarray(x, dtype=np.float64)
    ref64 = np.asarray(ref, dtype=np.float64)
    w64 = np.asarray(w, dtype=np.float64)
    return (np.exp(x64) * (ref64 * w64 + eps) - eps) / w64


# --------------------------------------------------------------------------
# Reference
# --------------------------------------------------------------------------


def _check_cells(cells: ArrayLike) -> NDArray[np.int64]:
    idx = np.asarray(cells, dtype=np.int64).ravel()
    if idx.size == 0:
        raise ValueError("no cells given")
    if idx.min() < 0 or idx.max() >= N_CELLS:
        raise ValueError(f"cell indices must lie in [0, {N_CELLS})")
    if idx.size > 1 and not (np.diff(idx) > 0).all():
        raise ValueError("cells must be strictly increasing")
    return idx


def median_rows(block: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
    """Per-column median of a ``(rows, cols)`` block, in float64; equals ``np.median(block, axis=0)``.

    Partitions a transposed float32 copy, one row of values per column, in
    sub-blocks of 8,192 columns (2× faster than ``np.median`` along axis 0);
    the middle value(s) are exact and an even count's two are averaged in
    float64.
    """
    n, ncols = block.shape
    k = n // 2
    out = np.empty(ncols, dtype=np.float64)
    for a in range(0, ncols, _SUB_COLS):
        b = min(a + _SUB_COLS, ncols)
        t = np.ascontiguousarray(block[:, a:b].T)
        if n % 2:
            out[a:b] = np.partition(t, k, axis=1)[:, k]
        else:
            part = np.partition(t, [k - 1, k], axis=1)
            out[a:b] = 0.5 * (part[:, k - 1].astype(np.float64) + part[:, k].astype(np.float64))
    return out


def median_reference(
    store: BrdfStore | str | os.PathLike[str], rows_materials: Sequence[str], cells: ArrayLike
) -> NDArray[np.float64]:
    """ρ_ref: per-cell median over all channels of ``rows_materials``, shape ``(p,)`` float64.

    ``store`` is an opened store or its path; ``cells`` strictly increasing
    flat cell indices (normally ``np.flatnonzero(store.valid)``).  The median
    is over the 3 × len(rows_materials) values of each cell (float32 data,
    median taken in float64).  Streamed by 145,800-cell blocks.  ValueError
    for unknown / duplicate / no materials or bad cells.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    idx = np.sort(material_indices(st, rows_materials, "rows_materials"))
    cells64 = _check_cells(cells)
    ref = np.empty(cells64.size, dtype=np.float64)
    for j0, j1, data in iter_cell_blocks(st, idx, cells64):
        ref[j0:j1] = median_rows(data.reshape(-1, j1 - j0))
    return ref


# --------------------------------------------------------------------------
# Writing and opening a log-map
# --------------------------------------------------------------------------


class _ChunkWriter:
    """Buffers column blocks of a 2-D array and writes whole chunks (no read-modify-write)."""

    def __init__(self, array: zarr.Array, width: int) -> None:
        self.array = array
        self.width = width
        self.buf = np.empty((array.shape[0], width), dtype=array.dtype)
        self.fill = 0
        self.offset = 0

    def write(self, block: NDArray[Any]) -> None:
        a = 0
        n = block.shape[1]
        while a < n:
            take = min(n - a, self.width - self.fill)
            self.buf[:, self.fill : self.fill + take] = block[:, a : a + take]
            self.fill += take
            a += take
            if self.fill == self.width:
                self.flush()

    def flush(self) -> None:
        if self.fill:
            self.array[:, self.offset : self.offset + self.fill] = self.buf[:, : self.fill]
            self.offset += self.fill
            self.fill = 0


def _check_split(split: str, st: BrdfStore, train: Sequence[str]) -> None:
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; expected one of {', '.join(SPLITS)}")
    if split == "all" and set(train) != set(st.materials):
        missing = [m for m in st.materials if m not in set(train)]
        raise ValueError(
            f"split 'all' trains on every material of the store, but materials_train lacks "
            f"{len(missing)}: {', '.join(missing[:5])}{' …' if len(missing) > 5 else ''}"
        )
    if split == "train" and set(train) == set(st.materials):
        raise ValueError("split 'train' must hold out at least one test material, but "
                         "materials_train lists every material of the store (use split 'all')")


def write_logmap(
    store_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    split: str,
    materials_train: Sequence[str],
    materials_out: Sequence[str] | None = None,
    weighting: str = "product",
    eps: float = EPS,
) -> None:
    """Write the log-map of ``materials_out`` (default: the training materials) to ``out``.

    ρ_ref is the median over every channel of ``materials_train``; columns are
    the store's valid cells; rows are ``3·i + c`` for material ``i`` of
    ``materials_out`` in the order given.  See the module docstring for the
    format.  Raises ValueError (before writing anything) for an unknown
    ``split`` or ``weighting``, an empty training set, unknown or duplicate
    materials, a training set inconsistent with ``split``, ε ≤ 0, or an
    ``out`` that exists and is not a log-map (a store or any other folder is
    never replaced: :class:`brdfpipe.core.atomic.OutputError`, checked before the
    store is read); and :class:`brdfpipe.data.store.StoreError` naming the store
    and the material for a bad store, including a shard that is missing or
    does not match its digest (the store is verified when it is opened).
    Atomic (:func:`brdfpipe.core.atomic.atomic_dir`): after any error or
    interrupt an earlier log-map at ``out`` is left exactly as it was.
    """
    _check_weighting(weighting)
    if not (isinstance(eps, (int, float)) and np.isfinite(eps) and eps > 0):
        raise ValueError(f"eps must be a positive finite number, got {eps!r}")
    eps = float(eps)
    out = Path(out)
    check_replaceable(out, replaceable=is_logmap)
    st = open_store(store_path)
    train_idx = material_indices(st, materials_train, "materials_train")
    _check_split(split, st, list(materials_train))
    if materials_out is None:
        materials_out = list(materials_train)
    out_idx = material_indices(st, materials_out, "materials_out")
    train_names = [st.materials[i] for i in sorted(train_idx)]  # store order
    out_names = [st.materials[i] for i in out_idx]  # order given

    valid = np.asarray(st.valid[:], dtype=bool)
    cells = np.flatnonzero(valid).astype(np.int64)
    if cells.size == 0:
        raise ValueError(f"{st.path}: no cell is valid in every material")
    w = cell_weights(cells, weighting)
    if not (w > 0).all():
        bad = cells[~(w > 0)]
        raise ValueError(f"weighting {weighting!r} gives w <= 0 at {bad.size} valid cell(s) (first: {bad[0]})")
    m_out, p = 3 * len(out_names), int(cells.size)

    # Rows read from the store: training ∪ output materials, ascending (long runs).
    need = np.union1d(train_idx, out_idx).astype(np.intp)
    pos = {int(r): k for k, r in enumerate(need)}
    train_pos = np.array([pos[int(r)] for r in sorted(train_idx)], dtype=np.intp)
    out_pos = np.array([pos[int(r)] for r in out_idx], dtype=np.intp)

    logger.info("log-mapping %d rows x %d cells of %s (train: %d materials, split %s, weighting %s) -> %s",
                m_out, p, st.path, len(train_names), split, weighting, out)
    with atomic_dir(out, replaceable=is_logmap) as tmp:
        group = zarr.open_group(tmp, mode="w-", zarr_format=3)
        x_arr = create_array(group, "X", (m_out, p), (m_out, CHUNK_COLS), "float32", ("row", "column"))
        writer = _ChunkWriter(x_arr, CHUNK_COLS)
        ref = np.empty(p, dtype=np.float64)
        for j0, j1, data in iter_cell_blocks(st, need, cells):
            for a in range(0, j1 - j0, _SUB_COLS):
                b = min(a + _SUB_COLS, j1 - j0)
                sub = data[:, :, a:b]
                r = median_rows(sub[train_pos].reshape(-1, b - a))
                ref[j0 + a : j0 + b] = r
                x = forward(sub[out_pos].reshape(m_out, b - a), r, w[j0 + a : j0 + b], eps)
                writer.write(x.astype(np.float32))
        writer.flush()
        if writer.offset != p:  # cannot happen unless the store changed underfoot
            raise LogmapError(f"{out}: wrote {writer.offset} of {p} columns")
        create_array(group, "reference", ref, (p,), "float64", ("column",))
        create_array(group, "weight", w, (p,), "float64", ("column",))
        create_array(group, "cells", cells.astype(np.int32), (p,), "int32", ("column",))
        attrs = {
            "format": LOGMAP_FORMAT,
            "split": split,
            "weighting": weighting,
            "epsilon": eps,
            "materials": out_names,
            "rows": [[name, c] for name in out_names for c in range(3)],
            "train_materials": train_names,
            "database": st.database,
            "brdfpipe_version": full_version(),
        }
        group.attrs.update(attrs)
        digest = hashlib.sha256(json.dumps([attrs, st.sources], sort_keys=True).encode())
        digest.update(ref.tobytes())
        finish_group(group, tmp, {"rows": m_out, "columns": p, "id": digest.hexdigest()[:16]})
        open_logmap(tmp)  # check what was written
    logger.info("wrote log-map %s", out)


@dataclass
class Logmap:
    """An opened, checked log-map (see :func:`open_logmap`).

    ``X`` is the lazily read Zarr array; ``reference``, ``weight`` and
    ``cells`` are loaded (p values each) and were checked against their
    digests when opened.  Read ``X`` through :meth:`read_columns` or
    :func:`iter_columns`, which check each chunk against its digest before
    the first read (a direct ``X[...]`` read is unchecked).
    """

    path: Path
    group: zarr.Group
    X: zarr.Array
    reference: NDArray[np.float64] = field(repr=False)
    weight: NDArray[np.float64] = field(repr=False)
    cells: NDArray[np.int32] = field(repr=False)
    materials: tuple[str, ...]
    rows: tuple[tuple[str, int], ...] = field(repr=False)
    train_materials: tuple[str, ...] = field(repr=False)
    split: str
    weighting: str
    epsilon: float
    database: str
    id: str
    digests: GroupDigests | None = field(default=None, repr=False, compare=False)

    @property
    def m(self) -> int:
        """Number of rows (3 × materials)."""
        return int(self.X.shape[0])

    @property
    def p(self) -> int:
        """Number of columns (cells)."""
        return int(self.X.shape[1])

    @property
    def chunk_cols(self) -> int:
        """Columns per chunk of ``X``."""
        return int(self.X.chunks[1])

    def verify_columns(self, start: int, stop: int) -> None:
        """Check the chunks of ``X`` holding columns ``start:stop`` against their digests (once per handle).

        :class:`LogmapError` naming the log-map, the chunk file and what to rerun.
        """
        if self.digests is None or stop <= start:
            return
        w = self.chunk_cols
        self.digests.verify_chunks(self.X, "X", [(0, j) for j in range(start // w, (stop - 1) // w + 1)])

    def read_columns(self, start: int, stop: int) -> NDArray[np.float32]:
        """``X[:, start:stop]`` (float32), its chunks checked against their digests first."""
        self.verify_columns(start, stop)
        return np.asarray(self.X[:, start:stop], dtype=np.float32)


def open_logmap(path: str | os.PathLike[str]) -> Logmap:
    """Open a finished log-map after checking it; :class:`LogmapError` naming ``path`` if not.

    Refuses a missing or unreadable group, one without the completion marker
    (never finished), of another format, or whose arrays and attributes
    disagree (shapes, dtypes, rows vs materials, split / weighting / ε values,
    cells not strictly increasing, weights not positive), and one whose
    integrity record (:mod:`brdfpipe.core.integrity`) does not match: the
    attributes, files missing, extra or resized, the array metadata and the
    chunks of ``reference``, ``weight`` and ``cells`` (read here).  The
    chunks of ``X`` are checked as they are read (:meth:`Logmap.read_columns`,
    :func:`iter_columns`): a job reading a quarter of the columns checks a
    quarter of the chunks.
    """
    path = Path(path)
    group, attrs, digests = open_sealed_group(
        path, fmt=LOGMAP_FORMAT, what="log-map", kind="brdfpipe log-map", error=LogmapError
    )
    for name in ("reference", "weight", "cells"):
        digests.verify_array(name)
    marker = attrs[COMPLETE_ATTR]
    arrays: dict[str, zarr.Array] = {}
    for name, dtype, ndim in (("X", np.float32, 2), ("reference", np.float64, 1),
                              ("weight", np.float64, 1), ("cells", np.int32, 1)):
        arr = group.get(name)
        if not isinstance(arr, zarr.Array):
            raise LogmapError(f"{path}: log-map lacks array {name!r}")
        if arr.dtype != dtype or arr.ndim != ndim:
            raise LogmapError(f"{path}: {name!r} is {arr.dtype} {arr.shape}, expected {np.dtype(dtype)} {ndim}-D")
        arrays[name] = arr
    m, p = arrays["X"].shape
    if marker.get("rows") != m or marker.get("columns") != p or not isinstance(marker.get("id"), str):
        raise LogmapError(f"{path}: completion marker {marker} disagrees with X {arrays['X'].shape}")
    for name in ("reference", "weight", "cells"):
        if arrays[name].shape != (p,):
            raise LogmapError(f"{path}: {name!r} has shape {arrays[name].shape}, expected ({p},)")
    materials = attrs.get("materials")
    rows = attrs.get("rows")
    train = attrs.get("train_materials")
    if not isinstance(materials, list) or not materials or 3 * len(materials) != m:
        raise LogmapError(f"{path}: attribute 'materials' does not match the {m} rows of X")
    if rows != [[name, c] for name in materials for c in range(3)]:
        raise LogmapError(f"{path}: attribute 'rows' is not [material, channel] for 3·i + c")
    if not isinstance(train, list) or not train:
        raise LogmapError(f"{path}: attribute 'train_materials' must be a non-empty list")
    if attrs.get("split") not in SPLITS or attrs.get("weighting") not in WEIGHTINGS:
        raise LogmapError(f"{path}: bad split {attrs.get('split')!r} or weighting {attrs.get('weighting')!r}")
    eps = attrs.get("epsilon")
    if not isinstance(eps, (int, float)) or not eps > 0:
        raise LogmapError(f"{path}: bad epsilon {eps!r}")
    cells = np.asarray(arrays["cells"][:], dtype=np.int32)
    if p and (cells.min() < 0 or cells.max() >= N_CELLS or (p > 1 and not (np.diff(cells) > 0).all())):
        raise LogmapError(f"{path}: 'cells' must be strictly increasing cell indices in [0, {N_CELLS})")
    weight = np.asarray(arrays["weight"][:], dtype=np.float64)
    if not (weight > 0).all():
        raise LogmapError(f"{path}: 'weight' must be positive")
    return Logmap(
        path=path,
        group=group,
        X=arrays["X"],
        reference=np.asarray(arrays["reference"][:], dtype=np.float64),
        weight=weight,
        cells=cells,
        materials=tuple(materials),
        rows=tuple((str(a), int(c)) for a, c in rows),
        train_materials=tuple(train),
        split=str(attrs["split"]),
        weighting=str(attrs["weighting"]),
        epsilon=float(eps),
        database=str(attrs.get("database")),
        id=str(marker["id"]),
        digests=digests,
    )


def iter_columns(
    logmap: Logmap | str | os.PathLike[str], start: int = 0, stop: int | None = None
) -> Iterator[tuple[int, int, NDArray[np.float32]]]:
    """Yield ``(a, b, X[:, a:b])`` (float32) over columns ``start:stop`` of a log-map.

    Blocks are cut at chunk boundaries, so each is at most one chunk wide and
    every chunk is decoded once, after it is checked against its digest.
    """
    lm = logmap if isinstance(logmap, Logmap) else open_logmap(logmap)
    stop = lm.p if stop is None else int(stop)
    if not 0 <= start <= stop <= lm.p:
        raise ValueError(f"column range [{start}, {stop}) outside [0, {lm.p}]")
    width = lm.chunk_cols
    a = start
    while a < stop:
        b = min((a // width + 1) * width, stop)
        yield a, b, lm.read_columns(a, b)
        a = b
