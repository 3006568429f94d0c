"""The ``merl`` Mitsuba 3 BSDF of brdfpipe.rendering.render: lookup, sampling, rendering, errors.

Everything runs in the ``llvm_ad_rgb`` variant; the tests that need it are
skipped (with the reason) where its backend (libLLVM) is unavailable.  MERL
files are generated once per session (tabulated Mitsuba BSDFs, a synthetic
material, random and Lambertian tables) under ``tmp_path_factory``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from brdfpipe.data import merl, synth
from brdfpipe.rendering import render

VARIANT = "llvm_ad_rgb"

#: Mitsuba BSDFs that are tabulated into MERL files (GGX: the distribution the sampler fits).
ANALYTIC: dict[str, dict[str, Any]] = {
    "roughconductor-0.1": {"type": "roughconductor", "distribution": "ggx", "alpha": 0.1, "material": "Au"},
    "roughconductor-0.3": {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "material": "Cu"},
    "roughplastic": {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": 0.2,
        "diffuse_reflectance": {"type": "rgb", "value": [0.2, 0.4, 0.7]},
    },
    "diffuse": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.4, 0.3]}},
}
CHI2_MATERIALS = ("roughconductor-0.1", "roughconductor-0.3", "roughplastic", "diffuse", "synth-hazy-metal")
CHI2_ANGLES = (10.0, 45.0, 75.0)


# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


@pytest.fixture(scope="session")
def _llvm_available() -> None:
    try:
        render.use_variant(VARIANT)
    except render.RenderError as exc:
        pytest.skip(f"Mitsuba variant {VARIANT} unavailable here: {exc}")


@pytest.fixture()
def mi(_llvm_available: None) -> Any:
    """Mitsuba with the llvm variant set and the ``merl`` plugin registered."""
    import mitsuba

    render.use_variant(VARIANT)  # cheap; guards against another test changing it
    render.register_merl_bsdf()
    return mitsuba


@pytest.fixture(params=render.VARIANTS)
def mi_any(request: pytest.FixtureRequest, _llvm_available: None) -> Any:
    """Mitsuba in each supported variant (skipped where its backend is missing, e.g. no GPU)."""
    import mitsuba

    try:
        render.use_variant(request.param)
    except render.RenderError as exc:
        pytest.skip(str(exc))
    render.register_merl_bsdf()
    yield mitsuba
    render.use_variant(VARIANT)


def _random_table(seed: int = 0) -> np.ndarray:
    """Uniform random values, 10 % random cells and the unmeasurable region negative."""
    rng = np.random.default_rng(seed)
    table = rng.uniform(0.05, 3.0, merl.SHAPE)
    holes = (rng.uniform(size=merl.DIMS) < 0.1) | ~merl.measured_mask()
    table[:, holes] = -merl.SCALES[:, None]
    return table


def _hazy_metal() -> synth.MaterialSpec:
    """The first synthetic metal with a strong haze lobe (fitted with two GGX lobes)."""
    return next(s for s in synth.plan_database(100, 0) if s.family == "metal" and s.params["haze"] > 0.15)


class _Materials:
    """MERL files made on first request and kept for the session."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.paths: dict[str, Path] = {}

    def path(self, name: str) -> Path:
        if name not in self.paths:
            import mitsuba

            previous = mitsuba.variant()
            render.use_variant(VARIANT)
            if name in ANALYTIC:
                table = render.tabulate_bsdf(ANALYTIC[name])
            elif name == "synth-hazy-metal":
                table = synth.generate_table(_hazy_metal())
            elif name == "random":
                table = _random_table()
            elif name.startswith("lambert-"):
                table = render.lambertian_table(float(name.split("-")[1]))
            else:  # pragma: no cover - test bug
                raise KeyError(name)
            path = self.folder / f"{name}.binary"
            merl.write_merl(path, table)
            self.paths[name] = path
            if previous is not None and previous != VARIANT:
                render.use_variant(previous)
        return self.paths[name]

    def table(self, name: str) -> np.ndarray:
        return merl.read_merl(self.path(name))


@pytest.fixture(scope="module")
def materials(tmp_path_factory: pytest.TempPathFactory, _llvm_available: None) -> _Materials:
    return _Materials(tmp_path_factory.mktemp("merl"))


def _load(mi: Any, path: Path) -> Any:
    return mi.load_dict(render.merl_bsdf(path))


def _si(mi: Any, wi: np.ndarray) -> Any:
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f, wi.shape[0])
    si.wi = mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32))
    return si


def _np(x: Any) -> np.ndarray:
    return np.asarray(x.numpy(), dtype=np.float64)


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# --------------------------------------------------------------------------
# Evaluation = brdfpipe.data.merl.lookup
# --------------------------------------------------------------------------


def _bin_edge_distance(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Distance (in bins) of each pair's continuous MERL coordinates to the nearest bin edge."""
    th, td, pd = merl.half_diff(wi, wo)
    coords = [
        np.sqrt(th / (np.pi / 2)) * merl.N_THETA_H,
        td / (np.pi / 2) * merl.N_THETA_D,
        np.where(pd < 0, pd + np.pi, pd) / np.pi * merl.N_PHI_D,
    ]
    return np.minimum.reduce([np.abs(c - np.round(c)) for c in coords])


def test_eval_matches_merl_lookup_times_cosine(mi_any: Any, materials: _Materials) -> None:
    mi = mi_any
    rng = np.random.default_rng(7)
    n = 6000
    # random pairs over the whole sphere (~¼ front side), plus front-side pairs with
    # tiny θh (MERL's first θh bins are 0.011° wide: a float32 acos would miss them)
    wi = _unit(rng, n)
    wo = _unit(rng, n)
    m = 1500
    th = np.exp(rng.uniform(np.log(1e-5), np.log(0.05), m))
    wi2, wo2 = merl.directions_from_half_diff(
        th, rng.uniform(0.0, 1.2, m), rng.uniform(-np.pi, np.pi, m), rng.uniform(-np.pi, np.pi, m)
    )
    wi = np.concatenate([wi, wi2]).astype(np.float32).astype(np.float64)
    wo = np.concatenate([wo, wo2]).astype(np.float32).astype(np.float64)

    table = materials.table("random")
    bsdf = _load(mi, materials.path("random"))
    got = _np(bsdf.eval(mi.BSDFContext(), _si(mi, wi), mi.Vector3f(wo.T.astype(np.float32)))).reshape(3, -1).T

    front = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    want = np.maximum(merl.lookup(table, wi, wo), 0.0) * wo[:, 2:3]
    want[~front] = 0.0
    same = np.isclose(got, want, rtol=3e-6, atol=0.0).all(axis=1)
    # the test covers unmeasured cells (→ 0), measured ones and the back side
    assert ((want == 0).all(axis=1) & front).sum() > 100
    assert (want > 0).all(axis=1).sum() > 2000
    assert (~front).sum() > 3000 and (got[~front] == 0).all()
    # single precision may move a pair that sits on a bin edge into the neighbouring cell
    bad = ~same
    assert bad.mean() < 1e-3, f"{bad.sum()} of {bad.size} pairs differ from merl.lookup"
    assert (_bin_edge_distance(wi[bad], wo[bad]) < 1e-4).all()


def test_tabulating_a_merl_bsdf_gives_its_table_back(mi: Any, materials: _Materials) -> None:
    table = materials.table("random")
    back = render.tabulate_bsdf(_load(mi, materials.path("random")))
    mask = merl.measured_mask()
    # measured cells: the table (float32 on the device), unmeasured ones (stored 0) read 0
    assert np.allclose(back[:, mask], np.maximum(table[:, mask], 0.0), rtol=2e-7, atol=0.0)
    assert (back[:, ~mask] < 0).all()


def test_eval_pdf_and_context_flags(mi: Any, materials: _Materials) -> None:
    rng = np.random.default_rng(3)
    wi, wo = _unit(rng, 2000), _unit(rng, 2000)
    bsdf = _load(mi, materials.path("roughplastic"))
    ctx = mi.BSDFContext()
    si, vo = _si(mi, wi), mi.Vector3f(wo.T.astype(np.float32))
    value, pdf = bsdf.eval_pdf(ctx, si, vo)
    assert np.array_equal(_np(value), _np(bsdf.eval(ctx, si, vo)))
    assert np.array_equal(_np(pdf), _np(bsdf.pdf(ctx, si, vo)))
    back = (wi[:, 2] <= 0) | (wo[:, 2] <= 0)
    assert (_np(pdf)[back] == 0).all() and (_np(pdf)[~back] > 0).all()
    ctx.type_mask = +mi.BSDFFlags.DiffuseReflection  # the glossy lobe is switched off
    assert not _np(bsdf.eval(ctx, si, vo)).any() and not _np(bsdf.pdf(ctx, si, vo)).any()
    assert bsdf.flags() == +(mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide)


# --------------------------------------------------------------------------
# Sampling
# --------------------------------------------------------------------------


def _chi2_adapter(mi: Any, bsdf: Any, wi: Any) -> tuple[Any, Any]:
    """``sample_func``/``pdf_func`` for ChiSquareTest.

    Unlike ``mitsuba.chi2.BSDFAdapter`` a sample counts when it is valid
    (``bs.pdf > 0``), not when its weight is non-zero: a sample landing in an
    unmeasured cell (value 0) is still a sample of the density.
    """
    import drjit as dr

    ctx = mi.BSDFContext()

    def make(n: int) -> Any:
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi = wi
        return si

    def sample_func(sample: Any) -> Any:
        bs, _ = bsdf.sample(ctx, make(dr.width(sample)), sample[0], mi.Point2f(sample[1], sample[2]))
        return bs.wo, dr.select(bs.pdf > 0.0, 1.0, 0.0)

    def pdf_func(wo: Any) -> Any:
        return bsdf.pdf(ctx, make(dr.width(wo)), wo)

    return sample_func, pdf_func


def _chi2(mi: Any, sample_func: Any, pdf_func: Any) -> Any:
    from mitsuba.chi2 import ChiSquareTest, SphericalDomain

    # ires=16: the trapezoid rule must resolve lobes as narrow as α ≈ 0.03 (the hazy metal)
    return ChiSquareTest(
        domain=SphericalDomain(), sample_func=sample_func, pdf_func=pdf_func,
        sample_dim=3, sample_count=1_000_000, res=201, ires=16, seed=1,
    )


def _wi(mi: Any, degrees: float) -> Any:
    t = np.radians(degrees)
    return mi.Vector3f(float(np.sin(t)), 0.0, float(np.cos(t)))


@pytest.mark.parametrize("angle", CHI2_ANGLES)
@pytest.mark.parametrize("name", CHI2_MATERIALS)
def test_chi2_sampling_matches_pdf(mi: Any, materials: _Materials, name: str, angle: float) -> None:
    bsdf = _load(mi, materials.path(name))
    chi2 = _chi2(mi, *_chi2_adapter(mi, bsdf, _wi(mi, angle)))
    ok = chi2.run(significance_level=0.01, test_count=len(CHI2_MATERIALS) * len(CHI2_ANGLES), quiet=True)
    assert ok, f"{name} at {angle}°: {chi2.messages}"


def test_chi2_rejects_a_slightly_wrong_pdf(mi: Any, materials: _Materials) -> None:
    # Negative control: the same sampler judged against the pdf of a lobe 15 % rougher.
    bsdf = _load(mi, materials.path("roughconductor-0.1"))
    wrong = _load(mi, materials.path("roughconductor-0.1"))
    fit = bsdf.fit
    wrong._set_fit(render.SamplingFit(fit.w_cos, tuple(1.15 * a for a in fit.alphas), fit.weights, 0.0))
    sample_func, _ = _chi2_adapter(mi, bsdf, _wi(mi, 45.0))
    _, pdf_func = _chi2_adapter(mi, wrong, _wi(mi, 45.0))
    assert not _chi2(mi, sample_func, pdf_func).run(significance_level=0.01, quiet=True)


@pytest.mark.parametrize("name", ["roughconductor-0.1", "synth-hazy-metal", "random"])
def test_sample_weight_is_eval_over_pdf(mi_any: Any, materials: _Materials, name: str) -> None:
    mi = mi_any
    rng = np.random.default_rng(11)
    n = 20000
    wi = _unit(rng, n)
    wi[: n // 2, 2] = np.abs(wi[: n // 2, 2])  # mostly front side, some back side
    bsdf = _load(mi, materials.path(name))
    ctx = mi.BSDFContext()
    si = _si(mi, wi)
    s1 = mi.Float(rng.uniform(size=n).astype(np.float32))
    s2 = mi.Point2f(rng.uniform(size=(2, n)).astype(np.float32))
    bs, weight = bsdf.sample(ctx, si, s1, s2)
    weight, spdf = _np(weight).reshape(3, -1).T, _np(bs.pdf)
    value, pdf = (_np(x) for x in bsdf.eval_pdf(ctx, si, bs.wo))
    value = value.reshape(3, -1).T
    valid = spdf > 0
    assert np.isfinite(weight).all()
    assert valid.sum() > 0.4 * n  # front-side wi give valid samples (a few go below the horizon)
    assert not valid[wi[:, 2] <= 0].any() and not weight[~valid].any()
    assert np.allclose(spdf[valid], pdf[valid], rtol=1e-4)
    assert np.allclose(weight[valid], value[valid] / pdf[valid, None], rtol=1e-4, atol=1e-6)
    wo = _np(bs.wo).reshape(3, -1).T
    assert (wo[valid, 2] > 0).all() and np.allclose(np.linalg.norm(wo[valid], axis=1), 1.0, atol=1e-5)


def test_fit_uses_the_lobe_of_the_table(materials: _Materials) -> None:
    fit = render.fit_sampling(materials.table("roughconductor-0.1"))
    assert len(fit.alphas) == 1 and 0.085 < fit.alphas[0] < 0.115
    assert fit.w_cos < 0.05
    # the fitted mixture beats both pure strategies on its own objective
    table = materials.table("roughconductor-0.1")
    cos_only = render.sampling_report(table)["cosine"]
    assert fit.rel_variance < 0.05 < cos_only
    # a hazy metal gets (and profits from) a second, wider lobe
    hazy = materials.table("synth-hazy-metal")
    fit2, fit1 = render.fit_sampling(hazy), render.fit_sampling(hazy, n_lobes=1)
    assert len(fit2.alphas) == 2 and fit2.rel_variance < 0.8 * fit1.rel_variance
    assert np.isclose(fit2.w_cos + sum(fit2.weights), 1.0)


def test_fit_degenerate_tables() -> None:
    diffuse = render.fit_sampling(render.lambertian_table(0.6))
    assert diffuse.w_cos == 1.0 and diffuse.rel_variance < 1e-3
    zero = np.zeros(merl.SHAPE)
    assert render.fit_sampling(zero).w_cos == 1.0
    unmeasured = np.full(merl.SHAPE, -1.0)
    assert render.fit_sampling(unmeasured).w_cos == 1.0
    with pytest.raises(ValueError, match="shape"):
        render.fit_sampling(np.zeros((3, 4)))


def test_all_zero_table_renders_black_without_nan(mi: Any, tmp_path: Path) -> None:
    import drjit as dr

    path = tmp_path / "black.binary"
    merl.write_merl(path, np.zeros(merl.SHAPE))
    bsdf = _load(mi, path)
    n = 1000
    rng = np.random.default_rng(0)
    si = _si(mi, np.abs(_unit(rng, n)))
    bs, w = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.uniform(size=n)), mi.Point2f(rng.uniform(size=(2, n))))
    assert not _np(w).any() and np.isfinite(_np(bs.pdf)).all() and dr.all(bs.pdf > 0)


# --------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------


def _scene(mi: Any, bsdf: dict[str, Any], spp: int, *, env: float, sun: bool, res: int = 48) -> Any:
    d: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2},  # a convex sphere: one bounce is exact
        "sensor": {
            "type": "perspective",
            "fov": 20.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "sphere": {"type": "sphere", "bsdf": bsdf},
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": env}},
    }
    if sun:
        d["sun"] = {"type": "directional", "direction": [-1, -1, -1],
                    "irradiance": {"type": "rgb", "value": 3.0}}
    return mi.load_dict(d)


def _rel_rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b**2)))


@pytest.mark.parametrize("albedo", [0.5, 0.8])
def test_white_furnace(mi_any: Any, materials: _Materials, albedo: float) -> None:
    mi = mi_any
    # A sphere under a uniform environment of radiance 1: every pixel's expectation is
    # exactly the albedo (the sphere fills the frame: 4 units away, fov 20°).
    scene = _scene(mi, render.merl_bsdf(materials.path(f"lambert-{albedo}")), 128, env=1.0, sun=False, res=32)
    img = np.asarray(mi.render(scene, seed=3), dtype=np.float64).mean(axis=2)  # channels are equal
    # Pixels are independent estimates: the mean's standard error is std/sqrt(n).  4σ
    # (two-sided p ≈ 6e-5) keeps a correct plugin green; a missing cosine, a pdf that
    # does not match the sampler, or a lost cell biases the mean by far more.
    se = img.std(ddof=1) / np.sqrt(img.size)
    assert abs(img.mean() - albedo) < 4.0 * se + 1e-5, (img.mean(), se)
    assert se < 0.002 * albedo  # the test is sharp: ±0.8 % at most


def test_render_matches_analytic_diffuse(mi: Any, materials: _Materials) -> None:
    # Same scene, same seed: the camera/emitter random numbers are shared and the
    # tabulated diffuse is sampled exactly like Mitsuba's (cosine), so what differs is
    # only the grazing cells whose centre is below the horizon and float32 rounding:
    # measured 0.015 %.  Threshold 0.5 %.
    spp = 64
    ref = np.asarray(mi.render(_scene(mi, ANALYTIC["diffuse"], spp, env=0.3, sun=True), seed=0))
    img = np.asarray(mi.render(_scene(mi, render.merl_bsdf(materials.path("diffuse")), spp, env=0.3, sun=True), seed=0))
    assert _rel_rmse(img, ref) < 0.005


def test_render_matches_analytic_roughconductor(mi: Any, materials: _Materials) -> None:
    # GGX α = 0.1 gold.  Measured relative RMSE (48², 64 spp, seed 0): 0.8 %, of which
    # ~0.5 % is the table's binning (nearest cell; 0.51 % at 4096 spp) and the rest the
    # BSDF-sampling noise that the two renders do not share.  Threshold 3 %: a
    # 5 % rougher analytic lobe (α = 0.105) already differs by 6 %.
    spp = 64
    path = materials.path("roughconductor-0.1")
    img = np.asarray(mi.render(_scene(mi, render.merl_bsdf(path), spp, env=0.3, sun=True), seed=0))
    ref = np.asarray(mi.render(_scene(mi, ANALYTIC["roughconductor-0.1"], spp, env=0.3, sun=True), seed=0))
    assert _rel_rmse(img, ref) < 0.03
    rougher = dict(ANALYTIC["roughconductor-0.1"], alpha=0.105)  # negative control
    other = np.asarray(mi.render(_scene(mi, rougher, spp, env=0.3, sun=True), seed=0))
    assert _rel_rmse(img, other) > 0.03


# --------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------


def test_lambertian_table() -> None:
    t = render.lambertian_table([0.2, 0.5, 0.9])
    assert t.shape == merl.SHAPE
    assert np.allclose(t.reshape(3, -1), (np.array([0.2, 0.5, 0.9]) / np.pi)[:, None])
    # directional albedo of the table = albedo at every incident angle
    assert np.allclose(merl.directional_albedo(render.lambertian_table(0.5), [0.1, 0.8]), 0.5, rtol=0.02)
    with pytest.raises(ValueError):
        render.lambertian_table(1.5)


def test_tabulate_diffuse_and_roughconductor(mi: Any) -> None:
    diff = render.tabulate_bsdf({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}})
    mask = merl.measured_mask()
    assert np.allclose(diff[:, mask], 0.5 / np.pi, rtol=1e-5)
    assert np.array_equal(diff[:, ~mask], np.broadcast_to(-merl.SCALES[:, None], (3, int((~mask).sum()))))
    # a GGX gold conductor: the peak at θh ≈ 0, θd ≈ 0 is F(0) D(0) G2 / 4 with
    # D(0) = 1/(π α²), G2 ≈ 1 and F(0) ≈ 0.95 in red (an instance works as well as a dict)
    bsdf = mi.load_dict(ANALYTIC["roughconductor-0.1"])
    tab = render.tabulate_bsdf(bsdf)
    assert np.isclose(tab[0, 0, 0, 0], 0.95 / (np.pi * 0.01) / 4.0, rtol=0.1)
    assert (tab[:, 60, 5, :] < tab[:, 0, 5, :1]).all()  # falls off with θh


# --------------------------------------------------------------------------
# API and errors
# --------------------------------------------------------------------------


def test_unknown_variant_is_rejected(mi: Any) -> None:
    with pytest.raises(render.RenderError, match=r"'scalar_rgb'.*llvm_ad_rgb, cuda_ad_rgb"):
        render.use_variant("scalar_rgb")
    with pytest.raises(render.RenderError, match="nope"):
        render.use_variant("nope")
    assert mi.variant() == VARIANT  # unchanged


def test_cuda_without_gpu_is_rejected(mi: Any) -> None:
    import drjit as dr

    if dr.has_backend(dr.JitBackend.CUDA):
        pytest.skip("a CUDA GPU is available here")
    with pytest.raises(render.RenderError, match=r"'cuda_ad_rgb' is not available.*llvm_ad_rgb"):
        render.use_variant("cuda_ad_rgb")
    assert mi.variant() == VARIANT


def test_missing_and_corrupt_files_are_named(mi: Any, tmp_path: Path) -> None:
    missing = tmp_path / "missing-material.binary"
    with pytest.raises(Exception, match="missing-material.binary"):
        _load(mi, missing)
    corrupt = tmp_path / "corrupt-material.binary"
    corrupt.write_bytes(np.asarray(merl.DIMS, dtype="<i4").tobytes() + b"\0" * 1000)
    with pytest.raises(Exception, match=r"corrupt-material.binary.*truncated"):
        _load(mi, corrupt)
    with pytest.raises(Exception, match="filename"):
        mi.load_dict({"type": "merl"})


def test_plugin_class_registration_and_traverse(mi: Any, materials: _Materials) -> None:
    render.register_merl_bsdf()  # idempotent
    assert render.merl_bsdf("a/b.binary") == {"type": "merl", "filename": str(Path("a/b.binary"))}
    bsdf = _load(mi, materials.path("diffuse"))
    assert isinstance(bsdf, render.MerlBSDF) and issubclass(render.MerlBSDF, mi.BSDF)
    params = mi.traverse(bsdf)
    assert "table" in params and len(params["table"]) == 3 * merl.N_CELLS
    wi = np.array([[0.3, 0.0, np.sqrt(1 - 0.09)]])
    wo = np.array([[-0.5, 0.2, np.sqrt(1 - 0.29)]])
    before = _np(bsdf.eval(mi.BSDFContext(), _si(mi, wi), mi.Vector3f(wo.T.astype(np.float32))))
    params["table"] = params["table"] * 2.0
    params.update()
    after = _np(bsdf.eval(mi.BSDFContext(), _si(mi, wi), mi.Vector3f(wo.T.astype(np.float32))))
    assert np.allclose(after, 2.0 * before) and before.min() > 0


def test_import_does_not_set_a_variant() -> None:
    code = "import brdfpipe.rendering.render, mitsuba; assert mitsuba.variant() is None, mitsuba.variant()"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
