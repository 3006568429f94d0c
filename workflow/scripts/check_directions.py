"""Predicted E(S) of a split's direction sets vs a direct recomputation (rule check_directions)."""

from brdfpipe.acquisition import evaluation
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    evaluation.check_consistency(
        snakemake.input.logmap,
        snakemake.input.model,
        list(snakemake.input.directions),
        out=snakemake.output.consistency,
    )
