"""E(S) of each run's optimal single image at 25 degrees, scored on every grid's lattice (rescore.csv here).

    python rescore.py MODEL    (MODEL: the runs' results/svd/all.zarr; reads grid<G>[-seed<S>]/directions/all/
                                nearfield-fov25-error.json)

E(S) (Xu eq. 15) counts every pixel as an observation against a fixed eta = 40, so the same direction scores
lower on a finer lattice.  Scoring every run's direction on one lattice separates "a better direction" from
"more pixels".  Each run's own lattice must give back the E(S) its directions file records (checked).
"""

import csv
import re
import sys
from pathlib import Path

import numpy as np

from brdfpipe.acquisition import metrics, optimize, svd
from brdfpipe.acquisition.geometry import Setup, observation_cells
from brdfpipe.data import merl

HERE = Path(__file__).resolve().parent
FOV = 25.0


def main() -> None:
    model = svd.open_model(sys.argv[1])
    lookup = np.full(merl.N_CELLS, -1, dtype=np.int64)
    lookup[np.asarray(model.cells)] = np.arange(model.p)
    valid = lookup >= 0
    em = metrics.ErrorModel(model.sigma, model.U, eta=40.0, beta=0.0)
    runs = {}
    for p in sorted(HERE.iterdir()):
        if p.is_dir() and (m := re.fullmatch(r"grid(\d+)(?:-seed(\d+))?", p.name)):
            runs[(int(m[1]), int(m[2] or 2016))] = optimize.read_directions(p / "directions/all/nearfield-fov25-error.json")
    grids = sorted({g for g, _ in runs})
    rows = []
    for (g, seed), d in sorted(runs.items()):
        assert d.setup.grid == g and d.split == "all" and d.eta == 40.0 and d.beta == 0.0, (g, seed)
        (config,) = next(s for s in d.sets if s.n == 1).configurations
        for at in grids:
            cells = observation_cells(Setup("nearfield", FOV, at), config, valid)
            idx, count = np.unique(lookup[cells], return_counts=True)
            rows_q = np.asarray(model.Q.get_orthogonal_selection((idx, slice(None))), dtype=np.float64)
            G, qsum = metrics.selection_stats(np.repeat(rows_q, count, axis=0))  # a pixel is a row
            e = metrics.expected_error(em, G, qsum)
            if at == g:
                recorded = next(s for s in d.sets if s.n == 1).expected_error
                assert abs(e - recorded) <= 1e-6 * recorded, (g, seed, e, recorded)
            rows.append([g, seed, at, cells.size, f"{e:.6g}"])
    with open(HERE / "rescore.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["grid", "seed", "scored_at_grid", "observations", "expected_error"])
        w.writerows(rows)


if __name__ == "__main__":
    main()
