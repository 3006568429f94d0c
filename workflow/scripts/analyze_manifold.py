"""Albedos, albedo maps, latent paths and reproduction errors of the GPLVM fits (rule analyze_manifold)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import analysis

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    analysis.analyze_manifold(
        store=snakemake.input.store,
        gram=snakemake.input.gram,
        models=dict(zip(snakemake.params.latent_dims, snakemake.input.models)),
        paths=snakemake.params.paths,
        path_q=snakemake.params.path_q,
        seed=snakemake.params.seed,
        steps=snakemake.params.steps,
        albedo_grid=snakemake.params.albedo_grid,
        pca_ks=snakemake.params.pca_ks,
        albedos=snakemake.input.albedos,
        albedo_out=snakemake.output.albedo,
        albedo_maps_out=dict(zip(snakemake.params.albedo_map_dims, snakemake.output.albedo_maps)),
        paths_out=snakemake.output.paths,
        reproduction_out=snakemake.output.reproduction,
    )
