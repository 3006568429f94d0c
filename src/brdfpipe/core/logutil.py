"""Logging set-up shared by the command line and the workflow scripts."""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from brdfpipe.core import atomic, stamps
from brdfpipe.core.threads import THREAD_VARIABLES

__all__ = ["QUIET_LOGGERS", "log_to", "quiet_third_party", "setup_console_logging"]

_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
#: Third-party loggers that chatter at INFO (fontTools writes one line per PDF
#: font subset: half of a run's console output); they log warnings only.
QUIET_LOGGERS: tuple[str, ...] = ("fontTools", "matplotlib", "PIL", "numcodecs", "zarr", "asyncio", "urllib3")


def quiet_third_party(level: int = logging.WARNING) -> None:
    """Raise the threshold of :data:`QUIET_LOGGERS` to ``level``."""
    for name in QUIET_LOGGERS:
        logging.getLogger(name).setLevel(level)


def setup_console_logging(level: int = logging.INFO) -> None:
    """Send brdfpipe's log records to stderr (used by the ``brdfpipe`` CLI)."""
    logging.basicConfig(level=level, format=_FORMAT, stream=sys.stderr, force=True)
    quiet_third_party()


@contextmanager
def log_to(path: str | Path, level: int = logging.INFO, console_level: int = logging.WARNING, *,
           stamp: str | Path | None = None) -> Iterator[logging.Logger]:
    """Log to ``path`` (records from ``level`` on) and to stderr (from ``console_level`` on) during a job.

    The job log keeps the detail (progress, optimiser steps, per-pass
    messages); the console, which Snakemake shares between all jobs of a run,
    gets only warnings and errors, so that a run prints Snakemake's progress
    and what needs attention.

    An exception escaping the block is written with its traceback to the log
    before it propagates, so a failed job's log says why it failed.  The job
    holds the lease on its log file for the block
    (:func:`brdfpipe.core.atomic.job_lease`): if a newer run starts the same
    job (Snakemake deletes the log first), this process puts no output in
    place any more.

    ``stamp``: the job's stamp (its input ``stamp``, :mod:`brdfpipe.core.stamps`).
    When the block ends without error, the stamp's text as the job found it
    is written to its done mark (:func:`brdfpipe.core.stamps.mark_done`,
    under the lease): the next run takes the job's outputs as made by that
    definition; a job killed or failed before leaves the stamp out of date.
    """
    path = Path(path)
    started_with = None if stamp is None else stamps.read_stamp(stamp)
    path.parent.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    file_handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    opened = os.fstat(file_handler.stream.fileno())
    console = logging.StreamHandler(sys.stderr)
    console.setLevel(console_level)
    handlers: list[logging.Handler] = [file_handler, console]
    for h in handlers:
        h.setFormatter(logging.Formatter(_FORMAT))
        root.addHandler(h)
    old_level = root.level
    root.setLevel(level)
    quiet_third_party()
    logger = logging.getLogger("brdfpipe.workflow")
    logger.info("thread settings: %s", " ".join(f"{k}={os.environ.get(k, '(unset)')}" for k in THREAD_VARIABLES))
    try:
        with atomic.job_lease(path, opened):
            yield logger
            if started_with is not None:
                stamps.mark_done(stamp, started_with)
    except BaseException:
        logger.exception("job failed")
        raise
    finally:
        for h in handlers:
            root.removeHandler(h)
            h.close()
        root.setLevel(old_level)
