"""Tests of :mod:`brdfpipe.acquisition.figures` (Xu 2016 figure analogues) on small fixtures.

The fixtures are written here: an errors.csv with 2 near-field FOVs (15° and
25°), fixed camera / fixed light at 25°, point sampling, n = 1…3, both
metrics, 3 held-out materials × 3 channels (+ ``all`` and ``mean`` rows) and
the deviation floor; a training_size.csv with two material orders; directions
files written by :func:`brdfpipe.acquisition.optimize.write_directions`.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import re
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from brdfpipe.acquisition import figures
from brdfpipe.core import filenames, integrity
from brdfpipe.core.plot import figure_stem, FigureInputError
from brdfpipe.data.databases import title as database_label
from brdfpipe.acquisition.figures import (
    AcquisitionFigureInputs,
    fig05_error_vs_images,
    fig08_optimal_configurations,
    fig18_per_material,
    make_acquisition_figures,
    read_errors,
)
from brdfpipe.acquisition.geometry import config_to_dict, Setup
from brdfpipe.acquisition.optimize import DirectionSet, read_directions, write_directions
from brdfpipe.core.filenames import FIGURE_STEMS
from brdfpipe.registry import figures as fig_spec
from brdfpipe.registry import tables

DB = "synthetic"
MATERIALS = ("blue-acrylic", "gold-metallic-paint", "white-fabric")
FOVS = (15.0, 25.0)
N_MAX = 3
# (setup, fov) → base error; condition-number directions are worse.
SETUPS = {("point", 0.0): 1.2, ("nearfield", 15.0): 0.5, ("nearfield", 25.0): 0.4,
          ("fixed_camera", 25.0): 0.55, ("fixed_light", 25.0): 0.6}
# Near-field configurations (iθh, iθd, iφd) per FOV: n = 1, then n = 2 (grown from n = 1).
CONFIGS = {15.0: [(16, 50, 90), (20, 70, 60)], 25.0: [(17, 48, 90), (30, 75, 100)]}


def _value(setup: str, fov: float, metric: str, n: int, mi: int, ch: int) -> float:
    base = SETUPS[(setup, fov)] * {"error": 1.0, "condition": 1.6, "condition_nielsen": 1.8}[metric]
    return base / n ** 0.7 * (1.0 + 0.15 * mi) * (1.0 + 0.05 * ch)


def write_errors(path: Path, database: str = DB, drop: str | None = None) -> Path:
    cols = [c for c in tables.ERRORS if c != drop]
    rows = []
    for (setup, fov), _ in SETUPS.items():
        for metric in ("error", "condition", "condition_nielsen"):
            if metric == "condition_nielsen" and setup != "point":  # Nielsen's κ: point samples only
                continue
            for n in range(1, N_MAX + 1):
                for kind in ("rms_log", "relrms_linear"):
                    scale = 1.0 if kind == "rms_log" else 0.3
                    per_mat = []
                    for mi, mat in enumerate(MATERIALS):
                        chans = [scale * _value(setup, fov, metric, n, mi, ch) for ch in range(3)]
                        for ch, v in enumerate(chans):
                            rows.append((database, "train", setup, fov, metric, n, mat, str(ch), kind, v))
                        v_all = float(np.sqrt(np.mean(np.square(chans))))
                        rows.append((database, "train", setup, fov, metric, n, mat, "all", kind, v_all))
                        per_mat.append(v_all)
                    rows.append((database, "train", setup, fov, metric, n, "mean", "all", kind,
                                 float(np.mean(per_mat))))
    devs = []
    for mi, mat in enumerate(MATERIALS):
        d = 0.1 + 0.02 * mi
        devs.append(d)
        for ch in ("0", "1", "2", "all"):
            rows.append((database, "train", "all", 0, "none", 0, mat, ch, "deviation", d))
    rows.append((database, "train", "all", 0, "none", 0, "mean", "all", "deviation", float(np.mean(devs))))
    fh = io.StringIO()
    w = csv.writer(fh)
    w.writerow(cols)
    for r in rows:
        rec = dict(zip(tables.ERRORS, r))
        w.writerow([f"{rec[c]:g}" if isinstance(rec[c], float) and c == "fov" else rec[c] for c in cols])
    integrity.write_csv(path, fh.getvalue())  # as the workflow writes it: with its digest line
    return path


def write_training(path: Path, database: str = DB) -> Path:
    fh = io.StringIO()
    w = csv.writer(fh)
    w.writerow(tables.TRAINING_SIZE)
    for seed in (0, 1):
        for n_train in range(5, 30, 5):
            vals = []
            for mi, mat in enumerate(MATERIALS):
                v = 0.3 + 2.0 / n_train + 0.02 * mi + 0.01 * seed * (n_train % 10 == 0)
                vals.append(v)
                w.writerow([database, n_train, seed, mat, "all", "rms_log", v])
            w.writerow([database, n_train, seed, "mean", "all", "rms_log", float(np.mean(vals))])
    integrity.write_csv(path, fh.getvalue())
    return path


def write_dirs(root: Path, database: str = DB) -> tuple[dict[float, Path], list[Path]]:
    """Directions for FOV 15 (split train only) and FOV 25 (train and all: 'all' must win).

    Returns the file each FOV's table must use and every file written (in
    writing order: FOV 25's 'train' file before its 'all' file).
    """
    used = {}
    written = []
    for fov, configs in CONFIGS.items():
        setup = Setup("nearfield", fov)
        sets = [DirectionSet(n=k, configurations=tuple(configs[:k]),
                             records=tuple(config_to_dict(setup, c) for c in configs[:k]),
                             expected_error=0.5 / k + fov / 1000.0, condition_number=1e3 * k,
                             n_observations=700 * k)
                for k in (1, 2)]
        splits = ("train",) if fov == 15.0 else ("train", "all")
        for split in splits:
            # the 'train' file of FOV 25 carries a different E(S): the table must not use it
            ss = sets if split == "all" or fov == 15.0 else [
                DirectionSet(s.n, s.configurations, s.records, 9.0, s.condition_number, s.n_observations)
                for s in sets]
            p = write_directions(root / filenames.directions(split, "nearfield", fov, "error"), ss, setup=setup,
                                 metric="error", split=split, model_path="model.zarr", seed=0,
                                 eta=40.0, beta=0.0, database=database)
            used[fov] = p  # the last one written: 'all' for 25, 'train' for 15
            written.append(p)
    return used, written


def figure_map(out: Path, keys: "tuple[str, ...] | None" = None) -> dict[str, list[Path]]:
    """The workflow's figure files (:func:`brdfpipe.core.filenames.figure_files`), under ``out`` instead of results/."""
    return {k: [out / Path(f).name for f in filenames.figure_files(stem, table=_table(k))]
            for k, stem in FIGURE_STEMS.items() if keys is None or k in keys}


def _table(key: str) -> bool:
    """Whether figure ``key`` writes a table next to it (its registry record)."""
    return fig_spec.figure(f"xu-{key}").table


def files_under(folder: Path) -> list[Path]:
    """Every file under ``folder`` (none when it does not exist)."""
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("fig-inputs")
    used, written = write_dirs(root)
    return {
        "errors": write_errors(root / "errors.csv"),
        "training": write_training(root / "training_size.csv"),
        "dirs": written,
        "dir15": used[15.0],
        "dir25": used[25.0],
    }


@pytest.fixture(scope="module")
def outputs(inputs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    out = tmp_path_factory.mktemp("figs-a")
    files = make_acquisition_figures(errors_csv=inputs["errors"], training_csv=inputs["training"],
                                     directions=inputs["dirs"], figures=figure_map(out), fovs=FOVS, n_point=N_MAX)
    return out, files


def test_wrapper_writes_every_file(outputs: tuple[Path, list[Path]]) -> None:
    out, files = outputs
    expected = {out / f"{stem}.{ext}" for k, stem in FIGURE_STEMS.items()
                for ext in ("png", "pdf", *(("csv", "md") if _table(k) else ()))}
    assert {p.name for p in expected} >= {"fig08-optimal-configurations.csv", "fig03-recon-vs-deviation.md",
                                          "fig09-configurations-fov25.csv", "fig14-fixed-configurations.csv"}
    assert expected == {p for v in figure_map(out).values() for p in v}
    assert set(files) == expected
    assert len(files) == len(expected)
    for p in files:
        assert p.is_file() and p.stat().st_size > 200, p
    # exactly the files passed in: no temporary or other file left behind
    assert files_under(out) == sorted(expected)
    for stem in FIGURE_STEMS.values():
        img = matplotlib.image.imread(out / f"{stem}.png")
        assert img.ndim == 3 and img.shape[2] in (3, 4) and min(img.shape[:2]) > 300
        assert float(img[..., :3].std()) > 0.02, f"{stem}.png looks blank"
        assert (out / f"{stem}.pdf").read_bytes().startswith(b"%PDF-")


def test_png_shape_and_titles(inputs: dict[str, Path], tmp_path: Path) -> None:
    res = fig05_error_vs_images(AcquisitionFigureInputs(inputs["errors"], fovs=FOVS), tmp_path / "f5")
    img = matplotlib.image.imread(res.files[0])
    assert img.shape[:2] == res.size_px
    assert "synthetic MERL-format database" in res.title
    assert res.panel_titles == ("near-field, FOV 15°", "near-field, FOV 25°")
    assert res.warnings == ()
    # The title is the PNG's and the PDF's Title metadata.
    assert b"synthetic MERL-format database" in res.files[0].read_bytes()
    assert b"synthetic MERL-format database" in res.files[1].read_bytes()


def test_database_named_in_every_title(outputs: tuple[Path, list[Path]]) -> None:
    out, _ = outputs
    for stem in FIGURE_STEMS.values():
        for ext in ("png", "pdf"):
            data = (out / f"{stem}.{ext}").read_bytes()
            assert b"synthetic MERL-format database" in data, f"{stem}.{ext}"
    assert "synthetic MERL-format database" in (out / "fig08-optimal-configurations.md").read_text(encoding="utf-8")


def test_database_taken_from_input(tmp_path: Path) -> None:
    errs = write_errors(tmp_path / "errors.csv", database="merl")
    res = fig18_per_material(AcquisitionFigureInputs(errs, n_point=2), tmp_path / "f18")
    assert "MERL (Matusik et al. 2003)" in res.title and res.database == "merl"
    assert database_label("synthetic") == "synthetic MERL-format database (brdfpipe)"
    assert database_label("merl") == "MERL (Matusik et al. 2003)"
    assert database_label("merl-nbrdf") == "MERL materials, NBRDF fits (Sztrajman et al. 2021)"
    assert "MERL" not in database_label("derived") and "NBRDF" in database_label("rgl-nbrdf")
    assert database_label("my-db") == "my-db database"


def test_fig08_table_matches_directions(inputs: dict[str, Path], outputs: tuple[Path, list[Path]]) -> None:
    out, _ = outputs
    rows = integrity.read_csv_rows(out / "fig08-optimal-configurations.csv")[1]
    assert tuple(rows[0].keys()) == tables.FIG08
    assert len(rows) == 2 * (1 + 2)  # 2 FOVs × (1 + 2 images)
    for fov, path in ((15.0, inputs["dir15"]), (25.0, inputs["dir25"])):
        d = read_directions(path)
        assert d.split == ("train" if fov == 15.0 else "all")
        for s in d.sets:
            got = [r for r in rows if float(r["fov_deg"]) == fov and int(r["n_images"]) == s.n]
            assert [int(r["image"]) for r in got] == list(range(1, s.n + 1))
            for r, rec in zip(got, s.records):
                assert r["split"] == d.split and r["database"] == DB
                assert float(r["expected_error"]) == pytest.approx(s.expected_error, rel=1e-9)
                for col, key in (("theta_h_deg", "theta_h_deg"), ("theta_d_deg", "theta_d_deg"),
                                 ("phi_d_deg", "phi_d_deg")):
                    assert float(r[col]) == pytest.approx(rec[key], abs=1e-5)
                for who in ("light", "camera"):
                    x, y, z = rec[who]
                    assert float(r[f"{who}_theta_deg"]) == pytest.approx(math.degrees(math.acos(z)), abs=1e-5)
                    phi = math.degrees(math.atan2(y, x)) % 360.0
                    assert float(r[f"{who}_phi_deg"]) == pytest.approx(phi, abs=1e-5)
    md = (out / "fig08-optimal-configurations.md").read_text(encoding="utf-8")
    assert md.count("\n| 15° |") == 3 and md.count("\n| 25° |") == 3


def test_deterministic(inputs: dict[str, Path], outputs: tuple[Path, list[Path]], tmp_path: Path) -> None:
    out_a, files_a = outputs
    files_b = make_acquisition_figures(errors_csv=inputs["errors"], training_csv=inputs["training"],
                                       directions=inputs["dirs"], figures=figure_map(tmp_path), fovs=FOVS,
                                       n_point=N_MAX)
    assert [p.name for p in files_a] == [p.name for p in files_b]
    for a, b in zip(files_a, files_b):
        assert a.read_bytes() == b.read_bytes(), a.name
    # The order of the direction files does not matter: 'all' wins by split, not by position.
    rev = tmp_path / "reversed"
    files_c = make_acquisition_figures(errors_csv=inputs["errors"], training_csv=None,
                                       directions=inputs["dirs"][::-1], figures=figure_map(rev, ("fig08",)),
                                       fovs=FOVS, n_point=N_MAX)
    assert sorted(files_c) == sorted(figure_map(rev)["fig08"])
    for c in files_c:
        assert c.read_bytes() == (out_a / c.name).read_bytes(), c.name


def test_absent_fov_is_skipped_with_warning(inputs: dict[str, Path], tmp_path: Path,
                                            caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="brdfpipe"):
        files = make_acquisition_figures(errors_csv=inputs["errors"], training_csv=inputs["training"],
                                         directions=inputs["dirs"], figures=figure_map(tmp_path),
                                         fovs=(15, 25, 35), n_point=7, fov_fixed=30)
    assert len(files) == sum(len(v) for v in figure_map(tmp_path).values())
    assert sorted(files) == files_under(tmp_path)
    text = caplog.text
    assert "FOV 35°" in text  # fig05/06/08
    assert "n = 7" in text  # fig18
    assert "FOV 30°" in text  # fig13
    with (tmp_path / "fig08-optimal-configurations.csv").open(encoding="utf-8") as fh:
        assert sum(1 for _ in fh) == 1 + 1 + 6  # the digest line, the header; FOV 35 has no rows


def test_no_directions_at_all(inputs: dict[str, Path], tmp_path: Path) -> None:
    res = fig08_optimal_configurations(AcquisitionFigureInputs(directions=[], fovs=(25,)), tmp_path / "f8")
    assert len(res.files) == 4 and all(p.is_file() for p in res.files)
    assert sorted(res.files) == sorted(tmp_path / f"f8.{ext}" for ext in ("png", "pdf", "csv", "md"))
    assert res.warnings and "FOV 25°" in res.warnings[0]
    # Files for other FOVs only: the same no-data figure, with a warning per FOV.
    res = fig08_optimal_configurations(AcquisitionFigureInputs(directions=[inputs["dir15"]], fovs=(25,)),
                                       tmp_path / "g8")
    assert res.warnings and "FOV 25°" in res.warnings[0]
    with (tmp_path / "g8.csv").open(encoding="utf-8") as fh:
        assert sum(1 for _ in fh) == 2  # the digest line and the header only


def test_missing_directions_file_is_an_error(inputs: dict[str, Path], tmp_path: Path) -> None:
    absent = tmp_path / filenames.directions("all", "nearfield", 15, "error")
    with pytest.raises(FigureInputError, match=r"nearfield-fov15-error\.json"):
        fig08_optimal_configurations(AcquisitionFigureInputs(directions=[inputs["dir25"], absent], fovs=(15, 25)),
                                     tmp_path / "out" / "f8")
    assert files_under(tmp_path / "out") == []


def test_missing_column_names_file(tmp_path: Path) -> None:
    bad = write_errors(tmp_path / "bad-errors.csv", drop="kind")
    with pytest.raises(FigureInputError, match=r"bad-errors\.csv.*kind"):
        read_errors(bad)
    with pytest.raises(FigureInputError, match=r"bad-errors\.csv"):
        make_acquisition_figures(errors_csv=bad, training_csv=tmp_path / "t.csv", directions=[],
                                 figures=figure_map(tmp_path / "out"), fovs=FOVS, n_point=3)
    assert files_under(tmp_path / "out") == []
    tr = tmp_path / "bad-training.csv"
    integrity.write_csv(tr, "database,n_train,material,channel,kind,value\nsynthetic,5,mean,all,rms_log,0.3\n")
    with pytest.raises(FigureInputError, match=r"bad-training\.csv.*order_seed"):
        figures.fig07_training_size(AcquisitionFigureInputs(training_csv=tr), tmp_path / "f7")
    # The wrapper checks every input first: nothing is written when one is bad.
    good = write_errors(tmp_path / "good-errors.csv")
    with pytest.raises(FigureInputError, match=r"bad-training\.csv"):
        make_acquisition_figures(errors_csv=good, training_csv=tr, directions=[], figures=figure_map(tmp_path / "out2"),
                                 fovs=FOVS, n_point=3)
    assert files_under(tmp_path / "out2") == []  # nor the folder itself: below


def test_bad_input_creates_no_output_folder(tmp_path: Path) -> None:
    bad = write_errors(tmp_path / "bad-errors.csv", drop="kind")
    out = tmp_path / "out"
    with pytest.raises(FigureInputError, match=r"bad-errors\.csv"):
        make_acquisition_figures(errors_csv=bad, training_csv=None, directions=[],
                                 figures=figure_map(out, POINT_ONLY), fovs=FOVS, n_point=3)
    assert not out.exists()


def test_empty_missing_and_malformed_inputs(inputs: dict[str, Path], tmp_path: Path) -> None:
    empty = tmp_path / "empty.csv"
    integrity.write_csv(empty, "")
    with pytest.raises(FigureInputError, match=r"empty\.csv.*empty"):
        read_errors(empty)
    header_only = tmp_path / "header.csv"
    integrity.write_csv(header_only, ",".join(tables.ERRORS) + "\n")
    with pytest.raises(FigureInputError, match=r"header\.csv.*no data rows"):
        read_errors(header_only)
    with pytest.raises(FileNotFoundError, match=r"absent\.csv"):
        read_errors(tmp_path / "absent.csv")
    badnum = tmp_path / "badnum.csv"
    integrity.write_csv(badnum, ",".join(tables.ERRORS) + "\nsynthetic,train,point,0,error,x,mean,all,rms_log,1\n")
    with pytest.raises(FigureInputError, match=r"badnum\.csv: line 3.*'n'"):
        read_errors(badnum)
    two_db = tmp_path / "twodb.csv"
    integrity.write_csv(two_db, ",".join(tables.ERRORS) + "\nA,train,point,0,error,1,mean,all,rms_log,1\n"
                      "B,train,point,0,error,2,mean,all,rms_log,1\n")
    with pytest.raises(FigureInputError, match=r"twodb\.csv.*more than one database"):
        read_errors(two_db)
    # A malformed directions file is an error naming it, not a skipped FOV.
    malformed = tmp_path / filenames.directions("all", "nearfield", 25, "error")
    malformed.parent.mkdir(parents=True)
    malformed.write_text("{not json")
    with pytest.raises(ValueError, match=r"nearfield-fov25-error\.json"):
        fig08_optimal_configurations(AcquisitionFigureInputs(directions=[inputs["dir15"], malformed], fovs=(25,)),
                                     tmp_path / "f8")
    # ... also when the FOV it would serve is not asked for
    with pytest.raises(ValueError, match=r"nearfield-fov25-error\.json"):
        fig08_optimal_configurations(AcquisitionFigureInputs(directions=[inputs["dir15"], malformed], fovs=(15,)),
                                     tmp_path / "f8")
    assert not list(tmp_path.glob("f8.*"))


POINT_ONLY = ("fig05", "fig06", "fig18", "fig19")


def test_subset_of_figures_writes_exactly_those_files(inputs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "figs"
    # Names the library never chose: it writes where it is told.
    wanted = {k: [out / f"my-{k}.png", out / f"my-{k}.pdf"] for k in POINT_ONLY}
    files = make_acquisition_figures(errors_csv=inputs["errors"], training_csv=None, directions=[],
                                     figures=wanted, fovs=FOVS, n_point=N_MAX)
    expected = sorted(p for v in wanted.values() for p in v)
    assert sorted(files) == expected and len(files) == len(expected)
    assert files_under(out) == expected  # nothing else in the folder: no other figure, no temporary
    for k in POINT_ONLY:
        png, pdf = wanted[k]
        assert float(matplotlib.image.imread(png)[..., :3].std()) > 0.02, f"{png.name} looks blank"
        assert pdf.read_bytes().startswith(b"%PDF-")
    # Same bytes as the same figures drawn with the full set.
    full = tmp_path / "full"
    make_acquisition_figures(errors_csv=inputs["errors"], training_csv=inputs["training"], directions=inputs["dirs"],
                             figures=figure_map(full), fovs=FOVS, n_point=N_MAX)
    for k in POINT_ONLY:
        for ours, theirs in zip(wanted[k], figure_map(full)[k]):
            assert ours.read_bytes() == theirs.read_bytes(), ours.name
    # fig07 needs the training-size table.
    with pytest.raises(ValueError, match="fig07"):
        make_acquisition_figures(errors_csv=inputs["errors"], training_csv=None, directions=[],
                                 figures=figure_map(tmp_path / "f7", ("fig07",)), fovs=FOVS, n_point=N_MAX)
    assert files_under(tmp_path / "f7") == []
    # No figure asked for: nothing drawn.
    assert make_acquisition_figures(errors_csv=inputs["errors"], training_csv=None, directions=[], figures={},
                                    fovs=FOVS, n_point=N_MAX) == []


@pytest.mark.parametrize("bad", ["unknown-key", "suffix-order", "fig08-without-table", "table-on-plain-figure",
                                 "two-stems", "missing-pdf"])
def test_bad_figures_mapping_is_refused_before_writing(inputs: dict[str, Path], tmp_path: Path, bad: str) -> None:
    out = tmp_path / "figs"
    mapping: dict[str, list[Path]] = figure_map(out)
    if bad == "unknown-key":
        mapping["fig99"] = [out / "fig99.png", out / "fig99.pdf"]
    elif bad == "suffix-order":
        mapping["fig06"] = mapping["fig06"][::-1]
    elif bad == "fig08-without-table":
        mapping["fig08"] = mapping["fig08"][:2]
    elif bad == "table-on-plain-figure":
        mapping["fig19"] = [*mapping["fig19"], out / "fig19-error-vs-n.csv", out / "fig19-error-vs-n.md"]
    elif bad == "two-stems":
        mapping["fig13"] = [out / "fig13-a.png", out / "fig13-b.pdf"]
    else:
        mapping["fig18"] = mapping["fig18"][:1]
    with pytest.raises(ValueError, match="fig99" if bad == "unknown-key" else "figure outputs"):
        make_acquisition_figures(errors_csv=inputs["errors"], training_csv=inputs["training"],
                                 directions=inputs["dirs"], figures=mapping, fovs=FOVS, n_point=N_MAX)
    assert files_under(out) == []
    assert files_under(tmp_path) == []


def test_figure_stem(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    assert figure_stem([a / "x.png", a / "x.pdf"]) == a / "x"
    assert figure_stem([str(b / f"y.{e}") for e in ("png", "pdf", "csv", "md")], table=True) == b / "y"
    for files, table in ((["x.pdf", "x.png"], False), (["x.png", "x.pdf"], True), (["x.png"], False),
                         (["x.png", "y.pdf"], False), (["x.png", "x.pdf", "x.md", "x.csv"], True)):
        with pytest.raises(ValueError):
            figure_stem([tmp_path / "c" / f for f in files], table=table)
    assert files_under(tmp_path) == [] and not (tmp_path / "c").exists()


def test_the_previous_work_curve_is_nielsens_kappa_and_eq6_has_its_own(inputs: dict[str, Path], tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Xu Figs. 6, 18, 19: "previous work" is Nielsen 2015's κ as released (first n components), drawn red;
    eq. 6 over all k components is a curve of its own, labelled so; the two are never confused."""
    legends: list[str] = []
    colours: dict[str, str] = {}
    save = figures.finish

    def record(fig, *args, **kwargs):  # the legend texts of every figure, then the real save
        boxes = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends)
        legends.extend(t.get_text() for box in boxes for t in box.get_texts())
        colours.update({line.get_label(): line.get_color() for ax in fig.axes for line in ax.get_lines()})
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(figures, "finish", record)
    figures.fig06_fov_vs_point(AcquisitionFigureInputs(inputs["errors"], fovs=FOVS), tmp_path / "f6")
    fig18_per_material(AcquisitionFigureInputs(inputs["errors"], n_point=N_MAX), tmp_path / "f18")
    kappa = [t for t in legends if "κ" in t]
    nielsen = "min κ, first n components (Nielsen 2015 as released)"
    eq6 = "min κ, all k components (Xu eq. 6)"
    assert {f"previous work: point samples, {nielsen}", f"point samples, {eq6}", f"previous work: directions: {nielsen}",
            f"directions: {eq6}"} <= set(kappa), legends
    assert not [t for t in legends if "Nielsen" in t and "previous work" not in t], legends
    assert not [t for t in legends if "eq. 6" in t and ("Nielsen" in t or "previous" in t)], legends
    assert colours[f"previous work: point samples, {nielsen}"] == "#d62728"  # red, as the paper's Fig. 6


def test_an_edited_errors_table_is_refused(inputs: dict[str, Path], tmp_path: Path) -> None:
    """errors.csv edited by hand (one value) no longer drives the figures: its digest line fails, naming it."""
    edited = tmp_path / "results" / "evaluation" / "errors.csv"
    edited.parent.mkdir(parents=True)
    lines = inputs["errors"].read_text(encoding="utf-8").splitlines(keepends=True)
    row = lines[3].rstrip("\n").split(",")
    row[-1] = str(float(row[-1]) * 2)
    lines[3] = ",".join(row) + "\n"
    edited.write_text("".join(lines), encoding="utf-8")
    with pytest.raises(FigureInputError, match=re.escape(f"{edited}: its content does not match its recorded "
                                                         "digest (damaged or edited); rerun its rule: snakemake "
                                                         "--forcerun evaluate_directions")):
        read_errors(edited)
    with pytest.raises(FigureInputError, match=re.escape(str(edited))):
        make_acquisition_figures(errors_csv=edited, training_csv=None, directions=[],
                                 figures=figure_map(tmp_path / "out", POINT_ONLY), fovs=FOVS, n_point=3)
    assert not (tmp_path / "out").exists()
