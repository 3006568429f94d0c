"""What the Snakemake report holds: one entry per figure, table and error map.

Parse-time planning, standard library only (the Snakefile calls
:func:`report_items` while it builds the DAG).  Each :class:`Item` names the
file a rule's ``report()`` flag marks, its category (one per track), its
subcategory, its labels (figure number and database) and the generated
caption file that rule ``write_claims`` writes (:mod:`brdfpipe.report.captions`).
The same list is what the tests check the built ``report.zip`` against.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from brdfpipe.core import filenames
from brdfpipe.registry import figures as figure_specs

__all__ = [
    "ACQUISITION",
    "MANIFOLD",
    "RENDERING",
    "CLAIMS",
    "FIGURE_NUMBERS",
    "Item",
    "report_items",
    "figure_notes",
]

#: Report categories: one per track, and the claims table.
ACQUISITION = "Acquisition — Xu 2016"
MANIFOLD = "Manifold — Soler 2018"
RENDERING = "Rendering"
CLAIMS = "Claims"

#: Caption key → the paper figure (or equation) the output is an analogue of (:mod:`brdfpipe.registry.figures`).
FIGURE_NUMBERS: dict[str, str] = figure_specs.paper_figures()


@dataclass(frozen=True)
class Item:
    """One file of the report: ``path`` (as the rule declares it) and how it is shown."""

    key: str  #: caption key (:data:`FIGURE_NUMBERS`, :data:`brdfpipe.report.captions.CAPTIONS`)
    path: str
    category: str
    subcategory: str
    caption: str  #: generated caption file (:func:`brdfpipe.core.filenames.caption`)
    labels: dict[str, str] = field(default_factory=dict)

    def report_kwargs(self, caption_path: str) -> dict[str, object]:
        """Keyword arguments of Snakemake's ``report()`` (``caption_path``: the caption as the rule sees it)."""
        return {"caption": caption_path, "category": self.category, "subcategory": self.subcategory,
                "labels": dict(self.labels)}


def _png(files: Sequence[str]) -> str:
    pngs = [f for f in files if f.endswith(".png")]
    if len(pngs) != 1:
        raise ValueError(f"a figure needs exactly one PNG, got {list(files)}")
    return pngs[0]


def report_items(
    *,
    database: str,
    acquisition_figures: Mapping[str, Sequence[str]],
    manifold_figures: Mapping[str, Sequence[str]],
    render_figures: Mapping[str, Sequence[str]],
    floor_figure: Sequence[str] = (),
    spaces_table: str | None = None,
    errormaps: Sequence[tuple[str, str, str]] = (),
    errormap_summary: str | None = None,
    floor_check_table: str | None = None,
    closedloop_figure: Sequence[str] = (),
    closedloop_table: str | None = None,
    unseen_figure: Sequence[str] = (),
    unseen_table: str | None = None,
    unseen_albedo: Sequence[str] = (),
    manifold_unseen_figure: Sequence[str] = (),
    manifold_unseen_table: str | None = None,
) -> list[Item]:
    """Every report entry of a configuration, in report order.

    Figures: the PNG of each figure of ``*_figures`` (:mod:`brdfpipe.plan.outputs`; the
    PDF next to it is the same figure; ``acquisition_figures``: those of both
    Xu figure rules, shown in the registry's order); Xu Fig. 8's CSV table;
    ``errormaps``: ``(path, t, error.png)`` per rendered path point (the EXR
    maps are data: browsers cannot show them, the captions name them);
    the summary tables when the configuration writes them; the closed
    loop's figure and ``closedloop.csv`` when it runs; the unseen
    materials' figures, tables and albedo CSVs (config ``unseen``) when
    there are any (subcategory "Unseen materials"); the claims table.
    ``database``: ``merl`` or ``synthetic`` (a label of every entry).
    """
    items: list[Item] = []

    def add(key: str, file: str, category: str, sub: str, caption: str | None = None, **labels: str) -> None:
        lab = {"figure": FIGURE_NUMBERS[key], **labels, "database": database}
        items.append(Item(key, file, category, sub, filenames.caption(caption or key), lab))

    order = [f.key for f in figure_specs.track_figures("acquisition")]
    for k, files in sorted(acquisition_figures.items(), key=lambda kv: order.index(kv[0])):
        add(f"xu-{k}", _png(files), ACQUISITION, "Figures")
        if k == "fig08":
            add("xu-fig08-table", next(f for f in files if f.endswith(".csv")), ACQUISITION, "Tables")
    if closedloop_figure:
        add("xu-closedloop", _png(closedloop_figure), ACQUISITION, "Closed loop")
    if closedloop_table:
        add("xu-closedloop-table", closedloop_table, ACQUISITION, "Closed loop")
    if unseen_figure:
        add("xu-unseen", _png(unseen_figure), ACQUISITION, "Unseen materials")
    if unseen_table:
        add("xu-unseen-table", unseen_table, ACQUISITION, "Unseen materials")
    for path in unseen_albedo:
        add("unseen-albedo", path, ACQUISITION, "Unseen materials", unseen=path.rsplit("/", 1)[-1][: -len("-albedo.csv")])
    for k, files in manifold_figures.items():
        add(f"soler-{k}", _png(files), MANIFOLD, "Figures")
    if spaces_table:
        add("soler-spaces-table", spaces_table, MANIFOLD, "Tables")
    if manifold_unseen_figure:
        add("soler-unseen", _png(manifold_unseen_figure), MANIFOLD, "Unseen materials")
    if manifold_unseen_table:
        add("soler-unseen-table", manifold_unseen_table, MANIFOLD, "Unseen materials")
    for k, files in render_figures.items():
        add(f"render-{k}", _png(files), RENDERING, "Figures")
    for path, t, png in errormaps:
        add("render-errormap", png, RENDERING, "Error maps", caption="render-errormaps", path=path, t=t)
    if errormap_summary:
        add("render-summary", errormap_summary, RENDERING, "Tables")
    if floor_figure:
        add("render-floor-check", _png(floor_figure), RENDERING, "Noise-floor check")
    if floor_check_table:
        add("render-floor-check-table", floor_check_table, RENDERING, "Noise-floor check")
    add("claims", filenames.claims_csv(), CLAIMS, "Claims")
    return items


def figure_notes(
    *,
    acquisition_figures: Mapping[str, Sequence[str]],
    manifold_figures: Mapping[str, Sequence[str]],
    render_figures: Mapping[str, Sequence[str]],
) -> dict[str, str]:
    """Report key → the note file (``<stem>.json``) of every planned figure that writes one (its caption quotes it)."""
    out: dict[str, str] = {}
    for track, figures in (("acquisition", acquisition_figures), ("manifold", manifold_figures),
                           ("rendering", render_figures)):
        for k, files in figures.items():
            notes = [f for f in files if f.endswith(".json")]
            if notes:
                out[f"{figure_specs.TRACK_PREFIX[track]}-{k}"] = notes[0]
    return out
