"""Tests of :mod:`brdfpipe.rendering.scene`: env map convention, preview scene, deterministic renders.

Renders are tiny (32 × 24 pixels, 4–8 spp, max_depth 3) with Mitsuba's own
``diffuse`` / ``roughplastic`` bsdfs on the ``llvm_ad_rgb`` variant.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from brdfpipe.core.exr import read_exr, read_exr_attrs
from brdfpipe.rendering import scene

RES = (32, 24)
PLASTIC = {"type": "roughplastic", "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.3, 0.1]}}
DIFFUSE = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}


@pytest.fixture(scope="module")
def mi() -> Any:
    try:
        scene.set_variant("llvm_ad_rgb")
    except scene.SceneError as exc:  # no LLVM library on this machine
        pytest.skip(str(exc))
    import mitsuba

    return mitsuba


@pytest.fixture(scope="module")
def envmap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("env") / "sky.exr"
    scene.make_envmap(path, width=64, height=32)
    return path


# --------------------------------------------------------------------------
# variant
# --------------------------------------------------------------------------


@pytest.mark.parametrize("bad", ["llvm_ad_spectral", "scalar_mono", "", "LLVM_AD_RGB"])
def test_bad_variant_names_it_and_the_allowed_set(bad: str) -> None:
    with pytest.raises(ValueError) as info:
        scene.set_variant(bad)
    msg = str(info.value)
    assert repr(bad) in msg
    assert all(v in msg for v in scene.VARIANTS)


def test_unusable_backend_is_a_clear_error() -> None:
    # in a subprocess: a failed CUDA initialisation must not disturb this process's variant
    code = (
        "from brdfpipe.rendering import scene\n"
        "try:\n"
        "    scene.set_variant('cuda_ad_rgb')\n"
        "    print('OK')\n"
        "except scene.SceneError as e:\n"
        "    print('ERR', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    line = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else out.stderr
    # OK where a GPU exists; otherwise a SceneError naming the variant
    assert line == "OK" or line.startswith("ERR Mitsuba variant 'cuda_ad_rgb' is not usable"), out


# --------------------------------------------------------------------------
# environment map
# --------------------------------------------------------------------------


def test_pixel_directions_follow_mitsuba_convention() -> None:
    d = scene.envmap_pixel_directions(8, 5)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
    assert np.allclose(d[0, :, 1], 1.0) and np.allclose(d[-1, :, 1], -1.0)  # row 0 = +Y (up)
    mid = d[2]  # horizon row
    # column c at φ = 2π(c + ½)/W: columns 1|2 straddle +X, 5|6 straddle −X, 0|7 straddle −Z, 3|4 +Z
    assert np.allclose((mid[1] + mid[2]) / 2 / np.linalg.norm((mid[1] + mid[2]) / 2), [1, 0, 0])
    assert np.allclose((mid[3] + mid[4]) / 2 / np.linalg.norm((mid[3] + mid[4]) / 2), [0, 0, 1])
    assert np.allclose((mid[0] + mid[7]) / 2 / np.linalg.norm((mid[0] + mid[7]) / 2), [0, 0, -1])
    assert np.allclose(scene.sun_direction(90.0, 0.0), [0, 1, 0])
    assert np.allclose(scene.sun_direction(0.0, 90.0), [1, 0, 0])
    assert np.allclose(scene.sun_direction(0.0, 180.0), [0, 0, 1])


@pytest.mark.parametrize("elev, azim", [(35.0, scene.SUN_AZIMUTH_DEG), (60.0, 250.0), (10.0, 20.0)])
def test_envmap_sun_is_where_documented(tmp_path: Path, elev: float, azim: float) -> None:
    w, h = 256, 128
    path = tmp_path / "sky.exr"
    scene.make_envmap(path, width=w, height=h, sun_elevation_deg=elev, sun_azimuth_deg=azim, sun_radius_deg=1.0)
    img = read_exr(path)
    assert img.shape == (h, w, 3)
    r, c = np.unravel_index(np.argmax(img.sum(axis=-1)), img.shape[:2])
    d = scene.envmap_pixel_directions(w, h)[r, c]
    angle = math.degrees(math.acos(np.clip(d @ scene.sun_direction(elev, azim), -1, 1)))
    assert angle < 360.0 / w  # within one pixel
    assert math.degrees(math.asin(d[1])) == pytest.approx(elev, abs=180.0 / (h - 1))
    attrs = read_exr_attrs(path)
    assert attrs["sun_elevation_deg"] == f"{elev:g}" and attrs["sun_azimuth_deg"] == f"{azim:g}"


def test_envmap_sky_is_up_and_deterministic(tmp_path: Path) -> None:
    scene.make_envmap(tmp_path / "a.exr", width=64, height=32, sun_intensity=0.0)
    scene.make_envmap(tmp_path / "b.exr", width=64, height=32, sun_intensity=0.0)
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    img = read_exr(tmp_path / "a.exr").astype(np.float64)
    top, bottom = img[: 16].mean(), img[16:].mean()
    assert top > 2.0 * bottom  # sky above, darker ground below
    assert img[0, :, 2].mean() > img[0, :, 0].mean()  # zenith is blue


def test_mitsuba_envmap_emitter_agrees_with_the_documented_directions(mi: Any, envmap: Path) -> None:
    import drjit as dr

    em = mi.load_dict({"type": "envmap", "filename": str(envmap)})
    dirs = np.array([scene.sun_direction(35.0, scene.SUN_AZIMUTH_DEG), [0, 1, 0], [0, -1, 0],
                     scene.sun_direction(-35.0, scene.SUN_AZIMUTH_DEG)])
    si = dr.zeros(mi.SurfaceInteraction3f, len(dirs))
    si.wi = mi.Vector3f(*(-dirs.T))  # wi points away from the emitter
    val = np.array(em.eval(si)).T  # (n, 3)
    lum = val.mean(axis=1)
    sun, zenith, nadir, mirror = lum
    assert sun > 50.0 * zenith  # the sun is where sun_direction says
    assert mirror < 0.5 * zenith  # the sun's mirror image below the horizon is dark ground
    assert zenith > 2.0 * nadir  # +Y is up
    assert val[1, 2] > val[1, 0]  # blue zenith


# --------------------------------------------------------------------------
# scene and renders
# --------------------------------------------------------------------------


@pytest.mark.parametrize("emitters", [True, False])
def test_scene_loads(mi: Any, envmap: Path, emitters: bool) -> None:
    d = scene.scene_dict(PLASTIC, envmap=envmap, resolution=RES, max_depth=3, spp=4, seed=1, emitters=emitters)
    loaded = mi.load_dict(d)
    assert len(loaded.emitters()) == (2 if emitters else 1)
    # ground + sphere + cube + cylinder + cap (+ the area light's rectangle)
    assert len(loaded.shapes()) == (6 if emitters else 5)
    film = loaded.sensors()[0].film()
    assert tuple(film.size()) == RES
    assert d["sensor"]["sampler"] == {"type": "independent", "sample_count": 4, "seed": 1}
    assert d["integrator"] == {"type": "path", "max_depth": 3}
    # the material is the only thing that differs between two scenes
    other = scene.scene_dict(DIFFUSE, envmap=envmap, resolution=RES, max_depth=3, spp=4, seed=1, emitters=emitters)
    assert [k for k in d if str(d[k]) != str(other[k])] == ["material"]


def test_scene_dict_checks_its_inputs(mi: Any, envmap: Path, tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="missing.exr"):
        scene.scene_dict(PLASTIC, envmap=tmp_path / "missing.exr")
    with pytest.raises(ValueError, match="'type'"):
        scene.scene_dict({"reflectance": 0.5}, envmap=envmap)
    with pytest.raises(ValueError, match="resolution"):
        scene.scene_dict(PLASTIC, envmap=envmap, resolution=(0, 10))


def test_a_damaged_environment_map_is_refused_a_foreign_one_taken(mi: Any, envmap: Path, tmp_path: Path) -> None:
    """Mitsuba reads the map itself: the workflow's map (with its digest) is checked first; a user's HDRI
    (another program's file, no digest) is used as it is."""
    import OpenEXR

    f = OpenEXR.File(str(envmap), separate_channels=True)
    header, planes = dict(f.header()), {c: np.array(p.pixels) for c, p in f.channels().items()}
    planes["R"][5, 5] *= 100.0
    damaged = tmp_path / "results" / "renders" / "preview" / "envmap.exr"
    damaged.parent.mkdir(parents=True)
    with OpenEXR.File(header, planes) as g:
        g.write(str(damaged))
    with pytest.raises(ValueError, match=re.escape(f"{damaged}: its pixels or attributes do not match their "
                                                   "recorded digest (damaged or edited); rerun its rule: "
                                                   "snakemake --forcerun make_envmap")):
        scene.scene_dict(PLASTIC, envmap=damaged)
    header.pop("brdfpipe_digest")
    foreign = tmp_path / "hdri.exr"
    with OpenEXR.File(header, planes) as g:
        g.write(str(foreign))
    assert scene.scene_dict(PLASTIC, envmap=foreign)["sky"]["filename"] == str(foreign)


def test_pass_seeds() -> None:
    assert scene.pass_seeds(10, 3, 4) == [(3000, 4), (3001, 4), (3002, 2)]
    assert scene.pass_seeds(4, 0, 32) == [(0, 4)]
    with pytest.raises(ValueError, match="at most 1000"):
        scene.pass_seeds(2000, 0, 1)


def test_render_is_deterministic_and_records_attrs(mi: Any, envmap: Path, tmp_path: Path) -> None:
    d = scene.scene_dict(PLASTIC, envmap=envmap, resolution=RES, max_depth=3)
    lines: list[str] = []
    a = scene.render_to_exr(d, tmp_path / "a.exr", spp=8, seed=5, pass_spp=4, progress=lines.append,
                            attrs={"database": "synthetic", "material": "orange-plastic"})
    scene.render_to_exr(d, tmp_path / "b.exr", spp=8, seed=5, pass_spp=4, progress=lines.append,
                        attrs={"database": "synthetic", "material": "orange-plastic"})
    scene.render_to_exr(d, tmp_path / "c.exr", spp=8, seed=6, pass_spp=4,
                        attrs={"database": "synthetic", "material": "orange-plastic"})
    assert a.shape == (RES[1], RES[0], 3) and a.dtype == np.float32
    assert np.isfinite(a).all() and a.mean() > 0.0
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    assert (tmp_path / "a.exr").read_bytes() != (tmp_path / "c.exr").read_bytes()
    assert np.array_equal(read_exr(tmp_path / "a.exr"), a)
    assert len(lines) == 4 and "pass 1/2" in lines[0] and "8/8 spp" in lines[1]
    attrs = read_exr_attrs(tmp_path / "a.exr")
    assert attrs["database"] == "synthetic" and attrs["material"] == "orange-plastic"
    assert attrs["spp"] == "8" and attrs["seed"] == "5" and attrs["mitsuba_variant"] == "llvm_ad_rgb"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr", "b.exr", "c.exr"]  # no temp files
    with pytest.raises(ValueError, match="may not set spp"):
        scene.render_to_exr(d, tmp_path / "d.exr", spp=4, seed=0, attrs={"spp": "999"})


def test_render_bad_scene_is_a_scene_error(mi: Any, tmp_path: Path) -> None:
    with pytest.raises(scene.SceneError, match=r"x\.exr: Mitsuba could not load the scene"):
        scene.render_to_exr({"type": "scene", "shape": {"type": "no-such-plugin"}}, tmp_path / "x.exr",
                            spp=1, seed=0)
    assert not (tmp_path / "x.exr").exists()


def test_up_is_up_and_the_sun_side_is_lit(mi: Any, tmp_path: Path) -> None:
    """A diffuse sphere under the sky alone: top brighter than bottom, sun side (+X, image right) brighter."""
    env = tmp_path / "sky.exr"
    scene.make_envmap(env, width=64, height=32, sun_azimuth_deg=90.0, sun_elevation_deg=20.0)
    T = mi.ScalarTransform4f
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective",
            "fov": 40.0,
            "to_world": T().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": 24, "height": 24, "rfilter": {"type": "box"}},
        },
        "ball": {"type": "sphere", "bsdf": DIFFUSE},
        "sky": {"type": "envmap", "filename": str(env)},
    }
    img = scene.render_to_exr(d, tmp_path / "ball.exr", spp=8, seed=0).mean(axis=-1)
    # the sphere (radius 1 at distance 4, 40° fov) covers the central ~11 pixels; compare inner patches
    top, bottom = img[7:10, 10:14].mean(), img[14:17, 10:14].mean()
    left, right = img[10:14, 7:10].mean(), img[10:14, 14:17].mean()
    assert top > 1.5 * bottom
    assert right > 2.0 * left


def test_preview_render_has_sky_above_ground(mi: Any, envmap: Path, tmp_path: Path) -> None:
    d = scene.scene_dict(DIFFUSE, envmap=envmap, resolution=RES, max_depth=3, emitters=False)
    img = scene.render_to_exr(d, tmp_path / "p.exr", spp=4, seed=0)
    # the top rows show the blue sky (B > R), the bottom rows the grey checkerboard
    assert img[0, :, 2].mean() > img[0, :, 0].mean()
    assert abs(img[-1, :, 2].mean() - img[-1, :, 0].mean()) < 0.5 * img[-1].mean()


def test_render_material_uses_the_merl_plugin(mi: Any, envmap: Path, tmp_path: Path) -> None:
    """A Lambertian MERL table renders like Mitsuba's diffuse bsdf of the same albedo (same seed)."""
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    table = render.lambertian_table(0.5)
    merl.write_merl(tmp_path / "lambert.binary", table)
    kw = dict(envmap=envmap, resolution=(24, 18), spp=8, max_depth=3)
    img = scene.render_material(tmp_path / "lambert.binary", tmp_path / "m.exr", variant="llvm_ad_rgb", seed=3,
                                attrs={"database": "synthetic"}, **kw)
    ref = scene.render_to_exr(scene.scene_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}},
                                               seed=3, **kw), tmp_path / "d.exr", spp=8, seed=3)
    assert read_exr_attrs(tmp_path / "m.exr")["material_file"] == "lambert.binary"
    assert abs(img.mean() - ref.mean()) < 0.05 * ref.mean()
    scene.render_material_seeds(tmp_path / "lambert.binary", [tmp_path / "a.exr", tmp_path / "b.exr"],
                                seeds=[0, 1], variant="llvm_ad_rgb", **kw)
    assert not np.array_equal(read_exr(tmp_path / "a.exr"), read_exr(tmp_path / "b.exr"))
    with pytest.raises(render.RenderError, match="scalar_spectral"):
        scene.render_material(tmp_path / "lambert.binary", tmp_path / "x.exr", variant="scalar_spectral", seed=0, **kw)
    (tmp_path / "bad.binary").write_bytes(b"\x00" * 100)
    with pytest.raises(Exception, match="bad.binary"):
        scene.render_material(tmp_path / "bad.binary", tmp_path / "y.exr", variant="llvm_ad_rgb", seed=0, **kw)
    assert not (tmp_path / "x.exr").exists() and not (tmp_path / "y.exr").exists()
    with pytest.raises(ValueError, match="distinct seed"):
        scene.render_material_seeds(tmp_path / "lambert.binary", [tmp_path / "a.exr"], seeds=[0, 1],
                                    variant="llvm_ad_rgb", **kw)


def test_a_batch_renders_each_material_as_it_renders_alone(mi: Any, envmap: Path, tmp_path: Path) -> None:
    """render_materials (one process, one Mitsuba start): every image is the one its material gives alone,
    whatever the order of the batch (nothing of one material carries over to the next)."""
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    tables = {"grey": render.lambertian_table(0.5), "dark": render.lambertian_table(0.1),
              "red": render.lambertian_table([0.6, 0.1, 0.1])}
    for name, table in tables.items():
        merl.write_merl(tmp_path / f"{name}.binary", table)
    kw = dict(envmap=envmap, max_depth=3, variant="llvm_ad_rgb", seed=2)

    def batch(order: list[str], tag: str) -> dict[str, Path]:
        outs = {m: tmp_path / f"{tag}-{m}.exr" for m in order}
        # two settings (scene folders): the configured render and a smaller one with more samples
        scene.render_materials([tmp_path / f"{m}.binary" for m in order],
                               [[outs[m] for m in order], [tmp_path / f"{tag}-{m}-small.exr" for m in order]],
                               outs_one=[[tmp_path / f"{tag}-{m}-one.exr" for m in order],
                                         [tmp_path / f"{tag}-{m}-small-one.exr" for m in order]],
                               materials=order, settings=[((24, 18), 8), ((8, 8), 40)],
                               attrs={"database": "synthetic"}, **kw)
        return outs

    forward = batch(["grey", "dark", "red"], "f")
    backward = batch(["red", "dark", "grey"], "b")
    for m in tables:
        alone = scene.render_material(tmp_path / f"{m}.binary", tmp_path / f"alone-{m}.exr", resolution=(24, 18),
                                      spp=8, **kw)
        assert np.array_equal(read_exr(forward[m]), alone), m
        assert np.array_equal(read_exr(backward[m]), alone), m
        small = scene.render_material(tmp_path / f"{m}.binary", tmp_path / f"alone-{m}-s.exr", resolution=(8, 8),
                                      spp=40, **kw)
        assert np.array_equal(read_exr(tmp_path / f"f-{m}-small.exr"), small), m
        assert read_exr_attrs(tmp_path / f"f-{m}-small.exr")["spp"] == "40"
        assert read_exr_attrs(forward[m])["material"] == m
        assert (tmp_path / f"f-{m}-one.exr").is_file()
    # the materials differ (the batch did not render one material three times)
    assert read_exr(forward["grey"]).mean() > read_exr(forward["dark"]).mean() + 0.1
    assert not np.array_equal(read_exr(forward["grey"]), read_exr(forward["red"]))

    # a missing source stops the batch before any render, naming the file
    with pytest.raises(FileNotFoundError, match="missing.binary"):
        scene.render_materials([tmp_path / "grey.binary", tmp_path / "missing.binary"],
                               [[tmp_path / "m1.exr", tmp_path / "m2.exr"]],
                               outs_one=[[tmp_path / "m1o.exr", tmp_path / "m2o.exr"]], materials=["a", "b"],
                               settings=[((24, 18), 8)], **kw)
    assert not (tmp_path / "m1.exr").exists()
    with pytest.raises(ValueError, match="outs needs one list of 2 files per setting"):
        scene.render_materials([tmp_path / "grey.binary", tmp_path / "dark.binary"], [[tmp_path / "m1.exr"]],
                               outs_one=[[tmp_path / "a.exr", tmp_path / "b.exr"]], materials=["a", "b"],
                               settings=[((24, 18), 8)], **kw)
    with pytest.raises(ValueError, match="materials repeat"):
        scene.render_materials([tmp_path / "grey.binary", tmp_path / "dark.binary"],
                               [[tmp_path / "m1.exr", tmp_path / "m2.exr"]],
                               outs_one=[[tmp_path / "a.exr", tmp_path / "b.exr"]], materials=["a", "a"],
                               settings=[((24, 18), 8)], **kw)
    with pytest.raises(ValueError, match="named twice"):
        scene.render_materials([tmp_path / "grey.binary"], [[tmp_path / "m1.exr"]],
                               outs_one=[[tmp_path / "m1.exr"]], materials=["a"], settings=[((24, 18), 8)], **kw)


def test_path_points_render_in_one_call_as_each_alone(mi: Any, envmap: Path, tmp_path: Path) -> None:
    """render_points: two seeds per point, the same images as render_material_seeds point by point."""
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    for name, albedo in (("p0", 0.3), ("p1", 0.7)):
        merl.write_merl(tmp_path / f"{name}.binary", render.lambertian_table(albedo))
    kw = dict(envmap=envmap, resolution=(24, 18), spp=8, max_depth=3, variant="llvm_ad_rgb")
    outs = [[tmp_path / f"{p}-s{s}.exr" for s in (0, 1)] for p in ("p0", "p1")]
    ones = [[tmp_path / f"{p}-s{s}-one.exr" for s in (0, 1)] for p in ("p0", "p1")]
    scene.render_points([tmp_path / "p0.binary", tmp_path / "p1.binary"], outs=outs, outs_one=ones,
                        seeds=[0, 1], labels=["a--b-t0.25", "a--b-t0.75"], attrs={"database": "synthetic"}, **kw)
    for k, p in enumerate(("p0", "p1")):
        alone = [tmp_path / f"alone-{p}-{s}.exr" for s in (0, 1)]
        scene.render_material_seeds(tmp_path / f"{p}.binary", alone, seeds=[0, 1], **kw)
        for s in (0, 1):
            assert np.array_equal(read_exr(outs[k][s]), read_exr(alone[s])), (p, s)
        assert not np.array_equal(read_exr(outs[k][0]), read_exr(outs[k][1]))  # two seeds, two images
        assert read_exr_attrs(outs[k][0])["path_point"] == ["a--b-t0.25", "a--b-t0.75"][k]
    with pytest.raises(ValueError, match="one output per seed"):
        scene.render_points([tmp_path / "p0.binary"], outs=[[tmp_path / "x.exr"]], outs_one=[[tmp_path / "y.exr"]],
                            seeds=[0, 1], labels=["a"], **kw)
    with pytest.raises(FileNotFoundError, match="nope.binary"):
        scene.render_points([tmp_path / "nope.binary"], outs=[[tmp_path / "x.exr", tmp_path / "x2.exr"]],
                            outs_one=[[tmp_path / "y.exr", tmp_path / "y2.exr"]], seeds=[0, 1], labels=["a"], **kw)
    assert not (tmp_path / "x.exr").exists()


def test_one_thread_render_finishes_and_equals_two_threads(mi: Any, envmap: Path, tmp_path: Path) -> None:
    """A job given one core (Snakemake --cores 1) renders, and the image does not depend on the thread count.

    Mitsuba 3.9 never finishes loading an environment map with Dr.Jit's worker
    pool disabled; run in a fresh process, with a timeout, so a hang fails.
    """
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    merl.write_merl(tmp_path / "lambert.binary", render.lambertian_table(0.5))
    code = (
        "import sys; from brdfpipe.rendering import scene\n"
        "scene.render_material(sys.argv[1], sys.argv[2], envmap=sys.argv[3], variant='llvm_ad_rgb',"
        " resolution=(24, 18), spp=8, max_depth=3, seed=0, threads=int(sys.argv[4]))\n"
    )
    for threads in (1, 2):
        subprocess.run([sys.executable, "-c", code, str(tmp_path / "lambert.binary"), str(tmp_path / f"t{threads}.exr"),
                        str(envmap), str(threads)], check=True, timeout=120)
    assert np.array_equal(read_exr(tmp_path / "t1.exr"), read_exr(tmp_path / "t2.exr"))


@pytest.mark.parametrize(("size", "spp", "expected"), [
    ((256, 192), 64, 32),      # the default render: passes of 32, as always
    ((1024, 768), 64, 32),     # larger images never take larger passes
    ((48, 36), 4096, 512),     # the floor check: 8 passes instead of 128
    ((16, 12), 64, 64),        # one pass: never more than spp
    ((32, 24), 4, 32),         # one pass either way: the default, as always
    ((48, 36), 32, 32),
    ((257, 192), 64, 32),
])
def test_small_images_render_in_fewer_larger_passes(size: tuple[int, int], spp: int, expected: int) -> None:
    p = scene.auto_pass_spp(*size, spp)
    assert p == expected
    assert size[0] * size[1] * p <= max(scene.PASS_SAMPLES, size[0] * size[1] * scene.DEFAULT_PASS_SPP)


def test_render_material_records_its_pass_size(mi: Any, envmap: Path, tmp_path: Path) -> None:
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    merl.write_merl(tmp_path / "lambert.binary", render.lambertian_table(0.5))
    scene.render_material(tmp_path / "lambert.binary", tmp_path / "m.exr", envmap=envmap, resolution=(16, 12),
                          spp=200, max_depth=2, variant="llvm_ad_rgb", seed=0)
    attrs = read_exr_attrs(tmp_path / "m.exr")
    assert attrs["pass_spp"] == str(scene.auto_pass_spp(16, 12, 200)) == "200" and attrs["spp"] == "200"
