"""The interpolated materials at every point of the latent paths (rule interpolate_path_points)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import analysis

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    analysis.path_points_to_files(
        model=snakemake.input.model,
        store=snakemake.input.store,
        points=snakemake.params.points,
        merl_outs=snakemake.output.merl,
        weights_outs=snakemake.output.weights,
    )
