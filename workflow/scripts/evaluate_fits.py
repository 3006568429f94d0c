"""The run's database of NBRDF fits on the MERL grid: MERL files and their ingest rows (rule evaluate_fits)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import nbrdf

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    nbrdf.evaluate_to_files(
        archive=snakemake.input.archive,
        fits=snakemake.params.fits,
        binaries=list(snakemake.output.binaries),
        rows=list(snakemake.output.rows),
        database=snakemake.params.database,
        threads=snakemake.threads,
    )
