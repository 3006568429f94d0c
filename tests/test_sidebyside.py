"""report.sidebyside: the claims of several runs, each column headed by its CSV's own database."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from brdfpipe.report import claims, rst, sidebyside


def _claim(key: str, measured: str, holds: str, database: str) -> claims.Claim:
    return claims.Claim(key=key, paper="Xu 2016", where="Fig. 5", claim=f"{key} | as checked", paper_value="3°",
                        measured=measured, value=1.0 if holds != "not measured" else math.nan, holds=holds,
                        database=database, source="errors.csv")


def _write(folder: Path, rows: list[claims.Claim]) -> Path:
    folder.mkdir()
    csv_path = folder / "claims.csv"
    claims.write_claims(rows, csv_path=csv_path, json_path=folder / "claims.json", rst_path=folder / "claims.rst")
    return csv_path


def test_columns_are_headed_by_each_runs_database_and_hold_its_own_numbers(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", "no", "merl-nbrdf"),
                                _claim("albedo", "4.3 %", "no", "merl-nbrdf")])
    b = _write(tmp_path / "b", [_claim("one_shot", "θh 11.7°", "no", "synthetic"),
                                _claim("bounces", "10.5 %", "yes", "synthetic")])
    page = sidebyside.side_by_side_markdown([sidebyside.read_run(a), sidebyside.read_run(b)])
    header = next(line for line in page.splitlines() if line.startswith("| paper"))
    assert header.endswith("| merl-nbrdf | synthetic |")
    rows = {line.split(" | ")[2]: line for line in page.splitlines() if line.startswith("| Xu 2016")}
    assert "θh 7.2° (**NO**)" in rows["one_shot \\| as checked"] and "θh 11.7° (**NO**)" in rows["one_shot \\| as checked"]
    assert rows["albedo \\| as checked"].endswith("| 4.3 % (**NO**) | (not in this run) |")
    assert rows["bounces \\| as checked"].endswith("| (not in this run) | 10.5 % (yes) |")


def test_a_tampered_claims_file_is_refused_naming_it(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", "yes", "merl-nbrdf")])
    a.write_text(a.read_text().replace("7.2", "3.0"))
    with pytest.raises(claims.ClaimsInputError, match="claims.csv"):
        sidebyside.read_run(a)
    out = tmp_path / "page.md"
    assert sidebyside.main([str(a), "--out", str(out)]) == 1
    assert not out.exists()


def test_command_line_writes_the_page(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", "yes", "merl-nbrdf")])
    out = tmp_path / "page.md"
    assert sidebyside.main([str(a), "--out", str(out), "--title", "Claims"]) == 0
    assert out.read_text().startswith("# Claims\n")


def test_recorded_runs_leave_out_the_runs_own_database_and_name_the_key_of_a_bad_file(tmp_path: Path) -> None:
    a = _write(tmp_path / "a", [_claim("one_shot", "θh 7.2°", "no", "merl-nbrdf")])
    b = _write(tmp_path / "b", [_claim("one_shot", "θh 11.7°", "no", "synthetic")])
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
    recorded = _write(tmp_path / "rec", [_claim("one_shot", "θh 11.7°", "no", "synthetic"),
                                         _claim("bounces", "10.5 % | pipe", "yes", "synthetic")])
    run = sidebyside.recorded_runs(["rec/claims.csv"], root=tmp_path, exclude="merl-nbrdf")
    mine = [_claim("one_shot", "θh 7.2°", "no", "merl-nbrdf"), _claim("albedo", "4.3 %", "no", "merl-nbrdf")]
    table = claims.claims_table_rst(mine, run)
    lines = table.splitlines()
    assert lines[2] == "   :widths: 8 10 26 20 26 6 8 26"
    assert "     - synthetic (recorded run)" in lines
    rows = table.split("   * - ")[2:]
    assert rows[0].rstrip().splitlines()[-1] == f"     - {claims.rst_cell('θh 11.7°')} (**NO**)"  # text, not markup
    assert rows[1].split("\n\n")[0].splitlines()[-1] == "     - (not in that run)"  # the recorded run has no albedo claim
    # a claim only the recorded run makes gets its own row, marked in this run's column
    assert len(rows) == 3 and "     - (not in this run)" in rows[2].splitlines()
    assert rows[2].split("\n\n")[0].splitlines()[-1] == f"     - {claims.rst_cell('10.5 % | pipe')} (**yes**)"
    assert f"- synthetic: {rst.literal('rec/claims.csv')}" in lines
    # only this run's claims go to its CSV; the table holds the recorded column
    out = tmp_path / "out"
    out.mkdir()
    claims.write_claims(mine, csv_path=out / "claims.csv", json_path=out / "claims.json", rst_path=out / "claims.rst",
                        recorded=run)
    assert {r["database"] for r in claims.read_claims(out / "claims.csv")} == {"merl-nbrdf"}
    assert (out / "claims.rst").read_text() == table


def test_the_runs_recorded_with_brdfpipe_are_the_default_and_ship_with_the_package() -> None:
    """report.compare_with: null shows the shipped recorded runs, found from the package (a copied workflow too)."""
    import tomllib

    for exclude, want in (("merl-nbrdf", ["synthetic"]), ("synthetic", ["merl-nbrdf"]), ("rgl-nbrdf", ["merl-nbrdf", "synthetic"])):
        runs = sidebyside.recorded_runs(None, root=Path("/nonexistent"), exclude=exclude)
        assert [r.database for r in runs] == want
        assert all(r.source.startswith(f"brdfpipe's recorded run {sidebyside.RECORDED_RUN}") for r in runs)
    assert sidebyside.recorded_runs([], root=Path("/nonexistent"), exclude="synthetic") == []
    # the package data ships them (an installed, non-editable brdfpipe has them too)
    root = Path(__file__).resolve().parents[1]
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["brdfpipe.report"]
    package = root / "src" / "brdfpipe" / "report"
    shipped = {p for g in globs for p in package.glob(g)}
    assert set(sidebyside.RECORDED.values()) <= shipped
