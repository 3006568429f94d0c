"""Xu 2016 Figs. 2 and 15: renders of reconstructed held-out materials next to their pre-renders (rule plot_reconstruction_figures)."""

from brdfpipe.acquisition import figures
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.make_reconstruction_figures(
        errors_csv=snakemake.input.errors,
        materials=snakemake.params.materials,
        sets=snakemake.params.sets,
        columns=snakemake.params.columns,
        prerenders=list(snakemake.input.prerenders),
        renders=list(snakemake.input.renders),
        inputs=list(snakemake.input.inputs),
        figures={key: list(snakemake.output[key]) for key in snakemake.params.figure_keys},
    )
