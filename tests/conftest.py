"""Test-suite wide settings: the order the tests start in.

`make test` runs pytest under xdist (`-n 2 --maxschedchunk 2`): each worker
takes the next two tests of the collection whenever it runs short, so the
collection's order is the order the tests start in.  The suite is
CPU-bound on two cores; it ends soonest when the long tests start first and
the short ones fill in at the end, and when no worker waits on a shared run
another is building (tests/shared_runs.py).  So:

* The test that starts the Slurm run (tests/test_slurm.py), which takes
  minutes of waiting on Slurm's queue, comes first: the run goes on beside
  the suite.
* Then the tests that build the session's shared runs and the long
  workflow tests (:data:`EARLY`, in that order): the first two build
  different runs (tiny-nbrdf and tiny), so neither worker waits on the other.
* Last, the test that waits for the Slurm run and compares it with the
  shared run of tiny-point, after the other test that reads that run, so
  that both find their runs built rather than wait for them (:data:`LAST`).

And the cores it takes: numpy's and scipy's OpenBLAS each start a thread per
core, so two workers on two cores ran four BLAS threads that spun while they
waited for a core (five BLAS-heavy test files took 1.4x the time and 1.6x
the CPU).  Each worker's BLAS gets its share of the cores
(:func:`pytest_configure`).  Workflow jobs the tests start are not touched:
each job sets its own BLAS threads from its rule (brdfpipe.core.threads).

And the disk it takes: the suite's runs write tens of GB in all, more than a
fresh machine may have free, so nothing outlives its use.  A passing test's
``tmp_path`` goes at its teardown (``tmp_path_retention_policy = "failed"``
in pyproject.toml), and a module's folders (its module-scoped fixtures'
``tmp_path_factory.mktemp``) go when the module's fixtures are torn down
(:func:`_module_folders_removed`), unless a test of this worker failed: then
everything stays for inspection.  The session's shared folders (the shared
runs and the Slurm run: tests/shared_runs.py, names starting with
``SHARED_PREFIX``) live to the session's end: beside the workers' folders
under xdist, in the session's folder without it; a session-scoped fixture
must put its folder there too.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
from collections.abc import Iterator

import pytest

from shared_runs import SHARED_PREFIX

FIRST = ("tests/test_slurm.py::test_slurm_takes_the_workflows_jobs",)
#: Node-id prefixes of the long tests, started in this order after FIRST.
EARLY = ("tests/test_documented_commands.py::test_the_report_commands",
         "tests/test_resume.py::test_candidates_config_change_interrupted_and_resumed",
         "tests/test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-nearfield]",
         "tests/test_resume.py::",
         "tests/test_documented_commands.py::",
         "tests/test_workflow.py::",
         "tests/test_marks_workflow.py::",
         "tests/test_unseen.py::",
         "tests/test_solerfigs.py::")
LAST = ("tests/test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-point]",
        "tests/test_slurm.py::test_workflow_on_slurm_matches_local_run")


_blas = contextlib.ExitStack()


def _keep_freed_memory() -> None:
    """Let glibc's malloc reuse freed blocks of up to 1 GiB instead of unmapping them (this process only).

    Its default unmaps every block over 32 MiB when freed, so each full MERL table
    (35 MB) a test makes is faulted in and zeroed by the kernel again: in
    test_merl_format.py and test_logmap.py, 4.5 million page faults and 40 % of
    their CPU in the kernel.  The process keeps up to 1 GiB more of freed
    memory.
    """
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:  # not glibc: its own allocator
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    for param in (m_mmap_threshold, m_trim_threshold):
        libc.mallopt(param, 1 << 30)


def pytest_configure(config: pytest.Config) -> None:
    """This process's malloc keeps freed memory (:func:`_keep_freed_memory`); under xdist, this worker's BLAS gets
    its share of the cores (in this process only, not its children)."""
    _keep_freed_memory()
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if workers > 1:
        from brdfpipe.core.threads import blas_threads

        _blas.enter_context(blas_threads(max(1, (os.cpu_count() or 1) // workers)))


def pytest_unconfigure(config: pytest.Config) -> None:
    _blas.close()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> tuple[int, int]:
        if item.nodeid in FIRST:
            return 0, 0
        if item.nodeid in LAST:
            return 3, LAST.index(item.nodeid)
        for i, prefix in enumerate(EARLY):
            if item.nodeid.startswith(prefix):
                return 1, i
        return 2, 0

    items.sort(key=rank)


_failed = False


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    global _failed
    if report.failed:
        _failed = True


@pytest.fixture(scope="module", autouse=True)
def _module_folders_removed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Remove the folders a test module made in this worker's temporary folder once its fixtures are torn down."""
    base = tmp_path_factory.getbasetemp()
    before = set(base.iterdir())
    yield
    if _failed:
        return
    for path in set(base.iterdir()) - before:
        if not path.name.startswith(SHARED_PREFIX):
            shutil.rmtree(path, ignore_errors=True)
