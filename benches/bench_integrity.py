#!/usr/bin/env python
"""What verifying every intermediate costs, next to the stage that consumes it (issue 21).

Every intermediate carries a digest that its reader checks (:mod:`brdfpipe.core.integrity`).
This bench takes a finished workflow run and prints, per kind of intermediate, the
time its verification takes and the time of the job that reads it, and their ratio
``verification / (stage − verification)``, all measured in this run (target < 10 %,
as for the store in ``benches/bench_verify.py``, which covers the store itself).

What is measured
----------------
Verification (best of ``--rounds``, warm page cache):

* Zarr groups (log-map, PCA model): reading every file of the group and checking
  its CRC-32C (:meth:`brdfpipe.core.integrity.GroupDigests.verify` on a fresh handle);
* npz / JSON / EXR / CSV files: recomputing the digest from the decoded content
  (:func:`~brdfpipe.core.integrity.npz_digest`, :func:`~brdfpipe.core.integrity.json_digest`,
  :func:`~brdfpipe.core.integrity.exr_digest`, sha256 of the CSV body), summed over
  the files the stage reads (the decoding itself the stage needs anyway);
* the explorer page (with ``chromium``): the page's own time to check its four data
  files' CRC-32 (``explorer.verifyMs``) next to its time to be ready, for the run's
  page and for a synthetic page of the default run's size (``--explorer-n 100``
  pre-renders of 256 × 192, ``tests/explorer_fixture.py``).

Stages (best of ``--rounds``; each includes its own verification), run on the run's
files into a temporary folder:

=====================  ===========================================================
intermediate           consuming stage (rule)
=====================  ===========================================================
log-map X              ``svd.gram_partial`` over all columns (``accumulate_gram``)
Gram partials          ``svd.write_model`` (``decompose_svd``; partials made first)
PCA model, directions  ``evaluation.write_evaluation`` (``evaluate_directions``)
GPLVM Gram file        ``gplvm.fit_to_files`` q = 2 (``fit_gplvm``)
GPLVM models           ``analysis.path_points_to_files`` (``interpolate_path_points``)
pre-renders, refs      ``blend.error_maps_from_files`` (``error_maps``)
closed-loop tables     ``closedloop.write_closedloop`` (``evaluate_closedloop``)
CSV tables             ``claims.compute_claims`` (``write_claims``)
=====================  ===========================================================

Usage::

    python benches/bench_integrity.py [--run DIR] [--rounds 3] [--work DIR] [--explorer-n 100]

``--run``: the working folder of a finished run (holding ``results/``); default the
repository's own when ``results/merl.zarr`` exists there, else a tiny run
(``tests/config/tiny.yaml``, 12 materials, ~3 min) is made under ``--work``.
Exits 0 either way: benches report, they do not gate CI.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from _common import best_time  # noqa: E402  (benches/ is on sys.path)

ROOT = Path(__file__).resolve().parents[1]
TARGET = 0.10


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _tiny_run(work: Path) -> Path:
    run = work / "tiny-run"
    run.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    snakemake = Path(sys.executable).with_name("snakemake")
    cmd = [str(snakemake), "--snakefile", str(ROOT / "workflow" / "Snakefile"), "--directory", str(run),
           "--configfile", str(ROOT / "tests" / "config" / "tiny.yaml"), "--cores", str(os.cpu_count() or 1)]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=run, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"the tiny run failed:\n{(r.stdout + r.stderr)[-3000:]}")
    print(f"made a tiny run (tests/config/tiny.yaml) in {time.perf_counter() - t0:.0f} s: {run}")
    return run


# -- digest recomputation per container --------------------------------------------------------------


def _npz_cost(paths: list[Path], rounds: int) -> float:
    import numpy as np

    from brdfpipe.core import integrity

    loaded = []
    for p in paths:
        with np.load(p, allow_pickle=False) as z:
            loaded.append({k: z[k] for k in z.files if k != integrity.DIGEST_KEY})
    return best_time(lambda: [integrity.npz_digest(a) for a in loaded], rounds)


def _json_cost(paths: list[Path], rounds: int) -> float:
    from brdfpipe.core import integrity

    docs = [json.loads(p.read_text(encoding="utf-8")) for p in paths]
    return best_time(lambda: [integrity.json_digest(d) for d in docs], rounds)


def _exr_cost(paths: list[Path], rounds: int) -> float:
    import numpy as np
    import OpenEXR

    from brdfpipe.core import integrity

    loaded = []
    for p in paths:
        f = OpenEXR.File(str(p), separate_channels=True)
        attrs = {str(k): v for k, v in f.header().items() if isinstance(v, str)}
        loaded.append(({c: np.asarray(f.channels()[c].pixels) for c in "RGB"}, attrs))
    return best_time(lambda: [integrity.exr_digest(pl, at) for pl, at in loaded], rounds)


def _csv_cost(paths: list[Path], rounds: int) -> float:
    bodies = [p.read_bytes().partition(b"\n")[2] for p in paths]
    return best_time(lambda: [hashlib.sha256(b).hexdigest() for b in bodies], rounds)


def _group_cost(path: Path, rounds: int, *, prefix: str = "") -> tuple[float, int]:
    import zarr

    from brdfpipe.core import integrity

    attrs = dict(zarr.open_group(path, mode="r", zarr_format=3).attrs)

    def verify() -> None:
        d = integrity.open_group_digests(path, attrs)
        d.verify(d.names(prefix))

    d = integrity.open_group_digests(path, attrs)
    size = sum(d.files[n][1] for n in d.names(prefix))
    return best_time(verify, rounds), size


# -- the run's files ----------------------------------------------------------------------------------


def _default_candidate(results: Path) -> tuple[Path, int] | None:
    """(candidate folder, q) of the path points' model: the explorer's candidate (else the first), the q of
    the path points' weights."""
    weights = sorted(results.glob("renders/*/paths/*-weights.json"))
    if not weights:
        return None
    q = int(json.loads(weights[0].read_text())["q"])
    folders = [f for f in sorted((results / "gplvm").glob("*")) if (f / f"q{q}.npz").is_file()]
    manifest = results / "explorer" / "manifest.json"
    if manifest.is_file():
        from brdfpipe.manifold.fidelity import candidate_label

        doc = json.loads(manifest.read_text())
        label = candidate_label(doc["space"], float(doc["mu"]))
        folders = [f for f in folders if f.name == label] or folders
    return (folders[0], q) if folders else None


def _scene(results: Path) -> Path | None:
    for scene in sorted((results / "renders").glob("*")):
        if any(scene.glob("paths/*-weights.json")):
            return scene
    return None


def _explorer(args: argparse.Namespace, work: Path, site: Path | None,
              rows: list[tuple[str, str, float, float, str]]) -> None:
    """The explorer page's check of its data files (``explorer.verifyMs``) against its time to be ready:
    the run's page (``site``, when there is one) and a synthetic page of ``--explorer-n`` pre-renders."""
    try:
        from brdfpipe.explorer import chromium
        have = chromium.find_chromium() is not None
    except Exception:  # noqa: BLE001  (an optional part)
        have = False
    if not have:
        print("  explorer: no chromium, page verification not measured")
        return

    def page(folder: Path, label: str) -> None:
        best_v, best_ready = float("inf"), float("inf")
        for _ in range(args.rounds):
            with chromium.Browser() as b:
                b.open(folder / "index.html", ready="window.explorer && (window.explorer.ready || window.explorer.error)",
                       timeout=600)
                if b.evaluate("explorer.error"):
                    raise SystemExit(f"the explorer page failed: {b.evaluate('explorer.error')}")
                best_v = min(best_v, float(b.evaluate("explorer.verifyMs")) / 1e3)
                best_ready = min(best_ready, float(b.evaluate("performance.now()")) / 1e3)
        size = sum(p.stat().st_size for p in (folder / "data").glob("*.js"))
        rows.append((label, "page load to ready", best_v, best_ready, f"{size / 1e6:.1f} MB"))
        print(f"  {label:28s} verify {best_v * 1e3:9.2f} ms   {'page load to ready':22s} "
              f"{best_ready:8.2f} s   {100 * best_v / max(best_ready - best_v, 1e-9):6.2f} %  "
              f"{size / 1e6:.1f} MB (headless chromium, CRC-32 in JavaScript)", flush=True)

    if site is not None and site.is_dir():
        page(site, "explorer data (4 .js)")
    if args.explorer_n > 0:
        sys.path.insert(0, str(ROOT / "tests"))
        from explorer_fixture import make_inputs

        from brdfpipe.explorer import export

        inputs = make_inputs(work / "explorer-inputs", n=args.explorer_n, width=256, height=192, qs=(2,))
        export.write_explorer(out=work / "explorer", **inputs)
        page(work / "explorer", f"explorer, {args.explorer_n} x 256x192")


def _verdict(rows: list[tuple[str, str, float, float, str]]) -> None:
    worst = max(v / max(t - v, 1e-9) for _, _, v, t, _ in rows) if rows else 0.0
    verdict = "PASS" if worst < TARGET else "FAIL"
    print(f"{verdict}: verification adds at most {100 * worst:.2f} % to a consuming stage "
          f"(target < {100 * TARGET:.0f} %)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--run", type=Path, help="working folder of a finished run (holding results/)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--work", type=Path, help="folder for temporaries (default: a temporary one)")
    ap.add_argument("--explorer-only", action="store_true", help="only the synthetic explorer page (no run needed)")
    ap.add_argument("--explorer-n", type=int, default=100,
                    help="also a synthetic explorer of N pre-renders of 256 x 192, the default run's size "
                         "(tests/explorer_fixture.py; 0: skip)")
    args = ap.parse_args(argv)
    import logging

    logging.getLogger("brdfpipe").setLevel(logging.ERROR)  # the stages' own warnings are not the point here

    from brdfpipe.acquisition import closedloop, evaluation, svd
    from brdfpipe.core import integrity
    from brdfpipe.data import store
    from brdfpipe.manifold import analysis, gplvm
    from brdfpipe.rendering import blend
    from brdfpipe.report import claims

    work = Path(tempfile.mkdtemp(prefix="bench-integrity-", dir=args.work))
    try:
        if args.explorer_only:
            print(f"machine: {os.cpu_count()} cores, {_cpu_name()}; best of {args.rounds}")
            rows: list[tuple[str, str, float, float, str]] = []
            _explorer(args, work, None, rows)
            _verdict(rows)
            return 0
        run = args.run
        if run is None:
            run = ROOT if (ROOT / "results" / "merl.zarr").is_dir() else _tiny_run(work)
        results = run / "results"
        st = store.open_store(results / "merl.zarr")
        splits = integrity.read_json(results / "splits.json")
        print(f"run {run}: {st.n_materials} materials ({st.database}), {len(splits['test'])} held out")
        print(f"machine: {os.cpu_count()} cores, {_cpu_name()}; python {sys.version.split()[0]}; "
              f"best of {args.rounds}, warm page cache")
        rows = []  # intermediate, stage, verify, stage, note

        def measure(what: str, stage_name: str, verify_s: float, stage: Callable[[], Any], note: str = "") -> None:
            t = best_time(stage, args.rounds)
            rows.append((what, stage_name, verify_s, t, note))
            print(f"  {what:28s} verify {verify_s * 1e3:9.2f} ms   {stage_name:22s} {t:8.2f} s   "
                  f"{100 * verify_s / max(t - verify_s, 1e-9):6.2f} %  {note}", flush=True)

        # log-map X -> accumulate_gram (all columns in one block)
        lm_path = results / "logmap" / "all.zarr"
        if lm_path.is_dir():
            from brdfpipe.data import logmap

            v, size = _group_cost(lm_path, args.rounds, prefix="X/")
            measure("log-map all.zarr (X)", "accumulate_gram", v,
                    lambda: svd.gram_partial(logmap.open_logmap(lm_path), 0, 1), f"{size / 1e6:.0f} MB of X")
            parts = [work / f"gram-{i}-of-4.npz" for i in range(1, 5)]
            for i, p in enumerate(parts):
                svd.write_partial(p, logmap_path=lm_path, block=i, n_blocks=4)
            measure("Gram partials (4 npz)", "decompose_svd", _npz_cost(parts, args.rounds),
                    lambda: svd.write_model(lm_path, parts, work / "model.zarr"))

        # PCA model + directions -> evaluate_directions
        model = results / "svd" / "train.zarr"
        dirs = sorted((results / "directions" / "train").glob("*.json"))
        if model.is_dir() and dirs:
            v, size = _group_cost(model, args.rounds)
            evaluate = lambda: evaluation.write_evaluation(  # noqa: E731
                results / "merl.zarr", model, dirs, work / "errors.csv", test_materials=splits["test"])
            measure("PCA model train.zarr", "evaluate_directions", v, evaluate, f"{size / 1e6:.0f} MB")
            measure(f"directions ({len(dirs)} JSON)", "evaluate_directions", _json_cost(dirs, args.rounds), evaluate)

        # GPLVM Gram file -> fit_gplvm; models -> interpolate_path_points
        found = _default_candidate(results)
        if found is not None:
            cand, q = found
            space = cand.name.split("-mu")[0]
            gram = results / "gplvm" / f"gram-{space}.npz"
            measure(f"Gram file {gram.name}", "fit_gplvm (q = 2)", _npz_cost([gram], args.rounds),
                    lambda: gplvm.fit_to_files(gram, work / "q2.npz", work / "q2-trace.csv", q=2, seed=7,
                                               max_sweeps=100))
            weights = sorted(results.glob("renders/*/paths/*-weights.json"))
            docs = [json.loads(w.read_text()) for w in weights]
            points = [(d["material_a"], d["material_b"], float(d["t"])) for d in docs]
            measure(f"GPLVM model {cand.name}/q{q}.npz", "interpolate_path_points",
                    _npz_cost([cand / f"q{q}.npz"], args.rounds),
                    lambda: analysis.path_points_to_files(
                        model=cand / f"q{q}.npz", store=results / "merl.zarr", points=points,
                        merl_outs=[work / f"p{k}.binary" for k in range(len(points))],
                        weights_outs=[work / f"p{k}.json" for k in range(len(points))]))

        # pre-renders, references, weights -> error_maps
        scene = _scene(results)
        if scene is not None:
            names = list(st.materials)
            pre = {m: scene / "materials" / f"{m}.exr" for m in names}
            one = {m: scene / "materials-one" / f"{m}.exr" for m in names}
            weights = sorted(scene.glob("paths/*-weights.json"))
            stems = [str(w)[: -len("-weights.json")] for w in weights]
            refs = {k: [Path(s + suffix) for s in stems]
                    for k, suffix in (("image", ".exr"), ("noise", "-noise.exr"), ("one", "-one.exr"),
                                      ("one_noise", "-one-noise.exr"))}
            exrs = [*pre.values(), *one.values(), *(p for v in refs.values() for p in v)]
            out = work / "maps"
            v = _exr_cost(exrs, args.rounds) + _json_cost(weights, args.rounds)
            measure(f"EXRs ({len(exrs)}) + weights", "error_maps", v, lambda: blend.error_maps_from_files(
                prerenders=pre, weights=weights, references=refs["image"], references_noise=refs["noise"],
                blended=[out / f"b{k}.exr" for k in range(len(stems))],
                error_exrs=[out / f"e{k}.exr" for k in range(len(stems))],
                error_pngs=[out / f"e{k}.png" for k in range(len(stems))], summary=out / "summary.csv",
                database=st.database, prerenders_one=one, references_one=refs["one"],
                references_one_noise=refs["one_noise"]), f"{sum(p.stat().st_size for p in exrs) / 1e6:.1f} MB")

        # closed-loop tables -> evaluate_closedloop
        tables = sorted((results / "closedloop").glob("*/*-sensor.npz"))
        if tables and model.is_dir():
            pat = re.compile(r"(?P<set>.+)-n(?P<n>\d+)-sensor\.npz$")
            materials = sorted({t.parent.name for t in tables})
            sets = sorted({pat.match(t.name)["set"] for t in tables})  # type: ignore[index]
            ns = sorted({int(pat.match(t.name)["n"]) for t in tables})  # type: ignore[index]
            directions = [results / "directions" / "train" / f"{s}.json" for s in sets]
            keys = closedloop.table_layout(materials, len(sets), ns)
            noiseless = [results / "closedloop" / m / f"{sets[d]}-n{n}-noiseless.npz" for m, d, n in keys]
            sensor = [results / "closedloop" / m / f"{sets[d]}-n{n}-sensor.npz" for m, d, n in keys]
            measure(f"closed-loop tables ({2 * len(keys)})", "evaluate_closedloop",
                    _npz_cost(noiseless + sensor, args.rounds),
                    lambda: closedloop.write_closedloop(results / "merl.zarr", model, directions, noiseless, sensor,
                                                        work / "closedloop.csv", materials=materials, n_images=ns))

        # CSV tables -> write_claims
        def opt(p: Path) -> Path | None:
            return p if p.is_file() else None

        traces = {int(p.stem[1:].split("-")[0]): p for p in (found[0].glob("q*-trace.csv") if found else [])}
        inputs = claims.ClaimInputs(
            errors=opt(results / "evaluation" / "errors.csv"),
            training_size=opt(results / "evaluation" / "training_size.csv"),
            fig08_table=opt(results / "figures" / "fig08-optimal-configurations.csv"),
            reproduction=opt(results / "manifold" / "reproduction.csv"),
            spaces=opt(results / "manifold" / "spaces.csv"), paths=opt(results / "manifold" / "paths.csv"),
            traces=traces, bounce_shares=next(iter(results.glob("renders/*/bounce-shares.csv")), None),
            errormap_summary=opt(scene.parent.parent / "errormaps" / scene.name / "summary.csv") if scene else None,
            floor_check=next(iter(results.glob("errormaps/*/floor-check.csv")), None),
            closedloop=opt(results / "evaluation" / "closedloop.csv"))
        csvs = [Path(p) for p in (*vars(inputs).values(), *traces.values()) if isinstance(p, (str, Path))]
        measure(f"CSV tables ({len(csvs)})", "write_claims", _csv_cost(csvs, args.rounds),
                lambda: claims.compute_claims(inputs), f"{sum(p.stat().st_size for p in csvs) / 1e3:.0f} kB")

        _explorer(args, work, results / "explorer", rows)

        _verdict(rows)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
