"""The report's front page: what ran, the claims table, versions, configuration, wall time per stage.

Two files, so that every file a run writes under ``results/`` except one
is the same from run to run: ``front.rst`` (rule ``write_claims``: what
ran, the database from ``splits.json``, the claims, the versions and the
configuration) and ``stage-times.csv``/``.rst`` (rule
``summarize_stage_times``: the jobs' ``benchmark:`` files summed per rule
and track; wall times differ between runs by nature).  The static front
page ``workflow/report/workflow.rst`` includes both.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import platform
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from brdfpipe.core import atomic, version
from brdfpipe.report import rst
from brdfpipe.report.claims import Claim, RunClaims, claims_table_rst, rst_cell, verdict_counts

__all__ = [
    "TRACKS",
    "track_of",
    "versions",
    "StageTime",
    "read_benchmarks",
    "stage_times",
    "write_stage_times",
    "front_rst",
    "write_front",
]

#: Rules of each track, for the wall-time table (rules not listed: "other").
TRACKS: dict[str, tuple[str, ...]] = {
    "data": ("synthesize_material", "write_manifest", "ingest_material", "assemble_store", "write_splits"),
    "acquisition (Xu 2016)": ("map_logrelative", "accumulate_gram", "decompose_svd", "optimize_directions",
                              "evaluate_directions", "check_directions", "evaluate_training_size",
                              "evaluate_paper_directions",
                              "plot_acquisition_figures", "reconstruct_figure_material", "plot_reconstruction_figures"),
    "manifold (Soler 2018)": ("compute_gram", "fit_gplvm", "measure_material_albedos", "analyze_manifold", "measure_gplvm_candidate",
                              "compare_spaces", "measure_lengthscales", "plot_manifold_figures"),
    "rendering": ("make_envmap", "prerender_materials", "interpolate_path_points", "render_path_points",
                  "sample_latent_materials", "render_latent_samples",
                  "render_object_mask", "bounce_shares", "error_maps", "plot_render_figures", "render_reconstructions",
                  "interpolate_candidate_path_points", "render_candidate_path_points", "measure_candidate_blends",
                  "summarize_floor_check", "plot_floor_check"),
    "unseen materials": ("evaluate_unseen_fits", "capture_unseen_closedloop", "evaluate_unseen", "locate_unseen",
                         "plot_unseen_errors", "plot_unseen_latent"),
}
_PACKAGES = ("snakemake", "numpy", "scipy", "zarr", "matplotlib", "mitsuba", "drjit")


def track_of(rule: str) -> str:
    for track, rules in TRACKS.items():
        if rule in rules:
            return track
    return "other"


def versions() -> dict[str, str]:
    """brdfpipe (release + code digest), Python, and the packages the workflow runs on."""
    out = {"brdfpipe": version.full_version(), "python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


@dataclass(frozen=True)
class StageTime:
    """The jobs of one rule: count, summed and longest wall time (s), peak RSS (MB), summed CPU time (s)."""

    track: str
    rule: str
    jobs: int
    wall_s: float
    max_wall_s: float
    max_rss_mb: float
    cpu_s: float


def read_benchmarks(folder: str | os.PathLike[str]) -> dict[str, list[dict[str, float]]]:
    """Every Snakemake benchmark TSV under ``folder`` (``<rule>.tsv`` or ``<rule>/…tsv``), by rule.

    ValueError naming the file for a TSV without the ``s`` column or with a
    value that is not a number.
    """
    root = Path(folder)
    out: dict[str, list[dict[str, float]]] = {}
    for f in sorted(root.rglob("*.tsv")):
        rel = f.relative_to(root)
        rule = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        with open(f, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
        if not rows or "s" not in rows[0]:
            raise ValueError(f"{f}: not a Snakemake benchmark file (no 's' column)")
        for r in rows:  # one row per repeat
            rec = {}
            for c in ("s", "max_rss", "cpu_time"):
                text = (r.get(c) or "").strip()
                try:
                    rec[c] = float(text) if text not in ("", "NA", "-") else math.nan
                except ValueError:
                    raise ValueError(f"{f}: column {c!r} is not a number: {text!r}") from None
            out.setdefault(rule, []).append(rec)
    return out


def stage_times(bench: Mapping[str, Sequence[Mapping[str, float]]]) -> list[StageTime]:
    """One :class:`StageTime` per rule, ordered by track (:data:`TRACKS`) then rule."""
    order = {r: (i, j) for i, rules in enumerate(TRACKS.values()) for j, r in enumerate(rules)}

    def fsum(vals: Sequence[float]) -> float:
        return float(sum(v for v in vals if math.isfinite(v)))

    def fmax(vals: Sequence[float]) -> float:
        v = [x for x in vals if math.isfinite(x)]
        return max(v) if v else math.nan

    out = [StageTime(track_of(rule), rule, len(rows), fsum([r["s"] for r in rows]), fmax([r["s"] for r in rows]),
                     fmax([r["max_rss"] for r in rows]), fsum([r["cpu_time"] for r in rows]))
           for rule, rows in bench.items()]
    return sorted(out, key=lambda s: (order.get(s.rule, (len(TRACKS), 0)), s.rule))


def _stage_rst(stages: Sequence[StageTime]) -> str:
    if not stages:
        return "No benchmark files were found (``benchmarks/``).\n"
    lines = ["Summed over each rule's jobs from their ``benchmark:`` files (``benchmarks/``); jobs run in "
             "parallel, so the sums exceed the run's wall time. Rules without a benchmark (the light local "
             "rules) are not listed.", "",
             ".. list-table::", "   :header-rows: 1", "",
             "   * - track", "     - rule", "     - jobs", "     - wall time, sum (s)", "     - longest job (s)",
             "     - peak RSS (MB)", "     - CPU time (s)"]
    for s in stages:
        lines += [f"   * - {rst_cell(s.track)}", f"     - {rst_cell(s.rule)}", f"     - {s.jobs}",
                  f"     - {s.wall_s:.1f}", f"     - {s.max_wall_s:.1f}", f"     - {s.max_rss_mb:.0f}",
                  f"     - {s.cpu_s:.1f}"]
    totals: dict[str, list[StageTime]] = {}
    for s in stages:
        totals.setdefault(s.track, []).append(s)
    lines += ["", "Per track: " + "; ".join(
        f"{rst_cell(t)} {sum(x.wall_s for x in v):.1f} s over {sum(x.jobs for x in v)} jobs" for t, v in totals.items())
        + f"; all {sum(s.wall_s for s in stages):.1f} s over {sum(s.jobs for s in stages)} jobs."]
    return "\n".join(lines) + "\n"


def write_stage_times(benchmarks: str | os.PathLike[str], *, csv_path: str | os.PathLike[str],
                      rst_path: str | os.PathLike[str]) -> list[StageTime]:
    """``stage-times.csv`` (one row per rule) and its rst table, from the benchmark folder."""
    stages = stage_times(read_benchmarks(benchmarks))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["track", "rule", "jobs", "wall_s", "max_wall_s", "max_rss_mb", "cpu_s"])
    for s in stages:
        w.writerow([s.track, s.rule, s.jobs, f"{s.wall_s:.3f}", f"{s.max_wall_s:.3f}", f"{s.max_rss_mb:.2f}",
                    f"{s.cpu_s:.3f}"])
    atomic.write_text(csv_path, buf.getvalue())
    atomic.write_text(rst_path, _stage_rst(stages))
    return stages


def _literal(text: str) -> list[str]:
    return ["::", ""] + ["   " + line for line in text.rstrip("\n").splitlines()] + [""]


def _database_note(database: str) -> str:
    """The front page's sentence on what a database label means (nothing for measured MERL data)."""
    if database == "merl":
        return ""
    if database.endswith("nbrdf"):
        return (" These are tables evaluated from published neural fits of measured materials (NBRDF, "
                "Sztrajman et al. 2021): smooth approximations of the measurements, as accurate as the fits, "
                "not the measurements themselves.")
    if database == "synthetic":
        return " This is the generated synthetic MERL-format database, not real MERL data."
    if database == "derived":
        return (" These are materials derived by brdfpipe (interpolated, sampled, extrapolated or reconstructed; "
                "see each file's provenance mark), not measurements.")
    return " These are not measured MERL data."


def front_rst(*, claims: Sequence[Claim], splits: Mapping[str, Any], config: Mapping[str, Any],
              configfiles: Sequence[str], targets: Mapping[str, int], versions: Mapping[str, str],
              recorded: Sequence[RunClaims] = ()) -> str:
    """The front page body (reStructuredText): what ran, the claims, versions, the configuration.

    The claims table shows the ``recorded`` runs (other databases, config
    ``report.compare_with``) beside this run's.
    """
    database = str(splits["database"])
    title = str(splits.get("database_title") or database)
    counts = verdict_counts([c.row() for c in claims])
    ours = sum(c.ours for c in claims)
    lines = ["What ran", "--------", "",
             f"Database: **{rst.text(title)}** (label ``{rst.text(database)}``; "
             f"{len(splits['materials'])} materials: {len(splits['train'])} training, "
             f"{len(splits['test'])} held out: {rst_cell(', '.join(splits['test']))}), as recorded in "
             "``results/splits.json`` from the store." +
             _database_note(database),
             "",
             "Configuration file(s): " + (", ".join(rst.literal(c) for c in configfiles) or "none")
             + " (validated contents below).",
             "", "Targets of rule ``all`` (files):", ""]
    lines += [f"- {rst_cell(k)}: {v}" for k, v in targets.items()]
    lines += ["", "Claims", "------", "",
              "Each claim of the two papers as the paper states it (its sentence, the tolerance its wording "
              "implies), computed from this run's CSVs: "
              + ", ".join(f"{n} {rst_cell(v)}" for v, n in counts.items())
              + f" (``results/report/claims.csv``); then {ours} check(s) of our own that the papers do not make. "
              "A verdict's cause gives the measurement behind it. The figure captions repeat the claims next to "
              "their figures."
              + (" Beside this run's column, the same claims as measured by recorded runs on other databases "
                 "(config ``report.compare_with``)." if recorded else ""), "",
              claims_table_rst(claims, recorded), "",
              "Versions", "--------", "",
              ".. list-table::", "   :header-rows: 1", "", "   * - package", "     - version"]
    for k, v in versions.items():
        lines += [f"   * - {rst_cell(k)}", f"     - {rst_cell(v)}"]
    lines += ["", "Configuration", "-------------", ""]
    # a literal block: ASCII JSON has no line break, control or separator character inside a string, so no
    # config value can end the block (every line stays indented) and nothing in it is markup
    lines += _literal(json.dumps(config, indent=2, sort_keys=True, default=str, ensure_ascii=True))
    return "\n".join(lines) + "\n"


def write_front(path: str | os.PathLike[str], **kwargs: Any) -> None:
    """:func:`front_rst` written atomically to ``path``."""
    atomic.write_text(path, front_rst(**kwargs))
