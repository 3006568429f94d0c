"""The analytic BRDF models of the synthetic database (:mod:`brdfpipe.data.synth`), evaluated anywhere.

Each of the five families is a reciprocal, (approximately) energy-conserving
model (:func:`evaluate` at any direction pairs; :func:`model_values` at the
MERL cell centres, times the material's smooth deviation, :func:`cell_grid`).  What a material's
parameters are, the plan of a database and its files: :mod:`brdfpipe.data.synth`.

``lobe(α)`` is a microfacet lobe D·G2/(4 cosθi cosθo) with the exact
height-correlated Smith G2 = 1/(1 + Λ(θi) + Λ(θo)) of its distribution; with
a ``ggx`` weight t it is t·GGX(α) + (1 − t)·Beckmann(α) (tail shape between
Beckmann's and GGX's).  ``F_d`` is the exact unpolarised dielectric Fresnel
term, ``T = (1 − F_d(θi))(1 − F_d(θo))`` the transmission through a
dielectric interface both ways (so a diffuse base under it conserves energy).

==================  =========================================================
family / variant    model
==================  =========================================================
metal               conductor Fresnel F(θd; n, k) per channel (exact, as
                    pbrt's ``FrConductor``) × [(1−h)·lobe(α) + h·lobe(α_haze)]
paint / plastic     ks·F_d(θd; η)·[w1·lobe(α1) + w2·lobe(α2)]
                    + T·ρ/π·ON(σ)  (ON: Oren–Nayar factor, below)
metallic-paint      clear coat F_d(θd; η)·lobe(α_coat)
                    + T·[kd·c/π + k1·c·lobe(α1) + k2·c_flake·lobe(α_flake)]
fabric (velvet,     ρ/π·ON(σ) + sheen·D_charlie(θh; r)·V_np + ks·F_d·lobe(α)
felt, satin)        ON(σ) = A + B·max(0, cos Δφ)·sin(max θ)·tan(min θ) (Oren &
                    Nayar 1994, qualitative model: retro-reflection at grazing);
                    D_charlie = (2 + 1/r) sin(θh)^(1/r)/(2π) (Estevez & Kulla
                    2017), V_np = 1/(4(cosθi + cosθo − cosθi cosθo)) (Neubelt &
                    Pettineo 2013); ks > 0 for satin only
phenolic / acrylic  coat F_d(θd; η)·[(1−h)·lobe(α_coat) + h·lobe(α_haze)]
                    + T·ρ·[(1−kb)/π + kb·lobe(α_b)]
==================  =========================================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.data import merl

__all__ = ["DEV_SHARED", "DEV_CHANNEL", "Grid", "cell_grid", "evaluate", "model_values"]

_HALF_PI: Final = 0.5 * math.pi
#: Deviation basis sizes (θh in u = sqrt(θh/(π/2)), θd, φd): shared by the channels, and per channel.
DEV_SHARED: Final = (5, 5, 3)
DEV_CHANNEL: Final = (3, 3, 2)
_DEV_GAIN_LIMIT: Final = 0.25  # positive log deviations are squashed to below this


# --------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class _Geom:
    """Per-pair geometry.

    Functions of θh or θd alone go through :meth:`h` / :meth:`d`.  For
    direction pairs ``cos_h`` and ``cos_d`` are per pair; on the MERL grid
    they hold the 90 bin-centre values and ``ih`` / ``idd`` each cell's bin,
    so such functions are evaluated once per bin and gathered.
    """

    mu_i: NDArray[np.float64]  # cos θi
    mu_o: NDArray[np.float64]  # cos θo
    cos_h: NDArray[np.float64]  # cos θh (n·h)
    cos_d: NDArray[np.float64]  # cos θd (wi·h = wo·h)
    cos_phi: NDArray[np.float64]  # cos(φi − φo)
    ih: NDArray[np.intp] | None = None  # θh bin of each cell (grid only)
    idd: NDArray[np.intp] | None = None  # θd bin of each cell (grid only)

    def h(self, fn):
        if self.ih is None:
            return fn(self.cos_h)
        return fn(self.cos_h)[..., self.ih]

    def d(self, fn):
        if self.idd is None:
            return fn(self.cos_d)
        return fn(self.cos_d)[..., self.idd]


def _direct_geom(wi: NDArray[np.float64], wo: NDArray[np.float64]) -> _Geom:
    """Geometry of direction pairs, computed with formulas symmetric in (wi, wo)."""
    s = wi + wo
    norm = np.sqrt(np.sum(s * s, axis=1))
    cos_h = np.clip(s[:, 2] / norm, -1.0, 1.0)
    cos_d = np.clip(0.5 * norm, 0.0, 1.0)  # wi·h = (1 + wi·wo)/|wi + wo| = |wi + wo|/2
    ri = np.hypot(wi[:, 0], wi[:, 1])
    ro = np.hypot(wo[:, 0], wo[:, 1])
    dot = wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_phi = np.where((ri > 0) & (ro > 0), dot / (ri * ro), 0.0)
    return _Geom(wi[:, 2].copy(), wo[:, 2].copy(), cos_h, cos_d, np.clip(cos_phi, -1.0, 1.0))


@dataclass(frozen=True)
class Grid:
    """The geometry of the measured MERL cell centres and their bins (:func:`cell_grid`)."""

    geom: _Geom
    cells: NDArray[np.intp]  # flat indices of the measured cells
    u: NDArray[np.float64]  # sqrt(θh/(π/2)) at the θh centres, (90,)
    theta_d: NDArray[np.float64]  # (90,)
    phi_d: NDArray[np.float64]  # (180,)
    mask: NDArray[np.bool_]  # (90, 90, 180)


@lru_cache(maxsize=1)
def cell_grid() -> Grid:
    """Geometry of the measured MERL cell centres (cached per process)."""
    # every cell's directions once: the measured mask (merl.measured_mask) and the measured cells' directions
    wi_all, wo_all = merl.cell_directions()
    mask = merl.above_horizon(wi_all, wo_all).reshape(merl.DIMS)
    cells = np.flatnonzero(mask)
    wi, wo = wi_all[cells], wo_all[cells]
    ih, rest = np.divmod(cells, merl.N_THETA_D * merl.N_PHI_D)
    id_ = rest // merl.N_PHI_D
    u = (np.arange(merl.N_THETA_H) + 0.5) / merl.N_THETA_H
    theta_h = u * u * _HALF_PI
    theta_d = (np.arange(merl.N_THETA_D) + 0.5) / merl.N_THETA_D * _HALF_PI
    phi_d = (np.arange(merl.N_PHI_D) + 0.5) / merl.N_PHI_D * math.pi
    d = _direct_geom(wi, wo)
    geom = _Geom(
        d.mu_i, d.mu_o, np.cos(theta_h), np.cos(theta_d), d.cos_phi, ih.astype(np.intp),
        id_.astype(np.intp),
    )
    for a in (geom.mu_i, geom.mu_o, geom.cos_phi, geom.ih, geom.idd, cells):
        a.setflags(write=False)
    return Grid(geom, cells, u, theta_d, phi_d, mask)


# --------------------------------------------------------------------------
# Model building blocks
# --------------------------------------------------------------------------


def _ndf(dist: str, alpha: float, c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normal distribution D(θh), normalised (∫ D cos θh dω = 1): GGX or Beckmann."""
    c2 = c * c
    a2 = alpha * alpha
    if dist == "ggx":
        t = c2 * (a2 - 1.0) + 1.0
        return a2 / (math.pi * t * t)
    if dist == "beckmann":
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            out = np.exp(-(1.0 - c2) / (c2 * a2)) / (math.pi * a2 * c2 * c2)
        return np.where(c > 0.0, out, 0.0)
    raise ValueError(f"unknown microfacet distribution {dist!r}")


def _erfc(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.special.erfc``, imported on first use (the workflow parses without scipy)."""
    from scipy.special import erfc

    return erfc(x)


def _smith_lambda(dist: str, alpha: float, mu: NDArray[np.float64]) -> NDArray[np.float64]:
    tan2 = (1.0 - mu * mu) / (mu * mu)
    if dist == "ggx":
        return 0.5 * (np.sqrt(1.0 + alpha * alpha * tan2) - 1.0)
    if dist == "beckmann":
        with np.errstate(divide="ignore", invalid="ignore"):
            a = 1.0 / (alpha * np.sqrt(tan2))
            lam = 0.5 * (np.exp(-a * a) / (a * math.sqrt(math.pi)) - _erfc(a))
        return np.where(tan2 > 0.0, np.maximum(lam, 0.0), 0.0)
    raise ValueError(f"unknown microfacet distribution {dist!r}")


def _lobe1(g: _Geom, alpha: float, dist: str) -> NDArray[np.float64]:
    d = g.h(lambda c: _ndf(dist, alpha, c))
    lam = _smith_lambda(dist, alpha, g.mu_i) + _smith_lambda(dist, alpha, g.mu_o)
    return d / ((1.0 + lam) * (4.0 * (g.mu_i * g.mu_o)))


def _lobe(g: _Geom, alpha: float, ggx: float = 1.0) -> NDArray[np.float64]:
    """Microfacet lobe D·G2/(4 μi μo) without Fresnel, shape (n,).

    A mixture ``ggx``·GGX(α) + (1 − ``ggx``)·Beckmann(α), each with its exact
    height-correlated Smith G2, so the tail shape varies between Beckmann's
    short and GGX's long tail while each part stays energy-consistent.
    """
    if ggx >= 1.0:
        return _lobe1(g, alpha, "ggx")
    if ggx <= 0.0:
        return _lobe1(g, alpha, "beckmann")
    return ggx * _lobe1(g, alpha, "ggx") + (1.0 - ggx) * _lobe1(g, alpha, "beckmann")


def _fresnel_dielectric(eta: float, c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unpolarised Fresnel reflectance from air into a dielectric of index eta > 1."""
    c = np.clip(c, 0.0, 1.0)
    g = np.sqrt(eta * eta - 1.0 + c * c)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


def _fresnel_conductor(
    n: ArrayLike, k: ArrayLike, c: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Unpolarised Fresnel reflectance of a conductor (n + ik) per channel, (3, len(c))."""
    eta = np.asarray(n, dtype=np.float64)[:, None]
    etak = np.asarray(k, dtype=np.float64)[:, None]
    cos2 = np.clip(c, 0.0, 1.0)[None, :] ** 2
    sin2 = 1.0 - cos2
    eta2, etak2 = eta * eta, etak * etak
    t0 = eta2 - etak2 - sin2
    a2b2 = np.sqrt(t0 * t0 + 4.0 * eta2 * etak2)
    t1 = a2b2 + cos2
    a = np.sqrt(0.5 * (a2b2 + t0))
    t2 = 2.0 * np.sqrt(cos2) * a
    rs = (t1 - t2) / (t1 + t2)
    t3 = cos2 * a2b2 + sin2 * sin2
    t4 = t2 * sin2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rp + rs)


def _col(x: Any) -> NDArray[np.float64]:
    return np.asarray(x, dtype=np.float64).reshape(3, 1)


def _transmission(g: _Geom, eta: float) -> NDArray[np.float64]:
    """(1 − F(θi))(1 − F(θo)): energy through a dielectric interface both ways."""
    return (1.0 - _fresnel_dielectric(eta, g.mu_i)) * (1.0 - _fresnel_dielectric(eta, g.mu_o))


def _oren_nayar(g: _Geom, sigma: float) -> NDArray[np.float64]:
    """Qualitative Oren–Nayar factor (multiplies ρ/π)."""
    s2 = sigma * sigma
    a = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    mu_min = np.minimum(g.mu_i, g.mu_o)  # cos of α = max(θi, θo)
    mu_max = np.maximum(g.mu_i, g.mu_o)  # cos of β = min(θi, θo)
    sin_alpha = np.sqrt(np.maximum(1.0 - mu_min * mu_min, 0.0))
    tan_beta = np.sqrt(np.maximum(1.0 - mu_max * mu_max, 0.0)) / mu_max
    return a + b * np.maximum(g.cos_phi, 0.0) * sin_alpha * tan_beta


def _charlie(g: _Geom, r: float) -> NDArray[np.float64]:
    """Charlie sheen D (Estevez & Kulla 2017) × Neubelt–Pettineo visibility."""
    inv_r = 1.0 / r
    d = g.h(
        lambda c: (2.0 + inv_r) * np.sqrt(np.maximum(1.0 - c * c, 0.0)) ** inv_r / (2.0 * math.pi)
    )
    v = 1.0 / (4.0 * ((g.mu_i + g.mu_o) - g.mu_i * g.mu_o))
    return d * v


# --------------------------------------------------------------------------
# Families
# --------------------------------------------------------------------------


def _eval_metal(p: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    f = g.d(lambda c: _fresnel_conductor(p["n"], p["k"], c))
    lobes = (1.0 - p["haze"]) * _lobe(g, p["alpha"], p["ggx"])
    if p["haze"] > 0.0:
        lobes = lobes + p["haze"] * _lobe(g, p["alpha_haze"], p["ggx"])
    return f * lobes * p.get("scale", 1.0)


def _eval_paint(p: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    eta = p["eta"]
    f = g.d(lambda c: _fresnel_dielectric(eta, c))
    spec = 0.0
    for alpha, w in p["lobes"]:
        if w > 0.0:
            spec = spec + w * _lobe(g, alpha, p["ggx"])
    diffuse = _col(p["diffuse"]) / math.pi * (_oren_nayar(g, p["sigma"]) * _transmission(g, eta))
    return (p["ks"] * f * spec)[None, :] + diffuse


def _eval_metallic_paint(p: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    eta = p["coat_eta"]
    coat = g.d(lambda c: _fresnel_dielectric(eta, c)) * _lobe(g, p["coat_alpha"])
    base = (
        _col(p["base"]) * (p["kd"] / math.pi + p["k1"] * _lobe(g, p["alpha1"], p["ggx"]))
        + _col(p["flake_colour"]) * (p["k2"] * _lobe(g, p["alpha_flake"], p["ggx"]))
    )
    return coat[None, :] + _transmission(g, eta) * base


def _eval_fabric(p: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    out = _col(p["diffuse"]) / math.pi * _oren_nayar(g, p["sigma"])
    out = out + _col(p["sheen"]) * _charlie(g, p["sheen_roughness"])
    if p["ks"] > 0.0:
        eta = p["eta"]
        spec = g.d(lambda c: _fresnel_dielectric(eta, c)) * _lobe(g, p["alpha"])
        out = out + p["ks"] * spec
    return out


def _eval_phenolic(p: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    eta = p["eta"]
    lobes = (1.0 - p["haze"]) * _lobe(g, p["coat_alpha"])
    if p["haze"] > 0.0:
        lobes = lobes + p["haze"] * _lobe(g, p["alpha_haze"], p["ggx"])
    coat = g.d(lambda c: _fresnel_dielectric(eta, c)) * lobes
    kb = p["kb"]
    base = _col(p["diffuse"]) * ((1.0 - kb) / math.pi + kb * _lobe(g, p["alpha_base"], p["ggx"]))
    return coat[None, :] + _transmission(g, eta) * base


_EVALUATORS: Final = {
    "metal": _eval_metal,
    "paint": _eval_paint,
    "metallic-paint": _eval_metallic_paint,
    "fabric": _eval_fabric,
    "phenolic": _eval_phenolic,
}


def _params_of(spec_or_params: Any) -> Mapping[str, Any]:
    """The parameters of a :class:`brdfpipe.data.synth.MaterialSpec` (its ``params``), or ``spec_or_params`` itself."""
    params = getattr(spec_or_params, "params", spec_or_params)
    family = params.get("family")
    if family not in _EVALUATORS:
        raise ValueError(f"unknown material family {family!r} (expected one of {tuple(_EVALUATORS)})")
    return params


def _model(params: Mapping[str, Any], g: _Geom) -> NDArray[np.float64]:
    out = _EVALUATORS[params["family"]](params, g)
    return np.broadcast_to(out, (3, g.mu_i.shape[0]))


def _as_dirs(v: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = merl.as_directions(v, name)
    return arr / np.linalg.norm(arr, axis=1, keepdims=True)


def evaluate(
    spec_or_params: Any, wi: ArrayLike, wo: ArrayLike
) -> NDArray[np.float64]:
    """The analytic model of a material (no deviations, noise or energy scale).

    ``wi``, ``wo``: ``(n, 3)`` directions in the local frame (z = normal;
    normalised here).  Returns ``(n, 3)`` RGB in physical units (sr⁻¹); pairs
    with either direction at or below the horizon give 0.  Reciprocal:
    ``evaluate(p, wi, wo) == evaluate(p, wo, wi)`` up to rounding.
    """
    params = _params_of(spec_or_params)
    wi = _as_dirs(wi, "wi")
    wo = _as_dirs(wo, "wo")
    if wi.shape != wo.shape:
        raise ValueError(f"wi and wo must have the same shape, got {wi.shape} and {wo.shape}")
    ok = (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)
    out = np.zeros((wi.shape[0], 3))
    if ok.any():
        out[ok] = _model(params, _direct_geom(wi[ok], wo[ok])).T
    return out


def _deviation_log(params: Mapping[str, Any], grid: Grid) -> NDArray[np.float64]:
    """Log of the multiplicative deviation on the full grid, (3, 90, 90, 180)."""
    dev = params["deviation"]

    def cube(coef: NDArray[np.float64]) -> NDArray[np.float64]:
        na, nb, nc = coef.shape
        tu = np.cos(np.pi * np.arange(na)[:, None] * grid.u[None, :])  # (na, 90)
        td = np.cos(2.0 * np.arange(nb)[:, None] * grid.theta_d[None, :])  # (nb, 90)
        tp = np.cos(2.0 * np.arange(nc)[:, None] * grid.phi_d[None, :])  # (nc, 180)
        x = np.einsum("abc,ai,bj->ijc", coef, tu, td)
        return x @ tp  # (90, 90, 180)

    shared = cube(np.asarray(dev["shared"], dtype=np.float64).reshape(DEV_SHARED))
    channel = np.asarray(dev["channel"], dtype=np.float64).reshape(3, *DEV_CHANNEL)
    return np.stack([shared + cube(channel[c]) for c in range(3)])


def model_values(spec: Any) -> NDArray[np.float64]:
    """Analytic model × deviation at the measured cells, (3, n_measured)."""
    params = _params_of(spec)
    grid = cell_grid()
    values = np.array(_model(params, grid.geom), dtype=np.float64)
    log_dev = _deviation_log(params, grid).reshape(3, -1)[:, grid.cells]
    log_dev -= log_dev.mean(axis=1, keepdims=True)  # no change of overall brightness
    # soft limit of the gains (not the losses): exp(g) < exp(_DEV_GAIN_LIMIT)
    pos = log_dev > 0.0
    log_dev[pos] = _DEV_GAIN_LIMIT * np.tanh(log_dev[pos] / _DEV_GAIN_LIMIT)
    values *= np.exp(log_dev)
    return values
