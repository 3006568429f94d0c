"""brdfpipe.manifold.perceptual: the PR12 perceptual BRDF distance (RMS CIELAB ΔE over light/view pairs)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy import integrate

from brdfpipe.data import merl, synth
from brdfpipe.manifold import perceptual

# --------------------------------------------------------------------------
# Independent reference: the continuous metric for constant-colour Lambertian BRDFs
# --------------------------------------------------------------------------
#
# For ρ_c = albedo_c / π the compared quantity is t_c = albedo_c · cos θi, the same for
# every ωo and depending on ωi only through μ = cos θi.  Over pairs uniform in solid
# angle, ωo integrates out and μ is uniform on [0, 1] (dω = dμ dφ), so
#
#     d² = ∫₀¹ ‖Lab(albedo_a μ) − Lab(albedo_b μ)‖² dμ.
#
# For achromatic albedos a, b (X/Xn = Y/Yn = Z/Zn = a μ, a* = b* = 0):
#
#     d² = 116² ∫₀¹ (f(a μ) − f(b μ))² dμ,
#
# and where both a μ and b μ are above the CIELAB breakpoint ε = (6/29)³ the integrand is
# (a^⅓ − b^⅓)² μ^⅔.  The integral is piecewise polynomial in μ^⅓ with breaks at ε/a and
# ε/b; it is evaluated in closed form below (and cross-checked with quadrature).

EPS = (6.0 / 29.0) ** 3
TOE_K = 1.0 / (3.0 * (6.0 / 29.0) ** 2)
TOE_C = 4.0 / 29.0
M_SRGB = np.array(
    [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]
)


def _f(s: np.ndarray | float) -> np.ndarray:
    s = np.asarray(s, dtype=float)
    return np.where(s > EPS, np.cbrt(s), TOE_K * s + TOE_C)


def _lab(rgb: np.ndarray) -> np.ndarray:
    """CIE 1976 L*a*b* of linear sRGB relative to the white RGB (1, 1, 1); rgb (..., 3)."""
    xyz = rgb @ M_SRGB.T / M_SRGB.sum(axis=1)
    fx, fy, fz = _f(xyz[..., 0]), _f(xyz[..., 1]), _f(xyz[..., 2])
    return np.stack([116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)], axis=-1)


def _grey_closed_form(a: float, b: float) -> float:
    """116 · sqrt(∫₀¹ (f(aμ) − f(bμ))² dμ) in closed form, piecewise in μ."""
    lo, hi = sorted((a, b))  # the darker one leaves the toe later (at ε/lo)
    m1, m2 = min(1.0, EPS / hi), min(1.0, EPS / lo)
    total = 0.0
    # [0, m1]: both in the toe: (K (a − b) μ)²
    total += (TOE_K * (a - b)) ** 2 * m1**3 / 3.0
    # [m1, m2]: hi in the cube root, lo in the toe: (hi^⅓ μ^⅓ − K lo μ − C)²
    if m2 > m1:
        c = np.cbrt(hi)

        def prim(m: float) -> float:
            return (
                c * c * 0.6 * m ** (5 / 3)
                + (TOE_K * lo) ** 2 * m**3 / 3.0
                + TOE_C**2 * m
                - 2 * c * TOE_K * lo * (3 / 7) * m ** (7 / 3)
                - 2 * c * TOE_C * 0.75 * m ** (4 / 3)
                + 2 * TOE_K * lo * TOE_C * m**2 / 2.0
            )

        total += prim(m2) - prim(m1)
    # [m2, 1]: both in the cube root: (a^⅓ − b^⅓)² μ^⅔
    total += (np.cbrt(a) - np.cbrt(b)) ** 2 * 0.6 * (1.0 - m2 ** (5 / 3))
    return 116.0 * float(np.sqrt(total))


def _colour_reference(albedo_a: np.ndarray, albedo_b: np.ndarray) -> float:
    """sqrt(∫₀¹ ‖Lab(a μ) − Lab(b μ)‖² dμ) by adaptive quadrature (independent of the module)."""
    albedo_a, albedo_b = np.asarray(albedo_a, float), np.asarray(albedo_b, float)
    ys = np.concatenate([albedo_a @ M_SRGB.T, albedo_b @ M_SRGB.T]) / np.tile(M_SRGB.sum(axis=1), 2)
    breaks = sorted({min(1.0, EPS / y) for y in ys if y > EPS})

    def g(mu: float) -> float:
        d = _lab(albedo_a * mu) - _lab(albedo_b * mu)
        return float(d @ d)

    val = integrate.quad(g, 0.0, 1.0, points=breaks or None, epsabs=1e-13, epsrel=1e-12, limit=200)[0]
    return float(np.sqrt(val))


# The discrete metric is a midpoint rule on MERL's 90 × 90 × 180 cells (exact cell
# measures, centre values) over a domain whose horizon edge is resolved only to a cell
# (centre test): the domain measure itself comes out 1.5e-4 high (test below).  For
# Lambertian BRDFs the observed error is 2.5e-5 … 3.6e-5 relative over albedos 0.002 … 0.9;
# 1e-4 relative is the tolerance this discretisation justifies.
DISCRETISATION_RTOL = 1e-4

MASK = merl.measured_mask()


def lambertian(albedo: float | tuple[float, float, float]) -> np.ndarray:
    """Lambertian MERL table ρ = albedo/π on the measured cells, −SCALES elsewhere."""
    table = np.empty(merl.SHAPE)
    table[...] = -merl.SCALES[:, None, None, None]
    alb = np.broadcast_to(np.asarray(albedo, dtype=float), (3,))
    table[:, MASK] = alb[:, None] / np.pi
    return table


@pytest.fixture(scope="module")
def realistic() -> tuple[np.ndarray, np.ndarray]:
    specs = synth.plan_database(5, 20240611)
    return synth.generate_table(specs[0]), synth.generate_table(specs[1])  # a metal, a paint


@pytest.fixture(scope="module")
def random_tables() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    out = []
    for scale in (0.3, 1.0, 3.0):
        t = rng.uniform(0.0, scale, merl.SHAPE)
        t[:, ~MASK] = -1.0
        out.append(t)
    return out


# --------------------------------------------------------------------------
# Geometry and definition
# --------------------------------------------------------------------------


def test_cell_measure_integrates_the_half_difference_jacobian_exactly() -> None:
    # dωi dωo = 4 cos θd sin θh sin θd dθh dφh dθd dφd; over θh, θd ∈ [0, π/2] and
    # φd ∈ [0, 2π) (two branches per folded cell) this is exactly 8π².
    w = perceptual._cell_measure()
    assert w.shape == merl.DIMS and (w > 0).all()
    assert 2 * w.sum() == pytest.approx(8 * np.pi**2, rel=1e-13)
    # The domain (both directions above the horizon) has measure (2π)² = 4π²; the
    # centre test resolves the horizon to a cell.
    dom = 2 * w[MASK].sum()
    assert dom == pytest.approx(4 * np.pi**2, rel=3e-4)
    # Specular cells near θh = 0 are tiny (square-root bins): the first θh bin holds
    # far less measure than a uniform bin would.
    assert w[0].sum() < 1e-3 * w[45].sum()


def test_features_are_weighted_cielab_of_cosine_weighted_brdf() -> None:
    geo = perceptual._geometry()
    f = perceptual.pr12_features(lambertian(1.0)).reshape(2, 3, -1)  # white Lambertian
    assert f.shape[2] == geo.cells.size == int(MASK.sum())
    assert perceptual.pr12_n_features() == 6 * geo.cells.size
    # White Lambertian: t = cos θi, so L* = 116 f(cos θi) − 16 (L* = 100 head-on), a* = b* = 0.
    for b in range(2):
        lab = f[b] / geo.sqrt_w
        assert np.allclose(lab[0], 116.0 * _f(geo.cos[b]) - 16.0, rtol=0, atol=1e-9)
        assert np.abs(lab[1:]).max() < 1e-9
    # Branch 1 is the reciprocal pair: its cos θi is branch 0's cos θo.
    wi, wo = merl.cell_directions(geo.cells[:100])
    assert np.allclose(geo.cos[0, :100], wi[:, 2]) and np.allclose(geo.cos[1, :100], wo[:, 2])
    # Normalised weights: both branches together sum to 1.
    assert 2 * geo.w.sum() == pytest.approx(1.0, rel=1e-12)


# --------------------------------------------------------------------------
# Metric properties
# --------------------------------------------------------------------------


def test_distance_to_itself_is_zero(realistic: tuple[np.ndarray, np.ndarray]) -> None:
    a, _ = realistic
    fa = perceptual.pr12_features(a)
    assert not np.isnan(fa).any()  # synth tables are measured over the whole domain
    assert perceptual.pr12_distance(fa, fa) == 0.0
    assert perceptual.pr12_distance(a, fa) == 0.0  # table and features agree
    assert perceptual.pr12_distance(a, a.copy()) == 0.0


def test_distance_is_symmetric_and_positive(realistic: tuple[np.ndarray, np.ndarray]) -> None:
    a, b = realistic
    fa, fb = perceptual.pr12_features(a), perceptual.pr12_features(b)
    dab, dba = perceptual.pr12_distance(fa, fb), perceptual.pr12_distance(fb, fa)
    assert dab == dba
    assert np.isfinite(dab) and dab > 1.0  # a metal and a paint differ by more than 1 ΔE
    assert perceptual.pr12_distance(a, fb) == pytest.approx(dab, rel=1e-12)


def test_triangle_inequality_on_random_tables(random_tables: list[np.ndarray]) -> None:
    feats = [perceptual.pr12_features(t) for t in random_tables]
    d = np.array([[perceptual.pr12_distance(a, b) for b in feats] for a in feats])
    assert np.array_equal(d, d.T) and (np.diag(d) == 0).all()
    assert (d[np.triu_indices(3, 1)] > 0).all()
    for i, j, k in [(0, 1, 2), (1, 2, 0), (2, 0, 1)]:
        assert d[i, k] <= d[i, j] + d[j, k]
    # Also with a point between two others (the case of an interpolation path).
    mid = 0.5 * (random_tables[0] + random_tables[2])
    fm = perceptual.pr12_features(mid)
    assert perceptual.pr12_distance(feats[0], feats[2]) <= (
        perceptual.pr12_distance(feats[0], fm) + perceptual.pr12_distance(fm, feats[2])
    )


# --------------------------------------------------------------------------
# Known answers
# --------------------------------------------------------------------------


def test_closed_form_matches_quadrature() -> None:
    # The test's own closed form, against an independent numerical integral.
    for a, b in [(0.2, 0.7), (0.002, 0.9), (0.004, 0.006), (0.01, 0.02)]:
        ref = 116.0 * np.sqrt(
            integrate.quad(
                lambda m: float((_f(a * m) - _f(b * m)) ** 2),
                0.0,
                1.0,
                points=sorted({min(1.0, EPS / a), min(1.0, EPS / b)}),
                epsabs=1e-14,
                epsrel=1e-13,
            )[0]
        )
        assert _grey_closed_form(a, b) == pytest.approx(ref, rel=1e-9)
    # Both above the breakpoint everywhere but μ → 0: close to 116 |a^⅓ − b^⅓| sqrt(3/5).
    assert _grey_closed_form(0.5, 0.8) == pytest.approx(
        116 * (np.cbrt(0.8) - np.cbrt(0.5)) * np.sqrt(0.6), rel=1e-3
    )


@pytest.mark.parametrize("a, b", [(0.2, 0.7), (0.002, 0.9), (0.01, 0.02)])
def test_grey_lambertian_pair_matches_closed_form(a: float, b: float) -> None:
    d = perceptual.pr12_distance(lambertian(a), lambertian(b))
    assert d == pytest.approx(_grey_closed_form(a, b), rel=DISCRETISATION_RTOL)


def test_coloured_lambertian_pair_matches_continuous_metric() -> None:
    # Colour enters through CIELAB: a*, b* as well as L*.
    ca, cb = np.array([0.6, 0.25, 0.1]), np.array([0.1, 0.3, 0.55])
    d = perceptual.pr12_distance(lambertian(tuple(ca)), lambertian(tuple(cb)))
    assert d == pytest.approx(_colour_reference(ca, cb), rel=DISCRETISATION_RTOL)


# --------------------------------------------------------------------------
# Monotonicity and colour handling
# --------------------------------------------------------------------------


def test_farther_albedo_is_farther() -> None:
    ref = perceptual.pr12_features(lambertian(0.4))
    up = [perceptual.pr12_distance(ref, lambertian(x)) for x in (0.45, 0.6, 0.9)]
    down = [perceptual.pr12_distance(ref, lambertian(x)) for x in (0.3, 0.1, 0.01)]
    assert 0 < up[0] < up[1] < up[2]
    assert 0 < down[0] < down[1] < down[2]
    # Perceptual compression: equal albedo steps matter more in the dark (cube root).
    assert perceptual.pr12_distance(lambertian(0.05), lambertian(0.1)) > (
        perceptual.pr12_distance(lambertian(0.8), lambertian(0.85))
    )


def test_chroma_counts_at_equal_luminance() -> None:
    # Two colours with the same CIE Y (hence the same L* everywhere): a luminance-only
    # metric would call them equal; CIELAB separates them through a*, b*.
    red = np.array([0.5, 0.2, 0.2])
    y = M_SRGB[1] @ red
    grey = np.full(3, y / M_SRGB[1].sum())  # same Y, achromatic
    assert M_SRGB[1] @ grey == pytest.approx(y, rel=1e-12)
    f_red = perceptual.pr12_features(lambertian(tuple(red))).reshape(2, 3, -1)
    f_grey = perceptual.pr12_features(lambertian(tuple(grey))).reshape(2, 3, -1)
    assert np.allclose(f_red[:, 0], f_grey[:, 0], rtol=0, atol=1e-9)  # identical L*
    assert np.abs(f_grey[:, 1:]).max() < 1e-9  # grey: a* = b* = 0
    d = perceptual.pr12_distance(f_red.ravel(), f_grey.ravel())
    assert d > 5.0
    assert d == pytest.approx(_colour_reference(red, grey), rel=DISCRETISATION_RTOL)


def test_channel_swap_changes_distance_like_cielab() -> None:
    # Swapping R and B of a colour keeps luminance-ish but moves b*: distance > 0 and
    # matches the continuous metric; swapping channels of a grey changes nothing.
    c = np.array([0.7, 0.3, 0.1])
    d = perceptual.pr12_distance(lambertian(tuple(c)), lambertian(tuple(c[::-1])))
    assert d == pytest.approx(_colour_reference(c, c[::-1]), rel=DISCRETISATION_RTOL)
    g = lambertian(0.3)
    assert perceptual.pr12_distance(g, g[::-1].copy()) == 0.0


# --------------------------------------------------------------------------
# Unmeasured cells
# --------------------------------------------------------------------------


def test_values_below_the_horizon_are_never_read(random_tables: list[np.ndarray]) -> None:
    t = random_tables[1].copy()
    f0 = perceptual.pr12_features(t)
    t[:, ~MASK] = 123.0  # positive garbage outside the domain
    assert np.array_equal(perceptual.pr12_features(t), f0)


def test_unmeasured_cells_are_excluded(random_tables: list[np.ndarray]) -> None:
    a, b = random_tables[0], random_tables[1]
    geo = perceptual._geometry()
    rng = np.random.default_rng(3)
    drop = rng.choice(geo.cells, size=geo.cells.size // 5, replace=False)  # 20 % of the domain
    b_hole = b.copy()
    b_hole.reshape(3, -1)[:, drop] = -1.0
    b_hole.reshape(3, -1)[1, drop[:10]] = -0.5  # any negative channel marks the cell
    fb = perceptual.pr12_features(b_hole).reshape(6, -1)
    hole = np.isin(geo.cells, drop)
    assert np.isnan(fb[:, hole]).all() and not np.isnan(fb[:, ~hole]).any()
    # Reference: fill a's values into b's holes (zero contribution there), compare
    # whole domains, then renormalise to the measure of the cells actually compared.
    b_fill = b.copy()
    b_fill.reshape(3, -1)[:, drop] = a.reshape(3, -1)[:, drop]
    full = perceptual.pr12_distance(a, b_fill) ** 2
    frac = 2 * geo.w[~hole].sum()
    d = perceptual.pr12_distance(a, b_hole)
    assert d == pytest.approx(np.sqrt(full / frac), rel=1e-12)
    # Same result whichever side has the hole, and a hole on both sides at the same cells
    # (whatever negative number marks it) gives the same distance again.
    assert perceptual.pr12_distance(b_hole, a) == d
    a_hole = a.copy()
    a_hole.reshape(3, -1)[:, drop] = -7.0
    assert perceptual.pr12_distance(a_hole, b_hole) == pytest.approx(d, rel=1e-12)
    # For a pair of Lambertians the RMS over the remaining pairs barely moves.
    la, lb = lambertian(0.2), lambertian(0.7)
    lb_hole = lb.copy()
    lb_hole.reshape(3, -1)[:, drop] = -1.0
    assert perceptual.pr12_distance(la, lb_hole) == pytest.approx(
        perceptual.pr12_distance(la, lb), rel=1e-2
    )


def test_no_common_measured_cell_is_an_error() -> None:
    t = lambertian(0.5)
    t[:, MASK] = -1.0
    with pytest.raises(ValueError, match="no measured cell in common"):
        perceptual.pr12_distance(t, lambertian(0.5))


# --------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------


def test_bad_tables_raise_value_error() -> None:
    good = lambertian(0.5)
    with pytest.raises(ValueError, match="shape"):
        perceptual.pr12_features(np.zeros((3, 90, 90, 179)))
    with pytest.raises(ValueError, match="shape"):
        perceptual.pr12_features(np.zeros((90, 90, 180)))
    with pytest.raises(ValueError, match="dtype"):
        perceptual.pr12_features(good.astype(np.complex128))
    with pytest.raises(ValueError, match="dtype"):
        perceptual.pr12_features(good > 0)
    with pytest.raises(ValueError, match="dtype"):
        perceptual.pr12_features(np.full(merl.SHAPE, "x"))
    nan = good.copy()
    nan[1, 3, 4, 5] = np.nan
    with pytest.raises(ValueError, match=r"NaN at channel G, cell \(3, 4, 5\)"):
        perceptual.pr12_features(nan)
    inf = good.copy()
    inf[0, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="Inf"):
        perceptual.pr12_distance(inf, good)
    # integer tables are real numbers: accepted
    assert perceptual.pr12_features(np.zeros(merl.SHAPE, dtype=np.int32)).dtype == np.float64


def test_bad_features_raise_value_error() -> None:
    f = perceptual.pr12_features(lambertian(0.5))
    with pytest.raises(ValueError, match="feature vector"):
        perceptual.pr12_distance(f[:-1], f)
    with pytest.raises(ValueError, match="feature vector"):
        perceptual.pr12_distance(f.reshape(6, -1), f)
    partial = f.copy()
    partial[0] = np.nan  # NaN in one of the cell's six entries only
    with pytest.raises(ValueError, match="only some"):
        perceptual.pr12_distance(partial, f)
    inf = f.copy()
    inf[5] = np.inf
    with pytest.raises(ValueError, match="Inf"):
        perceptual.pr12_distance(f, inf)


def test_features_are_fast_enough() -> None:
    t = lambertian((0.3, 0.4, 0.5))
    perceptual.pr12_features(t)  # warm-up (geometry cache)
    start = time.perf_counter()
    perceptual.pr12_features(t)
    elapsed = time.perf_counter() - start
    assert elapsed < 2.0, f"pr12_features took {elapsed:.2f} s (≈0.2 s expected)"
