"""Which database a run uses: a folder of real MERL files, or the synthetic one.

The workflow reads the real MERL BRDF database from a folder named in the
config when a user has it; otherwise it generates a synthetic MERL-format
database (:mod:`brdfpipe.synth`).  This module resolves either into a
:class:`Database` (material names → source files) and resolves the held-out
``test_materials`` against it, with clear errors for a missing folder or an
unknown name.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from brdfpipe import synth
from brdfpipe.version import full_version
from brdfpipe.synth import default_test_count

__all__ = [
    "XU2016_TEST_MATERIALS",
    "EXTRA_TEST_MATERIAL",
    "Database",
    "DatabaseError",
    "merl_database",
    "synthetic_database",
    "folder_database",
    "default_test_count",
    "resolve_test_materials",
    "write_splits",
]

#: The nine held-out MERL materials named in Xu et al. 2016, §6 (Fig. 2 and its text).
XU2016_TEST_MATERIALS: tuple[str, ...] = (
    "black-soft-plastic",
    "blue-acrylic",
    "green-fabric",
    "light-red-paint",
    "pink-jasper",
    "silver-metallic-paint",
    "specular-violet-phenolic",
    "two-layer-silver",
    "white-fabric",
)
#: Our tenth held-out material: Xu's nine contain no bare metal, so we add MERL's
#: ``alum-bronze`` (a rough conductor) so that every broad family is tested.
EXTRA_TEST_MATERIAL = "alum-bronze"

MERL_SUFFIX = ".binary"


class DatabaseError(ValueError):
    """The configured database cannot be used (missing folder, unknown name, …)."""


@dataclass(frozen=True)
class Database:
    """A database of MERL-format materials.

    ``sources`` maps each material name to its ``.binary`` file (for the
    synthetic database, the file the workflow will generate).
    """

    kind: Literal["merl", "synthetic"]
    sources: dict[str, Path]
    default_test: tuple[str, ...] = field(default=())

    @property
    def materials(self) -> list[str]:
        """Material names in row order of the store (sorted)."""
        return sorted(self.sources)


def merl_database(folder: str | os.PathLike[str]) -> Database:
    """The real MERL database in ``folder`` (every ``*.binary`` file in it).

    Raises :class:`DatabaseError` if the folder is missing, is not a folder,
    or holds no ``.binary`` file.  The files themselves are validated at
    ingest (:func:`brdfpipe.store.ingest_material`).
    """
    path = Path(folder).expanduser()
    if not path.exists():
        raise DatabaseError(f"merl_dir {path}: folder does not exist")
    if not path.is_dir():
        raise DatabaseError(f"merl_dir {path}: not a folder")
    sources = {p.name[: -len(MERL_SUFFIX)]: p.resolve() for p in path.glob(f"*{MERL_SUFFIX}")}
    if not sources:
        raise DatabaseError(f"merl_dir {path}: no MERL files (*{MERL_SUFFIX}) in the folder")
    default = tuple(sorted((*XU2016_TEST_MATERIALS, EXTRA_TEST_MATERIAL)))
    return Database("merl", sources, default)


def folder_database(folder: str | os.PathLike[str]) -> Database:
    """The database in a folder: synthetic if it holds a synthetic ``manifest.json``.

    Otherwise the folder is taken as (a subset of) the real MERL database.
    """
    db = merl_database(folder)
    manifest = Path(folder) / "manifest.json"
    if manifest.is_file():
        try:
            doc = json.loads(manifest.read_text(encoding="utf-8"))
        except json.JSONDecodeError as err:
            raise DatabaseError(f"{manifest}: not valid JSON ({err})") from None
        if doc.get("kind") == "synthetic":
            test = tuple(n for n in doc.get("test_materials", []) if n in db.sources)
            return Database("synthetic", db.sources, test)
    return db


def synthetic_database(out_dir: str | os.PathLike[str], count: int, seed: int) -> Database:
    """The synthetic database that :mod:`brdfpipe.synth` generates into ``out_dir``."""
    specs = synth.plan_database(count, seed)
    sources = {s.name: Path(out_dir) / f"{s.name}{MERL_SUFFIX}" for s in specs}
    default = tuple(synth.default_test_materials(specs, n=default_test_count(count)))
    return Database("synthetic", sources, default)


def resolve_test_materials(requested: Sequence[str] | None, db: Database) -> list[str]:
    """The held-out materials: ``requested``, or the database's default if ``None``.

    Raises :class:`DatabaseError` naming every unknown material, on
    duplicates, and if nothing would be left to train on.
    """
    names = list(db.default_test if requested is None else requested)
    what = "default test_materials" if requested is None else "test_materials"
    unknown = [n for n in names if n not in db.sources]
    if unknown:
        avail = ", ".join(db.materials[:12]) + (" …" if len(db.sources) > 12 else "")
        raise DatabaseError(
            f"{what}: unknown material(s) {', '.join(unknown)} in the {db.kind} database "
            f"({len(db.sources)} materials: {avail})"
        )
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DatabaseError(f"{what}: listed more than once: {', '.join(dupes)}")
    if not names:
        raise DatabaseError(f"{what}: empty")
    if len(names) >= len(db.sources):
        raise DatabaseError(
            f"{what}: all {len(db.sources)} materials are held out; none is left to train on"
        )
    return sorted(names)


def write_splits(
    path: str | os.PathLike[str], *, store: str | os.PathLike[str], test: Sequence[str]
) -> None:
    """Write the train/test split of the materials in ``store`` as JSON.

    The material names and the database kind are read from the validated
    store, so the split always describes the data downstream stages see.
    Raises :class:`DatabaseError` if a test material is not in the store.
    Written atomically (temporary name, then rename).
    """
    from brdfpipe.store import open_store

    st = open_store(store)
    materials = list(st.materials)
    missing = sorted(set(test) - set(materials))
    if missing:
        raise DatabaseError(f"{store}: test material(s) not in the store: {', '.join(missing)}")
    test_set = set(test)
    doc = {
        "database": st.database,
        "materials": materials,
        "test": [m for m in materials if m in test_set],
        "train": [m for m in materials if m not in test_set],
        "brdfpipe_version": full_version(),
    }
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)
