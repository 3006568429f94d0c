"""Declared memory (mem_mb) of every rule vs the peak RSS its jobs reached.

Reads the Snakemake benchmark files of a finished run (``benchmarks/<rule>/…tsv``,
column ``max_rss`` in MB) and the number of materials of its store, and prints
per rule: jobs measured, the largest peak RSS, the ``mem_mb`` that
:func:`brdfpipe.plan.memory.mem_mb` declares for that number of materials (first
attempt), and their ratio.  The target of the cluster issue: every ratio in
[1, 2] on the default config (declared ≥ measured, ≤ twice it).  Prints; never
fails a build.

    python benches/bench_memory.py [--benchmarks benchmarks] [--store results/merl.zarr]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from brdfpipe import plan  # noqa: E402


def peaks(bench_dir: Path) -> dict[str, list[float]]:
    """max_rss (MB) of every benchmark file, by rule (the first folder under ``bench_dir``)."""
    out: dict[str, list[float]] = defaultdict(list)
    for f in sorted(bench_dir.rglob("*.tsv")):
        rel = f.relative_to(bench_dir)
        rule = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        with open(f, newline="") as fh:
            for row in csv.DictReader(fh, delimiter="\t"):
                try:
                    out[rule].append(float(row["max_rss"]))
                except (KeyError, ValueError):
                    continue
    return out


def n_materials(store: Path) -> int:
    doc = json.loads((store / "zarr.json").read_text())
    return len(doc["attributes"]["materials"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--benchmarks", type=Path, default=Path("benchmarks"))
    ap.add_argument("--store", type=Path, default=Path("results/merl.zarr"))
    args = ap.parse_args()
    if not args.benchmarks.is_dir() or not (args.store / "zarr.json").is_file():
        print(f"no finished run here ({args.benchmarks}, {args.store}): run `make run` first")
        return 0
    n = n_materials(args.store)
    measured = peaks(args.benchmarks)
    # outputs of the rules whose memory grows with them (one job per run)
    outputs = {"interpolate_path_points": len(list(args.store.parent.glob("renders/*/paths/*-weights.json")))}
    print(f"{n} materials; declared mem_mb (first attempt) vs measured peak RSS")
    print(f"{'rule':28s} {'jobs':>5s} {'peak MB':>9s} {'declared':>9s} {'ratio':>6s}  in [1, 2]")
    worst = []
    for rule in sorted(set(measured) | set(plan.MEMORY_MB)):
        declared = plan.mem_mb(rule, n, outputs=outputs.get(rule, 1)) if rule in plan.MEMORY_MB else None
        vals = measured.get(rule, [])
        peak = max(vals) if vals else None
        ratio = declared / peak if declared and peak else None
        ok = "yes" if ratio is not None and 1.0 <= ratio <= 2.0 else ("-" if ratio is None else "NO")
        if ok == "NO":
            worst.append(rule)
        print(f"{rule:28s} {len(vals):5d} {peak if peak is not None else float('nan'):9.0f} "
              f"{declared if declared is not None else float('nan'):9.0f} "
              f"{ratio if ratio is not None else float('nan'):6.2f}  {ok}")
    print("all declared within [1, 2] x measured" if not worst else f"outside [1, 2]: {', '.join(worst)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
