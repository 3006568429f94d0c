"""brdfpipe.core.threads: a job's BLAS uses the threads its rule declares."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from brdfpipe.core.threads import blas_threads, openblas_libraries


def current_blas_threads() -> dict[str, int]:
    """Thread count of each loaded OpenBLAS (numpy's and scipy's), by library path (empty where none can be queried)."""
    importlib.import_module("scipy.linalg")  # scipy's own OpenBLAS, beside numpy's
    return {path: int(get()) for path, _, _, get in openblas_libraries()}


def test_every_openblas_is_limited_and_restored() -> None:
    before = current_blas_threads()
    if not before:
        pytest.skip("no OpenBLAS with a thread-count API loaded (threadpoolctl or another BLAS)")
    assert len(before) >= 2  # numpy's and scipy's own copies
    n = 2 if set(before.values()) == {1} else 1  # a count that differs from what they had (tests/conftest.py)
    with blas_threads(n):
        assert set(current_blas_threads().values()) == {n}
        a = np.random.default_rng(0).normal(size=(64, 64))
        assert np.allclose(np.linalg.inv(a) @ a, np.eye(64), atol=1e-8)  # BLAS still works
    assert current_blas_threads() == before


def test_none_leaves_threads_alone_and_bad_counts_raise() -> None:
    before = current_blas_threads()
    with blas_threads(None):
        assert current_blas_threads() == before
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError):
            with blas_threads(bad):  # type: ignore[arg-type]
                pass
