"""Xu 2016's figures of acquisition configurations, drawn from the optimiser's directions files.

* Fig. 8 (:func:`fig08_optimal_configurations`): the table of the optimal
  1- and 2-image near-field configurations per field of view, and their 3-D
  sketches (optimised on all materials, as the paper's table).
* Fig. 9 (:func:`fig09_configurations`): the one- and two-shot light/camera
  pairs at one field of view (25°), of the sets the held-out materials are
  acquired with (split ``train``).
* Fig. 14 (:func:`fig14_fixed_configurations`): the optimal two-image
  configurations of the fixed-camera and fixed-light set-ups, with their
  angles in in-out (θi, φi, θo, φo) and Rusinkiewicz (θh, θd, φd) coordinates.

Each figure writes ``<stem>.png``/``.pdf`` and a table next to it
(``<stem>.csv`` with its digest line, ``<stem>.md``): one row per image.
Angles are those of the configuration's centre (the centre pixel of an
image); ``light`` and ``camera`` are the directions file's unit vectors
(z = the sample's normal), θ from the normal and φ in [0, 360).  Directions
files: ``{directions_dir}/{split}/{setup}-fov{fov}-{metric}.json``
(:func:`brdfpipe.acquisition.optimize.read_directions`).  Missing sets are
skipped with a logged warning; a missing or malformed file raises
:class:`~brdfpipe.core.plot.FigureInputError` (or ValueError) naming it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from brdfpipe.acquisition.figure_inputs import FOV_TOL, AcquisitionFigureInputs
from brdfpipe.core import integrity
from brdfpipe.core.atomic import atomic_write
from brdfpipe.core.plot import FigureInputError, FigureOutput, Warnings, finish, new_figure, no_data, style
from brdfpipe.data import databases
from brdfpipe.registry import acquisition as acquisition_spec
from brdfpipe.registry import tables

__all__ = [
    "fig08_optimal_configurations",
    "configurations_figure",
    "fig09_configurations",
    "fig14_fixed_configurations",
]

_IMAGE_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")


def _setup_label(name: str) -> str:
    """A set-up's legend from its record (the name itself for a set-up no record knows)."""
    record = acquisition_spec.SETUPS.get(name)
    return record.label if record is not None else name


def _fov_text(fov: float) -> str:
    return f"{fov:g}°"




def _spherical_deg(v: Sequence[float]) -> tuple[float, float]:
    x, y, z = (float(c) for c in v)
    theta = math.degrees(math.acos(max(-1.0, min(1.0, z))))
    phi = math.degrees(math.atan2(y, x)) % 360.0 if math.hypot(x, y) > 1e-9 else 0.0
    if phi >= 360.0 - 1e-9:
        phi = 0.0
    return theta, phi


@dataclass
class _ConfigRow:
    fov: float
    n_images: int
    image: int
    theta_h: float
    theta_d: float
    phi_d: float
    light: tuple[float, float, float]
    camera: tuple[float, float, float]
    expected_error: float
    split: str
    database: str
    setup: str
    light_sph: tuple[float, float] = field(init=False)
    camera_sph: tuple[float, float] = field(init=False)

    def __post_init__(self) -> None:
        self.light_sph = _spherical_deg(self.light)
        self.camera_sph = _spherical_deg(self.camera)

    def csv_values(self) -> list[str]:
        return [f"{self.fov:g}", str(self.n_images), str(self.image),
                f"{self.theta_h:.6f}", f"{self.theta_d:.6f}", f"{self.phi_d:.6f}",
                f"{self.light_sph[0]:.6f}", f"{self.light_sph[1]:.6f}",
                f"{self.camera_sph[0]:.6f}", f"{self.camera_sph[1]:.6f}",
                f"{self.expected_error:.10g}", self.split, self.database]


def _load_configurations(directions: Sequence[str | os.PathLike[str]], fovs: Sequence[float],
                         n_images: Sequence[int], setup: str, metric: str, splits: Sequence[str],
                         warn: Warnings) -> tuple[list[_ConfigRow], str]:
    from brdfpipe.acquisition.optimize import read_directions  # noqa: PLC0415 (heavy import, only needed here)

    loaded = []
    for p in directions:
        path = Path(p)
        if not path.is_file():
            raise FigureInputError(f"{path}: directions file not found")
        loaded.append((path, read_directions(path)))  # ValueError naming the file if malformed
    rows: list[_ConfigRow] = []
    seen_databases: dict[str, Path] = {}
    for fov in fovs:
        found = None
        for split in splits:
            found = next(((p, d) for p, d in loaded if d.split == split and d.setup.kind == setup
                          and d.metric == metric and abs(d.setup.fov_deg - float(fov)) <= FOV_TOL), None)
            if found is not None:
                break
        if found is None:
            warn(f"no {setup} {metric} directions file for FOV {_fov_text(fov)} among the inputs "
                 f"(splits tried: {', '.join(splits)}); skipped")
            continue
        path, d = found
        if not d.database:
            raise FigureInputError(f"{path}: empty 'database'")
        seen_databases.setdefault(d.database, path)
        by_n = {s.n: s for s in d.sets}
        for n in n_images:
            s = by_n.get(n)
            if s is None:
                warn(f"{path}: no set of {n} image(s); skipped")
                continue
            for i, rec in enumerate(s.records, start=1):
                rows.append(_ConfigRow(
                    fov=float(fov), n_images=n, image=i,
                    theta_h=float(rec["theta_h_deg"]), theta_d=float(rec["theta_d_deg"]),
                    phi_d=float(rec["phi_d_deg"]),
                    light=tuple(float(c) for c in rec["light"]),  # type: ignore[arg-type]
                    camera=tuple(float(c) for c in rec["camera"]),  # type: ignore[arg-type]
                    expected_error=s.expected_error, split=d.split, database=d.database, setup=setup))
    if len(seen_databases) > 1:
        raise FigureInputError("directions files from different databases: "
                               + "; ".join(f"{db!r} ({p})" for db, p in sorted(seen_databases.items())))
    return rows, next(iter(seen_databases), "")


def _markdown(rows: Sequence[_ConfigRow], database: str, setup: str, metric: str) -> str:
    lines = [
        f"# Optimal {'- and '.join(sorted({str(r.n_images) for r in rows})) or '1- and 2'}-image "
        f"{_setup_label(setup)} configurations (Xu 2016 Fig. 8 analogue), {databases.title(database)}",
        "",
        f"Directions optimised with {'E(S) (eq. 15)' if metric == 'error' else 'the condition number'}; "
        "angles in degrees at the centre of the sample (θh, θd, φd: Rusinkiewicz half/difference angles; "
        "light and camera as (θ, φ) spherical angles from the sample normal). "
        "E(S) is the expected error of the whole set.",
        "",
    ]
    if not rows:
        lines.append("No directions files were found for the requested fields of view.")
        return "\n".join(lines) + "\n"
    lines += [
        "| FOV | images | image | θh | θd | φd | light (θ, φ) | camera (θ, φ) | E(S) | split |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.fov:g}° | {r.n_images} | {r.image} | {r.theta_h:.1f} | {r.theta_d:.1f} | {r.phi_d:.1f} "
            f"| ({r.light_sph[0]:.1f}, {r.light_sph[1]:.1f}) | ({r.camera_sph[0]:.1f}, {r.camera_sph[1]:.1f}) "
            f"| {r.expected_error:.4g} | {r.split} |"
        )
    return "\n".join(lines) + "\n"


def _draw_configuration(ax: Any, rows: Sequence[_ConfigRow], fov: float) -> None:
    """3-D sketch: hemisphere, sample disk (radius tan(fov/2)), light arrows and camera positions."""
    t = np.linspace(0.0, 2.0 * np.pi, 73)
    for el in (0.0, 30.0, 60.0):  # parallels
        r, z = math.cos(math.radians(el)), math.sin(math.radians(el))
        ax.plot(r * np.cos(t), r * np.sin(t), np.full_like(t, z), color="#c8c8c8", linewidth=0.6)
    s = np.linspace(0.0, 0.5 * np.pi, 25)
    for az in range(0, 360, 45):  # meridians
        a = math.radians(az)
        ax.plot(np.cos(s) * math.cos(a), np.cos(s) * math.sin(a), np.sin(s), color="#dddddd", linewidth=0.5)
    nu = math.tan(math.radians(fov) / 2.0)
    ax.plot_trisurf(np.concatenate([[0.0], nu * np.cos(t)]), np.concatenate([[0.0], nu * np.sin(t)]),
                    np.zeros(t.size + 1), color="#9e9e9e", alpha=0.55, linewidth=0, shade=False)
    ax.plot(nu * np.cos(t), nu * np.sin(t), np.zeros_like(t), color="#555555", linewidth=0.8)
    ax.plot([0, 0], [0, 0], [0, 1.05], color="#888888", linewidth=0.7, linestyle=":")
    rim = np.stack([nu * np.cos(t[::9]), nu * np.sin(t[::9]), np.zeros(t[::9].size)], axis=1)
    for r in rows:
        colour = _IMAGE_COLOURS[(r.image - 1) % len(_IMAGE_COLOURS)]
        li = np.asarray(r.light, dtype=np.float64)
        ca = np.asarray(r.camera, dtype=np.float64)
        start = 1.25 * li
        ax.quiver(start[0], start[1], start[2], -start[0] * 0.88, -start[1] * 0.88, -start[2] * 0.88,
                  color=colour, linewidth=1.8, arrow_length_ratio=0.18)
        ax.text(*(1.34 * li), f"L{r.image}", color=colour, fontsize=8.5, fontweight="bold",
                ha="center", va="center")
        for p in rim:  # viewing cone to the disk rim
            ax.plot([ca[0], p[0]], [ca[1], p[1]], [ca[2], p[2]], color=colour, linewidth=0.5, alpha=0.6)
        ax.scatter([ca[0]], [ca[1]], [ca[2]], color=colour, marker="s", s=30, depthshade=False,
                   label=(f"image {r.image}: L ({r.light_sph[0]:.0f}, {r.light_sph[1]:.0f}), "
                          f"C ({r.camera_sph[0]:.0f}, {r.camera_sph[1]:.0f}); θh {r.theta_h:.0f}, "
                          f"θd {r.theta_d:.0f}, φd {r.phi_d:.0f}"))
        ax.text(*(1.14 * ca), f"C{r.image}", color=colour, fontsize=8.5, fontweight="bold",
                ha="center", va="center")
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_zlim(0.0, 1.1)
    ax.set_box_aspect((1.0, 1.0, 0.55), zoom=1.3)
    ax.view_init(elev=24, azim=-62)
    ax.set_axis_off()


def fig08_optimal_configurations(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Figs. 8 and 9: table and sketch of the optimal 1- and 2-image near-field configurations per FOV.

    ``inp.directions``: the direction files to choose from; for each FOV of
    ``inp.fovs`` the first of the splits ``all``, ``train`` with a near-field
    E(S) file at that FOV is used (``all``, the full database, as Xu's Fig. 8;
    else ``train``).  Writes
    ``<stem>.csv`` (columns :data:`~brdfpipe.registry.tables.FIG08`, one row per image),
    ``<stem>.md`` and the sketch ``<stem>.png``/``.pdf`` (one 3-D panel per
    FOV and set size: the hemisphere, the sample disk, light arrows L and
    camera positions C with their viewing cones).
    """
    warn = Warnings("fig08")
    setup, metric, n_images = "nearfield", "error", [1, 2]
    rows, database = _load_configurations(inp.directions, [float(f) for f in inp.fovs or ()], n_images, setup,
                                          metric, ["all", "train"], warn)
    stem = Path(stem)
    csv_path = stem.with_name(stem.name + ".csv")
    md_path = stem.with_name(stem.name + ".md")

    integrity.write_csv(csv_path, [tables.FIG08, *(r.csv_values() for r in rows)])  # with its digest line
    md = _markdown(rows, database, setup, metric)
    atomic_write(md_path, lambda fh: fh.write(md), binary=False)

    present = sorted({r.fov for r in rows})
    sizes = [n for n in n_images if any(r.n_images == n for r in rows)]
    with style():
        ncols = max(1, len(sizes))
        nrows = max(1, len(present))
        fig = new_figure(4.2 * ncols + 0.2, 3.9 * nrows + 0.9)
        if not rows:
            ax = fig.subplots()
            no_data(ax, "no directions files for the requested FOVs")
        else:
            # per FOV: a row of 3-D sketches and, under each, a strip holding its legend
            gs = fig.add_gridspec(2 * nrows, ncols, height_ratios=[6.0, 1.0] * nrows)
            for i, fov in enumerate(present):
                for j, n in enumerate(sizes):
                    ax = fig.add_subplot(gs[2 * i, j], projection="3d")
                    key = fig.add_subplot(gs[2 * i + 1, j])
                    key.set_axis_off()
                    sel = [r for r in rows if r.fov == fov and r.n_images == n]
                    if not sel:
                        ax.set_axis_off()
                        ax.set_title(f"FOV {_fov_text(fov)}, {n} image{'s' if n > 1 else ''}: no set")
                        continue
                    _draw_configuration(ax, sel, fov)
                    ax.set_title(f"FOV {_fov_text(fov)}, {n} image{'s' if n > 1 else ''}, "
                                 f"E(S) = {sel[0].expected_error:.3g}")
                    handles, labels = ax.get_legend_handles_labels()
                    key.legend(handles, labels, loc="upper center", fontsize=7.5, frameon=False,
                               handletextpad=0.3, borderaxespad=0.0,
                               title="L: light, C: camera as (θ, φ); angles in degrees", title_fontsize=7.5)
        title = (f"Optimal {_setup_label(setup)} configurations per field of view "
                 f"({databases.title(database) if database else 'no directions files found'})")
        splits_used = sorted({r.split for r in rows})
        subtitle = ("Xu 2016 Figs. 8-9 analogue; arrows L: light, squares C: camera with its view cone "
                    f"to the sample disk; directions from split {', '.join(splits_used) or '-'}")
        return finish(fig, stem, title, subtitle, database, warn, extra=(csv_path, md_path))


# ---------------------------------------------------------------------------
# Figs. 9 and 14: chosen sets at one field of view, angles in in-out and Rusinkiewicz coordinates
# ---------------------------------------------------------------------------



def _configuration_values(r: _ConfigRow) -> list[str]:
    return [r.setup, f"{r.fov:g}", str(r.n_images), str(r.image),
            f"{r.light_sph[0]:.6f}", f"{r.light_sph[1]:.6f}", f"{r.camera_sph[0]:.6f}", f"{r.camera_sph[1]:.6f}",
            f"{r.theta_h:.6f}", f"{r.theta_d:.6f}", f"{r.phi_d:.6f}", f"{r.expected_error:.10g}", r.split,
            r.database]


def _configurations_markdown(rows: Sequence[_ConfigRow], title: str, metric: str) -> str:
    lines = [f"# {title}", "",
             f"Directions optimised with {'E(S) (eq. 15)' if metric == 'error' else metric}; angles in degrees at "
             "the centre of the sample: in-out (θi, φi: light; θo, φo: camera; θ from the sample normal) and "
             "Rusinkiewicz (θh, θd, φd). E(S) is the expected error of the whole set.", ""]
    if not rows:
        return "\n".join(lines + ["No directions file holds the requested sets."]) + "\n"
    lines += ["| set-up | FOV | images | image | θi | φi | θo | φo | θh | θd | φd | E(S) | split |",
              "|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|"]
    for r in rows:
        lines.append(f"| {_setup_label(r.setup)} | {r.fov:g}° | {r.n_images} | {r.image} "
                     f"| {r.light_sph[0]:.1f} | {r.light_sph[1]:.1f} | {r.camera_sph[0]:.1f} | {r.camera_sph[1]:.1f} "
                     f"| {r.theta_h:.1f} | {r.theta_d:.1f} | {r.phi_d:.1f} | {r.expected_error:.4g} | {r.split} |")
    return "\n".join(lines) + "\n"


def _draw_polar(ax: Any, rows: Sequence[_ConfigRow]) -> None:
    """Top view of the hemisphere: each image's light L (star) and camera C (square) at radius θ, angle φ."""
    ax.set_ylim(0.0, 90.0)
    ax.set_yticks([30.0, 60.0, 90.0], ["30°", "60°", "90°"], fontsize=6)
    ax.set_xticks(np.radians(np.arange(0.0, 360.0, 90.0)), ["φ 0°", "90°", "180°", "270°"], fontsize=6)
    for r in rows:
        colour = _IMAGE_COLOURS[(r.image - 1) % len(_IMAGE_COLOURS)]
        for (theta, phi), marker, tag in ((r.light_sph, "*", "L"), (r.camera_sph, "s", "C")):
            ax.plot([math.radians(phi)], [theta], marker=marker, markersize=9 if marker == "*" else 6,
                    color=colour, linestyle="none")
            ax.annotate(f"{tag}{r.image}", (math.radians(phi), theta), xytext=(5, 3), textcoords="offset points",
                        color=colour, fontsize=7.5, fontweight="bold")


def _angle_text(r: _ConfigRow) -> str:
    return (f"image {r.image}: θi {r.light_sph[0]:.1f}, φi {r.light_sph[1]:.1f}; θo {r.camera_sph[0]:.1f}, "
            f"φo {r.camera_sph[1]:.1f}\n    θh {r.theta_h:.1f}, θd {r.theta_d:.1f}, φd {r.phi_d:.1f}")


def configurations_figure(directions: Sequence[str | os.PathLike[str]], stem: str | os.PathLike[str], *,
                          sets: Sequence[tuple[str, float, int]], title: str, subtitle: str,
                          metric: str = "error", split: str = "train", database: str = "") -> FigureOutput:
    """One column per set ``(setup, fov, n)`` of the ``split``/``metric`` directions files: 3-D sketch, top view, angles.

    The 3-D sketch is Fig. 8's (hemisphere, sample disk, light arrows L,
    cameras C with their view cones); under it the top view (θ radial, φ
    round) and the angles of each image.  Writes ``<stem>.csv``
    (:data:`~brdfpipe.registry.tables.CONFIGURATIONS`, one row per image) and ``<stem>.md``.
    ``database``: the run's, named when no directions file holds a set.
    ``title`` (ASCII: it is the PDF's Title too) is followed by the database's name.
    """
    warn = Warnings(Path(stem).name)
    panels: list[tuple[tuple[str, float, int], list[_ConfigRow]]] = []
    seen_databases: set[str] = set()
    for setup, fov, n in sets:
        rows, found = _load_configurations(directions, [float(fov)], [int(n)], setup, metric, [split], warn)
        panels.append(((setup, float(fov), int(n)), rows))
        seen_databases |= {found} if found else set()
    if len(seen_databases) > 1:
        raise FigureInputError(f"directions files from different databases: {', '.join(sorted(seen_databases))}")
    database = next(iter(seen_databases), database)
    title = f"{title} ({databases.title(database) if database else 'no directions files found'})"
    rows_all = [r for _, rows in panels for r in rows]
    stem = Path(stem)
    csv_path, md_path = stem.with_name(stem.name + ".csv"), stem.with_name(stem.name + ".md")
    integrity.write_csv(csv_path, [tables.CONFIGURATIONS, *(_configuration_values(r) for r in rows_all)])
    md = _configurations_markdown(rows_all, title, metric)
    atomic_write(md_path, lambda fh: fh.write(md), binary=False)
    with style():
        ncols = max(1, len(panels))
        fig = new_figure(4.4 * ncols + 0.2, 9.4)
        gs = fig.add_gridspec(3, ncols, height_ratios=[5.0, 3.6, 1.3])
        for j, ((setup, fov, n), rows) in enumerate(panels):
            what = f"{_setup_label(setup)}, FOV {_fov_text(fov)}, {n} image{'s' if n > 1 else ''}"
            sketch = fig.add_subplot(gs[0, j], projection="3d")
            top = fig.add_subplot(gs[1, j], projection="polar")
            text = fig.add_subplot(gs[2, j])
            text.set_axis_off()
            if not rows:
                sketch.set_axis_off()
                sketch.set_title(f"{what}: no set")
                no_data(top, "no directions file holds this set")
                continue
            _draw_configuration(sketch, rows, fov)
            sketch.set_title(f"{what}\nE(S) = {rows[0].expected_error:.3g}")
            _draw_polar(top, rows)
            text.text(0.0, 1.0, "\n".join(_angle_text(r) for r in rows), va="top", ha="left", fontsize=7,
                      family="monospace", transform=text.transAxes)
        return finish(fig, stem, title, subtitle, database, warn, extra=(csv_path, md_path))


def fig09_configurations(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 9: the one- and two-shot near-field light/camera pairs at ``inp.figure_fov`` (E(S), ``inp.split``)."""
    fov, split = inp.figure_fov, inp.split
    return configurations_figure(
        inp.directions, stem, sets=[("nearfield", fov, 1), ("nearfield", fov, 2)], metric="error", split=split,
        database=inp.database,
        title="One- and two-shot near-field configurations",
        subtitle=(f"Xu 2016 Fig. 9 analogue, FOV {_fov_text(fov)}; directions optimised on split {split} (the sets the held-out materials "
                  "are acquired with); L: light (star), C: camera (square); top view: θ radial, φ round"))


def fig14_fixed_configurations(inp: AcquisitionFigureInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Xu Fig. 14: the optimal 2-image sets of the fixed-camera and fixed-light set-ups at ``inp.fov_fixed``."""
    fov, split, n = inp.fov_fixed, inp.split, 2
    return configurations_figure(
        inp.directions, stem, sets=[("fixed_camera", fov, n), ("fixed_light", fov, n)], metric="error", split=split,
        database=inp.database,
        title=f"Optimal {n}-image configurations with a fixed camera and with a fixed light",
        subtitle=(f"Xu 2016 Fig. 14 analogue, FOV {_fov_text(fov)}; directions optimised on split {split}; angles in in-out (θi, φi, θo, "
                  "φo) and Rusinkiewicz (θh, θd, φd) coordinates; the shared direction at φ = 0"))
