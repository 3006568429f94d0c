"""Blended pre-renders vs reference renders along the latent paths (rule error_maps)."""

from brdfpipe import blend
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    blend.error_maps_from_files(
        prerenders=dict(zip(snakemake.params.materials, snakemake.input.prerenders)),
        weights=snakemake.input.weights,
        references=snakemake.input.references,
        references_noise=snakemake.input.references_noise,
        out_dir=snakemake.params.out_dir,
        database=snakemake.params.database,
    )
