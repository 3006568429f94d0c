"""The scene's sky + sun environment map (rule make_envmap)."""

from brdfpipe.rendering import scene
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0]):
    scene.make_envmap(
        snakemake.output.envmap,
        width=snakemake.params.width,
        height=snakemake.params.height,
        sun_elevation_deg=snakemake.params.sun_elevation,
        sun_azimuth_deg=snakemake.params.sun_azimuth,
    )
