"""Write the train/test split of the stored materials (rule write_splits)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import database

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    database.write_splits(
        snakemake.output.splits,
        store=snakemake.input.store,
        test=snakemake.params.test_materials,
    )
