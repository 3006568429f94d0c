"""Write the train/test split of the stored materials (rule write_splits)."""

from brdfpipe import database
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    database.write_splits(
        snakemake.output.splits,
        store=snakemake.input.store,
        test=snakemake.params.test_materials,
    )
