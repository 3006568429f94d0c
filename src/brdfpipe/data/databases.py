"""The databases a run can use, and the label every output carries: one registry.

A *database* is where a run's materials come from; its *label* is what every
store, table, figure title, caption and claim says about them.  Labels are
never guessed from configuration: the labeller
(:func:`brdfpipe.data.database.database_from_folder`) reads them from the
files (their provenance marks, :mod:`brdfpipe.data.provenance`), and a
database of fit-made tables is never labelled ``merl``.

==================  ===========  ==============================================================
``database:``       label        what it is
==================  ===========  ==============================================================
``merl-nbrdf``      merl-nbrdf   the 100 MERL materials through their published neural fits
                                 (default; shipped: ``merl_nbrdf.zip``)
``rgl-nbrdf``       rgl-nbrdf    51 isotropic RGL materials through their fits (shipped)
``nielsen-nbrdf``   nielsen-…    8 materials of Nielsen et al. 2015 through their fits (shipped)
``nbrdf``           nbrdf        a user's own archive of NBRDF fits (``nbrdf_archive``)
``merl``            from files   a folder of MERL-format files (``merl_dir``): real MERL
                                 (``merl``), or files brdfpipe wrote (their marks say)
``synthetic``       synthetic    the generated synthetic database (``synthetic.*``)
==================  ===========  ==============================================================

Material names follow one rule, :func:`check_material_name` (every writer
and the labeller apply it; :mod:`brdfpipe.data.database` exports it too).

Labels that are not a configurable database: ``derived`` (tables brdfpipe
derived from others: blends, samples, reconstructions).  Standard library
only (the Snakefile reads it at parse time).  To add a database of fits,
add a :class:`DatabaseSpec` to :data:`DATABASES`: the provenance marks, the
labeller, the config schema's choices (checked by a test) and the titles
follow.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal

__all__ = [
    "ARCHIVES_DIR",
    "DatabaseError",
    "MAX_NAME_LENGTH",
    "RESERVED_NAMES",
    "check_material_name",
    "DatabaseSpec",
    "DATABASES",
    "DEFAULT_DATABASE",
    "FIT_DATABASES",
    "TITLES",
    "XU2016_TEST_MATERIALS",
    "EXTRA_TEST_MATERIAL",
    "MERL_TEST_MATERIALS",
    "title",
    "is_measurement",
    "shipped_archive",
]

#: The folder of the shipped archives of fits (package data).
ARCHIVES_DIR: Final = Path(__file__).resolve().parent / "archives"

#: The nine held-out MERL materials named in Xu et al. 2016, §6 (Fig. 2 and its text).
XU2016_TEST_MATERIALS: Final[tuple[str, ...]] = (
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
EXTRA_TEST_MATERIAL: Final = "alum-bronze"
#: The held-out MERL materials (sorted): Xu's nine and alum-bronze.
MERL_TEST_MATERIALS: Final = tuple(sorted((*XU2016_TEST_MATERIALS, EXTRA_TEST_MATERIAL)))

_SZTRAJMAN: Final = "NBRDF fits (Sztrajman et al. 2021)"


@dataclass(frozen=True)
class DatabaseSpec:
    """One configurable database.

    ``name``: the config value (and, for fits and the synthetic database, the
    label of its files); ``title``: how figures, captions and claims name its
    materials; ``source``: ``archive`` (a shipped archive of fits, file
    ``archive`` in :data:`ARCHIVES_DIR`), ``user-archive`` (the config's
    ``nbrdf_archive``), ``folder`` (the config's ``merl_dir``) or
    ``generated`` (the synthetic generator); ``default_test``: its held-out materials
    (``None``: chosen by the database's rule, see
    :func:`brdfpipe.data.database.resolve_test_materials`); ``archive_sha256``:
    the digest of the shipped archive whose every fit passes
    :func:`brdfpipe.data.nbrdf.check_archive` (a test runs the check and
    compares the digest), so the parse-time check of these bytes is skipped.
    """

    name: str
    title: str
    source: Literal["archive", "user-archive", "folder", "generated"]
    archive: str | None = None
    default_test: tuple[str, ...] | None = None
    archive_sha256: str | None = None

    @property
    def is_fit(self) -> bool:
        """Tables evaluated from neural fits (never a measurement)."""
        return self.source in ("archive", "user-archive")


#: Every configurable database, the default first.
DATABASES: Final[dict[str, DatabaseSpec]] = {
    d.name: d
    for d in (
        DatabaseSpec("merl-nbrdf", f"MERL materials, {_SZTRAJMAN}", "archive",
                     archive="merl_nbrdf.zip", default_test=MERL_TEST_MATERIALS,
                     archive_sha256="d1678c0cc5059f315d3d3284f36f3082787474106d72e3cae41fbad76d8f271a"),
        DatabaseSpec("rgl-nbrdf", f"RGL isotropic materials (Dupuy & Jakob 2018), {_SZTRAJMAN}", "archive",
                     archive="rgl-isotropic_nbrdf.zip",
                     archive_sha256="401f588f08a66714ebd9d1355298f85e4d2f3782c9a87f370538dc8657cf5389"),
        DatabaseSpec("nielsen-nbrdf", f"Nielsen et al. 2015 materials, {_SZTRAJMAN}", "archive",
                     archive="nielsen_nbrdf.zip",
                     archive_sha256="fd034c57b2cbe0e976b088ea4bb7ccbdda3782dad90946243124e07316442166"),
        DatabaseSpec("nbrdf", "materials of a user's archive, NBRDF fits", "user-archive"),
        DatabaseSpec("merl", "MERL (Matusik et al. 2003)", "folder", default_test=MERL_TEST_MATERIALS),
        DatabaseSpec("synthetic", "synthetic MERL-format database (brdfpipe)", "generated"),
    )
}
#: The database a run uses when the config names none.
DEFAULT_DATABASE: Final = "merl-nbrdf"
#: The databases of fit-made tables (their names are provenance-mark kinds and labels).
FIT_DATABASES: Final = tuple(n for n, d in DATABASES.items() if d.is_fit)

#: Every label an output can carry → how titles and captions name it.
TITLES: Final[dict[str, str]] = {
    **{n: d.title for n, d in DATABASES.items()},
    "derived": "derived materials (brdfpipe blends, samples or reconstructions)",
}


def title(label: str) -> str:
    """How titles, captions and claims name the materials of a database label.

    ``merl-nbrdf`` → "MERL materials, NBRDF fits (Sztrajman et al. 2021)",
    ``merl`` → "MERL (Matusik et al. 2003)"; an unknown label ``x`` → "x
    database" (never mistaken for a known one); empty → "unknown database".
    """
    label = str(label).strip()
    if not label:
        return "unknown database"
    return TITLES.get(label, label if label.lower().endswith("database") else f"{label} database")


def is_measurement(label: str) -> bool:
    """True only for real measured tables (``merl``): never for fits, synthetic or derived data."""
    return label == "merl"


def shipped_archive(name: str) -> Path:
    """The path of a shipped archive of fits (``DATABASES[name].archive``)."""
    spec = DATABASES[name]
    if spec.archive is None:
        raise KeyError(f"database {name!r} ships no archive")
    return ARCHIVES_DIR / spec.archive


#: Longest material name: ``.NAME.zarr.tmp-PID-RANDOM`` siblings must fit in 255 bytes.
MAX_NAME_LENGTH = 100
_NAME_CHARS = re.compile(r"[A-Za-z0-9._+-]*")
_NAME_RULE = (
    "material names use only ASCII letters, digits, '.', '_', '+' and '-', start with a "
    f"letter or digit and have at most {MAX_NAME_LENGTH} characters"
)
#: Names the results use for something else: ``mean`` is the material of the mean rows of
#: ``errors.csv``, ``closedloop.csv`` and ``training_size.csv``.
RESERVED_NAMES: frozenset[str] = frozenset({"mean"})


class DatabaseError(ValueError):
    """The configured database cannot be used (missing folder, unknown name, …)."""


def check_material_name(name: str, source: str) -> str:
    """Return ``name`` if it is a safe material name, else raise :class:`DatabaseError`.

    A material name becomes file and folder names and Snakemake wildcards:
    it must consist of ASCII letters, digits, ``.``, ``_``, ``+`` and ``-``,
    start with a letter or digit and be at most :data:`MAX_NAME_LENGTH`
    characters long; it must not be one of :data:`RESERVED_NAMES`.  ``source`` says where the name comes from (a file, or a
    config key such as ``test_materials``) and starts the one-line message,
    which also names the broken rule.
    """
    if not isinstance(name, str):
        raise DatabaseError(f"{source}: material name {name!r} is not a string; {_NAME_RULE}")
    if not name:
        problem = "is empty"
    elif len(name) > MAX_NAME_LENGTH:
        problem = f"is too long ({len(name)} characters)"
    elif not _NAME_CHARS.fullmatch(name):
        bad = sorted({c for c in name if not _NAME_CHARS.fullmatch(c)})
        problem = "contains " + ", ".join(repr(c) for c in bad)
    elif not name[0].isascii() or not name[0].isalnum():
        problem = f"starts with {name[0]!r}"
    elif name in RESERVED_NAMES:
        raise DatabaseError(
            f"{source}: material name {name!r} is reserved (the results' tables name their mean rows "
            f"{name!r}); rename the file"
        )
    else:
        return name
    raise DatabaseError(f"{source}: material name {name!r} {problem}; {_NAME_RULE}")
