"""Workflow runs that several tests read, built once per test session.

`make test` runs pytest under xdist (`-n 2`): each worker is its own process,
so a session fixture alone would build the same run once per worker.  The
first caller builds the run under an exclusive ``flock`` in the session's
shared temporary folder; the others wait for it and read the same folder.
A build that failed fails every test that asks for it, with the build's
output.  Readers must not write into the run: copy it first.
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "workflow" / "Snakefile"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")


def _shared_root(factory: pytest.TempPathFactory) -> Path:
    base = factory.getbasetemp()
    # under xdist each worker's basetemp is <session>/popen-gwN; the session folder is shared
    return base.parent if base.name.startswith("popen-gw") else base


def workflow_env() -> dict[str, str]:
    """The environment of a shared run: this checkout's library first (as the Slurm harness does)."""
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), *paths])}


def shared_run(factory: pytest.TempPathFactory, config: Path, *, cores: int = 2, timeout: int = 900) -> Path:
    """The working directory of a finished local run of ``config`` (built by the first caller)."""
    folder = _shared_root(factory) / f"shared-{config.stem}"
    folder.mkdir(exist_ok=True)
    work, status = folder / "work", folder / "status.json"
    with open(folder / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not status.exists():
                work.mkdir(exist_ok=True)
                cmd = [str(SNAKEMAKE), "--snakefile", str(SNAKEFILE), "--directory", str(work),
                       "--configfile", str(config), "--cores", str(cores)]
                try:
                    r = subprocess.run(cmd, capture_output=True, text=True, cwd=work, env=workflow_env(),
                                       timeout=timeout)
                    result = {"returncode": r.returncode, "tail": (r.stdout + r.stderr)[-4000:]}
                except subprocess.TimeoutExpired:
                    result = {"returncode": -1, "tail": f"timed out after {timeout} s"}
                status.write_text(json.dumps(result))
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    result = json.loads(status.read_text())
    if result["returncode"] != 0:
        pytest.fail(f"the shared run of {config.name} failed ({result['returncode']}):\n{result['tail']}")
    return work
