"""Fidelity: each claim of both papers, its sentence, and each run's verdict and cause side by side.

Each run's ``results/report/claims.csv`` (digest-checked, through
:func:`brdfpipe.report.claims.read_run`) gives one column; the rows are the
claims in the order of the first run, claims missing from a run say so; the
papers' claims first, then the checks of our own (``ours``).  A column is
headed by the database its CSV names (``database`` column), never by what
the caller believes it to be: a run made on synthetic data cannot be headed
"MERL".  Claims about materials outside a run's database
(:func:`brdfpipe.report.claims.is_unseen_claim`) name those materials'
database and do not count.  Nothing is typed in: every cell is a run's own
verdict and cause.

``python -m brdfpipe.report.sidebyside MERL_RUN/results/report/claims.csv
SYNTHETIC_RUN/results/report/claims.csv --out docs/results/fidelity.md``
writes the page ``docs/results/fidelity.md``; it heads itself with that
command (:func:`command_line`).  A ``claims.csv`` of the yes/no schema before
issue 32 is refused as superseded.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from brdfpipe.core import atomic
from brdfpipe.core.command import OneLineParser, run
from brdfpipe.report import claims as claims_mod
from brdfpipe.report.claims import RunClaims, read_run

__all__ = ["RunClaims", "read_run", "RECORDED_RUN", "RECORDED", "recorded_runs", "command_line",
           "side_by_side_markdown", "write_run_page", "build_parser", "main"]

#: The recorded runs' tag (date and machine): the default workflow on each database on the 2-core
#: development machine, 2026-11-29, with 256-px images: merl-nbrdf at commit eb6130c, synthetic at
#: 55163f0 (docs/results/runs/2026-11-29-cpu/ keeps their configs; docs/results/fidelity.md shows their
#: claims side by side).  Shown beside a run's claims by default (config ``report.compare_with``: null).
RECORDED_RUN: str = "2026-11-29-cpu"
#: The runs recorded with brdfpipe: each one's claims.csv, shipped in the package so that a copied
#: workflow or an installed library finds them.
RECORDED: dict[str, Path] = {
    db: Path(__file__).resolve().parent / "recorded" / f"{RECORDED_RUN}-{db}.csv" for db in ("merl-nbrdf", "synthetic")
}


def recorded_runs(entries: Sequence[str] | None, *, root: Path, exclude: str) -> list[RunClaims]:
    """The recorded runs of config ``report.compare_with`` shown beside a run on database ``exclude``.

    ``None``: the runs recorded with brdfpipe (:data:`RECORDED`).  Otherwise
    each entry is a run's ``claims.csv``; a relative path is taken from
    ``root`` (the working directory).  A run on the database ``exclude`` (the
    run's own) is left out: the run's own column is that database's.  A file
    that is missing, damaged, without claims or with several databases'
    claims, or a second run of one database, raises
    :class:`~brdfpipe.report.claims.ClaimsInputError` naming the key.
    """
    if entries is None:
        shipped = [read_run(path, f"brdfpipe's recorded run {RECORDED_RUN} ({db})") for db, path in RECORDED.items()]
        return [run for run in shipped if run.database != exclude]
    runs: list[RunClaims] = []
    seen: dict[str, int] = {}
    for k, entry in enumerate(entries):
        key = f"config report.compare_with[{k}] = {entry!r}"
        path = Path(entry) if os.path.isabs(entry) else root / entry
        if not path.is_file():
            raise claims_mod.ClaimsInputError(f"{key}: no such file ({path})")
        try:
            run = read_run(path, entry)
        except (claims_mod.ClaimsInputError, OSError, UnicodeDecodeError, ValueError) as err:
            raise claims_mod.ClaimsInputError(f"{key}: not a run's claims.csv: {err}") from None
        if not run.rows or run.database == "(nothing measured)":
            raise claims_mod.ClaimsInputError(f"{key}: measures no claim on any database")
        if run.database in seen:
            raise claims_mod.ClaimsInputError(
                f"{key}: a second recorded run of {run.database} (report.compare_with[{seen[run.database]}] is one)")
        seen[run.database] = k
        if run.database != exclude:
            runs.append(run)
    return runs


def _cell(text: str) -> str:
    """Markdown table-cell text: pipes escaped, line breaks flattened."""
    return " ".join(text.split()).replace("\\", "\\\\").replace("|", "\\|")


DEFAULT_TITLE = "Fidelity: the papers' claims as the papers state them"
_MARK = {claims_mod.DIFFERS: "**differs**"}


def _shell_word(word: str) -> str:
    """``word`` as a shell reads it back: bare, in double quotes (no ``"$`\\`` inside), or :func:`shlex.quote`d."""
    if re.fullmatch(r"[\w@%+=:,./-]+", word):
        return word
    return f'"{word}"' if not re.search(r'["$`\\!]', word) else shlex.quote(word)


def command_line(claims: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], title: str) -> str:
    """The command that writes the page ``out`` from ``claims`` (shown on the page, so it can be made again)."""
    words = ["python", "-m", "brdfpipe.report.sidebyside", *map(str, claims)]
    if title != DEFAULT_TITLE:
        words += ["--title", title]
    return " ".join(_shell_word(w) for w in [*words, "--out", str(out)])


def _table(runs: Sequence[RunClaims], keys: Sequence[str], first: dict[str, dict[str, str]]) -> list[str]:
    lines = ["| paper | where | claim as checked (tolerance) | the paper's sentence | "
             + " | ".join(f"{_cell(r.database)}: verdict — cause" for r in runs) + " |",
             "|" + "---|" * (4 + len(runs))]
    for k in keys:
        f = first[k]
        cells = [f["paper"], f["where"], f["claim"], f["sentence"]]
        for r in runs:
            row = r.rows.get(k)
            cells.append("(not in this run)" if row is None else
                         f"{_MARK.get(row['verdict'], row['verdict'])} — {row['cause']}")
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return lines


def side_by_side_markdown(runs: Sequence[RunClaims], *, title: str = DEFAULT_TITLE, command: str | None = None) -> str:
    """A Markdown page: the verdict counts per run, then one row per claim — claim, sentence, each run's verdict and cause.

    ``command``: the command line that writes the page (:func:`command_line`), shown at its top.
    """
    if not runs:
        raise ValueError("no runs to compare")
    keys = list(dict.fromkeys(list(runs[0].order) + [k for r in runs[1:] for k in r.order]))
    first = {k: next(r.rows[k] for r in runs if k in r.rows) for k in keys}
    lines = [f"# {_cell(title)}", ""]
    if command is not None:
        lines += ["Generated by", "", "```sh", command, "```", ""]
    lines += ["from these runs' `claims.csv` (each column is headed by the database its CSV names):", ""]
    lines += [f"- {_cell(r.database)}: `{_cell(str(r.path))}`" for r in runs]
    lines += ["", "Each claim as its paper states it: the sentence, what is compared with what and the tolerance its "
              "wording implies. Verdicts: *reproduces*; *reproduces within the stated tolerance*; *differs*, its "
              "cause headed by the data, the method (a stated deviation of ours) or a real difference; *not "
              "checkable here* (the supplementary material, real captures, hardware — or not measured by that "
              "run's configuration).", "",
              "| the papers' claims | " + " | ".join(_cell(r.database) for r in runs) + " |",
              "|" + "---|" * (1 + len(runs))]
    counts = [claims_mod.verdict_counts(list(r.rows.values())) for r in runs]
    lines += [f"| {v} | " + " | ".join(str(c[v]) for c in counts) + " |" for v in claims_mod.VERDICTS]
    papers = [k for k in keys if first[k]["paper"] != claims_mod.OURS]
    ours = [k for k in keys if first[k]["paper"] == claims_mod.OURS]
    lines += ["", "## The papers' claims", ""] + _table(runs, papers, first)
    if ours:
        lines += ["", "## Our own checks (not claims of the papers)", ""] + _table(runs, ours, first)
    return "\n".join(lines) + "\n"


def write_run_page(path: str | os.PathLike[str], *, claims_csv: str | os.PathLike[str],
                   recorded: Sequence[RunClaims] = ()) -> None:
    """A run's fidelity page (rule ``write_claims``): its own claims beside the ``recorded`` runs of other databases.

    ``claims_csv`` (the run's ``results/report/claims.csv``, just written) is
    read back digest-checked, so the page shows what the CSV holds.  The page
    names the rule, not a command: it is made again by the run.
    """
    runs = [read_run(claims_csv, str(claims_csv)), *recorded]
    page = side_by_side_markdown(runs)
    note = (f"Written by the run (rule `write_claims`) from its `{_cell(str(claims_csv))}`"
            + (" and the recorded runs of other databases (config `report.compare_with`)" if recorded else "")
            + ".")
    head, rest = page.split("\n", 1)
    atomic.write_text(path, f"{head}\n\n{note}\n{rest}")


#: The command's name in its messages.
PROG = "python -m brdfpipe.report.sidebyside"


def build_parser() -> OneLineParser:
    """The argument parser of ``python -m brdfpipe.report.sidebyside``."""
    parser = OneLineParser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument("claims", nargs="+", help="a run's results/report/claims.csv, one per column")
    parser.add_argument("--out", required=True, help="the Markdown page to write (docs/results/fidelity.md)")
    parser.add_argument("--title", default=DEFAULT_TITLE)
    return parser


def _write_page(args: argparse.Namespace) -> int:
    """Check --out against the inputs and its folder, read every run, then write the page."""
    atomic.check_not_input(args.out, args.claims)
    if Path(args.out).is_dir():
        raise atomic.OutputError(f"--out {args.out}: is a folder; give the Markdown file to write")
    atomic.check_writable(args.out)
    runs = [read_run(path) for path in args.claims]  # each digest-checked: ClaimsInputError naming the file
    page = side_by_side_markdown(runs, title=args.title, command=command_line(args.claims, args.out, args.title))
    atomic.write_text(args.out, page)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``CLAIMS_CSV ... --out PAGE.md``; the exit status.

    Errors: one line ``python -m brdfpipe.report.sidebyside: error: ...``
    naming the file or option (:func:`brdfpipe.core.command.run`); an
    ``--out`` that is one of the inputs is refused before anything is read.
    """
    args = build_parser().parse_args(argv)
    return run(PROG, lambda: _write_page(args))


if __name__ == "__main__":
    sys.exit(main())
