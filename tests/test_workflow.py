"""The Snakemake workflow on the tiny config: lint, dry-run, a real run, bad config.

These run the real ``snakemake`` of the virtual environment in a scratch working
directory (``--directory``), so the repository's own ``results/`` is untouched.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from brdfpipe.core import filenames, integrity
from brdfpipe.data import merl, store
from shared_runs import copy_run, shared_run

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "workflow" / "Snakefile"
TINY = ROOT / "tests" / "config" / "tiny.yaml"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")

pytestmark = pytest.mark.slow


def snakemake(workdir: Path, *args: str, configfile: Path = TINY) -> subprocess.CompletedProcess:
    cmd = [
        str(SNAKEMAKE), "--snakefile", str(SNAKEFILE), "--directory", str(workdir),
        "--configfile", str(configfile), "--cores", "2", *args,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=workdir, timeout=900)


def write_config(path: Path, **overrides: object) -> Path:
    cfg = yaml.safe_load(TINY.read_text())
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(cfg.get(key), dict):
            cfg[key] = {**cfg[key], **value}
        else:
            cfg[key] = value
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_lint_is_clean(tmp_path: Path) -> None:
    r = snakemake(tmp_path, "--lint")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Congratulations" in r.stdout + r.stderr, r.stdout + r.stderr


def test_the_shipped_config_plans_without_warnings(tmp_path: Path) -> None:
    """make run's default (merl-nbrdf, no synthetic manifest): a dry run plans it and warns about nothing."""
    r = snakemake(tmp_path, "-n", "--quiet", "rules", configfile=ROOT / "config" / "config.yaml")
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert "evaluate_fits" in out and "write_manifest" not in out
    assert "not present" not in out and "warning" not in out.lower(), out[-3000:]
    assert not (tmp_path / "results").exists()


def test_dry_run_plans_one_job_per_material(tmp_path: Path) -> None:
    r = snakemake(tmp_path, "-n", "--quiet", "rules")
    assert r.returncode == 0, r.stderr
    out = r.stdout + r.stderr
    for rule, n in [("synthesize_material", 12), ("ingest_material", 12), ("assemble_store", 1),
                    ("write_splits", 1), ("write_manifest", 1), ("map_logrelative", 2),
                    ("accumulate_gram", 8), ("decompose_svd", 2), ("optimize_directions", 10),
                    ("evaluate_directions", 1), ("evaluate_training_size", 1), ("check_directions", 2),
                    ("evaluate_paper_directions", 1),  # Xu §6's one-shot direction (tiny: FOV 25° only)
                    ("plot_acquisition_figures", 1),
                    # the closed loop: one capture per held-out material, one evaluation, one figure
                    ("capture_closedloop", 3), ("evaluate_closedloop", 1), ("plot_closedloop", 1),
                    # Xu Figs. 2, 15: each held-out material reconstructed and rendered, one figure job
                    ("reconstruct_figure_material", 3), ("render_reconstructions", 3),
                    ("plot_reconstruction_figures", 1),
                    ("compute_gram", 2), ("fit_gplvm", 4), ("measure_material_albedos", 1), ("analyze_manifold", 1),
                    ("measure_gplvm_candidate", 2), ("compare_spaces", 1),
                    ("measure_lengthscales", 1),  # Soler Fig. 6
                    ("make_envmap", 1), ("interpolate_path_points", 1),
                    # Soler Fig. 1: the latent samples drawn in one job, rendered in one
                    ("sample_latent_materials", 1), ("render_latent_samples", 1),
                    # pre-renders: 12 materials in 2 batches of 6 (materials_per_job 10), both scene folders
                    ("prerender_materials_b00", 1), ("prerender_materials_b01", 1),
                    ("render_path_points", 1), ("error_maps", 1), ("render_object_mask", 1),
                    ("bounce_shares", 1),
                    # the noise-floor check: both candidates' path points, every material again
                    ("interpolate_candidate_path_points", 2), ("render_candidate_path_points", 2),
                    ("measure_candidate_blends", 2), ("summarize_floor_check", 1), ("plot_floor_check", 1)]:
        assert any(line.split()[:2] == [rule, str(n)] for line in out.splitlines()), out


def test_tiny_run_builds_a_valid_store(tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    # the session's one run of tiny (tests/shared_runs.py; test_resume.py copies it too), copied: the
    # report below is built in the run folder
    copy_run(shared_run(tmp_path_factory, TINY), tmp_path)
    g = store.open_store(tmp_path / "results" / "merl.zarr")
    assert g.database == "synthetic"
    names = list(g.materials)
    assert len(names) == 12 and g.brdf.shape == (12, 3 * merl.N_CELLS)
    # ingest == direct read of the generated files (two rows suffice here; test_store covers all)
    for row in (0, 11):
        direct = merl.read_merl(tmp_path / "results" / "synthetic" / f"{names[row]}.binary")
        assert np.array_equal(g.brdf[row], direct.reshape(-1).astype(np.float32))
    splits = json.loads((tmp_path / "results" / "splits.json").read_text())
    assert len(splits["test"]) == 3 and len(splits["train"]) == 9
    assert sorted(splits["test"] + splits["train"]) == sorted(names)
    manifest = json.loads((tmp_path / "results" / "synthetic" / "manifest.json").read_text())
    assert sorted(splits["test"]) == sorted(manifest["test_materials"])
    assert all(0 < m["params"]["energy_scale"] <= 1 for m in manifest["materials"])
    # per-material ingest rows are temporary and gone; logs and benchmarks exist
    assert not list((tmp_path / "results").glob("ingest/*.zarr"))
    assert (tmp_path / "logs" / "assemble_store.log").stat().st_size > 0
    assert len(list((tmp_path / "benchmarks" / "ingest_material").glob("*.tsv"))) == 12
    # acquisition track: models of both splits, direction sets of every setup
    from brdfpipe.acquisition import optimize, svd

    model = svd.open_model(tmp_path / "results" / "svd" / "train.zarr")
    assert model.database == "synthetic" and model.m == 27
    files = sorted((tmp_path / "results" / "directions" / "train").glob("*.json"))
    # every set-up × metric of tiny.yaml (fov 0 for point samples), Nielsen's κ for point samples only
    expect = [f"point-fov0-{m}.json" for m in ("error", "condition", "condition_nielsen")]
    expect += [f"{s}-fov25-{m}.json" for s in ("nearfield", "fixed_camera", "fixed_light") for m in ("error", "condition")]
    assert sorted(f.name for f in files) == sorted(expect)
    for f in files:
        d = optimize.read_directions(f)
        assert [s.n for s in d.sets] == list(range(1, len(d.sets) + 1))
    assert (tmp_path / "results" / "directions" / "all" / "nearfield-fov25-error.json").is_file()
    # evaluation: every predicted E(S) matched its direct recomputation (else the rule fails)

    rows = integrity.read_csv_rows(tmp_path / "results" / "evaluation" / "consistency-train.csv")[1]
    # one row per (file, n): point 3 + three image setups x 2, for both metrics; Nielsen's κ: point only
    assert len(rows) == 2 * (3 + 3 * 2) + 3
    assert all(float(r["rel_diff"]) <= 1e-6 for r in rows)
    errors = integrity.read_csv_rows(tmp_path / "results" / "evaluation" / "errors.csv")[1]
    assert {r["database"] for r in errors} == {"synthetic"}
    assert {r["kind"] for r in errors} == {"rms_log", "relrms_linear", "deviation"}
    figures = sorted(p.name for p in (tmp_path / "results" / "figures").iterdir())
    # Xu's (Figs. 2, 3, 8, 9, 14, 15 with their tables), Soler's, the renders', the closed loop's, the floor check's;
    # + Soler Figs. 1 and 6 (PNG, PDF and note each) and the notes of Figs. 12 and 13
    assert len(figures) == 36 + 16 + 6 + 2 + 2 + 8 and "fig05-error-vs-images.png" in figures
    assert "closedloop-vs-table.png" in figures
    # the closed loop: every held-out material photographed by the 25° sets of 1 and 2 images
    closed = integrity.read_csv_rows(tmp_path / "results" / "evaluation" / "closedloop.csv")[1]
    assert list(closed[0]) == list(errors[0]) and {r["database"] for r in closed} == {"synthetic"}
    assert {r["material"] for r in closed} == set(splits["test"]) | {"mean"}
    assert {r["kind"] for r in closed} >= {"rms_log", "closedloop_rms_log", "closedloop_noiseless_rms_log"}
    for m in splits["test"]:
        shots = sorted(p.name for p in (tmp_path / "results" / "closedloop" / m).glob("*.exr"))
        assert len(shots) == 2 * (1 + 2), shots
    assert "render-floor-check.png" in figures
    assert "manifold-spaces.png" in figures
    assert "manifold-fig09-paths.pdf" in figures and "render-fig13-errors.png" in figures
    # manifold track: one GPLVM fit per candidate (data space, mu) and latent dimension, with its trace
    from brdfpipe.manifold import gplvm

    for cand, space in (("standardised-mu1e-06", "standardised"), ("raw-mu0.0001", "raw")):
        for q in (2, 5):
            fit = gplvm.load_model(tmp_path / "results" / "gplvm" / cand / f"q{q}.npz")
            assert fit.X.shape == (12, q) and list(fit.names) == names and fit.space == space
            trace = integrity.read_csv_text(tmp_path / "results" / "gplvm" / cand / f"q{q}-trace.csv").splitlines()
            assert trace[0] == "step,stage,log_likelihood" and len(trace) > 2
    spaces = integrity.read_csv_rows(tmp_path / "results" / "manifold" / "spaces.csv")[1]
    assert sorted((r["candidate"], r["q"], r["default"]) for r in spaces) == [
        ("raw-mu0.0001", "2", "false"), ("raw-mu0.0001", "5", "false"),
        ("standardised-mu1e-06", "2", "true"), ("standardised-mu1e-06", "5", "true")]
    assert all(0.0 <= float(r["albedo_bad_hull"]) <= 1.0 for r in spaces)
    # manifold analyses: three seeded paths of path_steps + 1 points, exact ends
    rows = integrity.read_csv_rows(tmp_path / "results" / "manifold" / "paths.csv")[1]
    assert len(rows) == 3 * 5 and {r["database"] for r in rows} == {"synthetic"}
    ends = [r for r in rows if r["step"] in ("0", "4")]
    assert all(float(r["deviation"]) <= 1e-6 * max(float(x["deviation"]) for x in rows) for r in ends)
    # rendering track: every material pre-rendered, every path point rendered twice, error maps
    renders = tmp_path / "results" / "renders" / "preview"
    assert sorted(p.stem for p in (renders / "materials").glob("*.exr")) == sorted(names)
    assert len(list((renders / "paths").glob("*-t0.5-noise.exr"))) == 3
    summary = integrity.read_csv_rows(tmp_path / "results" / "errormaps" / "preview" / "summary.csv")[1]
    assert len(summary) == 3 and all(float(r["rmse_noise"]) > 0 for r in summary)
    assert all(float(r["rmse_noise_one"]) > 0 and float(r["ratio_one_seed2"]) > 0 for r in summary)
    # the I¹⁻ part of every render, and the I²⁺ share of every material
    assert sorted(p.stem for p in (renders / "materials-one").glob("*.exr")) == sorted(names)
    assert len(list((renders / "paths").glob("*-t0.5-one-noise.exr"))) == 3
    shares = integrity.read_csv_rows(renders / "bounce-shares.csv")[1]
    assert sorted(r["material"] for r in shares) == sorted(names)
    assert all(-1e-3 <= float(r["share_image"]) < 0.5 and int(r["object_pixels"]) > 0 for r in shares)
    check_floor(tmp_path, names)
    # the Snakemake report of this run: every declared figure with its caption, the claims (test_report.py)
    from test_report import check_tiny_report

    check_tiny_report(tmp_path, snakemake)
    # a second run has nothing to do
    again = snakemake(tmp_path, "-n")
    assert again.returncode == 0 and "Nothing to be done" in again.stdout + again.stderr


def check_floor(workdir: Path, names: list[str]) -> None:
    """The tiny run's noise-floor check: both candidates, every path point, ratios recomputed from the images."""
    from brdfpipe.core.exr import read_exr, read_exr_attrs

    floor = workdir / "results" / "renders" / "preview-16x12-64spp"
    assert sorted(p.stem for p in (floor / "materials-one").glob("*.exr")) == sorted(names)
    rows = integrity.read_csv_rows(workdir / "results" / "errormaps" / "preview-16x12-64spp" / "floor-check.csv")[1]
    assert sorted({(r["candidate"], r["default"]) for r in rows}) == [
        ("raw-mu0.0001", "0"), ("standardised-mu1e-06", "1")]
    assert len(rows) == 2 * 3 and {r["database"] for r in rows} == {"synthetic"}
    assert {(r["width"], r["height"], r["spp"]) for r in rows} == {("16", "12", "64")}
    ones = np.stack([read_exr(floor / "materials-one" / f"{m}.exr").astype(np.float64) for m in names])
    for r in rows:
        base = floor / "paths" / r["candidate"] / f"{r['path']}-t{r['t']}"
        doc = json.loads(Path(f"{base}-weights.json").read_text())
        w = np.array([doc["weights"][m] for m in names])
        assert float(r["sum_abs_w"]) == pytest.approx(np.abs(w).sum(), rel=1e-8)
        assert float(r["clamped_fraction"]) == pytest.approx(doc["clamped"] / doc["measured_values"], rel=1e-8)
        assert read_exr_attrs(f"{base}-one-noise.exr")["spp"] == "64"
        # I¹⁻ blend vs the second seed's I¹⁻ reference, over the floor between the two references
        ref, ref2 = (read_exr(f"{base}{k}.exr").astype(np.float64) for k in ("-one", "-one-noise"))
        blend = np.tensordot(w, ones, axes=1)
        rmse = lambda a, b: np.sqrt(np.mean((a - b) ** 2)) / ref.mean()  # noqa: E731
        assert float(r["ratio_one_seed2"]) == pytest.approx(rmse(blend, ref2) / rmse(ref, ref2), rel=1e-4)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"test_materials": ["no-such-material"]}, "unknown material"),
        ({"render": {"floor_check": {"candidates": "some"}}}, "render.floor_check.candidates = 'some': must be one of"),
        ({"render": {"floor_check": {"spp": 0}}}, "render.floor_check.spp = 0: must be ≥ 1"),
        ({"synthetic": {"count": 0}}, "synthetic.count = 0: must be ≥ 1"),
        ({"colour": "red"}, "config colour: unknown key"),
        ({"render": {"resolutoin": [3, 4]}}, "render.resolutoin: unknown key; did you mean 'resolution'?"),
        ({"render": {"spp": "1e5"}}, "render.spp = '1e5': must be an integer"),
        ({"acquisition": {"fovs": [25, 25]}}, "acquisition.fovs: 25 is listed more than once"),
        ({"materials": []}, "config materials: must not be empty"),
        ({"database": "merl", "merl_dir": "/nonexistent/merl"}, "does not exist"),
        ({"merl_dir": "/some/folder"}, "merl_dir is set but database is 'synthetic'; set database: merl"),
        ({"database": "merl"}, "database: merl reads a folder of MERL files: set merl_dir"),
        ({"database": "nbrdf"}, "database: nbrdf reads your archive of NBRDF fits: set nbrdf_archive"),
        ({"database": "nbrdf", "nbrdf_archive": "/no/such.zip"}, "nbrdf_archive: /no/such.zip: no such archive"),
        ({"database": "mit"}, "config database = 'mit': must be one of"),
        ({"acquisition": {"setups": ["gonioreflectometer"]}}, "acquisition.setups[0] = 'gonioreflectometer': must be one of"),
        ({"acquisition": {"fovs": [0]}}, "acquisition.fovs[0] = 0: must be > 0"),
        ({"acquisition": {"fovs": [90]}}, "acquisition.fovs[0] = 90: must be < 90"),
        ({"acquisition": {"n_max_images": 0}}, "acquisition.n_max_images = 0: must be ≥ 1"),
        ({"acquisition": {"eta": 0}}, "acquisition.eta = 0: must be ≥ 1e-06"),
        ({"manifold": {"latent_dims": [0]}}, "manifold.latent_dims[0] = 0: must be ≥ 1"),
        ({"manifold": {"ell": 0}}, "manifold.ell = 0: must be ≥ 1e-06"),
        ({"manifold": {"mu": -1e-4}}, "manifold.mu = -0.0001: must be ≥ 1e-10"),
        ({"manifold": {"paths": [["no-such-material", "other"]]}}, "unknown material 'no-such-material'"),
        ({"manifold": {"path_q": 3}}, "is not one of manifold.latent_dims"),
        ({"manifold": {"clamped_hull_points": 0}}, "manifold.clamped_hull_points = 0: must be ≥ 1"),
        ({"manifold": {"clamped_hull_points": 20001}}, "manifold.clamped_hull_points = 20001: must be ≤ 20000"),
        ({"render": {"variant": "scalar_spectral"}}, "render.variant = 'scalar_spectral': must be one of"),
        ({"render": {"noise_seed": 0}}, "must differ from render.seed"),
        ({"render": {"materials_per_job": 0}}, "render.materials_per_job = 0: must be ≥ 1"),
        ({"render": {"materials_per_job": 2.5}}, "render.materials_per_job = 2.5: must be an integer"),
        ({"manifold": {"ell": float("nan")}}, "manifold.ell"),
        ({"manifold": {"mu": float("inf")}}, "manifold.mu"),
        ({"acquisition": {"eta": float("nan")}}, "acquisition.eta"),
        ({"manifold": {"latent_dims": [2, 12]}}, "below the number of materials"),
        ({"acquisition": {"training_sizes": [3, 50]}}, "acquisition.training_sizes"),
        ({"render": {"path_points": [0.1234561, 0.1234562]}}, "render.path_points"),
        ({"closed_loop": {"n_images": [3]}}, "closed_loop.n_images"),
        ({"database": "merl", "merl_dir": ""}, "merl_dir: empty path"),
        ({"materials": ["no-such-*"]}, "materials: 'no-such-*' match"),
        ({"acquisition": {"screen_grid": 16}}, "acquisition.screen_grid = 16: must be below acquisition.grid (12)"),
        ({"render": {"envmap": {"width": 100000, "height": 50000}}}, "render.envmap.width × height = 5,000,000,000"),
        ({"closed_loop": {"sensor": {"enabled": True, "brackets": [2, 8]}}}, "closed_loop.sensor.brackets"),
        ({"report": {"compare_with": ["no/such/claims.csv"]}}, "report.compare_with[0] = 'no/such/claims.csv': no such file"),
        ({"report": {"compare_with": [str(ROOT / "README.md")]}}, "README.md': not a run's claims.csv"),
    ],
)
def test_bad_config_fails_before_any_job(tmp_path: Path, overrides: dict, message: str) -> None:
    cfg = write_config(tmp_path / "bad.yaml", **overrides)
    r = snakemake(tmp_path, "-n", configfile=cfg)
    assert r.returncode != 0
    out = r.stdout + r.stderr
    assert message in out
    # one line naming the key: no schema dump, no traceback (Snakemake adds its header and the Snakefile line)
    assert "Failed validating" not in out and "Traceback" not in out and len(out.splitlines()) <= 5, out
    assert not (tmp_path / "results").exists()


def three_merl_files_one_truncated(tmp_path: Path, keep: int | None = None) -> tuple[Path, Path, bytes]:
    """A folder of three measured-looking MERL files, ``beta`` cut to ``keep`` bytes (half of it by default), and a
    config of ``database: merl`` on it; returns the folder, the config and beta's whole bytes."""
    folder = tmp_path / "merl"
    folder.mkdir()
    table = np.full(merl.SHAPE, 0.1)
    table[:, ~merl.measured_mask()] = -1.0
    for name in ("alpha", "beta", "gamma"):
        merl.write_merl(folder / f"{name}.binary", table)
    good = (folder / "beta.binary").read_bytes()
    (folder / "beta.binary").write_bytes(good[: len(good) // 2 if keep is None else keep])  # truncated
    cfg = write_config(tmp_path / "merl.yaml", database="merl", merl_dir=str(folder), test_materials=["alpha"],
                       manifold={"latent_dims": [2]}, acquisition={"training_sizes": [2]})  # 3 materials
    return folder, cfg, good


def test_corrupt_merl_file_fails_the_run_and_leaves_no_store(tmp_path: Path) -> None:
    folder, cfg, good = three_merl_files_one_truncated(tmp_path)
    r = snakemake(tmp_path, "--keep-going", configfile=cfg)
    assert r.returncode != 0
    log = (tmp_path / "logs" / "ingest_material" / "beta.log").read_text()
    assert "beta.binary" in log and "truncated" in log
    assert not (tmp_path / "results" / "merl.zarr").exists()
    assert not (tmp_path / "results" / "ingest" / "beta.zarr").exists()
    # repair the file: the rerun completes and the store is trusted
    (folder / "beta.binary").write_bytes(good)
    r = snakemake(tmp_path, "results/merl.zarr", configfile=cfg)  # the data stage
    assert r.returncode == 0, r.stderr[-3000:]
    g = store.open_store(tmp_path / "results" / "merl.zarr")
    assert g.database == "merl" and list(g.materials) == ["alpha", "beta", "gamma"]
    shutil.rmtree(tmp_path / "results")


def test_dry_run_console_shows_the_job_stats_not_each_jobs_record(tmp_path: Path) -> None:
    """The console is for people (issue 34): a dry run lists the job counts, not every job's record."""
    r = snakemake(tmp_path, "-n")
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert "Job stats:" in out and "synthesize_material" in out and "This was a dry-run" in out
    for record in ["jobid:", "    output:", "reason:", "Shell command", "Snakemake version:"]:
        assert record not in out, f"{record!r} on the console:\n{out[:3000]}"
    r = snakemake(tmp_path, "-n", "--verbose")  # everything, when asked
    assert r.returncode == 0 and "jobid:" in r.stdout + r.stderr


def test_failed_job_console_shows_progress_error_and_log_not_records(tmp_path: Path) -> None:
    """A run's console: progress, then the failed job's error with its log path and log; records in .snakemake/log/."""
    _, cfg, _ = three_merl_files_one_truncated(tmp_path, keep=1000)
    r = snakemake(tmp_path, "--keep-going", filenames.store(), configfile=cfg)
    out = r.stdout + r.stderr
    assert r.returncode != 0
    assert "2 of 4 steps (50%) done" in out and "(Rule: ingest_material)" in out, out[-3000:]
    assert "Error in rule ingest_material:" in out and "logs/ingest_material/beta.log" in out, out[-3000:]
    assert "truncated" in out  # the log itself (show-failed-logs)
    for record in ["reason:", "Execute 1 jobs", "Shell command", "Snakemake version:", "brdfpipe: the run"]:
        assert record not in out, f"{record!r} on the console:\n{out[-3000:]}"
    complete = "".join(p.read_text() for p in (tmp_path / ".snakemake" / "log").glob("*.snakemake.log"))
    assert "rule ingest_material:" in complete and "reason:" in complete and "Finished jobid" in complete


def declared_outputs(configfile: Path) -> set[str]:
    """The files rule all asks for under ``configfile``, from brdfpipe.plan (as the Snakefile does)."""
    from brdfpipe import plan

    cfg = yaml.safe_load(configfile.read_text())
    files = {f for figs in (plan.acquisition_figures(cfg["acquisition"]), plan.reconstruction_figures(cfg["acquisition"]),
                            plan.manifold_figures(cfg["manifold"]))
             for fs in figs.values() for f in fs}
    if plan.closedloop_directions(cfg):
        files |= set(filenames.figure_files(filenames.CLOSEDLOOP_STEM))
    return files


@pytest.mark.parametrize("shape", ["tiny-point", "tiny-nearfield"])
def test_other_dag_shapes_run_end_to_end(tmp_path: Path, tmp_path_factory: pytest.TempPathFactory,
                                         shape: str) -> None:
    """Schema-valid configs of other DAG shapes build every output they declare (no MissingOutputException).

    tiny-point: point samples and the error metric only, log space with q = 1, no
    rendered path point; tiny-nearfield: near-field and the condition metric only,
    cosine space with q = 3. On tiny-point, an edit of one library module then
    plans exactly the jobs that run it and what depends on them; the tiny-point run is the
    session's shared one (built with this checkout's library, checked here with a private copy
    of it: the code digests depend on the code, not on where it lives).
    """
    from brdfpipe import plan

    config = ROOT / "tests" / "config" / f"{shape}.yaml"
    cfg = yaml.safe_load(config.read_text())
    # the library under test is a private copy, so that it can be edited below
    pkg = tmp_path / "pkg"
    shutil.copytree(ROOT / "src" / "brdfpipe", pkg / "brdfpipe", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(pkg)}
    work = tmp_path / "work"
    if shape == "tiny-point":
        # the session's one run of tiny-point, which the Slurm test compares with (tests/shared_runs.py);
        # copied, since the stale-results check below must not touch the shared folder
        shutil.copytree(shared_run(tmp_path_factory, config), work, symlinks=True)
    else:
        work.mkdir()
    cmd = [str(SNAKEMAKE), "--snakefile", str(SNAKEFILE), "--directory", str(work), "--configfile", str(config),
           "--cores", "2"]
    if shape != "tiny-point":
        start = time.monotonic()
        r = subprocess.run([*cmd, "--verbose"], capture_output=True, text=True, cwd=work, env=env, timeout=900)
        seconds = time.monotonic() - start
        assert r.returncode == 0, r.stderr[-4000:]
        # Snakemake's rate limiter ended every scheduling round with a timer for another one and each finished
        # job started a round, so the rounds grew with jobs x seconds (5,931 for the 98 jobs of a tiny run), each
        # stat()ing every waiting job's inputs; with one pending timer (workflow/rules/common.smk), about one
        # round per finished job and one per second
        out = r.stdout + r.stderr
        finished = out.count("Finished jobid")
        rounds = sum(line.startswith("Ready jobs") for line in out.splitlines())  # rounds with jobs to choose
        assert 0 < rounds <= 2 * (finished + seconds) + 10, f"{rounds} rounds for {finished} jobs in {seconds:.0f} s"
    figures = {p.relative_to(work).as_posix() for p in (work / "results" / "figures").iterdir()}
    samples = cfg["render"].get("latent_samples", {}).get("count", 11)  # the schema's default: Soler Fig. 1's 11
    render = {f for fs in plan.render_figures(len(cfg["render"]["path_points"]), samples).values() for f in fs}
    floor_checked = cfg["render"]["floor_check"]["candidates"] != "none"  # tiny-nearfield: default; tiny-point: none
    assert floor_checked == (shape == "tiny-nearfield")
    if floor_checked:
        render |= set(filenames.figure_files(filenames.FLOOR_CHECK_STEM))
        (table,) = (work / "results" / "errormaps").glob("*/floor-check.csv")
        rows = integrity.read_csv_rows(table)[1]
        assert len(rows) == len(cfg["manifold"]["paths"]) * len(cfg["render"]["path_points"])  # the default candidate
    assert figures == declared_outputs(config) | render
    assert store.open_store(work / "results" / "merl.zarr").database == "synthetic"
    assert (work / "results" / "evaluation" / "errors.csv").is_file()
    assert not (work / "results" / "evaluation" / "training_size.csv").exists()  # neither shape has the curve
    if shape == "tiny-point":
        assert not (work / "results" / "errormaps").exists()
        assert not list((work / "results" / "manifold").glob("albedo-map-*.npz"))
    else:
        assert len(integrity.read_csv_rows(work / "results" / "errormaps" / "preview" / "summary.csv")[1]) == 1
    again = subprocess.run([*cmd, "-n"], capture_output=True, text=True, cwd=work, env=env, timeout=300)
    assert again.returncode == 0 and "Nothing to be done" in again.stdout + again.stderr
    if shape != "tiny-point":
        return
    # Stale results: an edit of svd.py replans the jobs that run it and their dependents, nothing else.
    svd_py = pkg / "brdfpipe" / "acquisition" / "svd.py"
    svd_py.write_text(svd_py.read_text() + "\n# an edit\n")
    plan_run = subprocess.run([*cmd, "-n", "--quiet", "rules"], capture_output=True, text=True, cwd=work, env=env,
                              timeout=300)
    assert plan_run.returncode == 0, plan_run.stderr[-3000:]
    planned = {line.split()[0] for line in (plan_run.stdout + plan_run.stderr).splitlines()
               if len(line.split()) == 2 and line.split()[1].isdigit()}
    assert {"accumulate_gram", "decompose_svd", "optimize_directions", "evaluate_directions"} <= planned
    untouched = {"synthesize_material", "write_manifest", "ingest_material", "assemble_store", "write_splits",
                 "map_logrelative", "make_envmap", "prerender_materials", "compute_gram", "fit_gplvm"}
    planned_families = {filenames.rule_family(r) for r in planned}
    assert not planned_families & untouched, planned_families & untouched


@pytest.mark.parametrize("name", ["brace{x}", "with space", "café", "x" * 101, "mean"])
def test_unsafe_material_names_fail_at_parse_naming_the_file(tmp_path: Path, name: str) -> None:
    folder = tmp_path / "merl"
    folder.mkdir()
    table = np.full(merl.SHAPE, 0.1)
    table[:, ~merl.measured_mask()] = -1.0
    for stem in ("alpha", "beta", name):
        merl.write_merl(folder / f"{stem}.binary", table)
    cfg = write_config(tmp_path / "merl.yaml", database="merl", merl_dir=str(folder), test_materials=["alpha"],
                       manifold={"latent_dims": [2]}, acquisition={"training_sizes": [2]})  # 3 materials
    r = snakemake(tmp_path, "-n", configfile=cfg)
    assert r.returncode != 0
    out = r.stdout + r.stderr
    assert "merl_dir" in out and "material name" in out and "Traceback" not in out, out[-2000:]
    assert not (tmp_path / "results").exists()


def test_synth_folder_as_merl_dir_is_labelled_synthetic(tmp_path: Path) -> None:
    """A folder written by `brdfpipe synth` and given as merl_dir: the store says synthetic, like the CLI.

    The folder is read as it is: the workflow does not plan synthesis (or a manifest) of its own for it.
    """
    from brdfpipe import cli

    folder = tmp_path / "db"
    assert cli.main(["-q", "synth", "--count", "3", "--seed", "3", "--out", str(folder), "--jobs", "2"]) == 0
    (folder / "manifest.json").unlink()  # the label comes from the files, not from the manifest
    names = sorted(p.stem for p in folder.glob("*.binary"))
    cfg = write_config(tmp_path / "synth.yaml", database="merl", merl_dir=str(folder), test_materials=names[:1],
                       manifold={"latent_dims": [2]}, acquisition={"training_sizes": [2]})  # 3 materials
    r = snakemake(tmp_path, "results/splits.json", configfile=cfg)
    assert r.returncode == 0, r.stderr[-3000:]
    assert store.open_store(tmp_path / "results" / "merl.zarr").database == "synthetic"
    assert json.loads((tmp_path / "results" / "splits.json").read_text())["test"] == names[:1]
    assert not (tmp_path / "results" / "synthetic").exists()


def test_a_subset_of_materials_plans_jobs_for_those_only(tmp_path: Path) -> None:
    """A `materials` subset of the synthetic database: jobs for those only, and the data stage runs through."""
    from brdfpipe.data import database

    names = database.synthetic_database("x", 12, 7).materials
    subset = [n for n in names if n.startswith(("metal-", "paint-"))]
    cfg = write_config(tmp_path / "subset.yaml", materials=["metal-*", "paint-*"], test_materials=subset[:1],
                       manifold={"latent_dims": [2]}, acquisition={"training_sizes": [2]})
    r = snakemake(tmp_path, "-n", "--quiet", "rules", configfile=cfg)
    assert r.returncode == 0, r.stderr[-3000:]
    out = r.stdout + r.stderr
    assert any(line.split()[:2] == ["ingest_material", str(len(subset))] for line in out.splitlines()), out
    r = snakemake(tmp_path, "results/splits.json", configfile=cfg)  # synthesis, manifest, ingest, store, split
    assert r.returncode == 0, r.stderr[-3000:]
    manifest = json.loads((tmp_path / "results" / "synthetic" / "manifest.json").read_text())
    assert sorted(m["name"] for m in manifest["materials"]) == subset and manifest["count"] == 12
    assert json.loads((tmp_path / "results" / "splits.json").read_text())["materials"] == subset


def test_a_rule_without_a_memory_model_fails_at_parse_naming_it(tmp_path: Path) -> None:
    """The memory check reads Snakemake's own rules: a rule the model lacks is refused before any job, by name."""
    workflow = tmp_path / "workflow"
    shutil.copytree(ROOT / "workflow", workflow)
    report = workflow / "rules" / "report.smk"
    report.write_text(report.read_text() + '''

rule count_claims:
    input:
        claims=fn.claims_csv(),
        stamp=stamp_of("count_claims"),
    output:
        "results/report/claims.count",
    shell:
        "wc -l {input.claims} > {output}"
''')
    cmd = [str(SNAKEMAKE), "--snakefile", str(workflow / "Snakefile"), "--directory", str(tmp_path),
           "--configfile", str(TINY), "--cores", "2", "-n"]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, timeout=900)
    out = r.stdout + r.stderr
    assert r.returncode != 0
    assert "rules without a memory model (brdfpipe.plan.memory.MEMORY_MB): count_claims" in out, out
    assert not (tmp_path / "results").exists()
