"""Where a finished run's wall time went: the critical path, CPU per rule, idle cores.

Reads what every Snakemake run leaves behind — its log
(``.snakemake/log/<date>.snakemake.log``: each job's start and finish time,
rule, wildcards, threads, inputs, outputs and benchmark file) and the jobs'
``benchmark:`` files (wall and CPU seconds, peak RSS) — and answers:

* **the critical path**: the chain of jobs that ends with the last job to
  finish, each one's predecessor being the dependency it waited for longest
  (the one that finished last); for every job on it, its duration, how long
  it waited after that dependency finished (ready but not started: no free
  core), and both as a share of the run's wall time;
* **CPU per rule**: jobs, summed CPU and wall seconds, the longest job;
* **idle cores**: core-seconds no job used while the path ran (the run's
  ``Provided cores`` minus the threads of the jobs running), i.e. how much
  parallelism was left on the table.

The log's timestamps have one-second resolution; a job's duration comes from
its benchmark file when it has one (10 ms resolution).  Standard library only.
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from brdfpipe.core.filenames import rule_family

__all__ = [
    "Job",
    "Run",
    "PathStep",
    "RuleCpu",
    "RunLogError",
    "latest_log",
    "read_run",
    "critical_path",
    "cpu_per_rule",
    "idle_core_seconds",
    "report",
]

_STAMP = re.compile(r"^\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]$")
_RULE = re.compile(r"^(?:local)?(?:rule|checkpoint) (?P<rule>\S+):$")
_FIELD = re.compile(r"^    (?P<key>[a-z_]+): (?P<value>.*)$")
_FINISHED = re.compile(r"^Finished jobid: (?P<id>\d+) \(Rule: (?P<rule>\S+)\)$")
_ERROR = re.compile(r"^Error in rule (?P<rule>\S+):$")
_CORES = re.compile(r"^Provided cores: (?P<n>\d+)")


class RunLogError(ValueError):
    """A run's log cannot be read as a Snakemake log; the message names the file."""


@dataclass
class Job:
    """One job of the run, as its log tells it (times in seconds since the run started)."""

    jobid: int
    rule: str
    start: float
    end: float | None = None
    wildcards: str = ""
    threads: int = 1
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    benchmark: str | None = None
    wall: float | None = None  # benchmark's ``s``
    cpu: float | None = None  # benchmark's ``cpu_time``
    max_rss_mb: float | None = None
    failed: bool = False

    @property
    def label(self) -> str:
        return f"{self.rule}[{self.wildcards}]" if self.wildcards else self.rule

    @property
    def duration(self) -> float:
        """Wall seconds: the benchmark's when known, else finish − start from the log."""
        if self.wall is not None:
            return self.wall
        return max(0.0, (self.end if self.end is not None else self.start) - self.start)


@dataclass
class Run:
    """A run's jobs, its cores and wall time, read from its log."""

    log: Path
    cores: int
    jobs: dict[int, Job]
    wall: float
    deps: dict[int, list[int]] = field(default_factory=dict)


def latest_log(workdir: str | os.PathLike[str]) -> Path:
    """The newest ``.snakemake/log/*.snakemake.log`` of a working directory."""
    logs = sorted(Path(workdir, ".snakemake", "log").glob("*.snakemake.log"))
    if not logs:
        raise RunLogError(f"{workdir}: no Snakemake log in .snakemake/log/ (run the workflow there first)")
    return logs[-1]


def _split(value: str) -> tuple[str, ...]:
    return tuple(p.strip() for p in value.split(", ") if p.strip())


def _read_benchmark(path: Path) -> tuple[float, float, float] | None:
    """(s, cpu_time, max_rss) of a Snakemake benchmark TSV (its last row), or None."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
        row = rows[-1]
        return float(row["s"]), float(row["cpu_time"]), float(row["max_rss"]) if row["max_rss"] not in ("", "NA") else 0.0
    except (OSError, KeyError, ValueError, IndexError):
        return None


def read_run(log: str | os.PathLike[str], workdir: str | os.PathLike[str] | None = None) -> Run:
    """Parse a Snakemake log (and the benchmark files its jobs name, relative to ``workdir``).

    ``workdir`` defaults to the folder that holds ``.snakemake/`` (the log's
    grandparent's parent).  Jobs without a finish line (interrupted) keep
    ``end = None``; failed jobs are flagged.
    """
    log = Path(log)
    workdir = Path(workdir) if workdir is not None else log.parent.parent.parent
    try:
        lines = log.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as err:
        raise RunLogError(f"{log}: cannot be read ({err.strerror or err})") from None
    cores = 1
    now: datetime | None = None
    t0: datetime | None = None
    jobs: dict[int, Job] = {}
    current: dict[str, str] | None = None
    current_rule = ""
    current_time = 0.0
    last = 0.0

    def close() -> None:
        nonlocal current
        if current is not None and "jobid" in current:
            jid = int(current["jobid"])
            jobs[jid] = Job(
                jobid=jid, rule=current_rule, start=current_time,
                wildcards=current.get("wildcards", ""), threads=int(current.get("threads", "1")),
                inputs=_split(current.get("input", "")), outputs=_split(current.get("output", "")),
                benchmark=current.get("benchmark"),
            )
        current = None

    for line in lines:
        m = _CORES.match(line)
        if m:
            cores = int(m["n"])
            continue
        m = _STAMP.match(line)
        if m:
            close()
            now = datetime.strptime(m[1], "%a %b %d %H:%M:%S %Y")
            t0 = t0 or now
            last = (now - t0).total_seconds()
            continue
        if current is not None:
            f = _FIELD.match(line)
            if f:
                current[f["key"]] = f["value"]
                continue
            close()
        m = _RULE.match(line)
        if m and now is not None:
            current, current_rule, current_time = {}, m["rule"], last
            continue
        m = _FINISHED.match(line)
        if m and int(m["id"]) in jobs:
            jobs[int(m["id"])].end = last
            continue
        m = _ERROR.match(line)
        if m:
            for j in jobs.values():
                if j.rule == m["rule"] and j.end is None:
                    j.failed = True
    close()
    if t0 is None:
        raise RunLogError(f"{log}: no timestamped job in the file; is it a Snakemake log?")
    for job in jobs.values():
        if job.benchmark:
            got = _read_benchmark(workdir / job.benchmark)
            if got is not None:
                job.wall, job.cpu, job.max_rss_mb = got
    run = Run(log=log, cores=cores, jobs=jobs, wall=last)
    run.deps = _dependencies(jobs.values())
    return run


def _dependencies(jobs: Iterable[Job]) -> dict[int, list[int]]:
    """jobid → the jobs of this run that wrote one of its inputs."""
    jobs = list(jobs)
    producer = {out: j.jobid for j in jobs for out in j.outputs}
    return {j.jobid: sorted({producer[i] for i in j.inputs if i in producer} - {j.jobid}) for j in jobs}


@dataclass(frozen=True)
class PathStep:
    """One job of the critical path: when it could start, when it did, and how long it ran."""

    job: Job
    ready: float  # when its last dependency finished (the run's start for the first job)
    wait: float  # start − ready: ready but not started
    share: float  # duration / wall


def critical_path(run: Run) -> list[PathStep]:
    """The chain of jobs ending with the last to finish; each predecessor is the dependency that finished last."""
    done = [j for j in run.jobs.values() if j.end is not None]
    if not done:
        return []
    wall = max(run.wall, 1e-9)
    chain: list[Job] = []
    job: Job | None = max(done, key=lambda j: (j.end, j.start, j.jobid))
    seen: set[int] = set()
    while job is not None and job.jobid not in seen:
        seen.add(job.jobid)
        chain.append(job)
        preds = [run.jobs[d] for d in run.deps.get(job.jobid, []) if run.jobs[d].end is not None]
        job = max(preds, key=lambda j: (j.end, j.start, j.jobid)) if preds else None
    chain.reverse()
    steps = []
    for k, j in enumerate(chain):
        ready = chain[k - 1].end if k else 0.0
        wait = max(0.0, j.start - ready)
        steps.append(PathStep(j, ready, wait, j.duration / wall))
    return steps


@dataclass(frozen=True)
class RuleCpu:
    """The jobs of one rule in the run: count, summed CPU and wall seconds, longest wall."""

    rule: str
    jobs: int
    cpu: float
    wall: float
    longest: float


def cpu_per_rule(run: Run) -> list[RuleCpu]:
    """Per rule, from the benchmark files of this run's jobs; largest CPU first."""
    by: dict[str, list[Job]] = {}
    for j in run.jobs.values():
        by.setdefault(rule_family(j.rule), []).append(j)  # a batch rule's jobs count as its family's
    out = [
        RuleCpu(rule, len(js), sum(j.cpu or 0.0 for j in js), sum(j.duration for j in js),
                max(j.duration for j in js))
        for rule, js in by.items()
    ]
    return sorted(out, key=lambda r: (-r.cpu, r.rule))


def idle_core_seconds(run: Run, start: float = 0.0, end: float | None = None) -> tuple[float, float]:
    """(idle, available) core-seconds between ``start`` and ``end`` (default: the whole run).

    A job occupies its declared threads from its start to its end (log times);
    idle = Σ over the interval of max(0, cores − busy threads).
    """
    end = run.wall if end is None else end
    events: list[tuple[float, int]] = []
    for j in run.jobs.values():
        if j.end is None:
            continue
        a, b = max(j.start, start), min(j.end, end)
        if b > a:
            events += [(a, min(j.threads, run.cores)), (b, -min(j.threads, run.cores))]
    events.sort()
    idle, busy, t = 0.0, 0, start
    for when, delta in events:
        idle += max(0, run.cores - busy) * (when - t)
        busy += delta
        t = when
    idle += max(0, run.cores - busy) * (end - t)
    return idle, run.cores * max(0.0, end - start)


def _fmt(seconds: float) -> str:
    m, s = divmod(seconds, 60.0)
    return f"{int(m)} min {s:4.1f} s" if m else f"{s:.1f} s"


def report(run: Run, *, top_rules: int = 20, path_rows: int = 40) -> str:
    """The text the bench prints: wall time, the critical path, CPU per rule, idle cores."""
    steps = critical_path(run)
    rules = cpu_per_rule(run)
    cpu_total = sum(r.cpu for r in rules)
    lines = [
        f"run log: {run.log}",
        f"wall time {_fmt(run.wall)}; {len(run.jobs)} jobs on {run.cores} cores; "
        f"jobs' CPU {cpu_total:.0f} s (benchmark files: {sum(1 for j in run.jobs.values() if j.cpu is not None)} jobs)",
    ]
    if any(j.end is None for j in run.jobs.values()):
        lines.append(f"unfinished jobs: {sum(1 for j in run.jobs.values() if j.end is None)} (the run was interrupted or failed)")
    lines += ["", "critical path (each job waits for the one above it):",
              f"  {'start':>8} {'wait':>7} {'duration':>9} {'share':>6}  job"]
    shown = steps if len(steps) <= path_rows else steps[: path_rows // 2] + steps[-path_rows // 2:]
    for s in shown:
        lines.append(f"  {s.job.start:8.0f} {s.wait:7.0f} {s.job.duration:9.1f} {100 * s.share:5.1f}%  {s.job.label}")
    if steps:
        busy = sum(s.job.duration for s in steps)
        waits = sum(s.wait for s in steps)
        lines.append(f"  path: {len(steps)} jobs, running {_fmt(busy)} ({100 * busy / max(run.wall, 1e-9):.0f} % of wall), "
                     f"waiting for a core {_fmt(waits)} ({100 * waits / max(run.wall, 1e-9):.0f} %)")
        idle, avail = idle_core_seconds(run, 0.0, steps[-1].job.end)
        lines.append(f"  idle cores while the path ran: {idle:.0f} of {avail:.0f} core-seconds "
                     f"({100 * idle / max(avail, 1e-9):.0f} %)")
    lines += ["", "CPU per rule (benchmark files):", f"  {'cpu s':>8} {'wall s':>8} {'longest':>8} {'jobs':>5}  rule"]
    for r in rules[:top_rules]:
        lines.append(f"  {r.cpu:8.1f} {r.wall:8.1f} {r.longest:8.1f} {r.jobs:5d}  {r.rule}")
    if len(rules) > top_rules:
        rest = rules[top_rules:]
        lines.append(f"  {sum(r.cpu for r in rest):8.1f} {sum(r.wall for r in rest):8.1f} {'':8} "
                     f"{sum(r.jobs for r in rest):5d}  ({len(rest)} more rules)")
    return "\n".join(lines)
