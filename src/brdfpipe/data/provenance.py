"""Provenance marks: what a MERL-format file is, and what it was made from.

A MERL ``.binary`` file has no metadata, so a table written by this project
(synthetic, or derived by blending, sampling, extrapolating or reconstructing)
would otherwise look exactly like a measurement.  Every such file carries a
*mark* inside the table itself, in cells that no measurement can fill, and
the one folder labeller (:func:`brdfpipe.data.database.database_from_folder`)
and every ingest (:func:`brdfpipe.data.ingest.ingest_material`) read it.

Kinds
-----
A mark has a *kind*, which is also the label of a database made of such files
(the store's ``database`` attribute, the splits, every CSV and figure title).
The kinds are registered in one place, :data:`KINDS`; a file without a mark
is a measurement, labelled :data:`UNMARKED` (``"merl"``).

* ``synthetic`` – written by :mod:`brdfpipe.data.synth`: material ``name``,
  the plan (``count``, ``seed``), ``noise``, ``family``, ``index`` and
  ``material_seed``.  The name is *bound*: a file whose mark names another
  material is refused at ingest (a file copied over another).
* ``derived`` – written by a brdfpipe command from other data: ``name`` (the
  name it was written under; not bound, a user may rename a derived file),
  ``operation`` (``interpolate``, ``sample``, ``extrapolate``, ``path-point``,
  ``reconstruct``, ``capture-reconstruct``), ``source_database`` (the label of
  the data it came from) and ``inputs`` (digests of the model, the store's
  rows, the observations, the latent point, the weights …; see the writers).

To add a kind (e.g. tables evaluated from published neural fits), add a
:class:`MarkKind` to :data:`KINDS`: the labeller, the store and the ingest
checks take it from there.

Where the mark lives
--------------------
In the red channel, at the cells :data:`MARK_CELLS`: iθh = 89 (θh ≥ 88.0°),
iθd = 80 … 88 (θd ∈ [80°, 89°)), every iφd except 89 and 90 (φd within 1° of
90°), 9 × 178 = 1,602 cells in file order.  For a pair in such a cell,
``min(cos θi, cos θo) = cos θd cos θh − sin θd sin θh |cos φd|`` is at most
``cos 80° cos 88.0° − sin 80° sin 88.0° cos 89° ≈ −0.011 < 0`` (and a pair
whose half vector lies below the horizon, which :func:`brdfpipe.data.merl.bin_indices`
clips into θh bin 89, has a direction below it anyway): light or view is
below the horizon, no gonioreflectometer reaches the cell, and every reader
treats its negative value as unmeasured, like MERL's own −1 entries.  The
mark's values are all in [−2, −1), so nothing that reads tables changes.

Encoding (format 1)
-------------------
Each cell holds 6 bytes ``n`` as the raw value ``−(1 + n / 2⁴⁸)`` (exactly
representable: sign 1, exponent 0x3FF, mantissa ``n << 4``); ``n = 0`` is
−1.0, MERL's usual unmeasured value.  Cell 0 holds the magic
:data:`MAGIC` (``b"brdfpv"``), cell 1 the format version (2 bytes) and the
payload length (4 bytes), cell 2 the CRC-32 of cell 1's 6 bytes and the
payload (4 bytes, then 2 zero bytes); the payload follows from cell 3, zero
padded, then −1.0 up to the end of the region (capacity :data:`CAPACITY`
bytes).  The payload is canonical JSON (UTF-8, sorted keys, no spaces, no
NaN), so the same inputs give the same bytes.  The values are written at
the raw-file level (:func:`brdfpipe.data.merl.write_merl` with ``mark=``), so
no channel scale rounds them.

The old synthetic watermark (:data:`WATERMARK_CELLS`, eight cells of
iθh = iθd = 89 in every channel) is kept: files with a ``synthetic`` mark
carry it too, other marks clear it (a table blended from synthetic ones
could hold it), and a file carrying only the watermark
(written before marks existed) still reads as synthetic, with no fields
(:attr:`Mark.legacy`).

Reading
-------
:func:`read_mark` reads 24 bytes (the header) of an unmarked file, plus 64
bytes (the watermark); of a marked file also the payload's cells (one read)
and the watermark.  A damaged mark is a :class:`ProvenanceError` (a
:class:`brdfpipe.data.merl.MerlFormatError`) naming the file: a magic within
6 bits of :data:`MAGIC`, a wrong CRC, a cell that is not of the mark's form,
non-zero padding, a payload that is not a JSON object of a registered kind
with its fields, or a mark that disagrees with the watermark.  A file whose
first mark cell is not within 6 bits of the magic (a real MERL file holds
−1.0 there, 22 bits away) is unmarked.  Marks are declarations, not
signatures: anyone can write one; they guard against mistakes (a derived
table taken for a measurement, a file copied over another), not against
forgery.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.data import databases, merl
from brdfpipe.data.merl import MerlFormatError

__all__ = [
    "UNMARKED",
    "MarkKind",
    "KINDS",
    "OPERATIONS",
    "database_labels",
    "kind_title",
    "Mark",
    "ProvenanceError",
    "MAGIC",
    "FORMAT_VERSION",
    "MARK_CELLS",
    "CAPACITY",
    "WATERMARK_MAGIC",
    "WATERMARK_CELLS",
    "WATERMARK_RAW",
    "synthetic_mark",
    "derived_mark",
    "fit_mark",
    "mark_raw_values",
    "stamp",
    "read_mark",
    "file_label",
    "check_source",
    "check_sources",
    "output_name",
    "file_sha256",
    "store_identity",
]

#: The label of a file (and a database) without a mark: measured data, e.g. the real MERL files.
UNMARKED: Final = "merl"


@dataclass(frozen=True)
class MarkKind:
    """One kind of mark; its ``name`` is also the database label of a folder of such files.

    ``fields`` maps every field a mark of this kind must have to the JSON
    types it may take (``int`` excludes ``bool``; ``type(None)`` allows null).
    ``binds_name``: the mark's ``name`` must equal the material name a file
    is ingested under.  ``title`` describes the files in messages.
    """

    name: str
    title: str
    fields: Mapping[str, tuple[type, ...]]
    binds_name: bool


_INT = (int,)
_NUM = (int, float)
_STR = (str,)
_OPT_INT = (int, type(None))

#: Every kind of mark, by name (the database label).  Add an entry here to add a kind.
KINDS: Final[Mapping[str, MarkKind]] = {
    k.name: k
    for k in (
        MarkKind(
            "synthetic",
            "synthetic files written by `brdfpipe synth`",
            {"name": _STR, "generator": _STR, "count": _OPT_INT, "seed": _OPT_INT, "noise": _NUM,
             "family": _STR, "index": _INT, "material_seed": _INT},
            binds_name=True,
        ),
        MarkKind(
            "derived",
            "derived files written by brdfpipe",
            {"name": _STR, "operation": _STR, "source_database": _STR, "inputs": (dict,)},
            binds_name=False,
        ),
        # tables evaluated from neural fits (brdfpipe.data.nbrdf), one kind per database of fits
        *(
            MarkKind(
                name,
                f"tables evaluated from NBRDF fits ({name}) by `brdfpipe nbrdf`",
                {"name": _STR, "fit": _STR, "archive": _STR, "fit_sha256": _STR, "clamped": _INT},
                binds_name=True,
            )
            for name in databases.FIT_DATABASES
        ),
    )
}

#: Operations recorded by the project's writers of ``derived`` files.
OPERATIONS: Final = ("interpolate", "sample", "extrapolate", "path-point", "reconstruct", "capture-reconstruct")


def database_labels() -> tuple[str, ...]:
    """Every database label: :data:`UNMARKED` and the registered kinds."""
    return (UNMARKED, *KINDS)


def kind_title(label: str) -> str:
    """How messages name the files of a label ("unmarked (measured) MERL files" for ``merl``)."""
    if label == UNMARKED:
        return "unmarked (measured) MERL files"
    kind = KINDS.get(label)
    return kind.title if kind is not None else f"{label} files"


class ProvenanceError(MerlFormatError):
    """A file's provenance mark is damaged, or says the file is not what it is used as; names the file."""


# --------------------------------------------------------------------------
# Geometry and encoding
# --------------------------------------------------------------------------

_MARK_THETA_H: Final = merl.N_THETA_H - 1
_MARK_THETA_D: Final = range(80, merl.N_THETA_D - 1)
_SKIP_PHI: Final = (merl.N_PHI_D // 2 - 1, merl.N_PHI_D // 2)  # φd bins 89 and 90: around 90°
#: Flat cell indices (inside the red channel) of the mark, in file (and mark) order.
MARK_CELLS: Final = np.array(
    [
        (_MARK_THETA_H * merl.N_THETA_D + d) * merl.N_PHI_D + p
        for d in _MARK_THETA_D
        for p in range(merl.N_PHI_D)
        if p not in _SKIP_PHI
    ],
    dtype=np.intp,
)
_HEADER_CELLS: Final = 3
_CELL_BYTES: Final = 6
#: Largest payload (bytes) a mark can hold.
CAPACITY: Final = (MARK_CELLS.size - _HEADER_CELLS) * _CELL_BYTES
#: The mark's magic: the first cell holds these 6 bytes.
MAGIC: Final = b"brdfpv"
#: Format of the mark's header and payload.
FORMAT_VERSION: Final = 1
_FORM: Final = 0xBFF << 52  # sign 1, exponent 0x3FF: values in [−2, −1)
_TOP: Final = 0xFFF << 52
_LOW: Final = 0xF
_MAGIC_U64: Final = _FORM | (int.from_bytes(MAGIC, "big") << 4)
_MAGIC_NEAR: Final = 6  # bits: a first cell this close to the magic is a (damaged) mark

#: The watermark of synthetic files, one byte per watermark cell (the format before marks; kept).
WATERMARK_MAGIC: Final = b"brdfsyn1"
#: Flat cell indices (inside a channel) of the watermark: iθh = 89, iθd = 89, iφd = 0 … 7.
#: Light or view direction lies below the horizon for every pair in these cells.
WATERMARK_CELLS: Final = np.arange(len(WATERMARK_MAGIC)) + (
    (merl.N_THETA_H - 1) * merl.N_THETA_D + (merl.N_THETA_D - 1)
) * merl.N_PHI_D
#: Raw (file) values of the watermark cells, negative (unmeasured): −(1 + b/2²⁰).  (Chosen so
#: that in every channel some float64 divides by the channel scale to exactly this value.)
WATERMARK_RAW: Final = np.array([-(1.0 + b / 2.0**20) for b in WATERMARK_MAGIC], dtype="<f8")
_WATERMARK_BYTES: Final = WATERMARK_RAW.tobytes()
_WATERMARK_OFFSET: Final = merl.HEADER_BYTES + int(WATERMARK_CELLS[0]) * 8


def _offset(cell: int) -> int:
    """Byte offset of a red-channel cell in the file."""
    return merl.HEADER_BYTES + 8 * int(cell)


def _cell(n: int) -> int:
    return _FORM | (n << 4)


def _canonical(doc: Mapping[str, Any]) -> bytes:
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode()


def _type_ok(value: Any, types: tuple[type, ...]) -> bool:
    if isinstance(value, bool):
        return bool in types
    if isinstance(value, float) and not math.isfinite(value):
        return False
    return isinstance(value, types)


def _problem(doc: Any) -> str | None:
    """What is wrong with a decoded payload, or ``None``."""
    if not isinstance(doc, dict):
        return "payload is not a JSON object"
    kind = doc.get("kind")
    if kind not in KINDS:
        return (f"unknown kind {kind!r} (this brdfpipe knows {', '.join(KINDS)}; written by a newer one?)"
                if isinstance(kind, str) else "payload has no 'kind'")
    for key, types in KINDS[kind].fields.items():
        if key not in doc:
            return f"{kind} mark lacks the field {key!r}"
        if not _type_ok(doc[key], types):
            return f"{kind} mark's field {key!r} is {doc[key]!r}, not of type {'/'.join(t.__name__ for t in types)}"
    return None


@dataclass(frozen=True)
class Mark:
    """A provenance mark: its ``kind`` (a key of :data:`KINDS`) and its ``fields``.

    ``fields`` are normalised through canonical JSON on construction
    (tuples become lists); :meth:`payload` is that JSON.  A ``legacy`` mark
    stands for the old synthetic watermark alone: kind ``synthetic``, no
    fields.  Raises :class:`ValueError` for an unknown kind, a missing or
    mistyped field, a value that is not JSON (NaN included), or a payload
    beyond :data:`CAPACITY` bytes.
    """

    kind: str
    fields: Mapping[str, Any] = field(default_factory=dict)
    legacy: bool = False

    def __post_init__(self) -> None:
        if self.legacy:
            if self.kind != "synthetic" or self.fields:
                raise ValueError("a legacy mark is the synthetic watermark alone: kind 'synthetic', no fields")
            return
        if "kind" in self.fields:
            raise ValueError("'kind' is not a field: give it as Mark.kind")
        try:
            payload = _canonical({"kind": self.kind, **self.fields})
        except (TypeError, ValueError) as err:
            raise ValueError(f"{self.kind} mark: fields are not plain JSON ({err})") from None
        doc = json.loads(payload)
        problem = _problem(doc)
        if problem is not None:
            raise ValueError(problem)
        if len(payload) > CAPACITY:
            raise ValueError(f"{self.kind} mark: payload of {len(payload)} bytes exceeds the {CAPACITY} a file holds")
        doc.pop("kind")
        object.__setattr__(self, "fields", doc)

    @property
    def name(self) -> str | None:
        """The material name recorded in the mark (``None`` for a legacy mark)."""
        value = self.fields.get("name")
        return value if isinstance(value, str) else None

    def payload(self) -> bytes:
        """The canonical JSON of ``{"kind": …, **fields}`` (UTF-8, sorted keys)."""
        return _canonical({"kind": self.kind, **self.fields})

    def stamp(self, raw: NDArray[np.float64]) -> None:
        """Write this mark into raw (file) values of shape ``(3, N_CELLS)`` in place (:func:`stamp`).

        What :func:`brdfpipe.data.merl.write_merl` calls with ``mark=``, so that
        the file format needs no import of this module.
        """
        stamp(raw, self)

    def to_json(self) -> dict[str, Any]:
        """The mark as a JSON object (``{"kind": "synthetic", "legacy": true}`` for a legacy mark)."""
        if self.legacy:
            return {"kind": self.kind, "legacy": True}
        return {"kind": self.kind, **json.loads(self.payload())}

    def describe(self) -> str:
        """One phrase for messages, e.g. "synthetic material 'metal-gold-005' (count 12, seed 5, noise 0.01)"."""
        f = self.fields
        if self.legacy:
            return "a synthetic material of the old watermark (no name recorded)"
        if self.kind == "synthetic":
            return (f"synthetic material {f['name']!r} (count {f['count']}, seed {f['seed']}, "
                    f"noise {f['noise']})")
        if self.kind == "derived":
            return f"derived material {f['name']!r} ({f['operation']} of {f['source_database']} data)"
        if self.kind in databases.FIT_DATABASES:
            return f"{self.kind} material {f['name']!r} (fit {f['fit']!r} of {f['archive']})"
        return f"{self.kind} material {self.name!r}"


def synthetic_mark(
    *, name: str, count: int | None, seed: int | None, noise: float, family: str, index: int, material_seed: int
) -> Mark:
    """The mark of a file of :mod:`brdfpipe.data.synth` (``count``/``seed``: its plan, ``None`` if unknown)."""
    return Mark("synthetic", {"name": name, "generator": "brdfpipe.data.synth", "count": count, "seed": seed,
                              "noise": float(noise), "family": family, "index": int(index),
                              "material_seed": int(material_seed)})


def derived_mark(*, name: str, operation: str, source_database: str, inputs: Mapping[str, Any]) -> Mark:
    """The mark of a file derived from other data (``operation`` one of :data:`OPERATIONS`)."""
    if operation not in OPERATIONS:
        raise ValueError(f"unknown derivation {operation!r}; one of {', '.join(OPERATIONS)}")
    return Mark("derived", {"name": name, "operation": operation, "source_database": source_database,
                            "inputs": dict(inputs)})


def fit_mark(*, database: str, name: str, fit: str, archive: str, fit_sha256: str, clamped: int) -> Mark:
    """The mark of a table evaluated from an NBRDF fit (``database``: one of :data:`brdfpipe.data.databases.FIT_DATABASES`).

    ``name``: the material name it is written under (bound); ``fit``: the
    fit's name in the archive; ``archive``: the archive's file name;
    ``fit_sha256``: the digest of the fit's weights file; ``clamped``: how
    many negative outputs were clamped to 0.
    """
    if database not in databases.FIT_DATABASES:
        raise ValueError(f"{database!r} is not a database of fits ({', '.join(databases.FIT_DATABASES)})")
    return Mark(database, {"name": name, "fit": fit, "archive": archive, "fit_sha256": fit_sha256,
                           "clamped": int(clamped)})


def mark_raw_values(mark: Mark) -> NDArray[np.float64]:
    """The raw (file) values of :data:`MARK_CELLS` that encode ``mark``, float64 ``(1602,)``."""
    if mark.legacy:
        raise ValueError("a legacy mark cannot be written; write a synthetic mark with its fields")
    payload = mark.payload()
    header1 = (FORMAT_VERSION << 32) | len(payload)
    crc = zlib.crc32(header1.to_bytes(_CELL_BYTES, "big") + payload)
    padded = payload + b"\0" * (-len(payload) % _CELL_BYTES)
    ns = [int.from_bytes(MAGIC, "big"), header1, crc << 16]
    ns += [int.from_bytes(padded[i : i + _CELL_BYTES], "big") for i in range(0, len(padded), _CELL_BYTES)]
    ns += [0] * (MARK_CELLS.size - len(ns))
    return np.array([_cell(n) for n in ns], dtype="<u8").view("<f8")


def stamp(raw: NDArray[np.float64], mark: Mark) -> None:
    """Write ``mark`` into raw (file) values ``raw`` of shape ``(3, N_CELLS)`` in place.

    The red channel's :data:`MARK_CELLS` get :func:`mark_raw_values`; the
    watermark cells of every channel get :data:`WATERMARK_RAW` for a
    ``synthetic`` mark; for any other, those that hold it get −1.0
    (unmeasured).
    """
    if raw.shape != (3, merl.N_CELLS):
        raise ValueError(f"raw values have shape {raw.shape}, expected (3, {merl.N_CELLS})")
    raw[0, MARK_CELLS] = mark_raw_values(mark)
    if mark.kind == "synthetic":
        raw[:, WATERMARK_CELLS] = WATERMARK_RAW
    else:
        held = raw[:, WATERMARK_CELLS]
        raw[:, WATERMARK_CELLS] = np.where(held == WATERMARK_RAW, -1.0, held)


# --------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------


_LEGACY: Final = Mark("synthetic", legacy=True)


def _damaged(path: str, what: str) -> ProvenanceError:
    return ProvenanceError(
        f"{path}: damaged provenance mark ({what}); the file was changed after brdfpipe wrote it: "
        "write it again with the command that made it"
    )


def _decode(path: str, fd: int) -> Mark | None:
    head = os.pread(fd, 8 * _HEADER_CELLS, _offset(MARK_CELLS[0]))
    watermark = os.pread(fd, len(_WATERMARK_BYTES), _WATERMARK_OFFSET) == _WATERMARK_BYTES
    if len(head) < 8 * _HEADER_CELLS:
        return None  # too short to be a MERL file: the format check names it
    c0, c1, c2 = (int.from_bytes(head[i : i + 8], "little") for i in range(0, 24, 8))
    if bin(c0 ^ _MAGIC_U64).count("1") > _MAGIC_NEAR:
        return _LEGACY if watermark else None
    if c0 != _MAGIC_U64:
        raise _damaged(path, "magic altered")
    for c in (c1, c2):
        if c & _TOP != _FORM or c & _LOW:
            raise _damaged(path, "header cell altered")
    h1, h2 = c1 >> 4 & (1 << 48) - 1, c2 >> 4 & (1 << 48) - 1
    version, length = h1 >> 32, h1 & 0xFFFFFFFF
    if version != FORMAT_VERSION:
        raise ProvenanceError(
            f"{path}: provenance mark of format {version}; this brdfpipe reads format {FORMAT_VERSION} "
            "(written by a newer brdfpipe, or damaged)"
        )
    if not 0 < length <= CAPACITY or h2 & 0xFFFF:
        raise _damaged(path, f"header says {length} bytes")
    ncells = -(-length // _CELL_BYTES)
    cells = MARK_CELLS[_HEADER_CELLS : _HEADER_CELLS + ncells]
    first, last = int(cells[0]), int(cells[-1])
    data = os.pread(fd, 8 * (last - first + 1), _offset(first))
    if len(data) != 8 * (last - first + 1):
        raise _damaged(path, "file too short for its payload")
    u = np.frombuffer(data, dtype="<u8")[cells - first]
    if np.any(u & np.uint64(_TOP) != np.uint64(_FORM)) or np.any(u & np.uint64(_LOW)):
        raise _damaged(path, "payload cell altered")
    payload = ((u >> np.uint64(4)).astype(">u8").view(np.uint8).reshape(-1, 8)[:, 2:]).tobytes()
    if any(payload[length:]):
        raise _damaged(path, "padding altered")
    payload = payload[:length]
    if zlib.crc32(h1.to_bytes(_CELL_BYTES, "big") + payload) != h2 >> 16:
        raise _damaged(path, "CRC mismatch")
    try:
        doc = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise _damaged(path, "payload is not JSON") from None
    problem = _problem(doc)
    if problem is not None:
        raise ProvenanceError(f"{path}: provenance mark not understood: {problem}")
    kind = doc.pop("kind")
    if watermark != (kind == "synthetic"):
        raise _damaged(path, f"{kind} mark {'with' if watermark else 'without'} the synthetic watermark")
    if len(payload) > CAPACITY:  # pragma: no cover - the header's length was checked
        raise _damaged(path, "payload too long")
    mark = object.__new__(Mark)  # checked above (_problem); no second round trip through JSON
    object.__setattr__(mark, "kind", kind)
    object.__setattr__(mark, "fields", doc)
    object.__setattr__(mark, "legacy", False)
    return mark


def read_mark(path: str | os.PathLike[str]) -> Mark | None:
    """The provenance mark of a MERL-format file, or ``None`` for an unmarked one (a measurement).

    Reads only the mark's bytes (see the module's docstring); the rest of the
    file is not validated (a file too short to hold a mark is unmarked here
    and refused by the format check of the ingest).  Raises
    :class:`ProvenanceError` naming the file for a damaged or unknown mark,
    :class:`OSError` if the file cannot be read.
    """
    p = os.fspath(path)
    fd = os.open(p, os.O_RDONLY)
    try:
        return _decode(p, fd)
    finally:
        os.close(fd)


def file_label(path: str | os.PathLike[str]) -> str:
    """The database label of one file: its mark's kind, or :data:`UNMARKED`."""
    mark = read_mark(path)
    return UNMARKED if mark is None else mark.kind


_UNMARKED_WHAT: Final = "an unmarked MERL file (a measurement)"


class _What:
    """A mark's :meth:`Mark.describe`, formatted only into a message that is raised."""

    def __init__(self, mark: Mark) -> None:
        self.mark = mark

    def __format__(self, spec: str) -> str:
        return self.mark.describe()


def check_source(
    path: str | os.PathLike[str], *, name: str, expect: Mapping[str, Any] | None = None
) -> Mark | None:
    """The mark of a file read as material ``name``, after checking that it is that material.

    * A mark whose kind binds names (:attr:`MarkKind.binds_name`: synthetic)
      must name ``name``: a file copied over another fails, naming both.
    * ``expect["database"]`` (if given) must be the file's label: a file
      replaced by one of another kind after the run was planned fails.
    * Every other key of ``expect`` must equal the mark's field of that name
      (the workflow's synthetic files: ``count``, ``seed``, ``noise``); a file
      without such a mark (unmarked, or of the old watermark) fails.

    Raises :class:`ProvenanceError` (one line naming the file) or the errors
    of :func:`read_mark`.
    """
    p = os.fspath(path)
    mark = read_mark(p)
    label = UNMARKED if mark is None else mark.kind
    what = _UNMARKED_WHAT if mark is None else _What(mark)
    if mark is not None and not mark.legacy and KINDS[mark.kind].binds_name and mark.name != name:
        raise ProvenanceError(
            f"{p}: is {what}, not {name!r}: a file copied or renamed over that material's own; "
            "restore it or regenerate it"
        )
    if expect:
        want = expect.get("database")
        if want is not None and want != label:
            raise ProvenanceError(
                f"{p}: is {what}, but material {name!r} belongs to the {want} database (labelled when the run "
                f"was planned); the file was replaced since: restore it, or relabel by planning the run again"
            )
        for key, value in expect.items():
            if key == "database":
                continue
            if mark is None or mark.legacy:
                raise ProvenanceError(
                    f"{p}: is {what}, which records no {key!r}; expected {key} = {value!r}: regenerate the file"
                )
            got = mark.fields.get(key)
            if got != value or isinstance(got, bool) != isinstance(value, bool):
                raise ProvenanceError(
                    f"{p}: is {what}, made with {key} = {got!r}, but this run expects {key} = {value!r}: "
                    "a file of another configuration; regenerate it"
                )
    return mark


def check_sources(tables: Mapping[str, str | os.PathLike[str]] | Sequence[tuple[str, str | os.PathLike[str]]], *,
                  database: str | None, what: str = "material file") -> None:
    """Every table of ``tables`` (material → file, or pairs) is that material, checked before any work is done.

    The check a job makes before it reads the tables it renders or
    captures, as the ingest does (:func:`check_source`): each file exists,
    its mark names the material it is read as (for the kinds that bind
    names), and its label is ``database`` (when given).  For the ``derived``
    files of the workflow (``database="derived"``), the mark's ``name`` must
    be the file's own (:func:`output_name`): a path point renamed over
    another is refused.  Raises :class:`FileNotFoundError` or
    :class:`ProvenanceError`, one line naming the first file that fails.
    """
    pairs = list(tables.items()) if isinstance(tables, Mapping) else list(tables)
    for name, path in pairs:
        if not Path(path).is_file():
            raise FileNotFoundError(f"{os.fspath(path)}: {what} not found")
    for name, path in pairs:
        expect: dict[str, Any] | None = None if database is None else {"database": database}
        if database == "derived":
            expect = {"database": database, "name": output_name(path)}
        check_source(path, name=name, expect=expect)


# --------------------------------------------------------------------------
# Digests for the marks of derived files
# --------------------------------------------------------------------------


def output_name(path: str | os.PathLike[str]) -> str:
    """The name a derived file records: its file name without ``.binary``."""
    name = Path(path).name
    return name[: -len(".binary")] if name.endswith(".binary") and len(name) > len(".binary") else name


def file_sha256(path: str | os.PathLike[str]) -> str:
    """The sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def store_identity(store: Any) -> dict[str, Any]:
    """What a derived file records of the store it came from.

    ``store`` is an open :class:`brdfpipe.data.store.BrdfStore` (its
    ``database``, ``materials`` and row ``digests``): ``{"database", "materials"
    (count), "rows_sha256"}``, the last the sha256 of the canonical JSON of the
    ``[name, row digest]`` pairs in row order (the row digests cover the
    names and the rows' bytes, see :func:`brdfpipe.data.store.shard_digest`).
    """
    materials: Sequence[str] = tuple(store.materials)
    digests = [int(d) for d in store.digests]
    if len(digests) != len(materials):
        raise ValueError(f"{store.path}: {len(digests)} row digests for {len(materials)} materials")
    rows = hashlib.sha256(_canonical({"rows": [[m, d] for m, d in zip(materials, digests)]})).hexdigest()
    return {"database": str(store.database), "materials": len(materials), "rows_sha256": rows}
