# The report's two light local rules: the claims of both papers computed from
# the run's CSVs, one caption per report entry and the front page's body
# (write_claims), and the wall time per stage (summarize_stage_times).
# Snakemake reads the captions and workflow/report/workflow.rst when it builds
# the report, so they can hold the run's numbers (see brdfpipe.report).


rule write_claims:
    input:
        splits=fn.splits(),
        errors=fn.errors(),
        training_size=fn.training_size() if CURVE_DIRECTIONS else [],
        fig08_table=[
            f for f in ACQUISITION_FIGURES.get("fig08", []) if f.endswith(".csv")
        ],
        paper_directions=fn.paper_directions() if PAPER_DIRECTIONS else [],
        reproduction=fn.reproduction(),
        spaces=fn.spaces_csv(),
        paths=fn.paths_csv(),
        traces=expand(fn.gplvm_trace(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        bounce_shares=fn.bounce_shares(SCENE),
        errormap_summary=fn.errormap_summary(SCENE) if PATH_POINTS else [],
        floor_check=fn.floor_check_csv(FLOOR_SCENE) if FLOOR_CANDIDATES else [],
        closedloop=fn.closedloop_errors() if CLOSEDLOOP_SETS else [],
        unseen=fn.unseen_errors() if UNSEEN_EVALUATED else [],
        unseen_albedo=[fn.unseen_albedo(d) for d in UNSEEN],
        notes=list(FIGURE_NOTES.values()),
        stamp=stamp_of("write_claims"),
    output:
        claims=reported(fn.claims_csv()),
        json=fn.claims_json(),
        rst=fn.claims_rst(),
        front=fn.front_rst(),
        fidelity=fn.fidelity_md(),
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
        note_keys=list(FIGURE_NOTES),
        # the recorded runs' claims, read (digest-checked) at parse time: by content, so that
        # where the library or a user's file lives does not rerun the job, and an edit of them does
        recorded=[
            {"source": run.source, "rows": [run.rows[k] for k in run.order]}
            for run in RECORDED
        ],
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
        stamp=stamp_of("summarize_stage_times"),
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
