"""The memory each rule's jobs declare: a model of their peak RSS and its check at parse time.

:data:`MEMORY_MB` holds a line per rule (base + per material) measured on
finished runs (``benches/bench_memory.py`` prints measured vs declared);
:func:`mem_mb` is what a rule declares (with headroom and, on a retry, more);
:func:`check_memory` refuses, naming the key, a configuration whose largest
job would not fit :data:`JOB_MEMORY_LIMIT_MB`.  Standard library only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from brdfpipe.plan.outputs import closedloop_directions
from brdfpipe.registry.errors import ConfigError

__all__ = [
    "MEMORY_MB",
    "PER_OUTPUT_MB",
    "MEMORY_HEADROOM",
    "MEMORY_RETRY_GROWTH",
    "JOB_MEMORY_LIMIT_MB",
    "MEASURED_SIZES",
    "PATH_CHUNK",
    "SIZE_MEMORY_MB",
    "SIZE_KEYS",
    "FLOOR_RULES",
    "job_sizes",
    "model_mb",
    "mem_mb",
    "check_memory",
]


#: Peak memory model of each rule's jobs, MB = base + per_material × N: a line
#: through the peak RSS (``max_rss`` of the benchmark files) of the default run
#: (N = 100, synthetic database, 2-core AMD EPYC) and of the tiny-point run
#: (N = 6); the local rules and ``interpolate_path_points`` were measured at
#: N = 100 with ``/usr/bin/time`` on the same run's inputs (one path point;
#: each further point adds :data:`PER_OUTPUT_MB`).  A slope 0 means the
#: two sizes peaked alike.  ``benches/bench_memory.py`` prints measured vs
#: declared for any finished run.  The declared value (:func:`mem_mb`) adds
#: :data:`MEMORY_HEADROOM` on top.
MEMORY_MB: dict[str, tuple[float, float]] = {
    # data stage
    "synthesize_material": (306.0, 0.0),
    "write_manifest": (135.0, 0.0),  # not measured at N = 100: as write_splits (the same imports)
    "ingest_material": (64.0, 0.0),
    "evaluate_fits": (480.0, 0.0),  # 287 MB measured at 2 threads (100 merl-nbrdf fits); ~90 MB more per material in flight, up to 4 threads
    "assemble_store": (78.0, 0.28),
    "write_splits": (135.0, 0.0),
    # acquisition track
    "map_logrelative": (170.0, 5.82),
    "accumulate_gram": (96.0, 2.93),
    "decompose_svd": (137.0, 5.32),
    # the rules whose peak grows with the near-field lattice: at 256 × 256 pixels, 100 materials (the grid study,
    # docs/results/runs/2026-11-28-cpu/resolution/cost.csv, three seeds: the largest peak)
    "optimize_directions": (435.0, 13.4),  # 1,665-1,772 MB (32 px: 1,436-1,451)
    "evaluate_directions": (280.0, 3.5),
    "check_directions": (136.0, 6.8),
    "evaluate_training_size": (250.0, 2.45),  # N = 100 only: slope as evaluate_directions'
    # Q in memory and near-field images, then the optimiser for a second image: as optimize_directions
    # (1,917 MB peak measured on merl-nbrdf at 256 px, N = 100, both directions)
    "evaluate_paper_directions": (435.0, 13.4),
    "plot_acquisition_figures": (157.0, 0.0),
    "capture_closedloop": (940.0, 0.0),  # 825-937 MB (32 px: 242-264)
    "evaluate_closedloop": (1560.0, 0.0),  # 1,498-1,554 MB: 10 held-out materials × 8 sets (32 px: 1,101-1,145)
    "plot_closedloop": (157.0, 0.0),  # as plot_acquisition_figures
    # Xu Figs. 2 and 15, a held-out material reconstructed from each figure set (a job per material): 447 MB peak measured on the tiny config (k = 26, 4 sets); at k = 269 and 5 sets one chunk
    # of Q (36,450 × k, float32 and float64) and x̂ (3 × sets × p float64) add about 130 MB
    "reconstruct_figure_material": (600.0, 0.0),
    "plot_reconstruction_figures": (240.0, 0.0),  # 108 MB measured (tiny, 3 materials × 10 images of 32 × 24)
    # materials outside the training database (config unseen); see SIZE_MEMORY_MB for their number
    "evaluate_unseen_fits": (480.0, 0.0),  # as evaluate_fits (same library call, up to 4 threads)
    # as capture_closedloop, plus every material's tables: 250 MB measured at 32 px, and at 256 px its
    # SIZE_MEMORY_MB term's 200 B per lattice pixel and material over the 59 unseen materials (modelled, not measured)
    "capture_unseen_closedloop": (9400.0, 0.0),
    "evaluate_unseen": (280.0, 3.5),  # as evaluate_directions: one streamed pass per unseen database
    "locate_unseen": (276.0, 3.93),  # as compute_gram: one streamed pass over the store
    "plot_unseen_errors": (157.0, 0.0),  # as plot_acquisition_figures
    "plot_unseen_latent": (204.0, 0.0),  # as plot_manifold_figures
    # manifold track
    "compute_gram": (276.0, 3.93),
    "fit_gplvm": (95.0, 0.0),
    "measure_material_albedos": (720.0, 0.0),  # 8 float64 tables at a time: 709 MB peak RSS, N = 100
    "analyze_manifold": (380.0, 16.8),
    "measure_gplvm_candidate": (400.0, 16.8),
    "compare_spaces": (60.0, 0.0),
    "plot_manifold_figures": (204.0, 0.0),
    "measure_lengthscales": (115.0, 0.0),  # 114 MB measured at N = 13, 95 MB at N = 100 (N × N matrices only)
    # rendering track
    "make_envmap": (116.0, 0.0),
    "prerender_materials": (350.0, 0.0),  # a batch: 248 MB for 1 material, 344 MB for 12 or 24 (4 tables cached)
    "interpolate_path_points": (250.0, 2.22),  # N = 100 only: grows with the rows read per block
    "render_path_points": (350.0, 0.0),  # as prerender_materials: several renders in one process
    "sample_latent_materials": (250.0, 2.22),  # as interpolate_path_points: 622 MB (N = 13), 817 MB (N = 100), 11 tables
    "render_latent_samples": (350.0, 0.0),  # as render_path_points: 385 MB (32 × 24, N = 13), 374 MB (256 × 192, N = 100)
    "render_reconstructions": (350.0, 0.0),  # as render_path_points (306 MB measured, tiny): renders in one process
    "render_object_mask": (253.0, 0.0),  # as one render of render_path_points: one small render, not measured alone
    "bounce_shares": (110.0, 0.0),  # not measured: reads two images at a time, less than error_maps
    "error_maps": (110.0, 0.1),  # reads the I¹⁻ pre-renders too: twice error_maps' per-material share
    "interpolate_candidate_path_points": (250.0, 2.22),  # as interpolate_path_points
    "render_candidate_path_points": (350.0, 0.0),  # as render_path_points
    "measure_candidate_blends": (110.0, 0.1),  # as error_maps (smaller images)
    "summarize_floor_check": (120.0, 0.0),  # one small CSV per candidate
    "plot_floor_check": (240.0, 0.0),  # as plot_render_figures, without the images
    "plot_render_figures": (240.0, 1.0),
    # the report
    "write_claims": (60.0, 0.0),  # as compare_spaces (small CSVs); the library alone peaks at 24 MB (tiny run)
    "summarize_stage_times": (60.0, 0.0),  # as write_claims: one small TSV per job
    # the explorer: pre-renders in float32 and float64 (SVD), their half floats and base64 text
    "write_explorer": (250.0, 6.0),
}


#: MB per output on top of :data:`MEMORY_MB`, for rules whose jobs hold every
#: output in memory: ``interpolate_path_points`` holds one float64 MERL table
#: (35 MB) per path point, plus the blend of one column block (and
#: ``sample_latent_materials`` one per latent sample).
PER_OUTPUT_MB: dict[str, float] = {"interpolate_path_points": 36.0, "interpolate_candidate_path_points": 36.0,
                                   "sample_latent_materials": 36.0}


#: Declared / modelled peak on the first attempt (keeps declared within [1, 2] × measured).
MEMORY_HEADROOM: float = 1.3


#: Growth of the declared memory with each retry (attempt 2: × 1.5, attempt 3: × 2.25).
MEMORY_RETRY_GROWTH: float = 1.5


#: The most memory one job may declare (``mem_mb`` of its first attempt, :func:`mem_mb`): the per-job
#: memory of the Slurm profile (``profiles/slurm``: ``resources: mem_mb: 16000``), below the 24 GiB of
#: the build machine.  :func:`check_memory` refuses a configuration whose model exceeds it.
JOB_MEMORY_LIMIT_MB: int = 16000


#: The sizes at which :data:`MEMORY_MB` was measured (the default configuration): pixels of a render
#: (``render.resolution``) and of the environment map, a near-field image lattice (``acquisition.grid``²),
#: points of the albedo map (``manifold.albedo_grid``²), path points held at once, the largest latent
#: dimension + 4, the lattice pixels of one material's closed-loop images, held-out materials.
MEASURED_SIZES: dict[str, float] = {
    "render_pixels": 256 * 192,
    "envmap_pixels": 256 * 128,
    "lattice": 256 * 256,
    "albedo_points": 96 * 96,
    "path_chunk": 21,
    "q_plus": 5 + 4,
    "captured_lattice": (1 + 2) * 4 * 256 * 256,
    "test_materials": 10,
    "unseen_materials": 59,
}


#: Path points whose tables the manifold analyses hold at once (brdfpipe.manifold.analysis: 24, and the end).
PATH_CHUNK: int = 25


#: Memory that grows with a size beyond :data:`MEASURED_SIZES`, on top of :data:`MEMORY_MB`: per rule,
#: terms ``(size, multipliers, MB)`` adding ``MB × (size − measured size)⁺ × Π multipliers`` (a multiplier
#: is another size or ``materials``).  Measured with peak RSS on 2-core AMD EPYC (see each comment).
SIZE_MEMORY_MB: dict[str, tuple[tuple[str, tuple[str, ...], float], ...]] = {
    # the envmap: 302 B per pixel (sub-pixel sun coverage in float64); 4096 × 2048: 2,476 MB
    "make_envmap": (("envmap_pixels", (), 3.0e-4),),
    # a render: film, AOVs and float64 accumulators, 240 B per pixel (1024 × 768: 437 MB, 2048 × 1536:
    # 1,028 MB, 32 spp per pass); Mitsuba's copy of the envmap, 63 B per pixel (4096 × 2048: +529 MB)
    "prerender_materials": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_path_points": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_latent_samples": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_object_mask": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_candidate_path_points": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_reconstructions": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    # readers of the renders (tiny config, 12 materials, 32 × 24 → 384 × 288: +5.6, +30, +56 and +264 MB)
    "bounce_shares": (("render_pixels", (), 6.0e-5),),
    "error_maps": (("render_pixels", (), 2.8e-4), ("render_pixels", ("materials",), 2.0e-6)),
    "measure_candidate_blends": (("render_pixels", (), 2.8e-4), ("render_pixels", ("materials",), 2.0e-6)),
    "plot_render_figures": (("render_pixels", ("materials",), 4.3e-5),),
    # Figs. 2 and 15: up to 7 materials × 6 renders held at once, float64 RGB and the 8-bit copy shown (~1.9 kB a pixel)
    "plot_reconstruction_figures": (("render_pixels", (), 1.9e-3),),
    "write_explorer": (("render_pixels", ("materials",), 2.0e-4),),
    # path points: an interpolated table (35 MB) and its perceptual features (53 MB) each, up to PATH_CHUNK at
    # once (tiny config, path_steps 4 → 30: +1,760 MB); the albedo map: distances and kernel values of every
    # point to every material, 8·(q + 4) bytes (albedo_grid 16 → 256 at q = 5, 12 materials: +78 MB)
    # the optimiser: per-configuration geometry and cells, 5.0 kB per lattice pixel on merl-nbrdf (k = 269,
    # 500 candidates: grid 32: 1,451 MB, 128: 1,560 MB, 256: 1,772 MB; docs/results/runs/2026-11-28-cpu/
    # resolution/cost.csv); a tiny model with 40 candidates grows 0.7 kB per pixel (12: 309 MB, 512: 492 MB)
    "optimize_directions": (("lattice", (), 5.0e-3),),
    "evaluate_paper_directions": (("lattice", (), 5.0e-3),),
    # the capture: one configuration's footprint rays, 8.6 kB per lattice pixel (grid 32: 254 MB, 128: 274 MB,
    # 256: 717 MB, 512: 2,493 MB), and every image of the material kept (render, photograph, SNR, saturation
    # and geometry, 170 B per pixel); the evaluation holds every kept pixel's model column and value per source
    "capture_closedloop": (("lattice", (), 8.6e-3), ("captured_lattice", (), 1.7e-4)),
    "evaluate_closedloop": (("captured_lattice", ("test_materials",), 6.4e-5),),
    # the unseen materials: every observation table of a database in one job (~200 B per lattice pixel and
    # material); the streamed passes hold the unseen rows of a block (1.7 MB per material) and the cross products
    # (a lattice or a number of unseen materials above the measured: (L·U − L₀·U₀) = (L − L₀)·U + L₀·(U − U₀))
    "capture_unseen_closedloop": (("captured_lattice", ("unseen_materials",), 2.0e-4),
                                  ("unseen_materials", (), 2.0e-4 * (1 + 2) * 4 * 256 * 256)),
    "evaluate_unseen": (("unseen_materials", (), 2.0),),
    "locate_unseen": (("unseen_materials", (), 2.0),),
    "analyze_manifold": (("path_chunk", (), 88.0), ("albedo_points", ("materials", "q_plus"), 1.2e-5)),
    "measure_gplvm_candidate": (("path_chunk", (), 88.0), ("albedo_points", ("materials", "q_plus"), 1.2e-5)),
}


#: Config key of each size, for messages.
SIZE_KEYS: dict[str, str] = {
    "render_pixels": "render.resolution",
    "envmap_pixels": "render.envmap.width × height",
    "lattice": "acquisition.grid",
    "albedo_points": "manifold.albedo_grid",
    "path_chunk": "manifold.path_steps",
    "q_plus": "manifold.latent_dims",
    "captured_lattice": "acquisition.grid",
    "test_materials": "test_materials",
    "unseen_materials": "unseen.materials",
}


#: Rules whose jobs render or read the noise-floor check's scene (render.floor_check.resolution).
FLOOR_RULES: frozenset[str] = frozenset({
    "render_candidate_path_points", "measure_candidate_blends", "summarize_floor_check", "plot_floor_check",
    "interpolate_candidate_path_points",
})


def job_sizes(
    config: Mapping[str, Any], *, resolution: Sequence[int] | None = None, n_test: int = 10, n_unseen: int = 0
) -> dict[str, float]:
    """The sizes of :data:`MEASURED_SIZES` in ``config`` (``resolution``: the scene's, default ``render.resolution``).

    ``n_test``: the number of held-out materials; ``n_unseen``: of unseen materials (config ``unseen``).
    """
    acq, man, render = config["acquisition"], config["manifold"], config["render"]
    w, h = resolution if resolution is not None else render["resolution"]
    lattice = float(acq["grid"]) ** 2
    return {
        "render_pixels": float(w) * float(h),
        "envmap_pixels": float(render["envmap"]["width"]) * float(render["envmap"]["height"]),
        "lattice": lattice,
        "albedo_points": float(man["albedo_grid"]) ** 2,
        "path_chunk": float(min(int(man["path_steps"]) + 1, PATH_CHUNK)),
        "q_plus": float(max(int(q) for q in man["latent_dims"]) + 4),
        # lattice pixels of the closed loop's images of one material: Σ n_images over its direction sets
        "captured_lattice": float(sum(int(n) for n in config["closed_loop"]["n_images"])
                                  * max(1, len(closedloop_directions(config))) * lattice),
        "test_materials": float(n_test),
        "unseen_materials": float(n_unseen),
    }


def _size_terms(rule: str, n_materials: int, sizes: Mapping[str, float] | None) -> list[tuple[str, float, float]]:
    """(size, MB per unit of it above the measured size, that excess) of each size term of ``rule``."""
    if not sizes:
        return []
    have = {**sizes, "materials": float(n_materials)}
    out = []
    for size, multipliers, mb in SIZE_MEMORY_MB.get(rule, ()):
        per_unit = mb * math.prod(have[m] for m in multipliers)
        out.append((size, per_unit, max(0.0, have[size] - MEASURED_SIZES[size])))
    return out


def model_mb(rule: str, n_materials: int, *, outputs: int = 1, sizes: Mapping[str, float] | None = None) -> float:
    """Modelled peak memory (MB) of a job of ``rule``: :data:`MEMORY_MB`, :data:`PER_OUTPUT_MB`, :data:`SIZE_MEMORY_MB`.

    ``sizes``: :func:`job_sizes` of the job's configuration; None = the measured ones (no size term).
    """
    base, per = MEMORY_MB[rule]
    base += PER_OUTPUT_MB.get(rule, 0.0) * max(0, int(outputs) - 1)
    extra = sum(per_unit * excess for _, per_unit, excess in _size_terms(rule, n_materials, sizes))
    return base + per * int(n_materials) + extra


def mem_mb(
    rule: str, n_materials: int, attempt: int = 1, *, outputs: int = 1, sizes: Mapping[str, float] | None = None
) -> int:
    """``mem_mb`` a job of ``rule`` declares for ``n_materials`` materials at retry ``attempt`` (≥ 1).

    ``outputs``: how many outputs the job writes (counts only for the rules
    of :data:`PER_OUTPUT_MB`); ``sizes``: the config's :func:`job_sizes`
    (None: those :data:`MEMORY_MB` was measured at).  The model
    (:func:`model_mb`) × :data:`MEMORY_HEADROOM`, rounded up to 50 MB; at
    least 100 MB.  KeyError for a rule without a model.
    """
    need = model_mb(rule, n_materials, outputs=outputs, sizes=sizes)
    need *= MEMORY_HEADROOM * MEMORY_RETRY_GROWTH ** (max(1, int(attempt)) - 1)
    return max(100, int(math.ceil(need / 50.0)) * 50)


def _largest(rule: str, what: str, n_materials: int, n_out: int, sizes: Mapping[str, float], budget: float) -> float:
    """Largest value of ``what`` (a size, ``materials`` or ``outputs``) for which ``rule``'s model stays within ``budget``."""
    base, per = MEMORY_MB[rule]
    if what == "outputs":
        step = PER_OUTPUT_MB.get(rule, 0.0)
        rest = model_mb(rule, n_materials, outputs=1, sizes=sizes)
        return math.inf if step <= 0 else 1 + (budget - rest) / step
    if what == "materials":
        # the model is linear in N: base + per·N + N-proportional size terms
        at0, at1 = (model_mb(rule, n, outputs=n_out, sizes=sizes) for n in (0, 1))
        slope = at1 - at0
        return math.inf if slope <= 0 else (budget - at0) / slope
    terms = [t for t in _size_terms(rule, n_materials, sizes) if t[0] == what]
    per_unit = sum(t[1] for t in terms)
    if per_unit <= 0:
        return math.inf
    rest = model_mb(rule, n_materials, outputs=n_out, sizes=sizes) - sum(t[1] * t[2] for t in terms)
    return MEASURED_SIZES[what] + max(0.0, (budget - rest) / per_unit)


def check_memory(
    config: Mapping[str, Any],
    n_materials: int,
    rules: Sequence[str],
    *,
    outputs: Mapping[str, int] | None = None,
    floor_resolution: Sequence[int] | None = None,
    materials_key: str = "materials",
    n_test: int = 10,
    n_unseen: int = 0,
    limit_mb: int = JOB_MEMORY_LIMIT_MB,
) -> None:
    """Refuse a configuration one of whose jobs would declare more than ``limit_mb`` (:data:`JOB_MEMORY_LIMIT_MB`).

    For each rule (``rules``: those the workflow defines for ``config``, read
    from Snakemake's own rule list at parse time) the first attempt's
    ``mem_mb`` (:func:`mem_mb`) with the config's sizes (the floor check's
    rules with ``floor_resolution``).  The job that needs most decides:
    :class:`ConfigError` naming the key whose term grew most (a size of
    :data:`SIZE_KEYS`, the number of path points, or the number of
    materials, ``materials_key``), the job's need, the limit, and the
    largest value of that key that every planned job fits with.
    """
    outputs = outputs or {}
    budget = limit_mb / MEMORY_HEADROOM  # what a model may reach (declared: × headroom, rounded up to 50 MB)
    jobs = []
    for rule in rules:
        if floor_resolution is None:
            scenes: list[Sequence[int] | None] = [None]
        elif rule in FLOOR_RULES:
            scenes = [floor_resolution]
        else:  # prerender_materials renders both scene folders
            scenes = [None, floor_resolution] if rule == "prerender_materials" else [None]
        for res in scenes:
            sizes = job_sizes(config, resolution=res, n_test=n_test, n_unseen=n_unseen)
            n_out = int(outputs.get(rule, 1))
            jobs.append((mem_mb(rule, n_materials, outputs=n_out, sizes=sizes), rule, res, sizes, n_out))
    need, rule, res, sizes, n_out = max(jobs, key=lambda j: j[0])
    if need <= limit_mb:
        return
    # what grew: the size term with the largest share, else path points, else materials
    grown = {size: per_unit * excess for size, per_unit, excess in _size_terms(rule, n_materials, sizes)}
    grown["outputs"] = PER_OUTPUT_MB.get(rule, 0.0) * (n_out - 1)
    grown["materials"] = MEMORY_MB[rule][1] * n_materials
    what = max(grown, key=lambda k: (grown[k], k != "materials"))
    most = min(_largest(r, what, n_materials, o, z, budget) for _, r, q, z, o in jobs
               if what != "render_pixels" or (q is None) == (res is None))
    why = f"one {rule} job would need {need:,} MB, above the {limit_mb:,} MB a job may have (the Slurm profile's per-job memory)"
    if what == "materials":
        raise ConfigError(f"config {materials_key}: {n_materials} materials: {why}; at most {int(most)} materials")
    if what == "outputs":
        raise ConfigError(f"config render.path_points × manifold.paths: {n_out} path points: {why}; "
                          f"at most {int(most)} path points")
    key = "render.floor_check.resolution" if what == "render_pixels" and res is not None else SIZE_KEYS[what]
    have = sizes[what]
    if what == "captured_lattice":
        per_grid2 = sizes[what] / sizes["lattice"]  # images per material
        if sizes["lattice"] > MEASURED_SIZES["lattice"]:
            key = "acquisition.grid"
            value, limit_text = f"{int(round(math.sqrt(sizes['lattice'])))}", f"at most {math.isqrt(int(most / per_grid2))}"
        else:
            key = "closed_loop.n_images × setups × fovs"
            value, limit_text = f"{int(per_grid2)} images per material", f"at most {int(most / sizes['lattice'])}"
    elif what in ("lattice", "albedo_points"):
        value, limit_text = f"{int(round(math.sqrt(have)))}", f"at most {math.isqrt(int(most))}"
    elif what in ("render_pixels", "envmap_pixels"):
        value, limit_text = f"{int(have):,} pixels", f"at most {int(most):,} pixels"
    else:
        value, limit_text = f"{int(have)}", f"at most {int(most)}"
    why = f"one {rule} job would need {need:,} MB with {n_materials} materials, above the {limit_mb:,} MB a job may have (the Slurm profile's per-job memory)"
    raise ConfigError(f"config {key} = {value}: {why}; {limit_text}")
