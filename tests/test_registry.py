"""The specs (brdfpipe.registry): the registries of what people add are the one source every stage reads.

Figures: each record's drawing function exists in its track's figures
module and the track's ``make_*_figures`` calls it; its stem is the file
name the workflow declares; its caption and paper figure are the report's.
Set-ups and data spaces: the science modules take their properties from the
records, so a record's change reaches them.
"""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

import pytest

from brdfpipe import plan
from brdfpipe.core import filenames
from brdfpipe.plan import report as items
from brdfpipe.report import captions
from brdfpipe.registry import acquisition as acq_spec
from brdfpipe.registry import figures as fig_spec
from brdfpipe.registry import manifold as man_spec

MAKERS = {
    "plot_acquisition_figures": ("brdfpipe.acquisition.figures", "make_acquisition_figures"),
    "plot_reconstruction_figures": ("brdfpipe.acquisition.figures", "make_reconstruction_figures"),
    "plot_manifold_figures": ("brdfpipe.manifold.figures", "make_manifold_figures"),
    "plot_render_figures": ("brdfpipe.rendering.figures", "make_render_figures"),
}


@pytest.mark.parametrize("fig", fig_spec.FIGURES, ids=lambda f: f.report_key)
def test_every_registered_figure_is_drawn_by_its_function(fig: fig_spec.Figure) -> None:
    """The record is the dispatcher: its function exists, takes the rule's inputs and a stem, and no maker names it."""
    module = importlib.import_module(f"brdfpipe.{fig.track}.figures")
    draw = getattr(module, fig.draw, None)
    assert callable(draw), f"brdfpipe.{fig.track}.figures has no {fig.draw}"
    if fig.rule in MAKERS:
        assert list(inspect.signature(draw).parameters) == ["inp", "stem"], fig.draw
        mod, maker = MAKERS[fig.rule]
        source = inspect.getsource(getattr(importlib.import_module(mod), maker))
        assert fig.draw not in source and "draw_figures(" in source, (maker, fig.draw)


def test_a_figure_record_alone_makes_its_rule_draw_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A new record naming a new function is drawn by its rule's maker with no other edit (core.plot.draw_figures)."""
    from brdfpipe.core import plot
    from brdfpipe.manifold import figures as manifold_figures

    drawn = []

    def manifold_fig99_new(inp: object, stem: Path) -> plot.FigureOutput:
        drawn.append((inp, stem))
        return plot.FigureOutput((stem.with_suffix(".png"),), "a title", (), "synthetic", (1, 1))

    extra = fig_spec.Figure("manifold", "fig99", "manifold-fig99-new", "Soler Fig. 99", rule="plot_manifold_figures",
                            draw="manifold_fig99_new", caption="A new figure.")
    monkeypatch.setattr(fig_spec, "FIGURES", (*fig_spec.FIGURES, extra))
    monkeypatch.setattr(manifold_figures, "manifold_fig99_new", manifold_fig99_new, raising=False)
    stems = plot.figure_stems("manifold", "plot_manifold_figures",
                              {"fig99": [tmp_path / "x.png", tmp_path / "x.pdf"]}, "test")
    out = plot.draw_figures(manifold_figures, "manifold", "plot_manifold_figures", stems, "the inputs")
    assert drawn == [("the inputs", tmp_path / "x")] and out[0].files == (tmp_path / "x.png",)
    with pytest.raises(ValueError, match=r"test: unknown figure key\(s\) \['fig98'\]"):
        plot.figure_stems("manifold", "plot_manifold_figures", {"fig98": []}, "test")


def test_report_keys_stems_and_draw_functions_are_unique() -> None:
    for attr in ("report_key", "stem"):
        values = [getattr(f, attr) for f in fig_spec.FIGURES]
        assert len(values) == len(set(values)), attr
    keys = [f.report_key for f in fig_spec.FIGURES] + [e.key for e in fig_spec.REPORT_ENTRIES]
    assert len(keys) == len(set(keys))


def test_file_names_report_and_captions_read_the_registry() -> None:
    assert filenames.FIGURE_STEMS == {f.key: f.stem for f in fig_spec.track_figures("acquisition", "plot_acquisition_figures")}
    assert filenames.CLOSEDLOOP_STEM == fig_spec.figure("xu-closedloop").stem
    for f in fig_spec.FIGURES:
        assert items.FIGURE_NUMBERS[f.report_key] == f.paper
        assert captions.DESCRIPTIONS[f.report_key] == f.caption


def test_a_registered_figure_reaches_the_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    """A new record is planned without another edit: the planner and the file names read FIGURES."""
    extra = fig_spec.Figure("manifold", "fig99", "manifold-fig99-new", "Soler Fig. 99", rule="plot_manifold_figures",
                            draw="manifold_fig99_new", caption="A new figure.",
                            when=lambda m: 7 in [int(q) for q in m["latent_dims"]])
    monkeypatch.setattr(fig_spec, "FIGURES", (*fig_spec.FIGURES, extra))
    with_q7 = plan.manifold_figures({"latent_dims": [2, 7]})
    assert with_q7["fig99"] == filenames.figure_files("manifold-fig99-new")
    assert "fig99" not in plan.manifold_figures({"latent_dims": [2, 5]})
    assert fig_spec.captions()["soler-fig99"] == "A new figure."


def test_the_figures_a_config_produces_follow_the_when_predicates() -> None:
    acq = {"setups": ["point"], "metrics": ["error"], "training_sizes": [10], "fovs": [25], "fixed_fov": 25}
    assert list(plan.acquisition_figures(acq)) == ["fig05", "fig06", "fig18", "fig19"]
    acq["setups"] = ["nearfield", "fixed_light"]
    assert list(plan.acquisition_figures(acq)) == ["fig03", "fig05", "fig06", "fig07", "fig08", "fig09", "fig13",
                                                   "fig14", "fig19"]
    assert list(plan.reconstruction_figures({**acq, "n_max_images": 2})) == ["fig02"]  # Fig. 15: fixed camera only
    assert list(plan.render_figures(0)) == ["prerenders"]
    assert list(plan.render_figures(3)) == ["prerenders", "fig12", "fig13"]
    assert list(plan.render_figures(3, 11)) == ["fig01", "prerenders", "fig12", "fig13"]


def test_setup_records_drive_the_geometry_and_the_optimiser() -> None:
    from brdfpipe.acquisition import geometry

    for name, rec in acq_spec.SETUPS.items():
        s = geometry.Setup(name, fov_deg=25.0 if rec.images else 0.0)
        assert s.is_image == rec.images and s.spec is rec
    assert acq_spec.setup_fovs("point", [15, 25], 30) == [0]
    assert acq_spec.setup_fovs("nearfield", [15, 25], 30) == [15, 25]
    assert acq_spec.setup_fovs("fixed_camera", [15, 25], 30) == [30]
    with pytest.raises(ValueError, match="unknown acquisition setup 'dome'"):
        acq_spec.setup("dome")


def test_data_space_records_drive_the_manifold() -> None:
    assert man_spec.LINEAR_SPACES == tuple(n for n, s in man_spec.DATA_SPACES.items() if s.linear)
    assert man_spec.candidate_label("standardised", 1e-6) == "standardised-mu1e-06"
    with pytest.raises(ValueError, match="unknown data space"):
        man_spec.candidate_label("lab", 1e-4)


def test_every_data_space_has_its_maps() -> None:
    from brdfpipe.manifold import spaces

    assert list(spaces.MAPS) == list(man_spec.SPACE_NAMES)
    for name, record in man_spec.DATA_SPACES.items():  # the record's invertible is what the maps carry
        assert (spaces.MAPS[name].inverse is not None) == (not record.linear and record.invertible), name
        assert record.blendable
    with pytest.raises(ValueError, match="unknown data space 'lab'"):
        spaces.space_maps("lab")


def _aliases(module: Path) -> list[str]:
    """Module-level names of ``module`` bound to a name of another brdfpipe module (``X = tables.ERRORS``,
    ``X = ERRORS`` after ``from brdfpipe.registry.tables import ERRORS``, ``import … as`` another name)."""
    import brdfpipe

    package = Path(brdfpipe.__file__).parent.parent
    tree = ast.parse(module.read_text(encoding="utf-8"))
    imported = set()
    bad = []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("brdfpipe"):
            for a in node.names:
                imported.add(a.asname or a.name)
                where = package.joinpath(*node.module.split("."), a.name)
                is_module = where.with_suffix(".py").is_file() or where.is_dir()
                if a.asname and a.asname != a.name and not is_module:  # a module may be named for its role
                    bad.append(f"line {node.lineno}: imports {a.name} as {a.asname}")
    for node in tree.body:
        value = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
        if ((isinstance(value, ast.Attribute) and isinstance(value.value, ast.Name) and value.value.id in imported)
                or (isinstance(value, ast.Name) and value.id in imported)):
            bad.append(f"line {node.lineno}: {ast.unparse(node).splitlines()[0]}")
    return bad


def test_no_module_rebinds_a_name_of_another() -> None:
    """A name is read where it is declared (a spec record, a constant, a function): no library module binds
    it again under a name of its own.

    An alias hides which list a caller reads, and a test that patches one copy
    leaves the others (issue 34 counted 28 re-bound spec names in 13 modules
    before they went).  ``from brdfpipe.registry import manifold as manifold_spec``
    names a module, not one of its names, and stays.
    """
    import brdfpipe

    root = Path(brdfpipe.__file__).parent
    found = {m.relative_to(root).as_posix(): bad for m in sorted(root.rglob("*.py")) if (bad := _aliases(m))}
    assert found == {}


def test_the_alias_check_sees_an_alias(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("from brdfpipe.registry import tables\nfrom brdfpipe.registry.manifold import SPACE_NAMES\n"
                      "from brdfpipe.manifold.gram import gram_matrix as gm\n"
                      "COLUMNS: tuple = tables.ERRORS\nSPACES = SPACE_NAMES\nOTHER = len(tables.ERRORS)\n")
    assert [b.split(":")[0] for b in _aliases(module)] == ["line 3", "line 4", "line 5"]


def test_each_shared_table_has_one_column_declaration() -> None:
    """The readers of the tables in brdfpipe.registry.tables use its tuples, not copies."""
    from brdfpipe.manifold import figure_inputs as man_figures
    from brdfpipe.report import claims
    from brdfpipe.registry import tables

    assert set(man_figures.SPACES_FIGURE_COLUMNS) <= set(tables.SPACES)
    # the claims name no column tuple of their own: every table they read is its owner's (or a checked subset)
    modules = sorted(Path(claims.__file__).parent.glob("claims*.py"))
    assert {m.stem for m in modules} == {"claims", "claims_base", "claims_xu", "claims_setups", "claims_soler",
                                         "claims_ours", "claims_io"}
    reads = 0
    for module in modules:
        tree = ast.parse(module.read_text(encoding="utf-8"))
        calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
                 and getattr(node.func, "id", "") == "read_rows" and len(node.args) > 1]
        reads += len(calls)
        literal = [node.lineno for node in calls if isinstance(node.args[1], ast.Tuple) and node.args[1].elts]
        assert literal == [], f"{module.name} reads tables with literal columns at lines {literal}"
    assert reads >= 10  # the check sees the readers


def test_a_reader_cannot_name_a_column_its_table_lacks() -> None:
    from brdfpipe.registry import tables

    assert tables.columns(tables.ERRORS, "fov", "value") == ("fov", "value")
    with pytest.raises(ValueError, match="column.s. fov_deg not in the table"):
        tables.columns(tables.ERRORS, "fov_deg")


def test_the_directions_format_has_one_tag() -> None:
    from brdfpipe.rendering import capture

    assert "brdfpipe.directions" not in inspect.getsource(capture)


def test_a_space_that_is_not_linear_needs_its_inverse_before_blending(monkeypatch: pytest.MonkeyPatch) -> None:
    """A new non-linear space is refused where blends become tables, never blended as raw values."""
    from brdfpipe.manifold import spaces

    for name in man_spec.SPACE_NAMES:
        assert spaces.check_blendable(name) == name
    monkeypatch.setitem(man_spec.DATA_SPACES, "sqrt", man_spec.DataSpace("sqrt", False, "√ρ"))
    monkeypatch.setitem(spaces.MAPS, "sqrt", spaces.SpaceMaps(spaces.MAPS["raw"].cell_maps, spaces.MAPS["raw"].forward))
    with pytest.raises(ValueError, match="'sqrt' is not linear and has no inverse in its maps"):
        spaces.check_blendable("sqrt")
    with pytest.raises(ValueError, match="unknown data space 'lab'"):
        spaces.check_blendable("lab")
