"""Every candidate's blends against the noise floor in one table (rule summarize_floor_check)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.rendering import blend


def _per_candidate(files, candidates, points):
    files = list(files)
    return {c: files[k * points : (k + 1) * points] for k, c in enumerate(candidates)}


with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    labels = list(snakemake.params.candidates)
    blend.floor_check_table(
        candidates={c: tuple(v) for c, v in snakemake.params.candidates.items()},
        default=snakemake.params.default,
        summaries=dict(zip(labels, snakemake.input.summaries)),
        weights=_per_candidate(snakemake.input.weights, labels, snakemake.params.points),
        references=_per_candidate(snakemake.input.references, labels, snakemake.params.points),
        out=snakemake.output.table,
        database=snakemake.params.database,
    )
