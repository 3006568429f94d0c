"""Test-suite wide settings.

The Slurm run (tests/test_slurm.py) takes minutes, nearly all of them waiting
on Slurm's queue: it runs in the background, beside the suite.  The test that
starts it is moved to the front of the collection, so that under pytest-xdist
(`make test` runs `-n 2`) it starts at once; the test that waits for it and
compares it with the session's shared local run of tiny-point
(tests/shared_runs.py) is moved to the end, after the other test that reads
that run, so that both find their runs built rather than wait for them.
"""

from __future__ import annotations

import pytest

FIRST = ("tests/test_slurm.py::test_slurm_takes_the_workflows_jobs",)
LAST = ("tests/test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-point]",
        "tests/test_slurm.py::test_workflow_on_slurm_matches_local_run")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> tuple[int, int]:
        if item.nodeid in FIRST:
            return 0, 0
        if item.nodeid in LAST:
            return 2, LAST.index(item.nodeid)
        return 1, 0

    items.sort(key=rank)
