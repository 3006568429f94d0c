"""Wall time per stage from the jobs' benchmark files (rule summarize_stage_times)."""

from brdfpipe.core.logutil import log_to
from brdfpipe.report import runinfo

with log_to(snakemake.log[0], stamp=snakemake.input.stamp):
    runinfo.write_stage_times(
        snakemake.params.benchmarks,
        csv_path=snakemake.output.csv,
        rst_path=snakemake.output.rst,
    )
