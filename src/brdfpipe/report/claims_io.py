"""``claims.{csv,json,rst}``: writing a run's claims, reading another run's back, and the report's table.

``claims.csv`` has the columns :data:`~brdfpipe.report.claims_base.CLAIM_COLUMNS`
(with its digest line, like every table of the run).  A ``claims.csv`` of the
schema before issue 32 (columns ``paper_value`` and ``holds``, verdicts
yes/no/not measured) is *superseded*: its rows checked other statements
than today's claims, so it is refused with a message that says so, never
shown beside today's verdicts (``docs/results/claims.md`` keeps the last
such table as a record).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from brdfpipe.core import atomic, integrity
from brdfpipe.report import rst
from brdfpipe.report.claims_base import (
    CLAIM_COLUMNS,
    DIFFERS,
    NOT_CHECKABLE,
    OURS,
    REPRODUCES,
    VERDICTS,
    WITHIN,
    Claim,
    ClaimsInputError,
    read_rows,
)
from brdfpipe.report.claims_ours import is_unseen_claim

__all__ = [
    "SUPERSEDED_COLUMNS",
    "write_claims",
    "read_claims",
    "RunClaims",
    "read_run",
    "verdict_counts",
    "claims_table_rst",
    "rst_cell",
]

#: The columns that mark a ``claims.csv`` of the yes/no schema before issue 32 (superseded).
SUPERSEDED_COLUMNS: tuple[str, ...] = ("paper_value", "holds")


def write_claims(claims: Sequence[Claim], *, csv_path: str | os.PathLike[str], json_path: str | os.PathLike[str],
                 rst_path: str | os.PathLike[str], recorded: Sequence[RunClaims] = ()) -> None:
    """``claims.csv`` (:data:`CLAIM_COLUMNS`), ``claims.json`` (with the figures of each claim) and the rst table.

    The table shows the ``recorded`` runs' columns beside this run's (:func:`claims_table_rst`);
    the CSV and JSON hold this run's claims only.
    """
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(CLAIM_COLUMNS), lineterminator="\n")
    w.writeheader()
    for c in claims:
        w.writerow(c.row())
    integrity.write_csv(csv_path, buf.getvalue())  # with its digest line, like every table of the run
    records = [{**c.row(), "value": None if not math.isfinite(c.value) else c.value, "figures": list(c.figures)}
               for c in claims]
    atomic.write_text(json_path, json.dumps(records, indent=1, ensure_ascii=False) + "\n")
    atomic.write_text(rst_path, claims_table_rst(claims, recorded))


def read_claims(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The rows of a ``claims.csv`` (digest checked; a superseded yes/no file is refused, saying so)."""
    p, rows, old = read_rows(path, (), (*SUPERSEDED_COLUMNS, *CLAIM_COLUMNS))
    if set(SUPERSEDED_COLUMNS) <= old:
        raise ClaimsInputError(f"{p}: claims of the yes/no schema before issue 32 (columns paper_value, holds): "
                               "superseded by the four verdicts; write it again from its run (rule write_claims)")
    missing = [c for c in CLAIM_COLUMNS if c not in old]
    if missing:
        raise ClaimsInputError(f"{p}: missing column(s) {', '.join(missing)}")
    out = [{c: r[c] for c in CLAIM_COLUMNS} for r in rows]
    bad = next((r for r in rows if r["verdict"] not in VERDICTS), None)
    if bad is not None:
        raise ClaimsInputError(f"{p}: line {bad['__line__']}: verdict {bad['verdict']!r} is not one of "
                               f"{', '.join(VERDICTS)}")
    return out


def rst_cell(text: str) -> str:
    """Table-cell text safe for reStructuredText: renders exactly ``text`` (:func:`brdfpipe.report.rst.text`)."""
    return rst.text(text)


#: How the report marks each verdict (a difference stands out).
MARK = {REPRODUCES: "reproduces", WITHIN: "reproduces within the stated tolerance", DIFFERS: "**differs**",
        NOT_CHECKABLE: "not checkable here"}


class RunClaims:
    """The claims of another run, read back from its ``claims.csv``: its database and its rows by claim key.

    ``database`` is the one the CSV's rows name (claims about materials
    outside the run's database, :func:`is_unseen_claim`, name theirs and do
    not count), never what a caller believes it to be: a run made on
    synthetic data cannot be shown as MERL.  ``source`` is how the run is
    named where it is shown (the path as configured).
    """

    def __init__(self, path: Path, rows: Sequence[Mapping[str, str]], source: str | None = None) -> None:
        self.path = path
        self.source = str(path) if source is None else source
        self.rows = {r["key"]: dict(r) for r in rows}
        self.order = [r["key"] for r in rows]
        names = sorted({r["database"] for r in rows if r["database"] and not is_unseen_claim(r["key"])})
        if len(names) > 1:
            raise ClaimsInputError(f"{path}: claims of several databases: {names}")
        self.database = names[0] if names else "(nothing measured)"


def read_run(path: str | os.PathLike[str], source: str | None = None) -> RunClaims:
    """Another run's ``claims.csv`` (its digest checked; :class:`ClaimsInputError` naming the file)."""
    p = Path(path)
    return RunClaims(p, read_claims(p), source)


def verdict_counts(rows: Sequence[Mapping[str, str]]) -> dict[str, int]:
    """How many of the papers' claims (not :data:`OURS`) have each verdict, in :data:`VERDICTS` order."""
    return {v: sum(r["verdict"] == v and r["paper"] != OURS for r in rows) for v in VERDICTS}


def _recorded_cell(run: RunClaims, key: str) -> str:
    row = run.rows.get(key)
    if row is None:
        return "(not in that run)"
    return f"{MARK[row['verdict']]} — {rst_cell(row['cause'])} ({rst_cell(row['measured'])})"


def _table(title: str, rows: Sequence[Mapping[str, str]], recorded: Sequence[RunClaims], extra: Sequence[str]) -> list[str]:
    """One list-table: paper, where, sentence, claim as checked, this run, verdict, cause, database, recorded runs."""
    widths = " ".join(["6 8 20 22 20 8 16 6", *["22"] * len(recorded)])
    lines = [f".. list-table:: {rst_cell(title)}", "   :header-rows: 1", f"   :widths: {widths}", "",
             "   * - paper", "     - where", "     - the paper's sentence", "     - claim as checked (tolerance)",
             "     - this run", "     - verdict", "     - cause", "     - database"]
    lines += [f"     - {rst_cell(r.database)} (recorded run)" for r in recorded]
    for c in rows:
        cells = [rst_cell(c[f]) for f in ("paper", "where", "sentence", "claim", "measured")]
        cells += [MARK[c["verdict"]], rst_cell(c["cause"]), rst_cell(c["database"])]
        cells += [_recorded_cell(r, c["key"]) for r in recorded]
        lines.append(f"   * - {cells[0]}")
        lines += [f"     - {x}" for x in cells[1:]]
    for key in extra:  # claims only a recorded run makes (e.g. about unseen materials)
        first = next(r.rows[key] for r in recorded if key in r.rows)
        cells = [rst_cell(first[f]) for f in ("paper", "where", "sentence", "claim")]
        cells += ["(not in this run)", "", "", ""] + [_recorded_cell(r, key) for r in recorded]
        lines.append(f"   * - {cells[0]}")
        lines += [f"     - {x}" for x in cells[1:]]
    return lines + [""]


def claims_table_rst(claims: Sequence[Claim], recorded: Sequence[RunClaims] = ()) -> str:
    """The claims tables (``list-table``): the papers' claims, then the project's own checks.

    Each run of ``recorded`` (another database's run, read back with
    :func:`read_run`) adds a column: its verdict, cause and measurement for
    the same claim, headed by the database its CSV names; a claim only a
    recorded run makes gets a row of its own, "(not in this run)" in this
    run's columns; the runs' files are listed under the tables.
    """
    rows = [c.row() for c in claims]
    own = {r["key"] for r in rows}
    extra = list(dict.fromkeys(k for r in recorded for k in r.order if k not in own))
    ours_of = {k: next(r.rows[k] for r in recorded if k in r.rows)["paper"] == OURS for k in extra}
    lines = _table("The papers' claims", [r for r in rows if r["paper"] != OURS], recorded,
                   [k for k in extra if not ours_of[k]])
    mine = [r for r in rows if r["paper"] == OURS]
    if mine or any(ours_of.values()):
        lines += _table("Our own checks (not claims of the papers)", mine, recorded, [k for k in extra if ours_of[k]])
    if recorded:
        lines += ["Recorded runs, each column read from its ``claims.csv`` (digest checked):", ""]
        lines += [f"- {rst_cell(r.database)}: {rst.literal(r.source)}" for r in recorded]
    return "\n".join(lines).rstrip("\n") + "\n"
