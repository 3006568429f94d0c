"""One material-name rule for every writer (issue 31): ``brdfpipe nbrdf``, ``brdfpipe synth`` and the workflow.

Each applies :func:`brdfpipe.data.databases.check_material_name` (exported by
:mod:`brdfpipe.data.database` too) before it writes anything, as the labeller of
folders (``brdfpipe ingest``, ``merl_dir``) does (tests/test_provenance.py); and a
shipped database's name that is also a local path is refused as ambiguous.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import pytest

from brdfpipe import cli
from brdfpipe.data import database

ARCHIVES = Path(__file__).resolve().parents[1] / "src" / "brdfpipe" / "data" / "archives"
NIELSEN = ARCHIVES / "nielsen_nbrdf.zip"


@pytest.mark.parametrize("member,problem", [
    ("x/.h5", "is empty"),
    ("x/.hidden.h5", "starts with '.'"),
    ("x/$(touch pwned).h5", "contains ' ', '$', '(', ')'"),
    ("x/-rf.h5", "starts with '-'"),
    ("x/<b>bold<b>.h5", "contains '<', '>'"),
    ("x/mean.h5", "is reserved"),
])
def test_nbrdf_applies_the_material_name_rule_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], member: str, problem: str
) -> None:
    with zipfile.ZipFile(NIELSEN) as z:
        good = z.read("nielsen_nbrdf/cardboard.h5")
    archive = tmp_path / "fits.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("x/cardboard.h5", good)
        z.writestr(member, good)
    out = tmp_path / "out"
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert f"{archive}:{member}: material name" in err and problem in err and "\n" not in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["fits.zip"]
    with pytest.raises(database.DatabaseError, match=f"nbrdf_archive {archive}:"):
        database.configured_database({"database": "nbrdf", "nbrdf_archive": str(archive)})


def test_a_database_name_that_is_also_a_local_path_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "nielsen-nbrdf").mkdir()
    out = tmp_path / "out"
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "both" in err and "./nielsen-nbrdf" in err and str(NIELSEN) in err
    assert not out.exists()
    # the path, spelled as one, is the local folder (empty here: no fits)
    assert cli.main(["-q", "nbrdf", "./nielsen-nbrdf", "--out", str(out)]) == 1
    assert "no NBRDF fits" in capsys.readouterr().err
    os.rmdir(tmp_path / "nielsen-nbrdf")
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(out), "cardboard"]) == 0


def test_synth_and_the_workflow_apply_the_material_name_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A generator bug making a name outside the rule stops ``synth`` and the parse before anything is written."""
    from brdfpipe.data import synth

    monkeypatch.setitem(synth._PLANNERS, "metal", lambda rng, j: ("$(rm -rf)", {}))
    out = tmp_path / "syn"
    assert cli.main(["-q", "synth", "--count", "12", "--seed", "1", "--out", str(out), "--jobs", "1"]) == 1
    err = capsys.readouterr().err.strip()
    assert "material name 'metal-$(rm -rf)-" in err and "\n" not in err
    assert not out.exists()
    with pytest.raises(database.DatabaseError, match=r"material name 'metal-\$\(rm -rf\)-"):
        database.configured_database({"database": "synthetic", "synthetic": {"count": 12, "seed": 1}})
