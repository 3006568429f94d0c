"""The README and docs/: every relative link resolves (file and anchor), the README stays short.

The README is for users (issue 24): at most 300 lines, measurements live in docs/results/,
each of which says at its top which database produced its numbers.
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: Every Markdown page of the user documentation (the README, docs/, config/ and the profiles').
PAGES = sorted({README, *ROOT.glob("docs/**/*.md"), ROOT / "config" / "README.md",
                ROOT / "profiles" / "slurm" / "README.md",
                ROOT / "src" / "brdfpipe" / "data" / "archives" / "README.md"})
MAX_README_LINES = 300

_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
_FENCE = re.compile(r"^(```|~~~)")


def _outside_code(text: str) -> str:
    """The text without fenced code blocks and inline code spans (no links there)."""
    out, fenced = [], False
    for line in text.split("\n"):
        if _FENCE.match(line.strip()):
            fenced = not fenced
            continue
        if not fenced:
            out.append(re.sub(r"`[^`]*`", "", line))
    return "\n".join(out)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip()).lower()
    kept = "".join(c for c in text if c in " -" or unicodedata.category(c)[0] in "LN")
    return kept.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    lines = _outside_code(page.read_text(encoding="utf-8")).split("\n")
    return {_slug(m.group(2)) for line in lines if (m := re.match(r"^(#+)\s+(.*)$", line))}


def links(page: Path) -> list[str]:
    """The relative links (targets) of a Markdown page, images included."""
    targets = _LINK.findall(_outside_code(page.read_text(encoding="utf-8")))
    return [t for t in targets if not re.match(r"^[a-z][a-z0-9+.-]*:", t)]


def broken_links(page: Path) -> list[str]:
    """``target: why`` for every relative link of ``page`` that does not resolve."""
    bad = []
    for target in links(page):
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            bad.append(f"{target}: no heading #{anchor} in {dest.name}")
    return bad


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_relative_link_resolves(page: Path) -> None:
    assert page.is_file(), page
    assert broken_links(page) == []


def test_the_checker_sees_a_broken_link(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    (tmp_path / "there.md").write_text("# A heading — here\n", encoding="utf-8")
    page.write_text("[ok](there.md) [ok](there.md#a-heading--here) [bad](missing.md) "
                    "[bad](there.md#nope) ![img](gone.png) [web](https://example.org/x) `[code](no.md)`\n"
                    "```\n[fenced](no.md)\n```\n", encoding="utf-8")
    assert [b.split(":")[0] for b in broken_links(page)] == ["missing.md", "there.md#nope", "gone.png"]


def test_readme_is_short() -> None:
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_README_LINES, f"README.md has {n} lines (at most {MAX_README_LINES}: results go to docs/)"


def test_every_results_page_names_its_database() -> None:
    pages = sorted(ROOT.glob("docs/results/*.md"))
    assert pages
    for page in pages:
        head = "\n".join(page.read_text(encoding="utf-8").splitlines()[:12]).lower()
        assert "database" in head and ("synthetic" in head or "nbrdf" in head), (
            f"{page.relative_to(ROOT)}: say at the top which database produced its numbers")


def test_docs_index_lists_every_page() -> None:
    index = (ROOT / "docs" / "README.md").read_text(encoding="utf-8")
    listed = {(ROOT / "docs" / t.partition("#")[0]).resolve() for t in links(ROOT / "docs" / "README.md")}
    for page in sorted(ROOT.glob("docs/**/*.md")):
        if page.name != "README.md":
            assert page.resolve() in listed, f"docs/README.md does not link {page.relative_to(ROOT)}"
    assert "synthetic" in index


def test_layout_lists_every_rule_file_and_subpackage() -> None:
    """The README's Layout names every rule file and every library subpackage (issue 24: it listed 5 of 8)."""
    text = README.read_text(encoding="utf-8")
    layout = text[text.index("## Layout"):]
    for smk in sorted((ROOT / "workflow" / "rules").glob("*.smk")):
        assert f"workflow/rules/{smk.name}" in layout, f"README's Layout does not list workflow/rules/{smk.name}"
    for pkg in sorted(p for p in (ROOT / "src" / "brdfpipe").iterdir() if (p / "__init__.py").is_file()):
        assert f"  {pkg.name}/" in layout, f"README's Layout does not list the subpackage brdfpipe.{pkg.name}"


def _layout_entries() -> dict[str, str]:
    """The README's library layout: subpackage → its text (continuation lines included)."""
    text = README.read_text(encoding="utf-8")
    block = text[text.index("src/brdfpipe/\n"):]
    block = block[: block.index("```")]
    entries: dict[str, str] = {}
    current = None
    for line in block.splitlines()[1:]:
        m = re.match(r"^  (\w+)(/|\.py)\s+(.*)$", line)
        if m:
            current = m.group(1)
            entries[current] = m.group(3)
        elif current is not None and line.startswith("    "):
            entries[current] += " " + line.strip()
    return entries


def unnamed_modules(entries: dict[str, str], package: Path) -> list[str]:
    """The modules and packages of ``package`` that the Layout ``entries`` do not name.

    A top-level module needs its own line (``cli.py``); a module or package inside a
    subpackage, at any depth, is named on its subpackage's line (``manifold/`` …
    ``blendpass``).
    """
    missing = []
    for path in sorted([*package.rglob("*.py"), *(p.parent for p in package.rglob("*/*/__init__.py"))]):
        parts = path.relative_to(package).with_suffix("").parts
        if any(p.startswith("_") for p in parts):
            continue
        words = set(re.findall(r"[a-z_0-9]+", entries.get(parts[0], ""))) if parts[0] in entries else None
        if words is None or not set(parts[1:]) <= words:
            missing.append(str(path.relative_to(package)))
    return missing


def test_layout_names_every_module_and_package() -> None:
    """The README's Layout names every module of the library (it omitted manifold/blendpass.py)."""
    missing = unnamed_modules(_layout_entries(), ROOT / "src" / "brdfpipe")
    assert not missing, f"README's Layout does not name src/brdfpipe/{', '.join(missing)}"


def test_the_layout_check_sees_a_missing_module(tmp_path: Path) -> None:
    for name in ["cli.py", "core/__init__.py", "core/atomic.py", "core/_private.py",
                 "manifold/__init__.py", "manifold/gplvm/__init__.py", "manifold/gplvm/kernel.py"]:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).touch()
    entries = {"cli": "the command line", "core": "atomic", "manifold": "gplvm (kernel)"}
    assert unnamed_modules(entries, tmp_path) == []
    assert unnamed_modules({**entries, "manifold": "gplvm"}, tmp_path) == ["manifold/gplvm/kernel.py"]
    assert unnamed_modules({**entries, "core": "integrity"}, tmp_path) == ["core/atomic.py"]
    assert unnamed_modules({"core": "atomic", "manifold": "kernel"}, tmp_path) == [
        "cli.py", "manifold/gplvm", "manifold/gplvm/kernel.py"]


def _cells(row: str) -> int:
    """The number of cells of a table row as GitHub splits it: at every pipe not escaped as ``\\|``.

    A pipe inside a code span splits the cell too (GitHub splits rows before it
    reads code spans): write it ``\\|`` there as well.
    """
    body = row.strip()
    pipes, i = [], 0
    while i < len(body):
        if body[i] == "\\":
            i += 2
            continue
        if body[i] == "|":
            pipes.append(i)
        i += 1
    edges = (pipes[:1] == [0]) + (bool(pipes) and pipes[-1] == len(body) - 1 and len(body) > 1)
    return len(pipes) + 1 - edges


def table_problems(text: str) -> list[str]:
    """``line N: why`` for every Markdown table whose header, delimiter row and rows disagree.

    A table is a run of lines starting with ``|`` outside fenced code. Its first
    row is the header; the next must be the delimiter row (``|---|:--:|``) with
    as many cells, or GitHub renders the lines as one paragraph of pipes; every
    row has the header's number of cells.
    """
    lines, bad, fenced, start = text.split("\n"), [], False, None
    for i, line in enumerate([*text.split("\n"), ""]):
        if _FENCE.match(line.strip()):
            fenced = not fenced
        in_table = not fenced and line.lstrip().startswith("|")
        if in_table and start is None:
            start = i
        if in_table or start is None:
            continue
        header, rows, start = start, range(start + 1, i), None
        width = _cells(lines[header])
        if not rows or not re.fullmatch(r"\s*\|?(\s*:?-+:?\s*\|)*\s*:?-+:?\s*\|?\s*", lines[rows[0]]):
            bad.append(f"line {header + 2}: no delimiter row (|---|) under the header of line {header + 1}")
            continue
        bad += [f"line {r + 1}: {_cells(lines[r])} cells, the header has {width}"
                for r in rows if _cells(lines[r]) != width]
    return bad


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_table_has_its_header_and_columns(page: Path) -> None:
    """A table without its header row renders as one paragraph of pipes (docs/outputs.md lost it once)."""
    assert table_problems(page.read_text(encoding="utf-8")) == [], page.relative_to(ROOT)


def test_the_table_check_sees_a_broken_table() -> None:
    assert table_problems("text\n\n| a | b |\n| c | d |\n") == [
        "line 4: no delimiter row (|---|) under the header of line 3"]
    assert table_problems("| a | b |\n|---|:---:|\n| c | d |\n") == []
    assert table_problems("| a | b |\n|---|\n| c | d |\n") == ["line 2: 1 cells, the header has 2"]
    assert table_problems("| a | b |\n|---|---|\n| c | d | e |\n| f |\n") == [
        "line 3: 3 cells, the header has 2", "line 4: 1 cells, the header has 2"]
    # an escaped pipe is text, also in a code span; an unescaped one in a code span splits the cell
    assert table_problems("| a | b |\n|---|---|\n| Σ\\|w\\| | `x \\| y` |\n") == []
    assert table_problems("| a | b |\n|---|---|\n| c | `x | y` |\n") == ["line 3: 3 cells, the header has 2"]
    assert table_problems("```\n| a |\n| b |\n```\n| a |\n|---|\n") == []
