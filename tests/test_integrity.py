"""brdfpipe.core.integrity: the digest rules per container, and what a reader says when one fails.

The stage-level cases (the tester's, issue 21) live with their stages: test_svd (flipped bits in the model,
a damaged log-map chunk, an edited Gram partial), test_blend (a changed pixel of a pre-render or a
reference), test_closedloop (a rescaled observation table), test_latent (a store whose rows were swapped,
a truncated model), test_store (the 'database' attribute), test_explorer (a truncated payload),
test_figures / test_report (an edited table).
"""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
import zarr

from brdfpipe.core import exr, filenames, integrity
from brdfpipe.core.integrity import IntegrityError
from brdfpipe.core.zgroup import create_array, finish_group, open_sealed_group

ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------
# What to rerun
# --------------------------------------------------------------------------


def test_every_rule_named_for_a_file_exists_in_the_workflow() -> None:
    rules = set()
    for smk in (ROOT / "workflow" / "rules").glob("*.smk"):
        rules |= set(re.findall(r"^\s*(?:rule|checkpoint)\s+(\w+)\s*:", smk.read_text(), flags=re.M))
        rules |= set(re.findall(r'batch_rule\(\s*"(\w+)"', smk.read_text()))  # one rule per batch
    named = {rule for _, rule in filenames._producers()}
    assert named <= rules, sorted(named - rules)


@pytest.mark.parametrize("path, rule", [
    (filenames.svd_model("train"), "decompose_svd"),
    (filenames.svd_model("train") + "/Q/c/3/0", "decompose_svd"),
    (filenames.gram_partial("all", "2-of-4"), "accumulate_gram"),
    (filenames.logmap("all"), "map_logrelative"),
    (filenames.directions("train", "nearfield", 25, "error"), "optimize_directions"),
    (filenames.errors(), "evaluate_directions"),
    (filenames.closedloop_observations("brass", "nearfield", 25, "error", 2, "sensor"), "capture_closedloop"),
    (filenames.closedloop_errors(), "evaluate_closedloop"),
    (filenames.reconstruction("brass", "point", 0, "condition", 5), "reconstruct_figure_material"),
    (filenames.reconstruction_input("brass", "nearfield", 25, "error", 2, 1), "reconstruct_figure_material"),
    (filenames.reconstruction_render("preview", "brass", "nearfield", 25, "error", 2), "render_reconstructions"),
    (filenames.gram("raw"), "compute_gram"),
    (filenames.gplvm_model("standardised-mu1e-06", 5), "fit_gplvm"),
    (filenames.gplvm_trace("standardised-mu1e-06", 5), "fit_gplvm"),
    (filenames.material_albedos(), "measure_material_albedos"),
    (filenames.albedo(), "analyze_manifold"),
    (filenames.albedo_map(2), "analyze_manifold"),
    (filenames.prerender("preview", "brass"), "prerender_materials"),
    (filenames.prerender_one("preview", "brass"), "prerender_materials"),
    (filenames.path_point("preview", "a--b", 0.5, "weights"), "interpolate_path_points"),
    (filenames.path_point("preview", "a--b", 0.5, "noise"), "render_path_points"),
    (filenames.candidate_path_point("p-48x36-4096spp", "raw-mu1", "a--b", 0.5, "weights"),
     "interpolate_candidate_path_points"),
    (filenames.candidate_path_point("p-48x36-4096spp", "raw-mu1", "a--b", 0.5, "one"),
     "render_candidate_path_points"),
    (filenames.latent_sample("preview", 3, "binary"), "sample_latent_materials"),
    (filenames.latent_samples_json("preview"), "sample_latent_materials"),
    (filenames.latent_sample("preview", 3, "image"), "render_latent_samples"),
    (filenames.lengthscales_csv(), "measure_lengthscales"),
    (filenames.figure_files("render-fig13-errors", note=True)[-1], "plot_render_figures"),
    (filenames.figure_files("manifold-fig06-lengthscale", note=True)[-1], "plot_manifold_figures"),
    (filenames.figure_files("fig08-optimal-configurations", table=True)[2], "plot_acquisition_figures"),
    (filenames.errormap_summary("preview"), "error_maps"),
    (filenames.candidate_errormap_summary("p", "raw-mu1"), "measure_candidate_blends"),
    (filenames.floor_check_csv("p"), "summarize_floor_check"),
    (filenames.candidate_spaces_csv("raw-mu1"), "measure_gplvm_candidate"),
    (filenames.spaces_csv(), "compare_spaces"),
    (filenames.explorer_dir() + "/data/layers.js", "write_explorer"),
    (filenames.splits(), "write_splits"),
    (filenames.unseen_binary("rgl-nbrdf", "spectralon-rgb"), "evaluate_unseen_fits"),
    (filenames.unseen_store("rgl-nbrdf") + "/brdf/c/0/0", "evaluate_unseen_fits"),
    (filenames.unseen_albedo("rgl-nbrdf"), "evaluate_unseen_fits"),
    (filenames.unseen_observations("nielsen-nbrdf"), "capture_unseen_closedloop"),
    (filenames.unseen_errors(), "evaluate_unseen"),
    (filenames.unseen_manifold(), "locate_unseen"),
    ("/abs/work/" + filenames.svd_model("all"), "decompose_svd"),
    ("elsewhere/model.npz", None),
])
def test_rule_of_a_file(path: str, rule: str | None) -> None:
    assert filenames.rule_of(path) == rule
    hint = integrity.rerun_hint(path)
    if rule in filenames.BATCH_RULE_FAMILIES:  # one rule per batch: no single rule name to force
        assert hint == f"delete it and rerun the workflow (a {rule}_* job writes it again)"
    else:
        assert hint == (f"rerun its rule: snakemake --forcerun {rule}" if rule
                        else "write it again with the command that made it")


@pytest.mark.parametrize(("name", "family"), [
    ("prerender_materials_b00", "prerender_materials"),
    ("prerender_materials_b123", "prerender_materials"),
    ("prerender_materials", "prerender_materials"),
    ("prerender_materials_b1", "prerender_materials_b1"),  # batch numbers have two digits at least
    ("render_path_point", "render_path_point"),
    ("fit_gplvm_b01", "fit_gplvm_b01"),  # not a batch family
])
def test_rule_family(name: str, family: str) -> None:
    assert filenames.rule_family(name) == family


def test_batch_rule_names_round_trip() -> None:
    for k in (0, 7, 42, 150):
        name = filenames.batch_rule("prerender_materials", k)
        assert filenames.rule_family(name) == "prerender_materials" and name.endswith(f"_b{k:02d}")
    with pytest.raises(ValueError, match="not a batch-rule family"):
        filenames.batch_rule("fit_gplvm", 0)


@pytest.mark.parametrize(("n", "per_job", "sizes"), [
    (100, 10, [10] * 10), (12, 10, [6, 6]), (11, 10, [6, 5]), (3, 1, [1, 1, 1]), (5, 50, [5]), (0, 4, []),
])
def test_split_batches_keeps_order_and_balances(n: int, per_job: int, sizes: list[int]) -> None:
    items = [f"m{i:03d}" for i in range(n)]
    batches = filenames.split_batches(items, per_job)
    assert [len(b) for b in batches] == sizes
    assert [m for b in batches for m in b] == items
    assert all(len(b) <= per_job for b in batches)
    with pytest.raises(ValueError, match="per_job must be >= 1"):
        filenames.split_batches(items, 0)


# --------------------------------------------------------------------------
# npz
# --------------------------------------------------------------------------


def _arrays() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"X": rng.normal(size=(4, 3)), "names": np.array(["a", "bb", "c", "d"]), "k": np.int64(3),
            "F": np.asfortranarray(rng.normal(size=(3, 2)).astype(np.float32))}


def test_npz_round_trip_and_same_bytes(tmp_path: Path) -> None:
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    integrity.save_npz(a, _arrays())
    integrity.save_npz(b, _arrays())
    assert a.read_bytes() == b.read_bytes()  # no time stamp anywhere
    back = integrity.load_npz(a)
    assert sorted(back) == sorted(_arrays()) and integrity.DIGEST_KEY not in back
    for k, v in _arrays().items():
        assert np.array_equal(back[k], v) and back[k].dtype == np.asarray(v).dtype


@pytest.mark.parametrize("damage", ["value", "dtype", "shape", "dropped", "added", "renamed"])
def test_npz_any_change_is_refused(tmp_path: Path, damage: str) -> None:
    p = tmp_path / "results" / "gplvm" / "gram-raw.npz"
    integrity.save_npz(p, _arrays())
    with np.load(p) as z:
        arrays = dict(z)
    if damage == "value":
        arrays["X"] = arrays["X"].copy()
        arrays["X"][1, 2] = np.nextafter(arrays["X"][1, 2], np.inf)
    elif damage == "dtype":
        arrays["k"] = arrays["k"].astype(np.int32)
    elif damage == "shape":
        arrays["X"] = arrays["X"].reshape(3, 4)
    elif damage == "dropped":
        del arrays["F"]
    elif damage == "added":
        arrays["extra"] = np.zeros(1)
    else:
        arrays["Y"] = arrays.pop("X")
    np.savez(p, **arrays)
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: its arrays do not match their recorded digest "
                                                       "(damaged or edited); rerun its rule: snakemake --forcerun "
                                                       "compute_gram")):
        integrity.load_npz(p)


def test_npz_without_digest_truncated_or_foreign(tmp_path: Path) -> None:
    p = tmp_path / "x.npz"
    np.savez(p, x=np.zeros(3))
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: npz file carries no brdfpipe digest")):
        integrity.load_npz(p)
    assert list(integrity.load_npz(p, require=False)) == ["x"]  # a user's file, when the reader allows it
    integrity.save_npz(p, _arrays())
    data = p.read_bytes()
    for cut in (10, len(data) // 2, len(data) - 30):
        p.write_bytes(data[:cut])
        with pytest.raises(IntegrityError, match=re.escape(f"{p}: truncated or corrupt npz file (")) as exc:
            integrity.load_npz(p)
        assert len(str(exc.value).splitlines()) == 1
    p.write_bytes(b"\x80\x04K\x01.")  # a pickle, not an npz: numpy's message would talk about pickled data
    with pytest.raises(IntegrityError, match="not an npz file: no zip header"):
        integrity.load_npz(p)
    p.write_bytes(b"")
    with pytest.raises(IntegrityError, match="not an npz file: empty file"):
        integrity.load_npz(p)
    with pytest.raises(IntegrityError, match="no such npz file"):
        integrity.load_npz(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match="reserved"):
        integrity.save_npz(p, {integrity.DIGEST_KEY: np.zeros(1)})


def test_npz_corrupt_member_is_one_clean_error(tmp_path: Path) -> None:
    """A byte changed inside a stored member: zip's own CRC catches it, reported as corrupt (no traceback)."""
    p = tmp_path / "x.npz"
    integrity.save_npz(p, {"x": np.arange(1000.0)})
    with zipfile.ZipFile(p) as z:
        info = z.getinfo("x.npy")
    data = bytearray(p.read_bytes())
    data[info.header_offset + 30 + len(info.filename) + 200] ^= 0xFF
    p.write_bytes(bytes(data))
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: ") + "(truncated or corrupt|its arrays do not)"):
        integrity.load_npz(p)


# --------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------


def test_json_round_trip_order_free_and_same_bytes(tmp_path: Path) -> None:
    doc = {"b": [1, 2.5, None, "x"], "a": {"t": (0.1, 1e-300), "name": "é"}, "nan": float("nan")}
    p = tmp_path / "d.json"
    integrity.write_json(p, doc)
    first = p.read_bytes()
    integrity.write_json(p, doc)
    assert p.read_bytes() == first
    back = integrity.read_json(p)
    assert integrity.DIGEST_KEY not in back and back["a"]["t"] == [0.1, 1e-300] and back["b"] == [1, 2.5, None, "x"]
    # indentation and key order are free: the digest is of the canonical text
    raw = json.loads(p.read_text())
    p.write_text(json.dumps(dict(reversed(list(raw.items()))), indent=4, sort_keys=True))
    assert integrity.read_json(p)["a"]["name"] == "é"


def test_json_edits_truncation_and_no_digest(tmp_path: Path) -> None:
    p = tmp_path / "results" / "directions" / "train" / "point-fov0-error.json"
    integrity.write_json(p, {"sets": [{"n": 1, "e": 0.25}]})
    text = p.read_text()
    p.write_text(text.replace("0.25", "0.26"))
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: its content does not match its recorded digest "
                                                       "(damaged or edited); rerun its rule: snakemake --forcerun "
                                                       "optimize_directions")):
        integrity.read_json(p)
    p.write_text(text[: len(text) // 2])
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: truncated or corrupt JSON file (not JSON: ")):
        integrity.read_json(p)
    p.write_text('{"sets": []}')
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: JSON file carries no brdfpipe digest")):
        integrity.read_json(p)
    p.write_text("[1, 2]")
    with pytest.raises(IntegrityError, match="not a JSON object but list"):
        integrity.read_json(p)
    p.write_bytes(b"\xff\xfe{")
    with pytest.raises(IntegrityError, match="not UTF-8 text"):
        integrity.read_json(p)


def test_both_readers_of_a_directions_file_verify_it(tmp_path: Path) -> None:
    """The optimiser's reader and the capture's reader (the tracks meet in this file) both check its digest."""
    from brdfpipe.acquisition.optimize import read_directions
    from brdfpipe.rendering.capture import read_configurations

    p = tmp_path / "d.json"
    p.write_text(json.dumps({"format": "brdfpipe.acquisition.optimize.directions/1", "sets": [],
                             integrity.DIGEST_KEY: "sha256:" + "0" * 64}))
    for reader in (read_directions, read_configurations):
        with pytest.raises(ValueError, match=re.escape(f"{p}: its content does not match its recorded digest")):
            reader(p)


# --------------------------------------------------------------------------
# CSV
# --------------------------------------------------------------------------


def test_csv_digest_line_and_what_other_readers_see(tmp_path: Path) -> None:
    p = tmp_path / "results" / "evaluation" / "errors.csv"
    integrity.write_csv(p, [["material", "value"], ["brass", 0.5], ["chrome, polished", "1e-3"]])
    text = p.read_text()
    assert text.startswith(integrity.CSV_PREFIX) and re.fullmatch(r"# brdfpipe sha256=[0-9a-f]{64}", text.split("\n")[0])
    header, rows = integrity.read_csv_rows(p, required=("material", "value"))
    assert header == ["material", "value"] and rows[1] == {"material": "chrome, polished", "value": "1e-3"}
    # what other readers see: the digest line is a '#' comment (numpy's loadtxt counts it in skiprows)
    assert np.loadtxt(p, delimiter=",", skiprows=2, usecols=1, max_rows=1, dtype=str).item() == "0.5"
    # genfromtxt(names=True) would take the names from the comment: skip it
    assert np.genfromtxt(p, delimiter=",", names=True, skip_header=1, dtype=None, encoding="utf-8",
                         max_rows=1)["value"] == 0.5
    p.write_text(text.replace("0.5", "0.6"))
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: its content does not match its recorded digest "
                                                       "(damaged or edited); rerun its rule: snakemake --forcerun "
                                                       "evaluate_directions")):
        integrity.read_csv_text(p)
    p.write_text(text.split("\n", 1)[1])
    with pytest.raises(IntegrityError, match=re.escape(f"{p}: CSV file carries no brdfpipe digest")):
        integrity.read_csv_text(p)
    assert integrity.read_csv_text(p, require=False).startswith("material,value")
    p.write_text(text[: len(text) - 5])
    with pytest.raises(IntegrityError, match="does not match"):
        integrity.read_csv_text(p)
    integrity.write_csv(p, "a,b\n1,2\n")
    with pytest.raises(IntegrityError, match=r"missing column\(s\) c"):
        integrity.read_csv_rows(p, required=("a", "c"))


# --------------------------------------------------------------------------
# OpenEXR
# --------------------------------------------------------------------------


def test_exr_digest_covers_pixels_attributes_and_precision(tmp_path: Path) -> None:
    img = np.random.default_rng(1).uniform(0, 2, (6, 7, 3)).astype(np.float32)
    for half in (False, True):
        p = tmp_path / f"{half}.exr"
        exr.write_exr(p, img, half=half, attrs={"material": "brass", "spp": "64"})
        assert np.allclose(exr.read_exr(p), img, rtol=1e-3)
        assert exr.read_exr_attrs(p) == {"material": "brass", "spp": "64"}
        first = p.read_bytes()
        exr.write_exr(p, img, half=half, attrs={"spp": "64", "material": "brass"})
        assert p.read_bytes() == first
    with pytest.raises(ValueError, match="reserved"):
        exr.write_exr(tmp_path / "x.exr", img, attrs={integrity.DIGEST_KEY: "mine"})


# --------------------------------------------------------------------------
# Zarr groups
# --------------------------------------------------------------------------


def _group(folder: Path) -> Path:
    g = zarr.open_group(folder, mode="w", zarr_format=3)
    create_array(g, "X", np.arange(60, dtype=np.float32).reshape(3, 20), (3, 8), "float32", ("row", "column"))
    create_array(g, "w", np.ones(20), (20,), "float64", ("column",))
    g.attrs.update({"format": "test/1", "database": "synthetic"})
    finish_group(g, folder, {"rows": 3})
    return folder


def _open(path: Path):  # type: ignore[no-untyped-def]
    return open_sealed_group(path, fmt="test/1", what="group", kind="test group", error=IntegrityError)


def test_sealed_group_checks_attributes_files_and_chunks(tmp_path: Path) -> None:
    good = _group(tmp_path / "results" / "logmap" / "all.zarr")
    (good / ".snakemake_timestamp").touch()  # Snakemake's mark on a directory output: never read, ignored
    group, attrs, digests = _open(good)
    digests.verify()
    assert sorted(digests.names("X/")) == ["X/c/0/0", "X/c/0/1", "X/c/0/2", "X/zarr.json"]
    hint = "rerun its rule: snakemake --forcerun map_logrelative"

    def damaged(how: str) -> Path:
        import shutil

        bad = tmp_path / how / "results" / "logmap" / "all.zarr"
        shutil.copytree(good, bad)
        if how == "attribute":
            doc = json.loads((bad / "zarr.json").read_text())
            doc["attributes"]["database"] = "merl"
            (bad / "zarr.json").write_text(json.dumps(doc))
        elif how == "chunk":
            raw = bytearray((bad / "X" / "c" / "0" / "1").read_bytes())
            raw[-1] ^= 1
            (bad / "X" / "c" / "0" / "1").write_bytes(bytes(raw))
        elif how == "missing":
            (bad / "X" / "c" / "0" / "2").unlink()
        elif how == "extra":
            (bad / "X" / "c" / "0" / "3").write_bytes(b"")
        elif how == "metadata":
            doc = json.loads((bad / "w" / "zarr.json").read_text())
            doc["fill_value"] = 0.0
            (bad / "w" / "zarr.json").write_text(json.dumps(doc))
        return bad

    cases = {
        "attribute": "its attributes do not match their recorded digest (damaged or edited)",
        "missing": "file X/c/0/2 is missing",
        "extra": "unexpected file X/c/0/3 (not recorded when the group was written)",
        "metadata": "file w/zarr.json",
    }
    for how, message in cases.items():
        bad = damaged(how)
        with pytest.raises(IntegrityError, match=re.escape(f"{bad}: {message}") + ".*" + re.escape(hint)):
            _open(bad)
    bad = damaged("chunk")
    _, _, digests = _open(bad)  # opening reads no chunk
    digests.verify(["X/c/0/0"])
    with pytest.raises(IntegrityError, match=re.escape(f"{bad}: file X/c/0/1 does not match its recorded digest "
                                                       f"(damaged or edited); {hint}")):
        digests.verify_chunks(zarr.open_group(bad, mode="r")["X"], "X", [(0, 1)])


def test_an_unsealed_group_is_refused(tmp_path: Path) -> None:
    g = zarr.open_group(tmp_path / "old.zarr", mode="w", zarr_format=3)
    g.attrs.update({"format": "test/1", "brdfpipe_complete": {"rows": 3}})
    with pytest.raises(IntegrityError, match="old.zarr: group carries no brdfpipe digest .*older brdfpipe"):
        _open(tmp_path / "old.zarr")


def test_both_readers_of_a_directions_file_require_its_exact_format(tmp_path: Path) -> None:
    """A directions file of another format version is refused by the capture as by the optimiser (one tag)."""
    from brdfpipe.acquisition.optimize import read_directions
    from brdfpipe.rendering.capture import read_configurations
    from brdfpipe.registry.acquisition import DIRECTIONS_FORMAT

    p = tmp_path / "d.json"
    doc = {"format": DIRECTIONS_FORMAT.rsplit("/", 1)[0] + "/2", "setup": "nearfield", "fov": 25.0, "grid": 8,
           "metric": "error", "split": "train", "sets": []}
    integrity.write_json(p, doc)
    for reader in (read_directions, read_configurations):
        with pytest.raises(ValueError, match=re.escape(str(p))):
            reader(p)
