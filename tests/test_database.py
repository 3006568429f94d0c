"""Resolution of the configured database and of the held-out materials."""

from __future__ import annotations

from pathlib import Path

import pytest

from brdfpipe.data import database as db


def _touch_merl(folder: Path, names: list[str]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for n in names:
        (folder / f"{n}.binary").write_bytes(b"")


def test_merl_folder_lists_binary_files(tmp_path: Path) -> None:
    _touch_merl(tmp_path, ["b-mat", "a-mat"])
    (tmp_path / "notes.txt").write_text("not a material")
    d = db.database_from_folder(tmp_path)
    assert d.kind == "merl"
    assert d.materials == ["a-mat", "b-mat"]
    assert d.sources["a-mat"] == (tmp_path / "a-mat.binary").resolve()


def test_merl_folder_errors_name_the_folder(tmp_path: Path) -> None:
    with pytest.raises(db.DatabaseError, match="does not exist") as e:
        db.database_from_folder(tmp_path / "nope")
    assert "nope" in str(e.value)
    (tmp_path / "file").write_text("x")
    with pytest.raises(db.DatabaseError, match="not a folder"):
        db.database_from_folder(tmp_path / "file")
    (tmp_path / "empty").mkdir()
    with pytest.raises(db.DatabaseError, match="no MERL files"):
        db.database_from_folder(tmp_path / "empty")


def test_real_merl_default_test_set_is_xu2016_plus_one(tmp_path: Path) -> None:
    names = [*db.XU2016_TEST_MATERIALS, db.EXTRA_TEST_MATERIAL, "gold-paint", "teflon"]
    _touch_merl(tmp_path, names)
    d = db.database_from_folder(tmp_path)
    test = db.resolve_test_materials(None, d)
    assert len(test) == 10
    assert set(db.XU2016_TEST_MATERIALS) <= set(test)
    assert db.EXTRA_TEST_MATERIAL in test


def test_unknown_test_material_is_named(tmp_path: Path) -> None:
    _touch_merl(tmp_path, ["a", "b", "c"])
    d = db.database_from_folder(tmp_path)
    with pytest.raises(db.DatabaseError, match="unknown material.*zzz"):
        db.resolve_test_materials(["a", "zzz"], d)
    with pytest.raises(db.DatabaseError, match="more than once"):
        db.resolve_test_materials(["a", "a"], d)
    with pytest.raises(db.DatabaseError, match="none is left to train"):
        db.resolve_test_materials(["a", "b", "c"], d)
    # the real-MERL default names materials this partial folder lacks
    with pytest.raises(db.DatabaseError, match="default test_materials"):
        db.resolve_test_materials(None, d)
    assert db.resolve_test_materials(["c", "a"], d) == ["a", "c"]


def test_synthetic_database_plan(tmp_path: Path) -> None:
    d = db.synthetic_database(tmp_path, 12, 7)
    assert d.kind == "synthetic" and len(d.materials) == 12
    test = db.resolve_test_materials(None, d)
    assert len(test) == db.default_test_count(12) == 3
    assert all(d.sources[m].parent == tmp_path for m in d.materials)
    assert db.default_test_count(100) == 10


def test_select_materials_by_name_and_pattern() -> None:
    full = db.synthetic_database("unused", 40, 3)
    metals = [n for n in full.materials if n.startswith("metal-")]
    sub = db.select_materials(full, ["metal-*", full.materials[-1]])
    assert sub.kind == full.kind and sub.materials == sorted({*metals, full.materials[-1]})
    assert set(sub.default_test) == set(full.default_test) & set(sub.materials)
    assert db.select_materials(full, None) is full
    with pytest.raises(db.DatabaseError, match=r"materials: 'no-such-\*' match"):
        db.select_materials(full, ["metal-*", "no-such-*"])


def test_a_material_named_like_the_mean_rows_is_refused(tmp_path: Path) -> None:
    """errors.csv, closedloop.csv and training_size.csv call their mean rows material 'mean'."""
    _touch_merl(tmp_path, ["alpha", "mean"])
    with pytest.raises(db.DatabaseError, match=r"mean\.binary: material name 'mean' is reserved") as e:
        db.database_from_folder(tmp_path)
    assert "\n" not in str(e.value)
    assert db.check_material_name("meaning", "x") == "meaning"
