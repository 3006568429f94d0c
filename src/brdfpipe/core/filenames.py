"""Every file name of the workflow's DAG, in one small dependency-free module.

The Snakemake rules build their ``input:`` and ``output:`` paths from these
functions and hand the paths to the library explicitly; the library never
derives an output name on its own.  Standard library only, so parsing the
workflow does not import NumPy, SciPy, Zarr or matplotlib.

Arguments may be Snakemake wildcard patterns (``"{material}"``): every
function only formats strings.
"""

from __future__ import annotations

import math
import re

from brdfpipe.registry import figures as figure_specs
from brdfpipe.registry import layouts
from brdfpipe.registry.manifold import path_name  # the paths' names are Soler's paths' spec

__all__ = [
    "RESULTS",
    "FIGURES",
    "SYNTHETIC",
    "FIGURE_STEMS",
    "MANIFOLD_FIGURE_STEMS",
    "FLOOR_CHECK_STEM",
    "fov_tag",
    "BATCH_RULE_FAMILIES",
    "batch_rule",
    "rule_family",
    "split_batches",
    "format_t",
    "path_name",
    "synthetic_binary",
    "synthetic_record",
    "manifest",
    "ingest_row",
    "store",
    "splits",
    "logmap",
    "svd_model",
    "gram_partial",
    "directions",
    "errors",
    "consistency",
    "training_size",
    "paper_directions",
    "CLOSEDLOOP_STEM",
    "closedloop_image",
    "closedloop_observations",
    "closedloop_errors",
    "reconstruction",
    "reconstruction_input",
    "reconstruction_render",
    "UNSEEN_STEM",
    "MANIFOLD_UNSEEN_STEM",
    "unseen_tables",
    "unseen_binary",
    "unseen_store",
    "unseen_albedo",
    "unseen_observations",
    "unseen_errors",
    "unseen_manifold",
    "gram",
    "gplvm_model",
    "gplvm_trace",
    "spaces_csv",
    "spaces_stability_csv",
    "candidate_spaces_csv",
    "candidate_stability_csv",
    "albedo",
    "material_albedos",
    "albedo_map",
    "paths_csv",
    "lengthscales_csv",
    "reproduction",
    "figure_files",
    "envmap",
    "prerender",
    "prerender_one",
    "object_mask",
    "bounce_shares",
    "path_point",
    "latent_sample",
    "latent_samples_json",
    "errormap_summary",
    "errormap",
    "floor_scene",
    "candidate_path_point",
    "candidate_errormap_summary",
    "candidate_errormap",
    "floor_check_csv",
    "REPORT",
    "claims_csv",
    "claims_json",
    "claims_rst",
    "fidelity_md",
    "front_rst",
    "stage_times_csv",
    "stage_times_rst",
    "caption",
    "explorer_dir",
    "STAMPS",
    "stamp",
    "rule_of",
]

#: Root folder of every output.
RESULTS = "results"
#: Folder of the job stamps (:mod:`brdfpipe.core.stamps`): one subfolder per rule.
STAMPS = f"{RESULTS}/.stamps"
#: Folder of the figures (PNG + PDF, and Fig. 8's table).
FIGURES = f"{RESULTS}/figures"

#: Xu 2016 figure analogues drawn by rule plot_acquisition_figures: key → file stem (:mod:`brdfpipe.registry.figures`).
FIGURE_STEMS: dict[str, str] = {f.key: f.stem for f in figure_specs.track_figures("acquisition", "plot_acquisition_figures")}
#: Soler 2018 figure analogues of the manifold track: key → file stem.
MANIFOLD_FIGURE_STEMS: dict[str, str] = {
    f.key: f.stem for f in figure_specs.track_figures("manifold", "plot_manifold_figures")
}
#: The blends-vs-noise-floor figure of every GPLVM candidate (render.floor_check).
FLOOR_CHECK_STEM = figure_specs.figure("render-floor-check").stem


def fov_tag(fov: float | str) -> str:
    """File-name form of a field of view in degrees: ``25`` → ``"25"``, ``22.5`` → ``"22.5"``."""
    if isinstance(fov, str) and fov.startswith("{"):
        return fov
    return f"{float(fov):g}"


def format_t(t: float | str) -> str:
    """The text of a path parameter ``t`` in file names and ``summary.csv``: ``f"{t:g}"``.

    E.g. ``0.25 → "0.25"``, ``1.0 → "1"``; ``-0.0`` is written ``"0"``.
    ValueError for a non-finite ``t``.
    """
    if isinstance(t, str) and t.startswith("{"):
        return t
    t = float(t)
    if not math.isfinite(t):
        raise ValueError(f"t must be finite, got {t}")
    return f"{t + 0.0:g}"  # + 0.0 turns -0.0 into 0.0


# -- data stage -------------------------------------------------------------

#: Folder of the generated synthetic database (its layout: :mod:`brdfpipe.registry.layouts`).
SYNTHETIC = f"{RESULTS}/synthetic"


def synthetic_binary(material: str) -> str:
    return f"{SYNTHETIC}/{layouts.merl_file(material)}"


def synthetic_record(material: str) -> str:
    return f"{SYNTHETIC}/{layouts.record_file(material)}"


def manifest() -> str:
    return f"{SYNTHETIC}/{layouts.SYNTHETIC_MANIFEST}"


def ingest_row(material: str) -> str:
    return f"{RESULTS}/ingest/{material}.zarr"


def store() -> str:
    return f"{RESULTS}/merl.zarr"


def splits() -> str:
    return f"{RESULTS}/splits.json"


# -- acquisition track ------------------------------------------------------


def logmap(split: str) -> str:
    return f"{RESULTS}/logmap/{split}.zarr"


def svd_model(split: str) -> str:
    return f"{RESULTS}/svd/{split}.zarr"


def gram_partial(split: str, scatteritem: str) -> str:
    return f"{RESULTS}/svd/{split}/gram-{scatteritem}.npz"


def directions(split: str, setup: str, fov: float | str, metric: str) -> str:
    """Direction sets of one setup (fov 0 for point samples)."""
    return f"{RESULTS}/directions/{split}/{setup}-fov{fov_tag(fov)}-{metric}.json"


def errors() -> str:
    return f"{RESULTS}/evaluation/errors.csv"


def consistency(split: str) -> str:
    return f"{RESULTS}/evaluation/consistency-{split}.csv"


def training_size() -> str:
    return f"{RESULTS}/evaluation/training_size.csv"


def paper_directions() -> str:
    """E(S) of the near-field directions Xu §6 states in words (:mod:`brdfpipe.acquisition.paper_directions`)."""
    return f"{RESULTS}/evaluation/paper-directions.csv"


# -- closed-loop acquisition ------------------------------------------------

#: The closed loop's figure (table-lookup vs closed-loop error per FOV and n).
CLOSEDLOOP_STEM = figure_specs.figure("xu-closedloop").stem


def closedloop_image(material: str, setup: str, fov: float | str, metric: str, n: int | str, j: int | str,
                     kind: str) -> str:
    """EXR of image ``j`` of the n-image set of a directions file: kind ``render`` (noiseless) or ``sensor``."""
    if kind not in ("render", "sensor"):
        raise ValueError(f"closed-loop image kind must be render or sensor, got {kind!r}")
    return f"{RESULTS}/closedloop/{material}/{setup}-fov{fov_tag(fov)}-{metric}-n{n}-{j}-{kind}.exr"


def closedloop_observations(material: str, setup: str, fov: float | str, metric: str, n: int | str,
                            source: str) -> str:
    """Observation table (NPZ) read off the n-image set's images: source ``noiseless`` or ``sensor``."""
    if source not in ("noiseless", "sensor"):
        raise ValueError(f"closed-loop observation source must be noiseless or sensor, got {source!r}")
    return f"{RESULTS}/closedloop/{material}/{setup}-fov{fov_tag(fov)}-{metric}-n{n}-{source}.npz"


def closedloop_errors() -> str:
    """Table-lookup and closed-loop errors of the held-out materials (the columns of errors.csv)."""
    return f"{RESULTS}/evaluation/closedloop.csv"


# -- held-out materials reconstructed from direction sets (Xu Figs. 2, 15) ----


def _set_tag(setup: str, fov: float | str, metric: str, n: int | str) -> str:
    return f"{setup}-fov{fov_tag(fov)}-{metric}-n{n}"


def reconstruction(material: str, setup: str, fov: float | str, metric: str, n: int | str) -> str:
    """A held-out material's table reconstructed from the n-set of a directions file (MERL file, derived mark)."""
    return f"{RESULTS}/reconstructions/{material}/{_set_tag(setup, fov, metric, n)}.binary"


def reconstruction_input(material: str, setup: str, fov: float | str, metric: str, n: int | str,
                         j: int | str) -> str:
    """EXR of image ``j`` (1-based) of that set: the observed pixels it was reconstructed from."""
    return f"{RESULTS}/reconstructions/{material}/{_set_tag(setup, fov, metric, n)}-{j}-input.exr"


def reconstruction_render(scene: str, material: str, setup: str, fov: float | str, metric: str,
                          n: int | str) -> str:
    """The render of a reconstructed table in a scene folder (the pre-renders' settings)."""
    return f"{RESULTS}/renders/{scene}/reconstructions/{material}/{_set_tag(setup, fov, metric, n)}.exr"


# -- materials outside the training database (config unseen) ----------------

#: The unseen materials' acquisition errors next to the held-out ones (Xu Figs. 5/6 layout).
UNSEEN_STEM = figure_specs.figure("xu-unseen").stem
#: The unseen materials on the q = 2 latent map and their reproduction by the GPLVM and PCA.
MANIFOLD_UNSEEN_STEM = figure_specs.figure("soler-unseen").stem


def unseen_tables(database: str) -> str:
    """Folder of an unseen database's fit-made MERL files (``<material>.binary``; rule evaluate_unseen_fits)."""
    return f"{RESULTS}/unseen/{database}"


def unseen_binary(database: str, material: str) -> str:
    """One fit-made MERL file of an unseen database (inside :func:`unseen_tables`)."""
    return f"{unseen_tables(database)}/{layouts.merl_file(material)}"


def unseen_store(database: str) -> str:
    """The store of an unseen database's materials (one store per database: a store has one label)."""
    return f"{RESULTS}/unseen/{database}.zarr"


def unseen_albedo(database: str) -> str:
    """Directional albedo at normal incidence of every material of an unseen database (the radiometric check)."""
    return f"{RESULTS}/unseen/{database}-albedo.csv"


def unseen_observations(database: str) -> str:
    """Every closed-loop observation table of an unseen database's materials (one NPZ per database)."""
    return f"{RESULTS}/unseen/closedloop/{database}.npz"


def unseen_errors() -> str:
    """Acquisition errors of the unseen materials (the columns of errors.csv plus ``model_database``)."""
    return f"{RESULTS}/evaluation/unseen.csv"


def unseen_manifold() -> str:
    """Latent positions of the unseen materials and their reproduction by the GPLVM and by PCA."""
    return f"{RESULTS}/manifold/unseen.csv"


# -- manifold track ---------------------------------------------------------


def gram(space: str) -> str:
    return f"{RESULTS}/gplvm/gram-{space}.npz"


def gplvm_model(candidate: str, q: int | str) -> str:
    """A GPLVM fit of one candidate (``<space>-mu<μ>``, :func:`brdfpipe.registry.manifold.candidate_label`)."""
    return f"{RESULTS}/gplvm/{candidate}/q{q}.npz"


def gplvm_trace(candidate: str, q: int | str) -> str:
    return f"{RESULTS}/gplvm/{candidate}/q{q}-trace.csv"


def spaces_csv() -> str:
    """Every fidelity measure of every candidate data space (:mod:`brdfpipe.manifold.fidelity`)."""
    return f"{RESULTS}/manifold/spaces.csv"


def spaces_stability_csv() -> str:
    return f"{RESULTS}/manifold/spaces-stability.csv"


def candidate_spaces_csv(candidate: str) -> str:
    """One candidate's rows of :func:`spaces_csv`."""
    return f"{RESULTS}/manifold/spaces/{candidate}.csv"


def candidate_stability_csv(candidate: str) -> str:
    return f"{RESULTS}/manifold/spaces/{candidate}-stability.csv"


def albedo() -> str:
    return f"{RESULTS}/manifold/albedo.csv"


def material_albedos() -> str:
    """Every material's albedo, computed once from the store (``measure_material_albedos``)."""
    return f"{RESULTS}/manifold/material-albedo.npz"


def albedo_map(q: int | str) -> str:
    return f"{RESULTS}/manifold/albedo-map-q{q}.npz"


def paths_csv() -> str:
    return f"{RESULTS}/manifold/paths.csv"


def lengthscales_csv() -> str:
    """The interpolant and the eq. 7 bound along a latent path as the length scale shrinks (Soler Fig. 6)."""
    return f"{RESULTS}/manifold/lengthscales.csv"


def reproduction() -> str:
    return f"{RESULTS}/manifold/reproduction.csv"


def figure_files(stem: str, *, table: bool = False, note: bool = False) -> list[str]:
    """The files of one figure: PNG and PDF (plus CSV and Markdown for a table figure, and its note, ``.json``).

    A figure's note is one paragraph of this run's numbers that its report
    caption quotes (:mod:`brdfpipe.report.captions`), in a JSON file with its digest.
    """
    exts = ("png", "pdf", "csv", "md") if table else ("png", "pdf")
    return [f"{FIGURES}/{stem}.{ext}" for ext in exts + (("json",) if note else ())]


# -- rendering track --------------------------------------------------------


def envmap(scene: str) -> str:
    return f"{RESULTS}/renders/{scene}/envmap.exr"


def prerender(scene: str, material: str) -> str:
    return f"{RESULTS}/renders/{scene}/materials/{material}.exr"


def prerender_one(scene: str, material: str) -> str:
    """The I¹⁻ part of a pre-render (light paths with at most one scattering on the material)."""
    return f"{RESULTS}/renders/{scene}/materials-one/{material}.exr"


def object_mask(scene: str) -> str:
    return f"{RESULTS}/renders/{scene}/object-mask.exr"


def bounce_shares(scene: str) -> str:
    """Per-material share of I²⁺ (≥ 2 scatterings on the material) in the pre-renders."""
    return f"{RESULTS}/renders/{scene}/bounce-shares.csv"


def path_point(scene: str, path: str, t: float | str, kind: str) -> str:
    """A latent-path point's file: kind ``binary`` (material), ``image``, ``noise`` (second seed),
    ``one``, ``one_noise`` (their I¹⁻ parts) or ``weights``."""
    base = f"{RESULTS}/renders/{scene}/paths/{path}-t{format_t(t)}"
    suffix = {"binary": ".binary", "image": ".exr", "noise": "-noise.exr", "one": "-one.exr",
              "one_noise": "-one-noise.exr", "weights": "-weights.json"}
    if kind not in suffix:
        raise ValueError(f"kind must be one of {sorted(suffix)}, got {kind!r}")
    return base + suffix[kind]


def latent_sample(scene: str, index: int | str, kind: str) -> str:
    """A material at a random latent point (Soler Fig. 1): kind ``binary`` (its table) or ``image`` (its render)."""
    suffix = {"binary": ".binary", "image": ".exr"}
    if kind not in suffix:
        raise ValueError(f"kind must be one of {sorted(suffix)}, got {kind!r}")
    name = index if isinstance(index, str) else f"{int(index):03d}"
    return f"{RESULTS}/renders/{scene}/samples/sample-{name}{suffix[kind]}"


def latent_samples_json(scene: str) -> str:
    """What the latent samples of Soler Fig. 1 are: their points, weights and albedos."""
    return f"{RESULTS}/renders/{scene}/samples/samples.json"


def errormap_summary(scene: str) -> str:
    return f"{RESULTS}/errormaps/{scene}/summary.csv"


def errormap(scene: str, path: str, t: float | str, kind: str) -> str:
    """An error-map file of a path point: kind ``blended.exr``, ``error.exr`` or ``error.png``."""
    if kind not in ("blended.exr", "error.exr", "error.png"):
        raise ValueError(f"kind must be blended.exr, error.exr or error.png, got {kind!r}")
    return f"{RESULTS}/errormaps/{scene}/{path}-t{format_t(t)}-{kind}"


# -- the noise-floor check (render.floor_check): every candidate's path points
# rendered at an spp where the Monte Carlo floor is small --------------------


#: Rules written once per batch of materials (``<family>_bNN``): each job serves several
#: materials in one process.
BATCH_RULE_FAMILIES: tuple[str, ...] = ("prerender_materials",)
_BATCH_RULE_RE = re.compile(r"^(?P<family>[a-z_]+)_b\d{2,}$")


def batch_rule(family: str, index: int) -> str:
    """Name of batch ``index`` of a batch-rule family (``prerender_materials_b03``)."""
    if family not in BATCH_RULE_FAMILIES:
        raise ValueError(f"{family!r} is not a batch-rule family ({', '.join(BATCH_RULE_FAMILIES)})")
    return f"{family}_b{int(index):02d}"


def rule_family(name: str) -> str:
    """The family of a batch rule's name (``prerender_materials_b03`` → ``prerender_materials``); other names unchanged."""
    m = _BATCH_RULE_RE.match(name)
    if m is not None and m.group("family") in BATCH_RULE_FAMILIES:
        return m.group("family")
    return name


def split_batches(items: list[str] | tuple[str, ...], per_job: int) -> list[list[str]]:
    """``items`` in order, cut into ⌈n / per_job⌉ consecutive batches whose sizes differ by at most one."""
    if per_job < 1:
        raise ValueError(f"per_job must be >= 1, got {per_job}")
    n = len(items)
    count = -(-n // per_job)
    if count == 0:
        return []
    base, extra = divmod(n, count)
    out, start = [], 0
    for k in range(count):
        size = base + (1 if k < extra else 0)
        out.append(list(items[start:start + size]))
        start += size
    return out


def floor_scene(scene: str, resolution: tuple[int, int] | list[int], spp: int) -> str:
    """Folder name of the floor check's renders: the scene, its resolution and spp (``preview-48x36-4096spp``)."""
    w, h = resolution
    return f"{scene}-{int(w)}x{int(h)}-{int(spp)}spp"


def candidate_path_point(scene: str, candidate: str, path: str, t: float | str, kind: str) -> str:
    """:func:`path_point` of one GPLVM candidate's latent path (``renders/{scene}/paths/{candidate}/``)."""
    return path_point(scene, f"{candidate}/{path}", t, kind)


def candidate_errormap_summary(scene: str, candidate: str) -> str:
    return f"{RESULTS}/errormaps/{scene}/{candidate}/summary.csv"


def candidate_errormap(scene: str, candidate: str, path: str, t: float | str, kind: str) -> str:
    """:func:`errormap` of one GPLVM candidate's path point."""
    return errormap(scene, f"{candidate}/{path}", t, kind)


def floor_check_csv(scene: str) -> str:
    """Every candidate's blends against the noise floor, one row per path point."""
    return f"{RESULTS}/errormaps/{scene}/floor-check.csv"


# -- the report (snakemake --report): claims, captions and the front page ------

#: Folder of the report's generated files (read by ``snakemake --report``).
REPORT = f"{RESULTS}/report"


def claims_csv() -> str:
    """Every quantitative claim of both papers: paper value, this run's value, holds or not."""
    return f"{REPORT}/claims.csv"


def claims_json() -> str:
    return f"{REPORT}/claims.json"


def claims_rst() -> str:
    """The claims table as reStructuredText (included in the report's front page)."""
    return f"{REPORT}/claims.rst"


def fidelity_md() -> str:
    """The fidelity page: this run's verdict and cause per claim beside the recorded runs of other databases."""
    return f"{REPORT}/fidelity.md"


def front_rst() -> str:
    """The front page's body: what ran, database, the claims table, versions, configuration."""
    return f"{REPORT}/front.rst"


def stage_times_csv() -> str:
    """Wall time per stage (rule) from the jobs' benchmark files; differs from run to run."""
    return f"{REPORT}/stage-times.csv"


def stage_times_rst() -> str:
    return f"{REPORT}/stage-times.rst"


def caption(name: str) -> str:
    """A generated report caption (reStructuredText) for one figure, table or set of error maps."""
    return f"{REPORT}/captions/{name}.rst"
# -- the explorer (a static page over the manifold and the pre-renders) -----


def explorer_dir() -> str:
    """Folder of the in-browser material explorer (:mod:`brdfpipe.explorer`): open its ``index.html``."""
    return f"{RESULTS}/explorer"


def explorer_page() -> str:
    """The explorer's page: open it in a browser (from ``file://``, no server needed)."""
    return f"{explorer_dir()}/index.html"


def report_zip() -> str:
    """The Snakemake report of a finished run (``snakemake --report``, ``make report``): not a job's output."""
    return f"{RESULTS}/report.zip"


# -- job stamps (brdfpipe.core.stamps) -------------------------------------


def stamp(rule: str, job: str) -> str:
    """The stamp of the job ``job`` (:func:`brdfpipe.core.stamps.job_key` of its wildcards) of ``rule``."""
    return f"{STAMPS}/{rule}/{job}"


# -- which rule writes a file (the integrity messages' "what to rerun") -------


def _producers() -> list[tuple[str, str]]:
    """``(path pattern, rule)`` for every file a consumer reads, most specific first (wildcards ``{w}``)."""
    w = "{w}"
    floor_point = candidate_path_point(w, w, w, w, "image")
    return [
        (ingest_row(w), "ingest_material"),
        (store(), "assemble_store"),
        (splits(), "write_splits"),
        (synthetic_binary(w), "synthesize_material"),
        (logmap(w), "map_logrelative"),
        (gram_partial(w, w), "accumulate_gram"),
        (svd_model(w), "decompose_svd"),
        (directions(w, w, w, w), "optimize_directions"),
        (errors(), "evaluate_directions"),
        (consistency(w), "check_directions"),
        (training_size(), "evaluate_training_size"),
        (paper_directions(), "evaluate_paper_directions"),
        (closedloop_errors(), "evaluate_closedloop"),
        (unseen_observations(w), "capture_unseen_closedloop"),
        (unseen_errors(), "evaluate_unseen"),
        (unseen_manifold(), "locate_unseen"),
        (unseen_albedo(w), "evaluate_unseen_fits"),
        (unseen_store(w), "evaluate_unseen_fits"),
        (unseen_tables(w), "evaluate_unseen_fits"),
        (f"{RESULTS}/closedloop/{w}/{w}", "capture_closedloop"),
        (f"{RESULTS}/reconstructions/{w}/{w}", "reconstruct_figure_material"),
        (f"{RESULTS}/renders/{w}/reconstructions/{w}/{w}", "render_reconstructions"),
        (gram(w), "compute_gram"),
        (gplvm_model(w, w), "fit_gplvm"),
        (gplvm_trace(w, w), "fit_gplvm"),
        (candidate_spaces_csv(w), "measure_gplvm_candidate"),
        (candidate_stability_csv(w), "measure_gplvm_candidate"),
        (spaces_csv(), "compare_spaces"),
        (spaces_stability_csv(), "compare_spaces"),
        (material_albedos(), "measure_material_albedos"),
        (albedo(), "analyze_manifold"),
        (albedo_map(w), "analyze_manifold"),
        (paths_csv(), "analyze_manifold"),
        (reproduction(), "analyze_manifold"),
        (lengthscales_csv(), "measure_lengthscales"),
        # the figure files read back: the notes (by write_claims) and fig08's table
        (f"{FIGURES}/manifold-{w}.json", "plot_manifold_figures"),
        (f"{FIGURES}/render-{w}.json", "plot_render_figures"),
        (f"{FIGURES}/{w}", "plot_acquisition_figures"),
        (envmap(w), "make_envmap"),
        (prerender(w, w), "prerender_materials"),
        (prerender_one(w, w), "prerender_materials"),
        (object_mask(w), "render_object_mask"),
        (bounce_shares(w), "bounce_shares"),
        (floor_point.rsplit("/", 1)[0] + f"/{w}-t{w}.binary", "interpolate_candidate_path_points"),
        (floor_point.rsplit("/", 1)[0] + f"/{w}-t{w}-weights.json", "interpolate_candidate_path_points"),
        (floor_point.rsplit("/", 1)[0] + f"/{w}.exr", "render_candidate_path_points"),
        (latent_samples_json(w), "sample_latent_materials"),
        (latent_sample(w, w, "binary"), "sample_latent_materials"),
        (latent_sample(w, w, "image"), "render_latent_samples"),
        (path_point(w, w, w, "binary"), "interpolate_path_points"),
        (path_point(w, w, w, "weights"), "interpolate_path_points"),
        (f"{RESULTS}/renders/{w}/paths/{w}.exr", "render_path_points"),
        (floor_check_csv(w), "summarize_floor_check"),
        (candidate_errormap_summary(w, w), "measure_candidate_blends"),
        (f"{RESULTS}/errormaps/{w}/{w}/{w}", "measure_candidate_blends"),
        (errormap_summary(w), "error_maps"),
        (f"{RESULTS}/errormaps/{w}/{w}", "error_maps"),
        (explorer_dir(), "write_explorer"),
        (f"{REPORT}/{w}", "write_claims"),
    ]


_PRODUCER_RES: list[tuple["re.Pattern[str]", str]] | None = None


def rule_of(path: object) -> str | None:
    """The workflow rule that writes ``path`` (a ``results/…`` file or folder, or a file inside one), or None.

    Matched on the path's tail from its ``results`` folder on, so absolute
    paths and paths inside a Zarr group (``results/svd/train.zarr/Q/c/0/0``)
    work too.  Used by :mod:`brdfpipe.core.integrity` to say what to rerun.
    """
    global _PRODUCER_RES
    if _PRODUCER_RES is None:
        _PRODUCER_RES = [
            (re.compile("(?:^|/)" + "[^/]+".join(re.escape(p) for p in pattern.split("{w}")) + "(?:/.*)?$"), rule)
            for pattern, rule in _producers()
        ]
    text = str(path).replace("\\", "/")
    for rx, rule in _PRODUCER_RES:
        if rx.search(text):
            return rule
    return None
