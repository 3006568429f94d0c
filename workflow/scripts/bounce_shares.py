"""Share of I²⁺ (≥ 2 scatterings on the material) in each pre-render (rule bounce_shares)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import blend

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    blend.bounce_shares(
        images=dict(zip(snakemake.params.materials, snakemake.input.images)),
        ones=dict(zip(snakemake.params.materials, snakemake.input.ones)),
        mask=snakemake.input.mask,
        out=snakemake.output.shares,
        database=snakemake.params.database,
    )
