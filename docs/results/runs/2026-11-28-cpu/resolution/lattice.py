"""The held-out error of fixed direction sets looked up on every lattice (lattice.csv here).

    python lattice.py RESULTS    (RESULTS: the runs' results/ folder: merl.zarr, svd/train.zarr, splits.json;
                                  reads grid<G>[-seed<S>]/directions/train/nearfield-fov*-error.json)

A run at another grid changes two things at once: the lattice the sets are observed on, and the sets the
optimiser picks (a search seeded like every other, whose outcome moves by more than 2 % between seeds).  Here
the sets of every run are kept and only the lattice changes (table lookup, eta = 40, the runs' held-out
materials), so the lattice's own effect is read without the optimiser's.  Each run's own lattice must give back
its errors.csv (checked).  A second column looks the same sets up with eta grown with the pixel count,
eta = 40 (g / 32)^2: every pixel is a row of eq. 4, so a finer lattice weighs the data more against a fixed
eta; with the scaled eta the balance stays that of 32 pixels and only which cells are seen changes.
"""

import csv
import re
import sys
from pathlib import Path

import numpy as np

from brdfpipe.acquisition import evaluation, optimize
from brdfpipe.acquisition.geometry import Setup, observation_cells
from brdfpipe.core import integrity

HERE = Path(__file__).resolve().parent
FOVS = (15, 25, 35, 45)


def _lookup(results: Path, test: list[str], selections: list, labels: list, eta: float) -> dict:
    """Held-out mean rms_log of each selection (one streamed pass over the store)."""
    rows = evaluation.evaluate_selections(results / "merl.zarr", results / "svd/train.zarr", selections,
                                          test_materials=test, eta=eta, linear=False)
    return {labels[int(r["metric"])]: float(r["value"]) for r in rows
            if r["material"] == "mean" and r["kind"] == "rms_log" and r["setup"] == "nearfield"}


def main() -> None:
    results = Path(sys.argv[1])
    test = integrity.read_json(results / "splits.json", kind="splits file")["test"]
    runs = {}
    for p in sorted(HERE.iterdir()):
        if p.is_dir() and (m := re.fullmatch(r"grid(\d+)(?:-seed(\d+))?", p.name)):
            runs[(int(m[1]), int(m[2] or 2016))] = p
    grids = sorted({g for g, _ in runs})
    selections, labels = [], []
    for (g, seed), folder in sorted(runs.items()):
        for fov in FOVS:
            d = optimize.read_directions(folder / f"directions/train/nearfield-fov{fov}-error.json")
            assert d.setup.grid == g and d.split == "train" and d.eta == 40.0, (folder, fov)
            for s in d.sets:
                for at in grids:
                    cells = np.concatenate([observation_cells(Setup("nearfield", float(fov), at), c)
                                            for c in s.configurations])
                    # the run and the lattice ride in the metric label: evaluate_selections writes it back
                    label = f"{len(labels)}"
                    selections.append(({"setup": "nearfield", "fov": fov, "metric": label, "n": s.n}, cells))
                    labels.append((g, seed, at, fov, s.n))
    # one streamed pass over the store for every selection, with eta = 40 (the runs')
    value = _lookup(results, test, selections, labels, 40.0)
    for (g, seed), folder in sorted(runs.items()):
        _, own = integrity.read_csv_rows(folder / "errors.csv")
        for r in own:
            if r["setup"] == "nearfield" and r["material"] == "mean" and r["kind"] == "rms_log":
                v = value[(g, seed, g, int(float(r["fov"])), int(r["n"]))]
                assert abs(v - float(r["value"])) <= 1e-9 * v, (folder, r, v)
    # and with eta grown with the pixels, eta = 40 (g / 32)^2: the data's weight against eta as at 32 pixels
    scaled = {key: v for key, v in value.items() if key[2] == 32}  # eta = 40 there already
    for at in (g for g in grids if g != 32):
        mine = [i for i, lab in enumerate(labels) if lab[2] == at]
        scaled.update(_lookup(results, test, [selections[i] for i in mine], labels,  # labels: by global index
                              40.0 * (at / 32) ** 2))
    out = [[*key, f"{v:.6g}", f"{scaled[key]:.6g}"] for key, v in sorted(value.items())]
    with open(HERE / "lattice.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["grid", "seed", "looked_up_at_grid", "fov", "n", "heldout_error", "heldout_error_eta_scaled"])
        w.writerows(out)


if __name__ == "__main__":
    main()
