"""core.logutil.log_to: the job log keeps the detail, the run's console gets warnings and errors only."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from brdfpipe.core import logutil


def test_job_log_has_everything_console_only_warnings(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "logs" / "job.log"
    with logutil.log_to(log) as logger:
        logger.info("step 1 of 400: loss 3.2")
        logger.warning("albedo outside [0, 1] at 3 cells")
    text = log.read_text()
    assert "step 1 of 400" in text and "albedo outside" in text
    records = [line for line in capfd.readouterr().err.splitlines() if " brdfpipe.workflow: " in line]
    assert [r.split(" ", 2)[2] for r in records] == ["WARNING brdfpipe.workflow: albedo outside [0, 1] at 3 cells"]


def test_a_failed_job_says_why_on_the_console_and_in_its_log(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "job.log"
    with pytest.raises(ValueError), logutil.log_to(log):
        raise ValueError("results/svd/train.zarr: digest mismatch")
    assert "digest mismatch" in log.read_text() and "Traceback" in log.read_text()
    assert "digest mismatch" in capfd.readouterr().err
    assert not [h for h in logging.getLogger().handlers if getattr(h, "baseFilename", None) == str(log)]
