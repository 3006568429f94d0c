"""Report captions: what each figure shows, and the paper's claims it carries, with this run's numbers.

A caption is reStructuredText written by rule ``write_claims`` from the
run's claims (:mod:`brdfpipe.report.claims`), one file per figure, table or
set of error maps (:func:`brdfpipe.core.filenames.caption`).  Snakemake reads a
caption file when it builds the report (``snakemake --report``), not when
it parses the workflow, so the captions can hold numbers computed by a job.
Snakemake renders captions as Jinja2 templates first: the text is wrapped
in a ``raw`` block so no measured text is ever read as template syntax.
Every string that comes from the run (claims, the database label, file
names) is escaped by :mod:`brdfpipe.report.rst`, so no name can inject
markup, a link or template code.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from brdfpipe.core import atomic
from brdfpipe.report import rst
from brdfpipe.report.claims import Claim, rst_cell
from brdfpipe.registry import figures as figure_specs

__all__ = ["DESCRIPTIONS", "caption_rst", "write_captions"]

#: Caption key → what the figure or table shows (the claims follow it; :mod:`brdfpipe.registry.figures`).
DESCRIPTIONS: dict[str, str] = figure_specs.captions()

#: Extra note for the EXR error maps, which browsers cannot show ({error}, {blended}: rst literals).
_EXR_NOTE = ("The error maps' data are EXR files (float32, not shown: browsers cannot display EXR): "
             "{error} (\\|blend − reference\\|) and {blended} (the blend), next to each PNG shown here.")


def _bars(text: str) -> str:
    """``|x|`` in the descriptions is an absolute value, not an rst substitution."""
    return text.replace("|", "\\|")


def _claim_item(c: Claim) -> str:
    who = "Our own check" if c.ours else f"{rst_cell(c.paper)}, {rst_cell(c.where)}"
    said = "" if c.ours else f" The paper: {rst_cell(c.sentence)}."
    return (f"- {who}:{said} Checked: {rst_cell(c.claim)}. This run: {rst_cell(c.measured)}. "
            f"**{rst_cell(c.verdict)}**: {rst_cell(c.cause)}.")


def caption_rst(key: str, claims: Iterable[Claim], *, database: str, files: Sequence[str] = (),
                note: str = "") -> str:
    """The caption of one report entry: title with database, description, the figure's note (this run's
    numbers, when it writes one), its claims, the files it covers."""
    if key not in DESCRIPTIONS:
        raise KeyError(f"no caption description for {key!r}")
    mine = [c for c in claims if key in c.figures]
    lines = [f"**{figure_specs.paper_figures()[key]}** analogue — database: **{rst.text(database)}**", "",
             _bars(DESCRIPTIONS[key]), ""]
    if note:
        lines += ["This run: " + rst.text(note), ""]
    if mine:
        lines += ["Claims (the paper's sentence, as checked, this run, the verdict and its cause):", ""] + [_claim_item(c) for c in mine] + [""]
    else:
        lines += ["The paper makes no quantitative claim about this figure; it is shown for comparison.", ""]
    if key == "render-errormap":
        prefixes = sorted({f[: -len("-error.png")] for f in files if f.endswith("-error.png")})
        prefix = prefixes[0] if len(prefixes) == 1 else "<path>-t<t>"
        lines += [_EXR_NOTE.format(error=rst.literal(f"{prefix}-error.exr"),
                                   blended=rst.literal(f"{prefix}-blended.exr")), ""]
    pdfs = [f[:-4] + ".pdf" for f in files if f.endswith(".png") and key != "render-errormap"]
    if pdfs:
        lines += ["Vector version: " + ", ".join(rst.literal(p) for p in pdfs) + ".", ""]
    return rst.jinja_raw("\n".join(lines))


def write_captions(items: Sequence[Mapping[str, str]], claims: Sequence[Claim], *, database: str,
                   notes: Mapping[str, str] | None = None) -> list[Path]:
    """One caption file per distinct ``caption`` of ``items`` (dicts with ``key``, ``path``, ``caption``).

    ``notes``: report key → the figure's note (:func:`brdfpipe.core.notes.read_note`), quoted by its caption.
    """
    by_caption: dict[str, tuple[str, list[str]]] = {}
    for it in items:
        key, files = by_caption.setdefault(it["caption"], (it["key"], []))
        if key != it["key"]:
            raise ValueError(f"caption {it['caption']} is shared by {key!r} and {it['key']!r}")
        files.append(it["path"])
    out = []
    for cap, (key, files) in by_caption.items():
        atomic.write_text(cap, caption_rst(key, claims, database=database, files=files,
                                           note=(notes or {}).get(key, "")))
        out.append(Path(cap))
    return out
