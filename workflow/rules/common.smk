# Shared definitions: which database this run uses, its materials, the split,
# and every file name of the DAG (from brdfpipe.core.filenames). Everything that can
# fail on bad configuration fails here, at parse time, before any job runs.
# Parsing imports only light modules (no matplotlib, SciPy or Zarr).

import inspect
import re
import threading
import time
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.io import apply_wildcards, is_flagged
from snakemake.scheduling.job_scheduler import JobScheduler

from brdfpipe.data import database as brdf_db
from brdfpipe.data import databases as brdf_dbs
from brdfpipe.core import filenames as fn
from brdfpipe import plan
from brdfpipe.core import stamps as job_stamps
from brdfpipe.core.version import script_digest
from brdfpipe.report import claims as report_claims
from brdfpipe.report import sidebyside
from brdfpipe.registry import acquisition as setup_specs
from brdfpipe.registry import manifold as manifold_specs

SCRIPTS = Path(workflow.current_basedir).parent / "scripts"


# Scheduling rounds. Snakemake 9's job rate limiter (--max-jobs-per-timespan,
# default 100/1s) ends every scheduling round by starting a timer for another
# round one timespan later, and every finished job starts a round of its own,
# so the timers multiply with the jobs finished: the tiny config's 98 jobs took
# 5,931 rounds, each stat()ing the inputs of every job waiting for a core
# (snakemake/snakemake pull request 3744). One pending timer per scheduler does
# what they all did (a round within the timespan), and as a daemon it no longer
# holds Snakemake's exit (docs/results/run-cost.md has the measurement).
def _reevaluate_once(scheduler, delay):
    due = time.monotonic() + delay
    pending = getattr(scheduler, "_brdfpipe_round", None)
    if pending is not None and pending[0].is_alive() and pending[1] <= due:
        return  # a round comes by then already
    timer = threading.Timer(delay, scheduler._open_jobs.release)
    timer.daemon = True
    timer.start()
    scheduler._brdfpipe_round = (timer, due)


if hasattr(JobScheduler, "_schedule_reevalutation"):
    JobScheduler._schedule_reevalutation = _reevaluate_once


def code(script):
    """Digest of a script and of the library modules it runs.

    Every rule passes it as params.code, so Snakemake's params trigger reruns
    exactly the jobs whose library code changed (and their dependents).
    """
    return script_digest(SCRIPTS / script)


# Job stamps (brdfpipe.core.stamps): every rule takes its own stamp as an input,
# `stamp=stamp_of("<rule>")`: a file holding the record of the job's rule,
# wildcards, params (by name: code digest included) and input list, rewritten
# while a run builds its DAG when the record changed or an output is missing,
# so Snakemake reruns the job from modification times, whatever its metadata
# says. The Snakefile refuses a rule without its stamp.
# Params function -> its argument names.
_PARAM_ARGS = {}
_STAMP_MODE = []


def _stamp_mode():
    """run: a run writes stamps; plan: a dry run, a report, a locked directory; read: a job's own process."""
    if not _STAMP_MODE:
        if not workflow.is_main_process:
            mode = "read"
        elif workflow.executor_plugin is None or workflow.dryrun:
            mode = "plan"
        else:
            locks = Path(workflow.persistence.path) / "locks"
            mode = "plan" if locks.is_dir() and any(locks.iterdir()) else "run"
        _STAMP_MODE.append(mode)
    return _STAMP_MODE[0]


def _param_value(rule_name, name, value, wildcards):
    if not callable(value):
        return value
    args = _PARAM_ARGS.get(value)
    if args is None:
        args = _PARAM_ARGS[value] = tuple(inspect.signature(value).parameters)
    if len(args) != 1:
        raise WorkflowError(
            f"{rule_name}: params.{name} is a function of {', '.join(args) or 'nothing'}; "
            "a stamped param may depend on the wildcards only (job stamps)"
        )
    return value(wildcards)


def _input_values(item, wildcards):
    if getattr(item, "brdfpipe_stamp", None) is not None:
        return []
    if callable(item):
        got = item(wildcards)
        return [str(f) for f in got] if isinstance(got, (list, tuple)) else [str(got)]
    return [str(item)]


def stamp_of(rule_name):
    """Input function: the stamp of a job of ``rule_name`` (``results/.stamps/<rule>/<job>``)."""

    def stamp_input(wildcards):
        spec = workflow.get_rule(rule_name)
        named = dict(spec.params.items())
        if len(named) != len(spec.params):
            raise WorkflowError(f"{rule_name}: every param needs a name (job stamps)")
        params = {
            name: _param_value(rule_name, name, value, wildcards)
            for name, value in named.items()
        }
        inputs = [f for item in spec.input for f in _input_values(item, wildcards)]
        wc = dict(wildcards.items())
        try:
            record = job_stamps.job_record(rule_name, wc, params, inputs)
        except job_stamps.StampError as err:
            raise WorkflowError(str(err)) from None
        path = fn.stamp(rule_name, job_stamps.job_key(wc))
        missing = any(
            not Path(apply_wildcards(str(f), wc)).exists()
            for f in spec.output
            if not is_flagged(f, "temp")
        )
        return job_stamps.stamp_input(
            path, record, _stamp_mode(), outputs_missing=missing
        )

    stamp_input.brdfpipe_stamp = rule_name
    return stamp_input


def _load_database():
    try:
        db = brdf_db.configured_database(config, fn.RESULTS)
        db = brdf_db.select_materials(db, config["materials"])
        test = brdf_db.resolve_test_materials(config["test_materials"], db)
    except brdf_db.DatabaseError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None
    return db, test


DATABASE, TEST_MATERIALS = _load_database()
MATERIALS = DATABASE.materials


def _load_unseen():
    try:
        return brdf_db.unseen_databases(config, DATABASE, fn.RESULTS)
    except brdf_db.DatabaseError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


# Materials outside the run's database (config unseen): label -> its fits, each
# evaluated into a store of its own (rules/unseen.smk).
UNSEEN = _load_unseen()


def _load_recorded():
    try:
        return sidebyside.recorded_runs(
            config["report"]["compare_with"],
            root=Path.cwd(),
            exclude=DATABASE.kind,
        )
    except report_claims.ClaimsInputError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None


# Recorded runs on other databases, whose claims the report shows beside this
# run's (config report.compare_with; rule write_claims).
RECORDED = _load_recorded()
N_UNSEEN = sum(len(db.sources) for db in UNSEEN.values())
TRAIN_MATERIALS = [m for m in MATERIALS if m not in TEST_MATERIALS]
# The workflow generates the synthetic database (rules synthesize_material and
# write_manifest) for database: synthetic only: a folder written by `brdfpipe
# synth` given as merl_dir is labelled synthetic but is read as it is. A
# database of fits is evaluated by the workflow (rule evaluate_fits).
GENERATED = config["database"] == "synthetic"
FITS = bool(DATABASE.fits)
DATABASE_TITLE = brdf_dbs.title(DATABASE.kind)
ACQ = config["acquisition"]
MAN = config["manifold"]
RENDER = config["render"]
try:
    plan.check_config(config, materials=MATERIALS, train=TRAIN_MATERIALS)
    TRAINING_SIZES = plan.training_sizes(ACQ, len(TRAIN_MATERIALS))
    PATH_Q = plan.path_q(MAN)
    # GPLVM candidates: label -> GplvmCandidate (space, mu, normalise, method, init); the default first.
    CANDIDATES = plan.manifold_candidates(MAN)
    # Latent paths (Soler Fig. 9): checked against the database at load.
    MANIFOLD_PATHS = plan.latent_paths(MAN, MATERIALS)
except plan.ConfigError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None

PCA_SPLITS = ["all", "train"]
DIRECTIONS = {split: plan.direction_files(ACQ, split) for split in PCA_SPLITS}
# E(S) consistency checks: one per split that has direction sets.
CHECKED_SPLITS = [split for split in PCA_SPLITS if DIRECTIONS[split]]
CURVE_DIRECTIONS = plan.curve_directions(ACQ)
# The near-field directions Xu §6 states in words, evaluated on the split-all model (the claims' Fig. 8 rows).
PAPER_DIRECTIONS = plan.paper_directions(ACQ)
# Closed-loop acquisition: the held-out materials photographed by these
# training-split direction sets (setup, fov, metric), n images each.
CLOSED = config["closed_loop"]
CLOSEDLOOP_SETS = plan.closedloop_directions(config)
CLOSEDLOOP_N = sorted(CLOSED["n_images"])
CLOSEDLOOP_DIRECTIONS = [fn.directions("train", *s) for s in CLOSEDLOOP_SETS]
# The unseen materials' acquisition: the training split's point and near-field
# sets of the error metric looked up, the closed loop's sets photographed.
UNSEEN_DIRECTIONS = plan.unseen_directions(ACQ) if UNSEEN else []
UNSEEN_EVALUATED = bool(UNSEEN) and bool(UNSEEN_DIRECTIONS or CLOSEDLOOP_SETS)
UNSEEN_FIGURES = plan.unseen_figures(unseen=bool(UNSEEN), evaluated=UNSEEN_EVALUATED)
UNSEEN_MAP_Q = plan.unseen_map_q(MAN)
ACQUISITION_FIGURES = plan.acquisition_figures(ACQ)
# Xu Figs. 2 and 15: held-out materials (FIGURE_MATERIALS, also Fig. 3's) reconstructed
# from the training split's direction sets RECON_SETS (setup, fov, metric, n), one job
# per material, rendered in the pre-renders' scene, one job (one Mitsuba start) per material.
RECONSTRUCTION_FIGURES = plan.reconstruction_figures(ACQ)
RECON_COLUMNS = plan.reconstruction_columns(ACQ)
RECON_SETS = plan.reconstruction_sets(ACQ)
FIGURE_MATERIALS = plan.figure_materials(TEST_MATERIALS)
RECON_DIRECTIONS = list(
    dict.fromkeys(fn.directions("train", s, f, m) for s, f, m, _ in RECON_SETS)
)
RECON_MATERIALS = FIGURE_MATERIALS if RECON_SETS else []
MANIFOLD_FIGURES = plan.manifold_figures(MAN)
DEFAULT_CANDIDATE = next(iter(CANDIDATES))
CANDIDATE_SPACES = sorted({c.space for c in CANDIDATES.values()} | {"raw"})


def candidate_gram_spaces(candidate):
    """Gram matrices a candidate's measures read: raw (raw-unit stability) and its own space."""
    return sorted({"raw", CANDIDATES[candidate].space})


ALBEDO_MAP_DIMS = plan.albedo_map_dims(MAN)
MANIFOLD_DATA = [
    fn.albedo(),
    fn.paths_csv(),
    fn.reproduction(),
    fn.spaces_csv(),
    fn.spaces_stability_csv(),
] + [fn.albedo_map(q) for q in ALBEDO_MAP_DIMS]

# Rendering track: the scene's outputs and the rendered path points; render jobs
# ask for a GPU (the Slurm plugin's `gpu` resource) when the variant needs one.
SCENE = RENDER["scene"]
RENDER_GPUS = 1 if RENDER["variant"].startswith("cuda") else 0
# The rendered paths: manifold.paths and, where the database has both ends,
# Soler Figs. 12/13's chrome -> silver-paint (in the model of PATH_Q).
RENDER_PATHS = manifold_specs.rendered_paths(MANIFOLD_PATHS, MATERIALS)
PATH_ENDS = {fn.path_name(a, b): (a, b) for a, b in RENDER_PATHS}
PATH_POINTS = [(p, fn.format_t(t)) for p in PATH_ENDS for t in RENDER["path_points"]]
# Soler Fig. 6 along Figs. 12/13's path where it is rendered, else the first path.
FIG06_PATH = (
    manifold_specs.SOLER_FIG12_PATH
    if manifold_specs.SOLER_FIG12_PATH in RENDER_PATHS
    else RENDER_PATHS[0]
)
# Soler Fig. 1: materials at random latent points (render.latent_samples).
N_SAMPLES = RENDER["latent_samples"]["count"]
RENDER_FIGURES = plan.render_figures(len(PATH_POINTS), N_SAMPLES)
# The noise-floor check (render.floor_check): every material and the chosen
# candidates' path points rendered again, small and with many samples, in a
# scene folder of its own. Render settings per scene folder.
FLOOR_CANDIDATES = plan.floor_check_candidates(RENDER, CANDIDATES, len(PATH_POINTS))
RENDER_SETTINGS = {SCENE: (RENDER["resolution"], RENDER["spp"])}
if FLOOR_CANDIDATES:
    FLOOR = RENDER["floor_check"]
    FLOOR_SCENE = fn.floor_scene(SCENE, FLOOR["resolution"], FLOOR["spp"])
    RENDER_SETTINGS[FLOOR_SCENE] = (FLOOR["resolution"], FLOOR["spp"])
    FLOOR_FIGURE = fn.figure_files(fn.FLOOR_CHECK_STEM)
else:
    FLOOR_SCENE = None
    FLOOR_FIGURE = []


# Pre-render batches (render.materials_per_job materials a job, every scene folder).
RENDER_BATCHES = fn.split_batches(MATERIALS, RENDER["materials_per_job"])


def render_batch_rule(k):
    """Name of the rule that pre-renders batch k."""
    return fn.batch_rule("prerender_materials", k)


# Sizes the memory model reads, per scene folder (the floor check renders smaller).
JOB_SIZES = {
    scene: plan.job_sizes(
        config, resolution=res, n_test=len(TEST_MATERIALS), n_unseen=N_UNSEEN
    )
    for scene, (res, _) in RENDER_SETTINGS.items()
}
# The memory check's inputs (the Snakefile runs the check once all rules exist).
if config["materials"] is not None:
    MATERIALS_KEY = "materials"
else:
    MATERIALS_KEY = {
        "synthetic": "synthetic.count",
        "merl": "merl_dir",
        "nbrdf": "nbrdf_archive",
    }.get(config["database"], "database")
POINT_OUTPUTS = {
    **{r: len(PATH_POINTS) for r in plan.PER_OUTPUT_MB},
    "sample_latent_materials": N_SAMPLES,
}


def mem(rule, outputs=1, scenes=None):
    """A rule's mem_mb: modelled peak for this many materials, outputs and sizes, growing by half per retry (brdfpipe.plan.memory).

    ``scenes``: the scene folders a job without a {scene} wildcard renders in
    (a pre-render batch's), one after another: the largest need of them.
    """

    own_scene = FLOOR_SCENE if rule in plan.FLOOR_RULES else SCENE

    def mem_mb(wildcards, attempt):
        folders = scenes or [wildcards.get("scene", own_scene)]
        n = len(MATERIALS)
        need = [
            plan.mem_mb(rule, n, attempt, outputs=outputs, sizes=JOB_SIZES[s])
            for s in folders
        ]
        return max(need)

    return mem_mb


def split_training_materials(split):
    """Materials whose channels are the rows (and whose median is the reference) of a split."""
    return MATERIALS if split == "all" else TRAIN_MATERIALS


def flat(figures):
    """All files of a {key: [files]} figure mapping."""
    return [f for files in figures.values() for f in files]


def path_point_files(kind):
    """One file per rendered path point (kind: binary, image, noise, weights)."""
    return [fn.path_point(SCENE, p, t, kind) for p, t in PATH_POINTS]


def sample_files(kind):
    """One file per latent sample of Soler Fig. 1 (kind: binary, image)."""
    return [fn.latent_sample(SCENE, k, kind) for k in range(N_SAMPLES)]


def errormap_files(kind):
    """One error-map file per rendered path point (kind: blended.exr, error.exr, error.png)."""
    return [fn.errormap(SCENE, p, t, kind) for p, t in PATH_POINTS]


def candidate_point_files(candidate, kind):
    """One file per path point of a candidate in the floor check (kinds of fn.path_point)."""
    return [
        fn.candidate_path_point(FLOOR_SCENE, candidate, p, t, kind)
        for p, t in PATH_POINTS
    ]


def candidate_errormap_files(candidate, kind):
    """One floor-check error-map file per path point of a candidate (kinds of fn.errormap)."""
    return [
        fn.candidate_errormap(FLOOR_SCENE, candidate, p, t, kind)
        for p, t in PATH_POINTS
    ]


# Column blocks of the streamed SVD's Gram matrix (override: --set-scatter gram=N).
scattergather:
    gram=4,


try:
    plan.check_gram_blocks(len(scatter.gram("{scatteritem}")))
except plan.ConfigError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None


wildcard_constraints:
    material="|".join(re.escape(m) for m in MATERIALS),
    split="all|train",
    scatteritem=r"\d+-of-\d+",
    setup="|".join(setup_specs.SETUP_NAMES),
    metric="|".join(setup_specs.METRICS),
    fov=r"\d+(\.\d+)?",
    q=r"\d+",
    space="|".join(manifold_specs.SPACE_NAMES),
    candidate="|".join(re.escape(c) for c in CANDIDATES),
    path="|".join(re.escape(p) for p in PATH_ENDS) or "(?!)",
    t=r"\d+(\.\d+)?",
    scene="|".join(re.escape(s) for s in RENDER_SETTINGS),
    database="|".join(re.escape(d) for d in UNSEEN) or "(?!)",


def closedloop_images(material, kind):
    """A material's closed-loop EXRs of one kind (render, sensor), in the capture's output order."""
    return [
        fn.closedloop_image(material, *CLOSEDLOOP_SETS[d], n, j, kind)
        for d in range(len(CLOSEDLOOP_SETS))
        for n in CLOSEDLOOP_N
        for j in range(n)
    ]


def closedloop_tables(material, source):
    """A material's observation tables of one source (noiseless, sensor), in the capture's output order."""
    return [
        fn.closedloop_observations(material, *CLOSEDLOOP_SETS[d], n, source)
        for d in range(len(CLOSEDLOOP_SETS))
        for n in CLOSEDLOOP_N
    ]


def source_file(wildcards):
    """The .binary file of one material (real MERL folder or generated)."""
    return str(DATABASE.sources[wildcards.material])


def recon_image_count(recon_set):
    """Images of a reconstructed set (its n for an image set-up, none for point samples)."""
    setup, _, _, n = recon_set
    return n if setup_specs.SETUPS[setup].images else 0


def recon_tables(material):
    """A figure material's reconstructed tables, one per set of RECON_SETS."""
    return [fn.reconstruction(material, *s) for s in RECON_SETS]


def recon_inputs(material):
    """The input images of a figure material's image sets, set by set."""
    return [
        fn.reconstruction_input(material, *s, j)
        for s in RECON_SETS
        for j in range(1, recon_image_count(s) + 1)
    ]


def recon_renders(material):
    """The renders of a figure material's reconstructed tables, one per set of RECON_SETS."""
    return [fn.reconstruction_render(SCENE, material, *s) for s in RECON_SETS]
