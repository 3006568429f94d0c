"""Geometry and derived quantities of brdfpipe.data.merl (format I/O: test_merl_format.py)."""

from __future__ import annotations

import numpy as np
import pytest

from brdfpipe.data import merl


def _random_dirs(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_cell_directions_look_up_their_own_cell_over_the_whole_table() -> None:
    wi, wo = merl.cell_directions()
    mask = merl.measured_mask().ravel()
    idx = merl.cell_index(wi, wo)
    assert np.array_equal(idx[mask], np.flatnonzero(mask))
    # unit vectors, and the light/view of measured cells above the horizon
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0)
    assert np.allclose(np.linalg.norm(wo, axis=1), 1.0)
    assert (wi[mask, 2] > 0).all() and (wo[mask, 2] > 0).all()


def test_measured_region_is_close_to_real_merl() -> None:
    # Real MERL files measure 1,105,588 of 1,458,000 cells; the centre test is slightly stricter.
    n = int(merl.measured_mask().sum())
    assert 1_080_000 < n <= 1_105_588


def test_half_diff_inverts_directions_from_half_diff() -> None:
    rng = np.random.default_rng(1)
    th = rng.uniform(0.01, 1.5, 500)
    td = rng.uniform(0.01, 1.5, 500)
    pd = rng.uniform(-3.1, 3.1, 500)
    ph = rng.uniform(-3.1, 3.1, 500)
    wi, wo = merl.directions_from_half_diff(th, td, pd, ph)
    th2, td2, pd2 = merl.half_diff(wi, wo)
    assert np.allclose(th2, th, atol=1e-9)
    assert np.allclose(td2, td, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * (pd2 - pd))), 0.0, atol=1e-7)


def test_lookup_is_reciprocal_and_isotropic() -> None:
    rng = np.random.default_rng(2)
    table = rng.uniform(0.0, 1.0, merl.SHAPE)
    wi, wo = _random_dirs(rng, 2000), _random_dirs(rng, 2000)
    # Helmholtz reciprocity: swapping light and view maps φd → φd + π, folded onto the same cell.
    assert np.array_equal(merl.lookup(table, wi, wo), merl.lookup(table, wo, wi))
    # Isotropy: rotating both directions about the normal changes nothing...
    a = 0.7
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    same = merl.cell_index(wi, wo) == merl.cell_index(wi @ rot.T, wo @ rot.T)
    # ...up to pairs that sit on a bin edge (rounding), which must be very rare.
    assert same.mean() > 0.999


def test_mirror_direction_falls_in_first_theta_h_bin() -> None:
    t = np.radians(40.0)
    wi = np.array([[np.sin(t), 0.0, np.cos(t)]])
    wo = np.array([[-np.sin(t), 0.0, np.cos(t)]])
    ih, idd, _ = np.unravel_index(merl.cell_index(wi, wo), merl.DIMS)
    assert ih[0] == 0 and idd[0] == int(40.0 / 90.0 * 90)


def test_lookup_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match="shape"):
        merl.lookup(np.zeros((3, 90, 90, 90)), np.array([[0, 0, 1.0]]), np.array([[0, 0, 1.0]]))
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        merl.lookup(np.zeros(merl.SHAPE), np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="cell indices"):
        merl.cell_directions([merl.N_CELLS])


@pytest.mark.parametrize("albedo", [0.2, 0.8])
def test_directional_albedo_of_lambertian_table(albedo: float) -> None:
    table = np.full(merl.SHAPE, albedo / np.pi)
    got = merl.directional_albedo(table, np.radians([0.0, 30.0, 60.0, 85.0]))
    assert np.allclose(got, albedo, rtol=2e-3)


def test_directional_albedo_ignores_unmeasured_cells() -> None:
    table = np.full(merl.SHAPE, 0.5 / np.pi)
    table[:, ~merl.measured_mask()] = -1.0
    got = merl.directional_albedo(table, np.radians([0.0, 45.0]))
    assert (got > 0).all() and (got <= 0.5 + 1e-3).all()
