"""The ``brdfpipe`` command line.

Subcommands::

    brdfpipe synth  --count N --seed S --out DIR [--noise X] [--jobs J]
    brdfpipe nbrdf  ARCHIVE --out DIR [NAME ...]
    brdfpipe ingest DIR --out results/merl.zarr [--jobs J]
    brdfpipe info   results/merl.zarr
    brdfpipe interpolate --model results/gplvm/q5.npz (--at x1,…,xq | --between A B [--t 0.5]) --out F.binary
    brdfpipe nearest --model M (--at x1,…,xq | --material NAME) [-k 5]
    brdfpipe extrapolate --model M --store S --from A --through B [--step 0.05] [--max-s 3] [--out F.binary]
    brdfpipe sample --model M --store S --seed N --count K --out-dir DIR
    brdfpipe reconstruct OBSERVATIONS --model results/svd/train.zarr --out FILE.binary [--eta η]
    brdfpipe render MATERIAL.binary --out IMAGE.exr [--spp N] [--resolution W H] [--variant V]
    brdfpipe capture MATERIAL.binary DIRECTIONS.json --out DIR [--n 1 2] [--model M] [--spp N] [--no-noise] …

Every subcommand exits non-zero with one line ``brdfpipe CMD: error: ...``
naming the file or option and the problem on bad input or a failing
environment (full disk, unreadable or corrupt file, read-only folder, out of
memory), never a traceback; an argument error is one line too (exit 2); an
interrupt (Ctrl-C) exits 130.  No subcommand writes over one of its inputs
(:func:`brdfpipe.core.atomic.check_not_input`); every output's folder is
probed before any work (:func:`brdfpipe.core.atomic.check_writable`), and
every output is written atomically, so an error or interrupt leaves an
earlier output as it was.  The folder outputs of ``sample --out-dir`` and
``capture --out`` are built aside and swapped in whole; they replace only an
earlier output of the same command (recognised by the ``samples.json`` /
``capture.json`` it wrote and listing every file there), never a foreign
folder.

Sizes are bounded before any work, with the limit and why: ``synth
--count`` and ``sample --count`` by the free disk (a MERL file is 35 MB),
``--jobs`` by memory per worker, ``render --resolution`` by memory per pixel
and its ``--spp``/``--seed``/``--max-depth`` and ``capture --spp`` by what
Mitsuba accepts (32-bit unsigned), ``capture --full-well``/``--brackets`` by
NumPy's Poisson sampler (the config schema's bounds), ``extrapolate`` by the weights its walk
holds, ``sample --max-tries`` by time per candidate.  Numbers must be finite
(``nan``, ``inf`` and values that overflow are refused), and the JSON the
commands print is strict (no ``NaN``/``Infinity``).  Set
``BRDFPIPE_TRACEBACK=1`` to see the traceback of an unexpected error.
"""

from __future__ import annotations

import argparse
import decimal
import json
import logging
import math
import os
import sys
import types
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from brdfpipe.core.atomic import check_not_input, check_writable, output_of
from brdfpipe.core.command import OneLineParser, one_line, os_error_message
from brdfpipe.core.logutil import setup_console_logging
from brdfpipe.core.version import full_version

__all__ = ["main", "build_parser"]

log = logging.getLogger("brdfpipe.cli")


#: ``format`` of the ``samples.json`` that ``brdfpipe sample`` writes (recognises its --out-dir).
SAMPLES_FORMAT = "brdfpipe.samples/1"
#: ``format`` of the ``capture.json`` that ``brdfpipe capture`` writes (recognises its --out).
CAPTURE_FORMAT = "brdfpipe.capture/1"
#: Peak memory of one worker process of ``synth`` / ``ingest`` (a 35 MB material in float64 and its
#: generation or checks; the workflow's memory model, brdfpipe.plan.memory.MEMORY_MB, measured 306 MB for
#: synthesize_material), rounded up: ``--jobs`` is bounded by the machine's memory / this.
WORKER_BYTES = 350_000_000
#: ``sample --max-tries`` at most max(this, 100 × --count): a candidate costs up to ~1 ms (a batch of
#: 64 GPLVM solves and hull tests took 65 ms for 100 materials, q = 5, 2-core AMD EPYC), so ~17 min.
MAX_TRIES = 1_000_000


def _whole(text: str, minimum: int) -> int:
    """A whole number ≥ ``minimum``; ``1e9`` and ``1_000`` are read as the integers they write."""
    try:
        value = int(text)
    except ValueError:
        try:
            d = decimal.Decimal(text.strip().replace("_", ""))
        except decimal.InvalidOperation:
            d = None
        if d is None or not d.is_finite() or d != d.to_integral_value() or abs(d) > 10**30:
            raise argparse.ArgumentTypeError(f"expected a whole number ≥ {minimum}, got {text!r}") from None
        value = int(d)
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected a whole number ≥ {minimum}, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    return _whole(text, 1)


def _non_negative_int(text: str) -> int:
    return _whole(text, 0)


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _non_negative_float(text: str) -> float:
    value = _finite(text)
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, got {text}")
    return value


def _unit_fraction(text: str) -> float:
    value = _finite(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text}")
    return value


def _bits(text: str) -> int:
    value = _whole(text, 1)
    if value > 32:
        raise argparse.ArgumentTypeError(f"at most 32 (the ADC's bits), got {text}")
    return value


def _bracket(text: str) -> float:
    value = _finite(text)
    if not value >= 1.0:
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 1 (relative to the shortest, 1), got {text}")
    return value


def _strict_json(value: Any, what: str) -> str:
    """``value`` as strict JSON (RFC 8259: no NaN or Infinity); ValueError naming ``what`` otherwise."""
    try:
        return json.dumps(value, indent=2, allow_nan=False)
    except ValueError:
        raise ValueError(f"{what}: the result holds a non-finite number (NaN or ±inf), which JSON cannot "
                         "represent; nothing was printed") from None


def _check_jobs(jobs: int) -> None:
    from brdfpipe.core import resources

    total = resources.physical_memory()
    most = max(1, total // WORKER_BYTES) if total else jobs
    if jobs > most:
        raise ValueError(f"--jobs {jobs}: at most {most} on this machine (each worker peaks at about "
                         f"{resources.format_bytes(WORKER_BYTES)}; {resources.format_bytes(total)} of memory)")


def _check_disk_for_materials(out: str | os.PathLike[str], count: int, option: str, *, existing: int = 0) -> None:
    """``count`` MERL files of 35 MB must fit the free space of ``out``'s file system (less ``existing`` bytes)."""
    from brdfpipe.core import resources
    from brdfpipe.data import merl

    resources.check_free_space(
        out, max(0, count * merl.FILE_SIZE - existing), what=f"{option} {count}",
        how=f"{count} MERL files × {resources.format_bytes(merl.FILE_SIZE)}")


def _cmd_synth(args: argparse.Namespace) -> int:
    from brdfpipe.data import synth

    _check_jobs(args.jobs)
    check_writable(args.out, inside=True)
    out = Path(args.out)
    existing = sum(f.stat().st_size for f in out.glob("*.binary") if f.is_file()) if out.is_dir() else 0
    _check_disk_for_materials(out, args.count, "--count", existing=existing)
    # synthesize() refuses an --out that holds anything it did not write itself
    # (synth.check_output_folder) before it writes a byte.
    manifest = synth.synthesize(
        args.out, count=args.count, seed=args.seed, noise=args.noise, jobs=args.jobs
    )
    print(manifest)
    return 0


def _cmd_nbrdf(args: argparse.Namespace) -> int:
    from brdfpipe.data import databases, nbrdf

    archive = args.archive
    if archive in databases.DATABASES and databases.DATABASES[archive].archive is not None:
        shipped = databases.shipped_archive(archive)  # a shipped archive, by its database's name
        if os.path.lexists(archive):
            raise nbrdf.NbrdfError(f"{archive}: both the shipped database {archive} ({shipped}) and the local path "
                                   f"./{archive}; give ./{archive} for the local one, or {shipped} for the shipped one")
        archive = str(shipped)
    check_not_input(args.out, [archive], what="--out")
    check_writable(args.out, inside=True)
    with nbrdf.open_archive(archive) as fits:
        count = len(nbrdf.fit_names(fits, args.names))
    _check_disk_for_materials(Path(args.out), count, "fits:")
    for path, table in nbrdf.write_fits(archive, args.out, args.names):
        log.info("%s (%d values clamped at 0)", path, table.clamped)
    print(args.out)
    return 0


def _cmd_ingest(args: argparse.Namespace) -> int:
    from brdfpipe.data import database, ingest

    _check_jobs(args.jobs)
    db = database.database_from_folder(args.folder, key="folder")
    check_not_input(args.out, [args.folder, *db.sources.values()])
    check_writable(args.out)
    ingest.ingest(
        {name: db.sources[name] for name in db.materials},
        args.out,
        database=db.kind,
        jobs=args.jobs,
    )
    print(args.out)
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from brdfpipe.data import store

    st = store.open_store(args.store, verify=args.verify)
    summary = {
        "store": str(st.path),
        "database": st.database,
        "materials": st.n_materials,
        "shape": list(st.brdf.shape),
        "chunks": list(st.brdf.chunks),
        "valid_cells": int(st.valid[:].sum()),
        "brdfpipe_version": st.group.attrs.get("brdfpipe_version"),
        "verified": bool(args.verify),
    }
    print(_strict_json(summary, str(args.store)))
    return 0


def _positive_float(text: str) -> float:
    value = float(text)
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from brdfpipe.acquisition import reconstruct

    check_not_input(args.out, [args.observations, args.model])
    check_writable(args.out)
    reconstruct.write_reconstruction(args.model, args.observations, args.out, eta=args.eta)
    print(args.out)
    return 0


def _latent_point(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected finite numbers (no nan, inf or overflowing values), got {text!r}")
    return values


def _cmd_interpolate(args: argparse.Namespace) -> int:
    from brdfpipe.manifold import gplvm

    check_not_input(args.out, [args.model, args.store])
    check_writable(args.out)
    if args.at is not None:
        q = gplvm.load_model(args.model).X.shape[1]
        if len(args.at) != q:
            raise ValueError(f"--at: {args.model} has q = {q} latent coordinates, got {len(args.at)}")
    gplvm.interpolate_to_file(
        args.model, args.store, args.out,
        at=args.at, between=tuple(args.between) if args.between else None, t=args.t,
    )
    print(args.out)
    return 0


def _cmd_nearest(args: argparse.Namespace) -> int:
    import numpy as np

    from brdfpipe.manifold import gplvm, latent

    model = gplvm.load_model(args.model)
    with np.errstate(over="ignore", invalid="ignore"):  # an overflowing distance is refused below
        if args.material is not None:
            if args.material not in model.names:
                raise ValueError(f"--material: {args.material!r} is not a material of {args.model}")
            found = latent.nearest_materials(model, args.material, args.k, exclude=[args.material])
        else:
            q = model.X.shape[1]
            if len(args.at) != q:
                raise ValueError(f"--at: {args.model} has q = {q} latent coordinates, got {len(args.at)}")
            found = latent.nearest_materials(model, args.at, args.k)
    if not all(math.isfinite(d) for _, d in found):
        where = "--at " + ",".join(f"{v:g}" for v in args.at) if args.material is None else f"--material {args.material}"
        raise ValueError(f"{where}: the latent distances overflow (beyond 1.8e308 in units of ℓ = {model.ell:.6g}); "
                         "give a point nearer the materials")
    print(_strict_json([{"material": n, "latent_distance": d} for n, d in found], "nearest"))
    return 0


def _cmd_extrapolate(args: argparse.Namespace) -> int:
    from brdfpipe.manifold import gplvm, latent

    if args.out is not None:
        check_not_input(args.out, [args.model, args.store])
        check_writable(args.out)
    model = gplvm.load_model(args.model)
    for flag, name in (("--from", args.start), ("--through", args.through)):
        if name not in model.names:
            raise ValueError(f"{flag}: {name!r} is not a material of {args.model}")
    if args.start == args.through:
        raise ValueError("--from and --through name the same material; give two different ones")
    e = latent.extrapolate(model, args.store, args.start, args.through, step=args.step, max_s=args.max_s,
                           exact=args.exact)
    last = len(e.s) - 2 if e.stop_s is not None else len(e.s) - 1  # index of the last valid step
    summary = {
        "from": args.start, "through": args.through, "step": args.step, "max_s": args.max_s,
        "reason": e.reason, "channel": e.channel,
        "last_valid_s": None if e.last_valid_s is None else round(e.last_valid_s, 12),
        "stop_s": None if e.stop_s is None else round(e.stop_s, 12),
        "albedo_last_valid": None if e.last_valid_s is None else e.albedos[last].tolist(),
        "albedo_at_stop": None if e.stop_s is None else e.albedos[-1].tolist(),
        "out": args.out,
    }
    if args.out is not None:
        point = e.last_valid_point
        if point is None:
            raise ValueError(f"the albedo at {args.start} itself is outside [0, 1]; nothing to write to {args.out}")
        details = {"start": args.start, "through": args.through, "s": e.last_valid_s, "step": args.step}
        clamped = latent.write_blends(args.model, model, args.store, [point], [args.out], operation="extrapolate",
                                      details=[details])
        summary["clamped_values"] = int(clamped[0])  # negative interpolated values written as 0
    print(_strict_json(summary, "extrapolate"))
    return 0


def _cmd_sample(args: argparse.Namespace) -> int:
    import numpy as np

    from brdfpipe.core import atomic
    from brdfpipe.manifold import gplvm, latent

    out_dir = Path(args.out_dir)
    check_not_input(out_dir, [args.model, args.store], what="--out-dir")
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"--out-dir {out_dir}: exists and is not a folder")
    _check_own_folder(out_dir, "--out-dir", _is_samples_folder, "brdfpipe sample", "samples.json")
    check_writable(out_dir, what="--out-dir")
    most_tries = max(MAX_TRIES, 100 * args.count)
    if args.max_tries is not None and args.max_tries > most_tries:
        raise ValueError(f"--max-tries {args.max_tries}: at most {most_tries} (max({MAX_TRIES}, 100 × --count); a "
                         "candidate costs up to ~1 ms, so that is already ~17 min or more of drawing)")
    _check_disk_for_materials(out_dir, args.count, "--count")
    model = gplvm.load_model(args.model)
    s = latent.sample_material(model, args.store, np.random.default_rng(args.seed), args.count,
                               max_tries=args.max_tries, exact=args.exact)
    with atomic.atomic_dir(out_dir, replaceable=_is_samples_folder) as tmp:
        _write_samples(args, model, s, tmp)
    print(out_dir / "samples.json")
    return 0


def _write_samples(args: argparse.Namespace, model: Any, s: Any, out_dir: Path) -> None:
    """The sampled materials, samples.csv and samples.json into the (temporary) folder ``out_dir``."""
    import csv
    import io

    import numpy as np

    from brdfpipe.core import atomic
    from brdfpipe.manifold import latent

    files = [f"sample-{i:03d}.binary" for i in range(args.count)]
    latent.write_blends(args.model, model, args.store, s.points, [out_dir / f for f in files], operation="sample",
                        details=[{"seed": args.seed, "count": args.count, "index": i} for i in range(args.count)])
    q = model.X.shape[1]
    rows = []
    for i, name in enumerate(files):
        w = s.weights[i]
        top = np.argsort(-w, kind="stable")[:3]
        rows.append({
            "file": name, "latent": s.points[i].tolist(), "albedo": s.albedos[i].tolist(),
            "top_weights": {model.names[j]: float(w[j]) for j in top},
            "negative_weight_sum": float(w[w < 0].sum()),
            "weights": {n: float(v) for n, v in zip(model.names, w)},
        })
    meta = {"format": SAMPLES_FORMAT, "model": str(args.model), "store": str(args.store), "seed": args.seed,
            "count": args.count, "space": model.space, "exact_albedo": bool(args.exact), "candidates_drawn": s.tries,
            "samples": rows}
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(["file", *(f"x{k + 1}" for k in range(q)), "albedo_r", "albedo_g", "albedo_b",
                 "top_material", "top_weight", "negative_weight_sum"])
    for r in rows:
        (tn, tw), = list(r["top_weights"].items())[:1]
        wr.writerow([r["file"], *(repr(v) for v in r["latent"]), *(repr(v) for v in r["albedo"]), tn, repr(tw),
                     repr(r["negative_weight_sum"])])
    atomic.write_text(out_dir / "samples.csv", buf.getvalue())
    atomic.write_text(out_dir / "samples.json", _strict_json(meta, "samples.json") + "\n")


def _own_entries(folder: Path, listed: set[str]) -> bool:
    """Every entry of ``folder`` is a plain file named in ``listed`` (or a temporary sibling of one)."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return False
    return all(output_of(e).name in listed and e.is_file() and not e.is_symlink() for e in entries)


def _is_samples_folder(folder: Path) -> bool:
    """``folder`` is an earlier ``brdfpipe sample`` output: its samples.json lists every file there."""
    import re

    try:
        doc = json.loads((folder / "samples.json").read_text(encoding="utf-8"))
        files = {str(r["file"]) for r in doc["samples"]}
        legacy = "format" not in doc and {"model", "store", "seed", "count"} <= set(doc)  # before SAMPLES_FORMAT
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False
    if not (doc.get("format") == SAMPLES_FORMAT or legacy):
        return False
    if not all(re.fullmatch(r"sample-[0-9]{3,}\.binary", f) for f in files):
        return False
    return _own_entries(folder, files | {"samples.json", "samples.csv"})


def _is_capture_folder(folder: Path) -> bool:
    """``folder`` is an earlier ``brdfpipe capture`` output: its capture.json lists every file there."""
    try:
        doc = json.loads((folder / "capture.json").read_text(encoding="utf-8"))
        files = {str(f) for f in doc["files"]}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False
    if doc.get("format") != CAPTURE_FORMAT or any("/" in f or f.startswith(".") for f in files):
        return False
    return _own_entries(folder, files | {"capture.json"})


def _check_own_folder(out: Path, option: str, recognise: Any, command: str, manifest: str) -> None:
    """Refuse, before any work, an existing ``out`` that is neither empty nor an earlier output of ``command``."""
    from brdfpipe.core import atomic

    try:
        atomic.check_replaceable(out, replaceable=recognise)
    except atomic.OutputError:
        raise atomic.OutputError(
            f"{option} {out}: holds files `{command}` did not write (no {manifest} listing every file there); "
            "refusing to replace it: choose a new or empty folder") from None


def _check_material(path: str) -> None:
    """Read the MERL file before Mitsuba does: its ``merl`` plugin would bury the reader's error in a scene error."""
    from brdfpipe.data import merl

    merl.read_merl(path)  # MerlFormatError (a ValueError) naming the file


def _cmd_render(args: argparse.Namespace) -> int:
    import tempfile

    from brdfpipe.rendering import scene

    check_not_input(args.out, [args.material, args.envmap])
    scene.check_render_settings(tuple(args.resolution), args.spp, args.seed, args.max_depth,
                                names={"resolution": "--resolution", "spp": "--spp", "seed": "--seed",
                                       "max_depth": "--max-depth"})
    check_writable(args.out)
    _check_material(args.material)
    if args.envmap is not None:
        from brdfpipe.core import exr

        try:
            exr.read_exr(args.envmap)  # before Mitsuba, whose message would name the output
        except exr.ExrError as err:
            raise ValueError(f"--envmap: {err}") from None
    with tempfile.TemporaryDirectory(prefix="brdfpipe-render-") as tmp:
        envmap = args.envmap
        if envmap is None:
            envmap = os.path.join(tmp, "envmap.exr")
            scene.make_envmap(envmap)
        scene.render_material(
            args.material, args.out, envmap=envmap, variant=args.variant, resolution=tuple(args.resolution),
            spp=args.spp, max_depth=args.max_depth, seed=args.seed,
        )
    print(args.out)
    return 0


def _light_distance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 1 or inf, got {text!r}") from None
    if not value > 1.0:
        raise argparse.ArgumentTypeError(f"the light must lie beyond the camera (distance > 1 R), got {text!r}")
    return value


def _check_sensor_args(args: argparse.Namespace) -> None:
    """The sensor's bounds (:class:`brdfpipe.rendering.capture.Sensor`, the config schema's), naming the option."""
    from brdfpipe.rendering import capture

    why = "a pixel's photon count (full well × bracket) must stay within NumPy's Poisson sampler"
    if args.full_well > capture.MAX_FULL_WELL:
        raise ValueError(f"--full-well {args.full_well:g}: at most {capture.MAX_FULL_WELL:g} electrons ({why})")
    if len(args.brackets) > capture.MAX_BRACKETS:
        raise ValueError(f"--brackets: at most {capture.MAX_BRACKETS} exposures (each one is one more exposure of "
                         f"every image), got {len(args.brackets)}")
    if max(args.brackets) > capture.MAX_BRACKET:
        raise ValueError(f"--brackets {max(args.brackets):g}: at most {capture.MAX_BRACKET:g} (relative to the "
                         f"shortest exposure, 1; {why})")
    if min(args.brackets) != 1.0:
        raise ValueError(f"--brackets {' '.join(f'{b:g}' for b in args.brackets)}: the shortest must be 1 (the "
                         "exposure times are relative to it)")


def _cmd_capture(args: argparse.Namespace) -> int:
    from brdfpipe.core import atomic
    from brdfpipe.rendering import capture, scene

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: --out must be a folder")
    _check_sensor_args(args)
    if args.spp > scene.MITSUBA_UINT32_MAX:
        raise ValueError(f"--spp {args.spp}: at most {scene.MITSUBA_UINT32_MAX} (Mitsuba's sample count is a 32-bit "
                         "unsigned integer)")
    image_keys, table_keys = capture.output_layout(1, args.n)
    inputs = [args.material, args.directions] + ([args.model] if args.model else [])
    check_not_input(out, inputs)  # the folder is replaced whole: it may not hold an input
    _check_own_folder(out, "--out", _is_capture_folder, "brdfpipe capture", "capture.json")
    check_writable(out)
    _check_material(args.material)
    sensor = capture.Sensor(enabled=not args.no_noise, full_well=args.full_well, read_noise=args.read_noise,
                            bits=args.bits, peak_level=args.peak_level, brackets=tuple(args.brackets))
    with atomic.atomic_dir(out, replaceable=_is_capture_folder) as tmp:
        capture.capture_to_files(
            material=args.material, directions=[args.directions], n_images=args.n,
            renders=[tmp / f"n{n}-{j}-render.exr" for _, n, j in image_keys],
            photographs=[tmp / f"n{n}-{j}-sensor.exr" for _, n, j in image_keys],
            noiseless=[tmp / f"n{n}-noiseless.npz" for _, n in table_keys],
            observations=[tmp / f"n{n}-sensor.npz" for _, n in table_keys],
            spp=args.spp, seed=args.seed, light_distance=args.light_distance, min_snr=args.min_snr,
            sensor=sensor, variant=args.variant,
        )
        if args.model:
            from brdfpipe.acquisition import reconstruct

            for _, n in table_keys:
                reconstruct.write_reconstruction(args.model, tmp / f"n{n}-sensor.npz", tmp / f"n{n}.binary",
                                                 eta=args.eta, material=args.material)
        doc = {
            "format": CAPTURE_FORMAT, "material": str(args.material), "directions": str(args.directions),
            "model": None if args.model is None else str(args.model), "n": list(args.n), "spp": args.spp,
            "seed": args.seed, "light_distance": None if math.isinf(args.light_distance) else args.light_distance,
            "min_snr": args.min_snr, "eta": args.eta if args.model else None,
            "sensor": None if args.no_noise else {"full_well": args.full_well, "read_noise": args.read_noise,
                                                  "bits": args.bits, "peak_level": args.peak_level,
                                                  "brackets": list(args.brackets)},
            "files": sorted(p.name for p in tmp.iterdir()),
        }
        atomic.write_text(tmp / "capture.json", _strict_json(doc, "capture.json") + "\n")
    print(out)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``brdfpipe`` command."""
    parser = OneLineParser(prog="brdfpipe", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"brdfpipe {full_version()}")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", required=True)

    _add_data_commands(sub)
    _add_manifold_commands(sub)
    _add_tool_commands(sub)
    return parser


def _add_data_commands(sub: Any) -> None:
    """synth, nbrdf, ingest: making and ingesting databases."""
    p = sub.add_parser("synth", help="generate a synthetic MERL-format database")
    p.add_argument("--count", type=_positive_int, required=True, help="number of materials")
    p.add_argument("--seed", type=_non_negative_int, required=True, help="seed of every random choice")
    p.add_argument("--out", required=True, help="output folder (<name>.binary + manifest.json): new, "
                   "empty, or an earlier output of the same synth command")
    p.add_argument("--noise", type=_non_negative_float, default=0.01,
                   help="relative measurement noise (default 0.01)")
    p.add_argument("--jobs", type=_positive_int, default=os.cpu_count() or 1,
                   help="worker processes (default: all cores)")
    p.set_defaults(func=_cmd_synth)

    p = sub.add_parser("nbrdf", help="MERL files of measured materials from their published neural fits (NBRDF)")
    p.add_argument("archive", help="an archive of NBRDF fits (.zip or folder of NAME.h5 [+ NAME.json]), or the name "
                   "of a shipped one: merl-nbrdf, rgl-nbrdf, nielsen-nbrdf (a local path of the same name: ./NAME)")
    p.add_argument("--out", required=True, help="folder for <material>.binary (a fit's name with '_' written '-'): "
                   "new, empty, or an earlier output of this command")
    p.add_argument("names", nargs="*", metavar="NAME", help="fits to evaluate (default: all of the archive)")
    p.set_defaults(func=_cmd_nbrdf)

    p = sub.add_parser("ingest", help="ingest MERL files into the chunked Zarr store")
    p.add_argument("folder", help="folder of .binary files of one kind: real MERL, written by `brdfpipe synth`, "
                   "or derived by brdfpipe (labelled from the files' provenance marks)")
    p.add_argument("--out", required=True, help="the store to write (e.g. results/merl.zarr)")
    p.add_argument("--jobs", type=_positive_int, default=os.cpu_count() or 1,
                   help="worker processes (default: all cores)")
    p.set_defaults(func=_cmd_ingest)


def _add_manifold_commands(sub: Any) -> None:
    """interpolate, nearest, extrapolate, sample: a fitted GPLVM's latent space."""
    p = sub.add_parser("interpolate", help="write the BRDF at a point of a GPLVM latent space")
    p.add_argument("--model", required=True, help="a fit written by the workflow (results/gplvm/q5.npz)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--at", type=_latent_point, help="latent point x1,…,xq")
    where.add_argument("--between", nargs=2, metavar=("A", "B"), help="two materials of the model")
    p.add_argument("--t", type=_finite, default=0.5, help="fraction of the way from A to B (default 0.5)")
    p.add_argument("--store", default="results/merl.zarr", help="the store the model was fitted to")
    p.add_argument("--out", required=True, help="MERL file to write")
    p.set_defaults(func=_cmd_interpolate)

    p = sub.add_parser("nearest", help="the training materials nearest a point of a GPLVM latent space")
    p.add_argument("--model", required=True, help="a fit written by the workflow (results/gplvm/q5.npz)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--at", type=_latent_point, help="latent point x1,…,xq")
    where.add_argument("--material", help="a material of the model (itself left out of the answer)")
    p.add_argument("-k", "--k", type=_positive_int, default=5, help="how many (default 5)")
    p.set_defaults(func=_cmd_nearest)

    p = sub.add_parser("extrapolate", help="walk from material A through B until the albedo leaves [0, 1]")
    p.add_argument("--model", required=True, help="a fit written by the workflow (results/gplvm/q5.npz)")
    p.add_argument("--store", default="results/merl.zarr", help="the store the model was fitted to")
    p.add_argument("--from", dest="start", required=True, metavar="A", help="start material (s = 0)")
    p.add_argument("--through", required=True, metavar="B", help="material at s = 1")
    p.add_argument("--step", type=_positive_float, default=0.05, help="step in s (default 0.05)")
    p.add_argument("--max-s", type=_non_negative_float, default=3.0, help="farthest s (default 3)")
    p.add_argument("--exact", action="store_true",
                   help="albedo of the clamped interpolated table (slow) instead of w·A in linear spaces")
    p.add_argument("--out", default=None, help="MERL file to write the last valid material to")
    p.set_defaults(func=_cmd_extrapolate)

    p = sub.add_parser("sample", help="sample plausible new materials uniformly in the latent hull")
    p.add_argument("--model", required=True, help="a fit written by the workflow (results/gplvm/q5.npz)")
    p.add_argument("--store", default="results/merl.zarr", help="the store the model was fitted to")
    p.add_argument("--seed", type=_non_negative_int, required=True, help="seed of every random choice")
    p.add_argument("--count", type=_positive_int, required=True, help="number of materials")
    p.add_argument("--max-tries", type=_positive_int, default=None,
                   help="most candidates drawn (default max(1000, 100 × count))")
    p.add_argument("--exact", action="store_true",
                   help="albedo of the clamped interpolated table (slow) instead of w·A in linear spaces")
    p.add_argument("--out-dir", required=True,
                   help="folder for sample-NNN.binary, samples.json and samples.csv (created if needed)")
    p.set_defaults(func=_cmd_sample)


def _add_tool_commands(sub: Any) -> None:
    """info, reconstruct, render, capture: a store, a reconstruction, a render, a photograph."""
    p = sub.add_parser("info", help="validate a store and print a summary")
    p.add_argument("store", help="path of a store written by ingest")
    p.add_argument("--verify", action=argparse.BooleanOptionalAction, default=True,
                   help="check every row's bytes against its recorded digest (default; --no-verify checks "
                        "only the metadata, shard sizes and the valid mask)")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("reconstruct", help="reconstruct a full MERL BRDF from sparse observations")
    p.add_argument("observations", help="CSV (wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b or theta_h,theta_d,phi_d,r,g,b; "
                   "degrees) or NPZ (wi, wo, rgb or theta_h, theta_d, phi_d, rgb) of BRDF values in sr^-1")
    p.add_argument("--model", required=True, help="the PCA model (e.g. results/svd/train.zarr)")
    p.add_argument("--out", required=True, help="the MERL .binary file to write")
    p.add_argument("--eta", type=_positive_float, default=40.0,
                   help="Tikhonov weight of the coefficient fit (default 40, Xu et al. 2016)")
    p.set_defaults(func=_cmd_reconstruct)

    p = sub.add_parser("render", help="render a MERL material in the preview scene with Mitsuba 3 (EXR)")
    p.add_argument("material", help="a MERL .binary file")
    p.add_argument("--out", required=True, help="the EXR image to write")
    p.add_argument("--envmap", default=None, help="lat-long EXR environment (default: the generated sky + sun)")
    p.add_argument("--resolution", type=_positive_int, nargs=2, default=[256, 192], metavar=("W", "H"))
    p.add_argument("--spp", type=_positive_int, default=64, help="samples per pixel (default 64)")
    p.add_argument("--max-depth", type=_positive_int, default=6, help="longest light path (default 6)")
    p.add_argument("--seed", type=_non_negative_int, default=0)
    p.add_argument("--variant", default="llvm_ad_rgb", help="llvm_ad_rgb (CPU, default) or cuda_ad_rgb (GPU)")
    p.set_defaults(func=_cmd_render)

    p = sub.add_parser("capture", help="photograph a flat sample with the set-ups of a directions file (closed loop)")
    p.add_argument("material", help="a MERL .binary file (the sample)")
    p.add_argument("directions", help="a directions file of an image setup (results/directions/.../*.json)")
    p.add_argument("--out", required=True,
                   help="folder for the images (n{n}-{j}-render.exr, n{n}-{j}-sensor.exr) and the observation "
                        "tables (n{n}-noiseless.npz, n{n}-sensor.npz)")
    p.add_argument("--n", type=_positive_int, nargs="+", default=[1, 2], help="set sizes to capture (default 1 2)")
    p.add_argument("--model", default=None,
                   help="a PCA model: also reconstruct each set's BRDF from the sensor's observations (n{n}.binary)")
    p.add_argument("--eta", type=_positive_float, default=40.0, help="Tikhonov weight of the reconstruction")
    p.add_argument("--spp", type=_positive_int, default=64, help="samples per pixel (default 64)")
    p.add_argument("--seed", type=_non_negative_int, default=0)
    p.add_argument("--light-distance", type=_light_distance, default=20.0,
                   help="point light distance in units of the camera's (default 20; inf = distant light)")
    p.add_argument("--min-snr", type=_non_negative_float, default=3.0, help="mask pixels below this SNR (default 3)")
    p.add_argument("--no-noise", action="store_true", help="no sensor: the noiseless render is the photograph")
    p.add_argument("--full-well", type=_positive_float, default=20000.0, help="electrons at saturation")
    p.add_argument("--read-noise", type=_non_negative_float, default=5.0, help="electrons RMS per exposure")
    p.add_argument("--bits", type=_bits, default=12, help="ADC bits (1 to 32)")
    p.add_argument("--peak-level", type=_unit_fraction, default=0.8,
                   help="brightest disk pixel of the shortest exposure / full well")
    p.add_argument("--brackets", type=_bracket, nargs="+", default=[1.0, 8.0, 64.0],
                   help="relative exposure times (HDR bracketing; default 1 8 64)")
    p.add_argument("--variant", default="llvm_ad_rgb", help="llvm_ad_rgb (CPU, default) or cuda_ad_rgb (GPU)")
    p.set_defaults(func=_cmd_capture)


def _render_errors() -> tuple[type[Exception], ...]:
    """The rendering track's error classes (their modules import Mitsuba lazily)."""
    from brdfpipe.rendering.render import RenderError
    from brdfpipe.rendering.scene import SceneError

    return (RenderError, SceneError)


def _memory_error_message(args: argparse.Namespace) -> str:
    if args.command == "render":
        w, h = args.resolution
        return (
            f"the render is too large for memory ({w}×{h} pixels × {args.spp} samples per pixel); "
            "lower --resolution or --spp"
        )
    return "out of memory; nothing was written (an earlier output is kept)"


#: Arguments that name a command's input files.
_INPUT_ARGS = ("model", "store", "material", "directions", "observations", "folder", "envmap")


def _frames(err: BaseException) -> Iterator[types.FrameType]:
    """The frames of ``err``'s traceback, innermost first."""
    frames = []
    tb = err.__traceback__
    while tb is not None:
        frames.append(tb.tb_frame)
        tb = tb.tb_next
    return reversed(frames)


def _input_named_by(err: BaseException, args: argparse.Namespace) -> str | None:
    """The input file ``err`` arose from: the innermost frame of its traceback holding that path (or a file in it).

    ``None`` when no frame names an input and the command has several.
    """
    inputs = [str(v) for v in (getattr(args, a, None) for a in _INPUT_ARGS) if isinstance(v, str) and v]
    if not inputs:
        return None
    known = [(p, Path(os.path.abspath(p))) for p in inputs]
    for frame in _frames(err):
        for value in list(frame.f_locals.values()):
            name = getattr(value, "name", value) if not isinstance(value, (str, os.PathLike)) else value
            if not isinstance(name, (str, os.PathLike)):
                continue
            text = os.fspath(name)
            if not isinstance(text, str) or not text or len(text) > 4096 or "\0" in text or "\n" in text:
                continue
            where = Path(os.path.abspath(text))
            for shown, path in known:
                if where == path or path in where.parents:
                    return shown
    return inputs[0] if len(inputs) == 1 else None


#: Exceptions a reader may let through for a truncated, corrupt or wrong file.
_READ_ERRORS: tuple[type[BaseException], ...] = (EOFError, KeyError, IndexError, UnicodeDecodeError,
                                                 json.JSONDecodeError, OverflowError)


def _read_error_types() -> tuple[type[BaseException], ...]:
    import struct
    import zipfile
    import zlib

    return (*_READ_ERRORS, zipfile.BadZipFile, struct.error, zlib.error)


def _unexpected_message(err: BaseException, args: argparse.Namespace) -> str:
    """One line for an exception no library error class covers: the input it came from and what it says."""
    kind = type(err).__name__
    text = one_line(str(err)) or kind
    where = _input_named_by(err, args)
    if isinstance(err, _read_error_types()):
        what = where or ", ".join(str(getattr(args, a)) for a in _INPUT_ARGS if getattr(args, a, None)) or "an input"
        return (f"{what}: cannot read it ({kind}: {text}); it is truncated, corrupt or not the kind of file "
                "this option takes: write it again (rerun the step that made it)")
    if isinstance(err, RuntimeError):  # Mitsuba, Dr.Jit, OpenEXR
        return f"{where}: {kind}: {text}" if where else f"{kind}: {text}"
    return (f"internal error ({kind}: {text}{'; input ' + where if where else ''}); please report it with the "
            "command line (BRDFPIPE_TRACEBACK=1 shows the traceback)")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0 on success; 1 with one line ``brdfpipe CMD: error: ...`` on stderr for
    bad input, a refused output path or size, an OS error (the path is
    named; a full disk says "no space left on device writing PATH"), a
    MemoryError, or any other exception (a reader's ``BadZipFile``,
    ``EOFError``, ``KeyError``…, a Mitsuba ``RuntimeError``: the input file it
    came from is named); 130 after an interrupt.  Argument errors exit 2
    with one line.  ``BRDFPIPE_TRACEBACK=1`` re-raises unexpected errors.
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and getattr(args, "command", None) == "nbrdf" and not any(e.startswith("-") for e in extra):
        args.names = [*args.names, *extra]  # `nbrdf ARCHIVE --out DIR NAME ...`: names after the options
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    setup_console_logging(logging.WARNING if args.quiet else logging.INFO)
    prefix = f"brdfpipe {args.command}: error:"
    out = getattr(args, "out", None) or getattr(args, "out_dir", None)

    def fail(message: str, status: int = 1) -> int:
        print(f"{prefix} {one_line(message)}", file=sys.stderr)
        return status

    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        return fail("interrupted; nothing was written / earlier output kept "
                    "(outputs are replaced only when complete)", 130)
    except MemoryError:
        return fail(_memory_error_message(args))
    except OSError as err:
        return fail(os_error_message(err, out))
    except (json.JSONDecodeError, UnicodeDecodeError) as err:  # ValueErrors that do not name the file
        if os.environ.get("BRDFPIPE_TRACEBACK"):
            raise
        return fail(_unexpected_message(err, args))
    except ValueError as err:
        # MerlFormatError, DatabaseError, OutputError, ResourceError and store errors are
        # ValueErrors whose message names the file or option and the problem.
        return fail(str(err))
    except Exception as err:
        if isinstance(err, _render_errors()):  # RenderError, SceneError: the message names the file
            return fail(str(err))
        if os.environ.get("BRDFPIPE_TRACEBACK"):
            raise
        return fail(_unexpected_message(err, args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
