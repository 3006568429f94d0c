"""Figure analogues of Soler et al. 2018 ("A Versatile Parameterization for
Measured Material Manifolds") for the manifold track.

Figs. 5, 7, 8, 9, 10 and eq. 7 from the GPLVM fits and
:mod:`brdfpipe.manifold.analysis`'s tables, Fig. 6 from
:mod:`brdfpipe.manifold.lengthscale`'s (drawn by
:mod:`brdfpipe.manifold.lengthscale_figure`), and the comparison of data
spaces (:func:`manifold_spaces`); :func:`make_manifold_figures` draws those a
rule asks for, each by the function its record names.  Every input is read and checked first; a
missing or malformed file raises :class:`~brdfpipe.core.plot.FigureInputError`
naming it, before any figure is written (the readers:
:mod:`brdfpipe.manifold.figure_inputs`; the latent maps' zooms and labels:
:mod:`brdfpipe.manifold.latent_map`).  Style, determinism and atomic
writing are :mod:`brdfpipe.core.plot`'s.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.ticker import MaxNLocator

from brdfpipe.core.plot import (
    COLOURS,
    FigureInputError,
    FigureOutput,
    Warnings,
    draw_figures,
    figure_stems,
    figure_stem,
    finish,
    new_figure,
    no_data,
    style,
)
from brdfpipe.data import databases
from brdfpipe.manifold.figure_inputs import (
    LatentPath,
    ManifoldInputs,
    read_manifold_inputs,
    read_model,
    read_unseen,
)
from brdfpipe.manifold.latent_map import label_rows, latent_row, set_title, zoom_chain
from brdfpipe.manifold.lengthscale_figure import draw_lengthscale_figure

__all__ = [
    "manifold_fig05_likelihood",
    "manifold_fig10_latent_q2",
    "manifold_fig10_latent_q5",
    "manifold_fig07_albedo",
    "manifold_fig09_paths",
    "manifold_fig08_reproduction",
    "manifold_eq7_bound",
    "manifold_fig06_lengthscale",
    "manifold_spaces",
    "make_manifold_figures",
    "manifold_unseen",
]

#: Most path panels drawn in Figs. 9 and eq. 7 (the first paths of paths.csv, in file order).
MAX_PATH_PANELS: int = 6
#: GPLVM reproduction errors at or below this are drawn at it ("exact").
REPRODUCTION_FLOOR: float = 1e-16
#: Font size (points) of the material names on the latent maps.
LATENT_LABEL_SIZE: float = 4.8

_PATH_A_COLOUR = "#1f5fbf"
_PATH_B_COLOUR = "#d62728"


def _grid_shape(n: int, max_cols: int) -> tuple[int, int]:
    ncols = max(1, min(n, max_cols))
    return max(1, math.ceil(n / ncols)), ncols


def _fit_note(inp: ManifoldInputs) -> str:
    """"standardised space, mu 1e-06" for the titles: which data space and noise term the fits use (ASCII: PDF metadata)."""
    fits = sorted({(str(m.space), float(m.mu)) for m in inp.models.values()})
    return "; ".join(f"{s} space, mu {mu:g}" for s, mu in fits) or "no model"


def _space_note(spaces: Iterable[str]) -> str:
    s = sorted(set(spaces))
    return f"data space {', '.join(s)}" if s else ""


# ---------------------------------------------------------------------------
# The manifold figures
# ---------------------------------------------------------------------------


def manifold_fig05_likelihood(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 5: log-likelihood vs optimisation step, one line per q; right: gap to the best L (log y)."""
    warn = Warnings("manifold-fig05")
    with style():
        fig = new_figure(10.0, 4.2)
        ax, gap = fig.subplots(1, 2)
        if not inp.traces:
            warn("no trace files given")
            no_data(ax, "no trace files")
            gap.set_visible(False)
        else:
            allL = np.concatenate([t.log_likelihood for t in inp.traces.values()])
            switch_drawn = False
            for i, (q, tr) in enumerate(sorted(inp.traces.items())):
                colour = COLOURS[i % len(COLOURS)]
                ax.plot(tr.step, tr.log_likelihood, color=colour, linewidth=1.3, label=f"q = {q}")
                best = float(tr.log_likelihood.max())
                g = best - tr.log_likelihood
                ok = g > 0
                gap.plot(tr.step[ok], g[ok], color=colour, linewidth=1.3, label=f"q = {q}")
                for s in tr.switches:
                    for a, v in ((ax, tr.log_likelihood[s]), (gap, g[s] if g[s] > 0 else np.nan)):
                        a.axvline(tr.step[s], color=colour, linestyle=":", linewidth=1.0)
                        if math.isfinite(v):
                            a.plot([tr.step[s]], [v], marker="o", markersize=4.5, color=colour,
                                   markerfacecolor="white", linestyle="none")
                    ax.annotate(str(tr.stage[s]), (tr.step[s], tr.log_likelihood[s]), fontsize=6, color=colour,
                                xytext=(3, -10), textcoords="offset points")
                    switch_drawn = True
                model = inp.models.get(q)
                if model is not None:
                    L_model = float(model.log_likelihood)
                    if abs(L_model - float(tr.log_likelihood[-1])) > 1e-6 * max(1.0, abs(L_model)):
                        warn(f"q = {q}: the trace ends at L = {tr.log_likelihood[-1]:.10g} but the model "
                             f"({inp.model_paths[q]}) has L = {L_model:.10g}")
            if switch_drawn:
                ax.plot([], [], color="#444444", linestyle=":", marker="o", markerfacecolor="white",
                        label="stage changes (label: the new stage)")
            # One sign and a wide range: |L| on a log scale (symlog, linear part below every value);
            # values of both signs: linear (the right panel shows the convergence on a log scale).
            a = np.abs(allL)
            if (allL.min() > 0 or allL.max() < 0) and a.max() / a.min() > 30.0:
                ax.set_yscale("symlog", linthresh=10.0 ** math.floor(math.log10(a.min())))
            last = max(int(t.step[-1]) for t in inp.traces.values())
            for a_ in (ax, gap):  # sweeps (tens) and L-BFGS iterations (thousands) both visible
                if last > 200:
                    a_.set_xscale("symlog", linthresh=10.0, linscale=0.6)
                a_.set_xlim(left=0.0)
            ax.set_xlabel("step (L-BFGS iteration, Newton step or Hooke–Jeeves sweep; stage changes marked)")
            ax.set_ylabel("log-likelihood L (eq. 6)")
            ax.set_title("log-likelihood")
            ax.legend(loc="lower right")
            gap.set_yscale("log")
            gap.set_xlabel("step")
            gap.set_ylabel("max L − L")
            gap.set_title("distance to the best log-likelihood")
            if not gap.get_lines():
                no_data(gap, "no improvement")
        title = f"GPLVM log-likelihood during the fit ({databases.title(inp.database)}, {_fit_note(inp)})"
        methods = sorted({str(m.method) for m in inp.models.values()})
        scales = sorted({f"{float(m.gram_scale):.4g}" for m in inp.models.values()})
        subtitle = (f"Soler 2018 Fig. 5 analogue; method {', '.join(methods)}; Gram matrix divided by "
                    f"{', '.join(scales)} before fitting")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _latent_names(names: Sequence[str]) -> list[str]:
    return [str(n) for n in names]


def manifold_fig10_latent_q2(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 (latent map): the 2-D latent points, each named, coloured by its albedo.

    Where the points crowd (names would overlap), zoomed panels on the most
    crowded cluster follow (at most two, nested); every material is named
    once, in the deepest panel that shows it.
    """
    warn = Warnings("manifold-fig10-q2")
    q = 2 if 2 in inp.models else min(inp.models)
    if q != 2:
        warn(f"no q = 2 model; drawing {'dims 0, 1' if q > 2 else 'dim 0 against the material index'} "
             f"of the q = {q} model")
    model = inp.models[q]
    X = np.asarray(model.X, dtype=np.float64)
    if q < 2:
        P = np.column_stack([X[:, 0], np.arange(len(X), dtype=np.float64)])
        labels = ("latent dim 0", "material index")
    else:
        P = X[:, :2]
        labels = ("latent dim 0", "latent dim 1")
    names = _latent_names(model.names)
    single = zoom_chain(P, (7.6, 6.6))
    views = single if len(single) == 1 else zoom_chain(P, (5.4, 4.9))
    with style():
        if len(views) == 1:
            fig = new_figure(9.0, 8.4)
            axes = [fig.subplots()]
        else:
            nrows, ncols = _grid_shape(len(views), 2 if len(views) == 4 else 3)
            fig = new_figure(6.1 * ncols + 0.3, 6.0 * nrows + 1.0)
            grid = fig.subplots(nrows, ncols, squeeze=False).ravel()
            axes = list(grid[: len(views)])
            for ax in grid[len(views):]:
                ax.set_visible(False)
        latent_row(axes, P, inp.albedo.display_colours(model.names), views, labels,
                    f"q = {q}, {len(names)} materials", size=22.0)
        title = f"The {'2-D ' if q == 2 else ''}latent space of the materials ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = (f"Soler 2018 Fig. 10 analogue; colour: hemispherical albedo (RGB / brightest channel, "
                    f"gamma 1/2.2); ℓ = {model.ell:g}, μ = {model.mu:g}; {_space_note([model.space])}"
                    + ("; each material named once, in the deepest panel showing it" if len(views) > 1 else ""))
        set_title(fig, title, subtitle)
        label_rows(fig, [(axes, P)], names, fontsize=LATENT_LABEL_SIZE, marker_radius=2.6)
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig10_latent_q5(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 10 for q = 5: the latent points projected onto dims (0,1), (1,2), (2,3), (3,4), named.

    The q = 5 model, else the largest q (its consecutive pairs, at most 4).
    One row per pair; crowded projections get zoomed panels to the right
    (as :func:`manifold_fig10_latent_q2`).
    """
    warn = Warnings("manifold-fig10-q5")
    q = 5 if 5 in inp.models else max(inp.models)
    if q != 5:
        warn(f"no q = 5 model; drawing the q = {q} model")
    model = inp.models[q]
    X = np.asarray(model.X, dtype=np.float64)
    names = _latent_names(model.names)
    pairs = [(k, k + 1) for k in range(min(q, 5) - 1)]
    chains = [zoom_chain(X[:, list(dims)], (4.4, 4.2)) for dims in pairs]
    with style():
        ncols = max([len(c) for c in chains] + [1])
        if len(chains) == 4 and ncols == 1:  # nothing crowded: a 2 × 2 grid
            fig = new_figure(2 * 5.4 + 0.3, 2 * 5.0 + 0.8)
            grid = fig.subplots(2, 2, squeeze=False).ravel()
            rows_axes = [[ax] for ax in grid]
        else:
            nrows = max(1, len(pairs))
            fig = new_figure(5.0 * ncols + 0.3, 4.8 * nrows + 0.8)
            grid = fig.subplots(nrows, ncols, squeeze=False)
            rows_axes = [list(grid[r, : len(chains[r])]) for r in range(len(chains))]
            for r in range(nrows):
                for c in range(len(chains[r]) if r < len(chains) else 0, ncols):
                    grid[r, c].set_visible(False)
        colours = inp.albedo.display_colours(model.names)
        if not pairs:
            warn(f"the q = {q} model has one latent dimension: no 2-D projection")
            ax0 = grid.ravel()[0]
            ax0.set_visible(True)
            no_data(ax0, f"q = {q}: no pair of latent dimensions")
        rows = []
        for axes, dims, views in zip(rows_axes, pairs, chains):
            P = X[:, list(dims)]
            latent_row(axes, P, colours, views, (f"latent dim {dims[0]}", f"latent dim {dims[1]}"),
                        f"dims {dims[0]}, {dims[1]}", size=16.0)
            rows.append((axes, P))
        title = f"Projections of the q = {q} latent space ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = (f"Soler 2018 Fig. 10 analogue; latent points projected onto pairs of latent dimensions; "
                    f"colour: hemispherical albedo (gamma 1/2.2); {_space_note([model.space])}"
                    + ("; each material named once per row, in the deepest panel showing it"
                       if ncols > 1 else ""))
        set_title(fig, title, subtitle)
        label_rows(fig, rows, names, fontsize=4.5, marker_radius=2.2)
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig07_albedo(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 7: luminance albedo of the interpolated BRDFs over the latent plane, with iso-lines."""
    warn = Warnings("manifold-fig07")
    maps = [inp.maps[q] for q in sorted(inp.maps)]
    with style():
        nrows, ncols = _grid_shape(max(1, len(maps)), 2)
        fig = new_figure(5.6 * ncols + 0.3, 4.9 * nrows + 0.8)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        if not maps:
            warn("no albedo maps given")
            no_data(axes[0], "no albedo maps")
        for ax, m in zip(axes, maps):
            L = m.luminance
            dx, dy = np.diff(m.x), np.diff(m.y)
            uniform = np.allclose(dx, dx[0], rtol=1e-6) and np.allclose(dy, dy[0], rtol=1e-6)
            if uniform:
                extent = (m.x[0] - dx[0] / 2, m.x[-1] + dx[0] / 2, m.y[0] - dy[0] / 2, m.y[-1] + dy[0] / 2)
                im = ax.imshow(L, origin="lower", extent=extent, cmap="viridis", interpolation="nearest",
                               aspect="equal")
            else:
                im = ax.pcolormesh(m.x, m.y, L, cmap="viridis", shading="nearest")
                ax.set_aspect("equal")
            lo, hi = float(L.min()), float(L.max())
            if hi - lo > 1e-12 * max(1.0, abs(hi)):
                levels = [v for v in MaxNLocator(nbins=8).tick_values(lo, hi) if lo < v < hi]
                if levels:
                    cs = ax.contour(m.x, m.y, L, levels=levels, colors="#111111", linewidths=0.6, alpha=0.8)
                    ax.clabel(cs, fmt="%.3g", fontsize=6.0, inline=True)
                phys = [v for v in (0.0, 1.0) if lo < v < hi]
                if phys:  # where the albedo leaves the physical range [0, 1]
                    ax.contour(m.x, m.y, L, levels=phys, colors="#ff3030", linewidths=1.3, linestyles="solid")
            else:
                warn(f"{m.path}: constant luminance {lo:.4g}; no iso-lines")
            model = inp.models[m.q]
            X = np.asarray(model.X, dtype=np.float64)
            if m.inside_hull.any() and not m.inside_hull.all():
                ax.contour(m.x, m.y, m.inside_hull.astype(float), levels=[0.5], colors="white", linewidths=1.2,
                           linestyles="dashed", zorder=3)
            ax.scatter(X[:, m.dims[0]], X[:, m.dims[1]], s=7.0, c="white", edgecolors="#222222",
                       linewidths=0.35, zorder=4)
            ax.text(0.01, 0.01, f"albedo outside [0, 1]: {100 * m.bad_inside:.2f} % of the grid inside the hull, "
                    f"{100 * m.bad_outside:.1f} % outside\nsmooth map vs own albedo at the training points: "
                    f"median {m.training_gap[0]:.2g}, max {m.training_gap[1]:.2g}",
                    transform=ax.transAxes, fontsize=6.0, color="white", va="bottom", zorder=5,
                    bbox={"facecolor": "#000000", "alpha": 0.45, "edgecolor": "none", "pad": 1.5})
            if uniform:
                ax.set_xlim(extent[0], extent[1])
                ax.set_ylim(extent[2], extent[3])
            else:
                ax.set_xlim(m.x[0], m.x[-1])
                ax.set_ylim(m.y[0], m.y[-1])
            ax.set_xlabel(f"latent dim {m.dims[0]}")
            ax.set_ylabel(f"latent dim {m.dims[1]}")
            ax.grid(False)
            if m.q > 2:
                others = [k for k in range(m.q) if k not in m.dims]
                held = ", ".join(f"x{k} = {m.fixed[k]:.3g}" for k in others)
                ax.set_title(f"q = {m.q}: slice through dims {m.dims[0]}, {m.dims[1]} ({held})")
            else:
                ax.set_title(f"q = {m.q}: latent plane")
            if lo < 0.0 or hi > 1.0:
                ax.set_title(ax.get_title() + "\nred iso-lines: albedo 0 and 1 (limits of the physical range)",
                             fontsize=8.0)
            cax = ax.inset_axes((1.04, 0.0, 0.045, 1.0))  # follows the (equal-aspect) image's height
            cb = fig.colorbar(im, cax=cax)
            cb.set_label("albedo (luminance)")
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            off = ~((X[:, m.dims[0]] >= x0) & (X[:, m.dims[0]] <= x1) & (X[:, m.dims[1]] >= y0) & (X[:, m.dims[1]] <= y1))
            if off.any():
                warn(f"{m.path}: {int(off.sum())} of {len(off)} training points lie outside the map "
                     f"(is it the map of {inp.model_paths[m.q]}?)")
            if lo < 0.0 or hi > 1.0:
                warn(f"{m.path}: luminance albedo outside [0, 1] ({lo:.4g}..{hi:.4g})")
        for ax in axes[max(1, len(maps)):]:
            ax.set_visible(False)
        title = f"Albedo of the interpolated BRDFs over the latent space ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 7 analogue; luminance 0.2126 R + 0.7152 G + 0.0722 B of the hemispherical "
                    "albedo, iso-lines labelled; white dashed line: the convex hull of the training points "
                    "(for q > 2, where the slice cuts the q-dimensional hull); white dots: training materials "
                    "(for q > 2 their projection onto the slice, so their albedo need not match the map). "
                    "The map is the smooth interpolant (kernel without the μδ term): no grid point is a "
                    "training point, where the δ term would give the material's own albedo exactly")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _selected_paths(inp: ManifoldInputs, warn: Warnings) -> list[LatentPath]:
    paths = list(inp.paths.paths)
    if len(paths) > MAX_PATH_PANELS:
        warn(f"{inp.paths.path}: {len(paths)} paths; drawing the first {MAX_PATH_PANELS}")
    return paths[:MAX_PATH_PANELS]


def manifold_fig09_paths(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 9: perceptual distance to A and to B along latent paths (normalised axes)."""
    warn = Warnings("manifold-fig09")
    paths = _selected_paths(inp, warn)
    with style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = new_figure(3.7 * ncols + 0.3, 3.5 * nrows + 0.9)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        line = np.array([0.0, 1.0])
        for ax, lp in zip(axes, paths):
            u = lp.latent_distance / lp.latent_distance[-1]
            ax.plot(line, line, color=_PATH_A_COLOUR, linestyle="--", linewidth=0.9, alpha=0.7)
            ax.plot(line, 1.0 - line, color=_PATH_B_COLOUR, linestyle="--", linewidth=0.9, alpha=0.7)
            ax.plot(u, lp.perceptual_a / lp.perceptual_ab, color=_PATH_A_COLOUR, marker="o", markersize=3.0,
                    linewidth=1.2, label=f"to A: {lp.material_a}")
            ax.plot(u, lp.perceptual_b / lp.perceptual_ab, color=_PATH_B_COLOUR, marker="s", markersize=3.0,
                    linewidth=1.2, label=f"to B: {lp.material_b}")
            ax.set_title(lp.title, fontsize=8.0)
            ax.set_xlim(-0.03, 1.03)
            ax.set_xlabel("latent distance from A / distance A–B")
            ax.set_ylabel("perceptual distance / d(A, B)")
            ax.legend(loc="best", fontsize=6.5)
        _hide_unused_path_panels(axes, len(paths))
        title = f"Perceptual distances along latent paths ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 9 analogue; blue: distance of the interpolated BRDF to A, red: to B, "
                    "both divided by the distance between A and B; dashed: perceptually uniform; "
                    f"{_space_note(p.space for p in paths)}")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def _hide_unused_path_panels(axes: Sequence[Any], n_paths: int) -> None:
    """Hide the panels after the last path; with no path at all, say so in the first."""
    for ax in axes[n_paths:]:
        if not n_paths and ax is axes[0]:
            no_data(ax, "no paths")
        else:
            ax.set_visible(False)


def manifold_fig08_reproduction(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 8: relative error reproducing each training material, PCA (k components) vs GPLVM (q)."""
    warn = Warnings("manifold-fig08")
    tab = inp.reproduction
    spaces = tab.spaces()
    model_spaces = sorted({str(m.space) for m in inp.models.values()})
    if len(spaces) == 1:
        space = spaces[0]
    else:
        common = [s for s in model_spaces if s in spaces]
        if not common:
            raise FigureInputError(f"{tab.path}: rows for data spaces {', '.join(spaces)}; none is the models' "
                                   f"({', '.join(model_spaces)})")
        space = common[0]
        warn(f"{tab.path}: several data spaces ({', '.join(spaces)}); drawing {space}")
    pca_k = tab.ks(space, "pca")
    gp_q = tab.ks(space, "gplvm")
    sort_k = 20 if 20 in pca_k else (min(pca_k, key=lambda k: (abs(k - 20), k)) if pca_k else None)
    if sort_k is not None and sort_k != 20:
        warn(f"no PCA-20 rows; materials sorted by PCA-{sort_k}")
    mats = sorted({m for (s, _, _), per in tab.values.items() if s == space for m in per})
    if sort_k is not None:
        key_vals = tab.values[(space, "pca", sort_k)]
        mats.sort(key=lambda m: (0, key_vals[m], m) if m in key_vals else (1, 0.0, m))
    xs = np.arange(len(mats), dtype=np.float64)
    with style():
        fig = new_figure(10.0, 4.8)
        ax = fig.subplots()
        for i, k in enumerate(pca_k):
            per = tab.values[(space, "pca", k)]
            v = np.array([per.get(m, np.nan) for m in mats])
            ok = np.isfinite(v) & (v > 0)
            ax.plot(xs[ok], v[ok], color=COLOURS[i % len(COLOURS)], marker="o", markersize=2.6,
                    linewidth=1.0, label=f"PCA, {k} components")
        exact_any = False
        gp_markers = ("v", "^", "D", "s", "P", "X")
        for j, q in enumerate(gp_q):
            per = tab.values[(space, "gplvm", q)]
            v = np.array([per.get(m, np.nan) for m in mats])
            ok = np.isfinite(v)
            exact = ok & (v <= REPRODUCTION_FLOOR)
            exact_any |= bool(exact.any())
            drawn = np.where(exact, REPRODUCTION_FLOOR, v)
            ax.plot(xs[ok], drawn[ok], linestyle="none", marker=gp_markers[j % len(gp_markers)],
                    markersize=3.4 + 1.2 * j, color="#111111" if j == 0 else "#555555",
                    markerfacecolor="#111111" if j == 0 else "none", markeredgewidth=0.7,
                    label=f"GPLVM, q = {q} (max {np.nanmax(v):.2g})")
        if exact_any:
            ax.axhline(REPRODUCTION_FLOOR, color="#999999", linewidth=0.7, linestyle=":")
            ax.annotate("exact (≤1e-16)", xy=(0.995, REPRODUCTION_FLOOR), xycoords=("axes fraction", "data"),
                        xytext=(0.0, 7.0), textcoords="offset points", ha="right", va="bottom", fontsize=7.0,
                        color="#333333")
        for q_model in sorted(inp.models):
            if q_model not in gp_q:
                warn(f"{tab.path}: no gplvm rows for q = {q_model}")
        if not ax.get_lines():
            no_data(ax, f"no rows for data space {space}")
        else:
            ax.set_yscale("log")
            lo = min([REPRODUCTION_FLOOR] + [float(np.nanmin(line.get_ydata())) for line in ax.get_lines()
                                             if len(line.get_ydata())])
            ax.set_ylim(bottom=lo / 8.0)
            ax.set_xlim(-1.0, max(len(mats), 1))
            ax.set_xlabel("materials (sorted)" + (f" by PCA-{sort_k} error" if sort_k is not None else ""))
            ax.set_ylabel("relative error ‖ẑ − z‖ / ‖z‖")
            ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), borderaxespad=0.0)
        ax.set_title(f"reproduction of the {len(mats)} training materials ({space} space)")
        title = f"Reproducing the training materials: PCA vs GPLVM ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 Fig. 8 analogue; PCA truncated to k components vs the GPLVM interpolant at "
                    "each material's latent point (exact in exact arithmetic: b(x_i) = e_i)")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_eq7_bound(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Eq. 7: actual deviation from the nearest training material vs the bound, along each path."""
    warn = Warnings("manifold-eq7")
    paths = _selected_paths(inp, warn)
    with style():
        nrows, ncols = _grid_shape(len(paths), 3)
        fig = new_figure(3.7 * ncols + 0.3, 3.3 * nrows + 0.9)
        axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
        for ax, lp in zip(axes, paths):
            dv, bd, t = lp.deviation, lp.bound, lp.t
            # Omitted: points with a zero bound (x* on a training point: the ends) whose deviation is
            # zero or rounding noise (≤ 1e-9 of the path's largest); a real deviation there stays.
            noise = 1e-9 * float(dv.max())
            keep = ~((bd == 0) & (dv <= noise))
            okd, okb = keep & (dv > 0), keep & (bd > 0)
            ax.plot(t[okd], dv[okd], color=COLOURS[0], marker="o", markersize=2.8, linewidth=1.2,
                    label="deviation ‖z* − z_nearest‖")
            ax.plot(t[okb], bd[okb], color=COLOURS[3], linestyle="--", marker="s", markersize=2.4,
                    linewidth=1.2, label="eq. 7 bound")
            over = keep & (dv > bd * (1.0 + 1e-9)) & (dv > noise)
            if over.any():
                ax.plot(t[over], dv[over], linestyle="none", marker="x", markersize=6.0, markeredgewidth=1.2,
                        color="black", label="deviation above the bound")
                warn(f"path {lp.name!r}: the deviation exceeds the eq. 7 bound at {int(over.sum())} point(s)")
            ax.set_title(lp.title, fontsize=8.0)
            ax.set_xlim(0.0, 1.0)
            ax.set_xlabel("t (fraction of the path A → B)")
            ax.set_ylabel("distance in data space")
            if okd.any() or okb.any():
                ax.set_yscale("log")
                ax.legend(loc="best", fontsize=6.5)
            else:
                warn(f"path {lp.name!r}: deviation and bound are zero at every point")
                no_data(ax, "deviation and bound are 0")
                ax.set_title(lp.title, fontsize=8.0)
        _hide_unused_path_panels(axes, len(paths))
        title = f"Deviation from the nearest training material vs the eq. 7 bound ({databases.title(inp.database)}, {_fit_note(inp)})"
        subtitle = ("Soler 2018 eq. 7: ‖z* − z_j‖ ≤ e^(−1/2)·√(2N)/ℓ·κ(K)·‖Z‖·‖x* − x_j‖, j the nearest "
                    "training point in latent space; the path ends (bound 0, deviation 0 up to rounding) omitted; "
                    f"{_space_note(p.space for p in paths)}")
        return finish(fig, stem, title, subtitle, inp.database, warn)


def manifold_fig06_lengthscale(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """Soler Fig. 6: eq. 7 as ℓ shrinks, from ``lengthscales.csv`` (:func:`draw_lengthscale_figure`)."""
    if inp.lengthscales is None:
        raise FigureInputError("the 'fig06' figure needs lengthscales_csv")
    return draw_lengthscale_figure(inp.lengthscales, stem, inp.database)


def manifold_spaces(inp: ManifoldInputs, stem: str | os.PathLike[str]) -> FigureOutput:
    """The data spaces compared: albedo outside [0, 1], stability near the training points, κ(K) and Σ|w|."""
    if inp.spaces is None:
        raise FigureInputError("the 'spaces' figure needs spaces_csv and stability_csv")
    table = inp.spaces
    warn = Warnings("manifold-spaces")
    cands = table.candidates
    dims = table.dims
    with style():
        fig = new_figure(12.0, 8.6)
        (ax_a, ax_s), (ax_k, ax_w) = fig.subplots(2, 2)
        x = np.arange(len(cands))
        width = 0.8 / max(1, len(dims))
        for j, q in enumerate(dims):
            colour = COLOURS[j % len(COLOURS)]
            off = (j - (len(dims) - 1) / 2) * width
            hull = [100 * table.rows.get((c, q), {}).get("albedo_clamped_bad_hull", np.nan) for c in cands]
            ax_a.bar(x + off, hull, width * 0.9, color=colour, label=f"q = {q}: inside the hull")
            unclamped = [100 * table.rows.get((c, q), {}).get("albedo_bad_hull", np.nan) for c in cands]
            ax_a.plot(x + off, unclamped, "x", color="#222222", markersize=4,
                      label="unclamped table (Σ wᵢ Aᵢ: negative lobes)" if j == 0 else None)
            if q == 2:
                mp = [100 * table.rows.get((c, q), {}).get("albedo_clamped_bad_map", np.nan) for c in cands]
                ax_a.plot(x + off, mp, "v", color="#222222", markersize=5, label="q = 2: plotted map (box 15 % past the data)")
            kap = [table.rows.get((c, q), {}).get("kappa", np.nan) for c in cands]
            ax_k.bar(x + off, kap, width * 0.9, color=colour, label=f"q = {q}")
            ws = [table.rows.get((c, q), {}).get("sum_abs_w_path_max", np.nan) for c in cands]
            wh = [table.rows.get((c, q), {}).get("sum_abs_w_hull_median", np.nan) for c in cands]
            ax_w.bar(x + off, ws, width * 0.9, color=colour, label=f"q = {q}: max along the paths")
            ax_w.plot(x + off, wh, "o", color="#222222", markersize=4, label="median over the hull" if j == 0 else None)
        ax_a.axhline(1.0, color="#aa0000", linestyle=":", linewidth=1.0, label="target: ≤ 1 %")
        ax_a.set_ylabel("albedo outside [0, 1] (% of points)")
        ax_a.set_title("(a) physically implausible albedo")
        ax_k.set_yscale("log")
        ax_k.set_ylabel("κ(K) (2-norm)")
        ax_k.set_title("(c) condition number of K")
        ax_w.set_yscale("log")
        ax_w.axhline(1.0, color="#777777", linestyle=":", linewidth=1.0)
        ax_w.set_ylabel("Σ|wᵢ| (1 = convex blend)")
        ax_w.set_title("(d) cancelling blend weights")
        for ax in (ax_a, ax_k, ax_w):
            ax.set_xticks(x)
            ax.set_xticklabels([c + (" (default)" if c == table.default else "") for c in cands], rotation=30,
                               ha="right", fontsize=7)
            ax.legend(fontsize=6.5)
        qs = max(dims)
        for i, c in enumerate(cands):
            colour = COLOURS[i % len(COLOURS)]
            for norm, linestyle in (("space", "-"), ("raw", ":")):
                v = table.stability.get((c, qs, norm))
                if v is None:
                    continue
                eps, med, _ = v
                ok = med > 0
                ax_s.plot(eps[ok], med[ok], linestyle, color=colour, marker="o", markersize=2.5, linewidth=1.4 if c == table.default else 0.9,
                          label=f"{c}" if norm == "space" else None)
        ax_s.axhline(0.01, color="#aa0000", linestyle=":", linewidth=1.0)
        ax_s.set_xscale("log")
        ax_s.set_yscale("log")
        ax_s.set_xlabel("offset ε from the training point (ℓ)")
        ax_s.set_ylabel("median ‖z(xᵢ+εu) − zᵢ‖ / ‖zᵢ‖")
        ax_s.set_title(f"(b) stability near the training points, q = {qs}\nsolid: the fit's own space; dotted: raw BRDF units; red: 1 %")
        ax_s.legend(fontsize=6.5)
        title = f"GPLVM data spaces compared ({databases.title(table.database)})"
        subtitle = (f"candidates: data space and kernel noise μ (and how fitted, when not the standard fit); default: "
                    f"{table.default}. (a) albedo outside [0, 1] of the interpolated table as rendered (negative "
                    "values clamped to 0; ×: before clamping); (b) change of the interpolated "
                    "material a distance ε from a training point; (c) κ(K); (d) Σ|w|")
        return finish(fig, stem, title, subtitle, table.database, warn)


def make_manifold_figures(*, models: Mapping[int, str | os.PathLike[str]],
                          traces: Mapping[int, str | os.PathLike[str]], albedo_csv: str | os.PathLike[str],
                          albedo_maps: Mapping[int, str | os.PathLike[str]], paths_csv: str | os.PathLike[str],
                          reproduction_csv: str | os.PathLike[str],
                          figures: Mapping[str, Sequence[str | os.PathLike[str]]],
                          database: str | None = None,
                          spaces_csv: str | os.PathLike[str] | None = None,
                          stability_csv: str | os.PathLike[str] | None = None,
                          lengthscales_csv: str | os.PathLike[str] | None = None) -> list[Path]:
    """Write the requested Soler 2018 figure analogues (keys of the rule's records in :mod:`brdfpipe.registry.figures`).

    ``models``, ``traces``, ``albedo_maps``: q → path.  ``figures``: key →
    its PNG and PDF paths, as the workflow declares them; only these are
    drawn.  Every input is read and checked first
    (:func:`~brdfpipe.manifold.figure_inputs.read_manifold_inputs`): a missing or malformed file raises
    :class:`FigureInputError` naming it and nothing is written.  Returns the
    files written (PNG then PDF of each figure, in key order).

    ==============================  ===========================================
    ``fig05`` likelihood             L vs step per q, L-BFGS switch marked;
                                     gap to the best L on a log axis
    ``fig10_q2`` latent q = 2        q = 2 latent points, named, albedo colours
    ``fig10_q5`` latent q = 5        q = 5 projections on dims (0,1)…(3,4)
    ``fig07`` albedo                 luminance albedo maps with iso-lines
    ``fig09`` paths                  perceptual distance to A / B along paths
    ``fig08`` reproduction           per-material reproduction error, PCA vs GPLVM
    ``eq7`` bound                    deviation vs eq. 7 bound along paths
    ``fig06`` length scale           eq. 7 as ℓ shrinks (``lengthscales_csv``),
                                     PNG, PDF and its note
    ``spaces`` data spaces           the candidates of ``compare_spaces``
                                     (``spaces_csv``, ``stability_csv``)
    ==============================  ===========================================
    """
    stems = figure_stems("manifold", "plot_manifold_figures", figures, "make_manifold_figures")
    if "spaces" in stems and (spaces_csv is None or stability_csv is None):
        raise FigureInputError("the 'spaces' figure needs spaces_csv and stability_csv")
    if "fig06" in stems and lengthscales_csv is None:
        raise FigureInputError("the 'fig06' figure needs lengthscales_csv")
    inp = read_manifold_inputs(models=models, traces=traces, albedo_csv=albedo_csv, albedo_maps=albedo_maps,
                               paths_csv=paths_csv, reproduction_csv=reproduction_csv, database=database,
                               spaces_csv=spaces_csv, stability_csv=stability_csv, lengthscales_csv=lengthscales_csv)
    results = draw_figures(sys.modules[__name__], "manifold", "plot_manifold_figures", stems, inp)
    return [p for r in results for p in r.files]


# ---------------------------------------------------------------------------
# Materials outside the training set (config unseen)
# ---------------------------------------------------------------------------

_UNSEEN_COLOURS = ("#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b")

def manifold_unseen(model_path: str | os.PathLike[str], q: int, unseen_csv: str | os.PathLike[str],
                    files: Sequence[str | os.PathLike[str]]) -> FigureOutput:
    """The unseen materials on the latent map of the q model, and their reproduction by the GPLVM and PCA.

    Left: the training materials' latent points (grey) and each unseen
    material's x* by the GP likelihood (filled, named) and by least squares
    (open), joined, coloured by database (q = 2: the plane; q > 2: dims 0, 1;
    q = 1: dim 0 against the material index).  Right: relative reproduction
    error of each unseen material by b(x*) (both ways, each q) and by the
    projection on k principal components of the same training materials.
    """
    stem = figure_stem(files)
    model = read_model(model_path, q)
    table = read_unseen(unseen_csv)
    warn = Warnings("manifold-unseen")
    X = np.asarray(model.X, dtype=np.float64)
    if q < 2:
        warn(f"the q = {q} model has one latent dimension: drawn against the material index")
    dbs = table.databases()
    colours = {db: _UNSEEN_COLOURS[i % len(_UNSEEN_COLOURS)] for i, db in enumerate(dbs)}

    def plane(x: Sequence[float], index: float) -> tuple[float, float]:
        return (x[0], x[1]) if q >= 2 else (x[0], index)

    with style():
        fig = new_figure(13.0, 6.2)
        left, right = fig.subplots(1, 2, width_ratios=[1.25, 1.0])
        P = np.array([plane(x, i) for i, x in enumerate(X)])
        left.scatter(P[:, 0], P[:, 1], s=10, color="#b0b0b0", label=f"training materials ({table.model_database})",
                     zorder=1)
        drawn = 0
        for db in dbs:
            mats = sorted({k[1] for k in table.latent if k[0] == db and k[3] == q})
            for j, mat in enumerate(mats):
                gp = table.latent.get((db, mat, "gplvm-likelihood", q))
                ls = table.latent.get((db, mat, "gplvm-least-squares", q))
                idx = len(X) + j
                if gp is not None and ls is not None:
                    a, b = plane(gp, idx), plane(ls, idx)
                    left.plot([a[0], b[0]], [a[1], b[1]], color=colours[db], lw=0.6, alpha=0.6, zorder=2)
                if ls is not None:
                    b = plane(ls, idx)
                    left.scatter([b[0]], [b[1]], s=22, facecolors="none", edgecolors=colours[db], zorder=3)
                if gp is not None:
                    a = plane(gp, idx)
                    left.scatter([a[0]], [a[1]], s=22, color=colours[db], zorder=4)
                    left.annotate(mat, a, fontsize=LATENT_LABEL_SIZE, color=colours[db], xytext=(3, 2),
                                  textcoords="offset points")
                    drawn += 1
            left.scatter([], [], s=22, color=colours[db], label=f"{db}: x* by likelihood (named)")
            left.scatter([], [], s=22, facecolors="none", edgecolors=colours[db], label=f"{db}: x* by least squares")
        if not drawn:
            warn(f"no unseen latent position for q = {q}")
        left.set_xlabel("latent dim 0")
        left.set_ylabel("latent dim 1" if q >= 2 else "material index")
        left.set_title(f"latent map, q = {q}, {len(X)} training materials")
        left.legend(loc="best", fontsize=6)
        methods = sorted({(k[2], k[3]) for k in table.errors},
                         key=lambda mk: (mk[0] != "pca", mk[1], mk[0]))
        labels = [("PCA" if m == "pca" else "GPLVM, " + m.removeprefix("gplvm-")) + f", k = {k}" for m, k in methods]
        allv: list[float] = []
        for xi, (m, k) in enumerate(methods):
            for off, db in enumerate(dbs):
                vals = [v for key, v in sorted(table.errors.items()) if key[0] == db and key[2] == m and key[3] == k]
                if not vals:
                    continue
                xs = xi + (off - (len(dbs) - 1) / 2) * 0.18 + np.zeros(len(vals))
                right.scatter(xs, vals, s=10, color=colours[db], alpha=0.7, label=db if xi == 0 else None)
                right.plot([xi - 0.3, xi + 0.3], [float(np.median(vals))] * 2, color=colours[db], lw=1.5)
                allv += vals
        right.set_xticks(np.arange(len(methods)), labels, rotation=35, ha="right", fontsize=7)
        right.set_ylabel(f"relative reproduction error ({table.space} space)")
        right.set_title("reproduction of each unseen material (bar: median)")
        if allv and min(allv) > 0 and max(allv) / min(allv) > 8:
            right.set_yscale("log")
        if allv:
            right.legend(loc="best", fontsize=7)
        else:
            no_data(right, "no reproduction rows")
        title = (f"Materials outside the training set on the GPLVM manifold "
                 f"(model: {databases.title(table.model_database)})")
        subtitle = (f"Soler 2018 Fig. 10 / Fig. 8 analogue for unseen materials ({'; '.join(databases.title(d) for d in dbs)}); "
                    "x* maximises the "
                    f"GP likelihood of the material or minimises ‖z − Σ bᵢ(x) zᵢ‖ in the {table.space} space")
        return finish(fig, stem, title, subtitle, table.model_database, warn)
