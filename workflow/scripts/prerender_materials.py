"""Global-illumination pre-renders of a batch of materials and their I¹⁻ parts, every scene folder, in one process (rules prerender_materials_bNN)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    n = len(snakemake.params.materials)
    settings = snakemake.params.settings  # one (resolution, spp) per scene folder, in output order
    scene.render_materials(
        snakemake.input.merl,
        [snakemake.output.images[s * n : (s + 1) * n] for s in range(len(settings))],
        outs_one=[snakemake.output.ones[s * n : (s + 1) * n] for s in range(len(settings))],
        materials=snakemake.params.materials,
        settings=[(tuple(res), spp) for res, spp in settings],
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        seed=snakemake.params.seed,
        database=snakemake.params.database,
    )
