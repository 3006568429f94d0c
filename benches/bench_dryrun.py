"""How long `snakemake -n` takes on the tiny config, and how much of it is the workflow's own imports.

Prints, best of ``--rounds`` (each in a fresh process, a scratch working
directory, nothing built yet):

* ``snakemake --version``: Snakemake's own start-up (the baseline);
* ``snakemake -n`` on ``tests/config/tiny.yaml``: the whole dry run;
* importing the modules the workflow's Snakefile imports at parse time
  (``brdfpipe.data.database`` and ``brdfpipe.core``'s ``plan``, ``filenames``,
  ``stamps``, ``version``), measured
  inside one fresh interpreter;

with the cluster issue's targets (dry run ≤ 1.5 s, own imports ≤ 0.2 s) and
the ratios.  Every cluster job re-parses the Snakefile, so this is paid per
job.

``--label-files N`` (default 100) also times the folder labeller
(:func:`brdfpipe.data.database.database_from_folder`, run at parse time for
``merl_dir``) on folders of N files of each kind — unmarked (real MERL),
``derived``, ``synthetic`` and old-watermark synthetic — against the labeller
before provenance marks (list, check each name, read the 64-byte watermark),
measured in the same run (the same function with the mark read replaced by
the watermark read).  The files are sparse (only the header and the
mark's rows are written), so the page cache is warm; ``--cold`` writes whole
35 MB files and evicts them (``posix_fadvise(DONTNEED)``, these files only)
before every round.  Prints; never fails a build.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
IMPORTS = "brdfpipe.data.database, brdfpipe.plan, brdfpipe.core.filenames, brdfpipe.core.stamps, brdfpipe.core.version"


def wall(cmd: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - t0


def import_time() -> float:
    code = f"import time; t0 = time.perf_counter(); import {IMPORTS}; print(time.perf_counter() - t0)"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(out.stdout.strip())


def _write_folder(folder: Path, n: int, kind: str, full: bool) -> list[Path]:
    """n MERL-format files of one kind (sparse unless ``full``): header, the mark's rows, the watermark."""
    import numpy as np

    from brdfpipe.data import merl, provenance

    folder.mkdir(parents=True)
    lo = int(provenance.MARK_CELLS[0]) - int(provenance.MARK_CELLS[0]) % merl.N_PHI_D  # first cell of the first row
    hi = int(provenance.WATERMARK_CELLS[-1]) + 1
    files = []
    for i in range(n):
        raw = np.full((3, merl.N_CELLS), -1.0)
        name = f"material-{i:03d}"
        if kind == "derived":
            provenance.stamp(raw, provenance.derived_mark(
                name=name, operation="sample", source_database="synthetic",
                inputs={"model": {"sha256": "0" * 64, "space": "standardised", "q": 5, "materials": 100},
                        "store": {"database": "synthetic", "materials": 100, "rows_sha256": "1" * 64},
                        "latent": [0.123456789] * 5, "weights_sha256": "2" * 64, "seed": 1, "count": n, "index": i}))
        elif kind == "synthetic":
            provenance.stamp(raw, provenance.synthetic_mark(name=name, count=n, seed=1, noise=0.01, family="metal",
                                                            index=i, material_seed=12345))
        elif kind == "legacy":
            raw[:, provenance.WATERMARK_CELLS] = provenance.WATERMARK_RAW
        path = folder / f"{name}.binary"
        with open(path, "wb") as fh:
            fh.write(np.asarray(merl.DIMS, dtype="<i4").tobytes())
            if full:
                fh.write(raw.astype("<f8").tobytes())
                fh.flush()
                os.fsync(fh.fileno())  # clean pages: posix_fadvise(DONTNEED) can evict them
            else:
                fh.truncate(merl.FILE_SIZE)
                for c in range(3):
                    fh.seek(merl.HEADER_BYTES + 8 * (c * merl.N_CELLS + lo))
                    fh.write(raw[c, lo:hi].astype("<f8").tobytes())
        files.append(path)
    return files


def _old_labeller(folder: Path) -> str:
    """database_from_folder with the mark read replaced by the 64-byte watermark read of the labeller before marks."""
    from unittest import mock

    from brdfpipe.data import database, provenance, synth

    def watermark_only(path: Path, *, name: str) -> provenance.Mark | None:
        return provenance.Mark("synthetic", legacy=True) if synth.is_synthetic_file(path) else None

    with mock.patch.object(provenance, "check_source", watermark_only):
        return database.database_from_folder(folder).kind


def _best(fn: Callable[[], object], rounds: int, evict: list[Path] | None) -> float:
    best = float("inf")
    for _ in range(rounds):
        for f in evict or []:
            fd = os.open(f, os.O_RDONLY)
            try:
                os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
            finally:
                os.close(fd)
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def label_bench(n: int, rounds: int, cold: bool) -> None:
    """Time the folder labeller on n files of each kind, against the labeller before marks."""
    from brdfpipe.data import database

    print(f"folder labeller, {n} files per folder ({'cold: whole files, evicted' if cold else 'warm, sparse files'}), "
          f"best of {rounds}:")
    with tempfile.TemporaryDirectory(prefix="bench-label-") as tmp:
        for kind in ("unmarked", "derived", "synthetic", "legacy"):
            folder = Path(tmp) / kind
            files = _write_folder(folder, n, kind, full=cold)
            label = database.database_from_folder(folder).kind
            new = _best(lambda: database.database_from_folder(folder), rounds, files if cold else None)
            old = _best(lambda: _old_labeller(folder), rounds, files if cold else None)
            print(f"  {kind:9s} -> {label:9s}: {new * 1e3:7.1f} ms ({new / n * 1e6:6.0f} µs/file); before marks "
                  f"{old * 1e3:7.1f} ms: {new / old:5.2f}x")
            if cold:
                for f in files:
                    f.unlink()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--label-files", type=int, default=100, help="files per folder of the labeller bench (0: skip)")
    ap.add_argument("--cold", action="store_true", help="labeller bench on whole files evicted from the page cache")
    ap.add_argument("--label-only", action="store_true", help="only the labeller bench")
    args = ap.parse_args()
    if args.label_files:
        label_bench(args.label_files, args.rounds, args.cold)
    if args.label_only:
        return 0
    with tempfile.TemporaryDirectory(prefix="bench-dryrun-") as tmp:
        work = Path(tmp)
        base = min(wall([str(SNAKEMAKE), "--version"], work) for _ in range(args.rounds))
        dry = min(
            wall([str(SNAKEMAKE), "--snakefile", str(ROOT / "workflow" / "Snakefile"), "--directory", str(work),
                  "--configfile", str(ROOT / "tests" / "config" / "tiny.yaml"), "-n", "--quiet", "all"], work)
            for _ in range(args.rounds)
        )
    imp = min(import_time() for _ in range(args.rounds))
    print(f"snakemake --version (start-up):   {base:6.2f} s")
    print(f"snakemake -n, tiny config:        {dry:6.2f} s   target 1.5 s: {dry / 1.5:5.2f}x of target")
    print(f"  workflow's own imports:         {imp:6.3f} s   target 0.2 s: {imp / 0.2:5.2f}x of target")
    print(f"  parse + DAG beyond start-up:    {dry - base:6.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
