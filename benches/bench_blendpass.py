#!/usr/bin/env python
"""The blends of a GPLVM candidate's measurements: one pass over the store against one table per point.

What ``measure_gplvm_candidate`` blends (issue 23): in the ``log`` space the
albedo of the interpolated tables at :data:`brdfpipe.manifold.fidelity.LOG_ALBEDO_POINTS`
hull points of each fit (q = 2 and 5), and for every space the PR12
distances along the latent paths (3 paths of ``--steps`` + 1 points, q = 5).

* **per point** (the route before issue 23, kept here as the baseline): each
  batch of points formed whole by ``gplvm.interpolate_tables`` (8 hull points
  per pass over the store, a path's points per pass; in the ``log`` space each
  call also reads the store once for the median reference), then
  ``albedo.material_albedo`` and ``perceptual.pr12_features`` /
  ``pr12_distance`` of each table;
* **one pass**: ``blendpass.measure_blends`` for all points together.

Prints both times, the ratio per point / one pass and the largest relative
difference of the albedos and distances (rounding only: the sums are taken
in another order).  The per-point route's ``material_albedo`` already has the
cached sampling geometry of ``merl.directional_albedo`` (0.30 → 0.05 s per
table), so the ratio is that of the blending alone.

The store: ``--store PATH`` (default ``results/merl.zarr`` when present), else
``--count`` synthetic materials generated and ingested under ``--work``
(kept between runs).  Gram matrices and fits are computed under ``--work``
(not timed).  Exits 0 either way: benches report, they do not gate CI.

Usage::

    python benches/bench_blendpass.py [--count 30] [--store PATH] [--spaces log standardised]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _store(args: argparse.Namespace) -> Path:
    from brdfpipe.data import ingest, synth

    if args.store is not None:
        return args.store
    default = ROOT / "results" / "merl.zarr"
    if default.is_dir():
        return default
    out = args.work / f"merl-{args.count}.zarr"
    if not out.is_dir():
        db = args.work / f"db-{args.count}"
        synth.synthesize(db, count=args.count, seed=3, jobs=os.cpu_count() or 1, progress=False)
        ingest.ingest(sorted(db.glob("*.binary")), out, database="synthetic", jobs=os.cpu_count() or 1)
    return out


def _fits(st_path: Path, work: Path, space: str) -> dict[int, object]:
    from brdfpipe.manifold import fitting, gplvm, likelihood
    from brdfpipe.manifold.gram import gram_matrix

    G, d, info = gram_matrix(st_path, space=space)
    fits = {}
    for q in (2, 5):
        path = work / f"{st_path.stem}-{space}-q{q}.npz"
        res = fitting.fit(G / likelihood.gram_scale(G, d), d, q=q, mu=1e-4, seed=1)
        gplvm.save_model(path, res, info.materials, space=space, data_digests=info.digests)
        fits[q] = gplvm.load_model(path)
    return fits


def per_point(st_path: Path, hull_W: dict[int, np.ndarray], paths: list, model5) -> tuple[np.ndarray, np.ndarray]:
    """The route before issue 23: tables formed whole, a few per pass over the store."""
    from brdfpipe.manifold import albedo, gplvm, perceptual

    alb = []
    for q, W in hull_W.items():
        for c0 in range(0, W.shape[0], 8):
            tables, _ = gplvm.interpolate_tables(st_path, W[c0 : c0 + 8], materials=model5.names,
                                                 space=model5.space)
            alb += [albedo.material_albedo(t) for t in tables]
    dist = []
    for p in paths:
        tables, _ = gplvm.interpolate_tables(st_path, p.weights, model=model5, space=model5.space)
        feats = [perceptual.pr12_features(t) for t in tables]
        del tables
        dist += [perceptual.pr12_distance(f, feats[0]) for f in feats]
        dist += [perceptual.pr12_distance(f, feats[-1]) for f in feats]
        dist.append(perceptual.pr12_distance(feats[0], feats[-1]))
    return np.array(alb).reshape(-1, 3), np.array(dist)


def one_pass(st_path: Path, hull_W: dict[int, np.ndarray], paths: list, model5) -> tuple[np.ndarray, np.ndarray]:
    from brdfpipe.manifold import blendpass

    blocks = list(hull_W.values())
    at = sum(W.shape[0] for W in blocks)
    pairs = []
    for p in paths:
        pairs += p.pairs(at)
        blocks.append(p.weights)
        at += p.weights.shape[0]
    got = blendpass.measure_blends(st_path, np.vstack(blocks), materials=model5.names, space=model5.space,
                                   pairs=pairs)
    n_hull = sum(W.shape[0] for W in hull_W.values())
    return got.albedo[:n_hull], got.distances


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--count", type=int, default=30, help="synthetic materials to generate (default 30)")
    ap.add_argument("--store", type=Path, help="use this store (default results/merl.zarr when present)")
    ap.add_argument("--spaces", nargs="+", default=["log", "standardised"])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--work", type=Path, default=Path("/tmp/brdfpipe-bench-blendpass"))
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)

    import logging

    logging.disable(logging.WARNING)  # the clamp counts of every batch
    from brdfpipe.registry.manifold import default_paths
    from brdfpipe.data.store import open_store
    from brdfpipe.manifold import analysis, fidelity, latent

    st_path = _store(args)
    n = open_store(st_path).n_materials
    print(f"{_cpu_name()}, {os.cpu_count()} cores; store {st_path} ({n} materials); {args.steps + 1} points "
          f"per path", flush=True)
    print(f"{'space':14s} {'points':>6s} {'per point s':>11s} {'one pass s':>10s} {'ratio':>6s} "
          f"{'albedo rel':>10s} {'dist rel':>9s}")
    for space in args.spaces:
        fits = _fits(st_path, args.work, space)
        hull_W = {}
        if space == "log":  # the linear spaces take the albedo as w·A, no table
            for q, m in fits.items():
                H = latent.sample_in_hull(m.X, fidelity.LOG_ALBEDO_POINTS, np.random.default_rng(q))
                hull_W[q] = fidelity.smooth_weights(m, H)
        paths = [analysis.latent_path(fits[5], a, b, args.steps) for a, b in default_paths(fits[5].names, 1)]
        points = sum(W.shape[0] for W in hull_W.values()) + sum(p.ts.size for p in paths)
        t0 = time.perf_counter()
        a_old, d_old = per_point(st_path, hull_W, paths, fits[5])
        t1 = time.perf_counter()
        a_new, d_new = one_pass(st_path, hull_W, paths, fits[5])
        t2 = time.perf_counter()
        ra = float(np.max(np.abs(a_new - a_old) / np.abs(a_old))) if a_old.size else 0.0
        nz = d_old > 0
        rd = float(np.max(np.abs(d_new[nz] - d_old[nz]) / d_old[nz]))
        print(f"{space:14s} {points:6d} {t1 - t0:11.1f} {t2 - t1:10.1f} {(t1 - t0) / (t2 - t1):6.2f} "
              f"{ra:10.1e} {rd:9.1e}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
