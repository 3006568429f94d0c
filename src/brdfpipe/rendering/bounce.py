"""A path tracer that splits the image into I¹⁻ and I²⁺ (Soler et al. 2018 §5.2).

Blending pre-rendered images with the manifold's weights (:mod:`brdfpipe.rendering.blend`)
is exact only for the light paths that scatter **at most once** on the edited
material: the image is affine in the BRDF for those paths (``I¹⁻``) and
quadratic or worse for paths with two or more scatterings on it (``I²⁺``, the
object's inter-reflections on itself).  The ``bouncesplit`` integrator renders
both at once::

    from brdfpipe.rendering import bounce, render
    render.use_variant("llvm_ad_rgb")
    render.register_merl_bsdf()
    bounce.register_bounce_integrator()
    scene = {..., "integrator": {"type": "bouncesplit", "max_depth": 6}}

Each sample returns the total radiance (the film's R, G, B), the ``I¹⁻``
part as three AOV channels and the object mask (1 where the camera ray's first
hit is on the material, so the film gives the pixel's coverage) as a fourth
(:data:`AOV_NAMES`, after R, G, B in the image ``mi.render`` returns);
``I²⁺ = total − I¹⁻``.

The path tracer
---------------
A unidirectional path tracer with next-event estimation and multiple
importance sampling (power heuristic), a line-by-line port of Mitsuba 3's
``path`` integrator (``src/integrators/path.cpp``): the same ``max_depth``
semantics (1: only directly visible emitters; 2: direct illumination; −1:
unbounded), the same Russian roulette (from ``rr_depth``, default 5, survival
probability ``min(max(throughput)·η², 0.95)``), and the same order of sampler
draws (emitter 2D, BSDF 1D + 2D, roulette 1D per vertex), so with the same
seed it follows the same paths as ``path`` and its total agrees with ``path``
pixel by pixel up to floating-point rounding (tests compare the two with
independent seeds, within the noise).  ``hide_emitters`` is supported as in
``path``.  It assumes no participating media (like ``path``).

Counting scatterings on the material
------------------------------------
The material is the BSDF whose id is ``material_id`` (default ``"material"``,
the shared bsdf of :func:`brdfpipe.rendering.scene.scene_dict`); a vertex is on the
material when ``si.bsdf()`` is that BSDF (pointer comparison, so every shape
that references it counts).  ``n`` is the number of scatterings on the
material so far (vertices where the path was continued by BSDF sampling).

* Emission found by BSDF sampling (or seen directly) at vertex ``k`` has
  ``n`` scatterings on the material (the emitter itself is not the material).
* Next-event estimation at vertex ``si`` scatters at ``si``: it has
  ``n + [si on material]``.

A contribution goes to ``I¹⁻`` when its count is ≤ 1.  Both MIS halves of a
path (the NEE one and the BSDF-sampled one) have the same vertices, hence the
same count, so ``I¹⁻`` is an unbiased estimate of the paths with ≤ 1
scattering on the material, and it is exactly affine in the material's BRDF
values (importance sampling only changes the variance).  With
``max_depth ≤ 2`` there is at most one scattering vertex, so ``I²⁺`` is 0.

Like :mod:`brdfpipe.rendering.render`, the plugin class is created for the current
variant on first use (:func:`register_bounce_integrator` after
:func:`brdfpipe.rendering.render.use_variant`); importing this module does not import
Mitsuba.
"""

from __future__ import annotations

import threading
from functools import lru_cache
from typing import Any, Final

__all__ = [
    "PLUGIN_NAME",
    "AOV_NAMES",
    "MATERIAL_ID",
    "register_bounce_integrator",
    "bounce_integrator",
]

#: Mitsuba plugin name of the integrator.
PLUGIN_NAME: Final = "bouncesplit"
#: AOV channels (after R, G, B in ``mi.render``'s output): the I¹⁻ image, then the
#: object mask (fraction of a pixel's camera rays whose first hit is on the material).
AOV_NAMES: Final = ("one.R", "one.G", "one.B", "object")
#: Default id of the edited material's BSDF (see :func:`brdfpipe.rendering.scene.scene_dict`).
MATERIAL_ID: Final = "material"

_registered: set[str] = set()
_lock = threading.Lock()


def bounce_integrator(max_depth: int, *, rr_depth: int = 5, material_id: str = MATERIAL_ID) -> dict[str, Any]:
    """The :func:`mitsuba.load_dict` entry of a ``bouncesplit`` integrator."""
    return {"type": PLUGIN_NAME, "max_depth": int(max_depth), "rr_depth": int(rr_depth),
            "material_id": str(material_id)}


def register_bounce_integrator() -> None:
    """Register the ``bouncesplit`` integrator with Mitsuba for the current variant.

    Call after :func:`brdfpipe.rendering.render.use_variant`.  Idempotent per variant.
    """
    import mitsuba as mi

    from brdfpipe.rendering import render

    variant = render.current_variant()
    with _lock:
        if variant in _registered:
            return
        cls = _bounce_class(variant)
        mi.register_integrator(PLUGIN_NAME, lambda props: cls(props))
        _registered.add(variant)


def _mis_weight(dr: Any, pdf_a: Any, pdf_b: Any) -> Any:
    """Power heuristic ``a² / (a² + b²)``, 0 where not finite (as Mitsuba's ``path``)."""
    a2 = dr.square(pdf_a)
    w = a2 / (a2 + dr.square(pdf_b))
    return dr.detach(dr.select(dr.isfinite(w), w, 0.0))


def _settings(props: Any) -> tuple[int, int, bool, str]:
    """``max_depth``, ``rr_depth``, ``hide_emitters``, ``material_id`` of the integrator's properties.

    ``max_depth`` −1 (unbounded) comes back as ``0xFFFFFFFF``, as path.cpp
    (an unsigned comparison); RenderError for a depth out of range.
    """
    from brdfpipe.rendering.render import RenderError

    max_depth = int(props.get("max_depth", -1))
    if max_depth < 0 and max_depth != -1:
        raise RenderError(f"bouncesplit: max_depth must be >= 0 or -1, got {max_depth}")
    rr_depth = int(props.get("rr_depth", 5))
    if rr_depth <= 0:
        raise RenderError(f"bouncesplit: rr_depth must be > 0, got {rr_depth}")
    return (0xFFFFFFFF if max_depth == -1 else max_depth, rr_depth,
            bool(props.get("hide_emitters", False)), str(props.get("material_id", MATERIAL_ID)))


def _find_material(scene: Any, material_id: str) -> Any:
    """The BSDF with id ``material_id`` of a shape of ``scene`` (RenderError naming the id if none has it)."""
    from brdfpipe.rendering.render import RenderError

    ids = set()
    for shape in scene.shapes():
        bsdf = shape.bsdf()
        if bsdf is None:
            continue
        if bsdf.id() == material_id:
            return bsdf
        ids.add(bsdf.id())
    raise RenderError(
        f"bouncesplit: no shape of the scene has a bsdf with id {material_id!r} "
        f"(bsdf ids: {', '.join(sorted(ids)) or 'none'})"
    )


def _sample_split(self: Any, scene: Any, sampler: Any, ray: Any, medium: Any = None,
                  active: Any = True) -> tuple[Any, Any, list[Any]]:
    """``BounceSplitIntegrator.sample``: one path per ray, its total and its I¹⁻ part (module docstring).

    Not called as it is: :func:`_bounce_class` makes it the method through
    ``drjit.syntax``, which rewrites the ``while`` loop into a symbolic loop.
    """
    # dr.syntax recompiles this function from its source in this module's globals: import here
    import drjit as dr
    import mitsuba as mi

    material = mi.BSDFPtr(self._material(scene))
    bsdf_ctx = mi.BSDFContext()

    ray = mi.Ray3f(ray)
    depth = mi.UInt32(0)
    n_mat = mi.UInt32(0)  # scatterings on the material so far
    result = mi.Spectrum(0.0)
    one = mi.Spectrum(0.0)  # contributions with ≤ 1 scattering on the material
    throughput = mi.Spectrum(1.0)
    eta = mi.Float(1.0)
    active = mi.Bool(active)
    valid_ray = mi.Bool((not self.hide_emitters) and scene.environment() is not None)

    obj = mi.Float(0.0)  # first hit on the material (object mask)
    prev_si = dr.zeros(mi.Interaction3f)
    prev_bsdf_pdf = mi.Float(1.0)
    prev_bsdf_delta = mi.Bool(True)

    while dr.hint(active, label="bouncesplit"):
        si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=(depth == 0),
                                 active=active)

        # ---------------------- Direct emission ----------------------
        hit_em = active
        if dr.hint(self.hide_emitters, mode="scalar"):
            hit_em &= ~((depth == 0) & ~si.is_valid())
        ds = mi.DirectionSample3f(scene, si, prev_si)
        em_pdf = scene.pdf_emitter_direction(prev_si, ds, hit_em & ~prev_bsdf_delta)
        em_pdf = dr.select(prev_bsdf_delta, 0.0, em_pdf)
        mis_bsdf = _mis_weight(dr, prev_bsdf_pdf, em_pdf)
        emitter = si.emitter(scene, hit_em)
        le = throughput * emitter.eval(si, hit_em & (prev_bsdf_pdf > 0.0)) * mis_bsdf
        le = dr.select(hit_em, le, 0.0)
        result += le
        one += dr.select(n_mat <= 1, le, 0.0)

        active_next = active & (depth + 1 < self.max_depth) & si.is_valid()

        bsdf = si.bsdf(ray)
        hit_mat = active & si.is_valid() & (bsdf == material)
        obj = dr.select((depth == 0) & hit_mat, 1.0, obj)
        on_mat = active_next & hit_mat
        n_here = n_mat + dr.select(on_mat, 1, 0)

        # ---------------------- Emitter sampling ----------------------
        active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), True, active_em)
        active_em &= ds.pdf != 0.0
        wo = si.to_local(ds.d)

        # ------------------ BSDF evaluation and sampling ------------------
        sample_1 = sampler.next_1d()
        sample_2 = sampler.next_2d()
        bsdf_val, bsdf_pdf, bsdf_sample, bsdf_weight = bsdf.eval_pdf_sample(
            bsdf_ctx, si, wo, sample_1, sample_2, active_next)

        mis_em = dr.select(ds.delta, 1.0, _mis_weight(dr, ds.pdf, bsdf_pdf))
        lr = dr.select(active_em, throughput * bsdf_val * em_weight * mis_em, 0.0)
        result += lr
        one += dr.select(n_here <= 1, lr, 0.0)

        # ---------------------- Update the path ----------------------
        ray = si.spawn_ray(si.to_world(bsdf_sample.wo))
        throughput *= bsdf_weight
        eta *= bsdf_sample.eta
        valid_ray |= active & si.is_valid() & ~mi.has_flag(bsdf_sample.sampled_type,
                                                           mi.BSDFFlags.Null)
        prev_si = mi.Interaction3f(si)
        prev_bsdf_pdf = bsdf_sample.pdf
        prev_bsdf_delta = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
        n_mat = dr.select(active_next, n_here, n_mat)

        # ---------------------- Stopping criterion ----------------------
        depth[si.is_valid()] += 1
        throughput_max = dr.max(mi.unpolarized_spectrum(throughput))
        rr_prob = dr.minimum(throughput_max * dr.square(eta), 0.95)
        rr_active = depth >= self.rr_depth
        rr_continue = sampler.next_1d() < rr_prob
        throughput[rr_active] *= dr.rcp(dr.detach(rr_prob))
        active = active_next & (~rr_active | rr_continue) & (throughput_max != 0.0)

    return (dr.select(valid_ray, result, 0.0), valid_ray,
            [one[0], one[1], one[2], obj])


@lru_cache(maxsize=None)
def _bounce_class(variant: str) -> type:
    """The ``BounceSplitIntegrator`` class for ``variant`` (which must be the current one).

    The class only wires the module's functions into Mitsuba's interface:
    :func:`_settings` (properties), :func:`_find_material` and
    :func:`_sample_split` (the path tracer).
    """
    import drjit as dr
    import mitsuba as mi

    from brdfpipe.rendering import render

    if mi.variant() != variant:
        raise render.RenderError(f"variant {variant!r} is not the current Mitsuba variant ({mi.variant()!r})")

    class BounceSplitIntegrator(mi.SamplingIntegrator):
        """Mitsuba integrator ``bouncesplit``: ``path`` plus the I¹⁻ image as AOVs.

        Properties: ``max_depth`` (int, default −1 = unbounded; ≥ 1 or −1),
        ``rr_depth`` (int, default 5), ``hide_emitters`` (bool, default
        false), ``material_id`` (string, default ``"material"``): the id of
        the edited material's BSDF.
        """

        def __init__(self, props: Any) -> None:
            super().__init__(props)
            self.max_depth, self.rr_depth, self.hide_emitters, self.material_id = _settings(props)

        def aov_names(self) -> list[str]:
            return list(AOV_NAMES)

        def _material(self, scene: Any) -> Any:
            """The edited material's BSDF (RenderError naming the id if no shape uses it)."""
            return _find_material(scene, self.material_id)

        sample = dr.syntax(_sample_split)

        def to_string(self) -> str:
            return (f"BounceSplitIntegrator[max_depth={self.max_depth}, rr_depth={self.rr_depth}, "
                    f"material_id={self.material_id!r}]")

    BounceSplitIntegrator.__qualname__ = "BounceSplitIntegrator"
    BounceSplitIntegrator.__module__ = __name__
    return BounceSplitIntegrator
