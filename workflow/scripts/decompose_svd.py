"""Combine the Gram blocks, decompose and write the PCA model (rule decompose_svd)."""

from brdfpipe.acquisition import svd
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    svd.write_model(
        snakemake.input.logmap,
        list(snakemake.input.partials),
        snakemake.output.model,
    )
