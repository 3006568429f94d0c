# The report (snakemake --report results/report.zip; make report): which
# figures, tables and error maps it holds (brdfpipe.report.items; the rules
# that write them wrap those outputs in reported()), and two light local rules
# that write what the report shows besides the files: the claims of both
# papers computed from the run's CSVs, one caption per entry and the front
# page (write_claims), and the wall time per stage (summarize_stage_times).
# Snakemake reads the captions and workflow/report/workflow.rst when it builds
# the report, so they can hold the run's numbers (see brdfpipe.report).

from brdfpipe.report import items as report_plan

REPORT_ITEMS = report_plan.report_items(
    database=DATABASE.kind,
    acquisition_figures=ACQUISITION_FIGURES,
    manifold_figures=MANIFOLD_FIGURES,
    render_figures=RENDER_FIGURES,
    floor_figure=FLOOR_FIGURE,
    spaces_table=fn.spaces_csv(),
    errormaps=[(p, t, fn.errormap(SCENE, p, t, "error.png")) for p, t in PATH_POINTS],
    errormap_summary=fn.errormap_summary(SCENE) if PATH_POINTS else None,
    floor_check_table=fn.floor_check_csv(FLOOR_SCENE) if FLOOR_CANDIDATES else None,
)
_REPORTED = {item.path: item for item in REPORT_ITEMS}
REPORT_CAPTIONS = sorted({item.caption for item in REPORT_ITEMS})
REPORT_FILES = [
    fn.claims_csv(),
    fn.claims_json(),
    fn.claims_rst(),
    fn.front_rst(),
    fn.stage_times_csv(),
    fn.stage_times_rst(),
] + REPORT_CAPTIONS


report: "../report/workflow.rst"


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


rule write_claims:
    input:
        splits=fn.splits(),
        errors=fn.errors(),
        training_size=fn.training_size() if CURVE_DIRECTIONS else [],
        fig08_table=[
            f for f in ACQUISITION_FIGURES.get("fig08", []) if f.endswith(".csv")
        ],
        reproduction=fn.reproduction(),
        spaces=fn.spaces_csv(),
        paths=fn.paths_csv(),
        traces=expand(fn.gplvm_trace(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        bounce_shares=fn.bounce_shares(SCENE),
        errormap_summary=fn.errormap_summary(SCENE) if PATH_POINTS else [],
        floor_check=fn.floor_check_csv(FLOOR_SCENE) if FLOOR_CANDIDATES else [],
    output:
        claims=reported(fn.claims_csv()),
        json=fn.claims_json(),
        rst=fn.claims_rst(),
        front=fn.front_rst(),
        captions=REPORT_CAPTIONS,
    log:
        "logs/write_claims.log",
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("write_claims"),
        runtime=5,
    params:
        entries=[
            {"key": it.key, "path": it.path, "caption": it.caption}
            for it in REPORT_ITEMS
        ],
        latent_dims=MAN["latent_dims"],
        config=dict(config),
        configfiles=[str(f) for f in workflow.configfiles],
        targets={k: len(v) if isinstance(v, list) else 1 for k, v in TARGETS.items()},
        code=code("write_claims.py"),
    script:
        "../scripts/write_claims.py"


rule summarize_stage_times:
    input:
        targets=[
            f for v in TARGETS.values() for f in (v if isinstance(v, list) else [v])
        ],
        claims=fn.claims_csv(),
    output:
        csv=fn.stage_times_csv(),
        rst=fn.stage_times_rst(),
    log:
        "logs/summarize_stage_times.log",
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("summarize_stage_times"),
        runtime=5,
    params:
        benchmarks="benchmarks",
        code=code("summarize_stage_times.py"),
    script:
        "../scripts/summarize_stage_times.py"
