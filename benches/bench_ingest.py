#!/usr/bin/env python
"""Ingest speed and memory of ``brdfpipe.data.store`` against a plain ``np.fromfile`` read.

Target (from the store issue): ingesting 100 materials takes ≤ 1.5× the time
of reading the same files with ``np.fromfile`` in the same run, and the peak
RSS of the ingest stays < 2 GB.

What it does
------------
1. Generates 100 MERL-format materials (``brdfpipe.data.synth.synthesize``), or
   reuses the ``*.binary`` files in ``--data DIR``.
   Generation runs in a separate process so it does not inflate the RSS
   figures.
2. In a fresh measuring process: reads every file once (page cache warm-up,
   so both contenders read from memory; stated in the output), then, per
   round, times

   a. a sequential ``np.fromfile`` of all files (the reference);
   b. ``ingest.ingest(..., jobs=N)`` with N = number of cores (how Snakemake
      spreads it: one job per material, then one assembly job);
   c. ``ingest.ingest(..., jobs=1)``;
   d. sha256 of all files, sequential (a lower bound of what the ingest must
      do: the store records every source's sha256).

   and keeps the best of ``--rounds`` rounds of each (the machine is shared).
   With ``--cold`` it also evicts the sources from the page cache
   (``posix_fadvise(DONTNEED)`` on these files only) before (a) and (b).
3. Prints the ratios, peak RSS (self, and the largest worker process, via
   ``resource.getrusage``), the store size and compression ratio, and a
   PASS/FAIL line against the 1.5× and 2 GB targets.  Exits 0 either way:
   benches report, they do not gate CI.

Usage::

    python benches/bench_ingest.py [--count 100] [--data DIR] [--jobs N] [--rounds 3] [--cold]
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPEED_TARGET = 1.5
RSS_TARGET_BYTES = 2 * 1024**3


# ---------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------


def generate(out_dir: Path, count: int, seed: int = 0) -> str:
    """Write ``count`` synthetic materials into ``out_dir``; returns a description of the source."""
    from brdfpipe.data import synth

    synth.synthesize(out_dir, count=count, seed=seed, jobs=os.cpu_count() or 1, progress=False)
    return f"brdfpipe.data.synth.synthesize(count={count}, seed={seed})"


def list_sources(data: Path) -> list[Path]:
    """The ``*.binary`` files in ``data`` (recursively), sorted."""
    return sorted(Path(p) for p in glob.glob(str(data / "**" / "*.binary"), recursive=True))


# ---------------------------------------------------------------------------
# Measurement (runs in a fresh process)
# ---------------------------------------------------------------------------


def _evict(paths: Sequence[Path]) -> None:
    """Drop these files (only) from the page cache."""
    for p in paths:
        fd = os.open(p, os.O_RDONLY)
        try:
            os.fdatasync(fd)
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)


def _cpu() -> float:
    """CPU seconds (user + system) of this process and its reaped children so far."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _timed(fn: Callable[[], float], cpu_log: list[float]) -> float:
    """Run ``fn`` (which returns its wall time); append its CPU time to ``cpu_log``."""
    c0 = _cpu()
    wall = fn()
    cpu_log.append(_cpu() - c0)
    return wall


def _read_all(paths: Sequence[Path]) -> float:
    t0 = time.perf_counter()
    for p in paths:
        arr = np.fromfile(p, dtype="<f8", offset=12)
        del arr
    return time.perf_counter() - t0


def _sha_all(paths: Sequence[Path]) -> float:
    t0 = time.perf_counter()
    for p in paths:
        with open(p, "rb") as fh:
            hashlib.file_digest(fh, "sha256")
    return time.perf_counter() - t0


def _ingest(paths: Sequence[Path], out: Path, jobs: int) -> float:
    from brdfpipe.data import ingest

    t0 = time.perf_counter()
    ingest.ingest({p.stem: p for p in paths}, out, database="synthetic", jobs=jobs)
    return time.perf_counter() - t0


def _dir_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def measure(paths: list[Path], jobs: int, rounds: int, cold: bool, work: Path) -> dict[str, object]:
    """All timings, in this (fresh) process.  Returns a JSON-able dict."""
    import multiprocessing

    from brdfpipe.data import ingest, store

    # Fork the workers from this process (ingest.ingest would use a forkserver once this
    # process has threads), so that their CPU time and RSS show up in RUSAGE_CHILDREN.
    ingest._mp_context = lambda: multiprocessing.get_context("fork")  # type: ignore[attr-defined]
    out = work / "merl.zarr"
    res: dict[str, object] = {"n": len(paths), "jobs": jobs, "rounds": rounds}
    for p in paths:  # warm the page cache: both contenders read from memory
        with open(p, "rb") as fh:
            while fh.read(1 << 24):
                pass
    read_t, ing_t, ing1_t, sha_t = [], [], [], []
    read_c: list[float] = []
    ing_c: list[float] = []
    ing1_c: list[float] = []
    for _ in range(rounds):
        read_t.append(_timed(lambda: _read_all(paths), read_c))
        ing_t.append(_timed(lambda: _ingest(paths, out, jobs), ing_c))
    children_after_parallel = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    for _ in range(rounds):
        ing1_t.append(_timed(lambda: _ingest(paths, out, 1), ing1_c))
        sha_t.append(_sha_all(paths))
    res.update(read=read_t, ingest=ing_t, ingest1=ing1_t, sha=sha_t)
    res.update(read_cpu=read_c, ingest_cpu=ing_c, ingest1_cpu=ing1_c)
    res["loadavg_1min"] = os.getloadavg()[0]
    if cold:
        cr, ci = [], []
        for _ in range(rounds):
            _evict(paths)
            cr.append(_read_all(paths))
            _evict(paths)
            ci.append(_ingest(paths, out, jobs))
        res.update(cold_read=cr, cold_ingest=ci)
    st = store.open_store(out, verify=True)
    size = _dir_bytes(out)
    res.update(
        store_bytes=size,
        raw_f32_bytes=st.n_materials * store.N_COLS * 4,
        source_bytes=sum(p.stat().st_size for p in paths),
        self_maxrss=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
        child_maxrss=children_after_parallel,
    )
    return res


# ---------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------


def report(res: dict[str, object], source: str, cold: bool) -> None:
    """Print the results and the PASS/FAIL line."""

    def best(key: str) -> float:
        return min(res[key])  # type: ignore[arg-type, no-any-return]

    def fmt(key: str) -> str:
        return ", ".join(f"{t:.2f}" for t in res[key])  # type: ignore[union-attr]

    n, jobs = res["n"], res["jobs"]
    gb = res["source_bytes"] / 1e9  # type: ignore[operator]
    print(f"\nmaterials: {n} ({gb:.2f} GB of .binary), {source}")
    print("page cache: every source was read once before timing, so (a)–(d) all read from memory")
    print(f"timings: best of {res['rounds']} rounds (all rounds in brackets), seconds\n")
    r = best("read")
    rows = [
        ("(a) np.fromfile, sequential", "read"),
        (f"(b) ingest.ingest, jobs={jobs}", "ingest"),
        ("(c) ingest.ingest, jobs=1", "ingest1"),
        ("(d) sha256 of all files, 1 core", "sha"),
    ]
    for label, key in rows:
        print(f"{label:<34} {best(key):7.2f} s  ({fmt(key)})   ratio to (a): {best(key) / r:5.2f}")
    print(
        f"\nCPU time (user + sys, incl. workers), best round: (a) {best('read_cpu'):.2f} s, "
        f"(b) {best('ingest_cpu'):.2f} s, (c) {best('ingest1_cpu'):.2f} s; "
        f"ingest CPU / fromfile CPU = {best('ingest_cpu') / best('read_cpu'):.1f} "
        f"(a wall ratio of ~{best('ingest_cpu') / best('read_cpu') / jobs:.1f} on {jobs} idle cores)"  # type: ignore[operator]
    )
    print(f"1-minute load average at the end of the timings: {res['loadavg_1min']:.2f} (other work on the machine)")
    sha_floor = best("sha") / jobs  # type: ignore[operator]
    print(
        f"lower bound from sha256 alone on {jobs} cores: {sha_floor:.2f} s = "
        f"{sha_floor / r:.2f}× (a); per file: read {1e3 * r / n:.1f} ms, "  # type: ignore[operator]
        f"sha256 {1e3 * best('sha') / n:.1f} ms, ingest {1e3 * best('ingest1') / n:.1f} ms (1 core)"  # type: ignore[operator]
    )
    if cold:
        cr, ci = best("cold_read"), best("cold_ingest")
        print(
            f"cold page cache (sources evicted before each): (a) {cr:.2f} s, (b) {ci:.2f} s, "
            f"ratio {ci / cr:.2f}"
        )
    self_rss, child_rss = res["self_maxrss"], res["child_maxrss"]
    bound = self_rss + jobs * child_rss  # type: ignore[operator]
    print(
        f"\npeak RSS: this process {self_rss / 2**20:.0f} MiB (incl. the jobs=1 ingest), largest worker "  # type: ignore[operator]
        f"{child_rss / 2**20:.0f} MiB; self + {jobs} × worker = {bound / 2**20:.0f} MiB"  # type: ignore[operator]
    )
    sb, raw = res["store_bytes"], res["raw_f32_bytes"]
    print(
        f"store: {sb / 1e6:.0f} MB on disk; compression ratio {raw / sb:.2f}× vs float32, "  # type: ignore[operator]
        f"{res['source_bytes'] / sb:.2f}× vs the float64 sources"  # type: ignore[operator]
    )
    ratio = best("ingest") / r
    speed_ok = ratio <= SPEED_TARGET
    mem_ok = bound < RSS_TARGET_BYTES
    print(
        f"\n{'PASS' if speed_ok and mem_ok else 'FAIL'}: speed {'PASS' if speed_ok else 'FAIL'} "
        f"(ingest jobs={jobs} / fromfile = {ratio:.2f}, target ≤ {SPEED_TARGET}), memory "
        f"{'PASS' if mem_ok else 'FAIL'} (peak {bound / 2**30:.2f} GiB, target < 2 GiB)"  # type: ignore[operator]
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Generate or reuse data, measure in a fresh process, print the report."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--count", type=int, default=100, help="number of materials (default 100)")
    ap.add_argument("--data", type=Path, help="folder of *.binary files to reuse (generated there if short)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="ingest workers (default: cores)")
    ap.add_argument("--rounds", type=int, default=3, help="timing rounds, best kept (default 3)")
    ap.add_argument("--cold", action="store_true", help="also time with the sources evicted from the page cache")
    ap.add_argument("--measure", nargs=2, metavar=("PATHS_JSON", "WORKDIR"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.measure:  # child mode
        paths = [Path(p) for p in json.loads(Path(args.measure[0]).read_text())]
        res = measure(paths, args.jobs, args.rounds, args.cold, Path(args.measure[1]))
        print("RESULT " + json.dumps(res))
        return 0

    with tempfile.TemporaryDirectory(prefix="bench_ingest-") as tmp:
        work = Path(tmp)
        data = args.data or work / "data"
        sources = list_sources(data) if data.exists() else []
        if len(sources) >= args.count:
            source = f"reused from {data}"
        else:
            print(f"generating {args.count} materials in {data} ...", flush=True)
            t0 = time.perf_counter()
            code = (
                "import sys; sys.path.insert(0, %r); from bench_ingest import generate; "
                "print(generate(__import__('pathlib').Path(%r), %d))" % (str(HERE), str(data), args.count)
            )
            out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
            source = out.stdout.strip().splitlines()[-1]
            print(f"generated in {time.perf_counter() - t0:.0f} s", flush=True)
            sources = list_sources(data)
        sources = sources[: args.count]
        paths_json = work / "paths.json"
        paths_json.write_text(json.dumps([str(p) for p in sources]))
        cmd = [sys.executable, __file__, "--jobs", str(args.jobs), "--rounds", str(args.rounds)]
        cmd += ["--cold"] if args.cold else []
        cmd += ["--measure", str(paths_json), str(work)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            print(proc.stdout, proc.stderr, sep="\n")
            print("FAIL: the measuring process failed")
            return 0
        line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
        report(json.loads(line[len("RESULT "):]), source, args.cold)
    return 0


if __name__ == "__main__":
    logging.basicConfig(level=logging.WARNING)
    sys.exit(main())
