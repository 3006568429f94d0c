"""The job lease (brdfpipe.core.atomic.job_lease, held by brdfpipe.core.logutil.log_to).

A process whose job was started again by a newer run (Snakemake deletes the
job's log before it runs the job again) puts no output in place any more: a
process that outlived its run (the main process killed alone, a Slurm step
that survived scancel) cannot write over the newer attempt's outputs.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from brdfpipe.core import atomic
from brdfpipe.core.logutil import log_to


def _start_again(log: Path) -> None:
    """What Snakemake does before it runs the job again: delete its log; the new attempt opens a new one."""
    log.unlink()
    log.write_text("the new attempt's log\n")


def test_a_superseded_job_writes_no_file(tmp_path: Path) -> None:
    log, out = tmp_path / "logs" / "job.log", tmp_path / "out.csv"
    with log_to(log):
        atomic.write_text(out, "mine\n")  # the lease holds: written
        assert out.read_text() == "mine\n"
        _start_again(log)
        out.write_text("the new attempt's table\n")
        with pytest.raises(atomic.SupersededError, match=r"job\.log: this job was started again by a newer run"):
            atomic.write_text(out, "stale\n")
        with pytest.raises(atomic.SupersededError):
            atomic.save_npz(tmp_path / "x.npz", {"a": [1]})
    assert out.read_text() == "the new attempt's table\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs", "out.csv"]  # no x.npz, no temporary left


def test_a_superseded_job_replaces_no_folder(tmp_path: Path) -> None:
    log, out = tmp_path / "job.log", tmp_path / "model.zarr"
    mine = lambda p: (p / "mine").exists()  # noqa: E731
    with log_to(log):
        with atomic.atomic_dir(out, replaceable=mine) as tmp:
            (tmp / "mine").write_text("1")
        _start_again(log)
        shutil.rmtree(out)
        out.mkdir()
        (out / "mine").write_text("the new attempt's")
        with pytest.raises(atomic.SupersededError):
            with atomic.atomic_dir(out, replaceable=mine) as tmp:
                (tmp / "mine").write_text("stale")
    assert (out / "mine").read_text() == "the new attempt's"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.log", "model.zarr"]


def test_the_lease_ends_with_the_job(tmp_path: Path) -> None:
    log = tmp_path / "job.log"
    with log_to(log):
        pass
    log.unlink()
    atomic.write_text(tmp_path / "out.txt", "no job, no lease\n")  # the command line, tests
    assert (tmp_path / "out.txt").read_text() == "no job, no lease\n"
