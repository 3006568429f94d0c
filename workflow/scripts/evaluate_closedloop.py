"""Closed-loop vs table-lookup errors of the held-out materials (rule evaluate_closedloop)."""

from brdfpipe.acquisition import closedloop
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    closedloop.write_closedloop(
        snakemake.input.store,
        snakemake.input.model,
        list(snakemake.input.directions),
        list(snakemake.input.noiseless),
        list(snakemake.input.observations),
        snakemake.output.errors,
        materials=snakemake.params.materials,
        n_images=snakemake.params.n_images,
        eta=snakemake.params.eta,
    )
