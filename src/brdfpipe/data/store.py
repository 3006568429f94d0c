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
computed the digests from the bytes it placed, uses the internal loader); the
readers of this module (:func:`iter_column_blocks`, :func:`iter_cell_blocks`,
:func:`iter_valid_blocks`) still verify each row they read on such a handle
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

Ingest
------
One job per material (:func:`ingest_material`) writes a one-row store with
the final array's chunking, sharding and codec; one assembly job
(:func:`assemble_store`) copies each row's compressed shard file
byte-for-byte into the final store (no decode / re-encode), checks it against
the CRC-32C recorded at ingest, ANDs the measured masks into ``valid``,
validates the whole store, sets the completion marker last and renames the
store into place.  :func:`ingest` does both with a process pool.  The
per-material reader streams the source one chunk at a time (hash, validate,
scale, cast, compress), so a worker needs ~15 MB and the sha256 is of exactly
the bytes that were ingested.  Row stores are written with plain file writes
of metadata documents generated by Zarr itself (the Zarr API's event-loop round
trips cost more per store); the tests check Zarr reads them back
exactly and that the shard bytes equal those Zarr writes.

Speed and memory of the ingest: ``benches/bench_ingest.py`` (measured:
``docs/results/data.md``).

Checks at ingest: a file without any measured cell is a
:class:`~brdfpipe.data.merl.MerlFormatError` naming it (it would empty ``valid``
for the whole store), and the assembly logs a warning naming the source file
of any material that alone leaves more than 1 % of the cells measured by all
the others unmeasured.  Provenance: each row records its file's label and
mark (:func:`brdfpipe.data.provenance.check_source`: a synthetic file must be
the material it is ingested as, and of the expected database and
configuration), and the assembly refuses a row whose label is not the
store's ``database``.

Every writer builds its output in a temporary sibling directory and swaps it
into place (:func:`brdfpipe.core.atomic.atomic_dir`): after any error or
interrupt (a bad file, Ctrl-C, a kill) an earlier store or row store at the
output is left exactly as it was.  An output that exists and is not an
output of the same kind (a folder, a Zarr group without the store's
``format`` attribute) is refused with :class:`brdfpipe.core.atomic.OutputError`
before any work.  A process killed with SIGKILL can leave a
``.NAME.tmp-PID-*`` (or ``.NAME.rows-PID-*``, the ingest's row stores)
sibling behind; the next run writing the same output removes those whose
process is gone.  After a power cut, :func:`open_store` re-checks every
shard against its digest.
"""

from __future__ import annotations

import hashlib
import json
import logging
import multiprocessing
import multiprocessing.context
import os
import queue
import re
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_EXCEPTION, Future, ProcessPoolExecutor, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Final

import google_crc32c
import numpy as np
import zarr
import zarr.storage
from numcodecs import Blosc
from numpy.typing import NDArray
from zarr.codecs import BloscCodec
from zarr.core.buffer import default_buffer_prototype
from zarr.core.group import GroupMetadata

from brdfpipe.core.atomic import atomic_dir, check_replaceable, clean_stale_siblings, remove_tree, tmp_sibling
from brdfpipe.core.integrity import attributes_digest
from brdfpipe.core.version import full_version
from brdfpipe.core.zgroup import COMPLETE_ATTR, format_predicate, open_finished_group
from brdfpipe.data import merl, provenance
from brdfpipe.data.merl import DIMS, FILE_SIZE, HEADER_BYTES, MerlFormatError, N_CELLS, SCALES

__all__ = [
    "read_ahead",
    "N_COLS",
    "CHUNK_COLS",
    "N_CHUNKS",
    "BRDF_CODEC",
    "COMPLETE_ATTR",
    "DATABASES",
    "LAYOUT",
    "STORE_FORMAT",
    "ROW_FORMAT",
    "StoreError",
    "BrdfStore",
    "ingest_material",
    "assemble_store",
    "open_store",
    "is_store",
    "shard_digest",
    "ingest",
    "material_indices",
    "row_runs",
    "iter_column_blocks",
    "iter_cell_blocks",
    "iter_valid_blocks",
]

logger = logging.getLogger("brdfpipe.data.store")

#: Columns of the matrix: the R, G, B blocks of all cells.
N_COLS: Final = 3 * N_CELLS  # 4,374,000
#: Columns per chunk (9 θh rows of one channel; divides N_CELLS).
CHUNK_COLS: Final = 145_800
#: Chunks per row (all in one shard file).
N_CHUNKS: Final = N_COLS // CHUNK_COLS  # 30
#: Blosc configuration of the ``brdf`` chunks (Zarr v3 ``blosc`` codec).
BRDF_CODEC: Final[Mapping[str, Any]] = {
    "cname": "lz4",
    "clevel": 5,
    "shuffle": "shuffle",
    "typesize": 4,
    "blocksize": 0,
}
_MASK_CODEC: Final[Mapping[str, Any]] = {
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
ROW_FORMAT: Final = "brdfpipe.data.merl-row/1"
#: Algorithm of the ``digests`` attribute (recorded in it, checked on open).
DIGEST_ALGORITHM: Final = "crc32c(utf8(name) NUL shard file)"
#: Share of the cells measured by all other materials that one file may leave unmeasured without a warning.
REMOVAL_WARN_FRACTION: Final = 0.01
#: Threads that read and check shards in :func:`open_store`.
VERIFY_THREADS: Final = 2
#: Human-readable description of the layout (the ``layout`` attribute).
LAYOUT: Final = (
    "brdf[i, k]: float32 BRDF (sr^-1, physical units; unmeasured cells negative) of "
    "material attrs['materials'][i]; column k = channel k // 1458000 (0=R, 1=G, 2=B) "
    "of cell k % 1458000 in MERL file order, cell = i_theta_h*16200 + i_theta_d*180 "
    "+ i_phi_d (90 x 90 x 180, square-root theta_h binning); row i == "
    "brdfpipe.data.merl.read_merl(file).reshape(-1).astype(float32). valid[cell]: the cell "
    "is >= 0 in all three channels of every material. Chunks 1 x 145800 columns "
    "(blosc lz4 + byte shuffle), one shard file per row."
)

assert N_CELLS % CHUNK_COLS == 0


class StoreError(ValueError):
    """A store (or row store) is missing, incomplete or inconsistent; names the path."""


# --------------------------------------------------------------------------
# Metadata, paths and file helpers
# --------------------------------------------------------------------------


def _blosc(config: Mapping[str, Any]) -> Blosc:
    """The numcodecs Blosc codec Zarr builds for a v3 ``blosc`` configuration."""
    return Blosc(
        cname=config["cname"],
        clevel=config["clevel"],
        shuffle=_SHUFFLE[config["shuffle"]],
        blocksize=config["blocksize"],
        typesize=config["typesize"],
    )


def _create_brdf_array(group: zarr.Group, n_rows: int) -> zarr.Array:
    return group.create_array(
        "brdf",
        shape=(n_rows, N_COLS),
        shards=(1, N_COLS),
        chunks=(1, CHUNK_COLS),
        dtype="float32",
        compressors=BloscCodec(**BRDF_CODEC),
        fill_value=np.nan,
        dimension_names=("material", "column"),
        config={"write_empty_chunks": True},
    )


def _create_mask_array(group: zarr.Group, name: str) -> zarr.Array:
    return group.create_array(
        name,
        shape=(N_CELLS,),
        chunks=(N_CELLS,),
        dtype="bool",
        compressors=BloscCodec(**_MASK_CODEC),
        fill_value=False,
        dimension_names=("cell",),
        config={"write_empty_chunks": True},
    )


def _doc_bytes(metadata: Any) -> bytes:
    """The ``zarr.json`` document Zarr itself writes for a metadata object."""
    return metadata.to_buffer_dict(default_buffer_prototype())["zarr.json"].to_bytes()


@lru_cache(maxsize=1)
def _row_array_docs() -> tuple[bytes, bytes]:
    """``zarr.json`` of a row store's ``brdf`` and ``measured`` arrays, made by Zarr."""
    group = zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)
    brdf = _create_brdf_array(group, 1)
    measured = _create_mask_array(group, "measured")
    return _doc_bytes(brdf.metadata), _doc_bytes(measured.metadata)


def _group_doc(attributes: dict[str, Any]) -> bytes:
    return _doc_bytes(GroupMetadata(attributes=attributes, zarr_format=3))


def _layout_signature(doc: Mapping[str, Any]) -> dict[str, Any]:
    """The parts of an array's metadata that must agree for chunk bytes to be copied."""
    keys = ("data_type", "chunk_grid", "chunk_key_encoding", "codecs", "fill_value")
    return json.loads(json.dumps({k: doc.get(k) for k in keys}))


@lru_cache(maxsize=1)
def _reference_signature() -> dict[str, Any]:
    """Layout signature of a ``brdf`` array as this version writes it."""
    return _layout_signature(json.loads(_row_array_docs()[0]))


def _shard_key(row: int) -> str:
    """Key of row ``row``'s shard (default chunk key encoding, ``/`` separator)."""
    return f"c/{row}/0"


#: ``replaceable`` predicate of :func:`brdfpipe.core.atomic.atomic_dir` for a store (any version).
is_store: Final[Callable[[Path], bool]] = format_predicate((STORE_FORMAT, *RETIRED_STORE_FORMATS))
_is_row_store: Final[Callable[[Path], bool]] = format_predicate((ROW_FORMAT,))


def shard_digest(name: str, data: bytes | bytearray | memoryview) -> int:
    """The digest recorded for a row: CRC-32C of ``utf8(name) + b"\\0" + data`` (the shard file's bytes).

    Binding the digest to the material name makes a store whose names were
    swapped (or whose shard files were swapped) fail verification.
    """
    return google_crc32c.extend(google_crc32c.value(name.encode("utf-8") + b"\0"), data)


def _write_file(path: Path, parts: Iterable[bytes | bytearray | memoryview]) -> None:
    with open(path, "wb") as fh:
        for part in parts:
            fh.write(part)


def _read_file(path: Path) -> bytes:
    with open(path, "rb") as fh:
        return fh.read()


def _read_json(path: Path) -> dict[str, Any]:
    with open(path, "rb") as fh:
        doc = json.load(fh)
    if not isinstance(doc, dict):
        raise ValueError("not a JSON object")
    return doc


def _normalise_database(database: str) -> str:
    if database not in DATABASES:
        raise ValueError(f"database must be one of {DATABASES}, got {database!r}")
    return database


# --------------------------------------------------------------------------
# Per-material ingest
# --------------------------------------------------------------------------


def _format_error(path: Path, fallback: str) -> MerlFormatError:
    """The canonical :class:`MerlFormatError` for a bad file (from ``merl``), else ``fallback``.

    The fast streaming reader only detects that something is wrong; the
    message comes from :func:`brdfpipe.data.merl.read_merl_raw`, so both readers
    report bad files identically.
    """
    try:
        merl.read_merl_raw(path)
    except MerlFormatError as exc:
        return exc
    return MerlFormatError(f"{path}: {fallback}")


def _readinto_exact(fh: Any, buf: memoryview) -> int:
    """Fill ``buf`` from ``fh`` (looping over short reads); returns bytes read."""
    got = 0
    while got < len(buf):
        n = fh.readinto(buf[got:])
        if not n:
            break
        got += n
    return got


@dataclass
class _EncodedRow:
    sha256: str
    measured: NDArray[np.bool_]
    shard_parts: list[bytes]  # the compressed chunks, then the shard index
    shard_crc32c: int
    shard_nbytes: int


def _encode_source(path: Path) -> _EncodedRow:
    """Read, validate, convert and compress one MERL file, one chunk at a time.

    Produces the bytes of the row's shard (the 30 compressed float32 chunks in
    order, then the shard index: (offset, nbytes) uint64 pairs plus their
    CRC-32C, as Zarr's ``sharding_indexed`` codec writes them), the sha256 of
    the file and its measured mask.  Raises :class:`MerlFormatError` naming
    the file.
    """
    sha = hashlib.sha256()
    encoder = _blosc(BRDF_CODEC)
    buf64 = np.empty(CHUNK_COLS, dtype="<f8")
    raw_view = memoryview(buf64).cast("B")
    buf32 = np.empty(CHUNK_COLS, dtype="<f4")
    ge0 = np.empty(CHUNK_COLS, dtype=bool)
    measured = np.ones(N_CELLS, dtype=bool)
    parts: list[bytes] = []
    index = np.empty((N_CHUNKS, 2), dtype="<u8")
    offset = 0
    with open(path, "rb", buffering=0) as fh:
        size = os.fstat(fh.fileno()).st_size
        header = fh.read(HEADER_BYTES)
        if size != FILE_SIZE or len(header) != HEADER_BYTES or tuple(np.frombuffer(header, "<i4")) != DIMS:
            raise _format_error(path, f"bad header or size ({size} bytes)")
        sha.update(header)
        for j in range(N_CHUNKS):
            if _readinto_exact(fh, raw_view) != raw_view.nbytes:
                raise _format_error(path, "file shrank while being read")
            sha.update(raw_view)
            channel, k0 = divmod(j * CHUNK_COLS, N_CELLS)
            # The same float64 product as read_merl, then the same rounding as astype.
            np.multiply(buf64, SCALES[channel], out=buf64)
            with np.errstate(over="ignore"):  # overflow is reported just below
                buf32[:] = buf64
            if not np.isfinite(buf32).all():
                if np.isfinite(buf64).all():
                    raise MerlFormatError(
                        f"{path}: value(s) beyond the float32 range in channel "
                        f"{'RGB'[channel]}, cells {k0}…{k0 + CHUNK_COLS - 1}"
                    )
                raise _format_error(path, "non-finite value(s)")
            np.greater_equal(buf64, 0.0, out=ge0)
            measured[k0 : k0 + CHUNK_COLS] &= ge0
            data = encoder.encode(buf32)
            parts.append(data)
            index[j] = (offset, len(data))
            offset += len(data)
        if fh.read(1):
            raise _format_error(path, "file grew while being read")
    if not measured.any():
        raise MerlFormatError(
            f"{path}: no measured cell (every cell is negative in at least one channel); "
            "it would leave no valid cell in the store"
        )
    index_bytes = index.tobytes()
    parts.append(index_bytes + np.array([google_crc32c.value(index_bytes)], dtype="<u4").tobytes())
    crc = 0
    for part in parts:
        crc = google_crc32c.extend(crc, part)
    return _EncodedRow(sha.hexdigest(), measured, parts, crc, offset + len(parts[-1]))


def ingest_material(
    src: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    name: str,
    expect: Mapping[str, Any] | None = None,
) -> None:
    """Convert one MERL file into a one-row Zarr v3 store at ``out``.

    The row store holds ``brdf`` (float32, shape ``(1, N_COLS)``, the final
    array's chunking, sharding and codec, so assembly copies its shard file
    as is), a bool array ``measured`` (cell ≥ 0 in all three channels) and
    attributes ``name``, ``source_file``, ``sha256`` (of the source file),
    ``shard_crc32c`` / ``shard_nbytes`` (of the shard file) and the
    completion marker.  Raises :class:`FileNotFoundError` for a missing file
    and :class:`MerlFormatError` (naming the file) for an invalid one; a value
    beyond the float32 range is also a :class:`MerlFormatError`.

    A file without any measured cell is a :class:`MerlFormatError` too.

    Provenance (:func:`brdfpipe.data.provenance.check_source`): a file whose
    mark names another material (a synthetic file copied over another), a
    damaged mark, a file whose label is not ``expect["database"]`` or whose
    mark disagrees with the other keys of ``expect`` (the workflow's
    synthetic files: ``count``, ``seed``, ``noise``) is a
    :class:`brdfpipe.data.provenance.ProvenanceError` naming the file.  The row
    records the label (``database``) and the mark (``mark``, JSON or null).

    The store is built in a temporary sibling directory and renamed into
    place (:func:`brdfpipe.core.atomic.atomic_dir`), replacing an earlier row
    store at ``out`` only on success: after any error (or an interrupt) an
    earlier row store is left exactly as it was and nothing else is left
    behind.  An ``out`` that exists and is not a row store (a folder, a
    store, another Zarr group) is refused with
    :class:`brdfpipe.core.atomic.OutputError` before the file is read.
    """
    src = Path(src)
    out = Path(out)
    if not isinstance(name, str) or not name:
        raise ValueError(f"material name must be a non-empty string, got {name!r}")
    if not src.is_file():
        raise FileNotFoundError(f"{src}: no such MERL file")
    check_replaceable(out, replaceable=_is_row_store)
    with atomic_dir(out, replaceable=_is_row_store) as tmp:
        row = _encode_source(src)
        mark = provenance.check_source(src, name=name, expect=expect)
        brdf_doc, measured_doc = _row_array_docs()
        for d in (tmp / "brdf", tmp / "brdf" / "c", tmp / "brdf" / "c" / "0", tmp / "measured", tmp / "measured" / "c"):
            os.mkdir(d)
        _write_file(tmp / "brdf" / "zarr.json", [brdf_doc])
        _write_file(tmp / "brdf" / _shard_key(0), row.shard_parts)
        _write_file(tmp / "measured" / "zarr.json", [measured_doc])
        _write_file(tmp / "measured" / "c" / "0", [_blosc(_MASK_CODEC).encode(row.measured.view(np.uint8))])
        attrs: dict[str, Any] = {
            "format": ROW_FORMAT,
            "name": name,
            "source_file": src.name,
            "sha256": row.sha256,
            "shard_crc32c": row.shard_crc32c,
            "shard_nbytes": row.shard_nbytes,
            "database": provenance.UNMARKED if mark is None else mark.kind,
            "mark": None if mark is None else mark.to_json(),
            "channel_scales": [float(s) for s in SCALES],
            "brdfpipe_version": full_version(),
            COMPLETE_ATTR: {"format": ROW_FORMAT},
        }
        _write_file(tmp / "zarr.json", [_group_doc(attrs)])  # last: carries the marker
    logger.debug(
        "ingested %s (%s) -> %s: %.1f MB, compression ratio %.2f",
        name, src, out, row.shard_nbytes / 1e6, N_COLS * 4 / row.shard_nbytes,
    )


@dataclass(frozen=True)
class _RowInfo:
    path: Path
    name: str
    sha256: str
    source_file: str
    shard_crc32c: int
    shard_nbytes: int
    database: str


def _open_row(path: Path) -> _RowInfo:
    """Read and check a row store written by :func:`ingest_material` (metadata only)."""
    if not path.is_dir():
        raise StoreError(f"{path}: row store is missing")
    try:
        group = _read_json(path / "zarr.json")
        brdf = _read_json(path / "brdf" / "zarr.json")
        measured = _read_json(path / "measured" / "zarr.json")
    except (OSError, ValueError) as exc:
        raise StoreError(f"{path}: not a readable brdfpipe row store ({exc})") from exc
    attrs = group.get("attributes", {})
    if group.get("zarr_format") != 3 or group.get("node_type") != "group" or not isinstance(attrs, dict):
        raise StoreError(f"{path}: not a Zarr v3 group")
    if COMPLETE_ATTR not in attrs:
        raise StoreError(f"{path}: row store is incomplete (no completion marker); re-run its ingest")
    if attrs.get("format") != ROW_FORMAT:
        raise StoreError(f"{path}: not a brdfpipe row store (format {attrs.get('format')!r}, expected {ROW_FORMAT!r})")
    if brdf.get("shape") != [1, N_COLS]:
        raise StoreError(f"{path}: 'brdf' has shape {brdf.get('shape')}, expected [1, {N_COLS}]")
    sig = _layout_signature(brdf)
    if sig != _reference_signature():
        raise StoreError(
            f"{path}: row layout (chunks/codec/dtype) {sig} does not match this version's {_reference_signature()}"
        )
    if {k: v for k, v in measured.items() if k != "attributes"} != {
        k: v for k, v in json.loads(_row_array_docs()[1]).items() if k != "attributes"
    }:
        raise StoreError(f"{path}: 'measured' array has unexpected metadata")
    name, sha = attrs.get("name"), attrs.get("sha256")
    crc, nbytes = attrs.get("shard_crc32c"), attrs.get("shard_nbytes")
    if not isinstance(name, str) or not name or not isinstance(sha, str) or len(sha) != 64:
        raise StoreError(f"{path}: row store lacks a valid name / sha256 attribute")
    if not isinstance(crc, int) or not isinstance(nbytes, int):
        raise StoreError(f"{path}: row store lacks its shard digest")
    if [float(s) for s in attrs.get("channel_scales", [])] != [float(s) for s in SCALES]:
        raise StoreError(f"{path}: channel_scales {attrs.get('channel_scales')} differ from {list(SCALES)}")
    label = attrs.get("database")
    if label not in DATABASES:
        raise StoreError(f"{path}: row store lacks its source file's database label (got {label!r}); re-run its ingest")
    return _RowInfo(path, name, sha, str(attrs.get("source_file", "")), crc, nbytes, label)


def _read_measured(info: _RowInfo) -> NDArray[np.bool_]:
    try:
        data = _blosc(_MASK_CODEC).decode(_read_file(info.path / "measured" / "c" / "0"))
    except Exception as exc:
        raise StoreError(f"{info.path}: cannot read the 'measured' mask ({exc})") from exc
    mask = np.frombuffer(data, dtype=np.uint8)
    if mask.size != N_CELLS or mask.max(initial=0) > 1:
        raise StoreError(f"{info.path}: 'measured' mask is damaged")
    return mask.view(bool)


# --------------------------------------------------------------------------
# Assembly
# --------------------------------------------------------------------------


def _run_threads(fn: Callable[[int], None], items: Iterable[int], threads: int) -> None:
    """Run ``fn(item)`` for all items on up to ``threads`` threads; re-raise the first error."""
    items = list(items)
    if threads <= 1 or len(items) <= 1:
        for it in items:
            fn(it)
        return
    with ThreadPoolExecutor(max_workers=threads) as ex:
        futures = [ex.submit(fn, it) for it in items]
        wait(futures, return_when=FIRST_EXCEPTION)
        for f in futures:
            f.cancel()
        for f in futures:
            if not f.cancelled():
                f.result()  # re-raises the first error in submission order


def assemble_store(
    rows: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    database: str,
    threads: int = 2,
    link: bool = False,
) -> None:
    """Assemble per-material row stores (in row order) into the final store at ``out``.

    Each row's compressed shard file is copied byte-for-byte (never decoded)
    and checked against the CRC-32C recorded when the row was ingested; its
    store digest (:func:`shard_digest`, bound to the material name) is
    computed from the same bytes.  ``valid`` is the AND of the rows' ``measured``
    masks; a row that alone leaves more than 1 % of the cells measured by all
    the other rows unmeasured is logged as a warning naming its source file.
    The finished store is then validated as a whole (shape, dtype, layout,
    every shard present with its size, row order = names, attributes, the
    ``valid`` digest), the completion marker is written last, and the store
    is swapped into place (:func:`brdfpipe.core.atomic.atomic_dir`).

    Raises :class:`StoreError` naming the offending row store for a missing,
    incomplete or damaged row, duplicate names, a mismatched layout or a row
    whose source file's label (recorded at ingest) is not ``database``,
    :class:`ValueError` for an unknown ``database`` and
    :class:`brdfpipe.core.atomic.OutputError` (before reading any row) for an
    ``out`` that exists and is not a brdfpipe store.  After any error (or an
    interrupt) an earlier store at ``out`` is left exactly as it was.
    ``threads`` threads copy rows concurrently.

    ``link=True`` hard-links the shard files instead of copying them (falling
    back to a copy across file systems): no data is written, and the store
    shares the immutable shard files with the row stores (which are only ever
    replaced by rename, never modified in place).  :func:`ingest` uses it for
    its private, temporary row stores.  The digests are checked either way.
    """
    out = Path(out)
    database = _normalise_database(database)
    check_replaceable(out, replaceable=is_store)
    row_paths = [Path(r) for r in rows]
    if not row_paths:
        raise StoreError(f"{out}: no row stores to assemble")
    infos = [_open_row(p) for p in row_paths]
    _check_row_set(infos, database)
    names = [info.name for info in infos]
    n = len(infos)
    logger.info("assembling %d rows into %s", n, out)
    with atomic_dir(out, replaceable=is_store) as tmp:
        group = zarr.open_group(tmp, mode="w-", zarr_format=3)
        _create_brdf_array(group, n)
        valid_arr = _create_mask_array(group, "valid")
        digests, missing, missing_count = _place_rows(infos, tmp, link=link, threads=threads)
        valid = missing_count == 0
        _warn_removals(infos, missing, missing_count)
        valid_arr[:] = valid
        group.attrs.update(_store_attributes(tmp, infos, database, digests))
        _validate_store(tmp, names=names, sources={i.name: i.sha256 for i in infos}, valid=valid)
        group.attrs[COMPLETE_ATTR] = _marker(n)  # last
        _load_store(tmp)
    logger.info("assembled %s: %d materials, %d valid cells", out, n, int(valid.sum()))


def _check_row_set(infos: Sequence[_RowInfo], database: str) -> None:
    """Refuse duplicate material names, then any row whose source file is not labelled ``database``."""
    seen: dict[str, int] = {}
    for k, info in enumerate(infos):
        if info.name in seen:
            j = seen[info.name]
            raise StoreError(
                f"{info.path}: duplicate material name {info.name!r} (row {k}; also row {j}, {infos[j].path})"
            )
        seen[info.name] = k
    for info in infos:
        if info.database != database:
            raise StoreError(
                f"{info.path}: material {info.name!r} was ingested from {info.source_file or 'a file'} labelled "
                f"{info.database!r} (its provenance mark), but the store is assembled as the {database!r} database; "
                "one kind per store: re-plan the run or replace the file"
            )


def _place_shard(info: _RowInfo, dst: Path, link: bool) -> bytes:
    """Link (``link``; else, or across file systems, copy) a row's shard file to ``dst``; its checked bytes."""
    src = info.path / "brdf" / _shard_key(0)
    os.mkdir(dst.parent)
    linked = False
    if link:
        try:
            os.link(src, dst)
            linked = True
        except FileNotFoundError:
            raise StoreError(f"{info.path}: shard file of row {info.name!r} is missing") from None
        except OSError:
            pass  # another file system, or no hard links there: copy
    try:
        data = _read_file(dst if linked else src)
    except FileNotFoundError:
        raise StoreError(f"{info.path}: shard file of row {info.name!r} is missing") from None
    if len(data) != info.shard_nbytes or google_crc32c.value(data) != info.shard_crc32c:
        raise StoreError(
            f"{info.path}: shard of row {info.name!r} does not match the digest recorded at "
            "ingest (row store damaged); re-run its ingest"
        )
    if not linked:
        _write_file(dst, [data])
    return data


def _place_rows(
    infos: Sequence[_RowInfo], tmp: Path, *, link: bool, threads: int
) -> tuple[list[int], list[NDArray[np.uint8]], NDArray[np.unsignedinteger[Any]]]:
    """Place every row's shard in the store being built at ``tmp`` (on ``threads`` threads).

    Returns the rows' store digests (:func:`shard_digest`), their packed "not
    measured" masks and, per cell, the number of rows that do not measure it.
    """
    n = len(infos)
    digests = [0] * n
    missing = [np.empty(0, dtype=np.uint8)] * n  # packed "not measured" masks, one per row
    missing_count = np.zeros(N_CELLS, dtype=np.uint16 if n < 65_535 else np.uint32)
    lock = threading.Lock()

    def place_row(i: int) -> None:
        info = infos[i]
        data = _place_shard(info, tmp / "brdf" / _shard_key(i), link)
        digests[i] = shard_digest(info.name, data)
        miss = ~_read_measured(info)
        missing[i] = np.packbits(miss)
        with lock:
            missing_count[miss] += 1

    os.makedirs(tmp / "brdf" / "c")
    _run_threads(place_row, range(n), threads)
    return digests, missing, missing_count


def _store_attributes(tmp: Path, infos: Sequence[_RowInfo], database: str, digests: list[int]) -> dict[str, Any]:
    """The finished store's attributes, its digests included (the ``valid`` chunk read back from ``tmp``)."""
    attrs: dict[str, Any] = {
        "format": STORE_FORMAT,
        "materials": [info.name for info in infos],
        "database": database,
        "sources": {info.name: info.sha256 for info in infos},
        "source_files": {info.name: info.source_file for info in infos},
        "channel_scales": [float(s) for s in SCALES],
        "layout": LAYOUT,
        "brdfpipe_version": full_version(),
    }
    attrs["digests"] = {
        "algorithm": DIGEST_ALGORITHM,
        "shards": digests,
        "shard_nbytes": [info.shard_nbytes for info in infos],
        "valid": google_crc32c.value(_read_file(tmp / "valid" / "c" / "0")),
        "attributes": attributes_digest(attrs),
    }
    return attrs


def _warn_removals(
    infos: Sequence[_RowInfo], missing: Sequence[NDArray[np.uint8]], missing_count: NDArray[np.unsignedinteger[Any]]
) -> None:
    """Warn about each row that alone removes > 1 % of the cells all other rows measured.

    For row i, the cells measured by every other row are those missed by no
    row, plus those missed by row i only; the latter are what row i removes
    from ``valid``.  Works on packed bit masks (a few ms for 100 rows).
    """
    if len(infos) < 2:
        return
    only = np.packbits(missing_count == 1)
    n_all = int(np.count_nonzero(missing_count == 0))
    for info, miss in zip(infos, missing):
        removed = int(np.bitwise_count(only & miss).sum())
        others = n_all + removed
        if others and removed > REMOVAL_WARN_FRACTION * others:
            logger.warning(
                "%s: material %r leaves %d of the %d cells measured by all other materials unmeasured "
                "(%.1f%%); they are dropped from 'valid' for the whole store",
                info.source_file or info.path, info.name, removed, others, 100.0 * removed / others,
            )


def _marker(n_rows: int) -> dict[str, Any]:
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
    of this module (:func:`iter_column_blocks`, :func:`iter_cell_blocks`,
    :func:`iter_valid_blocks`) verify the rows they read first, once per
    opened store.
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

    @property
    def verified(self) -> bool:
        """Whether every row's shard has been checked against its digest."""
        return len(self._verified) == self.n_materials

    def shard_path(self, row: int) -> Path:
        """The shard file of row ``row``."""
        return self.path / "brdf" / _shard_key(row)

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

        _run_threads(check_row, todo, threads)


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
        mask = np.frombuffer(_blosc(_MASK_CODEC).decode(data), dtype=np.uint8)
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
    if need_marker and attrs[COMPLETE_ATTR] != _marker(len(materials)):
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


def _validate_store(path: Path, *, names: Sequence[str], sources: Mapping[str, str], valid: NDArray[np.bool_]) -> None:
    """Check a store being assembled (before its marker) against what was assembled into it."""
    st = _load_store(path, need_marker=False)
    if list(st.materials) != list(names):
        raise StoreError(f"{path}: row order {st.materials} differs from {list(names)}")
    if st.sources != dict(sources):
        raise StoreError(f"{path}: 'sources' attribute differs from the row stores' sha256")
    if _layout_signature(st.brdf.metadata.to_dict()) != _reference_signature():
        raise StoreError(f"{path}: 'brdf' layout differs from this version's")
    if not np.array_equal(st.valid, valid):
        raise StoreError(f"{path}: 'valid' does not read back as written")
    # Decode the first values of every row through Zarr: proves the copied bytes are readable.
    head = np.asarray(st.brdf[:, :16])
    if not np.isfinite(head).all():
        raise StoreError(f"{path}: rows do not decode to finite values")


def open_store(
    path: str | os.PathLike[str], *, verify: bool = True, threads: int = VERIFY_THREADS
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
    from a store opened with ``verify=False`` are unchecked.
    """
    st = _load_store(Path(path))
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


def iter_valid_blocks(
    store_or_path: BrdfStore | zarr.Group | str | os.PathLike[str],
    block_cols: int | None = None,
    rows: Any = None,
) -> Iterator[tuple[NDArray[np.int64], NDArray[np.float32]]]:
    """Like :func:`iter_column_blocks`, restricted to the columns of valid cells.

    Yields ``(columns, block)``: the column indices (int64, ascending) whose
    cell is valid in every material, and the float32 block of those columns,
    shape ``(n_rows, len(columns))``.  Blocks without any valid column are
    skipped.  Every yielded value is ≥ 0.
    """
    st = _as_store(store_or_path)
    valid = np.asarray(st.valid, dtype=bool)
    for start, stop, block in iter_column_blocks(st, block_cols, rows):
        cols = np.arange(start, stop, dtype=np.int64)
        keep = valid[cols % N_CELLS]
        if keep.any():
            yield cols[keep], block[:, keep]


# --------------------------------------------------------------------------
# Convenience: the whole ingest
# --------------------------------------------------------------------------


def _mp_context() -> multiprocessing.context.BaseContext:
    """``fork`` while this process is single-threaded (cheap), else a preloaded forkserver."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["brdfpipe.data.store"])
        return ctx
    return multiprocessing.get_context("spawn")


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]", "_", name)[:80]


def ingest(
    sources: Mapping[str, str | os.PathLike[str]] | Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    database: str,
    jobs: int = 1,
    workdir: str | os.PathLike[str] | None = None,
) -> None:
    """Ingest MERL files into the store at ``out`` (:func:`ingest_material` + :func:`assemble_store`).

    ``sources`` maps material names to files (row order = mapping order) or
    lists files (names = file stems, in list order).  ``jobs`` worker
    processes convert materials in parallel (``jobs=1``: in this process).
    Row stores go to ``workdir`` (kept afterwards) or to a temporary sibling
    ``.NAME.rows-PID-RANDOM`` of ``out`` (removed afterwards; one left by a
    killed run is removed by the next run, see
    :func:`brdfpipe.core.atomic.clean_stale_siblings`).  The first failing
    material aborts the ingest with its error (naming the file).  An earlier
    store at ``out`` is replaced only when the new one is complete: after any
    error or interrupt it is left exactly as it was.  An ``out`` that exists
    and is not a brdfpipe store is refused
    (:class:`brdfpipe.core.atomic.OutputError`) before any file is read.
    Every file must be of the ``database`` label
    (:func:`brdfpipe.data.provenance.check_source`).
    """
    database = _normalise_database(database)
    expect = {"database": database}
    out = Path(out)
    if isinstance(sources, Mapping):
        items = [(str(k), Path(v)) for k, v in sources.items()]
    else:
        items = [(Path(p).stem, Path(p)) for p in sources]
    if not items:
        raise ValueError("no sources to ingest")
    names = [n for n, _ in items]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"duplicate material names: {dup}")
    check_replaceable(out, replaceable=is_store)
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_siblings(out)
    own_workdir = workdir is None
    wd = tmp_sibling(out, "rows") if workdir is None else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    row_paths = [wd / f"{i:04d}-{_safe(n)}.zarr" for i, (n, _) in enumerate(items)]
    n = len(items)
    try:
        logger.info("ingesting %d materials into %s with %d job(s)", n, out, jobs)
        if jobs <= 1 or n == 1:
            for k, ((name, src), row) in enumerate(zip(items, row_paths), 1):
                ingest_material(src, row, name=name, expect=expect)
                if k % 10 == 0 or k == n:
                    logger.info("ingested %d/%d materials", k, n)
        else:
            with ProcessPoolExecutor(max_workers=min(jobs, n), mp_context=_mp_context()) as ex:
                futures: list[Future[None]] = [
                    ex.submit(ingest_material, src, row, name=name, expect=expect)
                    for (name, src), row in zip(items, row_paths)
                ]
                wait(futures, return_when=FIRST_EXCEPTION)
                for f in futures:
                    f.cancel()
                for f in futures:
                    if not f.cancelled():
                        f.result()  # re-raises the first error (in row order)
            logger.info("ingested %d/%d materials", n, n)
        # The row stores are private temporaries here: hard-link their shards.
        assemble_store(row_paths, out, database=database, threads=max(1, min(jobs, 4)), link=own_workdir)
    finally:
        if own_workdir:
            remove_tree(wd)


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
