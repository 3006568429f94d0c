"""Materials outside the training database (config ``unseen``, issue 22 item 3).

Library-level checks of: which unseen materials a config names
(:func:`brdfpipe.data.database.unseen_databases`), their stores and albedos
(:func:`brdfpipe.data.nbrdf.evaluate_to_store`), their latent positions on a
fitted GPLVM (:mod:`brdfpipe.manifold.unseen`, :func:`brdfpipe.manifold.gram.cross_gram`),
their table-lookup reconstruction (:mod:`brdfpipe.acquisition.unseen`, on a
model of six MERL fits), the spectralon claim and the plan; then one shared
run of ``tests/config/tiny-nbrdf.yaml`` end to end.  The many-material
capture is compared with the one-material capture in ``test_closedloop.py``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from brdfpipe import plan
from brdfpipe.core import filenames, integrity
from brdfpipe.data import database, databases, ingest, merl, nbrdf, store
from brdfpipe.manifold import fitting, gplvm, gram, likelihood, unseen
from brdfpipe.manifold.gram import MEAN_HANDLING, cross_gram, gram_matrix
from brdfpipe.manifold.spaces import STANDARDISED_FLOOR
from brdfpipe.registry import tables

RESULTS = "results"


def _run_db(**over: object) -> database.Database:
    return database.configured_database({"database": "merl-nbrdf", **over})


# -- which materials ----------------------------------------------------------


def test_unseen_materials_of_a_config() -> None:
    run = _run_db()
    got = database.unseen_databases({"unseen": {"databases": ["rgl-nbrdf", "nielsen-nbrdf"], "materials": None}},
                                    run, RESULTS)
    assert list(got) == ["rgl-nbrdf", "nielsen-nbrdf"]
    assert len(got["rgl-nbrdf"].materials) == 51 and len(got["nielsen-nbrdf"].materials) == 8
    assert got["rgl-nbrdf"].kind == "rgl-nbrdf" and got["rgl-nbrdf"].fits["spectralon-rgb"] == "spectralon_rgb"
    assert got["rgl-nbrdf"].sources["spectralon-rgb"] == Path(filenames.unseen_binary("rgl-nbrdf", "spectralon-rgb"))
    # patterns pick among every unseen database; a database left with none is dropped
    got = database.unseen_databases({"unseen": {"databases": ["rgl-nbrdf", "nielsen-nbrdf"],
                                                "materials": ["spectralon-*", "paper-*"]}}, run, RESULTS)
    assert list(got) == ["rgl-nbrdf"]
    assert got["rgl-nbrdf"].materials == ["paper-blue-rgb", "paper-green-rgb", "paper-red-rgb", "paper-white-rgb",
                                          "paper-yellow-rgb", "spectralon-rgb"]
    assert database.unseen_databases({"unseen": {"databases": [], "materials": None}}, run) == {}
    # unset: the default set on MERL's materials, none on another database (whose own fits may be in the set)
    got = database.unseen_databases({}, run)
    assert {n: tuple(db.materials) for n, db in got.items()} == {
        n: tuple(sorted(ms)) for n, ms in database.DEFAULT_UNSEEN.items()}
    assert "spectralon-rgb" in got["rgl-nbrdf"].materials
    assert database.unseen_databases({"unseen": {"databases": None, "materials": None}}, run) == got
    assert database.unseen_databases({}, _run_db(database="rgl-nbrdf")) == {}
    assert database.unseen_databases({}, database.Database("synthetic", {"a": Path("a.binary")})) == {}


@pytest.mark.parametrize("name", ["merl-nbrdf", "rgl-nbrdf", "nielsen-nbrdf"])
def test_the_shipped_config_on_each_database_of_fits(name: str) -> None:
    """config/config.yaml with only ``database`` changed: the default set on MERL's fits, none (no error) elsewhere."""
    import yaml
    from snakemake.utils import validate

    root = Path(__file__).resolve().parents[1]
    cfg = yaml.safe_load((root / "config" / "config.yaml").read_text())
    cfg["database"] = name
    validate(cfg, str(root / "workflow" / "schemas" / "config.schema.yaml"), set_default=True)
    got = database.unseen_databases(cfg, database.configured_database(cfg), RESULTS)
    if name == "merl-nbrdf":
        assert sum(len(db.materials) for db in got.values()) == 8 and "spectralon-rgb" in got["rgl-nbrdf"].materials
    else:
        assert got == {}


@pytest.mark.parametrize("spec,message", [
    ({"databases": ["merl-nbrdf"]}, "unseen.databases: merl-nbrdf is the run's own database"),
    ({"databases": ["synthetic"]}, "unseen.databases: 'synthetic' is not a shipped database of fits"),
    ({"databases": ["nbrdf"]}, "unseen.databases: 'nbrdf' is not a shipped database of fits"),
    ({"databases": ["rgl-nbrdf", "rgl-nbrdf"]}, "unseen.databases: listed more than once: rgl-nbrdf"),
    ({"databases": [], "materials": ["x"]}, "unseen.materials is set but unseen.databases is empty"),
    ({"materials": ["spectralon-rgb"]}, "unseen.materials is set but unseen.databases is not"),
    ({"databases": ["rgl-nbrdf"], "materials": ["spectralon-rgb", "no-such-*"]},
     "unseen.materials: 'no-such-*' match(es) no material of rgl-nbrdf"),
])
def test_bad_unseen_config_is_one_line_naming_the_key(spec: dict, message: str) -> None:
    with pytest.raises(database.DatabaseError) as err:
        database.unseen_databases({"unseen": spec}, _run_db(), RESULTS)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_material_the_model_has_seen_is_not_unseen() -> None:
    # a run on a folder whose materials include an RGL fit's name: that material is not unseen
    run = database.Database("merl", {"spectralon-rgb": Path("x.binary"), "alum-bronze": Path("y.binary")})
    with pytest.raises(database.DatabaseError, match="spectralon-rgb .rgl-nbrdf. is also a material of the run's"):
        database.unseen_databases({"unseen": {"databases": ["rgl-nbrdf"], "materials": None}}, run, RESULTS)


def test_schema_offers_the_shipped_databases_of_fits() -> None:
    import yaml

    schema = yaml.safe_load((Path(__file__).resolve().parents[1] / "workflow" / "schemas"
                             / "config.schema.yaml").read_text())
    entry = schema["properties"]["unseen"]["properties"]["databases"]
    assert entry["items"]["enum"] == list(database.UNSEEN_DATABASES)
    assert set(database.UNSEEN_DATABASES) == {n for n, d in databases.DATABASES.items() if d.source == "archive"}


# -- stores, albedos ----------------------------------------------------------


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A training store of six MERL fits and an unseen store of two RGL fits (each with its tables)."""
    d = tmp_path_factory.mktemp("unseen")
    out = {}
    for label, names in (("merl-nbrdf", ["alum-bronze", "blue-acrylic", "gold-paint", "red-plastic", "teflon",
                                         "white-paint"]),
                         ("rgl-nbrdf", ["paper-red-rgb", "spectralon-rgb"])):
        fits = {m: m.replace("-", "_") if label == "rgl-nbrdf" else m for m in names}
        nbrdf.evaluate_to_store(archive=databases.shipped_archive(label), fits=fits,
                                binaries=[d / label / f"{m}.binary" for m in names],
                                store_out=d / f"{label}.zarr", albedo_out=d / f"{label}-albedo.csv",
                                database=label, threads=2)
        out[label] = d / f"{label}.zarr"
        out[f"{label}-albedo"] = d / f"{label}-albedo.csv"
        out[f"{label}-tables"] = d / label
    return out


def test_unseen_store_albedos_and_labels(stores: dict[str, Path]) -> None:
    st = store.open_store(stores["rgl-nbrdf"])
    assert st.database == "rgl-nbrdf" and list(st.materials) == ["paper-red-rgb", "spectralon-rgb"]
    table = merl.read_merl(stores["rgl-nbrdf-tables"] / "spectralon-rgb.binary")
    np.testing.assert_array_equal(st.brdf[1], table.reshape(-1).astype(np.float32))
    _, albedo_rows = integrity.read_csv_rows(stores["rgl-nbrdf-albedo"])  # written with its digest
    rows = {r["material"]: r for r in albedo_rows}
    assert list(next(iter(rows.values()))) == list(tables.FIT_ALBEDO)
    spec = rows["spectralon-rgb"]
    assert spec["database"] == "rgl-nbrdf" and float(spec["theta_i_deg"]) == 0.0
    # an independent evaluation of the same integral: the directional albedo of the table at θi = 0
    want = merl.directional_albedo(table, [0.0])[0]
    np.testing.assert_allclose([float(spec[c]) for c in "rgb"], want, rtol=1e-12)
    assert 0.9 < float(spec["luminance"]) < 1.0  # a near-white diffuse reflector
    assert float(rows["paper-red-rgb"]["r"]) > 2 * float(rows["paper-red-rgb"]["b"])


def test_fits_of_another_database_are_refused(tmp_path: Path) -> None:
    with pytest.raises(nbrdf.NbrdfError, match="are not those of the rgl-nbrdf database"):
        nbrdf.evaluate_to_store(archive=databases.shipped_archive("merl-nbrdf"), fits={"teflon": "teflon"},
                                binaries=[tmp_path / "teflon.binary"], store_out=tmp_path / "x.zarr",
                                albedo_out=tmp_path / "a.csv", database="rgl-nbrdf")
    assert not (tmp_path / "x.zarr").exists() and not (tmp_path / "a.csv").exists()


# -- the manifold ---------------------------------------------------------------


class Toy:
    """A GPLVM of 12 random 'materials' (d = 60): Gram, model and the data, dense."""

    def __init__(self, q: int = 2, mu: float = 1e-4) -> None:
        rng = np.random.default_rng(5)
        base = rng.normal(size=(3, 60))
        t = rng.uniform(-1, 1, size=(12, 3))
        self.Z = np.tanh(t @ base) + 0.05 * rng.normal(size=(12, 60))
        self.mean = self.Z.mean(axis=0)
        self.Y = self.Z - self.mean
        self.G = self.Y @ self.Y.T
        scale = likelihood.gram_scale(self.G, 60)
        res = fitting.fit(self.G / scale, 60, q=q, mu=mu, method="newton")
        names = [f"m{i:02d}" for i in range(12)]
        self.model = gplvm.GplvmModel(tuple(names), res.X, res.ell, res.mu, "raw", MEAN_HANDLING,
                                      np.linalg.cholesky(likelihood.kernel_matrix(res.X, res.ell, res.mu)),
                                      res.log_likelihood, 60.0, np.zeros((0, 2)), scale, res.method)

    def objective(self, z: np.ndarray) -> unseen.Objective:
        y = z - self.mean
        return unseen.Objective(self.model, self.G, self.Y @ y, float(y @ y), 60.0)


@pytest.fixture(scope="module")
def toy() -> Toy:
    return Toy()


def test_a_training_material_is_placed_at_its_own_latent_point(toy: Toy) -> None:
    for j in (0, 5, 11):
        obj = toy.objective(toy.Z[j])
        ls = unseen.locate(obj, "least-squares", norm=float(np.linalg.norm(toy.Z[j])))
        assert np.array_equal(ls.x, toy.model.X[j]) and ls.nearest == f"m{j:02d}"
        assert ls.relative_error < 1e-6
        gp = unseen.locate(obj, "likelihood", norm=1.0)
        spacing = np.sort(np.linalg.norm(toy.model.X - toy.model.X[j], axis=1))[1]
        assert np.linalg.norm(gp.x - toy.model.X[j]) < 1e-3 * spacing, (gp.x, toy.model.X[j])
        assert gp.nearest == f"m{j:02d}"


def test_least_squares_recovers_a_blend_of_training_materials(toy: Toy) -> None:
    X = toy.model.X
    x0 = 0.6 * X[2] + 0.4 * X[7]
    w = gplvm.blend_weights(gplvm.weights(toy.model, x0))
    z = w @ toy.Z
    obj = toy.objective(z)
    ls = unseen.locate(obj, "least-squares", norm=float(np.linalg.norm(z)))
    assert ls.relative_error < 1e-5
    assert np.linalg.norm(ls.x - x0) < 1e-3 * np.linalg.norm(X[2] - X[7])
    # R by the objective agrees with the dense residual of the interpolant
    zhat = gplvm.blend_weights(gplvm.weights(toy.model, ls.x)) @ toy.Z
    assert math.isclose(obj.residual_at(ls.x), float(np.sum((z - zhat) ** 2)), rel_tol=1e-6, abs_tol=1e-12)


def test_the_likelihood_is_the_fit_objective_gained_by_adding_the_material(toy: Toy) -> None:
    """log p(y | x) = L(X ∪ x, Y ∪ y) − L(X, Y) (Soler eq. 6 on G/s), up to the constant term."""
    rng = np.random.default_rng(1)
    z = toy.Z[3] + 0.3 * rng.normal(size=60)
    obj = toy.objective(z)
    s = toy.model.gram_scale
    Yplus = np.vstack([toy.Y, z - toy.mean])
    base = likelihood.log_likelihood(toy.model.X, toy.G / s, 60, toy.model.ell, toy.model.mu)
    values = []
    for x in (toy.model.X[3] + 0.05, toy.model.X[8] - 0.2, np.array([3.0, -2.0])):
        joint = likelihood.log_likelihood(np.vstack([toy.model.X, x]), Yplus @ Yplus.T / s, 60, toy.model.ell,
                                     toy.model.mu)
        values.append((joint - base, obj.log_likelihood(x)))
    diffs = [a - b for a, b in values]
    assert max(diffs) - min(diffs) < 1e-6 * max(abs(a) for a, _ in values)


def test_objective_gradients_match_finite_differences(toy: Toy) -> None:
    obj = toy.objective(toy.Z[4] + 0.1)
    x = toy.model.X[4] + np.array([0.07, -0.05])
    for fun in (obj._ls, obj._nll):  # noqa: SLF001 - the optimiser's own functions
        f, g = fun(x)
        h = 1e-6
        fd = [(fun(x + h * e)[0] - fun(x - h * e)[0]) / (2 * h) for e in np.eye(2)]
        np.testing.assert_allclose(g, fd, rtol=1e-4, atol=1e-8 * max(1.0, abs(f)))


def test_pca_residuals_equal_an_explicit_projection(toy: Toy) -> None:
    rng = np.random.default_rng(2)
    Z = rng.normal(size=(3, 60))
    ys = Z - toy.mean
    got = unseen.pca_residuals(toy.G, toy.Y @ ys.T, np.einsum("ij,ij->i", ys, ys), [1, 3, 20])
    _, _, Vt = np.linalg.svd(toy.Y, full_matrices=False)
    for k, kk in ((1, 1), (3, 3), (20, 11)):  # capped at N − 1 = 11
        P = Vt[:kk]
        want = np.sum((ys - (ys @ P.T) @ P) ** 2, axis=1)
        np.testing.assert_allclose(got[k], want, rtol=1e-8)


def test_cross_gram_equals_a_dense_computation(stores: dict[str, Path]) -> None:
    train, other = store.open_store(stores["merl-nbrdf"]), store.open_store(stores["rgl-nbrdf"])
    cells = np.flatnonzero(np.asarray(train.valid[:], dtype=bool))
    wi, wo = merl.cell_directions(cells)
    root_cos = np.sqrt(np.maximum(wi[:, 2] * wo[:, 2], 0.0))

    def rows(st: store.BrdfStore) -> np.ndarray:
        return np.stack([np.asarray(st.brdf[i], dtype=np.float64).reshape(3, -1)[:, cells]
                         for i in range(st.n_materials)])

    Zt, Zo = rows(train), rows(other)
    scale = root_cos / np.maximum(Zt.std(axis=0), STANDARDISED_FLOOR)
    T, O = (Zt * scale).reshape(len(Zt), -1), (Zo * scale).reshape(len(Zo), -1)
    mean = T.mean(axis=0)
    got = cross_gram(train, [other], space="standardised")
    assert got.others == (("rgl-nbrdf", "paper-red-rgb"), ("rgl-nbrdf", "spectralon-rgb"))
    np.testing.assert_allclose(got.gram, (T - mean) @ (T - mean).T, rtol=1e-9, atol=1e-9 * np.abs(got.gram).max())
    np.testing.assert_allclose(got.cross, (T - mean) @ (O - mean).T, rtol=1e-9, atol=1e-9 * np.abs(got.cross).max())
    np.testing.assert_allclose(got.norms2, np.sum((O - mean) ** 2, axis=1), rtol=1e-9)
    np.testing.assert_allclose(got.raw_norms2, np.sum(O ** 2, axis=1), rtol=1e-9)
    gram, d, _ = gram_matrix(train, space="standardised")
    assert d == got.d and np.abs(gram - got.gram).max() <= 1e-12 * np.abs(gram).max()


def test_unseen_csv_of_the_manifold(stores: dict[str, Path], tmp_path: Path) -> None:
    gram.write_gram(stores["merl-nbrdf"], tmp_path / "gram.npz", space="standardised")
    models = {}
    for q in (1, 2):
        models[q] = tmp_path / f"q{q}.npz"
        gplvm.fit_to_files(tmp_path / "gram.npz", models[q], tmp_path / f"q{q}.csv", q=q, mu=1e-4)
    out = unseen.write_unseen(tmp_path / "unseen.csv", store=stores["merl-nbrdf"], gram=tmp_path / "gram.npz",
                              models=models, unseen_stores=[stores["rgl-nbrdf"]], pca_ks=[3, 20])
    _, rows = integrity.read_csv_rows(out)  # written with its digest
    assert list(rows[0]) == list(tables.MANIFOLD_UNSEEN)
    assert {r["database"] for r in rows} == {"rgl-nbrdf"} and {r["model_database"] for r in rows} == {"merl-nbrdf"}
    assert {r["space"] for r in rows} == {"standardised"}
    by = {(r["material"], r["method"], int(r["k"])): r for r in rows}
    # per material: 2 methods × 2 q, PCA at k = 1, 2, 3 and 20 capped at N − 1 = 5
    assert sorted(k for (m, meth, k) in by if m == "spectralon-rgb" and meth == "pca") == [1, 2, 3, 5]
    for m in ("spectralon-rgb", "paper-red-rgb"):
        for q in (1, 2):
            for meth in ("gplvm-likelihood", "gplvm-least-squares"):
                r = by[(m, meth, q)]
                assert len(r["latent"].split()) == q and r["nearest"] in store.open_store(stores["merl-nbrdf"]).materials
                assert 0 < float(r["relative_error"]) and math.isfinite(float(r["log_likelihood"]))
            # least squares minimises the reproduction error the likelihood trades against σ²
            assert float(by[(m, "gplvm-least-squares", q)]["relative_error"]) <= \
                float(by[(m, "gplvm-likelihood", q)]["relative_error"]) * (1 + 1e-9)
        # PCA with more components reproduces better
        assert float(by[(m, "pca", 5)]["relative_error"]) <= float(by[(m, "pca", 1)]["relative_error"])
    # a Gram matrix of another space: the materials would be mapped to the wrong space
    gram.write_gram(stores["merl-nbrdf"], tmp_path / "gram-raw.npz", space="raw")
    G_raw, _, _ = gram.load_gram(tmp_path / "gram-raw.npz")
    cross = cross_gram(stores["merl-nbrdf"], [stores["rgl-nbrdf"]], space="standardised")
    with pytest.raises(ValueError, match="differs from the models'"):
        unseen.unseen_rows(cross, {2: gplvm.load_model(models[2])}, gram=G_raw, model_database="merl-nbrdf")


def test_a_store_not_measured_where_the_model_is_is_refused(stores: dict[str, Path], tmp_path: Path) -> None:
    # a table measuring fewer cells (one more θh row unmeasured) cannot be mapped to the training space
    table = merl.read_merl(stores["rgl-nbrdf-tables"] / "spectralon-rgb.binary")
    table[:, 3] = -1.0 * merl.SCALES[:, None, None]
    from brdfpipe.data import provenance

    merl.write_merl(tmp_path / "holey.binary", table, mark=provenance.fit_mark(
        database="rgl-nbrdf", name="holey", fit="spectralon_rgb", archive="x.zip", fit_sha256="0" * 64, clamped=0))
    ingest.ingest({"holey": tmp_path / "holey.binary"}, tmp_path / "holey.zarr", database="rgl-nbrdf")
    with pytest.raises(ValueError, match="holey.zarr: .* cell.s. valid in every material"):
        cross_gram(stores["merl-nbrdf"], [tmp_path / "holey.zarr"], space="raw")


# -- the plan -------------------------------------------------------------------


def test_plan_of_the_unseen_materials() -> None:
    acq = {"metrics": ["error", "condition"], "setups": ["point", "nearfield", "fixed_camera"], "fovs": [15, 25]}
    assert plan.unseen_directions(acq) == [filenames.directions("train", "point", 0, "error"),
                                           filenames.directions("train", "nearfield", 15, "error"),
                                           filenames.directions("train", "nearfield", 25, "error")]
    assert plan.unseen_directions({**acq, "metrics": ["condition"]}) == []
    assert plan.unseen_figures(unseen=False, evaluated=True) == {}
    assert set(plan.unseen_figures(unseen=True, evaluated=True)) == {"acquisition", "manifold"}
    assert set(plan.unseen_figures(unseen=True, evaluated=False)) == {"manifold"}
    assert plan.unseen_map_q({"latent_dims": [5, 2]}) == 2 and plan.unseen_map_q({"latent_dims": [3, 5]}) == 3


# -- the acquisition (table lookup) ----------------------------------------------


class Acq:
    """The merl-nbrdf store's model (teflon held out: 5 training materials) and two optimised directions files.

    ``unseen``: a store labelled rgl-nbrdf of the two RGL fits and copies, marked as RGL tables, of a
    training material (``copy-gold-paint``) and of the held-out one (``copy-teflon``).
    """

    def __init__(self, d: Path, stores: dict[str, Path]) -> None:
        from brdfpipe.acquisition import geometry, optimize, svd
        from brdfpipe.data import logmap, provenance

        st = store.open_store(stores["merl-nbrdf"])
        self.store = stores["merl-nbrdf"]
        self.train = [m for m in st.materials if m != "teflon"]
        logmap.write_logmap(self.store, d / "logmap.zarr", split="train", materials_train=self.train)
        self.model = d / "svd.zarr"
        svd.fit(d / "logmap.zarr", self.model)
        mdl = svd.open_model(self.model)
        self.dirs = []
        for kind, fov, n_max in (("point", 0.0, 3), ("nearfield", 25.0, 2)):
            setup = geometry.Setup(kind, fov, 16)
            sets = optimize.optimize(mdl, setup, metric="error", n_max=n_max, candidates=6, steps=(1,), seed=3,
                                     log=lambda line: None)
            self.dirs.append(optimize.write_directions(
                d / filenames.directions("train", kind, fov, "error"), sets, setup=setup, metric="error",
                split="train", model_path=self.model, seed=3, eta=40.0, beta=0.0, database=mdl.database))
        sources = {m: stores["rgl-nbrdf-tables"] / f"{m}.binary" for m in ("paper-red-rgb", "spectralon-rgb")}
        for m in ("gold-paint", "teflon"):
            table = merl.read_merl(stores["merl-nbrdf-tables"] / f"{m}.binary")
            sources[f"copy-{m}"] = d / f"copy-{m}.binary"
            merl.write_merl(sources[f"copy-{m}"], table, mark=provenance.fit_mark(
                database="rgl-nbrdf", name=f"copy-{m}", fit=m, archive="x.zip", fit_sha256="0" * 64, clamped=0))
        self.unseen = d / "unseen.zarr"
        ingest.ingest(sources, self.unseen, database="rgl-nbrdf")


@pytest.fixture(scope="module")
def acq(stores: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Acq:
    return Acq(tmp_path_factory.mktemp("unseen-acq"), stores)


def _by_key(rows: list[dict], material: str) -> dict[tuple, float]:
    """(setup, fov, metric, n, channel, kind) → value of one material's rms_log and deviation rows ("all": mean)."""
    out = {(r["setup"], float(r["fov"]), r["metric"], int(r["n"]), r["channel"], r["kind"]): r["value"]
           for r in rows if r["material"] == material and r["kind"] in ("rms_log", "deviation")}
    for key in {k[:4] + k[5:] for k in out}:
        out[(*key[:4], "all", key[4])] = float(np.mean([out[(*key[:4], ch, key[4])] for ch in ("R", "G", "B")]))
    return out


def test_unseen_csv_columns_labels_and_the_held_out_identity(acq: Acq, tmp_path: Path) -> None:
    from brdfpipe.acquisition import evaluation
    from brdfpipe.acquisition import unseen as acq_unseen

    out = acq_unseen.write_unseen(tmp_path / "unseen.csv", stores={"rgl-nbrdf": acq.unseen}, model=acq.model,
                                  directions=acq.dirs)
    header, rows = integrity.read_csv_rows(out, required=tables.UNSEEN_ERRORS)
    assert tuple(header) == tables.UNSEEN_ERRORS == ("database", "model_database", *tables.ERRORS[1:])
    assert {r["database"] for r in rows} == {"rgl-nbrdf"}  # the material's own database, never merl
    assert {r["model_database"] for r in rows} == {"merl-nbrdf"} and {r["split"] for r in rows} == {"train"}
    assert {r["material"] for r in rows} == {"paper-red-rgb", "spectralon-rgb", "copy-gold-paint", "copy-teflon",
                                             "mean"}
    # every set of both files (n = 1..3 points, 1..2 images) and the floor, per material and channel
    sets = {(r["setup"], r["n"]) for r in rows if r["kind"] == "rms_log"}
    assert sets == {("point", "1"), ("point", "2"), ("point", "3"), ("nearfield", "1"), ("nearfield", "2")}
    # the held-out material, copied into another database's store, gets exactly its leave-out evaluation
    rows_d = [{**r, "value": float(r["value"])} for r in rows]
    held = evaluation.evaluate(acq.store, acq.model, acq.dirs, test_materials=["teflon"])
    want, got = _by_key(held, "teflon"), _by_key(rows_d, "copy-teflon")
    assert set(want) == set(got) and len(got) == (5 + 1) * 4  # (5 sets + the floor) × (R, G, B, all)
    for k, v in want.items():
        assert math.isclose(got[k], v, rel_tol=1e-9, abs_tol=1e-12), (k, got[k], v)


def test_a_training_material_as_unseen_reproduces_with_small_error(acq: Acq) -> None:
    from brdfpipe.acquisition import unseen as acq_unseen

    rows = acq_unseen.evaluate_unseen(stores={"rgl-nbrdf": acq.unseen}, model=acq.model, directions=acq.dirs)
    mine, other = _by_key(rows, "copy-gold-paint"), _by_key(rows, "spectralon-rgb")
    # in the span of the basis (5 training materials): reconstructed from every cell, it is itself
    assert max(v for k, v in mine.items() if k[-1] == "deviation") < 1e-5
    # and every set reconstructs it better than a material the model never saw (mean over channels)
    sets = {k[:4] for k in mine if k[-1] == "rms_log"}
    assert len(sets) == 5
    for s in sets:
        assert mine[(*s, "all", "rms_log")] < 0.6 * other[(*s, "all", "rms_log")], s


def test_unseen_evaluation_refuses_the_models_own_database(acq: Acq) -> None:
    from brdfpipe.acquisition import unseen as acq_unseen

    with pytest.raises(ValueError, match="is the model's own"):
        acq_unseen.evaluate_unseen(stores={"merl-nbrdf": acq.store}, model=acq.model, directions=acq.dirs)
    with pytest.raises(ValueError, match="is database 'rgl-nbrdf', expected 'nielsen-nbrdf'"):
        acq_unseen.evaluate_unseen(stores={"nielsen-nbrdf": acq.unseen}, model=acq.model, directions=acq.dirs)


# -- end to end: tests/config/tiny-nbrdf.yaml (12 MERL fits, 2 unseen materials) ------------------


@pytest.mark.slow
def test_tiny_nbrdf_runs_the_unseen_materials_end_to_end(tmp_path_factory: pytest.TempPathFactory) -> None:
    """One shared run of tiny-nbrdf (69 jobs): the unseen outputs exist, carry their digests and true labels."""
    from shared_runs import shared_run

    check_tiny_nbrdf_run(shared_run(tmp_path_factory, Path(__file__).resolve().parent / "config" / "tiny-nbrdf.yaml"))


def check_tiny_nbrdf_run(work: Path) -> None:
    """The unseen materials' outputs of a finished run of tiny-nbrdf in ``work``."""
    from brdfpipe.acquisition import unseen as acq_unseen
    from brdfpipe.report import claims

    res = work / "results"
    # the table lookup and the closed loop of both materials, with the MERL-trained model
    _, rows = integrity.read_csv_rows(res / "evaluation" / "unseen.csv", required=tables.UNSEEN_ERRORS)
    assert {(r["database"], r["material"]) for r in rows if r["material"] != "mean"} == {
        ("rgl-nbrdf", "spectralon-rgb"), ("nielsen-nbrdf", "glossyredpaper")}
    assert {r["model_database"] for r in rows} == {"merl-nbrdf"}
    kinds = {r["kind"] for r in rows}
    assert {"rms_log", "deviation", "closedloop_rms_log", "closedloop_noiseless_rms_log"} <= kinds
    assert {r["setup"] for r in rows if r["kind"] == "rms_log"} == {"point", "nearfield"}
    assert all(math.isfinite(float(r["value"])) for r in rows)
    # the manifold: both ways of placing each material, and PCA
    _, mrows = integrity.read_csv_rows(res / "manifold" / "unseen.csv", required=tables.MANIFOLD_UNSEEN)
    assert {r["method"] for r in mrows} == {"gplvm-likelihood", "gplvm-least-squares", "pca"}
    assert {r["database"] for r in mrows} == {"rgl-nbrdf", "nielsen-nbrdf"}
    # the radiometric check holds on the spectralon fit, and each unseen database has its claim
    _, crows = integrity.read_csv_rows(work / filenames.claims_csv(), required=claims.CLAIM_COLUMNS)
    by_key = {c["key"]: c for c in crows}
    spectralon = by_key["unseen-rgl-spectralon-albedo"]
    assert spectralon["verdict"] == claims.REPRODUCES and spectralon["database"] == "rgl-nbrdf"
    assert spectralon["paper"] == claims.OURS  # a radiometric check of ours, not a claim of a paper
    assert abs(float(spectralon["value"]) - 0.96) < 0.03
    assert {"unseen-xu-rgl-nbrdf", "unseen-xu-nielsen-nbrdf"} <= set(by_key)
    # the side-by-side page heads the run's column by the run's own database, the unseen rows naming theirs
    from brdfpipe.report import sidebyside

    page = sidebyside.side_by_side_markdown([sidebyside.read_run(work / filenames.claims_csv())])
    assert next(line for line in page.splitlines() if line.startswith("| paper")).endswith(
        "| merl-nbrdf: verdict — cause |")
    assert "luminance 0.9" in page.split("## Our own checks")[1]
    for stem in (filenames.UNSEEN_STEM, filenames.MANIFOLD_UNSEEN_STEM):
        assert all((work / f).stat().st_size > 0 for f in filenames.figure_files(stem))
    # every store carries its own label: the unseen fits are never labelled merl
    assert store.open_store(res / "unseen" / "rgl-nbrdf.zarr").database == "rgl-nbrdf"
    assert store.open_store(res / "unseen" / "nielsen-nbrdf.zarr").database == "nielsen-nbrdf"


def test_spectralon_claim(tmp_path: Path) -> None:
    from brdfpipe.report import claims

    def albedo_csv(name: str, database: str, material: str, lum: float) -> Path:
        path = tmp_path / name
        integrity.write_csv(path, [list(tables.FIT_ALBEDO), [database, material, 0.0, lum, lum, lum, lum]])
        return path

    ok = claims.spectralon_albedo([albedo_csv("a.csv", "rgl-nbrdf", "spectralon-rgb", 0.958)])
    assert ok.verdict == claims.REPRODUCES and ok.database == "rgl-nbrdf" and math.isclose(ok.value, 0.958)
    assert "±0.03 of 0.96" in ok.claim  # the tolerance is in the row's text
    dark = claims.spectralon_albedo([albedo_csv("b.csv", "rgl-nbrdf", "spectralon-rgb", 0.80)])
    assert dark.verdict == claims.DIFFERS and dark.cause.startswith("the data: luminance 0.800")
    absent = claims.spectralon_albedo([albedo_csv("c.csv", "nielsen-nbrdf", "bluebook", 0.3)])
    assert absent.verdict == claims.NOT_CHECKABLE and absent.cause.startswith("not measured by this run")
    with pytest.raises(claims.ClaimsInputError, match="appears twice"):
        claims.spectralon_albedo([tmp_path / "a.csv", albedo_csv("d.csv", "rgl-nbrdf", "spectralon-rgb", 0.95)])


def test_unseen_claims_do_not_change_the_runs_database_side_by_side(tmp_path: Path) -> None:
    from brdfpipe.report import claims, sidebyside

    def claim(key: str, database: str) -> claims.Claim:
        return claims.Claim(key=key, paper="Xu 2016", where="§7", sentence="-", claim=key, measured=f"{database} m",
                            value=1.0, verdict=claims.REPRODUCES, cause="c", database=database, source="x.csv")

    rows = [claim("one_shot", "merl-nbrdf"), claim(f"{claims.UNSEEN_CLAIM_PREFIX}xu-rgl-nbrdf", "rgl-nbrdf"),
            claim(f"{claims.UNSEEN_CLAIM_PREFIX}rgl-spectralon-albedo", "rgl-nbrdf")]
    claims.write_claims(rows, csv_path=tmp_path / "c.csv", json_path=tmp_path / "c.json", rst_path=tmp_path / "c.rst")
    assert sidebyside.read_run(tmp_path / "c.csv").database == "merl-nbrdf"
    # another database among the run's own claims is still refused
    claims.write_claims([*rows, claim("albedo", "synthetic")], csv_path=tmp_path / "d.csv",
                        json_path=tmp_path / "d.json", rst_path=tmp_path / "d.rst")
    with pytest.raises(claims.ClaimsInputError, match="claims of several databases"):
        sidebyside.read_run(tmp_path / "d.csv")


def test_a_training_material_as_unseen_sits_at_its_own_latent_point(stores: dict[str, Path], acq: Acq,
                                                                     tmp_path: Path) -> None:
    """Real tables: a copy of a training material (another store, another label) is placed on its own x_i."""
    gram.write_gram(stores["merl-nbrdf"], tmp_path / "gram.npz", space="standardised")
    gplvm.fit_to_files(tmp_path / "gram.npz", tmp_path / "q2.npz", tmp_path / "q2.csv", q=2, mu=1e-4)
    out = unseen.write_unseen(tmp_path / "unseen.csv", store=stores["merl-nbrdf"], gram=tmp_path / "gram.npz",
                              models={2: tmp_path / "q2.npz"}, unseen_stores=[acq.unseen], pca_ks=[5])
    _, rows = integrity.read_csv_rows(out)
    by = {(r["material"], r["method"]): r for r in rows}
    model = gplvm.load_model(tmp_path / "q2.npz")
    for m in ("gold-paint", "teflon"):  # both in the manifold's store (the SVD's split is not the manifold's)
        own = model.X[list(model.names).index(m)]
        ls = by[(f"copy-{m}", "gplvm-least-squares")]
        assert ls["nearest"] == m and float(ls["relative_error"]) < 1e-6
        np.testing.assert_array_equal([float(v) for v in ls["latent"].split()], own)
        # PCA on all N − 1 = 5 components of the centred training set reproduces it too
        assert float(by[(f"copy-{m}", "pca")]["relative_error"]) < 1e-6
    # the RGL materials are reproduced by neither
    for m in ("spectralon-rgb", "paper-red-rgb"):
        assert float(by[(m, "gplvm-least-squares")]["relative_error"]) > 1e-3
        assert float(by[(m, "pca")]["relative_error"]) > 1e-3
