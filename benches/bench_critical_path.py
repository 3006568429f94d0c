#!/usr/bin/env python
"""Where a finished run's wall time went: critical path, CPU per rule, idle cores (issue 23).

Reads a run's Snakemake log and its jobs' benchmark files
(:mod:`brdfpipe.report.critical_path`) and prints the wall time, the critical
path with each job's share of it (and how long each waited for a free core
after its inputs were ready), the CPU seconds per rule, the jobs' CPU sum and
the core-seconds left idle while the path ran.  Usable on any finished run::

    python benches/bench_critical_path.py [WORKDIR_OR_LOG ...]

Default: this checkout's own run (``make run``: the newest log in
``.snakemake/log/``).  Prints the targets of the speed issue next to the
numbers (jobs' CPU ≤ 900 s; wall ≤ 10 min on 2 cores, ≤ 2 min on a 16-core
GPU host); a bench reports, it never fails the build.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from brdfpipe.report import critical_path as cp  # noqa: E402

CPU_TARGET_S = 900.0
WALL_TARGET_S = {2: 600.0, 16: 120.0}  # issue 33


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="*", default=[str(ROOT)], help="working directories or Snakemake log files")
    parser.add_argument("--rules", type=int, default=25, help="rules listed in the CPU table")
    args = parser.parse_args(argv)
    for where in args.runs:
        p = Path(where)
        try:
            log = cp.latest_log(p) if p.is_dir() else p
            run = cp.read_run(log)
        except cp.RunLogError as err:
            print(f"bench_critical_path: {err}")
            continue
        print(cp.report(run, top_rules=args.rules))
        cpu = sum(r.cpu for r in cp.cpu_per_rule(run))
        verdict = "PASS" if cpu <= CPU_TARGET_S else "FAIL"
        print(f"\n{verdict}: jobs' CPU sum {cpu:.0f} s (target ≤ {CPU_TARGET_S:.0f} s)")
        target = WALL_TARGET_S.get(run.cores)
        if target is not None:
            verdict = "PASS" if run.wall <= target else "FAIL"
            print(f"{verdict}: wall {run.wall:.0f} s on {run.cores} cores (target ≤ {target:.0f} s; "
                  "default config, empty results/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
