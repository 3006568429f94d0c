"""The greedy add screened on a coarse lattice (``acquisition.screen_grid``, ours) against the exhaustive add.

Xu §5.1's greedy add scores every one of its t random candidates at the full image lattice;
:class:`brdfpipe.acquisition.candidates.Screen` scores them at a coarse lattice (counts scaled to the
full one) and only the ``keep`` best in full.  This runs both on the same model, draws and local
search, one near-field optimisation (n = 1, 2, E(S) metric) per grid, FOV and seed:

    OPENBLAS_NUM_THREADS=1 python screen.py MODEL --coarse 32 --keep 10 --grids 32,128,256 \\
        --fovs 15,25,35 --seeds 0,1 > results.jsonl

One JSON line per (grid, FOV, seed, method): CPU seconds of ``optimize`` (this process, one BLAS
thread), E(S) after the greedy add and after the local search for n = 1, 2, and the configurations.
"""

from __future__ import annotations

import argparse
import json
import time

from brdfpipe.acquisition import geometry, svd
from brdfpipe.acquisition.candidates import Screen
from brdfpipe.acquisition.optimize import optimize


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("--coarse", type=int, default=32)
    ap.add_argument("--keep", type=int, default=10)
    ap.add_argument("--grids", default="32,128,256")
    ap.add_argument("--fovs", default="15,25,35")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--candidates", type=int, default=500)
    args = ap.parse_args()
    model = svd.open_model(args.model)
    screen = Screen(args.coarse, args.keep)
    # untimed warm-up: the first call alone pays Q's first read from disk and the lazy imports
    optimize(model, geometry.Setup("nearfield", 25.0, 32), metric="error", n_max=1, candidates=10, log=None)
    for grid in (int(g) for g in args.grids.split(",")):
        for fov in (float(f) for f in args.fovs.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                for method in ("exhaustive", f"screened-{args.coarse}-keep{args.keep}"):
                    if method != "exhaustive" and grid <= args.coarse:
                        continue
                    c0 = time.process_time()
                    sets = optimize(model, geometry.Setup("nearfield", fov, grid), metric="error", n_max=2,
                                    candidates=args.candidates, seed=seed, log=None,
                                    screen=None if method == "exhaustive" else screen)
                    cpu = time.process_time() - c0
                    print(json.dumps({"grid": grid, "fov": fov, "seed": seed, "method": method, "cpu_s": round(cpu, 2),
                                      "greedy_E": [s.greedy_value for s in sets], "E": [s.expected_error for s in sets],
                                      "configs": [[list(map(int, c)) for c in s.configurations] for s in sets]}),
                          flush=True)


if __name__ == "__main__":
    main()
