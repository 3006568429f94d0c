#!/usr/bin/env python
"""Principal-component spectrum of the log-mapped database in a store.

How many principal components of the log-mapped set explain 90/95/99/99.9 %
of its variance — the check that the synthetic database is not trivially
low-dimensional.  Rows are material-channels (3 × materials), columns the cells
measured in every material; ρ → ln((ρ·w + ε)/(ρ_ref·w + ε)) with ε = 0.001,
w = max(cos θi · cos θo, 0.01) at the cell centre and ρ_ref the per-cell median
over the rows (Xu et al. 2016 §3, Nielsen et al. 2015's weighting); rows are
then mean-centred and the eigenvalues of the row Gram matrix (accumulated in
float64 over cell blocks, never holding the matrix densely) are the variances.

Usage::

    python benches/spectrum.py [results/merl.zarr] [--step 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from brdfpipe.data import merl, store

EPS = 1e-3


def log_spectrum(path: str, step: int = 1, block: int = store.CHUNK_COLS) -> tuple[np.ndarray, str, int]:
    """Eigenvalues (descending) of the centred log-mapped row Gram matrix, database kind, columns."""
    st = store.open_store(path)
    valid = np.asarray(st.valid[:])
    n = st.n_materials
    gram = np.zeros((3 * n, 3 * n))
    row_sum = np.zeros(3 * n)
    cols = 0
    for start in range(0, merl.N_CELLS, block):
        stop = min(start + block, merl.N_CELLS)
        cells = start + np.flatnonzero(valid[start:stop])[::step]
        if cells.size == 0:
            continue
        wi, wo = merl.cell_directions(cells)
        w = np.maximum(wi[:, 2] * wo[:, 2], 0.01)
        rows = np.concatenate(
            [np.asarray(st.brdf[:, c * merl.N_CELLS + start : c * merl.N_CELLS + stop])[:, cells - start]
             for c in range(3)]
        ).astype(np.float64)  # (3n, cells): channel-major rows
        ref = np.median(rows, axis=0)
        x = np.log((rows * w + EPS) / (ref * w + EPS))
        gram += x @ x.T
        row_sum += x.sum(axis=1)
        cols += cells.size
    # Centre the columns over rows: Xc = (I - 11ᵀ/m) X  →  Gc = C G C.
    m = 3 * n
    centre = np.eye(m) - 1.0 / m
    gc = centre @ gram @ centre
    eig = np.sort(np.linalg.eigvalsh(gc))[::-1].clip(min=0.0)
    return eig, st.database, cols


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("store", nargs="?", default="results/merl.zarr")
    ap.add_argument("--step", type=int, default=1, help="use every step-th valid cell (default 1: all)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    eig, database, cols = log_spectrum(args.store, args.step)
    frac = np.cumsum(eig) / eig.sum()
    print(f"store {args.store} ({database} database): {eig.size} rows x {cols} columns, "
          f"{time.perf_counter() - t0:.1f} s")
    for level in (0.90, 0.95, 0.99, 0.999):
        print(f"  {100 * level:5.1f} % of variance: {int(np.searchsorted(frac, level) + 1):4d} components")


if __name__ == "__main__":
    main()
