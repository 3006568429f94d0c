"""The ``brdfpipe`` command line.

Subcommands::

    brdfpipe synth  --count N --seed S --out DIR [--noise X] [--jobs J]
    brdfpipe ingest DIR --out results/merl.zarr [--jobs J]
    brdfpipe info   results/merl.zarr
    brdfpipe interpolate --model results/gplvm/q5.npz (--at x1,…,xq | --between A B [--t 0.5]) --out F.binary
    brdfpipe reconstruct OBSERVATIONS --model results/svd/train.zarr --out FILE.binary [--eta η]
    brdfpipe render MATERIAL.binary --out IMAGE.exr [--spp N] [--resolution W H] [--variant V]

Every subcommand exits non-zero with one line ``brdfpipe CMD: error: ...``
naming the file and the problem on bad input or a failing environment (full
disk, unreadable file, out of memory), never a traceback; an interrupt
(Ctrl-C) exits 130.  No subcommand writes over one of its inputs
(:func:`brdfpipe.atomic.check_not_input`), and every output is written
atomically, so an error or interrupt leaves an earlier output as it was.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Sequence

from brdfpipe.atomic import check_not_input, is_out_of_space
from brdfpipe.logutil import setup_console_logging
from brdfpipe.version import full_version

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
    from brdfpipe import synth

    # synthesize() refuses an --out that holds anything it did not write itself
    # (synth.check_output_folder) before it writes a byte.
    manifest = synth.synthesize(
        args.out, count=args.count, seed=args.seed, noise=args.noise, jobs=args.jobs
    )
    print(manifest)
    return 0


def _cmd_ingest(args: argparse.Namespace) -> int:
    from brdfpipe import database, store

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
    from brdfpipe import store

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
    from brdfpipe import reconstruct

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
    from brdfpipe import gplvm

    check_not_input(args.out, [args.model, args.store])
    gplvm.interpolate_to_file(
        args.model, args.store, args.out,
        at=args.at, between=tuple(args.between) if args.between else None, t=args.t,
    )
    print(args.out)
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    import tempfile

    from brdfpipe import scene

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
    return parser


def _render_errors() -> tuple[type[Exception], ...]:
    """The rendering track's error classes (their modules import Mitsuba lazily)."""
    from brdfpipe.render import RenderError
    from brdfpipe.scene import SceneError

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
