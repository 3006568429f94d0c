#!/usr/bin/env python
"""Frame time of the explorer's blend in headless Chromium on software GL (SwiftShader).

Targets (the explorer issue): ≥ 30 fps at 256 × 192 blending all N = 100
pre-renders exactly, and ≥ 30 fps at 512 × 384 with a reduced basis whose
error stays below the Monte Carlo noise floor of the pre-renders.  Baseline:
a naive shader over an N-layer RGBA16F texture array (one fetch per image
and pixel), measured in the same run.

What it does
------------
1. Inputs: the finished run's (``results/explorer/manifest.json`` names the
   candidate; its models, the scene's pre-renders, albedos and errormaps
   summary are read again), or — without a run — synthetic inputs
   (``tests/explorer_fixture.py``: 100 low-rank-plus-noise images, a GPLVM
   fit, a 3.5 % noise floor).  The page is exported twice
   (:func:`brdfpipe.explorer.export.write_explorer`): at the pre-renders'
   size, and with every pixel repeated 2 × 2 (``upsample=2``, 512 × 384 from
   256 × 192: the basis and its relative error are those of the original
   images).
2. In one headless Chromium (``--use-angle=swiftshader``) each page runs
   ``explorer.bench``: ``--frames`` blends with changing weights, each
   finished by ``gl.finish()`` and a one-pixel ``readPixels`` (so the time
   is the GPU's, not only the submission), after three warm-up frames;
   best of ``--rounds``.  Shaders: ``naive`` and ``packed`` (eight half
   floats per RGBA32UI texel, unpackHalf2x16, the page's) and ``bits`` (the
   same texels converted by integer bit operations), each over the whole
   canvas or with tiles (``+t``: the full blend only on the 8 × 8 tiles where
   the images differ, one fetch elsewhere — the page's default,
   ``export.blend_tiles``); sets: ``exact`` (N images) and ``reduced``
   (mean + k components).  The synthetic inputs have a background (3/8 of
   the width) that is the same in every image, as the preview scene has.
3. Prints fps, the fraction of tiles blended in full, the ratio page /
   naive, PASS/FAIL against the targets, and the basis' k, errors and floor.
   Exits 0 either way: benches report, they do not gate CI.

Usage::

    python benches/bench_explorer.py [--results results] [--scene preview] [--frames 30] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def run_inputs(results: Path, scene: str) -> dict | None:
    """write_explorer's inputs from a finished run (None without one)."""
    from brdfpipe.core import filenames as fn
    from brdfpipe import plan
    from brdfpipe.registry import manifold as manifold_spec

    manifest = results / "explorer" / "manifest.json"
    if not manifest.is_file():
        return None
    man = json.loads(manifest.read_text())
    cand = manifold_spec.candidate_label(man["space"], man["mu"])
    rel = lambda p: str(results.parent / p)  # noqa: E731 (file names are relative to the run's folder)
    summary = rel(fn.errormap_summary(scene))
    return {
        "models": [rel(fn.gplvm_model(cand, m["q"])) for m in man["models"]],
        "prerenders": {n: rel(fn.prerender(scene, n)) for n in man["materials"]},
        "albedo": rel(fn.albedo()),
        "summary": summary if Path(summary).is_file() else None,
        "database": man["database"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", type=Path, default=ROOT / "results")
    ap.add_argument("--scene", default="preview")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()

    from brdfpipe.explorer import chromium, export

    if chromium.find_chromium() is None:
        print("bench_explorer: no chromium here (Debian: apt-get install chromium); nothing measured")
        return
    with tempfile.TemporaryDirectory(prefix="bench-explorer-") as tmp:
        inputs = run_inputs(args.results.resolve(), args.scene)
        source = f"the run's pre-renders ({args.results})"
        if inputs is None:
            from explorer_fixture import make_inputs

            inputs = make_inputs(Path(tmp) / "inputs", n=100, width=256, height=192, qs=(2,))
            source = "synthetic images (no results/explorer: run the workflow first for real pre-renders)"
        sites = {}
        for up in (1, 2):
            t0 = time.perf_counter()
            out = Path(tmp) / f"explorer-x{up}"
            man = export.write_explorer(out=out, upsample=up, **inputs)
            sites[up] = (out, man)
            print(f"export x{up}: {man['width']} x {man['height']}, {man['n']} images, "
                  f"{man['bytes_total'] / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s")
        b0 = sites[1][1]["basis"]
        print(f"inputs: {source}; {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
              f"chromium {chromium.find_chromium()}, SwiftShader")
        print(f"reduced basis: k = {b0['k']} components + mean; largest relative RMSE "
              f"{b0['error_prerenders_max']:.4f} over the {sites[1][1]['n']} pre-renders, "
              f"{b0['error_blends_max']:.4f} over {b0['blend_samples']} blends in the hulls (median "
              f"{b0['error_blends_median']:.4f}); target {b0['target']:.4f} "
              f"({'noise floor of one pre-render' if b0['floor'] is not None else 'no floor known: fallback'})")
        rows = []
        with chromium.Browser() as b:
            for up, (out, man) in sites.items():
                b.open(out / "index.html", ready="window.explorer && (window.explorer.ready || window.explorer.error)",
                       timeout=300)
                if b.evaluate("explorer.error"):
                    print("page error:", b.evaluate("explorer.error"))
                    return
                tiles = man["tiles"]
                for basis in ("exact", "reduced"):
                    fps = {}
                    for shader, use_tiles in (("naive", False), ("naive", True), ("packed", False),
                                              ("packed", True), ("bits", True)):
                        best = 0.0
                        for _ in range(args.rounds):
                            r = b.evaluate(f"explorer.bench({{basis: '{basis}', shader: '{shader}', "
                                           f"tiles: {'true' if use_tiles else 'false'}, frames: {args.frames}}})")
                            best = max(best, r["fps"])
                        fps[shader, use_tiles] = (best, r["images"])
                    blended = tiles["exact_blended" if basis == "exact" else "reduced_blended"] / tiles["total"]
                    rows.append((f"{man['width']}x{man['height']}", basis, blended, fps))
            if b.errors:
                print("page errors:", b.errors)
        print("\nfps, best of the rounds; 'tiles': the full blend only on the tiles where the images differ "
              "(the page's default), one fetch elsewhere; baseline: naive over the whole canvas")
        print(f"\n{'size':>9} {'set':>8} {'images':>6} {'tiles':>6} {'naive':>7} {'naive+t':>8} {'packed':>7} "
              f"{'packed+t':>9} {'bits+t':>7} {'page/naive':>11}  target")
        for size, basis, blended, fps in rows:
            n = fps["naive", False][1]
            f = {key: v[0] for key, v in fps.items()}
            target = ("≥ 30 fps" if (size == "256x192" and basis == "exact") or
                      (size == "512x384" and basis == "reduced") else "")
            page = f["packed", True]
            verdict = (" PASS" if page >= 30 else " FAIL") if target else ""
            print(f"{size:>9} {basis:>8} {n:>6} {blended:>6.0%} {f['naive', False]:>7.1f} {f['naive', True]:>8.1f} "
                  f"{f['packed', False]:>7.1f} {page:>9.1f} {f['bits', True]:>7.1f} "
                  f"{page / f['naive', False]:>10.2f}x  {target}{verdict}")


if __name__ == "__main__":
    main()
