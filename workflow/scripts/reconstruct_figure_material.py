"""A held-out material reconstructed from each direction set of Xu Figs. 2 and 15, with its input images (rule reconstruct_figure_material)."""

from brdfpipe.acquisition import reconstruct
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    files = iter(snakemake.output.inputs)  # set by set, its images' files
    reconstruct.reconstruct_sets(
        snakemake.input.store,
        snakemake.input.model,
        snakemake.wildcards.material,
        [(path, n) for path, n in snakemake.params.sets],
        outs=list(snakemake.output.tables),
        inputs=[[next(files) for _ in range(k)] for k in snakemake.params.images],
        eta=snakemake.params.eta,
    )
