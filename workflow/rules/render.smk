# Rendering track (Soler 2018 §5.2): one global-illumination pre-render per
# material, reference renders of interpolated materials along the latent
# paths (two seeds: the Monte Carlo noise floor), and blended-vs-reference
# error maps.


rule make_envmap:
    output:
        envmap=f"{RENDER_DIR}/envmap.exr",
    params:
        width=RENDER["envmap"]["width"],
        height=RENDER["envmap"]["height"],
        sun_elevation=RENDER["envmap"]["sun_elevation"],
        sun_azimuth=RENDER["envmap"]["sun_azimuth"],
    log:
        f"logs/make_envmap/{RENDER['scene']}.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/make_envmap.py"


rule prerender_material:
    input:
        merl=source_file,
        envmap=rules.make_envmap.output.envmap,
    output:
        image=f"{RENDER_DIR}/materials/{{material}}.exr",
    params:
        variant=RENDER["variant"],
        resolution=RENDER["resolution"],
        spp=RENDER["spp"],
        max_depth=RENDER["max_depth"],
        seed=RENDER["seed"],
        database=DATABASE.kind,
    log:
        f"logs/prerender_material/{RENDER['scene']}/{{material}}.log",
    benchmark:
        f"benchmarks/prerender_material/{RENDER['scene']}/{{material}}.tsv"
    threads: 2
    resources:
        mem_mb=3000,
        runtime=30,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/prerender_material.py"


rule interpolate_path_point:
    input:
        model=f"{RESULTS}/gplvm/q{PATH_Q}.npz",
        store=STORE,
    output:
        merl=f"{RENDER_DIR}/paths/{{path}}-t{{t}}.binary",
        weights=f"{RENDER_DIR}/paths/{{path}}-t{{t}}-weights.json",
    params:
        ends=lambda wildcards: PATH_ENDS[wildcards.path],
    log:
        f"logs/interpolate_path_point/{RENDER['scene']}/{{path}}-t{{t}}.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/interpolate_path_point.py"


rule render_path_point:
    input:
        merl=rules.interpolate_path_point.output.merl,
        envmap=rules.make_envmap.output.envmap,
    output:
        image=f"{RENDER_DIR}/paths/{{path}}-t{{t}}.exr",
        noise=f"{RENDER_DIR}/paths/{{path}}-t{{t}}-noise.exr",
    params:
        variant=RENDER["variant"],
        resolution=RENDER["resolution"],
        spp=RENDER["spp"],
        max_depth=RENDER["max_depth"],
        seeds=[RENDER["seed"], RENDER["noise_seed"]],
        database=DATABASE.kind,
    log:
        f"logs/render_path_point/{RENDER['scene']}/{{path}}-t{{t}}.log",
    benchmark:
        f"benchmarks/render_path_point/{RENDER['scene']}/{{path}}-t{{t}}.tsv"
    threads: 2
    resources:
        mem_mb=3000,
        runtime=60,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/render_path_point.py"


rule error_maps:
    input:
        prerenders=expand(f"{RENDER_DIR}/materials/{{material}}.exr", material=MATERIALS),
        weights=[f"{RENDER_DIR}/paths/{p}-t{t}-weights.json" for p, t in PATH_POINTS],
        references=[f"{RENDER_DIR}/paths/{p}-t{t}.exr" for p, t in PATH_POINTS],
        references_noise=[f"{RENDER_DIR}/paths/{p}-t{t}-noise.exr" for p, t in PATH_POINTS],
    output:
        summary=f"{ERRORMAP_DIR}/summary.csv",
        maps=[f"{ERRORMAP_DIR}/{p}-t{t}-{kind}" for p, t in PATH_POINTS
              for kind in ("blended.exr", "error.exr", "error.png")],
    params:
        materials=MATERIALS,
        out_dir=lambda wildcards, output: os.path.dirname(output.summary),
        database=DATABASE.kind,
    log:
        f"logs/error_maps/{RENDER['scene']}.log",
    benchmark:
        f"benchmarks/error_maps/{RENDER['scene']}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/error_maps.py"


rule plot_render_figures:
    input:
        prerenders=expand(f"{RENDER_DIR}/materials/{{material}}.exr", material=MATERIALS),
        weights=[f"{RENDER_DIR}/paths/{p}-t{t}-weights.json" for p, t in PATH_POINTS],
        references=[f"{RENDER_DIR}/paths/{p}-t{t}.exr" for p, t in PATH_POINTS],
        summary=f"{ERRORMAP_DIR}/summary.csv",
    output:
        figures=RENDER_FIGURES,
    params:
        materials=MATERIALS,
        errormap_dir=lambda wildcards, input: os.path.dirname(input.summary),
        out_dir=lambda wildcards, output: os.path.dirname(output.figures[0]),
        database=DATABASE.kind,
    log:
        f"logs/plot_render_figures/{RENDER['scene']}.log",
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    conda:
        "../../envs/brdfpipe.yaml"
    script:
        "../scripts/plot_render_figures.py"
