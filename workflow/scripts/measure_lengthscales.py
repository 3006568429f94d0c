"""The interpolant and the eq. 7 bound along a latent path as the length scale shrinks (rule measure_lengthscales)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import lengthscale

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    lengthscale.measure_lengthscales(
        model=snakemake.input.model,
        gram=snakemake.input.gram,
        path=snakemake.params.path,
        out=snakemake.output.table,
        database=snakemake.params.database,
    )
