"""Write the synthetic database's manifest (rule write_manifest)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import synth

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    synth.write_database_manifest(
        snakemake.output.manifest,
        count=snakemake.params.n_materials,
        seed=snakemake.params.seed,
        noise=snakemake.params.noise,
        test_materials=snakemake.params.test_materials,
        record_files=snakemake.input.records,
        materials=snakemake.params.materials,
    )
