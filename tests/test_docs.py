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


def test_layout_names_every_module_of_every_subpackage() -> None:
    """Each subpackage's line of the README's Layout names all its modules (it omitted manifold/blendpass.py)."""
    entries = _layout_entries()
    for pkg in sorted(p for p in (ROOT / "src" / "brdfpipe").iterdir() if (p / "__init__.py").is_file()):
        words = set(re.findall(r"[a-z_]+", entries.get(pkg.name, "")))
        missing = [m.stem for m in sorted(pkg.glob("*.py")) if not m.stem.startswith("_") and m.stem not in words]
        assert not missing, f"README's Layout line of {pkg.name}/ does not name {', '.join(missing)}"


def _tables_without_header(text: str) -> list[int]:
    """Line numbers (1-based) of Markdown tables whose first row is not followed by a |---| separator."""
    lines, bad, fenced = text.split("\n"), [], False
    for i, line in enumerate(lines):
        if _FENCE.match(line.strip()):
            fenced = not fenced
        starts = line.lstrip().startswith("|") and not (i and lines[i - 1].lstrip().startswith("|"))
        if fenced or not starts:
            continue
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if not re.fullmatch(r"\s*\|(\s*:?-+:?\s*\|)+\s*", nxt):
            bad.append(i + 1)
    return bad


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_table_has_a_header(page: Path) -> None:
    """A table without its header row renders as one paragraph of pipes (docs/outputs.md lost it once)."""
    assert not _tables_without_header(page.read_text(encoding="utf-8")), (
        f"{page.relative_to(ROOT)}: tables without a header at lines {_tables_without_header(page.read_text())}")


def test_the_header_check_sees_a_headless_table() -> None:
    assert _tables_without_header("text\n\n| a | b |\n| c | d |\n") == [3]
    assert _tables_without_header("| a | b |\n|---|:---:|\n| c | d |\n") == []
