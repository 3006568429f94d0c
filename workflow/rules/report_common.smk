# What the report (snakemake --report results/report.zip; make report) holds:
# every figure, table and error map (brdfpipe.plan.report), with category,
# labels and a generated caption. The rules that write them wrap those outputs
# in reported(); rules/report.smk writes the captions and the front page.

from brdfpipe.plan import report as report_plan

REPORT_ITEMS = report_plan.report_items(
    database=DATABASE.kind,
    acquisition_figures={**ACQUISITION_FIGURES, **RECONSTRUCTION_FIGURES},
    manifold_figures=MANIFOLD_FIGURES,
    render_figures=RENDER_FIGURES,
    floor_figure=FLOOR_FIGURE,
    spaces_table=fn.spaces_csv(),
    errormaps=[(p, t, fn.errormap(SCENE, p, t, "error.png")) for p, t in PATH_POINTS],
    errormap_summary=fn.errormap_summary(SCENE) if PATH_POINTS else None,
    floor_check_table=fn.floor_check_csv(FLOOR_SCENE) if FLOOR_CANDIDATES else None,
    closedloop_figure=fn.figure_files(fn.CLOSEDLOOP_STEM) if CLOSEDLOOP_SETS else (),
    closedloop_table=fn.closedloop_errors() if CLOSEDLOOP_SETS else None,
    unseen_figure=UNSEEN_FIGURES.get("acquisition", ()),
    unseen_table=fn.unseen_errors() if UNSEEN_EVALUATED else None,
    unseen_albedo=[fn.unseen_albedo(d) for d in UNSEEN],
    manifold_unseen_figure=UNSEEN_FIGURES.get("manifold", ()),
    manifold_unseen_table=fn.unseen_manifold() if UNSEEN else None,
)
# Report key -> the note (this run's numbers) a figure writes next to it, quoted by its caption.
FIGURE_NOTES = report_plan.figure_notes(
    acquisition_figures=ACQUISITION_FIGURES,
    manifold_figures=MANIFOLD_FIGURES,
    render_figures=RENDER_FIGURES,
)
_REPORTED = {item.path: item for item in REPORT_ITEMS}
REPORT_CAPTIONS = sorted({item.caption for item in REPORT_ITEMS})
REPORT_FILES = [
    fn.claims_csv(),
    fn.claims_json(),
    fn.claims_rst(),
    fn.front_rst(),
    fn.fidelity_md(),
    fn.stage_times_csv(),
    fn.stage_times_rst(),
] + REPORT_CAPTIONS


def reported(path):
    """``path``, flagged for the report (category, labels, caption) when the report holds it."""
    item = _REPORTED.get(path)
    if item is None:
        return path
    # the generated caption, by absolute path: Snakemake resolves a relative
    # caption against this file's folder, while results/ lies in the working directory
    return report(path, **item.report_kwargs(os.path.abspath(item.caption)))


def reported_figures(figures):
    """A {key: [files]} figure mapping with its report files flagged (see reported)."""
    return {key: [reported(f) for f in files] for key, files in figures.items()}


def reported_pattern(pattern, key):
    """An output pattern with wildcards (``{database}``), flagged for the report as the items of ``key``.

    Every concrete item of ``key`` shares one caption; the pattern's
    wildcards become the ``unseen`` label (Snakemake expands them per job).
    """
    items = [item for item in REPORT_ITEMS if item.key == key]
    if not items:
        return pattern
    first = items[0]
    labels = {
        k: ("{database}" if k == "unseen" else v) for k, v in first.labels.items()
    }
    return report(
        pattern,
        caption=os.path.abspath(first.caption),
        category=first.category,
        subcategory=first.subcategory,
        labels=labels,
    )
