# The in-browser material explorer (brdfpipe.explorer): a static page over the
# default candidate's GPLVM models and the pre-renders, with the rendered path
# points as references. Every latent dimension is exported: the page opens on
# the q = 2 map, shows slices of q > 2 and a line for q = 1.

from brdfpipe.explorer import assets_digest as explorer_assets_digest


rule write_explorer:
    input:
        models=expand(fn.gplvm_model(DEFAULT_CANDIDATE, "{q}"), q=MAN["latent_dims"]),
        prerenders=expand(fn.prerender(SCENE, "{material}"), material=MATERIALS),
        albedo=fn.albedo(),
        weights=path_point_files("weights"),
        references=path_point_files("image"),
        summary=fn.errormap_summary(SCENE) if PATH_POINTS else [],
        stamp=stamp_of("write_explorer"),
    output:
        explorer=directory(fn.explorer_dir()),
    log:
        "logs/write_explorer/explorer.log",
    benchmark:
        "benchmarks/write_explorer/explorer.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("write_explorer"),
        runtime=10,
    params:
        materials=MATERIALS,
        database=DATABASE.kind,
        max_rank=32,
        code=code("write_explorer.py"),
        assets=explorer_assets_digest(),
    script:
        "../scripts/write_explorer.py"
