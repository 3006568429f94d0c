#!/usr/bin/env python
"""Measure Zarr chunk codecs and chunk widths for the MERL store (``brdfpipe.data.store``).

What it measures
----------------
Each candidate compresses the float32 rows of a few synthetic-like BRDF tables
(physical units, unmeasured cells negative, exactly what ``brdfpipe.data.store``
writes), chunk by chunk, single-threaded (as Zarr and our ingest workers run
Blosc).  For each candidate it prints the compression ratio (raw / compressed
bytes over all tables) and the compress and decompress throughput in MB/s of
*uncompressed* float32 data (best of ``--repeat`` passes, since other work may
share the machine).  A second table varies the chunk width for the leading
codecs.

Candidates: Blosc zstd / lz4 / lz4hc × byte shuffle / bitshuffle × clevels,
plain zstd, plain lz4 and no compression.

Tables come from ``brdfpipe.data.synth.synthesize`` (the synthetic database
generator, default 1 % noise).  The source is printed with the results.

Usage::

    python benches/bench_codecs.py [--tables 4] [--repeat 3] [--data DIR]

``--data DIR`` uses the ``*.binary`` files in DIR instead (the first
``--tables`` of them, sorted by name).  Exits 0; this is a report, not a test.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

import zarr.codecs  # noqa: F401  (sets numcodecs.blosc.use_threads = False, as in Zarr)
from numcodecs import LZ4, Blosc, Zstd
from numcodecs.abc import Codec

from _common import best_time  # benches/ is on sys.path
from brdfpipe.data import merl

N_COLS = 3 * merl.N_CELLS


# ---------------------------------------------------------------------------
# Test tables
# ---------------------------------------------------------------------------


def make_database(out_dir: str, count: int, seed: int = 0) -> tuple[list[str], str]:
    """Write ``count`` synthetic materials into ``out_dir``; returns (paths, description)."""
    from brdfpipe.data import synth

    synth.synthesize(out_dir, count=count, seed=seed, jobs=os.cpu_count() or 1, progress=False)
    paths = sorted(glob.glob(os.path.join(out_dir, "*.binary")))
    return paths[:count], f"brdfpipe.data.synth.synthesize(count={count}, seed={seed})"


def load_rows(paths: Sequence[str]) -> list[NDArray[np.float32]]:
    """The float32 store rows of the given MERL files."""
    return [merl.read_merl(p).reshape(-1).astype(np.float32) for p in paths]


# ---------------------------------------------------------------------------
# Measurement
# ---------------------------------------------------------------------------


@dataclass
class Result:
    """One measured candidate."""

    name: str
    ratio: float
    compress_mbs: float
    decompress_mbs: float


def candidates() -> list[tuple[str, Codec | None]]:
    """The codec candidates, by printable name (``None`` = no compression)."""
    out: list[tuple[str, Codec | None]] = []
    levels = {"zstd": (1, 3, 5), "lz4": (1, 5, 9), "lz4hc": (1, 5)}
    for cname, lv in levels.items():
        for shuffle, sname in ((Blosc.SHUFFLE, "shuffle"), (Blosc.BITSHUFFLE, "bitshuffle")):
            for level in lv:
                out.append((f"blosc {cname}-{level} {sname}", Blosc(cname, level, shuffle)))
    out += [("zstd-1 (plain)", Zstd(1)), ("zstd-3 (plain)", Zstd(3)), ("lz4 (plain)", LZ4())]
    out.append(("none (a memcpy)", None))
    return out




def measure(
    name: str, codec: Codec | None, rows: Sequence[NDArray[np.float32]], width: int, repeat: int
) -> Result:
    """Compress every ``width``-column chunk of every row with ``codec``."""
    chunks = [row[j : j + width] for row in rows for j in range(0, row.size, width)]
    raw = sum(c.nbytes for c in chunks)
    if codec is None:
        t = best_time(lambda: [c.tobytes() for c in chunks], repeat)
        return Result(name, 1.0, raw / t / 1e6, raw / t / 1e6)
    encoded: list[bytes] = [codec.encode(c) for c in chunks]
    for c, e in zip(chunks[:3], encoded[:3]):  # sanity: lossless
        assert np.array_equal(np.frombuffer(codec.decode(e), np.float32), c)
    tc = best_time(lambda: [codec.encode(c) for c in chunks], repeat)
    td = best_time(lambda: [codec.decode(e) for e in encoded], repeat)
    return Result(name, raw / sum(len(e) for e in encoded), raw / tc / 1e6, raw / td / 1e6)


def print_table(title: str, results: Sequence[Result], key: str = "codec") -> None:
    """Print results as a fixed-width table."""
    print(f"\n{title}")
    print(f"{key:<28} {'ratio':>6} {'compress MB/s':>14} {'decompress MB/s':>16}")
    print("-" * 67)
    for r in results:
        print(f"{r.name:<28} {r.ratio:6.2f} {r.compress_mbs:14.0f} {r.decompress_mbs:16.0f}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurements and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tables", type=int, default=4, help="number of BRDF tables (default 4)")
    ap.add_argument("--repeat", type=int, default=3, help="timing repeats, best kept (default 3)")
    ap.add_argument("--width", type=int, default=145_800, help="chunk width for the codec table")
    ap.add_argument("--data", help="use the *.binary files in this folder")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="bench_codecs-") as tmp:
        if args.data:
            paths = sorted(glob.glob(os.path.join(args.data, "*.binary")))[: args.tables]
            source = f"{len(paths)} files from {args.data}"
        else:
            paths, source = make_database(tmp, args.tables)
        rows = load_rows(paths)
    mb = sum(r.nbytes for r in rows) / 1e6
    print(f"tables: {source}; {len(rows)} rows, {mb:.0f} MB float32")
    print(f"single-threaded Blosc; throughput = uncompressed MB/s, best of {args.repeat}")

    results = [measure(n, c, rows, args.width, args.repeat) for n, c in candidates()]
    print_table(f"codecs at chunk width {args.width} columns ({args.width * 4 / 1e3:.0f} kB raw)", results)

    widths = [16_200, 48_600, 145_800, 486_000, 1_458_000]
    lead = [
        ("blosc lz4-5 shuffle", Blosc("lz4", 5, Blosc.SHUFFLE)),
        ("blosc lz4-5 bitshuffle", Blosc("lz4", 5, Blosc.BITSHUFFLE)),
        ("blosc zstd-1 shuffle", Blosc("zstd", 1, Blosc.SHUFFLE)),
    ]
    for name, codec in lead:
        res = [measure(f"{w:>9,d} cols ({w * 4 / 1e3:6.0f} kB)", codec, rows, w, args.repeat) for w in widths]
        print_table(f"chunk widths with {name}", res, key="width")
    return 0


if __name__ == "__main__":
    sys.exit(main())
