"""Global-illumination pre-render of one material (rule prerender_material)."""

from brdfpipe import scene
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    scene.render_material(
        snakemake.input.merl,
        snakemake.output.image,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        seed=snakemake.params.seed,
        attrs={"database": snakemake.params.database, "material": snakemake.wildcards.material},
    )
