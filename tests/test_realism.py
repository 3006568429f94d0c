"""brdfpipe.acquisition.realism: the statistics that compare a database with another (issue 22, item 5)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.acquisition import realism
from brdfpipe.data import merl, provenance

TH = np.radians(realism.theta_h_centres())  # θh of the bin centres
UNMEASURED = ~merl.measured_mask()


def table(profile: np.ndarray, colour=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A (3, 90, 90, 180) table that depends on θh only, unmeasured cells negative."""
    t = np.empty(merl.SHAPE)
    for c in range(3):
        t[c] = colour[c] * profile[:, None, None]
        t[c][UNMEASURED] = -1.0
    return t


def lobe(alpha: float, kd: float = 0.1, ks: float = 2.0) -> np.ndarray:
    """kd/π + ks·exp(−tan²θh/α²): half width at half maximum atan(α√ln2) over the floor."""
    return kd / math.pi + ks * np.exp(-np.tan(TH) ** 2 / alpha**2)


@pytest.mark.parametrize("alpha", [0.03, 0.1, 0.3])
def test_width_recovers_a_known_lobe(alpha: float) -> None:
    expected = math.degrees(math.atan(alpha * math.sqrt(math.log(2.0))))
    assert realism.specular_width(table(lobe(alpha))) == pytest.approx(expected, abs=0.1)


def test_width_grows_with_roughness_and_ignores_colour_and_floor() -> None:
    widths = [realism.specular_width(table(lobe(a))) for a in (0.05, 0.1, 0.2, 0.4)]
    assert widths == sorted(widths) and len(set(widths)) == 4
    assert realism.specular_width(table(lobe(0.1, kd=0.5), (0.2, 0.5, 0.9))) == pytest.approx(widths[1], abs=1e-9)


def test_no_peak_has_no_width() -> None:
    flat = np.full(merl.N_THETA_H, 0.3)
    rising = 0.1 + 0.2 * np.sin(TH) ** 2  # a sheen: brightest away from the mirror direction
    assert math.isnan(realism.specular_width(table(flat)))
    assert math.isnan(realism.specular_width(table(rising)))


def test_albedo_of_a_lambertian_table() -> None:
    a = realism.normal_albedo(table(np.full(merl.N_THETA_H, 1.0 / math.pi), (0.2, 0.5, 0.8)))
    assert a == pytest.approx([0.2, 0.5, 0.8], rel=0.01)


def grey_database(profiles: list[np.ndarray]) -> realism.Rows:
    return realism.rows_from_tables([f"m{i}" for i in range(len(profiles))], (table(p) for p in profiles))


def test_rows_keep_the_cells_measured_in_every_material() -> None:
    t = table(lobe(0.1))
    holed = t.copy()
    holed[1, 10, 20, 30] = -1.0  # one channel of one cell unmeasured in one material
    rows = realism.rows_from_tables(["a", "b"], [t, holed])
    expected = np.flatnonzero(merl.measured_mask().ravel())
    expected = expected[expected != 10 * 16200 + 20 * 180 + 30]
    assert np.array_equal(rows.cells, expected)
    assert rows.data.shape == (6, expected.size) and rows.data.dtype == np.float32
    assert np.array_equal(rows.data[4], t[1].ravel()[expected].astype(np.float32))


def test_identical_materials_have_no_spectrum_and_two_kinds_one_component() -> None:
    a, b = lobe(0.05), lobe(0.3, kd=0.4)
    with pytest.raises(ValueError, match="identical"):
        realism.pca_spectrum(grey_database([a, a, a]))
    s = realism.pca_spectrum(grey_database([a, b, a, b]))
    assert s.components == 1
    assert s.explained[0] == pytest.approx(1.0, abs=1e-9)
    assert s.sigma_ratio[1] == 0.0 and s.variance_per_entry > 0


def test_spectrum_is_ordered_and_counts_components() -> None:
    s = realism.pca_spectrum(grey_database([lobe(a, kd=k) for a, k in [(0.05, 0.1), (0.1, 0.3), (0.2, 0.05),
                                                                         (0.4, 0.5)]]))
    assert s.components == 3  # 4 distinct grey materials: rank 3 once centred
    assert list(s.explained) == sorted(s.explained) and s.explained[-1] == pytest.approx(1.0)
    assert list(s.sigma_ratio[:3]) == sorted(s.sigma_ratio[:3], reverse=True) and s.sigma_ratio[0] == 1.0


def test_holdout_reconstructs_copies_exactly_and_is_deterministic() -> None:
    a, b = lobe(0.05), lobe(0.3, kd=0.4)
    rows = grey_database([a, a, a, b, b, b])
    h = realism.holdout_errors(rows, ks=(0, 1, 2), folds=3, seed=1)
    assert h.rms_log[0] > 0.1  # the mean alone misses
    assert h.rms_log[1] < 1e-5 and h.relative[1] < 1e-5  # each held-out material has a copy in training
    again = realism.holdout_errors(rows, ks=(0, 1, 2), folds=3, seed=1)
    assert again == h
    with pytest.raises(ValueError, match="folds"):
        realism.holdout_errors(rows, folds=7)


def test_quantiles_are_ordered_and_skip_nan() -> None:
    rng = np.random.default_rng(0)
    q = realism.quantiles(np.append(rng.lognormal(size=50), np.nan))
    assert list(q) == sorted(q)
    assert realism.quantiles([1.0, 2.0, 3.0], (0.5,)) == (2.0,)
    assert all(math.isnan(x) for x in realism.quantiles([math.nan]))


def test_measure_table_and_json_round_trip(tmp_path) -> None:
    rows = grey_database([lobe(a, kd=k) for a, k in [(0.05, 0.1), (0.1, 0.3), (0.2, 0.05), (0.4, 0.5)]]
                         + [np.full(merl.N_THETA_H, 0.2)])
    r = realism.measure(rows, "synthetic", note="tiny", folds=2)
    assert r.no_peak == 1 and r.materials == 5
    assert list(r.width_quantiles) == sorted(r.width_quantiles)
    assert list(r.albedo_quantiles) == sorted(r.albedo_quantiles)
    path = tmp_path / "r.json"
    path.write_text(json.dumps(r.to_json()))
    back = realism.Realism.from_json(json.loads(path.read_text()))
    assert back == r
    text = realism.comparison_table([r, back])
    assert text.splitlines()[0] == "| statistic | synthetic, tiny | synthetic, tiny |"
    assert all(line.count("|") == 4 for line in text.splitlines())


def test_the_largest_value_is_each_materials_maximum() -> None:
    """``peak`` is the largest measured value of each table; unmeasured (negative) cells never count."""
    a = np.full(merl.SHAPE, 0.1)
    a[1, 3, 4, 5] = 7.5
    b = np.full(merl.SHAPE, 0.2)
    b[0, 0, 0, :] = -1.0  # unmeasured
    rows = realism.rows_from_tables(["a", "b"], [a, b])
    assert rows.peak.tolist() == [7.5, 0.2]


# --------------------------------------------------------------------------
# The command line: labelled by the files' provenance marks
# --------------------------------------------------------------------------


def write_folder(folder: Path, kinds: list[str]) -> None:
    """One table per entry of ``kinds``: ``synthetic`` (marked), ``merl-nbrdf`` (marked) or ``merl`` (unmarked)."""
    for i, kind in enumerate(kinds):
        name = f"m{i}"
        mark = {"synthetic": provenance.synthetic_mark(name=name, count=None, seed=None, noise=0.0, family="grey",
                                                         index=i, material_seed=i),
                "merl-nbrdf": provenance.fit_mark(database="merl-nbrdf", name=name, fit=name, archive="a.zip",
                                                  fit_sha256="0" * 64, clamped=0),
                "merl": None}[kind]
        colour = (0.5 + 0.1 * i, 1.0, 1.5 - 0.2 * i)  # channels differ: a held-out fold's one material has rank 1
        merl.write_merl(folder / f"{name}.binary", table(lobe(0.05 * (i + 1), kd=0.1 * (i + 1)), colour), mark=mark)


def one_error_line(capsys: pytest.CaptureFixture[str], command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"python -m brdfpipe.acquisition.realism {command}: error: "), err
    return err[0]


def test_measure_labels_the_column_by_the_files_marks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    synth_dir, merl_dir = tmp_path / "synth", tmp_path / "measured"
    write_folder(synth_dir, ["synthetic"] * 3)
    write_folder(merl_dir, ["merl"] * 2)
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert realism.main(["measure", str(synth_dir), "--note", "before (c461497)", "--out", str(a)]) == 0
    assert realism.main(["measure", str(merl_dir), "--out", str(b)]) == 0
    docs = [json.loads(p.read_text()) for p in (a, b)]
    assert [(d["database"], d["note"], d["materials"]) for d in docs] == [("synthetic", "before (c461497)", 3),
                                                                          ("merl", "", 2)]
    capsys.readouterr()
    assert realism.main(["table", str(a), str(b)]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "| statistic | synthetic, before (c461497) | merl |"


def test_measure_refuses_a_mixed_folder_and_a_note_naming_another_database(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's case: ``--label MERL`` headed a folder of fit-made and unmarked tables "MERL"."""
    mixed = tmp_path / "mixed"
    write_folder(mixed, ["merl-nbrdf", "merl"])
    out = tmp_path / "s.json"
    assert realism.main(["measure", str(mixed), "--note", "MERL", "--out", str(out)]) == 1
    line = one_error_line(capsys, "measure")
    assert f"folder {mixed}: mixes" in line and "m0.binary" in line and "m1.binary" in line
    synth_dir = tmp_path / "synth"
    write_folder(synth_dir, ["synthetic"] * 2)
    for note in ("MERL", "like merl-nbrdf", "two\nlines"):
        assert realism.main(["measure", str(synth_dir), "--note", note, "--out", str(out)]) == 1
        assert f"--note {note!r}" in one_error_line(capsys, "measure")
    with pytest.raises(SystemExit) as exit_:  # an argument error: argparse exits
        realism.main(["measure", str(synth_dir), "--label", "MERL", "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error: unrecognized arguments: --label MERL" in err[0], err
    assert not out.exists()
    realism.check_label("merl-nbrdf", "MERL (NBRDF fit)")  # parts of its own name
    realism.check_label("merl", "MERL, measured")
    with pytest.raises(ValueError, match="names the database 'merl'"):
        realism.check_label("nbrdf", "MERL materials")
    with pytest.raises(ValueError, match="not a database label"):
        realism.measure(grey_database([lobe(0.1), lobe(0.2)]), "MERL", folds=2)


def test_table_refuses_statistics_it_cannot_show(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A file of the old format (a free ``label``) or of other ``ks`` is one line naming it."""
    r = realism.measure(grey_database([lobe(0.05), lobe(0.1), lobe(0.2), lobe(0.4)]), "synthetic", folds=2)
    doc = r.to_json()
    old = {**{k: v for k, v in doc.items() if k not in ("database", "note")}, "label": "MERL"}
    other_ks = {**doc, "spectrum": {**doc["spectrum"], "ks": [1, 2]}}
    lying = {**doc, "note": "really merl-nbrdf"}
    for bad, why in ((old, "no 'database'"), (other_ks, "spectrum.ks is [1, 2]"), (lying, "names the database")):
        path = tmp_path / "s.json"
        path.write_text(json.dumps(bad))
        assert realism.main(["table", str(path)]) == 1
        line = one_error_line(capsys, "table")
        assert str(path) in line and why in line, line
    assert capsys.readouterr().out == ""
