"""Optimal acquisition directions for one setup, FOV, metric and split (rule optimize_directions)."""

from brdfpipe.acquisition import optimize
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    optimize.optimize_to_file(
        snakemake.input.model,
        snakemake.output.directions,
        setup=snakemake.wildcards.setup,
        fov=float(snakemake.wildcards.fov),
        grid=snakemake.params.grid,
        metric=snakemake.wildcards.metric,
        n_max=snakemake.params.n_max,
        candidates=snakemake.params.candidates,
        eta=snakemake.params.eta,
        beta=snakemake.params.beta,
        seed=snakemake.params.seed,
        threads=snakemake.threads,
        screen_grid=snakemake.params.screen_grid,
        screen_keep=snakemake.params.screen_keep,
    )
