"""The suite's disk: nothing outlives its use (CI's fresh machine ran out of space when the suite kept 28 GB).

A small suite runs with this suite's own conftest.py, shared_runs.py and
pytest settings (pyproject.toml), without xdist, in a basetemp of its own;
then the basetemp is read.  A passing test's ``tmp_path`` and a module's
folders are gone; a shared folder (tests/shared_runs.py's names) stays to the
session's end even though, without xdist, it sits beside the modules'
folders; a failed test's folder stays for inspection.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

MODULE_A = '''
import pytest
from shared_runs import shared_root


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("module-a-data")
    (d / "big.bin").write_bytes(b"x" * 1000)
    return d


def test_uses_module_data(data, tmp_path):
    (tmp_path / "passing.bin").write_bytes(b"y")
    assert (data / "big.bin").exists()


def test_makes_a_shared_folder(tmp_path_factory):
    folder = shared_root(tmp_path_factory) / "shared-run-x"
    folder.mkdir()
    (folder / "status.json").write_text("{}")
'''

MODULE_B = '''
import pytest
from shared_runs import shared_root


def test_the_shared_folder_outlives_the_module_that_made_it(tmp_path_factory):
    assert (shared_root(tmp_path_factory) / "shared-run-x" / "status.json").exists()


def test_fails(tmp_path):
    (tmp_path / "evidence.bin").write_bytes(b"z")
    assert False, "this failure is expected: its folder must stay"
'''


def test_a_passing_tests_and_a_modules_folders_are_removed_shared_and_failed_ones_stay(tmp_path: Path) -> None:
    proj = tmp_path / "proj"
    (proj / "tests").mkdir(parents=True)
    shutil.copy(ROOT / "pyproject.toml", proj / "pyproject.toml")
    for name in ("conftest.py", "shared_runs.py"):
        shutil.copy(ROOT / "tests" / name, proj / "tests" / name)
    (proj / "tests" / "test_a.py").write_text(MODULE_A)
    (proj / "tests" / "test_b.py").write_text(MODULE_B)
    base = tmp_path / "basetemp"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                        f"--basetemp={base}", "tests/test_a.py", "tests/test_b.py"],
                       cwd=proj, capture_output=True, text=True, timeout=300)
    out = r.stdout + r.stderr
    assert "1 failed, 3 passed" in out, out[-3000:]
    left = sorted(p.name for p in base.iterdir())
    assert not any(n.startswith("module-a-data") for n in left), left  # the module's folder
    assert not any(n.startswith("test_uses_module_data") for n in left), left  # a passing test's tmp_path
    assert "shared-run-x" in left, left  # lives to the session's end
    failed = [n for n in left if n.startswith("test_fails")]
    assert failed and (base / failed[0] / "evidence.bin").exists(), left
