# Shared definitions: which database this run uses, its materials, the split.
# Everything that can fail on bad configuration fails here, at parse time,
# before any job runs.

import os
import re

from snakemake.exceptions import WorkflowError

from brdfpipe import database as brdf_db
from brdfpipe import blend, manifold
from brdfpipe.figures import FIGURE_STEMS, MANIFOLD_FIGURE_STEMS, RENDER_FIGURE_STEMS


RESULTS = "results"
SYNTH_DIR = f"{RESULTS}/synthetic"
INGEST_DIR = f"{RESULTS}/ingest"
STORE = f"{RESULTS}/merl.zarr"
SPLITS = f"{RESULTS}/splits.json"
MANIFEST = f"{SYNTH_DIR}/manifest.json"
FIGURES = f"{RESULTS}/figures"


def _load_database():
    try:
        if config["merl_dir"]:
            db = brdf_db.merl_database(config["merl_dir"])
        else:
            syn = config["synthetic"]
            db = brdf_db.synthetic_database(SYNTH_DIR, syn["count"], syn["seed"])
        test = brdf_db.resolve_test_materials(config["test_materials"], db)
    except brdf_db.DatabaseError as err:
        raise WorkflowError(f"invalid configuration: {err}") from None
    return db, test


DATABASE, TEST_MATERIALS = _load_database()
MATERIALS = DATABASE.materials
TRAIN_MATERIALS = [m for m in MATERIALS if m not in TEST_MATERIALS]
SYNTHETIC = DATABASE.kind == "synthetic"
PCA_SPLITS = ["all", "train"]
ACQ = config["acquisition"]
MAN = config["manifold"]
PATH_Q = max(MAN["latent_dims"]) if MAN["path_q"] is None else MAN["path_q"]
if PATH_Q not in MAN["latent_dims"]:
    raise WorkflowError(
        f"config manifold.path_q = {PATH_Q} is not one of manifold.latent_dims {MAN['latent_dims']}"
    )
# Latent paths (Soler Fig. 9): checked against the database at load, so an
# unknown material fails before any job runs.
try:
    MANIFOLD_PATHS = (
        manifold.check_paths(MAN["paths"], MATERIALS)
        if MAN["paths"]
        else manifold.default_paths(MATERIALS, MAN["seed"])
    )
except ValueError as err:
    raise WorkflowError(f"config: {err}") from None
# Rendering track: the scene's outputs and the rendered path points.
RENDER = config["render"]
if RENDER["noise_seed"] == RENDER["seed"]:
    raise WorkflowError("config render.noise_seed must differ from render.seed (it measures the noise floor)")
RENDER_DIR = f"{RESULTS}/renders/{RENDER['scene']}"
ERRORMAP_DIR = f"{RESULTS}/errormaps/{RENDER['scene']}"
PATH_ENDS = {manifold.path_name(a, b): (a, b) for a, b in MANIFOLD_PATHS}
PATH_POINTS = [(p, blend.format_t(t)) for p in PATH_ENDS for t in RENDER["path_points"]]
RENDER_FIGURES = [
    f"{FIGURES}/{stem}.{ext}" for stem in RENDER_FIGURE_STEMS.values() for ext in ("png", "pdf")
]
MANIFOLD_DIR = f"{RESULTS}/manifold"
MANIFOLD_DATA = [
    f"{MANIFOLD_DIR}/albedo.csv",
    f"{MANIFOLD_DIR}/paths.csv",
    f"{MANIFOLD_DIR}/reproduction.csv",
] + [f"{MANIFOLD_DIR}/albedo-map-q{q}.npz" for q in MAN["latent_dims"]]
MANIFOLD_FIGURES = [
    f"{FIGURES}/{stem}.{ext}" for stem in MANIFOLD_FIGURE_STEMS.values() for ext in ("png", "pdf")
]


def split_training_materials(split):
    """Materials whose channels are the rows (and whose median is the reference) of a split."""
    return MATERIALS if split == "all" else TRAIN_MATERIALS


def _fov_tag(fov):
    """File-name form of a field of view (as brdfpipe.sampling.directions_path writes it)."""
    return f"{float(fov):g}"


def direction_files(split):
    """Direction sets optimised on a split: every setup x FOV x metric on `train`
    (they are evaluated); on `all` only the near-field sets of the error metric
    (the paper's table of optimal configurations, Xu Fig. 8)."""
    files = []
    for setup in ACQ["setups"]:
        if split == "all" and setup != "nearfield":
            continue
        if setup == "point":
            fovs = [0]
        elif setup == "nearfield":
            fovs = ACQ["fovs"]
        else:
            fovs = [ACQ["fixed_fov"]]
        metrics = ACQ["metrics"] if split == "train" else ["error"]
        files += [
            f"{RESULTS}/directions/{split}/{setup}-fov{_fov_tag(fov)}-{metric}.json"
            for fov in fovs
            for metric in metrics
        ]
    return files


# Error vs training-set size (Xu Fig. 7): sizes that fit the training set, and
# the two-image near-field directions at 25° (or the first FOV) it uses.
TRAINING_SIZES = [n for n in ACQ["training_sizes"] if n <= len(TRAIN_MATERIALS)]
_CURVE_FOV = 25 if 25 in ACQ["fovs"] else ACQ["fovs"][0]
CURVE_DIRECTIONS = (
    f"{RESULTS}/directions/train/nearfield-fov{_fov_tag(_CURVE_FOV)}-error.json"
    if "nearfield" in ACQ["setups"] and "error" in ACQ["metrics"]
    else None
)
ACQUISITION_FIGURES = [
    f"{FIGURES}/{stem}.{ext}" for stem in FIGURE_STEMS.values() for ext in ("png", "pdf")
] + [f"{FIGURES}/{FIGURE_STEMS['fig08']}.{ext}" for ext in ("csv", "md")]


# Column blocks of the streamed SVD's Gram matrix (override: --set-scatter gram=N).
scattergather:
    gram=4,


wildcard_constraints:
    material="|".join(re.escape(m) for m in MATERIALS),
    split="all|train",
    scatteritem=r"\d+-of-\d+",
    setup="point|nearfield|fixed_camera|fixed_light",
    metric="error|condition",
    fov=r"\d+(\.\d+)?",
    q=r"\d+",
    space="raw|cosine|log",
    path="|".join(re.escape(p) for p in PATH_ENDS),
    t=r"\d+(\.\d+)?",


def source_file(wildcards):
    """The .binary file of one material (real MERL folder or generated)."""
    return str(DATABASE.sources[wildcards.material])
