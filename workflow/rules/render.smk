# Rendering track (Soler 2018 §5.2): one global-illumination pre-render per
# material, reference renders of interpolated materials along the latent
# paths (two seeds: the Monte Carlo noise floor), and blended-vs-reference
# error maps.


rule make_envmap:
    output:
        envmap=fn.envmap(SCENE),
    log:
        f"logs/make_envmap/{SCENE}.log",
    benchmark:
        f"benchmarks/make_envmap/{SCENE}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("make_envmap"),
        runtime=5,
    params:
        width=RENDER["envmap"]["width"],
        height=RENDER["envmap"]["height"],
        sun_elevation=RENDER["envmap"]["sun_elevation"],
        sun_azimuth=RENDER["envmap"]["sun_azimuth"],
        code=code("make_envmap.py"),
    script:
        "../scripts/make_envmap.py"


rule prerender_material:
    input:
        merl=source_file,
        envmap=fn.envmap(SCENE),
    output:
        image=fn.prerender(SCENE, "{material}"),
        one=fn.prerender_one(SCENE, "{material}"),
    log:
        f"logs/prerender_material/{SCENE}/{{material}}.log",
    benchmark:
        f"benchmarks/prerender_material/{SCENE}/{{material}}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 2
    resources:
        gpu=RENDER_GPUS,
        mem_mb=mem("prerender_material"),
        runtime=30,
    params:
        variant=RENDER["variant"],
        resolution=RENDER["resolution"],
        spp=RENDER["spp"],
        max_depth=RENDER["max_depth"],
        seed=RENDER["seed"],
        database=DATABASE.kind,
        code=code("prerender_material.py"),
    script:
        "../scripts/prerender_material.py"


if PATH_POINTS:

    # One job for all path points: each point blends every material, so one
    # pass over the store serves them all (a job per point read it per point).
    rule interpolate_path_points:
        input:
            model=fn.gplvm_model(DEFAULT_CANDIDATE, PATH_Q),
            store=fn.store(),
        output:
            merl=path_point_files("binary"),
            weights=path_point_files("weights"),
        log:
            f"logs/interpolate_path_points/{SCENE}.log",
        benchmark:
            f"benchmarks/interpolate_path_points/{SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("interpolate_path_points", len(PATH_POINTS)),
            runtime=20,
        params:
            points=[(*PATH_ENDS[p], float(t)) for p, t in PATH_POINTS],
            code=code("interpolate_path_points.py"),
        script:
            "../scripts/interpolate_path_points.py"


rule render_path_point:
    input:
        merl=fn.path_point(SCENE, "{path}", "{t}", "binary"),
        envmap=fn.envmap(SCENE),
    output:
        image=fn.path_point(SCENE, "{path}", "{t}", "image"),
        noise=fn.path_point(SCENE, "{path}", "{t}", "noise"),
        one=fn.path_point(SCENE, "{path}", "{t}", "one"),
        one_noise=fn.path_point(SCENE, "{path}", "{t}", "one_noise"),
    log:
        f"logs/render_path_point/{SCENE}/{{path}}-t{{t}}.log",
    benchmark:
        f"benchmarks/render_path_point/{SCENE}/{{path}}-t{{t}}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 2
    resources:
        gpu=RENDER_GPUS,
        mem_mb=mem("render_path_point"),
        runtime=60,
    params:
        variant=RENDER["variant"],
        resolution=RENDER["resolution"],
        spp=RENDER["spp"],
        max_depth=RENDER["max_depth"],
        seeds=[RENDER["seed"], RENDER["noise_seed"]],
        database=DATABASE.kind,
        code=code("render_path_point.py"),
    script:
        "../scripts/render_path_point.py"


# The object's pixels (for the I²⁺ share over the object): one small render.
rule render_object_mask:
    input:
        envmap=fn.envmap(SCENE),
    output:
        mask=fn.object_mask(SCENE),
    log:
        f"logs/render_object_mask/{SCENE}.log",
    benchmark:
        f"benchmarks/render_object_mask/{SCENE}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 2
    resources:
        gpu=RENDER_GPUS,
        mem_mb=mem("render_object_mask"),
        runtime=10,
    params:
        variant=RENDER["variant"],
        resolution=RENDER["resolution"],
        spp=RENDER["spp"],
        seed=RENDER["seed"],
        database=DATABASE.kind,
        code=code("render_object_mask.py"),
    script:
        "../scripts/render_object_mask.py"


# Share of I²⁺ (paths with ≥ 2 scatterings on the material, which blending
# gets wrong) in each pre-render, over the image and over the object.
rule bounce_shares:
    input:
        images=expand(fn.prerender(SCENE, "{material}"), material=MATERIALS),
        ones=expand(fn.prerender_one(SCENE, "{material}"), material=MATERIALS),
        mask=fn.object_mask(SCENE),
    output:
        shares=fn.bounce_shares(SCENE),
    log:
        f"logs/bounce_shares/{SCENE}.log",
    benchmark:
        f"benchmarks/bounce_shares/{SCENE}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("bounce_shares"),
        runtime=10,
    params:
        materials=MATERIALS,
        database=DATABASE.kind,
        code=code("bounce_shares.py"),
    script:
        "../scripts/bounce_shares.py"


if PATH_POINTS:

    rule error_maps:
        input:
            prerenders=expand(fn.prerender(SCENE, "{material}"), material=MATERIALS),
            weights=path_point_files("weights"),
            references=path_point_files("image"),
            references_noise=path_point_files("noise"),
            prerenders_one=expand(
                fn.prerender_one(SCENE, "{material}"), material=MATERIALS
            ),
            references_one=path_point_files("one"),
            references_one_noise=path_point_files("one_noise"),
        output:
            summary=fn.errormap_summary(SCENE),
            blended=errormap_files("blended.exr"),
            error_exrs=errormap_files("error.exr"),
            error_pngs=errormap_files("error.png"),
        log:
            f"logs/error_maps/{SCENE}.log",
        benchmark:
            f"benchmarks/error_maps/{SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("error_maps"),
            runtime=10,
        params:
            materials=MATERIALS,
            database=DATABASE.kind,
            code=code("error_maps.py"),
        script:
            "../scripts/error_maps.py"


rule plot_render_figures:
    input:
        prerenders=expand(fn.prerender(SCENE, "{material}"), material=MATERIALS),
        weights=path_point_files("weights"),
        references=path_point_files("image"),
        blended=errormap_files("blended.exr"),
        errors=errormap_files("error.exr"),
        summary=fn.errormap_summary(SCENE) if PATH_POINTS else [],
    output:
        **RENDER_FIGURES,
    log:
        f"logs/plot_render_figures/{SCENE}.log",
    benchmark:
        f"benchmarks/plot_render_figures/{SCENE}.tsv"
    conda:
        "../envs/brdfpipe.yaml"
    threads: 1
    resources:
        mem_mb=mem("plot_render_figures"),
        runtime=10,
    params:
        figure_keys=list(RENDER_FIGURES),
        materials=MATERIALS,
        database=DATABASE.kind,
        code=code("plot_render_figures.py"),
    script:
        "../scripts/plot_render_figures.py"
