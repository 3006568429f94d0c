"""Which database a run uses: a folder of real MERL files, or the synthetic one.

The workflow reads the real MERL BRDF database from a folder named in the
config when a user has it; otherwise it generates a synthetic MERL-format
database (:mod:`brdfpipe.data.synth`).  This module resolves either into a
:class:`Database` (material names → source files) and resolves the held-out
``test_materials`` against it, with clear errors for a missing folder or an
unknown name.

A folder's label (``merl``, ``synthetic``, ``derived``: see
:func:`brdfpipe.data.provenance.database_labels`) is decided in one place,
:func:`database_from_folder`, from the files' own bytes (their provenance
marks, :mod:`brdfpipe.data.provenance`), never from a manifest alone; material
names are checked by :func:`check_material_name` (defined in the registry,
:mod:`brdfpipe.data.databases`, so that the writers below this module —
:mod:`brdfpipe.data.synth`, :mod:`brdfpipe.data.nbrdf` — apply the same rule).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from brdfpipe.core import integrity
from brdfpipe.data import databases
from brdfpipe.data.databases import EXTRA_TEST_MATERIAL, MERL_TEST_MATERIALS, XU2016_TEST_MATERIALS
from brdfpipe.data.databases import MAX_NAME_LENGTH, RESERVED_NAMES, DatabaseError, check_material_name
from brdfpipe.core.version import full_version
from brdfpipe.data import provenance, synth
from brdfpipe.data.synth import default_test_count
from brdfpipe.registry import layouts

__all__ = [
    "XU2016_TEST_MATERIALS",
    "EXTRA_TEST_MATERIAL",
    "Database",
    "DatabaseError",
    "MAX_NAME_LENGTH",
    "RESERVED_NAMES",
    "check_material_name",
    "database_from_folder",
    "synthetic_database",
    "fits_database",
    "configured_database",
    "spread_test_materials",
    "default_test_count",
    "select_materials",
    "resolve_test_materials",
    "UNSEEN_DATABASES",
    "UNSEEN_DEFAULT_FOR",
    "DEFAULT_UNSEEN",
    "unseen_databases",
    "write_splits",
]

_SHOWN = 8  # files named in one error message
@dataclass(frozen=True)
class Database:
    """A database of MERL-format materials.

    ``kind`` is its label (:func:`brdfpipe.data.provenance.database_labels`:
    ``merl`` for measurements, ``synthetic``, ``derived``).  ``sources`` maps
    each material name to its ``.binary`` file (for the synthetic database,
    the file the workflow will generate).
    """

    kind: str
    sources: dict[str, Path]
    default_test: tuple[str, ...] = field(default=())
    #: material → its fit's name in ``archive`` (databases of fits; empty otherwise)
    fits: dict[str, str] = field(default_factory=dict)
    #: the archive of fits the workflow evaluates (``None`` unless ``fits``)
    archive: Path | None = None

    @property
    def materials(self) -> list[str]:
        """Material names in row order of the store (sorted)."""
        return sorted(self.sources)


def _listing(paths: Sequence[Path] | Sequence[str]) -> str:
    names = [p.name if isinstance(p, Path) else p for p in paths]
    more = f" and {len(names) - _SHOWN} more" if len(names) > _SHOWN else ""
    return ", ".join(names[:_SHOWN]) + more


def _read_manifest(path: Path) -> dict | None:
    """The folder's ``manifest.json`` as a dict, or ``None`` if there is none."""
    if not (path.is_file() or path.is_symlink()):
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise DatabaseError(f"{path}: not valid JSON ({err})") from None
    except (OSError, UnicodeDecodeError) as err:
        raise DatabaseError(f"{path}: cannot be read ({err})") from None
    if not isinstance(doc, dict):
        raise DatabaseError(f"{path}: not a JSON object")
    return doc


def database_from_folder(folder: str | os.PathLike[str], *, key: str = "merl_dir") -> Database:
    """The database in a folder of MERL-format files, labelled from the files themselves.

    This is the one place that decides whether a folder is the real MERL
    database or a synthetic one (the workflow's ``merl_dir`` and ``brdfpipe
    ingest`` both use it).  Every ``*.binary`` file is a material named by
    its stem (:func:`check_material_name`).  A file written by brdfpipe
    carries a provenance mark in cells no measurement can fill
    (:func:`brdfpipe.data.provenance.read_mark`: 88 bytes read per unmarked
    file, a few hundred more per marked one):

    * all files synthetic (a ``synthetic`` mark, or the old watermark alone)
      → ``kind == "synthetic"`` (with or without ``manifest.json``; the
      manifest only supplies the default held-out materials, and must then
      agree with the files);
    * all files of another kind of mark (``derived``: interpolated,
      sampled, extrapolated, reconstructed) → that kind, no default held-out
      materials;
    * none marked → ``kind == "merl"``, default held-out materials
      :data:`XU2016_TEST_MATERIALS` + :data:`EXTRA_TEST_MATERIAL`;
    * files of several kinds → :class:`DatabaseError` listing the files of
      each kind.

    A mark that names its material (synthetic) must name the file's stem: a
    file copied over another is an error naming both.

    ``key`` names the setting in messages (``merl_dir`` for the workflow).
    Raises :class:`DatabaseError` (one line naming ``key``, the folder or the
    file) for an empty or blank path, a missing folder, a folder without
    ``*.binary`` files, a file whose suffix is ``.binary`` in another case
    (``.BINARY``), an entry that is not a file, an unsafe material name, a
    file that cannot be read, a damaged provenance mark, a file marked as
    another material, a mixed folder, or a ``manifest.json`` that disagrees
    with the files.  The files' contents are validated at ingest
    (:func:`brdfpipe.data.ingest.ingest_material`).
    """
    text = os.fspath(folder)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if not text.strip():
        raise DatabaseError(f"{key}: empty path; give the folder of MERL files")
    path = Path(text).expanduser()
    if not path.exists():
        raise DatabaseError(f"{key} {path}: folder does not exist")
    if not path.is_dir():
        raise DatabaseError(f"{key} {path}: not a folder")
    try:
        entries = sorted(path.iterdir())
    except OSError as err:
        raise DatabaseError(f"{key} {path}: cannot list the folder ({err.strerror or err})") from None
    suffix = layouts.MERL_SUFFIX
    other_case = [e for e in entries if e.name.lower().endswith(suffix) and not e.name.endswith(suffix)]
    if other_case:
        raise DatabaseError(
            f"{key} {path}: {_listing(other_case)}: suffix is not exactly '{layouts.MERL_SUFFIX}' "
            f"(lower case); rename the file(s) to end in {layouts.MERL_SUFFIX} or move them away"
        )
    files = [e for e in entries if e.name.endswith(layouts.MERL_SUFFIX)]
    if not files:
        raise DatabaseError(f"{key} {path}: no MERL files (*{layouts.MERL_SUFFIX}) in the folder")
    not_files = [e for e in files if not e.is_file()]
    if not_files:
        raise DatabaseError(f"{key} {path}: {_listing(not_files)}: not a file (a folder or a broken link)")
    by_label: dict[str, list[Path]] = {}
    for f in files:
        stem = f.name[: -len(layouts.MERL_SUFFIX)]
        check_material_name(stem, f"{key} {f}")
        try:
            mark = provenance.check_source(f, name=stem)
        except OSError as err:
            raise DatabaseError(f"{key} {f}: cannot be read ({err.strerror or err})") from None
        except provenance.ProvenanceError as err:
            raise DatabaseError(f"{key} {err}") from None
        by_label.setdefault(provenance.UNMARKED if mark is None else mark.kind, []).append(f)
    if len(by_label) > 1:
        order = [label for label in (*provenance.KINDS, provenance.UNMARKED) if label in by_label]
        kinds = " with ".join(f"{provenance.kind_title(label)} ({_listing(by_label[label])})" for label in order)
        raise DatabaseError(f"{key} {path}: mixes {kinds}; keep one kind per folder")
    (label,) = by_label
    sources = {f.name[: -len(layouts.MERL_SUFFIX)]: f.resolve() for f in files}
    manifest_path = path / layouts.SYNTHETIC_MANIFEST
    manifest = _read_manifest(manifest_path)
    says_synthetic = manifest is not None and manifest.get("kind") == "synthetic"
    if label != "synthetic":
        if says_synthetic:
            raise DatabaseError(
                f"{key} {manifest_path}: says the folder is synthetic but its files are "
                f"{provenance.kind_title(label)} ({_listing(by_label[label])}); remove the stray manifest.json, "
                "or regenerate the database with `brdfpipe synth`"
            )
        if label == provenance.UNMARKED:
            default = MERL_TEST_MATERIALS
            return Database(label, sources, default)
        return Database(label, sources, ())
    if not says_synthetic:
        return Database("synthetic", sources, ())
    assert manifest is not None
    listed_raw = manifest.get("materials")
    if not isinstance(listed_raw, list) or not all(
        isinstance(m, dict) and isinstance(m.get("name"), str) for m in listed_raw
    ):
        raise DatabaseError(f"{key} {manifest_path}: 'materials' is not a list of named materials")
    listed = {m["name"] for m in listed_raw}
    unlisted = sorted(n for n in sources if n not in listed)
    if unlisted:
        raise DatabaseError(
            f"{key} {manifest_path}: does not list the synthetic file(s) "
            f"{_listing([n + layouts.MERL_SUFFIX for n in unlisted])} of this folder; the manifest belongs "
            "to another database"
        )
    test_raw = manifest.get("test_materials", [])
    if not isinstance(test_raw, list):
        raise DatabaseError(f"{key} {manifest_path}: 'test_materials' is not a list")
    test = tuple(n for n in test_raw if n in sources)
    return Database("synthetic", sources, test)


def synthetic_database(out_dir: str | os.PathLike[str], count: int, seed: int) -> Database:
    """The synthetic database that :mod:`brdfpipe.data.synth` generates into ``out_dir``."""
    specs = synth.plan_database(count, seed)
    sources = {s.name: Path(out_dir) / layouts.merl_file(s.name) for s in specs}
    default = tuple(synth.default_test_materials(specs, n=default_test_count(count)))
    return Database("synthetic", sources, default)


def spread_test_materials(names: Sequence[str]) -> tuple[str, ...]:
    """Default held-out materials of a database without a published list: evenly spread over the sorted names.

    :func:`brdfpipe.data.synth.default_test_count` of them (ten from 40
    materials on, a quarter of a smaller database), at sorted positions
    ``round((i + ½)·n/k)``: deterministic, and spread over the alphabet.
    """
    ordered = sorted(names)
    k = default_test_count(len(ordered)) if len(ordered) > 1 else 0
    return tuple(ordered[min(len(ordered) - 1, int((i + 0.5) * len(ordered) / k))] for i in range(k))


def fits_database(name: str, archive: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                  key: str = "database") -> Database:
    """The database of an archive of NBRDF fits (label ``name``: one of :data:`brdfpipe.data.databases.FIT_DATABASES`).

    Every fit of the archive is a material named
    :func:`brdfpipe.data.nbrdf.material_name` (``_`` written ``-``), whose
    table the workflow evaluates to ``out_dir/<material>.binary``.  Default
    held-out materials: the database's published list if it has one
    (:data:`brdfpipe.data.databases.DATABASES`), else
    :func:`spread_test_materials`.  Every fit is read and checked
    (:func:`brdfpipe.data.nbrdf.check_archive`: sidecar, layer shapes, finite
    weights, and the bound of its output: no all-black channel, no overflow,
    no impossible albedo), so a bad archive stops the parse, not a job.
    Raises :class:`DatabaseError` naming ``key``, the archive and the fit for a
    missing or unreadable archive or fit, a fit that fails the checks, two fits
    that would share a material name, or an unsafe name.
    """
    from brdfpipe.data import nbrdf

    try:
        fit_names = nbrdf.check_archive(archive)
    except nbrdf.NbrdfError as err:
        raise DatabaseError(f"{key}: {err}") from None
    fits: dict[str, str] = {}
    for fit in fit_names:
        material = nbrdf.material_name(fit)
        check_material_name(material, f"{key} {archive}:{fit}")
        if material in fits:
            raise DatabaseError(f"{key} {archive}: fits {fits[material]!r} and {fit!r} would both be material "
                                f"{material!r}; rename one")
        fits[material] = fit
    sources = {m: Path(out_dir) / layouts.merl_file(m) for m in fits}
    spec = databases.DATABASES.get(name)
    listed = spec.default_test if spec is not None and spec.default_test is not None else None
    default = tuple(m for m in listed if m in fits) if listed is not None else spread_test_materials(list(fits))
    return Database(name, sources, default, fits, Path(archive))


def configured_database(config: Mapping[str, Any], results: str = "results") -> Database:
    """The database a (schema-valid) config names: ``database`` with ``merl_dir`` / ``nbrdf_archive`` / ``synthetic``.

    ``merl``: the folder ``merl_dir``, labelled from its files
    (:func:`database_from_folder`); ``synthetic``: the generated database
    (:func:`synthetic_database`, files under ``results/synthetic``); a
    shipped database of fits, or ``nbrdf`` with ``nbrdf_archive``: the
    archive's fits (:func:`fits_database`, tables under
    ``results/nbrdf/<database>``).  A ``merl_dir`` or ``nbrdf_archive`` that
    the chosen database does not read is an error naming both keys (a
    setting that would be silently ignored).
    """
    name = config.get("database") or databases.DEFAULT_DATABASE
    if name not in databases.DATABASES:
        raise DatabaseError(f"database: unknown {name!r}; one of {', '.join(databases.DATABASES)}")
    merl_dir, archive = config.get("merl_dir"), config.get("nbrdf_archive")
    if merl_dir is not None and name != "merl":
        raise DatabaseError(f"merl_dir is set but database is {name!r}; set database: merl to read the folder "
                            "(or merl_dir: null)")
    if archive is not None and name != "nbrdf":
        raise DatabaseError(f"nbrdf_archive is set but database is {name!r}; set database: nbrdf to read the "
                            "archive (or nbrdf_archive: null)")
    spec = databases.DATABASES[name]
    if spec.source == "generated":
        syn = config["synthetic"]
        return synthetic_database(f"{results}/synthetic", syn["count"], syn["seed"])
    if spec.source == "folder":
        if merl_dir is None:
            raise DatabaseError("database: merl reads a folder of MERL files: set merl_dir to it")
        return database_from_folder(merl_dir, key="merl_dir")
    if spec.source == "archive":
        return fits_database(name, databases.shipped_archive(name), f"{results}/nbrdf/{name}")
    if archive is None:
        raise DatabaseError("database: nbrdf reads your archive of NBRDF fits: set nbrdf_archive to it (a .zip or "
                            "a folder of NAME.h5 files)")
    if not str(archive).strip():
        raise DatabaseError("nbrdf_archive: empty path")
    return fits_database("nbrdf", Path(str(archive)).expanduser(), f"{results}/nbrdf/nbrdf", key="nbrdf_archive")


def select_materials(db: Database, patterns: Sequence[str] | None, *, key: str = "materials") -> Database:
    """The part of ``db`` whose names match ``patterns`` (names or shell-style globs); all if ``None``.

    Lets a user try the workflow (or the cluster path) on a few materials of
    a real MERL folder first.  The default held-out materials shrink to
    those selected.  Raises :class:`DatabaseError` naming ``key`` and every
    pattern that matches no material.
    """
    if patterns is None:
        return db
    import fnmatch

    names = db.materials
    unmatched = [p for p in patterns if not fnmatch.filter(names, p)]
    if unmatched:
        raise DatabaseError(
            f"{key}: {', '.join(repr(p) for p in unmatched)} match(es) no material of the {db.kind} database "
            f"({len(names)} materials: {', '.join(names[:8])}{' …' if len(names) > 8 else ''})"
        )
    keep = {n for p in patterns for n in fnmatch.filter(names, p)}
    return Database(
        db.kind,
        {n: src for n, src in db.sources.items() if n in keep},
        tuple(n for n in db.default_test if n in keep),
        {n: f for n, f in db.fits.items() if n in keep},
        db.archive,
    )


#: The databases whose materials the config's ``unseen`` may name: the shipped archives of fits.
UNSEEN_DATABASES: tuple[str, ...] = tuple(n for n, d in databases.DATABASES.items() if d.source == "archive")
#: The run databases that get :data:`DEFAULT_UNSEEN` when the config leaves ``unseen.databases`` unset (null):
#: MERL's, whose model has seen none of the RGL and Nielsen materials.
UNSEEN_DEFAULT_FOR: tuple[str, ...] = ("merl-nbrdf", "merl")
#: The default materials outside MERL: RGL's spectralon (the radiometric check, albedo ≈ 0.96 at normal
#: incidence), a white paper, a felt, a metallic and a satin paint, and three of Nielsen et al.'s.
DEFAULT_UNSEEN: dict[str, tuple[str, ...]] = {
    "rgl-nbrdf": ("spectralon-rgb", "paper-white-rgb", "acrylic-felt-green-rgb", "ilm-l3-37-metallic-rgb",
                  "satin-gold-rgb"),
    "nielsen-nbrdf": ("glossyredpaper", "paintedmetal", "greencloth"),
}


def unseen_databases(config: Mapping[str, Any], run: Database, results: str = "results") -> dict[str, Database]:
    """The materials outside the run's database that the config's ``unseen`` names: database label → its fits.

    ``unseen.databases`` lists shipped databases of fits
    (:data:`UNSEEN_DATABASES`); ``unseen.materials`` (names or shell-style
    patterns, None = all) picks among their materials.  Both unset (None):
    :data:`DEFAULT_UNSEEN` for a run on MERL's materials
    (:data:`UNSEEN_DEFAULT_FOR`), none otherwise.  Each database is a
    :class:`Database` of fits whose tables go to ``results/unseen/<database>``;
    a database none of whose materials is picked is left out.  Returned in
    the order of ``unseen.databases``; empty when the list is empty (off).

    Raises :class:`DatabaseError` naming the key for: an unknown or
    non-shipped database, the run's own database (its materials are not
    unseen), ``unseen.materials`` without ``unseen.databases``, a pattern
    that matches no material of them, a material of the run's database
    (the model has seen it) or a material name in two unseen databases.
    """
    spec = config.get("unseen") or {}
    names = spec.get("databases")
    patterns = spec.get("materials")
    if names is None:
        if patterns is not None:
            raise DatabaseError("unseen.materials is set but unseen.databases is not: name the databases the "
                                f"materials come from ({', '.join(UNSEEN_DATABASES)})")
        if run.kind not in UNSEEN_DEFAULT_FOR:
            return {}
        names = list(DEFAULT_UNSEEN)
        patterns = [m for ms in DEFAULT_UNSEEN.values() for m in ms]
    names = list(names)
    if not names:
        if patterns:
            raise DatabaseError("unseen.materials is set but unseen.databases is empty: name the databases the "
                                f"materials come from ({', '.join(UNSEEN_DATABASES)})")
        return {}
    for name in names:
        if name not in UNSEEN_DATABASES:
            raise DatabaseError(f"unseen.databases: {name!r} is not a shipped database of fits; one of "
                                f"{', '.join(UNSEEN_DATABASES)}")
        if name == run.kind:
            raise DatabaseError(f"unseen.databases: {name} is the run's own database (database: {run.kind}); its "
                                "materials are not unseen: drop it from unseen.databases")
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DatabaseError(f"unseen.databases: listed more than once: {', '.join(dupes)}")
    found = {n: fits_database(n, databases.shipped_archive(n), f"{results}/unseen/{n}", key="unseen.databases")
             for n in names}
    if patterns is not None:
        import fnmatch

        every = sorted({m for db in found.values() for m in db.sources})
        unmatched = [p for p in patterns if not fnmatch.filter(every, p)]
        if unmatched:
            raise DatabaseError(
                f"unseen.materials: {', '.join(repr(p) for p in unmatched)} match(es) no material of "
                f"{', '.join(names)} ({len(every)} materials: {', '.join(every[:8])}{' …' if len(every) > 8 else ''})"
            )
        found = {n: select_materials(db, [m for m in db.materials if any(fnmatch.fnmatch(m, p) for p in patterns)]
                                     or [], key="unseen.materials")
                 for n, db in found.items()}
        found = {n: db for n, db in found.items() if db.sources}
    seen_in: dict[str, str] = {}
    for n, db in found.items():
        for m in db.materials:
            if m in run.sources:
                raise DatabaseError(f"unseen.materials: {m} ({n}) is also a material of the run's {run.kind} "
                                    "database, so the model has seen it; leave it out of unseen.materials")
            if m in seen_in:
                raise DatabaseError(f"unseen.materials: {m} is a material of both {seen_in[m]} and {n}; pick it "
                                    "from one of them with unseen.materials")
            seen_in[m] = n
    return found


def resolve_test_materials(requested: Sequence[str] | None, db: Database) -> list[str]:
    """The held-out materials: ``requested``, or the database's default if ``None``.

    Raises :class:`DatabaseError` naming every unknown material, on
    duplicates, and if nothing would be left to train on.
    """
    names = list(db.default_test if requested is None else requested)
    what = "default test_materials" if requested is None else "test_materials"
    if requested is None and not names:
        raise DatabaseError(
            f"test_materials: no default held-out material among the {len(db.sources)} materials of the "
            f"{db.kind} database (a subset chosen with 'materials', or a synthetic folder without its "
            "manifest.json); list them in test_materials"
        )
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
    Written atomically with its digest (:func:`brdfpipe.core.integrity.write_json`).
    """
    from brdfpipe.data.store import open_store

    st = open_store(store)
    materials = list(st.materials)
    missing = sorted(set(test) - set(materials))
    if missing:
        raise DatabaseError(f"{store}: test material(s) not in the store: {', '.join(missing)}")
    test_set = set(test)
    doc = {
        "database": st.database,
        "database_title": databases.title(st.database),
        "measurement": databases.is_measurement(st.database),
        "materials": materials,
        "test": [m for m in materials if m in test_set],
        "train": [m for m in materials if m not in test_set],
        "brdfpipe_version": full_version(),
    }
    integrity.write_json(path, doc, indent=2)  # with its digest (brdfpipe.core.integrity)
