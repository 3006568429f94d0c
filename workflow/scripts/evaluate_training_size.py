"""Error vs number of training materials, Xu Fig. 7 (rule evaluate_training_size)."""

from brdfpipe.acquisition import evaluation
from brdfpipe.core.logutil import log_to

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    evaluation.write_training_size(
        snakemake.input.store,
        snakemake.input.logmap,
        snakemake.input.directions,
        snakemake.output.training_size,
        test_materials=snakemake.params.test_materials,
        sizes=snakemake.params.sizes,
        order_seed=snakemake.params.order_seed,
        orders=snakemake.params.orders,
        eta=snakemake.params.eta,
    )
