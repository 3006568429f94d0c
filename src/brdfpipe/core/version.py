"""Which code made an output: a content digest of the library's source.

``brdfpipe.__version__`` (0.1.0) names a release and says nothing about the
commit a result came from.  :func:`full_version` appends a digest of every
module of the package (``0.1.0+src.1a2b3c4d5e6f``), so two checkouts whose
library code differs write different versions, and the same code always
writes the same one (no clock, no git needed: an installed wheel gives the
same digest as the checkout it was built from).

:func:`script_digest` is the digest of a workflow script and of the modules
it actually runs: every ``brdfpipe`` module it imports, transitively (found
by reading the source, never by importing it).  The workflow passes it to
each rule as a parameter, so Snakemake's ``params`` rerun
trigger reruns exactly the jobs whose library code changed, and what depends
on them.  Standard library only: the Snakefile calls it at parse time.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path

from brdfpipe import __version__

__all__ = ["PACKAGE_DIR", "module_closure", "script_digest", "full_version"]

#: The folder of the installed package (its ``*.py`` files, subpackages
#: included, are what is hashed); this module lives in its ``core`` subpackage.
PACKAGE_DIR = Path(__file__).resolve().parent.parent
_PKG = "brdfpipe"


def _module_file(name: str) -> Path | None:
    """Source file of ``brdfpipe`` or ``brdfpipe.x`` (module or package), or None."""
    return _module_file_in(PACKAGE_DIR, name)


@lru_cache(maxsize=None)
def _module_file_in(root: Path, name: str) -> Path | None:
    # cached: a dry run asks ~2,800 times for ~120 names (a stat each: two thirds of the digests' time)
    parts = name.split(".")
    if parts[0] != _PKG:
        return None
    rel = Path(*parts[1:]) if len(parts) > 1 else Path()
    for cand in (root / rel.with_suffix(".py") if parts[1:] else None, root / rel / "__init__.py"):
        if cand is not None and cand.is_file():
            return cand
    return None


# ``import a.b [as c], d`` and ``from [.]a.b import (x [as y], z)`` statements,
# wherever they are (function bodies included).  A regular expression instead
# of ``ast``: the Snakefile calls this for every rule at parse time, and
# parsing the package's syntax trees cost ~0.3 s of each dry run.  Text that
# merely looks like an import (in a docstring) can only add a module to a
# closure: a spurious rerun, never a missed one.
_IMPORT_RE = re.compile(
    r"^[ \t]*(?:from[ \t]+(?P<mod>\.*[\w.]*)[ \t]+import[ \t]+(?P<names>\([^)]*\)|[^\n#;]*)"
    r"|import[ \t]+(?P<plain>[^\n#;]+))",
    re.MULTILINE,
)
_AS_RE = re.compile(r"\s+as\s+\w+")
_COMMENT_RE = re.compile(r"#[^\n]*")


def _import_names(source: str, base: list[str]) -> set[str]:
    """Absolute names of the modules (and ``module.name`` candidates) imported in ``source``.

    ``base`` is the package a relative import is resolved against.
    """
    found: set[str] = set()
    source = source.replace("\\\n", " ")  # backslash continuations
    for m in _IMPORT_RE.finditer(source):
        if m.group("plain") is not None:
            for part in _AS_RE.sub("", m.group("plain")).split(","):
                if part.strip():
                    found.add(part.strip())
            continue
        mod, names = m.group("mod"), m.group("names")
        level = len(mod) - len(mod.lstrip("."))
        if level:
            anchor = base[: len(base) - (level - 1)] if level > 1 else base
            rest = mod[level:]
            mod = ".".join([*anchor, rest] if rest else anchor)
        found.add(mod)
        for part in _AS_RE.sub("", _COMMENT_RE.sub("", names).strip("()")).split(","):
            if part.strip():
                found.add(f"{mod}.{part.strip()}")
    return found


@lru_cache(maxsize=None)
def _imports(name: str) -> frozenset[str]:
    """``brdfpipe`` modules imported anywhere in module ``name`` (including function bodies)."""
    path = _module_file(name)
    if path is None:
        return frozenset()
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    found = _import_names(path.read_text(encoding="utf-8"), base)
    return frozenset(m for m in found if m.split(".")[0] == _PKG and _module_file(m) is not None)


def _parents(name: str) -> list[str]:
    """The packages Python imports before module ``name``: ``brdfpipe.a.b`` → ``brdfpipe``, ``brdfpipe.a``."""
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def module_closure(modules: Iterable[str]) -> list[str]:
    """The named modules and every ``brdfpipe`` module they import, transitively (sorted).

    Names may be given with or without the ``brdfpipe.`` prefix
    (``acquisition.svd`` or ``brdfpipe.acquisition.svd``).  Importing a module
    runs its parent packages' ``__init__`` first, so every module reached
    brings its parents too (``brdfpipe.manifold.gplvm`` brings ``brdfpipe``
    and ``brdfpipe.manifold``); the package's ``__init__`` is always included.
    """
    todo = [m if m.startswith(f"{_PKG}.") or m == _PKG else f"{_PKG}.{m}" for m in modules]
    todo.append(_PKG)
    seen: set[str] = set()
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        if _module_file(m) is None:
            raise ValueError(f"no module {m} in {PACKAGE_DIR}")
        seen.add(m)
        todo.extend(_imports(m) - seen)
        todo.extend(p for p in _parents(m) if p not in seen)
    return sorted(seen)


def _digest(files: Iterable[tuple[str, Path]]) -> str:
    h = hashlib.sha256()
    for name, path in sorted(files):
        data = path.read_bytes()
        h.update(f"{name}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()


@lru_cache(maxsize=1)
def full_version() -> str:
    """``__version__`` plus a digest of every module of the package, e.g. ``0.1.0+src.1a2b3c4d5e6f``.

    Every ``*.py`` under :data:`PACKAGE_DIR`, subpackages included, named by
    its path relative to the package (``acquisition/svd.py``) and hashed in
    sorted order, so the digest does not depend on the file system's listing
    order or on where the package is installed.
    """
    files = [(p.relative_to(PACKAGE_DIR).as_posix(), p) for p in PACKAGE_DIR.rglob("*.py")]
    return f"{__version__}+src.{_digest(files)[:12]}"


def script_digest(script: str | Path) -> str:
    """sha256 of a workflow script and of every ``brdfpipe`` module it runs (its imports, transitively).

    The workflow gives each rule this digest as a parameter: editing a
    library module changes the digest of exactly the rules whose scripts
    import it, directly or not, so Snakemake reruns those jobs (and what
    depends on them) and nothing else.
    """
    path = Path(script)
    mods = _import_names(path.read_text(encoding="utf-8"), [])
    mods = {m for m in mods if m.split(".")[0] == _PKG and _module_file(m) is not None}
    files = [(m, _module_file(m)) for m in module_closure(mods)] + [("<script>", path)]
    return _digest(files)  # type: ignore[arg-type]
