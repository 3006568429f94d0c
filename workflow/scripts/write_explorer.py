"""The in-browser material explorer: results/explorer/ (rule write_explorer)."""

from brdfpipe.explorer import export
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    export.write_explorer(
        out=snakemake.output.explorer,
        models=list(snakemake.input.models),
        prerenders=dict(zip(snakemake.params.materials, snakemake.input.prerenders)),
        albedo=snakemake.input.albedo,
        path_points=[
            {"weights": w, "image": i}
            for w, i in zip(snakemake.input.weights, snakemake.input.references)
        ],
        summary=snakemake.input.summary or None,
        database=snakemake.params.database,
        max_rank=snakemake.params.max_rank,
    )
