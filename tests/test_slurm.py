"""The workflow through a real Slurm (tests/slurm/run_slurm_test.py, make slurm-test).

Runs when a Slurm cluster answers ``sinfo``, or when this process is root with
apt-get (Debian's Slurm is installed and started for the test, then stopped);
skips with the reason otherwise, or when BRDFPIPE_SLURM_TEST=0. The harness
checks, from Slurm's own records, that every non-local job ran as a Slurm job;
the test then checks that the results are byte-identical to a local run: the
session's shared local run of tiny-point (tests/shared_runs.py), which
test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-point] checks too.

The Slurm run takes minutes, nearly all of them waiting on Slurm's queue and
the plug-in's status checks, so it runs beside the suite instead of holding
a pytest worker: the first test (at the front of the collection, see
conftest.py) starts the harness once per session and returns once sbatch has
taken the run's first jobs; the last one waits for the harness and compares.
Either test alone starts the harness when no test of the session has.
"""

from __future__ import annotations

import fcntl
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from shared_runs import SHARED_PREFIX, shared_root, shared_run

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT / "tests" / "slurm" / "run_slurm_test.py"
TINY_POINT = ROOT / "tests" / "config" / "tiny-point.yaml"
SUBMITTED = "has been submitted with SLURM jobid"

pytestmark = pytest.mark.slow


def _slurm_answers() -> bool:
    if not shutil.which("sinfo"):
        return False
    try:
        return subprocess.run(["sinfo", "-h"], capture_output=True, timeout=15).returncode == 0
    except subprocess.TimeoutExpired:
        return False


def _harness():
    spec = importlib.util.spec_from_file_location("run_slurm_test", HARNESS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _alive(pid: int) -> bool:
    """Whether process ``pid`` is running (a zombie, whose parent has not reaped it, is not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


class Harness:
    """The session's background Slurm run: its folder, its process and what it has written so far."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.scratch, self.summary_file, self.output = folder / "scratch", folder / "summary.json", folder / "output"

    def pid(self) -> int:
        return int((self.folder / "pid").read_text())

    def summary(self) -> dict | None:
        return json.loads(self.summary_file.read_text()) if self.summary_file.exists() else None

    def submitted(self) -> bool:
        logs = (self.scratch / "slurm" / ".snakemake" / "log").glob("*.snakemake.log")
        return any(SUBMITTED in log.read_text(errors="replace") for log in logs)

    def wait(self, until, timeout: float) -> None:
        """Until ``until()`` holds or the harness has ended (its summary written, or its process gone)."""
        end = time.monotonic() + timeout
        while not until() and self.summary() is None and _alive(self.pid()):
            if time.monotonic() > end:
                pytest.fail(f"the Slurm harness took more than {timeout:.0f} s; its output: {self.output}")
            time.sleep(1)

    def ended(self) -> dict:
        """The harness's summary; a harness that ended without one fails the test with its output."""
        summary = self.summary()
        if summary is None:
            time.sleep(2)  # the summary is written just before the process exits
            summary = self.summary()
        if summary is None:
            pytest.fail(f"the Slurm harness ended without a summary:\n{self.output.read_text()[-6000:]}")
        if summary.get("exit_status") == 77:
            pytest.skip(summary.get("skipped", "the Slurm harness cannot run here"))
        return summary


def _preconditions() -> None:
    if os.environ.get("BRDFPIPE_SLURM_TEST") == "0":
        pytest.skip("BRDFPIPE_SLURM_TEST=0 turns the Slurm test off")
    if not _slurm_answers():
        if os.geteuid() != 0:
            pytest.skip("no Slurm cluster answers sinfo, and starting one needs root")
        if not shutil.which("apt-get") and not shutil.which("slurmctld"):
            pytest.skip("no Slurm cluster answers sinfo, and there is no apt-get to install one")
    harness = _harness()
    try:
        harness.check_plugin(harness.environment())
    except harness.Skip as why:
        pytest.skip(str(why))


def harness_started(factory: pytest.TempPathFactory) -> Harness:
    """The session's Slurm harness, started in the background by the first caller."""
    _preconditions()
    h = Harness(shared_root(factory) / f"{SHARED_PREFIX}slurm-run")
    h.folder.mkdir(exist_ok=True)
    with open(h.folder / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not (h.folder / "pid").exists():
                with open(h.output, "w") as out:
                    # pytest's process group: Ctrl-C reaches it too, and it stops the daemons it started
                    proc = subprocess.Popen([sys.executable, str(HARNESS), "--scratch", str(h.scratch),
                                             "--config", str(TINY_POINT), "--no-compare",
                                             "--summary", str(h.summary_file)],
                                            stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
                (h.folder / "pid").write_text(str(proc.pid))
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return h


def test_slurm_takes_the_workflows_jobs(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The profile and the plug-in submit the run's first jobs with sbatch (the run goes on beside the suite)."""
    h = harness_started(tmp_path_factory)
    h.wait(h.submitted, timeout=900)  # installing and starting Slurm on a fresh machine: about a minute
    if not h.submitted():
        summary = h.ended()
        pytest.fail(f"the Slurm run submitted no job: {summary}\n{h.output.read_text()[-6000:]}")


def test_workflow_on_slurm_matches_local_run(tmp_path_factory: pytest.TempPathFactory) -> None:
    h = harness_started(tmp_path_factory)
    reference = shared_run(tmp_path_factory, TINY_POINT)
    h.wait(lambda: False, timeout=1800)
    summary = h.ended()
    assert summary.get("ok") and summary.get("exit_status") == 0, (
        f"{summary}\n{h.output.read_text()[-6000:]}")
    assert summary["slurm_jobs"] > 0
    compared = _harness().compare_results(Path(summary["results"]), reference / "results")
    assert compared["files_compared"] > 0
    # the localrules stay in the main process (the synthetic manifest's too); everything else ran in Slurm jobs
    assert "write_manifest" in summary["local_rules"]
    assert set(summary["local_rules"]) <= {"all", "write_manifest", "write_splits", "make_envmap",
                                           "plot_acquisition_figures", "plot_manifold_figures",
                                           "plot_render_figures", "compare_spaces", "write_claims",
                                           "summarize_stage_times"}
