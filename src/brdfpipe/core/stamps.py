"""Job stamps: what made an output, kept where Snakemake cannot lose it.

Snakemake decides that a job is out of date from the modification times of its
files and from its metadata records (``.snakemake/metadata``).  The records
are not a safe ground for "no stale result":

* the params trigger compares the *set* of a job's parameter values, without
  their names (``persistence.params_changed``): swapping two values
  (``closed_loop.seed`` and ``closed_loop.spp``), or setting a value that
  another parameter already has while the old one stays in use, changes
  nothing that Snakemake sees, and the job keeps its old outputs;
* an output with no record at all (``.snakemake`` removed to clear a lock
  left by a killed run, results copied or restored, ``--drop-metadata``,
  ``--cleanup-metadata``) is never rerun on a change of parameters, code or
  input list (``Reason.no_metadata`` does not make a job run);
* a job's records are written when it *ends* (also when it failed), with
  the checksums its inputs have at that moment: a process that outlived its
  run and wrote meanwhile changes what they vouch for (against that, see the
  job lease of :mod:`brdfpipe.core.atomic`).

A stamp is one small file per job, ``results/.stamps/<rule>/<job>``, that
holds the record of everything that defines the job (:func:`job_record`):
the rule, its wildcards, its parameters by name (the code digest of its
script and of the library modules it runs among them,
:func:`brdfpipe.core.version.script_digest`) and the list of its input
files.  Every rule takes its own stamp as an input (``stamp=stamp_of("<rule>")``
in ``workflow/rules/``; the Snakefile refuses a rule without it).  While a
run builds its DAG, :func:`stamp_input` rewrites a stamp whose record
differs from the job's current one, so the stamp is newer than the job's
outputs and Snakemake reruns the job (and, through its files, everything
downstream) from modification times alone:

* any change of what defines a job reruns it, with or without Snakemake's
  records; with them, going back to a definition whose outputs are still
  there reruns nothing (Snakemake finds the stamp's checksum as recorded);
* a stamp counts only once its job succeeded: the job's own process writes
  the stamp's text to its *done mark* (:func:`done_path`,
  :func:`mark_done`, called by :func:`brdfpipe.core.logutil.log_to` when the
  job's block ends without error); a stamp whose done mark differs (a job
  that was killed, failed, or never started after the stamp was written) is
  out of date, and is rewritten with a ``retry`` line that changes its text:
  Snakemake records a failed job's input checksums too (its
  ``persistence.finished`` runs before it removes the outputs), so a stamp
  rewritten with the same text would look unchanged to it, and a killed
  job's missing outputs, which nothing downstream asks for any more, would
  never be made again;
* a temporary output (``temp()``) may be gone: its job's stamp stays, so a
  change upstream of it is still seen;
* a job with an output missing (not a temporary one) is out of date too:
  Snakemake would not rebuild a missing file that nothing out of date asks
  for (a job that an interrupted run started, whose outputs it removed, or
  that failed while the files downstream were already there);
* a job whose stamp does not exist yet (a fresh working directory, or
  results made before stamps existed) runs: nothing tells what made its
  outputs.

Only a run writes stamps, in Snakemake's main process and when no other
Snakemake holds the working directory's lock; a dry run (or a report, or a
run that will stop at the lock) that finds a stamp out of date points the
job to a fresh file under ``.snakemake/`` instead (:data:`PLAN_FILE`), so a
dry run plans what the run will do and leaves ``results/`` alone.  Jobs never share a stamp (its name is the
job's rule and wildcards).  The record is canonical JSON (sorted keys): the
order of a mapping's keys changes nothing.  Not covered: the rule's
``threads`` and ``resources``, and the versions of third-party packages.

Standard library only: the Snakefile computes stamps while it builds the DAG.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import quote

from brdfpipe.core import atomic

__all__ = [
    "DIGEST_CHARS",
    "PLAN_FILE",
    "StampError",
    "job_record",
    "job_key",
    "done_path",
    "read_stamp",
    "mark_done",
    "stamp_input",
]

#: Hex characters of the sha256 kept in a file name (80 bits).
DIGEST_CHARS = 20
#: Longest job key kept readable in a file name; longer keys are shortened with a digest of their own.
_MAX_KEY = 100


class StampError(ValueError):
    """A job cannot be stamped (a parameter that is not plain data), or a stamp does not match its record."""


def _plain(rule: str, what: str, value: Any) -> Any:
    """``value`` as JSON-ready plain data (tuples become lists), or :class:`StampError` naming it."""
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(rule, what, v) for v in value]
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise StampError(f"rule {rule}: {what} has a key of type {type(k).__name__} ({k!r}); "
                                 "stamps need str keys")
            out[k] = _plain(rule, what, v)
        return out
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise StampError(f"rule {rule}: {what} is of type {type(value).__name__}; stamps need plain data "
                     "(str, number, bool, None, list, dict)")


def job_record(rule: str, wildcards: Mapping[str, str], params: Mapping[str, Any], inputs: Iterable[Any]) -> str:
    """The canonical JSON text of what defines one job (its stamp's first line).

    ``params``: every parameter by name, functions already evaluated;
    ``inputs``: the input files in the rule's order (patterns as written,
    function results as returned), the stamp itself left out.  Keys are
    sorted, so the order of a mapping's keys (a config section rewritten by a
    YAML tool) changes nothing.
    """
    doc = {
        "rule": rule,
        "wildcards": {str(k): str(v) for k, v in wildcards.items()},
        "params": {str(k): _plain(rule, f"param {k}", v) for k, v in params.items()},
        "input": [_plain(rule, "an input", f) for f in inputs],
    }
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True)


def job_key(wildcards: Mapping[str, str]) -> str:
    """A file-name-safe name of one job of a rule: ``name=value`` of its wildcards, sorted (``_`` if none).

    Values are percent-encoded (``/``, ``,``, ``=``, ``%`` and anything but
    letters, digits and ``-._~``); a key longer than 100 characters keeps
    its first 60 and a digest of the whole (file names stay below 255 bytes).
    """
    if not wildcards:
        return "_"
    key = ",".join(f"{k}={quote(str(wildcards[k]), safe='')}" for k in sorted(wildcards))
    if len(key) > _MAX_KEY:
        key = f"{key[:60]}~{hashlib.sha256(key.encode('utf-8')).hexdigest()[:DIGEST_CHARS]}"
    return key


#: What a dry run gives a job whose stamp is out of date instead of it (under the working directory):
#: one empty file, written when the first such job is met, newer than every output.
PLAN_FILE = ".snakemake/brdfpipe-stamps/out-of-date"
_planned: set[str] = set()


def done_path(stamp: str | os.PathLike[str]) -> Path:
    """The done mark of ``stamp``: ``<stamp>.done``, the stamp's text once its job succeeded.

    Job keys (:func:`job_key`) start with ``name=`` or are ``_``, so no
    stamp's name ends with ``.done`` of another's.
    """
    return Path(f"{os.fspath(stamp)}.done")


def read_stamp(path: str | os.PathLike[str]) -> str | None:
    """The text of a stamp or done mark, ``None`` if there is none (or it is not text)."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except (FileNotFoundError, NotADirectoryError, IsADirectoryError, UnicodeDecodeError):
        return None


def mark_done(stamp: str | os.PathLike[str], text: str) -> None:
    """Record that the job of ``stamp``, started with the stamp's ``text``, succeeded (atomic).

    Called by the job's own process at the end of its work
    (:func:`brdfpipe.core.logutil.log_to`); under a job lease
    (:func:`brdfpipe.core.atomic.job_lease`) a superseded job cannot write it.
    """
    atomic.write_text(done_path(stamp), text)


def _retry_text(record: str, current: str) -> str:
    """The stamp's next text for an unchanged record whose job has not succeeded: a ``retry`` line that differs."""
    return f"{record}\nretry {hashlib.sha256(current.encode('utf-8')).hexdigest()[:DIGEST_CHARS]}\n"


def stamp_input(path: str, record: str, mode: str, *, outputs_missing: bool = False) -> str:
    """The file a job takes as its stamp input; ``path``: its stamp, ``record``: its current :func:`job_record`.

    The stamp is up to date when its first line is ``record``, its done mark
    (:func:`done_path`) holds the stamp's text (the job succeeded since the
    stamp was written) and not ``outputs_missing`` (an output of the job
    that is not temporary is missing: an interrupted run removed it, and
    Snakemake does not rebuild a missing file that nothing out of date asks
    for).  Otherwise it is out of date: its next text is ``record`` when the
    record changed, else ``record`` and a ``retry`` line that differs from
    the current text (:func:`_retry_text`).  ``mode``:

    * ``"run"`` (a run's main process): write an out-of-date stamp
      (atomically: a new modification time and a new text); return ``path``;
    * ``"plan"`` (a dry run, a report, a working directory locked by another
      Snakemake): return ``path`` if it is up to date, else
      :data:`PLAN_FILE`, written by this process once (a modification time
      as fresh as a run will give ``path``);
    * ``"read"`` (a job's own Snakemake process): return ``path``, write nothing.
    """
    if mode == "read":
        return path
    if mode not in ("run", "plan"):
        raise ValueError(f"unknown stamp mode {mode!r}")
    current = read_stamp(path)
    same_record = current is not None and current.split("\n", 1)[0] == record
    if same_record and not outputs_missing and read_stamp(done_path(path)) == current:
        return path
    if mode == "run":
        atomic.write_text(path, _retry_text(record, current) if same_record else record + "\n")
        return path
    here = os.path.abspath(PLAN_FILE)
    if here not in _planned:  # a marker, not a result: no atomic write, no fsync
        Path(PLAN_FILE).parent.mkdir(parents=True, exist_ok=True)
        Path(PLAN_FILE).touch()
        _planned.add(here)
    return PLAN_FILE
