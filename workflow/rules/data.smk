# Data stage: (synthetic database) -> one ingest job per material -> one
# validated Zarr store, plus the train/test split.


if SYNTHETIC:

    rule synthesize_material:
        output:
            binary=f"{SYNTH_DIR}/{{material}}.binary",
            record=f"{SYNTH_DIR}/records/{{material}}.json",
        params:
            n_materials=config["synthetic"]["count"],
            seed=config["synthetic"]["seed"],
            noise=config["synthetic"]["noise"],
        log:
            "logs/synthesize_material/{material}.log",
        benchmark:
            "benchmarks/synthesize_material/{material}.tsv"
        threads: 1
        resources:
            mem_mb=1500,
            runtime=10,
        conda:
            "../../envs/brdfpipe.yaml"
        script:
            "../scripts/synthesize_material.py"

    rule write_manifest:
        input:
            records=expand(f"{SYNTH_DIR}/records/{{material}}.json", material=MATERIALS),
        output:
            manifest=MANIFEST,
        params:
            n_materials=config["synthetic"]["count"],
            seed=config["synthetic"]["seed"],
            noise=config["synthetic"]["noise"],
            test_materials=TEST_MATERIALS,
        log:
            "logs/write_manifest.log",
        threads: 1
        resources:
            mem_mb=200,
            runtime=5,
        conda:
            "../../envs/brdfpipe.yaml"
        script:
            "../scripts/write_manifest.py"


rule ingest_material:
    input:
        binary=source_file,
    output:
        row=temp(directory(f"{INGEST_DIR}/{{material}}.zarr")),
    log:
        "logs/ingest_material/{material}.log",
    benchmark:
        "benchmarks/ingest_material/{material}.tsv"
    threads: 1
    resources:
        mem_mb=600,
        runtime=10,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/ingest_material.py"


rule assemble_store:
    input:
        rows=expand(f"{INGEST_DIR}/{{material}}.zarr", material=MATERIALS),
    output:
        store=directory(STORE),
    params:
        database=DATABASE.kind,
    log:
        "logs/assemble_store.log",
    benchmark:
        "benchmarks/assemble_store.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/assemble_store.py"


rule write_splits:
    input:
        store=STORE,
        manifest=MANIFEST if SYNTHETIC else [],
    output:
        splits=SPLITS,
    params:
        test_materials=TEST_MATERIALS,
    log:
        "logs/write_splits.log",
    threads: 1
    resources:
        mem_mb=200,
        runtime=5,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/write_splits.py"
