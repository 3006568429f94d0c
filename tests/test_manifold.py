"""brdfpipe.manifold.analysis: albedo, albedo maps, paths, the eq. 7 bound, reproduction errors."""

from __future__ import annotations


import numpy as np
import pytest
import scipy.linalg

from brdfpipe.core import integrity
from brdfpipe.registry.errors import ConfigError
from brdfpipe.data import ingest, merl, provenance, store, synth
from brdfpipe.manifold import albedo, analysis, gplvm, gram, likelihood
from brdfpipe.registry import tables


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("manifold")
    db = tmp / "db"
    synth.synthesize(db, count=6, seed=3, jobs=1, progress=False)
    zarr_path = tmp / "merl.zarr"
    ingest.ingest(sorted(db.glob("*.binary")), zarr_path, database="synthetic", jobs=1)
    gram_path = tmp / "gram.npz"
    gram.write_gram(zarr_path, gram_path)
    models = {}
    for q in (2, 3):
        models[q] = tmp / f"q{q}.npz"
        gplvm.fit_to_files(gram_path, models[q], tmp / f"q{q}-trace.csv", q=q, seed=1, max_sweeps=30)
    st = store.open_store(zarr_path)
    brdf = np.asarray(st.brdf[:], dtype=np.float64)
    return {"tmp": tmp, "store": zarr_path, "gram": gram_path, "models": models, "names": list(st.materials),
            "brdf": brdf, "valid": np.asarray(st.valid[:], dtype=bool)}


def test_lambertian_albedo_is_its_reflectance() -> None:
    for a in (0.2, 0.75):
        table = np.full(merl.SHAPE, a / np.pi) * np.array([1.0, 0.5, 0.25])[:, None, None, None]
        alb = albedo.material_albedo(table)
        # MERL's θh grid loses a sliver near grazing; 1 % is the discretisation
        assert np.allclose(alb, a * np.array([1.0, 0.5, 0.25]), rtol=1e-2)
    with pytest.raises(ValueError, match="shape"):
        albedo.material_albedo(np.zeros((3, 9, 9, 9)))


def test_material_albedos_match_per_table(small: dict) -> None:
    names = small["names"]
    A = albedo.material_albedos(small["store"], [names[3], names[0]])
    for k, i in enumerate((3, 0)):
        assert np.allclose(A[k], albedo.material_albedo(small["brdf"][i].reshape(merl.SHAPE)), rtol=1e-12)
    with pytest.raises(ValueError, match="unknown material"):
        albedo.material_albedos(small["store"], ["nope"])


def test_material_albedo_file_round_trips_and_refuses_another_store(small: dict, tmp_path) -> None:
    """measure_material_albedos' file: the albedos computed once, read back bit for bit in any order;
    a damaged file, a file of another store (rows re-ingested) and a missing material are refused."""
    st = store.open_store(small["store"])
    names = small["names"]
    out = tmp_path / "material-albedo.npz"
    written = albedo.write_material_albedos(store=small["store"], out=out)
    assert np.array_equal(written, albedo.material_albedos(st, names))
    picked = [names[4], names[1]]
    assert np.array_equal(albedo.read_material_albedos(out, st, picked), written[[4, 1]])
    with pytest.raises(albedo.MaterialAlbedoError, match="no albedo of material 'nope'"):
        albedo.read_material_albedos(out, st, ["nope"])
    # a file written from another store of the same names (rows ingested from other data): its recorded
    # row digest differs from the store's, so the file is refused (written consistently, digest and all)
    doc = integrity.load_npz(out)
    doc = {k: v for k, v in doc.items() if k != integrity.DIGEST_KEY}
    doc["row_digests"] = doc["row_digests"].copy()
    doc["row_digests"][1] += 1
    other = tmp_path / "other.npz"
    integrity.save_npz(other, doc)
    assert np.array_equal(albedo.read_material_albedos(other, st, [names[0]]), written[[0]])
    with pytest.raises(albedo.MaterialAlbedoError, match=f"albedo of {names[1]!r} was computed from other data"):
        albedo.read_material_albedos(other, st, names)
    doc["database"] = np.array("merl")
    integrity.save_npz(other, doc)
    with pytest.raises(albedo.MaterialAlbedoError, match="written from a merl store"):
        albedo.read_material_albedos(other, st, names)
    # a damaged file is refused by its digest
    raw = bytearray(out.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    out.write_bytes(bytes(raw))
    with pytest.raises(albedo.MaterialAlbedoError, match=str(out)):
        albedo.read_material_albedos(out, st, names)


def test_deviation_is_exact_norm_of_the_blend_difference(small: dict) -> None:
    G, _, _ = gram.load_gram(small["gram"])
    cols = np.flatnonzero(np.tile(small["valid"], 3))
    Z = small["brdf"][:, cols]
    w = np.array([0.5, 0.3, -0.1, 0.2, 0.0, 0.1])
    direct = np.linalg.norm(w @ Z - Z[2])
    assert analysis.deviation(G, w, 2) == pytest.approx(direct, rel=1e-7)


def test_paths_bound_holds_and_ends_are_exact(small: dict) -> None:
    model = gplvm.load_model(small["models"][3])
    G, _, _ = gram.load_gram(small["gram"])
    a, b = small["names"][0], small["names"][4]
    rows = analysis.paths_analysis(small["store"], model, G, [(a, b)], steps=4)
    assert [r["step"] for r in rows] == list(range(5)) and rows[-1]["t"] == 1.0
    assert rows[0]["perceptual_a"] == 0.0 and rows[-1]["perceptual_b"] == 0.0
    assert rows[0]["perceptual_b"] == pytest.approx(rows[0]["perceptual_ab"]) and rows[0]["perceptual_ab"] > 0
    for r in rows:
        assert r["deviation"] <= r["bound"] * (1 + 1e-9) + 1e-6 * np.sqrt(np.trace(G))
    assert rows[0]["nearest"] == a and rows[-1]["nearest"] == b
    assert rows[0]["bound"] == 0.0
    with pytest.raises(ValueError, match="unknown material 'zzz'"):
        analysis.paths_analysis(small["store"], model, G, [(a, "zzz")])


def test_path_memory_does_not_grow_with_its_steps(small: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """manifold.path_steps: no point's table (35 MB) or perceptual features (53 MB) is ever held whole.

    (Holding all of them took one job to 22.7 GB.)  The points are blended a block of cells at a time, the
    block the narrower the more points (blendpass.POINT_CELLS, made small here): the values are those of
    the default blocks, and the peak of 13 points stays that of 3.
    """
    import tracemalloc

    model = gplvm.load_model(small["models"][3])
    G, _, _ = gram.load_gram(small["gram"])
    a, b = small["names"][0], small["names"][4]
    whole = analysis.paths_analysis(small["store"], model, G, [(a, b)], steps=12)
    from brdfpipe.manifold import blendpass

    monkeypatch.setattr(blendpass, "POINT_CELLS", 3 * 4096)
    peaks = {}
    for steps in (2, 12):
        tracemalloc.start()
        rows = analysis.paths_analysis(small["store"], model, G, [(a, b)], steps=steps)
        peaks[steps] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    for r, w in zip(rows, whole):
        for k in ("perceptual_a", "perceptual_b", "perceptual_ab"):
            assert r[k] == pytest.approx(w[k], rel=1e-9, abs=1e-9)
    feature_bytes = 8 * __import__("brdfpipe.manifold.perceptual", fromlist=["x"]).pr12_n_features()
    assert peaks[12] < peaks[2] + 2 * feature_bytes, peaks


def test_check_and_default_paths() -> None:
    names = [f"m{i}" for i in range(10)]
    p1 = analysis.default_paths(names, seed=4)
    assert p1 == analysis.default_paths(names, seed=4) and len(p1) == 3
    assert len({m for pair in p1 for m in pair}) == 6
    soler = [m for pair in analysis.SOLER_PATHS for m in pair] + ["x"]
    assert analysis.default_paths(soler, seed=0) == list(analysis.SOLER_PATHS)
    assert analysis.check_paths([["m1", "m2"]], names) == [("m1", "m2")]
    # A path and its reverse are two paths.
    assert analysis.check_paths([["m1", "m2"], ["m2", "m1"]], names) == [("m1", "m2"), ("m2", "m1")]
    for bad, msg in [([["m1", "nope"]], "unknown material 'nope'"), ([["m1", "m1"]], "two different"),
                     ([["m1"]], "pair of material names"),
                     ([["m1", "m2"], ["m3", "m4"], ["m1", "m2"]], "listed more than once: m1--m2")]:
        with pytest.raises(ConfigError, match=msg):
            analysis.check_paths(bad, names)
    assert issubclass(ConfigError, ValueError)
    assert analysis.path_name("m1", "m2") == "m1--m2"


def test_albedo_map_is_the_weighted_albedo(small: dict) -> None:
    model = gplvm.load_model(small["models"][3])
    A = np.random.default_rng(0).uniform(0.1, 0.9, size=(6, 3))
    amap = analysis.albedo_map(model, A, dims=(0, 2), n=8)
    j, i = 5, 2
    x = amap["fixed"].copy()
    x[0], x[2] = amap["x"][i], amap["y"][j]
    w = gplvm.blend_weights(gplvm.weights(model, x))
    assert np.allclose(amap["albedo"][j, i], w @ A, rtol=1e-9)
    assert amap["albedo"].shape == (8, 8, 3) and int(amap["q"]) == 3
    with pytest.raises(ValueError, match="dims"):
        analysis.albedo_map(model, A, dims=(0, 3))


def test_reproduction_errors(small: dict) -> None:
    G, _, info = gram.load_gram(small["gram"])
    models = {q: gplvm.load_model(p) for q, p in small["models"].items()}
    res = {(m, k): e for m, k, e in analysis.reproduction_errors(G, info.raw_gram, models, ks=(1, 5))}
    assert set(res) == {("pca", 1), ("pca", 2), ("pca", 3), ("pca", 5), ("gplvm", 2), ("gplvm", 3)}
    assert np.all(res[("gplvm", 2)] < 1e-6) and np.all(res[("gplvm", 3)] < 1e-6)
    assert np.all(res[("pca", 5)] < 1e-6)  # N − 1 components of centred data: exact
    assert np.all(res[("pca", 1)] >= res[("pca", 2)] - 1e-12)
    # against a dense truncated SVD
    cols = np.flatnonzero(np.tile(small["valid"], 3))
    Z = small["brdf"][:, cols]
    mu = Z.mean(axis=0)
    U, S, Vt = np.linalg.svd(Z - mu, full_matrices=False)
    rec = mu + (U[:, :2] * S[:2]) @ Vt[:2]
    direct = np.linalg.norm(rec - Z, axis=1) / np.linalg.norm(Z, axis=1)
    assert np.allclose(res[("pca", 2)], direct, rtol=1e-5)


def test_analyze_manifold_writes_everything(small: dict) -> None:
    out = small["tmp"] / "out"
    names = small["names"]
    # Names the library never chose: it writes exactly the paths given.
    outputs = {"albedo_out": out / "a" / "my-albedo.csv",
               "albedo_maps_out": {2: out / "maps" / "two.npz", 3: out / "maps" / "three.npz"},
               "paths_out": out / "my-paths.csv", "reproduction_out": out / "b" / "my-reproduction.csv"}
    analysis.analyze_manifold(store=small["store"], gram=small["gram"], models=small["models"],
                              paths=[[names[1], names[2]]], path_q=3, seed=0, steps=2, albedo_grid=6,
                              pca_ks=(2,), **outputs)
    written = sorted(p for p in out.rglob("*") if p.is_file())
    assert written == sorted([outputs["albedo_out"], *outputs["albedo_maps_out"].values(), outputs["paths_out"],
                              outputs["reproduction_out"]])
    rows = integrity.read_csv_rows(outputs["paths_out"])[1]
    assert len(rows) == 3 and tuple(rows[0]) == tables.LATENT_PATHS and rows[0]["database"] == "synthetic"
    rep = integrity.read_csv_rows(outputs["reproduction_out"])[1]
    assert {(r["method"], r["k"]) for r in rep} == {("pca", "2"), ("pca", "3"), ("gplvm", "2"), ("gplvm", "3")}
    for q, target in outputs["albedo_maps_out"].items():
        z = integrity.load_npz(target)
        assert z["albedo"].shape == (6, 6, 3) and str(z["database"]) == "synthetic" and int(z["q"]) == q
    assert len(integrity.read_csv_rows(outputs["albedo_out"])[1]) == 6
    # Only the albedo maps asked for are written.
    only = small["tmp"] / "only-q3"
    analysis.analyze_manifold(store=small["store"], gram=small["gram"], models=small["models"],
                              paths=[[names[1], names[2]]], path_q=3, seed=0, steps=2, albedo_grid=6,
                              pca_ks=(2,), albedo_out=only / "albedo.csv", albedo_maps_out={3: only / "q3.npz"},
                              paths_out=only / "paths.csv", reproduction_out=only / "reproduction.csv")
    assert sorted(p.name for p in only.iterdir()) == ["albedo.csv", "paths.csv", "q3.npz", "reproduction.csv"]
    fresh = small["tmp"] / "fresh"
    with pytest.raises(ValueError, match="no fitted model"):
        analysis.analyze_manifold(store=small["store"], gram=small["gram"], models=small["models"], paths=None,
                                  path_q=7, seed=0, albedo_out=fresh / "albedo.csv", albedo_maps_out={},
                                  paths_out=fresh / "paths.csv", reproduction_out=fresh / "reproduction.csv")
    with pytest.raises(ValueError, match="no q = 5 model"):
        analysis.analyze_manifold(store=small["store"], gram=small["gram"], models=small["models"], paths=None,
                                  path_q=3, seed=0, albedo_out=fresh / "albedo.csv",
                                  albedo_maps_out={5: fresh / "q5.npz"}, paths_out=fresh / "paths.csv",
                                  reproduction_out=fresh / "reproduction.csv")
    assert not fresh.exists()  # nothing written by a failed call


#: Unit roundoff of float64 and γ_n = n·u / (1 − n·u), the bound on the relative error of a sum of n
#: products in any order (Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed., §3.1, §3.5).
U = np.finfo(np.float64).eps / 2


def _gamma(n: int) -> float:
    return n * U / (1 - n * U)


def _blend_tolerance(w: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Per value, the largest |a − b| between two float64 evaluations of Σ wᵢ zᵢ in any summation order (BLAS
    kernel, blocking, FMA) that then pass through a MERL file: each sum is within γ_n Σ|wᵢ||zᵢ| of the exact
    one, and writing (÷ channel scale) and reading (× scale) round twice more (≤ 3u relative)."""
    absolute = np.abs(w) @ np.abs(Z)
    return 2 * _gamma(w.size) * absolute + 3 * U * np.abs(w @ Z)


def _reproduction_bound(m: gplvm.GplvmModel, a: int) -> np.ndarray:
    """Bound on |w − e_a| for the blend weights of a training point x_a (exact reproduction: w = e_a in exact
    arithmetic), to first order, ×2 for the rest.

    b = K⁻¹k with k = k(x_a) = K e_a up to the rounding of the squared distances (kernel_vector and
    kernel_matrix sum them in other orders: ≤ 2γ_{q+2}|arg| + 4u relative in each entry); the Cholesky solve
    is backward stable, (K + ΔK) b̂ = k̂ with |ΔK| ≤ γ_{3n+1}|C||Cᵀ| (Higham Thm 10.4), so
    |b̂ − e_a| ≤ |K⁻¹| (|Δk| + γ_{3n+1}|C||Cᵀ||b̂|); then w = b̂ + (1 − Σb̂)/N.
    """
    n, q = m.X.shape
    C = m.chol
    Kinv = scipy.linalg.cho_solve((C, True), np.eye(n))
    b = gplvm.weights(m, m.X[a])
    arg = ((m.X - m.X[a]) ** 2).sum(axis=1) / (2 * m.ell**2)
    dk = (2 * _gamma(q + 2) * arg + 4 * U) * likelihood.kernel_vector(m.X, m.X[a], m.ell, m.mu)
    db = np.abs(Kinv) @ (dk + _gamma(3 * n + 1) * (np.abs(C) @ (np.abs(C.T) @ np.abs(b))))
    return 2 * (db + db.sum() / n) + 4 * _gamma(n) * (1 + np.abs(b).sum())


def test_path_points_are_the_blends_of_their_weights(small: dict) -> None:
    """One pass over the store writes, per point, the table Σ wᵢ Zᵢ of that point's own weights.

    Tolerances from the arithmetic (the error bounds above), not from one machine's output: the table
    and the test's own Σ wᵢ Zᵢ are two summation orders of the same sum (BLAS kernels differ between
    machines); at t = 0 the weights are e_a up to the solve's error bound.
    """

    names = small["names"]
    points = [(names[0], names[3], 0.0), (names[0], names[3], 0.5), (names[1], names[4], 0.25)]
    out = small["tmp"] / "points"
    merls = [out / f"p{k}.binary" for k in range(3)]
    jsons = [out / f"p{k}.json" for k in range(3)]
    W = analysis.path_points_to_files(model=small["models"][2], store=small["store"], points=points,
                                      merl_outs=merls, weights_outs=jsons)
    m = gplvm.load_model(small["models"][2])
    valid = np.tile(small["valid"], 3)  # per cell -> per column (3 channels)
    Z = small["brdf"][[names.index(n) for n in m.names]][:, valid]
    for k, (a, b, t) in enumerate(points):
        x = (1 - t) * m.X[m.names.index(a)] + t * m.X[m.names.index(b)]
        w = gplvm.blend_weights(gplvm.weights(m, x))
        np.testing.assert_array_equal(W[k], w)  # the same computation in the same process: the same bits
        doc = integrity.read_json(jsons[k])
        assert (doc["material_a"], doc["material_b"], doc["t"]) == (a, b, t)
        assert [doc["weights"][n] for n in m.names] == list(w)  # JSON floats round-trip exactly
        table = merl.read_merl(merls[k]).reshape(-1)
        tol = _blend_tolerance(w, Z)
        assert np.all(np.abs(table[valid] - np.maximum(w @ Z, 0.0)) <= tol)  # clamping at 0 is 1-Lipschitz
        # the bound has teeth: one weight off by 1e-6 leaves it in almost every value
        wrong = w.copy()
        wrong[1] += 1e-6
        assert np.mean(np.abs(table[valid] - np.maximum(wrong @ Z, 0.0)) > tol) > 0.99
        marked = np.zeros(table.size, dtype=bool)
        marked[provenance.MARK_CELLS] = True  # red channel: the provenance mark (negative, unmeasured)
        assert np.all(table[~valid & ~marked] == -1.0) and np.all(table[marked] < 0.0)
        mark = provenance.read_mark(merls[k])
        assert mark is not None and mark.kind == "derived" and mark.fields["operation"] == "path-point"
        assert mark.fields["inputs"]["path"] == [a, b] and mark.fields["inputs"]["t"] == t
    # t = 0 is the first material itself (exact reproduction at training points): the weights are e_a up to
    # the solve's rounding, and the table is z_a up to those weights' pull on the other materials
    a = m.names.index(points[0][0])
    bound = _reproduction_bound(m, a)
    e_a = np.eye(len(m.names))[a]
    assert np.all(np.abs(W[0] - e_a) <= bound) and not np.array_equal(bound, np.zeros_like(bound))
    first = merl.read_merl(merls[0]).reshape(-1)[valid]
    assert np.all(np.abs(first - np.maximum(Z[a], 0.0)) <= bound @ np.abs(Z) + _blend_tolerance(W[0], Z))
    with pytest.raises(ValueError, match="one MERL and one weights output per path point"):
        analysis.path_points_to_files(model=small["models"][2], store=small["store"], points=points,
                                      merl_outs=merls[:2], weights_outs=jsons)
