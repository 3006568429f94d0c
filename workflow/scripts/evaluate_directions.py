"""Leave-out evaluation of every training-split direction set (rule evaluate_directions)."""

from brdfpipe.acquisition import evaluation
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    evaluation.write_evaluation(
        snakemake.input.store,
        snakemake.input.model,
        list(snakemake.input.directions),
        snakemake.output.errors,
        test_materials=snakemake.params.test_materials,
        eta=snakemake.params.eta,
    )
