"""What a claim is, its four verdicts, and the small CSV readers every claim module shares.

A :class:`Claim` is one row of ``claims.csv`` (:data:`CLAIM_COLUMNS`): the
paper's sentence (quoted, with section and figure), the claim as checked
here (what is compared with what, the tolerance the wording implies and
why), this run's numbers, the verdict (:data:`VERDICTS`) and its cause.
Rows of :data:`OURS` are checks of this project's own, not claims of a
paper: the report shows them apart and never counts them as the papers'.

The verdicts:

* ``reproduces`` — the statement holds on this run's numbers as the
  paper states it, without the tolerance;
* ``reproduces within the stated tolerance`` — it holds only within the
  tolerance its wording implies ("essentially the same" → a factor,
  "about 50°" → an interval; each row names it and why);
* ``differs`` — it does not; the cause gives the measurement that shows
  why, headed by one of :data:`CAUSES` (the data, the method — a stated
  deviation of this project's from the paper's —, or a real difference);
* ``not checkable here`` — it needs what a run cannot have (the papers'
  supplementary material, real captures, hardware, a user study), or this
  run's configuration does not measure it (the cause says which).

Standard library only.  Bad input (missing file or column, a number that
does not parse, two databases) raises :class:`ClaimsInputError` naming the
file.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from brdfpipe.core import integrity

__all__ = [
    "ClaimsInputError",
    "Claim",
    "ClaimInputs",
    "CLAIM_COLUMNS",
    "VERDICTS",
    "REPRODUCES",
    "WITHIN",
    "DIFFERS",
    "NOT_CHECKABLE",
    "CAUSES",
    "XU",
    "SOLER",
    "OURS",
    "TIE",
    "read_rows",
    "number",
    "one_database",
    "truthy",
    "g",
    "pct",
    "deg",
    "le",
    "graded",
    "not_measured",
    "absent",
    "not_checkable",
]

#: Columns of ``claims.csv`` (the table's one declaration).
CLAIM_COLUMNS: tuple[str, ...] = (
    "key", "paper", "where", "sentence", "claim", "measured", "value", "verdict", "cause", "database", "source",
)
REPRODUCES = "reproduces"
WITHIN = "reproduces within the stated tolerance"
DIFFERS = "differs"
NOT_CHECKABLE = "not checkable here"
#: The values of :attr:`Claim.verdict`, best first.
VERDICTS: tuple[str, ...] = (REPRODUCES, WITHIN, DIFFERS, NOT_CHECKABLE)
#: What a ``differs`` cause is headed by: the data (a property of this database), the method (a stated
#: deviation of this project's from the paper's), or a real difference (the paper's statement does not
#: hold here, and neither the data nor a deviation of method is shown to explain it).
CAUSES: tuple[str, ...] = ("the data", "the method", "a real difference")

XU = "Xu 2016"
SOLER = "Soler 2018"
#: The ``paper`` of a report-only row: a check of this project's own, not a claim of either paper.
OURS = "ours"
#: Relative tolerance of "at most" comparisons between two measured numbers (rounding; ties count as holding).
TIE: float = 1e-9


class ClaimsInputError(ValueError):
    """A CSV a claim is computed from is missing or malformed; the message names the file."""


@dataclass(frozen=True)
class Claim:
    """One claim of a paper (or one check of ours, ``paper`` :data:`OURS`) and what this run measured."""

    key: str
    paper: str  #: ``Xu 2016``, ``Soler 2018`` (or another source), or :data:`OURS`
    where: str  #: section / figure of the sentence
    sentence: str  #: the paper's sentence, quoted
    claim: str  #: the claim as checked here: what is compared with what, the tolerance and why
    measured: str  #: this run's numbers, in words
    value: float  #: the primary measured number (NaN when not measured)
    verdict: str  #: one of :data:`VERDICTS`
    cause: str  #: why: the measurement behind the verdict (a ``differs`` one headed by one of :data:`CAUSES`)
    database: str  #: from the CSV's ``database`` column ("" when not measured)
    source: str  #: the file(s) it was computed from
    figures: tuple[str, ...] = field(default=(), compare=False)  #: caption keys it belongs to

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"claim {self.key}: verdict {self.verdict!r} is not one of {VERDICTS}")
        if self.verdict == DIFFERS and not self.cause.startswith(CAUSES):
            raise ValueError(f"claim {self.key}: a 'differs' cause must start with one of {CAUSES}: {self.cause!r}")

    @property
    def ours(self) -> bool:
        """A check of this project's own (shown apart from the papers' claims)."""
        return self.paper == OURS

    def row(self) -> dict[str, str]:
        """The ``claims.csv`` row (``value`` with 9 significant digits, empty when not measured)."""
        d = {c: str(getattr(self, c)) for c in CLAIM_COLUMNS}
        d["value"] = "" if not math.isfinite(self.value) else f"{self.value:.9g}"
        return d


@dataclass(frozen=True)
class ClaimInputs:
    """The CSVs the claims read; None for an output this configuration does not produce."""

    errors: str | os.PathLike[str] | None = None
    training_size: str | os.PathLike[str] | None = None
    fig08_table: str | os.PathLike[str] | None = None
    #: ``evaluation/paper-directions.csv``: the directions Xu §6 states in words, evaluated (beside Fig. 8's optimum)
    paper_directions: str | os.PathLike[str] | None = None
    reproduction: str | os.PathLike[str] | None = None
    spaces: str | os.PathLike[str] | None = None
    paths: str | os.PathLike[str] | None = None
    traces: Mapping[int, str | os.PathLike[str]] = field(default_factory=dict)
    bounce_shares: str | os.PathLike[str] | None = None
    errormap_summary: str | os.PathLike[str] | None = None
    floor_check: str | os.PathLike[str] | None = None
    closedloop: str | os.PathLike[str] | None = None
    #: ``evaluation/unseen.csv`` (materials outside the training database) and the unseen databases' albedo CSVs
    unseen: str | os.PathLike[str] | None = None
    unseen_albedo: Sequence[str | os.PathLike[str]] = ()


# -- reading ------------------------------------------------------------------


def read_rows(path: str | os.PathLike[str], required: Sequence[str],
              optional: Sequence[str] = ()) -> tuple[Path, list[dict[str, str]], set[str]]:
    """A digest-checked CSV's rows (with ``__line__``), and which of ``optional`` its header has.

    ``optional``: columns a claim uses when the table has them (a column
    another stage is to add); the claim says what it used.
    """
    p = Path(path)
    if not p.is_file():
        raise ClaimsInputError(f"{p}: no such file")
    # every table a claim reads carries its digest (brdfpipe.core.integrity): checked here
    reader = csv.DictReader(io.StringIO(integrity.read_csv_text(p, error=ClaimsInputError), newline=""))
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in required if c not in header]
    if missing:
        raise ClaimsInputError(f"{p}: missing column(s) {', '.join(missing)} (header: {', '.join(header) or 'none'})")
    rows = []
    for i, r in enumerate(reader, start=3):  # line 1: the digest, 2: the header
        r = {k.strip(): (v or "").strip() for k, v in r.items() if k is not None}
        r["__line__"] = str(i)
        rows.append(r)
    return p, rows, {c for c in optional if c in header}


def number(p: Path, r: Mapping[str, str], column: str) -> float:
    """A cell as a float (NaN when empty); :class:`ClaimsInputError` naming the file and line otherwise."""
    text = r[column]
    if text == "":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise ClaimsInputError(f"{p}: line {r['__line__']}: column {column!r} is not a number: {text!r}") from None


def one_database(p: Path, rows: Iterable[Mapping[str, str]]) -> str:
    """The one database of ``rows`` ("" for no rows: the claim then says it is not measured)."""
    names = sorted({r["database"] for r in rows})
    if not names:
        return ""
    if len(names) != 1 or not names[0]:
        raise ClaimsInputError(f"{p}: expected one database in column 'database', got {names or 'no rows'}")
    return names[0]


def truthy(text: str) -> bool:
    """A CSV boolean: ``true`` (spaces.csv) or ``1`` (floor-check.csv)."""
    return text.strip().lower() in ("true", "1", "yes")


def g(x: float) -> str:
    """A measured number as the report prints it (3 significant digits)."""
    return "–" if not math.isfinite(x) else f"{x:.3g}"


def pct(x: float) -> str:
    """A share as a percentage (3 significant digits)."""
    return "–" if not math.isfinite(x) else f"{100 * x:.3g} %"


def deg(x: float) -> str:
    """An angle in degrees, as short as it goes."""
    return f"{x:g}°"


def le(a: float, b: float) -> bool:
    """``a ≤ b`` up to :data:`TIE` (rounding)."""
    return a <= b + TIE * abs(b)


def graded(strict: bool, tolerant: bool) -> str:
    """The verdict of a claim whose strict reading is ``strict`` and whose stated tolerance is ``tolerant``."""
    return REPRODUCES if strict else WITHIN if tolerant else DIFFERS


def not_measured(key: str, paper: str, where: str, sentence: str, claim: str, reason: str,
                 source: str = "", figures: Sequence[str] = ()) -> Claim:
    """A claim this run's configuration does not measure (``not checkable here``, with the reason)."""
    return Claim(key, paper, where, sentence, claim, f"not measured in this run: {reason}", math.nan, NOT_CHECKABLE,
                 f"not measured by this run: {reason}", "", source, tuple(figures))


def absent(key: str, paper: str, where: str, sentence: str, claim: str, what: str,
           figures: Sequence[str] = ()) -> Claim:
    """A claim whose input (``what``) this configuration does not produce (``not checkable here``)."""
    return not_measured(key, paper, where, sentence, claim, f"{what} is not produced by this configuration",
                        figures=figures)


def not_checkable(key: str, paper: str, where: str, sentence: str, needs: str, figures: Sequence[str] = ()) -> Claim:
    """A claim no run can check: it ``needs`` the papers' supplementary material, real captures, hardware …"""
    return Claim(key, paper, where, sentence, f"not checked: it needs {needs}", "–", math.nan, NOT_CHECKABLE,
                 f"needs {needs}", "", "", tuple(figures))
