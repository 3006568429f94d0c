"""Logging set-up shared by the command line and the workflow scripts."""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["log_to", "setup_console_logging"]

_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def setup_console_logging(level: int = logging.INFO) -> None:
    """Send brdfpipe's log records to stderr (used by the ``brdfpipe`` CLI)."""
    logging.basicConfig(level=level, format=_FORMAT, stream=sys.stderr, force=True)


@contextmanager
def log_to(path: str | Path, level: int = logging.INFO) -> Iterator[logging.Logger]:
    """Log to ``path`` (and stderr) for the duration of a workflow job.

    An exception escaping the block is written with its traceback to the log
    before it propagates, so a failed job's log says why it failed.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    handlers: list[logging.Handler] = [
        logging.FileHandler(path, mode="w", encoding="utf-8"),
        logging.StreamHandler(sys.stderr),
    ]
    for h in handlers:
        h.setFormatter(logging.Formatter(_FORMAT))
        root.addHandler(h)
    old_level = root.level
    root.setLevel(level)
    logger = logging.getLogger("brdfpipe.workflow")
    try:
        yield logger
    except BaseException:
        logger.exception("job failed")
        raise
    finally:
        for h in handlers:
            root.removeHandler(h)
            h.close()
        root.setLevel(old_level)
