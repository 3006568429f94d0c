"""Tests of :mod:`brdfpipe.acquisition.svd`: the streamed PCA of a log-map against a dense SVD.

One store of six synthetic materials (~5 s) and its ``all`` log-map (m = 18,
p ≈ 1.1 M, 80 MB float32) are built once; the dense reference is
``numpy.linalg.svd`` of the float64 centred matrix (160 MB).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import zarr

from brdfpipe.acquisition import svd
from brdfpipe.acquisition.svd import ModelError
from brdfpipe.core import integrity
from brdfpipe.core.atomic import OutputError
from brdfpipe.core.version import full_version
from brdfpipe.data import ingest, logmap, merl, provenance, synth
from brdfpipe.data.database import database_from_folder

# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("svd")
    synth.synthesize(d / "db", count=6, seed=5, noise=0.01, jobs=1, progress=False)
    db = database_from_folder(d / "db", key="folder")
    st_path = d / "merl.zarr"
    ingest.ingest(db.sources, st_path, database=db.kind, jobs=1)
    lm_path = d / "all.zarr"
    logmap.write_logmap(st_path, lm_path, split="all", materials_train=db.materials)
    return {"db": d / "db", "store": st_path, "logmap": lm_path, "dir": d}


@pytest.fixture(scope="module")
def dense(data: dict[str, Path]) -> dict[str, np.ndarray]:
    x = logmap.open_logmap(data["logmap"]).X[:].astype(np.float64)
    mu = x.mean(axis=0)
    u, s, vt = np.linalg.svd(x - mu, full_matrices=False)
    return {"X": x, "mu": mu, "U": u, "s": s, "Vt": vt}


@pytest.fixture(scope="module")
def model(data: dict[str, Path]) -> svd.Model:
    out = data["dir"] / "model.zarr"
    svd.fit(data["logmap"], out, n_blocks=3)
    return svd.open_model(out)


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --------------------------------------------------------------------------
# Against the dense SVD
# --------------------------------------------------------------------------


def test_singular_values_match_dense(model: svd.Model, dense: dict[str, np.ndarray]) -> None:
    m = dense["X"].shape[0]
    assert m == 18 and model.m == 18
    assert model.k == m - 1  # six distinct materials: full rank after centring
    assert dense["s"][-1] < 1e-9 * dense["s"][0]  # the null direction of the centred matrix
    np.testing.assert_allclose(model.sigma, dense["s"][: model.k], rtol=1e-6)


def test_q_spans_the_dense_principal_subspace(model: svd.Model, dense: dict[str, np.ndarray]) -> None:
    q = np.asarray(model.Q[:], dtype=np.float64)
    vs = dense["Vt"][: model.k].T * dense["s"][: model.k]
    assert scipy.linalg.subspace_angles(q, vs).max() < 1e-4
    # Column by column too (signs aside): every component is well separated here.
    cos = np.abs(np.sum(q * vs, axis=0)) / (np.linalg.norm(q, axis=0) * np.linalg.norm(vs, axis=0))
    assert np.all(cos > 1 - 1e-6)


def test_qtq_is_sigma_squared(model: svd.Model) -> None:
    q = np.asarray(model.Q[:], dtype=np.float64)
    qtq = q.T @ q
    scale = np.outer(model.sigma, model.sigma)
    assert np.abs(qtq - np.diag(model.sigma**2)).max() <= 1e-5 * scale.max()
    assert np.all(np.abs(qtq - np.diag(model.sigma**2)) <= 1e-5 * scale)


def test_every_row_is_reproduced(model: svd.Model, dense: dict[str, np.ndarray]) -> None:
    x = dense["X"]
    q = np.asarray(model.Q[:], dtype=np.float64)
    np.testing.assert_allclose(model.mean, dense["mu"], rtol=0, atol=1e-12)
    recon = model.mean + model.U @ q.T  # row r: μ + Q u_r
    err = np.abs(recon - x).max()
    assert err <= 4 * np.finfo(np.float32).eps * np.abs(x).max(), err
    # U is orthonormal, orthogonal to 1, and matches the dense U up to sign.
    np.testing.assert_allclose(model.U.T @ model.U, np.eye(model.k), atol=1e-12)
    assert np.abs(model.U.sum(axis=0)).max() < 1e-12
    np.testing.assert_allclose(np.abs(model.U), np.abs(dense["U"][:, : model.k]), atol=1e-7)


def test_model_format(model: svd.Model, data: dict[str, Path]) -> None:
    lm = logmap.open_logmap(data["logmap"])
    assert model.Q.dtype == np.float32 and model.Q.shape == (lm.p, model.k)
    assert model.Q.chunks == (lm.chunk_cols, model.k)
    assert np.array_equal(model.cells, lm.cells) and np.array_equal(model.reference, lm.reference)
    assert np.array_equal(model.weight, lm.weight)
    attrs = dict(model.group.attrs)
    assert attrs["rows"] == [list(r) for r in lm.rows] and attrs["materials"] == list(lm.materials)
    assert attrs["split"] == "all" and attrs["weighting"] == "product" and attrs["epsilon"] == 1e-3
    assert attrs["database"] == "synthetic" and attrs["k"] == model.k and attrs["tolerance"] == svd.TOL
    assert attrs["brdfpipe_version"] == full_version()
    assert attrs[logmap.COMPLETE_ATTR]["logmap_id"] == lm.id


# --------------------------------------------------------------------------
# Scatter / gather
# --------------------------------------------------------------------------


def test_block_ranges_cover_and_align() -> None:
    for p, chunk in ((1_096_216, 36_450), (100, 7), (5, 10)):
        n_chunks = -(-p // chunk)
        for n in (1, 2, 3, n_chunks, n_chunks + 1, 3 * n_chunks + 2):
            edges = [svd.block_range(p, n, b, chunk) for b in range(n)]
            assert edges[0][0] == 0 and edges[-1][1] == p
            assert all(edges[i][1] == edges[i + 1][0] for i in range(n - 1))
            assert all(a <= b for a, b in edges)
            if n <= n_chunks:
                assert all(a % chunk == 0 for a, _ in edges)
    with pytest.raises(ValueError):
        svd.block_range(10, 0, 0, 5)
    with pytest.raises(ValueError):
        svd.block_range(10, 2, 2, 5)


def test_partial_grams_add_up(data: dict[str, Path], dense: dict[str, np.ndarray]) -> None:
    lm = logmap.open_logmap(data["logmap"])
    g1, s1, p1 = svd.combine([svd.gram_partial(lm, 0, 1)])
    x = dense["X"]
    assert p1 == lm.p
    np.testing.assert_allclose(g1, x @ x.T, rtol=1e-12)
    np.testing.assert_allclose(s1, x.sum(axis=1), rtol=1e-11)
    n_chunks = -(-lm.p // lm.chunk_cols)
    for n in (2, 5, n_chunks, n_chunks + 3):
        g, s, p = svd.combine(svd.gram_partial(lm, b, n) for b in range(n))
        assert p == lm.p
        np.testing.assert_allclose(g, g1, rtol=1e-12)
        np.testing.assert_allclose(s, s1, rtol=1e-11, atol=1e-9)


def test_saved_partials_give_the_fitted_model(data: dict[str, Path], model: svd.Model, tmp_path: Path) -> None:
    n = 4
    paths = []
    for b in range(n):
        part = svd.gram_partial(data["logmap"], b, n)
        path = tmp_path / "parts" / f"{b}.npz"
        svd.save_partial(path, part, logmap_path=data["logmap"], block=b, n_blocks=n)
        loaded, info = svd.read_partial(path)
        assert np.array_equal(loaded.gram, part.gram) and np.array_equal(loaded.colsum, part.colsum)
        assert loaded.ncols == part.ncols
        assert (info.block, info.n_blocks, info.m) == (b, n, 18)
        paths.append(path)
    assert _leftovers(tmp_path / "parts") == []
    # The workflow's entry point: Snakemake scatter item "i-of-n" is block i - 1 of n.
    via_item = tmp_path / "item.npz"
    svd.write_partial(via_item, logmap_path=data["logmap"], scatteritem="2-of-4")
    (via, via_info), (second, second_info) = svd.read_partial(via_item), svd.read_partial(paths[1])
    assert via_info == second_info and np.array_equal(via.gram, second.gram)
    for item in ("0-of-4", "5-of-4", "2of4"):
        with pytest.raises(ValueError, match="scatter item"):
            svd.write_partial(tmp_path / "bad.npz", logmap_path=data["logmap"], scatteritem=item)
    out = tmp_path / "model.zarr"
    svd.write_model(data["logmap"], paths[::-1], out)  # any order
    other = svd.open_model(out)
    np.testing.assert_allclose(other.sigma, model.sigma, rtol=1e-10)
    q = model.Q[:]
    np.testing.assert_allclose(other.Q[:], q, rtol=0, atol=1e-6 * np.abs(q).max())
    assert np.array_equal(other.mean, model.mean)

    # Refusals: missing / repeated blocks, mixed block counts, another log-map's partials.
    odd = tmp_path / "parts" / "odd.npz"
    svd.save_partial(odd, svd.gram_partial(data["logmap"], 0, 3), logmap_path=data["logmap"], block=0, n_blocks=3)
    foreign = tmp_path / "parts" / "foreign.npz"
    doc = integrity.load_npz(paths[0])
    doc["logmap_id"] = np.array("0123456789abcdef")
    integrity.save_npz(foreign, doc)  # a well-formed partial of another log-map
    bad_sets = {
        "missing": (paths[:3], "missing \\[3\\]"),
        "repeated": ([*paths, paths[1]], "repeated \\[1\\]"),
        "mixed": ([*paths, odd], "different block counts"),
        "foreign": ([foreign, *paths[1:]], "another log-map"),
    }
    for name, (subset, message) in bad_sets.items():
        bad_out = tmp_path / f"{name}.zarr"
        with pytest.raises(ModelError, match=message):
            svd.write_model(data["logmap"], subset, bad_out)
        assert not bad_out.exists()
    with pytest.raises(ModelError, match="no such Gram partial"):
        svd.read_partial(tmp_path / "nothing.npz")
    with pytest.raises(ValueError, match="columns"):
        svd.save_partial(tmp_path / "x.npz", svd.gram_partial(data["logmap"], 0, 2), logmap_path=data["logmap"],
                         block=1, n_blocks=2)
    assert _leftovers(tmp_path) == []


# --------------------------------------------------------------------------
# decompose, rank deficiency
# --------------------------------------------------------------------------


def test_decompose_small_dense_cases() -> None:
    rng = np.random.default_rng(0)
    for m, p, rank in ((6, 400, 6), (9, 300, 4), (12, 5, 5), (3, 50, 1)):
        x = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, p)) + 3.0  # offset: centring matters
        g = x @ x.T
        u, s = svd.decompose(g, x.sum(axis=1), p)
        xc = x - x.mean(axis=0)
        ref = np.linalg.svd(xc, compute_uv=False)
        expect_k = min(np.linalg.matrix_rank(xc), m - 1)
        assert u.shape == (m, expect_k) and s.shape == (expect_k,) and expect_k <= m - 1
        np.testing.assert_allclose(s, ref[:expect_k], rtol=1e-8)
        np.testing.assert_allclose(u.T @ u, np.eye(expect_k), atol=1e-12)
        assert np.abs(u.sum(axis=0)).max() < 1e-12
        q = xc.T @ u
        np.testing.assert_allclose(x.mean(axis=0) + u @ q.T, x, atol=1e-9 * np.abs(x).max())


def test_decompose_errors() -> None:
    g = np.eye(3)
    with pytest.raises(ValueError, match="square"):
        svd.decompose(np.ones((2, 3)), np.zeros(2), 10)
    with pytest.raises(ValueError, match="colsum"):
        svd.decompose(g, np.zeros(4), 10)
    with pytest.raises(ValueError, match="tol"):
        svd.decompose(g, np.zeros(3), 10, tol=0.0)
    with pytest.raises(ValueError, match="at least 2 rows"):
        svd.decompose(np.ones((1, 1)), np.ones(1), 10)
    with pytest.raises(ValueError, match="NaN"):
        svd.decompose(np.full((3, 3), np.nan), np.zeros(3), 10)
    with pytest.raises(ValueError, match="all rows identical"):
        svd.decompose(np.full((3, 3), 4.0), np.full(3, 2.0), 1)  # three identical rows of ones·2
    with pytest.raises(ValueError, match="no partials"):
        svd.combine([])


def test_duplicate_material_is_rank_deficient(data: dict[str, Path], tmp_path: Path) -> None:
    """Four materials, one a byte copy of another: the centred 12 × p matrix has rank 8."""
    db = database_from_folder(data["db"], key="folder")
    names = db.materials[:3]
    sources = {n: db.sources[n] for n in names}
    sources["twin"] = tmp_path / "twin.binary"
    # a byte copy of the data; its provenance mark names "twin" (a plain copy is refused at ingest as a
    # file copied over another material)
    raw = merl.read_merl_raw(db.sources[names[1]]).reshape(3, -1)
    mark = provenance.read_mark(db.sources[names[1]])
    provenance.stamp(raw, provenance.Mark("synthetic", {**mark.fields, "name": "twin"}))
    sources["twin"].write_bytes(np.asarray(merl.DIMS, dtype="<i4").tobytes() + raw.astype("<f8").tobytes())
    st_path = tmp_path / "merl.zarr"
    ingest.ingest(sources, st_path, database="synthetic", jobs=1)
    lm_path = tmp_path / "lm.zarr"
    logmap.write_logmap(st_path, lm_path, split="all", materials_train=list(sources))
    out = tmp_path / "model.zarr"
    svd.fit(lm_path, out, n_blocks=2)
    md = svd.open_model(out)
    assert md.m == 12 and md.k == 12 - 1 - 3
    x = logmap.open_logmap(lm_path).X[:].astype(np.float64)
    recon = md.mean + md.U @ np.asarray(md.Q[:], dtype=np.float64).T
    assert np.abs(recon - x).max() <= 4 * np.finfo(np.float32).eps * np.abs(x).max()


# --------------------------------------------------------------------------
# Atomic output and checks
# --------------------------------------------------------------------------


def test_failed_fit_leaves_nothing(data: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "model.zarr"
    svd.fit(data["logmap"], out)  # an earlier, good model
    before = _tree(out)
    real = svd.iter_columns

    def failing(lm, start=0, stop=None):  # type: ignore[no-untyped-def]
        for i, item in enumerate(real(lm, start, stop)):
            if i == 2:
                raise OSError("disk full")
            yield item

    monkeypatch.setattr(svd, "iter_columns", failing)
    with pytest.raises(OSError, match="disk full"):
        svd.fit(data["logmap"], out)
    assert _tree(out) == before and _leftovers(tmp_path) == []  # the earlier model is kept as it was
    svd.open_model(out)


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("kind", ["folder", "zarr group", "store"])
def test_refuses_a_foreign_output_before_any_work(kind: str, data: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "model.zarr"
    if kind == "folder":
        out.mkdir()
        (out / "notes.txt").write_text("keep me")
    elif kind == "zarr group":
        zarr.open_group(out, mode="w", zarr_format=3).attrs["format"] = "brdfpipe.pca-model/0"
    else:
        shutil.copytree(data["store"], out)
    before = _tree(out)
    part = tmp_path / "p.npz"
    svd.write_partial(part, logmap_path=data["logmap"], block=0, n_blocks=1)
    for call in (lambda: svd.fit(data["logmap"], out), lambda: svd.write_model(data["logmap"], [part], out)):
        with pytest.raises(OutputError, match=re.escape(str(out)) + ".*refusing to replace"):
            call()
        assert _tree(out) == before
    assert _leftovers(tmp_path) == []


def test_stale_sibling_of_a_dead_writer_is_removed(data: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "model.zarr"
    dead = int(subprocess.run(["sh", "-c", "echo $$"], capture_output=True, text=True, check=True).stdout)
    stale = tmp_path / f".model.zarr.tmp-{dead}-0123abcd"
    stale.mkdir()
    (stale / "zarr.json").write_text("{}")
    svd.fit(data["logmap"], out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.zarr"]


def test_refuses_to_overwrite_the_logmap(data: dict[str, Path], tmp_path: Path) -> None:
    copy = tmp_path / "lm.zarr"
    shutil.copytree(data["logmap"], copy)
    with pytest.raises(ValueError, match="refusing to replace"):
        svd.fit(copy, copy)
    logmap.open_logmap(copy)


def test_open_model_refuses_bad_outputs(model: svd.Model, data: dict[str, Path], tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="no such model"):
        svd.open_model(tmp_path / "none.zarr")
    with pytest.raises(ModelError, match="not a brdfpipe model"):
        svd.open_model(data["logmap"])

    def edit(name: str, fn, reseal: bool = True) -> Path:  # type: ignore[no-untyped-def]
        """A copy with edited attributes, re-sealed (so the checks behind the digest are reached)."""
        bad = tmp_path / f"{name}.zarr"
        shutil.copytree(model.path, bad)
        doc = json.loads((bad / "zarr.json").read_text())
        attrs = doc["attributes"]
        fn(attrs)
        if reseal and integrity.ZARR_ATTR in attrs:
            attrs[integrity.ZARR_ATTR]["attributes"] = integrity.attributes_digest(attrs, (integrity.ZARR_ATTR,))
        (bad / "zarr.json").write_text(json.dumps(doc))
        return bad

    # an edit of an attribute without re-sealing: the digest names the model and what to rerun
    with pytest.raises(ModelError, match=r"k_edit\.zarr: its attributes do not match their recorded digest "
                                         r"\(damaged or edited\); write it again"):
        svd.open_model(edit("k_edit", lambda a: a.update(database="merl"), reseal=False))
    with pytest.raises(ModelError, match="incomplete model"):
        svd.open_model(edit("incomplete", lambda a: a.pop(logmap.COMPLETE_ATTR)))
    with pytest.raises(ModelError, match="completion marker"):
        svd.open_model(edit("k", lambda a: a.update(k=3)))
    with pytest.raises(ModelError, match="'rows'"):
        svd.open_model(edit("rows", lambda a: a.update(rows=a["rows"][:-3])))


# --------------------------------------------------------------------------
# Integrity (issue 21): the model and the log-map are verified when read
# --------------------------------------------------------------------------


def test_two_flipped_bits_in_the_model_stop_every_consumer(model: svd.Model, data: dict[str, Path],
                                                           tmp_path: Path) -> None:
    """Two flipped bits in a chunk of Q (the tester's case: 355 of 371 rows of errors.csv changed with exit 0)
    are refused when the model is opened, naming the model, the file and the rule to rerun."""
    bad = tmp_path / "results" / "svd" / "train.zarr"
    shutil.copytree(model.path, bad)
    chunk = sorted(p for p in (bad / "Q" / "c").rglob("*") if p.is_file())[-1]
    raw = bytearray(chunk.read_bytes())
    raw[len(raw) // 3] ^= 0x04
    raw[2 * len(raw) // 3] ^= 0x40
    chunk.write_bytes(bytes(raw))
    rel = chunk.relative_to(bad).as_posix()
    with pytest.raises(ModelError, match=re.escape(f"{bad}: file {rel} does not match its recorded digest "
                                                   "(damaged or edited); rerun its rule: snakemake --forcerun "
                                                   "decompose_svd")):
        svd.open_model(bad)


def test_a_damaged_logmap_chunk_stops_the_gram_partial(data: dict[str, Path], tmp_path: Path) -> None:
    """A flipped bit in a chunk of the log-map's X stops the scatter job that reads it, naming the chunk."""
    bad = tmp_path / "results" / "logmap" / "all.zarr"
    shutil.copytree(data["logmap"], bad)
    chunk = sorted(p for p in (bad / "X" / "c").rglob("*") if p.is_file())[0]
    raw = bytearray(chunk.read_bytes())
    raw[len(raw) // 2] ^= 0x01
    chunk.write_bytes(bytes(raw))
    lm = logmap.open_logmap(bad)  # the small arrays and the metadata are fine: opening works
    with pytest.raises(logmap.LogmapError, match=re.escape(f"{bad}: file {chunk.relative_to(bad).as_posix()} does "
                                                           "not match") + ".*snakemake --forcerun map_logrelative"):
        svd.gram_partial(lm, 0, 1)


def test_an_edited_gram_partial_is_refused(data: dict[str, Path], tmp_path: Path) -> None:
    """A partial re-saved with a changed Gram matrix (valid npz, valid zip CRCs) is refused; so is a truncated one."""
    part = tmp_path / "results" / "svd" / "all" / "gram-1-of-1.npz"
    svd.write_partial(part, logmap_path=data["logmap"], block=0, n_blocks=1)
    with np.load(part) as z:
        arrays = dict(z)
    arrays["gram"] = arrays["gram"] * 1.001
    np.savez(part, **arrays)
    with pytest.raises(ModelError, match=re.escape(f"{part}: its arrays do not match their recorded digest") +
                       ".*snakemake --forcerun accumulate_gram"):
        svd.read_partial(part)
    svd.write_partial(part, logmap_path=data["logmap"], block=0, n_blocks=1)
    part.write_bytes(part.read_bytes()[:-100])
    with pytest.raises(ModelError, match=re.escape(f"{part}: truncated or corrupt Gram partial")):
        svd.read_partial(part)
