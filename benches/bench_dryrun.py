"""How long `snakemake -n` takes on the tiny config, and how much of it is the workflow's own imports.

Prints, best of ``--rounds`` (each in a fresh process, a scratch working
directory, nothing built yet):

* ``snakemake --version``: Snakemake's own start-up (the baseline);
* ``snakemake -n`` on ``tests/config/tiny.yaml``: the whole dry run;
* importing the modules the workflow's Snakefile imports at parse time
  (``brdfpipe.data.database`` and ``brdfpipe.core``'s ``plan``, ``filenames``,
  ``stamps``, ``version``), measured
  inside one fresh interpreter;

with the cluster issue's targets (dry run ≤ 1.5 s, own imports ≤ 0.2 s) and
the ratios.  Every cluster job re-parses the Snakefile, so this is paid per
job.  Prints; never fails a build.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
IMPORTS = "brdfpipe.data.database, brdfpipe.core.plan, brdfpipe.core.filenames, brdfpipe.core.stamps, brdfpipe.core.version"


def wall(cmd: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - t0


def import_time() -> float:
    code = f"import time; t0 = time.perf_counter(); import {IMPORTS}; print(time.perf_counter() - t0)"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(out.stdout.strip())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-dryrun-") as tmp:
        work = Path(tmp)
        base = min(wall([str(SNAKEMAKE), "--version"], work) for _ in range(args.rounds))
        dry = min(
            wall([str(SNAKEMAKE), "--snakefile", str(ROOT / "workflow" / "Snakefile"), "--directory", str(work),
                  "--configfile", str(ROOT / "tests" / "config" / "tiny.yaml"), "-n", "--quiet", "all"], work)
            for _ in range(args.rounds)
        )
    imp = min(import_time() for _ in range(args.rounds))
    print(f"snakemake --version (start-up):   {base:6.2f} s")
    print(f"snakemake -n, tiny config:        {dry:6.2f} s   target 1.5 s: {dry / 1.5:5.2f}x of target")
    print(f"  workflow's own imports:         {imp:6.3f} s   target 0.2 s: {imp / 0.2:5.2f}x of target")
    print(f"  parse + DAG beyond start-up:    {dry - base:6.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
