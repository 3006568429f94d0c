"""The chunked Zarr store of the materials × cells BRDF matrix (``results/merl.zarr``).

Layout
------
A Zarr v3 group holding

* ``brdf`` – float32, shape ``(n_materials, 4_374_000)``, dimensions
  ``("material", "column")``.  Row *i* is material ``attrs["materials"][i]``;
  its columns are the red, green and blue blocks of 1,458,000 cells each in
  MERL file order, i.e. exactly ``merl.read_merl(path).reshape(-1)`` cast to
  float32 (physical units, sr⁻¹; unmeasured cells stay negative).  Column
  ``k`` is channel ``k // N_CELLS`` of cell ``k % N_CELLS``, and the cell index
  is ``iθh·16200 + iθd·180 + iφd``.  Fill value NaN, so a missing chunk can
  never pass for data.
* ``valid`` – bool ``(1_458_000,)``: the cell is measured (≥ 0 in all three
  channels, judged on the float64 source values) in *every* material.

Group attributes: ``format`` (``"brdfpipe.data.merl-store/3"``), ``materials``
(row order), ``database`` (the label of every row's source file:
``"merl"`` for unmarked measurements, ``"synthetic"``, ``"derived"``, or the
name of a database of fits such as ``"merl-nbrdf"``, see
:mod:`brdfpipe.data.provenance`), ``sources``
(sha256 of each source file, by material name), ``source_files`` (file
names, by material name), ``channel_scales``, ``layout`` (human-readable
description), ``digests`` (see below), ``brdfpipe_version`` and, written
last, the completion marker ``brdfpipe_complete``.  Format ``/1`` stores
(digests not bound to names, no ``valid`` digest) and ``/2`` stores (no
digest of the attributes) are refused with a message to re-ingest; an ingest
may replace them.

Integrity (verification on read)
--------------------------------
``digests`` = ``{"algorithm": "crc32c(utf8(name) NUL shard file)", "shards":
[...], "shard_nbytes": [...], "valid": ..., "attributes": "sha256:…"}``:
for row *i* the CRC-32C of ``materials[i]`` (UTF-8), a NUL byte and the
bytes of its shard file (:func:`shard_digest`), and the shard's size; for
``valid`` the CRC-32C of its chunk file; for the attributes the digest of
every other group attribute (``database``, ``materials``, ``sources``,
``source_files``, ``channel_scales``, ``layout``, ``format``,
``brdfpipe_version``; :func:`brdfpipe.core.integrity.attributes_digest`),
checked on every open, so a store relabelled ``merl`` by hand, or whose
sources were edited, is refused.  Binding the digest to the name means that
swapped names (or swapped shard files) fail verification naming the
material, not only flipped bits.

Every :func:`open_store` checks the metadata, the presence and size of every
shard file (a deleted shard can never read back as the NaN fill value) and
the ``valid`` chunk against its digest (decoded here: a damaged chunk is a
:class:`StoreError`, never a Zarr / Blosc traceback).  By default it also
*verifies*: it reads every shard file (2 threads) and checks its digest, so
every library consumer (log-map, Gram matrix, GPLVM tables, manifold,
reconstruction, ``brdfpipe info --verify``) fails with a :class:`StoreError`
naming the store and the material before it uses a damaged, missing or
mislabelled row.  Verifying on open (rather than per chunk) was chosen
because it is simple, covers consumers that read ``brdf`` directly, and is
cheap next to any stage that reads the data (``benches/bench_verify.py``;
measured: ``docs/results/data.md``).
Only callers that name ``verify=False`` skip the read (today ``brdfpipe
info`` without ``--verify``; the assembly's final check, which has just
computed the digests from the bytes it placed, opens it without it); the
readers of this module (:func:`iter_column_blocks`, :func:`iter_cell_blocks`)
still verify each row they read on such a handle
(:meth:`BrdfStore.verify`).  A file changed after it was verified is not
detected (the check is at open, not per chunk).

Chunks and codec (measured with ``benches/bench_codecs.py``)
------------------------------------------------------------
Chunks are 1 row × 145,800 columns (583 kB raw float32 = 9 θh rows of one
channel, so no chunk straddles two channels; 30 chunks per row), compressed
with Blosc lz4, clevel 5, byte shuffle (typesize 4), single-threaded.  The 30
chunks of a row are stored in one shard file (Zarr v3 ``sharding_indexed``,
shard = one whole row), so a material is one file (~8–10 MB) instead of 30:
each file created has a fixed cost, which would otherwise be paid 3,000
times in the per-material jobs and again 3,000 times in the assembly copy,
and a cluster file system prefers few files.  Reads still fetch single
145,800-column chunks (byte ranges of the shard).

The codec compresses fast enough that the ingest's cost stays the sha256 of
the sources it must compute anyway; the chunk width is chosen for access:
145,800-column blocks of 100 materials (58 MB) are a convenient unit for
Gram matrices, and no chunk straddles two channels.  The codec table and
the measurements behind both choices: ``docs/results/data.md``.

Writing a store — one row store per material, their assembly, the checks at
ingest — is :mod:`brdfpipe.data.ingest`'s; after a power cut,
:func:`open_store` re-checks every shard against its digest.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import google_crc32c
import numpy as np
import zarr
from numcodecs import Blosc
from numpy.typing import NDArray

from brdfpipe.core.integrity import attributes_digest
from brdfpipe.core.threads import run_threads
from brdfpipe.core.zgroup import COMPLETE_ATTR, format_predicate, open_finished_group
from brdfpipe.data import provenance
from brdfpipe.data.merl import N_CELLS, SCALES

__all__ = [
    "read_ahead",
    "N_COLS",
    "CHUNK_COLS",
    "MASK_CODEC",
    "COMPLETE_ATTR",
    "DATABASES",
    "STORE_FORMAT",
    "RETIRED_STORE_FORMATS",
    "DIGEST_ALGORITHM",
    "VERIFY_THREADS",
    "StoreError",
    "BrdfStore",
    "blosc_codec",
    "shard_key",
    "completion_marker",
    "open_store",
    "is_store",
    "shard_digest",
    "material_indices",
    "row_runs",
    "iter_column_blocks",
    "iter_cell_blocks",
]

#: Columns of the matrix: the R, G, B blocks of all cells.
N_COLS: Final = 3 * N_CELLS  # 4,374,000
#: Columns per chunk (9 θh rows of one channel; divides N_CELLS).
CHUNK_COLS: Final = 145_800
#: Blosc configuration of the ``valid`` mask (and of a row store's ``measured`` mask).
MASK_CODEC: Final[Mapping[str, Any]] = {
    "cname": "lz4",
    "clevel": 5,
    "shuffle": "bitshuffle",
    "typesize": 1,
    "blocksize": 0,
}
_SHUFFLE: Final = {"noshuffle": Blosc.NOSHUFFLE, "shuffle": Blosc.SHUFFLE, "bitshuffle": Blosc.BITSHUFFLE}
#: Allowed values of the ``database`` attribute (:func:`brdfpipe.data.provenance.database_labels`).
DATABASES: Final = provenance.database_labels()
#: ``format`` attribute of a store.  /2: shard digests bound to the material names, ``valid`` digest;
#: /3: and a digest of the attributes (``database``, ``materials``, ``sources``, …).
STORE_FORMAT: Final = "brdfpipe.data.merl-store/3"
#: Earlier store formats: recognised (an ingest may replace them) but refused by :func:`open_store`.
RETIRED_STORE_FORMATS: Final = {
    "brdfpipe.data.merl-store/1": "its shard digests do not cover the material names; re-ingest the store",
    "brdfpipe.data.merl-store/2": "no digest covers its 'database', 'materials' and 'sources' attributes; "
                                  "re-ingest the store",
}
#: Algorithm of the ``digests`` attribute (recorded in it, checked on open).
DIGEST_ALGORITHM: Final = "crc32c(utf8(name) NUL shard file)"
#: Threads that read and check shards in :func:`open_store`.
VERIFY_THREADS: Final = 2

assert N_CELLS % CHUNK_COLS == 0


class StoreError(ValueError):
    """A store (or row store) is missing, incomplete or inconsistent; names the path."""


# --------------------------------------------------------------------------
# Metadata, paths and file helpers
# --------------------------------------------------------------------------


def blosc_codec(config: Mapping[str, Any]) -> Blosc:
    """The numcodecs Blosc codec Zarr builds for a v3 ``blosc`` configuration."""
    return Blosc(
        cname=config["cname"],
        clevel=config["clevel"],
        shuffle=_SHUFFLE[config["shuffle"]],
        blocksize=config["blocksize"],
        typesize=config["typesize"],
    )


def shard_key(row: int) -> str:
    """Key of row ``row``'s shard (default chunk key encoding, ``/`` separator)."""
    return f"c/{row}/0"


#: ``replaceable`` predicate of :func:`brdfpipe.core.atomic.atomic_dir` for a store (any version).
is_store: Final[Callable[[Path], bool]] = format_predicate((STORE_FORMAT, *RETIRED_STORE_FORMATS))


def shard_digest(name: str, data: bytes | bytearray | memoryview) -> int:
    """The digest recorded for a row: CRC-32C of ``utf8(name) + b"\\0" + data`` (the shard file's bytes).

    Binding the digest to the material name makes a store whose names were
    swapped (or whose shard files were swapped) fail verification.
    """
    return google_crc32c.extend(google_crc32c.value(name.encode("utf-8") + b"\0"), data)


def _read_file(path: Path) -> bytes:
    with open(path, "rb") as fh:
        return fh.read()


def completion_marker(n_rows: int) -> dict[str, Any]:
    """The completion marker (attribute :data:`COMPLETE_ATTR`) of a finished store of ``n_rows`` rows."""
    return {"format": STORE_FORMAT, "n_materials": n_rows}


# --------------------------------------------------------------------------
# Opening and validation
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class BrdfStore:
    """An opened, checked store (see :func:`open_store`).

    ``valid`` is the decoded mask (a read-only numpy array, checked against
    its digest when the store was opened).  ``digests`` / ``shard_nbytes``
    are the recorded digest (:func:`shard_digest`) and size of each row's
    shard file.  :meth:`verify` checks shard files against them; the readers
    of this module (:func:`iter_column_blocks`, :func:`iter_cell_blocks`)
    verify the rows they read first, once per opened store.
    """

    path: Path
    group: zarr.Group
    brdf: zarr.Array
    valid: NDArray[np.bool_] = field(repr=False)
    materials: tuple[str, ...]
    database: str
    sources: dict[str, str] = field(repr=False)
    digests: tuple[int, ...] = field(repr=False, default=())
    shard_nbytes: tuple[int, ...] = field(repr=False, default=())
    _verified: set[int] = field(init=False, repr=False, compare=False, default_factory=set)
    _lock: threading.Lock = field(init=False, repr=False, compare=False, default_factory=threading.Lock)

    @property
    def n_materials(self) -> int:
        """Number of rows."""
        return len(self.materials)

    @property
    def chunk_cols(self) -> int:
        """Columns per (inner) chunk of ``brdf``."""
        return int(self.brdf.chunks[1])

    def shard_path(self, row: int) -> Path:
        """The shard file of row ``row``."""
        return self.path / "brdf" / shard_key(row)

    def verify(self, rows: Iterable[int] | None = None, *, threads: int = VERIFY_THREADS) -> None:
        """Check the shard files of ``rows`` (default: all) against their recorded digests.

        Reads each file once (``threads`` threads; CRC-32C releases the GIL)
        and raises :class:`StoreError` naming the store and the material for
        a missing, resized or corrupt shard (also: names or shards swapped,
        as the digest covers the name).  Rows already checked on this handle
        are skipped.
        """
        want = range(self.n_materials) if rows is None else rows
        with self._lock:
            todo = sorted({int(r) for r in want} - self._verified)
        if not todo:
            return

        def check_row(i: int) -> None:
            name = self.materials[i]
            try:
                data = _read_file(self.shard_path(i))
            except FileNotFoundError:
                raise StoreError(
                    f"{self.path}: shard of material {name!r} (row {i}) is missing; re-ingest the store"
                ) from None
            if len(data) != self.shard_nbytes[i] or shard_digest(name, data) != self.digests[i]:
                raise StoreError(
                    f"{self.path}: shard of material {name!r} (row {i}) is corrupt: it does not match the "
                    "digest recorded for this material (damaged file, or names / shards swapped); "
                    "re-ingest the store"
                )
            with self._lock:
                self._verified.add(i)

        run_threads(check_row, todo, threads)


def _attr_int_list(path: Path, value: Any, n: int, what: str) -> tuple[int, ...]:
    if not isinstance(value, list) or len(value) != n or not all(isinstance(v, int) and v >= 0 for v in value):
        raise StoreError(f"{path}: attribute 'digests' must give {n} non-negative integers as {what!r}")
    return tuple(value)


def _read_valid(path: Path, digest: Any) -> NDArray[np.bool_]:
    """Decode the ``valid`` chunk after checking its file against ``digest``; StoreError otherwise."""
    chunk = path / "valid" / "c" / "0"
    try:
        data = _read_file(chunk)
    except FileNotFoundError:
        raise StoreError(f"{path}: the 'valid' mask's chunk {chunk.relative_to(path)} is missing; "
                         "re-ingest the store") from None
    if not isinstance(digest, int) or google_crc32c.value(data) != digest:
        raise StoreError(f"{path}: the 'valid' mask is corrupt (digest mismatch); re-ingest the store")
    try:
        mask = np.frombuffer(blosc_codec(MASK_CODEC).decode(data), dtype=np.uint8)
    except Exception as exc:  # blosc errors are not one type
        raise StoreError(f"{path}: the 'valid' mask cannot be decoded ({exc})") from exc
    if mask.size != N_CELLS or mask.max(initial=0) > 1:
        raise StoreError(f"{path}: the 'valid' mask is damaged ({mask.size} values, expected {N_CELLS} of 0/1)")
    valid = mask.view(bool).copy()
    valid.setflags(write=False)
    return valid


def _load_store(path: Path, *, need_marker: bool = True) -> BrdfStore:
    """Open and check a store's metadata, its ``valid`` mask and the presence and size of every shard.

    Raises :class:`StoreError` naming ``path`` (and the material, for a shard).
    Does not read the shards (see :meth:`BrdfStore.verify`).
    """
    group, attrs = open_finished_group(
        path, fmt=STORE_FORMAT, what="store", kind="brdfpipe MERL store", error=StoreError,
        retired=RETIRED_STORE_FORMATS, need_marker=need_marker, rerun="re-run the ingest",
    )
    try:
        brdf = group["brdf"]
        valid_arr = group["valid"]
    except KeyError as exc:
        raise StoreError(f"{path}: store lacks array {exc}") from exc
    except Exception as exc:  # a damaged array zarr.json
        raise StoreError(f"{path}: unreadable array metadata ({type(exc).__name__}: {exc})") from exc
    if not isinstance(brdf, zarr.Array) or not isinstance(valid_arr, zarr.Array):
        raise StoreError(f"{path}: 'brdf' and 'valid' must be arrays")
    if brdf.dtype != np.float32 or brdf.ndim != 2 or brdf.shape[1] != N_COLS:
        raise StoreError(f"{path}: 'brdf' is {brdf.dtype} {brdf.shape}, expected float32 (n_materials, {N_COLS})")
    if valid_arr.dtype != np.bool_ or valid_arr.shape != (N_CELLS,):
        raise StoreError(f"{path}: 'valid' is {valid_arr.dtype} {valid_arr.shape}, expected bool ({N_CELLS},)")
    materials = attrs.get("materials")
    if not isinstance(materials, list) or not all(isinstance(m, str) and m for m in materials):
        raise StoreError(f"{path}: attribute 'materials' must be a list of names")
    if len(materials) != brdf.shape[0] or not materials:
        raise StoreError(f"{path}: {len(materials)} material names for {brdf.shape[0]} rows")
    if len(set(materials)) != len(materials):
        raise StoreError(f"{path}: duplicate material names")
    sources = attrs.get("sources")
    if not isinstance(sources, dict) or set(sources) != set(materials):
        raise StoreError(f"{path}: attribute 'sources' must give a sha256 for every material")
    database = attrs.get("database")
    if database not in DATABASES:
        raise StoreError(f"{path}: attribute 'database' is {database!r}, expected one of {DATABASES}")
    scales = attrs.get("channel_scales")
    if not isinstance(scales, list) or [float(s) for s in scales] != [float(s) for s in SCALES]:
        raise StoreError(f"{path}: attribute 'channel_scales' {scales} differs from {list(SCALES)}")
    if need_marker and attrs[COMPLETE_ATTR] != completion_marker(len(materials)):
        raise StoreError(f"{path}: completion marker {attrs[COMPLETE_ATTR]} disagrees with the arrays")
    dig = attrs.get("digests")
    if not isinstance(dig, dict) or dig.get("algorithm") != DIGEST_ALGORITHM:
        raise StoreError(f"{path}: attribute 'digests' is missing or not {DIGEST_ALGORITHM!r}")
    if dig.get("attributes") != attributes_digest(attrs, ("digests", COMPLETE_ATTR)):
        raise StoreError(
            f"{path}: its attributes (database, materials, sources, ...) do not match their recorded digest "
            "(damaged or edited); re-ingest the store"
        )
    n = len(materials)
    digests = _attr_int_list(path, dig.get("shards"), n, "shards")
    nbytes = _attr_int_list(path, dig.get("shard_nbytes"), n, "shard_nbytes")
    valid = _read_valid(path, dig.get("valid"))
    st = BrdfStore(path, group, brdf, valid, tuple(materials), str(database), dict(sources), digests, nbytes)
    _check_shard_files(st)
    return st


def _check_shard_files(st: BrdfStore) -> None:
    """Every row's shard file exists with its recorded size, and nothing else is in ``brdf/c``."""
    rows_dir = st.path / "brdf" / "c"
    try:
        present = set(os.listdir(rows_dir))
    except FileNotFoundError:
        present = set()
    extra = present - {str(i) for i in range(st.n_materials)}
    if extra:
        raise StoreError(f"{st.path}: unexpected shard folders {sorted(extra)}")
    for i, name in enumerate(st.materials):
        shard = st.shard_path(i)
        try:
            size = shard.stat().st_size
            others = set(os.listdir(shard.parent)) - {shard.name}
        except FileNotFoundError:
            raise StoreError(
                f"{st.path}: shard of material {name!r} (row {i}) is missing; re-ingest the store"
            ) from None
        if size != st.shard_nbytes[i]:
            raise StoreError(
                f"{st.path}: shard of material {name!r} (row {i}) has {size} bytes, expected "
                f"{st.shard_nbytes[i]} (truncated or replaced); re-ingest the store"
            )
        if others:
            raise StoreError(f"{st.path}: unexpected files {sorted(others)} beside the shard of {name!r}")


def open_store(
    path: str | os.PathLike[str], *, verify: bool = True, threads: int = VERIFY_THREADS, need_marker: bool = True
) -> BrdfStore:
    """Open a finished store read-only after checking it.

    Always refuses, with a :class:`StoreError` naming the path (and the
    material where one is at fault), a store that is missing, of a retired
    format (re-ingest), lacks the completion marker (half-written or
    crashed), has a ``brdf`` / ``valid`` array of the wrong shape or dtype,
    attributes inconsistent with the shape (names, sources, database,
    scales, marker, digests), a missing or corrupt ``valid`` chunk (checked
    against its digest and decoded here), or a missing or resized shard file.

    ``verify=True`` (the default) also reads every shard file and checks it
    against the digest recorded at assembly, which is bound to the material
    name (:func:`shard_digest`): a flipped bit, a swapped shard or swapped
    names fail here, before any consumer uses the data.  ``verify=False``
    skips only that read; the readers of this module still verify each row
    they read first (:meth:`BrdfStore.verify`).  Direct reads of ``brdf``
    from a store opened with ``verify=False`` are unchecked.  ``need_marker=False``
    opens a store being assembled, before its completion marker is set (the
    assembly's own check, :mod:`brdfpipe.data.ingest`).
    """
    st = _load_store(Path(path), need_marker=need_marker)
    if verify:
        st.verify(threads=threads)
    return st


# --------------------------------------------------------------------------
# Reading rows and columns (the one home of it)
# --------------------------------------------------------------------------


def _as_store(store_or_path: BrdfStore | zarr.Group | str | os.PathLike[str]) -> BrdfStore:
    if isinstance(store_or_path, BrdfStore):
        return store_or_path
    if isinstance(store_or_path, zarr.Group):
        root = getattr(store_or_path.store, "root", None)
        if root is None:
            raise StoreError(f"{store_or_path.store}: only stores in a local folder can be opened")
        return open_store(Path(root))
    return open_store(store_or_path)


def material_indices(st: BrdfStore, names: Sequence[str], what: str) -> NDArray[np.intp]:
    """Row indices of the material ``names`` (in the order given); ValueError naming ``what`` for bad input.

    Refuses a bare string, an empty list, non-strings, duplicates and names
    not in the store (the message lists the store's first materials).
    """
    if isinstance(names, str):
        raise ValueError(f"{what} must be a list of material names, not the string {names!r}")
    names = list(names)
    if not names:
        raise ValueError(f"{what} is empty: at least one material is needed")
    bad = [n for n in names if not isinstance(n, str)]
    if bad:
        raise ValueError(f"{what}: material names must be strings, got {bad!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"{what}: listed more than once: {', '.join(dup)}")
    index = {m: i for i, m in enumerate(st.materials)}
    unknown = [n for n in names if n not in index]
    if unknown:
        avail = ", ".join(st.materials[:8]) + (" …" if st.n_materials > 8 else "")
        raise ValueError(
            f"{what}: unknown material(s) {', '.join(unknown)} in {st.path} "
            f"({st.n_materials} materials: {avail})"
        )
    return np.array([index[n] for n in names], dtype=np.intp)


def row_runs(rows: NDArray[np.intp]) -> list[tuple[int, int]]:
    """Runs ``(r0, r1)`` of consecutive row indices in ``rows`` (each read with one basic slice).

    Zarr's orthogonal selection is ~10x slower on sharded arrays than a few
    basic slices.
    """
    rows = np.asarray(rows, dtype=np.intp)
    if rows.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(rows) != 1) + 1
    return [(int(r[0]), int(r[-1]) + 1) for r in np.split(rows, breaks)]


def _row_selection(st: BrdfStore, rows: Any) -> NDArray[np.intp]:
    """Row indices of a selection: None (all), a slice, indices, a bool mask or material names."""
    if rows is None:
        return np.arange(st.n_materials, dtype=np.intp)
    if isinstance(rows, slice):
        return np.arange(*rows.indices(st.n_materials), dtype=np.intp)
    if isinstance(rows, (str, int, np.integer)):
        rows = [rows]
    seq = rows if isinstance(rows, np.ndarray) else list(rows)
    if isinstance(seq, list) and seq and all(isinstance(r, str) for r in seq):
        index = {m: i for i, m in enumerate(st.materials)}
        missing = [r for r in seq if r not in index]
        if missing:
            raise KeyError(f"{st.path}: no material(s) {missing}")
        return np.array([index[r] for r in seq], dtype=np.intp)
    arr = np.asarray(seq)
    if arr.dtype == np.bool_:
        if arr.shape != (st.n_materials,):
            raise ValueError(f"row mask has shape {arr.shape}, expected ({st.n_materials},)")
        return np.flatnonzero(arr)
    idx = arr.astype(np.intp).ravel()
    if idx.size and (idx.min() < -st.n_materials or idx.max() >= st.n_materials):
        raise IndexError(f"row index out of range for {st.n_materials} materials")
    return np.where(idx < 0, idx + st.n_materials, idx)


def iter_column_blocks(
    store_or_path: BrdfStore | zarr.Group | str | os.PathLike[str],
    block_cols: int | None = None,
    rows: Any = None,
) -> Iterator[tuple[int, int, NDArray[np.float32]]]:
    """Yield ``(start, stop, block)`` over the columns of ``brdf``, left to right.

    ``block`` is a float32 array of shape ``(n_rows, stop - start)``.  The
    blocks cover all 4,374,000 columns exactly once.  ``block_cols`` defaults
    to the chunk width (145,800), so blocks are aligned to chunks; multiples of
    it stay aligned (other widths work but decode some chunks twice).
    ``rows`` selects rows: None (all), a slice, integer indices, a bool mask or
    material names (in the order given).  One block is in memory at a time;
    the whole matrix never is.  The selected rows are verified against their
    digests before the first block (:meth:`BrdfStore.verify`).
    """
    st = _as_store(store_or_path)
    width = st.chunk_cols if block_cols is None else int(block_cols)
    if width <= 0:
        raise ValueError(f"block_cols must be positive, got {block_cols}")
    sel = _row_selection(st, rows)
    st.verify(sel)
    runs = row_runs(sel)
    for start in range(0, N_COLS, width):
        stop = min(start + width, N_COLS)
        block = np.empty((sel.size, stop - start), dtype=np.float32)
        k = 0
        for r0, r1 in runs:
            block[k : k + r1 - r0] = st.brdf[r0:r1, start:stop]
            k += r1 - r0
        yield start, stop, block


def iter_cell_blocks(
    st: BrdfStore, rows: NDArray[np.intp], cells: NDArray[np.int64]
) -> Iterator[tuple[int, int, NDArray[np.float32]]]:
    """Yield ``(j0, j1, data)``: cells ``cells[j0:j1]`` of store rows ``rows`` (ascending), all channels.

    ``cells`` are strictly increasing flat cell indices; ``data`` is float32
    ``(len(rows), 3, j1 - j0)``, read one chunk-aligned block of 145,800
    cells at a time (blocks without a selected cell are skipped).  The rows
    are verified against their digests before the first block.
    """
    rows = np.asarray(rows, dtype=np.intp)
    st.verify(rows)
    runs = row_runs(rows)
    n = rows.size
    for start in range(0, N_CELLS, CHUNK_COLS):
        stop = start + CHUNK_COLS
        j0, j1 = (int(v) for v in np.searchsorted(cells, [start, stop]))
        if j0 == j1:
            continue
        raw = np.empty((n, 3, stop - start), dtype=np.float32)
        for c in range(3):
            k = 0
            for r0, r1 in runs:
                raw[k : k + r1 - r0, c] = st.brdf[r0:r1, c * N_CELLS + start : c * N_CELLS + stop]
                k += r1 - r0
        local = cells[j0:j1] - start
        yield j0, j1, raw[:, :, local] if local.size < raw.shape[2] else raw


# --------------------------------------------------------------------------
# Streaming helper
# --------------------------------------------------------------------------


_READ_AHEAD_END: Final = object()


def read_ahead(items: Iterable[Any]) -> Iterator[Any]:
    """Iterate ``items`` in a background thread, one item ahead.

    Used by the streaming stages so that decoding the next block (Blosc and
    casts release the GIL) overlaps the BLAS work on the current one.  An
    exception in the producer is re-raised in the consumer; leaving the loop
    early stops the producer.
    """
    box: queue.Queue[Any] = queue.Queue(maxsize=1)
    halt = threading.Event()

    def put(item: Any) -> bool:
        while not halt.is_set():
            try:
                box.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put(item):
                    return
            put(_READ_AHEAD_END)
        except BaseException as exc:  # handed to the consumer
            put(exc)

    reader = threading.Thread(target=produce, name="brdfpipe-read-ahead", daemon=True)
    reader.start()
    try:
        while True:
            item = box.get()
            if item is _READ_AHEAD_END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        halt.set()
        reader.join()
