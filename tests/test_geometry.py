"""Tests of :mod:`brdfpipe.acquisition.geometry`.

Setups: point (one cell per configuration), nearfield (a pinhole camera over a
disk, every pixel its own view direction), fixed_camera / fixed_light (images
sharing the camera / light direction).  See the section comment in
``brdfpipe/acquisition/geometry.py`` for the pixel model and the fixed_* parametrisation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from brdfpipe.acquisition import geometry
from brdfpipe.acquisition.geometry import DEFAULT_GRID, Setup, centre_directions, config_from_dict, config_to_dict, observation_cells, pixel_directions
from brdfpipe.data import merl
from brdfpipe.registry.acquisition import SETUP_NAMES
from brdfpipe.registry import nearfield

MEASURED = merl.measured_mask()
MEASURED_CELLS = np.flatnonzero(MEASURED.ravel())
IMAGE_KINDS = ("nearfield", "fixed_camera", "fixed_light")


def cell_config(cell: int) -> tuple[int, int, int]:
    ih, idd, ip = np.unravel_index(int(cell), merl.DIMS)
    return int(ih), int(idd), int(ip)


def random_configs(kind: str, n: int, seed: int = 0) -> list[tuple[int, int, int]]:
    """Random configurations whose centre cell is geometrically measured."""
    rng = np.random.default_rng(seed)
    if kind in ("point", "nearfield"):
        return [cell_config(c) for c in rng.choice(MEASURED_CELLS, n, replace=False)]
    out = []
    while len(out) < n:
        c = (int(rng.integers(0, 90)), int(rng.integers(0, 90)), int(rng.integers(0, 180)))
        if c[1] == 0 and c[2] != 0:
            continue  # the zenith has no azimuth: only (s, 0, 0) is valid
        wi, wo = centre_directions(Setup(kind, 25.0), c)
        if MEASURED.ravel()[merl.cell_index(wi, wo)[0]]:
            out.append(c)
    return out


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


# ---------------------------------------------------------------------------
# Setup
# ---------------------------------------------------------------------------


def test_setup_valid_and_normalised() -> None:
    s = Setup("nearfield", 25, 16)
    assert (s.kind, s.fov_deg, s.grid) == ("nearfield", 25.0, 16)
    assert isinstance(s.fov_deg, float)
    assert math.isclose(s.nu, math.tan(math.radians(12.5)))
    assert Setup("point") == Setup("point", 0.0, 32) == Setup("point", 0, 1)
    assert Setup("point").grid == 1 and not Setup("point").is_image
    assert Setup("fixed_light", 25.0).grid == DEFAULT_GRID
    assert set(SETUP_NAMES) == {"point", "nearfield", "fixed_camera", "fixed_light"}
    with pytest.raises(AttributeError):
        s.fov_deg = 30.0  # type: ignore[misc]  # frozen


@pytest.mark.parametrize(
    "args",
    [
        ("spherical", 25.0, 32),
        ("Point", 0.0, 1),
        ("point", 25.0, 1),
        ("point", 0.0, 0),
        ("nearfield", 0.0, 32),
        ("nearfield", -5.0, 32),
        ("nearfield", 180.0, 32),
        ("nearfield", 90.0, 32),  # ν = 1: no image frames the whole disk from every direction
        ("nearfield", float("nan"), 32),
        ("nearfield", float("inf"), 32),
        ("fixed_camera", "25", 32),
        ("fixed_light", True, 32),
        ("nearfield", 25.0, 0),
        ("nearfield", 25.0, 2.5),
        ("nearfield", 25.0, True),
        ("nearfield", 25.0, 10**6),
    ],
)
def test_bad_setups_raise(args: tuple) -> None:
    with pytest.raises(ValueError):
        Setup(*args)


@pytest.mark.parametrize("config", [(90, 0, 0), (0, 90, 0), (0, 0, 180), (-1, 0, 0), (1, 2), (1, 2, 3, 4),
                                    (1.0, 2, 3), (True, 2, 3), "abc", 5])
@pytest.mark.parametrize("kind", SETUP_NAMES)
def test_bad_configs_raise(kind: str, config: object) -> None:
    setup = Setup(kind, 0.0 if kind == "point" else 25.0)
    with pytest.raises(ValueError):
        observation_cells(setup, config)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        centre_directions(setup, config)  # type: ignore[arg-type]


def test_numpy_integer_configs_accepted() -> None:
    setup = Setup("nearfield", 25.0)
    c = np.array([30, 10, 0])
    assert np.array_equal(observation_cells(setup, c), observation_cells(setup, (30, 10, 0)))


# ---------------------------------------------------------------------------
# point
# ---------------------------------------------------------------------------


def test_point_observation_is_the_cell() -> None:
    setup = Setup("point")
    for c in random_configs("point", 50, seed=1):
        cell = np.ravel_multi_index(c, merl.DIMS)
        assert observation_cells(setup, c).tolist() == [cell]
        wi, wo = centre_directions(setup, c)
        ref_wi, ref_wo = merl.cell_directions([cell])
        np.testing.assert_allclose(wi, ref_wi[0], atol=1e-15)
        np.testing.assert_allclose(wo, ref_wo[0], atol=1e-15)
        pw, po = pixel_directions(setup, c)
        assert pw.shape == po.shape == (1, 3)


def test_point_unmeasured_cell_is_dropped() -> None:
    unmeasured = np.flatnonzero(~MEASURED.ravel())
    c = cell_config(unmeasured[len(unmeasured) // 2])
    assert observation_cells(Setup("point"), c).size == 0
    # ... unless the caller's valid mask says otherwise.
    valid = np.ones(merl.N_CELLS, dtype=bool)
    assert observation_cells(Setup("point"), c, valid).size == 1


# ---------------------------------------------------------------------------
# nearfield pixel model
# ---------------------------------------------------------------------------

# θh centre = (30.5/90)²·90° = 10.336°, θd centre = 10.5°, φd = 0.5°: the camera
# is 0.16° from the zenith.
ZENITH_CONFIG = (30, 10, 0)


@pytest.mark.parametrize("grid", [16, 31, 32])
def test_nearfield_zenith_pixel_count_and_centre(grid: int) -> None:
    setup = Setup("nearfield", 25.0, grid)
    wi, wo = centre_directions(setup, ZENITH_CONFIG)
    assert angle_deg(wo, np.array([0.0, 0.0, 1.0])) < 0.2
    cells = observation_cells(setup, ZENITH_CONFIG)
    radius_px = setup.nu / nearfield.pixel_pitch(25.0, grid)  # the disk's radius in pixels
    # lattice points in a disk of radius r: their unit squares lie within r ± √2/2
    assert math.pi * (radius_px - 0.5**0.5) ** 2 <= cells.size <= math.pi * (radius_px + 0.5**0.5) ** 2
    assert cells.size <= math.pi / 4 * grid * grid  # the disk no longer fills the image
    # The centre pixel looks exactly along −wo and sees the configuration's cell.
    pw, po = pixel_directions(setup, ZENITH_CONFIG)
    centre = np.flatnonzero(np.all(po == wo, axis=1))
    assert centre.size == 1
    flat = int(np.ravel_multi_index(ZENITH_CONFIG, merl.DIMS))
    assert int(merl.cell_index(pw[centre], po[centre])[0]) == flat
    assert flat in cells
    # Every pixel within α/2 of the camera direction at the zenith (up to its 0.16° tilt).
    assert angle_deg(po, wo).max() <= 12.5 + 1e-9 + 0.2
    np.testing.assert_array_equal(pw, np.broadcast_to(wi, pw.shape))


def test_nearfield_exact_zenith_disk_fills_image() -> None:
    # A fixed_camera configuration puts the camera exactly at the zenith.
    grid = 32
    setup = Setup("fixed_camera", 25.0, grid)
    _, po = pixel_directions(setup, (0, 40, 0))
    # lattice points (a, b) ∈ [−16, 15]² with (a² + b²)·Δ² ≤ ν², Δ = 2h/31
    assert po.shape[0] == 717
    step = nearfield.pixel_pitch(25.0, grid)
    angles = angle_deg(po, np.array([0.0, 0.0, 1.0]))
    assert angles.max() <= 12.5 + 1e-9
    assert angles.max() >= math.degrees(math.atan(math.tan(math.radians(12.5)) - step))  # the rim is imaged


@pytest.mark.parametrize("fov", [15.0, 25.0, 45.0])
@pytest.mark.parametrize("grid", [15, 32])
def test_image_frames_the_whole_disk(fov: float, grid: int) -> None:
    """From every camera elevation the pixel footprints cover the disk's whole image (Xu §5.2).

    A square image of half-width ν (the bound at the zenith) clips part of
    the disk at oblique views; the half-width h = ν/√(1 − ν²) clips nothing.
    """
    nu = math.tan(math.radians(fov) / 2)
    h = nearfield.image_half_width(fov)
    assert math.isclose(h, math.tan(math.asin(nu)))
    step = nearfield.pixel_pitch(fov, grid)
    lo, hi = -(grid // 2 + 0.5) * step, (grid - 1 - grid // 2 + 0.5) * step
    assert lo <= -h * (1 - 1e-12) and hi >= h * (1 - 1e-12)
    rng = np.random.default_rng(5)
    r = nu * np.sqrt(rng.random(50_000))
    phi = rng.random(50_000) * 2 * np.pi
    P = np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(r)], axis=1)
    clipped_old = []
    for theta in range(0, 90, 5):
        wo = np.array([math.sin(math.radians(theta)), 0.0, math.cos(math.radians(theta))])
        f, e_r = -wo, np.array([0.0, 1.0, 0.0])
        e_u = np.cross(e_r, f)
        ray = P - wo
        t = ray @ f
        u, v = (ray @ e_r) / t, (ray @ e_u) / t
        assert np.all((u >= lo) & (u <= hi) & (v >= lo) & (v <= hi))
        clipped_old.append(float(np.mean((np.abs(u) > nu) | (np.abs(v) > nu))))
    if fov == 45.0:
        assert max(clipped_old) > 0.02  # what the half-width-ν image lost


def test_lattice_position_in_a_symmetric_image() -> None:
    for grid in (1, 7, 8, 32):
        size, offset = nearfield.image_frame(grid)
        assert size % 2 == 1 and size - grid in (0, 1)
        # the centre pixel (a = b = ⌊grid/2⌋) is the image's centre
        assert offset + grid // 2 == size // 2
        assert size - 1 - offset - grid // 2 == size // 2


@pytest.mark.parametrize("kind", IMAGE_KINDS)
@pytest.mark.parametrize("fov", [15.0, 25.0, 45.0])
def test_pixel_views_within_the_disk_cone(kind: str, fov: float) -> None:
    """All views within asin(ν) of the camera direction (α/2 at the zenith), above the horizon."""
    setup = Setup(kind, fov, 24)
    nu = math.tan(math.radians(fov) / 2)
    bound = math.degrees(math.asin(nu))
    assert bound >= fov / 2
    for c in random_configs(kind, 40, seed=2):
        wi, wo = centre_directions(setup, c)
        pw, po = pixel_directions(setup, c)
        assert po.shape[0] >= 1
        assert np.all(po[:, 2] > 0.0)
        np.testing.assert_allclose(np.linalg.norm(po, axis=1), 1.0, atol=1e-12)
        assert angle_deg(po, wo).max() <= bound + 1e-9
        # Each view ray from the camera hits the plane within the disk radius.
        C = wo  # R = 1
        t = C[2] / po[:, 2]  # P = C − t·view lies on z = 0
        P = C - t[:, None] * po
        assert np.all(np.hypot(P[:, 0], P[:, 1]) <= nu * (1 + 1e-9))


def test_foreshortening_fewer_pixels_when_oblique() -> None:
    setup = Setup("fixed_camera", 25.0, 32)
    counts = [pixel_directions(setup, (theta, 0, 0))[1].shape[0] for theta in (0, 30, 60, 80, 89)]
    assert counts == sorted(counts, reverse=True)
    assert counts[0] == 717 and counts[-1] < 100
    # The ellipse's area ∝ cos θ, roughly.
    assert abs(counts[2] / counts[0] - math.cos(math.radians(60))) < 0.1


@pytest.mark.parametrize("kind", IMAGE_KINDS)
def test_small_fov_every_pixel_sees_the_centre_cell(kind: str) -> None:
    setup = Setup(kind, 1e-4, 8)
    for c in random_configs(kind, 30, seed=3):
        wi, wo = centre_directions(setup, c)
        centre = int(merl.cell_index(wi, wo)[0])
        cells = observation_cells(setup, c)
        assert cells.size == pixel_directions(setup, c)[1].shape[0] >= 1
        if kind == "nearfield":
            assert centre == int(np.ravel_multi_index(c, merl.DIMS))
            # cell centres are far from bin edges: every pixel lands in the cell
            assert np.all(cells == centre)
        else:
            # integer-degree directions often sit on a bin edge (θd, φd bins are 1°
            # wide): pixels then fall in the centre cell or a direct neighbour
            assert centre in cells
            got = np.stack(np.unravel_index(cells, merl.DIMS), axis=1)
            ref = np.array(np.unravel_index(centre, merl.DIMS))
            diff = np.abs(got - ref)
            diff[:, 2] = np.minimum(diff[:, 2], merl.N_PHI_D - diff[:, 2])
            assert diff.max() <= 1


@pytest.mark.parametrize("kind", IMAGE_KINDS)
def test_returned_cells_are_measured(kind: str) -> None:
    setup = Setup(kind, 35.0, 24)
    for c in random_configs(kind, 40, seed=4):
        cells = observation_cells(setup, c)
        assert cells.size >= 1 and cells.dtype.kind == "i"
        wi, wo = merl.cell_directions(cells)
        assert np.all(wi[:, 2] > 0.0) and np.all(wo[:, 2] > 0.0)
        # the centre pixel's cell is among them, and repeats are kept
        cwi, cwo = centre_directions(setup, c)
        assert int(merl.cell_index(cwi, cwo)[0]) in cells
    wide = observation_cells(Setup("nearfield", 35.0, 24), ZENITH_CONFIG)
    assert np.unique(wide).size < wide.size


def test_valid_mask_filters_and_is_checked() -> None:
    setup = Setup("nearfield", 25.0, 16)
    all_cells = observation_cells(setup, ZENITH_CONFIG)
    keep = np.zeros(merl.N_CELLS, dtype=bool)
    keep[all_cells[::2]] = True
    sub = observation_cells(setup, ZENITH_CONFIG, keep)
    assert np.all(keep[sub]) and sub.size == int(np.sum(keep[all_cells]))
    with pytest.raises(ValueError):
        observation_cells(setup, ZENITH_CONFIG, np.ones(10, dtype=bool))
    with pytest.raises(ValueError):
        observation_cells(setup, ZENITH_CONFIG, np.ones(merl.N_CELLS, dtype=np.int8))


def test_light_below_horizon_observes_nothing() -> None:
    # Unmeasured nearfield cell whose light is below the horizon.
    setup = Setup("nearfield", 25.0, 16)
    for cell in np.flatnonzero(~MEASURED.ravel())[::50_000]:
        c = cell_config(cell)
        wi, wo = centre_directions(setup, c)
        if wi[2] <= 0.0 or wo[2] <= 0.0:
            assert observation_cells(setup, c, np.ones(merl.N_CELLS, dtype=bool)).size == 0


# ---------------------------------------------------------------------------
# fixed camera / fixed light
# ---------------------------------------------------------------------------


def test_fixed_parametrisation() -> None:
    cam = Setup("fixed_camera", 25.0)
    wi, wo = centre_directions(cam, (64, 30, 45))  # camera 64°, light 30° at azimuth 90°
    np.testing.assert_allclose(wo, [math.sin(math.radians(64)), 0.0, math.cos(math.radians(64))], atol=1e-15)
    np.testing.assert_allclose(wi, [0.0, math.sin(math.radians(30)), math.cos(math.radians(30))], atol=1e-15)
    lig = Setup("fixed_light", 25.0)
    wi2, wo2 = centre_directions(lig, (64, 30, 45))
    np.testing.assert_allclose(wi2, wo, atol=1e-15)
    np.testing.assert_allclose(wo2, wi, atol=1e-15)
    # Light in the mirror direction of the camera: θh = 0, θd = θcam.
    rec = config_to_dict(cam, (40, 40, 90))
    assert rec["theta_h_deg"] == pytest.approx(0.0, abs=1e-9)
    assert rec["theta_d_deg"] == pytest.approx(40.0, abs=1e-9)


@pytest.mark.parametrize("kind", ["fixed_camera", "fixed_light"])
def test_fixed_images_share_the_direction(kind: str) -> None:
    """Images of one set share the camera (light) direction — up to a rotation about z."""
    setup = Setup(kind, 25.0, 24)
    shared = 52
    configs = [(shared, 10, 0), (shared, 70, 33), (shared, 35, 120), (shared, 0, 0)]
    dirs = [centre_directions(setup, c) for c in configs]
    pix = [pixel_directions(setup, c) for c in configs]
    idx = 1 if kind == "fixed_camera" else 0  # wo is the camera, wi the light
    for d, p in zip(dirs, pix):
        # same elevation of the shared direction (the rotation-invariant part) ...
        assert math.isclose(math.degrees(math.acos(d[idx][2])), shared, abs_tol=1e-9)
        # ... and in fact the very same vector
        np.testing.assert_array_equal(d[idx], dirs[0][idx])
        if kind == "fixed_camera":
            # the same camera: the same pixels and per-pixel view directions in every image
            np.testing.assert_array_equal(p[1], pix[0][1])
        else:
            # one light for every pixel of every image
            np.testing.assert_array_equal(p[0], np.broadcast_to(dirs[0][0], p[0].shape))
    if kind == "fixed_camera":
        # same pixels → same view directions in every image; the lights differ
        assert len({tuple(np.round(d[0], 12)) for d in dirs}) == len(configs)
    else:
        assert len({tuple(np.round(d[1], 12)) for d in dirs}) == len(configs)


def test_rotation_about_z_does_not_change_the_cells() -> None:
    """Isotropy + a rotationally symmetric disk: only relative directions matter."""
    setup = Setup("fixed_camera", 25.0, 24)
    from brdfpipe.acquisition import geometry

    c = (50, 35, 70)
    wi, wo = centre_directions(setup, c)
    base = merl.cell_index(np.broadcast_to(wi, (1, 3)), geometry._pixel_views(setup, wo)).tolist()
    for rot in (0.3, 1.7, -2.5):
        rz = np.array([[math.cos(rot), -math.sin(rot), 0], [math.sin(rot), math.cos(rot), 0], [0, 0, 1]])
        views = geometry._pixel_views(setup, rz @ wo)
        cells = merl.cell_index(np.broadcast_to(rz @ wi, views.shape), views)
        # rounding may move a pixel sitting on a bin edge
        assert len(cells) == len(base) and np.mean(cells == np.array(base)) > 0.97


# ---------------------------------------------------------------------------
# JSON records
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", SETUP_NAMES)
def test_config_dict_round_trip(kind: str) -> None:
    setup = Setup(kind, 0.0 if kind == "point" else 25.0)
    for c in random_configs(kind, 30, seed=5):
        rec = config_to_dict(setup, c)
        assert set(rec) == {"cell", "theta_h_deg", "theta_d_deg", "phi_d_deg", "light", "camera"}
        assert isinstance(rec["cell"], int) and all(isinstance(x, float) for x in rec["light"] + rec["camera"])
        assert 0.0 <= rec["phi_d_deg"] <= 180.0
        wi, wo = centre_directions(setup, c)
        assert rec["light"] == wi.tolist() and rec["camera"] == wo.tolist()
        assert rec["cell"] == int(merl.cell_index(wi, wo)[0])
        th, td, pd = merl.half_diff(wi, wo)
        assert rec["theta_h_deg"] == pytest.approx(math.degrees(th[0]), abs=1e-9)
        assert rec["theta_d_deg"] == pytest.approx(math.degrees(td[0]), abs=1e-9)
        assert config_from_dict(setup, rec) == tuple(c)
        if kind in ("point", "nearfield"):
            assert rec["cell"] == int(np.ravel_multi_index(c, merl.DIMS))


@pytest.mark.parametrize("kind", ["fixed_camera", "fixed_light"])
def test_fixed_record_rotated_about_z_reads_back(kind: str) -> None:
    setup = Setup(kind, 25.0)
    c = (47, 22, 101)
    rec = config_to_dict(setup, c)
    rot = 0.77
    rz = np.array([[math.cos(rot), -math.sin(rot), 0], [math.sin(rot), math.cos(rot), 0], [0, 0, 1]])
    rotated = dict(rec, light=(rz @ rec["light"]).tolist(), camera=(rz @ rec["camera"]).tolist())
    assert config_from_dict(setup, rotated) == c
    off_grid = dict(rec, light=[math.sin(0.3), 0.0, math.cos(0.3)] if kind == "fixed_camera" else rec["light"],
                    camera=rec["camera"] if kind == "fixed_camera" else [math.sin(0.3), 0.0, math.cos(0.3)])
    with pytest.raises(ValueError):
        config_from_dict(setup, off_grid)
    with pytest.raises(ValueError):
        config_from_dict(setup, dict(rec, cell=rec["cell"] + 1))
    with pytest.raises(ValueError):
        config_from_dict(setup, dict(rec, light=[0.0, 0.0, 2.0]))


def test_fixed_zenith_has_no_azimuth() -> None:
    setup = Setup("fixed_camera", 25.0)
    rec = config_to_dict(setup, (30, 0, 0))
    assert rec["light"] == [0.0, 0.0, 1.0]
    assert config_from_dict(setup, rec) == (30, 0, 0)
    with pytest.raises(ValueError):
        centre_directions(setup, (30, 0, 5))
    # the shared direction at the zenith is fine with any azimuth of the other one
    assert config_from_dict(setup, config_to_dict(setup, (0, 30, 77))) == (0, 30, 77)


def test_bad_records_raise() -> None:
    setup = Setup("nearfield", 25.0)
    with pytest.raises(ValueError):
        config_from_dict(setup, {"cell": -1})
    with pytest.raises(ValueError):
        config_from_dict(setup, {"cell": merl.N_CELLS})
    with pytest.raises(ValueError):
        config_from_dict(setup, {"cell": 3.0})
    with pytest.raises(ValueError):
        config_from_dict(setup, [1, 2, 3])  # type: ignore[arg-type]


def _kept_pixels_literal(setup: Setup, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The near-field pixel model as the section comment writes it: every lattice ray, then the kept ones."""
    u, v, centre = geometry._lattice(setup.fov_deg, setup.grid)
    f, e_r, e_u = nearfield.camera_basis(wo)
    ray = f + u[:, None] * e_r + v[:, None] * e_u
    hit = ray[:, 2] < 0.0
    t = np.where(hit, -wo[2] / np.where(hit, ray[:, 2], -1.0), 0.0)
    px, py = wo[0] + t * ray[:, 0], wo[1] + t * ray[:, 1]
    keep = hit & (px * px + py * py <= setup.nu * setup.nu * (1.0 + 1e-12))
    view = np.stack([wo[0] - px, wo[1] - py, np.full(px.shape, wo[2])], axis=1)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    view[centre] = wo
    return view[keep], np.flatnonzero(keep)


@pytest.mark.parametrize("kind", ["nearfield", "fixed_camera", "fixed_light"])
def test_kept_pixels_equal_the_literal_model_bit_for_bit(kind: str) -> None:
    """The views are computed for the kept pixels only, component by component: the same bits as the literal model."""
    rng = np.random.default_rng(11)
    for fov in (15.0, 25.0, 45.0):
        for grid in (1, 2, 7, 32, 128):
            setup = Setup(kind, fov, grid)
            for _ in range(6):
                config = (int(rng.integers(0, 90)), int(rng.integers(0, 90)), int(rng.integers(0, 180)))
                try:
                    _, wo = centre_directions(setup, config)
                except ValueError:
                    continue
                if wo[2] <= 0.0:
                    continue
                view, kept = geometry._kept_pixels(setup, wo)
                ref_view, ref_kept = _kept_pixels_literal(setup, wo)
                assert np.array_equal(kept, ref_kept) and np.array_equal(view, ref_view), (kind, fov, grid, config)


def test_half_diff_normalises_the_half_vector_as_numpy_norm_does() -> None:
    """θh, θd, φd equal, bit for bit, the angles of the half vector divided by np.linalg.norm (MERL's formulas)."""
    rng = np.random.default_rng(5)
    wi = rng.standard_normal((20_000, 3))
    wo = rng.standard_normal((20_000, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    cp, sp = np.cos(phi_h), np.sin(phi_h)
    x1 = wi[:, 0] * cp + wi[:, 1] * sp
    y1 = -wi[:, 0] * sp + wi[:, 1] * cp
    ct, st = np.cos(theta_h), np.sin(theta_h)
    dz = x1 * st + wi[:, 2] * ct
    expected = (theta_h, np.arccos(np.clip(dz, -1.0, 1.0)), np.arctan2(y1, x1 * ct - wi[:, 2] * st))
    for got, want in zip(merl.half_diff(wi, wo), expected):
        assert np.array_equal(got, want)
