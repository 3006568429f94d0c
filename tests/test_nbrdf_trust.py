"""Hostile archives of NBRDF fits (issue 31): one line naming the archive, the fit and the problem, nothing written.

Every bad archive here is built from the shipped Nielsen archive (8 fits, 37 kB) by replacing one
member.  Each case is refused by ``brdfpipe nbrdf`` (exit 1, one line, no output folder) and at
parse time by the configured database (``nbrdf_archive``), before any job.
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
import case_log

from brdfpipe import cli
from brdfpipe.data import database, merl, nbrdf

ARCHIVES = Path(__file__).resolve().parents[1] / "src" / "brdfpipe" / "data" / "archives"
NIELSEN = ARCHIVES / "nielsen_nbrdf.zip"
FOLDER = "nielsen_nbrdf/"
VICTIM = "bluebook"  # the fit each case damages (the first of the archive's sorted names)


def _members() -> dict[str, bytes]:
    with zipfile.ZipFile(NIELSEN) as z:
        return {i.filename: z.read(i) for i in z.infolist() if not i.is_dir()}


def _archive(tmp_path: Path, replace: dict[str, bytes | None], *, stored: bool = False) -> Path:
    """The Nielsen archive with members replaced (``None``: removed), written to ``tmp_path/fits.zip``."""
    members = {**_members(), **replace}
    path = tmp_path / "fits.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED if stored else zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            if data is not None:
                z.writestr(name, data)
    return path


def _h5(edit: Callable[[h5py.File], None], fit: str = VICTIM) -> bytes:
    """A copy of a shipped fit's weights file with ``edit`` applied."""
    buf = io.BytesIO()
    with h5py.File(io.BytesIO(_members()[f"{FOLDER}{fit}.h5"]), "r") as f, h5py.File(buf, "w") as g:
        for k, v in f.attrs.items():
            g.attrs[k] = v
        for name in f:
            f.copy(f[name], g, name)
        edit(g)
    return buf.getvalue()


def _patch_member_header(path: Path, member: str, *, method: int | None = None, flags: int | None = None) -> None:
    """Rewrite the compression method or the flag bits of ``member`` in its local and its central header."""
    data = bytearray(path.read_bytes())
    name = member.encode()
    for sig, at_flags, at_method, name_at in ((b"PK\x03\x04", 6, 8, 30), (b"PK\x01\x02", 8, 10, 46)):
        pos = data.find(sig)
        while data[pos + name_at: pos + name_at + len(name)] != name:
            pos = data.find(sig, pos + 1)
            assert pos >= 0, member
        if flags is not None:
            data[pos + at_flags: pos + at_flags + 2] = struct.pack("<H", flags)
        if method is not None:
            data[pos + at_method: pos + at_method + 2] = struct.pack("<H", method)
    path.write_bytes(bytes(data))


def _deep_json() -> bytes:
    return b"[" * 200_000 + b"]" * 200_000


def _bias(delta: float, layer: int = 3) -> Callable[[h5py.File], None]:
    def edit(g: h5py.File) -> None:
        g[f"dense_{layer}/dense_{layer}/bias:0"][...] += np.float32(delta)
    return edit


def _nan_weight(g: h5py.File) -> None:
    g["dense_2/dense_2/kernel:0"][3, 4] = np.nan


def _wrong_shapes(g: h5py.File) -> None:
    del g["dense_1/dense_1/kernel:0"]
    g["dense_1/dense_1"].create_dataset("kernel:0", data=np.zeros((7, 21), dtype=np.float32))


SIDECAR = f"{FOLDER}{VICTIM}.json"
WEIGHTS = f"{FOLDER}{VICTIM}.h5"

#: Bad archives: id → (members replaced, the words the one-line message must hold, the member it names).
CASES: dict[str, tuple[dict[str, bytes | None], str, str]] = {
    "deeply nested sidecar": ({SIDECAR: _deep_json()}, "nested too deeply", SIDECAR),
    "sidecar layers not objects": ({SIDECAR: b'{"config": {"layers": [1, "dense", null]}}'},
                                   "not a Keras model description", SIDECAR),
    "sidecar layers a dict": ({SIDECAR: b'{"config": {"layers": {"a": {"b": 1}}}}'},
                              "not a Keras model description", SIDECAR),
    "sidecar config not an object": ({SIDECAR: b'{"config": "Sequential"}'}, "not a Keras model description", SIDECAR),
    "sidecar a list": ({SIDECAR: b'[{"config": {}}]'}, "not a Keras model description", SIDECAR),
    "sidecar layer config not an object": (
        {SIDECAR: json.dumps({"config": {"layers": [{"class_name": "Dense", "config": [21]}] * 3
                                         + [{"class_name": "Lambda", "config": {}}]}}).encode()},
        "not a Keras model description", SIDECAR),
    "sidecar units overflow": (
        {SIDECAR: _members()[SIDECAR].replace(b'"units": 21', b'"units": 1e999', 1)},
        "not the published NBRDF network", SIDECAR),
    "truncated weights": ({WEIGHTS: _members()[WEIGHTS][:9000]}, "not a readable Keras weights file", WEIGHTS),
    "NaN weight": ({WEIGHTS: _h5(_nan_weight)}, "NaN or Inf", WEIGHTS),
    "wrong layer shapes": ({WEIGHTS: _h5(_wrong_shapes)}, "not the published NBRDF network", WEIGHTS),
    "scalar kernel": ({WEIGHTS: _h5(lambda g: (g["dense_3/dense_3"].pop("kernel:0"),
                                               g["dense_3/dense_3"].create_dataset("kernel:0", data=np.float32(1))))},
                      "not the published NBRDF network", WEIGHTS),
    "all-negative fit": ({WEIGHTS: _h5(_bias(-200.0))}, "negative everywhere", WEIGHTS),
    "overflowing fit": ({WEIGHTS: _h5(_bias(1000.0))}, "overflows", WEIGHTS),
    "bright fit (1e17 sr^-1)": ({WEIGHTS: _h5(_bias(39.0))}, "albedo at normal incidence", WEIGHTS),
}


def _one_line_naming(text: str, archive: Path, member: str, words: str) -> None:
    assert text.count("\n") == 0, text
    assert f"{archive}:{member}" in text and words in text, text


@pytest.mark.parametrize("case", CASES)
def test_nbrdf_ends_a_bad_archive_in_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    replace, words, member = CASES[case]
    archive = _archive(tmp_path, replace)
    out = tmp_path / "out"
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    case_log.record(f"brdfpipe nbrdf: {case}", err)
    assert err.startswith("brdfpipe nbrdf: error: ")
    _one_line_naming(err, archive, member, words)
    assert "internal error" not in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("case", CASES)
def test_a_bad_user_archive_fails_at_parse_time_naming_the_key(tmp_path: Path, case: str) -> None:
    replace, words, member = CASES[case]
    archive = _archive(tmp_path, replace)
    with pytest.raises(database.DatabaseError) as err:
        database.configured_database({"database": "nbrdf", "nbrdf_archive": str(archive)}, str(tmp_path / "results"))
    assert str(err.value).startswith("nbrdf_archive: ")
    _one_line_naming(str(err.value), archive, member, words)
    assert not (tmp_path / "results").exists()


@pytest.mark.slow
def test_the_workflow_stops_at_parse_time_on_a_bad_user_archive(tmp_path: Path) -> None:
    """The Snakefile's database loader: a dry run ends in one line naming the key, the archive and the fit."""
    import subprocess
    import sys

    import yaml

    root = Path(__file__).resolve().parents[1]
    archive = _archive(tmp_path, {WEIGHTS: _h5(_nan_weight)})
    cfg = yaml.safe_load((root / "tests" / "config" / "tiny.yaml").read_text())
    cfg.update(database="nbrdf", nbrdf_archive=str(archive))
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(cfg))
    r = subprocess.run([str(Path(sys.executable).with_name("snakemake")), "-n", "--snakefile",
                        str(root / "workflow" / "Snakefile"), "--directory", str(tmp_path), "--configfile",
                        str(tmp_path / "bad.yaml"), "--cores", "1"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=600)
    out = r.stdout + r.stderr
    assert r.returncode != 0
    assert f"invalid configuration: nbrdf_archive: {archive}:{WEIGHTS}: layer 2 holds NaN or Inf weights" in out, out
    assert "Traceback" not in out and not (tmp_path / "results").exists()


@pytest.mark.parametrize("how,words", [
    ("method", "compression method 9"),
    ("encrypted", "encrypted"),
    ("corrupt", "cannot be read"),
])
def test_zip_members_that_cannot_be_read_name_the_archive(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], how: str, words: str
) -> None:
    archive = _archive(tmp_path, {}, stored=how != "corrupt")
    if how == "method":  # deflate64: zipfile raises NotImplementedError
        _patch_member_header(archive, WEIGHTS, method=9)
    elif how == "encrypted":  # traditional PKWARE encryption: zipfile raises RuntimeError without the archive
        _patch_member_header(archive, WEIGHTS, flags=0x1)
    else:  # a damaged deflate stream
        data = bytearray(archive.read_bytes())
        with zipfile.ZipFile(archive) as z:
            info = z.getinfo(WEIGHTS)
        start = info.header_offset + 30 + len(WEIGHTS.encode()) + len(info.extra)
        data[start + 40: start + 400] = bytes(360)
        archive.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    case_log.record(f"brdfpipe nbrdf: zip member {how}", err)
    _one_line_naming(err, archive, WEIGHTS, words)
    assert not out.exists()
    with pytest.raises(database.DatabaseError) as e:
        database.configured_database({"database": "nbrdf", "nbrdf_archive": str(archive)})
    _one_line_naming(str(e.value), archive, WEIGHTS, words)


# -- the evaluation refuses a table that is not a material ----------------------------------------------


def _fit_with(edit: Callable[[h5py.File], None], tmp_path: Path, fit: str = VICTIM) -> nbrdf.Fit:
    archive = _archive(tmp_path, {f"{FOLDER}{fit}.h5": _h5(edit, fit)})
    return nbrdf.open_archive(archive).fit(fit)


def test_a_mostly_negative_fit_is_refused_by_the_evaluation_naming_the_share(tmp_path: Path) -> None:
    """bluebook with its output bias lowered by 1: 84 % of its values negative, passes the parse-time bound."""
    fit = _fit_with(_bias(-1.0), tmp_path)
    nbrdf.check_fit(fit)  # the bound cannot tell: the evaluation must
    out = tmp_path / "t.binary"
    with pytest.raises(nbrdf.NbrdfError) as err:
        nbrdf.write_fit(fit, out)
    text = str(err.value)
    assert text.startswith(fit.source) and "\n" not in text
    assert "84.3% of the values are negative" in text and f"at most {nbrdf.MAX_CLAMPED_SHARE:.0%}" in text
    assert not out.exists() and not any(tmp_path.glob(".t.binary*"))


def test_the_workflow_evaluation_refuses_a_bright_fit_naming_the_albedo(tmp_path: Path) -> None:
    """A fit with values around 1e17 sr^-1 (output bias + 39) never enters a store."""
    archive = _archive(tmp_path, {WEIGHTS: _h5(_bias(39.0)),  # a user's archive: no shipped weights in it
                                  f"{FOLDER}cardboard.h5": _h5(_bias(0.01), "cardboard")})
    with pytest.raises(nbrdf.NbrdfError, match="albedo at normal incidence"):
        nbrdf.check_fit(nbrdf.open_archive(archive).fit(VICTIM))  # parse time: the lower bound already proves it
    binaries = [tmp_path / "a.binary", tmp_path / "b.binary"]
    with pytest.raises(nbrdf.NbrdfError) as err:
        nbrdf.evaluate_to_files(archive=archive, fits={"a": "cardboard", "b": VICTIM}, binaries=binaries,
                                database="nbrdf")
    text = str(err.value)
    assert text.startswith(f"{tmp_path / 'fits.zip'}:{WEIGHTS}: directional albedo at normal incidence")
    assert f"allowed (0, {nbrdf.MAX_ALBEDO:g}]" in text and "e+17" in text and "\n" not in text
    assert not binaries[1].exists()


def test_an_all_negative_fit_is_refused_by_the_evaluation_too(tmp_path: Path) -> None:
    fit = _fit_with(_bias(-200.0), tmp_path)
    with pytest.raises(nbrdf.NbrdfError, match=r"100\.0% of the values are negative"):
        nbrdf.write_fit(fit, tmp_path / "t.binary")
    assert not (tmp_path / "t.binary").exists()


def test_every_shipped_fit_passes_the_parse_time_check_and_the_registry_has_its_digest(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The parse time skips the shipped archives by their digests: these bytes pass the whole check."""
    import hashlib

    from brdfpipe.data import databases

    monkeypatch.setattr(nbrdf, "_CHECKED", set())
    shipped = [n for n, d in databases.DATABASES.items() if d.source == "archive"]
    assert len(shipped) == 3
    for name in shipped:
        path = databases.shipped_archive(name)
        assert len(nbrdf.check_archive(path)) == {"merl-nbrdf": 100, "rgl-nbrdf": 51, "nielsen-nbrdf": 8}[name]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == databases.DATABASES[name].archive_sha256
    assert nbrdf._CHECKED == {d.archive_sha256 for d in databases.DATABASES.values() if d.archive_sha256}


def test_the_albedo_weight_bound_holds() -> None:
    """check_fit's bright-fit refusal: a table of ones has an albedo at normal incidence of at least 3."""
    ones = np.where(merl.measured_mask(), 1.0, -1.0)[None].repeat(3, axis=0)
    assert (merl.directional_albedo(ones, [0.0])[0] >= nbrdf._ALBEDO_WEIGHT_MIN).all()


def test_the_output_bound_holds_on_the_grid() -> None:
    """The interval bound of y contains every value of the network on the MERL grid (checked on shipped fits)."""
    cells, x = nbrdf._grid()
    for archive, name in ((NIELSEN, "glossyredpaper"), (ARCHIVES / "rgl-isotropic_nbrdf.zip", "cg_sunflower_rgb")):
        fit = nbrdf.open_archive(archive).fit(name)
        lo, hi = nbrdf.output_bounds(fit)
        y = np.log1p(nbrdf.evaluate(fit, *(a.ravel()[cells] for a in merl.cell_centres())))
        assert (y.min(axis=0) >= lo).all() and (y.max(axis=0) <= hi).all()


def test_nbrdf_with_a_bad_fit_among_good_ones_replaces_nothing(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The refusal comes after good fits were evaluated: none of them is written, an earlier output is kept."""
    out = tmp_path / "out"
    assert cli.main(["-q", "nbrdf", str(NIELSEN), "--out", str(out), "cardboard"]) == 0
    before = (out / "cardboard.binary").read_bytes()
    archive = _archive(tmp_path, {f"{FOLDER}notebook.h5": _h5(_bias(-1.0), "notebook")})
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(out), "cardboard", "bluebook", "notebook"]) == 1
    err = capsys.readouterr().err.strip()
    assert f"{archive}:{FOLDER}notebook.h5" in err and "values are negative" in err
    assert sorted(p.name for p in out.iterdir()) == ["cardboard.binary"]
    assert (out / "cardboard.binary").read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    # a new --out, and the folders above it that the command made, are gone again
    new = tmp_path / "new" / "deeper" / "out"
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(new), "cardboard", "notebook"]) == 1
    assert not (tmp_path / "new").exists()
