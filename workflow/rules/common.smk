# Shared definitions: which database this run uses, its materials, the split.
# Everything that can fail on bad configuration fails here, at parse time,
# before any job runs.

import re

from snakemake.exceptions import WorkflowError

from brdfpipe import database as brdf_db


RESULTS = "results"
SYNTH_DIR = f"{RESULTS}/synthetic"
INGEST_DIR = f"{RESULTS}/ingest"
STORE = f"{RESULTS}/merl.zarr"
SPLITS = f"{RESULTS}/splits.json"
MANIFEST = f"{SYNTH_DIR}/manifest.json"


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
SYNTHETIC = DATABASE.kind == "synthetic"


wildcard_constraints:
    material="|".join(re.escape(m) for m in MATERIALS),


def source_file(wildcards):
    """The .binary file of one material (real MERL folder or generated)."""
    return str(DATABASE.sources[wildcards.material])
