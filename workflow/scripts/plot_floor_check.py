"""The candidates' blends against the noise floor, per path point (rule plot_floor_check)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import figures

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.plot_floor_check(
        table=snakemake.input.table,
        files=list(snakemake.output.figure),
        database=snakemake.params.database,
    )
