"""brdfpipe.manifold.blendpass: one pass over the store equals the per-point route (whole tables).

The reference is what the measurements did before (issue 23): each interpolated table formed whole by
``gplvm.interpolate_tables``, its albedo by ``albedo.material_albedo`` and its distances by
``perceptual.pr12_distance``.  The store has an unmeasured region inside the PR12 domain in one material
(so the store's valid cells miss part of the domain), and the weights make negative values (clamped).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfpipe.data import ingest, merl, store, synth
from brdfpipe.manifold import albedo, blendpass, fitting, gplvm, gram, likelihood, perceptual

N = 6
RTOL = 1e-9


@pytest.fixture(scope="module")
def holed(tmp_path_factory: pytest.TempPathFactory) -> dict:
    tmp = tmp_path_factory.mktemp("blendpass")
    db = tmp / "db"
    synth.synthesize(db, count=N, seed=5, jobs=1, progress=False)
    files = sorted(db.glob("*.binary"))
    t = merl.read_merl(files[2])
    t[:, 20:30, 10:40, :] = -1.0  # an unmeasured region inside the PR12 domain
    merl.write_merl(files[2], t)
    out = tmp / "merl.zarr"
    ingest.ingest(files, out, database="synthetic", jobs=1)
    st = store.open_store(out)
    domain = merl.measured_mask().ravel()
    valid = np.asarray(st.valid[:], dtype=bool)
    assert (domain & ~valid).sum() >= 50_000  # the region is unmeasured in every blend
    names = list(st.materials)
    rng = np.random.default_rng(0)
    W = rng.normal(1.0 / N, 1.0, (5, N))  # spread enough for negative blends in every space (clamped)
    W[0] = np.eye(N)[1]  # a material itself
    W /= W.sum(axis=1, keepdims=True)
    return {"store": out, "names": names[::-1], "W": W}  # materials in another order than the store's


def _reference(holed: dict, space: str, pairs: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tables, clamped = gplvm.interpolate_tables(holed["store"], holed["W"], materials=holed["names"], space=space)
    alb = np.stack([albedo.material_albedo(t) for t in tables])
    d = np.array([perceptual.pr12_distance(tables[i], tables[j]) for i, j in pairs])
    return alb, clamped, d


@pytest.mark.parametrize("space", ["log", "raw", "standardised"])
def test_measure_blends_equals_the_per_point_tables(holed: dict, space: str) -> None:
    pairs = [(0, 1), (2, 0), (3, 4), (4, 3), (1, 1)]
    alb, clamped, d = _reference(holed, space, pairs)
    got = blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space=space, pairs=pairs)
    assert clamped.sum() > 0 and np.array_equal(got.clamped, clamped)  # negative values were clamped
    np.testing.assert_allclose(got.albedo, alb, rtol=RTOL, atol=0)
    np.testing.assert_allclose(got.distances, d, rtol=RTOL, atol=0)
    assert got.distances[-1] == 0.0


@pytest.mark.parametrize("space", ["log", "raw"])
def test_distance_to_a_material_is_that_of_the_clamped_table(holed: dict, space: str) -> None:
    """``targets``: ‖table − z_m‖ / ‖z_m‖ over the store's valid cells, the table clamped as written."""
    targets = [1, -1, 0, 5, 1]
    tables, _ = gplvm.interpolate_tables(holed["store"], holed["W"], materials=holed["names"], space=space)
    got = blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space=space,
                                   targets=targets)
    st = store.open_store(holed["store"])
    valid = np.tile(np.asarray(st.valid[:], dtype=bool), 3)
    for k, m in enumerate(targets):
        if m < 0:
            assert np.isnan(got.to_target[k])
            continue
        row = np.asarray(st.brdf[list(st.materials).index(holed["names"][m])], dtype=np.float64).reshape(-1)[valid]
        want = np.linalg.norm(tables[k].reshape(-1)[valid] - row) / np.linalg.norm(row)
        np.testing.assert_allclose(got.to_target[k], want, rtol=RTOL, atol=1e-12)
    assert got.to_target[0] < 1e-6 < got.to_target[2]  # row 0 is material 1 itself; row 2 a spread blend
    # the albedo alone needs only the cells it reads: the same albedo
    only = blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space=space,
                                    albedo_only=True)
    np.testing.assert_allclose(only.albedo, got.albedo, rtol=RTOL, atol=0)
    assert (only.clamped <= got.clamped).all() and only.clamped.sum() < got.clamped.sum()
    with pytest.raises(ValueError, match="targets must give one material index"):
        blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], targets=[0, 1])
    with pytest.raises(ValueError, match="albedo_only"):
        blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], targets=targets,
                                 albedo_only=True)


def test_narrow_blocks_give_the_same_measures(holed: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """The cells per block shrink with the number of points (memory); the sums do not depend on it."""
    pairs = [(0, 1), (3, 2)]
    wide = blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space="log", pairs=pairs)
    monkeypatch.setattr(blendpass, "POINT_CELLS", 5 * 1000)
    narrow = blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space="log",
                                      pairs=pairs)
    np.testing.assert_allclose(narrow.albedo, wide.albedo, rtol=RTOL, atol=0)
    np.testing.assert_allclose(narrow.distances, wide.distances, rtol=RTOL, atol=0)


def test_measure_blends_refuses_bad_input(holed: dict) -> None:
    with pytest.raises(ValueError, match=r"weights must have shape \(P, 6\)"):
        blendpass.measure_blends(holed["store"], holed["W"][:, :4], materials=holed["names"])
    bad = holed["W"].copy()
    bad[1, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        blendpass.measure_blends(holed["store"], bad, materials=holed["names"])
    with pytest.raises(ValueError, match="pairs must index the 5 blends"):
        blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], pairs=[(0, 5)])
    with pytest.raises(ValueError, match="unknown data space"):
        blendpass.measure_blends(holed["store"], holed["W"], materials=holed["names"], space="lab")


def test_albedo_cell_weights_give_the_albedo_of_a_table_with_negative_values() -> None:
    t = np.random.default_rng(2).normal(0.1, 0.2, merl.SHAPE)  # a third of the values negative
    got = np.maximum(t, 0.0).reshape(3, merl.N_CELLS) @ blendpass.albedo_cell_weights()
    np.testing.assert_allclose(got, albedo.material_albedo(t), rtol=1e-12, atol=0)


def _random_tables(rng: np.random.Generator) -> np.ndarray:
    t = rng.uniform(0.0, 2.0, (3, *merl.SHAPE))
    t[0, 1, 10:50] = -1.0  # unmeasured in table 0 only (one channel suffices)
    t[1, :, 40:70] = -1.0  # in table 1, overlapping table 0's
    t[2, :, :, 30:60] = -1.0
    return t


def test_streamed_distances_equal_pr12_distance_with_different_unmeasured_cells() -> None:
    """Per-table unmeasured cells, blocks of uneven width, cells outside the domain fed too."""
    rng = np.random.default_rng(3)
    t = _random_tables(rng)
    pairs = [(0, 1), (1, 2), (2, 0), (0, 0), (1, 0)]
    acc = perceptual.StreamedDistances(3, pairs)
    flat = t.reshape(3, 3, merl.N_CELLS)
    edges = [0, 1, 777, 50_000, 50_001, 400_000, merl.N_CELLS]
    for a, b in zip(edges[:-1], edges[1:]):
        acc.add(np.arange(a, b), flat[:, :, a:b])
    want = [perceptual.pr12_distance(t[i], t[j]) for i, j in pairs]
    np.testing.assert_allclose(acc.distances(), want, rtol=RTOL, atol=0)


def test_streamed_distances_count_cells_never_fed_as_unmeasured() -> None:
    rng = np.random.default_rng(4)
    t = rng.uniform(0.0, 2.0, (2, *merl.SHAPE))
    flat = t.reshape(2, 3, merl.N_CELLS)
    acc = perceptual.StreamedDistances(2, [(0, 1)])
    acc.add(np.arange(0, 700_000), flat[:, :, :700_000])  # the rest never fed
    t.reshape(2, 3, merl.N_CELLS)[:, :, 700_000:] = -1.0  # the cells not fed, marked unmeasured
    np.testing.assert_allclose(acc.distances(), [perceptual.pr12_distance(t[0], t[1])], rtol=RTOL, atol=0)


def test_streamed_distances_refuse_a_pair_without_common_cells() -> None:
    t = np.full((2, 3, merl.N_CELLS), 0.5)
    t[0, :, : merl.N_CELLS // 2] = -1.0
    t[1, :, merl.N_CELLS // 2 :] = -1.0
    acc = perceptual.StreamedDistances(2, [(0, 1)])
    acc.add(np.arange(merl.N_CELLS), t)
    with pytest.raises(ValueError, match="no measured cell in common"):
        acc.distances()
    with pytest.raises(ValueError, match="pairs must index the 2 tables"):
        perceptual.StreamedDistances(2, [(0, 2)])
    with pytest.raises(ValueError, match=r"values must have shape \(2, 3, 10\)"):
        acc.add(np.arange(10), t[:1, :, :10])


def test_path_analysis_equals_the_per_point_tables(holed: dict, tmp_path: Path) -> None:
    """paths_analysis (all paths, one pass) against each path's tables formed whole, in the log space."""
    from brdfpipe.manifold import analysis

    G, d, info = gram.gram_matrix(holed["store"], space="log")
    res = fitting.fit(G / likelihood.gram_scale(G, d), d, q=2, mu=1e-4, seed=1)
    gplvm.save_model(tmp_path / "m.npz", res, info.materials, space="log", data_digests=info.digests)
    model = gplvm.load_model(tmp_path / "m.npz")
    names = list(model.names)
    pairs = [(names[0], names[3]), (names[5], names[1])]
    rows = analysis.paths_analysis(holed["store"], model, G, pairs, steps=3)
    assert [(r["path"], r["step"]) for r in rows] == [(f"{a}--{b}", k) for a, b in pairs for k in range(4)]
    for a, b in pairs:
        p = analysis.latent_path(model, a, b, 3)
        tables, _ = gplvm.interpolate_tables(holed["store"], p.weights, model=model, space="log")
        mine = [r for r in rows if (r["material_a"], r["material_b"]) == (a, b)]
        for k, r in enumerate(mine):
            assert r["perceptual_a"] == pytest.approx(perceptual.pr12_distance(tables[k], tables[0]), rel=RTOL)
            assert r["perceptual_b"] == pytest.approx(perceptual.pr12_distance(tables[k], tables[-1]), rel=RTOL)
            assert r["perceptual_ab"] == pytest.approx(perceptual.pr12_distance(tables[0], tables[-1]), rel=RTOL)
        assert mine == analysis.paths_analysis(holed["store"], model, G, [(a, b)], steps=3)
