"""report.sidebyside: the fidelity page — each claim, its sentence, and each run's verdict and cause side by side."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from brdfpipe.core import integrity
from brdfpipe.report import claims, rst, sidebyside


_CAUSE = {claims.REPRODUCES: "as stated", claims.WITHIN: "within 1.1×", claims.DIFFERS: "a real difference: far off",
          claims.NOT_CHECKABLE: "needs real captures"}


def _claim(key: str, measured: str, verdict: str, database: str, paper: str = "Xu 2016") -> claims.Claim:
    return claims.Claim(key=key, paper=paper, where="Fig. 5", sentence='"θh = 3°"', claim=f"{key} | as checked",
                        measured=measured, value=1.0 if verdict != claims.NOT_CHECKABLE else math.nan, verdict=verdict,
                        cause=f"{_CAUSE[verdict]} ({measured})", database=database, source="errors.csv")


def _write(folder: Path, rows: list[claims.Claim]) -> Path:
    folder.mkdir()
    csv_path = folder / "claims.csv"
    claims.write_claims(rows, csv_path=csv_path, json_path=folder / "claims.json", rst_path=folder / "claims.rst")
    return csv_path


def test_columns_are_headed_by_each_runs_database_and_hold_its_own_verdicts(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", claims.DIFFERS, "merl-nbrdf"),
                                _claim("albedo", "4.3 %", claims.WITHIN, "merl-nbrdf"),
                                _claim("loop", "+5 %", claims.REPRODUCES, "merl-nbrdf", paper=claims.OURS)])
    b = _write(tmp_path / "b", [_claim("one_shot", "θh 11.7°", claims.DIFFERS, "synthetic"),
                                _claim("bounces", "10.5 %", claims.REPRODUCES, "synthetic")])
    page = sidebyside.side_by_side_markdown([sidebyside.read_run(a), sidebyside.read_run(b)])
    header = next(line for line in page.splitlines() if line.startswith("| paper"))
    assert header == ("| paper | where | claim as checked (tolerance) | the paper's sentence | merl-nbrdf: verdict — cause "
                      "| synthetic: verdict — cause |")
    rows = {line.split(" | ")[2]: line for line in page.splitlines() if line.startswith("| Xu 2016")}
    assert rows["one_shot \\| as checked"].endswith(
        "| **differs** — a real difference: far off (θh 7.2°) | **differs** — a real difference: far off (θh 11.7°) |")
    assert '"θh = 3°"' in rows["one_shot \\| as checked"]  # the paper's sentence
    assert rows["albedo \\| as checked"].endswith(
        "| reproduces within the stated tolerance — within 1.1× (4.3 %) | (not in this run) |")
    assert rows["bounces \\| as checked"].endswith("| (not in this run) | reproduces — as stated (10.5 %) |")
    # the verdict counts of the papers' claims per run; our own checks in a section of their own, not counted
    assert "| differs | 1 | 1 |" in page and "| reproduces | 0 | 1 |" in page
    papers, ours = page.split("## Our own checks (not claims of the papers)")
    assert "loop" not in papers and "| ours | Fig. 5 | loop \\| as checked" in ours


def test_a_tampered_claims_file_is_refused_naming_it(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", claims.REPRODUCES, "merl-nbrdf")])
    a.write_text(a.read_text().replace("7.2", "3.0"))
    with pytest.raises(claims.ClaimsInputError, match="claims.csv"):
        sidebyside.read_run(a)
    out = tmp_path / "page.md"
    assert sidebyside.main([str(a), "--out", str(out)]) == 1
    assert not out.exists()


def test_command_line_writes_the_page(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", claims.REPRODUCES, "merl-nbrdf")])
    out = tmp_path / "page.md"
    assert sidebyside.main([str(a), "--out", str(out), "--title", "Claims"]) == 0
    assert out.read_text().startswith("# Claims\n")


def test_recorded_runs_leave_out_the_runs_own_database_and_name_the_key_of_a_bad_file(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", claims.DIFFERS, "merl-nbrdf")])
    b = _write(tmp_path / "b", [_claim("one_shot", "θh 11.7°", claims.DIFFERS, "synthetic")])
    entries = ["a/claims.csv", str(b)]  # relative to the root, or absolute
    runs = sidebyside.recorded_runs(entries, root=tmp_path, exclude="synthetic")
    assert [(r.database, r.source) for r in runs] == [("merl-nbrdf", "a/claims.csv")]
    assert [r.database for r in sidebyside.recorded_runs(entries, root=tmp_path, exclude="merl")] == [
        "merl-nbrdf", "synthetic"]
    with pytest.raises(claims.ClaimsInputError, match=r"report.compare_with\[1\] = 'x.csv': no such file"):
        sidebyside.recorded_runs(["a/claims.csv", "x.csv"], root=tmp_path, exclude="synthetic")
    with pytest.raises(claims.ClaimsInputError, match=r"compare_with\[1\].*second recorded run of merl-nbrdf"):
        sidebyside.recorded_runs(["a/claims.csv", "a/claims.csv"], root=tmp_path, exclude="synthetic")
    a.write_text(a.read_text().replace("7.2", "3.0"))  # edited: its digest no longer matches
    with pytest.raises(claims.ClaimsInputError, match=r"compare_with\[0\] = 'a/claims.csv': not a run's claims.csv"):
        sidebyside.recorded_runs(entries, root=tmp_path, exclude="synthetic")


def test_the_report_table_shows_recorded_runs_beside_this_run(tmp_path: Path) -> None:
    recorded = _write(tmp_path / "rec", [_claim("one_shot", "θh 11.7°", claims.DIFFERS, "synthetic"),
                                         _claim("bounces", "10.5 % | pipe", claims.REPRODUCES, "synthetic")])
    run = sidebyside.recorded_runs(["rec/claims.csv"], root=tmp_path, exclude="merl-nbrdf")
    mine = [_claim("one_shot", "θh 7.2°", claims.DIFFERS, "merl-nbrdf"),
            _claim("albedo", "4.3 %", claims.DIFFERS, "merl-nbrdf")]
    table = claims.claims_table_rst(mine, run)
    lines = table.splitlines()
    assert lines[2] == "   :widths: 6 8 20 22 20 8 16 6 22"
    assert "     - synthetic (recorded run)" in lines
    rows = table.split("   * - ")[2:]
    cell = f"**differs** — {claims.rst_cell('a real difference: far off (θh 11.7°)')} ({claims.rst_cell('θh 11.7°')})"
    assert rows[0].rstrip().splitlines()[-1] == f"     - {cell}"  # text, not markup
    assert rows[1].split("\n\n")[0].splitlines()[-1] == "     - (not in that run)"  # the recorded run has no albedo claim
    # a claim only the recorded run makes gets its own row, marked in this run's column
    assert len(rows) == 3 and "     - (not in this run)" in rows[2].splitlines()
    assert rows[2].split("\n\n")[0].splitlines()[-1].endswith(f"({claims.rst_cell('10.5 % | pipe')})")
    assert f"- synthetic: {rst.literal('rec/claims.csv')}" in lines
    # only this run's claims go to its CSV; the table holds the recorded column
    out = tmp_path / "out"
    out.mkdir()
    claims.write_claims(mine, csv_path=out / "claims.csv", json_path=out / "claims.json", rst_path=out / "claims.rst",
                        recorded=run)
    assert {r["database"] for r in claims.read_claims(out / "claims.csv")} == {"merl-nbrdf"}
    assert (out / "claims.rst").read_text() == table


def test_the_runs_recorded_with_brdfpipe_are_the_default_and_the_yes_no_ones_are_superseded(tmp_path: Path) -> None:
    """report.compare_with: null shows the shipped recorded runs: none of the four-verdict schema yet.

    The yes/no runs of 2026-11-28 were superseded by issue 32: a file of that schema given in
    report.compare_with is refused, naming the key and saying why.
    """
    import tomllib

    assert sidebyside.RECORDED == {}
    for exclude in ("merl-nbrdf", "synthetic", "rgl-nbrdf"):
        assert sidebyside.recorded_runs(None, root=Path("/nonexistent"), exclude=exclude) == []
    assert sidebyside.recorded_runs([], root=Path("/nonexistent"), exclude="synthetic") == []
    old = tmp_path / "old.csv"
    integrity.write_csv(old, "key,paper,where,claim,paper_value,measured,value,holds,database,source\n"
                             "k,Xu 2016,§6,c,p,m,1,yes,merl-nbrdf,errors.csv\n")
    with pytest.raises(claims.ClaimsInputError, match=r"compare_with\[0\] = 'old.csv': not a run's claims.csv: .*"
                                                      r"yes/no schema before issue 32.*superseded"):
        sidebyside.recorded_runs(["old.csv"], root=tmp_path, exclude="synthetic")
    # the package data would ship recorded runs (an installed, non-editable brdfpipe has them too)
    root = Path(__file__).resolve().parents[1]
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["brdfpipe.report"]
    assert globs == ["recorded/*.csv"]
