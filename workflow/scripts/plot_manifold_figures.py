"""Soler 2018 figure analogues of the manifold track (rule plot_manifold_figures)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import figures

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    q = snakemake.params.latent_dims
    figures.make_manifold_figures(
        models=dict(zip(q, snakemake.input.models)),
        traces=dict(zip(q, snakemake.input.traces)),
        albedo_csv=snakemake.input.albedo,
        albedo_maps=dict(zip(snakemake.params.albedo_map_dims, snakemake.input.albedo_maps)),
        paths_csv=snakemake.input.paths,
        reproduction_csv=snakemake.input.reproduction,
        spaces_csv=snakemake.input.spaces,
        stability_csv=snakemake.input.stability,
        lengthscales_csv=snakemake.input.lengthscales,
        figures={key: list(snakemake.output[key]) for key in snakemake.params.figure_keys},
    )
