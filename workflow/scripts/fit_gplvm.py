"""GPLVM latent space of dimension q (rule fit_gplvm)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import gplvm

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    gplvm.fit_to_files(
        snakemake.input.gram,
        snakemake.output.model,
        snakemake.output.trace,
        q=int(snakemake.wildcards.q),
        ell=snakemake.params.ell,
        mu=snakemake.params.mu,
        seed=snakemake.params.seed,
        max_sweeps=snakemake.params.max_sweeps,
        normalise=snakemake.params.normalise,
        method=snakemake.params.method,
        init=snakemake.params.init,
        threads=snakemake.threads,
    )
