"""Soler Figs. 1, 12, 13 and the pre-render grid of the rendering track (rule plot_render_figures)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import figures

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    figures.make_render_figures(
        prerenders=dict(zip(snakemake.params.materials, snakemake.input.prerenders)),
        weights=list(snakemake.input.weights),
        references=list(snakemake.input.references),
        references_noise=list(snakemake.input.references_noise),
        blended=list(snakemake.input.blended),
        errors=list(snakemake.input.errors),
        summary=snakemake.input.summary or None,
        samples=snakemake.input.samples or None,
        sample_images=list(snakemake.input.sample_images),
        figures={key: list(snakemake.output[key]) for key in snakemake.params.figure_keys},
        database=snakemake.params.database,
    )
