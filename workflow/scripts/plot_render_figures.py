"""Pre-render grid, interpolation strip and error panel of the rendering track (rule plot_render_figures)."""

from brdfpipe import figures
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    figures.make_render_figures(
        prerenders=dict(zip(snakemake.params.materials, snakemake.input.prerenders)),
        weights=snakemake.input.weights,
        references=snakemake.input.references,
        errormap_dir=snakemake.params.errormap_dir,
        out_dir=snakemake.params.out_dir,
        database=snakemake.params.database,
    )
