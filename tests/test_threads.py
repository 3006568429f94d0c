"""brdfpipe.core.threads: a job's BLAS uses the threads its rule declares."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.core.threads import JOB_ENVIRONMENT, blas_threads, openblas_libraries


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


@pytest.mark.slow
def test_jobs_run_with_their_rules_threads_and_blas_threads_that_sleep(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """Each job's log gives its thread settings: its rule's ``threads`` and a short OpenBLAS spin.

    decompose_svd declares 2 threads, fit_gplvm 1; both run with
    ``OPENBLAS_THREAD_TIMEOUT`` of :data:`JOB_ENVIRONMENT` (set by the
    Snakefile), so their idle BLAS threads sleep instead of spinning.
    """
    from shared_runs import shared_run

    work = shared_run(tmp_path_factory, Path(__file__).resolve().parent / "config" / "tiny.yaml")
    timeout = JOB_ENVIRONMENT["OPENBLAS_THREAD_TIMEOUT"]
    for log, threads in ((work / "logs" / "decompose_svd" / "all.log", 2),
                         (next((work / "logs" / "fit_gplvm").rglob("*.log")), 1)):
        text = log.read_text()
        assert f"OPENBLAS_NUM_THREADS={threads} OPENBLAS_THREAD_TIMEOUT={timeout}" in text, (log, text[:2000])
