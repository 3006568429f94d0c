"""The planner: what the workflow plans from its configuration, decided before any job runs.

The layer on top of the library beside the command line, read by the
Snakefile at parse time: standard library only (``tests/test_plan.py``
guards it), built on the specs (:mod:`brdfpipe.registry`: set-ups, data spaces,
figures) and the DAG's file names (:mod:`brdfpipe.core.filenames`).  Nothing
below it imports it.

* :mod:`brdfpipe.plan.config`  – the config's parse-time checks (one :class:`ConfigError` line naming the key);
* :mod:`brdfpipe.plan.outputs` – which direction sets, figures and unseen-material files a config produces, where a run's results are;
* :mod:`brdfpipe.plan.memory`  – the memory each job declares, checked up front over the rules the workflow defines;
* :mod:`brdfpipe.plan.report`  – what the Snakemake report holds (one item per figure, table and error map).

``from brdfpipe import plan`` gives every public name of the four modules
(``plan.check_config``, ``plan.mem_mb``, …), each defined in one of them.
"""

from __future__ import annotations

from brdfpipe.plan import config, memory, outputs, report

_MODULES = (config, outputs, memory, report)

#: Every public name of the four modules (each defined, and listed in ``__all__``, once: in its module).
__all__ = [name for module in _MODULES for name in module.__all__]


def __getattr__(name: str) -> object:
    """``plan.<name>``: the public name of whichever of the four modules defines it."""
    for module in _MODULES:
        if name in module.__all__:
            return getattr(module, name)
    raise AttributeError(f"module 'brdfpipe.plan' has no attribute {name!r}")
