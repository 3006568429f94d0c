"""brdfpipe.acquisition.realism: the statistics that compare a database with another (issue 22, item 5)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from brdfpipe.acquisition import realism
from brdfpipe.data import merl

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
    r = realism.measure(rows, "tiny", folds=2)
    assert r.no_peak == 1 and r.materials == 5
    assert list(r.width_quantiles) == sorted(r.width_quantiles)
    assert list(r.albedo_quantiles) == sorted(r.albedo_quantiles)
    path = tmp_path / "r.json"
    path.write_text(json.dumps(r.to_json()))
    back = realism.Realism.from_json(json.loads(path.read_text()))
    assert back == r
    text = realism.comparison_table([r, back])
    assert text.splitlines()[0] == "| statistic | tiny | tiny |"
    assert all(line.count("|") == 4 for line in text.splitlines())


def test_the_largest_value_is_each_materials_maximum() -> None:
    """``peak`` is the largest measured value of each table; unmeasured (negative) cells never count."""
    a = np.full(merl.SHAPE, 0.1)
    a[1, 3, 4, 5] = 7.5
    b = np.full(merl.SHAPE, 0.2)
    b[0, 0, 0, :] = -1.0  # unmeasured
    rows = realism.rows_from_tables(["a", "b"], [a, b])
    assert rows.peak.tolist() == [7.5, 0.2]
