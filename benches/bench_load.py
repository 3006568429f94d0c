#!/usr/bin/env python
"""Jobs' CPU with a competing load against idle (issue 33: every job uses at most its threads, none spins).

Runs the workflow on one config twice from an empty folder: once on an idle
machine, once beside ``--load`` processes that keep as many cores busy (pure
Python loops, started before the run and stopped after it).  A job that
waits by spinning (a BLAS or Dr.Jit thread pool polling for work, a lock
held in a loop) or that runs more threads than its ``threads:`` costs more
CPU when it has to share the cores; a job that only computes costs the same.
So the total CPU of the run's process tree (Snakemake and every job it
waited for: ``getrusage(RUSAGE_CHILDREN)`` around the run) under load over
idle is the measure, with the per-rule CPU of the benchmark files beside it
(those sample the job's process tree, so short jobs are under-counted in
both runs alike).

Target: loaded / idle ≤ 1.10 for the run's CPU.  Prints PASS/FAIL; exit
status 0 either way (benches report, they do not gate CI).

Usage::

    python benches/bench_load.py [--config tests/config/tiny-point.yaml] [--cores 2] [--load 2]
"""

from __future__ import annotations

import argparse
import collections
import multiprocessing as mp
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1.10


def _spin() -> None:
    while True:
        pass


def run_once(config: Path, cores: int, load: int, work: Path) -> tuple[float, float, dict[str, float]]:
    """Wall time, the process tree's CPU and CPU per rule (benchmark files) of one run in ``work``."""
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    spinners = [mp.Process(target=_spin, daemon=True) for _ in range(load)]
    for p in spinners:
        p.start()
    try:
        cmd = [str(Path(sys.executable).with_name("snakemake")), "--snakefile", str(ROOT / "workflow" / "Snakefile"),
               "--directory", str(work), "--configfile", str(config), "--cores", str(cores), "--quiet", "all"]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    finally:
        for p in spinners:
            p.terminate()
            p.join()
    if r.returncode != 0:
        raise SystemExit(f"the run in {work} failed ({r.returncode}):\n{(r.stdout + r.stderr)[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    per_rule: dict[str, float] = collections.Counter()
    for f in (work / "benchmarks").rglob("*.tsv"):
        lines = f.read_text().splitlines()
        if len(lines) >= 2:
            rule = f.relative_to(work / "benchmarks").parts[0].removesuffix(".tsv")
            per_rule[rule] += float(lines[-1].split("\t")[9])
    return wall, cpu, dict(per_rule)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=ROOT / "tests" / "config" / "tiny-point.yaml")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--load", type=int, default=None, help="competing busy processes (default: --cores)")
    ap.add_argument("--work", type=Path, default=None, help="scratch folder (default: a new one in /tmp)")
    args = ap.parse_args()
    load = args.cores if args.load is None else args.load
    scratch = Path(tempfile.mkdtemp(prefix="bench_load-", dir="/tmp")) if args.work is None else args.work
    print(f"config {args.config}, --cores {args.cores}, competing load {load} busy processes; "
          f"{os.cpu_count()} cores; 1-min load average before {os.getloadavg()[0]:.2f}", flush=True)
    try:
        idle = run_once(args.config.resolve(), args.cores, 0, scratch / "idle")
        print(f"idle:   {idle[0]:7.1f} s wall, {idle[1]:7.1f} CPU-s (Snakemake and its jobs)", flush=True)
        loaded = run_once(args.config.resolve(), args.cores, load, scratch / "loaded")
        print(f"loaded: {loaded[0]:7.1f} s wall, {loaded[1]:7.1f} CPU-s", flush=True)
    finally:
        if args.work is None:
            shutil.rmtree(scratch, ignore_errors=True)
    print("\n| rule | CPU-s idle | CPU-s loaded | loaded / idle |\n|---|---|---|---|")
    for rule in sorted(set(idle[2]) | set(loaded[2]), key=lambda r: -idle[2].get(r, 0.0)):
        a, b = idle[2].get(rule, 0.0), loaded[2].get(rule, 0.0)
        print(f"| `{rule}` | {a:.1f} | {b:.1f} | {b / a:.2f} |" if a > 0 else f"| `{rule}` | {a:.1f} | {b:.1f} | — |")
    ratio = loaded[1] / idle[1]
    print(f"\n{'PASS' if ratio <= TARGET else 'FAIL'}: the run's CPU under a competing load is {ratio:.2f}x idle "
          f"(target <= {TARGET:.2f}x); wall {loaded[0] / idle[0]:.2f}x")


if __name__ == "__main__":
    main()
