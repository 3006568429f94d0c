"""Parse-time planning (brdfpipe.core.plan), the DAG's file names (brdfpipe.core.filenames), code versions (brdfpipe.core.version)."""

from __future__ import annotations

import copy
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from brdfpipe.core import filenames as fn, plan, version

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
TINY = yaml.safe_load((ROOT / "tests" / "config" / "tiny.yaml").read_text())
NAMES = [f"m{i:02d}" for i in range(12)]


def tiny(**sections: dict) -> dict:
    cfg = copy.deepcopy(TINY)
    for key, value in sections.items():
        cfg[key].update(value)
    return cfg


def test_tiny_config_passes() -> None:
    plan.check_config(TINY, materials=NAMES, train=NAMES[3:])


def test_closed_loop_captures_the_configured_sets() -> None:
    assert plan.closedloop_directions(TINY) == [("nearfield", 25.0, "error")]
    cfg = tiny(closed_loop={"setups": ["nearfield", "fixed_camera"], "fovs": None, "metric": "condition"},
               acquisition={"fovs": [15, 25]})
    assert plan.closedloop_directions(cfg) == [("nearfield", 15.0, "condition"), ("nearfield", 25.0, "condition"),
                                               ("fixed_camera", 25.0, "condition")]
    assert plan.closedloop_directions(tiny(closed_loop={"enabled": False, "setups": ["fixed_light"]})) == []
    plan.check_config(tiny(closed_loop={"enabled": False, "setups": ["fixed_light"]},
                           acquisition={"setups": ["point"]}), materials=NAMES, train=NAMES[3:])


@pytest.mark.parametrize(
    ("sections", "key"),
    [
        ({"manifold": {"ell": float("nan")}}, "manifold.ell"),
        ({"manifold": {"mu": float("inf")}}, "manifold.mu"),
        ({"acquisition": {"eta": float("nan")}}, "acquisition.eta"),
        ({"acquisition": {"beta": float("-inf")}}, "acquisition.beta"),
        ({"render": {"path_points": [0.5, float("nan")]}}, "render.path_points[1]"),
        ({"manifold": {"latent_dims": [2, 12]}}, "manifold.latent_dims"),
        ({"acquisition": {"training_sizes": [3, 10]}}, "acquisition.training_sizes"),
        ({"manifold": {"path_q": 3}}, "manifold.path_q"),
        ({"render": {"noise_seed": 0}}, "render.noise_seed"),
        ({"render": {"path_points": [0.1234561, 0.1234562]}}, "render.path_points"),
        ({"manifold": {"paths": [["m01", "m01"]]}}, "manifold.paths[0]"),
        ({"manifold": {"paths": [["m01", "zz"]]}}, "manifold.paths[0]"),
        ({"manifold": {"paths": [["m01", "m02"], ["m01", "m02"]]}}, "manifold.paths"),
        ({"closed_loop": {"setups": ["nearfield", "fixed_light"]}, "acquisition": {"setups": ["nearfield"]}},
         "closed_loop.setups"),
        ({"closed_loop": {"metric": "condition"}, "acquisition": {"metrics": ["error"]}}, "closed_loop.metric"),
        ({"closed_loop": {"fovs": [30]}}, "closed_loop.fovs"),
        ({"closed_loop": {"n_images": [1, 3]}}, "closed_loop.n_images"),
    ],
)
def test_bad_values_name_their_key(sections: dict, key: str) -> None:
    with pytest.raises(plan.ConfigError) as err:
        plan.check_config(tiny(**sections), materials=NAMES, train=NAMES[3:])
    assert key in str(err.value)


def test_default_paths_are_seeded_and_prefer_soler() -> None:
    p = plan.default_paths(NAMES, seed=4)
    assert p == plan.default_paths(NAMES, seed=4) and len(p) == 3
    assert len({m for pair in p for m in pair}) == 6
    soler = [m for pair in plan.SOLER_PATHS for m in pair] + ["x"]
    assert plan.default_paths(soler, seed=0) == list(plan.SOLER_PATHS)


def test_direction_files_of_the_default_config() -> None:
    acq = DEFAULT["acquisition"]
    train = plan.direction_files(acq, "train")
    n_fov = len(acq["fovs"])
    assert len(train) == len(acq["metrics"]) * (1 + n_fov + 2)
    assert plan.direction_files(acq, "all") == [fn.directions("all", "nearfield", f, "error") for f in acq["fovs"]]
    assert plan.curve_directions(acq) == fn.directions("train", "nearfield", 25, "error")
    assert fn.directions("train", "nearfield", 25.0, "error") == "results/directions/train/nearfield-fov25-error.json"
    assert fn.directions("train", "point", 0, "error").endswith("point-fov0-error.json")


@pytest.mark.parametrize(
    ("acq", "expected"),
    [
        ({"setups": ["point"], "metrics": ["error"]}, ["fig05", "fig06", "fig18", "fig19"]),
        ({"setups": ["nearfield"], "metrics": ["condition"]}, ["fig05", "fig06", "fig08", "fig19"]),
        ({"setups": ["nearfield", "fixed_light"], "metrics": ["error"]},
         ["fig05", "fig06", "fig07", "fig08", "fig13", "fig19"]),
    ],
)
def test_acquisition_figures_follow_the_setups(acq: dict, expected: list[str]) -> None:
    cfg = {**TINY["acquisition"], **acq}
    figs = plan.acquisition_figures(cfg)
    assert list(figs) == expected
    if "fig08" in figs:  # the table figure also writes its CSV and Markdown
        assert figs["fig08"][2:] == [f"{fn.FIGURES}/fig08-optimal-configurations.csv",
                                     f"{fn.FIGURES}/fig08-optimal-configurations.md"]
    assert all(len(files) == 2 for k, files in figs.items() if k != "fig08")
    assert (plan.curve_directions(cfg) is not None) == ("fig07" in figs)


def test_manifold_and_render_figures_follow_the_config() -> None:
    assert "fig07" not in plan.manifold_figures({"latent_dims": [1]})
    assert "fig10_q5" not in plan.manifold_figures({"latent_dims": [2]})
    assert set(plan.manifold_figures({"latent_dims": [2, 5]})) == set(fn.MANIFOLD_FIGURE_STEMS)
    assert plan.albedo_map_dims({"latent_dims": [1, 2, 5]}) == [2, 5]
    assert list(plan.render_figures(0)) == ["fig01"]
    assert list(plan.render_figures(3)) == ["fig01", "fig12", "fig13"]


def test_file_names_keep_wildcards_and_format_numbers() -> None:
    assert fn.path_point("preview", "{path}", "{t}", "noise") == "results/renders/preview/paths/{path}-t{t}-noise.exr"
    assert fn.path_point("s", "a--b", 0.50, "weights") == "results/renders/s/paths/a--b-t0.5-weights.json"
    assert fn.errormap("s", "a--b", 1.0, "error.png") == "results/errormaps/s/a--b-t1-error.png"
    assert [fn.format_t(t) for t in (0.25, 1.0, -0.0)] == ["0.25", "1", "0"]
    with pytest.raises(ValueError):
        fn.format_t(float("inf"))
    with pytest.raises(ValueError):
        fn.path_point("s", "p", 0.5, "thumbnail")


def test_parsing_imports_no_heavy_library() -> None:
    """The modules the Snakefile imports at parse time stay light."""
    code = (
        "import sys; import brdfpipe.core.filenames, brdfpipe.core.plan, brdfpipe.core.stamps, brdfpipe.core.version; "
        "heavy = [m for m in ('numpy', 'scipy', 'zarr', 'matplotlib', 'mitsuba') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == ""


# -- code versions ------------------------------------------------------------


def copy_package(tmp_path: Path) -> Path:
    dst = tmp_path / "brdfpipe"
    shutil.copytree(version.PACKAGE_DIR, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def test_module_closure_follows_imports() -> None:
    closure = version.module_closure(["acquisition.svd"])
    assert {"brdfpipe", "brdfpipe.acquisition.svd", "brdfpipe.data.store", "brdfpipe.data.merl"} <= set(closure)
    # importing a module runs its parent packages' __init__ first
    assert {"brdfpipe.acquisition", "brdfpipe.data", "brdfpipe.core"} <= set(closure)
    assert "brdfpipe.acquisition.figures" not in closure and "brdfpipe.rendering.render" not in closure
    with pytest.raises(ValueError):
        version.module_closure(["no_such_module"])


def _ast_imports(source: str, base: list[str]) -> set[str]:
    """Reference for the import scan: every import statement of the syntax tree."""
    import ast

    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                mod = ".".join([*anchor, node.module] if node.module else anchor)
            else:
                mod = node.module or ""
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)
    return found


def test_import_scan_finds_what_the_syntax_tree_has() -> None:
    """The fast textual scan finds every import the syntax tree has, in the package and the scripts."""
    files = [(p, ["brdfpipe", *p.relative_to(version.PACKAGE_DIR).parent.parts]) for p in version.PACKAGE_DIR.rglob("*.py")]
    files += [(p, []) for p in (ROOT / "workflow" / "scripts").glob("*.py")]
    for path, base in files:
        source = path.read_text(encoding="utf-8")
        scanned = version._import_names(source, base)
        expected = _ast_imports(source, base)
        assert expected <= scanned, f"{path}: missed {sorted(expected - scanned)}"
        own = ".".join([*base, path.stem]) if path.stem != "__init__" else ".".join(base)
        # a docstring's usage example may mention its own module (and so its
        # parent packages, which the closure has anyway): harmless
        parts = own.split(".")
        harmless = {".".join(parts[:i]) for i in range(1, len(parts) + 1)}
        spurious = {m for m in scanned - expected if m.startswith("brdfpipe") and m not in harmless}
        assert not spurious, f"{path}: spurious {sorted(spurious)}"
    tricky = (
        "def f():\n    from brdfpipe import (\n        svd,  # a comment\n        store as st,\n    )\n"
        "import brdfpipe.data.merl as m, os\nfrom . import atomic\nfrom .. import x\n"
        "from brdfpipe.core.zgroup import \\\n    open_group\n"
    )
    assert _ast_imports(tricky, ["brdfpipe", "sub"]) == version._import_names(tricky, ["brdfpipe", "sub"])


def test_digests_change_with_the_code_they_cover(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pkg = copy_package(tmp_path)
    script = tmp_path / "job.py"
    script.write_text("from brdfpipe.acquisition import svd\nfrom brdfpipe.core.logutil import log_to\n")
    other = tmp_path / "other.py"
    other.write_text("from brdfpipe.rendering import scene\n")

    def digests() -> tuple[str, str, str]:
        version._imports.cache_clear()
        version.full_version.cache_clear()
        return version.script_digest(script), version.script_digest(other), version.full_version()

    monkeypatch.setattr(version, "PACKAGE_DIR", pkg)
    before = digests()
    assert before == digests()  # deterministic
    assert before[2].startswith("0.1.0+src.")
    svd_py = pkg / "acquisition" / "svd.py"
    svd_py.write_text(svd_py.read_text() + "\n# an edit\n")
    after = digests()
    assert after[0] != before[0]  # the job that runs svd changes
    assert after[1] == before[1]  # a job that does not is untouched
    assert after[2] != before[2]  # and the version of every output tells the two apart
    # importing brdfpipe.rendering.scene runs brdfpipe/rendering/__init__.py: an edit there reruns it
    init = pkg / "rendering" / "__init__.py"
    init.write_text(init.read_text() + "\n# an edit\n")
    again = digests()
    assert again[1] != after[1] and again[0] == after[0]
    version._imports.cache_clear()
    version.full_version.cache_clear()


def test_every_rule_has_a_memory_model_that_grows_with_retries() -> None:
    import re

    rules = set()
    for smk in (ROOT / "workflow" / "rules").glob("*.smk"):
        rules |= set(re.findall(r"^\s*rule (\w+):", smk.read_text(), flags=re.M))
    assert rules == set(plan.MEMORY_MB), rules ^ set(plan.MEMORY_MB)
    for rule in rules:
        first, second, third = (plan.mem_mb(rule, 100, a) for a in (1, 2, 3))
        assert 100 <= first < second < third and first % 50 == 0
        assert plan.mem_mb(rule, 1000) >= first  # never shrinks with more materials
    assert plan.mem_mb("map_logrelative", 1000) > 5 * plan.mem_mb("map_logrelative", 100) / 2


def test_memory_grows_with_the_outputs_a_job_holds() -> None:
    """interpolate_path_points holds one table per path point: its mem_mb grows with them, other rules' do not."""
    one = plan.mem_mb("interpolate_path_points", 100, outputs=1)
    nine = plan.mem_mb("interpolate_path_points", 100, outputs=9)
    extra = 8 * plan.PER_OUTPUT_MB["interpolate_path_points"] * plan.MEMORY_HEADROOM
    assert extra - 50 <= nine - one <= extra + 50
    assert plan.mem_mb("prerender_material", 100, outputs=9) == plan.mem_mb("prerender_material", 100)


def test_floor_check_candidates() -> None:
    cands = {"standardised-mu1e-06": ("standardised", 1e-6), "raw-mu0.0001": ("raw", 1e-4)}
    render = {"floor_check": {"candidates": "all"}}
    assert plan.floor_check_candidates(render, cands, 9) == ["standardised-mu1e-06", "raw-mu0.0001"]
    assert plan.floor_check_candidates({"floor_check": {"candidates": "default"}}, cands, 9) == [
        "standardised-mu1e-06"]
    assert plan.floor_check_candidates({"floor_check": {"candidates": "none"}}, cands, 9) == []
    assert plan.floor_check_candidates(render, cands, 0) == []  # no path point, nothing to check
