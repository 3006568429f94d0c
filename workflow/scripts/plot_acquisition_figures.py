"""Xu 2016 figure analogues from the evaluation and the direction sets (rule plot_acquisition_figures)."""

from brdfpipe import figures
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    figures.make_acquisition_figures(
        snakemake.input.errors,
        snakemake.input.training_size,
        snakemake.params.directions_dir,
        snakemake.params.out_dir,
        fovs=snakemake.params.fovs,
        n_point=snakemake.params.n_point,
        fov_fixed=snakemake.params.fixed_fov,
    )
