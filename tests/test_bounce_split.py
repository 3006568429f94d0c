"""Tests of :mod:`brdfpipe.rendering.bounce`: the I¹⁻ / I²⁺ split of Soler et al. 2018 §5.2.

Small renders (48 × 36 or 64 × 48 pixels, the preview scene of
:mod:`brdfpipe.rendering.scene`, ``llvm_ad_rgb``).  Statistical checks compare image
means with a tolerance derived from the noise: pixels are independent
(``independent`` sampler), so the standard error of the mean over ``N``
pixels of a per-pixel difference ``d`` whose expectation is 0 in every pixel
is ``sqrt(Σ d²) / N``; a check asserts ``|mean d| < Z · SE`` with
:data:`Z` = 4 (a false failure about once in 16,000 runs), and each such
test also shows that it would catch a bias of the size it cares about.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from brdfpipe.data import merl
from brdfpipe.rendering import bounce, render, scene

VARIANT = "llvm_ad_rgb"
Z = 4.0


@pytest.fixture(scope="module")
def mi() -> Any:
    try:
        render.use_variant(VARIANT)
    except render.RenderError as exc:
        pytest.skip(str(exc))
    render.register_merl_bsdf()
    bounce.register_bounce_integrator()
    import mitsuba

    return mitsuba


@pytest.fixture(scope="module")
def envmap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("env") / "sky.exr"
    scene.make_envmap(path, width=64, height=32)
    return path


@pytest.fixture(scope="module")
def tables(mi: Any, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """MERL files: two Lambertian tables, a glossy gold, and the 50/50 mixes of pairs."""
    folder = tmp_path_factory.mktemp("merl")
    t = {
        "white": render.lambertian_table(0.95),
        "dark": render.lambertian_table([0.15, 0.05, 0.02]),
        "gold": render.tabulate_bsdf({"type": "roughconductor", "material": "Au", "alpha": 0.15}),
    }
    t["gold"] = np.maximum(t["gold"], 0.0)  # below-horizon cells black, so the mix is exact
    t["white+dark"] = 0.5 * t["white"] + 0.5 * t["dark"]
    t["white+gold"] = 0.5 * t["white"] + 0.5 * t["gold"]
    out = {}
    for name, table in t.items():
        out[name] = folder / f"{name}.binary"
        merl.write_merl(out[name], table)
    return out


def _render(mi: Any, envmap: Path, bsdf: dict[str, Any], *, integrator: dict[str, Any], spp: int,
            seed: int, res: tuple[int, int] = (48, 36), max_depth: int = 6) -> np.ndarray:
    d = scene.scene_dict(bsdf, envmap=envmap, resolution=res, max_depth=max_depth, spp=spp)
    d["integrator"] = integrator
    return np.asarray(mi.render(render.load_scene(d), seed=seed, spp=spp), dtype=np.float64)


def _split(mi: Any, envmap: Path, bsdf: dict[str, Any], *, spp: int, seed: int,
           max_depth: int = 6, res: tuple[int, int] = (48, 36)) -> np.ndarray:
    img = _render(mi, envmap, bsdf, integrator=bounce.bounce_integrator(max_depth), spp=spp, seed=seed,
                  res=res, max_depth=max_depth)
    assert img.shape[2] == 3 + len(bounce.AOV_NAMES)
    return img


def _z(d: np.ndarray) -> float:
    """Mean of the per-pixel differences ``d`` (H, W) in units of its standard error under E[d] = 0."""
    n = d.size
    se = float(np.sqrt(np.sum(np.square(d)))) / n
    z = float(d.mean()) / se if se > 0 else 0.0
    print(f"z = {z:.3g} over {n} pixels")
    return z


PLASTIC = {"type": "roughplastic", "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.5, 0.2]}}


def test_total_is_mitsubas_path_integrator(mi: Any, envmap: Path) -> None:
    path = {"type": "path", "max_depth": 6}
    split = bounce.bounce_integrator(6)
    # same seed: the same sampler draws, so the same paths (equal up to float rounding)
    a = _render(mi, envmap, PLASTIC, integrator=path, spp=16, seed=3)
    b = _render(mi, envmap, PLASTIC, integrator=split, spp=16, seed=3)
    assert np.allclose(b[..., :3], a[..., :3], rtol=1e-4, atol=1e-5)
    # independent seeds: equal in expectation (image mean and per-pixel z-scores)
    a = _render(mi, envmap, PLASTIC, integrator=path, spp=64, seed=0)
    b = _render(mi, envmap, PLASTIC, integrator=split, spp=64, seed=1)
    d = (b[..., :3] - a[..., :3]).mean(axis=2)
    assert abs(_z(d)) < Z
    # the check has power: a 3 % bias of the total would fail it
    assert abs(_z(1.03 * b[..., :3].mean(axis=2) - a[..., :3].mean(axis=2))) > Z


def test_total_matches_path_with_a_merl_material(mi: Any, envmap: Path, tables: dict[str, Path]) -> None:
    bsdf = render.merl_bsdf(tables["gold"])
    a = _render(mi, envmap, bsdf, integrator={"type": "path", "max_depth": 6}, spp=16, seed=5)
    b = _render(mi, envmap, bsdf, integrator=bounce.bounce_integrator(6), spp=16, seed=5)
    assert np.allclose(b[..., :3], a[..., :3], rtol=1e-4, atol=1e-5)


def test_one_bounce_has_no_second_part(mi: Any, envmap: Path, tables: dict[str, Path]) -> None:
    img = _split(mi, envmap, render.merl_bsdf(tables["white"]), spp=16, seed=0, max_depth=2)
    assert np.array_equal(img[..., 3:6], img[..., :3])  # I²⁺ exactly 0
    # …while deeper paths do scatter twice on the white object
    img = _split(mi, envmap, render.merl_bsdf(tables["white"]), spp=16, seed=0, max_depth=3)
    second = img[..., :3] - img[..., 3:6]
    assert second.min() >= -1e-5 * img[..., :3].max()
    assert second.mean() > 0.01 * img[..., :3].mean()


def test_object_mask(mi: Any, envmap: Path, tables: dict[str, Path]) -> None:
    img = _split(mi, envmap, render.merl_bsdf(tables["white"]), spp=4, seed=0, max_depth=1)
    mask = img[..., 6]
    assert set(np.unique(mask)) <= {0.0, 0.25, 0.5, 0.75, 1.0}
    h, w = mask.shape
    assert mask[h // 2, w // 2] == 1.0  # the sphere
    assert mask[0, 0] == 0.0 and mask[h - 1, 0] == 0.0  # sky, ground
    assert 0.15 < mask.mean() < 0.6


@pytest.mark.parametrize("pair", [("white", "dark"), ("white", "gold")])
def test_first_part_is_linear_in_the_material(mi: Any, envmap: Path, tables: dict[str, Path],
                                              pair: tuple[str, str]) -> None:
    a, b = pair
    spp, res = 128, (48, 36)
    ia, ib, im = (_split(mi, envmap, render.merl_bsdf(tables[n]), spp=spp, seed=s, res=res)
                  for n, s in ((a, 10), (b, 11), (f"{a}+{b}", 12)))
    one = {k: v[..., 3:6] for k, v in (("a", ia), ("b", ib), ("m", im))}
    d_one = (one["m"] - 0.5 * (one["a"] + one["b"])).mean(axis=2)
    assert abs(_z(d_one)) < Z
    obj = im[..., 6] >= 0.5
    assert abs(_z(d_one[obj])) < Z
    # the check has power: a bias of 5 % of the object's I¹⁻ would be caught
    assert abs(_z(d_one[obj] + 0.05 * one["m"].mean(axis=2)[obj])) > Z
    if (a, b) == ("white", "dark"):
        # I²⁺ is quadratic: for Lambertian tables with albedos a, b the mix has
        # ((a+b)/2)² < (a² + b²)/2, so the blend of I²⁺ overestimates the mix's
        second = {k: v[..., :3] - v[..., 3:6] for k, v in (("a", ia), ("b", ib), ("m", im))}
        d_two = (0.5 * (second["a"] + second["b"]) - second["m"]).mean(axis=2)
        assert _z(d_two[obj]) > Z


def test_missing_material_is_a_clear_error(mi: Any, envmap: Path) -> None:
    with pytest.raises(Exception) as info:
        _render(mi, envmap, PLASTIC, integrator={**bounce.bounce_integrator(3), "material_id": "nope"},
                spp=1, seed=0)
    chain = []
    err: BaseException | None = info.value
    while err is not None:  # mi.render wraps the integrator's error
        chain.append(str(err))
        err = err.__cause__
    assert any("no shape of the scene has a bsdf with id 'nope'" in m for m in chain), chain


def test_render_material_writes_both_parts_from_one_render(mi: Any, envmap: Path, tables: dict[str, Path],
                                                           tmp_path: Path) -> None:
    from brdfpipe.core.exr import read_exr, read_exr_attrs

    kw = dict(envmap=envmap, variant=VARIANT, resolution=(32, 24), spp=8, max_depth=4, seed=2)
    whole = scene.render_material(tables["white"], tmp_path / "i.exr", out_one=tmp_path / "one.exr", **kw)
    one = read_exr(tmp_path / "one.exr")
    assert np.array_equal(read_exr(tmp_path / "i.exr"), whole)
    assert (one <= whole + 1e-5 * whole.max()).all() and one.mean() < whole.mean()
    assert read_exr_attrs(tmp_path / "one.exr")["image"].startswith("I1-")
    # the whole image is the stock path integrator's (same passes and seeds)
    d = scene.scene_dict(render.merl_bsdf(tables["white"]), envmap=envmap, resolution=(32, 24), max_depth=4,
                         spp=8, seed=2)
    ref = scene.render_to_exr(d, tmp_path / "path.exr", spp=8, seed=2)
    assert np.allclose(whole, ref, rtol=1e-4, atol=1e-5)
    # same inputs, same bytes; without out_one the whole image is unchanged
    scene.render_material(tables["white"], tmp_path / "i2.exr", out_one=tmp_path / "one2.exr", **kw)
    scene.render_material(tables["white"], tmp_path / "i3.exr", **kw)
    assert (tmp_path / "one2.exr").read_bytes() == (tmp_path / "one.exr").read_bytes()
    assert np.array_equal(read_exr(tmp_path / "i3.exr"), whole)
    mask = scene.render_object_mask(tmp_path / "mask.exr", envmap=envmap, variant=VARIANT, resolution=(32, 24),
                                    spp=4, seed=0)
    assert mask.shape == (24, 32) and mask[12, 16] == 1.0 and mask[0, 0] == 0.0
    with pytest.raises(scene.SceneError, match="bouncesplit"):
        scene.render_split_to_exr(d, tmp_path / "x.exr", spp=1, seed=0)
