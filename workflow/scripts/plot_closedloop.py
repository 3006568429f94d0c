"""The closed loop's figure: table-lookup vs closed-loop error per FOV and n (rule plot_closedloop)."""

from brdfpipe.acquisition import figures
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.plot_closedloop(snakemake.input.closedloop, list(snakemake.output.closedloop))
