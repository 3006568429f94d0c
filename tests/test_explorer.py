"""The in-browser explorer: its export (no browser) and the page in headless Chromium.

The browser tests need Debian's ``chromium`` (``make test`` installs it when
run as root) and are skipped with the reason otherwise.  The fixture is a
small synthetic input (tests/explorer_fixture.py): 12 materials of 48 × 36
pixels, GPLVM fits at q = 2 and 5, two rendered path points.
"""

from __future__ import annotations

import base64
import functools
import http.server
import json
import re
import shutil
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.linalg

sys.path.insert(0, str(Path(__file__).resolve().parent))
from explorer_fixture import make_inputs  # noqa: E402

from brdfpipe.core import exr, integrity  # noqa: E402
from brdfpipe.manifold import fitting, gplvm, latent  # noqa: E402
from brdfpipe.rendering import blend  # noqa: E402
from brdfpipe.explorer import chromium, export  # noqa: E402


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return make_inputs(tmp_path_factory.mktemp("explorer-inputs"))


@pytest.fixture(scope="module")
def site(inputs: dict, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("explorer-site") / "explorer"
    export.write_explorer(out=out, **inputs)
    return out


def images_of(inputs: dict) -> np.ndarray:
    names = list(gplvm.load_model(inputs["models"][0]).names)
    return np.stack([exr.read_exr(inputs["prerenders"][n]) for n in names]).astype(np.float64)


def b64_array(text: str, dtype: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype=dtype)


def read_data_file(path: Path) -> Any:
    """The value a ``data/*.js`` file assigns, its CRC-32 checked as the page checks it."""
    body = path.read_text(encoding="ascii").partition("] = ")[2].rstrip()
    record = json.loads(body.removesuffix(";"))
    assert integrity.text_crc32(record["json"]) == record["crc32"], path
    return json.loads(record["json"])


def unpack_halves(words: np.ndarray, n: int) -> np.ndarray:
    """Inverse of :func:`export.pack_halves`: the first ``n`` images ``(n, H, W, 3)`` float16."""
    layers, hh, ww, _ = words.shape
    g = layers // 3
    w = words.astype(np.uint32).reshape(3, g, hh, ww, 4).transpose(1, 4, 2, 3, 0)  # G, j, H, W, channel
    bits = np.stack([(w & 0xFFFF).astype(np.uint16), (w >> 16).astype(np.uint16)], axis=2)
    return bits.reshape(g * export.PER_TEXEL, hh, ww, 3)[:n].view(np.float16)


# --------------------------------------------------------------------------
# The export, without a browser
# --------------------------------------------------------------------------


def test_blend_tiles_lists_the_tiles_where_the_images_differ() -> None:
    rng = np.random.default_rng(0)
    imgs = np.repeat(rng.random((1, 20, 27, 3)), 4, axis=0)  # 3 x 4 tiles of 8, the last row and column partial
    assert export.blend_tiles(imgs).size == 0
    imgs[2, 9, 26, 1] += 1.0  # tile row 1, column 3 (partial)
    imgs[1, 19, 0, 0] -= 0.5  # tile row 2 (partial), column 0
    assert export.blend_tiles(imgs).tolist() == [1 * 4 + 3, 2 * 4 + 0]
    # a mean + components basis: tiles where a component after the first is non-zero
    basis = np.zeros((3, 20, 27, 3))
    basis[0] = 1.0
    assert export.blend_tiles(basis, zero_after_first=True).size == 0
    basis[2, 0, 8, 2] = -1e-3
    assert export.blend_tiles(basis, zero_after_first=True).tolist() == [1]
    assert export.blend_tiles(basis[:1], zero_after_first=True).size == 0
    with pytest.raises(export.ExplorerError, match="expected a stack"):
        export.blend_tiles(imgs[0])


def test_pack_halves_round_trips_and_puts_eight_images_in_a_texel() -> None:
    rng = np.random.default_rng(0)
    imgs = rng.uniform(-2, 2, size=(13, 3, 5, 3)).astype(np.float16)
    words = export.pack_halves(imgs)
    assert words.shape == (3 * 2, 3, 5, 4) and words.dtype == np.uint32
    assert np.array_equal(unpack_halves(words, 13).view(np.uint16), imgs.view(np.uint16))
    # layer c*G + g, component j: image 8g + 2j in the low half, 8g + 2j + 1 in the high half
    c, g, j, y, x = 2, 1, 1, 2, 4
    word = int(words[c * 2 + g, y, x, j])
    assert word & 0xFFFF == imgs[8 * g + 2 * j, y, x, c].view(np.uint16)
    assert word >> 16 == imgs[8 * g + 2 * j + 1, y, x, c].view(np.uint16)
    assert int(words[c * 2 + 1, y, x, 3]) == 0  # images 14, 15 do not exist: zero


def test_exported_model_gives_gplvm_weights_and_the_images(inputs: dict, site: Path) -> None:
    doc = read_data_file(site / "data" / "model.js")
    manifest = integrity.read_json(site / "manifest.json")
    assert doc["manifest"]["materials"] == manifest["materials"] and manifest["format"] == export.FORMAT
    assert manifest["default_q"] == 2 and [m["q"] for m in manifest["models"]] == [2, 5]
    rng = np.random.default_rng(1)
    for path, mdoc in zip(inputs["models"], doc["models"]):
        model = gplvm.load_model(path)
        n, q = model.X.shape
        X = b64_array(mdoc["X"], "<f8").reshape(n, q)
        L = b64_array(mdoc["chol"], "<f8").reshape(n, n)
        assert np.array_equal(X, model.X) and np.array_equal(L, model.chol)
        assert (mdoc["ell"], mdoc["mu"]) == (model.ell, model.mu)
        # the page's arithmetic: forward and back substitution with L, mu where x is a training point
        for x in [*rng.normal(size=(5, q)), model.X[3]]:
            d2 = ((X - x) ** 2).sum(axis=1)
            k = np.exp(-d2 / (2 * mdoc["ell"] ** 2)) + mdoc["mu"] * (d2 == 0)
            b = scipy.linalg.solve_triangular(L.T, scipy.linalg.solve_triangular(L, k, lower=True), lower=False)
            np.testing.assert_allclose(b, gplvm.weights(model, x), rtol=0, atol=1e-10 * np.abs(b).max())
    # the packed layers are the pre-renders rounded to half floats
    layers = read_data_file(site / "data" / "layers.js")
    imgs = images_of(inputs)
    words = b64_array(layers["data"], "<u4").reshape(layers["layers"], manifest["height"], manifest["width"], 4)
    got = unpack_halves(words, layers["n"]).astype(np.float64)
    np.testing.assert_array_equal(got, imgs.astype(np.float16).astype(np.float64))
    albedo = b64_array(doc["albedo"], "<f8").reshape(-1, 3)
    assert albedo.shape == (len(manifest["materials"]), 3) and np.all((albedo > 0) & (albedo < 1))


def test_reduced_basis_meets_its_target_with_the_fewest_components(inputs: dict, site: Path) -> None:
    manifest = integrity.read_json(site / "manifest.json")
    basis = manifest["basis"]
    assert basis["floor"] == pytest.approx(0.05 / np.sqrt(2)) and basis["target"] == basis["floor"]
    imgs = images_of(inputs)
    n = imgs.shape[0]
    data = read_data_file(site / "data" / "basis.js")
    k1 = data["n"]
    assert k1 == basis["k"] + 1
    words = b64_array(data["data"], "<u4").reshape(data["layers"], manifest["height"], manifest["width"], 4)
    B = unpack_halves(words, k1).astype(np.float64).reshape(k1, -1)
    C = b64_array(data["coef"], "<f8").reshape(n, k1)
    recon = C @ B  # every pre-render from the shipped basis (w = e_i)
    flat = imgs.reshape(n, -1)
    err = np.sqrt(np.mean((recon - flat) ** 2, axis=1)) / flat.mean(axis=1)
    assert err.max() == pytest.approx(basis["error_prerenders_max"], rel=1e-6)
    assert basis["below_floor"] and max(err.max(), basis["error_blends_max"]) <= basis["target"]
    # one component fewer misses the target (on the pre-renders or the blends)
    mean, full, cu = export.reduced_basis(imgs)
    model = gplvm.load_model(inputs["models"][0])
    pts = latent.sample_in_hull(model.X, 64, np.random.default_rng(0))
    W = np.concatenate([np.eye(n), [gplvm.blend_weights(gplvm.weights(model, x)) for x in pts]])
    assert export.truncation_errors(imgs, W, mean, full, cu, basis["k"] - 1).max() > basis["target"]


def test_without_a_summary_the_fallback_target_and_a_q1_model(inputs: dict, tmp_path: Path) -> None:
    names = list(gplvm.load_model(inputs["models"][0]).names)
    rng = np.random.default_rng(2)
    g = rng.normal(size=(len(names), 30))
    fit = fitting.fit(g @ g.T / 30, 30, q=1, mu=1e-4, seed=0, max_sweeps=5, method="hooke-jeeves")
    q1 = tmp_path / "q1.npz"
    gplvm.save_model(q1, fit, names, space="log")
    out = tmp_path / "explorer"
    m = export.write_explorer(out=out, models=[q1], prerenders=inputs["prerenders"], albedo=inputs["albedo"])
    assert m["basis"]["floor"] is None and m["basis"]["target"] == export.FALLBACK_TARGET
    assert m["default_q"] == 1 and not m["linear"] and m["paths"] == []
    doc = read_data_file(out / "data" / "model.js")
    lo, hi = doc["models"][0]["hull"]["interval"]
    assert (lo, hi) == (fit.X.min(), fit.X.max())


def test_bad_inputs_fail_naming_the_file_and_keep_the_earlier_output(inputs: dict, site: Path, tmp_path: Path) -> None:
    out = tmp_path / "explorer"
    shutil.copytree(site, out)
    before = (out / "manifest.json").read_bytes()
    missing = dict(inputs["prerenders"])
    gone = sorted(missing)[3]
    del missing[gone]
    with pytest.raises(export.ExplorerError, match=f"no pre-render for {gone}"):
        export.write_explorer(out=out, **{**inputs, "prerenders": missing})
    bad = tmp_path / "albedo.csv"
    bad.write_text("material,r\nx,1\n")
    with pytest.raises(export.ExplorerError, match=str(bad) + ": albedo table carries no brdfpipe digest"):
        export.write_explorer(out=out, **{**inputs, "albedo": str(bad)})
    integrity.write_csv(bad, "material,r\nx,1\n")
    with pytest.raises(export.ExplorerError, match=str(bad) + ": not an albedo table"):
        export.write_explorer(out=out, **{**inputs, "albedo": str(bad)})
    assert (out / "manifest.json").read_bytes() == before
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    from brdfpipe.core.atomic import OutputError

    with pytest.raises(OutputError, match="not an output of this kind"):
        export.write_explorer(out=foreign, **inputs)
    assert (foreign / "notes.txt").read_text() == "mine"


def test_export_is_deterministic(inputs: dict, site: Path, tmp_path: Path) -> None:
    again = tmp_path / "explorer"
    export.write_explorer(out=again, **inputs)
    for f in sorted(p.relative_to(site) for p in site.rglob("*") if p.is_file()):
        assert (again / f).read_bytes() == (site / f).read_bytes(), f


# --------------------------------------------------------------------------
# The page in headless Chromium
# --------------------------------------------------------------------------

needs_chromium = pytest.mark.skipif(chromium.find_chromium() is None,
                                    reason="no chromium (Debian: apt-get install chromium; make test installs it as root)")
READY = "window.explorer && (window.explorer.ready || window.explorer.error)"


@pytest.fixture(scope="module")
def page(site: Path):
    if chromium.find_chromium() is None:
        pytest.skip("no chromium (Debian: apt-get install chromium; make test installs it as root)")
    with chromium.Browser() as b:
        b.open(site / "index.html", ready=READY)
        assert b.evaluate("explorer.error") is None, b.evaluate("explorer.error")
        yield b


def canvas(b: chromium.Browser, manifest: dict) -> np.ndarray:
    px = b64_array(b.evaluate("explorer.canvasPixels()"), "u1")
    return px.reshape(manifest["height"], manifest["width"], 4)[..., :3]


def linear_blend(b: chromium.Browser, **opts) -> tuple[np.ndarray, np.ndarray]:
    r = b.evaluate(f"explorer.debugBlend({json.dumps(opts)})")
    rgb = b64_array(r["rgb"], "<f4").reshape(r["height"], r["width"], 3).astype(np.float64)
    return rgb, np.array(r["weights"])


@needs_chromium
def test_page_loads_without_errors_and_draws(page: chromium.Browser) -> None:
    assert page.errors == [], page.errors
    m = page.evaluate("explorer.manifest")
    img = canvas(page, m)
    assert img.std() > 5 and img.max() > 50  # not blank
    assert page.evaluate("document.getElementById('weights').tBodies[0].rows.length") == 8


@needs_chromium
def test_pointer_moves_change_the_image(page: chromium.Browser, inputs: dict) -> None:
    page.evaluate("explorer.setMode('map')")
    page.evaluate("explorer.setModel(2)")
    m = page.evaluate("explorer.manifest")
    model = gplvm.load_model(inputs["models"][0])
    shots = []
    for j in (0, 5):
        x, y = page.evaluate(f"explorer.mapToPage({json.dumps(list(model.X[j] * 0.9 + model.X.mean(0) * 0.1))})")
        page.mouse("mouseMoved", x, y)
        page.evaluate("new Promise(r => requestAnimationFrame(() => r(1)))")
        shots.append((canvas(page, m), page.evaluate("explorer.state().point")))
    (a, pa), (b, pb) = shots
    assert pa != pb and np.abs(a.astype(int) - b.astype(int)).mean() > 1.0
    # the point under the pointer: the state's weights are the GPLVM's there
    w = np.array(page.evaluate("explorer.state().w"))
    np.testing.assert_allclose(w, gplvm.blend_weights(gplvm.weights(model, np.array(pb))), rtol=0, atol=1e-9)
    # a click on a material puts the point exactly on it: w = e_i (exact reproduction)
    x, y = page.evaluate(f"explorer.mapToPage({json.dumps(list(model.X[4]))})")
    page.mouse("mousePressed", x, y, buttons=1)
    page.mouse("mouseReleased", x, y)
    w = np.array(page.evaluate("explorer.state().w"))
    np.testing.assert_allclose(w, np.eye(len(w))[4], atol=1e-9)
    assert page.errors == []


def _overlap(a: dict, b: dict) -> bool:
    return a["x"] < b["x"] + b["w"] and b["x"] < a["x"] + a["w"] and a["y"] < b["y"] + b["h"] and b["y"] < a["y"] + a["h"]


@needs_chromium
def test_map_labels_never_overlap_and_a_dense_cluster_keeps_the_labels_that_fit(page: chromium.Browser) -> None:
    """Issue 24 item 7: the labels of a dense cluster no longer overlap into an unreadable block."""
    page.evaluate("explorer.setMode('map')")
    page.evaluate("explorer.setModel(2)")
    mw, mh = page.evaluate("explorer.mapSize()")
    drawn = page.evaluate("explorer.labels()")
    assert drawn and all(not _overlap(a, b) for i, a in enumerate(drawn) for b in drawn[i + 1:])
    assert all(0 <= l["x"] and l["x"] + l["w"] <= mw and 0 <= l["y"] and l["y"] + l["h"] <= mh for l in drawn)
    # 60 points within 40 pixels (a MERL-like cluster): the placement keeps only labels that fit, none overlapping
    rng = np.random.default_rng(3)
    pts = [{"name": f"material-{k:02d}", "px": float(260 + 20 * u), "py": float(220 + 20 * v)}
           for k, (u, v) in enumerate(rng.uniform(-1, 1, size=(60, 2)))]
    placed = page.evaluate(f"explorer.placeLabels({json.dumps(pts)})")
    assert 3 <= len(placed) < 60
    assert all(not _overlap(a, b) for i, a in enumerate(placed) for b in placed[i + 1:])
    # no label covers another point's marker (5 pixels around its centre)
    names = {p["name"]: p for p in pts}
    for lab in placed:
        for p in pts:
            if p["name"] != lab["name"]:
                marker = {"x": p["px"] - 5, "y": p["py"] - 5, "w": 10, "h": 10}
                assert not _overlap(lab, marker), (lab, p)
        p = names[lab["name"]]  # and each label sits next to its own point
        assert abs(lab["x"] + lab["w"] / 2 - p["px"]) <= lab["w"] / 2 + 8 and abs(lab["y"] + lab["h"] / 2 - p["py"]) <= 13
    # spread the same points 8 times wider (as zooming in does): more of them get their label
    wide = [{**p, "px": 260 + 8 * (p["px"] - 260), "py": 220 + 8 * (p["py"] - 220)} for p in pts]
    assert len(page.evaluate(f"explorer.placeLabels({json.dumps(wide)})")) > len(placed)
    assert page.errors == []


@needs_chromium
def test_wheel_zooms_about_the_pointer_and_drag_pans_the_map(page: chromium.Browser, inputs: dict) -> None:
    page.evaluate("explorer.setMode('map')")
    page.evaluate("explorer.setModel(2)")
    model = gplvm.load_model(inputs["models"][0])
    # pointer events carry whole page pixels: hover one, and its latent point (the state's) is the anchor
    x, y = (round(v) for v in page.evaluate(f"explorer.mapToPage({json.dumps(list(model.X[3]))})"))
    page.mouse("mouseMoved", x, y)
    anchor = page.evaluate("explorer.state().point")
    assert page.evaluate(f"explorer.mapToPage({json.dumps(anchor)})") == pytest.approx([x, y], abs=1e-6)
    other = list(model.X[7])
    ox, oy = page.evaluate(f"explorer.mapToPage({json.dumps(other)})")
    for _ in range(4):
        page.wheel(x, y, -120)
    view = page.evaluate("explorer.view()")
    assert view["zoom"] == pytest.approx(1.2 ** 4.8, rel=1e-6)
    # the latent point under the pointer stays under it; the others move away from it by the zoom factor
    assert page.evaluate(f"explorer.mapToPage({json.dumps(anchor)})") == pytest.approx([x, y], abs=1e-6)
    ox2, oy2 = page.evaluate(f"explorer.mapToPage({json.dumps(other)})")
    assert [ox2 - x, oy2 - y] == pytest.approx([view["zoom"] * (ox - x), view["zoom"] * (oy - y)], rel=1e-6)
    # a drag pans by the drag, and leaves the point where the press put it
    page.mouse("mouseMoved", x + 3, y + 60)
    page.mouse("mousePressed", x + 3, y + 60, buttons=1)
    point = page.evaluate("explorer.state().point")
    for k in range(1, 5):
        page.mouse("mouseMoved", x + 3 + 10 * k, y + 60 + 5 * k, buttons=1)
    page.mouse("mouseReleased", x + 43, y + 80)
    assert page.evaluate(f"explorer.mapToPage({json.dumps(anchor)})") == pytest.approx([x + 40, y + 20], abs=1e-6)
    assert page.evaluate("explorer.state().point") == point
    # hovering after the drag moves the point again; a double click resets the view
    page.mouse("mouseMoved", x + 50, y + 90)
    assert page.evaluate("explorer.state().point") != point
    page.call("Input.dispatchMouseEvent", {"type": "mousePressed", "x": x, "y": y, "button": "left", "clickCount": 2})
    page.call("Input.dispatchMouseEvent", {"type": "mouseReleased", "x": x, "y": y, "button": "left", "clickCount": 2})
    assert page.evaluate("explorer.view()") == {"zoom": 1, "dx": 0, "dy": 0}
    assert page.errors == []


@needs_chromium
def test_the_nearest_materials_are_listed_under_the_pointer(page: chromium.Browser, inputs: dict) -> None:
    page.evaluate("explorer.setMode('map')")
    for path in inputs["models"]:
        model = gplvm.load_model(path)
        page.evaluate(f"explorer.setModel({model.X.shape[1]})")
        x = model.X.mean(0) + 0.3 * (model.X[2] - model.X.mean(0))
        page.evaluate(f"explorer.setPoint({json.dumps(list(x))})")
        d = np.linalg.norm(model.X - x, axis=1)
        want = [model.names[j] for j in np.argsort(d, kind="stable")[:5]]
        got = page.evaluate("explorer.nearest()")
        assert [n["name"] for n in got] == want
        assert [n["d"] for n in got] == pytest.approx(np.sort(d)[:5].tolist(), rel=1e-9)
        shown = page.evaluate("Array.from(document.querySelectorAll('#nearest button'), b => b.textContent)")
        assert [t.rsplit(" (", 1)[0] for t in shown] == want
    # a click on a listed material puts the point on it: w = e_i
    first = page.evaluate("explorer.nearest()[0].name")
    page.evaluate("document.querySelector('#nearest button').click()")
    w = np.array(page.evaluate("explorer.state().w"))
    names = list(gplvm.load_model(inputs["models"][-1]).names)
    np.testing.assert_allclose(w, np.eye(len(w))[names.index(first)], atol=1e-9)
    page.evaluate("explorer.setModel(2)")  # the page is shared by the module's tests: back to the first model
    assert page.errors == []


@needs_chromium
def test_weights_and_hull_in_the_page_equal_the_library(page: chromium.Browser, inputs: dict) -> None:
    rng = np.random.default_rng(5)
    for path in inputs["models"]:
        model = gplvm.load_model(path)
        q = model.X.shape[1]
        pts = np.concatenate([rng.normal(scale=model.X.std() * 1.5, size=(20, q)), model.X[:2]])
        inside = latent.hull_contains(model.X, pts)
        assert inside.any() and not inside.all()
        for x, ins in zip(pts, inside):
            r = page.evaluate(f"explorer.weightsAt({q}, {json.dumps(list(x))})")
            b = gplvm.weights(model, x)
            np.testing.assert_allclose(r["b"], b, rtol=0, atol=1e-10 * max(1.0, np.abs(b).max()))
            np.testing.assert_allclose(r["w"], gplvm.blend_weights(b), rtol=0, atol=1e-10 * max(1.0, np.abs(b).max()))
            assert page.evaluate(f"explorer.hullContains({q}, {json.dumps(list(x))})") == bool(ins)


@needs_chromium
def test_blended_pixels_equal_numpy(page: chromium.Browser, inputs: dict) -> None:
    imgs = images_of(inputs)
    model = gplvm.load_model(inputs["models"][0])
    page.evaluate("explorer.setMode('map')")
    page.evaluate(f"explorer.setPoint({json.dumps(list(model.X[:3].mean(axis=0)))})")
    manifest = page.evaluate("explorer.manifest")
    tiles = manifest["tiles"]
    assert 0 < tiles["exact_blended"] < tiles["total"]  # the fixture's background is drawn with one fetch
    ref = None
    for shader in ("packed", "naive", "bits"):
        for use_tiles in (True, False):
            rgb, w = linear_blend(page, basis="exact", shader=shader, tiles=use_tiles)
            if ref is None:
                ref = np.einsum("i,ihwc->hwc", w, imgs)
            rel = np.sqrt(np.mean((rgb - ref) ** 2)) / np.sqrt(np.mean(ref ** 2))
            assert rel < 1e-3, (shader, use_tiles, rel)
            bound = 1e-3 * np.abs(ref).max() + 1e-3 * np.abs(w) @ imgs.reshape(len(w), -1).max(1)
            assert np.abs(rgb - ref).max() < bound, (shader, use_tiles)
    rgb, w = linear_blend(page, basis="exact")
    # the reduced basis: the same blend within the manifest's error, with or without the one-fetch tiles
    assert 0 < tiles["reduced_blended"] < tiles["total"]
    rgb_r, _ = linear_blend(page, basis="reduced")
    rel_r = np.sqrt(np.mean((rgb_r - ref) ** 2)) / ref.mean()
    assert rel_r <= manifest["basis"]["target"] * 1.01
    rgb_full, _ = linear_blend(page, basis="reduced", tiles=False)
    assert np.abs(rgb_r - rgb_full).max() <= 1e-6 * np.abs(rgb_full).max()
    # tone mapping in the shader: the canvas is blend.tonemap of the linear blend (± 1 level of rounding)
    page.evaluate("explorer.setBasis('exact')")
    for e in (0.0, 1.5):
        page.evaluate(f"explorer.setExposure({e})")
        shown = canvas(page, manifest).astype(int)
        assert np.abs(shown - blend.tonemap(rgb, e).astype(int)).max() <= 1
    page.evaluate("explorer.setExposure(0)")


@needs_chromium
def test_path_mode_shows_the_reference_and_uses_the_paths_weights(page: chromium.Browser, inputs: dict) -> None:
    doc = integrity.read_json(inputs["path_points"][1]["weights"])
    st = page.evaluate(f"explorer.setPath({json.dumps(doc['material_a'])}, {json.dumps(doc['material_b'])}, {doc['t']})")
    assert st["mode"] == "path" and st["q"] == doc["q"] == 5
    names = page.evaluate("explorer.manifest.materials")
    np.testing.assert_allclose(st["w"], [doc["weights"][n] for n in names], rtol=0, atol=1e-9)
    assert page.evaluate("document.getElementById('ref-fig').hidden") is False
    ref = page.evaluate("""(() => { const c = document.getElementById('ref');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let s = 0, s2 = 0, n = 0;
        for (let i = 0; i < d.length; i++) if (i % 4 !== 3) { s += d[i]; s2 += d[i] * d[i]; n++; }
        return Math.sqrt(s2 / n - (s / n) ** 2); })()""")
    assert ref > 5  # the reference render is drawn
    assert "t = 0.5" in page.evaluate("document.getElementById('ref-caption').textContent")
    st = page.evaluate(f"explorer.setPath({json.dumps(doc['material_a'])}, {json.dumps(doc['material_b'])}, 0.9)")
    assert "none" in page.evaluate("document.getElementById('ref-caption').textContent")
    page.evaluate("explorer.setMode('map')")
    assert page.errors == []


@needs_chromium
def test_q5_slices(page: chromium.Browser, inputs: dict) -> None:
    model = gplvm.load_model(inputs["models"][1])
    page.evaluate("explorer.setMode('map')")
    st = page.evaluate("explorer.setModel(5)")
    assert st["q"] == 5 and page.evaluate("document.getElementById('slices').querySelectorAll('input').length") == 3
    st = page.evaluate("explorer.setDims(2, 3)")
    before = st["point"]
    x, y = page.evaluate(f"explorer.mapToPage({json.dumps(list(model.X[7]))})")
    page.mouse("mouseMoved", x + 3, y + 3)
    after = page.evaluate("explorer.state().point")
    assert [before[i] for i in (0, 1, 4)] == [after[i] for i in (0, 1, 4)]  # the slice's other coordinates stay
    assert after[2] != before[2] and after[3] != before[3]
    w = page.evaluate("explorer.state().w")
    np.testing.assert_allclose(w, gplvm.blend_weights(gplvm.weights(model, np.array(after))), rtol=0, atol=1e-9)
    page.evaluate("explorer.setModel(2)")
    assert page.errors == []


@needs_chromium
def test_page_works_over_http(site: Path) -> None:
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(site))
    handler.log_message = lambda *a: None  # type: ignore[method-assign]
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        with chromium.Browser() as b:
            b.open(f"http://127.0.0.1:{server.server_port}/index.html", ready=READY)
            assert b.evaluate("explorer.error") is None and b.errors == [], b.errors
    finally:
        server.shutdown()


@needs_chromium
def test_reduced_option_says_approximate_only_above_the_noise_floor(site: Path, tmp_path: Path) -> None:
    """The blend menu marks the reduced basis approximate exactly when the manifest says its
    worst error is above the noise floor (the fixture's basis is below it; a copy says it is not)."""
    above = tmp_path / "site"
    shutil.copytree(site, above)
    model_js = above / "data" / "model.js"
    doc = read_data_file(model_js)
    assert doc["manifest"]["basis"]["below_floor"] is True
    doc["manifest"]["basis"]["below_floor"] = False
    model_js.write_text(export._script("model", doc), encoding="ascii")  # with its CRC-32, as the export writes it
    labels = {}
    for name, folder in (("below", site), ("above", above)):
        with chromium.Browser() as b:
            b.open(folder / "index.html", ready=READY)
            assert b.evaluate("explorer.error") is None and b.errors == [], b.errors
            labels[name] = b.evaluate("document.querySelector('#basis option[value=reduced]').textContent")
    assert labels["below"].startswith("reduced: mean + ") and "approximate" not in labels["below"]
    assert "approximate" in labels["above"] and labels["above"].startswith(labels["below"])


# --------------------------------------------------------------------------
# A damaged payload: one message naming the file and what to rerun, no image
# --------------------------------------------------------------------------


def _damaged_sites(site: Path, root: Path) -> dict[str, Path]:
    """Copies of the site with data/layers.js truncated, its pre-renders' payload shortened to half (still valid
    JavaScript and JSON: the tester's black image), one base64 digit of it changed, and data/refs.js missing."""
    out = {}
    for name in ("shortened", "edited", "truncated", "missing"):  # the tester's case (a black image) first
        out[name] = root / name
        shutil.copytree(site, out[name])
    layers = (site / "data" / "layers.js").read_text(encoding="ascii")
    run = max(re.finditer(r"[A-Za-z0-9+/]{64,}={0,2}", layers), key=lambda m: m.end() - m.start())  # the images
    a, b = run.span()
    (out["truncated"] / "data" / "layers.js").write_text(layers[: len(layers) * 2 // 3], encoding="ascii")
    (out["shortened"] / "data" / "layers.js").write_text(layers[: a + (b - a) // 8 * 4] + layers[b:], encoding="ascii")
    digit = "B" if layers[a + 100] != "B" else "C"
    (out["edited"] / "data" / "layers.js").write_text(layers[: a + 100] + digit + layers[a + 101 :], encoding="ascii")
    (out["missing"] / "data" / "refs.js").unlink()
    return out


@needs_chromium
def test_page_names_a_damaged_data_file_instead_of_drawing(site: Path, tmp_path: Path) -> None:
    """A truncated, edited or missing data file: the page shows one message naming it and what to rerun,
    hides the (otherwise black) canvases and never reports ready."""
    sites = _damaged_sites(site, tmp_path)
    expect = {
        "truncated": "data/layers.js did not load (missing, truncated or not an explorer data file)",
        "shortened": "data/layers.js: its payload does not match its recorded digest (damaged or edited)",
        "edited": "data/layers.js: its payload does not match its recorded digest (damaged or edited)",
        "missing": "data/refs.js did not load (missing, truncated or not an explorer data file)",
    }
    for name, folder in sites.items():
        with chromium.Browser() as b:
            b.open(folder / "index.html", ready=READY)
            error = b.evaluate("explorer.error")
            assert error is not None and error.startswith(expect[name]), (name, error)
            assert "snakemake --forcerun write_explorer" in error
            assert b.evaluate("explorer.ready") is False, name
            shown = b.evaluate("[!document.getElementById('error').hidden, document.getElementById('error')"
                               ".textContent, document.querySelector('main').hidden]")
            assert shown == [True, error, True], (name, shown)


@needs_chromium
def test_page_verifies_its_payload_when_intact(page: chromium.Browser) -> None:
    assert page.evaluate("explorer.error") is None and page.evaluate("explorer.verifyMs") >= 0


#: Material names and a database label that would run script or inject markup if the page
#: treated them as HTML, or end the data's script if it were inline.
HOSTILE_NAMES = [
    '<img src=x onerror="window.__pwned=1">',
    '</script><script>window.__pwned=2</script>',
    '"><svg onload="window.__pwned=3">',
    "javascript:window.__pwned=4",
    "<!-- x",
    "line\u2028sep\u2029para",
    "&lt;b&gt; &amp;",
    "{{7*7}} ${7*7}",
    "<b>bold</b>",
    "mat-09", "mat-10", "mat-11",
]
HOSTILE_DB = '<img src=y onerror="window.__pwned=5">'


def test_script_json_escapes_what_ends_a_script() -> None:
    value = {"n": HOSTILE_NAMES, "d": HOSTILE_DB}
    text = export.script_json(value)
    assert json.loads(text) == value and text.isascii()
    for bad in ("<", ">", "&", "\u2028", "\u2029"):
        assert bad not in text


@needs_chromium
def test_hostile_material_names_display_literally_and_run_nothing(tmp_path: Path) -> None:
    """Names and the database label from the data are shown as text: no script runs, no element appears."""
    kwargs = make_inputs(tmp_path / "in", names=HOSTILE_NAMES, database=HOSTILE_DB)
    site = tmp_path / "explorer"
    export.write_explorer(out=site, **kwargs)
    for js in (site / "data").glob("*.js"):
        text = js.read_text(encoding="ascii")
        assert "</script" not in text.lower() and "<!--" not in text and "<" not in text
    with chromium.Browser() as b:
        b.open(site / "index.html", ready=READY)
        assert b.evaluate("explorer.error") is None and b.errors == [], b.errors
        b.evaluate("explorer.setPath(explorer.manifest.materials[0], explorer.manifest.materials[1], 0.25)")
        b.evaluate("explorer.setMode('map')")
        b.evaluate("new Promise((r) => setTimeout(r, 300))")  # an <img onerror> would have fired by now
        assert b.evaluate("window.__pwned === undefined"), b.evaluate("String(window.__pwned)")
        assert b.evaluate("document.querySelectorAll('img, svg, script:not([src]), b').length") == 0
        shown = b.evaluate("Array.from(document.querySelectorAll('#path-a option'), (o) => o.textContent)")
        assert shown == HOSTILE_NAMES
        cells = b.evaluate("Array.from(document.querySelectorAll('#weights tbody tr td:first-child'), "
                           "(td) => td.textContent)")
        assert len(cells) == 8 and set(cells) <= set(HOSTILE_NAMES)
        assert HOSTILE_DB in b.evaluate("document.getElementById('subtitle').textContent")
        assert b.errors == [], b.errors
