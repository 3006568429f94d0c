#!/usr/bin/env python
"""Run every benchmark (``make bench``).

Benches print their measurements and ratios against baselines measured in the
same run; they never fail the build.  When the default workflow's synthetic
database exists (``results/synthetic``, from ``make run``) it is reused
instead of generating 100 materials again.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "results" / "synthetic"
STORE = ROOT / "results" / "merl.zarr"
LOGMAP = ROOT / "results" / "logmap" / "train.zarr"
MODEL = ROOT / "results" / "svd" / "train.zarr"


def run(*args: str) -> None:
    print(f"\n=== {' '.join(args)}", flush=True)
    subprocess.run([sys.executable, *args], cwd=ROOT, check=False)


def main() -> None:
    have_data = len(list(DATA.glob("*.binary"))) >= 100
    data = ["--data", str(DATA)] if have_data else []
    run("benches/bench_codecs.py", *data)
    run("benches/bench_ingest.py", *data, "--cold")
    if STORE.is_dir():
        run("benches/spectrum.py", str(STORE))
    # Acquisition track: reuse the default run's log-map and model when present.
    run("benches/bench_error_metric.py", *(["--model", str(MODEL)] if MODEL.is_dir() else []))
    run("benches/bench_svd.py", *(["--logmap", str(LOGMAP)] if LOGMAP.is_dir() else []))
    run("benches/bench_optimize.py", *(["--model", str(MODEL)] if MODEL.is_dir() else []))
    # Speed at the paper's resolution (issue 33): the near-field optimiser's CPU at 128 px against 32 px.
    run("benches/bench_optimize.py", *(["--model", str(MODEL)] if MODEL.is_dir() else []), "--grids", "32,128", "--screen", "32")
    # Manifold track: GPLVM fit vs scipy L-BFGS (and GPy, when a GPy environment is set up).
    # "entry" is the workflow's normalisation (manifold.normalise); "raw" the paper's units.
    run("benches/bench_gplvm.py", "--scaling", "entry")
    # A GPLVM candidate's blends (measure_gplvm_candidate): one pass over the store vs a table per point.
    run("benches/bench_blendpass.py", *(["--store", str(STORE)] if STORE.is_dir() else []))
    # Scale: time and peak memory of every stage at N = 50 … 400 synthetic materials (fewer cells),
    # growth exponents, log-log figure (its material files are kept in /tmp between runs).
    run("benches/bench_scaling.py")
    # Rendering track: the merl BSDF vs Mitsuba's analytic plugins.
    run("benches/bench_render.py")
    # Pre-renders: one process per material (before issue 23) vs one per batch, same images.
    run("benches/bench_render_batch.py")
    # The explorer: blend frame rate in headless chromium (SwiftShader), naive vs packed shaders.
    run("benches/bench_explorer.py")
    # Trust and cluster: verifying the store on open, parse time, declared memory vs the run's peaks.
    run("benches/bench_verify.py")
    # Every other intermediate's digest (model, log-map, GPLVM files, EXRs, tables, explorer) vs its consumer.
    run("benches/bench_integrity.py")
    run("benches/bench_dryrun.py")
    run("benches/bench_memory.py")
    # Speed (issue 33): the jobs' CPU beside a competing load against idle (no job spins or oversubscribes).
    run("benches/bench_load.py")
    # Speed: where the last run's wall time went (critical path, CPU per rule, idle cores).
    run("benches/bench_critical_path.py")


if __name__ == "__main__":
    main()
