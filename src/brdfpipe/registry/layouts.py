"""The layout of the folders one stage writes and another reads: a MERL folder, a synthetic database.

A *MERL folder* holds one ``<material>.binary`` per material (the MERL
format, :mod:`brdfpipe.data.merl`): real MERL, a database of fits evaluated
on the MERL grid, or the synthetic database.  A *synthetic database* folder
adds its ``manifest.json`` (the plan, seed, noise and every material's
generation record); the workflow also keeps each material's record as
``records/<material>.json`` until the manifest gathers them.  The writers
(:mod:`brdfpipe.data.synth`, :mod:`brdfpipe.data.nbrdf`), the folder
labeller (:mod:`brdfpipe.data.database`) and the DAG's file names
(:mod:`brdfpipe.core.filenames`) build these names here.  Standard library only.
"""

from __future__ import annotations

__all__ = ["MERL_SUFFIX", "SYNTHETIC_MANIFEST", "SYNTHETIC_RECORDS", "merl_file", "record_file"]

#: Suffix of a MERL-format file (exactly, lower case).
MERL_SUFFIX: str = ".binary"
#: The synthetic database's manifest, in its folder.
SYNTHETIC_MANIFEST: str = "manifest.json"
#: The sub-folder of the workflow's per-material generation records.
SYNTHETIC_RECORDS: str = "records"


def merl_file(material: str) -> str:
    """A material's file name in a MERL folder: ``<material>.binary``."""
    return f"{material}{MERL_SUFFIX}"


def record_file(material: str) -> str:
    """A material's generation record in a synthetic database folder: ``records/<material>.json``."""
    return f"{SYNTHETIC_RECORDS}/{material}.json"
