"""An unseen database's fits on the MERL grid: MERL files, a store of their own, albedos (rule evaluate_unseen_fits)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import nbrdf

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    nbrdf.evaluate_to_store(
        archive=snakemake.input.archive,
        fits=snakemake.params.fits,
        binaries=list(snakemake.params.binaries),
        store_out=snakemake.output.store,
        albedo_out=snakemake.output.albedo,
        database=snakemake.wildcards.database,
        threads=snakemake.threads,
    )
