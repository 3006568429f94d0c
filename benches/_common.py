"""Helpers shared by the benchmark scripts (run as `python benches/NAME.py`)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path


def best_time(fn: Callable[[], object], rounds: int) -> float:
    """Best wall time in seconds of ``rounds`` calls of ``fn``."""
    best = float("inf")
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def training_materials(store_path: Path, splits: Path):
    """The opened store and its training materials from ``splits.json`` (all materials without it).

    Exits with a message if the split file describes another store.
    """
    from brdfpipe.data import store

    st = store.open_store(store_path)
    if not splits.is_file():
        return st, list(st.materials)
    doc = json.loads(splits.read_text())
    train = list(doc["train"])
    if doc.get("database") != st.database or not set(train) <= set(st.materials):
        raise SystemExit(f"{splits} does not describe {store_path}")
    return st, train
