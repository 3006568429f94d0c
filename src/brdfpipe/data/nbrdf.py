"""Neural BRDF fits of measured materials (Sztrajman et al. 2021), evaluated on the MERL grid.

Sztrajman, Rainer, Ritschel and Weyrich, *Neural BRDF Representation and
Importance Sampling* (Computer Graphics Forum 40(6), 2021) published, under
the MIT licence, one small neural network per measured material: the 100
materials of MERL, 51 isotropic materials of the RGL database (Dupuy & Jakob
2018) and 8 materials measured by Nielsen et al. 2015.  Each fit is a Keras
model: ``NAME.h5`` (weights) and ``NAME.json`` (architecture).  The network is

    6 → 21 (ReLU) → 21 (ReLU) → 3 (linear), then exp(y) − 1,

its input the Rusinkiewicz half and difference vectors in Cartesian form with
φh = 0, ``(sin θh, 0, cos θh, sin θd cos φd, sin θd sin φd, cos θd)``, its
output the BRDF in RGB, sr⁻¹ (MERL's channel scales already applied).

This module reads the weights with h5py (no TensorFlow), from a ``.zip``
archive or a folder, and evaluates a fit at the centres of the MERL cells
(:func:`brdfpipe.data.merl.cell_centres`), giving a MERL-format table of
that material — as accurate as the fit is: a smooth approximation of the
measurement, never the measurement itself (a table made from a fit is
labelled "MERL (NBRDF fit)", never "MERL").  Conventions of the table:

* cells whose centre has the light or the view below the horizon
  (:func:`brdfpipe.data.merl.measured_mask` false) stay unmeasured: raw −1,
  exactly as in the synthetic database;
* negative network outputs (exp(y) − 1 < 0 where y < 0) are clamped to 0 and
  counted (:attr:`FitTable.clamped`);
* raw file value = value / MERL channel scale (:func:`brdfpipe.data.merl.write_merl`).

Trust: a fit is read with every check of its file (:meth:`Archive.fit`: the
member, the sidecar, the layer shapes, finite weights); :func:`check_fit`
refuses what an interval bound of the network proves (an all-black channel,
an impossible albedo) and :func:`check_archive` applies both to every fit of
an archive (the workflow's parse time).  A table that is not a material
(:func:`check_table`: too many clamped values, an albedo at normal incidence
outside (0, :data:`MAX_ALBEDO`]) is refused before it is written.  Every
error is one :class:`NbrdfError` line naming the archive, the member and the
problem.

The evaluation runs in float64 (the weights are float32), in blocks of
:data:`BLOCK_CELLS` cells.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import math
import os
import reprlib
import time
import zipfile
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

try:
    from lzma import LZMAError
except ImportError:  # a Python built without lzma: zipfile then raises RuntimeError for such members
    LZMAError = zlib.error  # type: ignore[misc,assignment]

from brdfpipe.core import atomic, integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import databases, merl, provenance
from brdfpipe.registry import tables

__all__ = [
    "NbrdfError",
    "ARCHITECTURE",
    "BLOCK_CELLS",
    "Fit",
    "FitTable",
    "Archive",
    "open_archive",
    "material_name",
    "MAX_CLAMPED_SHARE",
    "MAX_ALBEDO",
    "output_bounds",
    "check_fit",
    "check_archive",
    "check_table",
    "evaluate",
    "fit_table",
    "fit_names",
    "fit_database",
    "write_fit",
    "write_fits",
    "evaluate_to_files",
    "albedo_rows",
    "evaluate_to_store",
]

#: Layer widths of the published fits: input, hidden, hidden, output.
ARCHITECTURE: Final = (6, 21, 21, 3)
#: Cells evaluated per block: the (block, 21) temporaries stay in the cache (2,048–4,096 cells are
#: 2.3× faster than 131,072 on this project's 2-core AMD EPYC).
BLOCK_CELLS: Final = 4_096
logger = logging.getLogger("brdfpipe.data.nbrdf")

_H5_SUFFIX: Final = ".h5"
_BINARY: Final = ".binary"
_MAX_FIT_BYTES: Final = 16 * 1024 * 1024  # a published fit is ~8 kB; refuse absurd members
#: The zip compression methods Python's zipfile reads (it raises NotImplementedError for others: deflate64, …).
_ZIP_METHODS: Final = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA)


class NbrdfError(ValueError):
    """An archive or a fit cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Fit:
    """One material's network: the fit's name, its dense layers ``(W, b)`` and where it came from.

    ``layers[k] = (W, b)`` with ``W`` of shape (inputs, outputs) in float64
    (converted from the file's float32 exactly); ``source`` is
    ``"ARCHIVE:MEMBER"``; ``sha256`` is the digest of the ``.h5`` bytes.
    """

    name: str
    layers: tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]
    source: str
    sha256: str


@dataclass(frozen=True)
class FitTable:
    """A fit evaluated on the MERL grid: the table (physical units) and how many values were clamped at 0."""

    table: NDArray[np.float64]
    clamped: int
    measured_cells: int = field(default=0)


def material_name(fit_name: str) -> str:
    """The material name of a fit: the file stem with ``_`` written as ``-`` (``spectralon_rgb`` → ``spectralon-rgb``)."""
    return fit_name.replace("_", "-")


def _read_h5(data: bytes, where: str) -> tuple[tuple[NDArray[np.float64], NDArray[np.float64]], ...]:
    """The dense layers of a Keras 2 ``.h5`` weights file, in ``layer_names`` order."""
    import h5py

    try:
        with h5py.File(io.BytesIO(data), "r") as f:
            names = [n.decode() if isinstance(n, bytes) else str(n) for n in f.attrs.get("layer_names", [])]
            if not names:
                raise NbrdfError(f"{where}: not a Keras weights file (no 'layer_names' attribute)")
            layers = []
            for layer in names:
                group = f[layer]
                weights = [w.decode() if isinstance(w, bytes) else str(w) for w in group.attrs.get("weight_names", [])]
                if not weights:
                    continue  # the Lambda layer (exp(y) − 1) has no weights
                arrays = {w.rsplit("/", 1)[-1].split(":")[0]: np.asarray(group[w], dtype=np.float64) for w in weights}
                if set(arrays) != {"kernel", "bias"}:
                    raise NbrdfError(f"{where}: layer {layer!r} holds {sorted(arrays)}, expected kernel and bias")
                layers.append((arrays["kernel"], arrays["bias"]))
    except NbrdfError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as err:
        raise NbrdfError(f"{where}: not a readable Keras weights file ({type(err).__name__}: {err})") from None
    shapes = [(w.shape, b.shape) for w, b in layers]
    if shapes != [((i, o), (o,)) for i, o in zip(ARCHITECTURE, ARCHITECTURE[1:])]:
        raise NbrdfError(
            f"{where}: layers {shapes} are not the published NBRDF network {' → '.join(map(str, ARCHITECTURE))}"
        )
    for k, (w, b) in enumerate(layers):
        if not (np.isfinite(w).all() and np.isfinite(b).all()):
            raise NbrdfError(f"{where}: layer {k + 1} holds NaN or Inf weights")
    return tuple(layers)


#: The published architecture as a ``NAME.json`` sidecar lists it: (class_name, units, activation) per layer,
#: the last the Lambda layer exp(y) − 1.
_SIDECAR_LAYERS: Final = (("Dense", 21, "relu"), ("Dense", 21, "relu"), ("Dense", 3, "linear"),
                          ("Lambda", None, None))


def _check_architecture(doc_bytes: bytes, where: str) -> None:
    """Refuse a Keras architecture (``NAME.json``) other than the published one; any JSON gives one NbrdfError."""
    try:
        doc = json.loads(doc_bytes.decode("utf-8"))
    except RecursionError:
        raise NbrdfError(f"{where}: not a Keras model description (JSON nested too deeply)") from None
    except (UnicodeDecodeError, ValueError) as err:
        raise NbrdfError(f"{where}: not a Keras model description ({type(err).__name__}: {err})") from None
    config = doc.get("config") if isinstance(doc, dict) else None
    layers = config.get("layers") if isinstance(config, dict) else None
    if not isinstance(layers, list) or not all(isinstance(x, dict) and isinstance(x.get("config"), dict)
                                               for x in layers):
        raise NbrdfError(f"{where}: not a Keras model description (no list of layers, each an object with a "
                         "'config' object, under 'config' → 'layers')")
    found = tuple((x.get("class_name"), x["config"].get("units"), x["config"].get("activation")) for x in layers)
    if found != _SIDECAR_LAYERS:
        raise NbrdfError(
            f"{where}: architecture {reprlib.repr(found)} is not the published NBRDF network "
            "(Dense 21 relu, Dense 21 relu, Dense 3 linear, Lambda exp(y) − 1)"
        )


class Archive:
    """The fits of one archive (a ``.zip`` or a folder of ``NAME.h5`` [+ ``NAME.json``] files).

    ``names`` are the fits' names (file stems, sorted); :meth:`fit` reads
    one.  A fit's ``NAME.json``, when present, must describe the published
    architecture.  Members are looked up anywhere in the archive (the
    published archives keep them in one top folder); two fits of the same
    name are an error.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._zip: zipfile.ZipFile | None = None
        members: dict[str, str] = {}
        if self.path.is_dir():
            try:
                files = sorted(p.relative_to(self.path).as_posix() for p in self.path.rglob(f"*{_H5_SUFFIX}")
                               if p.is_file())
            except OSError as err:
                raise NbrdfError(f"{self.path}: cannot list the folder ({err.strerror or err})") from None
        elif self.path.is_file():
            try:
                self._zip = zipfile.ZipFile(self.path)
            except (zipfile.BadZipFile, OSError, EOFError, ValueError) as err:
                raise NbrdfError(f"{self.path}: not a zip archive or a folder of fits ({err})") from None
            files = sorted(i.filename for i in self._zip.infolist() if i.filename.endswith(_H5_SUFFIX) and not i.is_dir())
        else:
            raise NbrdfError(f"{self.path}: no such archive or folder")
        for member in files:
            name = member.rsplit("/", 1)[-1][: -len(_H5_SUFFIX)]
            if name in members:
                raise NbrdfError(f"{self.path}: two fits named {name!r} ({members[name]}, {member})")
            members[name] = member
        if not members:
            raise NbrdfError(f"{self.path}: no NBRDF fits (*{_H5_SUFFIX}) in the archive")
        self._members = members

    @property
    def names(self) -> list[str]:
        """The fits' names (file stems), sorted."""
        return sorted(self._members)

    def member(self, name: str) -> str:
        """The member (path inside the archive) of fit ``name``."""
        return self._members[name]

    def _read(self, member: str) -> bytes:
        where = f"{self.path}:{member}"
        try:
            if self._zip is not None:
                info = self._zip.getinfo(member)
                if info.file_size > _MAX_FIT_BYTES:
                    raise NbrdfError(f"{where}: {info.file_size} bytes, too large for a fit")
                if info.flag_bits & 0x1:
                    raise NbrdfError(f"{where}: encrypted (password-protected); give an archive without a password")
                if info.compress_type not in _ZIP_METHODS:
                    raise NbrdfError(f"{where}: compression method {info.compress_type} is not supported (stored, "
                                     "deflate, bzip2 or lzma are); recompress the archive")
                return self._zip.read(member)
            file = self.path / member
            if file.stat().st_size > _MAX_FIT_BYTES:
                raise NbrdfError(f"{where}: too large for a fit")
            return file.read_bytes()
        except NbrdfError:
            raise
        except (zlib.error, LZMAError) as err:
            raise NbrdfError(f"{where}: cannot be read: damaged compressed data ({err})") from None
        except (OSError, KeyError, zipfile.BadZipFile, EOFError, NotImplementedError, RuntimeError) as err:
            # RuntimeError, NotImplementedError: what zipfile raises for encryption or a method this Python
            # lacks, should the checks above miss one
            raise NbrdfError(f"{where}: cannot be read ({type(err).__name__}: {err})") from None

    def _exists(self, member: str) -> bool:
        if self._zip is not None:
            try:
                self._zip.getinfo(member)
                return True
            except KeyError:
                return False
        return (self.path / member).is_file()

    def fit(self, name: str) -> Fit:
        """Read fit ``name``; :class:`NbrdfError` naming the archive and member if it is missing or not an NBRDF fit."""
        member = self._members.get(name)
        if member is None:
            shown = ", ".join(self.names[:8]) + (" …" if len(self._members) > 8 else "")
            raise NbrdfError(f"{self.path}: no fit named {name!r} ({len(self._members)} fits: {shown})")
        data = self._read(member)
        where = f"{self.path}:{member}"
        arch = member[: -len(_H5_SUFFIX)] + ".json"
        if self._exists(arch):
            _check_architecture(self._read(arch), f"{self.path}:{arch}")
        layers = _read_h5(data, where)
        return Fit(name=name, layers=layers, source=where, sha256=hashlib.sha256(data).hexdigest())

    def __iter__(self) -> Iterator[Fit]:
        for name in self.names:
            yield self.fit(name)

    def close(self) -> None:
        """Close the zip file (a folder needs nothing)."""
        if self._zip is not None:
            self._zip.close()
            self._zip = None

    def __enter__(self) -> "Archive":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def open_archive(path: str | os.PathLike[str]) -> Archive:
    """The fits of a ``.zip`` archive or a folder (:class:`Archive`)."""
    return Archive(path)


def _features(theta_h: NDArray[np.float64], theta_d: NDArray[np.float64], phi_d: NDArray[np.float64]) -> NDArray[np.float64]:
    """The network's input (n, 6): half vector (φh = 0) and difference vector, Cartesian."""
    sd = np.sin(theta_d)
    return np.stack(
        [np.sin(theta_h), np.zeros_like(theta_h), np.cos(theta_h), sd * np.cos(phi_d), sd * np.sin(phi_d), np.cos(theta_d)],
        axis=1,
    )


def _forward(fit: Fit, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """exp(MLP(x)) − 1 for input rows ``x`` (n, 6)."""
    (w1, b1), (w2, b2), (w3, b3) = fit.layers
    h = x @ w1
    h += b1
    np.maximum(h, 0.0, out=h)
    h = h @ w2
    h += b2
    np.maximum(h, 0.0, out=h)
    y = h @ w3
    y += b3
    return np.expm1(y)


def evaluate(fit: Fit, theta_h: ArrayLike, theta_d: ArrayLike, phi_d: ArrayLike) -> NDArray[np.float64]:
    """The fit's BRDF (n, 3) in sr⁻¹ at half/difference angles (radians; φh = 0), unclamped."""
    th, td, pd = (np.asarray(a, dtype=np.float64).ravel() for a in np.broadcast_arrays(theta_h, theta_d, phi_d))
    return _forward(fit, _features(th, td, pd))


@lru_cache(maxsize=1)
def _grid() -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Flat indices of the measured cells and the network's input at their centres."""
    cells = np.flatnonzero(merl.measured_mask().ravel())
    th, td, pd = (a.ravel()[cells] for a in merl.cell_centres())
    x = _features(th, td, pd)
    x.setflags(write=False)
    return cells, x


def fit_table(fit: Fit, *, block: int = BLOCK_CELLS) -> FitTable:
    """The fit evaluated at the centre of every measured MERL cell: a ``(3, 90, 90, 180)`` table, physical units.

    Unmeasured cells (light or view below the horizon) hold ``-SCALES[c]``
    (raw −1); negative network outputs are clamped to 0 and counted.
    """
    cells, x = _grid()
    flat = np.empty((3, merl.N_CELLS))
    flat[...] = -merl.SCALES[:, None]
    clamped = 0
    for a in range(0, cells.size, block):
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below, in one line
            rho = _forward(fit, x[a : a + block])
        neg = rho < 0.0
        clamped += int(neg.sum())
        rho[neg] = 0.0
        flat[:, cells[a : a + block]] = rho.T
    if not np.isfinite(flat).all():
        raise NbrdfError(f"{fit.source}: the fit overflows (values beyond float64) on the MERL grid")
    return FitTable(flat.reshape(merl.SHAPE), clamped, int(cells.size))


#: Largest share of a table's values (3 channels × measured cells) that may be negative network outputs,
#: clamped at 0.  The 159 shipped fits: 0 to 20.0 % (MERL black-obsidian; RGL's largest 17.1 %, medians 0,
#: 0.9 %, 0; docs/results/data.md); more than half of a table black is no material (all-negative: 100 %).
MAX_CLAMPED_SHARE: Final = 0.5
#: Largest directional albedo at normal incidence of each channel (the smallest allowed: anything above 0).
#: The 159 shipped fits: 0.0042 (MERL black-obsidian) to 1.098 (RGL chm_orange_rgb, a fit 10 % above
#: energy conservation; docs/results/data.md); 2, 1.8× the largest, leaves room for a user's glossier fits
#: and still refuses a table that reflects twice the light it receives.
MAX_ALBEDO: Final = 2.0
#: A network output y below this cannot overflow exp(y) − 1 in float64 (log of the largest float64: 709.78;
#: 1 of margin covers the rounding of the bound).
_Y_SAFE: Final = float(np.log(np.finfo(np.float64).max)) - 1.0
#: The box holding the network's input on the MERL grid (:func:`_features`): sin θh, 0, cos θh,
#: sin θd cos φd, sin θd sin φd, cos θd with θh, θd ∈ [0, π/2] and φd ∈ [0, π].
_INPUT_BOX: Final = (np.array([0.0, 0.0, 0.0, -1.0, 0.0, 0.0]), np.array([1.0, 0.0, 1.0, 1.0, 1.0, 1.0]))
#: A lower bound of the total weight of the measured cells in the directional albedo at normal incidence
#: (:func:`brdfpipe.data.merl.directional_albedo` of a table of ones: 3.1412, the quadrature of
#: ∫ cos θo dωo = π; a test checks the bound): a table at least ρ everywhere has an albedo ≥ 3ρ.
_ALBEDO_WEIGHT_MIN: Final = 3.0


def output_bounds(fit: Fit) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bounds ``(lo, hi)``, each (3,), of the network's output y (before exp(y) − 1) on the whole MERL grid.

    Interval arithmetic over the input box ``[0,1] × {0} × [0,1] × [−1,1] × [0,1] × [0,1]``, which
    holds the input of every cell centre (:func:`_features`): a dense layer maps ``[lo, hi]`` to
    ``[lo·W⁺ + hi·W⁻ + b, hi·W⁺ + lo·W⁻ + b]`` (W⁺, W⁻ the positive and negative parts of W) and the
    ReLU clips both ends at 0, so every y the grid gives lies in ``[lo, hi]`` (up to the rounding of
    both computations, ~1e-13 relative).  The box ignores that the inputs are parts of unit vectors:
    the bound is loose (the shipped fits: hi ≤ 103, lo ≥ −37), never wrong.
    """
    lo, hi = _INPUT_BOX
    for k, (w, b) in enumerate(fit.layers):
        pos, neg = np.maximum(w, 0.0), np.minimum(w, 0.0)
        lo, hi = lo @ pos + hi @ neg + b, hi @ pos + lo @ neg + b
        if k < len(fit.layers) - 1:
            lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
    return lo, hi


def check_fit(fit: Fit) -> None:
    """The parse-time check of a read fit: refuse what :func:`output_bounds` proves the evaluation would refuse.

    Cheap (a few microseconds a fit) except in the one case the bound leaves open.  With ``[lo, hi]``
    the bound of a channel's output y on the MERL grid:

    * ``hi < 0``: every value of the channel is negative, clamped at 0 — an all-black channel, whose
      albedo (0) :func:`check_table` refuses;
    * ``hi ≥ log(float64 max) − 1``: the bound cannot exclude an overflow, so the fit is evaluated on the
      grid (:func:`fit_table`, :func:`check_table`: about a second; none of the shipped fits, hi ≤ 103);
    * ``lo > 0``: every value is at least ``expm1(lo)``, so the albedo at normal incidence is at least
      ``3 expm1(lo)`` (:data:`_ALBEDO_WEIGHT_MIN`); above :data:`MAX_ALBEDO` it is refused.

    Shapes, finite weights and the sidecar are checked when the fit is read (:meth:`Archive.fit`).
    """
    lo, hi = output_bounds(fit)
    if (hi < 0.0).any():
        c = int(np.argmax(hi < 0.0))
        raise NbrdfError(f"{fit.source}: channel {'rgb'[c]} is negative everywhere on the MERL grid (its network "
                         f"output is at most {hi[c]:.3g} < 0): an all-black channel is not a material")
    if hi.max() >= _Y_SAFE:
        check_table(fit, fit_table(fit))
    for c in range(lo.size):
        least = math.expm1(min(lo[c], _Y_SAFE))  # ≥ e^708 is bright enough to say so
        if least * _ALBEDO_WEIGHT_MIN > MAX_ALBEDO:
            raise NbrdfError(f"{fit.source}: channel {'rgb'[c]} is at least {least:.3g} sr⁻¹ everywhere on the MERL "
                             f"grid, so its directional albedo at normal incidence is at least "
                             f"{least * _ALBEDO_WEIGHT_MIN:.3g}, beyond the allowed (0, {MAX_ALBEDO:g}]: "
                             "not a material")


def check_table(fit: Fit, result: FitTable) -> NDArray[np.float64]:
    """Refuse a table that is not a material; returns its directional albedo at normal incidence (r, g, b).

    :class:`NbrdfError` naming the fit, the statistic, its value and the allowed range when more than
    :data:`MAX_CLAMPED_SHARE` of its values were clamped at 0, or when a channel's directional albedo
    at normal incidence (:func:`brdfpipe.data.merl.directional_albedo`) is not in (0, :data:`MAX_ALBEDO`].
    """
    share = result.clamped / (3 * result.measured_cells)
    if share > MAX_CLAMPED_SHARE:
        raise NbrdfError(f"{fit.source}: {share:.1%} of the values are negative (clamped at 0 on the MERL grid); at "
                         f"most {MAX_CLAMPED_SHARE:.0%} allowed (the shipped fits: at most 20%): not a material")
    albedo = merl.directional_albedo(result.table, [0.0])[0]
    if not ((albedo > 0.0) & (albedo <= MAX_ALBEDO)).all():
        raise NbrdfError(f"{fit.source}: directional albedo at normal incidence (r, g, b) = "
                         f"({', '.join(f'{a:.3g}' for a in albedo)}), allowed (0, {MAX_ALBEDO:g}] (the shipped fits: "
                         "0.0042 to 1.1): not a material")
    return albedo


#: sha256 of the zip archives whose every fit passes :func:`check_archive`: the shipped ones (their digests
#: in the registry, checked by a test) and those that passed in this process.
_CHECKED: set[str] = {d.archive_sha256 for d in databases.DATABASES.values() if d.archive_sha256}


def check_archive(path: str | os.PathLike[str]) -> list[str]:
    """Read and check every fit of an archive (the workflow's parse time); returns the fits' names.

    Each fit is read (:meth:`Archive.fit`: readable member, sidecar, layer shapes, finite weights)
    and checked (:func:`check_fit`); the first bad one raises :class:`NbrdfError` naming the archive,
    the member and the problem.  About 2–3 ms a fit (the 100 of merl-nbrdf: 0.2–0.3 s, h5py's import
    aside); a zip archive whose sha256 is one that passed (:data:`_CHECKED`: the shipped archives, and
    those checked earlier in this process) is not read again.
    """
    with open_archive(path) as archive:
        key = None
        if archive.path.is_file():
            with open(archive.path, "rb") as fh:
                key = hashlib.file_digest(fh, "sha256").hexdigest()
        if key not in _CHECKED:
            for name in archive.names:
                check_fit(archive.fit(name))
            if key is not None:
                _CHECKED.add(key)
        return archive.names


def fit_names(archive: Archive, requested: Sequence[str] | None = None) -> list[str]:
    """``requested`` fits (all when None or empty), checked against the archive; NbrdfError naming unknown ones."""
    if not requested:
        return archive.names
    unknown = [n for n in requested if n not in archive.names]
    if unknown:
        raise NbrdfError(f"{archive.path}: no fit named {', '.join(repr(n) for n in unknown)}")
    return list(requested)


@lru_cache(maxsize=1)
def _shipped_fits() -> dict[str, str]:
    """sha256 of every fit of the shipped archives → the database it belongs to."""
    out: dict[str, str] = {}
    for name in databases.FIT_DATABASES:
        spec = databases.DATABASES[name]
        if spec.archive is None:
            continue
        with zipfile.ZipFile(databases.shipped_archive(name)) as z:
            for info in z.infolist():
                if info.filename.endswith(_H5_SUFFIX):
                    out[hashlib.sha256(z.read(info)).hexdigest()] = name
    return out


def fit_database(fit: Fit) -> str:
    """The database label of tables made from ``fit``: the shipped database whose weights these are, else ``nbrdf``."""
    return _shipped_fits().get(fit.sha256, "nbrdf")


def write_fit(fit: Fit, out: str | os.PathLike[str], *, name: str | None = None) -> FitTable:
    """Evaluate ``fit`` on the MERL grid and write it as a MERL file with its provenance mark (atomic).

    ``name``: the material name the file is written under (default
    :func:`material_name` of the fit); the mark binds it, records the fit,
    its archive, the digest of its weights and the clamped count, and is of
    the fit's database (:func:`fit_database`), so the file is never taken for
    a measurement.  A table that is not a material (:func:`check_table`) is refused before anything is
    written.
    """
    out = Path(out)
    name = material_name(fit.name) if name is None else name
    result = fit_table(fit)
    check_table(fit, result)
    archive = fit.source.rsplit(":", 1)[0]
    mark = provenance.fit_mark(database=fit_database(fit), name=name, fit=fit.name, archive=Path(archive).name,
                               fit_sha256=fit.sha256, clamped=result.clamped)
    merl.write_merl(out, result.table, mark=mark)
    return result


def _own_file(path: Path) -> bool:
    """``path`` is a table an earlier ``write_fits`` wrote (a fit-made MERL file)."""
    try:
        mark = provenance.read_mark(path)
    except (OSError, ValueError):
        return False
    return mark is not None and mark.kind in databases.FIT_DATABASES


def write_fits(
    archive_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], names: Sequence[str] | None = None
) -> list[tuple[Path, FitTable]]:
    """``brdfpipe nbrdf``: every fit of ``names`` (default all) as ``OUT_DIR/<material>.binary``.

    The folder must be new, empty, or hold only tables written by this
    function (a fit-made mark): anything else is refused before any work
    (:class:`NbrdfError` naming the file), so no foreign file is replaced.
    Every material name must pass :func:`brdfpipe.data.databases.check_material_name`
    and every fit :func:`check_fit` before any evaluation; the tables are written
    into a temporary folder inside ``out_dir`` and moved into place only when
    every one passed :func:`check_table`, so a refused fit leaves ``out_dir``
    as it was (or absent, with the folders the call made).  Returns the paths and their tables' clamped counts, in the order of
    ``names``.
    """
    out_dir = Path(out_dir)
    with open_archive(archive_path) as archive:
        chosen = fit_names(archive, names)
        for n in chosen:
            databases.check_material_name(material_name(n), f"{archive.path}:{archive.member(n)}")
        targets = {n: out_dir / f"{material_name(n)}{_BINARY}" for n in chosen}
        clash = sorted({material_name(n) for n in chosen if sum(material_name(m) == material_name(n) for m in chosen) > 1})
        if clash:
            raise NbrdfError(f"{archive.path}: fits whose names differ only by '_' and '-' would share a file: "
                             f"{', '.join(clash)}")
        if out_dir.exists():
            if not out_dir.is_dir():
                raise NbrdfError(f"--out {out_dir}: exists and is not a folder")
            foreign = [
                e.name for e in sorted(out_dir.iterdir())
                if atomic.output_of(e) == e  # temporaries of a killed writer are cleaned by the next write
                and not (e.is_file() and not e.is_symlink() and e.name.endswith(_BINARY) and _own_file(e))
            ]
            if foreign:
                shown = ", ".join(foreign[:8]) + (f" and {len(foreign) - 8} more" if len(foreign) > 8 else "")
                raise NbrdfError(f"--out {out_dir}: holds files `brdfpipe nbrdf` did not write ({shown}); refusing "
                                 "to write there: choose a new or empty folder")
        fits = [archive.fit(n) for n in chosen]
    for fit in fits:
        check_fit(fit)
    created = next((p for p in (*reversed(out_dir.parents), out_dir) if not p.exists()), None)
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic.clean_stale_siblings(out_dir / "tables")
    stage = atomic.tmp_sibling(out_dir / "tables")  # inside --out: its parent may not be writable
    try:
        done = [(targets[f.name], write_fit(f, stage / targets[f.name].name)) for f in fits]
        for path, _ in done:
            os.replace(stage / path.name, path)
    except BaseException:
        if created is not None:
            atomic.remove_tree(created)  # the folders this call made: nothing else is in them
        raise
    finally:
        atomic.remove_tree(stage)
    return done


def evaluate_to_files(
    *,
    archive: str | os.PathLike[str],
    fits: Mapping[str, str],
    binaries: Sequence[str | os.PathLike[str]],
    rows: Sequence[str | os.PathLike[str]] | None = None,
    database: str,
    threads: int = 1,
) -> dict[str, int]:
    """The workflow's data stage for a database of fits (rule ``evaluate_fits``): one job for every material.

    ``fits`` maps each material (in the order of ``binaries`` and ``rows``)
    to its fit's name in ``archive``.  Each fit is evaluated on the MERL grid
    and written as a marked MERL file (:func:`write_fit`); with ``rows``,
    that file is also ingested into its one-row store
    (:func:`brdfpipe.data.ingest.ingest_material`, which checks that its mark
    is of ``database`` and names the material).  ``threads`` materials are
    processed at once (NumPy releases the GIL in the network's products and
    in the writes).  One process instead of one job per material: the
    evaluation of one material costs less than a job's start-up.  Returns the
    clamped count per material; raises :class:`NbrdfError` for a fit of
    another database than ``database``.
    """
    from concurrent.futures import ThreadPoolExecutor

    from brdfpipe.data import ingest

    materials = list(fits)
    if len(binaries) != len(materials) or (rows is not None and len(rows) != len(materials)):
        raise ValueError(f"{len(materials)} materials, {len(binaries)} binaries, "
                         f"{'no' if rows is None else len(rows)} rows")
    t0 = time.perf_counter()
    with open_archive(archive) as a:
        loaded = {m: a.fit(fits[m]) for m in materials}
    wrong = sorted(m for m, f in loaded.items() if fit_database(f) != database)
    if wrong:
        raise NbrdfError(f"{archive}: the fits of {', '.join(wrong[:5])} are not those of the {database} database "
                         f"(their weights are {fit_database(loaded[wrong[0]])}'s): the archive changed")

    def one(k: int) -> tuple[str, int]:
        m = materials[k]
        result = write_fit(loaded[m], binaries[k], name=m)
        if rows is not None:
            ingest.ingest_material(binaries[k], rows[k], name=m, expect={"database": database})
        return m, result.clamped

    _grid()  # once, before the threads share it
    # one BLAS thread per material in flight: the products are small, threads of their own only spin
    with blas_threads(1), ThreadPoolExecutor(max_workers=max(1, int(threads))) as pool:
        clamped = dict(pool.map(one, range(len(materials))))
    logger.info("%d %s fits evaluated on the MERL grid in %.1f s (%d threads); %d values clamped at 0",
                len(materials), database, time.perf_counter() - t0, threads, sum(clamped.values()))
    return clamped


_LUMA: Final = (0.2126, 0.7152, 0.0722)


def albedo_rows(binaries: Mapping[str, str | os.PathLike[str]], database: str,
                theta_i_deg: float = 0.0) -> list[dict[str, Any]]:
    """Directional albedo ``∫ ρ cos θo dωo`` at incidence ``theta_i_deg`` of each table (:data:`~brdfpipe.registry.tables.FIT_ALBEDO`).

    ``binaries`` maps material → MERL file; computed with
    :func:`brdfpipe.data.merl.directional_albedo` (MERL's θh grid, 360 φh
    steps).  A radiometric check of fit-made tables: a near-white diffuse
    reference (RGL's spectralon) should reflect nearly all the light at
    normal incidence.
    """
    out = []
    for material, path in binaries.items():
        a = merl.directional_albedo(merl.read_merl(path), np.radians([float(theta_i_deg)]))[0]
        out.append({"database": database, "material": material, "theta_i_deg": float(theta_i_deg),
                    "r": float(a[0]), "g": float(a[1]), "b": float(a[2]),
                    "luminance": float(np.dot(a, _LUMA))})
    return out


def _csv_text(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    import csv

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([repr(v) if isinstance(v, float) else str(v) for v in (r[c] for c in columns)])
    return buf.getvalue()


def evaluate_to_store(
    *,
    archive: str | os.PathLike[str],
    fits: Mapping[str, str],
    binaries: Sequence[str | os.PathLike[str]],
    store_out: str | os.PathLike[str],
    albedo_out: str | os.PathLike[str],
    database: str,
    threads: int = 1,
) -> dict[str, int]:
    """The fits of a database outside the run's (config ``unseen``): MERL files, a store of their own, albedos.

    The workflow's ``evaluate_unseen_fits`` job, one per unseen database:
    every fit of ``fits`` (material → fit name, in the order of
    ``binaries``) evaluated on the MERL grid and written as a marked MERL
    file (:func:`evaluate_to_files`, which refuses weights of another
    database than ``database``), ingested into private row stores and
    assembled into the store ``store_out`` (label ``database``: a store has
    one label, so each unseen database has its own), and the directional
    albedo of each table at normal incidence written to ``albedo_out``
    (:func:`albedo_rows`; CSV, :data:`~brdfpipe.registry.tables.FIT_ALBEDO`).  Returns the clamped
    count per material.
    """
    from brdfpipe.data import ingest, store

    store_out = Path(store_out)
    atomic.check_replaceable(store_out, replaceable=store.is_store)
    store_out.parent.mkdir(parents=True, exist_ok=True)
    atomic.clean_stale_siblings(store_out)
    work = atomic.tmp_sibling(store_out, "rows")
    work.mkdir()
    try:
        rows = [work / f"{i:04d}.zarr" for i in range(len(binaries))]
        clamped = evaluate_to_files(archive=archive, fits=fits, binaries=binaries, rows=rows, database=database,
                                    threads=threads)
        ingest.assemble_store(rows, store_out, database=database, threads=max(1, int(threads)), link=True)
    finally:
        atomic.remove_tree(work)
    rows_a = albedo_rows(dict(zip(fits, binaries)), database)
    integrity.write_csv(albedo_out, _csv_text(tables.FIT_ALBEDO, rows_a))
    logger.info("%d %s tables -> %s; directional albedo at normal incidence -> %s", len(binaries), database,
                store_out, albedo_out)
    return clamped
