"""Every material's albedo from the store, once for all the manifold's measurements (rule measure_material_albedos)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import albedo

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    albedo.write_material_albedos(store=snakemake.input.store, out=snakemake.output.albedos)
