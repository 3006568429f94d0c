"""Soler et al. 2018's claims (§3–§5), checked as the paper states them.

The manifold claims read the default GPLVM candidate's rows of the manifold
CSVs and say which candidate that is — its data space, μ and how it is
fitted — against the paper's recipe (:data:`~brdfpipe.registry.manifold.PAPER_RECIPE`: raw BRDF values
and Gram, no normalisation, μ = 1e-4, Hooke–Jeeves from the truncated PCA).
When ``spaces.csv`` has the recipe's own rows, a claim the default fails is
put down to the method only if the recipe passes it.  What is checked is
what a renderer receives:

* ``spaces.csv``: ``albedo_clamped_bad_hull``, ``albedo_clamped_bad_map``
  (the share of hull points / map pixels whose *clamped* interpolated table
  has an albedo outside [0, 1]), the unclamped table's Σ wᵢ Aᵢ beside it as a
  diagnostic of negative lobes; ``jump_nn_*_1e-6`` (the table next to each
  material, towards its nearest neighbour);
* the render's ``summary.csv`` and ``floor-check.csv``:
  ``ratio_isolated_seed2``, ``ratio_isolated_seed2_se`` (the blend against a
  reference that differs from it only by the L²⁺ paths, the paper's
  question, not by the clamping of negative values), with ``sum_abs_w`` and
  ``clamped_fraction`` and the clamped reference's ratio beside it.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Mapping
from pathlib import Path

from brdfpipe.report.claims_base import (
    DIFFERS,
    REPRODUCES,
    SOLER,
    WITHIN,
    Claim,
    ClaimsInputError,
    g,
    graded,
    le,
    not_checkable,
    absent,
    not_measured,
    number,
    one_database,
    pct,
    read_rows,
    truthy,
)
from brdfpipe.registry import manifold as manifold_spec
from brdfpipe.registry import tables

__all__ = [
    "PERFECT",
    "NEGLIGIBLE",
    "ORDER_OF_MAGNITUDE",
    "NOISE_SIGMAS",
    "PAPER_BLEND_POINT",
    "CLAMPED_ALBEDO",
    "ISOLATED_RATIO",
    "FIT_COLUMNS",
    "JUMP_COLUMNS",
    "reproduction_vs_pca",
    "albedo_in_unit_interval",
    "negligible_discontinuity",
    "eq7_bound",
    "likelihood_converges",
    "second_bounce_share",
    "blend_vs_noise_floor",
    "read_paths",
    "not_checkable_claims",
]

#: "always perfectly reproduces" (§4.2, Fig. 8): exact to rounding (strictly); within the tolerance 1 % of the
#: material's norm, a difference no render of Fig. 8 shows — and still below PCA-40's.
PERFECT: tuple[float, float] = (1e-6, 1e-2)
#: "a negligible discontinuity in the interpolant" (§3): next to a material (1e-6 of the way to its nearest
#: neighbour) the interpolated table within 1 % of the material's norm (raw BRDF units), what a renderer cannot
#: tell apart.
NEGLIGIBLE: float = 1e-2
#: "L2+ ≪ L1−" (§5.2): an order of magnitude, L²⁺ ≤ L¹⁻/10, i.e. an I²⁺ share of at most 1/11.
ORDER_OF_MAGNITUDE: float = 1.0 / 11.0
#: Standard errors of the noise floor's own estimate a blend may exceed the floor by (the tolerance of Fig. 13).
NOISE_SIGMAS: float = 2.0
#: Fig. 13's point: the midpoint of chrome → silver-paint (5-D latent space).
PAPER_BLEND_POINT: tuple[str, float] = ("chrome--silver-paint", 0.5)
#: The columns of the clamped table's albedo (spaces.csv) and of the isolated blend reference (summary, floor check).
CLAMPED_ALBEDO: tuple[str, str] = ("albedo_clamped_bad_hull", "albedo_clamped_bad_map")
ISOLATED_RATIO: tuple[str, str] = ("ratio_isolated_seed2", "ratio_isolated_seed2_se")
#: How a candidate is fitted (spaces.csv).
FIT_COLUMNS: tuple[str, ...] = ("candidate", "space", "mu", "normalise", "method", "init")
#: The table's jump next to each material, towards its nearest neighbour (spaces.csv).
JUMP_COLUMNS: tuple[str, ...] = ("jump_nn_median_1e-6", "jump_nn_p90_1e-6", "jump_nn_max_1e-6", "jump_nn_worst")


def _is_paper(r: Mapping[str, str]) -> bool:
    try:
        return manifold_spec.is_paper_recipe(r["space"], float(r["mu"]), truthy(r["normalise"]), r["method"], r["init"])
    except ValueError:
        return False


def _candidate(r: Mapping[str, str]) -> tuple[str, bool]:
    """The default candidate's name in words (space, μ, how it is fitted), and whether it is the paper's recipe."""
    paper = _is_paper(r)
    how = ("the paper's recipe" if paper else
           manifold_spec.describe_fit(truthy(r["normalise"]), r["method"], r["init"]))
    return f"{r['candidate']} ({r['space']}, μ = {r['mu']}; {how})", paper


def _paper_recipe_note(paper: bool) -> str:
    return "" if paper else (" (not the paper's recipe: raw Gram without normalisation, μ = 1e-4, Hooke–Jeeves from "
                             "the truncated PCA)")


def _paper_rows(rows: list[dict[str, str]]) -> dict[str, dict[str, str]]:
    """The paper's recipe's rows of spaces.csv by q (empty when it is not among the candidates)."""
    return {r["q"]: r for r in rows if _is_paper(r)}


def _method_or_real(paper: bool, recipe: Mapping[str, str] | None, recipe_ok: bool | None, recipe_text: str) -> str:
    """The cause's opening: the default's method, or a real difference (the paper's recipe measured as well)."""
    if paper:
        return "a real difference: "
    if recipe is None or recipe_ok is None:
        return ("the method: the default candidate is not the paper's recipe (raw Gram without normalisation, μ = "
                "1e-4, Hooke–Jeeves from the truncated PCA), which is not measured here; ")
    if recipe_ok:
        return f"the method: the paper's recipe ({recipe['candidate']}) passes ({recipe_text}); the default "
    return f"a real difference: the paper's recipe ({recipe['candidate']}) fails too ({recipe_text}); the default "


def reproduction_vs_pca(path: str | os.PathLike[str] | None) -> Claim:
    """§4.2, Fig. 8: the GPLVM "always perfectly reproduces the training materials"; PCA-20/40 does not."""
    key, where, figs = "soler-reproduction", "§4.2, Fig. 8", ("soler-fig08",)
    sentence = ('"Our method always perfectly reproduces the training materials, regardless of the dimension of the '
                'parameter space; this is not the case for kernel approximations (here, using 20- and 40-dimensional '
                'PCA approximations)." (Fig. 8)')
    claim = (f"the largest GPLVM reproduction error (any q, any training material, relative to its norm): strictly "
             f"≤ {PERFECT[0]:g} (exact to rounding); within the tolerance ≤ {pct(PERFECT[1])} (no render of Fig. 8 "
             "shows it); and the median error of PCA with 20 and 40 components (else every k evaluated) above both")
    if path is None:
        return absent(key, SOLER, where, sentence, claim, "reproduction.csv", figs)
    p, rows, _ = read_rows(path, tables.columns(tables.REPRODUCTION, "database", "material", "method", "k",
                                                "relative_error"))
    database = one_database(p, rows)
    gp: dict[int, list[float]] = {}
    pca: dict[int, list[float]] = {}
    for r in rows:
        (gp if r["method"] == "gplvm" else pca if r["method"] == "pca" else {}).setdefault(
            int(number(p, r, "k")), []).append(number(p, r, "relative_error"))
    if not gp or not pca:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} lacks GPLVM or PCA rows", str(p), figs)
    worst = max(max(v) for v in gp.values())
    medians = {k: statistics.median(v) for k, v in sorted(pca.items())}
    named = {k: m for k, m in medians.items() if k in (20, 40)} or medians
    measured = (", ".join(f"GPLVM q = {q}: max {pct(max(v))}" for q, v in sorted(gp.items())) + "; "
                + ", ".join(f"PCA-{k}: median {pct(m)}" for k, m in medians.items()))
    pca_worse = all(m > max(worst, PERFECT[0]) for m in named.values())
    verdict = graded(worst <= PERFECT[0] and pca_worse, worst <= PERFECT[1] and all(m > worst for m in named.values()))
    cause = {REPRODUCES: f"largest GPLVM error {pct(worst)}; PCA-{'/'.join(map(str, named))} medians "
                         + ", ".join(pct(m) for m in named.values()),
             WITHIN: f"largest GPLVM error {pct(worst)}, within {pct(PERFECT[1])}",
             DIFFERS: (f"a real difference: the largest GPLVM error is {pct(worst)}" if worst > PERFECT[1] else
                       f"a real difference: PCA reproduces as well here (median {pct(min(named.values()))})")}[verdict]
    return Claim(key, SOLER, where, sentence, claim, measured, worst, verdict, cause, database, str(p), figs)


def _default_rows(p: Path, rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return sorted((r for r in rows if truthy(r["default"])), key=lambda r: number(p, r, "q"))


def _spaces_rows(path: str | os.PathLike[str], *cols: str) -> tuple[Path, list[dict[str, str]], list[dict[str, str]]]:
    """spaces.csv's rows (how each candidate is fitted and ``cols`` required) and the default candidate's, by q."""
    p, rows, _ = read_rows(path, tables.columns(tables.SPACES, "database", *FIT_COLUMNS, "q", "default", *cols))
    return p, rows, _default_rows(p, rows)


def albedo_in_unit_interval(path: str | os.PathLike[str] | None) -> Claim:
    """§4.2, Fig. 7: "The albedo of our interpolated model is observed to be limited to [0, 1]" (q = 2).

    On the clamped interpolated table (what a renderer receives); the
    unclamped one's Σ wᵢ Aᵢ is reported beside it (negative lobes).
    """
    key, where, figs = "soler-albedo", "§4.2, Fig. 7", ("soler-fig07", "soler-spaces", "soler-spaces-table")
    sentence = ('"The albedo of our interpolated model is observed to be limited to [0, 1] and it smoothly interpolates '
                'the albedo of the input materials." (Fig. 7, "Zoomed region of a 2D manifold of MERL BRDFs")')
    claim = ("the white-sky albedo of the interpolated table as a renderer receives it (negative values clamped to 0, "
             "the table brdfpipe interpolate writes), default candidate, q = 2 (the paper's): strictly outside [0, 1] "
             "nowhere in the latent hull nor the plotted map. Within the tolerance: on at most 1 % of the hull "
             "points — the paper shows \"a zoomed region\", which a small share elsewhere escapes")
    if path is None:
        return absent(key, SOLER, where, sentence, claim, "spaces.csv", figs)
    p, rows, mine = _spaces_rows(path, *CLAMPED_ALBEDO, "albedo_clamped_points", "albedo_bad_hull", "albedo_bad_map")
    if not mine:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} has no default candidate", str(p), figs)
    database = one_database(p, mine)
    name, paper = _candidate(mine[0])

    def shares(r: Mapping[str, str], hull_col: str, map_col: str) -> str:
        hull, amap = number(p, r, hull_col), number(p, r, map_col)
        return f"q = {r['q']}: {pct(hull)} of the hull" + (f", {pct(amap)} of the map" if math.isfinite(amap) else "")

    two = next((r for r in mine if r["q"] == "2"), mine[0])
    hull, amap = number(p, two, CLAMPED_ALBEDO[0]), number(p, two, CLAMPED_ALBEDO[1])
    worst = max(hull, amap if math.isfinite(amap) else 0.0)
    measured = (f"outside [0, 1] ({name}), clamped table: " + "; ".join(shares(r, *CLAMPED_ALBEDO) for r in mine)
                + f" ({two['albedo_clamped_points']} hull points); unclamped Σ wᵢ Aᵢ (negative lobes): "
                + "; ".join(shares(r, "albedo_bad_hull", "albedo_bad_map") for r in mine))
    verdict = graded(worst == 0.0, hull <= 0.01)
    share = f"{pct(hull)} of the q = {two['q']} hull" + (f" and {pct(amap)} of the map" if math.isfinite(amap) else "")
    if verdict == DIFFERS:
        recipe = _paper_rows(rows).get(two["q"])
        r_hull = number(p, recipe, CLAMPED_ALBEDO[0]) if recipe is not None else math.nan
        opening = _method_or_real(paper, recipe, None if recipe is None else r_hull <= 0.01,
                                  f"{pct(r_hull)} of its hull")
        cause = opening + f"{share} outside [0, 1] on the clamped table"
    else:
        cause = f"{share} outside [0, 1] (clamped table)" + _paper_recipe_note(paper)
    return Claim(key, SOLER, where, sentence, claim, measured, worst, verdict, cause, database, str(p), figs)


def negligible_discontinuity(spaces: str | os.PathLike[str] | None) -> Claim:
    """§3: μ = 1e-4 improves stability "at the cost of introducing a negligible discontinuity in the interpolant".

    Next to each material, 1e-6 of the way towards its nearest neighbour in
    latent space (``brdfpipe interpolate --between A B --t 1e-6``), the
    interpolated table's distance from the material's, relative to its norm
    (spaces.csv's ``jump_nn_*``).
    """
    key, where, figs = "soler-negligible-discontinuity", "§2.1, §3", ("soler-spaces", "soler-spaces-table")
    sentence = ('"A small value for μ (10^-4) significantly improves numerical stability when inverting K at the cost '
                'of introducing a negligible discontinuity in the interpolant." (§3)')
    claim = (f"next to each training material (t = 1e-6 of the way towards its nearest neighbour in latent space), the "
             f"interpolated table's distance to the material, relative to its norm in raw BRDF units, default "
             f"candidate: \"negligible\" as at most {pct(NEGLIGIBLE)} — a table a renderer cannot tell from the "
             "material's. Strictly: for every material; within the tolerance: for 90 % of them")
    if spaces is None:
        return absent(key, SOLER, where, sentence, claim, "spaces.csv", figs)
    p, rows, mine = _spaces_rows(spaces, *JUMP_COLUMNS)
    if not mine:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} has no default candidate", str(p), figs)
    database = one_database(p, mine)
    name, paper = _candidate(mine[0])
    stats = {r["q"]: (number(p, r, JUMP_COLUMNS[0]), number(p, r, JUMP_COLUMNS[1]), number(p, r, JUMP_COLUMNS[2]),
                      r[JUMP_COLUMNS[3]]) for r in mine}
    if not all(math.isfinite(v[2]) for v in stats.values()):
        return not_measured(key, SOLER, where, sentence, claim, f"{name}: the interpolant of its space is not linear "
                            "in the tables, so the jump is not measured from the Gram matrix", str(p), figs)
    measured = f"{name}: " + "; ".join(f"q = {q}: median {pct(m)}, 90th percentile {pct(p9)}, max {pct(mx)} ({w})"
                                       for q, (m, p9, mx, w) in stats.items())
    top_q = max(stats, key=lambda q: stats[q][2])
    top, p90, pair = stats[top_q][2], max(v[1] for v in stats.values()), stats[top_q][3].replace(">", " → ")
    verdict = graded(top <= NEGLIGIBLE, p90 <= NEGLIGIBLE)
    if verdict == DIFFERS:
        recipe = _paper_rows(rows)
        r_top = max((number(p, r, JUMP_COLUMNS[2]) for r in recipe.values()), default=math.nan)
        opening = _method_or_real(paper, next(iter(recipe.values()), None),
                                  None if not recipe or not math.isfinite(r_top) else r_top <= NEGLIGIBLE,
                                  f"jumps by at most {pct(r_top)}")
        cause = (opening + f"the interpolant jumps by up to {pct(top)} of a material's norm next to it ({pair}, q = "
                 f"{top_q}; 90th percentile {pct(p90)}): with the noise term μ the weights next to a material are not "
                 "its own")
    else:
        cause = f"up to {pct(top)} ({pair}; 90th percentile {pct(p90)})" + _paper_recipe_note(paper)
    return Claim(key, SOLER, where, sentence, claim, measured, top, verdict, cause, database, str(p), figs)


def read_paths(path: str | os.PathLike[str]) -> tuple[Path, str, dict[str, list[dict[str, float]]]]:
    """``paths.csv``: per path, its points (t, perceptual distances, deviation and bound) by t."""
    p, rows, _ = read_rows(path, tables.columns(tables.LATENT_PATHS, "database", "path", "t", "perceptual_a",
                                                "perceptual_b", "perceptual_ab", "deviation", "bound"))
    database = one_database(p, rows)
    out: dict[str, list[dict[str, float]]] = {}
    for r in rows:
        out.setdefault(r["path"], []).append({c: number(p, r, c) for c in
                                              ("t", "perceptual_a", "perceptual_b", "perceptual_ab", "deviation", "bound")})
    for v in out.values():
        v.sort(key=lambda d: d["t"])
    return p, database, out


def eq7_bound(path: str | os.PathLike[str] | None) -> Claim:
    """§4.1, eq. 7: the interpolant's deviation ‖z* − z_j‖ stays below the bound, at every path point."""
    key, where, figs = "soler-eq7-bound", "§4.1, eq. 7", ("soler-eq7",)
    sentence = ('"every choice of x* in the latent space leads to a mapping z* that can be connected to at least one of '
                'the training data points using: ‖z* − z_j‖ ≤ e^(−1/2) √(2N) / ℓ κ(K) ‖Z‖ ‖x* − x_j‖" (§4.1, eq. 7)')
    claim = "the deviation ‖z* − z_j‖ at most the eq. 7 bound at every latent-path point (a bound: no tolerance)"
    if path is None:
        return absent(key, SOLER, where, sentence, claim, "paths.csv", figs)
    p, database, paths = read_paths(path)
    pts = [d for v in paths.values() for d in v if math.isfinite(d["bound"]) and d["bound"] > 0]
    if not pts:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} has no bounded point", str(p), figs)
    worst = max(d["deviation"] / d["bound"] for d in pts)
    ok = all(le(d["deviation"], d["bound"]) for d in pts)
    measured = f"largest deviation / bound {g(worst)} over {len(pts)} points"
    cause = (f"deviation / bound at most {g(worst)}" if ok else
             f"a real difference: the deviation exceeds the bound, ×{g(worst)}")
    return Claim(key, SOLER, where, sentence, claim, measured, worst, REPRODUCES if ok else DIFFERS, cause, database,
                 str(p), figs)


def likelihood_converges(traces: Mapping[int, str | os.PathLike[str]], database: str) -> Claim:
    """§3, Fig. 5: the log-likelihood rises and converges over the iterations (each q of the default candidate).

    The traces carry no database column; ``database`` comes from the run's other CSVs.
    """
    key, where, figs = "soler-likelihood", "§3, Fig. 5", ("soler-fig05",)
    sentence = '"Figure 5: Convergence of the log-likelihood when fitting the full MERL database using a latent space of dimension 2"'
    claim = ("each fit's log-likelihood ends above its start and levels off: the last 10 % of the trace's steps gain "
             "at most 1 % of the whole rise (\"convergence\")")
    if not traces:
        return not_measured(key, SOLER, where, sentence, claim, "no GPLVM trace", "", figs)
    parts, ok, gains, srcs = [], True, [], []
    for q, path in sorted(traces.items()):
        p, rows, _ = read_rows(path, tables.GPLVM_TRACE)
        if not rows:
            raise ClaimsInputError(f"{p}: no data rows")
        ll = [number(p, r, "log_likelihood") for r in rows]
        tail = ll[-1] - ll[min(len(ll) - 1, math.ceil(0.9 * (len(ll) - 1)))]
        rise = ll[-1] - ll[0]
        ok = ok and rise > 0 and tail <= 0.01 * rise
        gains.append(rise)
        stages = ", ".join(dict.fromkeys(r["stage"] for r in rows))
        parts.append(f"q = {q}: {ll[0]:.6g} → {ll[-1]:.6g} over {len(ll)} steps ({stages}); last 10 %: "
                     f"{tail / rise:.1%} of the rise" if rise > 0 else f"q = {q}: {ll[0]:.6g} → {ll[-1]:.6g}")
        srcs.append(str(p))
    cause = ("rises and levels off at every q" if ok else
             "the method: a fit still rising at its end, or not above its start (this project's optimiser, not the "
             "paper's Hooke–Jeeves search)")
    return Claim(key, SOLER, where, sentence, claim, "; ".join(parts), min(gains), REPRODUCES if ok else DIFFERS,
                 cause, database, ", ".join(srcs), figs)


def second_bounce_share(path: str | os.PathLike[str] | None) -> Claim:
    """§5.2: "In practice we expect L2+ ≪ L1−" (the I²⁺ share of each pre-render over the object)."""
    key, where, figs = "soler-second-bounce", "§5.2", ("render-prerenders",)
    sentence = ('"In practice we expect L2+ ≪ L1−, since the measure of multiple-bounce paths for which more than one of '
                'the bounces on ρ is expected to be small." (§5.2; not measured in the paper)')
    claim = (f"the I²⁺ share of each pre-render over the object: \"≪\" as an order of magnitude, L²⁺ ≤ L¹⁻/10, a share "
             f"≤ 1/11 ({pct(ORDER_OF_MAGNITUDE)}). Strictly: for every material; within the tolerance (\"in practice "
             "we expect\": the typical case): for the median material")
    if path is None:
        return absent(key, SOLER, where, sentence, claim, "bounce-shares.csv", figs)
    p, rows, _ = read_rows(path, tables.columns(tables.BOUNCE_SHARES, "database", "material", "share_object"))
    if not rows:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} has no rows", str(p), figs)
    database = one_database(p, rows)
    shares = {r["material"]: number(p, r, "share_object") for r in rows}
    worst = max(shares, key=lambda m: shares[m])
    median = statistics.median(shares.values())
    measured = f"median {pct(median)}, largest {pct(shares[worst])} ({worst}) over {len(shares)} materials"
    over = sorted(m for m, s in shares.items() if s > ORDER_OF_MAGNITUDE)
    verdict = graded(not over, median <= ORDER_OF_MAGNITUDE)
    cause = {REPRODUCES: f"largest share {pct(shares[worst])} ({worst})",
             WITHIN: f"median {pct(median)}; above {pct(ORDER_OF_MAGNITUDE)} for {len(over)} material(s), e.g. {worst}",
             DIFFERS: f"a real difference: median share {pct(median)}"}[verdict]
    return Claim(key, SOLER, where, sentence, claim, measured, shares[worst], verdict, cause, database, str(p), figs)


def _blend_rows(path: str | os.PathLike[str], floor_check: bool) -> tuple[Path, list[dict[str, str]]]:
    required = ("database", "path", "t", "ratio_seed2", "ratio_one_seed2", "ratio_seed2_se", "sum_abs_w",
                "clamped_fraction", *ISOLATED_RATIO)
    if floor_check:
        required += ("candidate", "default", "spp")
    p, rows, _ = read_rows(path, required)
    return p, ([r for r in rows if truthy(r["default"])] if floor_check else rows)


def blend_vs_noise_floor(path: str | os.PathLike[str] | None, *, floor_check: bool) -> Claim:
    """§5.2, Fig. 13: blended pre-renders against a reference render: "well below the numerical error".

    The paper's question is the L²⁺ approximation (eq. 13), so the verdict
    is on the blend against a reference that differs from it only by the
    L²⁺ paths (:data:`ISOLATED_RATIO`; :func:`brdfpipe.rendering.blend.error_maps`):
    ratio RMSE(blend, that reference of the second seed) / RMSE(the two
    seeds' references) on the whole image.  At the paper's point
    (:data:`PAPER_BLEND_POINT`) when rendered, else at every path point (the
    worst).  Strictly: at most 1; within the tolerance: at most 1 +
    :data:`NOISE_SIGMAS` standard errors of the floor's own estimate.  The
    clamped reference's ratio is reported with Σ|w| and the share of the
    table it clamps.  ``floor_check``: read ``floor-check.csv`` (default
    candidate, many samples) instead of the render's ``summary.csv``.
    """
    if floor_check:
        key, where = "soler-blend-vs-floor-check", "§5.2, Fig. 13 (noise-floor check)"
        figs: tuple[str, ...] = ("render-floor-check", "render-floor-check-table")
    else:
        key, where = "soler-blend-vs-noise-floor", "§5.2, Figs. 12, 13"
        figs = ("render-fig12", "render-fig13", "render-errormap", "render-summary")
    sentence = ('"The differences, due to the absence of L2+ paths in our solution, are barely perceptible (well below '
                'the numerical error between the two images in the difference inset image)." (Fig. 13: the midpoint '
                'of chrome → silver-paint, 5-D latent space)')
    if path is None:
        return absent(key, SOLER, where, sentence, "blend of pre-renders against a reference render",
                      "the noise-floor check" if floor_check else "a rendered path point", figs)
    p, rows = _blend_rows(path, floor_check)
    col, se_col = ISOLATED_RATIO
    paper_pt = [r for r in rows if r["path"] == PAPER_BLEND_POINT[0] and math.isclose(number(p, r, "t"), PAPER_BLEND_POINT[1])]
    where_text = ("at the paper's point (chrome → silver-paint, t = 0.5)" if paper_pt else
                  "at every rendered path point (the paper's chrome → silver-paint midpoint is not rendered here)")
    claim = ("blend of pre-renders against a reference render, whole image: RMSE(blend, reference) / RMSE(two seeds of "
             f"the reference) {where_text}, against a reference that differs only by the L²⁺ paths (Σ wᵢ I¹⁻ᵢ, the "
             "unclamped table's I¹⁻ part, plus the reference's I²⁺). \"well below the numerical error\": strictly at "
             "most 1 (a blend as close as a second render — both sides are noisy, so no blend reads below ≈ 1); "
             f"within the tolerance at most 1 + {NOISE_SIGMAS:g} standard errors of the floor's own estimate")
    if not rows:
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name} has no path point", str(p), figs)
    rows = paper_pt or rows
    database = one_database(p, rows)
    ratio = [number(p, r, col) for r in rows]
    if not all(map(math.isfinite, ratio)):
        return not_measured(key, SOLER, where, sentence, claim, f"{p.name}: no reference isolating the L²⁺ paths (no "
                            "I¹⁻ renders)", str(p), figs)
    se = [number(p, r, se_col) for r in rows]
    excess = [(w - 1.0) / e if e > 0 else (math.inf if w > 1.0 else -math.inf) for w, e in zip(ratio, se)]
    i = max(range(len(rows)), key=lambda j: excess[j])
    worst = rows[i]
    clamped_ratio = number(p, worst, "ratio_seed2")
    what = f"{rows[0]['candidate']}, {rows[0]['spp']} spp, " if floor_check else ""
    measured = (f"{what}{len(rows)} point(s): blend / floor {g(min(ratio))}–{g(max(ratio))} against the reference "
                f"isolating L²⁺; worst {worst['path']} t = {worst['t']}: {g(ratio[i])} ± {g(se[i])}, Σ|w| "
                f"{g(number(p, worst, 'sum_abs_w'))}, clamped share {pct(number(p, worst, 'clamped_fraction'))}; "
                f"against the clamped reference {g(clamped_ratio)}; I¹⁻ part "
                f"{g(min(number(p, r, 'ratio_one_seed2') for r in rows))}–"
                f"{g(max(number(p, r, 'ratio_one_seed2') for r in rows))}")
    verdict = graded(all(le(w, 1.0) for w in ratio), all(x <= NOISE_SIGMAS for x in excess))
    if verdict != DIFFERS:
        cause = f"worst {g(ratio[i])}" + (f", {excess[i]:.2g} s.e. above 1" if ratio[i] > 1 else "")
        if clamped_ratio > ratio[i] + NOISE_SIGMAS * max(se[i], 0.0):
            cause += (f"; against the clamped reference {g(clamped_ratio)}: the excess is the clamping of "
                      f"{pct(number(p, worst, 'clamped_fraction'))} of the table, which no blend of pre-renders can "
                      "do, not the L²⁺ approximation")
    else:
        cause = (f"a real difference: against a reference that differs only by the L²⁺ paths the blend is "
                 f"{excess[i]:.3g} s.e. above the floor at {worst['path']} t = {worst['t']} (Σ|w| "
                 f"{g(number(p, worst, 'sum_abs_w'))})")
    return Claim(key, SOLER, where, sentence, claim, measured, ratio[i], verdict, cause, database, str(p), figs)


def not_checkable_claims() -> list[Claim]:
    """Soler's claims no run of this project can check."""
    return [
        not_checkable("soler-plausible", SOLER, "§4.3, Fig. 1",
                      '"These experiments are consistent with the behavior that we observed, that the resulting '
                      'materials remain plausible everywhere in the latent space." (§4.3)',
                      "a perceptual user study, which the paper leaves out too (\"beyond the scope of our work\")",
                      ("soler-fig09",)),
    ]
