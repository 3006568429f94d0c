"""E(S) of the near-field directions Xu §6 states in words (rule evaluate_paper_directions)."""

from brdfpipe.acquisition import paper_directions
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    paper_directions.paper_directions_to_file(
        snakemake.input.model,
        snakemake.output.table,
        directions=snakemake.params.directions,
        grid=snakemake.params.grid,
        eta=snakemake.params.eta,
        beta=snakemake.params.beta,
        candidates=snakemake.params.candidates,
        seed=snakemake.params.seed,
        threads=snakemake.threads,
        screen_grid=snakemake.params.screen_grid,
        screen_keep=snakemake.params.screen_keep,
    )
