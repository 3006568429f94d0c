"""docs/design/extending.md's walkthrough, kept: a figure, a non-linear data space and a ring set-up.

``docs/design/walkthrough/walkthrough.patch`` is the three extensions made as
the page says (a record and its implementation each, the schema's lists); the
page records their real run on the tiny config.  Here the patch is applied to
a copy of the workflow and the library, and Snakemake plans the tiny config
with ``docs/design/walkthrough/overlay.yaml`` (which switches the three on):
the patch still applies, the config passes the schema and the parse-time
checks, and the plan holds each extension's outputs.  A change that makes an
extension need another file breaks the patch or the plan here.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WALKTHROUGH = ROOT / "docs" / "design" / "walkthrough"
PATCH = WALKTHROUGH / "walkthrough.patch"

#: The files each extension touches, as the page counts them (the schema's lists included).
EXTENSIONS = {
    "figure": {"src/brdfpipe/registry/figures.py", "src/brdfpipe/manifold/figures.py"},
    "data space": {"src/brdfpipe/registry/manifold.py", "src/brdfpipe/manifold/spaces.py",
                   "workflow/schemas/config.schema.yaml"},
    "set-up": {"src/brdfpipe/registry/acquisition.py", "workflow/schemas/config.schema.yaml"},
}


def test_each_extension_touches_at_most_three_files() -> None:
    touched = set(re.findall(r"^\+\+\+ b/(\S+)$", PATCH.read_text(encoding="utf-8"), flags=re.M))
    assert touched == set().union(*EXTENSIONS.values()), touched
    assert all(len(files) <= 3 for files in EXTENSIONS.values())


def test_the_walkthrough_applies_and_snakemake_plans_it(tmp_path: Path) -> None:
    for part in ("src", "workflow", "config"):
        shutil.copytree(ROOT / part, tmp_path / part, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "tests" / "config", tmp_path / "tests" / "config")
    applied = subprocess.run(["git", "apply", "--verbose", str(PATCH)], cwd=tmp_path, capture_output=True, text=True)
    assert applied.returncode == 0, applied.stderr
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "src")}
    plan = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "--verbose", "--configfile", "tests/config/tiny.yaml",
         str(WALKTHROUGH / "overlay.yaml")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    out = plan.stdout + plan.stderr
    assert plan.returncode == 0, out[-3000:]
    outputs = set(re.findall(r"^\s+output: (.+)$", out, flags=re.M))
    files = {f.strip() for line in outputs for f in line.split(",")}
    for expected in ("results/figures/manifold-scales.png",  # the figure, drawn by its record
                     "results/directions/train/ring-fov25-error.json",  # the set-up, optimised
                     "results/gplvm/sqrt-mu0.0001/q5.npz"):  # the data space, fitted
        assert expected in files, (expected, sorted(f for f in files if "ring" in f or "sqrt" in f or "scales" in f))
    assert any(f.startswith("results/closedloop/") and "ring" in f for f in files), "the ring is photographed"
