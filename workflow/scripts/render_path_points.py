"""Reference renders of the interpolated path points with two seeds, and their I¹⁻ parts, in one process (rules render_path_points, render_candidate_path_points)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    out = snakemake.output
    scene.render_points(
        snakemake.input.merl,
        outs=[list(pair) for pair in zip(out.images, out.noises)],
        outs_one=[list(pair) for pair in zip(out.ones, out.ones_noise)],
        labels=snakemake.params.labels,
        seeds=snakemake.params.seeds,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        derived=True,
        attrs={"database": snakemake.params.database},
    )
