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
