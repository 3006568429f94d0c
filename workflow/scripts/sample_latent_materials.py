"""Materials at random latent points, drawn as brdfpipe sample draws them (rule sample_latent_materials)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import samples

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    samples.sample_to_files(
        model=snakemake.input.model,
        store=snakemake.input.store,
        albedos=snakemake.input.albedos,
        seed=snakemake.params.seed,
        merl_outs=snakemake.output.merl,
        json_out=snakemake.output.samples,
    )
