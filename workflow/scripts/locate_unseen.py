"""The unseen materials on the default candidate's GPLVM manifold: x* and reproduction (rule locate_unseen)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import unseen

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    unseen.write_unseen(
        snakemake.output.unseen,
        store=snakemake.input.store,
        gram=snakemake.input.gram,
        models=dict(zip(snakemake.params.latent_dims, snakemake.input.models)),
        unseen_stores=list(snakemake.input.unseen),
        pca_ks=snakemake.params.pca_ks,
        threads=snakemake.threads,
    )
