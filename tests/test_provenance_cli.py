"""The CLI never writes over an input and never prints a traceback for bad input or environment."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import cli
from brdfpipe.data import merl


def _one_error_line(capsys: pytest.CaptureFixture[str], command: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"brdfpipe {command}: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def material(tmp_path: Path) -> Path:
    table = np.full(merl.SHAPE, 0.3)
    table[:, ~merl.measured_mask()] = -merl.SCALES[:, None]
    path = tmp_path / "grey.binary"
    merl.write_merl(path, table)
    return path


def _snapshot(*paths: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in paths}


# --------------------------------------------------------------------------
# --out equal to an input
# --------------------------------------------------------------------------


def test_render_refuses_its_material_as_out(
    tmp_path: Path, material: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _snapshot(material)
    link = tmp_path / "link.exr"
    link.symlink_to(material)
    for out in (material, link, tmp_path / "." / material.name):
        assert cli.main(["-q", "render", str(material), "--out", str(out)]) == 1
        line = _one_error_line(capsys, "render")
        assert "would write over the input" in line and str(material) in line
    assert _snapshot(material) == before
    envmap = tmp_path / "sky.exr"
    envmap.write_bytes(b"not really an exr")
    assert cli.main(["-q", "render", str(material), "--envmap", str(envmap), "--out", str(envmap)]) == 1
    assert "sky.exr" in _one_error_line(capsys, "render")
    assert envmap.read_bytes() == b"not really an exr"


def test_interpolate_refuses_its_model_or_store_as_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "q2.npz"
    model.write_bytes(b"model bytes")
    store = tmp_path / "merl.zarr"
    store.mkdir()
    (store / "zarr.json").write_text("{}")
    before = _snapshot(model, store / "zarr.json")
    argv = ["-q", "interpolate", "--model", str(model), "--store", str(store), "--at", "0,0"]
    for out in (model, store, tmp_path):
        assert cli.main([*argv, "--out", str(out)]) == 1
        assert "would write over the input" in _one_error_line(capsys, "interpolate")
    assert _snapshot(model, store / "zarr.json") == before


def test_reconstruct_refuses_its_observations_or_model_as_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    obs = tmp_path / "obs.csv"
    obs.write_text("theta_h,theta_d,phi_d,r,g,b\n1,2,3,0.1,0.1,0.1\n")
    model = tmp_path / "train.zarr"
    model.mkdir()
    (model / "zarr.json").write_text("{}")
    link = tmp_path / "obs-link.binary"
    link.symlink_to(obs)
    before = _snapshot(obs, model / "zarr.json")
    for out in (obs, link, model):
        assert cli.main(["-q", "reconstruct", str(obs), "--model", str(model), "--out", str(out)]) == 1
        assert "would write over the input" in _one_error_line(capsys, "reconstruct")
    assert _snapshot(obs, model / "zarr.json") == before


def test_ingest_refuses_its_source_as_out(
    tmp_path: Path, material: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _snapshot(material)
    for out in (tmp_path, material):
        assert cli.main(["-q", "ingest", str(tmp_path), "--out", str(out)]) == 1
        assert "would write over the input" in _one_error_line(capsys, "ingest")
    assert _snapshot(material) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grey.binary"]


def test_ingest_reports_bad_folders_cleanly(tmp_path: Path, material: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["-q", "ingest", " ", "--out", str(tmp_path / "s.zarr")]) == 1
    assert _one_error_line(capsys, "ingest").endswith(
        "folder: empty path; give the folder of MERL files"
    )
    (tmp_path / "Other.BINARY").write_bytes(material.read_bytes())
    assert cli.main(["-q", "ingest", str(tmp_path), "--out", str(tmp_path / "s.zarr")]) == 1
    assert "Other.BINARY" in _one_error_line(capsys, "ingest")


def test_synth_refuses_a_foreign_out_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "thesis.tex").write_text("precious")
    assert cli.main(["-q", "synth", "--count", "1", "--seed", "0", "--out", str(tmp_path)]) == 1
    assert "refusing to write into it" in _one_error_line(capsys, "synth")
    assert [p.name for p in tmp_path.iterdir()] == ["thesis.tex"]


# --------------------------------------------------------------------------
# Environment errors: one clean line, the right exit status
# --------------------------------------------------------------------------


def _reconstruct_raising(monkeypatch: pytest.MonkeyPatch, exc: BaseException) -> None:
    import brdfpipe.acquisition.reconstruct

    def fail(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(brdfpipe.acquisition.reconstruct, "write_reconstruction", fail)


def _reconstruct_argv(tmp_path: Path) -> list[str]:
    obs = tmp_path / "obs.csv"
    obs.write_text("x")
    return ["-q", "reconstruct", str(obs), "--model", str(tmp_path / "m.zarr"), "--out", str(tmp_path / "out.binary")]


def test_out_of_space_is_one_line_naming_the_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = _reconstruct_argv(tmp_path)
    _reconstruct_raising(monkeypatch, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    assert cli.main(argv) == 1
    line = _one_error_line(capsys, "reconstruct")
    assert line.endswith(f"no space left on device writing {tmp_path / 'out.binary'}")
    tmp = tmp_path / ".out.binary.tmp-1-abcdef12"
    _reconstruct_raising(monkeypatch, OSError(errno.EDQUOT, os.strerror(errno.EDQUOT), str(tmp)))
    assert cli.main(argv) == 1
    # the output the user named, not the hidden temporary file the OS error carries
    assert _one_error_line(capsys, "reconstruct").endswith(f"no space left on device writing {tmp_path / 'out.binary'}")


def test_other_os_errors_name_the_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = _reconstruct_argv(tmp_path)
    _reconstruct_raising(monkeypatch, OSError(errno.EIO, os.strerror(errno.EIO), "/data/m.zarr/c/0"))
    assert cli.main(argv) == 1
    assert _one_error_line(capsys, "reconstruct").endswith("/data/m.zarr/c/0: Input/output error")
    _reconstruct_raising(monkeypatch, IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), "/x/y"))
    assert cli.main(argv) == 1
    assert _one_error_line(capsys, "reconstruct").endswith("/x/y: Is a directory")
    _reconstruct_raising(monkeypatch, OSError(errno.EROFS, os.strerror(errno.EROFS), "/a", None, "/b"))
    assert cli.main(argv) == 1
    assert _one_error_line(capsys, "reconstruct").endswith("/a -> /b: Read-only file system")


def test_a_real_os_error_is_one_line(
    tmp_path: Path, material: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    out = blocker / "db"  # a folder under a file: a real NotADirectoryError/FileExistsError
    assert cli.main(["-q", "synth", "--count", "1", "--seed", "0", "--out", str(out)]) == 1
    assert str(blocker) in _one_error_line(capsys, "synth")
    assert cli.main(["-q", "info", str(material)]) == 1  # a file, not a store
    _one_error_line(capsys, "info")
    if os.geteuid() != 0:  # root can write anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        try:
            assert cli.main(["-q", "synth", "--count", "1", "--seed", "0", "--out", str(ro / "db")]) == 1
            line = _one_error_line(capsys, "synth")
            assert str(ro / "db") in line and "Permission denied" in line
        finally:
            ro.chmod(0o700)


def test_keyboard_interrupt_exits_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _reconstruct_raising(monkeypatch, KeyboardInterrupt())
    assert cli.main(_reconstruct_argv(tmp_path)) == 130
    line = _one_error_line(capsys, "reconstruct")
    assert "interrupted; nothing was written / earlier output kept" in line


def test_memory_error_in_render_names_the_settings(
    tmp_path: Path, material: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import brdfpipe.rendering.scene

    def fail(*args: object, **kwargs: object) -> None:
        raise MemoryError

    monkeypatch.setattr(brdfpipe.rendering.scene, "render_material", fail)
    import numpy as np

    from brdfpipe.core import exr

    envmap = tmp_path / "sky.exr"
    exr.write_exr(envmap, np.ones((3, 6, 3), dtype=np.float32))  # read before rendering: must be an image
    argv = ["-q", "render", str(material), "--envmap", str(envmap), "--out", str(tmp_path / "img.exr"),
            "--resolution", "4000", "3000", "--spp", "1024"]
    assert cli.main(argv) == 1
    line = _one_error_line(capsys, "render")
    assert "too large for memory" in line and "4000×3000" in line and "1024" in line
    assert "--resolution" in line and "--spp" in line
    assert not (tmp_path / "img.exr").exists()
