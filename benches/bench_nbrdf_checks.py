#!/usr/bin/env python
"""The statistics behind the plausibility thresholds of NBRDF tables, and the parse-time check's cost (issue 31).

For every fit of the shipped archives (merl-nbrdf, rgl-nbrdf, nielsen-nbrdf), evaluated on the MERL
grid (:func:`brdfpipe.data.nbrdf.fit_table`): the share of its values clamped at 0, the smallest and
the largest channel of its directional albedo at normal incidence, and the interval bound of its
network output (:func:`brdfpipe.data.nbrdf.output_bounds`); min / median / max per database, with
the fit at each end.  :data:`brdfpipe.data.nbrdf.MAX_CLAMPED_SHARE` and
:data:`brdfpipe.data.nbrdf.MAX_ALBEDO` are chosen from these (docs/results/data.md).  Then the
cost of :func:`brdfpipe.data.nbrdf.check_archive` on each archive without its digest cache (best of
``--rounds``; h5py already imported): what a user's archive of that size costs the parse.

Usage::

    python benches/bench_nbrdf_checks.py [--rounds 3]

About 2 minutes on 2 cores (the 159 evaluations).  Exits 0: benches report, they do not gate CI.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from brdfpipe.data import databases, merl, nbrdf


def _row(label: str, values: list[float], names: list[str], fmt: str = ".4g") -> str:
    v = np.asarray(values)
    lo, hi = int(np.argmin(v)), int(np.argmax(v))
    return (f"  {label:<26} min {v[lo]:{fmt}} ({names[lo]})  median {np.median(v):{fmt}}  "
            f"max {v[hi]:{fmt}} ({names[hi]})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}, numpy {np.__version__}")
    shipped = [n for n, d in databases.DATABASES.items() if d.source == "archive"]
    for name in shipped:
        path = databases.shipped_archive(name)
        with nbrdf.open_archive(path) as archive:
            fits = list(archive)
        share, a_min, a_max, y_lo, y_hi = [], [], [], [], []
        for fit in fits:
            table = nbrdf.fit_table(fit)
            albedo = merl.directional_albedo(table.table, [0.0])[0]
            lo, hi = nbrdf.output_bounds(fit)
            share.append(table.clamped / (3 * table.measured_cells))
            a_min.append(albedo.min())
            a_max.append(albedo.max())
            y_lo.append(lo.min())
            y_hi.append(hi.max())
        names = [f.name for f in fits]
        best = float("inf")
        for _ in range(args.rounds):
            nbrdf._CHECKED.clear()
            t0 = time.perf_counter()
            nbrdf.check_archive(path)
            best = min(best, time.perf_counter() - t0)
        print(f"{name}: {len(fits)} fits; check_archive {best:.3f} s ({best / len(fits) * 1e3:.1f} ms a fit)")
        print(_row("clamped share", share, names))
        print(_row("albedo(0), darkest channel", a_min, names))
        print(_row("albedo(0), brightest ch.", a_max, names))
        print(_row("bound of y: lo (min ch.)", y_lo, names))
        print(_row("bound of y: hi (max ch.)", y_hi, names))


if __name__ == "__main__":
    main()
