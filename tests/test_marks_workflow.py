"""The workflow's data stage checks every synthetic file against its name and the configuration.

Before provenance marks, a file copied over another inside ``results/synthetic/``
was re-ingested under the wrong name and changed a store row with exit 0.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from brdfpipe.data import provenance, store
from shared_runs import shared_run, workflow_env

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
TINY_POINT = ROOT / "tests" / "config" / "tiny-point.yaml"

pytestmark = pytest.mark.slow


def _data_stage(workdir: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [str(SNAKEMAKE), "--snakefile", str(ROOT / "workflow" / "Snakefile"), "--directory", str(workdir),
           "--configfile", str(TINY_POINT), "--cores", "2", *args, "results/merl.zarr"]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=workdir, env=workflow_env(), timeout=900)


def test_a_synthetic_file_copied_over_another_fails_the_data_stage(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    # the data stage of the session's shared tiny-point run (tests/shared_runs.py), copied with its
    # metadata, job stamps and times: nothing is left to do until a file changes
    shared = shared_run(tmp_path_factory, TINY_POINT)
    for part in (".snakemake", "results/.stamps", "results/synthetic", "results/merl.zarr"):
        shutil.copytree(shared / part, tmp_path / part, symlinks=True)
    r = _data_stage(tmp_path, "-n")
    assert r.returncode == 0 and "Nothing to be done" in r.stdout + r.stderr, (r.stdout + r.stderr)[-3000:]
    st_path = tmp_path / "results" / "merl.zarr"
    st = store.open_store(st_path)
    assert st.database == "synthetic"
    a, b = st.materials[0], st.materials[1]
    before = {p.relative_to(st_path): p.read_bytes() for p in st_path.rglob("*") if p.is_file()}
    folder = tmp_path / "results" / "synthetic"
    shutil.copyfile(folder / f"{b}.binary", folder / f"{a}.binary")
    r = _data_stage(tmp_path)
    assert r.returncode != 0
    log = (tmp_path / "logs" / "ingest_material" / f"{a}.log").read_text()
    assert f"{a}.binary" in log and f"synthetic material {b!r}" in log and f"not {a!r}" in log, log
    after = {p.relative_to(st_path): p.read_bytes() for p in st_path.rglob("*") if p.is_file()}
    assert after == before  # the store still holds A's row, untouched
    mark = provenance.read_mark(folder / f"{a}.binary")
    assert mark is not None and mark.name == b
