"""The brdfpipe command line: synth → ingest → info, and its errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import cli
from brdfpipe.data import merl, store


def test_synth_ingest_info_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "db"
    assert cli.main(["-q", "synth", "--count", "5", "--seed", "11", "--out", str(out), "--jobs", "2"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    names = sorted(m["name"] for m in manifest["materials"])
    assert sorted(p.stem for p in out.glob("*.binary")) == names

    zarr_path = tmp_path / "merl.zarr"
    assert cli.main(["-q", "ingest", str(out), "--out", str(zarr_path), "--jobs", "2"]) == 0
    st = store.open_store(zarr_path)
    assert st.database == "synthetic" and list(st.materials) == names
    row = merl.read_merl(out / f"{names[2]}.binary").reshape(-1).astype(np.float32)
    assert np.array_equal(st.brdf[2], row)

    capsys.readouterr()
    assert cli.main(["info", str(zarr_path), "--verify"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["materials"] == 5 and info["database"] == "synthetic" and info["verified"]
    assert info["valid_cells"] == int(merl.measured_mask().sum())

    # A flipped bit in one material's shard: plain `info` (verifying by default) names the store and material.
    shard = st.shard_path(3)
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0x10
    shard.write_bytes(bytes(data))
    capsys.readouterr()
    assert cli.main(["info", str(zarr_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(zarr_path) in err and names[3] in err, err
    assert cli.main(["info", str(zarr_path), "--no-verify"]) == 0  # metadata only: the bytes are not read


def test_ingest_of_a_bad_file_exits_non_zero_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "merl"
    folder.mkdir()
    table = np.full(merl.SHAPE, 0.2)
    table[:, ~merl.measured_mask()] = -1.0
    merl.write_merl(folder / "good.binary", table)
    data = bytearray((folder / "good.binary").read_bytes())
    data[100:108] = np.float64(np.nan).tobytes()
    (folder / "nan-inside.binary").write_bytes(bytes(data))
    out = tmp_path / "merl.zarr"
    assert cli.main(["-q", "ingest", str(folder), "--out", str(out), "--jobs", "1"]) == 1
    err = capsys.readouterr().err
    assert "nan-inside.binary" in err and "non-finite" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["synth", "--count", "0", "--seed", "1", "--out", "x"],
        ["synth", "--count", "3", "--seed", "1", "--out", "x", "--noise", "-1"],
        ["info"],
    ],
)
def test_bad_arguments_exit_with_usage_error(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2


def test_missing_folder_and_store_are_clear_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["ingest", str(tmp_path / "nowhere"), "--out", str(tmp_path / "s.zarr")]) == 1
    assert "does not exist" in capsys.readouterr().err
    assert cli.main(["info", str(tmp_path / "none.zarr")]) == 1
    assert "no such store" in capsys.readouterr().err


def test_interpolate_between_and_at(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from brdfpipe.manifold import gplvm, gram

    out = tmp_path / "db"
    assert cli.main(["-q", "synth", "--count", "5", "--seed", "3", "--out", str(out), "--jobs", "2"]) == 0
    zarr_path = tmp_path / "merl.zarr"
    assert cli.main(["-q", "ingest", str(out), "--out", str(zarr_path), "--jobs", "2"]) == 0
    gram_path, model_path = tmp_path / "gram.npz", tmp_path / "q2.npz"
    gram.write_gram(zarr_path, gram_path)
    gplvm.fit_to_files(gram_path, model_path, tmp_path / "q2-trace.csv", q=2, seed=1, max_sweeps=20)
    st = store.open_store(zarr_path)
    a, b = st.materials[0], st.materials[3]

    # t = 0 is material A's latent point exactly: the blend reproduces A
    res = tmp_path / "a.binary"
    argv = ["-q", "interpolate", "--model", str(model_path), "--store", str(zarr_path), "--out", str(res)]
    assert cli.main([*argv, "--between", a, b, "--t", "0"]) == 0
    got = merl.read_merl(res).reshape(-1)
    valid = np.tile(np.asarray(st.valid[:]), 3)
    want = np.asarray(st.brdf[0], dtype=np.float64)
    assert np.allclose(got[valid], want[valid], rtol=1e-6, atol=1e-9)
    assert (got[~valid] < 0).all()

    # far away in latent space: the mean of the materials
    assert cli.main([*argv, "--at", "1000,1000"]) == 0
    mean = np.mean(np.asarray(st.brdf[:, :], dtype=np.float64), axis=0)
    assert np.allclose(merl.read_merl(res).reshape(-1)[valid], np.maximum(mean[valid], 0), rtol=1e-6, atol=1e-9)

    capsys.readouterr()
    assert cli.main([*argv, "--at", "1,2,3"]) == 1
    assert "--at: " in (err := capsys.readouterr().err) and "has q = 2 latent coordinates, got 3" in err
    assert cli.main([*argv, "--between", a, "no-such-material"]) == 1
    assert "unknown material" in capsys.readouterr().err


def test_render_writes_an_exr_and_rejects_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("mitsuba")
    from brdfpipe.core import exr
    from brdfpipe.data import merl
    from brdfpipe.rendering import render

    merl.write_merl(tmp_path / "grey.binary", render.lambertian_table(0.4))
    out = tmp_path / "grey.exr"
    assert cli.main(["-q", "render", str(tmp_path / "grey.binary"), "--out", str(out),
                 "--resolution", "16", "12", "--spp", "4", "--max-depth", "2"]) == 0
    img = exr.read_exr(out)
    assert img.shape == (12, 16, 3) and img.mean() > 0
    assert cli.main(["-q", "render", str(tmp_path / "grey.binary"), "--out", str(tmp_path / "x.exr"),
                 "--variant", "scalar_mono"]) == 1
    assert "scalar_mono" in capsys.readouterr().err
    (tmp_path / "bad.binary").write_bytes(b"junk")
    assert cli.main(["-q", "render", str(tmp_path / "bad.binary"), "--out", str(tmp_path / "y.exr")]) == 1
    assert "bad.binary" in capsys.readouterr().err
    assert not (tmp_path / "x.exr").exists() and not (tmp_path / "y.exr").exists()
