"""Latent maps of the manifold figures: zoomed views of crowded clusters and the points' names without overlap.

Soler Fig. 10 (:func:`brdfpipe.manifold.figures.manifold_fig10_latent_q2`
and ``…_q5``) shows every material of the latent space by name.  A map's
views (:func:`zoom_chain`): the whole, then nested zooms on its most crowded
cluster; each row of views is drawn by :func:`latent_row` and, once the
figure's layout is final (:func:`set_title` first), named by
:func:`label_rows`: each point once, in the deepest view that shows it, on
the side where its label overlaps least, or in a column of call-outs.
Deterministic.
"""

from __future__ import annotations

import logging
import math
import textwrap
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import Rectangle

from brdfpipe.core.plot import RC_PARAMS

__all__ = ["set_title", "zoom_chain", "latent_row", "label_rows"]


def set_title(fig: Figure, title: str, subtitle: str) -> None:
    """The suptitle exactly as :func:`brdfpipe.core.plot.finish` writes it (so layout-dependent steps can run before saving)."""
    chars = max(30, int(float(fig.get_size_inches()[0]) * 72.0 / (0.6 * 10.5)))
    lines = textwrap.wrap(title, chars) + (textwrap.wrap(subtitle, chars) if subtitle else [])
    fig.suptitle("\n".join(lines))


# label directions (x, y) around a point and distances (points), in order of preference
_LABEL_DIRS = ((1, 0), (1, 1), (1, -1), (-1, 0), (-1, 1), (-1, -1), (0, 1), (0, -1))
_LABEL_RADII = (3.2, 7.0, 12.0, 18.0)


def _overlap(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Total overlap area of each of ``boxes`` (C × 4: x0, y0, x1, y1) with all of ``others`` (M × 4)."""
    if others.size == 0:
        return np.zeros(len(boxes))
    ox = np.minimum(boxes[:, None, 2], others[None, :, 2]) - np.maximum(boxes[:, None, 0], others[None, :, 0])
    oy = np.minimum(boxes[:, None, 3], others[None, :, 3]) - np.maximum(boxes[:, None, 1], others[None, :, 1])
    return (np.clip(ox, 0.0, None) * np.clip(oy, 0.0, None)).sum(axis=1)


def _label_panel(ax: Any, renderer: Any, x: np.ndarray, y: np.ndarray, names: Sequence[str], label: np.ndarray,
                 visible: np.ndarray, *, fontsize: float, marker_radius: float, colour: str = "#1a1a1a") -> None:
    """Name the points ``label`` (mask) of a panel, each on the side that overlaps least.

    Greedy and deterministic: crowded points first; each label goes to the
    candidate position (8 directions × 4 distances) of least cost: its
    overlap with the labels already placed, the ``visible`` markers and the
    area outside the axes.  A label that would still overlap the accepted
    ones by more than 8 % of its area goes instead to a column of
    call-outs at the emptier side of the panel, with a leader line.  The
    layout must be final (run after the title is set and a layout pass);
    labels are left out of the layout so saving does not move the axes.
    """
    px = ax.figure.dpi / 72.0
    P = ax.transData.transform(np.column_stack([x, y]))
    prop = FontProperties(family=RC_PARAMS["font.family"], size=fontsize)
    ab = ax.get_window_extent(renderer)
    rm = marker_radius * px
    markers = np.column_stack([P - rm, P + rm])
    cands = []
    for r in _LABEL_RADII:
        for cx, cy in _LABEL_DIRS:
            n = math.hypot(cx, cy)
            cands.append((r, cx, cy, r * px * cx / n, r * px * cy / n))
    c_off = np.array([[c[3], c[4]] for c in cands])
    c_dir = np.array([[c[1], c[2]] for c in cands], dtype=np.float64)
    pref = np.arange(len(cands), dtype=np.float64)
    vis = np.flatnonzero(visible)
    d2 = ((P[:, None, :] - P[None, vis, :]) ** 2).sum(-1)
    crowd = (d2 < (30.0 * px) ** 2).sum(1)
    order = sorted(np.flatnonzero(label).tolist(), key=lambda i: (-int(crowd[i]), i))
    sizes = {i: renderer.get_text_width_height_descent(names[i], prop, ismath=False)[:2] for i in order}
    placed = np.zeros((0, 4))
    accepted = np.zeros((0, 4))
    chosen: list[tuple[int, int]] = []
    failed: list[int] = []
    for i in order:
        w, h = sizes[i]
        anchor = P[i] + c_off
        x0 = np.where(c_dir[:, 0] > 0, anchor[:, 0], np.where(c_dir[:, 0] < 0, anchor[:, 0] - w, anchor[:, 0] - w / 2))
        y0 = np.where(c_dir[:, 1] > 0, anchor[:, 1], np.where(c_dir[:, 1] < 0, anchor[:, 1] - h, anchor[:, 1] - h / 2))
        boxes = np.column_stack([x0, y0, x0 + w, y0 + h])
        inside_w = np.clip(np.minimum(boxes[:, 2], ab.x1) - np.maximum(boxes[:, 0], ab.x0), 0.0, None)
        inside_h = np.clip(np.minimum(boxes[:, 3], ab.y1) - np.maximum(boxes[:, 1], ab.y0), 0.0, None)
        outside = w * h - inside_w * inside_h
        others = markers[vis[vis != i]]
        cost = (_overlap(boxes, placed) + 0.6 * _overlap(boxes, others) + 2.0 * outside
                + 1e-3 * w * h * pref)
        k = int(np.argmin(cost))
        placed = np.vstack([placed, boxes[k]])
        if _overlap(boxes[k : k + 1], accepted)[0] > 0.08 * w * h:
            failed.append(i)
            continue
        accepted = np.vstack([accepted, boxes[k]])
        chosen.append((i, k))
    for i, k in sorted(chosen):
        r, cx, cy, _, _ = cands[k]
        n = math.hypot(cx, cy)
        ann = ax.annotate(
            names[i], xy=(float(x[i]), float(y[i])), xytext=(r * cx / n, r * cy / n), textcoords="offset points",
            ha="left" if cx > 0 else "right" if cx < 0 else "center",
            va="bottom" if cy > 0 else "top" if cy < 0 else "center",
            fontsize=fontsize, color=colour, parse_math=False, annotation_clip=False, zorder=5,
            arrowprops=(dict(arrowstyle="-", linewidth=0.3, color="#777777", shrinkA=0.0, shrinkB=marker_radius)
                        if r > _LABEL_RADII[0] else None),
        )
        ann.set_in_layout(False)
    if not failed:
        return
    # Call-outs: columns at the side of the panel farther from these points, ordered by height.
    failed.sort(key=lambda i: (-P[i, 1], i))
    mean_x = float(np.mean(P[failed, 0]))
    right = (ab.x1 - mean_x) >= (mean_x - ab.x0)
    lh = 1.25 * max(sizes[i][1] for i in failed)
    cap = max(1, int((ab.height - 4.0 * px) // lh))
    cols = [failed[c : c + cap] for c in range(0, len(failed), cap)]
    inv = ax.transData.inverted()
    for c, col in enumerate(cols):
        cw = max(sizes[i][0] for i in col) + 3.0 * px
        tx = ab.x1 - 2.0 * px - (c + 1) * cw if right else ab.x0 + 2.0 * px + c * cw
        centre = float(np.mean(P[col, 1]))
        top = min(ab.y1 - 2.0 * px - lh / 2, max(ab.y0 + 2.0 * px + lh / 2 + (len(col) - 1) * lh,
                                                 centre + (len(col) - 1) * lh / 2))
        for j, i in enumerate(col):
            tdata = inv.transform((tx, top - j * lh))
            ann = ax.annotate(
                names[i], xy=(float(x[i]), float(y[i])), xytext=(float(tdata[0]), float(tdata[1])),
                textcoords="data", ha="left", va="center", fontsize=fontsize, color=colour, parse_math=False,
                annotation_clip=False, zorder=5,
                arrowprops=dict(arrowstyle="-", linewidth=0.3, color="#8a8a8a", shrinkA=0.5, shrinkB=marker_radius),
            )
            ann.set_in_layout(False)


#: Crowding on the latent maps: a point with at least _CROWD_K other points within _CROWD_R inches (at the
#: panel's scale) is crowded; the largest cluster of crowded points gets a zoomed panel (nested, at most _MAX_ZOOMS).
_CROWD_R = 0.2
_CROWD_K = 3
_MAX_ZOOMS = 3

_Box = tuple[float, float, float, float]  # x0, x1, y0, y1


def _bbox(P: np.ndarray, pad: float, min_span: float = 0.0) -> _Box:
    lo, hi = P.min(axis=0), P.max(axis=0)
    span = np.maximum(hi - lo, max(min_span, 1e-12 * max(1.0, float(np.abs(P).max()))))
    centre = (lo + hi) / 2.0
    half = span * (0.5 + pad)
    return (float(centre[0] - half[0]), float(centre[0] + half[0]), float(centre[1] - half[1]),
            float(centre[1] + half[1]))


def _inside(P: np.ndarray, box: _Box) -> np.ndarray:
    return (P[:, 0] >= box[0]) & (P[:, 0] <= box[1]) & (P[:, 1] >= box[2]) & (P[:, 1] <= box[3])


def _components(adj: np.ndarray) -> list[list[int]]:
    """Connected components of a boolean adjacency matrix, each sorted, in order of their smallest member."""
    seen = np.zeros(len(adj), dtype=bool)
    comps = []
    for s in range(len(adj)):
        if seen[s]:
            continue
        stack, comp = [s], []
        seen[s] = True
        while stack:
            v = stack.pop()
            comp.append(v)
            for u in np.flatnonzero(adj[v] & ~seen):
                seen[u] = True
                stack.append(int(u))
        comps.append(sorted(comp))
    return comps


def zoom_chain(P: np.ndarray, panel_in: tuple[float, float]) -> list[_Box]:
    """Views of a latent map: the whole (with a margin), then nested zooms on the most crowded cluster.

    At each level the points are scaled as the panel would show them (equal
    aspect, ``panel_in`` inches); if some are crowded (see :data:`_CROWD_R`),
    the next view is the box around the largest connected group of crowded
    points (linked within 2·_CROWD_R), unless it would not zoom in by at
    least 2×.  Deterministic.
    """
    views = [_bbox(P, 0.08)]
    for _ in range(_MAX_ZOOMS):
        view = views[-1]
        idx = np.flatnonzero(_inside(P, view))
        dx, dy = view[1] - view[0], view[3] - view[2]
        scale = min(panel_in[0] / dx, panel_in[1] / dy)  # inches per latent unit
        Q = P[idx] * scale
        d = np.sqrt(((Q[:, None, :] - Q[None, :, :]) ** 2).sum(-1))
        crowded = ((d < _CROWD_R).sum(axis=1) - 1) >= _CROWD_K
        if crowded.sum() <= _CROWD_K:
            break
        ci = np.flatnonzero(crowded)
        comps = _components(d[np.ix_(ci, ci)] < 2.0 * _CROWD_R)
        best = max(comps, key=lambda c: (len(c), -c[0]))
        members = idx[ci[best]]
        box = _bbox(P[members], 0.12, min_span=1e-6 * max(dx, dy))
        if (box[1] - box[0]) > dx / 2.0 and (box[3] - box[2]) > dy / 2.0:
            break
        views.append(box)
    return views


def latent_row(axes: Sequence[Any], P: np.ndarray, colours: np.ndarray, views: Sequence[_Box],
                labels: tuple[str, str], name: str, *, size: float) -> None:
    """Draw the points in each of ``axes`` (one per view), equal aspect, titled."""
    for k, (ax, view) in enumerate(zip(axes, views)):
        ax.scatter(P[:, 0], P[:, 1], s=size, c=colours, edgecolors="#202020", linewidths=0.4, zorder=3)
        ax.set_xlim(view[0], view[1])
        ax.set_ylim(view[2], view[3])
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        if k == 0:
            ax.set_title(f"{name}: all materials" if len(views) > 1 else name)
        else:
            z = (views[0][1] - views[0][0]) / (view[1] - view[0])
            ax.set_title(f"{name}: zoom ×{z:.3g} on the dashed box of the previous panel")


class _DropFixedLimits(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Ignoring fixed")


@contextmanager
def _quiet_fixed_limits() -> Iterator[None]:
    """Silence matplotlib's "Ignoring fixed x limits to fulfill fixed data aspect" during the first layout.

    The latent panels set both limits (the view) and ask for equal aspect
    with adjustable data limits: the first draw widens one of them, as
    intended; the widened limits are then fixed and later draws keep them.
    """
    log = logging.getLogger("matplotlib.axes._base")
    f = _DropFixedLimits()
    log.addFilter(f)
    try:
        yield
    finally:
        log.removeFilter(f)


def label_rows(fig: Figure, rows: Sequence[tuple[Sequence[Any], np.ndarray]], names: Sequence[str], *,
                fontsize: float, marker_radius: float) -> None:
    """After the layout: freeze each panel's limits, outline the next zoom, and name each point once per row.

    A point is named in the deepest view of its row that shows it (the
    whole view names only the points outside its zoom).
    """
    with _quiet_fixed_limits():
        fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    for axes, P in rows:
        lims = []
        for ax in axes:
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            ax.set_xlim(x0, x1)  # the aspect-adjusted limits, fixed
            ax.set_ylim(y0, y1)
            lims.append((x0, x1, y0, y1))
        for k, ax in enumerate(axes):
            visible = _inside(P, lims[k])
            if k + 1 < len(axes):
                nxt = lims[k + 1]
                ax.add_patch(Rectangle((nxt[0], nxt[2]), nxt[1] - nxt[0], nxt[3] - nxt[2], fill=False,
                                                   edgecolor="#555555", linestyle="--", linewidth=0.8, zorder=2))
                tag = ax.annotate("zoom: next panel", xy=(nxt[0], nxt[3]), xytext=(-4.0, 8.0),
                                  textcoords="offset points", ha="right", va="bottom", fontsize=5.5,
                                  color="#444444", zorder=6, annotation_clip=False,
                                  arrowprops=dict(arrowstyle="-", linewidth=0.4, color="#555555", shrinkA=0.0,
                                                  shrinkB=0.0))
                tag.set_in_layout(False)
                label = visible & ~_inside(P, nxt)
            else:
                label = visible
            _label_panel(ax, renderer, P[:, 0], P[:, 1], names, label, visible, fontsize=fontsize,
                         marker_radius=marker_radius)
