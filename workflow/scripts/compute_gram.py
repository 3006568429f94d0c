"""Centred Gram matrix of the stored materials in one data space (rule compute_gram)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import gram

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    gram.write_gram(snakemake.input.store, snakemake.output.gram, space=snakemake.wildcards.space)
