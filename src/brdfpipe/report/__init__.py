"""The Snakemake report (``snakemake --report results/report.zip``, ``make report``).

How the run's numbers reach the report.  Snakemake's ``report()`` flag marks
each figure, table and error map in the rule that writes it, with a
category per track, labels (figure number, database) and a caption file.
Snakemake reads a caption, and the workflow-level ``report:`` page, when it
builds the report, not when it parses the workflow (Snakemake 9.27:
``FileRecord.render`` opens ``raw_caption`` then).  So the captions are
files the run writes: rule ``write_claims`` reads the run's CSVs, computes
every claim of the two papers (:mod:`.claims`), and writes
``results/report/claims.{csv,json,rst}``, one caption per report entry
(:mod:`.captions`) and the front page's body (:mod:`.runinfo`); rule
``summarize_stage_times`` sums the jobs' benchmark files per stage.  Rule
``all`` requests both, so ``make run`` writes them and ``make report`` only
packs.  The alternative, a static caption that computes numbers in Jinja2,
cannot read files (Snakemake passes only the job's input, output, params,
wildcards and config), and a number typed into a caption would go stale.

Modules (which files the report holds is the planner's,
:mod:`brdfpipe.plan.report`): :mod:`brdfpipe.report.claims` (each claim as its paper
states it, with one of four verdicts and its cause; its parts:
:mod:`brdfpipe.report.claims_base`, :mod:`brdfpipe.report.claims_xu`,
:mod:`brdfpipe.report.claims_setups`, :mod:`brdfpipe.report.claims_soler`,
:mod:`brdfpipe.report.claims_ours`, :mod:`brdfpipe.report.claims_io`),
:mod:`brdfpipe.report.captions`, :mod:`brdfpipe.report.runinfo` (job time),
:mod:`brdfpipe.report.rst` (the one escaping of run-supplied text into
reStructuredText and Jinja2: every name reaches the page as text),
:mod:`brdfpipe.report.critical_path` (where a finished run's wall time went:
its critical path, CPU per rule, idle cores; ``benches/bench_critical_path.py``),
:mod:`brdfpipe.report.sidebyside` (the fidelity page: several runs' verdicts side by side, for ``docs/``).
"""
