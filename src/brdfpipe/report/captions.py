"""Report captions: what each figure shows, and the paper's claims it carries, with this run's numbers.

A caption is reStructuredText written by rule ``write_claims`` from the
run's claims (:mod:`brdfpipe.report.claims`), one file per figure, table or
set of error maps (:func:`brdfpipe.core.filenames.caption`).  Snakemake reads a
caption file when it builds the report (``snakemake --report``), not when
it parses the workflow, so the captions can hold numbers computed by a job.
Snakemake renders captions as Jinja2 templates first: the text is wrapped
in a ``raw`` block so no measured text is ever read as template syntax.
Every string that comes from the run (claims, the database label, file
names) is escaped by :mod:`brdfpipe.report.rst`, so no name can inject
markup, a link or template code.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from brdfpipe.core import atomic
from brdfpipe.report import rst
from brdfpipe.report.claims import Claim, rst_cell
from brdfpipe.report.items import FIGURE_NUMBERS

__all__ = ["DESCRIPTIONS", "caption_rst", "write_captions"]

#: Caption key → what the figure or table shows (the claims follow it).
DESCRIPTIONS: dict[str, str] = {
    "xu-fig05": "Mean RMS error of the log-mapped BRDF over the held-out materials vs the number of near-field "
                "images, one panel per field of view: direction sets chosen by min E(S) (eq. 15) and by "
                "min κ (Xu eq. 6, over all k components).",
    "xu-fig06": "Mean RMS error vs the number of images (near-field, every FOV) or point samples, min E(S); "
                "point samples chosen by min κ dashed.",
    "xu-fig07": "Mean RMS error of 2-image near-field acquisition vs the number of training materials "
                "(materials added in seeded random order).",
    "xu-fig08": "The optimal near-field configurations (1 and 2 images) per FOV, optimised on all materials: light "
                "and camera directions over the sample. The CSV/Markdown table next to it lists the angles.",
    "xu-fig08-table": "Xu Fig. 8's table: per FOV and set size, each image's (θh, θd, φd), light and camera "
                      "directions and the predicted E(S).",
    "xu-fig13": "Mean RMS error vs the number of images for the image setups at one FOV: near-field (both move), "
                "fixed camera with moving lights, fixed light with moving cameras; solid min E(S), dashed min κ.",
    "xu-fig18": "Per held-out material RMS error of point sampling with 5 samples (or fewer when n_max_point is "
                "smaller): min E(S) vs min κ, and the deviation floor (all cells observed).",
    "xu-fig19": "Mean RMS error of point sampling vs the number of samples n: min E(S) vs min κ, with the "
                "deviation floor.",
    "xu-closedloop": "Closed loop: each held-out material photographed by the optimised set-ups (Mitsuba 3, the "
                     "``merl`` BSDF on a flat sample, a point light, the set-up's camera and resolution, a sensor "
                     "with photon and read noise and HDR bracketing), its BRDF read off the pixels (fall-off and "
                     "cosine removed, low-signal pixels masked) and reconstructed; left: mean RMS log error of the "
                     "table lookup, of the noiseless render and of the sensor's photograph per direction set; right: "
                     "per material, closed-loop / table error against the share of disk pixels not used.",
    "xu-closedloop-table": "``closedloop.csv``: per held-out material, channel and captured direction set the "
                           "table-lookup errors (kinds ``rms_log``, ``relrms_linear``), the closed-loop errors from "
                           "the noiseless render (``closedloop_noiseless_*``) and from the sensor "
                           "(``closedloop_*``), the observations used and the share of pixels masked.",
    "xu-unseen": "Materials never seen by any model of the run (config ``unseen``: e.g. the RGL and Nielsen "
                 "materials through their NBRDF fits), acquired with the model and direction sets trained on the "
                 "run's database, next to its held-out materials. Left: mean RMS log error of point sampling (min "
                 "E(S)) vs the number of samples, per unseen database (thin: each material; dotted: the floors with "
                 "every cell observed). Then per set size (1, 2 images): near-field error vs field of view by table "
                 "lookup (solid) and by the closed loop from rendered photographs (dashed).",
    "xu-unseen-table": "``unseen.csv``: the columns of ``errors.csv`` plus ``model_database``: per unseen material "
                       "(``database`` its own), channel and direction set the table-lookup error (``rms_log``), the "
                       "closed loop's (``closedloop_noiseless_rms_log``, ``closedloop_rms_log``), the deviation "
                       "floor and the observations used; means per database as material ``mean``.",
    "unseen-albedo": "Directional albedo at normal incidence of each unseen material's fit-made table "
                     "(``merl.directional_albedo``), a radiometric check of the tables: RGL's spectralon should "
                     "reflect about 96 %.",
    "soler-unseen": "Materials outside the training set on the default candidate's manifold: left, their latent "
                    "position x* (filled: maximising the GP likelihood of the material given the fitted model; "
                    "open: least squares of Σ bᵢ(x) zᵢ against it) among the training materials; right, the relative "
                    "error of b(x*)'s reproduction of each, next to the projection on k principal components of the "
                    "same training materials (k = each q and the configured PCA sizes).",
    "soler-unseen-table": "``manifold/unseen.csv``: per unseen material and method (``gplvm-likelihood``, "
                          "``gplvm-least-squares`` with k = q, ``pca`` with k) the relative reproduction error, the "
                          "GP log-likelihood at x*, the nearest training material and x*.",
    "soler-fig05": "GPLVM log-likelihood over the optimiser's steps (start, L-BFGS, Newton, Hooke–Jeeves), default "
                   "candidate, each latent dimension q.",
    "soler-fig10_q2": "The 2-D latent space of the default candidate: every material at its latent point, "
                      "coloured by its albedo.",
    "soler-fig10_q5": "Slices of the 5-D latent space (pairs of dimensions) of the default candidate.",
    "soler-fig07": "Albedo of the interpolated BRDF over a latent plane (q = 2 and a slice of q = 5) with iso-lines "
                   "and the training materials; values outside [0, 1] marked.",
    "soler-fig09": "Perceptual distance of the interpolated materials to A and to B along the latent paths, "
                   "normalised by d(A, B) and the latent distance; dashed: perceptually uniform.",
    "soler-fig08": "Relative reproduction error of every training material by PCA-k and by the GPLVM (each q).",
    "soler-eq7": "Actual deviation ‖z* − z_j‖ of the interpolant from the nearest training material vs the "
                 "eq. 7 bound, along the latent paths.",
    "soler-spaces": "Every GPLVM candidate (data space, μ) measured the same way: κ(K), albedo outside [0, 1], "
                    "Σ|w|, stability near the training points, perceptual uniformity.",
    "soler-spaces-table": "``spaces.csv``: every candidate's measures (one row per candidate and q).",
    "render-fig01": "Global-illumination pre-renders of every material (Mitsuba 3, the ``merl`` BSDF), the "
                    "images the blends are made of.",
    "render-fig12": "Interpolation along each latent path: the blend of pre-renders Σ wᵢ Iᵢ next to the true "
                    "render of the interpolated material.",
    "render-fig13": "Error panel: blend, reference and their difference at each rendered path point, with the "
                    "two-seed noise floor.",
    "render-errormap": "False-colour map of |blend − reference| at one rendered path point (labels: path, t), "
                       "with a colour bar.",
    "render-summary": "``summary.csv``: per path point the relative RMSE of the blend vs the reference (same and "
                      "second seed), the two-seed noise floor and their ratios, for the whole image and its I¹⁻ part.",
    "render-floor-check": "The noise-floor check: blends vs the noise floor of every checked candidate's path "
                          "points, rendered small with many samples (render.floor_check).",
    "render-floor-check-table": "``floor-check.csv``: per candidate and path point Σ|w|, ‖w‖₂, the clamped share, "
                                "the two-seed noise floor and the blend / floor ratios.",
    "claims": "Every quantitative claim of both papers: the paper's value, this run's value computed from its "
              "CSVs, and whether it holds (also on the front page).",
}

#: Extra note for the EXR error maps, which browsers cannot show ({error}, {blended}: rst literals).
_EXR_NOTE = ("The error maps' data are EXR files (float32, not shown: browsers cannot display EXR): "
             "{error} (\\|blend − reference\\|) and {blended} (the blend), next to each PNG shown here.")


def _bars(text: str) -> str:
    """``|x|`` in the descriptions is an absolute value, not an rst substitution."""
    return text.replace("|", "\\|")


def _claim_item(c: Claim) -> str:
    mark = {"yes": "**holds**", "no": "**does not hold**", "not measured": "not measured"}[c.holds]
    return (f"- {rst_cell(c.paper)}, {rst_cell(c.where)}: {rst_cell(c.claim)}. Paper: {rst_cell(c.paper_value)}. "
            f"This run: {rst_cell(c.measured)}. {mark}.")


def caption_rst(key: str, claims: Iterable[Claim], *, database: str, files: Sequence[str] = ()) -> str:
    """The caption of one report entry: title with database, description, its claims, the files it covers."""
    if key not in DESCRIPTIONS:
        raise KeyError(f"no caption description for {key!r}")
    mine = [c for c in claims if key in c.figures]
    lines = [f"**{FIGURE_NUMBERS[key]}** analogue — database: **{rst.text(database)}**", "",
             _bars(DESCRIPTIONS[key]), ""]
    if mine:
        lines += ["Claims (paper value vs this run):", ""] + [_claim_item(c) for c in mine] + [""]
    else:
        lines += ["The paper makes no quantitative claim about this figure; it is shown for comparison.", ""]
    if key == "render-errormap":
        prefixes = sorted({f[: -len("-error.png")] for f in files if f.endswith("-error.png")})
        prefix = prefixes[0] if len(prefixes) == 1 else "<path>-t<t>"
        lines += [_EXR_NOTE.format(error=rst.literal(f"{prefix}-error.exr"),
                                   blended=rst.literal(f"{prefix}-blended.exr")), ""]
    pdfs = [f[:-4] + ".pdf" for f in files if f.endswith(".png") and key != "render-errormap"]
    if pdfs:
        lines += ["Vector version: " + ", ".join(rst.literal(p) for p in pdfs) + ".", ""]
    return rst.jinja_raw("\n".join(lines))


def write_captions(items: Sequence[Mapping[str, str]], claims: Sequence[Claim], *, database: str) -> list[Path]:
    """One caption file per distinct ``caption`` of ``items`` (dicts with ``key``, ``path``, ``caption``)."""
    by_caption: dict[str, tuple[str, list[str]]] = {}
    for it in items:
        key, files = by_caption.setdefault(it["caption"], (it["key"], []))
        if key != it["key"]:
            raise ValueError(f"caption {it['caption']} is shared by {key!r} and {it['key']!r}")
        files.append(it["path"])
    out = []
    for cap, (key, files) in by_caption.items():
        atomic.write_text(cap, caption_rst(key, claims, database=database, files=files))
        out.append(Path(cap))
    return out
