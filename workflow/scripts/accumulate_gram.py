"""One column block's share of the row Gram matrix (rule accumulate_gram)."""

from brdfpipe.acquisition import svd
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    svd.write_partial(
        snakemake.output.partial,
        logmap_path=snakemake.input.logmap,
        scatteritem=snakemake.wildcards.scatteritem,
    )
