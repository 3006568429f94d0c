"""Every claim of the report, checked as its paper states it (brdfpipe.report.claims, issue 32).

For each claim small hand-made CSVs make the paper's statement hold, hold
only within the tolerance its wording implies, and fail; each verdict is
asserted, and so is the tolerance in the row's text.  A claim whose wording
has no tolerance ("strictly lower", "on each BRDF", a bound) is shown to
apply none: a case a tolerance would let through differs.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import pytest

from brdfpipe.core import integrity
from brdfpipe.report import claims
from brdfpipe.report import claims_ours as ours
from brdfpipe.report import claims_setups as xu_setups
from brdfpipe.report import claims_soler as soler
from brdfpipe.report import claims_xu as xu
from brdfpipe.registry import tables

R, W, D, N = claims.REPRODUCES, claims.WITHIN, claims.DIFFERS, claims.NOT_CHECKABLE


def write_csv(path: Path, columns: Sequence[str], rows: Sequence[Mapping[str, object]]) -> Path:
    """A table as the workflow writes it: with its digest line (brdfpipe.core.integrity)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow(r)
    integrity.write_csv(path, buf.getvalue())
    return path


class Tables:
    """Small CSVs in one folder, each a new file."""

    def __init__(self, folder: Path) -> None:
        self.folder, self.count = folder, 0

    def __call__(self, columns: Sequence[str], rows: Sequence[Mapping[str, object]]) -> Path:
        self.count += 1
        return write_csv(self.folder / f"t{self.count}.csv", columns, rows)

    def errors(self, values: Mapping[tuple[str, float, str, int], float],
               materials: Mapping[tuple[str, float, str, int], Mapping[str, float]] | None = None) -> xu.ErrorMeans:
        rows = []
        for (setup, fov, metric, n), v in values.items():
            base = {"database": "synthetic", "split": "train", "setup": setup, "fov": fov, "metric": metric, "n": n}
            rows.append({**base, "material": "mean", "channel": "all", "kind": "rms_log", "value": v})
            rows.append({**base, "material": "mean", "channel": "all", "kind": "relrms_linear", "value": 99.0})
        for (setup, fov, metric, n), per in (materials or {}).items():
            base = {"database": "synthetic", "split": "train", "setup": setup, "fov": fov, "metric": metric, "n": n}
            for m, v in per.items():  # channels around the material's value: their mean is it
                rows += [{**base, "material": m, "channel": c, "kind": "rms_log", "value": v + d}
                         for c, d in (("R", -0.01), ("G", 0.0), ("B", 0.01))]
        return xu.read_errors(self(tables.ERRORS, rows))


@pytest.fixture
def t(tmp_path: Path) -> Tables:
    return Tables(tmp_path)


P, NF, E, K, NI = "point", "nearfield", "error", "condition", "condition_nielsen"


def nielsen(values: Mapping[int, float]) -> dict[tuple[str, float, str, int], float]:
    return {(P, 0.0, NI, n): v for n, v in values.items()}


def check(c: claims.Claim, verdict: str, *texts: str) -> claims.Claim:
    assert c.verdict == verdict, (c.key, c.verdict, c.cause, c.measured)
    for text in texts:
        assert text in c.claim, (c.key, text, c.claim)  # the tolerance is in the row's text
    assert c.sentence.startswith('"') and c.cause
    return c


# -- Xu: accuracy per number of samples, against the previous work ----------------------


def test_two_images_against_twenty_samples_of_the_previous_work(t: Tables) -> None:
    """§6 "essentially the same accuracy as 20 samples": 2 images at 25° vs Nielsen's κ as released, ×1.1."""
    curve = nielsen({18: 0.23, 19: 0.20, 20: 0.21})

    def claim(a: float, fov: float = 25.0) -> claims.Claim:
        return xu.images_vs_previous_work(t.errors({**curve, (NF, fov, E, 2): a, (NF, 45.0, E, 2): 0.1}), 2)

    c = check(claim(0.20), R, "1.1×", "previous work", "Nielsen 2015 as released", "FOV 25°")
    assert c.value == pytest.approx(0.20 / 0.21) and "as accurate as 19 samples" in c.measured
    assert c.database == "synthetic"
    check(claim(0.22), W)  # 0.22 ≤ 1.1 × 0.21
    c = check(claim(0.25), D)
    assert c.cause.startswith("a real difference: 0.25 is ×1.19") and "the images match its 18 samples" in c.cause
    # the eq.-15 and eq. 6 point sets are not what the paper compared with: they do not change the verdict
    e = t.errors({**curve, (NF, 25.0, E, 2): 0.25, (P, 0.0, E, 20): 0.5, (P, 0.0, K, 20): 0.5})
    assert xu.images_vs_previous_work(e, 2).verdict == D
    # without the previous work's sets: not checkable here, saying why
    c = xu.images_vs_previous_work(t.errors({(NF, 25.0, E, 2): 0.2, (P, 0.0, K, 20): 0.5}), 2)
    assert c.verdict == N and "min κ, first n components" in c.cause and math.isnan(c.value) and c.database == ""


def test_one_image_against_about_five_samples_of_the_previous_work(t: Tables) -> None:
    """§6 "similar accuracy as about 5 samples": ≤ N(5) strictly, ≤ 1.1 × the largest of N(4…6) within."""
    curve = nielsen({3: 0.5, 4: 0.40, 5: 0.36, 6: 0.34})

    def claim(a: float) -> claims.Claim:
        return xu.images_vs_previous_work(t.errors({**curve, (NF, 25.0, E, 1): a}), 1)

    check(claim(0.35), R, "1.1×", "n = 4–6")
    check(claim(0.43), W)  # 0.43 ≤ 1.1 × 0.40
    c = check(claim(0.45), D)
    assert "the image matches its 4 samples" in c.cause


def test_five_eq15_samples_against_twenty_of_the_previous_work(t: Tables) -> None:
    """Appendix B "our 5 directions is comparable to 20 samples using the previous condition number metric"."""
    def claim(e5: float) -> claims.Claim:
        return xu.eq15_vs_previous_work(t.errors({**nielsen({10: 0.3, 20: 0.21}), (P, 0.0, E, 5): e5}))

    check(claim(0.20), R, "1.25×", "comparable")
    check(claim(0.25), W)  # ≤ 1.25 × 0.21
    check(claim(0.27), D)


def test_eq15_strictly_below_the_previous_work_at_every_n(t: Tables) -> None:
    """Fig. 19 "strictly lower error than previous work": no tolerance, so 1 % above at one n differs."""
    ours_ = {(P, 0.0, E, n): v for n, v in ((1, 0.8), (2, 0.6), (3, 0.5))}
    check(xu.eq15_below_previous_work(t.errors({**ours_, **nielsen({1: 0.9, 2: 0.7, 3: 0.55})})), R, "no tolerance")
    c = check(xu.eq15_below_previous_work(t.errors({**ours_, **nielsen({1: 0.9, 2: 0.7, 3: 0.495})})), D)
    assert "n = 3 (0.5 vs 0.495)" in c.cause


def test_a_smooth_curve_against_the_previous_works_oscillating_one(t: Tables) -> None:
    """Appendix B: min E(S) gives "a smooth graph" (rises ≤ 2 % within the tolerance); Nielsen's "oscillates"."""
    osc = nielsen({1: 0.9, 2: 0.7, 3: 0.72, 4: 0.6})

    def claim(e3: float, theirs: dict = osc) -> claims.Claim:  # type: ignore[type-arg]
        return xu.smooth_vs_oscillating(t.errors({(P, 0.0, E, 1): 0.8, (P, 0.0, E, 2): 0.6, (P, 0.0, E, 3): e3,
                                                  (P, 0.0, E, 4): 0.5, **theirs}))

    check(claim(0.55), R, "2%")
    check(claim(0.61), W)  # +1.7 %
    assert check(claim(0.65), D).cause.startswith("a real difference: min E(S)'s curve rises by 8.3% at n = 3")
    monotone = nielsen({1: 0.9, 2: 0.7, 3: 0.65, 4: 0.6})
    assert "falls monotonically" in check(claim(0.55, monotone), D).cause


def test_per_material_lower_on_each_brdf(t: Tables) -> None:
    """Fig. 18 "lower error than previous work … on each BRDF", 5 samples, per held-out material."""
    mean = {(P, 0.0, E, 5): 0.3, (P, 0.0, NI, 5): 0.4}

    def claim(b_mat: float) -> claims.Claim:
        return xu.per_material_vs_previous_work(t.errors(mean, {(P, 0.0, E, 5): {"a": 0.2, "b": 0.3},
                                                                 (P, 0.0, NI, 5): {"a": 0.25, "b": b_mat}}))

    check(claim(0.35), R, "every held-out material", "no tolerance")
    c = check(claim(0.297), D)  # the previous work 1 % better for one material: no tolerance
    assert "not lower for b (0.3 vs 0.297)" in c.cause
    # fewer samples when n_max_point is smaller, as Fig. 18's analogue draws
    small = t.errors({}, {(P, 0.0, E, 3): {"a": 0.2}, (P, 0.0, NI, 3): {"a": 0.3}})
    assert "3 point samples" in check(xu.per_material_vs_previous_work(small), R).claim


def test_eq15_against_eq6_over_all_k_for_point_samples(t: Tables) -> None:
    """§6 "our error metric performs somewhat better even in that case", κ as eq. 6 prints it (all k)."""
    ours_ = {(P, 0.0, E, n): v for n, v in ((1, 0.8), (2, 0.6), (3, 0.5), (4, 0.45))}

    def claim(*kappa: float) -> claims.Claim:
        return xu.eq15_vs_eq6_point(t.errors({**ours_, **{(P, 0.0, K, n): v for n, v in zip((1, 2, 3, 4), kappa)}}))

    c = check(claim(0.8, 0.7, 0.6, 0.5), R, "all k components", "10%")  # a tie at n = 1 (one row: κ = 1) counts
    assert c.value == pytest.approx(1.0)
    check(claim(0.8, 0.7, 0.6, 0.44), W)  # median lower, n = 4 worse by 2 %
    check(claim(0.8, 0.58, 0.48, 0.44), D)  # better on the median: not the paper's claim


def test_eq15_against_kappa_for_near_field_images(t: Tables) -> None:
    """§6, Fig. 5 "significant advantages": better at every (FOV, n), κ's error ≥ 1.25× on the median."""
    ours_ = {(NF, f, E, n): v for f in (15.0, 25.0) for n, v in ((1, 0.4), (2, 0.3))}

    def claim(*kappa: float) -> claims.Claim:
        keys = [(NF, f, K, n) for f in (15.0, 25.0) for n in (1, 2)]
        return xu.eq15_vs_kappa_nearfield(t.errors({**ours_, **dict(zip(keys, kappa))}))

    check(claim(0.9, 0.7, 0.8, 0.6), R, "1.25×", "significant")
    check(claim(0.9, 0.7, 0.8, 0.29), W)  # κ better by 3 % at one (FOV, n)
    assert "only ×" in check(claim(0.44, 0.33, 0.44, 0.33), D).cause  # ×1.1: not significant


# -- Xu: the set-ups -------------------------------------------------------------------------------


def test_larger_fields_of_view_help(t: Tables) -> None:
    def claim(e45: float) -> claims.Claim:
        return xu_setups.larger_fovs_help(t.errors({(NF, 15.0, E, 2): 0.4, (NF, 25.0, E, 2): 0.3,
                                                    (NF, 45.0, E, 2): e45, (NF, 15.0, E, 1): 0.5}))

    check(claim(0.25), R, "5%")
    check(claim(0.31), W)  # +3.3 % from 25° to 45°
    assert "n = 2, 25° → 45°" in check(claim(0.33), D).cause


def test_25_degrees_nearly_best_for_two_shot_acquisition(t: Tables) -> None:
    """§6 "25° is already nearly best", at n = 2 (two-shot), within 1.1× the best FOV; the finding when it is not."""
    def claim(e45: float) -> claims.Claim:
        return xu_setups.fov25_nearly_best(t.errors({(NF, 15.0, E, 2): 0.4, (NF, 25.0, E, 2): 0.262,
                                                     (NF, 35.0, E, 2): 0.3, (NF, 45.0, E, 2): e45}))

    check(claim(0.3), R, "1.1×", "2 near-field images")
    check(claim(0.25), W)  # ×1.05
    c = check(claim(0.17), D)
    assert c.cause.startswith("a real difference: the 2-image error keeps falling past 25° (25° 0.262")
    assert c.value == pytest.approx(0.262 / 0.17)


def test_training_size_decreases_and_may_rise_slightly(t: Tables) -> None:
    """Fig. 7 "a steady decrease", "the error curve can therefore increase slightly": rises ≤ 5 % within."""
    cols = tables.TRAINING_SIZE

    def claim(*values: float) -> claims.Claim:
        rows = [{"database": "merl", "n_train": n, "order_seed": s, "material": "mean", "channel": "all",
                 "kind": "rms_log", "value": v + 0.01 * s} for n, v in zip((30, 60, 90), values) for s in (0, 1)]
        return xu_setups.training_size_decreasing(t(cols, rows))

    c = check(claim(0.5, 0.4, 0.3), R, "5%", "increase slightly")
    assert c.database == "merl" and c.measured.startswith("mean of 2 material orders: 30: 0.505, 60: 0.405")
    check(claim(0.5, 0.4, 0.41), W)  # +2.4 %
    check(claim(0.5, 0.4, 0.45), D)
    assert xu_setups.training_size_decreasing(None).verdict == N


FIG08_COLS = tables.FIG08


def fig08(t: Tables, rows: Sequence[tuple[float, int, int, float, float]]) -> Path:
    """(fov, n_images, image, θh, incidence) rows of split all, and one of the train split that must not count."""
    out = [dict.fromkeys(FIG08_COLS, 0) | {"fov_deg": f, "n_images": n, "image": i, "theta_h_deg": th,
                                           "light_theta_deg": ti, "expected_error": 0.3, "split": "all",
                                           "database": "synthetic"} for f, n, i, th, ti in rows]
    out.append(dict.fromkeys(FIG08_COLS, 0) | {"fov_deg": 25, "n_images": 1, "image": 1, "theta_h_deg": 3,
                                               "light_theta_deg": 50, "split": "train", "database": "synthetic"})
    return t(FIG08_COLS, out)


def test_one_shot_optimum_at_25_degrees(t: Tables) -> None:
    """§6 "slightly offspecular (θh = 3°) at an angle of incidence of about 50°": 2.5–3.5° and ±5° strictly;
    within: the mirror direction inside the image (θh ≤ FOV/4) and ±10°."""
    def claim(th: float, ti: float) -> claims.Claim:
        return xu_setups.one_shot_optimum(fig08(t, [(15, 1, 1, 40.0, 10.0), (25, 1, 1, th, ti)]))

    c = check(claim(3.2, 51.0), R, "2.5–3.5°", "±5°", "FOV/4 = 6.25°", "±10°")
    assert c.value == 3.2 and "other FOVs: 15°: θh 40.0°, 10.0°" in c.measured  # the other FOVs reported, not judged
    check(claim(5.5, 57.0), W)
    c = check(claim(7.2, 52.8), D)
    assert c.cause.startswith("a real difference: the optimum found here (E(S) 0.3) has θh 7.2° > 6.25°")


def test_two_shot_first_direction_exact_specular_at_15_degrees(t: Tables) -> None:
    def claim(th: float, ti: float) -> claims.Claim:
        return xu_setups.two_shot_first_specular(fig08(t, [(15, 2, 1, 30.0, 80.0), (15, 2, 2, th, ti)]))

    check(claim(0.3, 61.0), R, "θh ≤ 0.5°", "60 ± 2.5°", "FOV/4 = 3.75°")  # the image nearer the mirror direction
    check(claim(3.0, 64.0), W)
    check(claim(7.0, 60.0), D)


def paper_directions(t: Tables, key: str, images: Sequence[tuple[float, float]], e: float,
                     database: str = "synthetic", split: str = "all", fov: float | None = None) -> Path:
    """paper-directions.csv: one set (θh, incidence per image, its E(S)), and another split's that must not count."""
    fov = {"one-shot": 25.0, "two-shot": 15.0}[key] if fov is None else fov
    base = {"database": database, "direction": key, "fov_deg": fov, "grid": 256, "n_images": len(images),
            "theta_d_deg": 0, "phi_d_deg": 0, "expected_error": e, "matching": 1802, "evaluated": 604}
    rows = [base | {"split": split, "image": i + 1, "chosen_by": "sentence" if i == 0 else "optimiser",
                    "theta_h_deg": th, "light_theta_deg": ti} for i, (th, ti) in enumerate(images)]
    rows.append(base | {"split": "train", "image": 1, "chosen_by": "sentence", "theta_h_deg": 9.0,
                        "light_theta_deg": 9.0, "expected_error": 0.01})
    return t(tables.PAPER_DIRECTIONS, rows)


def test_the_paper_directions_e_is_reported_beside_the_optimum(t: Tables) -> None:
    """Where the optimum found here is not the paper's direction, the row gives the paper's direction's E(S) and the
    ratio to the optimum's; the verdict stays the comparison of directions."""
    table = fig08(t, [(25, 1, 1, 7.2, 52.8), (15, 2, 1, 7.0, 60.0), (15, 2, 2, 30.0, 80.0)])
    without = xu_setups.one_shot_optimum(table)
    assert without.cause.endswith("the paper's direction is not evaluated by this run")
    c = check(xu_setups.one_shot_optimum(table, paper=paper_directions(t, "one-shot", [(3.025, 54.95)], 0.36)), D)
    finding = ("the paper's direction (θh 3.0°, incidence 55.0°: the best of the 1,802 configurations matching the "
               "sentence, 604 evaluated: φd on the optimiser's coarsest step, the best refined) has E(S) 0.36 here, "
               "×1.20 the optimum's 0.3")
    assert c.cause == "a real difference: the optimum found here (E(S) 0.3) has θh 7.2° > 6.25°; " + finding
    assert c.measured.endswith("; " + finding) and c.value == without.value and c.source.count(".csv") == 2
    # the sentence fixes the claim's text: what "the paper's direction" is
    assert "nearest 3° (3.025°)" in c.claim and "50 ± 5°" in c.claim and "given its best value" in c.claim
    # the paper's direction better than the optimum: the search missed it (the method)
    better = xu_setups.one_shot_optimum(table, paper=paper_directions(t, "one-shot", [(3.025, 54.95)], 0.25))
    assert better.verdict == D and better.cause.startswith("the method: the search stopped above the paper's")
    assert "×0.83 the optimum's 0.3" in better.cause
    # two images: the first the sentence's, the second the optimiser's addition
    two = xu_setups.two_shot_first_specular(
        table, paper=paper_directions(t, "two-shot", [(0.469, 60.93), (35.47, 72.49)], 0.33))
    check(two, D)
    assert ("(θh 0.47°, incidence 60.9°: the best of the 1,802 configurations" in two.cause
            and "with the optimiser's best addition to it (θh 35.5°, incidence 72.5°) has E(S) 0.33 here, ×1.10 the "
                "optimum's 0.3" in two.cause)
    assert "held" in two.claim and "60 ± 2.5°" in two.claim
    # a verdict that holds keeps its cause; the number is still measured
    held = xu_setups.one_shot_optimum(fig08(t, [(25, 1, 1, 3.2, 51.0)]),
                                      paper=paper_directions(t, "one-shot", [(3.025, 50.1)], 0.3))
    check(held, R)
    assert held.cause == "θh 3.2°, incidence 51.0°" and "×1.00 the optimum's 0.3" in held.measured
    # no set at the claim's FOV and split: as without the table
    other = xu_setups.one_shot_optimum(table, paper=paper_directions(t, "one-shot", [(3.0, 50.0)], 0.3, fov=35.0))
    assert other.cause == without.cause
    with pytest.raises(claims.ClaimsInputError, match="database 'merl'"):
        xu_setups.one_shot_optimum(table, paper=paper_directions(t, "one-shot", [(3.0, 50.0)], 0.3, database="merl"))
    # through compute_claims: the input reaches both rows
    rows = {c.key: c for c in claims.compute_claims(claims.ClaimInputs(
        fig08_table=table, paper_directions=paper_directions(t, "one-shot", [(3.025, 54.95)], 0.36)))}
    assert rows["xu-one-shot-optimum"].cause == c.cause
    assert rows["xu-two-shot-first-specular"].cause.endswith("not evaluated by this run")


def fixed_errors(t: Tables, cam2: float, cam3: float = 0.3, point2: float = 0.6) -> xu.ErrorMeans:
    return t.errors({(P, 0.0, E, 1): 0.8, (P, 0.0, E, 2): point2, (NF, 25.0, E, 1): 0.35, (NF, 25.0, E, 2): 0.25,
                     (NF, 25.0, E, 3): 0.2, ("fixed_camera", 25.0, E, 1): 0.35, ("fixed_camera", 25.0, E, 2): cam2,
                     ("fixed_camera", 25.0, E, 3): cam3})


def test_fixed_camera_significantly_below_point_sampling(t: Tables) -> None:
    check(xu_setups.fixed_vs_point(fixed_errors(t, 0.27)), R, "1.25×", "significantly lower")
    check(xu_setups.fixed_vs_point(fixed_errors(t, 0.27, point2=0.3)), W)  # ×1.11 only
    check(xu_setups.fixed_vs_point(fixed_errors(t, 0.27, point2=0.26)), D)


def test_fixed_camera_only_somewhat_above_near_field(t: Tables) -> None:
    """§8 "only somewhat more than the unconstrained near-field case": 1 to 1.25× at n = 2."""
    check(xu_setups.fixed_vs_nearfield(fixed_errors(t, 0.27)), R, "1.25×", "somewhat more")
    c = check(xu_setups.fixed_vs_nearfield(fixed_errors(t, 0.245)), W)  # 2 % below: the search's scatter
    assert c.cause.startswith("the method: a fixed set-up is a constrained near-field one")
    assert check(xu_setups.fixed_vs_nearfield(fixed_errors(t, 0.35)), D).cause.startswith("a real difference")


def test_fixed_camera_decreases_more_slowly(t: Tables) -> None:
    check(xu_setups.fixed_slower_decrease(fixed_errors(t, 0.27, cam3=0.25)), R)  # ×1.08 at 2, ×1.25 at 3
    check(xu_setups.fixed_slower_decrease(fixed_errors(t, 0.27, cam3=0.2)), D)


# -- Soler ----------------------------------------------------------------------------------------


def test_reproduction_perfect_and_pca_not(t: Tables) -> None:
    cols = tables.REPRODUCTION

    def claim(gp: float, pca40: float = 0.05) -> claims.Claim:
        return soler.reproduction_vs_pca(t(cols, [
            {"database": "synthetic", "space": "raw", "material": m, "method": meth, "k": k, "relative_error": v}
            for m in ("a", "b", "c") for meth, k, v in (("pca", 20, 0.1), ("pca", 40, pca40), ("gplvm", 2, gp))]))

    check(claim(1e-12), R, "1e-06", "1 %")
    check(claim(0.005), W)
    check(claim(0.06), D)
    assert "PCA reproduces as well" in check(claim(0.005, pca40=0.001), D).cause


FIT = {"space": "standardised", "mu": 1e-5, "normalise": "true", "method": "newton", "init": "best"}
RECIPE = {"space": "raw", "mu": 1e-4, "normalise": "false", "method": "hooke-jeeves", "init": "pca"}
SPACES = ("database", *soler.FIT_COLUMNS, "q", "default", *soler.CLAMPED_ALBEDO, "albedo_clamped_points",
          "albedo_bad_hull", "albedo_bad_map", *soler.JUMP_COLUMNS)


def spaces(t: Tables, clamped: float, *, unclamped: float = 0.0, fit: Mapping[str, object] = FIT,
           jump: tuple[float, float, float] = (1e-4, 1e-3, 5e-3), worst: str = "a>b",
           recipe: tuple[float, float] | None = None) -> Path:
    """spaces.csv: the default candidate (q = 2 the claim's; q = 5's albedo does not count), another
    candidate that fails everything, and with ``recipe`` (clamped share, largest jump) the paper's recipe."""
    def row(name: str, f: Mapping[str, object], q: int, default: bool, c: float, u: float,
            j: tuple[float, float, float], w: str) -> dict[str, object]:
        return {"database": "synthetic", "candidate": name, **f, "q": q, "default": str(default).lower(),
                "albedo_clamped_bad_hull": c, "albedo_clamped_bad_map": "" if q == 5 else c,
                "albedo_clamped_points": 2000, "albedo_bad_hull": u, "albedo_bad_map": "" if q == 5 else u,
                "jump_nn_median_1e-6": j[0], "jump_nn_p90_1e-6": j[1], "jump_nn_max_1e-6": j[2],
                "jump_nn_worst": w}

    rows = [row("std", fit, 2, True, clamped, unclamped, jump, worst),
            row("std", fit, 5, True, 0.5, 0.5, (jump[0], jump[1], jump[2] / 2), "c>d"),
            row("other", FIT, 2, False, 0.5, 0.5, (0.9, 0.9, 0.9), "e>f")]
    if recipe is not None:
        rows += [row("paper", RECIPE, q, False, recipe[0], recipe[0], (recipe[1] / 4, recipe[1] / 2, recipe[1]), "g>h")
                 for q in (2, 5)]
    return t(SPACES, rows)


def test_albedo_in_the_unit_interval_at_q2(t: Tables) -> None:
    """Fig. 7 "observed to be limited to [0, 1]" (q = 2), on the clamped table a renderer receives."""
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.0)), R, "1 %", "q = 2", "negative values clamped")
    assert "not the paper's recipe" in c.cause
    check(soler.albedo_in_unit_interval(spaces(t, 0.005)), W)
    # the unclamped table's negative lobes are a diagnostic: the verdict is on the clamped table
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.0, unclamped=0.0687)), R)
    assert "unclamped Σ wᵢ Aᵢ (negative lobes): q = 2: 6.87 % of the hull" in c.measured
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.03)), D)
    assert c.cause.startswith("the method: the default candidate is not the paper's recipe") and "not measured" in c.cause
    # with the paper's recipe among the candidates: the method when it passes, a real difference when it fails too
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.03, recipe=(0.0, 0.0))), D)
    assert c.cause.startswith("the method: the paper's recipe (paper) passes (0 % of its hull)")
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.03, recipe=(0.2, 0.0))), D)
    assert c.cause.startswith("a real difference: the paper's recipe (paper) fails too (20 % of its hull)")
    c = check(soler.albedo_in_unit_interval(spaces(t, 0.03, fit=RECIPE)), D)
    assert c.cause.startswith("a real difference: 3 % of the q = 2 hull") and "the paper's recipe" in c.measured


def test_a_negligible_discontinuity_next_to_each_material(t: Tables) -> None:
    """§3 "a negligible discontinuity in the interpolant": ≤ 1 % of a material's norm next to it (t = 1e-6)."""
    check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(1e-4, 1e-3, 0.005))), R, "1 %", "t = 1e-6")
    check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(1e-4, 0.005, 0.48))), W)
    c = check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(0.01, 0.03, 0.48), worst="blue-fabric>green-fabric")),
              D)
    assert c.cause.startswith("the method: the default candidate is not the paper's recipe") and "48 %" in c.cause
    assert "blue-fabric → green-fabric, q = 2" in c.cause and c.value == 0.48  # other candidates do not count
    c = check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(0.01, 0.03, 0.48), recipe=(0.0, 0.003))), D)
    assert c.cause.startswith("the method: the paper's recipe (paper) passes (jumps by at most 0.3 %)")
    c = check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(0.01, 0.03, 0.48), recipe=(0.0, 0.2))), D)
    assert c.cause.startswith("a real difference: the paper's recipe (paper) fails too")
    nan = float("nan")  # a non-linear space: not measured
    check(soler.negligible_discontinuity(spaces(t, 0.0, jump=(nan, nan, nan))), N)


PATHS = ("database", "path", "t", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound")


def paths(t: Tables, mid_a: float, dev: float) -> Path:
    return t(PATHS, [{"database": "synthetic", "path": "a--b", "t": x, "perceptual_a": da, "perceptual_b": 2 - da,
                      "perceptual_ab": 2, "deviation": dev, "bound": 1.0}
                     for x, da in ((0.0, 0.0), (0.5, mid_a), (0.75, 1.5), (1.0, 2.0))])


def test_eq7_bound(t: Tables) -> None:
    """A bound: no tolerance, 1 % over it differs."""
    check(soler.eq7_bound(paths(t, 1.2, 0.5)), R, "no tolerance")
    check(soler.eq7_bound(paths(t, 1.2, 1.01)), D)


def test_likelihood_rises_and_levels_off(t: Tables) -> None:
    def trace(*ll: float) -> Path:
        return t(tables.GPLVM_TRACE, [{"step": i, "stage": "lbfgs", "log_likelihood": v} for i, v in enumerate(ll)])

    flat = trace(10, 50, 90, 99, 99.9, 100, 100, 100, 100, 100, 100)
    check(soler.likelihood_converges({2: flat}, "synthetic"), R, "1 %")
    rising = trace(10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110)
    assert check(soler.likelihood_converges({2: flat, 5: rising}, "synthetic"), D).cause.startswith("the method")
    check(soler.likelihood_converges({2: trace(10, 5)}, "synthetic"), D)


def test_second_bounce_an_order_of_magnitude_below(t: Tables) -> None:
    """§5.2 "L2+ ≪ L1−": a share ≤ 1/11 for every material; for the median within "in practice we expect"."""
    cols = ("database", "material", "share_object")

    def claim(*shares: float) -> claims.Claim:
        return soler.second_bounce_share(t(cols, [{"database": "synthetic", "material": f"m{i}", "share_object": s}
                                                  for i, s in enumerate(shares)]))

    check(claim(0.01, 0.05, 0.09), R, "1/11", "order of magnitude")
    c = check(claim(0.01, 0.05, 0.2), W)
    assert "(m2)" in c.measured
    check(claim(0.1, 0.2, 0.3), D)


SUMMARY = ("database", "path", "t", "ratio_seed2", "ratio_one_seed2", "ratio_seed2_se", "sum_abs_w", "clamped_fraction",
           *soler.ISOLATED_RATIO)


def summary(t: Tables, points: Sequence[tuple[str, float, float, float]], clamped: float = 1.07,
            fraction: float = 0.04) -> Path:
    """summary.csv: per point (path, t, ratio against the isolated reference, its s.e.); the clamped reference's
    ratio ``clamped`` (its s.e. that of the isolated one)."""
    return t(SUMMARY, [{"database": "synthetic", "path": p, "t": x, "ratio_seed2": clamped, "ratio_one_seed2": clamped,
                        "ratio_seed2_se": se, "sum_abs_w": 3.0, "clamped_fraction": fraction,
                        "ratio_isolated_seed2": r, "ratio_isolated_seed2_se": se} for p, x, r, se in points])


def test_blend_against_the_noise_floor(t: Tables) -> None:
    """Fig. 13 "well below the numerical error": against a reference differing only by L²⁺, ≤ 1 strictly,
    ≤ 1 + 2 s.e. of the floor within; the clamped reference's ratio does not decide."""
    def claim(r: float, se: float, **kw: float) -> claims.Claim:
        return soler.blend_vs_noise_floor(summary(t, [("a--b", 0.5, r, se)], **kw), floor_check=False)

    c = check(claim(0.98, 0.01), R, "2 standard errors", "not rendered here", "only by the L²⁺")
    assert "against the clamped reference 1.07" in c.measured and "Σ|w| 3" in c.measured
    assert "the excess is the clamping of 4 % of the table" in c.cause
    assert "clamping" not in check(claim(0.98, 0.01, clamped=0.99), R).cause
    check(claim(1.03, 0.02), W)
    assert check(claim(1.07, 0.01, clamped=1.0), D).cause.startswith(
        "a real difference: against a reference that differs only by the L²⁺ paths the blend is 7 s.e. above")
    check(claim(float("nan"), float("nan")), N)  # no I¹⁻ renders: no isolated reference
    # the paper's point (chrome → silver-paint, t = 0.5) alone, when rendered
    both = summary(t, [("a--b", 0.5, 1.5, 0.01), ("chrome--silver-paint", 0.5, 0.99, 0.01)])
    check(soler.blend_vs_noise_floor(both, floor_check=False), R, "at the paper's point")


def test_blend_floor_check_reads_the_default_candidate(t: Tables) -> None:
    cols = ("database", "candidate", "default", "path", "t", "spp", "ratio_seed2", "ratio_one_seed2",
            "ratio_seed2_se", "ratio_one_seed2_se", "sum_abs_w", "clamped_fraction", *soler.ISOLATED_RATIO)
    floor = t(cols, [{"database": "synthetic", "candidate": c, "default": d, "path": "a--b", "t": 0.5, "spp": 4096,
                      "ratio_seed2": r, "ratio_one_seed2": r, "ratio_seed2_se": 0.01, "ratio_one_seed2_se": 0.01,
                      "sum_abs_w": 1.0, "clamped_fraction": 0.0, "ratio_isolated_seed2": r,
                      "ratio_isolated_seed2_se": 0.01} for c, d, r in (("std", "true", 0.9), ("raw", "false", 29.0))])
    c = check(soler.blend_vs_noise_floor(floor, floor_check=True), R)
    assert c.value == 0.9 and "std, 4096 spp" in c.measured


# -- not checkable, ours, the whole run ---------------------------------------------------------


def test_claims_no_run_can_check_say_what_they_need() -> None:
    rows = xu.not_checkable_claims() + soler.not_checkable_claims()
    assert {c.key for c in rows} == {"xu-real-captures", "xu-wide-fovs", "xu-noise", "soler-plausible"}
    for c in rows:
        assert c.verdict == N and c.cause.startswith("needs ") and c.sentence.startswith('"') and c.database == ""
    assert "real captures" in next(c for c in rows if c.key == "xu-real-captures").cause


def test_our_own_checks_are_marked_ours(t: Tables) -> None:
    def table(noiseless: float) -> Path:
        rows = []
        for n, v in ((1, 0.30), (2, 0.25)):
            base = {"database": "synthetic", "split": "train", "setup": NF, "fov": 25, "metric": E, "n": n,
                    "material": "mean", "channel": "all"}
            rows += [{**base, "kind": "rms_log", "value": v},
                     {**base, "kind": "closedloop_noiseless_rms_log", "value": v * noiseless},
                     {**base, "kind": "closedloop_rms_log", "value": v * 1.4}]
        return t(tables.ERRORS, rows)

    c = check(ours.closed_loop_vs_table(table(1.05)), R, "ours:", "10 %")
    assert c.paper == claims.OURS and c.ours and "+40.0%" in c.measured
    check(ours.closed_loop_vs_table(table(0.85)), D)
    c = check(ours.perceptual_monotone(paths(t, 1.2, 0.5)), R, "ours:", "natural-lighting term")
    assert c.value == pytest.approx(0.1) and c.paper == claims.OURS
    check(ours.perceptual_monotone(paths(t, 1.7, 0.5)), D)  # d(A) falls from t 0.5 to 0.75


def test_a_claim_refuses_a_verdict_or_cause_it_does_not_know() -> None:
    with pytest.raises(ValueError, match="verdict 'yes'"):
        claims.Claim("k", "Xu 2016", "§1", "s", "c", "m", 1.0, "yes", "x", "db", "s")
    with pytest.raises(ValueError, match="a 'differs' cause must start with one of"):
        claims.Claim("k", "Xu 2016", "§1", "s", "c", "m", 1.0, D, "because", "db", "s")


def test_every_claim_of_a_run_is_one_row_and_a_missing_input_says_so(t: Tables) -> None:
    found = claims.compute_claims(claims.ClaimInputs())
    keys = [c.key for c in found]
    assert len(keys) == len(set(keys)) == 30
    assert {c.verdict for c in found} == {N}
    papers = [c for c in found if not c.ours]
    assert all(c.paper in (claims.XU, claims.SOLER) for c in papers) and len(papers) == 28
    errors = t.errors({(NF, 25.0, E, 2): 0.2, **nielsen({20: 0.21})})
    run = {c.key: c for c in claims.compute_claims(claims.ClaimInputs(errors=errors.path))}
    assert [c.key for c in run.values()] == keys and run["xu-2-images-vs-previous-work-20"].verdict == R
    assert run["xu-training-size"].cause == "not measured by this run: the training-size curve is not produced by " \
                                            "this configuration"


def test_unseen_materials_against_the_held_out_ones(t: Tables) -> None:
    """Ours: another database's materials within 2× the held-out error (2 images at 25°); their database named."""
    errors = t.errors({(NF, 25.0, E, 2): 0.25, (NF, 25.0, E, 1): 0.35, (P, 0.0, E, 3): 0.4})

    def claim(u2: float) -> list[claims.Claim]:
        cols = tables.UNSEEN_ERRORS
        rows = [{"database": "rgl-nbrdf", "model_database": "synthetic", "split": "train", "setup": s, "fov": f,
                 "metric": E, "n": n, "material": "mean", "channel": "all", "kind": "rms_log", "value": v}
                for s, f, n, v in ((NF, 25, 2, u2), (NF, 25, 1, 0.5), (P, 0, 3, 0.6))]
        return ours.unseen_vs_heldout(errors, t(cols, rows))

    (c,) = claim(0.45)
    check(c, R, "ours:", "2×")
    assert c.key == "unseen-xu-rgl-nbrdf" and c.database == "rgl-nbrdf" and c.paper == claims.OURS
    assert "3 points: 0.6 vs 0.4 (×1.50)" in c.measured
    (c,) = claim(0.6)
    assert check(c, D).cause.startswith("the data: the rgl-nbrdf materials lie outside the synthetic subspace")
