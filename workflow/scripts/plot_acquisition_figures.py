"""Xu 2016 figure analogues from the evaluation and the direction sets (rule plot_acquisition_figures)."""

from brdfpipe.acquisition import figures
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.make_acquisition_figures(
        errors_csv=snakemake.input.errors,
        training_csv=snakemake.input.training_size or None,
        directions=list(snakemake.input.directions),
        figures={key: list(snakemake.output[key]) for key in snakemake.params.figure_keys},
        fovs=snakemake.params.fovs,
        n_point=snakemake.params.n_point,
        fov_fixed=snakemake.params.fixed_fov,
        figure_fov=snakemake.params.figure_fov,
        figure_materials=snakemake.params.figure_materials,
    )
