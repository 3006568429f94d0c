"""Every fidelity measure of every GPLVM candidate (data space, mu) (rule compare_spaces)."""

from collections import defaultdict

from brdfpipe import fidelity
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    models = defaultdict(dict)
    for label, q, path in zip(snakemake.params.candidates, snakemake.params.dims, snakemake.input.models):
        models[label][int(q)] = path
    fidelity.compare_spaces(
        store=snakemake.input.store,
        grams=dict(zip(snakemake.params.spaces, snakemake.input.grams)),
        models=dict(models),
        default=snakemake.params.default,
        paths=snakemake.params.paths,
        path_q=snakemake.params.path_q,
        seed=snakemake.params.seed,
        steps=snakemake.params.steps,
        albedo_grid=snakemake.params.albedo_grid,
        spaces_out=snakemake.output.spaces,
        stability_out=snakemake.output.stability,
    )
