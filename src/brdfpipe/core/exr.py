"""OpenEXR images that are *data*: renders, blends and error maps.

Images are ``(H, W, 3)`` float32 linear RGB arrays.  Files are single-part
scanline OpenEXR with ``R``, ``G``, ``B`` channels, ZIP compression, float32
(or, on request, half) pixels, and optional string attributes in the header
(``database``, ``material``, ``spp``, ``seed``, …) that record where the
image came from.

Rules
-----
* Writing is atomic: the file is written under a temporary name in the same
  folder (``.<name>.<random>.tmp``) and renamed into place with
  :func:`os.replace`, so a crash or an error never leaves a partial file under
  the final name, and the temporary file is removed on error.
* Pixels must be finite on both sides: :func:`write_exr` refuses NaN/Inf (and
  values that overflow half precision when ``half=True``); :func:`read_exr`
  rejects a file holding them.
* Every problem with a file raises :class:`ExrError` (a :class:`ValueError`)
  whose message starts with the file's path and says what is wrong: missing
  file, not an OpenEXR file, truncated or corrupt data, missing RGB channels,
  non-finite pixels.
* The same image and attributes give the same bytes (the OpenEXR writer is
  deterministic; attributes are written in sorted order).
* Integrity: :func:`write_exr` records a digest of the pixels as stored and
  of every other string attribute in the header attribute
  ``brdfpipe_digest`` (:func:`brdfpipe.core.integrity.exr_digest`), and
  :func:`read_exr` checks it by default: a changed pixel or attribute, or a
  file without the attribute (written by another program or an older
  brdfpipe), is an :class:`ExrError` naming the file and what to rerun.
  (OpenEXR itself has no checksum: a byte changed inside a block was not
  detected before.)

:func:`tonemap` is the display version of such an image (figures, the
explorer's shader does the same).  Importing this module does not import Mitsuba.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
import OpenEXR
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_path

__all__ = [
    "ExrError",
    "RESERVED_ATTRIBUTES",
    "read_exr",
    "read_exr_attrs",
    "write_exr",
    "tonemap",
]

#: The four bytes every OpenEXR file starts with.
_MAGIC: Final = b"\x76\x2f\x31\x01"

#: Header attributes that OpenEXR itself defines; user attributes may not use these names.
RESERVED_ATTRIBUTES: Final = frozenset(
    {
        "channels", "compression", "dataWindow", "displayWindow", "lineOrder",
        "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type",
        "tiles", "name", "version", "chunkCount", "view", "multiView", "envmap",
        integrity.DIGEST_KEY,  # brdfpipe's own: written by write_exr
    }
)

_HALF_MAX: Final = float(np.finfo(np.float16).max)


class ExrError(ValueError):
    """A file is not a valid RGB OpenEXR data image; the message names the file."""


# --------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------


def _open(path: Path, *, header_only: bool) -> Any:
    """Open ``path`` with the OpenEXR bindings, turning every failure into :class:`ExrError`."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ExrError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ExrError(f"{path}: is a directory, not an OpenEXR file") from None
    except OSError as exc:
        raise ExrError(f"{path}: cannot read file: {exc.strerror or exc}") from exc
    if len(data) < len(_MAGIC) or data[: len(_MAGIC)] != _MAGIC:
        what = "empty file" if not data else f"{len(data)} bytes without the OpenEXR magic number"
        raise ExrError(f"{path}: not an OpenEXR file ({what})")
    try:
        exr = OpenEXR.File(io.BytesIO(data), separate_channels=True, header_only=header_only)
        if not header_only:
            exr.channels()  # forces the pixel data to be decoded (and checked) now
    except Exception as exc:  # the bindings raise ValueError/RuntimeError for bad data
        raise ExrError(f"{path}: truncated or corrupt OpenEXR file ({exc}); {integrity.rerun_hint(path)}") from exc
    return exr


def read_exr(path: str | os.PathLike[str], *, verify: bool = True, require: bool = True) -> NDArray[np.float32]:
    """Read the RGB channels of an OpenEXR file as an ``(H, W, 3)`` float32 array.

    Half and float32 channels are accepted (half is widened exactly); an
    ``A`` channel and any other extra channels are ignored.  Only the first
    part of a multi-part file is read.  Raises :class:`ExrError` naming the
    file for a missing file, a file that is not OpenEXR, a truncated or
    corrupt file, missing ``R``/``G``/``B`` channels, channels of different
    sizes, or NaN/Inf pixels; and, with ``verify`` (the default), for a file
    without the ``brdfpipe_digest`` attribute or whose pixels or string
    attributes do not match it (:mod:`brdfpipe.core.integrity`).
    ``verify=False`` reads images from elsewhere; ``require=False`` checks
    the digest of a file that carries one and accepts one without (a user's
    own environment map).
    """
    path = Path(path)
    exr = _open(path, header_only=False)
    channels = exr.channels()
    if verify:
        _verify(path, exr, channels, require=require)
    missing = [c for c in "RGB" if c not in channels]
    if missing:
        have = ", ".join(sorted(channels)) or "none"
        raise ExrError(f"{path}: missing channel(s) {', '.join(missing)} (file has: {have})")
    planes = [np.asarray(channels[c].pixels) for c in "RGB"]
    if any(p.ndim != 2 or p.shape != planes[0].shape for p in planes):
        shapes = ", ".join(f"{c}={p.shape}" for c, p in zip("RGB", planes))
        raise ExrError(f"{path}: R, G, B channels differ in size ({shapes})")
    if any(p.dtype.kind != "f" for p in planes):
        kinds = ", ".join(f"{c}={p.dtype}" for c, p in zip("RGB", planes))
        raise ExrError(f"{path}: RGB channels must be half or float, got {kinds}")
    image = np.stack([p.astype(np.float32, copy=False) for p in planes], axis=-1)
    finite = np.isfinite(image)
    if not finite.all():
        bad = np.argwhere(~finite)
        y, x, c = (int(v) for v in bad[0])
        raise ExrError(
            f"{path}: {bad.shape[0]} non-finite value(s) (NaN or Inf), first at "
            f"row {y}, column {x}, channel {'RGB'[c]}"
        )
    return np.ascontiguousarray(image)


def _verify(path: Path, exr: Any, channels: Mapping[str, Any], *, require: bool = True) -> None:
    """Check the pixels and string attributes of an opened file against its ``brdfpipe_digest``."""
    attrs = {str(k): v for k, v in exr.header().items() if isinstance(v, str)}
    recorded = attrs.get(integrity.DIGEST_KEY)
    if recorded is None:
        if not require:
            return
        raise integrity.no_digest(path, "OpenEXR image", error=ExrError)
    planes = {c: np.asarray(channels[c].pixels) for c in "RGB" if c in channels}
    if recorded != integrity.exr_digest(planes, attrs):
        raise integrity.mismatch(path, "its pixels or attributes", error=ExrError, plural=True)


def read_exr_attrs(path: str | os.PathLike[str]) -> dict[str, str]:
    """The string-valued header attributes of an OpenEXR file (e.g. ``database``, ``spp``).

    Only the header is decoded (the digest, which covers the pixels too, is
    checked by :func:`read_exr`, not here).  OpenEXR's own structural
    attributes (which are not strings) and ``brdfpipe_digest`` are left out.
    Raises :class:`ExrError` as :func:`read_exr`.
    """
    path = Path(path)
    header = _open(path, header_only=True).header()
    return {str(k): v for k, v in sorted(header.items()) if isinstance(v, str) and k != integrity.DIGEST_KEY}


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------


def _check_attrs(path: Path, attrs: Mapping[str, str] | None) -> dict[str, str]:
    if attrs is None:
        return {}
    out: dict[str, str] = {}
    for key, value in attrs.items():
        if not isinstance(key, str) or not key:
            raise ValueError(f"{path}: attribute names must be non-empty strings, got {key!r}")
        if key in RESERVED_ATTRIBUTES:
            raise ValueError(f"{path}: attribute name {key!r} is reserved (by OpenEXR or for the digest)")
        if not isinstance(value, str):
            raise ValueError(f"{path}: attribute {key!r} must be a string, got {type(value).__name__}")
        out[key] = value
    return dict(sorted(out.items()))


def write_exr(
    path: str | os.PathLike[str],
    image: ArrayLike,
    *,
    half: bool = False,
    attrs: Mapping[str, str] | None = None,
) -> None:
    """Write an ``(H, W, 3)`` RGB image as a ZIP-compressed OpenEXR file, atomically.

    Pixels are stored as float32 (exact for float32 input), or as half when
    ``half`` is true.  ``attrs`` are extra string attributes stored in the
    header (names of OpenEXR's own attributes, :data:`RESERVED_ATTRIBUTES`,
    are refused).  The file is written under a temporary name in the same
    folder and renamed into place; on any error the temporary file is removed
    and nothing appears under ``path``.  Raises :class:`ValueError` naming the
    file for a wrong shape, non-finite pixels, pixels that overflow half
    precision, or bad attributes.
    """
    path = Path(path)
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"{path}: image must have shape (H, W, 3), got {arr.shape}")
    if arr.dtype.kind not in "fiub":
        raise ValueError(f"{path}: image must be numeric, got dtype {arr.dtype}")
    arr32 = arr.astype(np.float32)
    if not np.isfinite(arr32).all():
        n_bad = int((~np.isfinite(arr32)).sum())
        raise ExrError(f"{path}: refusing to write {n_bad} non-finite value(s) (NaN or Inf)")
    header_attrs = _check_attrs(path, attrs)
    if half:
        peak = float(np.abs(arr32).max())
        if peak > _HALF_MAX:
            raise ValueError(f"{path}: value {peak:g} overflows half precision (max {_HALF_MAX:g})")
        store: NDArray[Any] = arr32.astype(np.float16)
    else:
        store = arr32
    header: dict[str, Any] = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        **header_attrs,
    }
    channels = {c: np.ascontiguousarray(store[..., i]) for i, c in enumerate("RGB")}
    header[integrity.DIGEST_KEY] = integrity.exr_digest(channels, header_attrs)

    with atomic_path(path) as tmp, OpenEXR.File(header, channels) as exr:
        exr.write(str(tmp))  # the OpenEXR writer opens the file by name


def tonemap(image: ArrayLike, exposure: float = 0.0) -> NDArray[np.uint8]:
    """Display version of a linear RGB image: ``× 2**exposure``, clamp to [0, 1], sRGB OETF, 8 bits."""
    x = np.asarray(image, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3:
        raise ValueError(f"image must have shape (H, W, 3), got {x.shape}")
    x = np.clip(np.nan_to_num(x * 2.0 ** float(exposure), nan=0.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)
