"""The small store of the GPLVM and Gram tests: six synthetic materials, and its data as dense arrays.

Module-scoped fixtures, imported by tests/test_gplvm.py and tests/test_gram.py
(each module builds its own store once).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfpipe.data import ingest, store, synth
from brdfpipe.data.merl import N_CELLS


@pytest.fixture(scope="module")
def small_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("gram")
    db = tmp / "db"
    synth.synthesize(db, count=6, seed=1, jobs=1, progress=False)
    out = tmp / "merl.zarr"
    ingest.ingest(sorted(db.glob("*.binary")), out, database="synthetic", jobs=1)
    return out


@pytest.fixture(scope="module")
def dense(small_store: Path) -> dict[str, np.ndarray]:
    """The store's data as dense float64 arrays (6 materials: small enough)."""
    st = store.open_store(small_store)
    brdf = np.asarray(st.brdf[:], dtype=np.float32)
    valid = np.asarray(st.valid[:], dtype=bool)
    cells = np.flatnonzero(valid)
    data = brdf.reshape(st.n_materials, 3, N_CELLS)[:, :, cells]  # float32 (n, 3, p)
    return {"brdf": brdf, "valid": valid, "cells": cells, "data": data}
