# Materials outside the run's database (config unseen; Xu 2016 §7: what
# acquisition is for): the fits of each unseen database evaluated into MERL
# files and a store of their own (one job per database: a store has one label),
# photographed by the closed loop's set-ups (one Mitsuba process per database),
# reconstructed with the run's training model and direction sets (one job),
# placed on the default candidate's GPLVM manifold (one job), and drawn next to
# the held-out materials.

if UNSEEN:

    rule evaluate_unseen_fits:
        input:
            archive=lambda w: str(UNSEEN[w.database].archive),
            stamp=stamp_of("evaluate_unseen_fits"),
        output:
            tables=directory(fn.unseen_tables("{database}")),
            store=directory(fn.unseen_store("{database}")),
            albedo=reported_pattern(fn.unseen_albedo("{database}"), "unseen-albedo"),
        log:
            "logs/evaluate_unseen_fits/{database}.log",
        benchmark:
            "benchmarks/evaluate_unseen_fits/{database}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 4
        resources:
            mem_mb=mem("evaluate_unseen_fits"),
            runtime=10,
        params:
            fits=lambda w: {
                m: UNSEEN[w.database].fits[m] for m in UNSEEN[w.database].materials
            },
            binaries=lambda w: [
                fn.unseen_binary(w.database, m) for m in UNSEEN[w.database].materials
            ],
            code=code("evaluate_unseen_fits.py"),
        script:
            "../scripts/evaluate_unseen_fits.py"

    if CLOSEDLOOP_SETS:

        rule capture_unseen_closedloop:
            input:
                tables=fn.unseen_tables("{database}"),
                directions=CLOSEDLOOP_DIRECTIONS,
                stamp=stamp_of("capture_unseen_closedloop"),
            output:
                observations=fn.unseen_observations("{database}"),
            log:
                "logs/capture_unseen_closedloop/{database}.log",
            benchmark:
                "benchmarks/capture_unseen_closedloop/{database}.tsv"
            conda:
                "../envs/brdfpipe.yaml"
            threads: 1
            resources:
                gpu=RENDER_GPUS,
                mem_mb=mem("capture_unseen_closedloop"),
                runtime=30,
            params:
                binaries=lambda w: {
                    m: fn.unseen_binary(w.database, m)
                    for m in UNSEEN[w.database].materials
                },
                n_images=CLOSEDLOOP_N,
                spp=CLOSED["spp"],
                seed=CLOSED["seed"],
                light_distance=CLOSED["light_distance"],
                min_snr=CLOSED["min_snr"],
                sensor=CLOSED["sensor"],
                variant=RENDER["variant"],
                code=code("capture_unseen_closedloop.py"),
            script:
                "../scripts/capture_unseen_closedloop.py"

    if UNSEEN_EVALUATED:

        rule evaluate_unseen:
            input:
                stores=[fn.unseen_store(d) for d in UNSEEN],
                model=fn.svd_model("train"),
                directions=UNSEEN_DIRECTIONS,
                closedloop_directions=CLOSEDLOOP_DIRECTIONS,
                observations=(
                    [fn.unseen_observations(d) for d in UNSEEN]
                    if CLOSEDLOOP_SETS
                    else []
                ),
                stamp=stamp_of("evaluate_unseen"),
            output:
                errors=reported(fn.unseen_errors()),
            log:
                "logs/evaluate_unseen.log",
            benchmark:
                "benchmarks/evaluate_unseen.tsv"
            conda:
                "../envs/brdfpipe.yaml"
            # BLAS limited to these threads by the library (many small solves)
            threads: 1
            resources:
                mem_mb=mem("evaluate_unseen"),
                runtime=30,
            params:
                databases=list(UNSEEN),
                n_images=CLOSEDLOOP_N,
                eta=ACQ["eta"],
                code=code("evaluate_unseen.py"),
            script:
                "../scripts/evaluate_unseen.py"

    rule locate_unseen:
        input:
            store=fn.store(),
            gram=fn.gram(MAN["space"]),
            models=expand(
                fn.gplvm_model(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]
            ),
            unseen=[fn.unseen_store(d) for d in UNSEEN],
            stamp=stamp_of("locate_unseen"),
        output:
            unseen=reported(fn.unseen_manifold()),
        log:
            "logs/locate_unseen.log",
        benchmark:
            "benchmarks/locate_unseen.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        # BLAS limited to these threads by the library (idle BLAS threads slow the searches' small products)
        threads: 1
        resources:
            mem_mb=mem("locate_unseen"),
            runtime=30,
        params:
            latent_dims=MAN["latent_dims"],
            pca_ks=MAN["pca_components"],
            code=code("locate_unseen.py"),
        script:
            "../scripts/locate_unseen.py"

    if UNSEEN_EVALUATED:

        rule plot_unseen_errors:
            input:
                errors=fn.errors(),
                closedloop=fn.closedloop_errors() if CLOSEDLOOP_SETS else [],
                unseen=fn.unseen_errors(),
                stamp=stamp_of("plot_unseen_errors"),
            output:
                **reported_figures({"acquisition": UNSEEN_FIGURES["acquisition"]}),
            log:
                "logs/plot_unseen_errors.log",
            benchmark:
                "benchmarks/plot_unseen_errors.tsv"
            localrule: True
            conda:
                "../envs/brdfpipe.yaml"
            threads: 1
            resources:
                mem_mb=mem("plot_unseen_errors"),
                runtime=10,
            params:
                code=code("plot_unseen_errors.py"),
            script:
                "../scripts/plot_unseen_errors.py"

    rule plot_unseen_latent:
        input:
            model=fn.gplvm_model(DEFAULT_CANDIDATE, UNSEEN_MAP_Q),
            unseen=fn.unseen_manifold(),
            stamp=stamp_of("plot_unseen_latent"),
        output:
            **reported_figures({"manifold": UNSEEN_FIGURES["manifold"]}),
        log:
            "logs/plot_unseen_latent.log",
        benchmark:
            "benchmarks/plot_unseen_latent.tsv"
        localrule: True
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("plot_unseen_latent"),
            runtime=10,
        params:
            map_q=UNSEEN_MAP_Q,
            code=code("plot_unseen_latent.py"),
        script:
            "../scripts/plot_unseen_latent.py"
