"""Test-suite wide settings.

The Slurm test (tests/test_slurm.py) takes minutes, most of them waiting on
Slurm's job-state polling: it is moved to the front of the collection so that,
under pytest-xdist (`make test` runs `-n 2`), one worker starts it at once and
the other worker runs the rest of the suite beside it.  It first builds the
session's shared local run of tiny-point (tests/shared_runs.py); the other test
that reads that run is moved to the end, so that it finds the run built rather
than waiting for it.
"""

from __future__ import annotations

import pytest

FIRST = ("tests/test_slurm.py",)
LAST = ("tests/test_workflow.py::test_other_dag_shapes_run_end_to_end[tiny-point]",)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: 0 if item.nodeid.startswith(FIRST) else 2 if item.nodeid in LAST else 1)
