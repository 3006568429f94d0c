"""The planner: what the workflow plans from its configuration, decided before any job runs.

The layer on top of the library beside the command line, read by the
Snakefile at parse time: standard library only (``tests/test_plan.py``
guards it), built on the specs (:mod:`brdfpipe.spec`: set-ups, data spaces,
figures) and the DAG's file names (:mod:`brdfpipe.core.filenames`).  Nothing
below it imports it.

* :mod:`brdfpipe.plan.config`  – the config's parse-time checks (one :class:`ConfigError` line naming the key);
* :mod:`brdfpipe.plan.outputs` – which direction sets, figures and unseen-material files a config produces;
* :mod:`brdfpipe.plan.memory`  – the rules a config runs and the memory each job declares, checked up front;
* :mod:`brdfpipe.plan.report`  – what the Snakemake report holds (one item per figure, table and error map).

``from brdfpipe import plan`` gives every public name of the four modules
(``plan.check_config``, ``plan.mem_mb``, …), each defined in one of them.
"""

from __future__ import annotations

from brdfpipe.plan.config import (
    ConfigError,
    MITSUBA_MAX_SAMPLES,
    config_key,
    describe_schema_error,
    schema_problem,
    check_finite,
    path_q,
    manifold_candidates,
    training_sizes,
    check_config,
    latent_paths,
    check_closed_loop,
    sensor_max_snr,
)
from brdfpipe.plan.outputs import (
    direction_files,
    closedloop_directions,
    unseen_directions,
    unseen_figures,
    unseen_map_q,
    curve_fov,
    curve_directions,
    albedo_map_dims,
    acquisition_figures,
    manifold_figures,
    render_figures,
    floor_check_candidates,
)
from brdfpipe.plan.memory import (
    UNSEEN_RULES,
    planned_rules,
    MEMORY_MB,
    PER_OUTPUT_MB,
    MEMORY_HEADROOM,
    MEMORY_RETRY_GROWTH,
    JOB_MEMORY_LIMIT_MB,
    MEASURED_SIZES,
    PATH_CHUNK,
    SIZE_MEMORY_MB,
    SIZE_KEYS,
    FLOOR_RULES,
    job_sizes,
    model_mb,
    mem_mb,
    check_memory,
)
from brdfpipe.plan.report import (
    ACQUISITION,
    MANIFOLD,
    RENDERING,
    CLAIMS,
    FIGURE_NUMBERS,
    Item,
    report_items,
)

__all__ = [
    "ConfigError",
    "MITSUBA_MAX_SAMPLES",
    "config_key",
    "describe_schema_error",
    "schema_problem",
    "check_finite",
    "path_q",
    "manifold_candidates",
    "training_sizes",
    "check_config",
    "latent_paths",
    "check_closed_loop",
    "sensor_max_snr",
    "direction_files",
    "closedloop_directions",
    "unseen_directions",
    "unseen_figures",
    "unseen_map_q",
    "curve_fov",
    "curve_directions",
    "albedo_map_dims",
    "acquisition_figures",
    "manifold_figures",
    "render_figures",
    "floor_check_candidates",
    "UNSEEN_RULES",
    "planned_rules",
    "MEMORY_MB",
    "PER_OUTPUT_MB",
    "MEMORY_HEADROOM",
    "MEMORY_RETRY_GROWTH",
    "JOB_MEMORY_LIMIT_MB",
    "MEASURED_SIZES",
    "PATH_CHUNK",
    "SIZE_MEMORY_MB",
    "SIZE_KEYS",
    "FLOOR_RULES",
    "job_sizes",
    "model_mb",
    "mem_mb",
    "check_memory",
    "ACQUISITION",
    "MANIFOLD",
    "RENDERING",
    "CLAIMS",
    "FIGURE_NUMBERS",
    "Item",
    "report_items",
]
