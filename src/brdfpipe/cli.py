"""The ``brdfpipe`` command line.

Subcommands::

    brdfpipe synth  --count N --seed S --out DIR [--noise X] [--jobs J]
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
naming the file and the problem on bad input or a failing environment (full
disk, unreadable file, out of memory), never a traceback; an interrupt
(Ctrl-C) exits 130.  No subcommand writes over one of its inputs
(:func:`brdfpipe.core.atomic.check_not_input`), and every output is written
atomically, so an error or interrupt leaves an earlier output as it was.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Sequence

from brdfpipe.core.atomic import check_not_input, is_out_of_space
from brdfpipe.core.logutil import setup_console_logging
from brdfpipe.core.version import full_version

__all__ = ["main", "build_parser"]

log = logging.getLogger("brdfpipe.cli")


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, got {value}")
    return value


def _non_negative_float(text: str) -> float:
    value = float(text)
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f"must be ≥ 0, got {text}")
    return value


def _cmd_synth(args: argparse.Namespace) -> int:
    from brdfpipe.data import synth

    # synthesize() refuses an --out that holds anything it did not write itself
    # (synth.check_output_folder) before it writes a byte.
    manifest = synth.synthesize(
        args.out, count=args.count, seed=args.seed, noise=args.noise, jobs=args.jobs
    )
    print(manifest)
    return 0


def _cmd_ingest(args: argparse.Namespace) -> int:
    from brdfpipe.data import database, store

    db = database.database_from_folder(args.folder, key="folder")
    check_not_input(args.out, [args.folder, *db.sources.values()])
    store.ingest(
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
    print(json.dumps(summary, indent=2))
    return 0


def _positive_float(text: str) -> float:
    value = float(text)
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from brdfpipe.acquisition import reconstruct

    check_not_input(args.out, [args.observations, args.model])
    reconstruct.write_reconstruction(args.model, args.observations, args.out, eta=args.eta)
    print(args.out)
    return 0


def _latent_point(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def _cmd_interpolate(args: argparse.Namespace) -> int:
    from brdfpipe.manifold import gplvm

    check_not_input(args.out, [args.model, args.store])
    gplvm.interpolate_to_file(
        args.model, args.store, args.out,
        at=args.at, between=tuple(args.between) if args.between else None, t=args.t,
    )
    print(args.out)
    return 0


def _cmd_nearest(args: argparse.Namespace) -> int:
    from brdfpipe.manifold import gplvm, latent

    model = gplvm.load_model(args.model)
    if args.material is not None:
        if args.material not in model.names:
            raise ValueError(f"--material: {args.material!r} is not a material of {args.model}")
        found = latent.nearest_materials(model, args.material, args.k, exclude=[args.material])
    else:
        q = model.X.shape[1]
        if len(args.at) != q:
            raise ValueError(f"--at: {args.model} has q = {q} latent coordinates, got {len(args.at)}")
        found = latent.nearest_materials(model, args.at, args.k)
    print(json.dumps([{"material": n, "latent_distance": d} for n, d in found], indent=2))
    return 0


def _cmd_extrapolate(args: argparse.Namespace) -> int:
    from brdfpipe.data import merl
    from brdfpipe.manifold import gplvm, latent

    if args.out is not None:
        check_not_input(args.out, [args.model, args.store])
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
        w = gplvm.blend_weights(gplvm.weights(model, point))
        table, clamped = gplvm.interpolate_table(args.store, w, materials=model.names, space=model.space,
                                                 model=model)
        merl.write_merl(args.out, table)
        summary["clamped_values"] = clamped  # negative interpolated values written as 0
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_sample(args: argparse.Namespace) -> int:
    import csv
    import io
    from pathlib import Path

    import numpy as np

    from brdfpipe.core import atomic
    from brdfpipe.data import merl
    from brdfpipe.manifold import gplvm, latent

    out_dir = Path(args.out_dir)
    check_not_input(out_dir, [args.model, args.store], what="--out-dir")
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"--out-dir {out_dir}: exists and is not a folder")
    model = gplvm.load_model(args.model)
    s = latent.sample_material(model, args.store, np.random.default_rng(args.seed), args.count,
                               max_tries=args.max_tries, exact=args.exact)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [f"sample-{i:03d}.binary" for i in range(args.count)]
    for a in range(0, args.count, 4):
        tables, _ = gplvm.interpolate_tables(args.store, s.weights[a : a + 4], materials=model.names,
                                             space=model.space, model=model)
        for j, table in enumerate(tables):
            merl.write_merl(out_dir / files[a + j], table)
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
    meta = {"model": str(args.model), "store": str(args.store), "seed": args.seed, "count": args.count,
            "space": model.space, "exact_albedo": bool(args.exact), "candidates_drawn": s.tries, "samples": rows}
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(["file", *(f"x{k + 1}" for k in range(q)), "albedo_r", "albedo_g", "albedo_b",
                 "top_material", "top_weight", "negative_weight_sum"])
    for r in rows:
        (tn, tw), = list(r["top_weights"].items())[:1]
        wr.writerow([r["file"], *(repr(v) for v in r["latent"]), *(repr(v) for v in r["albedo"]), tn, repr(tw),
                     repr(r["negative_weight_sum"])])
    atomic.write_text(out_dir / "samples.csv", buf.getvalue())
    atomic.write_text(out_dir / "samples.json", json.dumps(meta, indent=2) + "\n")
    print(out_dir / "samples.json")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    import tempfile

    from brdfpipe.rendering import scene

    check_not_input(args.out, [args.material, args.envmap])
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


def _cmd_capture(args: argparse.Namespace) -> int:
    from pathlib import Path

    from brdfpipe.rendering import capture

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: --out must be a folder")
    image_keys, table_keys = capture.output_layout(1, args.n)
    inputs = [args.material, args.directions] + ([args.model] if args.model else [])
    names = [f"n{n}-{j}-{kind}.exr" for _, n, j in image_keys for kind in ("render", "sensor")]
    names += [f"n{n}-{src}.npz" for _, n in table_keys for src in ("noiseless", "sensor")]
    names += [f"n{n}.binary" for _, n in table_keys] if args.model else []
    for name in names:
        check_not_input(out / name, inputs)
    sensor = capture.Sensor(enabled=not args.no_noise, full_well=args.full_well, read_noise=args.read_noise,
                            bits=args.bits, peak_level=args.peak_level, brackets=tuple(args.brackets))
    capture.capture_to_files(
        material=args.material, directions=[args.directions], n_images=args.n,
        renders=[out / f"n{n}-{j}-render.exr" for _, n, j in image_keys],
        photographs=[out / f"n{n}-{j}-sensor.exr" for _, n, j in image_keys],
        noiseless=[out / f"n{n}-noiseless.npz" for _, n in table_keys],
        observations=[out / f"n{n}-sensor.npz" for _, n in table_keys],
        spp=args.spp, seed=args.seed, light_distance=args.light_distance, min_snr=args.min_snr,
        sensor=sensor, variant=args.variant,
    )
    if args.model:
        from brdfpipe.acquisition import reconstruct

        for _, n in table_keys:
            reconstruct.write_reconstruction(args.model, out / f"n{n}-sensor.npz", out / f"n{n}.binary", eta=args.eta)
    print(out)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``brdfpipe`` command."""
    parser = argparse.ArgumentParser(prog="brdfpipe", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"brdfpipe {full_version()}")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("synth", help="generate a synthetic MERL-format database")
    p.add_argument("--count", type=_positive_int, required=True, help="number of materials")
    p.add_argument("--seed", type=int, required=True, help="seed of every random choice")
    p.add_argument("--out", required=True, help="output folder (<name>.binary + manifest.json): new, "
                   "empty, or an earlier output of the same synth command")
    p.add_argument("--noise", type=_non_negative_float, default=0.01,
                   help="relative measurement noise (default 0.01)")
    p.add_argument("--jobs", type=_positive_int, default=os.cpu_count() or 1,
                   help="worker processes (default: all cores)")
    p.set_defaults(func=_cmd_synth)

    p = sub.add_parser("ingest", help="ingest MERL files into the chunked Zarr store")
    p.add_argument("folder", help="folder of .binary files: real MERL, or written by "
                   "`brdfpipe synth` (recognised by the files' synthetic watermark)")
    p.add_argument("--out", required=True, help="the store to write (e.g. results/merl.zarr)")
    p.add_argument("--jobs", type=_positive_int, default=os.cpu_count() or 1,
                   help="worker processes (default: all cores)")
    p.set_defaults(func=_cmd_ingest)

    p = sub.add_parser("interpolate", help="write the BRDF at a point of a GPLVM latent space")
    p.add_argument("--model", required=True, help="a fit written by the workflow (results/gplvm/q5.npz)")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--at", type=_latent_point, help="latent point x1,…,xq")
    where.add_argument("--between", nargs=2, metavar=("A", "B"), help="two materials of the model")
    p.add_argument("--t", type=float, default=0.5, help="fraction of the way from A to B (default 0.5)")
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
    p.add_argument("--seed", type=int, required=True, help="seed of every random choice")
    p.add_argument("--count", type=_positive_int, required=True, help="number of materials")
    p.add_argument("--max-tries", type=_positive_int, default=None,
                   help="most candidates drawn (default max(1000, 100 × count))")
    p.add_argument("--exact", action="store_true",
                   help="albedo of the clamped interpolated table (slow) instead of w·A in linear spaces")
    p.add_argument("--out-dir", required=True,
                   help="folder for sample-NNN.binary, samples.json and samples.csv (created if needed)")
    p.set_defaults(func=_cmd_sample)

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
    p.add_argument("--seed", type=int, default=0)
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
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--light-distance", type=_light_distance, default=20.0,
                   help="point light distance in units of the camera's (default 20; inf = distant light)")
    p.add_argument("--min-snr", type=float, default=3.0, help="mask pixels below this SNR (default 3)")
    p.add_argument("--no-noise", action="store_true", help="no sensor: the noiseless render is the photograph")
    p.add_argument("--full-well", type=_positive_float, default=20000.0, help="electrons at saturation")
    p.add_argument("--read-noise", type=float, default=5.0, help="electrons RMS per exposure")
    p.add_argument("--bits", type=_positive_int, default=12, help="ADC bits")
    p.add_argument("--peak-level", type=_positive_float, default=0.8,
                   help="brightest disk pixel of the shortest exposure / full well")
    p.add_argument("--brackets", type=float, nargs="+", default=[1.0, 8.0, 64.0],
                   help="relative exposure times (HDR bracketing; default 1 8 64)")
    p.add_argument("--variant", default="llvm_ad_rgb", help="llvm_ad_rgb (CPU, default) or cuda_ad_rgb (GPU)")
    p.set_defaults(func=_cmd_capture)
    return parser


def _render_errors() -> tuple[type[Exception], ...]:
    """The rendering track's error classes (their modules import Mitsuba lazily)."""
    from brdfpipe.rendering.render import RenderError
    from brdfpipe.rendering.scene import SceneError

    return (RenderError, SceneError)


def _os_error_message(err: OSError, out: str | None) -> str:
    """One line for an OS error: the path involved and what went wrong."""
    if is_out_of_space(err):
        where = err.filename or out
        return f"no space left on device writing {where}" if where else "no space left on device"
    what = err.strerror or str(err) or type(err).__name__
    if err.filename is not None and err.filename2 is not None:
        return f"{err.filename} -> {err.filename2}: {what}"
    if err.filename is not None:
        return f"{err.filename}: {what}"
    return f"{what} (output {out})" if out else what


def _memory_error_message(args: argparse.Namespace) -> str:
    if args.command == "render":
        w, h = args.resolution
        return (
            f"the render is too large for memory ({w}×{h} pixels × {args.spp} samples per pixel); "
            "lower --resolution or --spp"
        )
    return "out of memory; nothing was written (an earlier output is kept)"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0 on success; 1 with one line ``brdfpipe CMD: error: ...`` on stderr for
    bad input, a refused output path, an OS error (the path is named; a full
    disk says "no space left on device writing PATH") or a MemoryError; 130
    after an interrupt.  Argument errors exit 2 (argparse).
    """
    args = build_parser().parse_args(argv)
    setup_console_logging(logging.WARNING if args.quiet else logging.INFO)
    prefix = f"brdfpipe {args.command}: error:"
    out = getattr(args, "out", None)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print(f"{prefix} interrupted; nothing was written / earlier output kept "
              "(outputs are replaced only when complete)", file=sys.stderr)
        return 130
    except MemoryError:
        print(f"{prefix} {_memory_error_message(args)}", file=sys.stderr)
        return 1
    except OSError as err:
        print(f"{prefix} {_os_error_message(err, out)}", file=sys.stderr)
        return 1
    except (ValueError, *_render_errors()) as err:
        # MerlFormatError, DatabaseError, OutputError and store errors are
        # ValueErrors whose message names the file and the problem.
        print(f"{prefix} {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
