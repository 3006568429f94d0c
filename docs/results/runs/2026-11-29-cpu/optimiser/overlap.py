#!/usr/bin/env python
"""Issue 33's lead "neighbouring candidates share most of their cells", measured.

Share of an image's distinct MERL cells that a one-step move keeps (near-field, 25°), per
axis and grid, and the rows a Gram update by the move would take against the rows of the moved
image's own Gram (cells whose pixel count changes, added or removed).  Geometry only (the
measured cells, observation_cells' default mask), 40 random configurations (seed 1) that
observe something at 32 px.  ``PYTHONPATH=src python overlap.py``, 9 s.
"""
import numpy as np
from brdfpipe.acquisition import geometry as g
rng = np.random.default_rng(1)
configs = []
s0 = g.Setup("nearfield", fov_deg=25.0, grid=32)
while len(configs) < 40:
    c = (int(rng.integers(0, 90)), int(rng.integers(0, 90)), int(rng.integers(0, 180)))
    if g.observation_cells(s0, c).size:
        configs.append(c)
for grid in (32, 128, 256):
    s = g.Setup("nearfield", fov_deg=25.0, grid=grid)
    out = []
    for axis in range(3):
        shares, sizes = [], []
        for c in configs:
            u = np.unique(g.observation_cells(s, c))
            m = list(c); m[axis] += 1
            if m[axis] >= (90, 90, 180)[axis]: continue
            v = np.unique(g.observation_cells(s, tuple(m)))
            if u.size and v.size:
                shares.append(np.intersect1d(u, v).size / u.size); sizes.append(u.size)
        out.append(f"axis {axis}: kept {np.median(shares):.2f} (median; {np.min(shares):.2f}-{np.max(shares):.2f})")
    print(f"{grid:4d} px, distinct cells median {int(np.median(sizes))}:", "; ".join(out))
print("rows of the Gram's change (cells whose count changes, added or removed) / rows of the moved image's own Gram:")
for grid in (128, 256):
    s = g.Setup("nearfield", fov_deg=25.0, grid=grid)
    out = []
    for axis in range(3):
        fr = []
        for c in configs:
            m = list(c); m[axis] += 1
            if m[axis] >= (90, 90, 180)[axis]: continue
            a = g.observation_cells(s, c); b = g.observation_cells(s, tuple(m))
            if not a.size or not b.size: continue
            ua, ca = np.unique(a, return_counts=True); ub, cb = np.unique(b, return_counts=True)
            allc = np.union1d(ua, ub)
            da = np.zeros(allc.size); da[np.searchsorted(allc, ua)] = ca
            db = np.zeros(allc.size); db[np.searchsorted(allc, ub)] = cb
            fr.append(np.count_nonzero(da != db) / ub.size)
        out.append(f"axis {axis}: {np.median(fr):.2f}")
    print(f"{grid:4d} px:", "; ".join(out))
