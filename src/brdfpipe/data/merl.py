"""The MERL BRDF file format: reading, writing, lookup and cell geometry.

A MERL ``.binary`` file (Matusik et al. 2003) is a 12-byte header of three
little-endian int32 dimensions ``(90, 90, 180)`` followed by
3 × 1,458,000 little-endian float64 values (34,992,012 bytes in all), stored
channel-major (red, green, blue blocks).  Inside a channel the flat index is
``iθh · 90·180 + iθd · 180 + iφd`` in Rusinkiewicz half/difference
coordinates:

* θh ∈ [0, π/2] with square-root binning: ``iθh = floor(sqrt(θh / (π/2) · 90²))``;
* θd ∈ [0, π/2] uniform: ``iθd = floor(θd / (π/2) · 90)``;
* φd ∈ [0, π) uniform after folding ``φd < 0 → φd + π`` (reciprocity):
  ``iφd = floor(φd / π · 180)``.

Raw values times the channel scales (1/1500, 1.15/1500, 1.66/1500) give the
BRDF in physical units (sr⁻¹).  Cells that were never measured hold negative
numbers; this module keeps them negative in both directions.

The public API of this module is stable: other tools call it.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import atomic

if TYPE_CHECKING:
    from brdfpipe.data.provenance import Mark

__all__ = [
    "N_THETA_H",
    "N_THETA_D",
    "N_PHI_D",
    "N_CELLS",
    "SHAPE",
    "DIMS",
    "SCALES",
    "HEADER_BYTES",
    "FILE_SIZE",
    "MerlFormatError",
    "read_merl",
    "read_merl_raw",
    "write_merl",
    "as_directions",
    "half_diff",
    "bin_indices",
    "cell_index",
    "lookup",
    "cell_centres",
    "cell_directions",
    "measured_mask",
    "above_horizon",
    "directional_albedo",
    "mean_directional_albedo_weights",
]

N_THETA_H: Final = 90
N_THETA_D: Final = 90
N_PHI_D: Final = 180
N_CELLS: Final = N_THETA_H * N_THETA_D * N_PHI_D  # 1,458,000 cells per channel
SHAPE: Final = (3, N_THETA_H, N_THETA_D, N_PHI_D)
DIMS: Final = (N_THETA_H, N_THETA_D, N_PHI_D)
#: Channel scales that turn raw file values into physical units (sr⁻¹).
SCALES: Final = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
HEADER_BYTES: Final = 12
FILE_SIZE: Final = HEADER_BYTES + 3 * N_CELLS * 8  # 34,992,012 bytes

_HALF_PI: Final = 0.5 * np.pi


class MerlFormatError(ValueError):
    """A file is not a valid MERL ``.binary`` BRDF; the message names the file."""


# --------------------------------------------------------------------------
# File I/O
# --------------------------------------------------------------------------


def read_merl_raw(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read and validate a MERL file; return the raw (unscaled) values.

    Returns an array of shape ``(3, 90, 90, 180)`` with the numbers exactly as
    stored.  Raises :class:`FileNotFoundError` for a missing file and
    :class:`MerlFormatError` (naming the file) for a wrong size, wrong header
    dimensions or non-finite values.
    """
    path = Path(path)
    with open(path, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        if size < HEADER_BYTES:
            raise MerlFormatError(
                f"{path}: truncated file: {size} bytes, shorter than the "
                f"{HEADER_BYTES}-byte header (a MERL file has {FILE_SIZE} bytes)"
            )
        dims = tuple(int(d) for d in np.frombuffer(fh.read(HEADER_BYTES), dtype="<i4"))
        if dims != DIMS:
            raise MerlFormatError(
                f"{path}: wrong header dimensions {dims}, expected {DIMS}"
            )
        if size != FILE_SIZE:
            kind = "truncated file" if size < FILE_SIZE else "wrong size (trailing bytes)"
            raise MerlFormatError(
                f"{path}: {kind}: {size} bytes, a MERL file has exactly {FILE_SIZE}"
            )
        raw = np.fromfile(fh, dtype="<f8", count=3 * N_CELLS)
    if raw.size != 3 * N_CELLS:  # the file shrank while we read it
        raise MerlFormatError(f"{path}: truncated file: read {raw.size} of {3 * N_CELLS} values")
    finite = np.isfinite(raw)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        first = int(bad[0])
        channel, cell = divmod(first, N_CELLS)
        raise MerlFormatError(
            f"{path}: {bad.size} non-finite value(s) (NaN or Inf), first at channel "
            f"{'RGB'[channel]}, cell {tuple(int(i) for i in np.unravel_index(cell, DIMS))} (θh, θd, φd index)"
        )
    return raw.reshape(SHAPE).astype(np.float64, copy=False)


def read_merl(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read a MERL file into physical units.

    Returns a float64 array of shape ``(3, 90, 90, 180)`` indexed
    ``(channel, θh, θd, φd)`` with the channel scales applied.  Unmeasured
    cells stay negative.  Errors as in :func:`read_merl_raw`.
    """
    raw = read_merl_raw(path)
    raw *= SCALES[:, None, None, None]
    return raw


def _check_table(table: ArrayLike, what: str = "table") -> NDArray[np.float64]:
    arr = np.asarray(table, dtype=np.float64)
    if arr.shape != SHAPE:
        raise ValueError(f"{what} has shape {arr.shape}, expected {SHAPE}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} contains NaN or Inf")
    return arr


def write_merl(path: str | os.PathLike[str], table: ArrayLike, *, mark: Mark | None = None) -> None:
    """Write a table in physical units as a MERL file (inverse of :func:`read_merl`).

    The table must have shape ``(3, 90, 90, 180)`` and be finite; negative
    (unmeasured) cells are written negative.  ``mark``: a provenance mark
    (:mod:`brdfpipe.data.provenance`) written into cells no measurement can
    fill, at the raw-file level (exact); every table the project derives or
    generates is written with one, so that it is never taken for a
    measurement.  Without a mark the file reads as measured data.  The file
    is written under a temporary name in the same folder and renamed into
    place, so a crash never leaves a partial file under ``path``
    (:func:`brdfpipe.core.atomic.write_bytes`: fsync'ed, mode 0644, stale
    temporaries of killed writers removed).
    """
    arr = _check_table(table)
    raw = np.ascontiguousarray(arr / SCALES[:, None, None, None], dtype="<f8")
    if mark is not None:
        mark.stamp(raw.reshape(3, N_CELLS))
    header = np.asarray(DIMS, dtype="<i4").tobytes()
    atomic.write_bytes(path, (header, memoryview(raw).cast("B")))


# --------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------


def as_directions(v: ArrayLike, name: str = "directions") -> NDArray[np.float64]:
    """``v`` as an ``(n, 3)`` float64 array (a single 3-vector becomes one row).

    Raises :class:`ValueError` naming ``name`` for any other shape.  Does not
    normalise.
    """
    arr = np.asarray(v, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {arr.shape}")
    return arr


def half_diff(
    wi: ArrayLike, wo: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Rusinkiewicz half/difference angles ``(θh, θd, φd)`` of direction pairs.

    ``wi`` and ``wo`` are ``(n, 3)`` unit vectors in the local frame
    (z = normal).  The difference vector is the incident direction expressed
    in the frame of the half vector, exactly as in MERL's ``BRDFRead.cpp``
    (rotate by −φh about the normal, then by −θh about the binormal).
    ``φd`` is returned in (−π, π], before the reciprocity fold.
    """
    wi = as_directions(wi, "wi")
    wo = as_directions(wo, "wo")
    h = wi + wo
    # ‖h‖ as np.linalg.norm(h, axis=1) sums it (x² + y²) + z², the same bits, without its (n, 3) temporary
    h /= np.sqrt(h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1] + h[:, 2] * h[:, 2])[:, None]
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    # Rotation about z by −φh, then about y by −θh (Rodrigues, as in MERL's code).
    cp, sp = np.cos(phi_h), np.sin(phi_h)
    x1 = wi[:, 0] * cp + wi[:, 1] * sp
    y1 = -wi[:, 0] * sp + wi[:, 1] * cp
    z1 = wi[:, 2]
    ct, st = np.cos(theta_h), np.sin(theta_h)
    dx = x1 * ct - z1 * st
    dy = y1
    dz = x1 * st + z1 * ct
    theta_d = np.arccos(np.clip(dz, -1.0, 1.0))
    phi_d = np.arctan2(dy, dx)
    return theta_h, theta_d, phi_d


def bin_indices(
    theta_h: NDArray[np.float64], theta_d: NDArray[np.float64], phi_d: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """MERL's bin indices ``(iθh, iθd, iφd)`` of half/difference angles in radians (square-root θh, φd folded)."""
    with np.errstate(invalid="ignore"):
        t = np.sqrt(np.maximum(theta_h, 0.0) / _HALF_PI * N_THETA_H * N_THETA_H)
    ih = np.clip(np.where(theta_h > 0.0, t, 0.0).astype(np.intp), 0, N_THETA_H - 1)
    idd = np.clip((theta_d / _HALF_PI * N_THETA_D).astype(np.intp), 0, N_THETA_D - 1)
    phi = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)
    ip = np.clip((phi / np.pi * N_PHI_D).astype(np.intp), 0, N_PHI_D - 1)
    return ih, idd, ip


def cell_index(wi: ArrayLike, wo: ArrayLike) -> NDArray[np.intp]:
    """Flat MERL cell index (0 … 1,457,999, inside one channel) of each pair."""
    ih, idd, ip = bin_indices(*half_diff(wi, wo))
    return (ih * N_THETA_D + idd) * N_PHI_D + ip


def lookup(table: ArrayLike, wi: ArrayLike, wo: ArrayLike) -> NDArray[np.float64]:
    """Look up the BRDF of ``table`` for direction pairs; returns ``(n, 3)`` RGB.

    ``table`` is a ``(3, 90, 90, 180)`` array in physical units (as returned
    by :func:`read_merl`); ``wi`` and ``wo`` are ``(n, 3)`` unit vectors in the
    local frame.  Nearest-cell lookup with MERL's conventions; unmeasured cells
    come back negative, as stored.
    """
    arr = np.asarray(table)
    if arr.shape != SHAPE:
        raise ValueError(f"table has shape {arr.shape}, expected {SHAPE}")
    idx = cell_index(wi, wo)
    return arr.reshape(3, N_CELLS)[:, idx].T.astype(np.float64, copy=False)


def cell_centres() -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Angles ``(θh, θd, φd)`` of the centres of all cells, each shape (90, 90, 180).

    Centres are taken in the binned coordinates: θh = ((i + ½)/90)² · π/2
    (the middle of the square-root bin), θd = (j + ½)/90 · π/2 and
    φd = (k + ½)/180 · π.
    """
    th = ((np.arange(N_THETA_H) + 0.5) / N_THETA_H) ** 2 * _HALF_PI
    td = (np.arange(N_THETA_D) + 0.5) / N_THETA_D * _HALF_PI
    pd = (np.arange(N_PHI_D) + 0.5) / N_PHI_D * np.pi
    return np.meshgrid(th, td, pd, indexing="ij")


def directions_from_half_diff(
    theta_h: ArrayLike, theta_d: ArrayLike, phi_d: ArrayLike, phi_h: ArrayLike = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Light and view directions ``(wi, wo)``, each ``(n, 3)``, of half/difference angles.

    Inverse of :func:`half_diff`: the difference vector is rotated by θh about
    the binormal and by φh about the normal to give ``wi``; ``wo`` is ``wi``
    mirrored about the half vector.
    """
    th, td, pd, ph = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64).ravel() for a in (theta_h, theta_d, phi_d, phi_h))
    )
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], axis=1)
    ct, st = np.cos(th), np.sin(th)
    x1 = d[:, 0] * ct + d[:, 2] * st
    z1 = -d[:, 0] * st + d[:, 2] * ct
    cp, sp = np.cos(ph), np.sin(ph)
    wi = np.stack([x1 * cp - d[:, 1] * sp, x1 * sp + d[:, 1] * cp, z1], axis=1)
    h = np.stack([st * cp, st * sp, ct], axis=1)
    wo = 2.0 * np.sum(wi * h, axis=1, keepdims=True) * h - wi
    return wi, wo


def cell_directions(
    cells: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Light and view directions ``(wi, wo)`` of cell centres (φh = 0).

    ``cells`` are flat cell indices (default: all 1,458,000 cells in file
    order).  Returns two ``(n, 3)`` arrays of unit vectors.  For every
    measured cell (both directions above the horizon) ``cell_index(wi, wo)``
    returns the cell itself.
    """
    th, td, pd = (a.ravel() for a in cell_centres())
    if cells is not None:
        idx = np.asarray(cells, dtype=np.intp).ravel()
        if idx.size and (idx.min() < 0 or idx.max() >= N_CELLS):
            raise ValueError(f"cell indices must lie in [0, {N_CELLS})")
        th, td, pd = th[idx], td[idx], pd[idx]
    return directions_from_half_diff(th, td, pd)


def measured_mask() -> NDArray[np.bool_]:
    """Cells whose centre has light and view direction above the horizon, (90, 90, 180).

    This is the geometric part of MERL's measured region: the cells a gonioreflectometer
    can reach.  Real MERL files measure 1,105,588 cells; this mask has
    slightly fewer because it tests the cell centre only.
    """
    wi, wo = cell_directions()
    return above_horizon(wi, wo).reshape(DIMS)


def above_horizon(wi: NDArray[np.float64], wo: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether both directions of each pair are above the horizon (z > 0): ``(n,)`` from two ``(n, 3)`` arrays."""
    return (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)


# --------------------------------------------------------------------------
# Derived quantities
# --------------------------------------------------------------------------


def _albedo_samples(
    theta_i: NDArray[np.float64], n_phi: int
) -> list[tuple[NDArray[np.intp], NDArray[np.float64]]]:
    """Per incident angle: the cells ``idx`` read by :func:`directional_albedo` and their weights ``jac``.

    ``a(θi) = Σ_k max(ρ[idx_k], 0) · jac_k`` per channel (a cell may occur
    several times).  The geometry depends on the angles only, so it is
    computed once per set of angles (:func:`_albedo_samples_cached`).
    """
    return _albedo_samples_cached(np.asarray(theta_i, dtype=np.float64).tobytes(), int(n_phi))


@lru_cache(maxsize=8)
def _albedo_samples_cached(theta_bytes: bytes, n_phi: int) -> list[tuple[NDArray[np.intp], NDArray[np.float64]]]:
    """:func:`_albedo_samples` for angles given as float64 bytes (hashable; read-only arrays, ≤ 0.5 MB per angle)."""
    theta_i = np.frombuffer(theta_bytes, dtype=np.float64)
    # θh = u² π/2 with u uniform in [0, 1]: midpoint rule in u, dθh = π u du.
    u = (np.arange(N_THETA_H) + 0.5) / N_THETA_H
    th = u * u * _HALF_PI
    w_th = np.pi * u / N_THETA_H * np.sin(th)
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2.0 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    W = np.broadcast_to(w_th[:, None] * (2.0 * np.pi / n_phi), TH.shape).ravel()
    h = np.stack(
        [np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], axis=-1
    ).reshape(-1, 3)
    out = []
    for t in theta_i:
        wi = np.array([np.sin(t), 0.0, np.cos(t)])
        cos_ih = h @ wi
        wo = 2.0 * cos_ih[:, None] * h - wi
        ok = (cos_ih > 0.0) & (wo[:, 2] > 0.0)
        idx = cell_index(np.broadcast_to(wi, (int(ok.sum()), 3)), wo[ok])
        jac = 4.0 * cos_ih[ok] * wo[ok, 2] * W[ok]
        idx.setflags(write=False)
        jac.setflags(write=False)
        out.append((idx, jac))
    return out


def directional_albedo(
    table: ArrayLike, theta_i: ArrayLike, n_phi: int = 360
) -> NDArray[np.float64]:
    """Directional albedo ``∫ ρ(wi, wo) cos θo dωo`` of a table, per incident angle.

    ``theta_i`` are incident zenith angles (radians); returns ``(len, 3)``.
    The integral is taken over the half vector, on MERL's own square-root θh
    grid (one node per θh bin, so narrow specular peaks are resolved), with
    ``dωo = 4 (wi·h) dωh``; ``n_phi`` uniform steps in φh.  Unmeasured
    (negative) cells and directions below the horizon contribute nothing.
    """
    arr = np.asarray(table, dtype=np.float64)
    if arr.shape != SHAPE:
        raise ValueError(f"table has shape {arr.shape}, expected {SHAPE}")
    theta_i = np.atleast_1d(np.asarray(theta_i, dtype=np.float64))
    flat = arr.reshape(3, N_CELLS)
    out = np.empty((theta_i.size, 3))
    for n, (idx, jac) in enumerate(_albedo_samples(theta_i, n_phi)):
        rho = np.maximum(flat[:, idx], 0.0)
        out[n] = rho @ jac
    return out


def mean_directional_albedo_weights(theta_i: ArrayLike, n_phi: int = 360) -> NDArray[np.float64]:
    """Per-cell weights ``(N_CELLS,)`` of the mean of :func:`directional_albedo` over ``theta_i``.

    The directional albedo is a linear functional of the table with its
    negative (unmeasured) values set to 0, so
    ``directional_albedo(t, theta_i).mean(axis=0) == max(t, 0).reshape(3, N_CELLS) @ weights``
    up to the order of summation; ``weights[c]`` is the total weight of cell
    ``c`` (the same for the three channels; zero for cells never read).
    """
    theta = np.atleast_1d(np.asarray(theta_i, dtype=np.float64))
    out = np.zeros(N_CELLS)
    for idx, jac in _albedo_samples(theta, n_phi):
        out += np.bincount(idx, weights=jac, minlength=N_CELLS)
    return out / theta.size
