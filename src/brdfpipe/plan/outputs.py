"""Which outputs a configuration produces: direction sets, figures, the unseen materials' files, rules.

Read by the Snakefile while it builds the DAG (``workflow/rules/*.smk``) and
by the tests: the direction sets each split optimises, the sets the closed
loop captures and the unseen materials are looked up with, the figures of
each track (from :data:`brdfpipe.spec.figures.FIGURES`), the GPLVM
candidates the floor check renders,
and which rules a configuration runs
(:func:`brdfpipe.plan.memory.planned_rules`).  Standard library only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from brdfpipe.core import filenames
from brdfpipe.spec import figures as figure_specs
from brdfpipe.spec.acquisition import setup_fovs

__all__ = [
    "direction_files",
    "closedloop_directions",
    "unseen_directions",
    "unseen_figures",
    "unseen_map_q",
    "curve_fov",
    "curve_directions",
    "albedo_map_dims",
    "acquisition_figures",
    "manifold_figures",
    "render_figures",
    "floor_check_candidates",
]


def direction_files(acquisition: Mapping[str, Any], split: str) -> list[str]:
    """Direction sets optimised on a split.

    ``train``: every setup × FOV × metric (they are evaluated); ``all``: only
    the near-field sets of the error metric (the paper's table of optimal
    configurations, Xu Fig. 8).
    """
    files = []
    for setup in acquisition["setups"]:
        if split == "all" and setup != "nearfield":
            continue
        fovs = setup_fovs(setup, acquisition["fovs"], acquisition["fixed_fov"])
        metrics = acquisition["metrics"] if split == "train" else ["error"]
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
