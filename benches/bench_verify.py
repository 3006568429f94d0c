#!/usr/bin/env python
"""What verifying the store on open costs, relative to the stages that consume it.

Target (from the trust issue): reading a store verified (every shard file
read and checked against its name-bound CRC-32C, see ``brdfpipe.data.store``)
adds < 10 % to the consuming stage.

What it does
------------
1. Generates ``--count`` synthetic materials (``brdfpipe.data.synth.synthesize``)
   and ingests them (``brdfpipe.data.ingest.ingest``) under a temporary folder, or
   reuses ``--store PATH``.  Not timed.
2. Warms the page cache (one verified open), then per round times

   a. ``open_store(path, verify=False)``: the metadata, ``valid`` digest and
      shard presence / size checks that every open does;
   b. ``open_store(path, verify=True)``: the same plus reading every shard
      and checking its digest (the default);
   c. ``gram.write_gram(path, out)`` (the ``compute_gram`` job, raw space);
   d. ``logmap.write_logmap(path, out, split="all", ...)`` (the
      ``map_logrelative`` job).

   (c) and (d) open the store themselves, so they include (b); the cost of
   verification is ``b − a`` and the stage without it ``stage − (b − a)``.
   Best of ``--rounds`` rounds (the machine is shared).
3. Prints the times and the ratios ``(b − a) / (stage − (b − a))`` against
   the 10 % target.  Exits 0 either way: benches report, they do not gate CI.

Usage::

    python benches/bench_verify.py [--count 20] [--store PATH] [--rounds 3] [--work DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

from _common import best_time  # noqa: E402  (benches/ is on sys.path)

TARGET = 0.10




def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--count", type=int, default=20, help="synthetic materials to generate (default 20)")
    ap.add_argument("--store", type=Path, help="use this store instead of generating one")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--work", type=Path, help="folder for the generated data (default: a temporary one)")
    args = ap.parse_args(argv)

    from brdfpipe.data import ingest, logmap, store, synth
    from brdfpipe.data.database import database_from_folder
    from brdfpipe.manifold import gram

    work = Path(tempfile.mkdtemp(prefix="bench-verify-", dir=args.work))
    try:
        if args.store is None:
            t0 = time.perf_counter()
            synth.synthesize(work / "db", count=args.count, seed=7, jobs=os.cpu_count() or 1, progress=False)
            db = database_from_folder(work / "db", key="folder")
            st_path = work / "merl.zarr"
            ingest.ingest(db.sources, st_path, database=db.kind, jobs=os.cpu_count() or 1)
            shutil.rmtree(work / "db")
            print(f"generated and ingested {args.count} synthetic materials in {time.perf_counter() - t0:.1f} s")
        else:
            st_path = args.store
        st = store.open_store(st_path)  # warms the page cache
        n = st.n_materials
        size = sum(p.stat().st_size for p in (st_path / "brdf").rglob("*") if p.is_file())
        print(f"store {st_path}: {n} materials, {size / 1e6:.0f} MB of shards")
        print(f"machine: {os.cpu_count()} cores, {_cpu_name()}; python {sys.version.split()[0]}; "
              f"best of {args.rounds}, warm page cache")

        t_open = best_time(lambda: store.open_store(st_path, verify=False), args.rounds)
        t_verified = best_time(lambda: store.open_store(st_path), args.rounds)
        cost = max(t_verified - t_open, 0.0)
        print(f"  open_store(verify=False)   {t_open * 1e3:9.1f} ms")
        print(f"  open_store(verify=True)    {t_verified * 1e3:9.1f} ms   (verification {cost * 1e3:.1f} ms, "
              f"{size / 1e9 / max(cost, 1e-9):.2f} GB/s)")

        stages = {
            "gram.write_gram (compute_gram)": lambda: gram.write_gram(st_path, work / "gram.npz"),
            "logmap.write_logmap (map_logrelative)": lambda: logmap.write_logmap(
                st_path, work / "lm.zarr", split="all", materials_train=list(st.materials)
            ),
        }
        worst = 0.0
        for name, fn in stages.items():
            t = best_time(fn, args.rounds)
            ratio = cost / max(t - cost, 1e-9)
            worst = max(worst, ratio)
            print(f"  {name:38s} {t:7.2f} s   verification / rest of the stage = {100 * ratio:5.1f} %")
        verdict = "PASS" if worst < TARGET else "FAIL"
        print(f"{verdict}: verification adds at most {100 * worst:.1f} % to a consuming stage "
              f"(target < {100 * TARGET:.0f} %)")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
