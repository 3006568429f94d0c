"""Every entry point is a command with the project's error contract (issue 31, item 2).

The entry points are collected from the code and the docs, not listed by hand: every subcommand of
the ``brdfpipe`` parser (:func:`brdfpipe.cli.build_parser`) and every ``python -m brdfpipe…`` module
that README.md or docs/**/*.md mention (each has ``build_parser`` and ``main``; its subcommands, if
it has any, are its commands).  Each command runs on a table of bad inputs: a missing file, a folder
where a file belongs, an empty file, a text or truncated file in place of its format, an output that
is one of the inputs (the same path, a hard link, a symlink), an output folder that cannot be written
(a path under a regular file, which fails for root too), out-of-range numbers.  Each must exit
non-zero with exactly one line on stderr, ``PROG: error: ...``, naming the file or option, with no
traceback and no "internal error" (an uncaught exception is a defect), and leave every input as it
was (and no stray file behind).  Progress records of the console log (``... INFO ...``, which
``brdfpipe`` prints without ``-q``) are not part of the error and are not counted.

The commands run in-process, ``main(argv)`` with stderr captured: ``python -m X`` is
``sys.exit(main())``, so that is what a user sees (:func:`test_python_m_prints_what_main_prints`
checks it once per module in a subprocess).  The archive's own content (zip members, sidecars) of
``brdfpipe nbrdf`` is tested with that command's reader (tests/test_nbrdf.py); here only its generic
cases.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import re
import shutil
import subprocess
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import case_log
from test_cli_hostile import latent_inputs  # noqa: F401 (a fixture: five materials, their store, a GPLVM)

from brdfpipe import cli
from brdfpipe.data import databases, merl, provenance

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"


# --------------------------------------------------------------------------
# The entry points, from the code and the docs
# --------------------------------------------------------------------------


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The subcommands of ``parser`` by name ({} when it has none)."""
    found: dict[str, argparse.ArgumentParser] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            found.update(action.choices)
    return found


def documented_modules() -> list[str]:
    """The ``python -m brdfpipe…`` modules README.md and docs/**/*.md mention."""
    texts = [(ROOT / "README.md").read_text(encoding="utf-8")]
    texts += [p.read_text(encoding="utf-8") for p in sorted((ROOT / "docs").rglob("*.md"))]
    return sorted({m for text in texts for m in re.findall(r"python -m (brdfpipe(?:\.\w+)*)", text)})


def entry_points() -> dict[str, tuple[Callable[[list[str]], int], list[str], argparse.ArgumentParser]]:
    """Every command: its name (the prefix of its errors) → (main, the arguments that select it, its parser)."""
    found = {f"brdfpipe {verb}": (cli.main, [verb], p) for verb, p in subcommands(cli.build_parser()).items()}
    for name in documented_modules():
        module = importlib.import_module(name)
        parser = module.build_parser()
        subs = subcommands(parser)
        if subs:
            found.update({f"python -m {name} {sub}": (module.main, [sub], p) for sub, p in subs.items()})
        else:
            found[f"python -m {name}"] = (module.main, [], parser)
    return found


def output_options(parser: argparse.ArgumentParser) -> list[str]:
    return [o for a in parser._actions for o in a.option_strings if o in ("--out", "--out-dir")]


# --------------------------------------------------------------------------
# The inputs: valid ones (to reach the later checks) and bad ones
# --------------------------------------------------------------------------

SMALL = 1 << 20  # files up to this size are compared byte for byte; larger ones by inode, size and mtime


@pytest.fixture(scope="module")
def inputs(latent_inputs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:  # noqa: F811
    """Every file the cases read, in one folder tree (``root``) whose state is compared around each case."""
    from brdfpipe.acquisition import svd
    from brdfpipe.data import logmap, store
    from brdfpipe.report import claims

    lat = latent_inputs["dir"]
    d = tmp_path_factory.mktemp("entry")
    names = list(store.open_store(latent_inputs["store"]).materials)
    logmap.write_logmap(latent_inputs["store"], d / "logmap.zarr", split="train", materials_train=names[:4])
    svd.fit(d / "logmap.zarr", d / "pca.zarr")
    i = SimpleNamespace(root=d, lat=lat, db=lat / "db", model=latent_inputs["model"], store=latent_inputs["store"],
                        pca=d / "pca.zarr", material=latent_inputs["material"], a=latent_inputs["a"],
                        b=latent_inputs["b"])
    i.missing = d / "missing.file"
    i.empty = d / "empty.file"
    i.empty.write_bytes(b"")
    i.text = d / "text.file"
    i.text.write_text("this is a note, not the file you are looking for\n")
    i.folder = d / "folder"
    i.folder.mkdir()
    i.file = d / "regular-file.txt"  # outputs under it cannot be written, even by root
    i.file.write_text("mine\n")
    i.truncated = d / "truncated.binary"
    with open(i.material, "rb") as fh:
        i.truncated.write_bytes(fh.read(5000))
    i.model_truncated = d / "model-truncated.npz"
    i.model_truncated.write_bytes(i.model.read_bytes()[:300])
    i.half_json = d / "half.json"
    i.half_json.write_text('{"database": "synthetic", "note": ')
    i.obs = d / "obs.csv"
    i.obs.write_text("theta_h,theta_d,phi_d,r,g,b\n10,20,30,0.1,0.1,0.1\n")
    i.claims = d / "run" / "claims.csv"
    i.claims.parent.mkdir()
    claim = claims.Claim(key="one_shot", paper="Xu 2016", where="Fig. 5", sentence="3°", claim="one image",
                         measured="7.2°", value=7.2, verdict=claims.DIFFERS, cause="a real difference: 7.2°",
                         database="synthetic", source="errors.csv")
    claims.write_claims([claim], csv_path=i.claims, json_path=d / "run" / "claims.json", rst_path=d / "run" / "c.rst")
    i.claims_json = d / "run" / "claims.json"
    i.claims_truncated = d / "claims-truncated.csv"
    i.claims_truncated.write_bytes(i.claims.read_bytes()[:40])
    grey = np.full(merl.SHAPE, 0.1)  # an unmarked table: a measurement
    merl.write_merl(d / "grey.binary", grey)
    for folder, content in (("db-truncated", i.truncated.read_bytes()), ("db-text", i.text.read_bytes())):
        (d / folder).mkdir()  # a valid table of the same kind beside the bad one
        os.link(d / "grey.binary", d / folder / "a.binary")
        (d / folder / "m.binary").write_bytes(content)
    i.db_truncated, i.db_text = d / "db-truncated", d / "db-text"
    i.db_mixed = d / "db-mixed"  # a table evaluated from a fit beside an unmarked one: the issue's `--label MERL`
    i.db_mixed.mkdir()
    os.link(d / "grey.binary", i.db_mixed / "measured.binary")
    merl.write_merl(i.db_mixed / "fitted.binary", grey, mark=provenance.fit_mark(
        database="merl-nbrdf", name="fitted", fit="fitted", archive="merl_nbrdf.zip", fit_sha256="0" * 64, clamped=0))
    i.archive = d / "merl_nbrdf.zip"
    shutil.copyfile(databases.shipped_archive("merl-nbrdf"), i.archive)
    i.dirs_text = d / "directions.json"
    i.dirs_text.write_text("not json\n")
    return i


def state(*roots: Path) -> dict[str, Any]:
    """Every file under ``roots``: its bytes (small files) or inode, size and mtime (large ones)."""
    found: dict[str, Any] = {}
    for root in roots:
        for p in sorted(root.rglob("*")):
            if p.is_symlink():
                found[str(p)] = ("link", os.readlink(p))
            elif p.is_file():
                st = p.stat()
                found[str(p)] = p.read_bytes() if st.st_size <= SMALL else (st.st_ino, st.st_size, st.st_mtime_ns)
    return found


# --------------------------------------------------------------------------
# The table of cases
# --------------------------------------------------------------------------

Make = Callable[[Any, Path], tuple[list[str], str]]


@dataclass(frozen=True)
class Case:
    """A command, what is wrong, and its arguments and the text its error line must hold (the file or option)."""

    command: str
    bad: str
    make: Make
    #: a defect outside this change, reported (the case fails until it is fixed; then remove this)
    known: str = ""

    @property
    def id(self) -> str:
        return f"{self.command.split()[-1]}: {self.bad}"


def hard_link(target: Path, tmp: Path) -> str:
    link = tmp / f"link-{target.name}"
    os.link(target, link)
    return str(link)


def sym_link(target: Path, tmp: Path) -> str:
    link = tmp / f"symlink-{target.name}"
    link.symlink_to(target)
    return str(link)


def under(i: Any, name: str) -> str:
    return str(i.file / name)


B = "brdfpipe"
REALISM = "python -m brdfpipe.acquisition.realism"
SIDE = "python -m brdfpipe.report.sidebyside"


def _cases() -> list[Case]:
    c: list[Case] = []

    def add(command: str, bad: str, make: Make, known: str = "") -> None:
        c.append(Case(command, bad, make, known))

    # brdfpipe synth: no input file
    synth = ["--count", "1", "--seed", "0"]
    add(f"{B} synth", "--out is a regular file", lambda i, t: ([*synth, "--out", str(i.file)], str(i.file)))
    add(f"{B} synth", "output under a file", lambda i, t: ([*synth, "--out", under(i, "db")], "--out"))
    add(f"{B} synth", "--count 0", lambda i, t: (["--count", "0", "--seed", "0", "--out", str(t / "db")], "--count"))
    add(f"{B} synth", "--count 1e12", lambda i, t: (["--count", "1e12", "--seed", "0", "--out", str(t / "db")],
                                                   "--count"))
    add(f"{B} synth", "--noise nan", lambda i, t: ([*synth, "--noise", "nan", "--out", str(t / "db")], "--noise"))
    add(f"{B} synth", "--jobs 0", lambda i, t: ([*synth, "--jobs", "0", "--out", str(t / "db")], "--jobs"))

    # brdfpipe nbrdf: generic cases (the archive's content is tests/test_nbrdf.py's)
    add(f"{B} nbrdf", "missing archive", lambda i, t: ([str(i.missing), "--out", str(t / "o")], str(i.missing)))
    add(f"{B} nbrdf", "--out is a regular file", lambda i, t: ([str(i.archive), "--out", str(i.file)], str(i.file)))
    add(f"{B} nbrdf", "output under a file", lambda i, t: ([str(i.archive), "--out", under(i, "o")], "--out"))
    add(f"{B} nbrdf", "--out is the archive", lambda i, t: ([str(i.archive), "--out", str(i.archive)], "--out"))
    add(f"{B} nbrdf", "--out is a symlink to the archive",
        lambda i, t: ([str(i.archive), "--out", sym_link(i.archive, t)], "--out"))

    # brdfpipe ingest
    ing = ["--jobs", "1"]
    add(f"{B} ingest", "missing folder", lambda i, t: ([str(i.missing), "--out", str(t / "s.zarr")], str(i.missing)))
    add(f"{B} ingest", "a file as the folder", lambda i, t: ([str(i.text), "--out", str(t / "s.zarr")], str(i.text)))
    add(f"{B} ingest", "empty folder", lambda i, t: ([str(i.folder), "--out", str(t / "s.zarr")], str(i.folder)))
    add(f"{B} ingest", "truncated table", lambda i, t: ([str(i.db_truncated), *ing, "--out", str(t / "s.zarr")],
                                                      str(i.db_truncated / "m.binary")))
    add(f"{B} ingest", "text table", lambda i, t: ([str(i.db_text), *ing, "--out", str(t / "s.zarr")],
                                                 str(i.db_text / "m.binary")))
    add(f"{B} ingest", "mixed folder", lambda i, t: ([str(i.db_mixed), *ing, "--out", str(t / "s.zarr")],
                                                   f"{i.db_mixed}: mixes"))
    add(f"{B} ingest", "--out is the folder", lambda i, t: ([str(i.db), "--out", str(i.db)], "--out"))
    add(f"{B} ingest", "--out is a table", lambda i, t: ([str(i.db), "--out", str(i.material)], "--out"))
    add(f"{B} ingest", "--out is a hard link to a table",
        lambda i, t: ([str(i.db), "--out", hard_link(i.material, t)], "--out"))
    add(f"{B} ingest", "--out is a symlink to the folder",
        lambda i, t: ([str(i.db), "--out", sym_link(i.db, t)], "--out"))
    add(f"{B} ingest", "output under a file", lambda i, t: ([str(i.db), *ing, "--out", under(i, "s.zarr")], "--out"))
    add(f"{B} ingest", "--jobs 0", lambda i, t: ([str(i.db), "--jobs", "0", "--out", str(t / "s.zarr")], "--jobs"))

    # brdfpipe info
    for bad, attr in (("missing store", "missing"), ("a file as the store", "text"), ("empty file", "empty"),
                      ("empty folder", "folder")):
        add(f"{B} info", bad, lambda i, t, a=attr: ([str(getattr(i, a))], str(getattr(i, a))))

    # brdfpipe interpolate, nearest, extrapolate, sample: a GPLVM and its store
    def model_cases(verb: str, rest: Callable[[Any, Path], list[str]]) -> None:
        for bad, attr in (("missing model", "missing"), ("a folder as the model", "folder"),
                          ("empty model", "empty"), ("text model", "text"), ("truncated model", "model_truncated")):
            add(f"{B} {verb}", bad, lambda i, t, a=attr: (["--model", str(getattr(i, a)), *rest(i, t)],
                                                          str(getattr(i, a))))

    def interp(i: Any, t: Path) -> list[str]:
        return ["--store", str(i.store), "--between", i.a, i.b, "--out", str(t / "x.binary")]

    model_cases("interpolate", interp)
    gp = lambda i: ["--model", str(i.model), "--store", str(i.store)]  # noqa: E731
    add(f"{B} interpolate", "missing store", lambda i, t: (["--model", str(i.model), "--store", str(i.missing),
                                                            "--at", "0,0", "--out", str(t / "x.binary")],
                                                           str(i.missing)))
    for bad, out in (("--out is the model", lambda i, t: str(i.model)),
                     ("--out is a hard link to the model", lambda i, t: hard_link(i.model, t)),
                     ("--out is a symlink to the model", lambda i, t: sym_link(i.model, t)),
                     ("--out is the store", lambda i, t: str(i.store))):
        add(f"{B} interpolate", bad, lambda i, t, o=out: ([*gp(i), "--at", "0,0", "--out", o(i, t)], "--out"))
    add(f"{B} interpolate", "output under a file", lambda i, t: ([*gp(i), "--at", "0,0", "--out", under(i, "x.binary")],
                                                               "--out"))
    add(f"{B} interpolate", "--t nan", lambda i, t: ([*gp(i), "--between", i.a, i.b, "--t", "nan", "--out",
                                                      str(t / "x.binary")], "--t"))
    add(f"{B} interpolate", "--at of another dimension", lambda i, t: ([*gp(i), "--at", "0,0,0", "--out",
                                                                        str(t / "x.binary")], "--at"))

    model_cases("nearest", lambda i, t: ["--at", "0,0"])
    add(f"{B} nearest", "-k 0", lambda i, t: (["--model", str(i.model), "--at", "0,0", "-k", "0"], "-k"))
    add(f"{B} nearest", "--at nan", lambda i, t: (["--model", str(i.model), "--at", "nan,0"], "--at"))
    add(f"{B} nearest", "unknown --material", lambda i, t: (["--model", str(i.model), "--material", "nope"],
                                                           "--material"))

    model_cases("extrapolate", lambda i, t: ["--store", str(i.store), "--from", i.a, "--through", i.b])
    ext = lambda i: [*gp(i), "--from", i.a, "--through", i.b]  # noqa: E731
    add(f"{B} extrapolate", "--out is the model", lambda i, t: ([*ext(i), "--out", str(i.model)], "--out"))
    add(f"{B} extrapolate", "--out is a hard link to the model",
        lambda i, t: ([*ext(i), "--out", hard_link(i.model, t)], "--out"))
    add(f"{B} extrapolate", "output under a file", lambda i, t: ([*ext(i), "--out", under(i, "e.binary")], "--out"))
    add(f"{B} extrapolate", "--step 0", lambda i, t: ([*ext(i), "--step", "0"], "--step"))
    add(f"{B} extrapolate", "--max-s -1", lambda i, t: ([*ext(i), "--max-s", "-1"], "--max-s"))
    add(f"{B} extrapolate", "unknown --from", lambda i, t: ([*gp(i), "--from", "nope", "--through", i.b], "--from"))

    smp = ["--seed", "0", "--count", "1"]
    model_cases("sample", lambda i, t: ["--store", str(i.store), *smp, "--out-dir", str(t / "s")])
    add(f"{B} sample", "--out-dir is the store", lambda i, t: ([*gp(i), *smp, "--out-dir", str(i.store)], "--out-dir"))
    add(f"{B} sample", "--out-dir is a regular file", lambda i, t: ([*gp(i), *smp, "--out-dir", str(i.file)],
                                                                   "--out-dir"))
    add(f"{B} sample", "output under a file", lambda i, t: ([*gp(i), *smp, "--out-dir", under(i, "s")], "--out-dir"))
    add(f"{B} sample", "--count 0", lambda i, t: ([*gp(i), "--seed", "0", "--count", "0", "--out-dir",
                                                  str(t / "s")], "--count"))
    add(f"{B} sample", "--seed -1", lambda i, t: ([*gp(i), "--seed", "-1", "--count", "1", "--out-dir",
                                                  str(t / "s")], "--seed"))

    # brdfpipe reconstruct
    for bad, attr in (("missing observations", "missing"), ("a folder as the observations", "folder"),
                      ("empty observations", "empty"), ("text observations", "text")):
        add(f"{B} reconstruct", bad, lambda i, t, a=attr: ([str(getattr(i, a)), "--model", str(i.pca), "--out",
                                                            str(t / "r.binary")], str(getattr(i, a))))
    for bad, attr in (("missing model", "missing"), ("text model", "text"), ("empty folder as the model", "folder")):
        add(f"{B} reconstruct", bad, lambda i, t, a=attr: ([str(i.obs), "--model", str(getattr(i, a)), "--out",
                                                            str(t / "r.binary")], str(getattr(i, a))))
    for bad, out in (("--out is the observations", lambda i, t: str(i.obs)),
                     ("--out is a hard link to the observations", lambda i, t: hard_link(i.obs, t)),
                     ("--out is a symlink to the observations", lambda i, t: sym_link(i.obs, t)),
                     ("--out is the model", lambda i, t: str(i.pca)),
                     ("output under a file", lambda i, t: under(i, "r.binary"))):
        add(f"{B} reconstruct", bad, lambda i, t, o=out: ([str(i.obs), "--model", str(i.pca), "--out", o(i, t)],
                                                          "--out"))
    add(f"{B} reconstruct", "--eta 0", lambda i, t: ([str(i.obs), "--model", str(i.pca), "--eta", "0", "--out",
                                                     str(t / "r.binary")], "--eta"))

    # brdfpipe render
    tiny = ["--resolution", "8", "6", "--spp", "1"]
    for bad, attr in (("missing material", "missing"), ("a folder as the material", "folder"),
                      ("empty material", "empty"), ("text material", "text"), ("truncated material", "truncated")):
        add(f"{B} render", bad, lambda i, t, a=attr: ([str(getattr(i, a)), *tiny, "--out", str(t / "r.exr")],
                                                     str(getattr(i, a))))
    for bad, out in (("--out is the material", lambda i, t: str(i.material)),
                     ("--out is a hard link to the material", lambda i, t: hard_link(i.material, t)),
                     ("--out is a symlink to the material", lambda i, t: sym_link(i.material, t)),
                     ("output under a file", lambda i, t: under(i, "r.exr"))):
        add(f"{B} render", bad, lambda i, t, o=out: ([str(i.material), *tiny, "--out", o(i, t)], "--out"))
    add(f"{B} render", "--spp 0", lambda i, t: ([str(i.material), "--spp", "0", "--out", str(t / "r.exr")], "--spp"))
    add(f"{B} render", "--resolution 0 0", lambda i, t: ([str(i.material), "--resolution", "0", "0", "--out",
                                                          str(t / "r.exr")], "--resolution"))
    add(f"{B} render", "missing --envmap", lambda i, t: ([str(i.material), *tiny, "--envmap", str(i.missing), "--out",
                                                          str(t / "r.exr")], str(i.missing)))
    add(f"{B} render", "text --envmap", lambda i, t: ([str(i.material), *tiny, "--envmap", str(i.text), "--out",
                                                       str(t / "r.exr")], str(i.text)))

    # brdfpipe capture
    cap = ["--n", "1", "--spp", "1"]
    for bad, attr in (("missing material", "missing"), ("a folder as the material", "folder"),
                      ("empty material", "empty"), ("text material", "text"), ("truncated material", "truncated")):
        add(f"{B} capture", bad, lambda i, t, a=attr: ([str(getattr(i, a)), str(i.dirs_text), *cap, "--out",
                                                       str(t / "c")], str(getattr(i, a))))
    for bad, attr in (("missing directions", "missing"), ("a folder as the directions", "folder"),
                      ("empty directions", "empty"), ("text directions", "dirs_text")):
        add(f"{B} capture", bad, lambda i, t, a=attr: ([str(i.material), str(getattr(i, a)), *cap, "--out",
                                                       str(t / "c")], str(getattr(i, a))))
    for bad, out in (("--out is the material", lambda i, t: str(i.material)),
                     ("--out is the material's folder", lambda i, t: str(i.db)),
                     ("--out is a symlink to the material's folder", lambda i, t: sym_link(i.db, t)),
                     ("output under a file", lambda i, t: under(i, "c"))):
        add(f"{B} capture", bad, lambda i, t, o=out: ([str(i.material), str(i.dirs_text), *cap, "--out", o(i, t)],
                                                      "--out"))
    for bad, args, option in (("--brackets 1 1e300", ["--brackets", "1", "1e300"], "--brackets"),
                              ("--brackets 2 8", ["--brackets", "2", "8"], "--brackets"),
                              ("17 brackets", ["--brackets", *["1"] * 17], "--brackets"),
                              ("--full-well 1e300", ["--full-well", "1e300"], "--full-well"),
                              ("--n 0", ["--n", "0"], "--n"), ("--spp 0", ["--spp", "0"], "--spp")):
        add(f"{B} capture", bad, lambda i, t, a=args, o=option: ([str(i.material), str(i.dirs_text), *cap, *a,
                                                                  "--out", str(t / "c")], o))

    # python -m brdfpipe.acquisition.realism measure / table
    m = f"{REALISM} measure"
    for bad, attr in (("missing folder", "missing"), ("a file as the folder", "text"), ("empty folder", "folder")):
        add(m, bad, lambda i, t, a=attr: ([str(getattr(i, a)), "--out", str(t / "s.json")], str(getattr(i, a))))
    for bad, attr in (("truncated table", "db_truncated"), ("text table", "db_text")):
        add(m, bad, lambda i, t, a=attr: ([str(getattr(i, a)), "--out", str(t / "s.json")],
                                          str(getattr(i, a) / "m.binary")))
    add(m, "mixed folder", lambda i, t: ([str(i.db_mixed), "--out", str(t / "s.json")], f"{i.db_mixed}: mixes"))
    for bad, out in (("--out is a table", lambda i, t: str(i.material)),
                     ("--out is a hard link to a table", lambda i, t: hard_link(i.material, t)),
                     ("--out is a symlink to a table", lambda i, t: sym_link(i.material, t)),
                     ("--out is the folder", lambda i, t: str(i.db)),
                     ("--out is a folder", lambda i, t: str(i.folder)),
                     ("output under a file", lambda i, t: under(i, "s.json"))):
        add(m, bad, lambda i, t, o=out: ([str(i.db), "--out", o(i, t)], "--out"))
    for bad, args, option in (("--folds 1", ["--folds", "1"], "--folds"), ("--folds x", ["--folds", "x"], "--folds"),
                              ("--folds 99", ["--folds", "99"], "--folds"), ("--seed -1", ["--seed", "-1"], "--seed"),
                              ("--note naming another database", ["--note", "MERL"], "--note"),
                              ("--weighting unknown", ["--weighting", "nope"], "--weighting")):
        add(m, bad, lambda i, t, a=args, o=option: ([str(i.db), *a, "--out", str(t / "s.json")], o))
    for bad, attr in (("missing file", "missing"), ("a folder", "folder"), ("empty file", "empty"),
                      ("text file", "text"), ("incomplete JSON", "half_json"), ("a MERL table", "truncated"),
                      ("a CSV file", "claims"), ("JSON of another kind", "claims_json")):
        add(f"{REALISM} table", bad, lambda i, t, a=attr: ([str(getattr(i, a))], str(getattr(i, a))))

    # python -m brdfpipe.report.sidebyside
    for bad, attr in (("missing file", "missing"), ("a folder", "folder"), ("empty file", "empty"),
                      ("text file", "text"), ("truncated claims", "claims_truncated"), ("a MERL table", "truncated")):
        add(SIDE, bad, lambda i, t, a=attr: ([str(getattr(i, a)), "--out", str(t / "p.md")], str(getattr(i, a))))
    for bad, out in (("--out is the claims", lambda i, t: str(i.claims)),
                     ("--out is a hard link to the claims", lambda i, t: hard_link(i.claims, t)),
                     ("--out is a symlink to the claims", lambda i, t: sym_link(i.claims, t)),
                     ("--out is a folder", lambda i, t: str(i.folder)),
                     ("output under a file", lambda i, t: under(i, "p.md"))):
        add(SIDE, bad, lambda i, t, o=out: ([str(i.claims), "--out", o(i, t)], "--out"))
    return c


CASES = _cases()


# --------------------------------------------------------------------------
# The tests
# --------------------------------------------------------------------------


def test_every_entry_point_has_cases() -> None:
    """A new verb or a newly documented module without a table of bad inputs fails here."""
    commands = entry_points()
    assert {"python -m brdfpipe.acquisition.realism measure", "python -m brdfpipe.report.sidebyside"} <= set(commands)
    covered = {c.command for c in CASES}
    assert set(commands) - covered == set(), "entry points without cases"
    assert covered - set(commands) == set(), "cases of commands that no longer exist"
    for name, (_, _, parser) in commands.items():
        if output_options(parser):
            assert any(c.command == name and c.bad == "output under a file" for c in CASES), name


def run_in_process(main: Callable[[list[str]], int], argv: list[str],
                   capsys: pytest.CaptureFixture[str]) -> tuple[Any, str]:
    """``main(argv)``'s exit status and stderr; an exception escaping it is reported as its traceback."""
    try:
        status: Any = main(argv)
    except SystemExit as exit_:
        status = exit_.code
    except BaseException:  # noqa: BLE001 (an uncaught exception is what this test looks for)
        return "uncaught", capsys.readouterr().err + traceback.format_exc()
    return status, capsys.readouterr().err


_ENTRY_POINTS: dict[str, Any] = {}


def entry_points_cached() -> dict[str, Any]:
    if not _ENTRY_POINTS:
        _ENTRY_POINTS.update(entry_points())
    return _ENTRY_POINTS


#: A progress record of the console log (brdfpipe.core.logutil's format, INFO): not part of the error.
PROGRESS = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} INFO ")


def error_lines(err: str) -> list[str]:
    """What stderr says beyond progress records."""
    return [line for line in err.strip().splitlines() if not PROGRESS.match(line)]


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=c.known)) if c.known
                                  else c for c in CASES], ids=lambda c: c.id)
def test_bad_input_is_one_line_naming_it(case: Case, inputs: SimpleNamespace, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    main, prefix_args, _ = entry_points_cached()[case.command]
    argv, named = case.make(inputs, tmp_path)
    before = state(inputs.root, inputs.lat, tmp_path)
    status, err = run_in_process(main, [*prefix_args, *argv], capsys)
    lines = error_lines(err)
    assert status not in (0, None) and len(lines) == 1, (status, err)
    line = lines[0]
    case_log.record(case.id, line)
    assert line.startswith(f"{case.command}: error: "), line
    assert named in line, (named, line)
    assert "Traceback" not in line and "internal error" not in line, line
    assert state(inputs.root, inputs.lat, tmp_path) == before


@pytest.mark.parametrize("module", ["brdfpipe.cli", *documented_modules()])
def test_python_m_prints_what_main_prints(module: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m MODULE`` on a missing input: the same one line and status as ``main`` in-process."""
    missing = str(tmp_path / "missing.file")
    argv = {"brdfpipe.cli": ["info", missing],
            "brdfpipe.acquisition.realism": ["table", missing],
            "brdfpipe.report.sidebyside": [missing, "--out", str(tmp_path / "p.md")]}[module]
    status, err = run_in_process(importlib.import_module(module).main, argv, capsys)
    r = subprocess.run([sys.executable, "-m", module, *argv], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(SRC)})
    assert (r.returncode, r.stderr) == (status, err) and status == 1 and missing in err, (r.returncode, r.stderr)


@pytest.mark.parametrize("module, call, argv", [
    ("brdfpipe.acquisition.realism", "read_database", lambda i, t: ["measure", str(i.db), "--out", str(t / "s.json")]),
    ("brdfpipe.report.sidebyside", "side_by_side_markdown", lambda i, t: [str(i.claims), "--out", str(t / "p.md")]),
])
def test_an_interrupt_exits_130_with_one_line_and_writes_nothing(
    module: str, call: str, argv: Callable[[Any, Path], list[str]], inputs: SimpleNamespace, tmp_path: Path,
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
) -> None:
    mod = importlib.import_module(module)

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        raise KeyboardInterrupt

    monkeypatch.setattr(mod, call, interrupted)
    status, err = run_in_process(mod.main, argv(inputs, tmp_path), capsys)
    lines = error_lines(err)
    assert status == 130 and len(lines) == 1 and "interrupted" in lines[0], (status, err)
    assert list(tmp_path.iterdir()) == []


def test_the_capture_bounds_are_the_schemas() -> None:
    """``capture --full-well/--brackets`` and the config schema bound the sensor with the same numbers."""
    import yaml

    from brdfpipe.rendering import capture

    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text(encoding="utf-8"))
    sensor = schema["properties"]["closed_loop"]["properties"]["sensor"]["properties"]
    assert sensor["full_well"]["maximum"] == capture.MAX_FULL_WELL
    assert sensor["brackets"]["items"]["maximum"] == capture.MAX_BRACKET
    assert sensor["brackets"]["maxItems"] == capture.MAX_BRACKETS
    # at the bounds, the largest expected photon count is within NumPy's Poisson sampler
    lam = capture.MAX_FULL_WELL * capture.MAX_BRACKET
    assert math.isfinite(float(np.random.default_rng(0).poisson(lam)))
    with pytest.raises(ValueError, match="sensor.brackets"):
        capture.Sensor(brackets=(1.0, capture.MAX_BRACKET * 2))
