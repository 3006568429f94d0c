"""NBRDF fits (brdfpipe.data.nbrdf): reading Keras weights without TensorFlow, evaluation on the MERL grid."""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest

from brdfpipe.data import merl, nbrdf

ARCHIVES = Path(__file__).resolve().parents[1] / "src" / "brdfpipe" / "data" / "archives"
MERL_FITS = ARCHIVES / "merl_nbrdf.zip"
RGL_FITS = ARCHIVES / "rgl-isotropic_nbrdf.zip"


def _weights_by_hand(path: Path, name: str) -> list[tuple[list[list[float]], list[float]]]:
    """The dense layers of a fit, read member by member with h5py and converted to Python floats."""
    with zipfile.ZipFile(path) as z:
        (member,) = [m for m in z.namelist() if m.endswith(f"/{name}.h5")]
        data = z.read(member)
    layers = []
    with h5py.File(io.BytesIO(data), "r") as f:
        for k in (1, 2, 3):
            g = f[f"dense_{k}"][f"dense_{k}"]
            layers.append(([[float(v) for v in row] for row in g["kernel:0"][()]], [float(v) for v in g["bias:0"][()]]))
    return layers


def _by_hand(layers, theta_h: float, theta_d: float, phi_d: float) -> list[float]:
    """exp(MLP(x)) − 1, written out with Python loops: an independent evaluation of the same weights."""
    x = [math.sin(theta_h), 0.0, math.cos(theta_h),
         math.sin(theta_d) * math.cos(phi_d), math.sin(theta_d) * math.sin(phi_d), math.cos(theta_d)]
    for k, (w, b) in enumerate(layers):
        y = [b[j] + sum(x[i] * w[i][j] for i in range(len(x))) for j in range(len(b))]
        x = [max(v, 0.0) for v in y] if k < 2 else y
    return [math.expm1(v) for v in x]


@pytest.mark.parametrize("archive,name", [(MERL_FITS, "alum-bronze"), (MERL_FITS, "white-paint"),
                                          (RGL_FITS, "spectralon_rgb")])
def test_evaluation_equals_a_hand_written_network(archive: Path, name: str) -> None:
    layers = _weights_by_hand(archive, name)
    fit = nbrdf.open_archive(archive).fit(name)
    points = [(0.0, 0.0, 0.0), (0.05, 0.3, 1.0), (0.4, 0.9, 2.5), (1.2, 0.2, 0.7), (0.01, 1.3, 3.1)]
    got = nbrdf.evaluate(fit, *np.array(points).T)
    for (th, td, pd), row in zip(points, got):
        want = _by_hand(layers, th, td, pd)
        np.testing.assert_allclose(row, want, rtol=1e-6, atol=0)


def test_table_at_cell_centres_matches_the_network_and_keeps_unmeasured_cells() -> None:
    fit = nbrdf.open_archive(MERL_FITS).fit("alum-bronze")
    out = nbrdf.fit_table(fit)
    table = out.table
    assert table.shape == merl.SHAPE
    mask = merl.measured_mask()
    # unmeasured cells (light or view below the horizon) are raw −1, as in the synthetic database
    for c in range(3):
        np.testing.assert_array_equal(table[c][~mask], -merl.SCALES[c])
        assert (table[c][mask] >= 0).all()
    assert out.measured_cells == int(mask.sum())
    th, td, pd = merl.cell_centres()
    rng = np.random.default_rng(3)
    cells = rng.choice(np.flatnonzero(mask.ravel()), size=50, replace=False)
    want = np.maximum(nbrdf.evaluate(fit, th.ravel()[cells], td.ravel()[cells], pd.ravel()[cells]), 0.0)
    np.testing.assert_allclose(table.reshape(3, -1)[:, cells].T, want, rtol=1e-12, atol=0)


def test_negative_outputs_are_clamped_and_counted() -> None:
    fit = nbrdf.open_archive(RGL_FITS).fit("spectralon_rgb")
    out = nbrdf.fit_table(fit)
    th, td, pd = merl.cell_centres()
    cells = np.flatnonzero(merl.measured_mask().ravel())
    raw = nbrdf.evaluate(fit, th.ravel()[cells], td.ravel()[cells], pd.ravel()[cells])
    assert out.clamped == int((raw < 0).sum()) > 0


def test_radiometry_of_known_materials() -> None:
    """Directional albedo at normal incidence: RGL spectralon ≈ 0.96 per channel, MERL white paint ≈ 0.35."""
    spectralon = nbrdf.fit_table(nbrdf.open_archive(RGL_FITS).fit("spectralon_rgb")).table
    np.testing.assert_allclose(merl.directional_albedo(spectralon, [0.0])[0], 0.96, atol=0.01)
    paint = nbrdf.fit_table(nbrdf.open_archive(MERL_FITS).fit("white-paint")).table
    np.testing.assert_allclose(merl.directional_albedo(paint, [0.0])[0], 0.34, atol=0.015)


def test_archives_list_every_fit_and_folders_read_like_zips(tmp_path: Path) -> None:
    merl_fits = nbrdf.open_archive(MERL_FITS)
    assert len(merl_fits.names) == 100 and "alum-bronze" in merl_fits.names
    assert len(nbrdf.open_archive(RGL_FITS).names) == 51
    assert len(nbrdf.open_archive(ARCHIVES / "nielsen_nbrdf.zip").names) == 8
    with zipfile.ZipFile(MERL_FITS) as z:
        z.extractall(tmp_path)
    folder = nbrdf.open_archive(tmp_path)
    assert folder.names == merl_fits.names
    a, b = folder.fit("gold-paint"), merl_fits.fit("gold-paint")
    assert a.sha256 == b.sha256
    for (wa, ba), (wb, bb) in zip(a.layers, b.layers):
        np.testing.assert_array_equal(wa, wb)
        np.testing.assert_array_equal(ba, bb)


def test_material_names_of_fits() -> None:
    assert nbrdf.material_name("spectralon_rgb") == "spectralon-rgb"
    assert nbrdf.material_name("alum-bronze") == "alum-bronze"


def _zip_with(tmp_path: Path, members: dict[str, bytes]) -> Path:
    path = tmp_path / "fits.zip"
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def _h5_bytes(widths: tuple[int, ...]) -> bytes:
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        names = [f"dense_{k + 1}" for k in range(len(widths) - 1)]
        f.attrs["layer_names"] = np.array([n.encode() for n in names])
        for k, n in enumerate(names):
            g = f.create_group(n)
            g.attrs["weight_names"] = np.array([f"{n}/kernel:0".encode(), f"{n}/bias:0".encode()])
            g.create_dataset(f"{n}/kernel:0", data=np.zeros((widths[k], widths[k + 1]), dtype=np.float32))
            g.create_dataset(f"{n}/bias:0", data=np.zeros(widths[k + 1], dtype=np.float32))
    return buf.getvalue()


@pytest.mark.parametrize("members,message", [
    ({"x/readme.txt": b"hello"}, "no NBRDF fits"),
    ({"x/a.h5": b"not hdf5 at all"}, "not a readable Keras weights file"),
    ({"x/a.h5": _h5_bytes((6, 10, 3))}, "not the published NBRDF network"),
    ({"x/a.h5": _h5_bytes((6, 21, 21, 3)), "x/a.json": b"{\"config\": {\"layers\": []}}"}, "not the published"),
    ({"x/a.h5": _h5_bytes((6, 21, 21, 3)), "y/a.h5": _h5_bytes((6, 21, 21, 3))}, "two fits named 'a'"),
])
def test_bad_archives_are_one_clear_error(tmp_path: Path, members: dict[str, bytes], message: str) -> None:
    path = _zip_with(tmp_path, members)
    with pytest.raises(nbrdf.NbrdfError, match=message) as err:
        archive = nbrdf.open_archive(path)
        archive.fit("a")
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_missing_archive_and_unknown_fit(tmp_path: Path) -> None:
    with pytest.raises(nbrdf.NbrdfError, match="no such archive"):
        nbrdf.open_archive(tmp_path / "nope.zip")
    (tmp_path / "junk.zip").write_bytes(b"PK\x03\x04 broken")
    with pytest.raises(nbrdf.NbrdfError, match="not a zip archive"):
        nbrdf.open_archive(tmp_path / "junk.zip")
    with pytest.raises(nbrdf.NbrdfError, match="no fit named 'nope'"):
        nbrdf.open_archive(MERL_FITS).fit("nope")


# -- writing fit-made MERL files: labels that never say "merl" ------------------------------------------


def test_fit_made_files_carry_their_database_and_ingest_under_it(tmp_path: Path) -> None:
    from brdfpipe import cli
    from brdfpipe.data import database, provenance, store

    out = tmp_path / "fits"
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(out), "bluebook", "cardboard"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["bluebook.binary", "cardboard.binary"]
    mark = provenance.read_mark(out / "bluebook.binary")
    assert mark is not None and mark.kind == "nielsen-nbrdf"
    assert mark.fields["fit"] == "bluebook" and mark.fields["archive"] == "nielsen_nbrdf.zip"
    # the table outside the mark is the fit's table
    table = merl.read_merl(out / "cardboard.binary")
    want = nbrdf.fit_table(nbrdf.open_archive(ARCHIVES / "nielsen_nbrdf.zip").fit("cardboard")).table
    keep = np.ones(merl.N_CELLS, dtype=bool)
    keep[provenance.MARK_CELLS] = False
    np.testing.assert_allclose(table.reshape(3, -1)[:, keep], want.reshape(3, -1)[:, keep], rtol=1e-15, atol=0)
    db = database.database_from_folder(out)
    assert db.kind == "nielsen-nbrdf"
    assert cli.main(["-q", "ingest", str(out), "--out", str(tmp_path / "s.zarr"), "--jobs", "1"]) == 0
    assert store.open_store(tmp_path / "s.zarr").database == "nielsen-nbrdf"


def test_fits_of_a_user_archive_are_labelled_nbrdf_and_names_use_dashes(tmp_path: Path) -> None:
    from brdfpipe import cli
    from brdfpipe.data import provenance

    with zipfile.ZipFile(RGL_FITS) as z:
        data = z.read("rgl-isotropic_nbrdf/spectralon_rgb.h5")
    with h5py.File(io.BytesIO(data), "r") as f:
        buf = io.BytesIO()
        with h5py.File(buf, "w") as g:
            for k, v in f.attrs.items():
                g.attrs[k] = v
            for name in f:
                f.copy(f[name], g, name)
            g["dense_3/dense_3/bias:0"][0] += 0.01  # another fit: not the shipped one
    archive = _zip_with(tmp_path, {"mine/my_fit.h5": buf.getvalue()})
    assert cli.main(["-q", "nbrdf", str(archive), "--out", str(tmp_path / "out")]) == 0
    mark = provenance.read_mark(tmp_path / "out" / "my-fit.binary")
    assert mark is not None and mark.kind == "nbrdf" and mark.name == "my-fit"


def test_nbrdf_refuses_a_foreign_folder_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from brdfpipe import cli

    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    merl.write_merl(out / "measured.binary", np.full(merl.SHAPE, 0.1))  # an unmarked (measured) table
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "did not write" in err and "measured.binary" in err and "notes.txt" in err and "\n" not in err
    assert sorted(p.name for p in out.iterdir()) == ["measured.binary", "notes.txt"]
    # its own earlier output is replaced
    mine = tmp_path / "mine"
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(mine), "cardboard"]) == 0
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(mine), "cardboard", "bluebook"]) == 0
    assert cli.main(["-q", "nbrdf", "nielsen-nbrdf", "--out", str(mine), "nope"]) == 1
    assert "no fit named 'nope'" in capsys.readouterr().err


def test_a_fit_made_file_copied_over_another_is_refused_at_ingest(tmp_path: Path) -> None:
    from brdfpipe.data import database, provenance

    out = tmp_path / "fits"
    nbrdf.write_fits(ARCHIVES / "nielsen_nbrdf.zip", out, ["bluebook", "cardboard"])
    (out / "cardboard.binary").write_bytes((out / "bluebook.binary").read_bytes())
    with pytest.raises(database.DatabaseError, match="material 'bluebook' .*, not 'cardboard'"):
        database.database_from_folder(out)
    with pytest.raises(provenance.ProvenanceError, match="copied or renamed"):
        provenance.check_source(out / "cardboard.binary", name="cardboard")


def test_a_folder_mixing_fits_and_measurements_is_an_error(tmp_path: Path) -> None:
    from brdfpipe.data import database

    out = tmp_path / "fits"
    nbrdf.write_fits(ARCHIVES / "nielsen_nbrdf.zip", out, ["bluebook"])
    merl.write_merl(out / "measured.binary", np.full(merl.SHAPE, 0.1))
    with pytest.raises(database.DatabaseError, match="mixes"):
        database.database_from_folder(out)
