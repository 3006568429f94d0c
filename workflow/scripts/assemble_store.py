"""Assemble and validate the whole materials x cells Zarr store (rule assemble_store)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import store

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    store.assemble_store(
        list(snakemake.input.rows),
        snakemake.output.store,
        database=snakemake.params.database,
    )
