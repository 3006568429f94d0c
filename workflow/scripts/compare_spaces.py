"""The GPLVM candidates' fidelity tables in one table each (rule compare_spaces)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import fidelity

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    fidelity.combine_candidates(
        spaces=snakemake.input.spaces,
        stability=snakemake.input.stability,
        spaces_out=snakemake.output.spaces,
        stability_out=snakemake.output.stability,
    )
