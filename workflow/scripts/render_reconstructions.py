"""A figure material's reconstructed tables rendered as the pre-renders, in one process (rule render_reconstructions)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    scene.render_points(
        snakemake.input.merl,
        outs=[[f] for f in snakemake.output.images],
        outs_one=None,
        labels=snakemake.params.labels,
        label_key="reconstruction",
        seeds=[snakemake.params.seed],
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        derived=True,
        attrs={"database": snakemake.params.database, "material": snakemake.wildcards.material},
    )
