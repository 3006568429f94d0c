"""Acquisition of materials outside the training database: what the optimised set-ups are for.

The leave-out evaluation (:mod:`brdfpipe.acquisition.evaluation`) measures
held-out materials of the run's own database.  Here the model trained on the
run's database (its ``train`` split: ρ_ref, w, μ, Q) and the direction sets
optimised with it reconstruct materials of *other* databases (config
``unseen``: e.g. the RGL and Nielsen materials through their NBRDF fits when
the run is on MERL's), which no model of the run has seen:

* **table lookup** — for every set of the given directions files (the point
  sets and the near-field sets of the error metric, every n), the unseen
  material's values at :func:`brdfpipe.acquisition.geometry.observation_cells`
  of the set's configurations (cells that are not model columns dropped,
  repeats repeated), c̄ by eq. 4 and ``rms_log`` = ‖x − μ − Qc̄‖/√p, exactly
  as :func:`~brdfpipe.acquisition.evaluation.evaluate` does for the
  held-out materials; plus the ``deviation`` floor (every cell observed);
* **closed loop** — the observation tables read off the rendered
  photographs of the unseen materials
  (:func:`brdfpipe.rendering.capture.capture_materials_to_file`, one file per
  database): ``closedloop_noiseless_rms_log`` (noiseless render) and
  ``closedloop_rms_log`` (the sensor's photograph), as
  :mod:`brdfpipe.acquisition.closedloop` does for the held-out materials,
  with the counts ``observations``, ``closedloop_observations`` and
  ``closedloop_masked``.

All errors are in log-mapped space, by the Gram identity from one streamed
pass over Q and the unseen rows per database
(:func:`brdfpipe.acquisition.evaluation.row_statistics`): ≈ the cost of
pass 1 of the held-out evaluation.  ``relrms_linear`` (a second pass whose
cost grows with sets × rows: ~60 CPU-s for the default 59 materials and 28
sets) is not computed here.

``unseen.csv`` has the columns of ``errors.csv`` plus ``model_database``:
``database`` is the unseen material's database (e.g. ``rgl-nbrdf``: never
``merl`` for a fit-made table, the store's own label), ``model_database``
the database the model and the direction sets were trained on; ``split``
the model's split (``train``).  Means over each database's materials are
material ``mean``, channel ``all``.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.acquisition import geometry
from brdfpipe.acquisition.evaluation import CHANNELS, row_statistics, write_errors
from brdfpipe.acquisition.metrics import DEFAULT_ETA, check_eta, reconstruct_coefficients
from brdfpipe.acquisition.optimize import read_directions
from brdfpipe.acquisition.svd import Model, open_model
from brdfpipe.core import integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import logmap, merl
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import open_store
from brdfpipe.registry import tables

__all__ = [
    "MANY_FORMAT",
    "ObservationTable",
    "read_many_observations",
    "evaluate_unseen",
    "write_unseen",
]

logger = logging.getLogger("brdfpipe.acquisition.unseen")

F64 = NDArray[np.float64]

#: Format of the capture's many-material observation file (written by brdfpipe.rendering.capture, which
#: this layer may not import: the value is the same string there).
MANY_FORMAT: Final = "brdfpipe.capture.observations-many/1"
_OBS_KEYS: Final = ("wi", "wo", "rgb")
_SOURCES: Final = {"noiseless": "closedloop_noiseless_", "sensor": "closedloop_"}


@dataclass(frozen=True)
class ObservationTable:
    """One observation table of a many-material capture file: its cells, BRDF values and pixel counts."""

    material: str
    setup: str
    fov: float
    metric: str
    n: int
    source: str
    cells: NDArray[np.intp]
    rgb: F64
    counts: dict[str, int]


def read_many_observations(path: str | os.PathLike[str], *, database: str) -> list[ObservationTable]:
    """Every table of a capture file of many materials (:data:`MANY_FORMAT`), checked.

    The file must be of ``database`` (its recorded label).  ValueError naming
    the file for another format or database, a malformed index, arrays of
    the wrong shape, or values that are negative or not finite.
    """
    path = Path(path)
    z = integrity.load_npz(path, kind="observations file")
    try:
        if "format" not in z or str(z["format"]) != MANY_FORMAT:
            raise ValueError(f"not a capture file of many materials (format {MANY_FORMAT})")
        label = str(z["database"])
        index = json.loads(str(z["index"]))
        arrays = {k: v for k, v in z.items() if k.split("_")[0] in _OBS_KEYS}
    except (KeyError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from exc
    if label != database:
        raise ValueError(f"{path}: observations of database {label!r}, expected {database!r}")
    out = []
    for i, e in enumerate(index):
        try:
            wi, wo, rgb = (np.asarray(arrays[f"{k}_{i}"], dtype=np.float64) for k in _OBS_KEYS)
            entry = (str(e["material"]), str(e["setup"]), float(e["fov"]), str(e["metric"]), int(e["n"]),
                     str(e["source"]), {str(k): int(v) for k, v in dict(e["counts"]).items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: table {i} is incomplete ({type(exc).__name__}: {exc})") from None
        k = rgb.shape[0]
        if (wi.shape != (k, 3) or wo.shape != (k, 3) or rgb.shape != (k, 3) or not np.isfinite(rgb).all()
                or (rgb < 0).any() or entry[5] not in _SOURCES):
            raise ValueError(f"{path}: table {i} ({entry[0]}, {entry[1]} {entry[2]:g}° n = {entry[4]}) has wrong "
                             "shapes, values or source")
        cells = merl.cell_index(wi, wo).astype(np.intp) if k else np.zeros(0, dtype=np.intp)
        out.append(ObservationTable(*entry[:6], cells, rgb, entry[6]))  # type: ignore[arg-type]
    return out


def _fov(value: float) -> float | int:
    return int(value) if float(value).is_integer() else float(value)


@dataclass(frozen=True)
class _Set:
    setup: str
    fov: float | int
    metric: str
    n: int
    cols: NDArray[np.intp]  # model columns observed (repeats repeated)

    @property
    def key(self) -> tuple[str, float, str, int]:
        return (self.setup, float(self.fov), self.metric, self.n)


def _sets(paths: Sequence[str | os.PathLike[str]], mdl: Model, lut: NDArray[np.intp],
          n_only: Sequence[int] | None = None) -> list[_Set]:
    """The direction sets of ``paths`` (all n, or only ``n_only``) with their observed model columns."""
    valid = lut >= 0
    out = []
    for p in paths:
        d = read_directions(p)
        if d.split != mdl.split or d.database != mdl.database:
            raise ValueError(f"{p}: directions of split {d.split!r} / database {d.database!r}, the model "
                             f"{mdl.path} is {mdl.split!r} / {mdl.database!r}")
        by_n = {s.n: s for s in d.sets}
        wanted = sorted(by_n) if n_only is None else [int(n) for n in n_only]
        for n in wanted:
            if n not in by_n:
                raise ValueError(f"{p}: no set of n = {n}")
            parts = [geometry.observation_cells(d.setup, c, valid) for c in by_n[n].configurations]
            cells = np.concatenate(parts) if parts else np.zeros(0, dtype=np.intp)
            out.append(_Set(d.setup.kind, _fov(d.setup.fov_deg), d.metric, n, lut[cells]))
    return out


def _evaluate_database(
    database: str,
    store_path: str | os.PathLike[str],
    mdl: Model,
    table_sets: Sequence[_Set],
    loop_sets: Sequence[_Set],
    observations: Sequence[ObservationTable],
    eta: float,
) -> list[dict[str, Any]]:
    """The rows of one unseen database (module docstring)."""
    st = open_store(store_path)
    materials = list(st.materials)
    lut = np.full(N_CELLS, -1, dtype=np.intp)
    lut[np.asarray(mdl.cells, dtype=np.intp)] = np.arange(mdl.p, dtype=np.intp)
    # closed-loop tables: one per (material, captured set, source), each exactly once
    loop_keys = {s.key for s in loop_sets}
    obs: dict[tuple[str, tuple[str, float, str, int], str], ObservationTable] = {}
    for t in observations:
        key = (t.material, (t.setup, float(t.fov), t.metric, t.n), t.source)
        if key in obs:
            raise ValueError(f"observations of {database}: {t.material} {t.setup} {t.fov:g}° n = {t.n} "
                             f"({t.source}) appears twice")
        if key[1] not in loop_keys or t.material not in materials:
            raise ValueError(f"observations of {database}: {t.material} {t.setup} {t.fov:g}° {t.metric} n = {t.n} "
                             "is not a captured set of a material of the store")
        obs[key] = t
    missing = [(m, s.key, src) for m in materials for s in loop_sets for src in _SOURCES if (m, s.key, src) not in obs]
    if missing:
        m, (setup, fov, metric, n), src = missing[0]
        raise ValueError(f"observations of {database}: no {src} table of {m} {setup} {fov:g}° {metric} n = {n} "
                         f"({len(missing)} missing)")
    loop_cols = {k: lut[t.cells] for k, t in obs.items()}
    keep = np.concatenate([s.cols for s in table_sets] + [c[c >= 0] for c in loop_cols.values()]
                          + [np.zeros(0, dtype=np.intp)])
    stats = row_statistics(st, mdl, materials, keep, database=database)
    m = 3 * len(materials)
    coef_cols: list[F64] = []
    owners: list[NDArray[np.intp]] = []
    labels: list[tuple[_Set, str]] = []  # (set, kind) of each block of m columns
    for s in table_sets:
        if s.cols.size:
            coef = reconstruct_coefficients(stats.q_at(s.cols), stats.y_at(s.cols).T, eta)
        else:
            logger.warning("%s %g %s n=%d observes no model column: reconstruction = mean", s.setup, s.fov,
                           s.metric, s.n)
            coef = np.zeros((mdl.k, m))
        coef_cols.append(coef)
        owners.append(np.arange(m, dtype=np.intp))
        labels.append((s, "rms_log"))
    counts: dict[tuple[str, tuple[str, float, str, int]], dict[str, float]] = {}
    for s in loop_sets:
        for source, prefix in _SOURCES.items():
            coef = np.zeros((mdl.k, m))
            for i, mat in enumerate(materials):
                t = obs[(mat, s.key, source)]
                cols = loop_cols[(mat, s.key, source)]
                ok = cols >= 0
                cols, v = cols[ok], t.rgb[ok]
                if cols.size:
                    x = logmap.forward(v.T, mdl.reference[cols], mdl.weight[cols], mdl.epsilon)
                    coef[:, 3 * i : 3 * i + 3] = reconstruct_coefficients(stats.q_at(cols), (x - mdl.mean[cols]).T,
                                                                           eta)
                else:
                    logger.warning("%s: no usable pixel of %s %g° n = %d (%s): its reconstruction is the model's "
                                   "mean", mat, s.setup, s.fov, s.n, source)
                if source == "sensor":
                    pixels = t.counts.get("pixels", 0)
                    counts[(mat, s.key)] = {
                        "observations": float(s.cols.size),
                        "closedloop_observations": float(cols.size),
                        "closedloop_masked": 1.0 - cols.size / pixels if pixels else 1.0,
                    }
            coef_cols.append(coef)
            owners.append(np.arange(m, dtype=np.intp))
            labels.append((s, f"{prefix}rms_log"))
    rms = stats.rms_log(np.concatenate(coef_cols, axis=1), np.concatenate(owners)) if coef_cols else np.zeros(0)
    base = {"database": database, "model_database": mdl.database, "split": mdl.split}
    rows: list[dict[str, Any]] = []
    chan = [(mat, CHANNELS[c]) for mat in materials for c in range(3)]

    def emit(setup: str, fov: float | int, metric: str, n: int, kind: str, values: F64) -> None:
        for (mat, ch), v in zip(chan, values):
            rows.append({**base, "setup": setup, "fov": fov, "metric": metric, "n": n, "material": mat,
                         "channel": ch, "kind": kind, "value": float(v)})
        rows.append({**base, "setup": setup, "fov": fov, "metric": metric, "n": n, "material": "mean",
                     "channel": "all", "kind": kind, "value": float(np.mean(values))})

    emit("all", 0, "none", 0, "deviation", stats.deviation())
    for b, (s, kind) in enumerate(labels):
        emit(s.setup, s.fov, s.metric, s.n, kind, rms[b * m : (b + 1) * m])
    for s in loop_sets:
        for kind in ("observations", "closedloop_observations", "closedloop_masked"):
            values = [counts[(mat, s.key)][kind] for mat in materials]
            for mat, v in zip(materials, values):
                rows.append({**base, "setup": s.setup, "fov": s.fov, "metric": s.metric, "n": s.n, "material": mat,
                             "channel": "all", "kind": kind, "value": v})
            rows.append({**base, "setup": s.setup, "fov": s.fov, "metric": s.metric, "n": s.n, "material": "mean",
                         "channel": "all", "kind": kind, "value": float(np.mean(values))})
    return rows


def evaluate_unseen(
    *,
    stores: Mapping[str, str | os.PathLike[str]],
    model: str | os.PathLike[str] | Model,
    directions: Sequence[str | os.PathLike[str]],
    closedloop_directions: Sequence[str | os.PathLike[str]] = (),
    observations: Mapping[str, str | os.PathLike[str]] | None = None,
    n_images: Sequence[int] = (),
    eta: float = DEFAULT_ETA,
) -> list[dict[str, Any]]:
    """Rows of ``unseen.csv`` (:data:`~brdfpipe.registry.tables.UNSEEN_ERRORS`) for the materials of every store (module docstring).

    ``stores``: unseen database label → its store (each store must carry that
    label and be of another database than the model); ``model``: the
    training split's PCA model; ``directions``: the direction sets looked up
    in the tables (every n); ``closedloop_directions`` with ``n_images`` and
    ``observations`` (database → the capture's file,
    :func:`read_many_observations`): the sets photographed.  A set in both
    lists is looked up once.
    """
    eta = check_eta(eta)
    t0 = time.perf_counter()
    mdl = model if isinstance(model, Model) else open_model(model)
    lut = np.full(N_CELLS, -1, dtype=np.intp)
    lut[np.asarray(mdl.cells, dtype=np.intp)] = np.arange(mdl.p, dtype=np.intp)
    loop_sets = _sets(closedloop_directions, mdl, lut, n_images) if closedloop_directions else []
    table_sets: list[_Set] = []
    seen: set[tuple[str, float, str, int]] = set()
    for s in _sets(directions, mdl, lut) + loop_sets:
        if s.key not in seen:
            seen.add(s.key)
            table_sets.append(s)
    if loop_sets and observations is None:
        raise ValueError("closed-loop sets given without observation files")
    rows: list[dict[str, Any]] = []
    for database, path in stores.items():
        if database == mdl.database:
            raise ValueError(f"{path}: database {database} is the model's own ({mdl.path}); its materials are not "
                             "unseen")
        tables = read_many_observations(observations[database], database=database) if loop_sets else []
        rows += _evaluate_database(database, path, mdl, table_sets, loop_sets, tables, eta)
    logger.info("unseen materials of %s: %d sets looked up, %d photographed, model of %s; %d rows in %.1f s",
                ", ".join(stores), len(table_sets), len(loop_sets), mdl.database, len(rows),
                time.perf_counter() - t0)
    return rows


def write_unseen(
    out: str | os.PathLike[str],
    *,
    stores: Mapping[str, str | os.PathLike[str]],
    model: str | os.PathLike[str],
    directions: Sequence[str | os.PathLike[str]],
    closedloop_directions: Sequence[str | os.PathLike[str]] = (),
    observations: Mapping[str, str | os.PathLike[str]] | None = None,
    n_images: Sequence[int] = (),
    eta: float = DEFAULT_ETA,
    threads: int | None = 1,
) -> Path:
    """:func:`evaluate_unseen`, written to ``out`` (``unseen.csv``, :data:`~brdfpipe.registry.tables.UNSEEN_ERRORS`) atomically.

    ``threads``: BLAS threads (the many small solves are slowed by idle BLAS threads spinning).
    """
    with blas_threads(threads):
        rows = evaluate_unseen(stores=stores, model=model, directions=directions,
                               closedloop_directions=closedloop_directions, observations=observations,
                               n_images=n_images, eta=eta)
    return write_errors(out, rows, tables.UNSEEN_ERRORS)
