"""Latent-space exploration (brdfpipe.latent): hull membership and sampling, neighbours, extrapolation, sampling."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.spatial
import scipy.stats

from brdfpipe import latent

# --------------------------------------------------------------------------
# hull_contains
# --------------------------------------------------------------------------


@pytest.mark.parametrize("q", [1, 2, 3, 4, 5, 6])
def test_convex_combinations_inside_points_beyond_a_facet_outside(q: int) -> None:
    rng = np.random.default_rng(q)
    X = rng.normal(size=(max(3 * q, 8), q))
    lam = rng.dirichlet(np.ones(X.shape[0]), size=200)
    inside = lam @ X
    assert latent.hull_contains(X, inside).all()
    # beyond a facet: a point of a facet pushed out along the facet's outward normal
    if q == 1:
        outside = np.array([[X.max() + 0.1], [X.min() - 1e-3]])
    else:
        hull = scipy.spatial.ConvexHull(X)
        eq = hull.equations[:50]
        mid = X[hull.simplices[:50]].mean(axis=1)
        outside = mid + 1e-3 * eq[:, :-1]
        # and the facet centres themselves (on the boundary) count as inside
        assert latent.hull_contains(X, mid).all()
    assert not latent.hull_contains(X, outside).any()
    for method in ("qhull", "lp"):
        assert latent.hull_contains(X, inside[:20], method=method).all()
        assert not latent.hull_contains(X, outside[:20], method=method).any()


@pytest.mark.parametrize(("q", "n"), [(2, 30), (3, 25), (5, 100)])
def test_lp_and_qhull_routes_agree_and_match_delaunay(q: int, n: int) -> None:
    rng = np.random.default_rng(10 + q)
    X = rng.normal(size=(n, q))
    P = rng.normal(size=(300, q)) * 1.3
    a = latent.hull_contains(X, P, method="qhull")
    b = latent.hull_contains(X, P, method="lp")
    c = scipy.spatial.Delaunay(X).find_simplex(P) >= 0
    assert 0.1 < a.mean() < 0.9  # both kinds are exercised
    assert np.array_equal(a, b) and np.array_equal(a, c)
    assert np.array_equal(latent.hull_contains(X, P), a)


def test_degenerate_sets_use_their_flat() -> None:
    rng = np.random.default_rng(3)
    # a triangle in 3-D (N = q): inside it vs off its plane
    X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]) @ scipy.stats.special_ortho_group.rvs(3, random_state=4)
    lam = rng.dirichlet(np.ones(3), size=50)
    assert latent.hull_contains(X, lam @ X).all()
    normal = np.cross(X[1] - X[0], X[2] - X[0])
    normal /= np.linalg.norm(normal)
    assert not latent.hull_contains(X, lam @ X + 1e-4 * normal).any()
    # in the plane but outside the triangle: beyond the edge opposite vertex 0
    assert not latent.hull_contains(X, (X[1] + X[2]) / 2 * 1.01 - X[0] * 0.01).any()
    # points on a 2-D plane in 5-D, N = 40 > q: LP and qhull routes agree with a 2-D Delaunay
    B = np.linalg.qr(rng.normal(size=(5, 2)))[0].T  # (2, 5) orthonormal
    Y = rng.normal(size=(40, 2))
    X5 = Y @ B + 0.3
    Q = rng.normal(size=(200, 2)) * 1.5
    expect = scipy.spatial.Delaunay(Y).find_simplex(Q) >= 0
    for method in ("qhull", "lp"):
        assert np.array_equal(latent.hull_contains(X5, Q @ B + 0.3, method=method), expect)
    assert not latent.hull_contains(X5, Q @ B + 0.3 + 1e-3 * rng.normal(size=(200, 5))).any()
    # a segment in 4-D; a single point; two equal points
    S = np.array([[0.0, 1, 2, 3], [1, 1, 2, 5]])
    assert list(latent.hull_contains(S, [[0.5, 1, 2, 4], [1.5, 1, 2, 6], [0.5, 1, 2, 4.1]])) == [True, False, False]
    assert list(latent.hull_contains(S[:1], [S[0], S[1]])) == [True, False]
    assert list(latent.hull_contains(np.vstack([S[:1], S[:1]]), [S[0], S[1]])) == [True, False]


def test_hull_contains_bad_input() -> None:
    with pytest.raises(ValueError, match="columns"):
        latent.hull_contains(np.zeros((4, 2)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        latent.hull_contains(np.array([[0.0, np.nan]]), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="method"):
        latent.hull_contains(np.eye(3), np.zeros((1, 3)), method="delaunay")


# --------------------------------------------------------------------------
# sample_in_hull
# --------------------------------------------------------------------------


def _binomial_ok(hits: int, n: int, p: float, z: float = 4.5) -> bool:
    return abs(hits - n * p) <= z * np.sqrt(n * p * (1 - p))


@pytest.mark.parametrize("method", ["rejection", "cones", "auto"])
def test_samples_uniform_in_a_triangle_and_a_square(method: str) -> None:
    n = 20000
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0], [0.5, 0.25]])  # an interior point too
    s = latent.sample_in_hull(tri, n, np.random.default_rng(0), method=method)
    assert s.shape == (n, 2) and latent.hull_contains(tri, s).all()
    # the sub-triangle with the midpoints of the legs has 1/4 of the area; the strip x < 0.5 has 7/16
    assert _binomial_ok(int((s[:, 0] / 2 + s[:, 1] < 0.5).sum()), n, 0.25)
    assert _binomial_ok(int((s[:, 0] < 0.5).sum()), n, 7 / 16)
    sq = np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]])
    s = latent.sample_in_hull(sq, n, np.random.default_rng(1), method=method)
    assert _binomial_ok(int(((s[:, 0] < 0.3) & (s[:, 1] > 0.6)).sum()), n, 0.12)
    assert _binomial_ok(int((s[:, 0] + s[:, 1] < 0.5).sum()), n, 0.125)


def test_samples_uniform_in_a_thin_simplex_in_5d_and_on_a_flat() -> None:
    # the standard 5-simplex fills 1/120 of its box: auto samples cones
    X = np.vstack([np.zeros(5), np.eye(5)])
    n = 20000
    s = latent.sample_in_hull(X, n, np.random.default_rng(2))
    assert latent.hull_contains(X, s).all()
    # P(x0 > 1/2) in the standard simplex = (1/2)^5
    assert _binomial_ok(int((s[:, 0] > 0.5).sum()), n, 0.5**5)
    assert _binomial_ok(int((s.sum(axis=1) < 0.5).sum()), n, 0.5**5)
    # a square on a plane in 3-D: uniform on it
    B = np.array([[1.0, 1, 0], [0, 0, 1]]) / np.array([[np.sqrt(2)], [1]])
    sq = np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]]) @ B
    s = latent.sample_in_hull(sq, n, np.random.default_rng(3))
    assert latent.hull_contains(sq, s).all()
    u = s @ B.T
    assert np.allclose(u @ B, s)
    assert _binomial_ok(int((u[:, 0] < 0.3).sum()), n, 0.3)


def test_sample_in_hull_is_deterministic_given_the_seed() -> None:
    X = np.random.default_rng(5).normal(size=(30, 3))
    a = latent.sample_in_hull(X, 500, np.random.default_rng(9))
    b = latent.sample_in_hull(X, 500, np.random.default_rng(9))
    c = latent.sample_in_hull(X, 500, np.random.default_rng(10))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    seg = np.array([[0.0, 0], [2, 2]])
    s = latent.sample_in_hull(seg, 1000, np.random.default_rng(1))
    assert np.allclose(s[:, 0], s[:, 1]) and 0 <= s.min() and s.max() <= 2
