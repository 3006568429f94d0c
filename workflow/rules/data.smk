# Data stage: (synthetic database) -> one ingest job per material -> one
# validated Zarr store, plus the train/test split.


if GENERATED:

    localrules:
        write_manifest,

    rule synthesize_material:
        input:
            stamp=stamp_of("synthesize_material"),
        output:
            binary=fn.synthetic_binary("{material}"),
            record=fn.synthetic_record("{material}"),
        log:
            "logs/synthesize_material/{material}.log",
        benchmark:
            "benchmarks/synthesize_material/{material}.tsv"
        priority: 30
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("synthesize_material"),
            runtime=10,
        params:
            n_materials=config["synthetic"]["count"],
            seed=config["synthetic"]["seed"],
            noise=config["synthetic"]["noise"],
            code=code("synthesize_material.py"),
        script:
            "../scripts/synthesize_material.py"

    rule write_manifest:
        input:
            records=expand(fn.synthetic_record("{material}"), material=MATERIALS),
            stamp=stamp_of("write_manifest"),
        output:
            manifest=fn.manifest(),
        log:
            "logs/write_manifest.log",
        benchmark:
            "benchmarks/write_manifest.tsv"
        priority: 30
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("write_manifest"),
            runtime=5,
        params:
            n_materials=config["synthetic"]["count"],
            seed=config["synthetic"]["seed"],
            noise=config["synthetic"]["noise"],
            test_materials=TEST_MATERIALS,
            materials=MATERIALS,
            code=code("write_manifest.py"),
        script:
            "../scripts/write_manifest.py"


# What every ingested file must be (brdfpipe.data.provenance.check_source): of the
# database labelled at parse time and, for the workflow's own synthetic files,
# made with this configuration (the material name is checked for every marked file).
INGEST_EXPECT = {"database": DATABASE.kind}
if GENERATED:
    INGEST_EXPECT.update(
        count=config["synthetic"]["count"],
        seed=config["synthetic"]["seed"],
        noise=float(config["synthetic"]["noise"]),
    )


if FITS:

    # A database of fits: every fit evaluated on the MERL grid (a marked MERL file
    # per material) and ingested into its row, in one job (a fit takes ~0.3 s;
    # a job's start-up more).
    rule evaluate_fits:
        input:
            archive=str(DATABASE.archive),
            stamp=stamp_of("evaluate_fits"),
        output:
            binaries=[str(DATABASE.sources[m]) for m in MATERIALS],
            rows=[temp(directory(fn.ingest_row(m))) for m in MATERIALS],
        log:
            "logs/evaluate_fits.log",
        benchmark:
            "benchmarks/evaluate_fits.tsv"
        priority: 30
        conda:
            "../envs/brdfpipe.yaml"
        threads: 4
        resources:
            mem_mb=mem("evaluate_fits"),
            runtime=10,
        params:
            fits={m: DATABASE.fits[m] for m in MATERIALS},
            database=DATABASE.kind,
            code=code("evaluate_fits.py"),
        script:
            "../scripts/evaluate_fits.py"

else:

    rule ingest_material:
        input:
            binary=source_file,
            stamp=stamp_of("ingest_material"),
        output:
            row=temp(directory(fn.ingest_row("{material}"))),
        log:
            "logs/ingest_material/{material}.log",
        benchmark:
            "benchmarks/ingest_material/{material}.tsv"
        priority: 30
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("ingest_material"),
            runtime=10,
        params:
            expect=INGEST_EXPECT,
            code=code("ingest_material.py"),
        script:
            "../scripts/ingest_material.py"


rule assemble_store:
    input:
        rows=expand(fn.ingest_row("{material}"), material=MATERIALS),
        stamp=stamp_of("assemble_store"),
    output:
        store=directory(fn.store()),
    log:
        "logs/assemble_store.log",
    benchmark:
        "benchmarks/assemble_store.tsv"
    priority: 30
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("assemble_store"),
        runtime=30,
    params:
        database=DATABASE.kind,
        code=code("assemble_store.py"),
    script:
        "../scripts/assemble_store.py"


rule write_splits:
    input:
        store=fn.store(),
        manifest=fn.manifest() if GENERATED else [],
        stamp=stamp_of("write_splits"),
    output:
        splits=fn.splits(),
    log:
        "logs/write_splits.log",
    benchmark:
        "benchmarks/write_splits.tsv"
    priority: 30
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("write_splits"),
        runtime=5,
    params:
        test_materials=TEST_MATERIALS,
        code=code("write_splits.py"),
    script:
        "../scripts/write_splits.py"
