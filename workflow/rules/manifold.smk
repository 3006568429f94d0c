# Manifold track (Soler 2018): the N x N Gram matrix of the mean-subtracted
# materials, streamed once from the store, then one GPLVM fit per latent
# dimension q.


rule compute_gram:
    input:
        store=STORE,
    output:
        gram=f"{RESULTS}/gplvm/gram-{{space}}.npz",
    log:
        "logs/compute_gram/{space}.log",
    benchmark:
        "benchmarks/compute_gram/{space}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/compute_gram.py"


rule fit_gplvm:
    input:
        gram=f"{RESULTS}/gplvm/gram-{MAN['space']}.npz",
    output:
        model=f"{RESULTS}/gplvm/q{{q}}.npz",
        trace=f"{RESULTS}/gplvm/q{{q}}-trace.csv",
    params:
        ell=MAN["ell"],
        mu=MAN["mu"],
        seed=MAN["seed"],
        max_sweeps=MAN["max_sweeps"],
        normalise=MAN["normalise"],
        method=MAN["method"],
    log:
        "logs/fit_gplvm/q{q}.log",
    benchmark:
        "benchmarks/fit_gplvm/q{q}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/fit_gplvm.py"


rule analyze_manifold:
    input:
        store=STORE,
        gram=f"{RESULTS}/gplvm/gram-{MAN['space']}.npz",
        models=expand(f"{RESULTS}/gplvm/q{{q}}.npz", q=MAN["latent_dims"]),
    output:
        albedo=f"{MANIFOLD_DIR}/albedo.csv",
        paths=f"{MANIFOLD_DIR}/paths.csv",
        reproduction=f"{MANIFOLD_DIR}/reproduction.csv",
        albedo_maps=expand(f"{MANIFOLD_DIR}/albedo-map-q{{q}}.npz", q=MAN["latent_dims"]),
    params:
        latent_dims=MAN["latent_dims"],
        paths=[list(p) for p in MANIFOLD_PATHS],
        path_q=PATH_Q,
        seed=MAN["seed"],
        steps=MAN["path_steps"],
        albedo_grid=MAN["albedo_grid"],
        pca_ks=MAN["pca_components"],
        out_dir=lambda wildcards, output: os.path.dirname(output.paths),
    log:
        "logs/analyze_manifold.log",
    benchmark:
        "benchmarks/analyze_manifold.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/analyze_manifold.py"


rule plot_manifold_figures:
    input:
        models=expand(f"{RESULTS}/gplvm/q{{q}}.npz", q=MAN["latent_dims"]),
        traces=expand(f"{RESULTS}/gplvm/q{{q}}-trace.csv", q=MAN["latent_dims"]),
        albedo=f"{MANIFOLD_DIR}/albedo.csv",
        albedo_maps=expand(f"{MANIFOLD_DIR}/albedo-map-q{{q}}.npz", q=MAN["latent_dims"]),
        paths=f"{MANIFOLD_DIR}/paths.csv",
        reproduction=f"{MANIFOLD_DIR}/reproduction.csv",
    output:
        figures=MANIFOLD_FIGURES,
    params:
        latent_dims=MAN["latent_dims"],
        out_dir=lambda wildcards, output: os.path.dirname(output.figures[0]),
    log:
        "logs/plot_manifold_figures.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/plot_manifold_figures.py"
