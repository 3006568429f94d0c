"""The number of BLAS threads a job uses: the threads its rule declares.

numpy and scipy each bundle their own OpenBLAS, and each starts as many
threads as the machine has cores when first used — more than a rule with
``threads: 1`` declares, and setting ``OPENBLAS_NUM_THREADS`` from a Snakemake
``script:`` is too late (the libraries are loaded when the script's first
import of numpy runs, before the script's own code).  :func:`blas_threads`
sets the thread count of every OpenBLAS loaded in the process at run time
and restores it afterwards, through ``threadpoolctl`` when it is installed and
otherwise through OpenBLAS's own ``*_set_num_threads`` functions (ctypes, on
the libraries listed in ``/proc/self/maps``; the symbol names of the numpy
and scipy wheels, ``scipy_openblas*``, and of a plain OpenBLAS).  Where
neither works (no OpenBLAS, not Linux) it does nothing and says so in the
log, once.

:func:`run_threads` runs work items on a few threads (reading and checking
files: CRC-32C and the file reads release the GIL).
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

__all__ = ["JOB_ENVIRONMENT", "THREAD_VARIABLES", "blas_threads", "openblas_libraries", "run_threads"]

logger = logging.getLogger("brdfpipe.core.threads")

_SET = ("openblas_set_num_threads", "openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
        "scipy_openblas_set_num_threads64_")
_GET = ("openblas_get_num_threads", "openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
        "scipy_openblas_get_num_threads64_")
_warned = False

#: Set in the environment of every job the workflow starts (workflow/Snakefile), unless already set.
#: An OpenBLAS thread spins for 2**28 cycles (about 0.1 s) after each call before it sleeps, so a job
#: with ``threads: 2`` kept its second core busy between its BLAS calls, taking a core from the job
#: beside it.  4 is the shortest spin OpenBLAS takes (2**4 cycles).  Measured on the tiny config
#: (2 cores, idle): evaluate_training_size 8.2 -> 4.2 CPU-s, the run's CPU 162 -> 155 s, wall the same.
JOB_ENVIRONMENT: dict[str, str] = {"OPENBLAS_THREAD_TIMEOUT": "4"}
#: The variables that set a job's thread pools (Snakemake sets the ``*_NUM_THREADS`` ones from the
#: rule's ``threads``); each job's log starts with their values.
THREAD_VARIABLES: tuple[str, ...] = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", *JOB_ENVIRONMENT)


def _load_blas() -> None:
    """Import numpy and scipy.linalg so that both OpenBLAS copies are loaded before they are set."""
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401


def openblas_libraries() -> list[tuple[str, ctypes.CDLL, ctypes._CFuncPtr, ctypes._CFuncPtr]]:
    """Every OpenBLAS mapped into this process: (path, library, set function, get function)."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return []
    paths = sorted({line.split()[-1] for line in maps.splitlines()
                    if "openblas" in line.rsplit("/", 1)[-1].lower() and "/" in line})
    out = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        set_fn = next((getattr(lib, n) for n in _SET if hasattr(lib, n)), None)
        get_fn = next((getattr(lib, n) for n in _GET if hasattr(lib, n)), None)
        if set_fn is not None and get_fn is not None:
            get_fn.restype = ctypes.c_int
            set_fn.argtypes = [ctypes.c_int]
            out.append((path, lib, set_fn, get_fn))
    return out


@contextlib.contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """Run the body with every loaded OpenBLAS limited to ``n`` threads (None: leave them alone).

    ``n`` is the job's declared thread count (``snakemake.threads``); a
    ValueError for ``n < 1``.  The previous counts are restored on exit.
    """
    global _warned
    if n is None:
        yield
        return
    if isinstance(n, bool) or int(n) != n or int(n) < 1:
        raise ValueError(f"threads must be a positive integer, got {n!r}")
    n = int(n)
    _load_blas()
    try:
        from threadpoolctl import threadpool_limits  # type: ignore[import-not-found]
    except ImportError:
        threadpool_limits = None
    if threadpool_limits is not None:
        with threadpool_limits(limits=n, user_api="blas"):
            yield
        return
    libs = openblas_libraries()
    if not libs and not _warned:
        _warned = True
        logger.info("no OpenBLAS found to limit to %d thread(s): BLAS threads left as they are", n)
    before = [(set_fn, int(get_fn())) for _, _, set_fn, get_fn in libs]
    for set_fn, _ in before:
        set_fn(n)
    try:
        yield
    finally:
        for set_fn, old in before:
            set_fn(old)


def run_threads(fn: Callable[[Any], None], items: Iterable[Any], threads: int) -> None:
    """Run ``fn(item)`` for all items on up to ``threads`` threads; re-raise the first error."""
    items = list(items)
    if threads <= 1 or len(items) <= 1:
        for it in items:
            fn(it)
        return
    with ThreadPoolExecutor(max_workers=threads) as ex:
        futures = [ex.submit(fn, it) for it in items]
        wait(futures, return_when=FIRST_EXCEPTION)
        for f in futures:
            f.cancel()
        for f in futures:
            if not f.cancelled():
                f.result()  # re-raises the first error in submission order
