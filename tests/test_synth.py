"""Tests of brdfpipe.data.synth: the synthetic MERL-format database.

Full-resolution tables cost ~0.5 s each, so the module generates one material
per family once (fixture ``generated``) and reuses it.
"""

from __future__ import annotations

import json
import logging
import math
import re
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.core.version import full_version
from brdfpipe.data import merl, provenance, synth, synthmodel

SEED = 11
NOISE = 0.01
THETA_I = np.radians(np.linspace(0.0, 89.5, 46))


@pytest.fixture(scope="module")
def specs5() -> list[synth.MaterialSpec]:
    specs = synth.plan_database(5, SEED)
    assert [s.family for s in specs] == list(synth.FAMILIES)
    return specs


@pytest.fixture(scope="module")
def generated(specs5) -> dict[str, tuple[np.ndarray, dict]]:
    return {s.name: synth.generate_material(s, NOISE) for s in specs5}


@pytest.fixture(scope="module")
def mask() -> np.ndarray:
    return merl.measured_mask()


def _variants() -> list[synth.MaterialSpec]:
    """Several materials of every family, covering every variant (cheap: plan only)."""
    specs = synth.plan_database(100, SEED)
    out = []
    for family in synth.FAMILIES:
        out += [s for s in specs if s.family == family][:6]
    return out


def _random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Unit vectors in the upper hemisphere, some close to grazing and to the normal."""
    cos_t = rng.uniform(0.0, 1.0, n) ** 0.5
    cos_t[: n // 10] = rng.uniform(1e-3, 0.05, n // 10)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    sin_t = np.sqrt(1.0 - cos_t**2)
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=1)


# --------------------------------------------------------------------------
# Plan: families, names, seeds, test materials
# --------------------------------------------------------------------------


def test_family_counts_mirror_merl() -> None:
    assert synth.family_counts(100) == {
        "metal": 25, "paint": 30, "metallic-paint": 12, "fabric": 12, "phenolic": 21,
    }
    for count in range(1, 160):
        counts = synth.family_counts(count)
        assert sum(counts.values()) == count
        if count >= 5:
            assert min(counts.values()) >= 1, (count, counts)
    assert synth.family_counts(200) == {f: 2 * n for f, n in synth.family_counts(100).items()}


def test_plan_is_fast_deterministic_and_seeded() -> None:
    synth.plan_database(100, SEED)  # warm-up (imports, caches)
    t0 = time.perf_counter()
    a = synth.plan_database(100, SEED)
    elapsed = time.perf_counter() - t0
    assert elapsed < 0.5, f"plan_database(100) took {elapsed:.3f} s"  # ~15 ms; slack for CI
    b = synth.plan_database(100, SEED)
    assert a == b
    assert json.dumps([s.to_json() for s in a]) == json.dumps([s.to_json() for s in b])
    assert [s.family for s in a].count("metal") == 25
    # a material's seed depends on (seed, index) only, not on the database size
    small = synth.plan_database(12, SEED)
    assert [s.seed for s in small] == [s.seed for s in a[:12]]
    assert len({s.seed for s in a}) == 100
    # different database seeds give different materials
    other = synth.plan_database(100, SEED + 1)
    assert all(x.seed != y.seed and x.params != y.params for x, y in zip(a, other))
    # params are JSON-serialisable and survive a round trip unchanged
    for s in a:
        assert json.loads(json.dumps(s.params, allow_nan=False)) == s.params


#: Material names: lower-case words joined by hyphens, ending in the running number.
NAME_RE = re.compile(r"^[a-z0-9]+(?:-[a-z0-9]+)*-[0-9]{3,}$")


def test_names_unique_valid_and_say_the_family() -> None:
    for count in (1, 5, 12, 100, 1234):
        specs = synth.plan_database(count, SEED)
        names = [s.name for s in specs]
        assert len(set(names)) == count
        for i, s in enumerate(specs):
            assert s.index == i
            assert NAME_RE.match(s.name), s.name
            assert set(s.name) <= set("abcdefghijklmnopqrstuvwxyz0123456789-")
            assert s.name.startswith(s.family + "-")
            assert int(s.name.rsplit("-", 1)[1]) == i
            assert s.family in synth.FAMILIES and s.params["family"] == s.family
    names = [s.name for s in synth.plan_database(100, SEED)]
    metals = {n.split("-")[1] for n in names if n.startswith("metal-")}
    assert metals == set(synth.METALS)
    assert any("-velvet-" in n for n in names) and any("-plastic-" in n for n in names)
    assert any("-acrylic-" in n for n in names)


def test_default_test_materials() -> None:
    specs = synth.plan_database(100, SEED)
    test = synth.default_test_materials(specs)
    assert len(test) == len(set(test)) == 10
    by_name = {s.name: s for s in specs}
    assert set(test) <= set(by_name)
    assert {by_name[n].family for n in test} == set(synth.FAMILIES)
    assert synth.default_test_materials(specs) == test  # deterministic
    assert synth.default_test_materials(synth.plan_database(100, SEED)) == test
    assert synth.default_test_materials(specs, n=0) == []
    five = synth.default_test_materials(specs, n=5)
    assert {by_name[n].family for n in five} == set(synth.FAMILIES)
    with pytest.raises(ValueError, match="test materials"):
        synth.default_test_materials(specs[:3], n=4)


# --------------------------------------------------------------------------
# Analytic models
# --------------------------------------------------------------------------


def test_fresnel_terms() -> None:
    c = np.linspace(0.0, 1.0, 101)
    n, k = np.array([0.2, 1.3, 2.9]), np.array([3.4, 7.5, 3.1])
    # exact complex-arithmetic Fresnel as an independent check of the real formula
    eta = (n + 1j * k)[:, None]
    cos_t = np.sqrt(1.0 - (1.0 - c**2) / eta**2)
    rs = (c - eta * cos_t) / (c + eta * cos_t)
    rp = (eta * c - cos_t) / (eta * c + cos_t)
    ref = 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)
    np.testing.assert_allclose(synthmodel._fresnel_conductor(n, k, c), ref, rtol=1e-10, atol=1e-12)
    f0 = ((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2)
    np.testing.assert_allclose(synthmodel._fresnel_conductor(n, k, np.ones(1))[:, 0], f0, rtol=1e-12)
    eta_d = 1.5
    cos_t = np.sqrt(1.0 - (1.0 - c**2) / eta_d**2)
    rs = (c - eta_d * cos_t) / (c + eta_d * cos_t)
    rp = (eta_d * c - cos_t) / (eta_d * c + cos_t)
    np.testing.assert_allclose(
        synthmodel._fresnel_dielectric(eta_d, c), 0.5 * (rs**2 + rp**2), rtol=1e-10, atol=1e-12
    )


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("alpha", [0.02, 0.1, 0.5])
def test_microfacet_distributions_are_normalised(dist: str, alpha: float) -> None:
    u = (np.arange(200_000) + 0.5) / 200_000  # θ = u² π/2: dense near the peak
    theta = u * u * np.pi / 2
    d = synthmodel._ndf(dist, alpha, np.cos(theta))
    integral = np.sum(d * np.cos(theta) * np.sin(theta) * 2 * np.pi * np.pi * u / u.size)
    assert integral == pytest.approx(1.0, rel=1e-4)


@pytest.mark.parametrize("spec", _variants(), ids=lambda s: s.name)
def test_evaluate_is_reciprocal_finite_and_non_negative(spec: synth.MaterialSpec) -> None:
    rng = np.random.default_rng(spec.seed)
    wi = _random_directions(rng, 2000)
    wo = _random_directions(rng, 2000)
    f = synthmodel.evaluate(spec, wi, wo)
    assert f.shape == (2000, 3)
    assert np.isfinite(f).all() and (f >= 0.0).all()
    np.testing.assert_allclose(synthmodel.evaluate(spec, wo, wi), f, rtol=1e-12, atol=0.0)
    # params alone work as well as the spec; below the horizon the BRDF is 0
    np.testing.assert_array_equal(synthmodel.evaluate(spec.params, wi, wo), f)
    below = wo * np.array([1.0, 1.0, -1.0])
    assert (synthmodel.evaluate(spec, wi, below) == 0.0).all()


def test_evaluate_rejects_bad_input(specs5) -> None:
    with pytest.raises(ValueError, match="family"):
        synthmodel.evaluate({"family": "wood"}, [0, 0, 1], [0, 0, 1])
    with pytest.raises(ValueError, match="shape"):
        synthmodel.evaluate(specs5[0], np.zeros((3, 2)), np.zeros((3, 2)))


# --------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------


def test_tables_have_merl_layout(generated, mask) -> None:
    for name, (table, record) in generated.items():
        assert table.shape == merl.SHAPE and table.dtype == np.float64
        measured = table[:, mask]
        assert np.isfinite(measured).all() and (measured >= 0.0).all(), name
        # (sharp Beckmann lobes underflow to exact zeros far from the peak)
        assert (measured > 0.0).mean() > 0.5, name
        # unmeasured cells hold raw -1, except the watermark cells (also negative,
        # raw -(1 + b/2**20)); the exact value is not the data, only its sign is
        mark = np.zeros(merl.N_CELLS, dtype=bool)
        mark[synth.WATERMARK_CELLS] = True
        plain = ~mask.reshape(-1) & ~mark
        unmeasured = table.reshape(3, -1)[:, plain]
        assert np.array_equal(unmeasured, np.broadcast_to(-merl.SCALES[:, None], unmeasured.shape))
        watermark = table.reshape(3, -1)[:, synth.WATERMARK_CELLS] / merl.SCALES[:, None]
        assert np.array_equal(watermark, np.broadcast_to(synth.WATERMARK_RAW, watermark.shape))


def test_albedo_at_most_one(generated, specs5) -> None:
    for spec in specs5:
        table, record = generated[spec.name]
        albedo = merl.directional_albedo(table, THETA_I)
        assert albedo.max() <= 1.0, (spec.name, albedo.max(axis=1))
        assert albedo.min() > 0.0
        assert 0.0 < record["energy_scale"] <= 1.0
        if record["energy_scale"] < 1.0:
            assert record["max_albedo"] * record["energy_scale"] == pytest.approx(
                synth.ALBEDO_BOUND
            )


def test_grid_values_equal_the_analytic_model(specs5) -> None:
    """Without deviations and noise, a table is evaluate() at the cell centres."""
    rng = np.random.default_rng(5)
    cells = rng.choice(synthmodel.cell_grid().cells, 20_000, replace=False)
    wi, wo = merl.cell_directions(cells)
    for spec in specs5:
        dev = spec.params["deviation"]
        flat = {
            **dev,
            "shared": [0.0] * len(dev["shared"]),
            "channel": [[0.0] * len(c) for c in dev["channel"]],
        }
        bare = replace(spec, params={**spec.params, "deviation": flat})
        table, record = synth.generate_material(bare, 0.0)
        got = table.reshape(3, -1)[:, cells].T
        want = synthmodel.evaluate(bare, wi, wo) * record["energy_scale"]
        np.testing.assert_allclose(got, want, rtol=1e-9, err_msg=spec.name)


def test_deviations_are_smooth_and_moderate(generated, specs5, mask) -> None:
    """The deviation is a smooth factor of moderate size, not a different material."""
    for spec in specs5:
        table, record = generated[spec.name]
        grid = synthmodel.cell_grid()
        model = np.asarray(synthmodel._model(spec.params, grid.geom)) * record["energy_scale"]
        ok = model > 1e-12
        log_ratio = np.log(table.reshape(3, -1)[:, grid.cells][ok] / model[ok])
        assert 0.02 < log_ratio.std() < 1.0, spec.name
        assert np.percentile(np.abs(log_ratio - np.median(log_ratio)), 99) < 2.0, spec.name


def test_generation_is_deterministic(generated, specs5) -> None:
    spec = specs5[2]
    table, record = generated[spec.name]
    again, record2 = synth.generate_material(spec, NOISE)
    assert again.tobytes() == table.tobytes() and record2 == record
    assert synth.generate_table(spec, NOISE).tobytes() == table.tobytes()
    # noise and seed matter
    quiet = synth.generate_table(spec, 0.0)
    assert not np.array_equal(quiet, table)
    other = synth.plan_database(5, SEED + 1)[2]
    assert not np.array_equal(synth.generate_table(other, NOISE), table)


def test_noise_is_relative_and_unbiased(generated, specs5, mask) -> None:
    spec = specs5[1]
    noisy, _ = generated[spec.name]
    quiet = synth.generate_table(spec, 0.0)
    ratio = noisy[:, mask] / quiet[:, mask]
    assert ratio.std() == pytest.approx(NOISE, rel=0.05)
    assert ratio.mean() == pytest.approx(1.0, abs=1e-4)


# --------------------------------------------------------------------------
# Files: material, manifest, database
# --------------------------------------------------------------------------


def _unmarked(table: np.ndarray) -> np.ndarray:
    """A copy of a (3, 90, 90, 180) table without the red channel's provenance-mark cells (the file holds the mark there)."""
    out = np.array(table, dtype=np.float64).reshape(3, -1)
    out[0, provenance.MARK_CELLS] = 0.0
    return out.reshape(table.shape)


def test_write_material_round_trips(tmp_path: Path, generated, specs5, mask) -> None:
    spec = specs5[0]
    table, record = generated[spec.name]
    path = tmp_path / f"{spec.name}.binary"
    assert synth.write_material(spec, path, NOISE) == record
    assert path.stat().st_size == merl.FILE_SIZE
    raw = merl.read_merl_raw(path)
    np.testing.assert_array_equal(_unmarked(raw), _unmarked(table / merl.SCALES[:, None, None, None]))
    assert provenance.read_mark(path) == synth.material_mark(spec, NOISE)
    assert (raw[:, ~mask] < 0.0).all()
    assert (raw.reshape(3, -1)[:, synth.WATERMARK_CELLS] == synth.WATERMARK_RAW).all()
    assert synth.is_synthetic_file(path)
    np.testing.assert_allclose(_unmarked(merl.read_merl(path)), _unmarked(table), rtol=1e-15)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left


def test_write_named_material(tmp_path: Path, generated, specs5) -> None:
    spec = specs5[3]
    path = tmp_path / "m.binary"
    record = synth.write_named_material(
        name=spec.name, count=5, seed=SEED, noise=NOISE, path=path
    )
    table, want = generated[spec.name]
    assert record == want
    np.testing.assert_array_equal(_unmarked(merl.read_merl_raw(path)),
                                  _unmarked(table / merl.SCALES[:, None, None, None]))
    mark = provenance.read_mark(path)
    assert mark is not None and mark.name == spec.name and (mark.fields["count"], mark.fields["seed"]) == (5, SEED)
    with pytest.raises(ValueError, match="no material named"):
        synth.write_named_material(name="metal-gold-999", count=5, seed=SEED, noise=NOISE,
                                   path=tmp_path / "x.binary")


def test_synthesize_writes_files_and_manifest(
    tmp_path: Path, generated, specs5, caplog: pytest.LogCaptureFixture
) -> None:
    out = tmp_path / "db"
    with caplog.at_level(logging.INFO, logger="brdfpipe.data.synth"):
        manifest = synth.synthesize(out, count=5, seed=SEED, noise=NOISE, jobs=2)
    assert manifest == out / "manifest.json"
    lines = [r.getMessage() for r in caplog.records if r.name == "brdfpipe.data.synth"]
    for spec in specs5:
        assert sum(spec.name in m for m in lines) == 1, lines
    doc = json.loads(manifest.read_text())
    assert doc["kind"] == "synthetic" and doc["generator"] == "brdfpipe.data.synth"
    assert doc["version"] == full_version()
    assert (doc["seed"], doc["count"], doc["noise"]) == (SEED, 5, NOISE)
    assert [m["name"] for m in doc["materials"]] == [s.name for s in specs5]
    assert len(doc["test_materials"]) == 1
    assert set(doc["test_materials"]) <= {s.name for s in specs5}
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"{s.name}.binary" for s in specs5] + ["manifest.json"]
    )
    for entry, spec in zip(doc["materials"], specs5):
        table, record = generated[spec.name]
        assert entry["family"] == spec.family and entry["index"] == spec.index
        assert entry["seed"] == spec.seed
        assert entry["params"] == {**spec.params, **record}
        raw = merl.read_merl_raw(out / f"{spec.name}.binary")
        assert _unmarked(raw).tobytes() == _unmarked(table / merl.SCALES[:, None, None, None]).tobytes()
        assert provenance.read_mark(out / f"{spec.name}.binary") == synth.material_mark(spec, NOISE, (5, SEED))
    # the manifest describes the materials completely
    specs = [synth.MaterialSpec(m["name"], m["family"], int(m["index"]), int(m["seed"]), m["params"])
             for m in doc["materials"]]
    assert [s.name for s in specs] == [s.name for s in specs5]
    assert synth.generate_table(specs[4], NOISE).tobytes() == generated[specs5[4].name][0].tobytes()


def test_write_manifest(tmp_path: Path, specs5) -> None:
    path = tmp_path / "manifest.json"
    synth.write_manifest(specs5, path, seed=SEED, noise=0.0, test_materials=[specs5[1].name])
    doc = json.loads(path.read_text())
    assert doc["count"] == 5 and doc["noise"] == 0.0 and doc["test_materials"] == [specs5[1].name]
    assert [m["params"] for m in doc["materials"]] == [s.params for s in specs5]
    assert [p.name for p in tmp_path.iterdir()] == ["manifest.json"]
    with pytest.raises(ValueError, match="not in the database"):
        synth.write_manifest(specs5, path, seed=SEED, noise=0.0, test_materials=["nope"])
    with pytest.raises(ValueError, match="unique"):
        synth.write_manifest(specs5 + specs5[:1], path, seed=SEED, noise=0.0, test_materials=[])
    assert json.loads(path.read_text()) == doc  # a failed write leaves the old file


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: synth.plan_database(0, 1), "count"),
        (lambda: synth.plan_database(-3, 1), "count"),
        (lambda: synth.plan_database(2.5, 1), "count"),
        (lambda: synth.plan_database(True, 1), "count"),
        (lambda: synth.plan_database(5, -1), "seed"),
        (lambda: synth.family_counts(0), "count"),
        (lambda: synth.generate_table(synth.plan_database(1, 0)[0], -0.1), "noise"),
        (lambda: synth.generate_table(synth.plan_database(1, 0)[0], math.nan), "noise"),
        (lambda: synth.default_test_materials(synth.plan_database(5, 0), n=-1), "n"),
    ],
)
def test_bad_arguments_raise_value_error(call, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"count": 0, "seed": 1, "noise": 0.01}, "count"),
        ({"count": 3, "seed": 1, "noise": -0.01}, "noise"),
        ({"count": 3, "seed": 1, "noise": math.inf}, "noise"),
        ({"count": 3, "seed": -2, "noise": 0.01}, "seed"),
        ({"count": 3, "seed": 1, "noise": 0.01, "jobs": 0}, "jobs"),
    ],
)
def test_synthesize_validates_before_writing(tmp_path: Path, kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        synth.synthesize(tmp_path / "db", **kwargs)
    assert not (tmp_path / "db").exists()


def test_database_manifest_collects_job_records(tmp_path: Path) -> None:
    specs = synth.plan_database(5, 3)
    files = []
    for s in specs[:4]:
        f = tmp_path / f"{s.name}.json"
        f.write_text(json.dumps({"name": s.name, "energy_scale": 0.9, "max_albedo": 1.07}))
        files.append(f)
    out = tmp_path / "manifest.json"
    with pytest.raises(ValueError, match="no generation record for: " + specs[4].name):
        synth.write_database_manifest(
            out, count=5, seed=3, noise=0.0, test_materials=[specs[0].name], record_files=files
        )
    assert not out.exists()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"name": "not-a-material-000"}))
    with pytest.raises(ValueError, match="bad.json"):
        synth.write_database_manifest(
            out, count=5, seed=3, noise=0.0, test_materials=[], record_files=[*files, bad]
        )
    last = tmp_path / f"{specs[4].name}.json"
    last.write_text(json.dumps({"name": specs[4].name, "energy_scale": 1.0, "max_albedo": 0.5}))
    synth.write_database_manifest(
        out, count=5, seed=3, noise=0.0, test_materials=[specs[0].name], record_files=[*files, last]
    )
    doc = json.loads(out.read_text())
    assert [m["params"]["energy_scale"] for m in doc["materials"]] == [0.9] * 4 + [1.0]


def test_database_manifest_of_a_subset_lists_the_generated_materials(tmp_path: Path) -> None:
    """The workflow's `materials` subset of the synthetic database: the manifest lists what was generated."""
    specs = synth.plan_database(5, 3)
    part = [specs[1].name, specs[3].name]
    files = []
    for name in part:
        f = tmp_path / f"{name}.json"
        f.write_text(json.dumps({"name": name, "energy_scale": 0.9, "max_albedo": 1.07}))
        files.append(f)
    out = tmp_path / "manifest.json"
    synth.write_database_manifest(out, count=5, seed=3, noise=0.0, test_materials=part[:1], record_files=files,
                                  materials=part)
    doc = json.loads(out.read_text())
    assert [m["name"] for m in doc["materials"]] == part and doc["count"] == 5 and doc["test_materials"] == part[:1]
    with pytest.raises(ValueError, match="not materials of this synthetic database: nope"):
        synth.write_database_manifest(out, count=5, seed=3, noise=0.0, test_materials=[], record_files=files,
                                      materials=[*part, "nope"])
