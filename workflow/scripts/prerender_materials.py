"""Global-illumination pre-renders of a batch of materials and their I¹⁻ parts, in one process (rules prerender_materials_*)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0]):
    scene.render_materials(
        snakemake.input.merl,
        snakemake.output.images,
        outs_one=snakemake.output.ones,
        materials=snakemake.params.materials,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        seed=snakemake.params.seed,
        attrs={"database": snakemake.params.database},
    )
