"""Job stamps (brdfpipe.core.stamps), and the Snakefile's refusal of a rule without its stamp.

The workflow-level kill-and-resume tests are in test_resume.py, the job lease
on outputs in test_lease.py.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from brdfpipe.core import filenames, stamps

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "config" / "tiny.yaml"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")

CAPTURE = {"n_images": [1, 2], "spp": 4, "seed": 7, "light_distance": 20, "min_snr": 3,
           "sensor": {"enabled": True, "brackets": [1, 8]}, "variant": "llvm_ad_rgb", "code": "ab12"}


def record(params: dict, wildcards: dict | None = None, inputs: list | None = None) -> str:
    """The record a stamp holds (its first line) for a capture_closedloop job."""
    wc = {"material": "paint-white-003"} if wildcards is None else wildcards
    return stamps.job_record("capture_closedloop", wc, params, inputs or ["a.binary"])


def test_a_swap_of_two_params_changes_the_stamp_though_snakemake_sees_the_same_values() -> None:
    swapped = {**CAPTURE, "seed": CAPTURE["spp"], "spp": CAPTURE["seed"]}
    # what Snakemake's params trigger compares (persistence._params: sorted reprs of the values, no names)
    assert sorted(map(repr, CAPTURE.values())) == sorted(map(repr, swapped.values()))
    assert record(swapped) != record(CAPTURE)
    # a value another param already has: the set of values stays the same too
    dup = {**CAPTURE, "light_distance": 4, "spp": 20}
    assert set(map(repr, dup.values())) == set(map(repr, CAPTURE.values())) and record(dup) != record(CAPTURE)


def test_the_stamp_covers_wildcards_inputs_code_and_nothing_else() -> None:
    assert record(CAPTURE, {"material": "metal-brass-001"}) != record(CAPTURE)
    assert record(CAPTURE, inputs=["a.binary", "b.json"]) != record(CAPTURE)
    assert record({**CAPTURE, "code": "ab13"}) != record(CAPTURE)
    # the order of a mapping's keys (a config rewritten by a YAML tool) and tuple vs list change nothing
    reordered = dict(reversed(list(CAPTURE.items())))
    reordered["sensor"] = {"brackets": (1, 8), "enabled": True}
    assert record(reordered) == record(CAPTURE)
    # 4 and 4.0 are different values for the library (an int seed, a float exposure)
    assert record({**CAPTURE, "spp": 4.0}) != record(CAPTURE)


@pytest.mark.parametrize("value", [{1, 2}, object(), {1: "a"}])
def test_a_param_that_is_not_plain_data_is_refused_naming_rule_and_param(value: object) -> None:
    with pytest.raises(stamps.StampError, match="rule capture_closedloop: param sensor"):
        record({**CAPTURE, "sensor": value})


def test_job_keys_are_file_names_and_tell_jobs_apart(tmp_path: Path) -> None:
    assert stamps.job_key({}) == "_"
    assert stamps.job_key({"split": "train", "fov": "25"}) == "fov=25,split=train"
    odd = {"a": "x/y", "b": "p,q=r%", "c": "café"}
    key = stamps.job_key(odd)
    assert "/" not in key and key.count(",") == 2 and key.count("=") == 3
    assert stamps.job_key({"a": "x,b=y"}) != stamps.job_key({"a": "x", "b": "y"})
    long1 = {"candidate": "standardised-mu1e-06", "path": "a" * 100 + "--" + "b" * 100, "t": "0.25"}
    long2 = {**long1, "t": "0.5"}
    key1, key2 = stamps.job_key(long1), stamps.job_key(long2)
    assert key1 != key2 and len(key1.encode()) <= 100
    for k in (key1, key):
        (tmp_path / k).touch()  # a valid file name


def test_a_run_rewrites_a_stamp_when_the_record_changed_or_its_job_has_not_succeeded(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    path = filenames.stamp("capture_closedloop", "material=m")
    a, b = (stamps.job_record("capture_closedloop", {"material": "m"}, {"seed": s}, []) for s in (1, 2))
    assert stamps.stamp_input(path, a, "run") == path and Path(path).read_text() == a + "\n"
    stamps.mark_done(path, a + "\n")  # the job succeeded
    os.utime(path, (1, 1))  # outputs made since are newer
    assert stamps.stamp_input(path, a, "run") == path and Path(path).stat().st_mtime == 1  # same record: untouched
    assert stamps.stamp_input(path, b, "run") == path and Path(path).read_text() == b + "\n"
    assert Path(path).stat().st_mtime > 1  # newer than the outputs: Snakemake reruns the job
    os.utime(path, (1, 1))
    stamps.mark_done(path, b + "\n")
    stamps.stamp_input(path, b, "run", outputs_missing=True)  # same record, an output gone: rerun too
    assert Path(path).stat().st_mtime > 1
    assert sorted(p.name for p in Path(path).parent.iterdir()) == ["material=m", "material=m.done"]  # no temporary


def test_a_stamp_counts_only_once_its_job_succeeded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A job killed after its stamp was written: the next run's stamp differs in text, not only in time.

    Snakemake records a failed job's input checksums (persistence.finished
    runs before the outputs are removed): a stamp rewritten with the same
    text would match them, and Snakemake would judge the job's input
    unchanged.  Each retry's text differs from the one before.
    """
    monkeypatch.chdir(tmp_path)
    path = filenames.stamp("capture_closedloop", "material=m")
    a, b = (stamps.job_record("capture_closedloop", {"material": "m"}, {"seed": s}, []) for s in (1, 2))
    stamps.stamp_input(path, a, "run")
    stamps.mark_done(path, a + "\n")
    stamps.stamp_input(path, b, "run")  # the config changed; the job is started and killed: no done mark
    texts = [Path(path).read_text()]
    for _ in range(3):  # resumed, killed again, ...
        assert stamps.stamp_input(path, b, "plan") == stamps.PLAN_FILE  # a dry run plans the job
        assert stamps.stamp_input(path, b, "run") == path
        texts.append(Path(path).read_text())
        assert texts[-1].split("\n")[0] == b and texts[-1] != texts[-2]
    stamps.mark_done(path, texts[-1])  # the job succeeded at last
    assert stamps.stamp_input(path, b, "plan") == path and stamps.stamp_input(path, b, "run") == path
    assert Path(path).read_text() == texts[-1]
    # a done mark of another definition (the job of record a succeeded, not of b) does not count
    stamps.mark_done(path, a + "\n")
    assert stamps.stamp_input(path, b, "plan") == stamps.PLAN_FILE


def test_log_to_marks_the_stamp_done_only_when_the_job_succeeds(tmp_path: Path) -> None:
    from brdfpipe.core.logutil import log_to

    stamp = tmp_path / "stamp"
    stamp.write_text("record\n")
    with pytest.raises(RuntimeError), log_to(tmp_path / "failed.log", stamp=stamp):
        raise RuntimeError("killed")
    assert not stamps.done_path(stamp).exists()
    with log_to(tmp_path / "job.log", stamp=stamp):
        stamp.write_text("record\nretry 0\n")  # a newer run rewrote it meanwhile: the job made the old one's
    assert stamps.done_path(stamp).read_text() == "record\n"


def test_a_dry_run_plans_with_a_fresh_copy_and_leaves_results_alone(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    path = filenames.stamp("fit_gplvm", "candidate=raw,q=2")
    a, b = (stamps.job_record("fit_gplvm", {"candidate": "raw", "q": "2"}, {"ell": e}, ["g.npz"]) for e in (1, 2))
    planned = stamps.stamp_input(path, a, "plan")  # no stamp yet: the run will write one
    assert planned == stamps.PLAN_FILE and Path(planned).is_file() and planned.startswith(".snakemake/")
    assert not Path("results").exists()
    stamps.stamp_input(path, a, "run")
    stamps.mark_done(path, a + "\n")
    assert stamps.stamp_input(path, a, "plan") == path  # up to date
    planned_b = stamps.stamp_input(path, b, "plan")
    assert planned_b != path and Path(path).read_text() == a + "\n"
    assert stamps.stamp_input(path, a, "plan", outputs_missing=True) != path
    assert stamps.stamp_input(path, b, "read") == path  # a job's own process writes nothing
    assert Path(path).read_text() == a + "\n"
    with pytest.raises(ValueError, match="unknown stamp mode"):
        stamps.stamp_input(path, a, "write")


def test_stamps_live_under_results() -> None:
    assert filenames.stamp("fit_gplvm", "candidate=raw,q=2") == "results/.stamps/fit_gplvm/candidate=raw,q=2"


# -- the Snakefile refuses a rule without its stamp -----------------------------------


@pytest.mark.slow
def test_a_rule_without_its_stamp_is_refused_at_parse(tmp_path: Path) -> None:
    wf = tmp_path / "workflow"
    shutil.copytree(ROOT / "workflow", wf)
    rules = wf / "rules" / "manifold.smk"
    text = rules.read_text()
    assert '        stamp=stamp_of("compare_spaces"),\n' in text
    rules.write_text(text.replace('        stamp=stamp_of("compare_spaces"),\n', ""))
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    r = subprocess.run([str(SNAKEMAKE), "--snakefile", str(wf / "Snakefile"), "--directory", str(tmp_path),
                        "--configfile", str(TINY), "-n"], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode != 0
    assert "rules without their stamp input (stamp=stamp_of(NAME)): compare_spaces" in r.stdout + r.stderr
