"""The unseen materials reconstructed with the training model: table lookup and closed loop (rule evaluate_unseen)."""

from brdfpipe.acquisition import unseen
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    databases = list(snakemake.params.databases)
    unseen.write_unseen(
        snakemake.output.errors,
        stores=dict(zip(databases, snakemake.input.stores)),
        model=snakemake.input.model,
        directions=list(snakemake.input.directions),
        closedloop_directions=list(snakemake.input.closedloop_directions),
        observations=dict(zip(databases, snakemake.input.observations)) or None,
        n_images=snakemake.params.n_images,
        eta=snakemake.params.eta,
        threads=snakemake.threads,
    )
