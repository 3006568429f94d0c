"""Test-suite wide settings.

The Slurm test (tests/test_slurm.py) takes minutes, most of them waiting on
Slurm's job-state polling: it is moved to the front of the collection so that,
under pytest-xdist (`make test` runs `-n 2`), one worker starts it at once and
the other worker runs the rest of the suite beside it.
"""

from __future__ import annotations

import pytest

FIRST = ("tests/test_slurm.py",)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: not item.nodeid.startswith(FIRST))
