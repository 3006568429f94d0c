"""The small pipeline of the acquisition tests, built once per test module that asks for it.

Eight synthetic materials (``synth.synthesize``) → store → ``train`` log-map
holding out two materials (m = 18 rows, p ≈ 1.1 M) → PCA model (k = 17) → two
optimised directions files (point n ≤ 3 and near-field 25° n ≤ 2, few
candidates).  The dense references hold Q (p × k float64, 150 MB) and the
log-mapped rows in memory.

Used by tests/test_reconstruct.py and tests/test_evaluation.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from brdfpipe.acquisition import geometry, optimize, svd
from brdfpipe.acquisition.geometry import Setup
from brdfpipe.core import filenames
from brdfpipe.data import ingest, logmap, merl, store, synth
from brdfpipe.data.database import database_from_folder


class Data:
    """Paths and dense arrays of the small pipeline."""

    def __init__(self, d: Path) -> None:
        synth.synthesize(d / "db", count=8, seed=11, noise=0.01, jobs=1, progress=False)
        db = database_from_folder(d / "db", key="folder")
        self.dir = d
        self.store = d / "merl.zarr"
        ingest.ingest(db.sources, self.store, database=db.kind, jobs=1)
        st = store.open_store(self.store)
        self.materials = list(st.materials)
        self.test = [self.materials[1], self.materials[6]]
        self.train = [m for m in self.materials if m not in self.test]
        self.logmap = d / "logmap" / "train.zarr"
        logmap.write_logmap(self.store, self.logmap, split="train", materials_train=self.train)
        self.model_path = d / "svd" / "train.zarr"
        svd.fit(self.logmap, self.model_path)
        self.model = svd.open_model(self.model_path)
        m = self.model
        self.Q = np.asarray(m.Q[:], dtype=np.float64)
        self.X = np.asarray(logmap.open_logmap(self.logmap).X[:], dtype=np.float64)
        # Held-out rows: physical values at the model's columns and their log-map (train reference).
        rows = [self.materials.index(n) for n in self.test]
        self.rho_test = np.stack([np.asarray(st.brdf[r], dtype=np.float64).reshape(3, merl.N_CELLS)[:, m.cells]
                                  for r in rows]).reshape(-1, m.p)  # (6, p), row 3i + c
        self.X_test = logmap.forward(self.rho_test, m.reference, m.weight, m.epsilon)
        # Two optimised directions files.
        self.dirs: dict[str, Path] = {}
        for kind, fov, n_max in (("point", 0.0, 3), ("nearfield", 25.0, 2)):
            setup = Setup(kind, fov, 16)
            sets = optimize.optimize(m, setup, metric="error", n_max=n_max, candidates=6, steps=(1,), seed=3,
                                     log=lambda line: None)
            self.dirs[kind] = optimize.write_directions(
                d / filenames.directions("train", kind, fov, "error"), sets, setup=setup, metric="error",
                split="train", model_path=self.model_path, seed=3, eta=40.0, beta=0.0, database=m.database)

    def rows_of(self, path: Path, n: int) -> NDArray[np.intp]:
        """Model columns observed by set n of a directions file (recomputed independently)."""
        d = optimize.read_directions(path)
        lut = np.full(merl.N_CELLS, -1, dtype=np.intp)
        lut[self.model.cells] = np.arange(self.model.p)
        (s,) = [s for s in d.sets if s.n == n]
        cells = np.concatenate([geometry.observation_cells(d.setup, c, lut >= 0) for c in s.configurations])
        return lut[cells]


def dense_coef(Q: NDArray[np.float64], y: NDArray[np.float64], eta: float) -> NDArray[np.float64]:
    """(QᵀQ + ηI)⁻¹ Qᵀ y for y (n, r)."""
    return np.linalg.solve(Q.T @ Q + eta * np.eye(Q.shape[1]), Q.T @ y)
