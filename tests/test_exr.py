"""Tests of :mod:`brdfpipe.core.exr`: round trips, attributes, and errors that name the file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.core import exr
from brdfpipe.core.exr import ExrError, read_exr, read_exr_attrs, write_exr


def _image(h: int = 9, w: int = 13, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    # a wide dynamic range, including tiny and large values and zeros
    img = rng.lognormal(mean=0.0, sigma=3.0, size=(h, w, 3)).astype(np.float32)
    img[0, 0] = 0.0
    return img


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_float32_round_trip_is_exact(tmp_path: Path) -> None:
    img = _image()
    write_exr(tmp_path / "a.exr", img)
    back = read_exr(tmp_path / "a.exr")
    assert back.dtype == np.float32 and back.shape == img.shape
    assert np.array_equal(back, img)
    assert _leftovers(tmp_path) == []


def test_half_round_trip_within_half_precision(tmp_path: Path) -> None:
    img = _image()
    img = np.clip(img, 0.0, 6.0e4)
    write_exr(tmp_path / "h.exr", img, half=True)
    back = read_exr(tmp_path / "h.exr")
    assert back.dtype == np.float32
    assert np.array_equal(back, img.astype(np.float16).astype(np.float32))
    normal = img >= np.finfo(np.float16).tiny
    assert np.all(np.abs(back - img)[normal] <= 2.0**-11 * img[normal])
    # a half file is smaller than a float one
    write_exr(tmp_path / "f.exr", img)
    assert (tmp_path / "h.exr").stat().st_size < (tmp_path / "f.exr").stat().st_size


def test_half_overflow_is_refused(tmp_path: Path) -> None:
    img = np.full((2, 2, 3), 1.0e5, dtype=np.float32)
    with pytest.raises(ValueError, match="overflows half"):
        write_exr(tmp_path / "o.exr", img, half=True)
    assert not (tmp_path / "o.exr").exists() and _leftovers(tmp_path) == []


def test_attributes_round_trip_and_same_bytes(tmp_path: Path) -> None:
    attrs = {"database": "merl", "material": "gold-metallic-paint", "spp": "64", "seed": "3", "note": "ü ✓"}
    img = _image()
    write_exr(tmp_path / "a.exr", img, attrs=attrs)
    write_exr(tmp_path / "b.exr", img, attrs=dict(reversed(list(attrs.items()))))
    assert read_exr_attrs(tmp_path / "a.exr") == attrs
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    write_exr(tmp_path / "c.exr", img)
    assert read_exr_attrs(tmp_path / "c.exr") == {}


@pytest.mark.parametrize(
    "attrs, match",
    [({"channels": "x"}, "reserved"), ({"spp": 64}, "must be a string"), ({"": "x"}, "non-empty")],
)
def test_bad_attributes_are_refused(tmp_path: Path, attrs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        write_exr(tmp_path / "a.exr", _image(), attrs=attrs)
    assert list(tmp_path.iterdir()) == []


def test_rgba_file_is_read_as_rgb(tmp_path: Path) -> None:
    import OpenEXR

    img = _image()
    channels = {c: np.ascontiguousarray(img[..., i]) for i, c in enumerate("RGB")}
    channels["A"] = np.ones(img.shape[:2], dtype=np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(str(tmp_path / "rgba.exr"))
    # another program's file: no brdfpipe digest, so only read unverified
    assert np.array_equal(read_exr(tmp_path / "rgba.exr", verify=False), img)
    with pytest.raises(ExrError, match=r"rgba\.exr: OpenEXR image carries no brdfpipe digest"):
        read_exr(tmp_path / "rgba.exr")


def test_missing_rgb_channels_name_the_file(tmp_path: Path) -> None:
    import OpenEXR

    y = np.ones((4, 5), dtype=np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"Y": y}) as f:
        f.write(str(tmp_path / "gray.exr"))
    with pytest.raises(ExrError, match=r"gray\.exr.*missing channel\(s\) R, G, B"):
        read_exr(tmp_path / "gray.exr", verify=False)


def test_missing_file_names_the_file(tmp_path: Path) -> None:
    p = tmp_path / "nope.exr"
    with pytest.raises(ExrError, match=r"nope\.exr: no such file"):
        read_exr(p)
    with pytest.raises(ExrError, match=r"nope\.exr: no such file"):
        read_exr_attrs(p)


def test_random_bytes_and_empty_file_name_the_file(tmp_path: Path) -> None:
    (tmp_path / "noise.exr").write_bytes(np.random.default_rng(1).bytes(1000))
    (tmp_path / "empty.exr").write_bytes(b"")
    with pytest.raises(ExrError, match=r"noise\.exr: not an OpenEXR file"):
        read_exr(tmp_path / "noise.exr")
    with pytest.raises(ExrError, match=r"empty\.exr: not an OpenEXR file \(empty file\)"):
        read_exr(tmp_path / "empty.exr")


@pytest.mark.parametrize("keep", [0.2, 0.5, 0.9, 0.99])
def test_truncated_file_names_the_file(tmp_path: Path, keep: float) -> None:
    write_exr(tmp_path / "full.exr", _image(40, 50))
    data = (tmp_path / "full.exr").read_bytes()
    cut = tmp_path / "cut.exr"
    cut.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(ExrError, match=r"cut\.exr: truncated or corrupt"):
        read_exr(cut)


def test_nan_pixels_name_the_file(tmp_path: Path) -> None:
    import OpenEXR

    img = _image()
    img[3, 4, 1] = np.nan
    img[5, 6, 0] = np.inf
    channels = {c: np.ascontiguousarray(img[..., i]) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(str(tmp_path / "nan.exr"))
    with pytest.raises(ExrError, match=r"nan\.exr: 2 non-finite value\(s\).*row 3, column 4, channel G"):
        read_exr(tmp_path / "nan.exr", verify=False)


def test_failed_write_leaves_no_file_and_no_temp(tmp_path: Path) -> None:
    img = _image()
    img[1, 1, 1] = np.nan
    with pytest.raises(ExrError, match=r"bad\.exr: refusing to write 1 non-finite"):
        write_exr(tmp_path / "bad.exr", img)
    with pytest.raises(ValueError, match=r"shape \(H, W, 3\)"):
        write_exr(tmp_path / "bad.exr", np.zeros((3, 3)))
    assert list(tmp_path.iterdir()) == []


def test_error_inside_the_writer_removes_the_temp_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # an existing output stays untouched when a later write fails half-way
    good = _image()
    write_exr(tmp_path / "out.exr", good)
    before = (tmp_path / "out.exr").read_bytes()

    class Boom:
        def __init__(self, *a: object, **k: object) -> None:
            pass

        def __enter__(self) -> "Boom":
            return self

        def __exit__(self, *a: object) -> None:
            return None

        def write(self, name: str) -> None:
            Path(name).write_bytes(b"partial")
            raise OSError("disk full")

    monkeypatch.setattr(exr.OpenEXR, "File", Boom)
    with pytest.raises(OSError, match="disk full"):
        write_exr(tmp_path / "out.exr", _image(seed=5))
    assert (tmp_path / "out.exr").read_bytes() == before
    assert _leftovers(tmp_path) == []


def test_importing_exr_blend_scene_does_not_import_mitsuba() -> None:
    code = "import sys, brdfpipe.core.exr, brdfpipe.rendering.blend, brdfpipe.rendering.scene; print('mitsuba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
