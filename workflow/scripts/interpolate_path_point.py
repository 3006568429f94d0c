"""The interpolated material at one point of a latent path (rule interpolate_path_point)."""

from brdfpipe import manifold
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    manifold.path_point_to_files(
        model=snakemake.input.model,
        store=snakemake.input.store,
        a=snakemake.params.ends[0],
        b=snakemake.params.ends[1],
        t=float(snakemake.wildcards.t),
        merl_out=snakemake.output.merl,
        weights_out=snakemake.output.weights,
    )
