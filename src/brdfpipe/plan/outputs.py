"""Which outputs a configuration produces: direction sets, figures, the unseen materials' files.

Read by the Snakefile while it builds the DAG (``workflow/rules/*.smk``) and
by the tests: the direction sets each split optimises, the sets the closed
loop captures and the unseen materials are looked up with, the figures of
each track (from :data:`brdfpipe.registry.figures.FIGURES`), the GPLVM
candidates the floor check renders; and where a finished run's results are
(the console's last lines).  Standard library only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from brdfpipe.core import filenames
from brdfpipe.registry import figures as figure_specs
from brdfpipe.registry.figures import ReconSet
from brdfpipe.registry.acquisition import PAPER_DIRECTIONS, setup_fovs, setup_metrics

__all__ = [
    "direction_files",
    "closedloop_directions",
    "unseen_directions",
    "unseen_figures",
    "unseen_map_q",
    "curve_fov",
    "curve_directions",
    "paper_directions",
    "albedo_map_dims",
    "acquisition_figures",
    "figure_materials",
    "reconstruction_columns",
    "reconstruction_sets",
    "reconstruction_figures",
    "manifold_figures",
    "render_figures",
    "floor_check_candidates",
    "where_results_are",
]


def direction_files(acquisition: Mapping[str, Any], split: str) -> list[str]:
    """Direction sets optimised on a split.

    ``train``: every setup × FOV × metric that applies to the setup (they are
    evaluated; :func:`brdfpipe.registry.acquisition.setup_metrics`); ``all``: only
    the near-field sets of the error metric (the paper's table of optimal
    configurations, Xu Fig. 8).
    """
    files = []
    for setup in acquisition["setups"]:
        if split == "all" and setup != "nearfield":
            continue
        fovs = setup_fovs(setup, acquisition["fovs"], acquisition["fixed_fov"])
        metrics = setup_metrics(setup, acquisition["metrics"]) if split == "train" else ["error"]
        files += [filenames.directions(split, setup, fov, metric) for fov in fovs for metric in metrics]
    return files


def closedloop_directions(config: Mapping[str, Any]) -> list[tuple[str, float, str]]:
    """(setup, fov, metric) of every training-split direction set the closed loop captures ([] when disabled).

    ``closed_loop.setups`` × their FOVs (``closed_loop.fovs``, null = the
    acquisition's: ``acquisition.fovs`` for nearfield, ``acquisition.fixed_fov``
    for fixed_*) with ``closed_loop.metric``.
    """
    cl = config["closed_loop"]
    if not cl["enabled"]:
        return []
    acq = config["acquisition"]
    out = []
    for setup in cl["setups"]:
        fovs = setup_fovs(setup, acq["fovs"] if cl["fovs"] is None else cl["fovs"], acq["fixed_fov"])
        out += [(setup, float(f), cl["metric"]) for f in fovs]
    return out


def unseen_directions(acquisition: Mapping[str, Any]) -> list[str]:
    """Direction sets the unseen materials are looked up with: the training split's point and near-field sets of the error metric.

    ``[]`` when the config optimises neither (or not with the error metric).
    """
    if "error" not in acquisition["metrics"]:
        return []
    files = []
    if "point" in acquisition["setups"]:
        files.append(filenames.directions("train", "point", 0, "error"))
    if "nearfield" in acquisition["setups"]:
        files += [filenames.directions("train", "nearfield", fov, "error") for fov in acquisition["fovs"]]
    return files


def unseen_figures(*, unseen: bool, evaluated: bool) -> dict[str, list[str]]:
    """The unseen materials' figures: ``acquisition`` (next to the held-out errors) when they are evaluated, ``manifold`` (latent map) when there are any."""
    out: dict[str, list[str]] = {}
    if unseen and evaluated:
        out["acquisition"] = filenames.figure_files(filenames.UNSEEN_STEM)
    if unseen:
        out["manifold"] = filenames.figure_files(filenames.MANIFOLD_UNSEEN_STEM)
    return out


def unseen_map_q(manifold: Mapping[str, Any]) -> int:
    """The latent dimension of the map the unseen materials are drawn on: 2 when fitted, else the smallest."""
    dims = [int(q) for q in manifold["latent_dims"]]
    return 2 if 2 in dims else min(dims)


def curve_fov(acquisition: Mapping[str, Any]) -> float:
    """FOV of the error-vs-training-size curve (Xu Fig. 7): 25° when configured, else the first."""
    fovs = [float(f) for f in acquisition["fovs"]]
    return 25.0 if 25.0 in fovs else fovs[0]


def curve_directions(acquisition: Mapping[str, Any]) -> str | None:
    """The direction set of the training-size curve, or None when the config has none (no curve)."""
    if figure_specs.figure("xu-fig07").produced(acquisition):  # the curve is drawn exactly when it is computed
        return filenames.directions("train", "nearfield", curve_fov(acquisition), "error")
    return None


def paper_directions(acquisition: Mapping[str, Any]) -> list[str]:
    """Keys of the paper's stated directions (:data:`~brdfpipe.registry.acquisition.PAPER_DIRECTIONS`) a config evaluates.

    Those the claims compare with a near-field set of split ``all`` that the
    config optimises (Xu Fig. 8's table): near-field images at the
    direction's FOV, with sets of its size.
    """
    if "nearfield" not in acquisition["setups"]:
        return []
    fovs = {float(f) for f in acquisition["fovs"]}
    return [d.key for d in PAPER_DIRECTIONS
            if d.fov_deg in fovs and d.n_images <= int(acquisition["n_max_images"])]


def albedo_map_dims(manifold: Mapping[str, Any]) -> list[int]:
    """Latent dimensions with an albedo map (a latent plane needs q ≥ 2)."""
    return [int(q) for q in manifold["latent_dims"] if int(q) >= 2]


def _track_figures(track: str, rule: str, settings: Mapping[str, Any]) -> dict[str, list[str]]:
    """The figures of ``track`` drawn by ``rule`` that a config with the track's ``settings`` produces: key → files."""
    return {f.key: filenames.figure_files(f.stem, table=f.table, note=f.note)
            for f in figure_specs.track_figures(track, rule) if f.produced(settings)}


def acquisition_figures(acquisition: Mapping[str, Any]) -> dict[str, list[str]]:
    """Xu 2016 figure analogues this config produces: key → files (PNG, PDF[, CSV, MD])."""
    return _track_figures("acquisition", "plot_acquisition_figures", acquisition)


def figure_materials(test_materials: Sequence[str]) -> list[str]:
    """The held-out materials of Xu Figs. 2, 3 and 15: those of Xu's Fig. 2 that are held out, in its order.

    A run that holds none of them out (another database, other
    ``test_materials``) shows its first :data:`~brdfpipe.registry.figures.FIG02_FALLBACK_COUNT`
    held-out materials.
    """
    held = list(test_materials)
    paper = [m for m in figure_specs.FIG02_MATERIALS if m in held]
    return paper or held[: figure_specs.FIG02_FALLBACK_COUNT]


def reconstruction_columns(acquisition: Mapping[str, Any]) -> dict[str, list[tuple[str, ReconSet]]]:
    """Per figure of rule plot_reconstruction_figures that the config produces: its columns, (label, set).

    Xu Fig. 2: 1 image (near-field, :func:`curve_fov`, min E(S)), 5 point
    samples of previous work (:data:`~brdfpipe.registry.figures.PREVIOUS_WORK_METRIC`),
    2 images, 20 point samples — set sizes capped at ``n_max_images`` /
    ``n_max_point``; the point columns only when the config optimises that
    metric for point samples.  Xu Fig. 15: 2 images with a fixed camera
    (``fixed_fov``), next to the 2-image near-field set.
    """
    fov = curve_fov(acquisition)
    n_img, n_pt = int(acquisition["n_max_images"]), int(acquisition["n_max_point"])
    points = "point" in acquisition["setups"] and figure_specs.PREVIOUS_WORK_METRIC in acquisition["metrics"]
    columns: dict[str, list[tuple[str, ReconSet]]] = {}
    for f in figure_specs.track_figures("acquisition", "plot_reconstruction_figures"):
        if not f.produced(acquisition):
            continue
        if f.key == "fig02":
            cols = []
            for n_images, n_points in zip((1, 2), figure_specs.PREVIOUS_WORK_POINTS):
                if n_images <= n_img:
                    cols.append((f"{n_images} image{'s' if n_images > 1 else ''}",
                                 ("nearfield", fov, "error", n_images)))
                if points:
                    n = min(n_points, n_pt)
                    cols.append((f"{n} point{'s' if n > 1 else ''}",
                                 ("point", 0.0, figure_specs.PREVIOUS_WORK_METRIC, n)))
            columns[f.key] = cols
        elif f.key == "fig15":
            columns[f.key] = [("2 images, fixed camera", ("fixed_camera", float(acquisition["fixed_fov"]), "error", 2))]
            if _nearfield_error(acquisition):
                columns[f.key].append(("2 images, near-field", ("nearfield", fov, "error", 2)))
        else:
            raise ValueError(f"no columns for figure {f.report_key}")
    return columns


def _nearfield_error(acquisition: Mapping[str, Any]) -> bool:
    return figure_specs.figure("xu-fig02").produced(acquisition)


def reconstruction_sets(acquisition: Mapping[str, Any]) -> list[ReconSet]:
    """Every direction set a held-out material of Figs. 2 and 15 is reconstructed from (each once, in order)."""
    return list(dict.fromkeys(s for cols in reconstruction_columns(acquisition).values() for _, s in cols))


def reconstruction_figures(acquisition: Mapping[str, Any]) -> dict[str, list[str]]:
    """Xu 2016 figures of rendered reconstructions (Figs. 2, 15) this config produces: key → files."""
    return _track_figures("acquisition", "plot_reconstruction_figures", acquisition)


def manifold_figures(manifold: Mapping[str, Any]) -> dict[str, list[str]]:
    """Soler 2018 figure analogues this config produces: key → files (PNG, PDF)."""
    return _track_figures("manifold", "plot_manifold_figures", manifold)


def render_figures(n_path_points: int, n_samples: int = 0) -> dict[str, list[str]]:
    """Rendering-track figures: the pre-render grid always; the path figures when there are path points; Soler
    Fig. 1 when there are latent samples (``render.latent_samples.count``)."""
    return _track_figures("rendering", "plot_render_figures", {"n_path_points": n_path_points, "n_samples": n_samples})


def floor_check_candidates(
    render: Mapping[str, Any], candidates: Mapping[str, tuple[str, float]], n_path_points: int
) -> list[str]:
    """Labels of the GPLVM candidates whose path points ``render.floor_check`` renders.

    None for ``floor_check.candidates: none`` or without path points; the
    default candidate (the first of ``candidates``, see
    :func:`manifold_candidates`) alone for ``default``; every candidate for
    ``all``.
    """
    check = render["floor_check"]
    if check["candidates"] == "none" or n_path_points == 0:
        return []
    labels = list(candidates)
    return labels[:1] if check["candidates"] == "default" else labels


def where_results_are(workdir: str | Path = ".") -> list[str]:
    """The lines a successful run ends with: where its results, claims, explorer, report and logs are.

    Paths are relative to the run's working directory ``workdir``. Results,
    figures, claims and the explorer are named where they exist there (a run of
    some targets only may not have written them); the report is built on demand
    (``make report``), the job logs are always there.
    """
    found = [
        ("results", f"{filenames.RESULTS}/", "every file and its format: docs/outputs.md"),
        ("figures", f"{filenames.FIGURES}/", "the papers' figures as this run draws them"),
        ("claims", filenames.claims_csv(), "every claim of both papers and this run's verdict"),
        ("explorer", filenames.explorer_page(), "open it in a browser, no server needed"),
    ]
    lines = ["brdfpipe: the run is complete."]
    lines += [f"  {label + ':':<10}{path}  ({what})" for label, path, what in found if (Path(workdir) / path).exists()]
    return lines + [
        f"  {'report:':<10}make report writes {filenames.report_zip()}  (unzip it, open report/report.html)",
        f"  {'job logs:':<10}logs/<rule>/  (one per job; Snakemake's own record of the run: .snakemake/log/)",
    ]
