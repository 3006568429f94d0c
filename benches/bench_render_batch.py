#!/usr/bin/env python
"""Pre-renders: one process per material (the workflow before issue 23) vs one process per batch.

Writes ``--materials`` synthetic MERL tables (``brdfpipe.data.synth``), then
renders each in the default preview scene and in the floor check's scene
(256 × 192 at 64 spp and 48 × 36 at 4,096 spp, as ``config/config.yaml``):

* **per process**: a fresh ``python`` per material and scene folder, as the
  ``prerender_material`` jobs did (Python, Mitsuba, the plugins and the JIT
  start every time; the floor renders in passes of 32 samples per pixel);
* **batch**: one process for all, ``scene.render_materials`` as the
  ``prerender_materials_bNN`` jobs do (one start, a table loaded and fitted
  once for both scenes, the floor in passes of ``scene.auto_pass_spp``).

Prints wall and CPU seconds (children's rusage) of each route and their
ratio, measured in the same run; checks that the batch's preview images equal
the per-process ones (same bytes: same passes).  It never fails a build.

    python benches/bench_render_batch.py [--materials 6] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from brdfpipe.core.exr import read_exr  # noqa: E402
from brdfpipe.data import merl, synth  # noqa: E402
from brdfpipe.rendering import scene  # noqa: E402

SETTINGS = (((256, 192), 64), ((48, 36), 4096))

ONE = """
import sys
from brdfpipe.rendering import scene
src, out, one, envmap, w, h, spp, threads, pass_spp = sys.argv[1:]
from brdfpipe.rendering import bounce, render
render.use_variant("llvm_ad_rgb"); render.set_cpu_threads(int(threads))
render.register_merl_bsdf(); bounce.register_bounce_integrator()
d = scene.scene_dict(render.merl_bsdf(src), envmap=envmap, resolution=(int(w), int(h)), max_depth=6,
                     spp=int(spp), seed=0)
d["integrator"] = bounce.bounce_integrator(6)
scene.render_split_to_exr(d, out, out_one=one, spp=int(spp), seed=0, pass_spp=int(pass_spp),
                          progress=lambda s: None)
"""

BATCH = """
import sys, json
from brdfpipe.rendering import scene
args = json.loads(sys.argv[1])
scene.render_materials(args["src"], args["outs"], outs_one=args["ones"], materials=args["names"],
                       settings=[(tuple(r), s) for r, s in args["settings"]], envmap=args["envmap"],
                       variant="llvm_ad_rgb", max_depth=6, seed=0, threads=args["threads"],
                       progress=lambda s: None)
"""


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(cmds: list[list[str]]) -> tuple[float, float]:
    c0, t0 = _children_cpu(), time.perf_counter()
    for cmd in cmds:
        subprocess.run(cmd, check=True, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})  # HOME: Dr.Jit's kernel cache
    return time.perf_counter() - t0, _children_cpu() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--materials", type=int, default=6)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    import json

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        envmap = d / "envmap.exr"
        scene.make_envmap(envmap)
        specs = synth.plan_database(100, 2016)[:: max(1, 100 // args.materials)][: args.materials]
        names = [s.name for s in specs]
        for s in specs:
            merl.write_merl(d / f"{s.name}.binary", synth.generate_table(s))
        per_cmds = []
        for i, (res, spp) in enumerate(SETTINGS):
            for n in names:
                per_cmds.append([sys.executable, "-c", ONE, str(d / f"{n}.binary"), str(d / f"p{i}-{n}.exr"),
                                 str(d / f"p{i}-{n}-one.exr"), str(envmap), str(res[0]), str(res[1]), str(spp),
                                 str(args.threads), str(scene.DEFAULT_PASS_SPP)])
        doc = {"src": [str(d / f"{n}.binary") for n in names], "names": names, "envmap": str(envmap),
               "outs": [[str(d / f"b{i}-{n}.exr") for n in names] for i in range(len(SETTINGS))],
               "ones": [[str(d / f"b{i}-{n}-one.exr") for n in names] for i in range(len(SETTINGS))],
               "settings": [[list(r), s] for r, s in SETTINGS], "threads": args.threads}
        batch_cmd = [[sys.executable, "-c", BATCH, json.dumps(doc)]]
        _timed([per_cmds[0]])  # warm the page cache and Dr.Jit's kernel cache for both routes
        per_wall, per_cpu = _timed(per_cmds)
        b_wall, b_cpu = _timed(batch_cmd)
        same = all(np.array_equal(read_exr(d / f"p0-{n}.exr"), read_exr(d / f"b0-{n}.exr")) for n in names)
    k = len(names) * len(SETTINGS)
    print(f"{len(names)} synthetic materials × {len(SETTINGS)} scene folders ({k} renders), "
          f"llvm_ad_rgb, {args.threads} threads")
    print(f"  one process per render : {per_wall:7.1f} s wall {per_cpu:7.1f} s CPU ({per_cpu / k:.2f} CPU-s a render)")
    print(f"  one process, batch     : {b_wall:7.1f} s wall {b_cpu:7.1f} s CPU ({b_cpu / k:.2f} CPU-s a render)")
    print(f"  ratio (per process / batch): wall {per_wall / b_wall:.2f}x, CPU {per_cpu / b_cpu:.2f}x")
    print(f"  preview images identical between the routes: {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
