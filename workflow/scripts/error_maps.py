"""Blended pre-renders vs reference renders along the latent paths (rule error_maps)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import blend

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    blend.error_maps_from_files(
        prerenders=dict(zip(snakemake.params.materials, snakemake.input.prerenders)),
        weights=list(snakemake.input.weights),
        references=list(snakemake.input.references),
        references_noise=list(snakemake.input.references_noise),
        blended=list(snakemake.output.blended),
        error_exrs=list(snakemake.output.error_exrs),
        error_pngs=list(snakemake.output.error_pngs),
        summary=snakemake.output.summary,
        database=snakemake.params.database,
        prerenders_one=dict(zip(snakemake.params.materials, snakemake.input.prerenders_one)),
        references_one=list(snakemake.input.references_one),
        references_one_noise=list(snakemake.input.references_one_noise),
    )
