"""Latent-space exploration (brdfpipe.manifold.latent): hull membership and sampling, neighbours, extrapolation, sampling."""

from __future__ import annotations

import json
import re
import types
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
import scipy.spatial
import scipy.stats

from brdfpipe import cli
from brdfpipe.data import ingest, merl, provenance, store, synth
from brdfpipe.manifold import albedo, analysis, gplvm, gram, latent, likelihood

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


# --------------------------------------------------------------------------
# Models by hand
# --------------------------------------------------------------------------


def _row_digests(path: Path, names: Sequence[str]) -> tuple[int, ...]:
    """The digests of the store rows of ``names`` (what a fit on that store records)."""
    st = store.open_store(path)
    return tuple(int(st.digests[i]) for i in store.material_indices(st, names, "materials"))


def _model(X: np.ndarray, names: Sequence[str], ell: float = 1.0, mu: float = 1e-4, space: str = "raw",
           store: Path | None = None) -> gplvm.GplvmModel:
    """A hand-placed model; with ``store``, tied to its rows (as a fit on that store would be)."""
    X = np.asarray(X, dtype=np.float64)
    chol = np.linalg.cholesky(likelihood.kernel_matrix(X, ell, mu))
    digests = _row_digests(store, names) if store is not None else ()
    return gplvm.GplvmModel(tuple(names), X, ell, mu, space, gram.MEAN_HANDLING, chol, 0.0, 1.0, np.zeros((0, 2)),
                            data_digests=digests)


def _albedo_by_weights(model: gplvm.GplvmModel, A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Independent route: gplvm.weights point by point."""
    return gplvm.blend_weights(gplvm.weights(model, x)) @ A


def _albedos(model: gplvm.GplvmModel, source: object, points: np.ndarray, exact: bool = False) -> np.ndarray:
    """The albedo ``(P, 3)`` at the latent points as extrapolate and sample_material compute it."""
    return latent._Albedo.of(model, source, exact)(np.atleast_2d(np.asarray(points, dtype=np.float64)))


def test_nearest_materials_units_order_ties_and_exclusion() -> None:
    m = _model([[0.0, 0.0], [0.0, 4.0], [4.0, 0.0], [1.0, 1.0]], ["zeta", "beta", "alpha", "mid"], ell=2.0)
    # from the origin: zeta 0, mid √2/2, then alpha and beta tie at 4/ℓ = 2: by name
    got = latent.nearest_materials(m, [0.0, 0.0], k=4)
    assert [n for n, _ in got] == ["zeta", "mid", "alpha", "beta"]
    assert np.allclose([d for _, d in got], [0.0, np.sqrt(2) / 2, 2.0, 2.0])
    assert latent.nearest_materials(m, [0.0, 0.0], k=3)[-1][0] == "alpha"
    assert len(latent.nearest_materials(m, "mid", k=10)) == 4
    got = latent.nearest_materials(m, "beta", k=2, exclude=["beta"])
    assert got == [("mid", pytest.approx(np.sqrt(10) / 2)), ("zeta", pytest.approx(2.0))]
    with pytest.raises(ValueError, match="unknown material 'nope'"):
        latent.nearest_materials(m, "nope")
    with pytest.raises(ValueError, match="q = 2"):
        latent.nearest_materials(m, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="k must be"):
        latent.nearest_materials(m, [0.0, 0.0], k=0)


def test_blend_weights_at_equals_gplvm_weights_point_by_point() -> None:
    rng = np.random.default_rng(7)
    X = rng.normal(size=(9, 3))
    m = _model(X, [f"m{i}" for i in range(9)], ell=1.3, mu=1e-3)
    pts = np.vstack([rng.normal(size=(5, 3)), X[4]])  # the last: exactly a training point (δ term)
    W = latent.blend_weights_at(m, pts)
    for p, w in zip(pts, W):
        assert np.allclose(w, gplvm.blend_weights(gplvm.weights(m, p)), atol=1e-10)
    assert np.allclose(W[-1], np.eye(9)[4], atol=1e-8) and np.allclose(W.sum(axis=1), 1.0)


_A3 = np.array([[0.2, 0.3, 0.1], [0.5, 0.6, 0.3], [0.8, 0.9, 0.5]])


@pytest.mark.parametrize(("start", "through", "reason", "channel"), [
    ("A", "B", "albedo above 1", "g"),  # beyond C the green albedo passes 1 first
    ("C", "B", "albedo below 0", "b"),  # beyond A the blue albedo drops below 0 first
])
def test_extrapolate_stops_at_the_first_step_leaving_0_1(start: str, through: str, reason: str, channel: str) -> None:
    m = _model([[0.0], [1.0], [2.0]], ["A", "B", "C"], ell=3.0)
    e = latent.extrapolate(m, _A3, start, through, step=0.05, max_s=5.0)
    assert e.reason == reason and e.channel == channel
    # independently: walk with gplvm.weights until the first albedo outside [0, 1]
    x0, x1 = m.X[m.names.index(start)], m.X[m.names.index(through)]
    k = 0
    while True:
        a = _albedo_by_weights(m, _A3, x0 + k * 0.05 * (x1 - x0))
        assert np.allclose(e.albedos[k], a, atol=1e-9)
        if (a > 1).any() or (a < 0).any():
            break
        k += 1
    assert k > 20 and len(e.s) == k + 1  # well beyond the material B at s = 1
    assert e.stop_s == pytest.approx(k * 0.05) and e.last_valid_s == pytest.approx((k - 1) * 0.05)
    bad = e.albedos[-1][latent._CHANNELS.index(channel)]
    assert (bad > 1) if reason == "albedo above 1" else (bad < 0)
    assert ((e.albedos[:-1] >= 0) & (e.albedos[:-1] <= 1)).all()
    assert np.allclose(e.point(1.0), x1) and np.allclose(e.last_valid_point, x0 + e.last_valid_s * (x1 - x0))


def test_extrapolate_max_s_direction_vectors_and_errors() -> None:
    m = _model([[0.0], [1.0], [2.0]], ["A", "B", "C"], ell=3.0)
    e = latent.extrapolate(m, _A3, "A", [1.0], step=0.25, max_s=1.0)
    assert e.reason == "max_s reached" and e.stop_s is None and e.last_valid_s == 1.0
    assert np.allclose(e.s, [0, 0.25, 0.5, 0.75, 1.0]) and np.allclose(e.albedos[-1], _A3[1])
    # a start outside [0, 1] already: no valid step
    A = _A3.copy()
    A[0, 2] = 1.5
    e = latent.extrapolate(m, A, "A", "B")
    assert e.last_valid_s is None and e.stop_s == 0.0 and e.reason == "albedo above 1" and e.channel == "b"
    with pytest.raises(ValueError, match="step"):
        latent.extrapolate(m, _A3, "A", "B", step=0)
    with pytest.raises(ValueError, match="zero"):
        latent.extrapolate(m, _A3, "B", "B")
    with pytest.raises(ValueError, match="albedos must be"):
        latent.extrapolate(m, _A3[:2], "A", "B")
    with pytest.raises(ValueError, match="not linear"):
        latent.extrapolate(_model(m.X, m.names, space="log"), _A3, "A", "B")


def test_sample_material_rejects_implausible_albedos_and_is_seeded() -> None:
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]])
    A = np.array([[1.6, 0.5, 0.5], [0.2, 0.3, 0.4], [0.5, 0.5, 0.5], [0.3, 0.2, 0.1], [0.4, 0.4, 0.4]])
    m = _model(X, ["a", "b", "c", "d", "e"], ell=0.7)
    s = latent.sample_material(m, A, np.random.default_rng(4), n=200)
    assert s.points.shape == (200, 2) and s.weights.shape == (200, 5) and s.albedos.shape == (200, 3)
    assert latent.hull_contains(X, s.points).all()
    assert ((s.albedos >= 0) & (s.albedos <= 1)).all()
    assert np.allclose(s.weights, latent.blend_weights_at(m, s.points)) and np.allclose(s.albedos, s.weights @ A)
    # the corner near "a" is implausible: rejections happened, and the same candidates are what was drawn
    assert s.tries > 200
    cand = latent.sample_in_hull(X, 400, np.random.default_rng(4))
    ok = ((_albedos(m, A, cand) >= 0) & (_albedos(m, A, cand) <= 1)).all(axis=1)
    assert 0.05 < 1 - ok.mean() < 0.95
    again = latent.sample_material(m, A, np.random.default_rng(4), n=200)
    assert np.array_equal(again.points, s.points) and again.tries == s.tries
    with pytest.raises(ValueError, match="only 0 of 3"):
        latent.sample_material(m, A + 2.0, np.random.default_rng(0), n=3, max_tries=500)


# --------------------------------------------------------------------------
# With a store: the albedo of the interpolated table
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("latent")
    db = tmp / "db"
    synth.synthesize(db, count=5, seed=3, jobs=1, progress=False)  # seed 3: its walks leave [0, 1]
    zarr_path = tmp / "merl.zarr"
    ingest.ingest(sorted(db.glob("*.binary")), zarr_path, database="synthetic", jobs=1)
    names = list(store.open_store(zarr_path).materials)
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.4, 0.6]])
    return {"tmp": tmp, "store": zarr_path, "names": names, "X": X,
            "albedos": albedo.material_albedos(zarr_path, names)}


def test_latent_albedos_equal_the_albedo_of_the_interpolated_table(tiny: dict) -> None:
    pts = np.array([[0.3, 0.2], [0.9, 0.7], [0.0, 0.0]])
    for space in ("raw", "log"):
        m = _model(tiny["X"], tiny["names"], ell=0.8, space=space, store=tiny["store"])
        got = _albedos(m, tiny["store"], pts, exact=True)
        for p, a in zip(pts, got):
            w = gplvm.blend_weights(gplvm.weights(m, p))
            table, clamped = gplvm.interpolate_table(tiny["store"], w, materials=m.names, space=space)
            assert np.allclose(a, albedo.material_albedo(table), rtol=1e-9, atol=0), space
        assert np.allclose(got[2], tiny["albedos"][0], rtol=1e-6)  # a training point reproduces its material
        linear = latent.blend_weights_at(m, pts) @ tiny["albedos"]
        default = _albedos(m, tiny["store"], pts)
        if space == "raw":
            # w·A, which ignores the clamping of the negative values that these weights produce
            assert np.allclose(default, linear, rtol=1e-12) and np.allclose(default[2], got[2], rtol=1e-6)
            assert not np.allclose(default[:2], got[:2], rtol=1e-3)
        else:  # the log blend is not the blend of the albedos: the table is always formed
            assert np.array_equal(default, got) and not np.allclose(got[:2], linear[:2], rtol=1e-3)


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def model_file(tiny: dict) -> Path:
    """A hand-placed raw-space model of the tiny store, saved like the workflow's fits."""
    fit = types.SimpleNamespace(X=tiny["X"], ell=2.0, mu=1e-4, log_likelihood=0.0, d=1.0,
                                trace=[(0, 0.0)], method="hybrid")
    path = tiny["tmp"] / "q2.npz"
    gplvm.save_model(path, fit, tiny["names"], space="raw",  # type: ignore[arg-type]
                     data_digests=_row_digests(tiny["store"], tiny["names"]))
    return path


def _one_line_error(capsys: pytest.CaptureFixture[str], *needles: str) -> None:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(n in err for n in needles), err


def test_cli_nearest(tiny: dict, model_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names = tiny["names"]
    capsys.readouterr()
    assert cli.main(["-q", "nearest", "--model", str(model_file), "--material", names[4], "-k", "3"]) == 0
    got = json.loads(capsys.readouterr().out)
    # x = (0.4, 0.6): nearest is (0, 1) at √0.32, then (0, 0) and (1, 1) tie at √0.52 (ℓ = 2): by name
    assert names[0] < names[3]
    assert [g["material"] for g in got] == [names[2], names[0], names[3]]
    assert np.allclose([g["latent_distance"] for g in got], np.sqrt([0.32, 0.52, 0.52]) / 2)
    assert cli.main(["-q", "nearest", "--model", str(model_file), "--at", "1,0.1", "-k", "1"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["material"] == names[1]
    assert cli.main(["-q", "nearest", "--model", str(model_file), "--material", "nope"]) == 1
    _one_line_error(capsys, "--material", "nope", str(model_file))
    assert cli.main(["-q", "nearest", "--model", str(model_file), "--at", "1,2,3"]) == 1
    _one_line_error(capsys, "--at", "q = 2")
    assert cli.main(["-q", "nearest", "--model", str(tiny["tmp"] / "missing.npz"), "--at", "1,2"]) == 1
    _one_line_error(capsys, "missing.npz")


def _unmarked(table: np.ndarray) -> np.ndarray:
    """A copy of a table without the red channel's provenance-mark cells (a written file holds the mark there)."""
    out = np.array(table, dtype=np.float64).reshape(3, -1)
    out[0, provenance.MARK_CELLS] = 0.0
    return out


def test_cli_extrapolate_writes_the_last_valid_material(
    tiny: dict, model_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    names, st = tiny["names"], str(tiny["store"])
    out = tmp_path / "last.binary"
    model = gplvm.load_model(model_file)
    # a walk of the fixture that leaves [0, 1] past its second material (which pair does depends on the generator)
    walks = [(a, b, latent.extrapolate(model, tiny["albedos"], a, b, step=0.05, max_s=3.0))
             for a in names for b in names if a != b]
    start, through, e = next(w for w in walks if w[2].reason == "albedo above 1" and 1.0 < w[2].stop_s < 3.0)
    capsys.readouterr()
    assert cli.main(["-q", "extrapolate", "--model", str(model_file), "--store", st, "--from", start,
                     "--through", through, "--step", "0.05", "--max-s", "3", "--out", str(out)]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["reason"] == e.reason == "albedo above 1" and 1.0 < got["stop_s"] < 3.0
    assert got["last_valid_s"] == pytest.approx(got["stop_s"] - 0.05)
    assert max(got["albedo_at_stop"]) > 1 and max(got["albedo_last_valid"]) <= 1
    w = gplvm.blend_weights(gplvm.weights(model, e.last_valid_point))
    table, _ = gplvm.interpolate_table(tiny["store"], w, materials=model.names, space="raw")
    assert np.allclose(_unmarked(merl.read_merl(out)), _unmarked(table), rtol=1e-12)
    mark = provenance.read_mark(out)
    assert mark.kind == "derived" and mark.fields["operation"] == "extrapolate"
    assert mark.fields["inputs"]["start"] == start and mark.fields["inputs"]["through"] == through
    capsys.readouterr()
    assert cli.main(["-q", "extrapolate", "--model", str(model_file), "--store", st, "--from", names[0],
                     "--through", "nope"]) == 1
    _one_line_error(capsys, "--through", "nope")
    assert cli.main(["-q", "extrapolate", "--model", str(model_file), "--store", st, "--from", names[0],
                     "--through", names[1], "--out", st]) == 1
    _one_line_error(capsys, "would write over the input")


def test_cli_sample_writes_seeded_plausible_materials(
    tiny: dict, model_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    st = str(tiny["store"])
    args = ["-q", "sample", "--model", str(model_file), "--store", st, "--seed", "5", "--count", "3"]
    assert cli.main([*args, "--out-dir", str(tmp_path / "a")]) == 0
    meta = json.loads((tmp_path / "a" / "samples.json").read_text())
    assert meta["count"] == 3 and len(meta["samples"]) == 3 and meta["candidates_drawn"] >= 3
    model = gplvm.load_model(model_file)
    pts = np.array([r["latent"] for r in meta["samples"]])
    assert latent.hull_contains(model.X, pts).all()
    for r in meta["samples"]:
        alb = np.array(r["albedo"])
        assert ((alb >= 0) & (alb <= 1)).all()
        w = np.array([r["weights"][n] for n in model.names])
        assert np.allclose(w, latent.blend_weights_at(model, np.array(r["latent"]))[0])
        assert np.allclose(alb, w @ tiny["albedos"])
        table, _ = gplvm.interpolate_table(tiny["store"], w, materials=model.names, space="raw")
        assert np.allclose(_unmarked(merl.read_merl(tmp_path / "a" / r["file"])), _unmarked(table), rtol=1e-12)
        mark = provenance.read_mark(tmp_path / "a" / r["file"])
        assert mark.kind == "derived" and mark.fields["operation"] == "sample" and mark.fields["inputs"]["seed"] == 5
        assert mark.fields["inputs"]["latent"] == r["latent"]
    rows = (tmp_path / "a" / "samples.csv").read_text().splitlines()
    assert len(rows) == 4 and rows[0].startswith("file,x1,x2,albedo_r")
    # the same seed gives the same files; another seed other points
    assert cli.main([*args, "--out-dir", str(tmp_path / "b")]) == 0
    for r in meta["samples"]:
        assert (tmp_path / "a" / r["file"]).read_bytes() == (tmp_path / "b" / r["file"]).read_bytes()
    args[args.index("5")] = "6"
    assert cli.main([*args, "--out-dir", str(tmp_path / "c")]) == 0
    other = json.loads((tmp_path / "c" / "samples.json").read_text())
    assert other["samples"][0]["latent"] != meta["samples"][0]["latent"]
    capsys.readouterr()
    assert cli.main(["-q", "sample", "--model", str(model_file), "--store", str(tmp_path / "no.zarr"),
                     "--seed", "1", "--count", "1", "--out-dir", str(tmp_path / "d")]) == 1
    _one_line_error(capsys, "no.zarr")


@pytest.mark.parametrize("method", ["rejection", "cones"])
def test_samples_uniform_in_an_irregular_polygon(method: str) -> None:
    # cones from the vertex mean have unequal areas here (a uniform choice of cone would fail)
    P = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 0.5], [0.3, 2.0], [-0.5, 0.4]])
    s = latent.sample_in_hull(P, 20000, np.random.default_rng(8), method=method)
    assert latent.hull_contains(P, s).all()
    # area of the part x > 3: clip the polygon by the half-plane (vertices right of it + edge crossings)
    pts = [p for p in P if p[0] > 3]
    for a, b in zip(P, np.roll(P, -1, axis=0)):
        if (a[0] - 3) * (b[0] - 3) < 0:
            t = (3 - a[0]) / (b[0] - a[0])
            pts.append(a + t * (b - a))
    share = scipy.spatial.ConvexHull(np.array(pts)).volume / scipy.spatial.ConvexHull(P).volume
    assert 0.1 < share < 0.2  # 0.128; cones chosen uniformly instead of by area would give 0.175
    assert _binomial_ok(int((s[:, 0] > 3).sum()), 20000, share)


# --------------------------------------------------------------------------
# Integrity (issue 21): a model is tied to the store rows it was fitted on
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fitted(tiny: dict) -> dict:
    """A store of measurement-like files (the tiny tables, unmeasured cells all -1: no synthetic watermark
    or mark binding them to a name), a q = 2 fit of it through the workflow's functions, and a store of the
    same names whose first two rows are swapped (each ingested from the other's file, as a folder of real
    MERL files could be)."""
    tmp = tiny["tmp"] / "fitted"
    plain = tmp / "plain"
    plain.mkdir(parents=True)
    names = tiny["names"]
    sources = {}
    for n in names:
        table = merl.read_merl(tiny["tmp"] / "db" / f"{n}.binary")
        table[table < 0] = -1.0
        sources[n] = plain / f"{n}.binary"
        merl.write_merl(sources[n], table)
    same = tmp / "merl.zarr"
    ingest.ingest(sources, same, database="merl")
    gram.write_gram(same, tmp / "gram-raw.npz")
    gplvm.fit_to_files(tmp / "gram-raw.npz", tmp / "q2.npz", tmp / "q2-trace.csv", q=2, seed=1, max_sweeps=10)
    a, b = names[0], names[1]
    swapped = tmp / "swapped.zarr"
    ingest.ingest({**sources, a: sources[b], b: sources[a]}, swapped, database="merl")
    assert list(store.open_store(swapped).materials) == names  # the same names, in the same order
    return {"model": tmp / "q2.npz", "gram": tmp / "gram-raw.npz", "store": same, "swapped": swapped, "a": a, "b": b}


def test_interpolate_with_a_store_whose_rows_were_swapped_is_refused(
    tiny: dict, fitted: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The tester's case: `interpolate --store` with a store of the same names but two rows swapped wrote
    one material's BRDF under the other's name with exit 0.  Now: exit 1, one line naming the model, the
    store and the material, nothing written."""
    out = tmp_path / "a.binary"
    args = ["interpolate", "--model", str(fitted["model"]), "--between", fitted["a"], tiny["names"][2],
            "--t", "0", "--out", str(out)]
    assert cli.main([*args, "--store", str(fitted["store"])]) == 0  # the store it was fitted on
    out.unlink()
    capsys.readouterr()
    assert cli.main([*args, "--store", str(fitted["swapped"])]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert (f"{fitted['model']}: material {fitted['a']!r} of the store {fitted['swapped']} is not the data the model "
            "was fitted on") in err[0], err[0]
    assert not out.exists()


def test_latent_tools_refuse_a_store_with_other_rows(tiny: dict, fitted: dict, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    model = gplvm.load_model(fitted["model"])
    pts = model.X[:2].mean(axis=0, keepdims=True)
    with pytest.raises(ValueError, match=f"material '{fitted['a']}' of the store .* is not the data"):
        _albedos(model, fitted["swapped"], pts)
    with pytest.raises(ValueError, match=f"material '{fitted['a']}' of the store .* is not the data"):
        analysis.path_points_to_files(model=fitted["model"], store=fitted["swapped"],
                                      points=[(fitted["a"], fitted["b"], 0.5)],
                                      merl_outs=[tmp_path / "p.binary"], weights_outs=[tmp_path / "p.json"])
    assert not (tmp_path / "p.binary").exists()
    assert cli.main(["sample", "--model", str(fitted["model"]), "--store", str(fitted["swapped"]), "--seed", "0",
                     "--count", "1", "--out-dir", str(tmp_path / "samples")]) == 1
    assert "is not the data the model was fitted on" in capsys.readouterr().err


def test_a_gram_file_is_tied_to_its_store(fitted: dict) -> None:
    _, _, info = gram.load_gram(fitted["gram"])
    with pytest.raises(ValueError, match=re.escape(f"{fitted['gram']}: material {fitted['a']!r} of the store "
                                                   f"{fitted['swapped']} is not the data the Gram matrix")):
        gram.check_gram_store(info, fitted["swapped"], fitted["gram"])


@pytest.mark.parametrize("damage", ["truncated", "not a zip", "edited"])
def test_a_damaged_model_is_one_clean_line(fitted: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           damage: str) -> None:
    """A truncated model gave a BadZipFile traceback, a file that is not a zip numpy's 'pickled data'
    message; an edited one (valid npz) passed."""
    bad = tmp_path / "q2.npz"
    data = fitted["model"].read_bytes()
    if damage == "truncated":
        bad.write_bytes(data[: len(data) // 2])
        why = "truncated or corrupt GPLVM model"
    elif damage == "not a zip":
        bad.write_bytes(b"\x80\x04 not a model at all")
        why = "truncated or corrupt GPLVM model (not an npz file: no zip header)"
    else:
        with np.load(fitted["model"]) as z:
            arrays = dict(z)
        arrays["X"] = arrays["X"] * 1.01
        np.savez(bad, **arrays)
        why = "its arrays do not match their recorded digest (damaged or edited)"
    assert cli.main(["nearest", "--model", str(bad), "--at", "0,0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"brdfpipe nearest: error: {bad}: {why}" in err[0], err
