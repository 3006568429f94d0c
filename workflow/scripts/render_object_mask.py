"""The preview object's pixel mask (rule render_object_mask)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    scene.render_object_mask(
        snakemake.output.mask,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        seed=snakemake.params.seed,
        threads=snakemake.threads,
        attrs={"database": snakemake.params.database},
    )
