"""Provenance marks: derived and synthetic tables say what they are, and are never labelled as measurements.

Every test here fails on the tree before :mod:`brdfpipe.data.provenance`: the
outputs of ``interpolate``, ``sample``, ``extrapolate`` and the path points
were ingested as ``database: merl``, a synthetic file copied over another was
ingested under the wrong name, and there was no mark to read or damage.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import types
import zlib
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import cli
from brdfpipe.data import database as db
from brdfpipe.data import ingest, merl, provenance, store, synth
from brdfpipe.data.provenance import MARK_CELLS, Mark, ProvenanceError
from brdfpipe.manifold import analysis, gplvm

COUNT, SEED, NOISE = 5, 2, 0.01


def _measured_table(value: float = 0.2) -> np.ndarray:
    """A real-looking MERL table: measured cells positive, the others raw −1 (no mark)."""
    table = np.full(merl.SHAPE, value)
    table[:, ~merl.measured_mask()] = -merl.SCALES[:, None]
    return table


def _derived(name: str = "blend") -> Mark:
    return provenance.derived_mark(name=name, operation="interpolate", source_database="synthetic",
                                   inputs={"latent": [0.25, -1.5], "model": {"sha256": "0" * 64}, "note": "café"})


def _offset(cell: int) -> int:
    return merl.HEADER_BYTES + 8 * int(cell)


def _poke(path: Path, cell: int, value: int) -> None:
    """Write the 64-bit pattern ``value`` into red cell ``cell`` of a file."""
    with open(path, "r+b") as fh:
        fh.seek(_offset(cell))
        fh.write(struct.pack("<Q", value))


def _peek(path: Path, cell: int) -> int:
    with open(path, "rb") as fh:
        fh.seek(_offset(cell))
        return struct.unpack("<Q", fh.read(8))[0]


def _one_line(err: BaseException, *needles: str) -> str:
    msg = str(err)
    assert "\n" not in msg and all(n in msg for n in needles), msg
    return msg


@pytest.fixture(scope="module")
def synth_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small database written by ``brdfpipe synth`` (never modified)."""
    out = tmp_path_factory.mktemp("marks-synth") / "db"
    synth.synthesize(out, count=COUNT, seed=SEED, noise=NOISE, jobs=1, progress=False)
    return out


# --------------------------------------------------------------------------
# Where the mark lives
# --------------------------------------------------------------------------


def test_mark_cells_are_unmeasurable_for_every_pair() -> None:
    """No pair of directions that falls in a mark cell has both directions above the horizon."""
    assert not merl.measured_mask().reshape(-1)[MARK_CELLS].any()
    assert not np.isin(MARK_CELLS, provenance.WATERMARK_CELLS).any()
    assert MARK_CELLS.size == np.unique(MARK_CELLS).size == 9 * 178
    ih, idd, ip = np.unravel_index(MARK_CELLS, merl.DIMS)
    # analytic bound: min(cos θi, cos θo) = cos θd cos θh − sin θd sin θh |cos φd| at the worst corner
    th_lo = (ih / 90.0) ** 2 * (np.pi / 2)
    td_lo = idd / 90.0 * (np.pi / 2)
    cos_phi = np.minimum(np.abs(np.cos(np.radians(ip))), np.abs(np.cos(np.radians(ip + 1))))
    assert (np.cos(td_lo) * np.cos(th_lo) - np.sin(td_lo) * np.sin(th_lo) * cos_phi).max() < -0.01
    # sampled: pairs drawn in the mark's (θh, θd, φd) ranges, both φd foldings, any φh
    rng = np.random.default_rng(0)
    n = 40_000
    th = np.sqrt(rng.uniform(89.0**2, 90.0**2, n)) / 90.0 * (np.pi / 2)
    td = rng.uniform(80.0, 89.0, n) * np.pi / 180.0
    pd = np.radians(rng.uniform(0.0, 180.0, n) - 180.0 * (rng.random(n) < 0.5))
    wi, wo = merl.directions_from_half_diff(th, td, pd, rng.uniform(-np.pi, np.pi, n))
    inside = np.isin(merl.cell_index(wi, wo), MARK_CELLS)
    assert inside.mean() > 0.9
    assert np.minimum(wi[:, 2], wo[:, 2])[inside].max() < 0.0


def test_mark_values_are_exact_and_negative(tmp_path: Path) -> None:
    path = tmp_path / "m.binary"
    mark = _derived()
    merl.write_merl(path, _measured_table(), mark=mark)
    raw = merl.read_merl_raw(path).reshape(3, -1)
    assert raw[0, MARK_CELLS].tobytes() == provenance.mark_raw_values(mark).tobytes()
    assert ((raw[0, MARK_CELLS] >= -2.0) & (raw[0, MARK_CELLS] <= -1.0)).all()
    # nothing else changed: every other cell is what the table says
    plain = tmp_path / "plain.binary"
    merl.write_merl(plain, _measured_table())
    other = np.ones(raw.shape, dtype=bool)
    other[0, MARK_CELLS] = False
    assert np.array_equal(raw[other], merl.read_merl_raw(plain).reshape(3, -1)[other])
    # readers see unmeasured cells there, and the store leaves them out of `valid`
    st_path = tmp_path / "s.zarr"
    ingest.ingest({"m": path}, st_path, database="derived", jobs=1)
    assert not store.open_store(st_path).valid[MARK_CELLS].any()


# --------------------------------------------------------------------------
# Round trip and determinism
# --------------------------------------------------------------------------


def test_round_trip(tmp_path: Path, synth_dir: Path) -> None:
    path = tmp_path / "d.binary"
    mark = _derived()
    merl.write_merl(path, _measured_table(), mark=mark)
    assert provenance.read_mark(path) == mark
    assert provenance.file_label(path) == "derived"
    spec = synth.plan_database(COUNT, SEED)[1]
    got = provenance.read_mark(synth_dir / f"{spec.name}.binary")
    assert got == synth.material_mark(spec, NOISE, (COUNT, SEED))
    assert got.fields["name"] == spec.name and (got.fields["count"], got.fields["seed"]) == (COUNT, SEED)
    assert synth.is_synthetic_file(synth_dir / f"{spec.name}.binary")  # the old watermark is still there
    assert not synth.is_synthetic_file(path)
    # a payload of exactly the capacity fits; one byte more does not
    base = len(provenance.derived_mark(name="x", operation="sample", source_database="merl",
                                       inputs={"pad": ""}).payload())
    full = provenance.derived_mark(name="x", operation="sample", source_database="merl",
                                   inputs={"pad": "a" * (provenance.CAPACITY - base)})
    assert len(full.payload()) == provenance.CAPACITY
    merl.write_merl(path, _measured_table(), mark=full)
    assert provenance.read_mark(path) == full
    with pytest.raises(ValueError, match="exceeds"):
        provenance.derived_mark(name="x", operation="sample", source_database="merl",
                                inputs={"pad": "a" * (provenance.CAPACITY - base + 1)})


def test_marks_are_deterministic(tmp_path: Path) -> None:
    a = provenance.derived_mark(name="n", operation="sample", source_database="merl",
                                inputs={"seed": 1, "latent": [0.1, 0.2], "store": {"b": 1, "a": 2}})
    b = provenance.derived_mark(name="n", operation="sample", source_database="merl",
                                inputs={"store": {"a": 2, "b": 1}, "latent": (0.1, 0.2), "seed": 1})
    assert a == b and a.payload() == b.payload()
    assert b"\n" not in a.payload() and b" " not in a.payload()  # canonical: sorted keys, no spaces
    merl.write_merl(tmp_path / "1.binary", _measured_table(), mark=a)
    merl.write_merl(tmp_path / "2.binary", _measured_table(), mark=b)
    assert (tmp_path / "1.binary").read_bytes() == (tmp_path / "2.binary").read_bytes()


@pytest.mark.parametrize(
    ("kind", "fields", "problem"),
    [
        ("alien", {"name": "x"}, "unknown kind 'alien'"),
        ("derived", {"name": "x", "operation": "sample", "source_database": "merl"}, "lacks the field 'inputs'"),
        ("synthetic", {"name": "x", "generator": "g", "count": True, "seed": 1, "noise": 0.0, "family": "metal",
                       "index": 0, "material_seed": 1}, "'count'"),
        ("derived", {"name": "x", "operation": "sample", "source_database": "merl", "inputs": {"t": float("nan")}},
         "not plain JSON"),
    ],
)
def test_invalid_marks_are_refused(kind: str, fields: dict, problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        Mark(kind, fields)


# --------------------------------------------------------------------------
# Unmarked files stay measurements
# --------------------------------------------------------------------------


def test_unmarked_real_looking_files_are_never_read_as_marked(tmp_path: Path) -> None:
    path = tmp_path / "real.binary"
    merl.write_merl(path, _measured_table())
    assert provenance.read_mark(path) is None and provenance.file_label(path) == "merl"
    # whatever negative numbers a real file holds in the mark's cells, it is unmarked
    table = _measured_table()
    table[:, ~merl.measured_mask()] = -1.0  # physical −1 (raw −1500 …), as the manifold's blends write
    merl.write_merl(path, table)
    assert provenance.read_mark(path) is None
    rng = np.random.default_rng(1)
    head = MARK_CELLS[:3]
    for trial in range(2000):
        if trial % 2:
            values = -rng.uniform(1.0, 2.0, 3)  # the marks' own range [−2, −1)
        else:
            values = -np.exp(rng.normal(0.0, 10.0, 3))
        for cell, v in zip(head, values):
            _poke(path, cell, struct.unpack("<Q", struct.pack("<d", v))[0])
        assert provenance.read_mark(path) is None
    assert db.database_from_folder(tmp_path).kind == "merl"


def test_a_file_too_short_for_a_mark_is_left_to_the_format_check(tmp_path: Path) -> None:
    (tmp_path / "short.binary").write_bytes(b"\x5a\0\0\0" * 3)
    assert provenance.read_mark(tmp_path / "short.binary") is None


# --------------------------------------------------------------------------
# Damaged marks: one clean line naming the file
# --------------------------------------------------------------------------


def _flip(path: Path, cell: int, bit: int) -> None:
    _poke(path, cell, _peek(path, cell) ^ (1 << bit))


DAMAGES = {
    "magic bit": (lambda p: _flip(p, MARK_CELLS[0], 20), "magic altered"),
    "magic exponent": (lambda p: _flip(p, MARK_CELLS[0], 55), "magic altered"),
    "length": (lambda p: _flip(p, MARK_CELLS[1], 4), "damaged provenance mark"),
    "crc": (lambda p: _flip(p, MARK_CELLS[2], 30), "CRC mismatch"),
    "payload bit": (lambda p: _flip(p, MARK_CELLS[5], 12), "CRC mismatch"),
    "payload form": (lambda p: _flip(p, MARK_CELLS[4], 1), "payload cell altered"),
    "payload value": (lambda p: _poke(p, MARK_CELLS[3], struct.unpack("<Q", struct.pack("<d", 0.5))[0]),
                      "payload cell altered"),
    "newer format": (lambda p: _flip(p, MARK_CELLS[1], 4 + 33), "format 3"),
    "watermark added": (lambda p: _poke(p, provenance.WATERMARK_CELLS[0],
                                        struct.unpack("<Q", provenance.WATERMARK_RAW[:1].tobytes())[0]), "watermark"),
}


@pytest.mark.parametrize("damage", sorted(DAMAGES))
def test_a_damaged_mark_is_one_clean_error(tmp_path: Path, damage: str, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "derived"
    folder.mkdir()
    path = folder / "blend.binary"
    merl.write_merl(path, _measured_table(), mark=_derived())
    if damage == "watermark added":  # the watermark is 8 cells in each channel: add it whole
        raw = merl.read_merl_raw(path).reshape(3, -1)
        raw[:, provenance.WATERMARK_CELLS] = provenance.WATERMARK_RAW
        path.write_bytes(np.asarray(merl.DIMS, "<i4").tobytes() + raw.tobytes())
    else:
        DAMAGES[damage][0](path)
    with pytest.raises(ProvenanceError) as e:
        provenance.read_mark(path)
    _one_line(e.value, str(path), DAMAGES[damage][1])
    with pytest.raises(db.DatabaseError) as e2:
        db.database_from_folder(folder)
    assert _one_line(e2.value, str(path)).startswith("merl_dir ")
    assert cli.main(["-q", "ingest", str(folder), "--out", str(tmp_path / "s.zarr")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and "Traceback" not in err, err
    assert not (tmp_path / "s.zarr").exists()


def test_a_synthetic_mark_without_its_watermark_is_damaged(tmp_path: Path, synth_dir: Path) -> None:
    name = synth.plan_database(COUNT, SEED)[0].name
    path = tmp_path / f"{name}.binary"
    shutil.copyfile(synth_dir / f"{name}.binary", path)
    for c in provenance.WATERMARK_CELLS:
        _poke(path, c, struct.unpack("<Q", struct.pack("<d", -1.0))[0])
    with pytest.raises(ProvenanceError, match="synthetic mark without the synthetic watermark"):
        provenance.read_mark(path)


def test_an_unknown_kind_with_a_valid_crc_is_not_understood(tmp_path: Path) -> None:
    """A mark of a kind this version does not know (a newer brdfpipe's) is refused, not guessed."""
    path = tmp_path / "m.binary"
    merl.write_merl(path, _measured_table(), mark=_derived())
    payload = json.dumps({"kind": "alien", "name": "m"}, sort_keys=True, separators=(",", ":")).encode()
    header1 = (provenance.FORMAT_VERSION << 32) | len(payload)
    crc = zlib.crc32(header1.to_bytes(6, "big") + payload)
    padded = payload + b"\0" * (-len(payload) % 6)
    ns = [header1, crc << 16] + [int.from_bytes(padded[i:i + 6], "big") for i in range(0, len(padded), 6)]
    for k, n in enumerate(ns, start=1):
        _poke(path, MARK_CELLS[k], (0xBFF << 52) | (n << 4))
    with pytest.raises(ProvenanceError) as e:
        provenance.read_mark(path)
    _one_line(e.value, str(path), "unknown kind 'alien'")


# --------------------------------------------------------------------------
# The folder labeller
# --------------------------------------------------------------------------


def test_a_folder_of_derived_files_is_derived(tmp_path: Path) -> None:
    for n in ("a", "b"):
        merl.write_merl(tmp_path / f"{n}.binary", _measured_table(), mark=_derived(n))
    d = db.database_from_folder(tmp_path)
    assert d.kind == "derived" and d.materials == ["a", "b"] and d.default_test == ()
    # a renamed derived file is still fine (derived names are not bound)
    os.rename(tmp_path / "b.binary", tmp_path / "nicer-name.binary")
    assert db.database_from_folder(tmp_path).kind == "derived"


def test_a_folder_mixing_kinds_is_an_error_naming_the_files_of_each(tmp_path: Path, synth_dir: Path) -> None:
    shutil.copytree(synth_dir, tmp_path / "mixed")
    folder = tmp_path / "mixed"
    (folder / "manifest.json").unlink()
    merl.write_merl(folder / "interp.binary", _measured_table(), mark=_derived("interp"))
    merl.write_merl(folder / "measured.binary", _measured_table())
    with pytest.raises(db.DatabaseError) as e:
        db.database_from_folder(folder)
    msg = _one_line(e.value, "interp.binary", "measured.binary", "synthetic files", "derived files",
                    "unmarked (measured) MERL files")
    assert all(p.name in msg for p in synth_dir.glob("*.binary"))
    (folder / "measured.binary").unlink()
    with pytest.raises(db.DatabaseError, match="mixes synthetic files .* with derived files .*interp.binary"):
        db.database_from_folder(folder)


def test_a_synthetic_file_copied_over_another_is_named_at_parse_time(tmp_path: Path, synth_dir: Path) -> None:
    folder = tmp_path / "copy"
    shutil.copytree(synth_dir, folder)
    a, b = (s.name for s in synth.plan_database(COUNT, SEED)[:2])
    shutil.copyfile(folder / f"{b}.binary", folder / f"{a}.binary")
    with pytest.raises(db.DatabaseError) as e:
        db.database_from_folder(folder)
    _one_line(e.value, f"{a}.binary", f"synthetic material {b!r}", f"not {a!r}")


def test_legacy_synthetic_files_stay_synthetic(tmp_path: Path, synth_dir: Path) -> None:
    """Files of the old format (the 8-cell watermark, no mark) are still synthetic."""
    folder = tmp_path / "old"
    shutil.copytree(synth_dir, folder)
    minus_one = struct.unpack("<Q", struct.pack("<d", -1.0))[0]
    for f in folder.glob("*.binary"):
        for c in MARK_CELLS[:3]:
            _poke(f, c, minus_one)
        mark = provenance.read_mark(f)
        assert mark is not None and mark.legacy and mark.kind == "synthetic" and mark.name is None
    d = db.database_from_folder(folder)
    assert d.kind == "synthetic" and len(d.materials) == COUNT
    f = sorted(folder.glob("*.binary"))[0]
    ingest.ingest_material(f, tmp_path / "row.zarr", name=f.stem, expect={"database": "synthetic"})
    with pytest.raises(ProvenanceError, match="records no 'count'.*regenerate"):
        ingest.ingest_material(f, tmp_path / "row2.zarr", name=f.stem,
                              expect={"database": "synthetic", "count": COUNT, "seed": SEED})


# --------------------------------------------------------------------------
# Ingest: names and configuration are bound
# --------------------------------------------------------------------------


def test_ingest_refuses_a_synthetic_file_under_another_name(tmp_path: Path, synth_dir: Path) -> None:
    a, b = (s.name for s in synth.plan_database(COUNT, SEED)[:2])
    src = tmp_path / f"{a}.binary"
    shutil.copyfile(synth_dir / f"{b}.binary", src)  # B's file copied over A's
    row = tmp_path / "row.zarr"
    ingest.ingest_material(synth_dir / f"{a}.binary", row, name=a)
    before = sorted(p.relative_to(row) for p in row.rglob("*"))
    with pytest.raises(ProvenanceError) as e:
        ingest.ingest_material(src, row, name=a, expect={"database": "synthetic"})
    _one_line(e.value, str(src), repr(a), repr(b))
    assert sorted(p.relative_to(row) for p in row.rglob("*")) == before  # the earlier row is kept
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize(
    ("expect", "problem"),
    [
        ({"database": "synthetic", "count": COUNT, "seed": SEED + 1, "noise": NOISE}, "seed = 2, but this run expects seed = 3"),
        ({"database": "synthetic", "count": 12, "seed": SEED, "noise": NOISE}, "count = 5, but this run expects count = 12"),
        ({"database": "synthetic", "count": COUNT, "seed": SEED, "noise": 0.0}, "noise"),
        ({"database": "merl"}, "belongs to the merl database"),
    ],
)
def test_ingest_checks_the_expected_database_and_configuration(
    tmp_path: Path, synth_dir: Path, expect: dict, problem: str
) -> None:
    spec = synth.plan_database(COUNT, SEED)[0]
    with pytest.raises(ProvenanceError) as e:
        ingest.ingest_material(synth_dir / f"{spec.name}.binary", tmp_path / "row.zarr", name=spec.name, expect=expect)
    _one_line(e.value, spec.name, problem)
    ok = {"database": "synthetic", "count": COUNT, "seed": SEED, "noise": NOISE}
    ingest.ingest_material(synth_dir / f"{spec.name}.binary", tmp_path / "row.zarr", name=spec.name, expect=ok)


def test_an_unmarked_file_replacing_a_synthetic_one_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "metal-gold-000.binary"
    merl.write_merl(path, _measured_table())
    with pytest.raises(ProvenanceError, match="is an unmarked MERL file .*belongs to the synthetic database"):
        ingest.ingest_material(path, tmp_path / "row.zarr", name="metal-gold-000", expect={"database": "synthetic"})


def test_assembly_refuses_rows_of_another_label(tmp_path: Path) -> None:
    merl.write_merl(tmp_path / "d.binary", _measured_table(), mark=_derived("d"))
    merl.write_merl(tmp_path / "m.binary", _measured_table(0.3))
    rows = [tmp_path / "d.zarr", tmp_path / "m.zarr"]
    ingest.ingest_material(tmp_path / "d.binary", rows[0], name="d")
    ingest.ingest_material(tmp_path / "m.binary", rows[1], name="m")
    for label in ("merl", "derived"):
        with pytest.raises(store.StoreError) as e:
            ingest.assemble_store(rows, tmp_path / "s.zarr", database=label)
        _one_line(e.value, "one kind per store")
    assert not (tmp_path / "s.zarr").exists()
    with pytest.raises(ProvenanceError, match="d.binary: is derived material 'd' .*belongs to the merl database"):
        ingest.ingest({"d": tmp_path / "d.binary", "m": tmp_path / "m.binary"}, tmp_path / "s.zarr", database="merl")


# --------------------------------------------------------------------------
# Derived outputs of the manifold tools are derived, never merl
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def blends(synth_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A store of the synthetic database, a hand-placed raw-space model, and one output of each manifold writer."""
    tmp = tmp_path_factory.mktemp("marks-blends")
    st_path = tmp / "merl.zarr"
    d = db.database_from_folder(synth_dir)
    ingest.ingest(d.sources, st_path, database=d.kind, jobs=1)
    names = list(store.open_store(st_path).materials)
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.4, 0.6]])
    fit = types.SimpleNamespace(X=X, ell=2.0, mu=1e-4, log_likelihood=0.0, d=1.0, trace=[(0, 0.0)], method="hybrid")
    model = tmp / "q2.npz"
    gplvm.save_model(model, fit, names, space="raw",  # type: ignore[arg-type]
                     data_digests=[int(v) for v in store.open_store(st_path).digests])  # tied to the store, as a fit on it
    out = tmp / "out"
    out.mkdir()
    common = ["--model", str(model), "--store", str(st_path)]
    assert cli.main(["-q", "interpolate", *common, "--between", names[0], names[1], "--t", "0.5",
                     "--out", str(out / "interp.binary")]) == 0
    assert cli.main(["-q", "sample", *common, "--seed", "3", "--count", "2", "--out-dir", str(tmp / "samples")]) == 0
    for f in sorted((tmp / "samples").glob("*.binary")):
        shutil.copyfile(f, out / f.name)
    assert cli.main(["-q", "extrapolate", *common, "--from", names[0], "--through", names[3], "--step", "0.25",
                     "--max-s", "1", "--out", str(out / "extra.binary")]) == 0
    analysis.path_points_to_files(model=model, store=st_path, points=[(names[0], names[2], 0.5)],
                                  merl_outs=[out / "point.binary"], weights_outs=[tmp / "point.json"])
    return {"tmp": tmp, "store": st_path, "model": model, "names": names, "out": out}


def test_every_manifold_output_is_marked_derived(blends: dict) -> None:
    st = store.open_store(blends["store"])
    ident = provenance.store_identity(st)
    model_sha = provenance.file_sha256(blends["model"])
    ops = {"interp": "interpolate", "sample-000": "sample", "sample-001": "sample", "extra": "extrapolate",
           "point": "path-point"}
    for stem, op in ops.items():
        mark = provenance.read_mark(blends["out"] / f"{stem}.binary")
        assert mark is not None and mark.kind == "derived", stem
        f = mark.fields
        assert (f["operation"], f["name"], f["source_database"]) == (op, stem, "synthetic")
        assert f["inputs"]["store"] == ident and f["inputs"]["model"]["sha256"] == model_sha
        assert len(f["inputs"]["latent"]) == 2 and len(f["inputs"]["weights_sha256"]) == 64
    names = blends["names"]
    assert provenance.read_mark(blends["out"] / "interp.binary").fields["inputs"]["between"] == names[:2]
    assert provenance.read_mark(blends["out"] / "point.binary").fields["inputs"]["path"] == [names[0], names[2]]


def test_ingesting_manifold_outputs_gives_a_derived_store(blends: dict, capsys: pytest.CaptureFixture[str]) -> None:
    out = blends["tmp"] / "derived.zarr"
    assert cli.main(["-q", "ingest", str(blends["out"]), "--out", str(out), "--jobs", "1"]) == 0, capsys.readouterr()
    st = store.open_store(out)
    assert st.database == "derived" and len(st.materials) == 5
    db.write_splits(blends["tmp"] / "splits.json", store=out, test=["extra"])
    assert json.loads((blends["tmp"] / "splits.json").read_text())["database"] == "derived"


def test_manifold_outputs_are_deterministic(blends: dict) -> None:
    again = blends["tmp"] / "again.binary"
    names = blends["names"]
    assert cli.main(["-q", "interpolate", "--model", str(blends["model"]), "--store", str(blends["store"]),
                     "--between", names[0], names[1], "--t", "0.5", "--out", str(again)]) == 0
    assert provenance.read_mark(again).fields["name"] == "again"
    first = merl.read_merl_raw(blends["out"] / "interp.binary").tobytes()
    raw = merl.read_merl_raw(again)
    assert raw.tobytes() != first  # the name differs …
    raw.reshape(3, -1)[0, MARK_CELLS] = provenance.mark_raw_values(
        provenance.read_mark(blends["out"] / "interp.binary"))
    assert raw.tobytes() == first  # … and nothing else
