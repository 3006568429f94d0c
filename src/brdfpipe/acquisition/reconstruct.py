"""Reconstruction of a full BRDF from sparse observations (Xu et al. 2016, issue §7).

Built on a PCA model (:func:`brdfpipe.acquisition.svd.open_model`: ``Q = VΣ``
(p × k), mean μ, and the log-relative mapping's reference ρ_ref and weight w
at the model's p columns = MERL cells): what ``brdfpipe reconstruct`` and
``brdfpipe capture --model`` run.  The leave-out evaluation of direction sets
on held-out materials, which reconstructs by the same eq. 4, is
:mod:`brdfpipe.acquisition.evaluation`.

Observations are physical BRDF values (sr⁻¹) of one material at some light /
view direction pairs, read by :func:`load_observations` from

* CSV with a header line: ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b`` (unit
  vectors in the local frame, z = normal; they are normalised) or
  ``theta_h,theta_d,phi_d,r,g,b`` (Rusinkiewicz angles in degrees, θh and θd
  in [0, 90], φd taken modulo 180 by reciprocity); header names are
  case-insensitive, extra columns are ignored, ``#`` lines are comments;
* NPZ with arrays ``wi``, ``wo`` (n, 3) and ``rgb`` (n, 3), or ``theta_h``,
  ``theta_d``, ``phi_d`` (n,) and ``rgb`` (n, 3).

Each observation is binned into its MERL cell (:func:`brdfpipe.data.merl.cell_index`,
or MERL's binning of the angles directly).  Repeated cells are kept as
repeated observations.  Every channel is its own BRDF (paper §3):
observations on cells that are not model columns are dropped, the rest are
log-mapped (:func:`brdfpipe.data.logmap.forward` with the model's ρ_ref, w, ε),
``ỹ = x̃ − μ̃`` and

    c̄ = (Q̃ᵀQ̃ + ηI)⁻¹ Q̃ᵀ ỹ                  (eq. 4, η = 40)
    x̂ = μ + Q c̄                              (all p model columns)
    ρ̂ = max(logmap.inverse(x̂), 0)

(:func:`reconstruct_log`, :func:`reconstruct_brdf`); cells that are not
model columns are written as unmeasured (raw value −1, negative as in MERL
files) by :func:`write_reconstruction`.

:func:`reconstruct_sets` (the workflow's rule ``reconstruct_figure_material``,
Xu Figs. 2 and 15) reconstructs a held-out material of the store from the
sets of directions files, observed as the evaluation observes it (the
store's values at the cells the geometry predicts), and writes each table
with its ``derived`` mark and the observed pixels of each image.
"""

from __future__ import annotations

import csv
import logging
import os
import warnings
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.acquisition import geometry
from brdfpipe.acquisition.metrics import DEFAULT_ETA, reconstruct_coefficients
from brdfpipe.acquisition.optimize import Directions, DirectionSet, read_directions
from brdfpipe.acquisition.svd import Model, open_model
from brdfpipe.core import integrity
from brdfpipe.core.atomic import check_not_input
from brdfpipe.core.exr import write_exr
from brdfpipe.data import logmap, merl, provenance
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import material_indices, open_store

__all__ = [
    "ObservationError",
    "load_observations",
    "as_model",
    "column_lookup",
    "q_chunks",
    "reconstruct_log",
    "reconstruct_brdf",
    "reconstruction_mark",
    "write_reconstruction",
    "reconstruct_sets",
]

logger = logging.getLogger("brdfpipe.acquisition.reconstruct")

F64 = NDArray[np.float64]

#: A direction counts as above the horizon when its z component exceeds this.
_HORIZON: Final = 1e-12

_DIR_COLS: Final = ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z")
_ANG_COLS: Final = ("theta_h", "theta_d", "phi_d")
_RGB_COLS: Final = ("r", "g", "b")


class ObservationError(ValueError):
    """An observations file is missing, malformed or holds invalid values; the message names the file."""


# ==========================================================================
# Observations
# ==========================================================================


def _csv_columns(path: Path) -> tuple[dict[str, int], int]:
    """Header (lower-cased name → column) of a CSV file and the number of lines before the data."""
    try:
        fh = open(path, encoding="utf-8-sig", newline="")
    except FileNotFoundError:
        raise ObservationError(f"{path}: no such observations file") from None
    except OSError as exc:
        raise ObservationError(f"{path}: cannot read observations ({exc})") from exc
    with fh:
        skipped = 0
        for line in fh:
            skipped += 1
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            names = [c.strip().lower() for c in next(csv.reader([line]))]
            break
        else:
            raise ObservationError(f"{path}: empty observations file (no header line)")
    dup = sorted({n for n in names if n and names.count(n) > 1})
    if dup:
        raise ObservationError(f"{path}: column(s) {', '.join(dup)} appear more than once in the header")
    return {n: i for i, n in enumerate(names)}, skipped


def _pick_format(path: Path, names: Iterable[str]) -> str:
    """``"directions"`` or ``"angles"`` from the available column / array names."""
    have = set(names)
    rgb_missing = [c for c in _RGB_COLS if c not in have]
    dirs = all(c in have for c in _DIR_COLS)
    angs = all(c in have for c in _ANG_COLS)
    if dirs and angs:
        raise ObservationError(f"{path}: holds both direction ({','.join(_DIR_COLS)}) and angle "
                               f"({','.join(_ANG_COLS)}) columns; keep one of them")
    if not (dirs or angs):
        miss_d = [c for c in _DIR_COLS if c not in have]
        miss_a = [c for c in _ANG_COLS if c not in have]
        raise ObservationError(
            f"{path}: missing columns: need {','.join(_DIR_COLS)},r,g,b (missing {','.join(miss_d + rgb_missing)}) "
            f"or {','.join(_ANG_COLS)},r,g,b (missing {','.join(miss_a + rgb_missing)})"
        )
    if rgb_missing:
        raise ObservationError(f"{path}: missing columns: {','.join(rgb_missing)}")
    return "directions" if dirs else "angles"


def _read_csv(path: Path) -> tuple[str, dict[str, F64]]:
    index, skip = _csv_columns(path)
    # a brdfpipe table carries a digest line (checked); a user's file need not
    integrity.read_csv_text(path, kind="observations file", error=ObservationError, require=False)
    fmt = _pick_format(path, index)
    names = (_DIR_COLS if fmt == "directions" else _ANG_COLS) + _RGB_COLS
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data": reported below
            data = np.loadtxt(path, delimiter=",", skiprows=skip, comments="#", usecols=[index[n] for n in names],
                              dtype=np.float64, ndmin=2, encoding="utf-8-sig", quotechar='"')
    except ValueError as exc:
        raise ObservationError(f"{path}: malformed observations ({exc})") from exc
    if data.shape[0] == 0:
        raise ObservationError(f"{path}: no observations (header only)")
    return fmt, {n: data[:, j] for j, n in enumerate(names)}


def _read_npz(path: Path) -> tuple[str, dict[str, F64]]:
    # truncated / corrupt files are one clean error; a brdfpipe table's digest is checked, a user's file needs none
    arrays = integrity.load_npz(path, kind="observations file", error=ObservationError, require=False)
    have = set(arrays)
    if "rgb" not in have:
        raise ObservationError(f"{path}: missing array 'rgb' (arrays: {', '.join(sorted(have)) or 'none'})")
    if {"wi", "wo"} & have and set(_ANG_COLS) & have:
        raise ObservationError(f"{path}: holds both direction (wi, wo) and angle ({', '.join(_ANG_COLS)}) arrays")
    if "wi" in have or "wo" in have:
        missing = [a for a in ("wi", "wo") if a not in have]
        if missing:
            raise ObservationError(f"{path}: missing array(s) {', '.join(missing)}")
        fmt, names3 = "directions", ("wi", "wo", "rgb")
    elif all(a in have for a in _ANG_COLS):
        fmt, names3 = "angles", ("rgb",)
    else:
        missing = [a for a in _ANG_COLS if a not in have]
        raise ObservationError(f"{path}: missing arrays: need wi, wo, rgb or theta_h, theta_d, phi_d, rgb "
                               f"(missing {', '.join(['wi', 'wo'] + missing)})")
    out: dict[str, F64] = {}
    n: int | None = None
    for name in names3:
        a = arrays[name]
        if a.ndim != 2 or a.shape[1] != 3 or not np.issubdtype(a.dtype, np.number):
            raise ObservationError(f"{path}: array {name!r} must be numeric with shape (n, 3), got {a.dtype} {a.shape}")
        n = a.shape[0] if n is None else n
        if a.shape[0] != n:
            raise ObservationError(f"{path}: arrays disagree in length ({name!r} has {a.shape[0]}, expected {n})")
        for j in range(3):
            key = {"wi": _DIR_COLS[j], "wo": _DIR_COLS[3 + j], "rgb": _RGB_COLS[j]}[name]
            out[key] = a[:, j].astype(np.float64)
    if fmt == "angles":
        for name in _ANG_COLS:
            a = arrays[name]
            if a.ndim != 1 or not np.issubdtype(a.dtype, np.number) or a.shape[0] != n:
                raise ObservationError(f"{path}: array {name!r} must be numeric with shape ({n},), "
                                       f"got {a.dtype} {a.shape}")
            out[name] = a.astype(np.float64)
    if not n:
        raise ObservationError(f"{path}: no observations (empty arrays)")
    return fmt, out


def _first(mask: NDArray[np.bool_]) -> int:
    return int(np.flatnonzero(mask)[0])


def load_observations(path: str | os.PathLike[str]) -> tuple[NDArray[np.intp], F64]:
    """Observations of one material from a CSV or NPZ file: ``(cells, rgb)``.

    See the module docstring for the formats (the file type is chosen by the
    ``.npz`` suffix; anything else is read as CSV).  Returns the flat MERL
    cell of each observation (``(n,)`` intp, repeats kept) and the physical
    RGB BRDF values (``(n, 3)`` float64, sr⁻¹).

    Raises
    ------
    ObservationError
        (a ValueError naming the file) for a missing file, missing columns /
        arrays, unparsable numbers, no observations, NaN or infinite values,
        negative BRDF values, zero-length direction vectors, θh or θd outside
        [0°, 90°], or a light or view direction at or below the horizon.
    """
    path = Path(path)
    fmt, cols = _read_npz(path) if path.suffix.lower() == ".npz" else _read_csv(path)
    names = (_DIR_COLS if fmt == "directions" else _ANG_COLS) + _RGB_COLS
    data = np.stack([cols[n] for n in names], axis=1)
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ObservationError(f"{path}: {int(bad.sum())} NaN or infinite value(s), first in observation {r + 1} "
                               f"(column {names[c]})")
    rgb = data[:, -3:].copy()
    if (rgb < 0).any():
        r = _first((rgb < 0).any(axis=1))
        raise ObservationError(f"{path}: {int((rgb < 0).any(axis=1).sum())} observation(s) with a negative BRDF value, "
                               f"first observation {r + 1} ({rgb[r].tolist()}); values must be physical BRDFs ≥ 0")
    if fmt == "directions":
        wi, wo = data[:, 0:3], data[:, 3:6]
        ni, no = np.linalg.norm(wi, axis=1), np.linalg.norm(wo, axis=1)
        zero = (ni == 0) | (no == 0)
        if zero.any():
            raise ObservationError(f"{path}: zero-length direction vector in observation {_first(zero) + 1}")
        wi, wo = wi / ni[:, None], wo / no[:, None]
        low = (wi[:, 2] <= _HORIZON) | (wo[:, 2] <= _HORIZON)
        if low.any():
            raise ObservationError(f"{path}: {int(low.sum())} observation(s) with a direction at or below the "
                                   f"horizon (z ≤ 0), first observation {_first(low) + 1}")
        cells = merl.cell_index(wi, wo)
    else:
        th, td, pd = data[:, 0], data[:, 1], data[:, 2]
        out = (th < 0) | (th > 90) | (td < 0) | (td > 90)
        if out.any():
            r = _first(out)
            raise ObservationError(f"{path}: θh and θd must lie in [0, 90] degrees; observation {r + 1} has "
                                   f"θh = {th[r]:g}, θd = {td[r]:g}")
        th_r, td_r = np.radians(th), np.radians(td)
        pd_r = np.radians(np.mod(pd, 180.0))
        wi, wo = merl.directions_from_half_diff(th_r, td_r, pd_r)
        low = (wi[:, 2] <= _HORIZON) | (wo[:, 2] <= _HORIZON)
        if low.any():
            r = _first(low)
            raise ObservationError(f"{path}: {int(low.sum())} observation(s) with the light or view direction at or "
                                   f"below the horizon, first observation {r + 1} (θh = {th[r]:g}, θd = {td[r]:g}, "
                                   f"φd = {pd[r]:g})")
        ih, idd, ip = merl.bin_indices(th_r, td_r, pd_r)
        cells = (ih * merl.N_THETA_D + idd) * merl.N_PHI_D + ip
    logger.info("%s: %d observations (%s), %d distinct cells", path, cells.size, fmt, np.unique(cells).size)
    return np.asarray(cells, dtype=np.intp), rgb


# ==========================================================================
# Reconstruction
# ==========================================================================


def as_model(model: Model | str | os.PathLike[str]) -> Model:
    """``model`` itself if it is an open :class:`~brdfpipe.acquisition.svd.Model`, else the model at that path."""
    return model if isinstance(model, Model) else open_model(model)


def column_lookup(cells: NDArray[np.integer[Any]]) -> NDArray[np.intp]:
    """MERL cell → model column (−1 where the cell is not a column), for a model's columns ``cells``."""
    lut = np.full(N_CELLS, -1, dtype=np.intp)
    lut[np.asarray(cells, dtype=np.intp)] = np.arange(cells.size, dtype=np.intp)
    return lut


def _q_rows(model: Model, rows: NDArray[np.intp]) -> F64:
    """Rows ``rows`` of Q (repeats allowed) as float64 (each needed chunk read once)."""
    uniq, inv = np.unique(rows, return_inverse=True)
    if uniq.size == 0:
        return np.zeros((0, model.k))
    got = np.asarray(model.Q.get_orthogonal_selection((uniq, slice(None))), dtype=np.float64)
    return got[inv]


def q_chunks(model: Model) -> Iterator[tuple[int, int]]:
    """The ranges ``(a, b)`` of model columns (rows of Q) of each stored chunk of Q, in increasing order."""
    width = int(model.Q.chunks[0])
    for a in range(0, model.p, width):
        yield a, min(a + width, model.p)


def _check_obs(cells: ArrayLike, rgb: ArrayLike) -> tuple[NDArray[np.intp], F64]:
    c = np.asarray(cells)
    v = np.asarray(rgb, dtype=np.float64)
    if c.ndim != 1 or (c.size and not np.issubdtype(c.dtype, np.integer)):
        raise ValueError(f"cells must be a 1-D integer array, got {c.dtype} {c.shape}")
    if v.shape != (c.size, 3):
        raise ValueError(f"rgb must have shape ({c.size}, 3), got {v.shape}")
    if c.size and (c.min() < 0 or c.max() >= N_CELLS):
        raise ValueError(f"cells must lie in [0, {N_CELLS})")
    if not np.isfinite(v).all() or (v < 0).any():
        raise ValueError("rgb must be finite and ≥ 0 (physical BRDF values)")
    return c.astype(np.intp), v


def _coefficients(mdl: Model, cells: ArrayLike, rgb: ArrayLike, eta: float) -> tuple[F64, int]:
    """The (k, 3) coefficients of eq. 4 from observations on MERL ``cells``, and how many fell on model columns."""
    c, v = _check_obs(cells, rgb)
    cols = column_lookup(mdl.cells)[c]
    keep = cols >= 0
    if not keep.all():
        logger.warning("%d of %d observations fall on cells that are not model columns; dropped",
                       int((~keep).sum()), c.size)
    cols, v = cols[keep], v[keep]
    if cols.size == 0:
        raise ValueError("no observation falls on a model column (a measured cell of the model)")
    x_obs = logmap.forward(v.T, mdl.reference[cols], mdl.weight[cols], mdl.epsilon)  # (3, n)
    y_obs = (x_obs - mdl.mean[cols]).T  # (n, 3)
    coef = reconstruct_coefficients(_q_rows(mdl, cols), y_obs, eta)  # (k, 3)
    logger.info("reconstructed from %d observations at %d distinct cells (k = %d, η = %g)",
                cols.size, np.unique(cols).size, mdl.k, eta)
    return coef, int(cols.size)


def _expand(mdl: Model, coef: F64) -> F64:
    """x̂ = μ + Q c̄ over the model's p columns for every column of ``coef`` (k, m): (m, p), one pass over Q."""
    xhat = np.empty((coef.shape[1], mdl.p))
    for a, b in q_chunks(mdl):
        q = np.asarray(mdl.Q[a:b], dtype=np.float64)
        xhat[:, a:b] = (q @ coef).T + mdl.mean[a:b]
    return xhat


def reconstruct_log(
    model: Model | str | os.PathLike[str], cells: ArrayLike, rgb: ArrayLike, eta: float = DEFAULT_ETA
) -> tuple[F64, F64, int]:
    """Log-space reconstruction ``x̂ = μ + Q c̄`` of each channel: ``(xhat, coef, n_used)``.

    ``xhat`` is (3, p) over the model's columns, ``coef`` the (k, 3)
    coefficients of eq. 4 and ``n_used`` the number of observations on model
    columns (the others are dropped, with a warning).  ValueError if none is
    left, for bad shapes or values, or η ≤ 0.
    """
    mdl = as_model(model)
    coef, n_used = _coefficients(mdl, cells, rgb, eta)
    return _expand(mdl, coef), coef, n_used


def _to_table(mdl: Model, xhat: F64) -> F64:
    """The (3, 90, 90, 180) table of a (3, p) log-space reconstruction (see :func:`reconstruct_brdf`)."""
    rho = logmap.inverse(xhat, mdl.reference, mdl.weight, mdl.epsilon)
    neg = rho < 0
    if neg.any():
        logger.info("clamped %s negative reconstructed value(s) to 0 (R, G, B: %s of %d cells)",
                    int(neg.sum()), ", ".join(str(int(n)) for n in neg.sum(axis=1)), mdl.p)
        rho[neg] = 0.0
    table = np.empty((3, N_CELLS))
    table[:] = -merl.SCALES[:, None]
    table[:, mdl.cells] = rho
    return table.reshape(merl.SHAPE)


def reconstruct_brdf(
    model: Model | str | os.PathLike[str], cells: ArrayLike, rgb: ArrayLike, eta: float = DEFAULT_ETA
) -> F64:
    """The reconstructed BRDF as a (3, 90, 90, 180) table in physical units (sr⁻¹).

    Per channel: :func:`reconstruct_log`, then ρ̂ = logmap.inverse(x̂) with
    negative values clamped to 0 (their number is logged).  Cells that are
    not model columns hold −SCALES[c] (raw MERL value −1: unmeasured).
    """
    mdl = as_model(model)
    xhat, _, _ = reconstruct_log(mdl, cells, rgb, eta)
    return _to_table(mdl, xhat)


def reconstruction_mark(
    model: Model, observations_path: str | os.PathLike[str], out: str | os.PathLike[str], eta: float,
    material: str | os.PathLike[str] | None = None,
) -> provenance.Mark:
    """The ``derived`` provenance mark of a reconstruction written to ``out``.

    Records the model (``id``, ``database``, ``k``, number of materials), the
    sha256 of the observations file and ``eta``; with ``material`` (the
    captured file of ``brdfpipe capture --model``) also that file's sha256
    and label, as operation ``capture-reconstruct``.
    """
    inputs: dict[str, Any] = {
        "model": {"id": model.id, "database": model.database, "k": model.k, "materials": len(model.materials)},
        "observations": {"sha256": provenance.file_sha256(observations_path)},
        "eta": float(eta),
    }
    if material is not None:
        inputs["material"] = {"sha256": provenance.file_sha256(material), "database": provenance.file_label(material)}
    operation = "reconstruct" if material is None else "capture-reconstruct"
    return provenance.derived_mark(name=provenance.output_name(out), operation=operation,
                                   source_database=model.database, inputs=inputs)


def write_reconstruction(
    model_path: Model | str | os.PathLike[str],
    observations_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    eta: float = DEFAULT_ETA,
    *,
    material: str | os.PathLike[str] | None = None,
) -> Path:
    """Reconstruct the material of ``observations_path`` and write it as a MERL file at ``out``.

    :func:`load_observations` → :func:`reconstruct_brdf` → :func:`brdfpipe.data.merl.write_merl`
    (atomic) with the ``derived`` mark of :func:`reconstruction_mark`
    (``material``: the file the observations were captured from, if known).
    Parent folders are created.  Returns ``out``.
    """
    out = Path(out)
    mdl = as_model(model_path)
    cells, rgb = load_observations(observations_path)
    mark = reconstruction_mark(mdl, observations_path, out, eta, material)
    try:
        table = reconstruct_brdf(mdl, cells, rgb, eta)
    except ValueError as exc:
        raise ValueError(f"{observations_path}: {exc}") from exc
    out.parent.mkdir(parents=True, exist_ok=True)
    merl.write_merl(out, table, mark=mark)
    logger.info("wrote %s", out)
    return out


# ==========================================================================
# Held-out materials reconstructed from direction sets (Xu Figs. 2, 15)
# ==========================================================================


def _set_mark(mdl: Model, store_id: dict[str, Any], material: str, path: Path, d: Directions, n: int,
              out: Path, eta: float) -> provenance.Mark:
    inputs = {
        "model": {"id": mdl.id, "database": mdl.database, "k": mdl.k, "materials": len(mdl.materials)},
        "store": store_id,
        "material": material,
        "directions": {"sha256": provenance.file_sha256(path), "setup": d.setup.kind, "fov": d.setup.fov_deg,
                       "metric": d.metric, "n": int(n)},
        "eta": float(eta),
    }
    return provenance.derived_mark(name=provenance.output_name(out), operation="reconstruct",
                                   source_database=mdl.database, inputs=inputs)


def _input_image(setup: geometry.Setup, config: geometry.Config, row: F64, valid: NDArray[np.bool_]) -> F64:
    """The observed pixels of one image: BRDF value × cos θi at each kept pixel's cell (0 where not observed)."""
    wi, view = geometry.pixel_directions(setup, config)
    rows, cols, size = geometry.pixel_positions(setup, config)
    image = np.zeros((size, size, 3))
    if view.shape[0] == 0 or wi[0, 2] <= 0.0:
        return image
    cells = merl.cell_index(wi, view)
    seen = valid[cells]
    image[rows[seen], cols[seen]] = row[:, cells[seen]].T * wi[0, 2]
    return image


def reconstruct_sets(
    store: str | os.PathLike[str],
    model: Model | str | os.PathLike[str],
    material: str,
    sets: Sequence[tuple[str | os.PathLike[str], int]],
    *,
    outs: Sequence[str | os.PathLike[str]],
    inputs: Sequence[Sequence[str | os.PathLike[str]]],
    eta: float = DEFAULT_ETA,
) -> list[Path]:
    """A held-out material reconstructed from each direction set by table lookup: MERL files and input images.

    ``sets[k]`` = (directions file, n): its n-set, optimised on the model's
    split.  The observations are the material's store values at
    :func:`brdfpipe.acquisition.geometry.observation_cells` of the set's
    configurations with the model's columns as the valid cells — the
    evaluation's (:mod:`brdfpipe.acquisition.evaluation`), so the table's
    ``rms_log`` is ``errors.csv``'s for this material and set.  The
    reconstruction is eq. 4 (η = ``eta``), ρ̂ = max(inverse(μ + Q c̄), 0)
    (:func:`reconstruct_brdf`), written to ``outs[k]`` with a ``derived``
    mark (operation ``reconstruct``: the model, the store, the material,
    the directions file's sha256 and set, η).  ``inputs[k]``: one EXR per
    image of an image set (none for point samples): the observed pixels,
    BRDF × cos θi of each pixel's cell (0 where no model column is
    observed), in the capture's image frame.  One pass over Q serves every
    set.  ValueError naming the problem for a training material, a
    directions file of another split or database, a missing set, an output
    that is an input, or a count of ``inputs`` that is not the set's.
    """
    mdl = as_model(model)
    if not (len(sets) == len(outs) == len(inputs)):
        raise ValueError(f"reconstruct_sets: {len(sets)} sets, {len(outs)} outputs and {len(inputs)} input lists")
    if material in mdl.train_materials:
        raise ValueError(f"{material} is a training material of the model {mdl.path}; the figures need held-out ones")
    st = open_store(store)
    if st.database != mdl.database:
        raise ValueError(f"{st.path} is database {st.database!r}, the model {mdl.path} {mdl.database!r}")
    read = [Path(p) for p, _ in sets] + [Path(store), Path(mdl.path)]
    for out in [*outs, *(f for files in inputs for f in files)]:
        check_not_input(out, read, what="output")
    chosen: list[tuple[Path, Directions, int, DirectionSet]] = []
    for (path, n), files in zip(sets, inputs):
        d = read_directions(path)
        if d.split != mdl.split or d.database != mdl.database:
            raise ValueError(f"{path}: directions of split {d.split!r}, database {d.database!r}; the model {mdl.path} "
                             f"is of split {mdl.split!r}, database {mdl.database!r}")
        found = next((s for s in d.sets if s.n == int(n)), None)
        if found is None:
            raise ValueError(f"{path}: no set of n = {n}")
        want = len(found.configurations) if d.setup.is_image else 0
        if len(files) != want:
            raise ValueError(f"{path}: the {n}-set has {want} image(s), got {len(files)} input file(s)")
        chosen.append((Path(path), d, int(n), found))
    r = int(material_indices(st, [material], "material")[0])
    st.verify([r])
    row = np.maximum(np.asarray(st.brdf[r], dtype=np.float64).reshape(3, N_CELLS), 0.0)
    valid = np.zeros(N_CELLS, dtype=bool)
    valid[np.asarray(mdl.cells, dtype=np.intp)] = True
    coefs = []
    for path, d, n, s in chosen:
        cells = np.concatenate([geometry.observation_cells(d.setup, c, valid) for c in s.configurations])
        logger.info("%s: %s FOV %g %s n = %d", material, d.setup.kind, d.setup.fov_deg, d.metric, n)
        coefs.append(_coefficients(mdl, cells, row[:, cells].T, eta)[0])
    xhat = _expand(mdl, np.concatenate(coefs, axis=1))
    store_id = provenance.store_identity(st)
    written = []
    for k, ((path, d, n, s), out, files) in enumerate(zip(chosen, outs, inputs)):
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        merl.write_merl(out, _to_table(mdl, xhat[3 * k : 3 * k + 3]),
                        mark=_set_mark(mdl, store_id, material, path, d, n, out, eta))
        written.append(out)
        for j, (config, f) in enumerate(zip(s.configurations, files), start=1):
            attrs = {"material": material, "database": mdl.database, "setup": d.setup.kind,
                     "fov": f"{d.setup.fov_deg:g}", "metric": d.metric, "n": str(n), "image": str(j),
                     "pixels": "BRDF x cos(theta_i) at each pixel's cell (table lookup); 0: not observed"}
            write_exr(f, _input_image(d.setup, config, row, valid).astype(np.float32), attrs=attrs)
            written.append(Path(f))
    logger.info("%s: wrote %d reconstructions and %d input images", material, len(outs), len(written) - len(outs))
    return written
