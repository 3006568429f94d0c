"""Parse-time planning (brdfpipe.plan), the DAG's file names (brdfpipe.core.filenames), code versions (brdfpipe.core.version)."""

from __future__ import annotations

import copy
import importlib.util
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from brdfpipe import plan
from brdfpipe.registry import manifold as manifold_spec
from brdfpipe.core import filenames as fn, version

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_PATH = ROOT / "workflow" / "schemas" / "config.schema.yaml"


def _with_defaults(path: Path) -> dict:
    """A config file as the workflow sees it: validated, the schema's defaults filled in."""
    from snakemake.utils import validate

    cfg = yaml.safe_load(path.read_text())
    validate(cfg, str(SCHEMA_PATH), set_default=True)
    return cfg


DEFAULT = _with_defaults(ROOT / "config" / "config.yaml")
TINY = _with_defaults(ROOT / "tests" / "config" / "tiny.yaml")
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
        ({"closed_loop": {"sensor": {**TINY["closed_loop"]["sensor"], "brackets": [2, 8]}}},
         "config closed_loop.sensor.brackets = [2, 8]: the shortest exposure must be 1"),
        ({"closed_loop": {"min_snr": 250}}, "config closed_loop.min_snr = 250: no pixel can reach it"),
        ({"manifold": {"mu": 1e-5, "candidates": [{"space": "standardised", "mu": 1.0000001e-5}]}},
         "config manifold.candidates[0]: mu = 1.0000001e-05 differs from manifold.mu = 1e-05 only past 6"),
        ({"closed_loop": {"spp": 65536}, "acquisition": {"grid": 512}},
         "config closed_loop.spp = 65536: at most 16320 with acquisition.grid = 512"),
        ({"closed_loop": {"sensor": {**TINY["closed_loop"]["sensor"], "read_noise": 1e4, "brackets": [1]}}},
         "config closed_loop.min_snr = 3: no pixel can reach it"),
        ({"acquisition": {"screen_grid": 12}},
         "config acquisition.screen_grid = 12: must be below acquisition.grid (12), or 0"),
    ],
)
def test_bad_values_name_their_key(sections: dict, key: str) -> None:
    with pytest.raises(plan.ConfigError) as err:
        plan.check_config(tiny(**sections), materials=NAMES, train=NAMES[3:])
    assert key in str(err.value)


def test_two_paths_whose_file_names_collide_are_refused() -> None:
    names = ["a", "b", "c", "a--b", "b--c"]
    with pytest.raises(plan.ConfigError, match=r"^manifold.paths\[0\] \['a--b', 'c'\] and \[1\] \['a', 'b--c'\] "
                                               "share the file name a--b--c"):
        manifold_spec.check_paths([["a--b", "c"], ["a", "b--c"]], names)


def test_sensor_checks_follow_what_the_capture_uses() -> None:
    """min_snr is checked against the sensor's best SNR only when the sensor is on; nothing when the loop is off."""
    sensor = TINY["closed_loop"]["sensor"]
    best = plan.sensor_max_snr(sensor)  # [1, 8] brackets of the default sensor: √2 · 20000 / √(20025 + lsb²/12)
    assert best == pytest.approx(math.sqrt(2) * 20000 / math.sqrt(20000 + 25 + (20000 / 4095) ** 2 / 12))
    plan.check_config(tiny(closed_loop={"min_snr": 0.99 * best}), materials=NAMES, train=NAMES[3:])
    plan.check_config(tiny(closed_loop={"min_snr": 1e6, "sensor": {**sensor, "enabled": False}}),
                      materials=NAMES, train=NAMES[3:])
    plan.check_config(tiny(closed_loop={"enabled": False, "sensor": {**sensor, "brackets": [4]}}),
                      materials=NAMES, train=NAMES[3:])


def test_default_paths_are_seeded_and_prefer_soler() -> None:
    p = manifold_spec.default_paths(NAMES, seed=4)
    assert p == manifold_spec.default_paths(NAMES, seed=4) and len(p) == 3
    assert len({m for pair in p for m in pair}) == 6
    soler = [m for pair in manifold_spec.SOLER_PATHS for m in pair] + ["x"]
    assert manifold_spec.default_paths(soler, seed=0) == list(manifold_spec.SOLER_PATHS)


def test_direction_files_of_the_default_config() -> None:
    acq = DEFAULT["acquisition"]
    train = plan.direction_files(acq, "train")
    n_fov = len(acq["fovs"])
    # Nielsen's κ (first n components) is a point-sampling metric: optimised for the point set-up only
    assert acq["metrics"] == ["error", "condition", "condition_nielsen"]
    assert len(train) == 2 * (1 + n_fov + 2) + 1
    assert [f for f in train if f.endswith("-condition_nielsen.json")] == [
        fn.directions("train", "point", 0, "condition_nielsen")]
    assert plan.direction_files(acq, "all") == [fn.directions("all", "nearfield", f, "error") for f in acq["fovs"]]
    assert plan.curve_directions(acq) == fn.directions("train", "nearfield", 25, "error")
    assert fn.directions("train", "nearfield", 25.0, "error") == "results/directions/train/nearfield-fov25-error.json"
    assert fn.directions("train", "point", 0, "error").endswith("point-fov0-error.json")


def test_paper_directions_where_the_claims_compare_them() -> None:
    """Xu §6's stated directions are evaluated at the FOVs of their claims, where Fig. 8's near-field sets exist."""
    assert plan.paper_directions(DEFAULT["acquisition"]) == ["one-shot", "two-shot"]  # 25° and 15°, 1 and 2 images
    assert plan.paper_directions(TINY["acquisition"]) == ["one-shot"]  # 25° only
    assert plan.paper_directions({**TINY["acquisition"], "fovs": [15, 35]}) == ["two-shot"]
    assert plan.paper_directions({**DEFAULT["acquisition"], "n_max_images": 1}) == ["one-shot"]
    no_images = {**DEFAULT["acquisition"], "setups": ["point", "fixed_camera"]}
    assert plan.paper_directions(no_images) == []
    assert fn.rule_of(fn.paper_directions()) == "evaluate_paper_directions"


@pytest.mark.parametrize(
    ("acq", "expected"),
    [
        ({"setups": ["point"], "metrics": ["error"]}, ["fig05", "fig06", "fig18", "fig19"]),
        ({"setups": ["nearfield"], "metrics": ["condition"]}, ["fig05", "fig06", "fig08", "fig19"]),
        ({"setups": ["nearfield", "fixed_light"], "metrics": ["error"]},
         ["fig03", "fig05", "fig06", "fig07", "fig08", "fig09", "fig13", "fig14", "fig19"]),
    ],
)
def test_acquisition_figures_follow_the_setups(acq: dict, expected: list[str]) -> None:
    cfg = {**TINY["acquisition"], **acq}
    figs = plan.acquisition_figures(cfg)
    assert list(figs) == expected
    if "fig08" in figs:  # the table figure also writes its CSV and Markdown
        assert figs["fig08"][2:] == [f"{fn.FIGURES}/fig08-optimal-configurations.csv",
                                     f"{fn.FIGURES}/fig08-optimal-configurations.md"]
    assert all(len(files) == 2 for k, files in figs.items() if k not in ("fig03", "fig08", "fig09", "fig14"))
    assert (plan.curve_directions(cfg) is not None) == ("fig07" in figs)


def test_manifold_and_render_figures_follow_the_config() -> None:
    assert "fig07" not in plan.manifold_figures({"latent_dims": [1]})
    assert "fig10_q5" not in plan.manifold_figures({"latent_dims": [2]})
    assert set(plan.manifold_figures({"latent_dims": [2, 5]})) == set(fn.MANIFOLD_FIGURE_STEMS)
    assert plan.albedo_map_dims({"latent_dims": [1, 2, 5]}) == [2, 5]
    assert list(plan.render_figures(0)) == ["prerenders"]
    assert list(plan.render_figures(3)) == ["prerenders", "fig12", "fig13"]
    assert list(plan.render_figures(3, 11)) == ["fig01", "prerenders", "fig12", "fig13"]


def test_file_names_keep_wildcards_and_format_numbers() -> None:
    assert fn.path_point("preview", "{path}", "{t}", "noise") == "results/renders/preview/paths/{path}-t{t}-noise.exr"
    assert fn.path_point("s", "a--b", 0.50, "weights") == "results/renders/s/paths/a--b-t0.5-weights.json"
    assert fn.errormap("s", "a--b", 1.0, "error.png") == "results/errormaps/s/a--b-t1-error.png"
    assert [fn.format_t(t) for t in (0.25, 1.0, -0.0)] == ["0.25", "1", "0"]
    with pytest.raises(ValueError):
        fn.format_t(float("inf"))
    with pytest.raises(ValueError):
        fn.path_point("s", "p", 0.5, "thumbnail")


#: What the Snakefile and its rule files import at parse time, and which heavy libraries each may pull in:
#: data.database labels a merl_dir folder by the provenance marks inside its MERL files (NumPy reads them).
PARSE_TIME_MODULES = {
    "brdfpipe.core.filenames": (), "brdfpipe.plan": (), "brdfpipe.core.stamps": (), "brdfpipe.core.version": (),
    "brdfpipe.data.databases": (), "brdfpipe.report.claims": (), "brdfpipe.report.sidebyside": (),
    "brdfpipe.plan.report": (), "brdfpipe.explorer": (), "brdfpipe.data.database": ("numpy",),
    "brdfpipe.registry.acquisition": (), "brdfpipe.registry.manifold": (), "brdfpipe.registry.figures": (),
    "brdfpipe.registry.nearfield": (), "brdfpipe.core.threads": (),
}
HEAVY = ("numpy", "scipy", "zarr", "matplotlib", "mitsuba", "h5py")


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # a name inside a module, not a submodule
        return False


def test_parsing_imports_no_heavy_library() -> None:
    """The modules the Snakefile imports at parse time stay light (each in a fresh interpreter)."""
    workflow = Path(__file__).resolve().parents[1] / "workflow"
    found = set()
    for f in [workflow / "Snakefile", *sorted((workflow / "rules").glob("*.smk"))]:
        for m in re.finditer(r"^\s*from (brdfpipe[\w.]*) import (\w+)|^\s*import (brdfpipe[\w.]*)", f.read_text(), re.M):
            pkg, name, plain = m.groups()
            found.add(plain or (f"{pkg}.{name}" if _is_module(f"{pkg}.{name}") else pkg))
    assert found - {"brdfpipe"} <= set(PARSE_TIME_MODULES), f"new parse-time imports: {found - set(PARSE_TIME_MODULES)}"
    for module, allowed in PARSE_TIME_MODULES.items():
        code = f"import sys, {module}; print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
        assert set(filter(None, out.split(","))) <= set(allowed), f"{module} imports {out} at parse time"


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

    version.script_digest(script)  # its modules looked up (and cached) in the installed package first
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
        rules |= set(re.findall(r'mem\("(\w+)", scenes=', smk.read_text()))  # batch rules: their family's model
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
    assert plan.mem_mb("prerender_materials", 100, outputs=9) == plan.mem_mb("prerender_materials", 100)


def test_floor_check_candidates() -> None:
    cands = {"standardised-mu1e-06": ("standardised", 1e-6), "raw-mu0.0001": ("raw", 1e-4)}
    render = {"floor_check": {"candidates": "all"}}
    assert plan.floor_check_candidates(render, cands, 9) == ["standardised-mu1e-06", "raw-mu0.0001"]
    assert plan.floor_check_candidates({"floor_check": {"candidates": "default"}}, cands, 9) == [
        "standardised-mu1e-06"]
    assert plan.floor_check_candidates({"floor_check": {"candidates": "none"}}, cands, 9) == []
    assert plan.floor_check_candidates(render, cands, 0) == []  # no path point, nothing to check


# --------------------------------------------------------------------------
# Schema violations: one line naming the key (not Snakemake's dump of the schema)
# --------------------------------------------------------------------------

SCHEMA = yaml.safe_load(SCHEMA_PATH.read_text())


def test_the_shipped_configs_satisfy_the_schema() -> None:
    for cfg in (DEFAULT, TINY, *(yaml.safe_load(p.read_text()) for p in (ROOT / "tests" / "config").glob("*.yaml"))):
        assert plan.schema_problem(cfg, SCHEMA) is None


@pytest.mark.parametrize(
    ("config", "line"),
    [
        ({"colour": "red"}, "config colour: unknown key; top-level keys are: database, merl_dir, nbrdf_archive, "
                            "synthetic, materials, test_materials, unseen, acquisition, manifold, render, "
                            "closed_loop, report"),
        ({"render": {"resolutoin": [3, 4]}}, "config render.resolutoin: unknown key; did you mean 'resolution'? "
                                              "render has: variant, scene, resolution, spp"),
        ({"closed_loop": {"sensor": {"gain": 2, "iso": 100}}}, "config closed_loop.sensor.gain: unknown key "
                                                                "(and iso); closed_loop.sensor has: enabled"),
        ({"render": {"spp": "1e5"}}, "config render.spp = '1e5': must be an integer"),
        ({"render": {"spp": True}}, "config render.spp = True: must be an integer"),
        ({"merl_dir": 3}, "config merl_dir = 3: must be a string or null"),
        ({"synthetic": None}, "config synthetic = None: must be a mapping (key: value)"),
        ({"render": {"spp": 0}}, "config render.spp = 0: must be ≥ 1"),
        ({"acquisition": {"fovs": [25, 90]}}, "config acquisition.fovs[1] = 90: must be < 90"),
        ({"acquisition": {"eta": 0}}, "config acquisition.eta = 0: must be ≥ 1e-06"),
        ({"acquisition": {"eta": 1e-16}}, "config acquisition.eta = 1e-16: must be ≥ 1e-06 (η is relative"),
        ({"manifold": {"mu": 0}}, "config manifold.mu = 0: must be ≥ 1e-10 (K + μI must stay positive definite"),
        ({"manifold": {"candidates": [{"space": "raw", "mu": 0.0}]}}, "config manifold.candidates[0].mu = 0: must be ≥"),
        ({"manifold": {"ell": 1e300}}, "config manifold.ell = 1e+300: must be ≤ 1000000 (ℓ² divides"),
        ({"acquisition": {"eta": 1e30}}, "config acquisition.eta = 1e+30: must be ≤ 1000000 (η is relative"),
        ({"render": {"variant": "cpu"}}, "config render.variant = 'cpu': must be one of llvm_ad_rgb, cuda_ad_rgb"),
        ({"render": {"resolution": [64]}}, "config render.resolution: needs at least 2 entries (has 1)"),
        ({"render": {"resolution": [64, 48, 3]}}, "config render.resolution: at most 2 entries (has 3)"),
        ({"materials": []}, "config materials: must not be empty"),
        ({"materials": [""]}, "config materials[0]: must not be empty"),
        ({"acquisition": {"fovs": [25, 25]}}, "config acquisition.fovs: 25 is listed more than once"),
        ({"manifold": {"candidates": [{"space": "raw"}]}}, "config manifold.candidates[0]: missing key mu"),
        ({"render": {"scene": "a/b"}}, "config render.scene = 'a/b': must"),
        ({"render": {"spp": 0, "colour": 1}}, "(and 1 more problem after it)"),
        ({"render": {"resolution": [2, 100]}}, "config render.resolution[0] = 2: must be ≥ 8 (the preview object"),
        ({"acquisition": {"training_sizes": [3, 3]}}, "config acquisition.training_sizes: 3 is listed more than once"),
        ({"manifold": {"paths": []}}, "config manifold.paths: must not be empty"),
        ({"acquisition": {"n_max_point": 5000}}, "config acquisition.n_max_point = 5000: must be ≤ 1000 (a directions"),
        ({"acquisition": {"candidates": 10**9}}, "config acquisition.candidates = 1000000000: must be ≤ 1458000"),
        ({"manifold": {"path_steps": 10**6}}, "config manifold.path_steps = 1000000: must be ≤ 1000"),
        ({"test_materials": ["a/b"]}, "config test_materials[0] = 'a/b': must be a material name"),
    ],
)
def test_schema_violations_are_one_line_naming_the_key(config: dict, line: str) -> None:
    problem = plan.schema_problem(config, SCHEMA)
    assert problem is not None and "\n" not in problem and len(problem) < 400
    assert problem.startswith(line) if line.startswith("config") else line in problem


def _schema_at(*path: str) -> dict:
    node = SCHEMA
    for key in path:
        node = node["items"] if key == "[]" else node["properties"][key]
    return node


def test_render_limits_in_the_schema_are_what_the_renderer_takes() -> None:
    """spp and seeds the schema accepts render (passes of rendering.scene); one more is refused in one line."""
    from brdfpipe.rendering import scene

    most = scene._MAX_PASSES * scene.DEFAULT_PASS_SPP
    for path in (("render", "spp"), ("render", "floor_check", "spp")):
        assert _schema_at(*path)["maximum"] == most
        scene.pass_seeds(most, 0)  # accepted
        with pytest.raises(ValueError):
            scene.pass_seeds(most + 1, 0)
    for key in ("seed", "noise_seed"):
        top = _schema_at("render", key)["maximum"]
        assert max(s for s, _ in scene.pass_seeds(most, top)) < 2**32
        with pytest.raises(ValueError, match="32-bit"):  # the renderer refuses one more
            scene.pass_seeds(most, top + 1)
    for cfg, key in [({"render": {"spp": most + 1}}, "render.spp = 32001: must be ≤ 32000 (a render runs in at most"),
                     ({"render": {"seed": 4294967}}, "render.seed = 4294967: must be ≤ 4294966 (pass p of a render"),
                     ({"render": {"floor_check": {"spp": 10**6}}}, "render.floor_check.spp = 1000000: must be ≤ 32000"),
                     ({"closed_loop": {"sensor": {"full_well": 1e12}}}, "closed_loop.sensor.full_well = 1e+12: must be ≤ 1000000000"),
                     ({"closed_loop": {"sensor": {"brackets": [1, 1e9]}}}, "closed_loop.sensor.brackets[1] = 1000000000: must be ≤ 1000000"),
                     ({"render": {"scene": "x" * 65}}, "render.scene = 'xxxx")]:
        problem = plan.schema_problem(cfg, SCHEMA)
        assert problem is not None and problem.startswith(f"config {key}"), problem


# --------------------------------------------------------------------------
# Sizes: no job may need more than a job may have (plan.check_memory)
# --------------------------------------------------------------------------


def _memory_problem(cfg: dict, n: int = 100, points: int = 9) -> str | None:
    floor = cfg["render"]["floor_check"]["resolution"]
    try:  # every modelled rule (a run checks those its config defines)
        plan.check_memory(cfg, n, list(plan.MEMORY_MB), outputs={r: points for r in plan.PER_OUTPUT_MB}, floor_resolution=floor,
                          materials_key="synthetic.count")
    except plan.ConfigError as err:
        return str(err)
    return None


def _sections(base: dict, **sections: dict) -> dict:
    cfg = copy.deepcopy(base)
    for key, value in sections.items():
        for k, v in value.items():
            cfg[key][k] = {**cfg[key][k], **v} if isinstance(v, dict) else v
    return cfg


def test_the_shipped_configs_fit_the_memory_limit() -> None:
    assert _memory_problem(DEFAULT) is None
    assert _memory_problem(TINY, n=12, points=3) is None
    # the declared memory of the default sizes is the measured model's, and grows with a size
    sizes = plan.job_sizes(DEFAULT)
    assert all(plan.mem_mb(r, 100, sizes=sizes) == plan.mem_mb(r, 100) for r in plan.MEMORY_MB)
    big = plan.job_sizes(_sections(DEFAULT, render={"resolution": [1024, 768]}))
    assert plan.mem_mb("prerender_materials", 100, sizes=big) > plan.mem_mb("prerender_materials", 100)
    assert plan.mem_mb("write_explorer", 200, sizes=big) > 1.9 * plan.mem_mb("write_explorer", 100, sizes=big) - 500


@pytest.mark.parametrize(
    ("sections", "n", "start"),
    [
        ({"render": {"resolution": [4096, 3072]}}, 100, "config render.resolution = 12,582,912 pixels: one "),
        ({"render": {"floor_check": {"resolution": [20000, 20000]}}}, 100,
         "config render.floor_check.resolution = 400,000,000 pixels: one "),
        ({"render": {"envmap": {"width": 100000, "height": 50000}}}, 100,
         "config render.envmap.width × height = 5,000,000,000 pixels: one make_envmap job would need"),
        ({}, 1000, "config synthetic.count: 1000 materials: one "),
        ({"manifold": {"albedo_grid": 2000}}, 100, "config manifold.albedo_grid = 2000: one analyze_manifold job"),
    ],
)
def test_a_size_beyond_the_memory_limit_names_its_key_and_largest_value(sections: dict, n: int, start: str) -> None:
    cfg = _sections(DEFAULT, **sections)
    problem = _memory_problem(cfg, n=n)
    assert problem is not None and problem.startswith(start) and "above the 16,000 MB a job may have" in problem
    # the largest value it names fits; a little more does not
    most = int(problem.rsplit("at most ", 1)[1].split()[0].replace(",", ""))
    if "materials" in start:
        assert _memory_problem(cfg, n=most) is None and _memory_problem(cfg, n=most + 1) is not None
        return
    if "albedo_grid" in start:
        assert _memory_problem(_sections(DEFAULT, manifold={"albedo_grid": most})) is None
        assert _memory_problem(_sections(DEFAULT, manifold={"albedo_grid": most + 1})) is not None
        return
    side = math.isqrt(most)
    key = "floor_check" if "floor_check" in start else "envmap" if "envmap" in start else None
    for w, fits in ((side, True), (side + 2, False)):
        if key == "envmap":
            patch = {"render": {"envmap": {"width": w, "height": w}}}
        elif key == "floor_check":
            patch = {"render": {"floor_check": {"resolution": [w, w]}}}
        else:
            patch = {"render": {"resolution": [w, w]}}
        assert (_memory_problem(_sections(DEFAULT, **patch)) is None) == fits, (w, fits)


def test_many_path_points_are_refused_by_the_outputs_a_job_holds() -> None:
    problem = _memory_problem(DEFAULT, points=400)
    assert problem is not None and problem.startswith("config render.path_points × manifold.paths: 400 path points")


def test_the_schema_offers_exactly_the_registered_databases() -> None:
    """The config's `database` choices are the registry's (brdfpipe.data.databases), the default its default."""
    from brdfpipe.data import databases

    entry = SCHEMA["properties"]["database"]
    assert entry["enum"] == list(databases.DATABASES)
    assert entry["default"] == databases.DEFAULT_DATABASE


def _schema_enums(schema: object, path: str = "") -> dict[str, list]:
    """Every ``enum`` of the schema, keyed by its property path (``acquisition.setups[]``)."""
    found: dict[str, list] = {}
    if isinstance(schema, dict):
        if "enum" in schema:
            found[path] = list(schema["enum"])
        for key, sub in schema.get("properties", {}).items():
            found.update(_schema_enums(sub, f"{path}.{key}" if path else key))
        if "items" in schema:
            found.update(_schema_enums(schema["items"], path + "[]"))
    return found


def test_each_schema_enum_equals_its_spec() -> None:
    """The schema's lists of set-ups, metrics, data spaces, optimisers and starts are the specs' (brdfpipe.registry), in order."""
    from brdfpipe.registry import acquisition as acq
    from brdfpipe.registry import manifold as man

    enums = _schema_enums(SCHEMA)
    expected = {
        "acquisition.setups[]": list(acq.SETUP_NAMES),
        "acquisition.metrics[]": list(acq.METRICS),
        "closed_loop.setups[]": list(acq.IMAGE_SETUPS),
        "closed_loop.metric": list(acq.IMAGE_METRICS),
        "manifold.space": list(man.SPACE_NAMES),
        "manifold.candidates[].space": list(man.SPACE_NAMES),
        "manifold.method": list(man.OPTIMISERS),
        "manifold.candidates[].method": list(man.OPTIMISERS),
        "manifold.init": list(man.INITS),
        "manifold.candidates[].init": list(man.INITS),
    }
    for key, names in expected.items():
        assert enums.get(key) == names, f"schema {key}: {enums.get(key)} != spec {names}"
    # every enum of a spec'd kind is covered above (a new enum of set-ups or spaces must be added here)
    spec_values = {tuple(v) for v in expected.values()}
    for key, values in enums.items():
        if set(values) & (set(acq.SETUP_NAMES) | set(man.SPACE_NAMES)):
            assert tuple(values) in spec_values and key in expected, f"schema {key} lists spec'd names: {values}"


def test_the_workflow_wildcards_come_from_the_specs() -> None:
    """common.smk builds its set-up, metric and data-space wildcard constraints from the specs, not literals."""
    text = (Path(__file__).resolve().parents[1] / "workflow" / "rules" / "common.smk").read_text()
    assert 'setup="|".join(setup_specs.SETUP_NAMES)' in text
    assert 'metric="|".join(setup_specs.METRICS)' in text
    assert 'space="|".join(manifold_specs.SPACE_NAMES)' in text
    for literal in ("nearfield|", "standardised", "error|condition"):
        assert literal not in text.split("wildcard_constraints:")[1].split("\n\n")[0], literal


def test_the_gram_blocks_are_bounded_by_the_log_map_chunks() -> None:
    """--set-scatter gram=N: 0 failed mid-run, 100,000 hung the dry run (200,000 jobs); refused at parse."""
    from brdfpipe.data import logmap, merl

    assert plan.MAX_GRAM_BLOCKS == -(-merl.N_CELLS // logmap.CHUNK_COLS)  # one block per chunk of the grid
    for n in (1, 4, plan.MAX_GRAM_BLOCKS):
        plan.check_gram_blocks(n)
    for n in (0, -1, plan.MAX_GRAM_BLOCKS + 1, 100_000):
        with pytest.raises(plan.ConfigError, match=rf"--set-scatter gram={n}: must be between 1 and 40"):
            plan.check_gram_blocks(n)


def test_a_run_ends_saying_where_its_results_are(tmp_path: Path) -> None:
    """The console's last lines (the Snakefile's onsuccess): the paths of filenames that exist, the report, the logs."""
    lines = plan.where_results_are(tmp_path)
    assert lines[0] == "brdfpipe: the run is complete." and len(lines) == 3
    assert fn.report_zip() in lines[1] and "make report" in lines[1] and "logs/" in lines[2]
    for path in [fn.claims_csv(), fn.explorer_page()]:
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text("")
    (tmp_path / fn.FIGURES).mkdir()
    named = [line.split()[1] for line in plan.where_results_are(tmp_path)[1:-2]]
    assert named == [f"{fn.RESULTS}/", f"{fn.FIGURES}/", fn.claims_csv(), fn.explorer_page()]
