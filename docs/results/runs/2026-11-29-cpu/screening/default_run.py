"""The screened greedy add (``acquisition.screen_grid: 32``, keep 10) against a default run's own directions.

For every image set-up optimised with the E(S) metric in a finished default run (its
``results/directions/{train,all}/*-error.json``, exhaustive search, 256 px, n = 1..5), re-run the
optimisation with the same model, parameters and seed, screened, and compare each n's configurations
and E(S) with the stored set. The ``train`` split first re-runs one file exhaustively, to show that the
current code reproduces the stored file.

    OPENBLAS_NUM_THREADS=1 python default_run.py RUN_DIR train > default-run-train.jsonl
    OPENBLAS_NUM_THREADS=1 python default_run.py RUN_DIR all > default-run-all.jsonl
"""

import glob
import json
import sys
import time

from brdfpipe.acquisition import svd
from brdfpipe.acquisition.candidates import Screen
from brdfpipe.acquisition.optimize import optimize, read_directions

root, split = f"{sys.argv[1]}/results", sys.argv[2]
model = svd.open_model(f"{root}/svd/{split}.zarr")
files = [f for f in sorted(glob.glob(f"{root}/directions/{split}/*-error.json")) if "point" not in f]
if split == "train":
    files = [f"{root}/directions/train/nearfield-fov25-error.json#exhaustive"] + files
for entry in files:
    path, _, how = entry.partition("#")
    d = read_directions(path)
    c0 = time.process_time()
    sets = optimize(model, d.setup, metric="error", n_max=len(d.sets), candidates=500, eta=d.eta, beta=d.beta,
                    seed=d.seed, log=None, screen=None if how == "exhaustive" else Screen(32, 10))
    cpu = time.process_time() - c0
    print(json.dumps({"file": path.split("results/")[1], "method": how or "screened-32-keep10", "cpu_s": round(cpu, 1),
                      "same_sets_per_n": [a.configurations == b.configurations for a, b in zip(sets, d.sets)],
                      "E_rel_diff_per_n": [a.expected_error / b.expected_error - 1 for a, b in zip(sets, d.sets)]}),
          flush=True)
