"""Generate one synthetic MERL-format material (rule synthesize_material)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.data import synth

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    synth.write_named_material(
        name=snakemake.wildcards.material,
        count=snakemake.params.n_materials,
        seed=snakemake.params.seed,
        noise=snakemake.params.noise,
        path=snakemake.output.binary,
        record_path=snakemake.output.record,
    )
