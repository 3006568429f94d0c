"""The command line against hostile input: foreign output folders, read-only folders, huge sizes,
Mitsuba's limits, non-finite numbers, corrupt files.  Every error is one line naming the file or
option, exits non-zero, and leaves what was there before as it was.
"""

from __future__ import annotations

import ctypes
import json
import math
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import cli
from brdfpipe.core import atomic
from brdfpipe.data import ingest, merl, store, synth
from brdfpipe.rendering import scene

SRC = Path(__file__).resolve().parents[1] / "src"


def one_line(capsys: pytest.CaptureFixture[str], command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"brdfpipe {command}: error: "), err
    assert "Traceback" not in err[0]
    return err[0]


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def latent_inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Five synthetic materials, their store and a q = 2 GPLVM fit (as test_cli's interpolation test)."""
    from brdfpipe.manifold import gplvm, gram

    d = tmp_path_factory.mktemp("latent")
    synth.synthesize(d / "db", count=5, seed=3, jobs=1, progress=False)
    from brdfpipe.data.database import database_from_folder

    db = database_from_folder(d / "db", key="folder")
    ingest.ingest(db.sources, d / "merl.zarr", database=db.kind, jobs=1)
    gram.write_gram(d / "merl.zarr", d / "gram.npz")
    gplvm.fit_to_files(d / "gram.npz", d / "q2.npz", d / "q2-trace.csv", q=2, seed=1, max_sweeps=20)
    names = list(store.open_store(d / "merl.zarr").materials)
    return {"dir": d, "model": d / "q2.npz", "store": d / "merl.zarr", "a": names[0], "b": names[3],
            "material": Path(db.sources[names[0]])}


# --------------------------------------------------------------------------
# Folder outputs replace only their own kind
# --------------------------------------------------------------------------


def test_sample_refuses_a_foreign_out_dir_and_replaces_its_own(
    latent_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["-q", "sample", "--model", str(latent_inputs["model"]), "--store", str(latent_inputs["store"])]
    foreign = tmp_path / "thesis"
    foreign.mkdir()
    (foreign / "chapter.tex").write_text("years of work\n")
    (foreign / "sample-000.binary").write_bytes(b"my own measurement")
    before = snapshot(foreign)
    assert cli.main([*base, "--seed", "1", "--count", "2", "--out-dir", str(foreign)]) == 1
    line = one_line(capsys, "sample")
    assert f"--out-dir {foreign}" in line and "did not write" in line
    assert snapshot(foreign) == before

    own = tmp_path / "samples"
    assert cli.main([*base, "--seed", "1", "--count", "2", "--out-dir", str(own)]) == 0
    doc = json.loads((own / "samples.json").read_text())
    assert doc["format"] == cli.SAMPLES_FORMAT and [r["file"] for r in doc["samples"]] == [
        "sample-000.binary", "sample-001.binary"]
    # an earlier output of sample is replaced whole: no stale sample-001 from the larger run
    assert cli.main([*base, "--seed", "2", "--count", "1", "--out-dir", str(own)]) == 0
    assert sorted(p.name for p in own.iterdir()) == ["sample-000.binary", "samples.csv", "samples.json"]
    # a file of the user's inside it makes it foreign again
    (own / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert cli.main([*base, "--seed", "2", "--count", "1", "--out-dir", str(own)]) == 1
    assert "did not write" in one_line(capsys, "sample") and (own / "notes.txt").read_text() == "mine"
    capsys.readouterr()


def test_capture_refuses_a_foreign_out_folder_before_rendering(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    material, directions = tmp_path / "m.binary", tmp_path / "d.json"
    material.write_bytes(b"x")
    directions.write_text("{}")
    out = tmp_path / "photos"
    out.mkdir()
    (out / "n1-0-render.exr").write_bytes(b"a photograph of mine")
    (out / "notes.txt").write_text("mine")
    before = snapshot(out)
    assert cli.main(["-q", "capture", str(material), str(directions), "--out", str(out), "--n", "1"]) == 1
    line = one_line(capsys, "capture")
    assert f"--out {out}" in line and "did not write" in line and snapshot(out) == before
    # an output folder that holds an input would delete it when replaced
    inside = tmp_path / "inside"
    inside.mkdir()
    (inside / "m.binary").write_bytes(b"x")
    assert cli.main(["-q", "capture", str(inside / "m.binary"), str(directions), "--out", str(inside)]) == 1
    assert "would write over the input" in one_line(capsys, "capture")
    assert (inside / "m.binary").read_bytes() == b"x"


def test_an_interrupted_synth_is_completed_by_a_rerun(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run stopped before its manifest leaves watermarked materials of its plan: a rerun finishes it."""
    import shutil

    out = tmp_path / "db"
    out.mkdir()
    spec = synth.plan_database(1, 7)[0]
    synth.write_material(spec, out / f"{spec.name}.binary", 0.01)
    # a folder with other files besides is still refused
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(out / f"{spec.name}.binary", other)
    (other / "mine.txt").write_text("x")
    assert cli.main(["-q", "synth", "--count", "1", "--seed", "7", "--out", str(other)]) == 1
    assert "no synthetic manifest.json" in one_line(capsys, "synth")
    assert cli.main(["-q", "synth", "--count", "1", "--seed", "7", "--out", str(out), "--jobs", "1"]) == 0
    assert json.loads((out / "manifest.json").read_text())["materials"][0]["name"] == spec.name


# --------------------------------------------------------------------------
# Read-only output folders: one line, before any work, earlier output kept
# --------------------------------------------------------------------------

_RO_DRIVER = textwrap.dedent("""
    import contextlib, io, json, sys
    from brdfpipe import cli
    results = []
    for argv in json.loads(sys.argv[1]):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                status = cli.main(argv)
            except BaseException as exc:  # a traceback would be the defect
                status = f"raised {type(exc).__name__}: {exc}"
        results.append([argv[1], status, err.getvalue()])
    print(json.dumps(results))
""")


def _drop_dac_override() -> None:
    """In the child: drop root's CAP_DAC_OVERRIDE / CAP_DAC_READ_SEARCH from the bounding set (exec loses them)."""
    libc = ctypes.CDLL(None, use_errno=True)
    for cap in (1, 2):  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
        if libc.prctl(24, cap, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="read-only folders as root need Linux capabilities")
def test_read_only_output_folders_are_one_line_before_any_work(tmp_path: Path) -> None:
    """Every subcommand with an output, pointed into a read-only folder (root loses DAC override)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    (ro / "earlier.binary").write_bytes(b"an earlier output")
    db = tmp_path / "db"
    synth.synthesize(db, count=1, seed=0, jobs=1, progress=False)
    material = next(db.glob("*.binary"))
    obs = tmp_path / "obs.csv"
    obs.write_text("theta_h,theta_d,phi_d,r,g,b\n10,20,30,0.1,0.1,0.1\n")
    model, st, dirs = tmp_path / "none.npz", tmp_path / "none.zarr", tmp_path / "none.json"
    cases = [
        ["-q", "synth", "--count", "1", "--seed", "0", "--out", str(ro / "db")],
        ["-q", "synth", "--count", "1", "--seed", "0", "--out", str(ro)],
        ["-q", "ingest", str(db), "--out", str(ro / "s.zarr"), "--jobs", "1"],
        ["-q", "interpolate", "--model", str(model), "--store", str(st), "--at", "0,0", "--out", str(ro / "earlier.binary")],
        ["-q", "extrapolate", "--model", str(model), "--store", str(st), "--from", "a", "--through", "b",
         "--out", str(ro / "e.binary")],
        ["-q", "sample", "--model", str(model), "--store", str(st), "--seed", "0", "--count", "1",
         "--out-dir", str(ro / "s")],
        ["-q", "reconstruct", str(obs), "--model", str(model), "--out", str(ro / "earlier.binary")],
        ["-q", "render", str(material), "--out", str(ro / "r.exr"), "--resolution", "8", "6", "--spp", "1"],
        ["-q", "capture", str(material), str(dirs), "--out", str(ro / "c"), "--n", "1", "--spp", "1"],
    ]
    ro.chmod(0o555)
    try:
        kwargs = {"preexec_fn": _drop_dac_override} if os.geteuid() == 0 else {}
        r = subprocess.run([sys.executable, "-c", _RO_DRIVER, json.dumps(cases)], capture_output=True, text=True,
                           env={**os.environ, "PYTHONPATH": str(SRC)}, timeout=300, **kwargs)
    finally:
        ro.chmod(0o755)
    assert r.returncode == 0, r.stderr[-3000:]
    results = json.loads(r.stdout.strip().splitlines()[-1])
    for (command, status, err), argv in zip(results, cases):
        lines = err.strip().splitlines()
        assert status == 1 and len(lines) == 1, (argv, status, err)
        out = argv[argv.index("--out-dir" if command == "sample" else "--out") + 1]
        assert lines[0].startswith(f"brdfpipe {command}: error: ") and out in lines[0], lines
        assert "cannot write in" in lines[0] and "Permission denied" in lines[0], lines
    assert sorted(p.name for p in ro.iterdir()) == ["earlier.binary"]  # nothing half-written, no temporary left
    assert (ro / "earlier.binary").read_bytes() == b"an earlier output"


def test_an_os_error_names_the_output_not_its_temporary_name() -> None:
    tmp = atomic.tmp_sibling("/data/out.binary")
    assert atomic.output_of(tmp) == Path("/data/out.binary")
    assert atomic.output_of(tmp.with_name(tmp.name + ".npz")) == Path("/data/out.binary")
    assert atomic.output_of("/data/.hidden") == Path("/data/.hidden")
    err = OSError(13, "Permission denied", str(tmp))
    from brdfpipe.core.command import os_error_message

    assert os_error_message(err) == "/data/out.binary: Permission denied"
    assert os_error_message(OSError(28, "No space left on device"), "/data/x.binary") == (
        "no space left on device writing /data/x.binary")


# --------------------------------------------------------------------------
# Sizes bounded up front
# --------------------------------------------------------------------------


@pytest.mark.parametrize("argv", [
    ["synth", "--count", "1000000000", "--seed", "1", "--out", "{tmp}/db"],
    ["synth", "--count", "1e9", "--seed", "1", "--out", "{tmp}/db"],
    ["sample", "--model", "{tmp}/m.npz", "--store", "{tmp}/s.zarr", "--seed", "1", "--count", "100000000",
     "--out-dir", "{tmp}/s"],
    ["sample", "--model", "{tmp}/m.npz", "--store", "{tmp}/s.zarr", "--seed", "1", "--count", "1e8",
     "--out-dir", "{tmp}/s"],
])
def test_huge_counts_are_refused_up_front_with_the_limit(
    argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """35 MB per MERL file against the free disk: refused at once (these hung with growing memory)."""
    args = [a.format(tmp=tmp_path) for a in argv]
    assert cli.main(["-q", *args]) == 1
    line = one_line(capsys, args[0])
    count = int(float(args[args.index("--count") + 1]))
    assert f"--count {count}: needs " in line and "MERL files × 35 MB" in line and "free" in line
    assert sorted(tmp_path.iterdir()) == []


def test_jobs_and_tries_are_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["-q", "synth", "--count", "2", "--seed", "1", "--out", str(tmp_path / "db"), "--jobs",
                     "100000"]) == 1
    line = one_line(capsys, "synth")
    assert "--jobs 100000: at most" in line and "350 MB" in line and not (tmp_path / "db").exists()
    assert cli.main(["-q", "sample", "--model", "m.npz", "--seed", "1", "--count", "1", "--max-tries", "1e21",
                     "--out-dir", str(tmp_path / "s")]) == 1
    assert f"--max-tries {10**21}: at most {cli.MAX_TRIES}" in one_line(capsys, "sample")


def test_extrapolation_steps_are_bounded(latent_inputs: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["-q", "extrapolate", "--model", str(latent_inputs["model"]), "--store", str(latent_inputs["store"]),
            "--from", latent_inputs["a"], "--through", latent_inputs["b"], "--step", "1e-300"]
    assert cli.main(argv) == 1
    line = one_line(capsys, "extrapolate")
    assert "steps; at most 2000000 for 5 materials" in line and "raise step or lower max_s" in line


# --------------------------------------------------------------------------
# Mitsuba's limits
# --------------------------------------------------------------------------


@pytest.mark.parametrize(("extra", "message"), [
    (["--spp", "64000"], "--spp 64000: at most 32000 samples per pixel"),
    (["--spp", "4294967296"], "--spp 4294967296: at most 32000"),
    (["--seed", "5000000"], "--seed 5000000: must be in [0, 4294966]"),
    (["--seed", "4294967296"], "--seed 4294967296: must be in [0, 4294966]"),
    (["--max-depth", "4294967296"], "--max-depth 4294967296: must be in [1, 4294967295]"),
    (["--resolution", "100000", "100000"], "--resolution 100000 100000: needs about 3 TB of memory"),
])
def test_render_settings_mitsuba_rejects_are_refused(
    extra: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    material = tmp_path / "m.binary"
    material.write_bytes(b"not read: the settings are checked first")
    argv = ["-q", "render", str(material), "--out", str(tmp_path / "x.exr"), "--resolution", "8", "6", *extra]
    assert cli.main(argv) == 1
    assert message in one_line(capsys, "render")
    assert not (tmp_path / "x.exr").exists()


def test_render_limits_follow_mitsubas_32_bit_seed() -> None:
    assert scene.MAX_SEED * 1000 + 999 <= scene.MITSUBA_UINT32_MAX < (scene.MAX_SEED + 1) * 1000 + 999
    assert scene.pass_seeds(32000, scene.MAX_SEED)[-1][0] == scene.MAX_SEED * 1000 + 999
    with pytest.raises(ValueError, match="32-bit"):
        scene.pass_seeds(32000, scene.MAX_SEED + 1)
    scene.check_render_settings((256, 192), 64, 0, 6, memory=16 * 10**9)
    with pytest.raises(ValueError, match="resolution 8000 8000: needs about 19.4 GB of memory"):
        scene.check_render_settings((8000, 8000), 1, 0, 6, memory=16 * 10**9)


def test_capture_spp_beyond_mitsuba_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["-q", "capture", str(tmp_path / "m.binary"), str(tmp_path / "d.json"), "--out", str(tmp_path / "c"),
            "--spp", "4294967296"]
    assert cli.main(argv) == 1
    assert "--spp 4294967296: at most 4294967295 (Mitsuba's sample count" in one_line(capsys, "capture")


# --------------------------------------------------------------------------
# Numbers: finite in, strict JSON out
# --------------------------------------------------------------------------


def test_nearest_refuses_an_overflowing_point_and_prints_strict_json(
    latent_inputs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["-q", "nearest", "--model", str(latent_inputs["model"])]
    assert cli.main([*argv, "--at", "1e308,1e308"]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and "Infinity" not in captured.out
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "--at 1e+308,1e+308: the latent distances overflow" in lines[0], lines
    assert cli.main([*argv, "--at", "0.1,-0.2", "-k", "2"]) == 0
    found = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"non-strict JSON: {c}"))
    assert len(found) == 2 and all(math.isfinite(f["latent_distance"]) for f in found)
    with pytest.raises(ValueError, match="non-finite number"):
        cli._strict_json({"x": float("nan")}, "test")


def test_interpolate_refuses_an_overflowing_t_and_writes_nothing(
    latent_inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--t 1e308 between two materials wrote a table (with a numpy warning) at a point beyond float64."""
    out = tmp_path / "far.binary"
    argv = ["-q", "interpolate", "--model", str(latent_inputs["model"]), "--store", str(latent_inputs["store"]),
            "--between", latent_inputs["a"], latent_inputs["b"], "--out", str(out)]
    assert cli.main([*argv, "--t", "1e308"]) == 1
    line = one_line(capsys, "interpolate")
    assert "t = 1e+308: the latent distances overflow" in line, line
    assert not out.exists()


def test_a_file_where_a_store_folder_belongs_is_named_as_such(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"\0" * 1000)
    assert cli.main(["-q", "info", str(junk)]) == 1
    line = one_line(capsys, "info")
    assert f"{junk}: not a" in line and "a store is a Zarr v3 folder" in line, line


@pytest.mark.parametrize(("argv", "option"), [
    (["synth", "--count", "1", "--seed", "1", "--out", "x", "--noise", "inf"], "--noise"),
    (["synth", "--count", "1", "--seed", "-1", "--out", "x"], "--seed"),
    (["synth", "--count", "x", "--seed", "1", "--out", "x"], "--count"),
    (["sample", "--model", "m", "--seed", "-1", "--count", "1", "--out-dir", "x"], "--seed"),
    (["nearest", "--model", "m", "--at", "nan,0"], "--at"),
    (["nearest", "--model", "m", "--at", "1e400,0"], "--at"),
    (["interpolate", "--model", "m", "--at", "inf,0", "--out", "x"], "--at"),
    (["interpolate", "--model", "m", "--between", "a", "b", "--t", "nan", "--out", "x"], "--t"),
    (["extrapolate", "--model", "m", "--from", "a", "--through", "b", "--max-s", "inf"], "--max-s"),
    (["render", "m", "--out", "x", "--seed", "-1"], "--seed"),
    (["capture", "m", "d", "--out", "x", "--read-noise", "-5"], "--read-noise"),
    (["capture", "m", "d", "--out", "x", "--min-snr", "nan"], "--min-snr"),
    (["capture", "m", "d", "--out", "x", "--brackets", "1", "nan"], "--brackets"),
    (["capture", "m", "d", "--out", "x", "--peak-level", "2"], "--peak-level"),
    (["capture", "m", "d", "--out", "x", "--bits", "100000"], "--bits"),
    (["capture", "m", "d", "--out", "x", "--seed", "-1"], "--seed"),
    (["sample"], "--model"),
])
def test_bad_numbers_and_arguments_are_one_line_naming_the_option(
    argv: list[str], option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"brdfpipe {argv[0]}: error: ") and option in err[0], err


# --------------------------------------------------------------------------
# The safety net: whatever a reader lets through is one line naming the file
# --------------------------------------------------------------------------


def test_a_truncated_model_is_one_line_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model = tmp_path / "q2.npz"
    np.savez(model, X=np.zeros((4, 2)), names=np.array(["a", "b", "c", "d"]))
    model.write_bytes(model.read_bytes()[:-40])  # truncated: the zip directory is gone
    with pytest.raises(zipfile.BadZipFile):
        np.load(model)
    assert cli.main(["-q", "nearest", "--model", str(model), "--at", "0,0"]) == 1
    line = one_line(capsys, "nearest")
    assert str(model) in line and "BadZipFile" in line and "truncated or corrupt GPLVM model" in line
    assert cli.main(["-q", "interpolate", "--model", str(model), "--store", str(tmp_path / "s.zarr"), "--at", "0,0",
                     "--out", str(tmp_path / "x.binary")]) == 1
    line = one_line(capsys, "interpolate")
    assert str(model) in line and not (tmp_path / "x.binary").exists()


def test_undecodable_input_names_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A UnicodeDecodeError (a ValueError without the file's name) from a reader names the file it read."""
    import brdfpipe.acquisition.reconstruct

    obs = tmp_path / "obs.csv"
    obs.write_bytes(b"\xff\xfe\x00 not text \x80")

    def write_reconstruction(model: str, observations: str, out: str, eta: float) -> None:
        Path(observations).read_text(encoding="utf-8")  # a reader that lets the decode error through

    monkeypatch.setattr(brdfpipe.acquisition.reconstruct, "write_reconstruction", write_reconstruction)
    assert cli.main(["-q", "reconstruct", str(obs), "--model", str(tmp_path / "m.zarr"), "--out",
                     str(tmp_path / "x.binary")]) == 1
    line = one_line(capsys, "reconstruct")
    assert str(obs) in line and "UnicodeDecodeError" in line


@pytest.mark.parametrize("exc", [KeyError("X"), IndexError("index 5"), EOFError(), OverflowError("too big"),
                                 RuntimeError("[Bitmap] boom\nsecond line"), TypeError("a bug")])
def test_any_leaked_exception_is_one_line(
    exc: BaseException, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from brdfpipe.manifold import gplvm

    model = tmp_path / "m.npz"

    def load(path: object) -> None:  # the reader's frame holds the path, as np.load's does
        raise exc

    monkeypatch.setattr(gplvm, "load_model", load)
    assert cli.main(["-q", "nearest", "--model", str(model), "--at", "0,0"]) == 1
    line = one_line(capsys, "nearest")
    assert type(exc).__name__ in line and str(model) in line
    if isinstance(exc, TypeError):
        assert "internal error" in line and "BRDFPIPE_TRACEBACK=1" in line
        monkeypatch.setenv("BRDFPIPE_TRACEBACK", "1")
        with pytest.raises(TypeError):
            cli.main(["-q", "nearest", "--model", str(model), "--at", "0,0"])


def test_free_space_and_memory_checks() -> None:
    from brdfpipe.core import resources

    resources.check_free_space("/", 1, what="--count 1")
    with pytest.raises(atomic.OutputError, match=r"--count 5: needs .* \(5 files\) but the file system of / has"):
        resources.check_free_space("/", resources.free_bytes("/") + 10**9, what="--count 5", how="5 files")
    assert resources.format_bytes(35e15) == "35 PB" and resources.format_bytes(999) == "999 B"
    with pytest.raises(resources.ResourceError, match="more than this machine's 1 GB"):
        resources.check_memory(2 * 10**9, what="x", memory=10**9)


def test_a_truncated_material_is_named_before_mitsuba_reads_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Mitsuba's merl plugin buried the reader's error (with a Python traceback's text) in a scene error."""
    material = tmp_path / "m.binary"
    material.write_bytes(np.array([90, 90, 180], "<i4").tobytes() + b"\0" * 988)
    assert cli.main(["-q", "render", str(material), "--out", str(tmp_path / "x.exr"), "--resolution", "8", "6",
                     "--spp", "1"]) == 1
    line = one_line(capsys, "render")
    assert line.startswith(f"brdfpipe render: error: {material}: truncated file") and "Traceback" not in line
    directions = tmp_path / "d.json"
    directions.write_text("{}")
    assert cli.main(["-q", "capture", str(material), str(directions), "--out", str(tmp_path / "c"), "--n", "1"]) == 1
    assert one_line(capsys, "capture").startswith(f"brdfpipe capture: error: {material}: truncated file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json", "m.binary"]
