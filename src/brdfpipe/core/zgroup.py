"""Finished brdfpipe Zarr groups: the one home of "open it and check it is ours and complete".

Every folder output of the library (the MERL store, its row stores, the
log-map, the PCA model) is a Zarr v3 group whose attribute ``format`` names
its kind and version and whose attribute :data:`COMPLETE_ATTR` (the
completion marker) is written last, after the writer checked its output.

* :func:`open_finished_group` opens such a group read-only and refuses, with
  the caller's error class and a one-line message naming the path, a missing
  folder, an unreadable group, another format (a retired version of the same
  kind gets its own message, e.g. "re-ingest") and a missing marker.
* :func:`group_format` reads the ``format`` attribute straight from
  ``zarr.json`` (no Zarr needed), and :func:`format_predicate` turns a set of
  formats into the ``replaceable`` predicate of :func:`brdfpipe.core.atomic.atomic_dir`:
  a writer replaces only an earlier output of its own kind.
* :func:`create_array` is the common way the writers create their
  (Blosc lz4 + shuffle, or uncompressed) arrays.
* :func:`finish_group` writes the completion marker together with the
  group's integrity record (:func:`brdfpipe.core.integrity.seal_group`: CRC-32C
  of every file, digest of the attributes), and :func:`open_sealed_group`
  opens such a group and checks the record (attributes, files present with
  their sizes, array metadata), returning the
  :class:`~brdfpipe.core.integrity.GroupDigests` with which a reader checks the
  chunks it reads.  (The MERL store has its own per-row scheme,
  :mod:`brdfpipe.data.store`.)
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
import zarr
from zarr.codecs import BloscCodec

from brdfpipe.core.integrity import ZARR_ATTR, GroupDigests, open_group_digests, seal_group

__all__ = [
    "COMPLETE_ATTR",
    "group_format",
    "format_predicate",
    "open_finished_group",
    "finish_group",
    "open_sealed_group",
    "create_array",
]

#: Group attribute written last by every writer; groups without it were never finished.
COMPLETE_ATTR: Final = "brdfpipe_complete"
_CODEC: Final = {"cname": "lz4", "clevel": 5, "shuffle": "shuffle", "blocksize": 0}


def group_format(path: str | os.PathLike[str]) -> str | None:
    """The ``format`` attribute of the Zarr v3 group at ``path``; None if it is not one or has none."""
    try:
        with open(Path(path) / "zarr.json", "rb") as fh:
            doc = json.load(fh)
        fmt = doc["attributes"]["format"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return fmt if isinstance(fmt, str) else None


def format_predicate(formats: Iterable[str]) -> Callable[[Path], bool]:
    """``replaceable`` predicate: true for a real folder holding a group of one of ``formats``."""
    allowed = frozenset(formats)

    def replaceable(path: Path) -> bool:
        return path.is_dir() and not path.is_symlink() and group_format(path) in allowed

    return replaceable


def open_finished_group(
    path: str | os.PathLike[str],
    *,
    fmt: str,
    what: str,
    kind: str,
    error: type[Exception],
    retired: Mapping[str, str] | None = None,
    need_marker: bool = True,
    rerun: str = "re-run it",
) -> tuple[zarr.Group, dict[str, Any]]:
    """Open the finished group of format ``fmt`` at ``path`` read-only; return it and its attributes.

    ``what`` names the output in messages ("store", "log-map"), ``kind`` its
    format in words ("brdfpipe log-map").  Raises ``error`` (one line, naming
    ``path``) for a missing folder ("no such ..."), an unreadable group, a
    format listed in ``retired`` (with that message), another format ("not a
    ..."), or — with ``need_marker`` — no completion marker ("incomplete ...").
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise error(f"{path}: not a {kind} (a file; a {what} is a Zarr v3 folder)")
    if not path.is_dir():
        raise error(f"{path}: no such {what}")
    try:
        group = zarr.open_group(path, mode="r", zarr_format=3)
        attrs = dict(group.attrs)
    except Exception as exc:  # zarr raises many kinds for a damaged zarr.json
        raise error(f"{path}: not a readable Zarr v3 group ({type(exc).__name__}: {exc})") from exc
    found = attrs.get("format")
    if retired and isinstance(found, str) and found in retired:
        raise error(f"{path}: {what} format {found!r} is no longer supported ({retired[found]})")
    if found != fmt:
        raise error(f"{path}: not a {kind} (format {found!r}, expected {fmt!r})")
    if need_marker and not isinstance(attrs.get(COMPLETE_ATTR), dict):
        raise error(
            f"{path}: incomplete {what} (no completion marker {COMPLETE_ATTR!r}): it was never "
            f"finished, e.g. its writer crashed; {rerun}"
        )
    return group, attrs


def finish_group(group: zarr.Group, folder: str | os.PathLike[str], marker: Mapping[str, Any]) -> None:
    """Write the completion marker ``marker`` and the integrity record, last, in one attribute update.

    ``folder`` is where ``group`` lives (the writer's temporary folder); every
    array must be complete.  The record covers every file of the group and
    every attribute (the marker included), see :mod:`brdfpipe.core.integrity`.
    """
    attrs = json.loads(json.dumps({**dict(group.attrs), COMPLETE_ATTR: dict(marker)}))
    attrs.pop(ZARR_ATTR, None)
    record = seal_group(folder, attrs)
    group.attrs.update({COMPLETE_ATTR: dict(marker), ZARR_ATTR: record})


def open_sealed_group(
    path: str | os.PathLike[str],
    *,
    fmt: str,
    what: str,
    kind: str,
    error: type[Exception],
    rerun: str = "re-run it",
) -> tuple[zarr.Group, dict[str, Any], GroupDigests]:
    """:func:`open_finished_group`, then the group's integrity record checked (:func:`~brdfpipe.core.integrity.open_group_digests`).

    Returns the group, its attributes and its :class:`~brdfpipe.core.integrity.GroupDigests`
    (chunks are not read here: the caller verifies what it reads).
    """
    group, attrs = open_finished_group(path, fmt=fmt, what=what, kind=kind, error=error, rerun=rerun)
    digests = open_group_digests(path, attrs, error=error, what=what)
    return group, attrs, digests


def create_array(
    group: zarr.Group,
    name: str,
    data_or_shape: Any,
    chunks: tuple[int, ...],
    dtype: Any,
    dims: tuple[str, ...],
    *,
    compress: bool = True,
) -> zarr.Array:
    """A Zarr array in ``group`` (Blosc lz4 + shuffle unless ``compress=False``), filled if data is given.

    Float arrays get fill value NaN (a missing chunk never passes for data),
    others 0; empty chunks are written too.
    """
    shape = data_or_shape.shape if isinstance(data_or_shape, np.ndarray) else data_or_shape
    fill = np.nan if np.dtype(dtype).kind == "f" else 0
    arr = group.create_array(
        name,
        shape=shape,
        chunks=chunks,
        dtype=dtype,
        compressors=BloscCodec(typesize=np.dtype(dtype).itemsize, **_CODEC) if compress else None,
        fill_value=fill,
        dimension_names=dims,
        config={"write_empty_chunks": True},
    )
    if isinstance(data_or_shape, np.ndarray):
        arr[...] = data_or_shape
    return arr
