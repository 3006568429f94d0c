"""The scene's sky + sun environment map (rule make_envmap)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import scene

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    scene.make_envmap(
        snakemake.output.envmap,
        width=snakemake.params.width,
        height=snakemake.params.height,
        sun_elevation_deg=snakemake.params.sun_elevation,
        sun_azimuth_deg=snakemake.params.sun_azimuth,
    )
