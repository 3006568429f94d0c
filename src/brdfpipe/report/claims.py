"""The two papers' quantitative claims, checked against this run's own CSVs.

Every :class:`Claim` holds the paper's statement (with section / figure),
the paper's value, the value measured in this run, whether the claim holds
here (``yes``, ``no`` or ``not measured``, with the reason) and the database,
read from the ``database`` column of the CSV it was computed from (never
from the configuration).  Nothing here is typed in: each measured number is
computed from ``errors.csv``, ``training_size.csv``, Xu Fig. 8's table, the
manifold CSVs, the GPLVM traces, the error-map summaries and the bounce
shares.  Where the paper is qualitative ("comparable", "nearly best", "well
below") the criterion used is written into the claim's text.

Standard library only: these are small tables.  Bad input (missing file
or column, a number that does not parse, two databases) raises
:class:`ClaimsInputError` naming the file.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from brdfpipe.core import atomic, integrity
from brdfpipe.report import rst
from brdfpipe.spec import tables

__all__ = [
    "ClaimsInputError",
    "Claim",
    "ClaimInputs",
    "CLAIM_COLUMNS",
    "HOLDS",
    "point_vs_images",
    "metric_vs_condition",
    "error_vs_fov",
    "fov25_nearly_best",
    "fixed_vs_nearfield",
    "training_size_decreasing",
    "one_shot_optimum",
    "reproduction_vs_pca",
    "albedo_in_unit_interval",
    "perceptual_uniformity",
    "eq7_bound",
    "likelihood_increases",
    "second_bounce_share",
    "blend_vs_noise_floor",
    "NOISE_SIGMAS",
    "closed_loop_vs_table",
    "CLOSED_LOOP_TOLERANCE",
    "UNSEEN_CLAIM_PREFIX",
    "is_unseen_claim",
    "UNSEEN_FACTOR",
    "SPECTRALON",
    "unseen_vs_heldout",
    "spectralon_albedo",
    "compute_claims",
    "write_claims",
    "read_claims",
    "RunClaims",
    "read_run",
    "claims_table_rst",
    "rst_cell",
]

#: Standard errors of the noise floor's own estimate a blend may exceed the floor by (claims blend_vs_noise_floor).
NOISE_SIGMAS = 2.0

#: Columns of ``claims.csv``.
CLAIM_COLUMNS: tuple[str, ...] = (
    "key", "paper", "where", "claim", "paper_value", "measured", "value", "holds", "database", "source",
)
#: The values of :attr:`Claim.holds`.
HOLDS: tuple[str, ...] = ("yes", "no", "not measured")
#: Closed loop vs table lookup: largest relative difference of the mean errors that counts as agreeing.
CLOSED_LOOP_TOLERANCE: float = 0.10
#: Relative tolerance of "at most" comparisons between two measured errors (ties count as holding).
TIE: float = 1e-9


class ClaimsInputError(ValueError):
    """A CSV a claim is computed from is missing or malformed; the message names the file."""


@dataclass(frozen=True)
class Claim:
    """One claim of a paper and what this run measured."""

    key: str
    paper: str  #: ``Xu 2016`` or ``Soler 2018``
    where: str  #: section / figure of the paper value
    claim: str  #: the claim as checked here (criterion included)
    paper_value: str
    measured: str  #: this run's numbers, in words
    value: float  #: the primary measured number (NaN when not measured)
    holds: str  #: one of :data:`HOLDS`
    database: str  #: from the CSV's ``database`` column ("" when not measured)
    source: str  #: the file(s) it was computed from
    figures: tuple[str, ...] = field(default=(), compare=False)  #: caption keys it belongs to

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


def _rows(path: str | os.PathLike[str], required: Sequence[str]) -> tuple[Path, list[dict[str, str]]]:
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
    return p, rows


def _num(p: Path, r: Mapping[str, str], column: str) -> float:
    text = r[column]
    if text == "":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise ClaimsInputError(f"{p}: line {r['__line__']}: column {column!r} is not a number: {text!r}") from None


def _database(p: Path, rows: Iterable[Mapping[str, str]]) -> str:
    """The one database of ``rows`` ("" for no rows: the claim then says "not measured")."""
    names = sorted({r["database"] for r in rows})
    if not names:
        return ""
    if len(names) != 1 or not names[0]:
        raise ClaimsInputError(f"{p}: expected one database in column 'database', got {names or 'no rows'}")
    return names[0]


def _true(text: str) -> bool:
    """A CSV boolean: ``true`` (spaces.csv) or ``1`` (floor-check.csv)."""
    return text.strip().lower() in ("true", "1", "yes")


def _g(x: float) -> str:
    """A measured number as the report prints it (3 significant digits)."""
    return "–" if not math.isfinite(x) else f"{x:.3g}"


def _pct(x: float) -> str:
    return "–" if not math.isfinite(x) else f"{100 * x:.3g} %"


def _deg(x: float) -> str:
    return f"{x:g}°"


def _le(a: float, b: float) -> bool:
    return a <= b + TIE * abs(b)


def _verdict(ok: bool) -> str:
    return "yes" if ok else "no"


def _not_measured(key: str, paper: str, where: str, claim: str, paper_value: str, reason: str,
                  source: str = "", figures: Sequence[str] = ()) -> Claim:
    return Claim(key, paper, where, claim, paper_value, f"not measured in this run: {reason}", math.nan,
                 "not measured", "", source, tuple(figures))


# -- Xu 2016 --------------------------------------------------------------------

_XU = "Xu 2016"
_SOLER = "Soler 2018"
_METRIC_TEXT = {"error": "min E(S) (eq. 15)", "condition": "min κ (Xu eq. 6)"}


@dataclass(frozen=True)
class _Errors:
    path: Path
    database: str
    values: dict[tuple[str, float, str, int], float]  #: (setup, fov, metric, n) → mean RMS log error

    def get(self, setup: str, fov: float, metric: str, n: int) -> float | None:
        v = self.values.get((setup, float(fov), metric, int(n)))
        return v if v is not None and math.isfinite(v) else None

    def fovs(self, setup: str, metric: str | None = None) -> list[float]:
        return sorted({k[1] for k in self.values if k[0] == setup and (metric is None or k[2] == metric)})

    def ns(self, setup: str, fov: float, metric: str) -> list[int]:
        return sorted(k[3] for k in self.values if k[:3] == (setup, float(fov), metric))

    def nearfield_fov(self) -> float | None:
        """25° when evaluated (the paper's comparisons), else the first near-field FOV."""
        fovs = self.fovs("nearfield", "error")
        return 25.0 if 25.0 in fovs else (fovs[0] if fovs else None)


def read_errors(path: str | os.PathLike[str]) -> _Errors:
    """The mean RMS error of the log-mapped BRDF (``kind rms_log``, material ``mean``) of ``errors.csv``.

    Rows of the ``train`` split: direction sets optimised on the training
    materials, evaluated on the held-out ones (Xu §6).
    """
    p, rows = _rows(path, tables.ERRORS)
    database = _database(p, rows)
    values: dict[tuple[str, float, str, int], float] = {}
    for r in rows:
        if r["split"] != "train" or r["material"] != "mean" or r["channel"] != "all" or r["kind"] != "rms_log":
            continue
        values[(r["setup"], _num(p, r, "fov"), r["metric"], int(_num(p, r, "n")))] = _num(p, r, "value")
    return _Errors(p, database, values)


def point_vs_images(errors: _Errors, images: int, points: int, baseline: str) -> Claim:
    """``images`` near-field images (FOV 25°, min E(S)) at least as accurate as ``points`` point samples.

    ``baseline``: the point sets' metric (``error`` = eq. 15, ``condition`` = κ).
    Holds when the images' mean error is at most the point samples'.
    """
    key = f"xu-{images}-image{'s' if images > 1 else ''}-vs-{points}-points-{'eq15' if baseline == 'error' else 'kappa'}"
    if images == 1:
        where, paper_value = "§6, Fig. 2, Fig. 6", f"1 image ≈ 5 point samples of Nielsen 2015 (min κ): \"similar accuracy as about 5 samples\""
    else:
        where = "Abstract, §1, §6, Fig. 2, Fig. 6"
        paper_value = "2 images ≈ 20 point samples of Nielsen 2015 (min κ): \"essentially the same accuracy as 20 samples\""
        if points < 20:
            paper_value += f"; so better than {points}"
    fov = errors.nearfield_fov()
    claim = (f"{images} near-field image{'s' if images > 1 else ''} (FOV {_deg(fov if fov is not None else 25)}, "
             f"min E(S)) at most the error of {points} point samples chosen by {_METRIC_TEXT[baseline]}")
    figs = ("xu-fig06", "xu-fig19")
    a = errors.get("nearfield", fov, "error", images) if fov is not None else None
    b = errors.get("point", 0.0, baseline, points)
    if a is None or b is None:
        what = []
        if a is None:
            what.append(f"no near-field error set with n = {images}")
        if b is None:
            what.append(f"no point set of {_METRIC_TEXT[baseline]} with n = {points}")
        return _not_measured(key, _XU, where, claim, paper_value, f"{errors.path.name} has {' and '.join(what)}",
                             str(errors.path), figs)
    ok = _le(a, b)
    measured = f"{_g(a)} ({images} image{'s' if images > 1 else ''}) {'≤' if ok else '>'} {_g(b)} ({points} points)"
    return Claim(key, _XU, where, claim, paper_value, measured, a / b, _verdict(ok), errors.database,
                 str(errors.path), figs)


def metric_vs_condition(errors: _Errors, setup: str) -> Claim:
    """Direction sets of min E(S) at most as wrong as those of min κ, at every FOV and n evaluated.

    ``setup`` ``nearfield`` (Xu §6, Fig. 5: "significant advantages") or
    ``point`` (appendix B, Figs. 18, 19: "somewhat lower error").
    value: the smallest ratio error(κ) / error(E(S)) over the pairs.
    """
    if setup == "nearfield":
        key, where, figs = "xu-eq15-vs-kappa-nearfield", "§3.1, §6, Fig. 5", ("xu-fig05", "xu-fig13")
        paper_value = "min E(S) clearly below min κ for near-field images at every FOV (κ \"breaks down\")"
    else:
        key, where, figs = "xu-eq15-vs-kappa-point", "appendix B, Figs. 18, 19", ("xu-fig18", "xu-fig19")
        paper_value = "min E(S) \"somewhat lower\" than min κ for point samples"
    claim = f"{setup} sets of min E(S) (eq. 15) have at most the error of min κ (Xu eq. 6) at every FOV and n"
    pairs = []
    for fov in errors.fovs(setup):
        for n in errors.ns(setup, fov, "error"):
            a, b = errors.get(setup, fov, "error", n), errors.get(setup, fov, "condition", n)
            if a is not None and b is not None:
                pairs.append((fov, n, a, b))
    if not pairs:
        return _not_measured(key, _XU, where, claim, paper_value,
                             f"{errors.path.name} lacks {setup} sets of both metrics", str(errors.path), figs)
    good = [p for p in pairs if _le(p[2], p[3])]
    ratios = [b / a for _, _, a, b in pairs]
    worst = min(pairs, key=lambda p: p[3] / p[2])
    fov_text = f"FOV {_deg(worst[0])}, " if setup == "nearfield" else ""
    measured = (f"E(S) ≤ κ in {len(good)} of {len(pairs)} (FOV, n); error(κ)/error(E(S)) from {_g(min(ratios))} "
                f"({fov_text}n = {worst[1]}: {_g(worst[2])} vs {_g(worst[3])}) to {_g(max(ratios))}")
    return Claim(key, _XU, where, claim, paper_value, measured, min(ratios), _verdict(len(good) == len(pairs)),
                 errors.database, str(errors.path), figs)


def error_vs_fov(errors: _Errors) -> Claim:
    """Near-field error (min E(S)) does not increase with the FOV, for 1 and 2 images."""
    key, where, figs = "xu-error-vs-fov", "§6, Fig. 6", ("xu-fig06", "xu-fig05")
    claim = "near-field error (min E(S)) does not grow with the FOV, at 1 and at 2 images"
    paper_value = "\"larger fields of view help\"; error falls from 15° to 45°"
    fovs = errors.fovs("nearfield", "error")
    if len(fovs) < 2:
        return _not_measured(key, _XU, where, claim, paper_value,
                             f"{len(fovs)} near-field FOV evaluated (need 2)", str(errors.path), figs)
    parts, worst, ok = [], 0.0, True
    for n in (1, 2):
        series = [(f, errors.get("nearfield", f, "error", n)) for f in fovs]
        series = [(f, v) for f, v in series if v is not None]
        if len(series) < 2:
            continue
        parts.append(f"n = {n}: " + ", ".join(f"{_deg(f)} {_g(v)}" for f, v in series))
        for (_, v0), (_, v1) in zip(series, series[1:]):
            worst = max(worst, v1 / v0)
            ok = ok and _le(v1, v0)
    if not parts:
        return _not_measured(key, _XU, where, claim, paper_value, "no n with two FOVs", str(errors.path), figs)
    measured = "; ".join(parts) + f" (largest ratio of consecutive FOVs {_g(worst)})"
    return Claim(key, _XU, where, claim, paper_value, measured, worst, _verdict(ok), errors.database,
                 str(errors.path), figs)


#: "25° is already nearly best" read as: within this factor of the best FOV's error at 2 images.
NEARLY_BEST: float = 1.10


def fov25_nearly_best(errors: _Errors) -> Claim:
    """Xu §6: "25° is already nearly best": 2-image error at 25° within :data:`NEARLY_BEST` × the best FOV's."""
    key, where, figs = "xu-fov25-nearly-best", "§6, Fig. 6", ("xu-fig06",)
    claim = f"2 near-field images at 25° are within {NEARLY_BEST:g}× the error of the best FOV (our reading of \"nearly best\")"
    paper_value = "\"25° is already nearly best\""
    fovs = errors.fovs("nearfield", "error")
    vals = {f: errors.get("nearfield", f, "error", 2) for f in fovs}
    vals = {f: v for f, v in vals.items() if v is not None}
    if 25.0 not in vals or len(vals) < 2:
        return _not_measured(key, _XU, where, claim, paper_value,
                             "needs 2-image near-field sets at 25° and another FOV", str(errors.path), figs)
    best = min(vals, key=lambda f: vals[f])
    ratio = vals[25.0] / vals[best]
    measured = f"25°: {_g(vals[25.0])}, best {_deg(best)}: {_g(vals[best])} (ratio {_g(ratio)})"
    return Claim(key, _XU, where, claim, paper_value, measured, ratio, _verdict(ratio <= NEARLY_BEST),
                 errors.database, str(errors.path), figs)


def fixed_vs_nearfield(errors: _Errors) -> Claim:
    """Xu §8: a fixed camera (or light) gives higher error than near-field images where both move, at 2 images."""
    key, where, figs = "xu-fixed-vs-nearfield", "§8, Fig. 13", ("xu-fig13",)
    claim = "2 images with a fixed camera (or fixed light) have at least the error of 2 near-field images where both move"
    paper_value = "fixed camera: \"higher error in Fig. 13, compared to the near-field case\""
    rows = []
    for setup in ("fixed_camera", "fixed_light"):
        for fov in errors.fovs(setup, "error"):
            a, b = errors.get(setup, fov, "error", 2), errors.get("nearfield", fov, "error", 2)
            if a is not None and b is not None:
                rows.append((setup, fov, a, b))
    if not rows:
        return _not_measured(key, _XU, where, claim, paper_value,
                             "no 2-image fixed-camera/light set with a near-field set at its FOV", str(errors.path), figs)
    ok = all(_le(b, a) for _, _, a, b in rows)
    measured = "; ".join(f"{s.replace('_', ' ')} {_g(a)} vs near-field {_g(b)} (FOV {_deg(f)})" for s, f, a, b in rows)
    value = min(a / b for _, _, a, b in rows)
    return Claim(key, _XU, where, claim, paper_value, measured, value, _verdict(ok), errors.database,
                 str(errors.path), figs)


def training_size_decreasing(path: str | os.PathLike[str]) -> Claim:
    """Xu Fig. 7: the 2-image error does not grow as training materials are added (mean over orders)."""
    key, where, figs = "xu-training-size", "§6, Fig. 7", ("xu-fig07",)
    claim = "mean error of the training-size curve does not grow with the number of training materials"
    paper_value = "\"a steady decrease\" of the error with more training materials"
    p, rows = _rows(path, tables.TRAINING_SIZE)
    database = _database(p, rows)
    by_n: dict[int, list[float]] = {}
    orders = set()
    for r in rows:
        if r["material"] == "mean" and r["channel"] == "all" and r["kind"] == "rms_log":
            by_n.setdefault(int(_num(p, r, "n_train")), []).append(_num(p, r, "value"))
            orders.add(r["order_seed"])
    if len(by_n) < 2:
        return _not_measured(key, _XU, where, claim, paper_value, f"{p.name} has {len(by_n)} training size(s)",
                             str(p), figs)
    series = [(n, statistics.fmean(v)) for n, v in sorted(by_n.items())]
    ok = all(_le(v1, v0) for (_, v0), (_, v1) in zip(series, series[1:]))
    measured = (f"mean of {len(orders)} material orders: " if len(orders) > 1 else "") + ", ".join(
        f"{n}: {_g(v)}" for n, v in series)
    return Claim(key, _XU, where, claim, paper_value, measured, series[-1][1] / series[0][1], _verdict(ok),
                 database, str(p), figs)


#: Xu §6: the optimal single image, θh = 3° at ~50° incidence; "about" read as these tolerances.
ONE_SHOT = {"theta_h": 3.0, "theta_h_tol": 5.0, "incidence": 50.0, "incidence_tol": 10.0}


def one_shot_optimum(path: str | os.PathLike[str]) -> Claim:
    """Xu §6, Fig. 8: the optimal single image is slightly off-specular (θh 3°) at about 50° incidence."""
    key, where, figs = "xu-one-shot-optimum", "§6, Fig. 8", ("xu-fig08", "xu-fig08-table")
    o = ONE_SHOT
    claim = (f"the optimal single near-field image has θh within {o['theta_h_tol']:g}° of {o['theta_h']:g}° and light "
             f"incidence within {o['incidence_tol']:g}° of {o['incidence']:g}°, at every FOV")
    paper_value = "θh = 3° at an angle of incidence of about 50°"
    p, rows = _rows(path, tables.columns(tables.FIG08, "fov_deg", "n_images", "image", "theta_h_deg", "light_theta_deg",
                                             "split", "database"))
    splits = {r["split"] for r in rows}
    split = "all" if "all" in splits else sorted(splits)[0] if splits else ""
    ones = [r for r in rows if r["split"] == split and r["n_images"] == "1"]
    if not ones:
        return _not_measured(key, _XU, where, claim, paper_value, f"{p.name} has no 1-image set", str(p), figs)
    database = _database(p, ones)
    pts = sorted((_num(p, r, "fov_deg"), _num(p, r, "theta_h_deg"), _num(p, r, "light_theta_deg")) for r in ones)
    ok = all(abs(th - o["theta_h"]) <= o["theta_h_tol"] and abs(ti - o["incidence"]) <= o["incidence_tol"]
             for _, th, ti in pts)
    measured = "; ".join(f"FOV {_deg(f)}: θh {th:.1f}°, incidence {ti:.1f}°" for f, th, ti in pts) + f" (split {split})"
    value = next((th for f, th, _ in pts if f == 25.0), pts[0][1])
    return Claim(key, _XU, where, claim, paper_value, measured, value, _verdict(ok), database, str(p), figs)


# -- Soler 2018 -----------------------------------------------------------------


def reproduction_vs_pca(path: str | os.PathLike[str]) -> Claim:
    """Soler §4.2, Fig. 8: the GPLVM reproduces every training material, PCA with k ≤ 40 does not.

    Holds when the largest GPLVM error (any q, any material) is below the
    median PCA-k error of every k in the table.  value: that largest error.
    """
    key, where, figs = "soler-reproduction-vs-pca", "§4.2, Fig. 8", ("soler-fig08",)
    claim = "largest GPLVM reproduction error (any q, any material) below the median PCA-k error for every k"
    paper_value = "GPLVM \"always perfectly reproduces\" the materials at any q; PCA with 20 and 40 components does not"
    p, rows = _rows(path, tables.columns(tables.REPRODUCTION, "database", "material", "method", "k", "relative_error"))
    database = _database(p, rows)
    gp: dict[int, list[float]] = {}
    pca: dict[int, list[float]] = {}
    for r in rows:
        (gp if r["method"] == "gplvm" else pca if r["method"] == "pca" else {}).setdefault(
            int(_num(p, r, "k")), []).append(_num(p, r, "relative_error"))
    if not gp or not pca:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} lacks GPLVM or PCA rows", str(p), figs)
    worst = max(max(v) for v in gp.values())
    medians = {k: statistics.median(v) for k, v in sorted(pca.items())}
    ok = all(worst < m for m in medians.values())
    measured = (", ".join(f"GPLVM q = {q}: max {_pct(max(v))}" for q, v in sorted(gp.items())) + "; "
                + ", ".join(f"PCA-{k}: median {_pct(m)}" for k, m in medians.items()))
    return Claim(key, _SOLER, where, claim, paper_value, measured, worst, _verdict(ok), database, str(p), figs)


def albedo_in_unit_interval(path: str | os.PathLike[str]) -> Claim:
    """Soler §4.2, Fig. 7: interpolated albedo stays in [0, 1] (default candidate; share of hull points outside)."""
    key, where, figs = "soler-albedo", "§4.2, Fig. 7", ("soler-fig07", "soler-spaces", "soler-spaces-table")
    claim = "albedo of interpolated BRDFs in [0, 1] at every sampled point of the latent hull (default data space)"
    paper_value = "\"observed to be limited to [0, 1]\" (q = 2, whole MERL)"
    p, rows = _rows(path, tables.columns(tables.SPACES, "database", "candidate", "q", "default", "albedo_bad_hull",
                                             "albedo_bad_map"))
    mine = [r for r in rows if _true(r["default"])]
    if not mine:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} has no default candidate", str(p), figs)
    database = _database(p, mine)
    parts, worst = [], 0.0
    for r in sorted(mine, key=lambda r: int(_num(p, r, "q"))):
        hull, amap = _num(p, r, "albedo_bad_hull"), _num(p, r, "albedo_bad_map")
        worst = max(worst, hull, amap if math.isfinite(amap) else 0.0)
        parts.append(f"q = {r['q']}: {_pct(hull)} of the hull" + (f", {_pct(amap)} of the map" if math.isfinite(amap) else ""))
    measured = f"outside [0, 1] ({mine[0]['candidate']}): " + "; ".join(parts)
    return Claim(key, _SOLER, where, claim, paper_value, measured, worst, _verdict(worst == 0.0), database,
                 str(p), figs)


def _paths(path: str | os.PathLike[str]) -> tuple[Path, str, dict[str, list[dict[str, float]]]]:
    p, rows = _rows(path, tables.columns(tables.LATENT_PATHS, "database", "path", "t", "perceptual_a", "perceptual_b",
                                             "perceptual_ab", "deviation", "bound"))
    database = _database(p, rows)
    out: dict[str, list[dict[str, float]]] = {}
    for r in rows:
        out.setdefault(r["path"], []).append({c: _num(p, r, c) for c in
                                              ("t", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound")})
    for v in out.values():
        v.sort(key=lambda d: d["t"])
    return p, database, out


def perceptual_uniformity(path: str | os.PathLike[str]) -> Claim:
    """Soler §4.3, Fig. 9: along latent paths the perceptual distance to A grows and to B falls, steadily.

    Holds when both are monotone on every path; value: the largest
    ``|d(A, x)/d(A, B) − t|`` (0 = perceptually uniform).
    """
    key, where, figs = "soler-perceptual-uniformity", "§4.3, Fig. 9", ("soler-fig09",)
    claim = "perceptual distance to A never decreases and to B never increases along any latent path"
    paper_value = "distances close to the ideal (uniform) dashed lines, for 3 paths of 20 steps"
    p, database, paths = _paths(path)
    if not paths:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} has no path", str(p), figs)
    dev, bad = 0.0, 0
    for pts in paths.values():
        dab = pts[-1]["perceptual_a"] or pts[0]["perceptual_ab"] or 1.0
        dev = max(dev, max(abs(d["perceptual_a"] / dab - d["t"]) for d in pts))
        bad += sum(b["perceptual_a"] < a["perceptual_a"] for a, b in zip(pts, pts[1:]))
        bad += sum(b["perceptual_b"] > a["perceptual_b"] for a, b in zip(pts, pts[1:]))
    steps = sum(len(v) - 1 for v in paths.values())
    measured = (f"{len(paths)} paths, {steps} steps: {bad} non-monotone step(s) of 2×{steps}; largest "
                f"|d(A, x)/d(A, B) − t| = {_g(dev)}")
    return Claim(key, _SOLER, where, claim, paper_value, measured, dev, _verdict(bad == 0), database, str(p), figs)


def eq7_bound(path: str | os.PathLike[str]) -> Claim:
    """Soler eq. 7: the interpolant's deviation ‖z* − z_j‖ stays below the bound, at every path point."""
    key, where, figs = "soler-eq7-bound", "§4.1, eq. 7", ("soler-eq7",)
    claim = "actual deviation ‖z* − z_j‖ ≤ the eq. 7 bound at every latent-path point"
    paper_value = "eq. 7 bounds the deviation from the nearest training material"
    p, database, paths = _paths(path)
    pts = [d for v in paths.values() for d in v if math.isfinite(d["bound"]) and d["bound"] > 0]
    if not pts:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} has no bounded point", str(p), figs)
    worst = max(d["deviation"] / d["bound"] for d in pts)
    ok = all(_le(d["deviation"], d["bound"]) for d in pts)
    measured = f"largest deviation / bound {_g(worst)} over {len(pts)} points"
    return Claim(key, _SOLER, where, claim, paper_value, measured, worst, _verdict(ok), database, str(p), figs)


def likelihood_increases(traces: Mapping[int, str | os.PathLike[str]], database: str) -> Claim:
    """Soler §3, Fig. 5: fitting raises the log-likelihood from its start (each q of the default candidate).

    The traces carry no database column; ``database`` comes from the run's other CSVs.
    """
    key, where, figs = "soler-likelihood", "§3, Fig. 5", ("soler-fig05",)
    claim = "the final log-likelihood of each fit is at least its starting value"
    paper_value = "L rises over the iterations and levels off (q = 2, whole MERL)"
    if not traces:
        return _not_measured(key, _SOLER, where, claim, paper_value, "no GPLVM trace", "", figs)
    parts, ok, gains, srcs = [], True, [], []
    for q, path in sorted(traces.items()):
        p, rows = _rows(path, tables.GPLVM_TRACE)
        if not rows:
            raise ClaimsInputError(f"{p}: no data rows")
        first, last = _num(p, rows[0], "log_likelihood"), _num(p, rows[-1], "log_likelihood")
        ok = ok and last >= first
        gains.append(last - first)
        parts.append(f"q = {q}: {first:.6g} → {last:.6g}")
        srcs.append(str(p))
    return Claim(key, _SOLER, where, claim, paper_value, "; ".join(parts), min(gains), _verdict(ok), database,
                 ", ".join(srcs), figs)


#: "L₂₊ ≪ L₁₋" read as: the I²⁺ share of every pre-render's object pixels at most this.
SECOND_BOUNCE_MAX: float = 0.10


def second_bounce_share(path: str | os.PathLike[str]) -> Claim:
    """Soler §5.2: paths with ≥ 2 scatterings on the material carry little light (I²⁺ share over the object)."""
    key, where, figs = "soler-second-bounce", "§5.2", ("render-prerenders",)
    claim = f"I²⁺ share of every pre-render over the object at most {SECOND_BOUNCE_MAX:.0%} (our reading of \"≪\")"
    paper_value = "\"we expect L2+ ≪ L1−\" (not measured in the paper)"
    p, rows = _rows(path, tables.columns(tables.BOUNCE_SHARES, "database", "material", "share_object"))
    if not rows:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} has no rows", str(p), figs)
    database = _database(p, rows)
    shares = {r["material"]: _num(p, r, "share_object") for r in rows}
    worst = max(shares, key=lambda m: shares[m])
    measured = (f"median {_pct(statistics.median(shares.values()))}, largest {_pct(shares[worst])} ({worst}) "
                f"over {len(shares)} materials")
    return Claim(key, _SOLER, where, claim, paper_value, measured, shares[worst],
                 _verdict(shares[worst] <= SECOND_BOUNCE_MAX), database, str(p), figs)


def blend_vs_noise_floor(path: str | os.PathLike[str], *, floor_check: bool) -> Claim:
    """Soler §5.2, Fig. 13: blended pre-renders are as close to a reference as a second render is.

    Ratio RMSE(blend, reference of the second seed) / RMSE(the two seeds'
    references), measured on the whole image (what the paper blends).  The
    floor comes from one pair of seeds, so the ratio carries the floor's own
    uncertainty (``ratio_seed2_se``,
    :func:`brdfpipe.rendering.blend.ratio_standard_error`): the claim fails
    only where a path point's ratio exceeds 1 by more than
    :data:`NOISE_SIGMAS` standard errors (value: the largest ratio; the
    largest excess in standard errors is in the text).  ``floor_check``:
    read ``floor-check.csv`` (default candidate, small many-sample renders)
    instead of the configured render's ``summary.csv``.
    """
    if floor_check:
        key, where = "soler-blend-vs-floor-check", "§5.2, Fig. 13 (noise-floor check)"
        figs: tuple[str, ...] = ("render-floor-check", "render-floor-check-table")
        required: tuple[str, ...] = ("database", "candidate", "default", "path", "t", "spp", "ratio_seed2",
                                     "ratio_one_seed2", "ratio_seed2_se", "ratio_one_seed2_se")
    else:
        key, where = "soler-blend-vs-noise-floor", "§5.2, Fig. 13"
        figs = ("render-fig12", "render-fig13", "render-errormap", "render-summary")
        required = ("database", "path", "t", "ratio_seed2", "ratio_one_seed2", "ratio_seed2_se", "ratio_one_seed2_se")
    claim = ("blend of pre-renders vs a reference: RMSE at most that between two seeds of the reference, "
             f"within {_g(NOISE_SIGMAS)} standard errors of the floor's own estimate (every path point, whole image)")
    paper_value = "differences \"well below the numerical error between the two images\""
    p, rows = _rows(path, required)
    if floor_check:
        rows = [r for r in rows if _true(r["default"])]
    if not rows:
        return _not_measured(key, _SOLER, where, claim, paper_value, f"{p.name} has no path point", str(p), figs)
    database = _database(p, rows)
    whole = [_num(p, r, "ratio_seed2") for r in rows]
    se = [_num(p, r, "ratio_seed2_se") for r in rows]
    one = [_num(p, r, "ratio_one_seed2") for r in rows]
    # how far above the floor each point is, in standard errors of the floor's estimate
    excess = [(w - 1.0) / e if e > 0 else (math.inf if w > 1.0 else -math.inf) for w, e in zip(whole, se)]
    what = f"{rows[0]['candidate']}, {rows[0]['spp']} spp, " if floor_check else ""
    finite_se = [e for e in se if math.isfinite(e)]
    measured = (f"{what}{len(rows)} points: blend / floor {_g(min(whole))}–{_g(max(whole))} (whole image; "
                f"s.e. of the floor's estimate {_g(max(finite_se)) if finite_se else 'n/a'}; largest excess over 1: "
                f"{_g(max(excess))} s.e.), {_g(min(one))}–{_g(max(one))} (I¹⁻ part)")
    return Claim(key, _SOLER, where, claim, paper_value, measured, max(whole),
                 _verdict(all(x <= NOISE_SIGMAS for x in excess) and all(math.isfinite(w) for w in whole)),
                 database, str(p), figs)


# -- all ------------------------------------------------------------------------


def closed_loop_vs_table(path: str | os.PathLike[str]) -> Claim:
    """Reconstructions from (simulated) photographs agree with the table-lookup evaluation (``closedloop.csv``).

    Xu §7 reconstructs real samples from two photographs and finds renders
    of the result matching them; here the photographs are renders, so the
    check is quantitative: for every captured direction set the mean RMS log
    error from the noiseless render is within :data:`CLOSED_LOOP_TOLERANCE`
    of the table lookup's (value: the largest |closed loop / table − 1|); the
    error with the sensor's noise and masking is reported next to it.
    """
    key, where = "xu-closed-loop", "§7, Figs. 11, 12"
    claim = (f"reconstruction from the rendered photographs (noiseless) within {_pct(CLOSED_LOOP_TOLERANCE)} of "
             "the table-lookup error, mean over the held-out materials, every captured set; with the sensor: reported")
    paper_value = 'real two-shot captures reconstruct BRDFs whose renders "match well" the photographs'
    figs = ("xu-closedloop", "xu-closedloop-table")
    kinds = ("rms_log", "closedloop_noiseless_rms_log", "closedloop_rms_log")
    p, rows = _rows(path, tables.ERRORS)
    means: dict[tuple[str, float, str, int], dict[str, float]] = {}
    for r in rows:
        if r["material"] == "mean" and r["channel"] == "all" and r["kind"] in kinds:
            k = (r["setup"], _num(p, r, "fov"), r["metric"], int(_num(p, r, "n")))
            means.setdefault(k, {})[r["kind"]] = _num(p, r, "value")
    sets = {k: v for k, v in sorted(means.items()) if len(v) == len(kinds) and v["rms_log"] > 0}
    if not sets:
        return _not_measured(key, _XU, where, claim, paper_value, f"{p.name} has no closed-loop set", str(p), figs)
    dev = {k: v["closedloop_noiseless_rms_log"] / v["rms_log"] - 1.0 for k, v in sets.items()}
    worst = max(dev, key=lambda k: abs(dev[k]))
    parts = [f"{s} {_deg(f)} n = {n}: table {_g(v['rms_log'])}, render {_g(v['closedloop_noiseless_rms_log'])} "
             f"({dev[(s, f, m, n)]:+.1%}), sensor {_g(v['closedloop_rms_log'])} "
             f"({v['closedloop_rms_log'] / v['rms_log'] - 1.0:+.1%})" for (s, f, m, n), v in sets.items()]
    ok = abs(dev[worst]) <= CLOSED_LOOP_TOLERANCE
    return Claim(key, _XU, where, claim, paper_value, "; ".join(parts), abs(dev[worst]), _verdict(ok),
                 _database(p, rows), str(p), figs)


#: Key prefix of the claims about materials outside the run's database (config ``unseen``): their ``database``
#: column names those materials' database, not the run's (:func:`is_unseen_claim`).
UNSEEN_CLAIM_PREFIX: str = "unseen-"


def is_unseen_claim(key: str) -> bool:
    """True for a claim about materials outside the run's database (its ``database`` is theirs, not the run's)."""
    return str(key).startswith(UNSEEN_CLAIM_PREFIX)


#: "The basis trained on one database reconstructs materials of another" read as: their mean error at most
#: this many times the held-out materials' (2 near-field images at the comparison FOV, min E(S)).
UNSEEN_FACTOR: float = 2.0


def unseen_vs_heldout(errors: _Errors, path: str | os.PathLike[str]) -> list[Claim]:
    """Materials outside the training database vs held-out ones, one claim per unseen database (``unseen.csv``).

    Xu §7 acquires materials that are not in MERL with the MERL-trained
    basis and direction sets.  Here: the mean RMS log error of 2 near-field
    images (FOV of the paper's comparisons, min E(S)) over an unseen
    database's materials against the held-out materials' (``errors.csv``);
    holds when at most :data:`UNSEEN_FACTOR` × (value: the ratio).  1 image,
    the largest point set and the closed loop (sensor) are reported next to it.
    """
    p, rows = _rows(path, tables.UNSEEN_ERRORS)
    means: dict[str, dict[tuple[str, float, int, str], float]] = {}
    models = sorted({r["model_database"] for r in rows})
    if len(models) > 1:
        raise ClaimsInputError(f"{p}: rows of several model databases: {models}")
    if models and errors.database and models[0] != errors.database:
        raise ClaimsInputError(f"{p}: model of {models[0]}, but {errors.path} is of {errors.database}")
    for r in rows:
        if not r["database"] or r["database"] == r["model_database"]:
            raise ClaimsInputError(f"{p}: line {r['__line__']}: database {r['database']!r} is not outside the "
                                   f"model's {r['model_database']}")
        if r["split"] == "train" and r["material"] == "mean" and r["channel"] == "all" and r["metric"] == "error":
            means.setdefault(r["database"], {})[(r["setup"], _num(p, r, "fov"), int(_num(p, r, "n")),
                                                 r["kind"])] = _num(p, r, "value")
    fov = errors.nearfield_fov()
    out = []
    for db, v in sorted(means.items()):
        key, where, figs = (f"{UNSEEN_CLAIM_PREFIX}xu-{db}", "§7 (materials outside the training set)",
                            ("xu-unseen", "xu-unseen-table"))
        claim = (f"2 near-field images (FOV {_deg(fov if fov is not None else 25)}, min E(S)) reconstruct the {db} "
                 f"materials, never seen by the {errors.database} model, within {UNSEEN_FACTOR:g}× the mean error of "
                 "the held-out materials")
        paper_value = "§7 acquires materials outside MERL with the MERL-trained basis (shown as renders, not measured)"
        u2 = v.get(("nearfield", float(fov), 2, "rms_log")) if fov is not None else None
        h2 = errors.get("nearfield", fov, "error", 2) if fov is not None else None
        if u2 is None or h2 is None or not h2 > 0:
            out.append(_not_measured(key, _XU, where, claim, paper_value, f"{p.name} or {errors.path.name} has no "
                                     "2-image near-field set at that FOV", str(p), figs))
            continue
        parts = [f"2 images: {_g(u2)} vs held-out {_g(h2)} (×{u2 / h2:.2f})"]
        u1, h1 = v.get(("nearfield", float(fov), 1, "rms_log")), errors.get("nearfield", fov, "error", 1)
        if u1 is not None and h1:
            parts.append(f"1 image: {_g(u1)} vs {_g(h1)} (×{u1 / h1:.2f})")
        ns = sorted(n for (s_, _, n, k) in v if s_ == "point" and k == "rms_log")
        if ns:
            up, hp = v[("point", 0.0, ns[-1], "rms_log")], errors.get("point", 0.0, "error", ns[-1])
            if hp:
                parts.append(f"{ns[-1]} points: {_g(up)} vs {_g(hp)} (×{up / hp:.2f})")
        ul = v.get(("nearfield", float(fov), 2, "closedloop_rms_log"))
        if ul is not None:
            parts.append(f"closed loop (sensor), 2 images: {_g(ul)}")
        ratio = u2 / h2
        out.append(Claim(key, _XU, where, claim, paper_value, f"{db}: " + "; ".join(parts), ratio,
                         _verdict(ratio <= UNSEEN_FACTOR), db, f"{p}, {errors.path}", figs))
    return out


#: RGL's spectralon: directional albedo at normal incidence ≈ 0.96 (issue 22), "≈" read as this tolerance.
SPECTRALON = {"database": "rgl-nbrdf", "material": "spectralon-rgb", "albedo": 0.96, "tolerance": 0.03}


def spectralon_albedo(paths: Sequence[str | os.PathLike[str]]) -> Claim:
    """A radiometric check of the fit-made tables: RGL's spectralon reflects ≈ 96 % at normal incidence.

    Read from the unseen databases' albedo CSVs (``database, material,
    theta_i_deg, r, g, b, luminance``): the luminance of the directional
    albedo of ``spectralon-rgb`` of ``rgl-nbrdf`` at θi = 0 within
    ``SPECTRALON["tolerance"]`` of 0.96.
    """
    sp = SPECTRALON
    key, where, figs = f"{UNSEEN_CLAIM_PREFIX}rgl-spectralon-albedo", "RGL database, spectralon (issue 22)", \
        ("unseen-albedo",)
    claim = (f"directional albedo (luminance) of the {sp['material']} fit at normal incidence within "
             f"±{sp['tolerance']:g} of {sp['albedo']:g}")
    paper_value = f"≈ {sp['albedo']:g} at normal incidence"
    paper = "Dupuy & Jakob 2018"
    found = []
    for path in paths:
        p, rows = _rows(path, tables.FIT_ALBEDO)
        found += [(p, r) for r in rows if r["database"] == sp["database"] and r["material"] == sp["material"]
                  and _num(p, r, "theta_i_deg") == 0.0]
    if not found:
        return _not_measured(key, paper, where, claim, paper_value,
                             f"{sp['material']} of {sp['database']} is not among this run's unseen materials",
                             ", ".join(str(x) for x in paths), figs)
    if len(found) > 1:
        raise ClaimsInputError(f"{found[1][0]}: {sp['material']} of {sp['database']} appears twice")
    p, r = found[0]
    lum = _num(p, r, "luminance")
    measured = (f"{sp['database']} {sp['material']}: r, g, b = {_num(p, r, 'r'):.3f}, {_num(p, r, 'g'):.3f}, {_num(p, r, 'b'):.3f}; "
                f"luminance {lum:.3f}")
    ok = abs(lum - sp["albedo"]) <= sp["tolerance"]
    return Claim(key, paper, where, claim, paper_value, measured, lum, _verdict(ok), sp["database"], str(p), figs)


def compute_claims(inputs: ClaimInputs) -> list[Claim]:
    """Every claim this run's outputs allow, in report order; the others as ``not measured``.

    :class:`ClaimsInputError` when the CSVs name different databases.
    """
    out: list[Claim] = []
    nm = _not_measured
    if inputs.errors is not None:
        e = read_errors(inputs.errors)
        for images, points in ((1, 5), (2, 10), (2, 20)):
            for baseline in ("error", "condition"):
                out.append(point_vs_images(e, images, points, baseline))
        out += [metric_vs_condition(e, "nearfield"), metric_vs_condition(e, "point"), error_vs_fov(e),
                fov25_nearly_best(e), fixed_vs_nearfield(e)]
    out.append(training_size_decreasing(inputs.training_size) if inputs.training_size is not None else
               nm("xu-training-size", _XU, "§6, Fig. 7", "error does not grow with the training set",
                  "a steady decrease", "this configuration has no training-size curve", figures=("xu-fig07",)))
    out.append(one_shot_optimum(inputs.fig08_table) if inputs.fig08_table is not None else
               nm("xu-one-shot-optimum", _XU, "§6, Fig. 8", "optimal single image slightly off-specular at ~50°",
                  "θh = 3° at about 50° incidence", "this configuration has no near-field sets", figures=("xu-fig08",)))
    if inputs.reproduction is not None:
        out.append(reproduction_vs_pca(inputs.reproduction))
    if inputs.spaces is not None:
        out.append(albedo_in_unit_interval(inputs.spaces))
    if inputs.paths is not None:
        out += [perceptual_uniformity(inputs.paths), eq7_bound(inputs.paths)]
    databases = {c.database for c in out if c.database}
    if inputs.traces:
        out.append(likelihood_increases(inputs.traces, next(iter(databases)) if len(databases) == 1 else ""))
    if inputs.bounce_shares is not None:
        out.append(second_bounce_share(inputs.bounce_shares))
    out.append(blend_vs_noise_floor(inputs.errormap_summary, floor_check=False) if inputs.errormap_summary is not None
               else nm("soler-blend-vs-noise-floor", _SOLER, "§5.2, Fig. 13", "blend within the noise floor",
                       "well below the numerical error", "this configuration renders no path point",
                       figures=("render-fig13",)))
    out.append(blend_vs_noise_floor(inputs.floor_check, floor_check=True) if inputs.floor_check is not None
               else nm("soler-blend-vs-floor-check", _SOLER, "§5.2, Fig. 13 (noise-floor check)",
                       "blend within the noise floor at many samples", "well below the numerical error",
                       "render.floor_check is off or there is no path point", figures=("render-floor-check",)))
    out.append(closed_loop_vs_table(inputs.closedloop) if inputs.closedloop is not None
               else nm("xu-closed-loop", _XU, "§7, Figs. 11, 12", "reconstruction from photographs",
                       'real two-shot captures reconstruct BRDFs whose renders "match well" the photographs',
                       "closed_loop is off", figures=("xu-closedloop",)))
    databases = {c.database for c in out if c.database}
    if len(databases) > 1:
        by_db = {d: sorted({c.source for c in out if c.database == d}) for d in sorted(databases)}
        raise ClaimsInputError(f"the run's CSVs name different databases: {by_db}")
    # materials outside the training database: each claim names its own (unseen) database
    if inputs.unseen is not None:
        if inputs.errors is None:
            raise ClaimsInputError(f"{inputs.unseen}: the unseen materials' claims need errors.csv")
        out += unseen_vs_heldout(read_errors(inputs.errors), inputs.unseen)
    if inputs.unseen_albedo:
        out.append(spectralon_albedo(inputs.unseen_albedo))
    return out


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
    """The rows of a ``claims.csv``."""
    p, rows = _rows(path, CLAIM_COLUMNS)
    return [{c: r[c] for c in CLAIM_COLUMNS} for r in rows]


def rst_cell(text: str) -> str:
    """Table-cell text safe for reStructuredText: renders exactly ``text`` (:func:`brdfpipe.report.rst.text`)."""
    return rst.text(text)


_MARK = {"yes": "**yes**", "no": "**NO**", "not measured": "not measured"}


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


def claims_table_rst(claims: Sequence[Claim], recorded: Sequence[RunClaims] = ()) -> str:
    """The claims table (a ``list-table``): paper, where, claim, paper value, this run, holds, database.

    Each run of ``recorded`` (another database's run, read back with
    :func:`read_run`) adds a column: its measurement and verdict for the same
    claim, headed by the database its CSV names; a claim only a recorded run
    makes (this run has no unseen materials, say) gets a row of its own,
    "(not in this run)" in this run's column; the runs' files are listed
    under the table.
    """
    widths = " ".join(["8 10 26 20 26 6 8", *["26"] * len(recorded)])
    lines = [".. list-table::", "   :header-rows: 1", f"   :widths: {widths}", "",
             "   * - paper", "     - where", "     - claim (as checked)", "     - paper value", "     - this run",
             "     - holds", "     - database"]
    lines += [f"     - {rst_cell(r.database)} (recorded run)" for r in recorded]
    for c in claims:
        cells = [rst_cell(c.paper), rst_cell(c.where), rst_cell(c.claim), rst_cell(c.paper_value), rst_cell(c.measured),
                 _MARK[c.holds], rst_cell(c.database)]
        for r in recorded:
            row = r.rows.get(c.key)
            cells.append("(not in that run)" if row is None
                         else f"{rst_cell(row['measured'])} ({_MARK.get(row['holds'], rst_cell(row['holds']))})")
        lines.append(f"   * - {cells[0]}")
        lines += [f"     - {x}" for x in cells[1:]]
    # the recorded runs' claims this run does not make (e.g. about unseen materials): their rows too
    own = {c.key for c in claims}
    extra = list(dict.fromkeys(k for r in recorded for k in r.order if k not in own))
    for key in extra:
        first = next(r.rows[key] for r in recorded if key in r.rows)
        cells = [rst_cell(first[f]) for f in ("paper", "where", "claim", "paper_value")]
        cells += ["(not in this run)", "", ""]
        for r in recorded:
            row = r.rows.get(key)
            cells.append("(not in that run)" if row is None
                         else f"{rst_cell(row['measured'])} ({_MARK.get(row['holds'], rst_cell(row['holds']))})")
        lines.append(f"   * - {cells[0]}")
        lines += [f"     - {x}" for x in cells[1:]]
    if recorded:
        lines += ["", "Recorded runs, each column read from its ``claims.csv`` (digest checked):", ""]
        lines += [f"- {rst_cell(r.database)}: {rst.literal(r.source)}" for r in recorded]
    return "\n".join(lines) + "\n"
