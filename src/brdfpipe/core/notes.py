"""A figure's note: one paragraph of the run's numbers, written next to the figure, quoted by its report caption.

:func:`brdfpipe.core.plot.finish` writes it (``<stem>.json``, with its
digest: :mod:`brdfpipe.core.integrity`) for the figures whose record says so
(:attr:`brdfpipe.registry.figures.Figure.note`); the report's captions
(:mod:`brdfpipe.report.captions`, rule ``write_claims``) read it back.
Light: no matplotlib, so the report's job reads notes without it.
"""

from __future__ import annotations

import os
from pathlib import Path

from brdfpipe.core import integrity

__all__ = ["NOTE_FORMAT", "write_note", "read_note"]

#: ``format`` of a note file.
NOTE_FORMAT = "brdfpipe.figure-note/1"


def write_note(stem: str | os.PathLike[str], title: str, note: str) -> Path:
    """Write ``<stem>.json`` (``format``, the figure's ``title``, ``note`` on one line; with its digest), atomically."""
    path = Path(stem).with_name(Path(stem).name + ".json")
    integrity.write_json(path, {"format": NOTE_FORMAT, "title": title, "note": " ".join(note.split())})
    return path


def read_note(path: str | os.PathLike[str], error: type[Exception] = integrity.IntegrityError) -> str:
    """The note of a note file (:func:`write_note`), its digest checked; ``error`` naming the file otherwise."""
    doc = integrity.read_json(path, kind="figure note", error=error)
    if doc.get("format") != NOTE_FORMAT or not isinstance(doc.get("note"), str):
        raise error(f"{path}: not a figure note (format {NOTE_FORMAT})")
    return str(doc["note"])
