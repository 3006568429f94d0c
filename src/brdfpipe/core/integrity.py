"""Integrity of intermediates: the one home of "every file a consumer reads carries a digest its reader checks".

Every intermediate the library writes for another stage to read carries a
digest of its content, written by the writer (through this module) and
checked by every reader by default.  A file that fails — damaged, edited,
truncated, written by another program or by an older brdfpipe without a
digest — stops the consumer with one line (a :class:`ValueError`, by default
:class:`IntegrityError`; readers pass their own error class) that names the
file, says what is wrong and what to rerun::

    results/svd/train.zarr: array file Q/c/3/0 does not match its recorded digest
    (damaged or edited); rerun its rule: snakemake --forcerun decompose_svd

("its rule" comes from :func:`brdfpipe.core.filenames.rule_of`, which knows
which rule writes every ``results/…`` file; a file outside a workflow's
``results`` folder gets "write it again with the command that made it").
Digests cover content only (no time stamps, no paths), so the same inputs
still give the same bytes.  They protect against accidents (bit rot, a
truncated copy, a hand edit, a file copied over another, a half-finished
transfer), not against someone who recomputes them on purpose.

Rules, per container
--------------------
* **npz** (:func:`save_npz` / :func:`load_npz`): an extra entry
  :data:`DIGEST_KEY` = ``"sha256:<hex>"`` over every other array, in name
  order: name, dtype (``dtype.str``), shape and the C-order bytes
  (:func:`npz_digest`).  The reader loads every array, so a truncated or
  corrupt zip is one clean error naming the file (never a ``BadZipFile``
  traceback, nor numpy's misleading "pickled data" message for a file that
  is not a zip at all).
* **JSON** (:func:`write_json` / :func:`read_json`): an extra top-level key
  :data:`DIGEST_KEY` = ``"sha256:<hex>"`` over the canonical text of the rest
  of the object (:func:`json_digest`: sorted keys, no spaces, UTF-8, floats
  as Python's shortest round-trip ``repr``), so indentation and key order
  are free.  The reader returns the object without the key.
* **OpenEXR** (:mod:`brdfpipe.core.exr` writes and checks it): a string header
  attribute :data:`DIGEST_KEY` over the R, G, B pixel planes as stored
  (name, half / float, shape, bytes) and every other string attribute
  (:func:`exr_digest`), so the recorded provenance (material, spp, seed, …)
  is covered too.
* **Zarr v3 groups** (:func:`seal_group` / :func:`open_group_digests`): a group
  attribute :data:`ZARR_ATTR` = ``{"algorithm": "crc32c(file)", "files":
  {relative path: [CRC-32C, size]}, "attributes": "sha256:<hex>"}``: the
  CRC-32C (``google_crc32c``, as the MERL store's shards) of every file of
  the group but its own ``zarr.json`` (array metadata and every chunk), and
  a digest of every other group attribute (completion marker included).
  Opening checks the attributes, that the recorded files are there with
  their sizes and no other file is in an array's folder (a deleted chunk
  would read back as the fill value; an extra one as data; files beside the
  arrays, such as Snakemake's ``.snakemake_timestamp``, are ignored), and
  the array metadata; chunks are checked when read
  (:meth:`GroupDigests.verify`), all at once or the ones a reader needs.
* **CSV** (:func:`write_csv` / :func:`read_csv_text` / :func:`read_csv_rows`):
  a first comment line ``# brdfpipe sha256=<hex>`` over the bytes of the rest
  of the file.  Every CSV reader of the library goes through
  :func:`read_csv_text`.  Other tools must skip that first line: pandas
  ``pd.read_csv(path, skiprows=1)`` (or ``comment="#"``; no field of these
  tables holds a ``#``), numpy ``np.loadtxt(path, delimiter=",",
  skiprows=2)`` (the comment counts in ``skiprows``, then the header) or
  ``np.genfromtxt(path, delimiter=",", names=True, skip_header=1)`` (with
  ``names=True`` alone it takes the names from the comment), R
  ``read.csv(path, comment.char="#")``, Python's ``csv`` module after
  ``next(fh)``.  A reader that does not skip it sees a first column named
  ``# brdfpipe sha256=…`` (pandas, ``csv.DictReader``): an obviously wrong
  table, not silently wrong numbers.
* **The explorer's data files** (``data/*.js``, :mod:`brdfpipe.explorer.export`):
  each holds its payload as a JSON text in a string and the CRC-32 (zlib's,
  which the page recomputes in JavaScript) of that text
  (:func:`text_crc32`); the page refuses a file that did not load or does
  not match, naming it.

The MERL store (:mod:`brdfpipe.data.store`) keeps its own, older scheme
(name-bound CRC-32C per row shard, checked on every open) and its
attributes' digest (:func:`attributes_digest`).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import threading
import zipfile
import zlib
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import google_crc32c

if TYPE_CHECKING:  # NumPy is imported by the functions that use it: the Snakefile parses with this module
    from numpy.typing import NDArray

from brdfpipe.core import atomic
from brdfpipe.core.filenames import BATCH_RULE_FAMILIES, rule_of
from brdfpipe.core.threads import run_threads

__all__ = [
    "DIGEST_KEY",
    "ZARR_ATTR",
    "CSV_PREFIX",
    "IntegrityError",
    "rerun_hint",
    "mismatch",
    "no_digest",
    "corrupt",
    "npz_digest",
    "save_npz",
    "load_npz",
    "json_digest",
    "attributes_digest",
    "dumps_json",
    "write_json",
    "read_json",
    "exr_digest",
    "seal_group",
    "GroupDigests",
    "open_group_digests",
    "csv_with_digest",
    "write_csv",
    "read_csv_text",
    "read_csv_rows",
    "text_crc32",
]

#: Name of the digest in an npz file (an entry), a JSON object (a key) and an EXR header (an attribute).
DIGEST_KEY: Final = "brdfpipe_digest"
#: Group attribute of a sealed Zarr group (see the module docstring).
ZARR_ATTR: Final = "brdfpipe_digests"
#: ``algorithm`` of :data:`ZARR_ATTR`.
ZARR_ALGORITHM: Final = "crc32c(file)"
#: First line of a CSV written by :func:`write_csv`, followed by 64 hex digits.
CSV_PREFIX: Final = "# brdfpipe sha256="
_NPZ_TAG: Final = b"brdfpipe npz digest/1\0"
_EXR_TAG: Final = b"brdfpipe exr digest/1\0"
_ZIP_MAGIC: Final = b"PK\x03\x04"
#: Threads that read and check Zarr files.
VERIFY_THREADS: Final = 2


class IntegrityError(ValueError):
    """A file a consumer reads is missing its digest, does not match it, or is truncated / corrupt."""


# --------------------------------------------------------------------------
# Messages
# --------------------------------------------------------------------------


def rerun_hint(path: str | os.PathLike[str]) -> str:
    """What to rerun to get ``path`` back: its workflow rule, else the command that made it."""
    rule = rule_of(Path(path).as_posix())
    if rule in BATCH_RULE_FAMILIES:  # one rule per batch: the file names its job
        return f"delete it and rerun the workflow (a {rule}_* job writes it again)"
    if rule is not None:
        return f"rerun its rule: snakemake --forcerun {rule}"
    return "write it again with the command that made it"


def mismatch(path: str | os.PathLike[str], what: str = "its content", *, error: type[Exception] = IntegrityError,
             plural: bool = False) -> Exception:
    """``error``: ``what`` of ``path`` does not match its recorded digest (damaged or edited); what to rerun.

    ``plural``: ``what`` is plural ("its attributes do not match their …").
    """
    verb = "do not match their" if plural else "does not match its"
    return error(f"{path}: {what} {verb} recorded digest (damaged or edited); {rerun_hint(path)}")


def no_digest(path: str | os.PathLike[str], kind: str, *, error: type[Exception] = IntegrityError) -> Exception:
    """``error``: the file carries no brdfpipe digest (another program, an older brdfpipe, or an edit)."""
    return error(f"{path}: {kind} carries no brdfpipe digest (written by another program or an older "
                 f"brdfpipe, or edited), so it cannot be verified; {rerun_hint(path)}")


def corrupt(path: str | os.PathLike[str], kind: str, detail: str, *,
            error: type[Exception] = IntegrityError) -> Exception:
    """``error``: a truncated or corrupt file of ``kind``, with the reader's ``detail``."""
    return error(f"{path}: truncated or corrupt {kind} ({detail}); {rerun_hint(path)}")


def _detail(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _sha(data: bytes) -> str:
    return "sha256:" + hashlib.sha256(data).hexdigest()


# --------------------------------------------------------------------------
# npz
# --------------------------------------------------------------------------


def npz_digest(arrays: Mapping[str, Any]) -> str:
    """``"sha256:<hex>"`` over the arrays (all but :data:`DIGEST_KEY`) in name order: name, dtype, shape, bytes."""
    import numpy as np

    h = hashlib.sha256(_NPZ_TAG)
    for name in sorted(arrays):
        if name == DIGEST_KEY:
            continue
        a = np.asarray(arrays[name])
        if a.dtype.hasobject:
            raise TypeError(f"array {name!r}: object arrays cannot be stored (dtype {a.dtype})")
        h.update(f"{name}\0{a.dtype.str}\0{list(a.shape)}\0".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return "sha256:" + h.hexdigest()


def save_npz(path: str | os.PathLike[str], arrays: Mapping[str, Any], *, compressed: bool = False) -> None:
    """``np.savez`` of ``arrays`` plus the :data:`DIGEST_KEY` entry, atomically (:func:`brdfpipe.core.atomic.save_npz`)."""
    import numpy as np

    if DIGEST_KEY in arrays:
        raise ValueError(f"{path}: {DIGEST_KEY!r} is reserved for the digest")
    plain = {str(k): np.asarray(v) for k, v in arrays.items()}
    plain[DIGEST_KEY] = np.array(npz_digest(plain))
    atomic.save_npz(path, plain, compressed=compressed)


def load_npz(
    path: str | os.PathLike[str],
    *,
    kind: str = "npz file",
    error: type[Exception] = IntegrityError,
    require: bool = True,
    fmt: str | None = None,
    retired: Mapping[str, tuple[str, str]] | None = None,
) -> dict[str, NDArray[Any]]:
    """Every array of an npz file (loaded), after checking its digest; the digest entry is left out.

    Raises ``error`` naming the file for a missing file, a file that is not a
    zip, a truncated or corrupt one (``BadZipFile``, bad CRC, a short
    member, pickled data), no digest (unless ``require=False``: files from
    elsewhere, e.g. a user's observations) or one that does not match.
    ``fmt``: the scalar ``format`` entry the file must have; a format of
    ``retired`` (format → ``(why, what to do)``) is refused saying why.
    """
    import numpy as np

    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except FileNotFoundError:
        raise error(f"{path}: no such {kind}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not an {kind}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read {kind} ({exc.strerror or exc})") from exc
    if head != _ZIP_MAGIC:
        what = "empty file" if not head else "no zip header"
        raise corrupt(path, kind, f"not an npz file: {what}", error=error)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: np.asarray(z[name]) for name in z.files}
    except (zipfile.BadZipFile, zlib.error, EOFError, ValueError, OSError, KeyError, TypeError) as exc:
        raise corrupt(path, kind, _detail(exc), error=error) from None
    recorded = arrays.pop(DIGEST_KEY, None)
    if recorded is None:
        if require:
            raise no_digest(path, kind, error=error)
        return arrays
    if recorded.shape != () or recorded.dtype.kind != "U" or str(recorded) != npz_digest(arrays):
        raise mismatch(path, "its arrays", error=error, plural=True)
    if fmt is not None:
        found = str(arrays["format"]) if "format" in arrays and arrays["format"].shape == () else None
        if retired and found in retired:
            why, todo = retired[found]
            raise error(f"{path}: {kind} format {found!r} is no longer supported: {why}; {todo} ({rerun_hint(path)})")
        if found != fmt:
            raise error(f"{path}: not a brdfpipe {kind} (format {found!r}, expected {fmt!r})")
    return arrays


# --------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------


def _canonical(doc: Any) -> bytes:
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True).encode()


def json_digest(doc: Mapping[str, Any]) -> str:
    """``"sha256:<hex>"`` of the canonical JSON text of ``doc`` without :data:`DIGEST_KEY`."""
    return _sha(_canonical({k: v for k, v in doc.items() if k != DIGEST_KEY}))


def attributes_digest(attrs: Mapping[str, Any], exclude: Iterable[str] = ()) -> str:
    """:func:`json_digest` of ``attrs`` without the keys in ``exclude`` (Zarr group attributes)."""
    skip = set(exclude)
    return json_digest({k: v for k, v in attrs.items() if k not in skip})


def dumps_json(doc: Mapping[str, Any], *, indent: int | None = 1, sort_keys: bool = False,
               allow_nan: bool = True, ensure_ascii: bool = True) -> str:
    """JSON text of ``doc`` with the :data:`DIGEST_KEY` key added last (and a final newline).

    The digest is computed on ``doc`` as it reads back (tuples become lists),
    so the reader recomputes exactly it.
    """
    if DIGEST_KEY in doc:
        raise ValueError(f"{DIGEST_KEY!r} is reserved for the digest")
    plain = json.loads(json.dumps(doc, allow_nan=allow_nan))
    if not isinstance(plain, dict):
        raise TypeError("only JSON objects carry a digest")
    plain[DIGEST_KEY] = json_digest(plain)
    return json.dumps(plain, indent=indent, sort_keys=sort_keys, allow_nan=allow_nan, ensure_ascii=ensure_ascii) + "\n"


def write_json(path: str | os.PathLike[str], doc: Mapping[str, Any], **kwargs: Any) -> None:
    """:func:`dumps_json` written to ``path`` atomically."""
    atomic.write_text(path, dumps_json(doc, **kwargs))


def read_json(
    path: str | os.PathLike[str],
    *,
    kind: str = "JSON file",
    error: type[Exception] = IntegrityError,
) -> dict[str, Any]:
    """The JSON object of ``path`` without its digest key, after checking it.

    Raises ``error`` naming the file for a missing or unreadable file, text
    that is not a JSON object (truncated or corrupt), no digest or one that
    does not match.
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise error(f"{path}: no such {kind}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not a {kind}") from None
    except UnicodeDecodeError as exc:
        raise corrupt(path, kind, f"not UTF-8 text: {exc.reason} at byte {exc.start}", error=error) from None
    except OSError as exc:
        raise error(f"{path}: cannot read {kind} ({exc.strerror or exc})") from exc
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise corrupt(path, kind, f"not JSON: {exc}", error=error) from None
    except RecursionError:
        raise corrupt(path, kind, "nested too deeply", error=error) from None
    if not isinstance(doc, dict):
        raise corrupt(path, kind, f"not a JSON object but {type(doc).__name__}", error=error)
    recorded = doc.pop(DIGEST_KEY, None)
    if recorded is None:
        raise no_digest(path, kind, error=error)
    if recorded != json_digest(doc):
        raise mismatch(path, "its content", error=error)
    return doc


# --------------------------------------------------------------------------
# OpenEXR
# --------------------------------------------------------------------------


def exr_digest(planes: Mapping[str, NDArray[Any]], attrs: Mapping[str, str]) -> str:
    """``"sha256:<hex>"`` over the pixel planes as stored (in channel-name order) and the string attributes.

    Planes: name, dtype (``dtype.str``, so half and float differ), shape,
    bytes; attributes (all but :data:`DIGEST_KEY`, sorted): name, value.
    """
    import numpy as np

    h = hashlib.sha256(_EXR_TAG)
    for name in sorted(planes):
        a = np.asarray(planes[name])
        h.update(f"{name}\0{a.dtype.str}\0{list(a.shape)}\0".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    for key in sorted(attrs):
        if key != DIGEST_KEY:
            h.update(f"\0{key}\0{attrs[key]}".encode())
    return "sha256:" + h.hexdigest()


# --------------------------------------------------------------------------
# Zarr groups
# --------------------------------------------------------------------------


def _group_files(folder: Path) -> dict[str, int]:
    """Every file of the group at ``folder`` but its own ``zarr.json``: relative POSIX path → size."""
    out: dict[str, int] = {}
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        rel_root = Path(root).relative_to(folder)
        for f in files:
            rel = (rel_root / f).as_posix()
            if rel == "zarr.json":
                continue
            out[rel] = (Path(root) / f).stat().st_size
    return out


def _crc_file(path: Path) -> int:
    crc = 0
    with open(path, "rb", buffering=0) as fh:
        while True:
            block = fh.read(1 << 22)
            if not block:
                return crc
            crc = google_crc32c.extend(crc, block)


def seal_group(folder: str | os.PathLike[str], attrs: Mapping[str, Any], *,
               threads: int = VERIFY_THREADS) -> dict[str, Any]:
    """The :data:`ZARR_ATTR` record of the finished group at ``folder`` whose other attributes will be ``attrs``.

    Reads every file of the group (arrays' ``zarr.json`` and chunks) for its
    CRC-32C; the caller stores the record as attribute :data:`ZARR_ATTR` in the
    same update as ``attrs`` (see :func:`brdfpipe.core.zgroup.finish_group`).
    """
    folder = Path(folder)
    sizes = _group_files(folder)
    names = sorted(sizes)
    crcs: dict[str, int] = {}
    lock = threading.Lock()

    def one(rel: str) -> None:
        crc = _crc_file(folder / rel)
        with lock:
            crcs[rel] = crc

    run_threads(one, names, threads)
    return {
        "algorithm": ZARR_ALGORITHM,
        "files": {rel: [crcs[rel], sizes[rel]] for rel in names},
        "attributes": attributes_digest(attrs, (ZARR_ATTR,)),
    }


class GroupDigests:
    """The recorded digests of a sealed Zarr group (:func:`open_group_digests`); verifies files on demand.

    :meth:`verify` reads files and checks their CRC-32C (each file once per
    handle; thread-safe), raising ``error`` naming the group, the file and
    what to rerun.
    """

    def __init__(self, path: Path, files: Mapping[str, tuple[int, int]], error: type[Exception]) -> None:
        self.path = path
        self.files = dict(files)
        self.error = error
        self._verified: set[str] = set()
        self._lock = threading.Lock()

    def names(self, prefix: str = "") -> list[str]:
        """Recorded files under ``prefix`` (e.g. ``"Q/"``), sorted."""
        return sorted(f for f in self.files if f.startswith(prefix))

    def verify(self, names: Iterable[str] | None = None, *, threads: int = VERIFY_THREADS) -> None:
        """Check the files ``names`` (relative paths; default: all) against their recorded CRC-32C."""
        want = self.files if names is None else list(names)
        with self._lock:
            todo = sorted(set(want) - self._verified)
        unknown = [n for n in todo if n not in self.files]
        if unknown:
            raise self.error(f"{self.path}: no recorded digest for {unknown[0]}; {rerun_hint(self.path)}")

        def one(rel: str) -> None:
            crc, size = self.files[rel]
            try:
                got = _crc_file(self.path / rel)
            except FileNotFoundError:
                raise self.error(f"{self.path}: file {rel} is missing; {rerun_hint(self.path)}") from None
            if got != crc:
                raise mismatch(self.path, f"file {rel}", error=self.error)
            with self._lock:
                self._verified.add(rel)

        run_threads(one, todo, threads)

    def verify_array(self, name: str, *, threads: int = VERIFY_THREADS) -> None:
        """Check every file of array ``name`` (its metadata and chunks)."""
        self.verify(self.names(f"{name}/"), threads=threads)

    def verify_chunks(self, array: Any, name: str, coords: Iterable[tuple[int, ...]]) -> None:
        """Check the chunks at chunk coordinates ``coords`` of the Zarr array ``array`` (named ``name``)."""
        self.verify([f"{name}/{array.metadata.encode_chunk_key(tuple(c))}" for c in coords])


def open_group_digests(
    path: str | os.PathLike[str],
    attrs: Mapping[str, Any],
    *,
    error: type[Exception] = IntegrityError,
    what: str = "group",
) -> GroupDigests:
    """Check a sealed group's attributes digest and files (presence, sizes, nothing extra, array metadata).

    ``attrs`` are the group's attributes as opened.  Returns the
    :class:`GroupDigests` with which the caller checks the chunks it reads.
    A group without :data:`ZARR_ATTR` (an older brdfpipe) is refused.
    Raises ``error`` naming ``path`` and what to rerun.
    """
    path = Path(path)
    record = attrs.get(ZARR_ATTR)
    if not isinstance(record, dict) or record.get("algorithm") != ZARR_ALGORITHM:
        raise no_digest(path, what, error=error)
    files = record.get("files")
    if not isinstance(files, dict) or not all(
        isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and x >= 0 for x in v) for v in files.values()
    ):
        raise error(f"{path}: attribute {ZARR_ATTR!r} is malformed; {rerun_hint(path)}")
    if record.get("attributes") != attributes_digest(attrs, (ZARR_ATTR,)):
        raise mismatch(path, "its attributes", error=error, plural=True)
    present = _group_files(path)
    missing = sorted(set(files) - set(present))
    if missing:
        raise error(f"{path}: file {missing[0]} is missing"
                    + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "") + f"; {rerun_hint(path)}")
    # a file inside an array's folder would be read as a chunk; others (Snakemake's .snakemake_timestamp
    # at the top of a directory output) are never read
    arrays = {f.split("/", 1)[0] for f in files if "/" in f}
    extra = sorted(f for f in set(present) - set(files) if "/" in f and f.split("/", 1)[0] in arrays)
    if extra:
        raise error(f"{path}: unexpected file {extra[0]} (not recorded when the {what} was written); "
                    f"{rerun_hint(path)}")
    for rel, (_, size) in sorted(files.items()):
        if present[rel] != size:
            raise error(f"{path}: file {rel} has {present[rel]} bytes, {size} were written (truncated or "
                        f"replaced); {rerun_hint(path)}")
    digests = GroupDigests(path, {k: (int(v[0]), int(v[1])) for k, v in files.items()}, error)
    digests.verify([f for f in files if f.endswith("zarr.json")])
    return digests


# --------------------------------------------------------------------------
# CSV
# --------------------------------------------------------------------------


def csv_with_digest(text: str) -> str:
    """``text`` (a CSV) with the digest line :data:`CSV_PREFIX` + sha256 of its UTF-8 bytes put first."""
    return f"{CSV_PREFIX}{hashlib.sha256(text.encode('utf-8')).hexdigest()}\n" + text


def write_csv(path: str | os.PathLike[str], text_or_rows: str | Iterable[Sequence[Any]]) -> None:
    """Write a CSV (its text, or rows for :mod:`csv`) with the digest line first, atomically."""
    if isinstance(text_or_rows, str):
        text = text_or_rows
    else:
        import csv

        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        for row in text_or_rows:
            writer.writerow(row)
        text = buf.getvalue()
    atomic.write_text(path, csv_with_digest(text))


def read_csv_text(
    path: str | os.PathLike[str],
    *,
    kind: str = "CSV file",
    error: type[Exception] = IntegrityError,
    require: bool = True,
) -> str:
    """The text of a CSV after its digest line, checked against it.

    Raises ``error`` naming the file for a missing or unreadable file, text
    that is not UTF-8, no digest line (unless ``require=False``: then the
    whole text) or a digest that does not match.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: no such {kind}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not a {kind}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read {kind} ({exc.strerror or exc})") from exc
    prefix = CSV_PREFIX.encode()
    if not data.startswith(prefix):
        if require:
            raise no_digest(path, kind, error=error)
        body = data
    else:
        head, nl, body = data.partition(b"\n")
        recorded = head[len(prefix):].decode("ascii", "replace").strip()
        if not nl or hashlib.sha256(body).hexdigest() != recorded:
            raise mismatch(path, "its content", error=error)
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise corrupt(path, kind, f"not UTF-8 text: {exc.reason}", error=error) from None


def read_csv_rows(
    path: str | os.PathLike[str],
    *,
    required: Sequence[str] = (),
    kind: str = "CSV file",
    error: type[Exception] = IntegrityError,
) -> tuple[list[str], list[dict[str, str]]]:
    """``(header, rows)`` of a verified CSV (:func:`read_csv_text`); ``error`` naming the file for missing columns."""
    import csv

    reader = csv.DictReader(io.StringIO(read_csv_text(path, kind=kind, error=error), newline=""))
    header = list(reader.fieldnames or [])
    missing = [c for c in required if c not in header]
    if missing:
        raise error(f"{path}: not the expected {kind}: missing column(s) {', '.join(missing)} "
                    f"(header: {', '.join(header) or 'none'})")
    rows = list(reader)
    return header, rows


# --------------------------------------------------------------------------
# The explorer's data files
# --------------------------------------------------------------------------


def text_crc32(text: str) -> str:
    """``"crc32:<8 hex>"`` (zlib's CRC-32) of an ASCII text: what the explorer page recomputes in JavaScript."""
    return f"crc32:{zlib.crc32(text.encode('ascii')):08x}"
