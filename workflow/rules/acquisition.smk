# Acquisition track (Xu 2016): log-relative mapping of the store, then the
# PCA/SVD of the mapped rows, streamed as scatter (one Gram block of columns
# per job; `--set-scatter gram=N` spreads it over N jobs) and gather
# (eigendecomposition, Q written block by block).


rule map_logrelative:
    input:
        store=STORE,
        splits=SPLITS,
    output:
        logmap=directory(f"{RESULTS}/logmap/{{split}}.zarr"),
    params:
        train=lambda wildcards: split_training_materials(wildcards.split),
        weighting=config["acquisition"]["weighting"],
    log:
        "logs/map_logrelative/{split}.log",
    benchmark:
        "benchmarks/map_logrelative/{split}.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/map_logrelative.py"


rule accumulate_gram:
    input:
        logmap=f"{RESULTS}/logmap/{{split}}.zarr",
    output:
        partial=temp(f"{RESULTS}/svd/{{split}}/gram-{{scatteritem}}.npz"),
    log:
        "logs/accumulate_gram/{split}-{scatteritem}.log",
    benchmark:
        "benchmarks/accumulate_gram/{split}-{scatteritem}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/accumulate_gram.py"


rule decompose_svd:
    input:
        logmap=f"{RESULTS}/logmap/{{split}}.zarr",
        partials=gather.gram(f"{RESULTS}/svd/{{{{split}}}}/gram-{{scatteritem}}.npz"),
    output:
        model=directory(f"{RESULTS}/svd/{{split}}.zarr"),
    log:
        "logs/decompose_svd/{split}.log",
    benchmark:
        "benchmarks/decompose_svd/{split}.tsv"
    threads: 2
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/decompose_svd.py"


rule optimize_directions:
    input:
        model=f"{RESULTS}/svd/{{split}}.zarr",
    output:
        directions=f"{RESULTS}/directions/{{split}}/{{setup}}-fov{{fov}}-{{metric}}.json",
    params:
        n_max=lambda wildcards: ACQ["n_max_point" if wildcards.setup == "point" else "n_max_images"],
        candidates=ACQ["candidates"],
        grid=ACQ["grid"],
        eta=ACQ["eta"],
        beta=ACQ["beta"],
        seed=ACQ["seed"],
    log:
        "logs/optimize_directions/{split}/{setup}-fov{fov}-{metric}.log",
    benchmark:
        "benchmarks/optimize_directions/{split}/{setup}-fov{fov}-{metric}.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=60,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/optimize_directions.py"


rule evaluate:
    input:
        store=STORE,
        model=f"{RESULTS}/svd/train.zarr",
        logmap=f"{RESULTS}/logmap/train.zarr",
        directions=direction_files("train"),
        curve=CURVE_DIRECTIONS or [],
    output:
        errors=f"{RESULTS}/evaluation/errors.csv",
        consistency=f"{RESULTS}/evaluation/consistency.csv",
        training_size=f"{RESULTS}/evaluation/training_size.csv",
    params:
        test_materials=TEST_MATERIALS,
        eta=ACQ["eta"],
        sizes=TRAINING_SIZES,
        order_seed=ACQ["seed"],
    log:
        "logs/evaluate.log",
    benchmark:
        "benchmarks/evaluate.tsv"
    threads: 2
    resources:
        mem_mb=6000,
        runtime=60,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/evaluate.py"


rule plot_acquisition_figures:
    input:
        errors=f"{RESULTS}/evaluation/errors.csv",
        training_size=f"{RESULTS}/evaluation/training_size.csv",
        directions=direction_files("train") + direction_files("all"),
    output:
        figures=ACQUISITION_FIGURES,
    params:
        directions_dir=lambda wildcards, input: os.path.dirname(os.path.dirname(input.directions[0])),
        out_dir=lambda wildcards, output: os.path.dirname(output.figures[0]),
        fovs=ACQ["fovs"],
        fixed_fov=ACQ["fixed_fov"],
        n_point=min(5, ACQ["n_max_point"]),
    log:
        "logs/plot_acquisition_figures.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/plot_acquisition_figures.py"


rule check_directions:
    input:
        logmap=f"{RESULTS}/logmap/all.zarr",
        model=f"{RESULTS}/svd/all.zarr",
        directions=direction_files("all"),
    output:
        consistency=f"{RESULTS}/evaluation/consistency-all.csv",
    log:
        "logs/check_directions.log",
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/check_directions.py"
