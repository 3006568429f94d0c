"""Tests of :mod:`brdfpipe.data.logmap`: the log-relative mapping and its Zarr output.

Two full-resolution stores are built once per module: six synthetic materials
(``synth.synthesize``, ~5 s) for the comparison against a dense computation,
and four constant materials (0.1, 0.2, 0.3 and 10 sr⁻¹) whose medians are
known by hand.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import zarr
from hypothesis import given, settings
from hypothesis import strategies as hs

from brdfpipe.core import integrity
from brdfpipe.core.atomic import OutputError
from brdfpipe.core.version import full_version
from brdfpipe.data import ingest, logmap, merl, store, synth
from brdfpipe.data.database import database_from_folder
from brdfpipe.data.logmap import EPS, LogmapError

# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synth_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A store of six synthetic materials (one per family and one more)."""
    d = tmp_path_factory.mktemp("synth")
    synth.synthesize(d / "db", count=6, seed=1, noise=0.01, jobs=1, progress=False)
    db = database_from_folder(d / "db", key="folder")
    out = d / "merl.zarr"
    ingest.ingest(db.sources, out, database=db.kind, jobs=1)
    return out


CONSTANTS = {"mat-a": 0.1, "mat-b": 0.2, "mat-c": 0.3, "mat-d": 10.0}


@pytest.fixture(scope="module")
def const_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four materials constant over all measured cells and channels; mat-d also misses 1000 cells."""
    d = tmp_path_factory.mktemp("const")
    mask = merl.measured_mask().ravel()
    sources = {}
    for name, value in CONSTANTS.items():
        table = np.full((3, merl.N_CELLS), value)
        table[:, ~mask] = -1.0
        if name == "mat-d":
            table[1, np.flatnonzero(mask)[::1000]] = -1.0  # unmeasured in one material, one channel
        path = d / f"{name}.binary"
        merl.write_merl(path, table.reshape(merl.SHAPE))
        sources[name] = path
    out = d / "merl.zarr"
    ingest.ingest(sources, out, database="merl", jobs=1)
    return out


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def _dense(st: store.BrdfStore, train: list[str], out: list[str], weighting: str) -> tuple[np.ndarray, ...]:
    """X, ρ_ref, w, cells computed densely in float64 from the whole store."""
    index = {m: i for i, m in enumerate(st.materials)}
    cells = np.flatnonzero(np.asarray(st.valid[:]))
    full = np.asarray(st.brdf[:]).reshape(st.n_materials, 3, merl.N_CELLS)[:, :, cells].astype(np.float64)
    ref = np.median(full[[index[m] for m in train]].reshape(-1, cells.size), axis=0)
    w = logmap.cell_weights(cells, weighting)
    x = np.log((full[[index[m] for m in out]].reshape(-1, cells.size) * w + EPS) / (ref * w + EPS))
    return x, ref, w, cells


# --------------------------------------------------------------------------
# The mapping
# --------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(seed=hs.integers(0, 2**32 - 1), rows=hs.integers(1, 4), eps=hs.sampled_from([EPS, 1e-6, 0.1]))
def test_forward_inverse_round_trip(seed: int, rows: int, eps: float) -> None:
    """Round trip to 1e-12 on the mapping's own scale: ρ is recovered to 1e-12·(ρ + ε/w)
    (below ε/w the mapping flattens out, so no relative accuracy is possible there)."""
    rng = np.random.default_rng(seed)
    p = 257
    rho = np.exp(rng.uniform(-12, 8, (rows, 2, p)))  # 6e-6 … 3000 sr⁻¹
    rho[..., :5] = 0.0
    ref = np.exp(rng.uniform(-8, 4, p))
    w = rng.uniform(0.01, 1.0, p)
    x = logmap.forward(rho, ref, w, eps)
    assert x.shape == rho.shape and x.dtype == np.float64
    back = logmap.inverse(x, ref, w, eps)
    assert np.all(np.abs(back - rho) <= 1e-12 * (rho + eps / w))
    np.testing.assert_allclose(logmap.forward(back, ref, w, eps), x, rtol=0, atol=1e-12)


def test_round_trip_relative_on_measured_range() -> None:
    rng = np.random.default_rng(7)
    rho = np.exp(rng.uniform(np.log(1e-2), np.log(1e4), (6, 10_000)))
    ref = np.exp(rng.uniform(np.log(1e-2), np.log(1e2), 10_000))
    w = rng.uniform(0.01, 1.0, 10_000)
    np.testing.assert_allclose(logmap.inverse(logmap.forward(rho, ref, w), ref, w), rho, rtol=1e-12)


def test_forward_matches_formula_and_broadcasts() -> None:
    rho = np.array([[0.5, 2.0], [0.0, 40.0]], dtype=np.float32)
    ref = np.array([1.0, 0.25])
    w = np.array([0.5, 0.01])
    expect = [[math.log((rho[i, j] * w[j] + 1e-3) / (ref[j] * w[j] + 1e-3)) for j in range(2)] for i in range(2)]
    np.testing.assert_allclose(logmap.forward(rho, ref, w), expect, rtol=1e-15)
    assert logmap.forward(rho[0, 0], ref[0], w[0]).shape == ()


def test_reference_maps_to_zero() -> None:
    rng = np.random.default_rng(3)
    ref = rng.uniform(0.0, 50.0, 1000)
    w = rng.uniform(0.01, 1.0, 1000)
    assert np.array_equal(logmap.forward(np.tile(ref, (3, 1)), ref, w), np.zeros((3, 1000)))
    assert np.array_equal(logmap.inverse(np.zeros(1000), ref, w), (ref * w + EPS - EPS) / w)
    np.testing.assert_allclose(logmap.inverse(np.zeros(1000), ref, w), ref, rtol=1e-12, atol=1e-15)


def _cos_in_out(ih: int, idd: int, ip: int) -> tuple[float, float]:
    """cos θi, cos θo of a cell centre by hand (φh = 0): with h = (sin θh, 0, cos θh) and the
    difference vector d = (sin θd cos φd, sin θd sin φd, cos θd) in h's frame,
    cos θi = cos θd cos θh − sin θd cos φd sin θh and cos θo = 2 cos θd cos θh − cos θi."""
    th = ((ih + 0.5) / 90) ** 2 * math.pi / 2
    td = (idd + 0.5) / 90 * math.pi / 2
    pd = (ip + 0.5) / 180 * math.pi
    ci = math.cos(td) * math.cos(th) - math.sin(td) * math.cos(pd) * math.sin(th)
    co = math.cos(td) * math.cos(th) + math.sin(td) * math.cos(pd) * math.sin(th)
    return ci, co


@pytest.mark.parametrize(
    "cell",
    [(0, 0, 0), (10, 20, 30), (45, 60, 170), (60, 30, 90), (89, 0, 0), (80, 5, 179), (30, 80, 45)],
)
def test_weights_by_hand(cell: tuple[int, int, int]) -> None:
    ci, co = _cos_in_out(*cell)
    flat = (cell[0] * 90 + cell[1]) * 180 + cell[2]
    prod = logmap.cell_weights([flat], "product")
    mx = logmap.cell_weights([flat], "max")
    assert prod.shape == (1,) and prod.dtype == np.float64
    assert prod[0] == pytest.approx(max(ci * co, 0.01), rel=1e-12, abs=1e-14)
    assert mx[0] == pytest.approx(max(ci, co), rel=1e-12, abs=1e-14)
    np.testing.assert_array_equal(logmap.cell_weights([flat]), prod)  # product is the default


def test_weights_examples() -> None:
    # θh ≈ 89°: both directions graze, cos θi·cos θo ≈ 3e-4 → the 0.01 floor applies.
    ci, co = _cos_in_out(89, 0, 0)
    assert ci * co < 0.01
    assert logmap.cell_weights([89 * 16200], "product")[0] == 0.01
    # At normal incidence both are ≈ 1.
    assert logmap.cell_weights([0], "product")[0] == pytest.approx(1.0, abs=2e-4)
    assert logmap.cell_weights([0], "max")[0] == pytest.approx(1.0, abs=1e-4)
    w = logmap.cell_weights(np.arange(0, merl.N_CELLS, 997), "max")
    assert w.shape == (len(range(0, merl.N_CELLS, 997)),)


def test_weight_errors() -> None:
    with pytest.raises(ValueError, match="unknown weighting 'sum'"):
        logmap.cell_weights([0], "sum")
    with pytest.raises(ValueError, match="cell indices"):
        logmap.cell_weights([merl.N_CELLS], "product")


# --------------------------------------------------------------------------
# The median reference
# --------------------------------------------------------------------------


def test_median_is_over_training_rows_only(const_store: Path, tmp_path: Path) -> None:
    st = store.open_store(const_store)
    cells = np.flatnonzero(np.asarray(st.valid[:]))
    n_measured = int(merl.measured_mask().sum())
    assert cells.size == n_measured - len(range(0, n_measured, 1000))  # mat-d's holes are not valid
    value = {m: float(np.float32(v)) for m, v in CONSTANTS.items()}  # as stored (float32)
    train = ["mat-a", "mat-b", "mat-c"]
    ref = logmap.median_reference(st, train, cells)
    assert ref.dtype == np.float64 and ref.shape == cells.shape
    assert np.all(ref == value["mat-b"])  # 9 values: 3×0.1, 3×0.2, 3×0.3
    # Including the test material mat-d (10 sr⁻¹) would move the median of 12 values to 0.25.
    with_test = logmap.median_reference(const_store, [*train, "mat-d"], cells)
    assert np.all(with_test == 0.5 * (value["mat-b"] + value["mat-c"]))

    out = tmp_path / "lm.zarr"
    logmap.write_logmap(const_store, out, split="train", materials_train=train,
                        materials_out=["mat-d", "mat-b"], weighting="product")
    lm = logmap.open_logmap(out)
    assert np.all(lm.reference == value["mat-b"])
    x = lm.X[:]
    assert np.all(x[3:] == 0.0)  # mat-b is the median: maps to 0
    expect = np.log((value["mat-d"] * lm.weight + EPS) / (value["mat-b"] * lm.weight + EPS))
    np.testing.assert_allclose(x[:3], np.broadcast_to(expect, (3, lm.p)), rtol=1e-6)
    # Columns are the cells valid in every material of the store (mat-d's holes excluded),
    # although mat-d is not among the training materials.
    assert np.array_equal(lm.cells, cells)


def test_median_reference_errors(const_store: Path) -> None:
    cells = np.arange(10)
    with pytest.raises(ValueError, match="empty"):
        logmap.median_reference(const_store, [], cells)
    with pytest.raises(ValueError, match="unknown material.*nope"):
        logmap.median_reference(const_store, ["mat-a", "nope"], cells)
    with pytest.raises(ValueError, match="strictly increasing"):
        logmap.median_reference(const_store, ["mat-a"], [5, 3])


# --------------------------------------------------------------------------
# write_logmap / open_logmap
# --------------------------------------------------------------------------


@pytest.mark.parametrize("weighting", ["product", "max"])
def test_written_logmap_equals_dense(synth_store: Path, tmp_path: Path, weighting: str) -> None:
    st = store.open_store(synth_store)
    mats = list(st.materials)
    train = [mats[4], mats[0], mats[2], mats[1]]  # any order; stored in store order
    rows_out = [mats[5], mats[0], mats[3]]  # rows follow this order
    out = tmp_path / "lm.zarr"
    logmap.write_logmap(synth_store, out, split="train", materials_train=train,
                        materials_out=rows_out, weighting=weighting)
    assert _leftovers(tmp_path) == []
    lm = logmap.open_logmap(out)
    x, ref, w, cells = _dense(st, train, rows_out, weighting)
    assert lm.X.dtype == np.float32 and lm.X.shape == (9, cells.size)
    assert lm.X.chunks == (9, logmap.CHUNK_COLS)
    np.testing.assert_allclose(lm.X[:], x, rtol=2e-7, atol=2e-7)
    assert np.array_equal(lm.reference, ref)
    assert np.array_equal(lm.weight, w)
    assert lm.cells.dtype == np.int32 and np.array_equal(lm.cells, cells)
    attrs = dict(lm.group.attrs)
    assert attrs["split"] == "train" and attrs["weighting"] == weighting and attrs["epsilon"] == EPS
    assert attrs["materials"] == rows_out
    assert attrs["rows"] == [[m, c] for m in rows_out for c in range(3)]
    assert attrs["train_materials"] == [m for m in mats if m in train]
    assert attrs["database"] == "synthetic" and attrs["brdfpipe_version"] == full_version()
    assert attrs[logmap.COMPLETE_ATTR]["rows"] == 9 and attrs[logmap.COMPLETE_ATTR]["columns"] == cells.size
    # The streamed median equals median_reference.
    assert np.array_equal(logmap.median_reference(st, train, cells), ref)
    # Round trip through the inverse recovers the store's values.
    rho = logmap.inverse(lm.X[:, :5000], lm.reference[:5000], lm.weight[:5000])
    index = {m: i for i, m in enumerate(mats)}
    full = np.asarray(st.brdf[[index[m] for m in rows_out]]).reshape(3, 3, merl.N_CELLS)[:, :, cells[:5000]]
    np.testing.assert_allclose(rho, full.reshape(9, -1), rtol=2e-6, atol=1e-6)


def test_default_rows_are_the_training_materials_and_split_all(synth_store: Path, tmp_path: Path) -> None:
    st = store.open_store(synth_store)
    mats = list(st.materials)
    out = tmp_path / "all.zarr"
    logmap.write_logmap(synth_store, out, split="all", materials_train=mats[::-1], weighting="product")
    lm = logmap.open_logmap(out)
    assert lm.materials == tuple(mats[::-1]) and lm.m == 18 and lm.split == "all"
    assert lm.train_materials == tuple(mats)
    # iter_columns covers every column once, cut at chunk boundaries.
    seen = 0
    for a, b, block in logmap.iter_columns(lm):
        assert a == seen and b - a <= lm.chunk_cols and (a % lm.chunk_cols == 0)
        assert block.shape == (18, b - a) and block.dtype == np.float32
        seen = b
    assert seen == lm.p
    a, b, block = next(logmap.iter_columns(out, 100, 200))
    assert (a, b) == (100, 200) and np.array_equal(block, lm.X[:, 100:200])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"weighting": "cosine"}, "unknown weighting 'cosine'"),
        ({"split": "test"}, "unknown split 'test'"),
        ({"materials_train": []}, "materials_train is empty"),
        ({"materials_train": ["mat-a", "zinc"]}, "unknown material.*zinc"),
        ({"materials_train": ["mat-a", "mat-a"]}, "more than once"),
        ({"materials_train": "mat-a"}, "list of material names"),
        ({"materials_out": ["gold"]}, "materials_out: unknown material.*gold"),
        ({"materials_out": []}, "materials_out is empty"),
        ({"split": "all"}, "split 'all' trains on every material"),
        ({"materials_train": list(CONSTANTS), "split": "train"}, "must hold out at least one"),
        ({"eps": 0.0}, "eps must be a positive"),
    ],
)
def test_bad_arguments(const_store: Path, tmp_path: Path, kwargs: dict, message: str) -> None:
    args = {"split": "train", "materials_train": ["mat-a", "mat-b"], "materials_out": None, "weighting": "product"}
    args.update(kwargs)
    out = tmp_path / "lm.zarr"
    with pytest.raises(ValueError, match=message):
        logmap.write_logmap(const_store, out, **args)
    assert not out.exists() and _leftovers(tmp_path) == []


def test_missing_store_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(store.StoreError, match="no such store"):
        logmap.write_logmap(tmp_path / "none.zarr", tmp_path / "lm.zarr", split="all", materials_train=["a"])


def test_failure_leaves_nothing(const_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "lm.zarr"
    kwargs = {"split": "train", "materials_train": ["mat-a", "mat-b", "mat-c"], "weighting": "product"}
    logmap.write_logmap(const_store, out, **kwargs)  # an earlier, good log-map
    before = _tree(out)
    calls = {"n": 0}
    real = logmap.forward

    def failing(*args, **kw):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 20:
            raise RuntimeError("disk on fire")
        return real(*args, **kw)

    monkeypatch.setattr(logmap, "forward", failing)
    with pytest.raises(RuntimeError, match="disk on fire"):
        logmap.write_logmap(const_store, out, **kwargs)
    assert calls["n"] == 20
    assert _tree(out) == before  # the earlier one is kept exactly as it was: no data lost
    assert _leftovers(tmp_path) == []
    logmap.open_logmap(out)


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_refuses_a_foreign_zarr_group_before_reading_the_store(
    const_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "lm.zarr"
    group = zarr.open_group(out, mode="w", zarr_format=3)
    group.create_array("data", shape=(3,), dtype="float32", fill_value=0.0)[:] = 1.0
    before = _tree(out)

    def no_work(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("the store was opened before the output was checked")

    monkeypatch.setattr(logmap, "open_store", no_work)
    with pytest.raises(OutputError, match=re.escape(str(out)) + ".*refusing to replace"):
        logmap.write_logmap(const_store, out, split="train", materials_train=["mat-a", "mat-b"])
    assert _tree(out) == before and _leftovers(tmp_path) == []


@pytest.mark.parametrize("damage", ["flipped bit", "deleted shard"])
def test_damaged_store_is_refused_and_nothing_written(damage: str, const_store: Path, tmp_path: Path) -> None:
    """map_logrelative: a damaged shard is a StoreError naming store and material, never NaN in X."""
    bad = Path(shutil.copytree(const_store, tmp_path / "merl.zarr"))
    shard = bad / "brdf" / "c" / "1" / "0"  # mat-b
    if damage == "flipped bit":
        data = bytearray(shard.read_bytes())
        data[4000] ^= 0x01
        shard.write_bytes(bytes(data))
    else:
        shard.unlink()
    out = tmp_path / "lm.zarr"
    with pytest.raises(store.StoreError, match=re.escape(str(bad)) + ".*'mat-b'"):
        logmap.write_logmap(bad, out, split="train", materials_train=["mat-a", "mat-b", "mat-c"])
    assert not out.exists() and _leftovers(tmp_path) == []


def test_refuses_to_replace_a_store_or_other_folder(const_store: Path, tmp_path: Path) -> None:
    copy = tmp_path / "store.zarr"
    shutil.copytree(const_store, copy)
    kwargs = {"split": "train", "materials_train": ["mat-a", "mat-b"]}
    with pytest.raises(ValueError, match="refusing to replace"):
        logmap.write_logmap(copy, copy, **kwargs)
    store.open_store(copy, verify=True)
    other = tmp_path / "notes"
    other.mkdir()
    (other / "a.txt").write_text("x")
    with pytest.raises(ValueError, match="refusing to replace"):
        logmap.write_logmap(copy, other, **kwargs)
    assert (other / "a.txt").read_text() == "x"


def test_rerun_replaces_existing(const_store: Path, tmp_path: Path) -> None:
    out = tmp_path / "lm.zarr"
    logmap.write_logmap(const_store, out, split="train", materials_train=["mat-a", "mat-b"])
    first = logmap.open_logmap(out)
    logmap.write_logmap(const_store, out, split="train", materials_train=["mat-c"], weighting="max")
    second = logmap.open_logmap(out)
    assert second.materials == ("mat-c",) and second.weighting == "max" and second.id != first.id
    assert np.all(second.X[:] == 0.0)  # one training material: every value is its own median
    assert _leftovers(tmp_path) == []


def _edit_attrs(path: Path, fn, reseal: bool = True) -> None:  # type: ignore[no-untyped-def]
    """Edit a group's attributes; re-seal them (so the checks behind the digest are reached) unless told not to."""
    doc = json.loads((path / "zarr.json").read_text())
    attrs = doc["attributes"]
    fn(attrs)
    if reseal and integrity.ZARR_ATTR in attrs:
        attrs[integrity.ZARR_ATTR]["attributes"] = integrity.attributes_digest(attrs, (integrity.ZARR_ATTR,))
    (path / "zarr.json").write_text(json.dumps(doc))


def test_open_logmap_refuses_bad_outputs(const_store: Path, tmp_path: Path) -> None:
    good = tmp_path / "good.zarr"
    logmap.write_logmap(const_store, good, split="train", materials_train=["mat-a", "mat-b"])
    with pytest.raises(LogmapError, match="no such log-map"):
        logmap.open_logmap(tmp_path / "missing.zarr")
    with pytest.raises(LogmapError, match="not a brdfpipe log-map"):
        logmap.open_logmap(const_store)
    cases = {
        "incomplete": (lambda a: a.pop(logmap.COMPLETE_ATTR), "incomplete log-map"),
        "rows": (lambda a: a.update(rows=a["rows"][::-1]), "'rows'"),
        "materials": (lambda a: a.update(materials=["mat-a"]), "'materials'"),
        "marker": (lambda a: a[logmap.COMPLETE_ATTR].update(columns=5), "completion marker"),
        "weighting": (lambda a: a.update(weighting="cosine"), "bad split .* or weighting"),
    }
    for name, (edit, message) in cases.items():
        bad = tmp_path / f"{name}.zarr"
        shutil.copytree(good, bad)
        _edit_attrs(bad, edit)
        with pytest.raises(LogmapError, match=message):
            logmap.open_logmap(bad)
    bad = tmp_path / "no-weight.zarr"
    shutil.copytree(good, bad)
    shutil.rmtree(bad / "weight")
    with pytest.raises(LogmapError, match=r"no-weight\.zarr: file weight/\S+ is missing.*rerun|write it again"):
        logmap.open_logmap(bad)
