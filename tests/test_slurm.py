"""The workflow through a real Slurm (tests/slurm/run_slurm_test.py, make slurm-test).

Runs when a Slurm cluster answers ``sinfo``, or when this process is root with
apt-get (Debian's Slurm is installed and started for the test, then stopped);
skips with the reason otherwise, or when BRDFPIPE_SLURM_TEST=0. The harness
checks, from Slurm's own records, that every non-local job ran as a Slurm job,
and that the results are byte-identical to a local run: the session's shared
local run of tiny-point (tests/shared_runs.py), which
test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-point] checks too.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from shared_runs import shared_run

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT / "tests" / "slurm" / "run_slurm_test.py"
TINY_POINT = ROOT / "tests" / "config" / "tiny-point.yaml"

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


def test_workflow_on_slurm_matches_local_run(tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
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
    except harness.Skip as why:  # before the shared run is built for nothing
        pytest.skip(str(why))
    reference = shared_run(tmp_path_factory, TINY_POINT)
    proc = subprocess.Popen([sys.executable, str(HARNESS), "--scratch", str(tmp_path), "--config", str(TINY_POINT),
                             "--reference", str(reference)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        stdout, stderr = proc.communicate(timeout=1800)
    except BaseException:
        proc.terminate()  # SIGTERM: the harness stops the daemons it started
        proc.communicate(timeout=120)
        raise
    r = subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)
    out = r.stdout + r.stderr
    summary = json.loads(r.stdout.strip().splitlines()[-1]) if r.stdout.strip() else {}
    if r.returncode == 77:
        pytest.skip(summary.get("skipped", out[-500:]))
    assert r.returncode == 0, out[-6000:]
    assert summary["ok"] and summary["slurm_jobs"] > 0 and summary["files_compared"] > 0
    assert summary["reference"] == str(reference)
    # the localrules stay in the main process; everything else ran inside Slurm jobs
    assert set(summary["local_rules"]) <= {"all", "write_manifest", "write_splits", "make_envmap",
                                           "plot_acquisition_figures", "plot_manifold_figures",
                                           "plot_render_figures", "compare_spaces", "write_claims",
                                           "summarize_stage_times"}
