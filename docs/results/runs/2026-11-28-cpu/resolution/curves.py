"""The grid study's table and curve from the runs kept here (docs/results/resolution-merl-nbrdf.md).

    python curves.py    (reads grid<G>[-seed<S>]/{errors.csv, closedloop.csv, directions/, benchmarks/}, rescore.csv
                         and lattice.csv; writes each run's fig08-fov25.csv, cost.csv, resolution.csv,
                         lattice-summary.csv here and ../../../resolution-merl-nbrdf.png next to the page)

A folder grid<G> is the run at acquisition.seed 2016 (the default), grid<G>-seed<S> the same grid with seed S.
The quantities per run: the held-out error (table lookup, rms_log of the held-out mean, near-field min E(S) sets
of 1 and 2 images at every FOV), the closed-loop gap (closed loop over table lookup - 1, noiseless and with the
sensor) and the one-shot optimum at 25 degrees (Xu Fig. 8's table, split all: theta_h, the light's incidence and
E(S)).  Per grid the mean over the seeds is compared with the finest grid's mean (RULES); the seeds' range says
how far one optimisation's outcome moves without any change of grid.
"""

import csv
import re
import statistics
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from brdfpipe.acquisition import figures  # noqa: E402
from brdfpipe.core import integrity  # noqa: E402

HERE = Path(__file__).resolve().parent
DEFAULT_SEED = 2016
RUNS = {(int(m[1]), int(m[2] or DEFAULT_SEED)): p for p in sorted(HERE.iterdir())
        if p.is_dir() and (m := re.fullmatch(r"grid(\d+)(?:-seed(\d+))?", p.name))}
GRIDS = sorted({g for g, _ in RUNS})
SEEDS = sorted({s for _, s in RUNS}, key=lambda s: (s != DEFAULT_SEED, s))
FOVS = (15, 25, 35, 45)
SIZES = (1, 2)
#: "within 2 % of the finest": errors and E(S) relative, the gap (itself a relative difference) in points,
#: the one-shot direction's angles in degrees.  one_shot_es is E(S) on the run's own lattice (every pixel a row
#: against a fixed eta: it falls with the pixel count by construction); one_shot_es_common is the same direction
#: scored on the finest grid's lattice (rescore.csv, written by rescore.py), which compares the directions alone.
RULES = {"heldout_error": ("relative", 0.02), "gap_noiseless": ("points", 0.02), "gap_sensor": ("points", 0.02),
         "one_shot_es": ("relative", 0.02), "one_shot_es_common": ("relative", 0.02),
         "one_shot_theta_h": ("degrees", 2.0), "one_shot_incidence": ("degrees", 2.0)}


def _means(path: Path) -> dict[tuple[int, int, str], float]:
    """(fov, n, kind) -> the held-out mean over all channels, near-field sets of the error metric."""
    _, rows = integrity.read_csv_rows(path, required=("setup", "fov", "n", "material", "channel", "kind", "value"))
    return {(int(float(r["fov"])), int(r["n"]), r["kind"]): float(r["value"]) for r in rows
            if r["setup"] == "nearfield" and r["material"] == "mean" and r["channel"] == "all"
            and r["split"] == "train" and r["metric"] == "error"}


def one_shot(folder: Path) -> dict[str, float]:
    """The optimal single image at 25 degrees (split all) as Xu Fig. 8's table states it; writes the table there."""
    with tempfile.TemporaryDirectory() as tmp:
        stem = Path(tmp) / "fig08"
        figures.fig08_optimal_configurations([folder / "directions/all/nearfield-fov25-error.json"], stem,
                                             fovs=[25], n_images=(1,))
        text = stem.with_name("fig08.csv").read_text(encoding="utf-8")
    (folder / "fig08-fov25.csv").write_text(text, encoding="utf-8")
    _, rows = integrity.read_csv_rows(folder / "fig08-fov25.csv")
    (row,) = rows
    return {"theta_h": float(row["theta_h_deg"]), "incidence": float(row["light_theta_deg"]),
            "es": float(row["expected_error"])}


def rescored() -> dict[tuple[int, int], float]:
    """(grid, seed) -> E(S) of the run's optimal single image scored on the finest grid's lattice (rescore.csv)."""
    with open(HERE / "rescore.csv", encoding="utf-8") as fh:  # this study's own file (plain csv, no digest)
        rows = list(csv.DictReader(fh))
    return {(int(r["grid"]), int(r["seed"])): float(r["expected_error"]) for r in rows
            if int(r["scored_at_grid"]) == max(GRIDS)}


def measure(folder: Path) -> dict[tuple[str, int, int], float]:
    """(quantity, fov, n) -> value of one run (without one_shot_es_common: see main)."""
    table, loop = _means(folder / "errors.csv"), _means(folder / "closedloop.csv")
    out = {}
    for fov in FOVS:
        for n in SIZES:
            t = table[(fov, n, "rms_log")]
            assert abs(loop[(fov, n, "rms_log")] - t) <= 1e-9 * t, (folder, fov, n)  # the same sets, the same lookup
            out[("heldout_error", fov, n)] = t
            out[("gap_noiseless", fov, n)] = loop[(fov, n, "closedloop_noiseless_rms_log")] / t - 1
            out[("gap_sensor", fov, n)] = loop[(fov, n, "closedloop_rms_log")] / t - 1
    out.update({(f"one_shot_{k}", 25, 1): v for k, v in one_shot(folder).items()})
    return out


def change(q: str, value: float, finest: float) -> tuple[float, bool]:
    how, tol = RULES[q]
    d = value / finest - 1 if how == "relative" else value - finest
    return d, abs(d) <= tol


def summarise(values: dict[tuple[int, int], dict[tuple[str, int, int], float]]) -> list[dict[str, object]]:
    """Per grid and quantity: each seed's value, their mean, range, and the mean's change against the finest's."""
    finest = max(GRIDS)
    keys = sorted(next(iter(values.values())))
    rows = []
    for key in keys:
        mean = {g: statistics.fmean(values[(g, s)][key] for s in SEEDS if (g, s) in values) for g in GRIDS}
        for g in GRIDS:
            per_seed = {s: values[(g, s)][key] for s in SEEDS if (g, s) in values}
            d, ok = change(key[0], mean[g], mean[finest])
            rows.append({"grid": g, "quantity": key[0], "fov": key[1], "n": key[2], "seeds": per_seed,
                         "mean": mean[g], "low": min(per_seed.values()), "high": max(per_seed.values()),
                         "change": d, "within": ok})
    return rows


def plot(rows: list[dict[str, object]], path: Path) -> None:
    def pick(q: str, fov: int, n: int) -> list[dict[str, object]]:
        return [next(r for r in rows if r["grid"] == g and r["quantity"] == q and r["fov"] == fov and r["n"] == n)
                for g in GRIDS]

    def band(ax, sel, scale, style, colour, label, marker="o"):  # noqa: ANN001, ANN202
        x = [g * (1 + 0.02 * (FOVS.index(sel[0]["fov"]) - 1.5)) for g in GRIDS]  # spread FOVs apart a little
        y = [scale * float(r["mean"]) for r in sel]
        err = [[scale * (float(r["mean"]) - float(r["low"])) for r in sel],
               [scale * (float(r["high"]) - float(r["mean"])) for r in sel]]
        ax.errorbar(x, y, yerr=err, fmt=style, marker=marker, color=colour, label=label, capsize=2, lw=1.2, ms=4)

    fig, axes = plt.subplots(1, 4, figsize=(18, 4.6), layout="constrained")
    colours = dict(zip(FOVS, ("tab:blue", "tab:orange", "tab:green", "tab:red")))
    for ax, q, scale, title, ylabel in (
        (axes[0], "heldout_error", 1.0, "held-out error (table lookup)", "mean RMS log error, 10 held-out materials"),
        (axes[1], "gap_noiseless", 100.0, "closed-loop gap, noiseless", "closed loop / table lookup − 1 (%)"),
        (axes[2], "gap_sensor", 100.0, "closed-loop gap, with the sensor", "closed loop / table lookup − 1 (%)"),
    ):
        for fov in FOVS:
            for n, style in ((1, "--"), (2, "-")):
                band(ax, pick(q, fov, n), scale, style, colours[fov], f"{fov}°, {n} image{'s' if n > 1 else ''}",
                     "o" if n == 2 else "s")
        if q != "heldout_error":
            ax.axhline(0, color="grey", lw=0.8)
        ax.set_title(title)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7, ncol=2)
    ax = axes[3]
    band(ax, pick("one_shot_es", 25, 1), 1.0, "-", "black", "E(S) on its own lattice")
    band(ax, pick("one_shot_es_common", 25, 1), 1.0, "-", "tab:grey", f"E(S) on the {max(GRIDS)}-px lattice", "D")
    ax.set_ylabel("E(S) of the optimal single image")
    ax.set_title("one-shot optimum at 25° (split all)")
    twin = ax.twinx()
    band(twin, pick("one_shot_theta_h", 25, 1), 1.0, "--", "tab:purple", "θh", "s")
    band(twin, pick("one_shot_incidence", 25, 1), 1.0, "--", "tab:brown", "incidence", "^")
    twin.set_ylabel("angle (degrees)")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = twin.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="center right")
    for a in axes:
        a.set_xscale("log", base=2)
        a.set_xticks(GRIDS, [str(g) for g in GRIDS])
        a.set_xlabel("pixels per image side (acquisition.grid)")
        a.grid(alpha=0.3)
    fig.suptitle(f"merl-nbrdf: near-field results against the image lattice; mean of the optimiser seeds "
                 f"{', '.join(map(str, SEEDS))}, bars: their range (2-core machine, 2026-11-28)")
    fig.savefig(path, dpi=100, metadata={"Software": None})


def costs() -> None:
    """cost.csv: per run and rule, the jobs' summed wall and CPU seconds and the largest peak RSS (benchmark files)."""
    out = []
    for (g, seed), folder in sorted(RUNS.items()):
        for rule in ("optimize_directions", "capture_closedloop", "evaluate_directions", "evaluate_closedloop"):
            files = sorted((folder / "benchmarks").glob(f"{rule}/**/*.tsv")) or [folder / f"benchmarks/{rule}.tsv"]
            stats = []
            for f in files:
                with open(f, encoding="utf-8") as fh:
                    stats.append(list(csv.DictReader(fh, delimiter="\t"))[-1])
            out.append([g, seed, rule, len(stats), f"{sum(float(r['s']) for r in stats):.1f}",
                        f"{sum(float(r['cpu_time']) for r in stats):.1f}", f"{max(float(r['max_rss']) for r in stats):.0f}"])
    with open(HERE / "cost.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["grid", "seed", "rule", "jobs", "wall_s", "cpu_s", "max_rss_mb"])
        w.writerows(out)


def lattice_summary() -> None:
    """lattice-summary.csv: the same direction sets looked up on each lattice (lattice.csv, written by lattice.py).

    Per lattice, FOV and n: over the runs' sets (every grid and seed), the mean, least and largest change of the
    held-out error against the same set looked up on the finest lattice, with eta = 40 and with the scaled eta.
    """
    with open(HERE / "lattice.csv", encoding="utf-8") as fh:  # this study's own file (plain csv, no digest)
        rows = list(csv.DictReader(fh))
    finest = max(GRIDS)
    val = {(int(r["grid"]), int(r["seed"]), int(r["looked_up_at_grid"]), int(r["fov"]), int(r["n"])):
           (float(r["heldout_error"]), float(r["heldout_error_eta_scaled"])) for r in rows}
    out = []
    for at in GRIDS:
        for fov in FOVS:
            for n in SIZES:
                ch = [[val[(g, s, at, fov, n)][i] / val[(g, s, finest, fov, n)][i] - 1 for (g, s) in RUNS]
                      for i in (0, 1)]
                out.append([at, fov, n, len(RUNS), *(f"{f(c):+.4f}" for c in ch for f in (statistics.fmean, min, max))])
    with open(HERE / "lattice-summary.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["looked_up_at_grid", "fov", "n", "sets", "change_mean", "change_min", "change_max",
                    "eta_scaled_change_mean", "eta_scaled_change_min", "eta_scaled_change_max"])
        w.writerows(out)


def main() -> None:
    costs()
    lattice_summary()
    common = rescored()
    values = {run: measure(folder) for run, folder in RUNS.items()}
    for run in values:
        values[run][("one_shot_es_common", 25, 1)] = common[run]
    rows = summarise(values)
    with open(HERE / "resolution.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["grid", "quantity", "fov", "n", *(f"seed{s}" for s in SEEDS), "mean", "low", "high",
                    "change_of_mean_vs_finest", "within_rule"])
        for r in rows:
            seeds = r["seeds"]
            w.writerow([r["grid"], r["quantity"], r["fov"], r["n"],
                        *(f"{seeds[s]:.6g}" if s in seeds else "" for s in SEEDS),  # type: ignore[operator]
                        *(f"{float(r[k]):.6g}" for k in ("mean", "low", "high")),
                        f"{float(r['change']):+.4f}", int(bool(r["within"]))])
    plot(rows, HERE.parents[2] / "resolution-merl-nbrdf.png")
    for q in RULES:
        ok = [g for g in GRIDS if all(r["within"] for r in rows if r["grid"] == g and r["quantity"] == q)]
        first = next((g for g in GRIDS if all(h in ok for h in GRIDS if h >= g)), None)
        print(f"{q}: within the rule at {ok}; smallest grid from which every finer one is too: {first}")


if __name__ == "__main__":
    main()
