"""Kill and resume after a change of config or code: every output as a clean run of the new config and code.

The property (issue 21): after any change of config or code and any
interruption, a resumed run ends with every output byte-identical to a clean
run of the current config and code.  Each test copies the session's shared
tiny run (tests/shared_runs.py), changes the config or the library (a private
copy of it), starts Snakemake, interrupts it at a known point (a line of
Snakemake's log, or a job of the edited library that says so and waits: no
timer), resumes the way a user does, and compares every file under
``results/`` with a reference: a second copy with the same change, run with
``--forcerun`` on the rules the change touches.  The reference does not
depend on how Snakemake judges what is out of date, and it is what a clean
run computes: every other output depends on nothing that changed.

Chains: the closed loop (capture_closedloop → evaluate_closedloop →
plot_closedloop, write_claims) and the manifold candidates
(measure_gplvm_candidate → compare_spaces → plot_manifold_figures,
write_claims).  Interruptions: SIGKILL of the whole process group (then
``--unlock``, or ``.snakemake`` removed, as users clear the lock a killed run
leaves), SIGINT (Ctrl-C), and SIGKILL of Snakemake alone, whose job goes on
after the resumed run (an orphan).

Run-dependent outputs, excluded from the comparison (two clean runs of one
config differ there and nowhere else under ``results/``):
``results/report/stage-times.csv`` and ``.rst``, the wall times per stage
summed from ``benchmarks/``.  The job stamps under ``results/.stamps`` are
the run's bookkeeping, not results: they record how the outputs came about
(a job retried after an interruption has a ``retry`` line there), and are
left out too.

Jobs killed as they start (:func:`run_killing_jobs`), Snakemake going on:
Snakemake records the failed job's input checksums, stamp included, then
removes its outputs, which nothing downstream asks for any more; before a
stamp counted only once its job succeeded, the resumed run left the
closed-loop table and the claims of the old seed in place.
"""

from __future__ import annotations

import contextlib
import filecmp
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from shared_runs import copy_run, run_state, shared_build, shared_run, workflow_env

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "workflow" / "Snakefile"
TINY = ROOT / "tests" / "config" / "tiny.yaml"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")

#: Files under results/ that differ between two clean runs of the same config (wall times).
RUN_DEPENDENT = {"report/stage-times.csv", "report/stage-times.rst"}

pytestmark = pytest.mark.slow


def snakemake_cmd(work: Path, config: Path, *args: str, cores: int = 2) -> list[str]:
    return [str(SNAKEMAKE), "--snakefile", str(SNAKEFILE), "--directory", str(work), "--configfile", str(config),
            "--cores", str(cores), *args]


def run(work: Path, config: Path, env: dict[str, str], *args: str) -> str:
    r = subprocess.run(snakemake_cmd(work, config, *args), cwd=work, env=env, capture_output=True, text=True,
                       timeout=900)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-4000:]
    return out


def _group_gone(pgid: int, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


def _default_sigint() -> None:
    """In the child before exec: SIGINT back to its default action.

    A shell starts a background command (``make test &`` in a script) with
    SIGINT ignored, and an ignored signal stays ignored across exec: Snakemake
    would never see the Ctrl-C this test sends, and the test would wait for
    its watchdog.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_and_kill(work: Path, config: Path, env: dict[str, str], *, sig: int, rule: str | None = None,
                 hold: Path | None = None, cores: int = 2) -> tuple[bool, str]:
    """Run Snakemake and send ``sig`` to its whole process group at a known point.

    The point: when a job of ``rule`` has finished (a line of Snakemake's
    log), or when the file ``hold`` appears (:func:`patched_library`: the
    first job of the edited code wrote its outputs and waits to be killed).
    Returns whether the signal was sent and the run's output, once no
    process of the group is left (the rest get SIGKILL after 60 s), so
    nothing writes afterwards.
    """
    proc = subprocess.Popen(snakemake_cmd(work, config, cores=cores), cwd=work, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True, preexec_fn=_default_sigint)
    killed = threading.Event()

    def kill() -> None:
        if not killed.is_set():
            killed.set()
            os.killpg(proc.pid, sig)

    def watch_hold() -> None:
        while proc.poll() is None and not killed.is_set():
            if hold is not None and hold.exists():
                kill()
            time.sleep(0.1)

    watchdog = threading.Timer(900, lambda: os.killpg(proc.pid, signal.SIGKILL))
    watchdog.start()
    watcher = threading.Thread(target=watch_hold, daemon=True)
    watcher.start()
    finished = re.compile(rf"Finished jobid: \d+ \(Rule: {rule}\)") if rule else None
    lines = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if finished is not None and finished.search(line):
                kill()
        proc.wait(timeout=300)
    finally:
        watchdog.cancel()
        if not _group_gone(proc.pid, 60):
            os.killpg(proc.pid, signal.SIGKILL)
            _group_gone(proc.pid, 30)
    return killed.is_set(), "".join(lines)


def _job_processes(session: int, rule: str) -> list[int]:
    """PIDs of the running jobs of ``rule`` in the process group ``session`` (Snakemake runs a script as
    ``python .snakemake/scripts/tmpXXXX.<rule>.py``)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if os.getpgid(int(proc.name)) != session:
                continue
            argv = (proc / "cmdline").read_bytes().split(b"\0")
        except (OSError, ProcessLookupError):
            continue
        if any(a.decode(errors="replace").endswith(f".{rule}.py") for a in argv):
            found.append(int(proc.name))
    return found


def run_killing_jobs(work: Path, config: Path, env: dict[str, str], *args: str, rule: str,
                     count: int | None = None) -> tuple[int, str]:
    """Run Snakemake and SIGKILL each job of ``rule`` as it starts (the first ``count``; all if None).

    Snakemake itself goes on: it sees the jobs fail, records them, removes
    their outputs and stops.  Returns how many jobs were killed and the
    run's output.
    """
    with open(work / "killed-run.log", "w+") as out:
        proc = subprocess.Popen(snakemake_cmd(work, config, *args), cwd=work, env=env, stdout=out,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True,
                                preexec_fn=_default_sigint)
        killed: set[int] = set()
        end = time.monotonic() + 900
        try:
            while proc.poll() is None and time.monotonic() < end:
                for pid in _job_processes(proc.pid, rule):
                    if pid not in killed and (count is None or len(killed) < count):
                        with contextlib.suppress(ProcessLookupError):
                            os.kill(pid, signal.SIGKILL)
                        killed.add(pid)
                time.sleep(0.02)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=60)
        out.seek(0)
        return len(killed), out.read()


def results_files(work: Path) -> set[str]:
    results = work / "results"
    files = {p.relative_to(results).as_posix() for p in results.rglob("*") if p.is_file()}
    return {f for f in files if not f.startswith(".stamps/")} - RUN_DEPENDENT


def differences(work: Path, ref: Path) -> list[str]:
    """The files under ``results/`` (the run-dependent ones left out) that differ between two runs, or that one lacks."""
    a, b = results_files(work), results_files(ref)
    diff = a ^ b
    for rel in a & b:
        p, q = work / "results" / rel, ref / "results" / rel
        if not os.path.samefile(p, q) and not filecmp.cmp(p, q, shallow=False):  # hard links of the base: same
            diff.add(rel)
    return sorted(diff)


def changed_config(path: Path, **sections: dict) -> Path:
    """tests/config/tiny.yaml with some keys of some sections changed (key order kept)."""
    cfg = yaml.safe_load(TINY.read_text())
    for section, values in sections.items():
        cfg[section].update(values)
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


#: Environment variables of the edited library (:func:`patched_library`) that hold a job at a known point.
HOLD_AFTER, HOLD_BEFORE = "BRDFPIPE_TEST_HOLD", "BRDFPIPE_TEST_HOLD_BEFORE"


def patched_library(root: Path, module: str, function: str, keyword: str, delta: int) -> dict[str, str]:
    """A private copy of the library whose ``module.function`` adds ``delta`` to its keyword ``keyword``.

    A code change that changes the results (as an edit of the module would;
    ``delta`` 0: a change of the code only); returns the environment that
    runs it.  Two points to kill a run at, each taken by the first call only
    (the others run on): with ``$BRDFPIPE_TEST_HOLD`` set to a path, the call
    creates that file once its outputs are written, then waits to be killed
    (done, but Snakemake does not know: with one core no other job has
    started); with ``$BRDFPIPE_TEST_HOLD_BEFORE``, it creates that file
    before it starts, then waits for the file ``<path>.release``.
    """
    pkg = root / "pkg"
    shutil.copytree(ROOT / "src" / "brdfpipe", pkg / "brdfpipe", ignore=shutil.ignore_patterns("__pycache__"))
    path = pkg / "brdfpipe" / Path(*module.split(".")).with_suffix(".py")
    path.write_text(path.read_text() + f"""

_unpatched_{function} = {function}


def _first_to(flag):
    import os

    try:
        os.close(os.open(flag, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def {function}(**kwargs):  # an edit: {keyword} + {delta}
    import os
    import time

    before = os.environ.get("{HOLD_BEFORE}")
    if before and _first_to(before):
        while not os.path.exists(before + ".release"):
            time.sleep(0.1)
    kwargs["{keyword}"] = kwargs["{keyword}"] + {delta}
    result = _unpatched_{function}(**kwargs)
    after = os.environ.get("{HOLD_AFTER}")
    if after and _first_to(after):
        while True:
            time.sleep(1)
    return result
""")
    return {**os.environ, "PYTHONPATH": str(pkg)}


def build_reference(base: Path, ref: Path, *, config: Path, env: dict[str, str], forcerun: list[str],
                    changed: str) -> None:
    """The reference: at ``ref``, a copy of ``base`` run with the change and ``--forcerun`` on ``forcerun``."""
    copy_run(base, ref)
    run(ref, config, env, "--forcerun", *forcerun)
    assert not filecmp.cmp(ref / "results" / changed, base / "results" / changed, shallow=False), (
        f"the change leaves {changed} as it was: it tests nothing")


def swap_reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """closed_loop.seed and .spp swapped: the config (one path, for the front page) and its reference, once a session."""
    base = shared_run(tmp_path_factory, TINY)

    def build(folder: Path) -> None:
        closed = yaml.safe_load(TINY.read_text())["closed_loop"]
        config = changed_config(folder / "changed.yaml", closed_loop={"seed": closed["spp"], "spp": closed["seed"]})
        build_reference(base, folder / "reference", config=config, env=workflow_env(),
                        forcerun=["capture_closedloop", "write_claims"], changed="evaluation/closedloop.csv")

    folder = shared_build(tmp_path_factory, "reference-closed-loop-swap", build)
    return folder / "changed.yaml", folder / "reference"


def check_same(work: Path, ref: Path, *, config: Path, env: dict[str, str], log: str) -> None:
    """``work`` has every output of ``ref`` (byte for byte), and a dry run of it has nothing to do."""
    diff = differences(work, ref)
    assert not diff, f"{len(diff)} files under results/ differ from a clean run of the change: {diff[:20]}\n{log}"
    again = run(work, config, env, "-n")
    assert "Nothing to be done" in again, again[-3000:]


def check_resume(tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, *, config: Path, env: dict[str, str],
                 sig: int, after_kill: str, changed: str, forcerun: list[str] | None = None, ref: Path | None = None,
                 rule: str | None = None, hold: bool = False, cores: int = 2) -> None:
    """Kill a run of the change at a known point, resume it, compare it with the reference.

    The reference: ``ref`` (built already), or one built here with ``forcerun``.
    """
    base = shared_run(tmp_path_factory, TINY)
    before = run_state(base)
    work = copy_run(base, tmp_path / "resumed")

    held = tmp_path / "held" if hold else None
    run_env = {**env, HOLD_AFTER: str(held)} if held else env
    killed, out = run_and_kill(work, config, run_env, sig=sig, rule=rule, hold=held, cores=cores)
    if after_kill == "unlock":
        run(work, config, env, "--unlock")
    elif after_kill == "drop-metadata":
        shutil.rmtree(work / ".snakemake")
    resumed = run(work, config, env)

    if ref is None:
        assert forcerun is not None
        ref = tmp_path / "reference"
        build_reference(base, ref, config=config, env=env, forcerun=forcerun, changed=changed)
    check_same(work, ref, config=config, env=env,
               log=f"--- interrupted run:\n{out[-3000:]}\n--- resumed run:\n{resumed[-3000:]}")
    assert killed, f"the run was not interrupted:\n{out[-3000:]}"
    assert run_state(base) == before, "a copy wrote into the shared run through a hard link"


def test_closed_loop_config_change_killed_and_resumed(tmp_path: Path,
                                                      tmp_path_factory: pytest.TempPathFactory) -> None:
    """closed_loop.seed and .spp swapped; SIGKILL after the first capture; --unlock; resume.

    Snakemake's params trigger compares the *set* of a job's parameter
    values: a swap leaves the set as it was, so before job stamps the
    captures were never rerun, while write_claims (whose params hold the
    whole config) was: the front page showed the new config over the old
    closed-loop table and claims.
    """
    config, ref = swap_reference(tmp_path_factory)
    check_resume(tmp_path, tmp_path_factory, config=config, env=workflow_env(), rule="capture_closedloop",
                 sig=signal.SIGKILL, after_kill="unlock", ref=ref, changed="evaluation/closedloop.csv")


def test_closed_loop_code_change_interrupted_and_resumed(tmp_path: Path,
                                                         tmp_path_factory: pytest.TempPathFactory) -> None:
    """An edit of rendering/capture.py that changes the photographs; Ctrl-C once a capture wrote them; resume."""
    env = patched_library(tmp_path, "rendering.capture", "capture_to_files", "seed", 1)
    check_resume(tmp_path, tmp_path_factory, config=TINY, env=env, hold=True, sig=signal.SIGINT,
                 after_kill="none", forcerun=["capture_closedloop"], changed="evaluation/closedloop.csv")


def test_candidates_config_change_interrupted_and_resumed(tmp_path: Path,
                                                          tmp_path_factory: pytest.TempPathFactory) -> None:
    """manifold.path_steps 4 → 3; Ctrl-C after the first candidate's measures; resume."""
    config = changed_config(tmp_path / "changed.yaml", manifold={"path_steps": 3})
    check_resume(tmp_path, tmp_path_factory, config=config, env=workflow_env(), rule="measure_gplvm_candidate",
                 sig=signal.SIGINT, after_kill="none",
                 forcerun=["measure_gplvm_candidate", "analyze_manifold", "write_claims"],
                 changed="manifold/spaces.csv")


def test_candidates_code_change_killed_without_metadata_and_resumed(
        tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """An edit of manifold/fidelity.py; one core, SIGKILL once the first candidate is measured; .snakemake removed.

    Removing ``.snakemake`` (to clear the lock a killed run leaves) drops
    Snakemake's records: before job stamps, an output without a record was
    never rerun on a change of code, so the candidate not yet measured kept
    its old table, and spaces.csv mixed the two codes.
    """
    env = patched_library(tmp_path, "manifold.fidelity", "measure_candidate", "steps", 1)
    check_resume(tmp_path, tmp_path_factory, config=TINY, env=env, hold=True, cores=1, sig=signal.SIGKILL,
                 after_kill="drop-metadata", forcerun=["measure_gplvm_candidate", "compare_spaces"],
                 changed="manifold/spaces.csv")


def test_closed_loop_orphan_of_an_interrupted_run_writes_nothing_over_the_resumed_run(
        tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """A capture of the old definition outlives its run and ends after the resumed run of the new one.

    The run of the old definition (tiny; the captures forced, one core) is
    killed alone (SIGKILL to the Snakemake process, as when its node or
    terminal goes): its capture job, held before it starts, is orphaned.
    closed_loop.seed and .spp are swapped, the lock removed, the run resumed
    to its end; then the orphan goes on.  Before the job lease it put its
    photographs and tables over the resumed run's, and the next run fed them
    to evaluate_closedloop.  With it, it stops at its first rename; what its
    Snakemake removes on failing, the next run makes again.
    """
    config, ref = swap_reference(tmp_path_factory)
    base = shared_run(tmp_path_factory, TINY)
    before = run_state(base)
    work = copy_run(base, tmp_path / "resumed")
    old = patched_library(tmp_path, "rendering.capture", "capture_to_files", "seed", 0)
    held = tmp_path / "held"
    first = tmp_path / "first-run.log"  # the orphan's output goes on to it
    with open(first, "w") as fh:
        proc = subprocess.Popen(snakemake_cmd(work, TINY, "--forcerun", "capture_closedloop", cores=1), cwd=work,
                                env={**old, HOLD_BEFORE: str(held)}, stdout=fh, stderr=subprocess.STDOUT,
                                start_new_session=True)
    env = workflow_env()
    try:
        end = time.monotonic() + 600
        while not held.exists() and proc.poll() is None and time.monotonic() < end:
            time.sleep(0.1)
        assert held.exists(), "no capture started"
        os.kill(proc.pid, signal.SIGKILL)  # Snakemake alone: its job goes on
        proc.wait(timeout=60)
        run(work, config, env, "--unlock")
        resumed = run(work, config, env)
        Path(f"{held}.release").touch()  # the orphan goes on
        assert _group_gone(proc.pid, 600), "the orphaned capture did not end"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    after = run(work, config, env)
    check_same(work, ref, config=config, env=env,
               log=f"--- resumed run:\n{resumed[-3000:]}\n--- the run after the orphan:\n{after[-3000:]}")
    orphan = first.read_text()
    assert "this job was started again by a newer run" in orphan, orphan[-3000:]
    assert run_state(base) == before, "a copy wrote into the shared run through a hard link"


def test_a_change_snakemake_cannot_see_replans_its_jobs(tmp_path: Path,
                                                        tmp_path_factory: pytest.TempPathFactory) -> None:
    """acquisition.eta 40 → 7 on tiny: optimize_directions' values stay the set {…, 40, 7} (candidates, seed).

    Before job stamps Snakemake replanned the evaluations (whose params changed
    visibly) over the ten direction sets optimised with η = 40; a dry run now
    plans every job that reads η.
    """
    base = shared_run(tmp_path_factory, TINY)
    acq = yaml.safe_load(TINY.read_text())["acquisition"]
    assert (acq["eta"], acq["candidates"], acq["seed"]) == (40, 40, 7)  # what makes the change invisible
    work = copy_run(base, tmp_path / "work")
    config = changed_config(tmp_path / "changed.yaml", acquisition={"eta": 7})
    before = run_state(work)
    out = run(work, config, workflow_env(), "-n", "--quiet", "rules")
    assert run_state(work) == before  # a dry run writes nothing under results/
    planned = {line.split()[0]: int(line.split()[1]) for line in out.splitlines()
               if len(line.split()) == 2 and line.split()[1].isdigit()}
    assert planned.get("optimize_directions") == 10, out[-3000:]  # point: 3 metrics, Nielsen's κ included
    assert {"evaluate_directions", "capture_closedloop", "evaluate_closedloop"} <= set(planned), out[-3000:]


def check_killed_jobs_resume(tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, *, config: Path,
                             ref: Path, rule: str, args: tuple[str, ...] = (), count: int | None = None,
                             at_least: int = 1) -> None:
    """Kill the jobs of ``rule`` as they start in a run of ``config`` with ``args``; resume plainly; compare."""
    base = shared_run(tmp_path_factory, TINY)
    before = run_state(base)
    work = copy_run(base, tmp_path / "resumed")
    env = workflow_env()
    killed, out = run_killing_jobs(work, config, env, *args, rule=rule, count=count)
    assert killed >= at_least, f"{killed} jobs of {rule} were killed:\n{out[-3000:]}"
    assert "Error in rule" in out or "error" in out.lower(), out[-3000:]
    resumed = run(work, config, env)
    check_same(work, ref, config=config, env=env,
               log=f"--- run with {killed} {rule} jobs killed:\n{out[-3000:]}\n--- resumed run:\n{resumed[-3000:]}")
    assert run_state(base) == before, "a copy wrote into the shared run through a hard link"


def test_closed_loop_config_change_with_its_captures_killed_as_they_start(
        tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """closed_loop.seed and .spp swapped; with --keep-going every capture job starts and is killed; resumed.

    Before: the resumed run ran write_claims alone, ``results/closedloop/``
    stayed empty and the closed-loop table and claims were the old seed's.
    """
    config, ref = swap_reference(tmp_path_factory)
    check_killed_jobs_resume(tmp_path, tmp_path_factory, config=config, ref=ref, rule="capture_closedloop",
                             args=("--keep-going",), at_least=3)


def test_forced_captures_killed_as_they_start_are_made_again(tmp_path: Path,
                                                           tmp_path_factory: pytest.TempPathFactory) -> None:
    """-R capture_closedloop with two of its three jobs killed; a plain run after it makes their files again."""
    base = shared_run(tmp_path_factory, TINY)
    check_killed_jobs_resume(tmp_path, tmp_path_factory, config=TINY, ref=base, rule="capture_closedloop",
                             args=("-R", "capture_closedloop"), count=2, at_least=2)


def test_forced_candidates_killed_before_compare_spaces_are_made_again(
        tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """-R measure_gplvm_candidate --until compare_spaces, its jobs killed as they start; then a plain run."""
    base = shared_run(tmp_path_factory, TINY)
    check_killed_jobs_resume(tmp_path, tmp_path_factory, config=TINY, ref=base, rule="measure_gplvm_candidate",
                             args=("-R", "measure_gplvm_candidate", "--until", "compare_spaces"))
