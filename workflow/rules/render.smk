# Rendering track (Soler 2018 §5.2): one global-illumination pre-render per
# material, reference renders of interpolated materials along the latent
# paths (two seeds: the Monte Carlo noise floor), and blended-vs-reference
# error maps.


rule make_envmap:
    input:
        stamp=stamp_of("make_envmap"),
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


# Pre-renders in batches: a job renders render.materials_per_job materials of
# one scene folder (RENDER_SETTINGS: the configured render, and the floor
# check's small, many-sample one) in one process, so Mitsuba, its plugins and
# compiled kernels start once per batch (RENDER_BATCHES; one rule per batch,
# prerender_materials[_floor]_bNN, each declaring its materials' files).
for _scene, _batches in RENDER_BATCHES.items():
    for _k, _batch in enumerate(_batches):

        rule:
            name:
                render_batch_rule(_scene, _k)
            input:
                merl=[str(DATABASE.sources[m]) for m in _batch],
                envmap=fn.envmap(SCENE),
                stamp=stamp_of(render_batch_rule(_scene, _k)),
            output:
                images=[fn.prerender(_scene, m) for m in _batch],
                ones=[fn.prerender_one(_scene, m) for m in _batch],
            log:
                f"logs/prerender_materials/{_scene}/b{_k:02d}.log",
            benchmark:
                f"benchmarks/prerender_materials/{_scene}/b{_k:02d}.tsv"
            conda:
                "../envs/brdfpipe.yaml"
            threads: 2
            resources:
                gpu=RENDER_GPUS,
                mem_mb=mem("prerender_materials", scene=_scene),
                runtime=5 + 2 * len(_batch),
            params:
                materials=list(_batch),
                variant=RENDER["variant"],
                resolution=RENDER_SETTINGS[_scene][0],
                spp=RENDER_SETTINGS[_scene][1],
                max_depth=RENDER["max_depth"],
                seed=RENDER["seed"],
                database=DATABASE.kind,
                code=code("prerender_materials.py"),
            script:
                "../scripts/prerender_materials.py"


if PATH_POINTS:

    # One job for all path points: each point blends every material, so one
    # pass over the store serves them all (a job per point read it per point).
    rule interpolate_path_points:
        input:
            model=fn.gplvm_model(DEFAULT_CANDIDATE, PATH_Q),
            store=fn.store(),
            stamp=stamp_of("interpolate_path_points"),
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
        stamp=stamp_of("render_path_point"),
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
        stamp=stamp_of("render_object_mask"),
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
        stamp=stamp_of("bounce_shares"),
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
            stamp=stamp_of("error_maps"),
        output:
            summary=reported(fn.errormap_summary(SCENE)),
            blended=errormap_files("blended.exr"),
            error_exrs=errormap_files("error.exr"),
            error_pngs=[reported(f) for f in errormap_files("error.png")],
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
        stamp=stamp_of("plot_render_figures"),
    output:
        **reported_figures(RENDER_FIGURES),
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


# The noise-floor check (render.floor_check): at the configured 64 spp the
# floor between two seeds is 18-36 % relative and hides any blending error.
# Every material and each chosen candidate's path points are rendered again,
# small and with many samples (FLOOR_SCENE), and the blends of each candidate's
# weights compared with its references there.
if FLOOR_CANDIDATES:

    localrules:
        summarize_floor_check,
        plot_floor_check,

    rule interpolate_candidate_path_points:
        input:
            model=fn.gplvm_model("{candidate}", PATH_Q),
            store=fn.store(),
            stamp=stamp_of("interpolate_candidate_path_points"),
        output:
            merl=candidate_point_files("{candidate}", "binary"),
            weights=candidate_point_files("{candidate}", "weights"),
        log:
            "logs/interpolate_candidate_path_points/{candidate}.log",
        benchmark:
            "benchmarks/interpolate_candidate_path_points/{candidate}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("interpolate_candidate_path_points", len(PATH_POINTS)),
            runtime=20,
        params:
            points=[(*PATH_ENDS[p], float(t)) for p, t in PATH_POINTS],
            code=code("interpolate_path_points.py"),
        script:
            "../scripts/interpolate_path_points.py"

    rule render_candidate_path_point:
        input:
            merl=fn.candidate_path_point(
                FLOOR_SCENE, "{candidate}", "{path}", "{t}", "binary"
            ),
            envmap=fn.envmap(SCENE),
            stamp=stamp_of("render_candidate_path_point"),
        output:
            image=fn.candidate_path_point(
                FLOOR_SCENE, "{candidate}", "{path}", "{t}", "image"
            ),
            noise=fn.candidate_path_point(
                FLOOR_SCENE, "{candidate}", "{path}", "{t}", "noise"
            ),
            one=fn.candidate_path_point(
                FLOOR_SCENE, "{candidate}", "{path}", "{t}", "one"
            ),
            one_noise=fn.candidate_path_point(
                FLOOR_SCENE, "{candidate}", "{path}", "{t}", "one_noise"
            ),
        log:
            f"logs/render_candidate_path_point/{FLOOR_SCENE}/{{candidate}}/{{path}}-t{{t}}.log",
        benchmark:
            f"benchmarks/render_candidate_path_point/{FLOOR_SCENE}/{{candidate}}/{{path}}-t{{t}}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("render_candidate_path_point"),
            runtime=60,
        params:
            variant=RENDER["variant"],
            resolution=FLOOR["resolution"],
            spp=FLOOR["spp"],
            max_depth=RENDER["max_depth"],
            seeds=[RENDER["seed"], RENDER["noise_seed"]],
            database=DATABASE.kind,
            code=code("render_path_point.py"),
        script:
            "../scripts/render_path_point.py"

    rule measure_candidate_blends:
        input:
            prerenders=expand(
                fn.prerender(FLOOR_SCENE, "{material}"), material=MATERIALS
            ),
            weights=candidate_point_files("{candidate}", "weights"),
            references=candidate_point_files("{candidate}", "image"),
            references_noise=candidate_point_files("{candidate}", "noise"),
            prerenders_one=expand(
                fn.prerender_one(FLOOR_SCENE, "{material}"), material=MATERIALS
            ),
            references_one=candidate_point_files("{candidate}", "one"),
            references_one_noise=candidate_point_files("{candidate}", "one_noise"),
            stamp=stamp_of("measure_candidate_blends"),
        output:
            summary=fn.candidate_errormap_summary(FLOOR_SCENE, "{candidate}"),
            blended=candidate_errormap_files("{candidate}", "blended.exr"),
            error_exrs=candidate_errormap_files("{candidate}", "error.exr"),
            error_pngs=candidate_errormap_files("{candidate}", "error.png"),
        log:
            f"logs/measure_candidate_blends/{FLOOR_SCENE}/{{candidate}}.log",
        benchmark:
            f"benchmarks/measure_candidate_blends/{FLOOR_SCENE}/{{candidate}}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("measure_candidate_blends"),
            runtime=10,
        params:
            materials=MATERIALS,
            database=DATABASE.kind,
            code=code("error_maps.py"),
        script:
            "../scripts/error_maps.py"

    rule summarize_floor_check:
        input:
            summaries=expand(
                fn.candidate_errormap_summary(FLOOR_SCENE, "{c}"), c=FLOOR_CANDIDATES
            ),
            weights=[
                f
                for c in FLOOR_CANDIDATES
                for f in candidate_point_files(c, "weights")
            ],
            references=[
                f for c in FLOOR_CANDIDATES for f in candidate_point_files(c, "image")
            ],
            stamp=stamp_of("summarize_floor_check"),
        output:
            table=reported(fn.floor_check_csv(FLOOR_SCENE)),
        log:
            f"logs/summarize_floor_check/{FLOOR_SCENE}.log",
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("summarize_floor_check"),
            runtime=5,
        params:
            candidates={c: list(CANDIDATES[c]) for c in FLOOR_CANDIDATES},
            default=DEFAULT_CANDIDATE,
            points=len(PATH_POINTS),
            database=DATABASE.kind,
            code=code("summarize_floor_check.py"),
        script:
            "../scripts/summarize_floor_check.py"

    rule plot_floor_check:
        input:
            table=fn.floor_check_csv(FLOOR_SCENE),
            stamp=stamp_of("plot_floor_check"),
        output:
            figure=[reported(f) for f in FLOOR_FIGURE],
        log:
            f"logs/plot_floor_check/{FLOOR_SCENE}.log",
        benchmark:
            f"benchmarks/plot_floor_check/{FLOOR_SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("plot_floor_check"),
            runtime=5,
        params:
            database=DATABASE.kind,
            code=code("plot_floor_check.py"),
        script:
            "../scripts/plot_floor_check.py"
