"""Closed-loop acquisition (issue 13): render what the set-up's camera sees, read the BRDF off it, reconstruct.

Checks of :mod:`brdfpipe.rendering.capture` and :mod:`brdfpipe.acquisition.closedloop`:

* geometry — a "cell-index" table (each cell's value encodes its index)
  rendered through each pixel centre decodes, pixel by pixel, to the cells
  the optimiser's geometry (:func:`brdfpipe.acquisition.geometry.observation_cells`)
  predicts; with the footprint averaged (the capture's default) the share of
  pixels whose footprint spans several cells is reported;
* radiometry — a Lambertian table of albedo ρ gives ρ/π at every kept
  pixel, for a point light (fall-off and cosine removed) and a distant one;
* the sensor — noise-free exposure is the identity, photon noise has the
  Poisson variance, saturated pixels are masked, bracketing recovers them;
* closed loop — on a small real pipeline (8 synthetic materials, PCA of 6,
  near-field 25° sets of 1 and 2 images), the closed-loop error at high spp
  and no sensor noise is within 10 % of the table-lookup error; with the
  default sensor the difference is printed.

Skipped with the reason when Mitsuba's LLVM backend is not available.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.acquisition import closedloop, evaluation, geometry, optimize, svd
from brdfpipe.acquisition.geometry import Setup
from brdfpipe.core import exr, filenames, integrity
from brdfpipe.data import ingest, logmap, merl, store, synth
from brdfpipe.data.database import database_from_folder
from brdfpipe.rendering import capture, render


def _llvm_reason() -> str | None:
    try:
        render.use_variant("llvm_ad_rgb")
        render.register_merl_bsdf()
    except Exception as exc:  # noqa: BLE001 - any backend failure means: skip
        return f"Mitsuba's llvm_ad_rgb variant is not usable here: {exc}"
    return None


_REASON = _llvm_reason()
needs_llvm = pytest.mark.skipif(_REASON is not None, reason=_REASON or "")

NO_NOISE = capture.Sensor(enabled=False)


@pytest.fixture(scope="module")
def tables(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("closedloop-tables")
    ih, idd, ip = np.meshgrid(np.arange(90), np.arange(90), np.arange(180), indexing="ij")
    cells = np.stack([ih + 0.5, idd + 0.5, ip + 0.5]).astype(np.float64)  # channel c = index + ½
    merl.write_merl(d / "cells.binary", cells)
    merl.write_merl(d / "lambert.binary", render.lambertian_table([0.2, 0.5, 0.8]))
    return {"cells": d / "cells.binary", "lambert": d / "lambert.binary"}


def _decode(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flat cells, pure) of cell-index pixels: pure = every channel at index + ½ (one cell in the footprint)."""
    idx = np.floor(values).astype(np.intp)
    pure = np.all(np.abs(values - idx - 0.5) < 1e-3, axis=1)
    idx = np.clip(idx, 0, np.array(merl.DIMS) - 1)
    return np.ravel_multi_index(tuple(idx.T), merl.DIMS), pure


CONFIGS = [("nearfield", 25.0, (40, 35, 60)), ("nearfield", 45.0, (20, 50, 30)), ("nearfield", 15.0, (10, 60, 90)),
           ("fixed_camera", 25.0, (64, 30, 45))]


@needs_llvm
@pytest.mark.parametrize(("kind", "fov", "config"), CONFIGS)
def test_cell_index_render_decodes_to_the_predicted_cells(tables: dict[str, Path], kind: str, fov: float,
                                                          config: tuple[int, int, int]) -> None:
    grid = 24
    setup = Setup(kind, fov, grid)
    wi, wo = geometry.centre_directions(setup, config)
    predicted = geometry.observation_cells(setup, config, valid=np.ones(merl.N_CELLS, dtype=bool))
    settings = capture.CaptureSettings(fov_deg=fov, grid=grid, spp=64, light_distance=math.inf, sensor=NO_NOISE)
    geom = capture.pixel_geometry(settings, wi, wo)
    assert int(geom.inside.sum()) == predicted.size > 100
    # Through each pixel centre: exactly the predicted cell, pixel by pixel.
    img = capture.render_capture(tables["cells"], settings, wi, wo, seed=1, centre_only=True)
    cells, pure = _decode(img[geom.row, geom.col][geom.inside] / geom.irradiance[geom.inside, None])
    mismatch = float(np.mean(cells != predicted))
    print(f"\n{kind} {fov}° {config}: {predicted.size} pixels, centre-ray mismatch {mismatch:.4f}", end="")
    assert pure.all()
    assert mismatch <= 0.01  # only pixel centres within float precision of a bin edge may differ
    # Averaged over the footprint (64 spp): pixels spanning several cells are not pure; pure ones still agree.
    img = capture.render_capture(tables["cells"], settings, wi, wo, seed=1)
    cells, pure = _decode(img[geom.row, geom.col][geom.inside] / geom.irradiance[geom.inside, None])
    print(f"; footprint spans several cells at {1 - pure.mean():.1%} of the pixels", end="")
    assert np.all(cells[pure] == predicted[pure])


@needs_llvm
@pytest.mark.parametrize("distance", [math.inf, 3.0, 20.0])
def test_lambertian_radiometry(tables: dict[str, Path], distance: float) -> None:
    setup = Setup("nearfield", 35.0, 20)
    for config in ((40, 35, 60), (70, 20, 120)):
        wi, wo = geometry.centre_directions(setup, config)
        settings = capture.CaptureSettings(fov_deg=35.0, grid=20, spp=16, light_distance=distance, sensor=NO_NOISE)
        geom = capture.pixel_geometry(settings, wi, wo)
        no_mask = (np.full((geom.size, geom.size, 3), np.inf), np.zeros((geom.size, geom.size, 3), bool))
        got = []
        for seed, centre in ((2, True), (2, False), (3, False)):
            raw = capture.render_capture(tables["lambert"], settings, wi, wo, seed=seed, centre_only=centre)
            table, counts = capture.observations_from_image(raw, *no_mask, geom, 0.0)
            assert counts["kept"] == counts["pixels"] > 100
            got.append(table["rgb"] * np.pi / np.array([0.2, 0.5, 0.8]))  # 1 = ρ/π
        # Through the pixel centres: ρ/π up to float32 (distant light), or up to the difference between E
        # at a pixel's centre and its footprint mean, which the conversion divides by (< 1e-3 at D = 3).
        np.testing.assert_allclose(got[0], 1.0, rtol=1e-5 if math.isinf(distance) else 1e-3)
        # Over the footprint (16 random rays): the light's fall-off varies across a pixel, so each value
        # carries Monte Carlo noise; σ from two seeds.  Every value within 6σ, the mean within 1e-3.
        sigma = float(np.std(got[1] - got[2]) / math.sqrt(2))
        assert sigma < (1e-5 if math.isinf(distance) else 0.01)
        assert np.abs(got[1] - 1.0).max() <= 6 * sigma + 1e-5
        assert abs(got[1].mean() - 1.0) < 1e-3
        if math.isfinite(distance):  # a point light: the light direction varies over the disk
            spread = np.degrees(np.arccos(np.clip(table["wi"] @ wi, -1, 1))).max()
            assert 0.5 * math.degrees(setup.nu / distance) < spread < 2 * math.degrees(setup.nu / (distance - 1))


def test_sensor_noise_model() -> None:
    rng = np.random.default_rng(0)
    img = np.full((64, 64, 3), 2.0)
    img[0, 0] = 4.0  # the brightest pixel sets the exposure
    inside = np.ones((64, 64), dtype=bool)
    off = capture.Sensor(enabled=False)
    hdr, snr, sat = capture.expose(img, inside, off, rng)
    np.testing.assert_array_equal(hdr, img)
    assert np.isinf(snr).all() and not sat.any()
    s = capture.Sensor(full_well=10000, read_noise=0.0, bits=16, peak_level=0.8, brackets=(1.0,))
    hdr, snr, sat = capture.expose(img, inside, s, rng)
    electrons = 2.0 * 0.8 * 10000 / 4.0  # 4000 e⁻ at half the peak
    rel = hdr[1:, 1:] / 2.0 - 1.0
    assert abs(rel.mean()) < 2e-3
    assert abs(rel.std() / (1 / math.sqrt(electrons)) - 1) < 0.05  # Poisson: σ/μ = 1/√N
    np.testing.assert_allclose(np.median(snr[1:, 1:]), math.sqrt(electrons), rtol=0.02)
    # A pixel far above the rest saturates in a single exposure, bracketing recovers it.
    img2 = np.full((16, 16, 3), 1.0)
    img2[5, 5] = 50.0
    mask = np.ones((16, 16), dtype=bool)
    mask[5, 5] = False  # exposure set on the others: the bright pixel saturates
    _, _, sat = capture.expose(img2, mask, s, rng)
    assert sat[5, 5].all() and sat.sum() == 3
    s3 = capture.Sensor(full_well=10000, read_noise=2.0, bits=16, peak_level=0.8, brackets=(1.0, 0.01 ** -1))
    hdr, _, sat = capture.expose(img2, np.ones((16, 16), bool), s3, rng)
    assert not sat.any()
    np.testing.assert_allclose(hdr[5, 5], 50.0, rtol=0.03)
    np.testing.assert_allclose(hdr.mean(axis=(0, 1)), img2.mean(axis=(0, 1)), rtol=0.01)
    with pytest.raises(ValueError, match="brackets"):
        capture.Sensor(brackets=(0.5, 1.0))


class Loop:
    """A small real pipeline: 8 synthetic materials, model of 6, near-field 25° sets of n ≤ 2."""

    def __init__(self, d: Path) -> None:
        synth.synthesize(d / "db", count=8, seed=11, noise=0.01, jobs=1, progress=False)
        db = database_from_folder(d / "db", key="folder")
        self.sources = {k: Path(v) for k, v in db.sources.items()}
        self.store = d / "merl.zarr"
        ingest.ingest(db.sources, self.store, database=db.kind, jobs=1)
        st = store.open_store(self.store)
        materials = list(st.materials)
        self.test = [materials[1], materials[6]]
        train = [m for m in materials if m not in self.test]
        lm = d / "logmap" / "train.zarr"
        logmap.write_logmap(self.store, lm, split="train", materials_train=train)
        self.model = d / "svd" / "train.zarr"
        svd.fit(lm, self.model)
        m = svd.open_model(self.model)
        setup = Setup("nearfield", 25.0, 24)
        sets = optimize.optimize(m, setup, metric="error", n_max=2, candidates=6, steps=(1,), seed=3,
                                 log=lambda line: None)
        self.directions = optimize.write_directions(
            d / filenames.directions("train", "nearfield", 25.0, "error"), sets, setup=setup, metric="error",
            split="train", model_path=self.model, seed=3, eta=40.0, beta=0.0, database=m.database)
        self.dir = d

    def run(self, tag: str, sensor: capture.Sensor, spp: int, min_snr: float = 3.0) -> dict[tuple[str, str, int], float]:
        obs = {}
        for name in self.test:
            folder = self.dir / tag / name
            image_keys, table_keys = capture.output_layout(1, [1, 2])
            capture.capture_to_files(
                material=self.sources[name], directions=[self.directions], n_images=[1, 2],
                renders=[folder / f"n{n}-{j}-render.exr" for _, n, j in image_keys],
                photographs=[folder / f"n{n}-{j}.exr" for _, n, j in image_keys],
                noiseless=[folder / f"n{n}-noiseless.npz" for _, n in table_keys],
                observations=[folder / f"n{n}.npz" for _, n in table_keys],
                spp=spp, seed=5, light_distance=20.0, min_snr=min_snr, sensor=sensor)
            for _, n in table_keys:
                obs[(name, 0, n)] = (folder / f"n{n}-noiseless.npz", folder / f"n{n}.npz")
        keys = closedloop.table_layout(self.test, 1, [1, 2])
        out = closedloop.write_closedloop(self.store, self.model, [self.directions], [obs[k][0] for k in keys],
                                          [obs[k][1] for k in keys], self.dir / f"{tag}.csv",
                                          materials=self.test, n_images=[1, 2])
        with io.StringIO(integrity.read_csv_text(out), newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert list(rows[0]) == ["database", "split", "setup", "fov", "metric", "n", "material", "channel", "kind",
                                 "value"]
        assert {r["kind"] for r in rows} == set(closedloop.CLOSEDLOOP_KINDS)
        return {(r["material"], r["kind"], int(r["n"])): float(r["value"]) for r in rows if r["channel"] in ("all",)}


@pytest.fixture(scope="module")
def loop(tmp_path_factory: pytest.TempPathFactory) -> Loop:
    if _REASON is not None:
        pytest.skip(_REASON)
    return Loop(tmp_path_factory.mktemp("closedloop"))


@needs_llvm
def test_closed_loop_matches_the_table_lookup(loop: Loop) -> None:
    """High spp and no sensor noise: the closed-loop error is within 10 % of the table lookup's."""
    got = loop.run("clean", NO_NOISE, spp=256)
    # The table-lookup rows are the leave-out evaluation's (same store, model, sets).
    ref = evaluation.evaluate(loop.store, loop.model, [loop.directions], test_materials=loop.test)
    for r in ref:
        if r["kind"] in ("rms_log", "relrms_linear") and r["material"] == "mean":
            assert math.isclose(got[("mean", r["kind"], int(r["n"]))], r["value"], rel_tol=1e-6)
    for n in (1, 2):
        table = got[("mean", "rms_log", n)]
        noiseless = got[("mean", "closedloop_noiseless_rms_log", n)]
        sensorless = got[("mean", "closedloop_rms_log", n)]
        print(f"\nn = {n}: table {table:.4f}, closed loop {noiseless:.4f} ({noiseless / table - 1:+.1%})", end="")
        assert sensorless == noiseless  # no sensor: the same observations
        assert abs(noiseless / table - 1) <= 0.10
        assert got[("mean", "closedloop_masked", n)] < 0.05
        assert got[("mean", "closedloop_observations", n)] > 0.95 * got[("mean", "observations", n)]


@needs_llvm
def test_closed_loop_with_the_default_sensor(loop: Loop) -> None:
    """The default sensor's noise and masking: reported, and the reconstruction still holds."""
    got = loop.run("sensor", capture.Sensor(), spp=64)
    for n in (1, 2):
        table = got[("mean", "rms_log", n)]
        noisy = got[("mean", "closedloop_rms_log", n)]
        masked = got[("mean", "closedloop_masked", n)]
        print(f"\nn = {n}: table {table:.4f}, default sensor {noisy:.4f} ({noisy / table - 1:+.1%}), "
              f"masked {masked:.1%}", end="")
        assert noisy < 3 * table
    # Same seed, same photograph: the capture is deterministic (up to a few float32 roundings of
    # Dr.Jit's LLVM kernels, ~1e-7 relative, in a few pixels; errors up to BLAS order).
    again = loop.run("sensor-again", capture.Sensor(), spp=64)
    assert again.keys() == got.keys()
    np.testing.assert_allclose([again[k] for k in got], [got[k] for k in got], rtol=1e-5)
    for first in (loop.dir / "sensor").rglob("*.exr"):
        second = loop.dir / "sensor-again" / first.relative_to(loop.dir / "sensor")
        np.testing.assert_allclose(exr.read_exr(first), exr.read_exr(second), rtol=1e-5, atol=1e-6)


@needs_llvm
def test_a_sensor_that_masks_every_pixel_gives_the_mean_reconstruction(loop: Loop) -> None:
    """min_snr above any pixel's SNR: the evaluation runs to the end and reports 0 observations, all masked."""
    got = loop.run("all-masked", capture.Sensor(), spp=4, min_snr=1e6)
    for n in (1, 2):
        assert got[("mean", "closedloop_observations", n)] == 0
        assert got[("mean", "closedloop_masked", n)] == 1.0
        assert math.isfinite(got[("mean", "closedloop_rms_log", n)])
        # no observation: eq. 4 gives the model's mean, the same reconstruction for n = 1 and n = 2
        assert got[("mean", "closedloop_rms_log", n)] == got[("mean", "closedloop_rms_log", 1)]
        assert got[("mean", "closedloop_noiseless_rms_log", n)] < got[("mean", "closedloop_rms_log", n)]


@needs_llvm
def test_capture_command(loop: Loop, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from brdfpipe.cli import main

    name = loop.test[0]
    out = tmp_path / "cap"
    assert main(["-q", "capture", str(loop.sources[name]), str(loop.directions), "--out", str(out), "--n", "2",
                 "--spp", "4", "--model", str(loop.model)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["capture.json", "n2-0-render.exr", "n2-0-sensor.exr",
                                                     "n2-1-render.exr", "n2-1-sensor.exr", "n2-noiseless.npz",
                                                     "n2-sensor.npz", "n2.binary"]
    assert json.loads((out / "capture.json").read_text())["files"] == sorted(
        p.name for p in out.iterdir() if p.name != "capture.json")
    table = merl.read_merl(out / "n2.binary")
    assert table.shape == merl.SHAPE and np.isfinite(table).all()
    from brdfpipe.data import provenance

    mark = provenance.read_mark(out / "n2.binary")  # a reconstruction, never taken for a measurement
    assert mark.kind == "derived" and mark.fields["operation"] == "capture-reconstruct"
    assert mark.fields["inputs"]["material"]["sha256"] == provenance.file_sha256(loop.sources[name])
    assert mark.fields["inputs"]["observations"]["sha256"] == provenance.file_sha256(out / "n2-sensor.npz")
    cells, rgb, counts = closedloop.read_observations(out / "n2-sensor.npz")
    assert cells.size == rgb.shape[0] == counts["kept"] > 100
    # its own earlier output is replaced whole (no n2 files left from the first capture)
    assert main(["-q", "capture", str(loop.sources[name]), str(loop.directions), "--out", str(out), "--n", "1",
                 "--spp", "2", "--no-noise"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["capture.json", "n1-0-render.exr", "n1-0-sensor.exr",
                                                     "n1-noiseless.npz", "n1-sensor.npz"]
    # Bad input: one line naming the file, exit 1, nothing written.
    bad = tmp_path / "not-directions.json"
    bad.write_text('{"format": "something else"}')
    capsys.readouterr()
    assert main(["capture", str(loop.sources[name]), str(bad), "--out", str(tmp_path / "none")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not-directions.json" in err[0] and "brdfpipe capture: error:" in err[0]
    assert not (tmp_path / "none").exists()


@needs_llvm
def test_closed_loop_figure(loop: Loop, tmp_path: Path) -> None:
    from brdfpipe.acquisition import figures

    csv_path = loop.dir / "clean.csv"
    if not csv_path.exists():
        loop.run("clean", NO_NOISE, spp=16)
    files = [tmp_path / "closedloop.png", tmp_path / "closedloop.pdf"]
    out = figures.plot_closedloop(csv_path, files)
    assert [p.name for p in out.files] == ["closedloop.png", "closedloop.pdf"] and all(p.stat().st_size for p in files)
    assert "synthetic" in out.title and not out.warnings
    with pytest.raises(ValueError):
        figures.plot_closedloop(csv_path, [tmp_path / "x.png"])


@needs_llvm
@pytest.mark.parametrize("damage", ["rescaled", "truncated", "not a table"])
def test_a_damaged_observation_table_is_refused(loop: Loop, tmp_path: Path, damage: str) -> None:
    """The tester's case: a closed-loop table with its rgb rescaled (a valid npz) passed and changed
    closedloop.csv.  Now its reader refuses it, naming the file and the rule to rerun; a truncated table or
    another file is one clean error too."""
    if not (loop.dir / "clean.csv").exists():
        loop.run("clean", NO_NOISE, spp=16)
    name = loop.test[0]
    src = loop.dir / "clean" / name / "n2.npz"
    bad = tmp_path / filenames.closedloop_observations(name, "nearfield", 25, "error", 2, "sensor")
    bad.parent.mkdir(parents=True)
    if damage == "rescaled":
        with np.load(src) as z:
            arrays = dict(z)
        arrays["rgb"] = arrays["rgb"] * 2.0
        np.savez(bad, **arrays)
        expect = re.escape(f"{bad}: its arrays do not match their recorded digest (damaged or edited)")
    elif damage == "truncated":
        bad.write_bytes(src.read_bytes()[:-200])
        expect = re.escape(f"{bad}: truncated or corrupt observation table")
    else:
        bad.write_bytes(b"\x93NUMPY not a zip")
        expect = re.escape(f"{bad}: truncated or corrupt observation table (not an npz file: no zip header)")
    with pytest.raises(ValueError, match=expect + ".*; rerun its rule: snakemake --forcerun capture_closedloop"):
        closedloop.read_observations(bad)


@needs_llvm
def test_many_materials_in_one_file_equal_one_capture_each(loop: Loop, tmp_path: Path) -> None:
    """capture_materials_to_file (the unseen materials' capture): the tables of capture_to_files, in one checked file."""
    from brdfpipe.acquisition import unseen as acq_unseen

    name, folder = loop.test[0], tmp_path / "one"
    settings = dict(spp=16, seed=5, light_distance=20.0, min_snr=3.0, sensor=capture.Sensor())
    image_keys, table_keys = capture.output_layout(1, [1, 2])
    capture.capture_to_files(
        material=loop.sources[name], directions=[loop.directions], n_images=[1, 2],
        renders=[folder / f"n{n}-{j}-render.exr" for _, n, j in image_keys],
        photographs=[folder / f"n{n}-{j}.exr" for _, n, j in image_keys],
        noiseless=[folder / f"n{n}-noiseless.npz" for _, n in table_keys],
        observations=[folder / f"n{n}.npz" for _, n in table_keys], **settings)
    many = tmp_path / "many.npz"
    capture.capture_materials_to_file(materials={name: loop.sources[name]}, database="synthetic",
                                      directions=[loop.directions], n_images=[1, 2], out=many, **settings)
    assert capture.MANY_FORMAT == acq_unseen.MANY_FORMAT  # the reader's layer may not import the writer's
    tables = {(t.material, t.n, t.source): t for t in acq_unseen.read_many_observations(many, database="synthetic")}
    assert set(tables) == {(name, n, s) for n in (1, 2) for s in ("noiseless", "sensor")}
    for n in (1, 2):
        for source, path in (("noiseless", folder / f"n{n}-noiseless.npz"), ("sensor", folder / f"n{n}.npz")):
            cells, rgb, counts = closedloop.read_observations(path)
            t = tables[(name, n, source)]
            assert (t.setup, t.fov, t.metric) == ("nearfield", 25.0, "error") and t.counts == counts
            np.testing.assert_array_equal(t.cells, cells)
            np.testing.assert_allclose(t.rgb, rgb, rtol=1e-5, atol=1e-7)
    with pytest.raises(ValueError, match="observations of database 'synthetic', expected 'rgl-nbrdf'"):
        acq_unseen.read_many_observations(many, database="rgl-nbrdf")
    data = bytearray(many.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="damaged.npz"):
        acq_unseen.read_many_observations(damaged, database="synthetic")
