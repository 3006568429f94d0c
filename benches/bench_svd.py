#!/usr/bin/env python
"""Streamed PCA (``brdfpipe.acquisition.svd.fit``) against a dense ``scipy.linalg.svd`` of the same data.

Targets (from the acquisition issue): the streamed fit is ≥ 10× faster than
``scipy.linalg.svd(dense float64 centred matrix, full_matrices=False)`` and
its peak RSS is ≤ 1/3 of the dense one's.

What it does
------------
1. Writes the ``train`` log-map of the store (``brdfpipe.data.logmap.write_logmap``:
   training materials from ``results/splits.json``, or the first
   ``--materials N`` of them) under a temporary folder in /tmp (or reuses
   ``--logmap PATH``).  Not timed.
2. Runs each contender in its own fresh Python process and reads that
   process's peak RSS (``ru_maxrss`` from ``os.wait4``); the wall time is
   measured inside the child, after imports:

   a. ``fit``: ``svd.fit(logmap, out)`` – two streamed passes over X, Gram
      matrix, eigen-decomposition, and Q = (X − μ̂)ᵀU *written* to a Zarr
      model (so it does strictly more than the baseline);
   b. ``dense``: X read into one float64 (m, p) array (chunk by chunk, no
      float32 copy of the whole), centred in place, then
      ``scipy.linalg.svd(X, full_matrices=False)`` (LAPACK gesdd).  Its
      time is reported in total and for the SVD call alone.

3. Prints both, the ratios, the largest relative difference between the two
   sets of singular values (a correctness check), and PASS/FAIL against the
   targets (on wall time; the CPU-time ratio of the whole processes is
   printed too, as it is less sensitive to other users of a shared
   machine).  The fit runs ``--rounds`` times (best wall time kept), the
   dense SVD ``--dense-rounds`` times.  Exits 0 either way: benches report,
   they do not gate CI.

Usage::

    python benches/bench_svd.py [--store results/merl.zarr] [--materials N] [--rounds 3] [--dense-rounds 1]
                                [--logmap PATH] [--work DIR] [--skip-dense]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import training_materials  # noqa: E402  (benches/ is on sys.path)

ROOT = Path(__file__).resolve().parents[1]
SPEED_TARGET = 10.0
RSS_TARGET = 1.0 / 3.0


# ---------------------------------------------------------------------------
# Children (fresh processes)
# ---------------------------------------------------------------------------


def child_fit(logmap_path: str, work: str) -> dict[str, object]:
    from brdfpipe.acquisition import svd

    out = Path(work) / "model.zarr"
    t0 = time.perf_counter()
    svd.fit(logmap_path, out)
    wall = time.perf_counter() - t0
    model = svd.open_model(out)
    np.save(Path(work) / "sigma_fit.npy", model.sigma)
    return {"wall": wall, "k": model.k}


def child_dense(logmap_path: str, work: str) -> dict[str, object]:
    import scipy.linalg

    from brdfpipe.data import logmap

    lm = logmap.open_logmap(logmap_path)
    t0 = time.perf_counter()
    x = np.empty((lm.m, lm.p), dtype=np.float64)
    for a, b, block in logmap.iter_columns(lm):
        x[:, a:b] = block
    t_load = time.perf_counter()
    x -= x.mean(axis=0)
    t_svd = time.perf_counter()
    _, s, _ = scipy.linalg.svd(x, full_matrices=False)
    t_end = time.perf_counter()
    np.save(Path(work) / "sigma_dense.npy", s)
    return {"wall": t_end - t0, "load": t_load - t0, "centre": t_svd - t_load, "svd": t_end - t_svd}


def run_child(kind: str, logmap_path: Path, work: Path) -> dict[str, object]:
    """Run one contender in a fresh interpreter; returns its report plus peak RSS (bytes)."""
    cmd = [sys.executable, __file__, "--child", kind, "--logmap", str(logmap_path), "--work", str(work)]
    load0 = os.getloadavg()[0]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None
    output = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{kind} child failed with exit code {proc.returncode}")
    report = json.loads(output.decode().strip().splitlines()[-1])
    report["rss"] = usage.ru_maxrss * 1024  # Linux: kilobytes
    report["cpu"] = usage.ru_utime + usage.ru_stime
    report["loadavg_before"] = load0
    report["loadavg_after"] = os.getloadavg()[0]
    return report


# ---------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------


def make_logmap(store_path: Path, splits: Path, n: int | None, out: Path) -> tuple[int, int]:
    from brdfpipe.data import logmap

    st, train = training_materials(store_path, splits)
    if n is not None:
        train = train[:n]
    split = "train" if set(train) != set(st.materials) else "all"
    t0 = time.perf_counter()
    logmap.write_logmap(store_path, out, split=split, materials_train=train)
    lm = logmap.open_logmap(out)
    print(f"log-map ({split}, {len(train)} materials): m = {lm.m}, p = {lm.p}, "
          f"written in {time.perf_counter() - t0:.1f} s -> {out}", flush=True)
    return lm.m, lm.p


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--store", type=Path, default=ROOT / "results" / "merl.zarr")
    ap.add_argument("--splits", type=Path, default=ROOT / "results" / "splits.json")
    ap.add_argument("--materials", type=int, default=None, help="use the first N training materials")
    ap.add_argument("--logmap", type=Path, default=None, help="reuse this log-map instead of writing one")
    ap.add_argument("--work", type=Path, default=None, help="scratch folder (default: a new one in /tmp)")
    ap.add_argument("--rounds", type=int, default=3, help="runs of the streamed fit; the best time is kept")
    ap.add_argument("--dense-rounds", type=int, default=1, help="runs of the dense SVD (~2 min each at m = 270)")
    ap.add_argument("--skip-dense", action="store_true", help="time the streamed fit only")
    ap.add_argument("--child", choices=["fit", "dense"], help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.child:
        fn = child_fit if args.child == "fit" else child_dense
        print(json.dumps(fn(str(args.logmap), str(args.work))), flush=True)
        return

    own_work = args.work is None
    work = Path(tempfile.mkdtemp(prefix="bench_svd-", dir="/tmp")) if own_work else args.work
    work.mkdir(parents=True, exist_ok=True)
    if (ROOT / "results") in work.resolve().parents:
        raise SystemExit("refusing to write scratch data under results/")
    try:
        print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
              f"{os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') / 2**30:.0f} GiB; "
              f"1-min load average {os.getloadavg()[0]:.2f} (other users count)", flush=True)
        if args.logmap is None:
            lm_path = work / "train.zarr"
            if not args.store.is_dir():
                raise SystemExit(f"{args.store}: no store (run the workflow's data stage first)")
            m, p = make_logmap(args.store, args.splits, args.materials, lm_path)
        else:
            from brdfpipe.data import logmap

            lm_path = args.logmap
            lm = logmap.open_logmap(lm_path)
            m, p = lm.m, lm.p
        print(f"dense float64 matrix: {m} x {p} = {m * p * 8 / 1e9:.2f} GB", flush=True)

        fits = [run_child("fit", lm_path, work) for _ in range(args.rounds)]
        fit = min(fits, key=lambda r: float(r["wall"]))  # type: ignore[arg-type]
        fit["rss"] = max(int(r["rss"]) for r in fits)  # type: ignore[call-overload]
        print("streamed fit rounds: " + ", ".join(f"{float(r['wall']):.1f} s" for r in fits))  # type: ignore[arg-type]
        print(f"streamed fit : {fit['wall']:7.1f} s wall, {fit['cpu']:7.1f} s CPU, peak RSS "
              f"{int(fit['rss']) / 2**30:6.2f} GiB, k = {fit['k']} "  # type: ignore[call-overload]
              f"(load {fit['loadavg_before']:.1f} -> {fit['loadavg_after']:.1f})", flush=True)
        if args.skip_dense:
            return
        denses = [run_child("dense", lm_path, work) for _ in range(args.dense_rounds)]
        dense = min(denses, key=lambda r: float(r["wall"]))  # type: ignore[arg-type]
        dense["rss"] = max(int(r["rss"]) for r in denses)  # type: ignore[call-overload]
        print(f"dense SVD    : {dense['wall']:7.1f} s wall (load {dense['load']:.1f} s, centre "
              f"{dense['centre']:.1f} s, scipy.linalg.svd {dense['svd']:.1f} s), {dense['cpu']:7.1f} s CPU, "
              f"peak RSS {int(dense['rss']) / 2**30:6.2f} GiB "  # type: ignore[call-overload]
              f"(load {dense['loadavg_before']:.1f} -> {dense['loadavg_after']:.1f})", flush=True)

        s_fit = np.load(work / "sigma_fit.npy")
        s_dense = np.load(work / "sigma_dense.npy")
        rel = np.abs(s_fit - s_dense[: s_fit.size]) / s_dense[: s_fit.size]
        print(f"singular values: k = {s_fit.size} of {s_dense.size}; max relative difference {rel.max():.2e} "
              f"(σ1 = {s_dense[0]:.4g}, σk = {s_fit[-1]:.4g}; dense σ_(k+1) = "
              f"{s_dense[s_fit.size] if s_dense.size > s_fit.size else float('nan'):.3g})")

        speed = float(dense["wall"]) / float(fit["wall"])  # type: ignore[arg-type]
        speed_svd = float(dense["svd"]) / float(fit["wall"])  # type: ignore[arg-type]
        rss = int(fit["rss"]) / int(dense["rss"])  # type: ignore[call-overload]
        cpu = float(dense["cpu"]) / float(fit["cpu"])  # type: ignore[arg-type]
        print(f"speed-up (dense total / fit): {speed:.1f}x  [SVD call alone / fit: {speed_svd:.1f}x; "
              f"CPU seconds, whole processes: {cpu:.1f}x]")
        print(f"peak RSS (fit / dense): {rss:.3f}")
        print(f"{'PASS' if speed >= SPEED_TARGET else 'FAIL'}: speed-up {speed:.1f}x vs target >= {SPEED_TARGET:.0f}x")
        print(f"{'PASS' if rss <= RSS_TARGET else 'FAIL'}: peak RSS ratio {rss:.3f} vs target <= 1/3")
    finally:
        if own_work:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
