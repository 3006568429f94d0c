"""Global-illumination pre-render of one material and its I¹⁻ part, one render (rule prerender_material)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0]):
    scene.render_material(
        snakemake.input.merl,
        snakemake.output.image,
        out_one=snakemake.output.one,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        seed=snakemake.params.seed,
        attrs={"database": snakemake.params.database, "material": snakemake.wildcards.material},
    )
