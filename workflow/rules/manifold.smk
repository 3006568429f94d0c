# Manifold track (Soler 2018): the N x N Gram matrix of the mean-subtracted
# materials in each data space, streamed once from the store, then one GPLVM
# fit per candidate (data space, mu, how it is fitted) and latent dimension q, the comparison of
# the candidates, the analyses of the default candidate's fits and figures.


rule compute_gram:
    input:
        store=fn.store(),
        stamp=stamp_of("compute_gram"),
    output:
        gram=fn.gram("{space}"),
    log:
        "logs/compute_gram/{space}.log",
    benchmark:
        "benchmarks/compute_gram/{space}.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("compute_gram"),
        runtime=30,
    params:
        code=code("compute_gram.py"),
    script:
        "../scripts/compute_gram.py"


rule fit_gplvm:
    input:
        gram=lambda w: fn.gram(CANDIDATES[w.candidate].space),
        stamp=stamp_of("fit_gplvm"),
    output:
        model=fn.gplvm_model("{candidate}", "{q}"),
        trace=fn.gplvm_trace("{candidate}", "{q}"),
    log:
        "logs/fit_gplvm/{candidate}/q{q}.log",
    benchmark:
        "benchmarks/fit_gplvm/{candidate}/q{q}.tsv"
    # BLAS limited to these threads by the script (brdfpipe.core.threads.blas_threads).
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("fit_gplvm"),
        runtime=30,
    params:
        ell=MAN["ell"],
        mu=lambda w: CANDIDATES[w.candidate].mu,
        seed=MAN["seed"],
        max_sweeps=MAN["max_sweeps"],
        normalise=lambda w: CANDIDATES[w.candidate].normalise,
        method=lambda w: CANDIDATES[w.candidate].method,
        init=lambda w: CANDIDATES[w.candidate].init,
        code=code("fit_gplvm.py"),
    script:
        "../scripts/fit_gplvm.py"


# Every material's albedo, once: each candidate's measurement and the analyses read it.
rule measure_material_albedos:
    input:
        store=fn.store(),
        stamp=stamp_of("measure_material_albedos"),
    output:
        albedos=fn.material_albedos(),
    log:
        "logs/measure_material_albedos.log",
    benchmark:
        "benchmarks/measure_material_albedos.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("measure_material_albedos"),
        runtime=10,
    params:
        code=code("measure_material_albedos.py"),
    script:
        "../scripts/measure_material_albedos.py"


rule analyze_manifold:
    input:
        store=fn.store(),
        albedos=fn.material_albedos(),
        gram=fn.gram(MAN["space"]),
        models=expand(fn.gplvm_model(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        stamp=stamp_of("analyze_manifold"),
    output:
        albedo=fn.albedo(),
        paths=fn.paths_csv(),
        reproduction=fn.reproduction(),
        albedo_maps=[fn.albedo_map(q) for q in ALBEDO_MAP_DIMS],
    log:
        "logs/analyze_manifold.log",
    benchmark:
        "benchmarks/analyze_manifold.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("analyze_manifold"),
        runtime=30,
    params:
        latent_dims=MAN["latent_dims"],
        albedo_map_dims=ALBEDO_MAP_DIMS,
        paths=[list(p) for p in MANIFOLD_PATHS],
        path_q=PATH_Q,
        seed=MAN["seed"],
        steps=MAN["path_steps"],
        albedo_grid=MAN["albedo_grid"],
        pca_ks=MAN["pca_components"],
        code=code("analyze_manifold.py"),
    script:
        "../scripts/analyze_manifold.py"


rule measure_gplvm_candidate:
    input:
        store=fn.store(),
        albedos=fn.material_albedos(),
        grams=lambda w: [fn.gram(s) for s in candidate_gram_spaces(w.candidate)],
        models=expand(fn.gplvm_model("{{candidate}}", "{q}"), q=MAN["latent_dims"]),
        stamp=stamp_of("measure_gplvm_candidate"),
    output:
        spaces=fn.candidate_spaces_csv("{candidate}"),
        stability=fn.candidate_stability_csv("{candidate}"),
    log:
        "logs/measure_gplvm_candidate/{candidate}.log",
    benchmark:
        "benchmarks/measure_gplvm_candidate/{candidate}.tsv"
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("measure_gplvm_candidate"),
        runtime=30,
    params:
        spaces=lambda w: candidate_gram_spaces(w.candidate),
        dims=MAN["latent_dims"],
        default=DEFAULT_CANDIDATE,
        paths=[list(p) for p in MANIFOLD_PATHS],
        path_q=PATH_Q,
        seed=MAN["seed"],
        steps=MAN["path_steps"],
        albedo_grid=MAN["albedo_grid"],
        clamped_hull_points=MAN["clamped_hull_points"],
        code=code("measure_gplvm_candidate.py"),
    script:
        "../scripts/measure_gplvm_candidate.py"


rule compare_spaces:
    input:
        spaces=expand(fn.candidate_spaces_csv("{c}"), c=CANDIDATES),
        stability=expand(fn.candidate_stability_csv("{c}"), c=CANDIDATES),
        stamp=stamp_of("compare_spaces"),
    output:
        spaces=reported(fn.spaces_csv()),
        stability=fn.spaces_stability_csv(),
    log:
        "logs/compare_spaces.log",
    priority: 20
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("compare_spaces"),
        runtime=5,
    params:
        code=code("compare_spaces.py"),
    script:
        "../scripts/compare_spaces.py"


# Soler Fig. 6: the interpolant and the eq. 7 bound along one path as the
# kernel's length scale shrinks (the default candidate's fit of the paths' q).
rule measure_lengthscales:
    input:
        model=fn.gplvm_model(DEFAULT_CANDIDATE, PATH_Q),
        gram=fn.gram(MAN["space"]),
        stamp=stamp_of("measure_lengthscales"),
    output:
        table=fn.lengthscales_csv(),
    log:
        "logs/measure_lengthscales.log",
    benchmark:
        "benchmarks/measure_lengthscales.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("measure_lengthscales"),
        runtime=5,
    params:
        path=list(FIG06_PATH),
        database=DATABASE.kind,
        code=code("measure_lengthscales.py"),
    script:
        "../scripts/measure_lengthscales.py"


rule plot_manifold_figures:
    input:
        models=expand(fn.gplvm_model(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        traces=expand(fn.gplvm_trace(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        spaces=fn.spaces_csv(),
        stability=fn.spaces_stability_csv(),
        albedo=fn.albedo(),
        albedo_maps=[fn.albedo_map(q) for q in ALBEDO_MAP_DIMS],
        paths=fn.paths_csv(),
        reproduction=fn.reproduction(),
        lengthscales=fn.lengthscales_csv(),
        stamp=stamp_of("plot_manifold_figures"),
    output:
        **reported_figures(MANIFOLD_FIGURES),
    log:
        "logs/plot_manifold_figures.log",
    benchmark:
        "benchmarks/plot_manifold_figures.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("plot_manifold_figures"),
        runtime=10,
    params:
        figure_keys=list(MANIFOLD_FIGURES),
        latent_dims=MAN["latent_dims"],
        albedo_map_dims=ALBEDO_MAP_DIMS,
        code=code("plot_manifold_figures.py"),
    script:
        "../scripts/plot_manifold_figures.py"
