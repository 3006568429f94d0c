#!/usr/bin/env python3
"""The workflow on a real Slurm, checked against Slurm's records and a local run.

    python tests/slurm/run_slurm_test.py [--config tests/config/tiny-point.yaml] [--reference WORKDIR]

1. Slurm: installs Debian's slurmctld/slurmd/munge when missing and starts a
   single-node cluster (tests/slurm/slurm_cluster.sh), unless `sinfo` already
   answers, in which case that cluster is used.
2. Runs the config with `snakemake --executor slurm --profile profiles/slurm`
   in a scratch directory.
3. Checks from Slurm's own records that every non-local job ran as a Slurm job:
   each sbatch job id in Snakemake's log is known to slurmctld (`scontrol show
   job`, and the job-completion log when this script started the cluster) as
   COMPLETED with exit code 0:0 on a node, under this run's job name; and the
   Slurm job's own output file (StdOut= in slurmctld's record) shows the inner
   Snakemake running exactly the non-local jobs that the main log announced.
4. Runs the same config locally (--cores 2) in another scratch directory and
   compares every file under results/ byte for byte; with --reference, compares
   with that finished local run of the same config instead of running one; with
   --no-compare, leaves the comparison to the caller (the Slurm run's results/
   are in <scratch>/slurm/results).
5. Prints the wall times and their ratio; stops only the daemons it started.

Exit status 0: all checks passed; 1: a check failed; 77: cannot run here (skip).
The last line of output is a JSON summary.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CLUSTER = ROOT / "tests" / "slurm" / "slurm_cluster.sh"
SNAKEFILE = ROOT / "workflow" / "Snakefile"
PROFILE = ROOT / "profiles" / "slurm"
SKIP = 77

BIN = Path(sys.executable).parent  # the virtual environment's bin/: snakemake, python
SNAKEMAKE = BIN / "snakemake"


class Skip(Exception):
    pass


class Failed(Exception):
    pass


def log(msg: str) -> None:
    print(f"[slurm-test] {msg}", flush=True)


# `make slurm-plugins` installs the executor plug-in here, outside site-packages
# (so local runs do not import it); a cluster user's environment may have it
# installed normally instead.
PLUGINS = Path(os.environ.get("BRDFPIPE_SLURM_PLUGINS", BIN.parent / "slurm-plugins"))


def environment() -> dict[str, str]:
    env = dict(os.environ)
    # jobs run `python -m snakemake` again on the node: sbatch exports this
    # environment, so the node finds the same virtual environment and library
    env["PATH"] = os.pathsep.join([str(BIN), env.get("PATH", "/usr/bin:/bin")])
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    extra = [str(PLUGINS)] if PLUGINS.is_dir() else []
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), *extra, *paths])
    return env


def check_plugin(env: dict[str, str]) -> None:
    r = subprocess.run([sys.executable, "-c", "import snakemake_executor_plugin_slurm"],
                       env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise Skip("the Slurm executor plug-in is not installed: run `make slurm-plugins` "
                   "(or pip install the project's `slurm` extra)")


def sh(*cmd: str, env=None, check=True, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, env=env, check=check, timeout=timeout)


# --- Snakemake's log: which jobs were local, which went to Slurm -----------------

HEADER = re.compile(r"^\s*(localrule|rule) (\w+):\s*$")
SUBMITTED = re.compile(r"Job (\S+) has been submitted with SLURM jobid (\d+)")


def announced_jobs(text: str) -> set[tuple[str, str, str]]:
    """(kind, rule, outputs) of every job a Snakemake log announces."""
    jobs, current = set(), None
    for line in text.splitlines():
        m = HEADER.match(line)
        if m:
            if current:
                jobs.add((*current, ""))
            current = (m.group(1), m.group(2))
            continue
        if current and line.strip().startswith("output:"):
            jobs.add((*current, line.strip()[len("output:"):].strip()))
            current = None
    if current:
        jobs.add((*current, ""))
    return jobs


def scontrol_job(jobid: str) -> dict[str, str]:
    r = sh("scontrol", "show", "job", "-o", jobid, check=False)
    if r.returncode != 0:
        return {}
    return dict(kv.split("=", 1) for kv in r.stdout.split() if "=" in kv)


def check_slurm_records(workdir: Path, text: str, jobcomp: Path | None) -> dict:
    submitted = SUBMITTED.findall(text)
    if not submitted:
        raise Failed("Snakemake's log names no sbatch submission")
    names = set()
    inner: set[tuple[str, str, str]] = set()
    completed = {}
    if jobcomp is not None:
        for line in jobcomp.read_text().splitlines():
            rec = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
            completed[rec.get("JobId")] = rec
    for sm_job, slurm_id in submitted:
        rec = scontrol_job(slurm_id)
        if not rec:
            raise Failed(f"slurmctld has no record of job {slurm_id} (Snakemake job {sm_job})")
        if rec.get("JobState") != "COMPLETED" or rec.get("ExitCode") != "0:0":
            raise Failed(f"Slurm job {slurm_id}: JobState={rec.get('JobState')} ExitCode={rec.get('ExitCode')}")
        if not rec.get("BatchHost") or rec.get("NodeList") in (None, "", "(null)"):
            raise Failed(f"Slurm job {slurm_id} ran on no node: {rec}")
        if jobcomp is not None:
            c = completed.get(slurm_id)
            if not c or c.get("JobState") != "COMPLETED":
                raise Failed(f"Slurm job {slurm_id} is not COMPLETED in the job-completion log {jobcomp}")
        names.add(rec.get("JobName"))
        out = Path(rec.get("StdOut", ""))
        if not out.is_file():
            raise Failed(f"Slurm job {slurm_id}: its output file {out} is missing")
        ran = {j for j in announced_jobs(out.read_text()) if j[0] == "rule"}
        if not ran:
            raise Failed(f"Slurm job {slurm_id}: its output {out} shows no job")
        if ran & inner:
            raise Failed(f"jobs ran twice in Slurm: {sorted(ran & inner)}")
        inner |= ran
    if len(names) != 1:
        raise Failed(f"Slurm jobs of one run carry several job names: {names}")
    main = announced_jobs(text)
    remote = {j for j in main if j[0] == "rule"}
    local = {j for j in main if j[0] == "localrule"}
    if inner != remote:
        raise Failed(
            "the jobs run inside Slurm jobs differ from the non-local jobs of the run:\n"
            f"  not in Slurm: {sorted(remote - inner)}\n  only in Slurm: {sorted(inner - remote)}"
        )
    return {
        "slurm_jobs": len(submitted),
        "workflow_jobs_in_slurm": len(inner),
        "local_jobs": len(local),
        "local_rules": sorted({j[1] for j in local}),
        "slurm_job_ids": [int(i) for _, i in submitted],
    }


# --- the runs ---------------------------------------------------------------


def snakemake(workdir: Path, config: Path, *args: str, env: dict, timeout: int) -> tuple[float, str]:
    cmd = [str(SNAKEMAKE), "--snakefile", str(SNAKEFILE), "--directory", str(workdir),
           "--configfile", str(config), *args]
    log(" ".join(cmd))
    t0 = time.monotonic()
    r = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True, timeout=timeout)
    wall = time.monotonic() - t0
    text = r.stdout + r.stderr
    (workdir / "snakemake-run.log").write_text(text)
    if r.returncode != 0:
        raise Failed(f"snakemake failed ({r.returncode}) in {workdir}:\n{text[-4000:]}")
    # Snakemake's complete log of the run (the console, for people, leaves out each job's record)
    return wall, max((workdir / ".snakemake" / "log").glob("*.snakemake.log")).read_text()


#: Files under results/ that differ between runs by nature: the report's wall times per stage.
RUN_DEPENDENT = {Path("report/stage-times.csv"), Path("report/stage-times.rst")}


def compare_results(a: Path, b: Path) -> dict:
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.relative_to(a) not in RUN_DEPENDENT)
    files_b = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file() and p.relative_to(b) not in RUN_DEPENDENT)
    if files_a != files_b:
        raise Failed(f"results/ differ in their files: only Slurm {sorted(set(files_a) - set(files_b))}, "
                     f"only local {sorted(set(files_b) - set(files_a))}")
    differ = [str(f) for f in files_a if not filecmp.cmp(a / f, b / f, shallow=False)]
    if differ:
        raise Failed(f"{len(differ)} of {len(files_a)} files differ between Slurm and local runs: {differ}")
    return {"files_compared": len(files_a)}


def node_limits() -> tuple[int, int]:
    """CPUs and memory (MB) of the smallest node of the default partition."""
    r = sh("sinfo", "-h", "-N", "-o", "%c %m")
    cpus, mems = zip(*(map(int, re.findall(r"\d+", line)[:2]) for line in r.stdout.splitlines() if line.strip()))
    return min(cpus), min(mems)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "tests" / "config" / "tiny-point.yaml")
    ap.add_argument("--scratch", type=Path, default=None, help="keep the run folders here")
    ap.add_argument("--status-interval", type=int, default=2,
                    help="seconds between the plug-in's status checks (the profile's 20 s suits real clusters)")
    ap.add_argument("--profile", type=Path, default=PROFILE,
                    help="the Slurm profile to run with (default: the project's profiles/slurm)")
    ap.add_argument("--timeout", type=int, default=900)
    ap.add_argument("--reference", type=Path, default=None,
                    help="a finished local run (its working directory) of the same config to compare with, "
                         "instead of running one")
    ap.add_argument("--no-compare", action="store_true",
                    help="check Slurm's records only: the caller compares <scratch>/slurm/results with a local run")
    ap.add_argument("--summary", type=Path, default=None,
                    help="also write the JSON summary to this file (once the daemons are stopped)")
    args = ap.parse_args()
    if args.no_compare and args.scratch is None:
        ap.error("--no-compare needs --scratch: the caller reads the Slurm run's results/ there")
    if args.reference is not None and not (args.reference / "results").is_dir():
        ap.error(f"--reference {args.reference}: no results/ folder there (a finished local run of the config)")
    config = args.config.resolve()

    scratch = Path(args.scratch or tempfile.mkdtemp(prefix="brdfpipe-slurm-"))
    scratch.mkdir(parents=True, exist_ok=True)
    state = scratch / "cluster"
    env = environment()
    summary: dict = {"config": str(config.relative_to(ROOT) if config.is_relative_to(ROOT) else config)}
    started = False

    def on_signal(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGHUP, on_signal)
    status = 1
    try:
        check_plugin(env)
        answers = shutil.which("sinfo") and sh("sinfo", "-h", check=False, timeout=15).returncode == 0
        if answers:
            log("sinfo answers: using the running cluster")
        else:
            if os.geteuid() != 0:
                raise Skip("no Slurm cluster answers and starting one needs root")
            if not shutil.which("slurmctld") and not shutil.which("apt-get"):
                raise Skip("no Slurm cluster answers, Slurm is not installed and there is no apt-get")
            r = subprocess.run([str(CLUSTER), "install"], text=True, capture_output=True)
            if r.returncode != 0:
                raise Skip(f"cannot install Slurm: {r.stderr.strip()[-500:]}")
            started = True
            # our cluster's configuration is /etc/slurm/slurm.conf (a link)
            os.environ.pop("SLURM_CONF", None)
            env.pop("SLURM_CONF", None)
            r = subprocess.run([str(CLUSTER), "start", str(state)], text=True, capture_output=True)
            print(r.stdout, end="")
            if r.returncode != 0:
                raise Skip(f"the Slurm daemons cannot start here: {r.stderr.strip()[-800:]}")
        summary["cluster"] = "started by the test" if not answers else "existing"
        cpus, mem = node_limits()
        # group jobs: at most one node's CPUs and most of its memory (local scopes)
        group_args = ["--cores", str(cpus), "--resources", f"mem_mb={int(mem * 0.8)}"]

        slurm_dir, local_dir = scratch / "slurm", scratch / "local"
        for d in (slurm_dir, local_dir):
            shutil.rmtree(d, ignore_errors=True)
            d.mkdir()
        wall_slurm, text = snakemake(
            slurm_dir, config, "--executor", "slurm", "--profile", str(args.profile.resolve()), *group_args,
            "--slurm-init-seconds-before-status-checks", str(args.status_interval),
            "--slurm-keep-successful-logs", env=env, timeout=args.timeout)
        jobcomp = state / "jobcomp.log" if started else None
        summary.update(check_slurm_records(slurm_dir, text, jobcomp))
        log(f"Slurm run: {wall_slurm:.1f} s, {summary['slurm_jobs']} Slurm jobs holding "
            f"{summary['workflow_jobs_in_slurm']} workflow jobs; {summary['local_jobs']} local jobs")

        if args.no_compare:
            summary.update(wall_slurm_s=round(wall_slurm, 1), results=str(slurm_dir / "results"))
        elif args.reference is not None:
            summary.update(compare_results(slurm_dir / "results", args.reference.resolve() / "results"))
            summary.update(reference=str(args.reference), wall_slurm_s=round(wall_slurm, 1))
            log(f"results/: {summary['files_compared']} files, byte-identical to the reference run "
                f"{args.reference}")
        else:
            wall_local, _ = snakemake(local_dir, config, "--cores", "2", env=env, timeout=args.timeout)
            log(f"local run (--cores 2): {wall_local:.1f} s")
            summary.update(compare_results(slurm_dir / "results", local_dir / "results"))
            log(f"results/: {summary['files_compared']} files, byte-identical")
            summary.update(wall_slurm_s=round(wall_slurm, 1), wall_local_s=round(wall_local, 1),
                           ratio=round(wall_slurm / wall_local, 2))
            log(f"wall time Slurm / local = {wall_slurm:.1f} / {wall_local:.1f} = {summary['ratio']:.2f} "
                f"(target <= 2)")
        summary["ok"] = True
        status = 0
    except Skip as err:
        summary.update(ok=False, skipped=str(err))
        log(f"SKIP: {err}")
        status = SKIP
    except Failed as err:
        summary.update(ok=False, error=str(err))
        log(f"FAILED: {err}")
        status = 1
    finally:
        if started:
            r = subprocess.run([str(CLUSTER), "stop", str(state)], text=True, capture_output=True)
            print(r.stdout + r.stderr, end="")
        if args.scratch is None and status == 0:
            shutil.rmtree(scratch, ignore_errors=True)
        else:
            log(f"run folders kept in {scratch}")
    print(json.dumps(summary))
    if args.summary is not None:
        summary["exit_status"] = status
        partial = args.summary.with_name(args.summary.name + ".partial")
        partial.write_text(json.dumps(summary))
        partial.replace(args.summary)
    return status


if __name__ == "__main__":
    sys.exit(main())
