"""Log-relative mapping of one split's training rows (rule map_logrelative)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import logmap

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    logmap.write_logmap(
        snakemake.input.store,
        snakemake.output.logmap,
        split=snakemake.wildcards.split,
        materials_train=snakemake.params.train,
        weighting=snakemake.params.weighting,
    )
