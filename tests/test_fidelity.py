"""brdfpipe.manifold.fidelity: every measure of a data-space candidate, recomputed here by another route."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.spatial

from brdfpipe.core import integrity
from brdfpipe.data import ingest, merl, store, synth
from brdfpipe.data.merl import N_CELLS
from brdfpipe.manifold import albedo, analysis, blendpass, fidelity, fitting, gplvm, gram, latent, likelihood

N = 8


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("fidelity")
    db = tmp / "db"
    synth.synthesize(db, count=N, seed=3, jobs=1, progress=False)
    st_path = tmp / "merl.zarr"
    ingest.ingest(sorted(db.glob("*.binary")), st_path, database="synthetic", jobs=1)
    st = store.open_store(st_path)
    grams, models = {}, {}
    for space in ("raw", "standardised"):
        G, d, info = gram.gram_matrix(st_path, space=space)
        grams[space] = tmp / f"gram-{space}.npz"
        gram.save_gram(grams[space], G, d, info)
    for q in (2, 3):
        G, d, info = gram.load_gram(grams["standardised"])
        res = fitting.fit(G / likelihood.gram_scale(G, d), d, q=q, mu=1e-6, seed=1, max_sweeps=30)
        models[q] = tmp / f"q{q}.npz"
        gplvm.save_model(models[q], res, info.materials, space="standardised", data_digests=info.digests)
    brdf = np.asarray(st.brdf[:], dtype=np.float64).reshape(st.n_materials, 3 * N_CELLS)
    return {"tmp": tmp, "store": st_path, "grams": grams, "models": models, "brdf": brdf,
            "valid": np.tile(np.asarray(st.valid[:], dtype=bool), 3), "names": list(st.materials)}


def _model(setup: dict, q: int) -> gplvm.GplvmModel:
    return gplvm.load_model(setup["models"][q])


def nearest_neighbour_jump(st: Path, model: gplvm.GplvmModel) -> tuple[np.ndarray, np.ndarray]:
    """Per material i: ``‖table(xᵢ + t(xⱼ − xᵢ)) − zᵢ‖ / ‖zᵢ‖`` (the table as written, clamped), and j, alone.

    The jump of one model in a pass of its own (measure_candidate measures every q's in its one pass).
    """
    W, nn = fidelity.nearest_neighbour_points(model)
    return blendpass.measure_blends(st, W, model=model, targets=range(W.shape[0])).to_target, nn


def test_candidate_label() -> None:
    assert fidelity.candidate_label("raw", 1e-4) == "raw-mu0.0001"
    assert fidelity.candidate_label("standardised", 1e-6) == "standardised-mu1e-06"
    with pytest.raises(ValueError, match="unknown data space"):
        fidelity.candidate_label("lab", 1e-4)
    with pytest.raises(ValueError, match="mu"):
        fidelity.candidate_label("raw", -1.0)


def test_smooth_weights_match_gplvm_weights_off_the_training_points(setup: dict) -> None:
    m = _model(setup, 2)
    rng = np.random.default_rng(0)
    P = m.X[rng.integers(0, N, 5)] + 0.05 * rng.standard_normal((5, 2))
    W = fidelity.smooth_weights(m, P)
    for p, w in zip(P, W):  # one point at a time, through the model's own weights
        assert np.allclose(w, gplvm.blend_weights(gplvm.weights(m, p)), atol=1e-10)
    # at a training point the smooth weights differ from e_i by μK⁻¹e_i (no δ term)
    K = likelihood.kernel_matrix(m.X, m.ell, m.mu)
    b = np.eye(N)[0] - m.mu * np.linalg.solve(K, np.eye(N)[0])
    assert np.allclose(fidelity.smooth_weights(m, m.X[:1])[0], gplvm.blend_weights(b), atol=1e-8)


def test_albedo_outside_equals_the_albedo_of_the_interpolated_tables(setup: dict) -> None:
    """w·A (linear) against albedos recomputed from the raw rows; the albedo is linear in the table."""
    m = _model(setup, 2)
    A = albedo.material_albedos(setup["store"], m.names)
    rows = setup["brdf"]
    valid = setup["valid"]
    own = np.stack([albedo.material_albedo(np.where(valid, r, -1.0).reshape(merl.SHAPE)) for r in rows])
    assert np.allclose(own, A, rtol=1e-6)
    # a convex blend (no negative value): its table's albedo is the blend of the albedos
    w = np.zeros(N)
    w[[0, 3]] = 0.3, 0.7
    blend = albedo.material_albedo(np.where(valid, w @ rows, -1.0).reshape(merl.SHAPE))
    assert np.allclose(blend, w @ A, rtol=1e-6)
    H = latent.sample_in_hull(m.X, 6, np.random.default_rng(1))
    far = m.X.mean(axis=0) + 40.0 * (m.X.max(axis=0) - m.X.min(axis=0))  # far outside: the mean material
    P = np.vstack([H, far])
    got = fidelity.albedo_outside(m, P, A)
    for p, flag in zip(P, got):
        a = gplvm.blend_weights(gplvm.weights(m, p)) @ own
        assert flag == bool(((a < 0) | (a > 1)).any())
    assert not got[-1]  # the mean of physical materials is physical


def test_stability_equals_direct_table_differences(setup: dict) -> None:
    """‖z(xᵢ+εu) − zᵢ‖/‖zᵢ‖ from the Gram matrix equals the norm of the difference of the raw rows."""
    m = _model(setup, 3)
    _, _, info = gram.load_gram(setup["grams"]["raw"])
    eps = (1e-6, 1e-2)
    res = fidelity.stability(m, info.raw_gram, epsilons=eps, rng=np.random.default_rng(5))
    rng = np.random.default_rng(5)  # the same directions
    u = rng.standard_normal((N, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    Z = setup["brdf"][:, setup["valid"]]
    for e in eps:
        for i in range(N):
            w = gplvm.blend_weights(gplvm.weights(m, m.X[i] + e * u[i]))
            direct = np.linalg.norm(w @ Z - Z[i]) / np.linalg.norm(Z[i])
            assert res[e][i] == pytest.approx(direct, rel=1e-5, abs=1e-12)
    assert np.median(res[1e-2]) > np.median(res[1e-6])  # further away, more change


def test_nearest_neighbour_spread_against_a_kd_tree() -> None:
    X = np.array([[0.0, 0.0], [0.0, 1e-6], [1.0, 0.0], [3.0, 0.0]])
    m = gplvm.GplvmModel(tuple("abcd"), X, 0.5, 1e-4, "raw", gram.MEAN_HANDLING,
                         np.linalg.cholesky(likelihood.kernel_matrix(X, 0.5, 1e-4)), 0.0, 10.0, np.zeros((0, 2)))
    got = fidelity.nearest_neighbour_spread(m)
    dist, _ = scipy.spatial.cKDTree(X / 0.5).query(X / 0.5, k=2)
    assert got["nn_median"] == pytest.approx(np.median(dist[:, 1]))
    assert got["nn_min"] == pytest.approx(2e-6)
    pairs = scipy.spatial.distance.pdist(X / 0.5)
    assert got["pairs_within_sqrt2mu"] == int((pairs < np.sqrt(2e-4)).sum()) == 1
    assert got["pairs_within_1e-5"] == 1


def test_path_uniformity() -> None:
    rows = [{"path": "p", "t": t, "perceptual_a": d} for t, d in ((0.0, 0.0), (0.5, 0.8), (1.0, 1.0))]
    rows += [{"path": "r", "t": t, "perceptual_a": d} for t, d in ((0.0, 0.0), (0.5, 1.2), (1.0, 1.0))]
    got = fidelity.path_uniformity(rows)
    assert got["perceptual_max_deviation"] == pytest.approx(0.7)  # 1.2 / 1.0 − 0.5
    assert got["perceptual_decreasing_steps"] == 1


def test_measure_candidate_and_combine(setup: dict) -> None:
    tmp = setup["tmp"]
    names = setup["names"]
    paths = [[names[0], names[1]]]
    out_s, out_t = tmp / "cand.csv", tmp / "cand-stab.csv"
    rows = fidelity.measure_candidate(
        store=setup["store"], grams=setup["grams"], models=setup["models"], candidate="standardised-mu1e-06",
        default="standardised-mu1e-06", paths=paths, path_q=3, seed=4, steps=4, albedo_grid=12,
        clamped_hull_points=300, spaces_out=out_s, stability_out=out_t)
    assert [r["q"] for r in rows] == [2, 3]
    for r, q in zip(rows, (2, 3)):
        m = _model(setup, q)
        assert r["kappa"] == pytest.approx(np.linalg.cond(likelihood.kernel_matrix(m.X, m.ell, m.mu)), rel=1e-6)
        assert 0.0 <= r["albedo_bad_hull"] <= 1.0 and r["hull_points"] == fidelity.HULL_POINTS
        assert r["sum_abs_w_hull_median"] >= 1.0 - 1e-9
        assert (r["normalise"], r["method"], r["init"]) == (True, "newton", "best")  # how the fixture was fitted
        # eq. 6 without the normalisation: the fit's L is that of G/s, another number
        Gc, d, _ = gram.load_gram(setup["grams"]["standardised"])
        assert r["log_likelihood_eq6"] == pytest.approx(likelihood.log_likelihood(m.X, Gc, d, m.ell, m.mu), rel=1e-12)
        assert r["log_likelihood"] == m.log_likelihood != pytest.approx(r["log_likelihood_eq6"], rel=1e-3)
        assert r["albedo_clamped_points"] == 300 and 0 <= r["albedo_clamped_bad_hull"] <= 1
        assert r["jump_nn_median_1e-6"] <= r["jump_nn_p90_1e-6"] <= r["jump_nn_max_1e-6"]
        assert r["jump_nn_worst"].count(">") == 1 and r["reproduction_max"] < 1e-6
    assert np.isnan(rows[1]["albedo_bad_map"]) and not np.isnan(rows[0]["albedo_bad_map"])
    assert np.isnan(rows[1]["albedo_clamped_bad_map"]) and not np.isnan(rows[0]["albedo_clamped_bad_map"])
    assert np.isnan(rows[0]["perceptual_max_deviation"]) and rows[1]["perceptual_max_deviation"] >= 0.0
    # the map statistic by another route: the grid of analysis.albedo_map, w·A outside [0, 1]
    m2 = _model(setup, 2)
    A = albedo.material_albedos(setup["store"], m2.names)
    amap = analysis.albedo_map(m2, A, n=12)
    assert rows[0]["albedo_bad_map"] == pytest.approx(((amap["albedo"] < 0) | (amap["albedo"] > 1)).any(axis=2).mean())
    table = integrity.read_csv_rows(out_s)[1]
    assert [t["default"] for t in table] == ["true", "true"] and table[0]["database"] == "synthetic"
    # more clamped points than hull points drawn: refused before any work
    for bad in (0, fidelity.HULL_POINTS + 1):
        with pytest.raises(ValueError, match=f"clamped_hull_points must be in \\[1, {fidelity.HULL_POINTS}\\], got {bad}"):
            fidelity.measure_candidate(
                store=setup["store"], grams=setup["grams"], models=setup["models"], candidate="standardised-mu1e-06",
                default="standardised-mu1e-06", paths=paths, path_q=3, seed=4, steps=4, albedo_grid=12,
                clamped_hull_points=bad, spaces_out=tmp / "x.csv", stability_out=tmp / "y.csv")
    assert not (tmp / "x.csv").exists()
    # a wrong label is refused, naming the file
    with pytest.raises(ValueError, match="q2.npz: a standardised-mu1e-06 fit, expected raw-mu0.0001"):
        fidelity.measure_candidate(
            store=setup["store"], grams=setup["grams"], models=setup["models"], candidate="raw-mu0.0001",
            default="raw-mu0.0001", paths=paths, path_q=3, seed=4, steps=4, albedo_grid=12,
            spaces_out=tmp / "x.csv", stability_out=tmp / "y.csv")
    # combining: one default exactly
    fidelity.combine_candidates(spaces=[out_s], stability=[out_t], spaces_out=tmp / "all.csv",
                                stability_out=tmp / "all-stab.csv")
    assert (tmp / "all.csv").read_text() == out_s.read_text()
    with pytest.raises(ValueError, match="cand.csv: a second row for standardised-mu1e-06, 2"):
        fidelity.combine_candidates(spaces=[out_s, out_s], stability=[out_t], spaces_out=tmp / "all2.csv",
                                    stability_out=tmp / "all2-stab.csv")
    nodefault = tmp / "nodefault.csv"
    nodefault.write_text(out_s.read_text().replace(",true,", ",false,"))  # edited by hand: refused
    with pytest.raises(ValueError, match="nodefault.csv: its content does not match its recorded digest"):
        fidelity.combine_candidates(spaces=[nodefault], stability=[out_t], spaces_out=tmp / "all2.csv",
                                    stability_out=tmp / "all2-stab.csv")
    integrity.write_csv(nodefault, integrity.read_csv_text(out_s).replace(",true,", ",false,"))
    with pytest.raises(ValueError, match="exactly one default"):
        fidelity.combine_candidates(spaces=[nodefault], stability=[out_t], spaces_out=tmp / "all2.csv",
                                    stability_out=tmp / "all2-stab.csv")
    assert not (tmp / "all2.csv").exists()


def test_albedo_map_hull_statistics(setup: dict) -> None:
    m = _model(setup, 2)
    A = albedo.material_albedos(setup["store"], m.names)
    amap = analysis.albedo_map(m, A, n=16)
    XX, YY = np.meshgrid(amap["x"], amap["y"])
    inside = latent.hull_contains(m.X, np.c_[XX.ravel(), YY.ravel()], method="lp").reshape(16, 16)
    assert (amap["inside_hull"] == inside).all() and inside.any() and (~inside).any()
    bad = ((amap["albedo"] < 0) | (amap["albedo"] > 1)).any(axis=2)
    assert float(amap["bad_inside"]) == pytest.approx(bad[inside].mean())
    assert float(amap["bad_outside"]) == pytest.approx(bad[~inside].mean())
    # the map's smooth interpolant at the training points vs their own albedo
    w = fidelity.smooth_weights(m, m.X)
    gap = np.abs((w @ A - A) @ np.array([0.2126, 0.7152, 0.0722]))
    assert float(amap["training_gap_max"]) == pytest.approx(gap.max())


def test_log_candidate_measures_its_blends_in_two_passes(setup: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """The log space: the clamped tables' hull points of every q in one pass over the albedo's cells, the path
    points in another (issue 23: not a pass per point); the measures equal to those of each point's table formed
    whole (the route before) to 1e-9."""
    from brdfpipe.manifold import blendpass, perceptual

    tmp = setup["tmp"]
    G, d, info = gram.gram_matrix(setup["store"], space="log")
    grams = {"raw": setup["grams"]["raw"], "log": tmp / "gram-log.npz"}
    gram.save_gram(grams["log"], G, d, info)
    models = {}
    for q in (2, 3):
        res = fitting.fit(G / likelihood.gram_scale(G, d), d, q=q, mu=1e-4, seed=1)
        models[q] = tmp / f"log-q{q}.npz"
        gplvm.save_model(models[q], res, info.materials, space="log", data_digests=info.digests)
    passes, given = [], {}
    real_blends, real_measure = blendpass.measure_blends, fidelity.measure_model

    def counted(*a, **k):
        passes.append(k.get("albedo_only", False))
        return real_blends(*a, **k)

    def spied(m, **k):
        given[m.X.shape[1]] = k["clamped_albedo"]  # the albedos the shared pass measured
        return real_measure(m, **k)

    monkeypatch.setattr(blendpass, "measure_blends", counted)
    monkeypatch.setattr(fidelity, "measure_model", spied)
    names = setup["names"]
    paths = [[names[0], names[5]], [names[3], names[1]]]
    rows = fidelity.measure_candidate(
        store=setup["store"], grams=grams, models=models, candidate="log-mu0.0001", default="log-mu0.0001",
        paths=paths, path_q=3, seed=4, steps=4, albedo_grid=6, clamped_hull_points=12,
        spaces_out=tmp / "log.csv", stability_out=tmp / "log-stab.csv")
    assert passes == [True, False] and [r["q"] for r in rows] == [2, 3]
    for q, row in zip((2, 3), rows):  # the albedo of each hull point's table, formed whole
        m = gplvm.load_model(models[q])
        H = latent.sample_in_hull(m.X, fidelity.HULL_POINTS, np.random.default_rng([4, q, *b"log-mu0.0001"]))
        tables, clamped = gplvm.interpolate_tables(setup["store"], fidelity.smooth_weights(m, H[:12]), model=m,
                                                   space="log")
        want = np.stack([albedo.material_albedo(t) for t in tables])
        np.testing.assert_allclose(given[q], want, rtol=1e-9, atol=0)
        bad = ((want < 0) | (want > 1)).any(axis=1).mean()
        assert row["albedo_clamped_bad_hull"] == row["albedo_bad_hull"] == bad and row["albedo_clamped_points"] == 12
        jump, nn = nearest_neighbour_jump(setup["store"], m)  # the tables of the log space's blends
        assert row["jump_nn_max_1e-6"] == pytest.approx(jump.max(), rel=1e-9) and row["jump_nn_worst"] == (
            f"{m.names[int(jump.argmax())]}>{m.names[int(nn[jump.argmax()])]}")
        assert np.isnan(row["reproduction_max"])  # a Gram quantity: linear spaces only
    assert 0.0 <= rows[0]["albedo_clamped_bad_map"] <= 1.0 and np.isnan(rows[1]["albedo_clamped_bad_map"])
    m3 = gplvm.load_model(models[3])
    ref = []
    for a, b in paths:  # each path's tables formed whole
        p = analysis.latent_path(m3, a, b, 4)
        tables, _ = gplvm.interpolate_tables(setup["store"], p.weights, model=m3, space="log")
        ref += [{"path": a + b, "t": t, "perceptual_a": perceptual.pr12_distance(tab, tables[0])}
                for t, tab in zip(p.ts, tables)]
    want = fidelity.path_uniformity(ref)
    assert rows[1]["perceptual_max_deviation"] == pytest.approx(want["perceptual_max_deviation"], rel=1e-9)
    assert rows[1]["perceptual_decreasing_steps"] == want["perceptual_decreasing_steps"]


# -- what is rendered: the clamped table and the table next to a material, through `brdfpipe interpolate` --

EPS = float(np.finfo(np.float64).eps)


def _interpolate(setup: dict, q: int, out: Path, *args: str) -> np.ndarray:
    """The table `brdfpipe interpolate` writes (the command line, as a user runs it)."""
    from brdfpipe import cli

    assert cli.main(["interpolate", "--model", str(setup["models"][q]), "--store", str(setup["store"]), *args,
                     "--out", str(out)]) == 0
    return merl.read_merl(out)


def test_clamped_albedo_is_that_of_the_table_brdfpipe_interpolate_writes(setup: dict, tmp_path: Path) -> None:
    """The albedo the fidelity measure gives a latent point equals the white-sky albedo of the MERL file that
    `brdfpipe interpolate --at` writes, computed here from the file's table (merl.directional_albedo over the
    same θi nodes), not from w·A — which differs where the blend has negative values."""
    m = _model(setup, 2)
    H = latent.sample_in_hull(m.X, 4, np.random.default_rng(1))
    got = fidelity.clamped_albedos(setup["store"], {2: m}, {2: H})[2]
    A = albedo.material_albedos(setup["store"], m.names)
    W = fidelity.smooth_weights(m, H)
    theta = np.arcsin(np.sqrt((np.arange(albedo.ALBEDO_NODES) + 0.5) / albedo.ALBEDO_NODES))
    differs = 0
    for k, x in enumerate(H):
        table = _interpolate(setup, 2, tmp_path / f"p{k}.binary", "--at=" + ",".join(repr(float(v)) for v in x))
        want = merl.directional_albedo(table, theta).mean(axis=0)
        # bound: the weights of one point (gplvm.weights) and of many (smooth_weights) differ by rounding, which
        # moves the clamped table's albedo by at most Σ|Δwᵢ| Aᵢ (clamping is 1-Lipschitz, the albedo weights are
        # ≥ 0 and the materials' values too); the sums over ≤ N_CELLS cells in another order and the MERL file's
        # scale factors (2 roundings a value) add 4 N_CELLS eps of the albedo
        dw = np.abs(gplvm.blend_weights(gplvm.weights(m, x)) - W[k])
        tol = dw @ A.max(axis=1) + 4 * N_CELLS * EPS * want
        assert np.all(np.abs(got[k] - want) <= tol), (got[k], want, tol)
        differs += bool(np.any(np.abs(W[k] @ A - want) > 100 * tol))  # the unclamped Σ wᵢ Aᵢ: another number
    assert differs >= 2


def _rounding(w: np.ndarray, i: int, norms: np.ndarray, n_values: int, dist: float, gram: bool = False) -> float:
    """Bound on the difference of two float64 routes to ‖Σ wⱼ zⱼ − zᵢ‖ / ‖zᵢ‖ (``dist``) from rounding alone.

    Each value of the blend is a dot product over the N materials, off by at most (N + 2)·eps·Σ|wⱼ||zⱼ| in any
    order of summation (and by 2 eps more through a MERL file's scale factors), so the difference vector by
    (N + 4)·eps·Σ|wⱼ|‖zⱼ‖ in norm; the norm itself sums n_values squares (n_values·eps relative).  ``gram``: one
    route is vᵀGv (v = w − eᵢ) with each entry of G = Z Zᵀ off by n_values·eps·‖zⱼ‖‖zₖ‖: its root by
    √(n_values·eps)·Σ|vⱼ|‖zⱼ‖ more.
    """
    v = np.abs(w - np.eye(len(w))[i]) @ norms
    return ((len(w) + 4) * EPS * float(np.abs(w) @ norms) + (np.sqrt(n_values * EPS) * v if gram else 0.0)) \
        / norms[i] + n_values * EPS * dist


def test_jump_next_to_a_material_is_the_table_brdfpipe_interpolate_writes(setup: dict, tmp_path: Path) -> None:
    """jump_nn: the distance from the material's own table of the table `brdfpipe interpolate --between i j
    --t 1e-6` writes (j the nearest neighbour), clamped as written — the unclamped blend is never nearer; at t = 0 the
    same command gives the material back (reproduction_max), the fidelity a measure at the points alone reports."""
    m = _model(setup, 3)
    jump, nn = nearest_neighbour_jump(setup["store"], m)
    _, _, info = gram.load_gram(setup["grams"]["raw"])
    repro = fidelity.reproduction_at_points(m, info.raw_gram)
    Z = setup["brdf"][:, setup["valid"]]
    norms = np.linalg.norm(Z, axis=1)
    i = int(jump.argmax())
    a, b = m.names[i], m.names[int(nn[i])]
    for t, measured in ((1e-6, jump[i]), (0.0, repro[i])):
        table = _interpolate(setup, 3, tmp_path / f"t{t:g}.binary", "--between", a, b, "--t", f"{t:g}")
        written = np.linalg.norm(table.reshape(-1)[setup["valid"]] - Z[i]) / norms[i]
        w = gplvm.blend_weights(gplvm.weights(m, (1.0 - t) * m.X[i] + t * m.X[int(nn[i])]))
        bound = _rounding(w, i, norms, Z.shape[1], written, gram=t == 0.0)  # reproduction_max: the Gram route
        assert abs(measured - written) <= bound, (t, measured, written)
        unclamped = np.linalg.norm(w @ Z - Z[i]) / norms[i]
        if t > 0:  # negative values written as 0, a projection onto the tables >= 0 where the material lies:
            # the rendered table is never farther from it than the unclamped blend
            assert written <= unclamped + 2 * _rounding(w, i, norms, Z.shape[1], unclamped)
    assert jump[i] > 1e3 * max(repro[i], 1e-12)  # next to the material, not at it: the jump the δ term hides
