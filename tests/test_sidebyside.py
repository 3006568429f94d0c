"""report.sidebyside: the claims of several runs, each column headed by its CSV's own database."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from brdfpipe.report import claims, sidebyside


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
