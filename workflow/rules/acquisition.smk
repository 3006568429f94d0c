# Acquisition track (Xu 2016): log-relative mapping of the store, then the
# PCA/SVD of the mapped rows, streamed as scatter (one Gram block of columns
# per job; `--set-scatter gram=N` spreads it over N jobs) and gather
# (eigendecomposition, Q written block by block); direction sets per setup,
# FOV and metric; their leave-out evaluation, E(S) check and training-size
# curve (three jobs), the directions Xu §6 states in words, and the figures;
# the closed loop (held-out materials photographed by the direction sets,
# reconstructed from the images).


rule map_logrelative:
    input:
        store=fn.store(),
        splits=fn.splits(),
        stamp=stamp_of("map_logrelative"),
    output:
        logmap=directory(fn.logmap("{split}")),
    log:
        "logs/map_logrelative/{split}.log",
    benchmark:
        "benchmarks/map_logrelative/{split}.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("map_logrelative"),
        runtime=30,
    params:
        train=lambda wildcards: split_training_materials(wildcards.split),
        weighting=ACQ["weighting"],
        code=code("map_logrelative.py"),
    script:
        "../scripts/map_logrelative.py"


rule accumulate_gram:
    input:
        logmap=fn.logmap("{split}"),
        stamp=stamp_of("accumulate_gram"),
    output:
        partial=temp(fn.gram_partial("{split}", "{scatteritem}")),
    log:
        "logs/accumulate_gram/{split}-{scatteritem}.log",
    benchmark:
        "benchmarks/accumulate_gram/{split}-{scatteritem}.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("accumulate_gram"),
        runtime=30,
    params:
        code=code("accumulate_gram.py"),
    script:
        "../scripts/accumulate_gram.py"


rule decompose_svd:
    input:
        logmap=fn.logmap("{split}"),
        partials=gather.gram(fn.gram_partial("{{split}}", "{scatteritem}")),
        stamp=stamp_of("decompose_svd"),
    output:
        model=directory(fn.svd_model("{split}")),
    log:
        "logs/decompose_svd/{split}.log",
    benchmark:
        "benchmarks/decompose_svd/{split}.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 2
    resources:
        mem_mb=mem("decompose_svd"),
        runtime=30,
    params:
        code=code("decompose_svd.py"),
    script:
        "../scripts/decompose_svd.py"


rule optimize_directions:
    input:
        model=fn.svd_model("{split}"),
        stamp=stamp_of("optimize_directions"),
    output:
        directions=fn.directions("{split}", "{setup}", "{fov}", "{metric}"),
    log:
        "logs/optimize_directions/{split}/{setup}-fov{fov}-{metric}.log",
    benchmark:
        "benchmarks/optimize_directions/{split}/{setup}-fov{fov}-{metric}.tsv"
    # BLAS limited to these threads by the script (brdfpipe.core.threads.blas_threads).
    priority: 10
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("optimize_directions"),
        runtime=60,
    params:
        n_max=lambda wildcards: ACQ[setup_specs.SETUPS[wildcards.setup].n_max_key],
        candidates=ACQ["candidates"],
        grid=ACQ["grid"],
        eta=ACQ["eta"],
        beta=ACQ["beta"],
        seed=ACQ["seed"],
        screen_grid=ACQ["screen_grid"],
        screen_keep=ACQ["screen_keep"],
        code=code("optimize_directions.py"),
    script:
        "../scripts/optimize_directions.py"


rule evaluate_directions:
    input:
        store=fn.store(),
        model=fn.svd_model("train"),
        directions=DIRECTIONS["train"],
        stamp=stamp_of("evaluate_directions"),
    output:
        errors=fn.errors(),
    log:
        "logs/evaluate_directions.log",
    benchmark:
        "benchmarks/evaluate_directions.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 2
    resources:
        mem_mb=mem("evaluate_directions"),
        runtime=60,
    params:
        test_materials=TEST_MATERIALS,
        eta=ACQ["eta"],
        code=code("evaluate_directions.py"),
    script:
        "../scripts/evaluate_directions.py"


rule check_directions:
    input:
        logmap=fn.logmap("{split}"),
        model=fn.svd_model("{split}"),
        directions=lambda wildcards: DIRECTIONS[wildcards.split],
        stamp=stamp_of("check_directions"),
    output:
        consistency=fn.consistency("{split}"),
    log:
        "logs/check_directions/{split}.log",
    benchmark:
        "benchmarks/check_directions/{split}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("check_directions"),
        runtime=30,
    params:
        code=code("check_directions.py"),
    script:
        "../scripts/check_directions.py"


if CURVE_DIRECTIONS:

    rule evaluate_training_size:
        input:
            store=fn.store(),
            logmap=fn.logmap("train"),
            directions=CURVE_DIRECTIONS,
            stamp=stamp_of("evaluate_training_size"),
        output:
            training_size=fn.training_size(),
        log:
            "logs/evaluate_training_size.log",
        benchmark:
            "benchmarks/evaluate_training_size.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            mem_mb=mem("evaluate_training_size"),
            runtime=60,
        params:
            test_materials=TEST_MATERIALS,
            eta=ACQ["eta"],
            sizes=TRAINING_SIZES,
            order_seed=ACQ["seed"],
            orders=ACQ["training_orders"],
            code=code("evaluate_training_size.py"),
        script:
            "../scripts/evaluate_training_size.py"


if PAPER_DIRECTIONS:

    # The directions Xu §6 states in words ("θh = 3° at about 50°", "exact specular at 60°"),
    # each the best configuration matching its sentence (the optimiser adds the unstated images),
    # with its E(S) on the model of all materials, beside Fig. 8's optimum in the claims.
    rule evaluate_paper_directions:
        input:
            model=fn.svd_model("all"),
            stamp=stamp_of("evaluate_paper_directions"),
        output:
            table=fn.paper_directions(),
        log:
            "logs/evaluate_paper_directions.log",
        benchmark:
            "benchmarks/evaluate_paper_directions.tsv"
        # BLAS limited to these threads by the script (brdfpipe.core.threads.blas_threads).
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("evaluate_paper_directions"),
            runtime=30,
        params:
            directions=PAPER_DIRECTIONS,
            grid=ACQ["grid"],
            eta=ACQ["eta"],
            beta=ACQ["beta"],
            candidates=ACQ["candidates"],
            seed=ACQ["seed"],
            screen_grid=ACQ["screen_grid"],
            screen_keep=ACQ["screen_keep"],
            code=code("evaluate_paper_directions.py"),
        script:
            "../scripts/evaluate_paper_directions.py"


rule plot_acquisition_figures:
    input:
        errors=fn.errors(),
        training_size=fn.training_size() if "fig07" in ACQUISITION_FIGURES else [],
        directions=DIRECTIONS["all"] + DIRECTIONS["train"],
        stamp=stamp_of("plot_acquisition_figures"),
    output:
        **reported_figures(ACQUISITION_FIGURES),
    log:
        "logs/plot_acquisition_figures.log",
    benchmark:
        "benchmarks/plot_acquisition_figures.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("plot_acquisition_figures"),
        runtime=15,
    params:
        figure_keys=list(ACQUISITION_FIGURES),
        fovs=ACQ["fovs"],
        fixed_fov=ACQ["fixed_fov"],
        figure_fov=plan.curve_fov(ACQ),
        figure_materials=FIGURE_MATERIALS,
        n_point=min(5, ACQ["n_max_point"]),
        code=code("plot_acquisition_figures.py"),
    script:
        "../scripts/plot_acquisition_figures.py"


if CLOSEDLOOP_SETS:

    # One job per held-out material: every image of its sets (small: grid ×
    # grid pixels, direct light only), the noiseless render and the sensor's
    # photograph, and the observation tables read off both.
    rule capture_closedloop:
        input:
            binary=source_file,
            directions=CLOSEDLOOP_DIRECTIONS,
            stamp=stamp_of("capture_closedloop"),
        output:
            renders=closedloop_images("{material}", "render"),
            photographs=closedloop_images("{material}", "sensor"),
            noiseless=closedloop_tables("{material}", "noiseless"),
            observations=closedloop_tables("{material}", "sensor"),
        log:
            "logs/capture_closedloop/{material}.log",
        benchmark:
            "benchmarks/capture_closedloop/{material}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("capture_closedloop"),
            runtime=30,
        params:
            n_images=CLOSEDLOOP_N,
            spp=CLOSED["spp"],
            seed=CLOSED["seed"],
            light_distance=CLOSED["light_distance"],
            min_snr=CLOSED["min_snr"],
            sensor=CLOSED["sensor"],
            variant=RENDER["variant"],
            database=DATABASE.kind,
            code=code("capture_closedloop.py"),
        script:
            "../scripts/capture_closedloop.py"

    rule evaluate_closedloop:
        input:
            store=fn.store(),
            model=fn.svd_model("train"),
            directions=CLOSEDLOOP_DIRECTIONS,
            noiseless=[
                f for m in TEST_MATERIALS for f in closedloop_tables(m, "noiseless")
            ],
            observations=[
                f for m in TEST_MATERIALS for f in closedloop_tables(m, "sensor")
            ],
            stamp=stamp_of("evaluate_closedloop"),
        output:
            errors=reported(fn.closedloop_errors()),
        log:
            "logs/evaluate_closedloop.log",
        benchmark:
            "benchmarks/evaluate_closedloop.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("evaluate_closedloop"),
            runtime=30,
        params:
            materials=TEST_MATERIALS,
            n_images=CLOSEDLOOP_N,
            eta=ACQ["eta"],
            code=code("evaluate_closedloop.py"),
        script:
            "../scripts/evaluate_closedloop.py"

    rule plot_closedloop:
        input:
            closedloop=fn.closedloop_errors(),
            stamp=stamp_of("plot_closedloop"),
        output:
            **reported_figures({"closedloop": fn.figure_files(fn.CLOSEDLOOP_STEM)}),
        log:
            "logs/plot_closedloop.log",
        benchmark:
            "benchmarks/plot_closedloop.tsv"
        localrule: True
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("plot_closedloop"),
            runtime=15,
        params:
            code=code("plot_closedloop.py"),
        script:
            "../scripts/plot_closedloop.py"


if RECON_SETS:

    # Xu Figs. 2 and 15: a held-out material reconstructed from each set of RECON_SETS
    # by table lookup (the evaluation's observations), written as MERL tables with a
    # derived mark, and the observed pixels of every image; one pass over Q per material.
    rule reconstruct_figure_material:
        input:
            store=fn.store(),
            model=fn.svd_model("train"),
            directions=RECON_DIRECTIONS,
            stamp=stamp_of("reconstruct_figure_material"),
        output:
            tables=recon_tables("{material}"),
            inputs=recon_inputs("{material}"),
        log:
            "logs/reconstruct_figure_material/{material}.log",
        benchmark:
            "benchmarks/reconstruct_figure_material/{material}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("reconstruct_figure_material"),
            runtime=15,
        params:
            sets=[[fn.directions("train", s, f, m), n] for s, f, m, n in RECON_SETS],
            images=[recon_image_count(s) for s in RECON_SETS],
            eta=ACQ["eta"],
            code=code("reconstruct_figure_material.py"),
        script:
            "../scripts/reconstruct_figure_material.py"

    rule plot_reconstruction_figures:
        input:
            errors=fn.errors(),
            prerenders=[fn.prerender(SCENE, m) for m in RECON_MATERIALS],
            renders=[f for m in RECON_MATERIALS for f in recon_renders(m)],
            inputs=[f for m in RECON_MATERIALS for f in recon_inputs(m)],
            stamp=stamp_of("plot_reconstruction_figures"),
        output:
            **reported_figures(RECONSTRUCTION_FIGURES),
        log:
            "logs/plot_reconstruction_figures.log",
        benchmark:
            "benchmarks/plot_reconstruction_figures.tsv"
        localrule: True
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("plot_reconstruction_figures"),
            runtime=15,
        params:
            figure_keys=list(RECONSTRUCTION_FIGURES),
            materials=RECON_MATERIALS,
            sets=[list(s) for s in RECON_SETS],
            columns={
                k: [[label, list(s)] for label, s in cols]
                for k, cols in RECON_COLUMNS.items()
            },
            code=code("plot_reconstruction_figures.py"),
        script:
            "../scripts/plot_reconstruction_figures.py"
