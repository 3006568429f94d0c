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


# Pre-renders in batches: a job renders render.materials_per_job materials in
# one process, in every scene folder (RENDER_SETTINGS: the configured render,
# and the floor check's small, many-sample one), so Mitsuba, its plugins and
# compiled kernels start once per batch and each material's table is loaded
# and fitted once (RENDER_BATCHES; one rule per batch, prerender_materials_bNN,
# each declaring its materials' files).
for _k, _batch in enumerate(RENDER_BATCHES):

    rule:
        name:
            render_batch_rule(_k)
        input:
            merl=[str(DATABASE.sources[m]) for m in _batch],
            envmap=fn.envmap(SCENE),
            stamp=stamp_of(render_batch_rule(_k)),
        output:
            images=[fn.prerender(s, m) for s in RENDER_SETTINGS for m in _batch],
            ones=[fn.prerender_one(s, m) for s in RENDER_SETTINGS for m in _batch],
        log:
            f"logs/prerender_materials/b{_k:02d}.log",
        benchmark:
            f"benchmarks/prerender_materials/b{_k:02d}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("prerender_materials", scenes=list(RENDER_SETTINGS)),
            runtime=5 + 2 * len(_batch) * len(RENDER_SETTINGS),
        params:
            materials=list(_batch),
            settings=[list(v) for v in RENDER_SETTINGS.values()],
            variant=RENDER["variant"],
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

    # One job renders every path point (two seeds each): the points come from
    # one interpolation job, so they change together; one Mitsuba start.
    rule render_path_points:
        input:
            merl=path_point_files("binary"),
            envmap=fn.envmap(SCENE),
            stamp=stamp_of("render_path_points"),
        output:
            images=path_point_files("image"),
            noises=path_point_files("noise"),
            ones=path_point_files("one"),
            ones_noise=path_point_files("one_noise"),
        log:
            f"logs/render_path_points/{SCENE}.log",
        benchmark:
            f"benchmarks/render_path_points/{SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("render_path_points"),
            runtime=10 + 4 * len(PATH_POINTS),
        params:
            labels=[f"{p}-t{t}" for p, t in PATH_POINTS],
            variant=RENDER["variant"],
            resolution=RENDER["resolution"],
            spp=RENDER["spp"],
            max_depth=RENDER["max_depth"],
            seeds=[RENDER["seed"], RENDER["noise_seed"]],
            database=DATABASE.kind,
            code=code("render_path_points.py"),
        script:
            "../scripts/render_path_points.py"


if N_SAMPLES:

    # Soler Fig. 1: materials at random latent points of the default candidate's
    # manifold, drawn as `brdfpipe sample` draws them (render.latent_samples),
    # blended in one pass over the store and written with their derived marks.
    rule sample_latent_materials:
        input:
            model=fn.gplvm_model(DEFAULT_CANDIDATE, PATH_Q),
            store=fn.store(),
            albedos=fn.material_albedos(),
            stamp=stamp_of("sample_latent_materials"),
        output:
            merl=sample_files("binary"),
            samples=fn.latent_samples_json(SCENE),
        log:
            f"logs/sample_latent_materials/{SCENE}.log",
        benchmark:
            f"benchmarks/sample_latent_materials/{SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 1
        resources:
            mem_mb=mem("sample_latent_materials", N_SAMPLES),
            runtime=20,
        params:
            seed=RENDER["latent_samples"]["seed"],
            code=code("sample_latent_materials.py"),
        script:
            "../scripts/sample_latent_materials.py"

    # Their renders, in the pre-renders' scene and settings (one seed, one Mitsuba start).
    rule render_latent_samples:
        input:
            merl=sample_files("binary"),
            envmap=fn.envmap(SCENE),
            stamp=stamp_of("render_latent_samples"),
        output:
            images=sample_files("image"),
        log:
            f"logs/render_latent_samples/{SCENE}.log",
        benchmark:
            f"benchmarks/render_latent_samples/{SCENE}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("render_latent_samples"),
            runtime=10 + 2 * N_SAMPLES,
        params:
            labels=[Path(f).stem for f in sample_files("binary")],
            variant=RENDER["variant"],
            resolution=RENDER["resolution"],
            spp=RENDER["spp"],
            max_depth=RENDER["max_depth"],
            seed=RENDER["seed"],
            database=DATABASE.kind,
            code=code("render_latent_samples.py"),
        script:
            "../scripts/render_latent_samples.py"


if RECON_SETS:

    # Xu Figs. 2 and 15: a figure material's reconstructed tables rendered exactly as
    # the pre-renders (scene, resolution, spp, depth, seed): the reference is the
    # material's pre-render. One job (one Mitsuba start) per material.
    rule render_reconstructions:
        input:
            merl=recon_tables("{material}"),
            envmap=fn.envmap(SCENE),
            stamp=stamp_of("render_reconstructions"),
        output:
            images=recon_renders("{material}"),
        log:
            f"logs/render_reconstructions/{SCENE}/{{material}}.log",
        benchmark:
            f"benchmarks/render_reconstructions/{SCENE}/{{material}}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("render_reconstructions"),
            runtime=5 + 2 * len(RECON_SETS),
        params:
            labels=[f"{s}-fov{fn.fov_tag(f)}-{m}-n{n}" for s, f, m, n in RECON_SETS],
            variant=RENDER["variant"],
            resolution=RENDER["resolution"],
            spp=RENDER["spp"],
            max_depth=RENDER["max_depth"],
            seed=RENDER["seed"],
            database=DATABASE.kind,
            code=code("render_reconstructions.py"),
        script:
            "../scripts/render_reconstructions.py"


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
        references_noise=path_point_files("noise"),
        samples=fn.latent_samples_json(SCENE) if N_SAMPLES else [],
        sample_images=sample_files("image"),
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

    rule render_candidate_path_points:
        input:
            merl=candidate_point_files("{candidate}", "binary"),
            envmap=fn.envmap(SCENE),
            stamp=stamp_of("render_candidate_path_points"),
        output:
            images=candidate_point_files("{candidate}", "image"),
            noises=candidate_point_files("{candidate}", "noise"),
            ones=candidate_point_files("{candidate}", "one"),
            ones_noise=candidate_point_files("{candidate}", "one_noise"),
        log:
            f"logs/render_candidate_path_points/{FLOOR_SCENE}/{{candidate}}.log",
        benchmark:
            f"benchmarks/render_candidate_path_points/{FLOOR_SCENE}/{{candidate}}.tsv"
        conda:
            "../envs/brdfpipe.yaml"
        threads: 2
        resources:
            gpu=RENDER_GPUS,
            mem_mb=mem("render_candidate_path_points"),
            runtime=10 + 4 * len(PATH_POINTS),
        params:
            labels=[f"{p}-t{t}" for p, t in PATH_POINTS],
            variant=RENDER["variant"],
            resolution=FLOOR["resolution"],
            spp=FLOOR["spp"],
            max_depth=RENDER["max_depth"],
            seeds=[RENDER["seed"], RENDER["noise_seed"]],
            database=DATABASE.kind,
            code=code("render_path_points.py"),
        script:
            "../scripts/render_path_points.py"

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
            candidates={
                c: [CANDIDATES[c].space, CANDIDATES[c].mu] for c in FLOOR_CANDIDATES
            },
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
