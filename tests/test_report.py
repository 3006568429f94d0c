"""The report: the claims' files and table, captions, front page, stage times.

Each claim's verdicts (reproduces, within the stated tolerance, differs)
from small hand-made CSVs are tests/test_claims.py's.  :func:`check_tiny_report` builds the Snakemake
report of the tiny run (called by ``test_tiny_run_builds_a_valid_store`` in
test_workflow.py, so the tiny run is not repeated) and opens the archive.
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
import re
import subprocess
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import pytest

from brdfpipe import plan
from brdfpipe.core import filenames, integrity
from brdfpipe.plan import report as items
from brdfpipe.report import captions, claims, runinfo, sidebyside
from brdfpipe.registry import tables


def write_csv(path: Path, columns: Sequence[str], rows: Sequence[Mapping[str, object]]) -> Path:
    """A table as the workflow writes it: with its digest line (brdfpipe.core.integrity)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow(r)
    integrity.write_csv(path, buf.getvalue())
    return path


ERR_COLS = ("database", "split", "setup", "fov", "metric", "n", "material", "channel", "kind", "value")


def errors_csv(path: Path, values: Mapping[tuple[str, float, str, int], float], database: str = "synthetic") -> Path:
    rows = []
    for (setup, fov, metric, n), v in values.items():
        base = {"database": database, "split": "train", "setup": setup, "fov": fov, "metric": metric, "n": n}
        rows.append({**base, "material": "mean", "channel": "all", "kind": "rms_log", "value": v})
        # per-material rows and other kinds must not enter the means
        rows.append({**base, "material": "m1", "channel": "R", "kind": "rms_log", "value": 99.0})
        rows.append({**base, "material": "mean", "channel": "all", "kind": "relrms_linear", "value": 99.0})
    return write_csv(path, ERR_COLS, rows)


# The numbers of docs/results/acquisition.md (default synthetic run; once in the README), and the previous work's.
README = {
    ("point", 0.0, "error", 5): 0.278, ("point", 0.0, "condition", 5): 0.337,
    ("point", 0.0, "error", 10): 0.206, ("point", 0.0, "condition", 10): 0.26,
    ("point", 0.0, "error", 20): 0.171, ("point", 0.0, "condition", 20): 0.186,
    ("point", 0.0, "error", 1): 0.776, ("point", 0.0, "condition", 1): 0.776,
    ("nearfield", 25.0, "error", 1): 0.321, ("nearfield", 25.0, "error", 2): 0.250,
    ("nearfield", 25.0, "condition", 1): 0.899, ("nearfield", 25.0, "condition", 2): 0.687,
    ("nearfield", 45.0, "error", 1): 0.260, ("nearfield", 45.0, "error", 2): 0.158,
    ("nearfield", 45.0, "condition", 1): 0.7, ("nearfield", 45.0, "condition", 2): 0.6,
    ("fixed_camera", 25.0, "error", 2): 0.246,
    # the previous work (Nielsen 2015's κ as released)
    ("point", 0.0, "condition_nielsen", 5): 0.35, ("point", 0.0, "condition_nielsen", 20): 0.24,
}


def by_key(found: Sequence[claims.Claim]) -> dict[str, claims.Claim]:
    return {c.key: c for c in found}


def test_bad_input_names_the_file_and_two_databases_are_refused(tmp_path: Path) -> None:
    bad = write_csv(tmp_path / "errors.csv", ERR_COLS[:-1], [])
    with pytest.raises(claims.ClaimsInputError, match=r"errors\.csv: missing column\(s\) value"):
        claims.read_errors(bad)
    with pytest.raises(claims.ClaimsInputError, match="nothing.csv: no such file"):
        claims.read_errors(tmp_path / "nothing.csv")
    text = errors_csv(tmp_path / "t.csv", {("point", 0.0, "error", 1): 0.5})
    edited = text.read_text().replace("0.5", "zero", 1)
    text.write_text(edited)  # an edit by hand: refused, naming the file and what to rerun
    with pytest.raises(claims.ClaimsInputError, match=r"t\.csv: its content does not match its recorded digest "
                                                      r"\(damaged or edited\)"):
        claims.read_errors(text)
    integrity.write_csv(text, edited.split("\n", 1)[1])  # the same table, sealed: its value is checked
    with pytest.raises(claims.ClaimsInputError, match=r"t\.csv: line 3: column 'value' is not a number"):
        claims.read_errors(text)
    e = errors_csv(tmp_path / "e.csv", README, database="synthetic")
    b = write_csv(tmp_path / "b.csv", ("database", "material", "share_object"),
                  [{"database": "merl", "material": "a", "share_object": 0.05}])
    with pytest.raises(claims.ClaimsInputError, match="different databases"):
        claims.compute_claims(claims.ClaimInputs(errors=e, bounce_shares=b))


def test_claims_files_and_rst_render_through_jinja_and_docutils(tmp_path: Path) -> None:
    jinja2 = pytest.importorskip("jinja2")
    docutils_core = pytest.importorskip("docutils.core")
    found = claims.compute_claims(claims.ClaimInputs(errors=errors_csv(tmp_path / "e.csv", README)))
    keys = [c.key for c in found]
    assert len(keys) == len(set(keys)) and "xu-1-image-vs-previous-work-5" in keys
    out = {k: tmp_path / f"claims.{k}" for k in ("csv", "json", "rst")}
    claims.write_claims(found, csv_path=out["csv"], json_path=out["json"], rst_path=out["rst"])
    rows = claims.read_claims(out["csv"])
    assert [r["key"] for r in rows] == keys
    assert list(rows[0]) == list(claims.CLAIM_COLUMNS)
    row = next(r for r in rows if r["key"] == "xu-1-image-vs-previous-work-5")  # 0.321 vs the previous work's 0.35
    assert row["verdict"] == claims.REPRODUCES and float(row["value"]) == pytest.approx(0.321 / 0.35, rel=1e-8)
    row = next(r for r in rows if r["key"] == "xu-2-images-vs-previous-work-20")  # 0.25 vs 0.24: within 1.1×
    assert row["verdict"] == claims.WITHIN and "1.1×" in row["claim"] and row["sentence"].startswith('"Note that')
    assert json.loads(out["json"].read_text())[0]["figures"]
    # a claims.csv of the yes/no schema before issue 32 is refused as superseded, naming the file
    old = write_csv(tmp_path / "old.csv", ("key", "paper", "where", "claim", "paper_value", "measured", "value",
                                          "holds", "database", "source"),
                    [{"key": "k", "paper": "Xu 2016", "holds": "yes", "database": "merl-nbrdf"}])
    with pytest.raises(claims.ClaimsInputError, match=r"old\.csv: claims of the yes/no schema before issue 32 .*"
                                                      r"superseded by the four verdicts"):
        claims.read_claims(old)

    def publish(text: str) -> str:  # what Snakemake does with a caption: Jinja2, then docutils
        rendered = jinja2.Environment().from_string(text).render(snakemake=None)
        return docutils_core.publish_parts(rendered, writer_name="html",
                                           settings_overrides={"halt_level": 2, "report_level": 5})["body"]

    page = publish(out["rst"].read_text())
    ours = sum(c.ours for c in found)
    assert page.count("<tr>") == len(found) + 2 and "differs" in page  # two tables, one header row each
    assert page.count("<table") == 2 and "Our own checks (not claims of the papers)" in page and ours == 2
    cap = captions.caption_rst("xu-fig06", found, database="synthetic",
                               files=["results/figures/fig06-fov-vs-point.png"])
    body = publish(cap)
    assert "Xu Fig. 6" in body and "synthetic" in body and "reproduces within the stated tolerance" in body
    assert "0.321" in body and "similar accuracy as about 5 samples" in body
    assert "fig06-fov-vs-point.pdf" in body
    for key in captions.DESCRIPTIONS:  # every caption is valid rst (halt_level 2: no warning)
        assert items.FIGURE_NUMBERS[key] in publish(captions.caption_rst(
            key, found, database="synthetic", files=["results/errormaps/p/a--b-t0.5-error.png"]))
    # measured text that looks like a template is kept as text
    weird = claims.Claim("k", "Xu 2016", "§1", "p", "{{ x }} {% if %}", "m", 1.0, claims.REPRODUCES, "c", "synthetic",
                         "s", ("xu-fig05",))
    assert "{{ x }} {% if %}" in publish(captions.caption_rst("xu-fig05", [weird], database="synthetic"))


def test_report_items_cover_every_planned_figure() -> None:
    import yaml

    cfg = yaml.safe_load((Path(__file__).parent / "config" / "tiny.yaml").read_text())
    acq, man = plan.acquisition_figures(cfg["acquisition"]), plan.manifold_figures(cfg["manifold"])
    ren = plan.render_figures(3, 11)
    floor = filenames.figure_files(filenames.FLOOR_CHECK_STEM)
    pts = [("a--b", "0.5", filenames.errormap("preview", "a--b", "0.5", "error.png"))]
    its = items.report_items(database="synthetic", acquisition_figures=acq, manifold_figures=man,
                             render_figures=ren, floor_figure=floor, spaces_table=filenames.spaces_csv(),
                             errormaps=pts, errormap_summary=filenames.errormap_summary("preview"),
                             floor_check_table=filenames.floor_check_csv("x"))
    paths = [it.path for it in its]
    pngs = [f for figs in (acq, man, ren) for files in figs.values() for f in files if f.endswith(".png")]
    assert set(pngs + [floor[0], pts[0][2]]) <= set(paths) and len(paths) == len(set(paths))
    assert {it.category for it in its} == {items.ACQUISITION, items.MANIFOLD, items.RENDERING, items.CLAIMS}
    assert all(it.labels["database"] == "synthetic" and it.labels["figure"] for it in its)
    assert all(it.key in captions.DESCRIPTIONS for it in its)
    emap = next(it for it in its if it.path == pts[0][2])
    assert emap.labels["path"] == "a--b" and emap.labels["t"] == "0.5" and emap.subcategory == "Error maps"


def test_stage_times_sum_the_benchmark_files(tmp_path: Path) -> None:
    head = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
    (tmp_path / "fit_gplvm" / "c").mkdir(parents=True)
    (tmp_path / "fit_gplvm" / "c" / "q2.tsv").write_text(head + "1.5\t0:00:01\t100\t0\t0\t0\t0\t0\t0\t1.0\n")
    (tmp_path / "fit_gplvm" / "c" / "q5.tsv").write_text(head + "2.5\t0:00:02\t150\t0\t0\t0\t0\t0\t0\t2.0\n")
    (tmp_path / "evaluate_directions.tsv").write_text(head + "4.0\t0:00:04\tNA\t0\t0\t0\t0\t0\t0\t3.5\n")
    stages = runinfo.write_stage_times(tmp_path, csv_path=tmp_path / "st.csv", rst_path=tmp_path / "st.rst")
    by = {s.rule: s for s in stages}
    assert [s.rule for s in stages] == ["evaluate_directions", "fit_gplvm"]  # track order: acquisition, manifold
    assert by["fit_gplvm"].jobs == 2 and by["fit_gplvm"].wall_s == 4.0 and by["fit_gplvm"].max_wall_s == 2.5
    assert by["fit_gplvm"].max_rss_mb == 150 and math.isnan(by["evaluate_directions"].max_rss_mb)
    assert "all 8.0 s over 3 jobs" in (tmp_path / "st.rst").read_text()
    (tmp_path / "broken.tsv").write_text("x\ty\n1\t2\n")
    with pytest.raises(ValueError, match="broken.tsv: not a Snakemake benchmark file"):
        runinfo.read_benchmarks(tmp_path)


# -- the report of the tiny run ------------------------------------------------------


def _js_value(page: str, name: str) -> object:
    """The JSON value of ``var <name> = …`` in the report's HTML page."""
    m = re.search(rf"var {name} = (?=[\[{{\"])", page)
    assert m, f"no data 'var {name}' in the report page"
    return json.JSONDecoder().raw_decode(page[m.end():])[0]


def _text(fragment: str) -> str:
    """HTML as plain text (tags dropped, entities decoded, whitespace collapsed)."""
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", fragment)).split())


def check_tiny_report(workdir: Path, snakemake: Callable[..., subprocess.CompletedProcess]) -> None:
    """Build ``results/report.zip`` of a finished tiny run in ``workdir`` and check what it holds.

    Every figure, table and error map the workflow declares for the report
    is in the archive with its labels and its caption (the caption's claims
    with this run's numbers); the front page has the claims table, whose
    numbers are the claims CSV's, the versions and the stage times; two
    claims are recomputed here from the run's own CSVs.
    """
    import yaml

    results = workdir / "results"
    r = snakemake(workdir, "--report", "results/report.zip")
    assert r.returncode == 0, r.stderr[-4000:]
    assert "ERROR/" not in r.stderr, r.stderr[-4000:]  # docutils complains on stderr without failing
    with zipfile.ZipFile(results / "report.zip") as z:
        names = z.namelist()
        page = z.read("report/report.html").decode("utf-8")
    stored = {Path(n).name for n in names if n.startswith("report/data/raw/")}
    entries = _js_value(page, "results")
    front = _text(str(_js_value(page, "workflow_desc")))
    # what the workflow declares (as rules/report_common.smk plans it)
    cfg = yaml.safe_load((Path(__file__).parent / "config" / "tiny.yaml").read_text())
    emaps = sorted(p.name for p in (results / "errormaps" / "preview").glob("*-error.png"))
    declared = items.report_items(
        database="synthetic",
        acquisition_figures={**plan.acquisition_figures(cfg["acquisition"]),
                             **plan.reconstruction_figures(cfg["acquisition"])},
        manifold_figures=plan.manifold_figures(cfg["manifold"]),
        render_figures=plan.render_figures(len(emaps), 11),  # Soler Fig. 1's 11 latent samples (the default)
        floor_figure=filenames.figure_files(filenames.FLOOR_CHECK_STEM), spaces_table=filenames.spaces_csv(),
        errormaps=[(n.split("-t")[0], "0.5", f"{filenames.RESULTS}/errormaps/preview/{n}") for n in emaps],
        errormap_summary=filenames.errormap_summary("preview"),
        floor_check_table=filenames.floor_check_csv("preview-16x12-64spp"),
        closedloop_figure=filenames.figure_files(filenames.CLOSEDLOOP_STEM),
        closedloop_table=filenames.closedloop_errors())
    pngs = [it for it in declared if it.path.endswith(".png")]
    assert len(emaps) == 3 and len(pngs) == 27 + 3  # 27 figures (the closed loop's included), 3 error maps
    assert set(entries) == {it.path for it in declared}, set(entries) ^ {it.path for it in declared}
    rows = claims.read_claims(results / "report" / "claims.csv")
    figs_of = {c["key"]: c["figures"] for c in json.loads((results / "report" / "claims.json").read_text())}
    for it in declared:
        e = entries[it.path]
        assert Path(it.path).name in stored, it.path
        assert e["labels"] == it.labels, (it.path, e["labels"])
        cap = _text(e["caption"])
        assert cap.startswith(f"{items.FIGURE_NUMBERS[it.key]} analogue — database: synthetic"), (it.path, cap)
        for row in rows:  # each claim of this entry, with this run's numbers and verdict
            if it.key in figs_of[row["key"]]:
                assert " ".join(row["measured"].split()) in cap, (it.path, row["key"])
    # the front page: the claims table with the CSV's numbers, versions, stage times
    assert rows and {r["database"] for r in rows if r["verdict"] != claims.NOT_CHECKABLE} == {"synthetic"}
    assert {r["verdict"] for r in rows} <= set(claims.VERDICTS)
    for row in rows:
        assert " ".join(row["measured"].split()) in front, row["key"]
    for needle in ("Claims", "Versions", "Wall time per stage", "Database: synthetic", "0.1.0+src."):
        assert needle in front, needle
    # the verdict counts of the papers' claims head the table (our own checks apart); beside this run's column, the
    # recorded run of the other database brdfpipe ships (config report.compare_with: null; its own one left out)
    counts = claims.verdict_counts(rows)
    assert ", ".join(f"{n} {v}" for v, n in counts.items()) in front and sum(counts.values()) == 28
    assert "Our own checks (not claims of the papers)" in front
    assert "merl-nbrdf (recorded run)" in front and "synthetic (recorded run)" not in front
    # the run's fidelity page: this run's verdict and cause per claim, from its own claims.csv
    page = (results / "report" / "fidelity.md").read_text()
    header = next(line for line in page.splitlines() if line.startswith("| paper |"))
    assert header.endswith("| synthetic: verdict — cause | merl-nbrdf: verdict — cause |")
    for row in rows:
        mark = f"**{row['verdict']}**" if row["verdict"] == claims.DIFFERS else row["verdict"]  # a difference stands out
        assert f"{mark} — " in page and " ".join(row["cause"].split()).replace("|", "\\|") in page, row["key"]
    n_bench = len(list((workdir / "benchmarks").rglob("*.tsv")))
    assert f"over {n_bench} jobs." in front
    # two claims recomputed from the run's CSVs, independently of brdfpipe.report
    with open(results / "evaluation" / "errors.csv", newline="") as fh:
        assert next(fh).startswith(integrity.CSV_PREFIX)  # what a csv user skips: the digest line
        mean = {(float(r["fov"]), r["metric"], r["n"]): float(r["value"]) for r in csv.DictReader(fh)
                if r["split"] == "train" and r["material"] == "mean" and r["kind"] == "rms_log"
                and r["setup"] == "nearfield"}
    row = next(r for r in rows if r["key"] == "xu-eq15-vs-kappa-nearfield")
    ratios = [mean[(f, "condition", n)] / mean[(f, "error", n)] for f, _, n in mean if (f, "error", n) in mean
              and (f, "condition", n) in mean]
    want, median = min(ratios), sorted(ratios)[len(ratios) // 2] if len(ratios) % 2 else sum(
        sorted(ratios)[len(ratios) // 2 - 1:len(ratios) // 2 + 1]) / 2
    assert float(row["value"]) == pytest.approx(want, rel=1e-8)
    assert row["verdict"] == (claims.REPRODUCES if median >= 1.25 and want > 1 else
                              claims.WITHIN if median >= 1.25 and want >= 1 / 1.1 else claims.DIFFERS)
    with open(results / "errormaps" / "preview" / "summary.csv", newline="") as fh:
        next(fh)  # the digest line
        points = [(float(r["ratio_isolated_seed2"]), float(r["ratio_isolated_seed2_se"])) for r in csv.DictReader(fh)]
    worst = max(points, key=lambda p: (p[0] - 1) / p[1])[0]  # the point farthest above the floor, in s.e.
    within = all(ratio - 1 <= claims.NOISE_SIGMAS * se for ratio, se in points)
    row = next(r for r in rows if r["key"] == "soler-blend-vs-noise-floor")
    assert float(row["value"]) == pytest.approx(worst, rel=1e-8)
    assert row["verdict"] == (claims.REPRODUCES if all(r <= 1 for r, _ in points) else
                              claims.WITHIN if within else claims.DIFFERS)


def test_header_only_csvs_give_not_measured_claims(tmp_path: Path) -> None:
    """A configuration whose tables are empty (no path, no curve point) says "not checkable here", never fails."""
    def empty(name: str, cols: Sequence[str]) -> Path:
        return write_csv(tmp_path / name, cols, [])

    found = claims.compute_claims(claims.ClaimInputs(
        errors=empty("errors.csv", ERR_COLS),
        training_size=empty("ts.csv", ("database", "n_train", "order_seed", "material", "channel", "kind", "value")),
        fig08_table=empty("f8.csv", tables.FIG08),
        reproduction=empty("rep.csv", ("database", "space", "material", "method", "k", "relative_error")),
        spaces=empty("sp.csv", tables.SPACES),
        paths=empty("pa.csv", ("database", "path", "t", "perceptual_a", "perceptual_b", "perceptual_ab",
                               "deviation", "bound")),
        bounce_shares=empty("bs.csv", ("database", "material", "share_object")),
        errormap_summary=empty("su.csv", tables.ERROR_MAP_SUMMARY),
    ))
    assert found and {c.verdict for c in found} == {claims.NOT_CHECKABLE}
    assert all(c.cause.startswith(("not measured by this run", "needs ")) for c in found)


def test_closed_loop_claim_follows_the_numbers(tmp_path: Path) -> None:
    """Ours: reproduces when every set's noiseless closed loop is within 10 % of its table lookup; reports the sensor."""
    def table(noiseless: float, sensor: float, name: str) -> Path:
        rows = []
        for n, t in ((1, 0.30), (2, 0.25)):
            base = {"database": "synthetic", "split": "train", "setup": "nearfield", "fov": 25, "metric": "error",
                    "n": n, "material": "mean", "channel": "all"}
            rows += [{**base, "kind": "rms_log", "value": t},
                     {**base, "kind": "closedloop_noiseless_rms_log", "value": t * noiseless},
                     {**base, "kind": "closedloop_rms_log", "value": t * sensor},
                     {**base, "material": "m1", "channel": "R", "kind": "closedloop_noiseless_rms_log", "value": 9.0}]
        return write_csv(tmp_path / name, ERR_COLS, rows)

    good = claims.closed_loop_vs_table(table(1.05, 1.4, "good.csv"))
    assert good.verdict == claims.REPRODUCES and math.isclose(good.value, 0.05) and "+40.0%" in good.measured
    assert good.paper == claims.OURS  # the paper's claim is about real captures: not checkable here
    bad = claims.closed_loop_vs_table(table(0.85, 1.0, "bad.csv"))
    assert bad.verdict == claims.DIFFERS and math.isclose(bad.value, 0.15)
    empty = claims.closed_loop_vs_table(write_csv(tmp_path / "empty.csv", ERR_COLS, []))
    assert empty.verdict == claims.NOT_CHECKABLE
    found = by_key(claims.compute_claims(claims.ClaimInputs(closedloop=table(1.0, 1.0, "c.csv"))))
    assert found["ours-closed-loop"].verdict == claims.REPRODUCES and "xu-closedloop" in found["ours-closed-loop"].figures
    assert found["xu-real-captures"].verdict == claims.NOT_CHECKABLE and "real captures" in found["xu-real-captures"].cause
    assert by_key(claims.compute_claims(claims.ClaimInputs()))["ours-closed-loop"].verdict == claims.NOT_CHECKABLE
    its = items.report_items(database="synthetic", acquisition_figures={}, manifold_figures={}, render_figures={},
                             closedloop_figure=filenames.figure_files(filenames.CLOSEDLOOP_STEM),
                             closedloop_table=filenames.closedloop_errors())
    keys = {it.key: it for it in its}
    assert keys["xu-closedloop"].path.endswith(".png") and keys["xu-closedloop-table"].path.endswith(".csv")
    assert all(k in captions.DESCRIPTIONS for k in keys)


# -- hostile names ----------------------------------------------------------------------

#: Strings a config file name, a config value, a file name or a CSV cell could hold: markup, links,
#: directives, template code, control and layout characters.  Each must reach the page as plain text.
HOSTILE: tuple[str, ...] = (
    "x``\n\n.. raw:: html\n\n   <script>window.pwned=1</script>\n\n``y",
    ".. raw:: html\n\n   <script>window.pwned=2</script>",
    ".. include:: /etc/passwd",
    ".. image:: javascript:alert(3)",
    "`click <javascript:alert(4)>`_",
    "javascript:alert(5)",
    ":raw-html:`<script>window.pwned=6</script>`",
    "<script>window.pwned=7</script>",
    "{%endraw%}{{ 7 * 191 }}{% raw %}",
    "{%- endraw -%}{{ 7 * 193 }}",
    "|sub| name_ [1]_ *e* **s** ``l``",
    "a\u2028.. raw:: html\u2029   <script>window.pwned=8</script>",
    "- item\n#. item\n===\n+--+\n| line\n>>> x\n:: \\ tail\\",
    "nul\x00bell\x07del\x7f \u202eevil",
)


def _publish_like_snakemake(text: str, **overrides: object) -> str:
    """A caption or the front page as Snakemake 9 builds it: Jinja2 (its settings), then docutils' defaults.

    Docutils' defaults are Snakemake's: the ``raw`` and ``include`` directives are enabled.
    """
    jinja2 = pytest.importorskip("jinja2")
    docutils_core = pytest.importorskip("docutils.core")
    rendered = jinja2.Environment(trim_blocks=True, lstrip_blocks=True).from_string(text).render(snakemake=None)
    return docutils_core.publish_parts(rendered, writer_name="html",
                                       settings_overrides={"report_level": 5, **overrides})["html_body"]


def _assert_inert(page: str, hostile: Sequence[str]) -> None:
    """No element, link, script or included file came from ``hostile``; each is shown as its text."""
    for bad in ("<script", "javascript:alert(3)\"", "href=\"javascript", "src=\"javascript", "<img", "<object",
                "<iframe", "root:x:0:0", "1337", "1351", "pwned=1</script>", "system-message"):
        assert bad not in page, (bad, page[:3000])
    assert not re.search(r"<a [^>]*href=\"(?!#)", page), page  # no link at all (our text makes none)
    shown = _text(page)
    for h in hostile:
        visible = "".join(c if c.isprintable() or c.isspace() else f"\\x{ord(c):02x}" if ord(c) < 0x100
                          else f"\\u{ord(c):04x}" for c in h)
        assert " ".join(visible.split()) in shown, (h, shown[:3000])


def test_hostile_names_reach_the_report_as_text(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Config file names, config strings, material and rule names, database labels: escaped in every rst.

    Renders the front page through ``workflow/report/workflow.rst`` (its ``include``), every caption and
    the claims table as Snakemake does; nothing of the hostile strings acts as markup.
    """
    from brdfpipe.report import rst

    # claims whose text carries a hostile material name and database label (from a CSV)
    bs = write_csv(tmp_path / "bs.csv", ("database", "material", "share_object"),
                   [{"database": HOSTILE[1], "material": h, "share_object": 0.01 * (i + 1)}
                    for i, h in enumerate(HOSTILE)])
    found = claims.compute_claims(claims.ClaimInputs(bounce_shares=bs))
    worst = HOSTILE[-1]  # largest share: named in the measured text
    assert worst in by_key(found)["soler-second-bounce"].measured
    paths = {k: tmp_path / f"claims.{k}" for k in ("csv", "json", "rst")}
    claims.write_claims(found, csv_path=paths["csv"], json_path=paths["json"], rst_path=paths["rst"])
    _assert_inert(_publish_like_snakemake(paths["rst"].read_text()), [HOSTILE[1], worst])

    # every caption, with a hostile database label and hostile file names (path and scene names)
    files = [f"results/errormaps/{h}/a--b-t0.5-error.png" for h in HOSTILE[:1]]
    for key in captions.DESCRIPTIONS:
        cap = captions.caption_rst(key, found, database=HOSTILE[0], files=files)
        _assert_inert(_publish_like_snakemake(cap), [HOSTILE[0]])

    # the front page: configuration file names, config strings, held-out names, rule names of benchmarks
    results = tmp_path / "results" / "report"
    splits = {"database": HOSTILE[3], "materials": list(HOSTILE), "train": [], "test": list(HOSTILE[4:8])}
    runinfo.write_front(results / "front.rst", claims=found, splits=splits,
                        config={"render": {"scene": HOSTILE[0]}, HOSTILE[1]: HOSTILE[2]},
                        configfiles=list(HOSTILE[:3]), targets={HOSTILE[5]: 1}, versions={"x": HOSTILE[6]})
    bench = tmp_path / "benchmarks"
    (bench / "rule`_x").mkdir(parents=True)
    (bench / "rule`_x" / "job.tsv").write_text("s\tmax_rss\tcpu_time\n1\t2\t3\n")
    runinfo.write_stage_times(bench, csv_path=results / "stage-times.csv", rst_path=results / "stage-times.rst")
    workflow_rst = Path(__file__).resolve().parents[1] / "workflow" / "report" / "workflow.rst"
    monkeypatch.chdir(tmp_path)
    page = _publish_like_snakemake(workflow_rst.read_text(encoding="utf-8"))
    assert "What ran" in page and "Wall time per stage" in page and "rule`_x" in _text(page)
    _assert_inert(page, list(HOSTILE[:8]))
    assert "{{" not in rst.text("{{ x }}") and "{%" not in rst.text("{% x %}")
