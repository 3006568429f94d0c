"""Provenance: a database folder's label comes from its files, names are safe, writes are atomic.

Every test here failed on the code before the synthetic watermark and
:func:`brdfpipe.data.database.database_from_folder`: a folder written by
``brdfpipe synth`` was labelled ``merl`` through ``merl_dir``, a mixed folder
was labelled synthetic, an empty path fell back silently, ``*.BINARY`` files
were skipped and any file stem became a material name.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.core import atomic
from brdfpipe.data import database as db, merl, synth, synthmodel

COUNT, SEED = 3, 5


@pytest.fixture(scope="module")
def synth_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small database written by :func:`brdfpipe.data.synth.synthesize` (never modified)."""
    out = tmp_path_factory.mktemp("synth") / "db"
    synth.synthesize(out, count=COUNT, seed=SEED, noise=0.01, jobs=1, progress=False)
    return out


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _measured_table(value: float = 0.2) -> np.ndarray:
    """A real-looking MERL table: measured cells positive, the others raw −1 (no watermark)."""
    table = np.full(merl.SHAPE, value)
    table[:, ~merl.measured_mask()] = -merl.SCALES[:, None]
    return table


def _merl_dir(folder: Path, names: list[str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i, n in enumerate(names):
        merl.write_merl(folder / f"{n}.binary", _measured_table(0.1 + 0.05 * i))
    return folder


# --------------------------------------------------------------------------
# The watermark
# --------------------------------------------------------------------------


def test_watermark_cells_are_geometrically_unmeasurable() -> None:
    """Every pair that falls in a watermark cell has a direction far below the horizon."""
    assert not merl.measured_mask().reshape(-1)[synth.WATERMARK_CELLS].any()
    rng = np.random.default_rng(0)
    n = 20_000
    # the watermark cells' extent: θh bin 89 (square-root binning), θd bin 89, φd bins 0…7
    # (φd ∈ [0°, 8°) and, folded, [−180°, −172°))
    th = np.sqrt(rng.uniform(89.0**2, 90.0**2, n)) / 90.0 * (np.pi / 2)
    td = rng.uniform(89.0, 90.0, n) * np.pi / 180.0
    pd = np.radians(rng.uniform(0.0, 8.0, n) - 180.0 * (rng.random(n) < 0.5))
    ph = rng.uniform(-np.pi, np.pi, n)
    wi, wo = merl.directions_from_half_diff(th, td, pd, ph)
    idx = merl.cell_index(wi, wo)
    inside = np.isin(idx, synth.WATERMARK_CELLS)
    assert inside.mean() > 0.95  # (bin edges aside)
    lowest = np.minimum(wi[:, 2], wo[:, 2])[inside]
    assert lowest.max() < -0.98
    # the lookup of such a pair is unmeasured (negative), as for any other such cell
    table = synth._table(np.ones((3, synthmodel.cell_grid().cells.size)), synthmodel.cell_grid())
    assert (merl.lookup(table, wi[inside], wo[inside]) < 0).all()


def test_watermark_bytes_in_every_channel(synth_dir: Path) -> None:
    for f in sorted(synth_dir.glob("*.binary")):
        raw = merl.read_merl_raw(f).reshape(3, -1)
        assert (raw[:, synth.WATERMARK_CELLS] == synth.WATERMARK_RAW).all()
        assert synth.is_synthetic_file(f)


def test_files_without_the_watermark_are_not_synthetic(tmp_path: Path) -> None:
    merl.write_merl(tmp_path / "m.binary", _measured_table())
    assert not synth.is_synthetic_file(tmp_path / "m.binary")
    (tmp_path / "empty.binary").write_bytes(b"")
    assert not synth.is_synthetic_file(tmp_path / "empty.binary")


# --------------------------------------------------------------------------
# database_from_folder: the one label
# --------------------------------------------------------------------------


def test_synth_folder_as_merl_dir_is_synthetic(synth_dir: Path) -> None:
    names = sorted(p.stem for p in synth_dir.glob("*.binary"))
    for key in ("merl_dir", "folder"):
        d = db.database_from_folder(synth_dir, key=key)
        assert d.kind == "synthetic" and d.materials == names
    manifest = json.loads((synth_dir / "manifest.json").read_text())
    assert db.database_from_folder(synth_dir).default_test == tuple(manifest["test_materials"])


def test_synthetic_label_comes_from_the_files_without_manifest(synth_dir: Path, tmp_path: Path) -> None:
    folder = _copy(synth_dir, tmp_path / "copy")
    (folder / "manifest.json").unlink()
    d = db.database_from_folder(folder)
    assert d.kind == "synthetic" and len(d.materials) == COUNT
    assert d.default_test == ()
    with pytest.raises(db.DatabaseError, match="no default held-out material.*test_materials"):
        db.resolve_test_materials(None, d)
    assert db.resolve_test_materials([d.materials[0]], d) == [d.materials[0]]


def test_real_looking_merl_folder_is_merl(tmp_path: Path) -> None:
    folder = _merl_dir(tmp_path / "merl", ["alum-bronze", "blue-acrylic", "gold-paint"])
    d = db.database_from_folder(folder)
    assert d.kind == "merl" and d.materials == ["alum-bronze", "blue-acrylic", "gold-paint"]
    assert set(db.XU2016_TEST_MATERIALS) <= set(d.default_test)


def test_mixed_folder_is_an_error_naming_the_files(synth_dir: Path, tmp_path: Path) -> None:
    folder = _copy(synth_dir, tmp_path / "mixed")
    _merl_dir(folder, ["real-one"])
    with pytest.raises(db.DatabaseError) as e:
        db.database_from_folder(folder)
    msg = str(e.value)
    assert "mixes synthetic" in msg and "real-one.binary" in msg
    assert all(f"{p.stem}.binary" in msg for p in synth_dir.glob("*.binary"))
    assert msg.startswith("merl_dir ") and "\n" not in msg


@pytest.mark.parametrize("path", ["", "   ", "\t"])
def test_empty_path_names_the_key(path: str) -> None:
    with pytest.raises(db.DatabaseError) as e:
        db.database_from_folder(path)
    assert str(e.value) == "merl_dir: empty path; give the folder of MERL files"
    with pytest.raises(db.DatabaseError, match="^source: empty path"):
        db.database_from_folder(path, key="source")


def test_manifest_in_a_real_folder_is_an_error(synth_dir: Path, tmp_path: Path) -> None:
    folder = _merl_dir(tmp_path / "merl", ["a-mat", "b-mat"])
    shutil.copy(synth_dir / "manifest.json", folder / "manifest.json")
    with pytest.raises(db.DatabaseError, match="manifest.json: says the folder is synthetic.*a-mat.binary"):
        db.database_from_folder(folder)


def test_manifest_must_list_every_synthetic_file(synth_dir: Path, tmp_path: Path) -> None:
    folder = _copy(synth_dir, tmp_path / "copy")
    doc = json.loads((folder / "manifest.json").read_text())
    dropped = doc["materials"].pop(0)["name"]
    (folder / "manifest.json").write_text(json.dumps(doc))
    with pytest.raises(db.DatabaseError, match=f"does not list the synthetic file.*{dropped}.binary"):
        db.database_from_folder(folder)
    # a subset of the files with the full manifest is fine (a partial copy)
    subset = _copy(synth_dir, tmp_path / "subset")
    (subset / f"{dropped}.binary").unlink()
    d = db.database_from_folder(subset)
    assert d.kind == "synthetic" and dropped not in d.materials and dropped not in d.default_test


def test_other_case_suffix_is_an_error_naming_the_file(tmp_path: Path) -> None:
    folder = _merl_dir(tmp_path / "merl", ["a-mat"])
    shutil.copy(folder / "a-mat.binary", folder / "Teflon.BINARY")
    with pytest.raises(db.DatabaseError, match=r"Teflon\.BINARY: suffix is not exactly '\.binary'"):
        db.database_from_folder(folder)


@pytest.mark.parametrize(
    ("stem", "problem"),
    [
        ("has space", "contains ' '"),
        ("{wild}", "contains"),
        ("café", "contains 'é'"),
        ("x" * 101, "too long"),
        ("-dash-first", "starts with '-'"),
        (".hidden", "starts with '.'"),
    ],
)
def test_unsafe_material_names_are_errors(tmp_path: Path, stem: str, problem: str) -> None:
    folder = _merl_dir(tmp_path / "merl", ["fine-name"])
    shutil.copy(folder / "fine-name.binary", folder / f"{stem}.binary")
    with pytest.raises(db.DatabaseError) as e:
        db.database_from_folder(folder)
    msg = str(e.value)
    assert f"{stem}.binary" in msg and problem in msg and "ASCII letters, digits" in msg


def test_check_material_name() -> None:
    for good in ("alum-bronze", "a.b_c+d-1", "X" * db.MAX_NAME_LENGTH, "9lives"):
        assert db.check_material_name(good, "test_materials") == good
    for bad in ("", "a/b", "a b", "a{b}", "ü", "_x", "x" * (db.MAX_NAME_LENGTH + 1), "a\n"):
        with pytest.raises(db.DatabaseError, match=r"^test_materials: material name"):
            db.check_material_name(bad, "test_materials")
    # the longest temporary sibling of a store row fits in a file name
    longest = f".{'x' * db.MAX_NAME_LENGTH}.zarr.tmp-{2**22}-{'f' * 8}"
    assert len(longest.encode()) < 255


# --------------------------------------------------------------------------
# Atomic writes and import weight
# --------------------------------------------------------------------------


def test_write_splits_is_atomic_and_uses_no_fixed_tmp_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import brdfpipe.data.store

    class _Store:
        materials = ("a", "b", "c")
        database = "merl"

    monkeypatch.setattr(brdfpipe.data.store, "open_store", lambda path: _Store())
    out = tmp_path / "splits.json"
    other = tmp_path / ".splits.json.tmp"  # the old fixed name: another writer's file
    other.write_text("someone else's")
    db.write_splits(out, store=tmp_path / "s.zarr", test=["b"])
    doc = json.loads(out.read_text())
    assert doc["test"] == ["b"] and doc["train"] == ["a", "c"] and doc["database"] == "merl"
    assert other.read_text() == "someone else's"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".splits.json.tmp", "splits.json"]


def test_write_merl_leaves_no_temporary_and_keeps_the_old_file_on_error(tmp_path: Path) -> None:
    path = tmp_path / "m.binary"
    merl.write_merl(path, _measured_table())
    before = path.read_bytes()
    with pytest.raises(ValueError, match="shape"):
        merl.write_merl(path, np.zeros((3, 2)))
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.binary"]
    assert (path.stat().st_mode & 0o777) == 0o644


def test_parse_time_modules_do_not_import_scipy_zarr_matplotlib() -> None:
    code = (
        "import sys, brdfpipe.data.database as d; d.synthetic_database('x', 100, 1); "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'zarr', 'matplotlib'}))"
    )
    src = str(Path(db.__file__).resolve().parents[2])
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": src, "PATH": "/usr/bin:/bin"})
    assert res.stdout.strip() == "[]"


# --------------------------------------------------------------------------
# synth never writes over what it did not write
# --------------------------------------------------------------------------


def test_synth_refuses_a_foreign_folder(tmp_path: Path) -> None:
    out = tmp_path / "data"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(atomic.OutputError, match="no synthetic manifest.json"):
        synth.synthesize(out, count=1, seed=0, progress=False)
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    (tmp_path / "file").write_text("x")
    with pytest.raises(atomic.OutputError, match="not a folder"):
        synth.synthesize(tmp_path / "file", count=1, seed=0, progress=False)


def test_synth_refuses_to_overwrite_a_foreign_file_of_a_planned_name(synth_dir: Path, tmp_path: Path) -> None:
    folder = _copy(synth_dir, tmp_path / "copy")
    target = folder / f"{synth.plan_database(COUNT, SEED)[0].name}.binary"
    merl.write_merl(target, _measured_table())  # a real-looking file under a planned name
    before = target.read_bytes()
    with pytest.raises(atomic.OutputError, match=f"{target.name} not written by `brdfpipe synth`"):
        synth.synthesize(folder, count=COUNT, seed=SEED, progress=False)
    assert target.read_bytes() == before


def test_synth_refuses_to_mix_two_plans(synth_dir: Path, tmp_path: Path) -> None:
    folder = _copy(synth_dir, tmp_path / "copy")
    with pytest.raises(atomic.OutputError, match="not materials of this database"):
        synth.synthesize(folder, count=1, seed=SEED + 1, progress=False)


def test_synth_rewrites_its_own_output(tmp_path: Path) -> None:
    out = tmp_path / "db"
    synth.synthesize(out, count=1, seed=2, progress=False)
    first = {p.name: p.read_bytes() for p in out.iterdir() if p.suffix == ".binary"}
    synth.synthesize(out, count=1, seed=2, progress=False)
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.suffix == ".binary"} == first
    assert db.database_from_folder(out).kind == "synthetic"


# -- consumers check identity: the renders and captures read the marks before any work -----------


def _fit_table(path: Path, name: str, value: float) -> Path:
    from brdfpipe.data import provenance

    mark = provenance.fit_mark(database="merl-nbrdf", name=name, fit=name.replace("-", "_"), archive="a.zip",
                               fit_sha256="0" * 64, clamped=0)
    merl.write_merl(path, _measured_table(value), mark=mark)
    return path


def test_a_table_renamed_over_another_materials_file_is_refused_by_renders_and_captures(tmp_path: Path) -> None:
    """A batch rendered a table renamed over another material's file as that material: now it is refused, by name."""
    from brdfpipe.data import provenance
    from brdfpipe.rendering import capture, scene

    blue = _fit_table(tmp_path / "blue-fabric.binary", "blue-fabric", 0.1)
    green = tmp_path / "green-fabric.binary"
    shutil.copyfile(blue, green)  # blue-fabric's table under green-fabric's name
    kw = dict(outs=[[tmp_path / "b.exr", tmp_path / "g.exr"]], outs_one=[[tmp_path / "b1.exr", tmp_path / "g1.exr"]],
              materials=["blue-fabric", "green-fabric"], settings=[((8, 6), 4)], envmap=tmp_path / "none.exr",
              variant="llvm_ad_rgb", max_depth=2, seed=0)
    with pytest.raises(provenance.ProvenanceError, match=r"green-fabric.binary: is merl-nbrdf material 'blue-fabric'.*"
                                                         r"not 'green-fabric'"):
        scene.render_materials([blue, green], database="merl-nbrdf", **kw)
    # the right tables, of another database than the run's: refused too
    _fit_table(green, "green-fabric", 0.2)
    with pytest.raises(provenance.ProvenanceError, match="belongs to the rgl-nbrdf database"):
        scene.render_materials([blue, green], database="rgl-nbrdf", **kw)
    assert not any(tmp_path.glob("*.exr"))

    shutil.copyfile(blue, green)
    with pytest.raises(provenance.ProvenanceError, match="not 'green-fabric'"):
        capture.capture_to_files(material=green, name="green-fabric", database="merl-nbrdf", directions=[],
                                 n_images=[1], renders=[], photographs=[], noiseless=[], observations=[], spp=1,
                                 seed=0, light_distance=None, min_snr=1, sensor={})
    with pytest.raises(provenance.ProvenanceError, match="not 'green-fabric'"):
        capture.capture_materials_to_file(materials={"blue-fabric": blue, "green-fabric": green},
                                          database="merl-nbrdf", directions=[], n_images=[1],
                                          out=tmp_path / "obs.npz", spp=1, seed=0, light_distance=None,
                                          min_snr=1, sensor={})
    assert not (tmp_path / "obs.npz").exists()


def test_a_path_point_renamed_over_another_is_refused_by_its_render(tmp_path: Path) -> None:
    from brdfpipe.data import provenance
    from brdfpipe.rendering import scene

    def point(name: str) -> Path:
        mark = provenance.derived_mark(name=name, operation="path-point", source_database="merl-nbrdf", inputs={})
        merl.write_merl(tmp_path / f"{name}.binary", _measured_table(0.3), mark=mark)
        return tmp_path / f"{name}.binary"

    a, b = point("a--b-t0.25"), point("a--b-t0.75")
    shutil.copyfile(a, b)
    with pytest.raises(provenance.ProvenanceError, match=r"a--b-t0.75.binary: is derived material 'a--b-t0.25'"):
        scene.render_points([a, b], outs=[[tmp_path / "x.exr"], [tmp_path / "y.exr"]],
                            outs_one=[[tmp_path / "x1.exr"], [tmp_path / "y1.exr"]], seeds=[0], labels=["p", "q"],
                            derived=True, envmap=tmp_path / "none.exr", variant="llvm_ad_rgb", resolution=(8, 6),
                            spp=4, max_depth=2)
    assert not any(tmp_path.glob("*.exr"))
