"""The library's layout follows the pipeline: stage subpackages, layered, no private imports.

Layers, bottom to top (a module may import its own subpackage and the
subpackages :data:`ALLOWED` lists for it, never a higher one nor a sibling
stage)::

    registry  <-  core  <-  data  <-  {acquisition, manifold}  <-  rendering  <-  cli (top-level modules)
    registry  <-  core  <-  plan (the planner, beside cli: nothing below imports it)

(rendering may use manifold, not acquisition: the tracks meet in files.)

Imports are read from the syntax tree of every module (function bodies
included), so a lazy import counts as much as a module-level one.
"""

from __future__ import annotations

import ast
from functools import lru_cache
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "brdfpipe"

#: Subpackage (stage) → the other subpackages it may import; top-level modules
#: (cli, the package's __init__) may import all of them.
ALLOWED: dict[str, set[str]] = {
    # the records of what people add (set-ups, data spaces, figures): the standard library only
    "registry": set(),
    "core": {"registry"},
    "data": {"core", "registry"},
    "acquisition": {"data", "core", "registry"},
    "manifold": {"data", "core", "registry"},
    "rendering": {"manifold", "data", "core", "registry"},
    # for people: the report reads the run's CSVs; the explorer exports models and pre-renders
    "report": {"core", "registry"},
    "explorer": {"rendering", "manifold", "data", "core", "registry"},
    # the planner, on top beside cli: read at parse time, so only the light layers
    "plan": {"core", "registry"},
}


def module_sources() -> dict[str, str]:
    """Every module of the package: dotted name → source."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path.read_text(encoding="utf-8")
    return out


@lru_cache(maxsize=None)
def _parse(source: str) -> ast.Module:
    return ast.parse(source)


def _is_package(name: str, sources: dict[str, str]) -> bool:
    return any(m.startswith(name + ".") for m in sources)


def _resolve(importer: str, node: ast.ImportFrom, sources: dict[str, str]) -> str:
    if not node.level:
        return node.module or ""
    base = importer.split(".") if _is_package(importer, sources) else importer.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def imports_of(name: str, source: str, sources: dict[str, str]) -> list[tuple[str, str | None, int]]:
    """``(module, imported name or None, line)`` for every brdfpipe import in ``source``.

    ``from brdfpipe.data import merl`` gives ``("brdfpipe.data.merl", None, …)``
    (a submodule); ``from brdfpipe.data.merl import N_CELLS`` gives
    ``("brdfpipe.data.merl", "N_CELLS", …)``.
    """
    found: list[tuple[str, str | None, int]] = []
    for node in ast.walk(_parse(source)):
        if isinstance(node, ast.Import):
            found += [(a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == "brdfpipe"]
        elif isinstance(node, ast.ImportFrom):
            mod = _resolve(name, node, sources)
            if mod.split(".")[0] != "brdfpipe":
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                if sub in sources:
                    found.append((sub, None, node.lineno))
                else:
                    found.append((mod, a.name, node.lineno))
    return found


def stage(module: str) -> str | None:
    """The subpackage a module belongs to (None: a top-level module or the package itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in ALLOWED) else None


def violations(sources: dict[str, str]) -> list[str]:
    """Every upward or sideways import and every import of another module's private name."""
    bad = []
    for name, source in sources.items():
        tree = _parse(source)
        aliases: dict[str, str] = {}  # local name → brdfpipe module it is bound to
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == "brdfpipe" and a.asname:
                        aliases[a.asname] = a.name
            elif isinstance(node, ast.ImportFrom):
                mod = _resolve(name, node, sources)
                for a in node.names:
                    if f"{mod}.{a.name}" in sources:
                        aliases[a.asname or a.name] = f"{mod}.{a.name}"
        for target, imported, line in imports_of(name, source, sources):
            where = f"{name} line {line}: imports {target}" + (f".{imported}" if imported else "")
            if target == "brdfpipe":
                pass  # the package itself (``__version__``): imported first by everything anyway
            elif stage(target) != stage(name) and (
                    stage(target) is None or (stage(name) is not None and stage(target) not in ALLOWED[stage(name)])):
                bad.append(f"{where} (brdfpipe.{stage(name)} may import only {sorted(ALLOWED[stage(name)])})"
                           if stage(name) else f"{where} (a top-level module)")
            if imported and imported.startswith("_") and not imported.startswith("__") and target != name:
                bad.append(f"{where}: a private name of another module")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and node.attr.startswith("_") and not node.attr.startswith("__")
                    and aliases[node.value.id] != name):
                bad.append(f"{name} line {node.lineno}: uses {aliases[node.value.id]}.{node.attr}, "
                           "a private name of another module")
    return bad


def subpackage_graph(sources: dict[str, str]) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for name, source in sources.items():
        for target, _, _ in imports_of(name, source, sources):
            a, b = stage(name) or "<top>", stage(target) or "<top>"
            if a != b and target != "brdfpipe":
                graph.setdefault(a, set()).add(b)
    return graph


def _type_checking_lines(source: str) -> set[int]:
    """Lines of the imports under ``if TYPE_CHECKING:`` (annotations only: never run)."""
    lines: set[int] = set()
    for node in ast.walk(_parse(source)):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for inner in node.body:
                for sub in ast.walk(inner):
                    if isinstance(sub, (ast.Import, ast.ImportFrom)):
                        lines.add(sub.lineno)
    return lines


def module_graph(sources: dict[str, str]) -> dict[str, set[str]]:
    """Module → the brdfpipe modules it imports when run (function bodies too; not annotation-only imports)."""
    graph: dict[str, set[str]] = {}
    for name, source in sources.items():
        typing_only = _type_checking_lines(source)
        for target, _, line in imports_of(name, source, sources):
            if line in typing_only:
                continue
            if target != name and target in sources and not _is_package(target, sources):
                graph.setdefault(name, set()).add(target)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (cyc := visit(nxt)):
                return cyc
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cyc := visit(node)):
            return cyc
    return None


def test_every_module_is_in_a_stage_subpackage_or_at_the_top() -> None:
    sources = module_sources()
    top = sorted(m for m in sources if stage(m) is None)
    assert top == ["brdfpipe", "brdfpipe.cli"], top
    for pkg in ALLOWED:
        assert f"brdfpipe.{pkg}" in sources, f"missing subpackage brdfpipe.{pkg}"
    assert not [m for m in sources if len(m.split(".")) > 3], "one level of subpackages only"


def test_no_upward_or_sideways_import_and_no_private_import() -> None:
    assert violations(module_sources()) == []


def test_no_cycle_between_subpackages() -> None:
    graph = subpackage_graph(module_sources())
    assert find_cycle(graph) is None, find_cycle(graph)
    assert graph.get("core", set()) <= {"registry"}  # core imports nothing of brdfpipe above it (the registries are below)
    assert graph.get("registry", set()) == set()  # the registries import nothing of brdfpipe


def test_no_cycle_between_modules() -> None:
    """Not even inside a subpackage (a deferred import in a function counts too)."""
    graph = module_graph(module_sources())
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_the_module_cycle_check_catches_a_cycle_inside_a_subpackage() -> None:
    sources = module_sources()
    sources["brdfpipe.data.merl"] += "\ndef f():\n    from brdfpipe.data import store\n"
    cycle = find_cycle(module_graph(sources))
    assert cycle is not None and "brdfpipe.data.merl" in cycle and "brdfpipe.data.store" in cycle, cycle


@pytest.mark.parametrize(
    ("module", "line"),
    [
        ("brdfpipe.core.atomic", "from brdfpipe.rendering import blend"),
        ("brdfpipe.core.atomic", "def f():\n    from brdfpipe.data.merl import N_CELLS"),
        ("brdfpipe.data.store", "import brdfpipe.acquisition.svd"),
        ("brdfpipe.acquisition.svd", "from brdfpipe.manifold import gplvm"),
        ("brdfpipe.manifold.gplvm", "from ..acquisition import svd"),
        ("brdfpipe.manifold.gplvm", "from brdfpipe import cli"),
        ("brdfpipe.rendering.scene", "from brdfpipe.acquisition.metrics import DEFAULT_ETA"),
        ("brdfpipe.rendering.blend", "from brdfpipe.data.store import _encode_source"),
        ("brdfpipe.rendering.blend", "from brdfpipe.data import store\nstore._open_row(1)"),
    ],
)
def test_the_checks_catch_a_bad_import(module: str, line: str) -> None:
    """Each kind of violation added to the real package is reported (the checks can fail)."""
    sources = module_sources()
    sources[module] = sources[module] + "\n" + line + "\n"
    assert [v for v in violations(sources) if v.startswith(module)], line


def test_the_cycle_check_catches_a_cycle() -> None:
    """core importing rendering closes a cycle (rendering imports core)."""
    sources = module_sources()
    sources["brdfpipe.core.atomic"] += "\nfrom brdfpipe.rendering import blend\n"
    cycle = find_cycle(subpackage_graph(sources))
    assert cycle is not None and "core" in cycle and "rendering" in cycle, cycle


def test_subpackage_inits_are_documented_and_light() -> None:
    """Each stage's __init__ describes it and imports nothing (the Snakefile imports core at parse time)."""
    for pkg in ALLOWED:
        tree = ast.parse((PACKAGE / pkg / "__init__.py").read_text(encoding="utf-8"))
        doc = ast.get_docstring(tree)
        assert doc, f"brdfpipe.{pkg} has no docstring"
        modules = sorted(p.stem for p in (PACKAGE / pkg).glob("*.py") if p.stem != "__init__")
        for m in modules:
            assert f"brdfpipe.{pkg}.{m}" in doc, f"brdfpipe.{pkg}'s docstring does not list {m}"
        modules_in = {(n.module or "") for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        if pkg == "plan":  # the planner's facade re-exports its own modules' names, nothing else
            modules_in = {m for m in modules_in if m != "brdfpipe.plan" and not m.startswith("brdfpipe.plan.")}
        imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        imported |= {m.split(".")[0] for m in modules_in}
        assert imported <= set(sys.stdlib_module_names) | {"__future__"}, (pkg, imported)  # the standard library only


def test_registry_modules_import_only_the_standard_library() -> None:
    """The registries are read at parse time and by every stage: the standard library and other registry modules only (outside TYPE_CHECKING or a function)."""
    for path in sorted((PACKAGE / "registry").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        typing_only = _type_checking_lines(path.read_text(encoding="utf-8"))
        for node in tree.body:  # module level only: a function body may import NumPy lazily
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for name in names:
                if node.lineno not in typing_only:
                    ok = name.split(".")[0] in set(sys.stdlib_module_names) | {"__future__"} or name.startswith("brdfpipe.registry.")
                    assert ok, (path.name, name)


def test_the_registry_check_catches_a_third_party_import(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A registry module importing NumPy at module level fails the check above (it can fail)."""
    fake = tmp_path / "registry"
    fake.mkdir()
    (fake / "bad.py").write_text("import numpy as np\n", encoding="utf-8")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", tmp_path)
    with pytest.raises(AssertionError, match="numpy"):
        test_registry_modules_import_only_the_standard_library()


#: The longest a library function may be (lines from ``def`` to its last line, docstring and nested code included).
MAX_FUNCTION_LINES = 120


def long_functions(sources: dict[str, str], limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``module.function (N lines)`` for every function of ``sources`` longer than ``limit`` lines."""
    found = []
    for name, source in sources.items():
        for node in ast.walk(_parse(source)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > limit:
                    found.append(f"{name}.{node.name} ({n} lines, line {node.lineno})")
    return found


def test_no_library_function_is_over_120_lines() -> None:
    """Wide functions are cut along their seams (issue 24): none over :data:`MAX_FUNCTION_LINES`."""
    assert long_functions(module_sources()) == []


def test_the_length_check_catches_a_long_function() -> None:
    sources = module_sources()
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    sources["brdfpipe.core.atomic"] += f"\n\ndef too_long():\n{body}\n"
    assert long_functions(sources) == [f"brdfpipe.core.atomic.too_long ({MAX_FUNCTION_LINES + 1} lines, "
                                       f"line {sources['brdfpipe.core.atomic'].count(chr(10)) - MAX_FUNCTION_LINES})"]


#: The longest a library module may be (lines of its file, docstring included): a module is one concept (issue 34).
MAX_MODULE_LINES = 1000


def long_modules(sources: dict[str, str], limit: int = MAX_MODULE_LINES) -> list[str]:
    """``module (N lines)`` for every module of ``sources`` longer than ``limit`` lines."""
    return [f"{name} ({n} lines)" for name, source in sources.items() if (n := len(source.splitlines())) > limit]


def test_no_library_module_is_over_1000_lines() -> None:
    """Modules are cut along their seams, or lose the code no caller needs: none over :data:`MAX_MODULE_LINES`."""
    assert long_modules(module_sources()) == []


def test_the_module_length_check_catches_a_long_module() -> None:
    sources = module_sources()
    n = len(sources["brdfpipe.core.atomic"].splitlines())
    sources["brdfpipe.core.atomic"] += "\n".join(f"x{i} = {i}" for i in range(MAX_MODULE_LINES + 1 - n)) + "\n"
    assert not [m for m in long_modules(module_sources()) if m.startswith("brdfpipe.core.atomic ")]
    assert f"brdfpipe.core.atomic ({MAX_MODULE_LINES + 1} lines)" in long_modules(sources)
