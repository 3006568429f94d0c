"""Tests of :mod:`brdfpipe.data.store`: the Zarr store of the materials × cells matrix.

Three full-resolution materials (35 MB each) made from smooth analytic tables,
each with its own extra unmeasured cells (some negative in one channel only),
so that ``valid`` really is an AND over materials and channels.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import zarr
from numpy.typing import NDArray

from brdfpipe.core import integrity
from brdfpipe.core.atomic import OutputError
from brdfpipe.core.zgroup import COMPLETE_ATTR
from brdfpipe.core.version import full_version
from brdfpipe.data import ingest, merl, store
from brdfpipe.data.merl import MerlFormatError, N_CELLS
from brdfpipe.data.store import N_COLS, StoreError
from brdfpipe.manifold import gram

N_MATERIALS = 3


def _table(seed: int, mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    """A smooth positive table with material-specific unmeasured cells."""
    rng = np.random.default_rng(seed)
    th, td, pd = merl.cell_centres()
    alpha = 0.05 + 0.1 * seed
    lobe = np.exp(-((th / alpha) ** 2)) * (1.0 + 0.3 * np.cos(td)) * (1.0 + 0.05 * np.cos(2 * pd))
    kd = np.array([0.1, 0.2, 0.3]) + 0.05 * seed
    table = kd[:, None, None, None] / np.pi + (2.0 + seed) * lobe[None]
    table = table.reshape(3, N_CELLS)
    table[:, ~mask.ravel()] = -merl.SCALES[:, None]
    extra = rng.choice(N_CELLS, size=2000, replace=False)
    table[seed % 3, extra] = -0.5 * merl.SCALES[seed % 3]  # unmeasured in one channel only
    table[:, extra[:5]] = 0.0  # zero counts as measured
    return table.reshape(merl.SHAPE)


@pytest.fixture(scope="module")
def sources(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """name -> MERL file, for three materials."""
    d = tmp_path_factory.mktemp("merl")
    mask = merl.measured_mask()
    out = {}
    for i in range(N_MATERIALS):
        path = d / f"mat-{i}.binary"
        merl.write_merl(path, _table(i, mask))
        out[f"mat-{i}"] = path
    return out


@pytest.fixture(scope="module")
def expected(sources: dict[str, Path]) -> NDArray[np.float32]:
    """The matrix as read directly with read_merl, in source order."""
    return np.stack([merl.read_merl(p).reshape(-1).astype(np.float32) for p in sources.values()])


@pytest.fixture(scope="module")
def built(sources: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A store made by ``ingest`` with two worker processes."""
    out = tmp_path_factory.mktemp("built") / "merl.zarr"
    ingest.ingest(sources, out, database="merl", jobs=2)
    return out


@pytest.fixture(scope="module")
def rows(sources: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Row stores made by ``ingest_material`` (read-only for the tests: copy before damaging)."""
    d = tmp_path_factory.mktemp("rows")
    paths = []
    for name, src in sources.items():
        row = d / f"{name}.zarr"
        ingest.ingest_material(src, row, name=name)
        paths.append(row)
    return paths


def _leftovers(folder: Path) -> list[str]:
    if not folder.exists():
        return []
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def _tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` by relative path, with its bytes."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _bits(a: NDArray[np.float32]) -> NDArray[np.uint32]:
    return np.ascontiguousarray(a).view(np.uint32)


# --------------------------------------------------------------------------
# Content
# --------------------------------------------------------------------------


def test_rows_equal_direct_read(built: Path, expected: NDArray[np.float32]) -> None:
    st = store.open_store(built, verify=True)
    assert st.brdf.shape == (N_MATERIALS, N_COLS) and st.brdf.dtype == np.float32
    for i in range(N_MATERIALS):
        np.testing.assert_array_equal(_bits(st.brdf[i, :]), _bits(expected[i]))


def test_valid_is_and_of_masks(built: Path, sources: dict[str, Path]) -> None:
    want = np.ones(N_CELLS, dtype=bool)
    for p in sources.values():
        want &= (merl.read_merl(p).reshape(3, N_CELLS) >= 0).all(axis=0)
    st = store.open_store(built)
    got = st.valid[:]
    assert got.dtype == np.bool_
    np.testing.assert_array_equal(got, want)
    assert want.sum() < merl.measured_mask().sum()  # the extra unmeasured cells matter


def test_attributes(built: Path, sources: dict[str, Path]) -> None:
    st = store.open_store(built)
    attrs = dict(st.group.attrs)
    assert attrs["materials"] == list(sources) and st.materials == tuple(sources)
    assert attrs["database"] == "merl"
    for name, path in sources.items():
        assert attrs["sources"][name] == hashlib.sha256(path.read_bytes()).hexdigest()
        assert attrs["source_files"][name] == path.name
    assert attrs["channel_scales"] == list(merl.SCALES)
    assert "column k" in attrs["layout"] and attrs["brdfpipe_version"] == full_version()
    assert attrs[store.COMPLETE_ATTR]["n_materials"] == N_MATERIALS
    assert st.brdf.chunks == (1, store.CHUNK_COLS)


def test_store_is_plain_zarr(built: Path, expected: NDArray[np.float32]) -> None:
    """Readable with zarr alone, nothing brdfpipe-specific needed."""
    group = zarr.open_group(built, mode="r")
    np.testing.assert_array_equal(group["brdf"][1, 1_000_000:1_000_100], expected[1, 1_000_000:1_000_100])


def test_row_shard_bytes_equal_zarrs(rows: list[Path], expected: NDArray[np.float32], tmp_path: Path) -> None:
    """The hand-written shard is byte-identical to what Zarr writes for the same row."""
    group = zarr.open_group(tmp_path / "ref.zarr", mode="w", zarr_format=3)
    arr = ingest._create_brdf_array(group, 1)
    arr[0, :] = expected[0]
    ours = (rows[0] / "brdf" / "c" / "0" / "0").read_bytes()
    assert (tmp_path / "ref.zarr" / "brdf" / "c" / "0" / "0").read_bytes() == ours
    row = zarr.open_group(rows[0], mode="r")
    np.testing.assert_array_equal(_bits(row["brdf"][0, :]), _bits(expected[0]))
    assert row.attrs["name"] == "mat-0"


# --------------------------------------------------------------------------
# Reading by blocks
# --------------------------------------------------------------------------


@pytest.mark.parametrize("block_cols", [None, 1_000_003, 2 * store.CHUNK_COLS])
def test_iter_column_blocks_cover_and_equal(
    built: Path, expected: NDArray[np.float32], block_cols: int | None
) -> None:
    nxt = 0
    for start, stop, block in store.iter_column_blocks(built, block_cols):
        assert start == nxt and stop > start and block.dtype == np.float32
        assert block.shape == (N_MATERIALS, stop - start)
        if block_cols is None:
            assert start % store.CHUNK_COLS == 0
        np.testing.assert_array_equal(block, expected[:, start:stop])
        nxt = stop
    assert nxt == N_COLS


@pytest.mark.parametrize(
    "rows_sel, want",
    [
        ([2, 0], [2, 0]),
        (["mat-1"], [1]),
        (np.array([True, False, True]), [0, 2]),
        (slice(1, 3), [1, 2]),
        (slice(None, None, -1), [2, 1, 0]),
        (-1, [2]),
    ],
)
def test_iter_column_blocks_rows(
    built: Path, expected: NDArray[np.float32], rows_sel: object, want: list[int]
) -> None:
    blocks = list(store.iter_column_blocks(store.open_store(built), 4 * store.CHUNK_COLS, rows=rows_sel))
    got = np.concatenate([b for _, _, b in blocks], axis=1)
    np.testing.assert_array_equal(got, expected[want])


# --------------------------------------------------------------------------
# Bad inputs and failures
# --------------------------------------------------------------------------


def _truncated(src: Path, dst: Path) -> Path:
    dst.write_bytes(src.read_bytes()[:-8])
    return dst


def _with_nan(src: Path, dst: Path) -> Path:
    data = bytearray(src.read_bytes())
    pos = merl.HEADER_BYTES + 8 * (2 * N_CELLS + 123_456)  # a blue value late in the file
    data[pos : pos + 8] = np.array([np.nan], "<f8").tobytes()
    dst.write_bytes(bytes(data))
    return dst


def _bad_header(src: Path, dst: Path) -> Path:
    data = bytearray(src.read_bytes())
    data[:4] = np.array([91], "<i4").tobytes()
    dst.write_bytes(bytes(data))
    return dst


def _too_big(src: Path, dst: Path) -> Path:
    data = bytearray(src.read_bytes())
    pos = merl.HEADER_BYTES + 8 * 77
    data[pos : pos + 8] = np.array([1e300], "<f8").tobytes()  # finite, not a float32
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize("damage", [_truncated, _with_nan, _bad_header, _too_big])
def test_bad_file_fails_and_leaves_nothing(
    damage: object, sources: dict[str, Path], rows: list[Path], tmp_path: Path
) -> None:
    bad = damage(sources["mat-0"], tmp_path / "bad.binary")  # type: ignore[operator]
    out = tmp_path / "out" / "row.zarr"
    with pytest.raises(MerlFormatError, match=re.escape(str(bad))):
        ingest.ingest_material(bad, out, name="bad")
    assert not out.exists() and _leftovers(out.parent) == []
    # An earlier row store at `out` is kept exactly as it was (no data lost).
    shutil.copytree(rows[0], out)
    before = _tree(out)
    with pytest.raises(MerlFormatError):
        ingest.ingest_material(bad, out, name="bad")
    assert _tree(out) == before and _leftovers(out.parent) == []


def test_missing_file_fails(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nope.binary"):
        ingest.ingest_material(tmp_path / "nope.binary", tmp_path / "row.zarr", name="x")
    assert list(tmp_path.iterdir()) == []


def test_ingest_with_a_bad_file_fails(sources: dict[str, Path], tmp_path: Path) -> None:
    bad = _with_nan(sources["mat-1"], tmp_path / "bad.binary")
    out = tmp_path / "store" / "merl.zarr"
    srcs = {"a": sources["mat-0"], "bad": bad, "c": sources["mat-2"]}
    with pytest.raises(MerlFormatError, match=re.escape(str(bad))):
        ingest.ingest(srcs, out, database="merl", jobs=2)
    assert not out.exists() and _leftovers(out.parent) == []


def _copy_rows(rows: list[Path], dst: Path) -> list[Path]:
    dst.mkdir()
    return [Path(shutil.copytree(r, dst / r.name)) for r in rows]


def _edit_json(path: Path, fn: object) -> None:
    doc = json.loads(path.read_text())
    fn(doc)  # type: ignore[operator]
    path.write_text(json.dumps(doc))


def _drop_marker(doc: dict) -> None:
    del doc["attributes"][store.COMPLETE_ATTR]


def _other_chunks(doc: dict) -> None:
    doc["codecs"][0]["configuration"]["chunk_shape"] = [1, 48_600]


def _rename(doc: dict) -> None:
    doc["attributes"]["name"] = "mat-0"


@pytest.mark.parametrize(
    "problem, message",
    [
        ("missing", "row store is missing"),
        ("no marker", "incomplete"),
        ("layout", "layout"),
        ("duplicate", "duplicate material name"),
        ("damaged", "does not match the digest"),
        ("no shard", "missing"),
    ],
)
def test_assemble_bad_row_fails_and_leaves_nothing(
    problem: str, message: str, rows: list[Path], tmp_path: Path
) -> None:
    copies = _copy_rows(rows, tmp_path / "rows")
    bad = copies[1]
    if problem == "missing":
        shutil.rmtree(bad)
    elif problem == "no marker":
        _edit_json(bad / "zarr.json", _drop_marker)
    elif problem == "layout":
        _edit_json(bad / "brdf" / "zarr.json", _other_chunks)
    elif problem == "duplicate":
        _edit_json(bad / "zarr.json", _rename)
    elif problem == "damaged":
        shard = bad / "brdf" / "c" / "0" / "0"
        data = bytearray(shard.read_bytes())
        data[1000] ^= 0xFF
        shard.write_bytes(bytes(data))
    elif problem == "no shard":
        (bad / "brdf" / "c" / "0" / "0").unlink()
    out = tmp_path / "out" / "merl.zarr"
    for link in (False, True):
        with pytest.raises(StoreError, match=message) as err:
            ingest.assemble_store(copies, out, database="merl", link=link)
        assert str(bad) in str(err.value)
        assert not out.exists() and _leftovers(out.parent) == []


def test_assemble_copies_and_verifies(rows: list[Path], expected: NDArray[np.float32], tmp_path: Path) -> None:
    out = tmp_path / "merl.zarr"
    ingest.assemble_store(list(reversed(rows)), out, database="merl")
    st = store.open_store(out, verify=True)
    assert st.materials == ("mat-2", "mat-1", "mat-0") and st.database == "merl"
    np.testing.assert_array_equal(st.brdf[0, :], expected[2])
    for i, row in enumerate(reversed(rows)):
        shard = out / "brdf" / "c" / str(i) / "0"
        assert shard.read_bytes() == (row / "brdf" / "c" / "0" / "0").read_bytes()
        assert shard.stat().st_nlink == 1  # a copy, not a link
    # A damaged shard passes the cheap checks (verify=False) but not the default open.
    shard = out / "brdf" / "c" / "1" / "0"
    data = bytearray(shard.read_bytes())
    data[-100] ^= 1
    shard.write_bytes(bytes(data))
    unverified = store.open_store(out, verify=False)
    with pytest.raises(StoreError, match=re.escape(str(out)) + ".*'mat-1'.*corrupt"):
        store.open_store(out)
    # ... and the readers verify the rows they read, even on an unverified handle.
    next(store.iter_column_blocks(unverified, rows=["mat-0"]))
    with pytest.raises(StoreError, match="'mat-1'.*corrupt"):
        next(store.iter_column_blocks(unverified))


def test_assemble_rejects_unknown_database(rows: list[Path], tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="database"):
        ingest.assemble_store(rows, tmp_path / "merl.zarr", database="mystery")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------
# open_store and reruns
# --------------------------------------------------------------------------


def test_open_store_refuses_incomplete(built: Path, tmp_path: Path) -> None:
    crashed = Path(shutil.copytree(built, tmp_path / "crashed.zarr"))
    _edit_json(crashed / "zarr.json", _drop_marker)  # as if the writer died before the marker
    with pytest.raises(StoreError, match=re.escape(str(crashed)) + ".*completion marker"):
        store.open_store(crashed)
    with pytest.raises(StoreError, match="completion marker"):
        next(store.iter_column_blocks(crashed))


def test_open_store_refuses_inconsistent(built: Path, tmp_path: Path) -> None:
    def fewer_names(doc: dict) -> None:
        doc["attributes"]["materials"] = doc["attributes"]["materials"][:2]

    def wrong_dtype(doc: dict) -> None:
        doc["data_type"] = "float64"

    bad = Path(shutil.copytree(built, tmp_path / "bad.zarr"))
    _edit_json(bad / "zarr.json", fewer_names)
    with pytest.raises(StoreError, match=re.escape(str(bad)) + ".*2 material names for 3 rows"):
        store.open_store(bad)
    bad2 = Path(shutil.copytree(built, tmp_path / "bad2.zarr"))
    _edit_json(bad2 / "brdf" / "zarr.json", wrong_dtype)
    with pytest.raises(StoreError, match="float32"):
        store.open_store(bad2)
    with pytest.raises(StoreError, match="no such store"):
        store.open_store(tmp_path / "absent.zarr")


def test_rerun_replaces_existing(sources: dict[str, Path], expected: NDArray[np.float32], tmp_path: Path) -> None:
    out = tmp_path / "merl.zarr"
    ingest.ingest(list(sources.values()), out, database="merl", jobs=1)
    assert store.open_store(out).materials == ("mat-0", "mat-1", "mat-2")
    ingest.ingest({"only": sources["mat-2"]}, out, database="merl", jobs=1)
    st = store.open_store(out, verify=True)
    assert st.materials == ("only",) and st.database == "merl"
    np.testing.assert_array_equal(st.brdf[:, :], expected[2:3])
    assert sorted(os.listdir(tmp_path)) == ["merl.zarr"]


def test_ingest_keeps_rows_in_workdir(sources: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "merl.zarr"
    ingest.ingest(sources, out, database="merl", jobs=1, workdir=tmp_path / "rows")
    kept = sorted(p.name for p in (tmp_path / "rows").iterdir())
    assert kept == ["0000-mat-0.zarr", "0001-mat-1.zarr", "0002-mat-2.zarr"]
    assert (out / "brdf" / "c" / "0" / "0").stat().st_nlink == 1  # kept rows are copied, not linked
    assert store.open_store(out, verify=True).materials == tuple(sources)


def _foreign_group(path: Path) -> Path:
    """A Zarr group that is not a brdfpipe store (no brdfpipe format attribute)."""
    group = zarr.open_group(path, mode="w", zarr_format=3)
    group.attrs["format"] = "someone-else/1"
    group.create_array("data", shape=(4,), dtype="int32", fill_value=0)[:] = np.arange(4)
    return path


@pytest.mark.parametrize("kind", ["folder", "zarr group", "row store"])
def test_writers_refuse_a_foreign_output_before_any_work(
    kind: str, sources: dict[str, Path], rows: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "results"
    if kind == "folder":
        out.mkdir()
        (out / "precious.txt").write_text("keep me")
    elif kind == "zarr group":
        _foreign_group(out)
    else:
        shutil.copytree(rows[0], out)  # a row store is not a store (and a store is not a row store)
    before = _tree(out)

    def no_work(path: Path) -> None:
        raise AssertionError("a source was read before the output was checked")

    monkeypatch.setattr(ingest, "_encode_source", no_work)
    monkeypatch.setattr(ingest, "_open_row", no_work)
    calls = [
        lambda: ingest.ingest(sources, out, database="merl", jobs=1),
        lambda: ingest.assemble_store(rows, out, database="merl"),
    ]
    if kind != "row store":
        calls.append(lambda: ingest.ingest_material(sources["mat-0"], out, name="x"))
    for call in calls:
        with pytest.raises(OutputError, match=re.escape(str(out)) + ".*refusing to replace"):
            call()
        assert _tree(out) == before
    assert sorted(os.listdir(tmp_path)) == ["results"]


def test_failed_reingest_keeps_the_old_store(
    sources: dict[str, Path], built: Path, rows: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = Path(shutil.copytree(built, tmp_path / "merl.zarr"))
    before = _tree(out)
    bad = _with_nan(sources["mat-1"], tmp_path / "bad.binary")
    with pytest.raises(MerlFormatError, match=re.escape(str(bad))):
        ingest.ingest({"a": sources["mat-0"], "bad": bad}, out, database="merl", jobs=2)
    assert _tree(out) == before and _leftovers(tmp_path) == []
    copies = _copy_rows(rows, tmp_path / "rows")
    (copies[2] / "brdf" / "c" / "0" / "0").unlink()
    with pytest.raises(StoreError, match="missing"):
        ingest.assemble_store(copies, out, database="merl")
    assert _tree(out) == before and _leftovers(tmp_path) == []

    # An interrupt (Ctrl-C) in the middle of the assembly.
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(ingest, "_warn_removals", interrupted)
    with pytest.raises(KeyboardInterrupt):
        ingest.ingest(sources, out, database="merl", jobs=1)
    assert _tree(out) == before and _leftovers(tmp_path) == []
    store.open_store(out)


def test_stale_siblings_of_dead_runs_are_removed(sources: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "merl.zarr"
    proc = subprocess.run(["sh", "-c", "echo $$"], capture_output=True, text=True, check=True)
    dead = int(proc.stdout)  # that shell has exited
    stale = [tmp_path / f".merl.zarr.tmp-{dead}-0badc0de", tmp_path / f".merl.zarr.rows-{dead}-deadbeef"]
    for d in stale:
        (d / "sub").mkdir(parents=True)
        (d / "sub" / "junk").write_bytes(b"x" * 100)
    alive = tmp_path / f".merl.zarr.tmp-{os.getpid()}-00000001"  # a live writer's: left alone
    alive.mkdir()
    ingest.ingest({"only": sources["mat-0"]}, out, database="merl", jobs=1)
    assert sorted(os.listdir(tmp_path)) == sorted([alive.name, "merl.zarr"])


def test_same_sources_give_the_same_bytes(sources: dict[str, Path], tmp_path: Path) -> None:
    """Determinism: two ingests (different worker counts) write byte-identical stores."""
    a, b = tmp_path / "a.zarr", tmp_path / "b.zarr"
    ingest.ingest(sources, a, database="merl", jobs=1)
    ingest.ingest(sources, b, database="merl", jobs=2)

    def tree(root: Path) -> dict[str, bytes]:
        return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}

    ta, tb = tree(a), tree(b)
    assert json.loads(ta["zarr.json"])["attributes"]["format"] == "brdfpipe.data.merl-store/3"
    assert ta.keys() == tb.keys() and len(ta) > 4
    assert all(ta[k] == tb[k] for k in ta)


# --------------------------------------------------------------------------
# Integrity: consumers verify what they read
# --------------------------------------------------------------------------


def _flip_bit(path: Path, pos: int = 5000) -> None:
    data = bytearray(path.read_bytes())
    data[pos] ^= 0x10
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", ["flipped bit", "deleted shard", "truncated shard"])
def test_damaged_shard_stops_the_gram_job(damage: str, built: Path, tmp_path: Path) -> None:
    """gram.write_gram (the compute_gram job) fails naming store and material, and writes nothing."""
    bad = Path(shutil.copytree(built, tmp_path / "merl.zarr"))
    shard = bad / "brdf" / "c" / "2" / "0"
    if damage == "flipped bit":
        _flip_bit(shard)
    elif damage == "deleted shard":
        shard.unlink()
    else:
        shard.write_bytes(shard.read_bytes()[:-10])
    out = tmp_path / "gram.npz"
    with pytest.raises(StoreError, match=re.escape(str(bad)) + ".*'mat-2'") as err:
        gram.write_gram(bad, out)
    assert "\n" not in str(err.value)
    assert not out.exists() and _leftovers(tmp_path) == []
    with pytest.raises(StoreError, match="'mat-2'"):
        gram.gram_matrix(bad)


def test_swapped_names_fail_verification(built: Path, tmp_path: Path) -> None:
    bad = Path(shutil.copytree(built, tmp_path / "merl.zarr"))

    def swap(doc: dict) -> None:
        names = doc["attributes"]["materials"]
        names[0], names[1] = names[1], names[0]
        doc["attributes"]["sources"] = dict(doc["attributes"]["sources"])  # same keys: still consistent

    _edit_json(bad / "zarr.json", swap)
    # every open (verify=False too) checks the attributes against their digest
    with pytest.raises(StoreError, match=re.escape(str(bad)) + ": its attributes .*do not match their recorded "
                                         r"digest \(damaged or edited\); re-ingest the store"):
        store.open_store(bad, verify=False)
    _edit_json(bad / "zarr.json", _reseal)  # a deliberate re-seal: the shards' name-bound digests still fail
    store.open_store(bad, verify=False)  # the metadata alone is consistent
    with pytest.raises(StoreError, match=re.escape(str(bad)) + ".*'mat-1'.*corrupt"):
        store.open_store(bad)
    # Swapping the shard files (names kept) fails too.
    bad2 = Path(shutil.copytree(built, tmp_path / "swapped.zarr"))
    a, b = bad2 / "brdf" / "c" / "0" / "0", bad2 / "brdf" / "c" / "1" / "0"
    da, db = a.read_bytes(), b.read_bytes()
    a.write_bytes(db)
    b.write_bytes(da)
    with pytest.raises(StoreError, match="'mat-0'"):
        store.open_store(bad2)


@pytest.mark.parametrize("damage", ["deleted", "flipped bit", "garbage"])
def test_damaged_valid_chunk_is_a_store_error(damage: str, built: Path, tmp_path: Path) -> None:
    bad = Path(shutil.copytree(built, tmp_path / "merl.zarr"))
    chunk = bad / "valid" / "c" / "0"
    if damage == "deleted":
        chunk.unlink()
    elif damage == "flipped bit":
        _flip_bit(chunk, 100)
    else:
        chunk.write_bytes(b"not blosc at all")
    for verify in (False, True):
        with pytest.raises(StoreError, match=re.escape(str(bad)) + ".*'valid' mask"):
            store.open_store(bad, verify=verify)


@pytest.mark.parametrize("version", [1, 2])
def test_old_format_is_refused_with_a_reingest_hint(built: Path, tmp_path: Path, version: int) -> None:
    old = Path(shutil.copytree(built, tmp_path / "old.zarr"))

    def older(doc: dict) -> None:
        doc["attributes"].update(format=f"brdfpipe.data.merl-store/{version}")
        doc["attributes"]["digests"].pop("attributes")  # format 2 had no digest of its attributes

    _edit_json(old / "zarr.json", older)
    why = "material names" if version == 1 else "'database', 'materials' and 'sources'"
    with pytest.raises(StoreError, match=re.escape(str(old)) + f".*no longer supported.*{why}.*re-ingest the store"):
        store.open_store(old)
    assert store.is_store(old)  # an ingest may replace it


@pytest.mark.parametrize("edit", ["database", "sources", "materials", "source_files", "layout"])
def test_an_edited_attribute_is_refused_on_every_open(built: Path, tmp_path: Path, edit: str) -> None:
    """The 'database' label (and the other attributes) is covered by a digest checked on every open."""
    bad = Path(shutil.copytree(built, tmp_path / "merl.zarr"))

    def change(doc: dict) -> None:
        a = doc["attributes"]
        if edit == "database":
            a["database"] = "merl" if a["database"] == "synthetic" else "synthetic"
        elif edit == "sources":
            a["sources"][a["materials"][0]] = "0" * 64
        elif edit == "materials":
            a["materials"][0], a["materials"][1] = a["materials"][1], a["materials"][0]
        elif edit == "source_files":
            a["source_files"][a["materials"][0]] = "other.binary"
        else:
            a["layout"] += " (edited)"

    _edit_json(bad / "zarr.json", change)
    for verify in (False, True):
        with pytest.raises(StoreError, match=re.escape(str(bad)) + r": its attributes \(database, materials, "
                                             r"sources, \.\.\.\) do not match their recorded digest"):
            store.open_store(bad, verify=verify)


def _reseal(doc: dict) -> None:
    """Recompute the store's attributes digest after an edit (what only a deliberate forger does)."""
    attrs = doc["attributes"]
    attrs["digests"]["attributes"] = integrity.attributes_digest(attrs, ("digests", COMPLETE_ATTR))


# --------------------------------------------------------------------------
# Ingest checks
# --------------------------------------------------------------------------


def test_file_without_measured_cells_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "empty.binary"
    merl.write_merl(src, np.full(merl.SHAPE, -1.0))
    with pytest.raises(MerlFormatError, match=re.escape(str(src)) + ".*no measured cell"):
        ingest.ingest_material(src, tmp_path / "row.zarr", name="empty")
    assert sorted(os.listdir(tmp_path)) == ["empty.binary"]


def test_file_removing_many_cells_is_warned(
    sources: dict[str, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    table = merl.read_merl(sources["mat-1"]).reshape(3, N_CELLS)
    measured = np.flatnonzero((table >= 0).all(axis=0))
    table[2, measured[: measured.size // 20]] = -1.0  # 5 % of the measured cells
    holey = tmp_path / "holey.binary"
    merl.write_merl(holey, table.reshape(merl.SHAPE))
    with caplog.at_level(logging.WARNING, logger="brdfpipe.data.ingest"):
        ingest.ingest({"a": sources["mat-0"], "holey": holey, "c": sources["mat-2"]},
                     tmp_path / "merl.zarr", database="merl", jobs=1)
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warned) == 1 and re.match(r"holey\.binary: material 'holey' leaves .* \(5\.\d%\)", warned[0])
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="brdfpipe.data.ingest"):
        ingest.ingest(sources, tmp_path / "fine.zarr", database="merl", jobs=1)
    assert not [r for r in caplog.records if r.levelno == logging.WARNING]  # 2000 of ~1 M cells: 0.2 %
