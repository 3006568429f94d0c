"""Soler et al. 2018 Fig. 6: the bound of eq. 7 on the interpolant as the length scale ℓ shrinks.

Drawn from ``lengthscales.csv`` (:mod:`brdfpipe.manifold.lengthscale`): one
latent path, the default candidate's latent points, the kernel's ℓ scaled.
Three panels: the distance ‖z* − z̄‖ of the interpolant from the mean of
the materials along the path for each ℓ (as ℓ → 0 it is the mean "everywhere
in the domain except very close to the xᵢ"); the deviation ‖z* − z_j‖ from
the nearest material against its eq. 7 bound along the path at the smallest,
the fitted and the largest ℓ; and both at their largest over the path, with
κ(K), against ℓ.  All distances are divided by ‖Z‖ = √tr G_c.  The figure's
note gives the numbers its report caption quotes.  Called by
:func:`brdfpipe.manifold.figures.make_manifold_figures`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from brdfpipe.core.plot import (
    FigureInputError,
    FigureOutput,
    Warnings,
    finish,
    new_figure,
    parse_float,
    read_csv,
    single_database,
    style,
)
from brdfpipe.data import databases
from brdfpipe.registry import tables

__all__ = ["LengthscaleTable", "read_lengthscales", "draw_lengthscale_figure"]


@dataclass(frozen=True)
class LengthscaleTable:
    """``lengthscales.csv``: per factor of ℓ (ascending) the values along t; distances divided by ‖Z‖."""

    path: Path
    database: str
    space: str
    q: int
    material_a: str
    material_b: str
    factors: NDArray[np.float64]
    kappa: NDArray[np.float64]  #: (F,)
    t: NDArray[np.float64]  #: (T,)
    deviation: NDArray[np.float64]  #: (F, T)
    bound: NDArray[np.float64]  #: (F, T)
    from_mean: NDArray[np.float64]  #: (F, T)


def read_lengthscales(path: str | os.PathLike[str]) -> LengthscaleTable:
    """Read and check ``lengthscales.csv`` (its digest, columns, one path, a full grid of ℓ × t)."""
    p, rows = read_csv(path, tables.LENGTHSCALES)
    database = single_database(p, (r["database"] for r in rows))
    for key in ("path", "space", "q"):
        if len({r[key] for r in rows}) != 1:
            raise FigureInputError(f"{p}: rows of more than one {key}")

    def num(r: dict[str, str], c: str) -> float:
        return parse_float(p, int(r["__line__"]), c, r[c])

    factors = sorted({num(r, "ell_factor") for r in rows})
    ts = sorted({num(r, "t") for r in rows})
    grid = {(num(r, "ell_factor"), num(r, "t")): r for r in rows}
    if len(grid) != len(rows) or len(grid) != len(factors) * len(ts):
        raise FigureInputError(f"{p}: expected one row per length scale and t ({len(factors)} × {len(ts)}), "
                               f"got {len(rows)}")
    z = num(rows[0], "z_norm")
    if not z > 0:
        raise FigureInputError(f"{p}: z_norm must be positive, got {z}")

    def field(c: str, scale: float = 1.0) -> NDArray[np.float64]:
        return np.array([[num(grid[(f, t)], c) / scale for t in ts] for f in factors])

    first = rows[0]
    return LengthscaleTable(p, database, first["space"], int(num(first, "q")), first["material_a"],
                            first["material_b"], np.array(factors), field("kappa")[:, 0], np.array(ts),
                            field("deviation", z), field("bound", z), field("from_mean", z))


def _note(tab: LengthscaleTable) -> str:
    """The figure's note: the numbers at the fitted, the smallest and the largest ℓ."""
    fit = int(np.argmin(np.abs(np.log(tab.factors))))
    mid = int(np.argmin(np.abs(tab.t - 0.5)))
    inner = (tab.t > 0) & (tab.t < 1)
    ok = tab.bound > 0
    worst = float(np.max(tab.deviation[ok] / tab.bound[ok])) if ok.any() else float("nan")

    def at(i: int) -> str:
        return (f"ℓ = {tab.factors[i]:g} ℓ_fit: κ(K) = {tab.kappa[i]:.3g}, largest deviation "
                f"{tab.deviation[i, inner].max():.3g} and bound {tab.bound[i, inner].max():.3g}, midpoint "
                f"‖z* − z̄‖ = {tab.from_mean[i, mid]:.3g}")

    return (f"Along {tab.material_a} → {tab.material_b} (q = {tab.q}, {tab.space} space; distances / ‖Z‖): "
            f"{at(0)}; {at(fit)}; {at(len(tab.factors) - 1)}. The deviation stays "
            + ("below" if worst <= 1.0 else "ABOVE") + f" the eq. 7 bound at every ℓ and point (largest ratio "
            f"{worst:.3g}).")


def draw_lengthscale_figure(table: LengthscaleTable | str | os.PathLike[str], stem: str | os.PathLike[str],
                               database: str | None = None) -> FigureOutput:
    """Soler Fig. 6 from ``lengthscales.csv`` or its table (see the module docstring); PNG, PDF and its note."""
    tab = table if isinstance(table, LengthscaleTable) else read_lengthscales(table)
    if database is not None and database.strip() and database.strip() != tab.database:
        raise FigureInputError(f"{tab.path}: database {tab.database!r}, but the figures are for {database!r}")
    warn = Warnings("manifold-fig06")
    with style():
        return _draw(tab, stem, warn)


def _draw(tab: LengthscaleTable, stem: str | os.PathLike[str], warn: Warnings) -> FigureOutput:
    """The three panels of :func:`draw_lengthscale_figure`, titled and saved with the note."""
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    shades = [cmap(k / max(1, len(tab.factors) - 1)) for k in range(len(tab.factors))]
    fit = int(np.argmin(np.abs(np.log(tab.factors))))
    inner = (tab.t > 0) & (tab.t < 1)
    fig = new_figure(11.0, 4.4)
    ax_m, ax_b, ax_l = fig.subplots(1, 3)
    for k, f in enumerate(tab.factors):
        ax_m.plot(tab.t, tab.from_mean[k], color=shades[k], lw=1.8 if k == fit else 1.0,
                  label=f"ℓ = {f:g} ℓ_fit" + (" (fitted)" if k == fit else ""))
    ax_m.set(xlabel="t along the path", ylabel="‖z* − z̄‖ / ‖Z‖",
             title="distance from the mean of the materials")
    ax_m.legend(fontsize=5.5, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3)
    for k in sorted({0, fit, len(tab.factors) - 1}):
        ax_b.plot(tab.t[inner], tab.deviation[k, inner], color=shades[k], lw=1.4,
                  label=f"deviation, {tab.factors[k]:g} ℓ_fit")
        ax_b.plot(tab.t[inner], tab.bound[k, inner], color=shades[k], lw=1.0, ls="--",
                  label=f"eq. 7 bound, {tab.factors[k]:g} ℓ_fit")
    ax_b.set_yscale("log")
    ax_b.set(xlabel="t along the path", ylabel="‖z* − z_j‖ / ‖Z‖",
             title="deviation from the nearest material")
    ax_b.legend(fontsize=5.5)
    dev = tab.deviation[:, inner].max(axis=1)
    bnd = tab.bound[:, inner].max(axis=1)
    ax_l.plot(tab.factors, bnd, "s--", color="#d62728", ms=3.5, label="eq. 7 bound (largest on the path)")
    ax_l.plot(tab.factors, dev, "o-", color="#1f77b4", ms=3.5, label="deviation (largest on the path)")
    ax_l.plot(tab.factors, tab.from_mean[:, int(np.argmin(np.abs(tab.t - 0.5)))], "^:", color="#2ca02c", ms=3.5,
              label="‖z* − z̄‖ at the midpoint")
    ax_l.set_xscale("log", base=2)
    ax_l.set_yscale("log")
    ax_l.axvline(1.0, color="0.6", lw=0.8, ls=":")
    ax_l.set(xlabel="ℓ / ℓ_fit", ylabel="distance / ‖Z‖", title="as the length scale shrinks")
    twin = ax_l.twinx()
    twin.plot(tab.factors, tab.kappa, "x-", color="0.45", lw=0.8, ms=3.5, label="κ(K) (right axis)")
    twin.set_yscale("log")
    twin.set_ylabel("κ(K)")
    twin.grid(False)
    lines = ax_l.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    ax_l.legend(lines[0] + more[0], lines[1] + more[1], fontsize=5.5, loc="upper center")
    if np.any(tab.deviation[:, inner] > tab.bound[:, inner] * (1 + 1e-9)):
        warn("the deviation exceeds the eq. 7 bound somewhere")
    title = f"The interpolant and the eq. 7 bound as the length scale shrinks ({databases.title(tab.database)})"
    subtitle = (f"Soler 2018 Fig. 6; {tab.material_a} → {tab.material_b}, the default candidate's q = {tab.q} "
                "latent points "
                f"({tab.space} space), kernel ℓ scaled by {tab.factors.min():g}–{tab.factors.max():g}; "
                "eq. 7: ‖z* − z_j‖ ≤ e^(−1/2)·√(2N)/ℓ·κ(K)·‖Z‖·‖x* − x_j‖")
    return finish(fig, stem, title, subtitle, tab.database, warn, note=_note(tab))
