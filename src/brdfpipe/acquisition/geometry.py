"""Acquisition geometry of minimal BRDF sampling (Xu et al. 2016 §5.2, §8):
which MERL cells one acquisition configuration observes.

Setups (:class:`Setup`: point, nearfield, fixed_camera, fixed_light), their
configurations (three grid indices, :data:`Config`), a configuration's centre
and per-pixel directions (:func:`centre_directions`, :func:`pixel_directions`),
the MERL cells it observes — one point sample, or every pixel of a near-field
image (:func:`observation_cells`) — and its JSON record in a directions file
(:func:`config_to_dict`, :func:`config_from_dict`).  The comment below the
imports describes each setup and the near-field pixel model.  The metrics
these observations feed are :mod:`brdfpipe.acquisition.metrics`; the
optimiser that searches configurations is :mod:`brdfpipe.acquisition.optimize`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.registry import nearfield
from brdfpipe.data import merl

__all__ = [
    "DEFAULT_GRID",
    "Config",
    "Setup",
    "centre_directions",
    "pixel_directions",
    "pixel_positions",
    "observation_cells",
    "config_to_dict",
    "config_from_dict",
    "CONFIG_DIMS",
    "cell_config",
    "centre_cells",
]

F64 = NDArray[np.float64]

# Which MERL cells one acquisition *configuration* observes.  Four setups:
#
# point (Nielsen et al. 2015)
#     One BRDF sample per configuration.  A configuration is a MERL cell
#     (iθh, iθd, iφd); its observation is that cell.  Centre directions: the
#     cell centre (merl.cell_centres) with φh = 0.
#
# nearfield (Xu et al. 2016 §5.2, Fig. 4)
#     A pinhole camera at C = R·wo (R = 1: only ν = r/R matters) looks at the
#     centre of a flat disk of radius r = ν = tan(α/2) (α = fov); the light is
#     distant, direction wi for every point of the disk.  A configuration is a
#     MERL cell (iθh, iθd, iφd): the cell of the *centre pixel*; wi and wo are
#     the cell centre's directions (φh = 0).  Every other pixel sees the disk
#     point P its ray hits and the view direction normalize(C − P), hence its
#     own (θh, θd, φd) cell.
#
# fixed_camera / fixed_light (Xu §8)
#     n images share the camera (resp. light) direction.  The BRDF is
#     isotropic and the disk rotationally symmetric, so only the shared
#     direction's elevation and each image's other direction *relative to it*
#     matter: the shared direction is put at azimuth 0 and a configuration is
#     three grid indices (i_shared, i_theta, i_phi):
#
#         shared direction  (θ = i_shared · 1°,  φ = 0)             i_shared ∈ [0, 90)
#         other direction   (θ = i_theta · 1°,   φ = i_phi · 2°)     i_theta ∈ [0, 90), i_phi ∈ [0, 180)
#
#     (fixed_camera: camera = shared, light = other; fixed_light: the
#     reverse).  All images of one set carry the same i_shared.  An other
#     direction at the zenith (i_theta = 0) has no azimuth: only i_phi = 0 is
#     a valid configuration there.  (With the shared direction at the zenith,
#     configurations differing in i_phi only are rotations of one another
#     about z: the same cells up to the pixel lattice's orientation.)  Each image is rendered with the near-field
#     pixel model above at the configured fov; its "cell" (reported like the
#     other setups') is that of its centre pixel.  Integer-degree directions
#     often sit on a MERL bin edge (θd and φd bins are 1° wide), so which of
#     two neighbouring cells a pixel falls in is decided by rounding — the
#     same way every time.
#
# The near-field pixel model
# --------------------------
# The image frames the whole disk (Xu §5.2: "the image always sees the full
# sample") at every camera direction.  The disk lies inside the ball of
# radius ν about the origin, which subtends the half-angle asin(ν) from C, so
# in tangent-plane coordinates (u, v) its image lies in [−h, h]² with
#
#     h = tan(asin ν) = ν / √(1 − ν²)          (:func:`brdfpipe.registry.nearfield.image_half_width`)
#
# (h = 0.2273 against ν = 0.2217 at 25°, 0.4551 against 0.4142 at 45°; a
# square image of half-width ν — the bound at the zenith — clipped 2–3.8 %
# of the disk at 45° oblique views).  Pixel centres lie on a grid × grid
# lattice of pitch Δ *centred on the optical axis*: u = (i − ⌊grid/2⌋)·Δ,
# i = 0 … grid − 1, so there always is a centre pixel, looking exactly along
# −wo.  Δ is the smallest pitch whose pixel footprints [u − Δ/2, u + Δ/2]
# cover [−h, h] (:func:`brdfpipe.registry.nearfield.pixel_pitch`): Δ = 2h/grid for an odd grid; an even
# grid has one more column on the negative side than on the positive one,
# so Δ = 2h/(grid − 1) (its negative side reaches past −h).  Camera frame:
# forward f = −wo, right e_r = (−sin φo, cos φo, 0) (horizontal, normal to
# the camera's plane of incidence; φo = atan2(wo_y, wo_x), 0 at the zenith),
# up e_u = e_r × f (:func:`brdfpipe.registry.nearfield.camera_basis`); where
# lattice index (a, b) sits in a rendered image: :func:`brdfpipe.registry.nearfield.image_frame`.
# The ray f + u·e_r + v·e_u from C meets the plane z = 0
# at P (rays with non-negative z component never do and are dropped); a
# pixel is kept iff |P| ≤ r: pixels outside the disk are masked, they are
# not observations.  At the zenith the disk spans ±ν/Δ pixels about the
# centre (717 of 1024 pixels kept for 25°/32); oblique cameras see it
# foreshortened into an ellipse and keep fewer (632 at 30°, 380 at 60°,
# 140 at 80° for 25°/32).  Every kept ray is within asin(ν) of the optical
# axis (α/2 at the zenith).
#
# The observed cells are cell_index(wi, view) of the kept pixels, in lattice
# order, with repeats (neighbouring pixels often share a cell; every pixel is
# one observation row).  Cells outside the *valid* set are dropped: by default
# the geometrically measured cells (merl.measured_mask: both directions of the
# cell centre above the horizon); the optimiser passes the model's columns.


#: Default pixel lattice (grid × grid) of an image setup.
DEFAULT_GRID: int = 32
_MAX_GRID: int = 4096

#: A configuration: three non-negative grid indices (see the section comment):
#: (iθh, iθd, iφd) of the centre cell for point / nearfield,
#: (i_shared, i_theta, i_phi) for fixed_camera / fixed_light.
Config = tuple[int, int, int]

#: Index range of each of a configuration's three axes, (90, 90, 180) for
#: every setup (the MERL grid (iθh, iθd, iφd), and 1° / 1° / 2° steps of fixed_*).
CONFIG_DIMS: tuple[int, int, int] = (merl.N_THETA_H, merl.N_THETA_D, merl.N_PHI_D)
_FIXED_THETA_DEG: float = 1.0  # elevation steps of fixed_* (shared and per image)
_FIXED_PHI_DEG: float = 2.0  # azimuth steps of fixed_* (per image)


@dataclass(frozen=True)
class Setup:
    """An acquisition setup: kind, field of view (degrees) and pixel lattice.

    ``kind``: a set-up of :data:`~brdfpipe.registry.acquisition.SETUPS`.  Image setups (``nearfield``,
    ``fixed_camera``, ``fixed_light``) need ``0 < fov_deg < 90`` (an image
    can frame the whole disk from every camera direction only if ν < 1) and a
    ``grid`` ≥ 1 (the image is a ``grid × grid`` lattice); ``point`` needs
    ``fov_deg == 0`` and its ``grid`` is normalised to 1 (one sample per
    configuration).  :class:`ValueError` otherwise.
    """

    kind: str
    fov_deg: float = 0.0
    grid: int = DEFAULT_GRID

    def __post_init__(self) -> None:
        acquisition_spec.setup(self.kind)  # ValueError naming the known set-ups
        if isinstance(self.fov_deg, (bool, np.bool_)) or not isinstance(
            self.fov_deg, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"fov_deg must be a number, got {self.fov_deg!r}")
        fov = float(self.fov_deg)
        if isinstance(self.grid, bool) or not isinstance(self.grid, (int, np.integer)):
            raise ValueError(f"grid must be an integer, got {self.grid!r}")
        grid = int(self.grid)
        if not self.spec.images:
            if fov != 0.0:
                raise ValueError(f"a point setup has no field of view: fov_deg must be 0, got {self.fov_deg!r}")
            if grid < 1:
                raise ValueError(f"grid must be ≥ 1, got {grid}")
            grid = 1
        else:
            if not (np.isfinite(fov) and 0.0 < fov < 90.0):
                raise ValueError(f"{self.kind} needs 0 < fov_deg < 90, got {self.fov_deg!r}")
            if not 1 <= grid <= _MAX_GRID:
                raise ValueError(f"grid must lie in [1, {_MAX_GRID}], got {grid}")
        object.__setattr__(self, "fov_deg", fov)
        object.__setattr__(self, "grid", grid)

    @property
    def spec(self) -> acquisition_spec.SetupKind:
        """The set-up's record (:data:`brdfpipe.registry.acquisition.SETUPS`)."""
        return acquisition_spec.SETUPS[self.kind]

    @property
    def is_image(self) -> bool:
        """True for the image (near-field) setups."""
        return self.spec.images

    @property
    def nu(self) -> float:
        """ν = r/R = tan(α/2) (0 for point)."""
        return math.tan(math.radians(self.fov_deg) / 2.0) if self.is_image else 0.0


def _check_config(setup: Setup, config: ArrayLike) -> Config:
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be a Setup, got {type(setup).__name__}")
    try:
        items = tuple(config)  # type: ignore[arg-type]
    except TypeError:
        raise ValueError(f"a configuration is three integer grid indices, got {config!r}") from None
    if len(items) != 3 or any(isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)) for x in items):
        raise ValueError(f"a configuration is three integer grid indices, got {config!r}")
    c = (int(items[0]), int(items[1]), int(items[2]))
    for value, dim in zip(c, CONFIG_DIMS):
        if not 0 <= value < dim:
            raise ValueError(f"configuration {c} out of range: indices must lie in [0, {CONFIG_DIMS})")
    if setup.spec.shared and c[1] == 0 and c[2] != 0:
        raise ValueError(f"configuration {c}: a direction at the zenith (i_theta = 0) needs i_phi = 0")
    return c


def _flat_cell(c: Config) -> int:
    return (c[0] * merl.N_THETA_D + c[1]) * merl.N_PHI_D + c[2]


def cell_config(cell: int) -> Config:
    """The (iθh, iθd, iφd) configuration of a flat MERL cell index (the point / nearfield grid)."""
    ih, rest = divmod(int(cell), merl.N_THETA_D * merl.N_PHI_D)
    idd, ip = divmod(rest, merl.N_PHI_D)
    return (ih, idd, ip)


def _centre_angles(c: Config) -> tuple[float, float, float]:
    """(θh, θd, φd) in radians of the centre of cell ``c`` (as merl.cell_centres)."""
    th = ((c[0] + 0.5) / merl.N_THETA_H) ** 2 * (0.5 * np.pi)
    td = (c[1] + 0.5) / merl.N_THETA_D * (0.5 * np.pi)
    pd = (c[2] + 0.5) / merl.N_PHI_D * np.pi
    return th, td, pd


def _unit_vectors(theta_deg: ArrayLike, phi_deg: ArrayLike) -> F64:
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    p = np.radians(np.asarray(phi_deg, dtype=np.float64))
    st = np.sin(t)
    return np.stack([st * np.cos(p), st * np.sin(p), np.cos(t)], axis=-1)


def _fixed_directions(kind: str, configs: NDArray[np.intp]) -> tuple[F64, F64]:
    """(wi, wo), each (n, 3), of (n, 3) fixed_* configurations."""
    shared = _unit_vectors(configs[:, 0] * _FIXED_THETA_DEG, 0.0)
    other = _unit_vectors(configs[:, 1] * _FIXED_THETA_DEG, configs[:, 2] * _FIXED_PHI_DEG)
    return (other, shared) if acquisition_spec.SETUPS[kind].shared == "camera" else (shared, other)


def centre_cells(setup: Setup, configs: NDArray[np.intp]) -> NDArray[np.intp]:
    """Centre cells of an (n, 3) array of in-range configurations (vectorised)."""
    configs = np.asarray(configs, dtype=np.intp).reshape(-1, 3)
    if setup.spec.shared:
        wi, wo = _fixed_directions(setup.kind, configs)
        return merl.cell_index(wi, wo)
    return (configs[:, 0] * merl.N_THETA_D + configs[:, 1]) * merl.N_PHI_D + configs[:, 2]


def centre_directions(setup: Setup, config: ArrayLike) -> tuple[F64, F64]:
    """Light and camera unit vectors ``(wi, wo)``, each (3,), of a configuration's centre.

    point / nearfield: the centre of cell (iθh, iθd, iφd) with φh = 0
    (:func:`brdfpipe.data.merl.directions_from_half_diff`); fixed_*: the shared
    direction at (i_shared°, azimuth 0) and the other one at
    (i_theta°, 2·i_phi°).  For nearfield and fixed_* ``wo`` is the direction
    from the disk centre to the camera.
    """
    c = _check_config(setup, config)
    if setup.spec.shared:
        wi, wo = _fixed_directions(setup.kind, np.asarray([c], dtype=np.intp))
    else:
        wi, wo = merl.directions_from_half_diff(*_centre_angles(c))
    return wi[0], wo[0]


@functools.lru_cache(maxsize=16)
def _lattice(fov_deg: float, grid: int) -> tuple[F64, F64, int]:
    """Tangent-plane pixel coordinates (u, v) of the axis-centred lattice and the centre pixel's index."""
    step = nearfield.pixel_pitch(fov_deg, grid)
    j = np.arange(grid) - grid // 2
    a, b = np.meshgrid(j, j, indexing="ij")
    u = a.ravel() * step
    v = b.ravel() * step
    for arr in (u, v):
        arr.setflags(write=False)
    return u, v, (grid // 2) * grid + grid // 2


def _pixel_views(setup: Setup, wo: F64) -> F64:
    """View directions (n, 3) of the kept pixels of a camera at ``wo`` (see the section comment)."""
    return _kept_pixels(setup, wo)[0]


def _kept_pixels(setup: Setup, wo: F64) -> tuple[F64, NDArray[np.intp]]:
    """:func:`_pixel_views` and the lattice indices (a·grid + b) of those pixels."""
    if wo[2] <= 0.0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.intp)
    u, v, centre = _lattice(setup.fov_deg, setup.grid)
    nu = setup.nu
    f, e_r, e_u = nearfield.camera_basis(wo)
    # each pixel's ray f + u·e_r + v·e_u, one component at a time; views of the kept pixels only
    dz = f[2] + u * e_r[2] + v * e_u[2]
    hit = dz < 0.0
    t = np.where(hit, -wo[2] / np.where(hit, dz, -1.0), 0.0)
    px = wo[0] + t * (f[0] + u * e_r[0] + v * e_u[0])
    py = wo[1] + t * (f[1] + u * e_r[1] + v * e_u[1])
    kept = np.flatnonzero(hit & (px * px + py * py <= nu * nu * (1.0 + 1e-12)))
    vx, vy, vz = wo[0] - px[kept], wo[1] - py[kept], np.full(kept.size, wo[2])
    length = np.sqrt(vx * vx + vy * vy + vz * vz)  # np.linalg.norm's sum, (x² + y²) + z²: the same bits
    view = np.stack([vx / length, vy / length, vz / length], axis=1)
    at = np.searchsorted(kept, centre)
    if at < kept.size and kept[at] == centre:
        view[at] = wo  # the centre pixel looks exactly along −wo (P = 0)
    return view, kept


def pixel_directions(setup: Setup, config: ArrayLike) -> tuple[F64, F64]:
    """Light and view directions ``(wi, wo)``, each (n, 3), of every sample of a configuration.

    point: the centre directions (n = 1).  Image setups: one row per kept
    pixel of the near-field pixel model (lattice order; the light is the same
    for every pixel) — before any cell filtering.  Empty (0, 3) arrays when
    the camera is not above the horizon.
    """
    wi, wo = centre_directions(setup, config)
    if not setup.is_image:
        return wi[None, :], wo[None, :]
    view = _pixel_views(setup, wo)
    return np.broadcast_to(wi, view.shape).copy(), view


def pixel_positions(setup: Setup, config: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.intp], int]:
    """Where each row of :func:`pixel_directions` lies in the image: ``(rows, cols, size)``.

    The image is :func:`brdfpipe.registry.nearfield.image_frame`'s ``size`` ×
    ``size`` frame (rows from the top, v up), the one the capture renders;
    lattice index (a, b) is its column ``offset + a`` and row ``size − 1 −
    offset − b``.  ValueError for a point set-up (it has no image).
    """
    if not setup.is_image:
        raise ValueError(f"a {setup.kind} configuration has no image")
    _, wo = centre_directions(setup, config)
    _, kept = _kept_pixels(setup, wo)
    size, offset = nearfield.image_frame(setup.grid)
    a, b = np.divmod(kept, setup.grid)
    return (size - 1 - offset - b).astype(np.intp), (offset + a).astype(np.intp), size


@functools.lru_cache(maxsize=1)
def _measured_flat() -> NDArray[np.bool_]:
    mask = merl.measured_mask().ravel()
    mask.setflags(write=False)
    return mask


def _as_valid(valid: ArrayLike | None) -> NDArray[np.bool_]:
    if valid is None:
        return _measured_flat()
    mask = np.asarray(valid)
    if mask.dtype != np.bool_ or mask.size != merl.N_CELLS:
        raise ValueError(f"valid must be a boolean mask of all {merl.N_CELLS} cells, got {mask.dtype} {mask.shape}")
    return mask.reshape(-1)


def observation_cells(setup: Setup, config: ArrayLike, valid: ArrayLike | None = None) -> NDArray[np.intp]:
    """MERL cells observed by one configuration, with repeats (one entry per observation).

    point: the configuration's cell.  Image setups: the cell of every kept
    pixel (see the section comment), in lattice order; the centre pixel's
    cell is the configuration's centre cell.  Cells not in ``valid`` — a
    boolean mask over all ``merl.N_CELLS`` cells, default
    :func:`brdfpipe.data.merl.measured_mask` (both directions of the cell centre
    above the horizon) — are dropped; so are all pixels when the light is
    not above the horizon.
    """
    mask = _as_valid(valid)
    c = _check_config(setup, config)
    if not setup.is_image:
        cell = _flat_cell(c)
        return np.array([cell] if mask[cell] else [], dtype=np.intp)
    wi, view = pixel_directions(setup, c)
    if view.shape[0] == 0 or wi[0, 2] <= 0.0:
        return np.zeros(0, dtype=np.intp)
    cells = merl.cell_index(wi, view)
    return cells[mask[cells]]


def _half_diff_deg(wi: F64, wo: F64) -> tuple[float, float, float]:
    th, td, pd = merl.half_diff(wi, wo)
    phi = float(pd[0]) + (np.pi if pd[0] < 0.0 else 0.0)
    return float(np.degrees(th[0])), float(np.degrees(td[0])), float(np.degrees(phi))


def config_to_dict(setup: Setup, config: ArrayLike) -> dict[str, Any]:
    """A JSON-friendly record of a configuration's centre.

    Keys: ``cell`` (flat MERL cell index of the centre pixel / point),
    ``theta_h_deg``, ``theta_d_deg``, ``phi_d_deg`` (the centre's half/difference
    angles in degrees, φd folded into [0, 180]: the cell centre for point and
    nearfield, the exact angles of the centre directions for fixed_*),
    ``light`` and ``camera`` (the centre directions ``wi`` and ``wo`` as
    [x, y, z] unit vectors).
    """
    c = _check_config(setup, config)
    wi, wo = centre_directions(setup, c)
    if setup.spec.shared:
        cell = int(merl.cell_index(wi, wo)[0])
        th, td, pd = _half_diff_deg(wi[None, :], wo[None, :])
    else:
        cell = _flat_cell(c)
        th, td, pd = (float(np.degrees(a)) for a in _centre_angles(c))
    return {
        "cell": cell,
        "theta_h_deg": th,
        "theta_d_deg": td,
        "phi_d_deg": pd,
        "light": [float(x) for x in wi],
        "camera": [float(x) for x in wo],
    }


def _vector(record: dict[str, Any], key: str) -> F64:
    v = np.asarray(record.get(key), dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or abs(float(np.linalg.norm(v)) - 1.0) > 1e-6:
        raise ValueError(f"configuration record: {key!r} must be a unit 3-vector, got {record.get(key)!r}")
    return v


def config_from_dict(setup: Setup, record: dict[str, Any]) -> Config:
    """Inverse of :func:`config_to_dict`.

    point / nearfield: from ``cell``.  fixed_*: from the ``light`` and
    ``camera`` vectors (any common rotation about z is allowed): the shared
    direction's elevation and the other direction's elevation and azimuth
    relative to it, rounded to the grid; :class:`ValueError` if the vectors
    are more than 1e-6 off the grid or the record's ``cell`` disagrees.
    """
    if not isinstance(record, dict):
        raise ValueError(f"configuration record must be a dict, got {type(record).__name__}")
    cell = record.get("cell")
    if isinstance(cell, bool) or not isinstance(cell, (int, np.integer)) or not 0 <= int(cell) < merl.N_CELLS:
        raise ValueError(f"configuration record: 'cell' must be a MERL cell index, got {cell!r}")
    if not setup.spec.shared:
        return _check_config(setup, cell_config(int(cell)))
    light, camera = _vector(record, "light"), _vector(record, "camera")
    shared, other = (camera, light) if setup.spec.shared == "camera" else (light, camera)
    ts = math.degrees(math.acos(min(1.0, max(-1.0, shared[2]))))
    to = math.degrees(math.acos(min(1.0, max(-1.0, other[2]))))
    phi_s = math.degrees(math.atan2(shared[1], shared[0])) if np.hypot(shared[0], shared[1]) > 1e-12 else 0.0
    phi_o = math.degrees(math.atan2(other[1], other[0])) if np.hypot(other[0], other[1]) > 1e-12 else phi_s
    c = (
        int(round(ts / _FIXED_THETA_DEG)),
        int(round(to / _FIXED_THETA_DEG)),
        int(round(((phi_o - phi_s) % 360.0) / _FIXED_PHI_DEG)) % merl.N_PHI_D,
    )
    c = _check_config(setup, c)
    wi, wo = centre_directions(setup, c)
    rot = math.radians(phi_s)
    rz = np.array([[math.cos(rot), -math.sin(rot), 0.0], [math.sin(rot), math.cos(rot), 0.0], [0.0, 0.0, 1.0]])
    if max(np.abs(rz @ wi - light).max(), np.abs(rz @ wo - camera).max()) > 1e-6:
        raise ValueError(f"configuration record is not on the {setup.kind} grid: {record!r}")
    if int(merl.cell_index(wi, wo)[0]) != int(cell):
        raise ValueError(f"configuration record: 'cell' {cell} disagrees with its directions")
    return c
