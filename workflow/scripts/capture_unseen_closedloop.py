"""Closed-loop photographs of every material of an unseen database, one Mitsuba process (rule capture_unseen_closedloop)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import capture

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    capture.capture_materials_to_file(
        materials=dict(snakemake.params.binaries),
        database=snakemake.wildcards.database,
        directions=list(snakemake.input.directions),
        n_images=snakemake.params.n_images,
        out=snakemake.output.observations,
        spp=snakemake.params.spp,
        seed=snakemake.params.seed,
        light_distance=snakemake.params.light_distance,
        min_snr=snakemake.params.min_snr,
        sensor=snakemake.params.sensor,
        variant=snakemake.params.variant,
        threads=snakemake.threads,
    )
