"""Validate one MERL file and write it as a one-row Zarr store (rule ingest_material)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import ingest

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    ingest.ingest_material(
        snakemake.input.binary,
        snakemake.output.row,
        name=snakemake.wildcards.material,
        expect=snakemake.params.expect,
    )
