"""Closed-loop evaluation: reconstruct held-out materials from captured images, next to the table lookup.

The leave-out evaluation (:mod:`brdfpipe.acquisition.evaluation`) observes a
held-out material by looking its table up at the cells the acquisition
geometry predicts.  The closed loop observes it through images instead:
:mod:`brdfpipe.rendering.capture` renders each configuration of a direction
set (Mitsuba 3, the ``merl`` BSDF, a point light, the set-up's camera) and
writes the observation table read off the pixels (NPZ: ``wi``, ``wo``,
``rgb`` per kept pixel).  Here, for every (material, directions file, n):

* ``rms_log``, ``relrms_linear`` — the table lookup, exactly as
  :func:`brdfpipe.acquisition.evaluation.evaluate` (observations = the
  store's values at :func:`brdfpipe.acquisition.geometry.observation_cells`
  of the set's configurations, dropped where not a model column);
* ``closedloop_noiseless_rms_log``, ``closedloop_noiseless_relrms_linear`` —
  from the noiseless render (each pixel the average over its footprint);
* ``closedloop_rms_log``, ``closedloop_relrms_linear`` — from the sensor's
  photograph (photon and read noise, saturation, ADC, HDR brackets;
  pixels masked for low signal);

each observation binned into its MERL cell (:func:`brdfpipe.data.merl.cell_index`
of the pixel's own light and view directions), observations on cells that
are not model columns dropped (unmeasured), and c̄ by eq. 4 with the same η.
The errors are measured against the store's row (the same ground truth as
the table lookup), per channel, with the means over the material-channels
as material ``mean``, channel ``all``.  Counts per (material, set), channel
``all``: ``observations`` (table lookup), ``closedloop_observations`` (sensor
pixels used) and ``closedloop_masked`` (share of the disk's pixels not used:
masked by the sensor or on a cell that is not a model column).  A set whose
photographs leave no usable pixel (every one masked: dark, below
``min_snr`` or saturated) is reconstructed from no observation, which eq. 4
makes the model's mean: its rows say so (``closedloop_observations`` 0,
``closedloop_masked`` 1) and the job logs a warning; it does not fail.

Cost: one streamed pass over Q for all (material, set, kind) coefficient
columns at once (as the evaluation's pass 2).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.acquisition import geometry
from brdfpipe.acquisition.evaluation import CHANNELS, write_errors
from brdfpipe.acquisition.metrics import DEFAULT_ETA, reconstruct_coefficients
from brdfpipe.acquisition.optimize import read_directions
from brdfpipe.acquisition.svd import Model, open_model
from brdfpipe.core import integrity
from brdfpipe.data import logmap, merl
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import material_indices, open_store
from brdfpipe.registry import tables

__all__ = [
    "CLOSEDLOOP_KINDS",
    "OBSERVATION_SOURCES",
    "read_observations",
    "evaluate_closedloop",
    "table_layout",
    "write_closedloop",
]

logger = logging.getLogger("brdfpipe.acquisition.closedloop")

F64 = NDArray[np.float64]

#: Observation sources: kind prefix of their error rows.
OBSERVATION_SOURCES: Final = {"table": "", "noiseless": "closedloop_noiseless_", "sensor": "closedloop_"}
#: Every kind of closedloop.csv.
CLOSEDLOOP_KINDS: Final = tuple(
    f"{prefix}{k}" for prefix in OBSERVATION_SOURCES.values() for k in ("rms_log", "relrms_linear")
) + ("observations", "closedloop_observations", "closedloop_masked")

_Q_ROWS: Final = 8192  # rows of Q per block of the error pass


def read_observations(path: str | os.PathLike[str]) -> tuple[NDArray[np.intp], F64, dict[str, int]]:
    """(cells, rgb, counts) of a capture's observation table (NPZ of :mod:`brdfpipe.rendering.capture`).

    ValueError naming the file (and what to rerun) when it is missing,
    truncated, corrupt, edited (its digest is checked:
    :func:`brdfpipe.core.integrity.load_npz`) or malformed.
    """
    path = Path(path)
    z = integrity.load_npz(path, kind="observation table")
    try:
        wi = np.asarray(z["wi"], dtype=np.float64)
        wo = np.asarray(z["wo"], dtype=np.float64)
        rgb = np.asarray(z["rgb"], dtype=np.float64)
        counts = {str(k): int(v) for k, v in zip(z["counts_keys"], z["counts"])}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: not a capture observation table ({type(exc).__name__}: {exc})") from exc
    n = rgb.shape[0]
    if wi.shape != (n, 3) or wo.shape != (n, 3) or rgb.shape != (n, 3) or not np.isfinite(rgb).all() or (rgb < 0).any():
        raise ValueError(f"{path}: observation arrays have wrong shapes or values")
    cells = merl.cell_index(wi, wo) if n else np.zeros(0, dtype=np.intp)
    return cells.astype(np.intp), rgb, counts


class _Rows:
    """Rows of Q (float64) at a fixed set of model columns, read with one selection (Q is read once)."""

    def __init__(self, mdl: Model, cols: NDArray[np.intp]) -> None:
        self.cols = np.unique(cols)
        self.q = (np.asarray(mdl.Q.get_orthogonal_selection((self.cols, slice(None))), dtype=np.float64)
                  if self.cols.size else np.zeros((0, mdl.k)))

    def get(self, cols: NDArray[np.intp]) -> F64:
        return self.q[np.searchsorted(self.cols, cols)]


def _model_columns(lut: NDArray[np.intp], cells: NDArray[np.intp], rgb: F64) -> tuple[NDArray[np.intp], F64]:
    """Observations on model columns: (columns, values); the others (unmeasured cells) are dropped."""
    cols = lut[cells]
    keep = cols >= 0
    return cols[keep], rgb[keep]


def _coefficients(mdl: Model, rows: _Rows, cols: NDArray[np.intp], v: F64, eta: float) -> F64:
    """(k, 3) coefficients of eq. 4 from observations on model columns ``cols`` with values ``v`` (n, 3)."""
    if cols.size == 0:
        return np.zeros((mdl.k, 3))
    x_obs = logmap.forward(v.T, mdl.reference[cols], mdl.weight[cols], mdl.epsilon)  # (3, n)
    y_obs = (x_obs - mdl.mean[cols]).T
    return reconstruct_coefficients(rows.get(cols), y_obs, eta)


def _errors(mdl: Model, truth: F64, coefs: F64, owner: NDArray[np.intp]) -> tuple[F64, F64]:
    """(rms_log, relrms_linear) of each coefficient column; ``owner[j]`` = row of ``truth`` (material-channel).

    Q is read chunk by chunk (each stored chunk decoded once), the work done
    in sub-blocks of :data:`_Q_ROWS` rows.
    """
    wi, wo = merl.cell_directions(mdl.cells)
    cc = wi[:, 2] * wo[:, 2]
    sq_log = np.zeros(coefs.shape[1])
    num = np.zeros(coefs.shape[1])
    den = np.zeros(coefs.shape[1])
    width = int(mdl.Q.chunks[0])
    t0 = time.monotonic()
    for a0 in range(0, mdl.p, width):
        qc = np.asarray(mdl.Q[a0 : min(a0 + width, mdl.p)], dtype=np.float64)
        for s0 in range(0, qc.shape[0], _Q_ROWS):
            a, b = a0 + s0, a0 + min(s0 + _Q_ROWS, qc.shape[0])
            ref, w = mdl.reference[a:b], mdl.weight[a:b]
            xhat = qc[s0 : s0 + (b - a)] @ coefs + mdl.mean[a:b, None]  # (b − a, ncols)
            rho = truth[:, a:b]  # (m, b − a)
            xt = logmap.forward(rho, ref[None, :], w[None, :], mdl.epsilon)[owner].T
            diff = xhat - xt
            sq_log += np.einsum("ij,ij->j", diff, diff)
            rho_hat = np.maximum(logmap.inverse(xhat.T, ref, w, mdl.epsilon), 0.0).T
            r = rho[owner].T * cc[a:b, None]
            d = rho_hat * cc[a:b, None] - r
            num += np.einsum("ij,ij->j", d, d)
            den += np.einsum("ij,ij->j", r, r)
        logger.info("closed-loop error pass: %d/%d model columns, %.1f s", min(a0 + width, mdl.p), mdl.p,
                    time.monotonic() - t0)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(den > 0, np.sqrt(num / den), np.where(num > 0, np.inf, 0.0))
    return np.sqrt(sq_log / mdl.p), rel


def evaluate_closedloop(
    store_path: str | os.PathLike[str],
    model_path: str | os.PathLike[str],
    directions: Sequence[str | os.PathLike[str]],
    observations: Mapping[tuple[str, int, int], tuple[str | os.PathLike[str], str | os.PathLike[str]]],
    *,
    materials: Sequence[str],
    n_images: Sequence[int],
    eta: float = DEFAULT_ETA,
) -> list[dict[str, Any]]:
    """Error rows (columns of ``errors.csv``) of the table lookup and the closed loop (module docstring).

    ``observations[(material, d, n)]`` = (noiseless NPZ, sensor NPZ) of the
    n-set of ``directions[d]``.
    """
    mdl = open_model(model_path)
    st = open_store(store_path)
    rows_idx = material_indices(st, list(materials), "closed-loop materials")
    lut = np.full(N_CELLS, -1, dtype=np.intp)
    lut[np.asarray(mdl.cells, dtype=np.intp)] = np.arange(mdl.p, dtype=np.intp)
    valid = np.zeros(N_CELLS, dtype=bool)
    valid[np.asarray(mdl.cells, dtype=np.intp)] = True
    truth = np.empty((3 * len(materials), mdl.p))
    for i, r in enumerate(rows_idx):
        row = np.asarray(st.brdf[int(r)], dtype=np.float64).reshape(3, N_CELLS)
        truth[3 * i : 3 * i + 3] = row[:, mdl.cells]
    sets = [read_directions(p) for p in directions]
    # Every observation first (table lookup, noiseless render, sensor), then one read of the Q rows they need.
    obs: list[tuple[int, int, int, str, NDArray[np.intp], F64]] = []
    counts: dict[tuple[int, int, int], dict[str, float]] = {}
    for i, name in enumerate(materials):
        for d, dset in enumerate(sets):
            by_n = {s.n: s for s in dset.sets}
            for n in n_images:
                if n not in by_n:
                    raise ValueError(f"{directions[d]}: no set of n = {n}")
                cells = np.concatenate([geometry.observation_cells(dset.setup, c, valid) for c in by_n[n].configurations])
                cols = lut[cells]
                obs.append((i, d, n, "table", cols, np.maximum(truth[3 * i : 3 * i + 3, cols].T, 0.0)))
                cnt: dict[str, float] = {"observations": int(cols.size)}
                noiseless_path, sensor_path = observations[(name, d, n)]
                for source, path in (("noiseless", noiseless_path), ("sensor", sensor_path)):
                    c_cells, rgb, px = read_observations(path)
                    c_cols, v = _model_columns(lut, c_cells, rgb)
                    if c_cols.size == 0:
                        # Every pixel masked (dark, below min_snr, saturated) or off the model's cells: eq. 4
                        # with no observation gives c̄ = 0, the model's mean; reported as such (0 observations,
                        # all masked), not an error.
                        logger.warning("%s: no pixel of %s %s n = %d is usable (%s); its reconstruction is the "
                                       "model's mean", path, name, Path(directions[d]).name, n,
                                       ", ".join(f"{k} {v}" for k, v in px.items()))
                    obs.append((i, d, n, source, c_cols, v))
                    if source == "sensor":
                        cnt["closedloop_observations"] = int(c_cols.size)
                        cnt["closedloop_masked"] = 1.0 - c_cols.size / px["pixels"] if px["pixels"] else 1.0
                counts[(i, d, n)] = cnt
    rows = _Rows(mdl, np.concatenate([o[4] for o in obs]))
    combos: list[tuple[int, int, int, str, int]] = []  # (material, directions index, n, source, channel)
    coef_cols: list[F64] = []
    owners: list[int] = []
    for i, d, n, source, cols, v in obs:
        coef = _coefficients(mdl, rows, cols, v, eta)
        for c in range(3):
            combos.append((i, d, n, source, c))
            coef_cols.append(coef[:, c])
            owners.append(3 * i + c)
    logger.info("closed loop: %d materials × %d sets × 3 sources; error pass over %d model columns",
                len(materials), len(sets) * len(n_images), mdl.p)
    rms, rel = _errors(mdl, truth, np.stack(coef_cols, axis=1), np.asarray(owners, dtype=np.intp))
    out: list[dict[str, Any]] = []
    base = {"database": st.database, "split": sets[0].split if sets else "train"}
    acc: dict[tuple[int, int, str, str], list[float]] = {}
    for j, (i, d, n, source, c) in enumerate(combos):
        dset = sets[d]
        key = dict(base, setup=dset.setup.kind, fov=_fov(dset.setup.fov_deg), metric=dset.metric, n=n)
        prefix = OBSERVATION_SOURCES[source]
        for kind, value in ((f"{prefix}rms_log", rms[j]), (f"{prefix}relrms_linear", rel[j])):
            out.append(dict(key, material=materials[i], channel=CHANNELS[c], kind=kind, value=float(value)))
            acc.setdefault((d, n, kind, ""), []).append(float(value))
    for (i, d, n), cnt in counts.items():
        dset = sets[d]
        key = dict(base, setup=dset.setup.kind, fov=_fov(dset.setup.fov_deg), metric=dset.metric, n=n)
        for kind, value in cnt.items():
            out.append(dict(key, material=materials[i], channel="all", kind=kind, value=value))
            acc.setdefault((d, n, kind, ""), []).append(float(value))
    for (d, n, kind, _), values in acc.items():
        dset = sets[d]
        out.append(dict(base, setup=dset.setup.kind, fov=_fov(dset.setup.fov_deg), metric=dset.metric, n=n,
                        material="mean", channel="all", kind=kind, value=float(np.mean(values))))
    return out


def _fov(value: float) -> float | int:
    return int(value) if float(value).is_integer() else float(value)


def table_layout(materials: Sequence[str], n_directions: int, n_images: Sequence[int]) -> list[tuple[str, int, int]]:
    """The order of :func:`write_closedloop`'s observation lists: (material, directions index, n)."""
    return [(m, d, int(n)) for m in materials for d in range(n_directions) for n in n_images]


def write_closedloop(
    store_path: str | os.PathLike[str],
    model_path: str | os.PathLike[str],
    directions: Sequence[str | os.PathLike[str]],
    noiseless: Sequence[str | os.PathLike[str]],
    observations: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    materials: Sequence[str],
    n_images: Sequence[int],
    eta: float = DEFAULT_ETA,
) -> Path:
    """:func:`evaluate_closedloop`, written to ``out`` (the columns of ``errors.csv``), atomically.

    ``noiseless`` / ``observations``: the capture's observation tables
    (noiseless render, sensor), in the order of :func:`table_layout`.
    """
    keys = table_layout(materials, len(directions), n_images)
    if not len(noiseless) == len(observations) == len(keys):
        raise ValueError(f"closed loop: need {len(keys)} observation tables of each kind, "
                         f"got {len(noiseless)} and {len(observations)}")
    observed = {k: (a, b) for k, a, b in zip(keys, noiseless, observations)}
    rows = evaluate_closedloop(store_path, model_path, directions, observed,
                               materials=materials, n_images=n_images, eta=eta)
    return write_errors(out, rows, tables.ERRORS)
