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

The evaluation runs in float64 (the weights are float32), in blocks of
:data:`BLOCK_CELLS` cells.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import time
import zipfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import atomic, integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import databases, merl, provenance
from brdfpipe.spec import tables

__all__ = [
    "NbrdfError",
    "ARCHITECTURE",
    "BLOCK_CELLS",
    "Fit",
    "FitTable",
    "Archive",
    "open_archive",
    "material_name",
    "evaluate",
    "fit_table",
    "fit_names",
    "fit_database",
    "write_fit",
    "write_fits",
    "evaluate_to_files",
    "ALBEDO_COLUMNS",
    "albedo_rows",
    "evaluate_to_store",
]

#: Layer widths of the published fits: input, hidden, hidden, output.
ARCHITECTURE: Final = (6, 21, 21, 3)
#: Activations of the published fits' dense layers (then exp(y) − 1).
_ACTIVATIONS: Final = ("relu", "relu", "linear")
#: Cells evaluated per block: the (block, 21) temporaries stay in the cache (2,048–4,096 cells are
#: 2.3× faster than 131,072 on this project's 2-core AMD EPYC).
BLOCK_CELLS: Final = 4_096
logger = logging.getLogger("brdfpipe.data.nbrdf")

_H5_SUFFIX: Final = ".h5"
_BINARY: Final = ".binary"
_MAX_FIT_BYTES: Final = 16 * 1024 * 1024  # a published fit is ~8 kB; refuse absurd members


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
    widths = [layers[0][0].shape[0]] + [w.shape[1] for w, _ in layers] if layers else []
    if tuple(widths) != ARCHITECTURE or any(w.ndim != 2 or b.shape != (w.shape[1],) for w, b in layers):
        shapes = [(tuple(w.shape), tuple(b.shape)) for w, b in layers]
        raise NbrdfError(
            f"{where}: layers {shapes} are not the published NBRDF network {' → '.join(map(str, ARCHITECTURE))}"
        )
    for k, (w, b) in enumerate(layers):
        if not (np.isfinite(w).all() and np.isfinite(b).all()):
            raise NbrdfError(f"{where}: layer {k + 1} holds NaN or Inf weights")
    return tuple(layers)


def _check_architecture(doc_bytes: bytes, where: str) -> None:
    """Refuse a Keras architecture (``NAME.json``) other than the published one."""
    try:
        doc = json.loads(doc_bytes.decode("utf-8"))
        layers = doc["config"]["layers"]
        dense = [lay["config"] for lay in layers if lay.get("class_name") == "Dense"]
        other = [lay.get("class_name") for lay in layers if lay.get("class_name") not in ("Dense", "Lambda")]
        acts = tuple(d["activation"] for d in dense)
        units = tuple(int(d["units"]) for d in dense)
    except (UnicodeDecodeError, ValueError, KeyError, TypeError) as err:
        raise NbrdfError(f"{where}: not a Keras model description ({type(err).__name__}: {err})") from None
    if other or acts != _ACTIVATIONS or units != ARCHITECTURE[1:] or layers[-1].get("class_name") != "Lambda":
        raise NbrdfError(
            f"{where}: architecture {list(zip(units, acts))} (+{other or 'no other layers'}) is not the published "
            "NBRDF network (Dense 21 relu, Dense 21 relu, Dense 3 linear, Lambda exp(y) − 1)"
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
            files = sorted(p.relative_to(self.path).as_posix() for p in self.path.rglob(f"*{_H5_SUFFIX}") if p.is_file())
        elif self.path.is_file():
            try:
                self._zip = zipfile.ZipFile(self.path)
            except (zipfile.BadZipFile, OSError) as err:
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
                return self._zip.read(member)
            file = self.path / member
            if file.stat().st_size > _MAX_FIT_BYTES:
                raise NbrdfError(f"{where}: too large for a fit")
            return file.read_bytes()
        except NbrdfError:
            raise
        except (OSError, KeyError, zipfile.BadZipFile, EOFError) as err:
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
        rho = _forward(fit, x[a : a + block])
        neg = rho < 0.0
        clamped += int(neg.sum())
        rho[neg] = 0.0
        flat[:, cells[a : a + block]] = rho.T
    if not np.isfinite(flat).all():
        raise NbrdfError(f"{fit.source}: the fit overflows (values beyond float64) on the MERL grid")
    return FitTable(flat.reshape(merl.SHAPE), clamped, int(cells.size))


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
    a measurement.
    """
    out = Path(out)
    name = material_name(fit.name) if name is None else name
    result = fit_table(fit)
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
    before anything is written.  Each file is written atomically.  Returns the paths and their tables'
    clamped counts, in the order of ``names``.
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
        out_dir.mkdir(parents=True, exist_ok=True)
        done = []
        for n in chosen:
            done.append((targets[n], write_fit(archive.fit(n), targets[n])))
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
    (:func:`brdfpipe.data.store.ingest_material`, which checks that its mark
    is of ``database`` and names the material).  ``threads`` materials are
    processed at once (NumPy releases the GIL in the network's products and
    in the writes).  One process instead of one job per material: the
    evaluation of one material costs less than a job's start-up.  Returns the
    clamped count per material; raises :class:`NbrdfError` for a fit of
    another database than ``database``.
    """
    from concurrent.futures import ThreadPoolExecutor

    from brdfpipe.data import store

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
            store.ingest_material(binaries[k], rows[k], name=m, expect={"database": database})
        return m, result.clamped

    _grid()  # once, before the threads share it
    # one BLAS thread per material in flight: the products are small, threads of their own only spin
    with blas_threads(1), ThreadPoolExecutor(max_workers=max(1, int(threads))) as pool:
        clamped = dict(pool.map(one, range(len(materials))))
    logger.info("%d %s fits evaluated on the MERL grid in %.1f s (%d threads); %d values clamped at 0",
                len(materials), database, time.perf_counter() - t0, threads, sum(clamped.values()))
    return clamped


#: Columns of an unseen database's albedo CSV (:func:`evaluate_to_store`).
ALBEDO_COLUMNS: Final = tables.FIT_ALBEDO
_LUMA: Final = (0.2126, 0.7152, 0.0722)


def albedo_rows(binaries: Mapping[str, str | os.PathLike[str]], database: str,
                theta_i_deg: float = 0.0) -> list[dict[str, Any]]:
    """Directional albedo ``∫ ρ cos θo dωo`` at incidence ``theta_i_deg`` of each table (:data:`ALBEDO_COLUMNS`).

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
    (:func:`albedo_rows`; CSV, :data:`ALBEDO_COLUMNS`).  Returns the clamped
    count per material.
    """
    from brdfpipe.data import store

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
        store.assemble_store(rows, store_out, database=database, threads=max(1, int(threads)), link=True)
    finally:
        atomic.remove_tree(work)
    rows_a = albedo_rows(dict(zip(fits, binaries)), database)
    integrity.write_csv(albedo_out, _csv_text(ALBEDO_COLUMNS, rows_a))
    logger.info("%d %s tables -> %s; directional albedo at normal incidence -> %s", len(binaries), database,
                store_out, albedo_out)
    return clamped
