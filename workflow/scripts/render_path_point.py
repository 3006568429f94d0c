"""Reference renders of an interpolated material with two seeds, and their I¹⁻ parts (rule render_path_point)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0]):
    scene.render_material_seeds(
        snakemake.input.merl,
        [snakemake.output.image, snakemake.output.noise],
        outs_one=[snakemake.output.one, snakemake.output.one_noise],
        seeds=snakemake.params.seeds,
        envmap=snakemake.input.envmap,
        variant=snakemake.params.variant,
        resolution=snakemake.params.resolution,
        spp=snakemake.params.spp,
        max_depth=snakemake.params.max_depth,
        threads=snakemake.threads,
        attrs={"database": snakemake.params.database, "path_point": snakemake.wildcards.path + "-t" + snakemake.wildcards.t},
    )
