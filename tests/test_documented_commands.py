"""Every command the README and the docs show runs (issue 31, item 3).

The commands are collected from the files, not listed by hand: every line of
a shell code block and every inline code span of README.md, config/README.md,
docs/, profiles/ and src/ that starts with ``make``, ``snakemake``,
``brdfpipe`` (with arguments) or ``python -m brdfpipe…`` / ``python -m
snakemake``.  :data:`RUNNERS` says how each is run here: the command itself,
with its placeholders (``DIR``, ``NAME``, ``M`` …) filled with small real
inputs (a copy of the session's tiny run and a two-material database), or as
a dry run (``-n``) where the whole run is too long for a test.  A documented
command without a runner fails :func:`test_every_documented_command_has_a_runner`,
so a new or changed command in the docs is run in CI; a runner whose command
left the docs fails it too.

Each runner runs in a private "checkout" (links to this checkout's workflow,
config, sources, profiles and virtual environment, and a hard-linked copy of
the tiny run's ``results/``), with the virtual environment's ``bin`` first on
``PATH``, so ``brdfpipe``, ``snakemake`` and ``python`` are the project's.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shared_runs import copy_run, shared_run

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "config" / "tiny.yaml"
TINY_NBRDF = ROOT / "tests" / "config" / "tiny-nbrdf.yaml"
BIN = Path(sys.executable).parent
#: Files whose commands are collected (README.md of every folder but the virtual environment's).
DOC_GLOBS = ("README.md", "config/README.md", "docs/**/*.md", "profiles/**/*.md", "src/**/*.md")
_FIRST = {"make", "snakemake", "brdfpipe", "python", "python3"}
#: What the tiny run provides (tests/config/tiny.yaml: standardised μ = 1e-6, q = 2 and 5).
MODEL = "results/gplvm/standardised-mu1e-06/q5.npz"
DIRECTIONS = "results/directions/train/nearfield-fov25-error.json"
OVERLAYS = "docs/results/runs/2026-11-28-cpu"

pytestmark = pytest.mark.slow


def _is_command(line: str) -> bool:
    words = line.split()
    while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):  # VAR=value before the command
        words = words[1:]
    if not words or words[0] not in _FIRST:
        return False
    if words[0] in ("python", "python3"):
        return len(words) > 2 and words[1] == "-m" and (words[2].startswith("brdfpipe") or words[2] == "snakemake")
    if words[0] == "brdfpipe":  # `brdfpipe info` alone names a command; with arguments it is one
        return len(words) > 2 and re.fullmatch(r"[a-z]+", words[1]) is not None
    if words[0] == "make":
        return re.fullmatch(r"[a-z-]+", words[1] if len(words) > 1 else "") is not None
    return len(words) > 1


def documented_commands() -> dict[str, list[str]]:
    """Every command the docs show (whitespace normalised, shell continuations joined) → the files showing it."""
    found: dict[str, set[str]] = {}
    files = sorted({p for g in DOC_GLOBS for p in ROOT.glob(g) if ".venv" not in p.parts})
    for path in files:
        text = path.read_text(encoding="utf-8")
        lines = []
        for m in re.finditer(r"^```([a-z]*)\n(.*?)^```", text, re.S | re.M):
            if m.group(1) in ("", "sh", "bash", "console", "shell"):
                body = re.sub(r"\\\n\s*", " ", m.group(2))
                lines += [re.sub(r"\s+#.*$", "", re.sub(r"^\$ ", "", ln.strip())) for ln in body.splitlines()]
        prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
        lines += [m.group(1) for m in re.finditer(r"`([^`\n]+)`", prose)]
        for line in lines:
            if _is_command(line.strip()):
                found.setdefault(" ".join(line.split()), set()).add(path.relative_to(ROOT).as_posix())
    return {c: sorted(f) for c, f in found.items()}


_SYNTH_SMALL = "brdfpipe synth --count 2 --seed 2016 --out {tmp}/synth"
_FITS_TWO = "brdfpipe nbrdf merl-nbrdf --out {tmp}/realism/merl-nbrdf teflon alum-bronze"
_DRY_DEFAULT = "snakemake -n --quiet=rules --cores 2 --configfile config/config.yaml"
_SLURM = "PYTHONPATH=.venv/slurm-plugins"
_REPORT = "report"  # one runner for both report commands (a finished tiny-nbrdf run; see test_the_report_commands)

#: Documented command → the command run here.  ``{tmp}``: a fresh folder; ``{a}``, ``{b}``: two materials
#: of the tiny run; ``{material}``: one of its tables; ``{obs}``: a CSV of observations of it.
RUNNERS: dict[str, str] = {
    # -- make targets: the real target, with Snakemake dry-running where a run is too long --------------
    "make run": "make run SMK='snakemake -n --quiet=rules'",
    "make run CONFIG=FILE": "make run CONFIG=tests/config/tiny.yaml SMK='snakemake -n --quiet=rules'",
    "make run CONFIG=tests/config/tiny-nbrdf.yaml":
        "make run CONFIG=tests/config/tiny-nbrdf.yaml SMK='snakemake -n --quiet=rules'",
    'make run CONFIG="config/config.yaml config/floor-check-all.yaml"':
        "make run CONFIG='config/config.yaml config/floor-check-all.yaml' SMK='snakemake -n --quiet=rules'",
    "make report": _REPORT,
    "make dryrun": "make dryrun",
    "make lint": "make lint",
    "make clean": "make clean && test ! -e results/merl.zarr && test ! -e .snakemake",
    "make slurm-plugins": "make slurm-plugins",
    "make test": "make -n test",  # the suite itself: this test is part of it
    "make bench": "make -n bench",  # minutes of benchmarks: benches/ runs them
    "make slurm-test": "make -n slurm-test",  # tests/test_slurm.py runs it
    # -- Snakemake as the docs call it (dry runs) -----------------------------------------------------
    "snakemake --cores all --configfile config/config.yaml": _DRY_DEFAULT,
    "snakemake --cores all --configfile config/config.yaml --config database=synthetic":
        f"{_DRY_DEFAULT} --config database=synthetic",
    "snakemake --configfile FILE": "snakemake -n --quiet=rules --configfile tests/config/tiny-nbrdf.yaml",
    "snakemake --cores N": "snakemake -n --quiet=rules --cores 2",
    "snakemake -n": "snakemake -n --quiet=rules",
    "snakemake --lint": "snakemake --lint --configfile tests/config/tiny.yaml",
    "snakemake --version": "snakemake --version",
    "snakemake --report": _REPORT,
    "snakemake --set-scatter gram=16": "snakemake -n --quiet=rules --set-scatter gram=16",
    "snakemake --list-rules | grep prerender_materials": "snakemake --list-rules | grep prerender_materials",
    # the plug-in importable, as after pip install -e ".[workflow,slurm]" (make test builds .venv/slurm-plugins)
    "snakemake --profile profiles/slurm": f"{_SLURM} snakemake -n --quiet=rules --profile profiles/slurm",
    "PYTHONPATH=.venv/slurm-plugins snakemake --profile profiles/slurm":
        f"{_SLURM} snakemake -n --quiet=rules --profile profiles/slurm",
    "snakemake --profile profiles/slurm --configfile config/config.yaml":
        f"{_SLURM} snakemake -n --quiet=rules --profile profiles/slurm --configfile config/config.yaml",
    "snakemake results/evaluation/errors.csv": "snakemake -n --quiet=rules results/evaluation/errors.csv",
    "snakemake --directory /tmp/cl/default --configfile config/config.yaml -- results/evaluation/closedloop.csv":
        "snakemake -n --quiet=rules --directory {tmp}/cl/default --configfile config/config.yaml -- "
        "results/evaluation/closedloop.csv",
    "snakemake --cores 2 --configfile config/config.yaml overlay.yaml -- "
    "results/errormaps/preview-48x36-4096spp/floor-check.csv results/explorer":
        f"snakemake -n --quiet=rules --cores 2 --configfile config/config.yaml {OVERLAYS}/merl-nbrdf/overlay.yaml -- "
        "results/errormaps/preview-48x36-4096spp/floor-check.csv results/explorer",
    "snakemake --cores 2 --configfile config/config.yaml overlay.yaml [grid64.yaml | grid128.yaml | "
    "distant-light.yaml] -- results/evaluation/closedloop.csv":
        " && ".join(f"snakemake -n --quiet=rules --cores 2 --configfile config/config.yaml "
                    f"{OVERLAYS}/closed-loop/overlay.yaml {OVERLAYS}/closed-loop/{o}.yaml -- "
                    "results/evaluation/closedloop.csv" for o in ("grid64", "grid128", "distant-light")),
    "snakemake --cores 2 --configfile config/config.yaml overlay.yaml grid<G>.yaml [seed<S>.yaml] -- "
    "results/evaluation/errors.csv results/evaluation/closedloop.csv results/directions/all/nearfield-fov25-error.json":
        " && ".join(f"snakemake -n --quiet=rules --cores 2 --configfile config/config.yaml "
                    f"{OVERLAYS}/resolution/overlay.yaml {OVERLAYS}/resolution/grid{g}.yaml{seed} -- "
                    "results/evaluation/errors.csv results/evaluation/closedloop.csv "
                    "results/directions/all/nearfield-fov25-error.json"
                    for g, seed in ((32, ""), (256, f" {OVERLAYS}/resolution/seed2.yaml"))),
    "python -m snakemake ...": "python -m snakemake -n --quiet=rules",
    "python3 -m snakemake --cores 16 --scheduler greedy": "python3 -m snakemake -n --quiet=rules --cores 16 "
                                                          "--scheduler greedy",
    # -- the brdfpipe command: placeholders filled, sizes cut where the docs' would take minutes or GB ---
    "brdfpipe synth --count 100 --seed 2016 --out DIR [--noise 0.01] [--jobs 2]":  # 100 tables: 3.5 GB
        "brdfpipe synth --count 2 --seed 2016 --out {tmp}/db --noise 0.01 --jobs 2",
    "brdfpipe synth --count 100 --seed 2016": _SYNTH_SMALL,
    "brdfpipe synth --count 100 --seed 2016 --out /tmp/realism/synth": _SYNTH_SMALL,
    "brdfpipe nbrdf ARCHIVE --out DIR [NAME ...]":
        "brdfpipe nbrdf src/brdfpipe/data/archives/nielsen_nbrdf.zip --out {tmp}/fits greencloth",
    "brdfpipe nbrdf merl-nbrdf --out DIR [NAME ...]": "brdfpipe nbrdf merl-nbrdf --out {tmp}/fits teflon",
    "brdfpipe nbrdf src/brdfpipe/data/archives/merl_nbrdf.zip --out /tmp/realism/merl-nbrdf":  # all 100: 3.5 GB
        "brdfpipe nbrdf src/brdfpipe/data/archives/merl_nbrdf.zip --out {tmp}/realism/merl-nbrdf teflon",
    "brdfpipe ingest DIR --out results/merl.zarr [--jobs 2]":
        f"{_SYNTH_SMALL} && brdfpipe ingest {{tmp}}/synth --out {{tmp}}/merl.zarr --jobs 2",
    "brdfpipe info results/merl.zarr [--no-verify]": "brdfpipe info results/merl.zarr",
    "brdfpipe info --no-verify": "brdfpipe info --no-verify results/merl.zarr",
    "brdfpipe reconstruct OBS.csv --model results/svd/train.zarr --out material.binary [--eta 40]":
        "brdfpipe reconstruct {obs} --model results/svd/train.zarr --out {tmp}/material.binary --eta 40",
    "brdfpipe interpolate --model results/gplvm/standardised-mu1e-05/q5.npz (--at x1,…,xq | --between A B "
    "[--t 0.5]) --out material.binary":
        f"brdfpipe interpolate --model {MODEL} --between {{a}} {{b}} --t 0.5 --out {{tmp}}/m.binary && "
        f"brdfpipe interpolate --model {MODEL} --at 0,0,0,0,0 --out {{tmp}}/m0.binary",
    "brdfpipe nearest --model M (--at x1,…,xq | --material NAME) [-k 5]":
        f"brdfpipe nearest --model {MODEL} --material {{a}} -k 5 && brdfpipe nearest --model {MODEL} --at 0,0,0,0,0",
    "brdfpipe extrapolate --model M --store results/merl.zarr --from A --through B [--step 0.05 --max-s 3] "
    "[--out last.binary]":
        f"brdfpipe extrapolate --model {MODEL} --store results/merl.zarr --from {{a}} --through {{b}} --step 0.05 "
        "--max-s 3 --out {tmp}/last.binary",
    "brdfpipe sample --model M --store results/merl.zarr --seed 0 --count 4 --out-dir DIR":
        f"brdfpipe sample --model {MODEL} --store results/merl.zarr --seed 0 --count 4 --out-dir {{tmp}}/samples",
    "brdfpipe render material.binary --out image.exr [--spp 64] [--resolution 256 192] [--variant llvm_ad_rgb]":
        "brdfpipe render {material} --out {tmp}/image.exr --spp 4 --resolution 32 24 --variant llvm_ad_rgb",
    "brdfpipe render MATERIAL.binary --out image.exr": "brdfpipe render {material} --out {tmp}/image.exr",
    "brdfpipe capture material.binary results/directions/train/nearfield-fov25-error.json --out DIR [--n 1 2] "
    "[--model results/svd/train.zarr]":
        f"brdfpipe capture {{material}} {DIRECTIONS} --out {{tmp}}/capture --n 1 2 --model results/svd/train.zarr",
    # -- the modules the docs run with python -m -------------------------------------------------------
    'python -m brdfpipe.acquisition.realism measure /tmp/realism/merl-nbrdf --note "MERL (NBRDF fit)" '
    "--out merl.json": f"{_FITS_TWO} && python -m brdfpipe.acquisition.realism measure {{tmp}}/realism/merl-nbrdf "
                       '--note "MERL (NBRDF fit)" --out {tmp}/merl.json',
    'python -m brdfpipe.acquisition.realism measure /tmp/realism/synth --note "before (c461497)" --out before.json':
        f"{_SYNTH_SMALL} && python -m brdfpipe.acquisition.realism measure {{tmp}}/synth "
        '--note "before (c461497)" --out {tmp}/before.json',
    "python -m brdfpipe.acquisition.realism table before.json narrow.json adopted.json merl.json":
        f"{_SYNTH_SMALL} && {_FITS_TWO} && "
        + " && ".join(f"python -m brdfpipe.acquisition.realism measure {{tmp}}/{src} --out {{tmp}}/{name}.json"
                      for name, src in (("before", "synth"), ("narrow", "synth"), ("adopted", "synth"),
                                        ("merl", "realism/merl-nbrdf")))
        + " && cd {tmp} && python -m brdfpipe.acquisition.realism table before.json narrow.json adopted.json merl.json",
    # the fidelity page from the recorded runs' claims (docs/results/fidelity.md heads itself with this command):
    # made again here, it is the page in the repository byte for byte
    "python -m brdfpipe.report.sidebyside src/brdfpipe/report/recorded/2026-11-29-cpu-merl-nbrdf.csv "
    "src/brdfpipe/report/recorded/2026-11-29-cpu-synthetic.csv --out docs/results/fidelity.md":
        "python -m brdfpipe.report.sidebyside src/brdfpipe/report/recorded/2026-11-29-cpu-merl-nbrdf.csv "
        "src/brdfpipe/report/recorded/2026-11-29-cpu-synthetic.csv --out docs/results/fidelity.md "
        "&& cmp docs/results/fidelity.md {root}/docs/results/fidelity.md",
}


def test_every_documented_command_has_a_runner() -> None:
    documented = documented_commands()
    missing = {c: f for c, f in documented.items() if c not in RUNNERS}
    assert not missing, f"documented commands without a runner in tests/test_documented_commands.py: {missing}"
    stale = sorted(set(RUNNERS) - set(documented))
    assert not stale, f"runners of commands no document shows any more: {stale}"


def test_the_collector_finds_commands_in_blocks_inline_and_across_lines(tmp_path: Path) -> None:
    assert _is_command("make run") and _is_command("brdfpipe info results/merl.zarr")
    assert not _is_command("brdfpipe info") and not _is_command("brdfpipe.data.nbrdf")
    assert not _is_command("python -m http.server -d results/explorer") and not _is_command("makefile")
    assert "make report" in documented_commands()  # inline, in README.md
    joined = ("snakemake --cores 2 --configfile config/config.yaml overlay.yaml -- "
              "results/errormaps/preview-48x36-4096spp/floor-check.csv results/explorer")
    assert joined in documented_commands()  # a code block's line continued with a backslash


def _checkout(tmp_path: Path, base: Path) -> Path:
    """A folder that looks like this checkout (links; a copy of ``docs``, which commands write) with a
    private copy of a run's results."""
    work = copy_run(base, tmp_path / "checkout")
    for name in ("workflow", "config", "src", "tests", "profiles", "benches", "Makefile", "pyproject.toml", ".venv"):
        if not (work / name).exists():
            (work / name).symlink_to(ROOT / name)
    if not (work / "docs").exists():
        shutil.copytree(ROOT / "docs", work / "docs")
    return work


#: make never reinstalls the virtual environment from a test (its stamps count as up to date): the checkout's
#: ``.venv`` is this one's.
_MAKE = "make -o .venv/.brdfpipe-installed -o .venv/slurm-plugins/.installed "


def _run(command: str, cwd: Path, **fill: str) -> subprocess.CompletedProcess[str]:
    command = re.sub(r"(^|&& )make ", lambda m: m.group(1) + _MAKE, command)
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}"}
    env.pop("PYTHONPATH", None)  # the checkout's own library, as a user runs it (the venv's editable install)
    return subprocess.run(["bash", "-eo", "pipefail", "-c", command.format(**fill)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def checkout(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _checkout(tmp_path_factory.mktemp("documented"), shared_run(tmp_path_factory, TINY))


def _observations(table: Path, out: Path) -> Path:
    """A CSV of 400 measured cells of a MERL table (theta_h, theta_d, phi_d in degrees; sr⁻¹)."""
    from brdfpipe.data import merl

    rho = merl.read_merl(table).reshape(3, -1)
    th, td, pd = (np.degrees(a).ravel() for a in merl.cell_centres())
    cells = np.flatnonzero(merl.measured_mask().ravel() & (rho.min(axis=0) >= 0))
    pick = np.random.default_rng(0).choice(cells, 400, replace=False)
    rows = np.column_stack([th[pick], td[pick], pd[pick], rho[:, pick].T])
    np.savetxt(out, rows, delimiter=",", header="theta_h,theta_d,phi_d,r,g,b", comments="")
    return out


@pytest.mark.parametrize("documented", sorted(c for c, r in RUNNERS.items() if r != _REPORT),
                         ids=lambda c: re.sub(r"[^\w.=-]+", "_", c)[:70])
def test_documented_command_runs(documented: str, checkout: Path, tmp_path: Path) -> None:
    command = RUNNERS[documented]
    if documented == "make clean":  # in a checkout of its own: it removes results/
        cwd = _checkout(tmp_path / "own", checkout)
    else:
        cwd = checkout
    materials = sorted(p.stem for p in (checkout / "results" / "synthetic").glob("*.binary"))
    table = checkout / "results" / "synthetic" / f"{materials[0]}.binary"
    fill = {"tmp": str(tmp_path), "a": materials[0], "b": materials[3], "material": str(table), "obs": "",
            "root": str(ROOT)}
    if "{obs}" in command:
        fill["obs"] = str(_observations(table, tmp_path / "obs.csv"))
    r = _run(command, cwd, **fill)
    assert r.returncode == 0, f"{documented!r} ran as {command.format(**fill)!r}:\n{(r.stdout + r.stderr)[-4000:]}"
    assert "Traceback" not in r.stderr, r.stderr[-4000:]


def test_the_report_commands(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> None:
    """``make report`` and ``snakemake --report`` on a finished run of fits (they failed at parse time there:
    a rule sized its threads from the cores that a report does not give)."""
    work = _checkout(tmp_path, shared_run(tmp_path_factory, TINY_NBRDF))
    r = _run("make report CONFIG=tests/config/tiny-nbrdf.yaml", work)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    assert (work / "results" / "report.zip").stat().st_size > 100_000
    r = _run("snakemake --configfile tests/config/tiny-nbrdf.yaml --unlock", work)
    assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
