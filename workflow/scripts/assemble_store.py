"""Assemble and validate the whole materials x cells Zarr store (rule assemble_store)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import ingest

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    ingest.assemble_store(
        list(snakemake.input.rows),
        snakemake.output.store,
        database=snakemake.params.database,
    )
