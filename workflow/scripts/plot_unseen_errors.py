"""The unseen materials' acquisition errors next to the held-out ones (rule plot_unseen_errors)."""

from brdfpipe.acquisition import figures
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.plot_unseen(snakemake.input.errors, snakemake.input.unseen, list(snakemake.output.acquisition),
                        closedloop_csv=snakemake.input.closedloop or None)
