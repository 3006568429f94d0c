"""Workflow runs that several tests read, built once per test session.

`make test` runs pytest under xdist (`-n 2`): each worker is its own process,
so a session fixture alone would build the same run once per worker.  The
first caller builds the run under an exclusive ``flock`` in the session's
shared temporary folder; the others wait for it and read the same folder.
A build that failed fails every test that asks for it, with the build's
output.  Readers must not write into the run: copy it first (:func:`copy_run`).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "workflow" / "Snakefile"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")


#: The names of the session's shared folders start with this: tests/conftest.py never removes them mid-session.
SHARED_PREFIX = "shared-"


def shared_root(factory: pytest.TempPathFactory) -> Path:
    base = factory.getbasetemp()
    # under xdist each worker's basetemp is <session>/popen-gwN; the session folder is shared
    return base.parent if base.name.startswith("popen-gw") else base


def workflow_env() -> dict[str, str]:
    """The environment of a shared run: this checkout's library first (as the Slurm harness does)."""
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), *paths])}


def shared_run(factory: pytest.TempPathFactory, config: Path, *, cores: int = 2, timeout: int = 900) -> Path:
    """The working directory of a finished local run of ``config`` (built by the first caller)."""
    folder = shared_root(factory) / f"{SHARED_PREFIX}{config.stem}"
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


def shared_build(factory: pytest.TempPathFactory, name: str, build: Callable[[Path], None]) -> Path:
    """A folder that ``build(folder)`` fills once per session (the first caller builds, under a lock).

    A build that raised fails every caller, with its message.  Readers must
    not write into the folder.
    """
    folder = shared_root(factory) / f"{SHARED_PREFIX}{name}"
    folder.mkdir(exist_ok=True)
    work, status = folder / "work", folder / "status.json"
    with open(folder / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not status.exists():
                work.mkdir(exist_ok=True)
                try:
                    build(work)
                    result = {"ok": True}
                except BaseException as err:  # recorded for the other callers, then raised here
                    status.write_text(json.dumps({"ok": False, "error": f"{type(err).__name__}: {err}"[-4000:]}))
                    raise
                status.write_text(json.dumps(result))
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    result = json.loads(status.read_text())
    if not result["ok"]:
        pytest.fail(f"the shared build {name} failed: {result['error']}")
    return work


def _link_or_copy(src: str, dst: str) -> None:
    try:
        os.link(src, dst)
    except OSError:  # another file system
        shutil.copy2(src, dst)


def copy_run(src: Path, dst: Path) -> Path:
    """A private copy of the run ``src`` at ``dst`` (created or empty) that a test may run Snakemake in.

    ``results/`` is copied as hard links (the run is 1.4 GB): every writer
    replaces a file by renaming a new one over it and Snakemake deletes an
    output before it runs the job again, so no file of ``src`` is written
    through a link.  Everything else (``.snakemake``, whose records Snakemake
    rewrites in place, logs, benchmarks) is copied.  Modification times are
    kept.  :func:`run_state` of ``src`` before and after tells whether a
    test wrote through a link after all.
    """
    dst.mkdir(parents=True, exist_ok=True)
    for entry in src.iterdir():
        target = dst / entry.name
        if entry.name == "results":
            shutil.copytree(entry, target, symlinks=True, copy_function=_link_or_copy, dirs_exist_ok=True)
        elif entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, target, symlinks=True, dirs_exist_ok=True)
        else:
            shutil.copy2(entry, target, follow_symlinks=False)
    return dst


def run_state(work: Path) -> dict[str, tuple[int, int]]:
    """``(size, mtime_ns)`` of every file under ``work/results`` (to check that copies left the run alone)."""
    results = work / "results"
    return {p.relative_to(results).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in results.rglob("*") if p.is_file() and not p.is_symlink()}
