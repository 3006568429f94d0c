"""Every figure of the three tracks, and every other entry of the report: one record each.

A :class:`Figure` holds what the stages need to know about one figure: its
track and key, its file stem (``results/figures/<stem>.png`` and ``.pdf``,
:func:`brdfpipe.core.filenames.figure_files`), the paper figure it is an
analogue of, its caption (the report's description, before the claims
that carry this run's numbers), the rule that draws it, the function that
draws it (in the track's ``figures`` module: ``brdfpipe.<track>.figures``)
and whether a configuration produces it.  The file names
(:mod:`brdfpipe.core.filenames`), the planner (:mod:`brdfpipe.plan`),
the report's entries and captions (:mod:`brdfpipe.plan.report`,
:mod:`brdfpipe.report.captions`) and the tracks' figure functions all read
this registry.  :class:`ReportEntry`: the report's other entries (tables,
error maps, the claims), with their caption.

Adding a figure drawn from a track's existing inputs: a record in
:data:`FIGURES` here and its drawing function in the track's
``figures.py`` (a line in its ``make_*_figures`` table calls it).  See
``docs/design/extending.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from brdfpipe.registry.acquisition import FIXED_SETUPS, METRIC_KINDS

__all__ = [
    "FIG02_MATERIALS",
    "FIG02_FALLBACK_COUNT",
    "PREVIOUS_WORK_METRIC",
    "PREVIOUS_WORK_POINTS",
    "ReconSet",
    "TRACK_PREFIX",
    "Figure",
    "ReportEntry",
    "FIGURES",
    "REPORT_ENTRIES",
    "track_figures",
    "figure",
    "paper_figures",
    "captions",
]

#: The held-out materials Xu Fig. 2 shows (Xu §6: their nine less green fabric and silver metallic paint, "whose
#: results are very similar to black soft plastic and two layer silver"); also Figs. 3 and 15's.
FIG02_MATERIALS: tuple[str, ...] = (
    "black-soft-plastic", "blue-acrylic", "light-red-paint", "pink-jasper", "specular-violet-phenolic",
    "two-layer-silver", "white-fabric",
)
#: On a database that holds none of them out: Figs. 2, 3 and 15 show its first held-out materials, this many.
FIG02_FALLBACK_COUNT: int = 4
#: The criterion of the point-sample sets of Xu Fig. 2's "previous work" columns (Nielsen et al. 2015).
#: ``condition`` is κ over all k components (Xu eq. 6); Nielsen's κ as released is ``condition_nielsen``.
PREVIOUS_WORK_METRIC: str = "condition_nielsen"
#: The point-sample counts of Xu Fig. 2's "previous work" columns: 5 beside the 1-image result, 20 beside the
#: 2-image one (fewer when ``acquisition.n_max_point`` is smaller).
PREVIOUS_WORK_POINTS: tuple[int, int] = (5, 20)

#: A direction set whose reconstructions a figure shows (Xu Figs. 2, 15): (setup, fov, metric, n).
ReconSet = tuple[str, float, str, int]

#: Track → the prefix of its figures' report keys (``xu-fig05``, ``soler-fig10_q2``, ``render-fig01``).
TRACK_PREFIX: dict[str, str] = {"acquisition": "xu", "manifold": "soler", "rendering": "render"}


# -- whether a configuration produces a figure --------------------------------
# Each takes the settings of the figure's track: the config's ``acquisition``
# or ``manifold`` section, or ``{"n_path_points": n, "n_samples": m}`` for the
# rendering track.

def _has_training_curve(acquisition: Mapping[str, Any]) -> bool:
    """Xu Fig. 7: a near-field error-metric set to draw the training-size curve with, and sizes to draw."""
    return ("nearfield" in acquisition["setups"] and "error" in acquisition["metrics"]
            and bool(acquisition["training_sizes"]))


def _has_nearfield(acquisition: Mapping[str, Any]) -> bool:
    return "nearfield" in acquisition["setups"]


def _has_fixed(acquisition: Mapping[str, Any]) -> bool:
    return bool(set(acquisition["setups"]) & set(FIXED_SETUPS))


def _has_nearfield_error(acquisition: Mapping[str, Any]) -> bool:
    """Xu Figs. 2, 3, 9: the near-field sets chosen by E(S)."""
    return "nearfield" in acquisition["setups"] and "error" in acquisition["metrics"]


def _has_fixed_error(acquisition: Mapping[str, Any]) -> bool:
    """Xu Fig. 14: a fixed-camera or fixed-light set-up's sets chosen by E(S)."""
    return _has_fixed(acquisition) and "error" in acquisition["metrics"]


def _has_fixed_camera_pair(acquisition: Mapping[str, Any]) -> bool:
    """Xu Fig. 15: the fixed-camera set of two images chosen by E(S)."""
    return ("fixed_camera" in acquisition["setups"] and "error" in acquisition["metrics"]
            and int(acquisition["n_max_images"]) >= 2)


def _has_point(acquisition: Mapping[str, Any]) -> bool:
    return "point" in acquisition["setups"]


def _has_q3(manifold: Mapping[str, Any]) -> bool:
    """Slices of a latent space need q ≥ 3."""
    return max(int(q) for q in manifold["latent_dims"]) >= 3


def _has_albedo_map(manifold: Mapping[str, Any]) -> bool:
    """An albedo map needs a latent plane (q ≥ 2)."""
    return any(int(q) >= 2 for q in manifold["latent_dims"])


def _has_path_points(rendering: Mapping[str, Any]) -> bool:
    return int(rendering["n_path_points"]) > 0


def _has_samples(rendering: Mapping[str, Any]) -> bool:
    """Soler Fig. 1: materials at random latent points (``render.latent_samples.count`` > 0)."""
    return int(rendering.get("n_samples", 0)) > 0


@dataclass(frozen=True)
class Figure:
    """One figure: ``track``, ``key`` (unique in the track), file ``stem``, ``paper`` figure, ``caption``.

    ``rule``: the workflow rule that draws it; ``draw``: the function of
    ``brdfpipe.<track>.figures`` that draws it.  ``table``: a CSV and a
    Markdown table are written next to the PNG and PDF.  ``note``: a note
    (``<stem>.json``: one paragraph of the run's numbers) is written next to
    them, and the report's caption quotes it.  ``when``: whether a
    configuration produces it (the track's settings → bool; None: always,
    once its rule runs).
    """

    track: str
    key: str
    stem: str
    paper: str
    rule: str
    draw: str
    caption: str
    table: bool = False
    note: bool = False
    when: Callable[[Mapping[str, Any]], bool] | None = None

    @property
    def report_key(self) -> str:
        """The key of its report entry and caption (``xu-fig05``)."""
        return f"{TRACK_PREFIX[self.track]}-{self.key}"

    def produced(self, settings: Mapping[str, Any]) -> bool:
        """Whether a configuration with the track's ``settings`` produces it."""
        return self.when is None or self.when(settings)


@dataclass(frozen=True)
class ReportEntry:
    """A report entry that is not a figure: its key, the paper figure it belongs to, its caption."""

    key: str
    paper: str
    caption: str


#: Every figure, in the report's order within each track.
FIGURES: tuple[Figure, ...] = (
    Figure('acquisition', 'fig02', 'fig02-reconstructions', 'Xu Fig. 2', rule='plot_reconstruction_figures', draw='fig02_reconstructions', table=True, when=_has_nearfield_error,
           caption=('Held-out materials reconstructed from 1 and from 2 near-field images (FOV 25°, else the first '
                    'configured; min E(S)) and from 5 and 20 point samples of previous work, '
                    f'{METRIC_KINDS[PREVIOUS_WORK_METRIC].label}, rendered in the pre-renders\' scene '
                    '(Mitsuba 3, same settings and seed), next to the reference, the material\'s own pre-render; '
                    'inputs: the observed pixels of each image (BRDF × cos θi, table lookup). Each panel gives the '
                    'RMS log error of its table and the relative RMS difference of its render from the reference; '
                    'the CSV/Markdown table next to it lists every panel.')),
    Figure('acquisition', 'fig03', 'fig03-recon-vs-deviation', 'Xu Fig. 3', rule='plot_acquisition_figures', draw='fig03_recon_vs_deviation', table=True, when=_has_nearfield_error,
           caption=('E_recon (eq. 12) of the 1- and 2-image near-field sets (FOV 25°, else the first configured; '
                    'min E(S)) next to '
                    'E_deviation (eq. 9) for each material of Fig. 2, RMS over the cells of the log-mapped BRDF; '
                    'E_recon = √(rms_log² − E_deviation²) from errors.csv (the residual of the least-squares '
                    'projection is orthogonal to the span of Q). The CSV/Markdown table next to it lists the '
                    'values.')),
    Figure('acquisition', 'fig05', 'fig05-error-vs-images', 'Xu Fig. 5', rule='plot_acquisition_figures', draw='fig05_error_vs_images',
           caption=('Mean RMS error of the log-mapped BRDF over the held-out materials vs the number of near-field '
                    'images, one panel per field of view: direction sets chosen by min E(S) (eq. 15) and by min κ (Xu'
                    ' eq. 6, over all k components).')),
    Figure('acquisition', 'fig06', 'fig06-fov-vs-point', 'Xu Fig. 6', rule='plot_acquisition_figures', draw='fig06_fov_vs_point',
           caption=('Mean RMS error vs the number of images (near-field, every FOV) or point samples, min E(S); point'
                    ' samples of the previous work (red: min κ of the first n components, Nielsen 2015 as released)'
                    ' and of min κ over all k components (Xu eq. 6, dotted).')),
    Figure('acquisition', 'fig07', 'fig07-training-size', 'Xu Fig. 7', rule='plot_acquisition_figures', draw='fig07_training_size', when=_has_training_curve,
           caption=('Mean RMS error of 2-image near-field acquisition vs the number of training materials (materials '
                    'added in seeded random order).')),
    Figure('acquisition', 'fig08', 'fig08-optimal-configurations', 'Xu Fig. 8', rule='plot_acquisition_figures', draw='fig08_optimal_configurations', table=True, when=_has_nearfield,
           caption=('The optimal near-field configurations (1 and 2 images) per FOV, optimised on all materials: '
                    'light and camera directions over the sample. The CSV/Markdown table next to it lists the angles.')),
    Figure('acquisition', 'fig09', 'fig09-configurations-fov25', 'Xu Fig. 9', rule='plot_acquisition_figures', draw='fig09_configurations', table=True, when=_has_nearfield_error,
           caption=('The one- and two-shot near-field configurations at FOV 25° (else the first configured) with '
                    'which the held-out materials '
                    'are acquired (min E(S), training split): light and camera over the sample (3-D sketch and top '
                    'view) and their angles; the CSV/Markdown table next to it lists them in in-out and '
                    'Rusinkiewicz coordinates.')),
    Figure('acquisition', 'fig13', 'fig13-fixed-camera-light', 'Xu Fig. 13', rule='plot_acquisition_figures', draw='fig13_fixed_camera_light', when=_has_fixed,
           caption=('Mean RMS error vs the number of images for the image setups at one FOV: near-field (both move), '
                    'fixed camera with moving lights, fixed light with moving cameras; solid min E(S), dashed min κ.')),
    Figure('acquisition', 'fig14', 'fig14-fixed-configurations', 'Xu Fig. 14', rule='plot_acquisition_figures', draw='fig14_fixed_configurations', table=True, when=_has_fixed_error,
           caption=('The optimal two-image configurations with a fixed camera (moving light) and with a fixed light '
                    '(moving camera), min E(S), training split, analogous to Fig. 9; angles in in-out (θi, φi, θo, '
                    'φo) and Rusinkiewicz (θh, θd, φd) coordinates (the CSV/Markdown table next to it).')),
    Figure('acquisition', 'fig15', 'fig15-fixed-camera-reconstructions', 'Xu Fig. 15', rule='plot_reconstruction_figures', draw='fig15_fixed_camera_reconstructions', table=True, when=_has_fixed_camera_pair,
           caption=('The materials of Fig. 2 reconstructed from two images with a fixed camera (min E(S)), rendered '
                    'as in Fig. 2 next to their 2-image near-field reconstruction and the reference; inputs: the '
                    'observed pixels of each image. The CSV/Markdown table next to it lists every panel.')),
    Figure('acquisition', 'fig18', 'fig18-per-material', 'Xu Fig. 18', rule='plot_acquisition_figures', draw='fig18_per_material', when=_has_point,
           caption=('Per held-out material RMS error of point sampling with 5 samples (or fewer when n_max_point is '
                    'smaller): min E(S) vs the previous work (red: min κ of the first n components, Nielsen 2015 as '
                    'released) and min κ over all k (Xu eq. 6), and the deviation floor (all cells observed).')),
    Figure('acquisition', 'fig19', 'fig19-error-vs-n', 'Xu Fig. 19', rule='plot_acquisition_figures', draw='fig19_error_vs_n',
           caption=('Mean RMS error of point sampling vs the number of samples n: min E(S) vs the previous work '
                    '(red: min κ of the first n components, Nielsen 2015 as released) and min κ over all k (Xu eq. 6),'
                    ' with the deviation floor.')),
    Figure('acquisition', 'closedloop', 'closedloop-vs-table', 'Xu §7 (closed loop)', rule='plot_closedloop', draw='plot_closedloop',
           caption=('Closed loop: each held-out material photographed by the optimised set-ups (Mitsuba 3, the '
                    "``merl`` BSDF on a flat sample, a point light, the set-up's camera and resolution, a sensor with"
                    ' photon and read noise and HDR bracketing), its BRDF read off the pixels (fall-off and cosine '
                    'removed, low-signal pixels masked) and reconstructed; left: mean RMS log error of the table '
                    "lookup, of the noiseless render and of the sensor's photograph per direction set; right: per "
                    'material, closed-loop / table error against the share of disk pixels not used.')),
    Figure('acquisition', 'unseen', 'unseen-vs-heldout', 'Xu Figs. 5/6 (unseen materials)', rule='plot_unseen_errors', draw='plot_unseen',
           caption=('Materials never seen by any model of the run (config ``unseen``: e.g. the RGL and Nielsen '
                    'materials through their NBRDF fits), acquired with the model and direction sets trained on the '
                    "run's database, next to its held-out materials. Left: mean RMS log error of point sampling (min "
                    'E(S)) vs the number of samples, per unseen database (thin: each material; dotted: the floors '
                    'with every cell observed). Then per set size (1, 2 images): near-field error vs field of view by'
                    ' table lookup (solid) and by the closed loop from rendered photographs (dashed).')),
    Figure('manifold', 'fig05', 'manifold-fig05-likelihood', 'Soler Fig. 5', rule='plot_manifold_figures', draw='manifold_fig05_likelihood',
           caption=("GPLVM log-likelihood over the optimiser's steps (start, L-BFGS, Newton, Hooke–Jeeves), default "
                    'candidate, each latent dimension q.')),
    Figure('manifold', 'fig10_q2', 'manifold-fig10-latent-q2', 'Soler Fig. 10 (q = 2)', rule='plot_manifold_figures', draw='manifold_fig10_latent_q2',
           caption=('The 2-D latent space of the default candidate: every material at its latent point, coloured by '
                    'its albedo.')),
    Figure('manifold', 'fig10_q5', 'manifold-fig10-latent-q5', 'Soler Fig. 10 (q = 5 slices)', rule='plot_manifold_figures', draw='manifold_fig10_latent_q5', when=_has_q3,
           caption=('Slices of the 5-D latent space (pairs of dimensions) of the default candidate.')),
    Figure('manifold', 'fig07', 'manifold-fig07-albedo', 'Soler Fig. 7', rule='plot_manifold_figures', draw='manifold_fig07_albedo', when=_has_albedo_map,
           caption=('Albedo of the interpolated BRDF over a latent plane (q = 2 and a slice of q = 5) with iso-lines '
                    'and the training materials; values outside [0, 1] marked.')),
    Figure('manifold', 'fig09', 'manifold-fig09-paths', 'Soler Fig. 9', rule='plot_manifold_figures', draw='manifold_fig09_paths',
           caption=('Perceptual distance of the interpolated materials to A and to B along the latent paths, '
                    'normalised by d(A, B) and the latent distance; dashed: perceptually uniform.')),
    Figure('manifold', 'fig08', 'manifold-fig08-reproduction', 'Soler Fig. 8', rule='plot_manifold_figures', draw='manifold_fig08_reproduction',
           caption=('Relative reproduction error of every training material by PCA-k and by the GPLVM (each q).')),
    Figure('manifold', 'eq7', 'manifold-eq7-bound', 'Soler eq. 7', rule='plot_manifold_figures', draw='manifold_eq7_bound',
           caption=('Actual deviation ‖z* − z_j‖ of the interpolant from the nearest training material vs the eq. 7 '
                    'bound, along the latent paths.')),
    Figure('manifold', 'fig06', 'manifold-fig06-lengthscale', 'Soler Fig. 6', rule='plot_manifold_figures', draw='manifold_fig06_lengthscale', note=True,
           caption=('The eq. 7 bound on the behaviour of the interpolant as the length scale ℓ shrinks: the default '
                    "candidate's latent points kept, the kernel's ℓ scaled; along Soler Figs. 12/13's path (chrome → "
                    'silver-paint) or the first latent path, the deviation ‖z* − z_j‖ from the nearest training '
                    'material and its eq. 7 bound, and the distance ‖z* − z̄‖ from the mean of the materials, '
                    'which the interpolant approaches away from the materials as ℓ → 0.')),
    Figure('manifold', 'spaces', 'manifold-spaces', 'Soler §4.1-4.3 (data spaces)', rule='plot_manifold_figures', draw='manifold_spaces',
           caption=('Every GPLVM candidate (data space, μ) measured the same way: κ(K), albedo outside [0, 1], Σ|w|, '
                    'stability near the training points, perceptual uniformity.')),
    Figure('manifold', 'unseen', 'manifold-unseen', 'Soler Figs. 10, 8 (unseen materials)', rule='plot_unseen_latent', draw='manifold_unseen',
           caption=("Materials outside the training set on the default candidate's manifold: left, their latent "
                    'position x* (filled: maximising the GP likelihood of the material given the fitted model; open: '
                    'least squares of Σ bᵢ(x) zᵢ against it) among the training materials; right, the relative error '
                    "of b(x*)'s reproduction of each, next to the projection on k principal components of the same "
                    'training materials (k = each q and the configured PCA sizes).')),
    Figure('rendering', 'fig01', 'render-fig01-latent-samples', 'Soler Fig. 1', rule='plot_render_figures', draw='render_fig01_latent_samples', note=True, when=_has_samples,
           caption=('Materials at random latent points of the manifold (default GPLVM candidate, the rendering '
                    "track's q), drawn as ``brdfpipe sample`` draws them (uniform in the convex hull of the "
                    "materials' latent points, albedo in [0, 1]; seed ``render.latent_samples.seed``), written as "
                    'MERL tables with a ``derived`` provenance mark and rendered in the pre-renders\' scene and '
                    "settings, among measured materials' pre-renders (Soler's four where the database has them) at "
                    "the paper's places.")),
    Figure('rendering', 'prerenders', 'render-prerenders', 'Soler §5.2 (pre-renders)', rule='plot_render_figures', draw='render_prerenders',
           caption=('Global-illumination pre-renders of every material (Mitsuba 3, the ``merl`` BSDF), the images the'
                    ' blends are made of.')),
    Figure('rendering', 'fig12', 'render-fig12-interpolation', 'Soler Fig. 12', rule='plot_render_figures', draw='render_fig12_interpolation', note=True, when=_has_path_points,
           caption=("Soler Fig. 12's path, chrome → silver-paint, in the rendering track's latent space (or, on a "
                    'database without both, the first rendered path): top, the two pre-rendered ends and between '
                    'them the blends Σ wᵢ Iᵢ of the pre-renders with the weights b(x*) = K⁻¹k(x*) of each rendered '
                    'point; bottom, the interpolated materials rendered (the reference). Then every other rendered '
                    'path the same way.')),
    Figure('rendering', 'fig13', 'render-fig13-errors', 'Soler Fig. 13', rule='plot_render_figures', draw='render_fig13_errors', note=True, when=_has_path_points,
           caption=("Soler Fig. 13's check at the midpoint of Fig. 12's path (the rendered point nearest t = 0.5): "
                    'the blend of pre-renders, the reference render of the interpolated material, |blend − '
                    "reference| against the reference's second seed, and the noise floor |reference − second seed|, "
                    'on one colour scale.')),
    Figure('rendering', 'floor-check', 'render-floor-check', 'Soler Fig. 13 (noise-floor check)', rule='plot_floor_check', draw='plot_floor_check',
           caption=("The noise-floor check: blends vs the noise floor of every checked candidate's path points, "
                    'rendered small with many samples (render.floor_check).')),
)

#: The report's other entries (tables, error maps, the claims).
REPORT_ENTRIES: tuple[ReportEntry, ...] = (
    ReportEntry('xu-fig08-table', 'Xu Fig. 8 (table)',
                caption=("Xu Fig. 8's table: per FOV and set size, each image's (θh, θd, φd), light and camera directions "
                         'and the predicted E(S).')),
    ReportEntry('xu-closedloop-table', 'Xu §7 (closed loop, table)',
                caption=('``closedloop.csv``: per held-out material, channel and captured direction set the table-lookup '
                         'errors (kinds ``rms_log``, ``relrms_linear``), the closed-loop errors from the noiseless render '
                         '(``closedloop_noiseless_*``) and from the sensor (``closedloop_*``), the observations used and '
                         'the share of pixels masked.')),
    ReportEntry('xu-unseen-table', 'Xu §7 (unseen materials, table)',
                caption=('``unseen.csv``: the columns of ``errors.csv`` plus ``model_database``: per unseen material '
                         '(``database`` its own), channel and direction set the table-lookup error (``rms_log``), the '
                         "closed loop's (``closedloop_noiseless_rms_log``, ``closedloop_rms_log``), the deviation floor "
                         'and the observations used; means per database as material ``mean``.')),
    ReportEntry('unseen-albedo', 'radiometric check (unseen materials)',
                caption=("Directional albedo at normal incidence of each unseen material's fit-made table "
                         "(``merl.directional_albedo``), a radiometric check of the tables: RGL's spectralon should "
                         'reflect about 96 %.')),
    ReportEntry('soler-unseen-table', 'Soler Figs. 10, 8 (unseen materials, table)',
                caption=('``manifold/unseen.csv``: per unseen material and method (``gplvm-likelihood``, '
                         '``gplvm-least-squares`` with k = q, ``pca`` with k) the relative reproduction error, the GP '
                         'log-likelihood at x*, the nearest training material and x*.')),
    ReportEntry('soler-spaces-table', 'Soler §4.1-4.3 (table)',
                caption=("``spaces.csv``: every candidate's measures (one row per candidate and q).")),
    ReportEntry('render-errormap', 'Soler Fig. 13 (error map)',
                caption=('False-colour map of |blend − reference| at one rendered path point (labels: path, t), with a '
                         'colour bar.')),
    ReportEntry('render-summary', 'Soler Fig. 13 (table)',
                caption=('``summary.csv``: per path point the relative RMSE of the blend vs the reference (same and second'
                         ' seed), the two-seed noise floor and their ratios, for the whole image and its I¹⁻ part; Σ|w|, '
                         'the share of the table the reference clamps, and the ratio against a reference that differs '
                         'from the blend only by the L²⁺ paths (Σ wᵢ I¹⁻ᵢ plus the reference\'s I²⁺).')),
    ReportEntry('render-floor-check-table', 'Soler Fig. 13 (noise-floor check, table)',
                caption=('``floor-check.csv``: per candidate and path point Σ|w|, ‖w‖₂, the clamped share, the two-seed '
                         'noise floor and the blend / floor ratios (whole image, I¹⁻, and against the reference that '
                         'differs only by the L²⁺ paths).')),
    ReportEntry('claims', 'all claims',
                caption=("Every quantitative claim of both papers: the paper's value, this run's value computed from its "
                         'CSVs, and whether it holds (also on the front page).')),
)


def track_figures(track: str, rule: str | None = None) -> tuple[Figure, ...]:
    """The figures of ``track`` (drawn by ``rule`` when given), in registry order."""
    if track not in TRACK_PREFIX:
        raise ValueError(f"unknown track {track!r}; expected one of {', '.join(TRACK_PREFIX)}")
    return tuple(f for f in FIGURES if f.track == track and (rule is None or f.rule == rule))


def figure(report_key: str) -> Figure:
    """The figure of a report key (``xu-closedloop``); KeyError naming it otherwise."""
    for f in FIGURES:
        if f.report_key == report_key:
            return f
    raise KeyError(f"no figure {report_key!r}")


def paper_figures() -> dict[str, str]:
    """Report key → the paper figure (or equation) each entry is an analogue of."""
    return {**{f.report_key: f.paper for f in FIGURES}, **{e.key: e.paper for e in REPORT_ENTRIES}}


def captions() -> dict[str, str]:
    """Report key → what the entry shows (its caption's description)."""
    return {**{f.report_key: f.caption for f in FIGURES}, **{e.key: e.caption for e in REPORT_ENTRIES}}
