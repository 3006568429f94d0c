"""Leave-out evaluation, E(S) consistency check and training-size curve (rule evaluate)."""

from pathlib import Path

from brdfpipe import reconstruct
from brdfpipe.logutil import log_to

with log_to(snakemake.log[0]):
    reconstruct.run_evaluation(
        snakemake.input.store,
        snakemake.input.model,
        snakemake.input.logmap,
        list(snakemake.input.directions),
        Path(snakemake.output.errors).parent,
        test_materials=snakemake.params.test_materials,
        eta=snakemake.params.eta,
        sizes=snakemake.params.sizes,
        order_seed=snakemake.params.order_seed,
        curve_directions=snakemake.input.curve or None,
    )
