"""Closed-loop photographs of one held-out material and their observation tables (rule capture_closedloop)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import capture

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    capture.capture_to_files(
        material=snakemake.input.binary,
        name=snakemake.wildcards.material,
        database=snakemake.params.database,
        directions=list(snakemake.input.directions),
        n_images=snakemake.params.n_images,
        renders=list(snakemake.output.renders),
        photographs=list(snakemake.output.photographs),
        noiseless=list(snakemake.output.noiseless),
        observations=list(snakemake.output.observations),
        spp=snakemake.params.spp,
        seed=snakemake.params.seed,
        light_distance=snakemake.params.light_distance,
        min_snr=snakemake.params.min_snr,
        sensor=snakemake.params.sensor,
        variant=snakemake.params.variant,
        threads=snakemake.threads,
    )
