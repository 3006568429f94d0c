"""Every fidelity measure of one GPLVM candidate (data space, mu) (rule measure_gplvm_candidate)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.manifold import fidelity

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    fidelity.measure_candidate(
        store=snakemake.input.store,
        grams=dict(zip(snakemake.params.spaces, snakemake.input.grams)),
        models=dict(zip(snakemake.params.dims, snakemake.input.models)),
        candidate=snakemake.wildcards.candidate,
        default=snakemake.params.default,
        paths=snakemake.params.paths,
        path_q=snakemake.params.path_q,
        seed=snakemake.params.seed,
        steps=snakemake.params.steps,
        albedo_grid=snakemake.params.albedo_grid,
        clamped_hull_points=snakemake.params.clamped_hull_points,
        albedos=snakemake.input.albedos,
        spaces_out=snakemake.output.spaces,
        stability_out=snakemake.output.stability,
    )
