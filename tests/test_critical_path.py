"""The critical-path report (brdfpipe.report.critical_path) on a hand-written Snakemake log."""

from __future__ import annotations

from pathlib import Path

import pytest

from brdfpipe.report import critical_path as cp

# Three jobs on 2 cores: a (2 threads, 0–10 s), b (needs a, 10–14 s), c (independent, 2–20 s,
# ready at 0 but started at 2), then d (needs b and c: waits for c, 25–26 s). d's start at 25 leaves
# cores idle from 20 to 25.
LOG = """\
Building DAG of jobs...
Provided cores: 2
Select jobs to execute...
[Thu Nov 26 10:00:00 2026]
rule a:
    output: results/a.txt
    jobid: 1
    benchmark: benchmarks/a.tsv
    threads: 2
Shell command: None
[Thu Nov 26 10:00:10 2026]
Finished jobid: 1 (Rule: a)
[Thu Nov 26 10:00:10 2026]
localrule b:
    input: results/a.txt
    output: results/b.txt
    jobid: 2
    wildcards: x=1
Shell command: None
[Thu Nov 26 10:00:12 2026]
rule c:
    output: results/c.txt
    jobid: 3
    benchmark: benchmarks/c.tsv
[Thu Nov 26 10:00:14 2026]
Finished jobid: 2 (Rule: b)
[Thu Nov 26 10:00:20 2026]
Finished jobid: 3 (Rule: c)
[Thu Nov 26 10:00:25 2026]
rule d:
    input: results/b.txt, results/c.txt
    output: results/d.txt
    jobid: 4
[Thu Nov 26 10:00:26 2026]
Finished jobid: 4 (Rule: d)
"""


@pytest.fixture()
def run(tmp_path: Path) -> cp.Run:
    log = tmp_path / ".snakemake" / "log" / "2026-11-26T100000.snakemake.log"
    log.parent.mkdir(parents=True)
    log.write_text(LOG)
    (tmp_path / "benchmarks").mkdir()
    header = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
    (tmp_path / "benchmarks" / "a.tsv").write_text(header + "9.50\t0:00:09\t100.0\t1\t1\t1\t0\t0\t190\t18.0\n")
    (tmp_path / "benchmarks" / "c.tsv").write_text(header + "8.00\t0:00:08\t50.0\t1\t1\t1\t0\t0\t90\t7.5\n")
    return cp.read_run(cp.latest_log(tmp_path))


def test_jobs_times_threads_and_dependencies(run: cp.Run) -> None:
    assert run.cores == 2 and run.wall == 26.0
    a, b, c, d = (run.jobs[i] for i in (1, 2, 3, 4))
    assert (a.start, a.end, a.threads, a.duration, a.cpu) == (0.0, 10.0, 2, 9.5, 18.0)
    assert (b.start, b.end, b.wildcards, b.duration, b.cpu) == (10.0, 14.0, "x=1", 4.0, None)
    assert (c.start, c.end, c.duration) == (12.0, 20.0, 8.0)
    assert run.deps == {1: [], 2: [1], 3: [], 4: [2, 3]}


def test_critical_path_follows_the_dependency_that_finished_last(run: cp.Run) -> None:
    steps = cp.critical_path(run)
    assert [s.job.rule for s in steps] == ["c", "d"]
    assert steps[0].ready == 0.0 and steps[0].wait == 12.0  # c was ready at once, started at 12
    assert steps[1].ready == 20.0 and steps[1].wait == 5.0
    assert steps[1].share == pytest.approx(1.0 / 26.0)


def test_idle_cores_and_cpu_per_rule(run: cp.Run) -> None:
    idle, avail = cp.idle_core_seconds(run)
    # a uses both cores 0–10; b 10–14 and c 12–20 one each; d 25–26 one:
    # idle = 0 + (10–12: 1) 2 + (12–14: 0) + (14–20: 1) 6 + (20–25: 2) 10 + (25–26: 1) 1 = 19
    assert (idle, avail) == (19.0, 52.0)
    rules = {r.rule: r for r in cp.cpu_per_rule(run)}
    assert rules["a"].cpu == 18.0 and rules["c"].cpu == 7.5 and rules["b"].cpu == 0.0
    text = cp.report(run)
    assert "idle cores while the path ran: 19 of 52 core-seconds" in text
    assert "path: 2 jobs, running 9.0 s" in text


def test_not_a_log_is_one_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "x.log"
    bad.write_text("hello\n")
    with pytest.raises(cp.RunLogError, match="no timestamped job"):
        cp.read_run(bad)
    with pytest.raises(cp.RunLogError, match="no Snakemake log"):
        cp.latest_log(tmp_path)
