"""The unseen materials on the latent map and their reproduction by the GPLVM and PCA (rule plot_unseen_latent)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import figures

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.manifold_unseen(snakemake.input.model, snakemake.params.map_q, snakemake.input.unseen,
                            list(snakemake.output.manifold))
