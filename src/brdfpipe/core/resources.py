"""The machine's memory and disk, for bounds checked before a command starts working.

A command whose size comes from the user (``brdfpipe synth --count``,
``sample --count``, ``render --resolution``) computes what it will need
from a per-item cost (bytes of disk per material file, bytes of memory per
pixel) and refuses up front, in one line giving the limit and why, when the
machine cannot hold it — instead of running for hours with growing memory
or filling the disk.  Standard library only.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from brdfpipe.core.atomic import OutputError, existing_ancestor

__all__ = [
    "ResourceError",
    "physical_memory",
    "free_bytes",
    "format_bytes",
    "check_free_space",
    "check_memory",
]


class ResourceError(ValueError):
    """The machine cannot hold what was asked for (memory or disk); the message gives the limit."""


def physical_memory() -> int:
    """Bytes of physical memory of this machine (0 when unknown)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 0


def free_bytes(path: str | os.PathLike[str]) -> int:
    """Bytes free to this user on the file system that holds ``path`` (or its nearest existing ancestor)."""
    return int(shutil.disk_usage(existing_ancestor(Path(path))).free)


def format_bytes(n: float) -> str:
    """``n`` bytes in decimal units, three significant digits (``35 MB``, ``3.5 PB``)."""
    value = float(n)
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(value) < 1000.0:
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.3g} {unit}"
        value /= 1000.0
    return f"{value:.3g} EB"


def check_free_space(out: str | os.PathLike[str], need: int, *, what: str, how: str = "") -> None:
    """Raise :class:`OutputError` if the file system of ``out`` has fewer than ``need`` bytes free.

    ``what`` starts the message (the option and its value); ``how`` says how
    ``need`` was computed (e.g. ``"1000 materials × 35 MB"``).
    """
    free = free_bytes(out)
    if need > free:
        detail = f" ({how})" if how else ""
        raise OutputError(f"{what}: needs {format_bytes(need)}{detail} but the file system of {out} has "
                          f"{format_bytes(free)} free; nothing was written")


def check_memory(need: int, *, what: str, how: str = "", memory: int | None = None) -> None:
    """Raise :class:`ResourceError` if ``need`` bytes exceed this machine's physical memory.

    ``memory`` overrides the machine's (tests).  Nothing is checked when the
    machine's memory is unknown.
    """
    total = physical_memory() if memory is None else int(memory)
    if total > 0 and need > total:
        detail = f" ({how})" if how else ""
        raise ResourceError(f"{what}: needs about {format_bytes(need)} of memory{detail}, more than this "
                            f"machine's {format_bytes(total)}")
