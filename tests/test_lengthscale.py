"""Soler Fig. 6: the interpolant and the eq. 7 bound as the length scale shrinks (brdfpipe.manifold.lengthscale).

A small GPLVM fitted to random data: every deviation is checked against the
blend formed from the data matrix itself (not the Gram matrix the module
uses), every bound against eq. 7 evaluated here, and the limit the paper
states (ℓ → 0: the mean of the materials everywhere but next to them).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from brdfpipe.core import integrity
from brdfpipe.core.notes import read_note
from brdfpipe.core.plot import FigureInputError
from brdfpipe.manifold import fitting, gplvm, gram, lengthscale, likelihood
from brdfpipe.manifold.lengthscale_figure import draw_lengthscale_figure, read_lengthscales

N, D = 9, 40
NAMES = tuple(f"m{i}" for i in range(N))


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> tuple[gplvm.GplvmModel, np.ndarray, Path, Path]:
    """A q = 2 model of random data (no store), the centred data Z (N × D), the model's and the Gram's files."""
    rng = np.random.default_rng(6)
    Z = rng.normal(size=(N, D)) * np.linspace(3.0, 0.1, D)
    Z -= Z.mean(axis=0)
    G = Z @ Z.T
    folder = tmp_path_factory.mktemp("lengthscale")
    mpath, gpath = folder / "q2.npz", folder / "gram.npz"
    gplvm.save_model(mpath, fitting.fit(G, D, q=2, mu=1e-4, max_sweeps=5, polish_iterations=40), NAMES)
    gram.save_gram(gpath, G, D, gram.GramInfo(NAMES, "raw", Z.sum(axis=1), G, "mean subtracted"))
    return gplvm.load_model(mpath), Z, mpath, gpath


def test_deviation_bound_and_mean_distance_are_those_of_the_blended_data(fitted) -> None:
    model, Z, _, _ = fitted
    G = Z @ Z.T
    rows = lengthscale.lengthscale_rows(model, G, "m0", "m5", factors=(0.05, 1.0, 3.0), steps=10)
    assert len(rows) == 3 * 11
    znorm = float(np.linalg.norm(Z))
    # the module takes √(vᵀ G v): its rounding is ~ ε·(Σ|v|)²·max|G|,
    # so its root is off by ~ √ε·Σ|v|·max‖zᵢ‖
    zmax = float(np.linalg.norm(Z, axis=1).max())
    for r in rows:
        ell = r["ell_factor"] * model.ell
        x = (1 - r["t"]) * model.X[0] + r["t"] * model.X[5]
        K = likelihood.kernel_matrix(model.X, ell, model.mu)
        b = np.linalg.solve(K, likelihood.kernel_vector(model.X, x, ell, model.mu))
        w = b + (1 - b.sum()) / N
        z = w @ Z  # the interpolated (centred) data themselves
        j = NAMES.index(r["nearest"])
        assert j == int(np.argmin(np.linalg.norm(model.X - x, axis=1)))
        tol = 4 * math.sqrt(np.finfo(float).eps) * (np.abs(w).sum() + 1) * zmax
        assert r["deviation"] == pytest.approx(np.linalg.norm(z - Z[j]), rel=1e-7, abs=tol)
        assert r["from_mean"] == pytest.approx(np.linalg.norm(z), rel=1e-7, abs=tol)
        kappa = np.linalg.cond(K)
        assert r["kappa"] == pytest.approx(kappa, rel=1e-6)
        bound = math.exp(-0.5) * math.sqrt(2 * N) / ell * kappa * znorm * np.linalg.norm(x - model.X[j])
        assert r["bound"] == pytest.approx(bound, rel=1e-6, abs=1e-12)
        assert r["deviation"] <= r["bound"] * (1 + 1e-9) or r["t"] in (0.0, 1.0)
        assert r["sum_abs_w"] == pytest.approx(np.abs(w).sum())


def test_as_the_length_scale_shrinks_the_interpolant_is_the_mean_but_at_the_materials(fitted) -> None:
    """Soler §4.1: as ℓ → 0 "the interpolated BRDF is the average of all measurements everywhere in the
    domain except very close to the xᵢ" — and at the materials themselves it is still each material."""
    model, Z, _, _ = fitted
    G = Z @ Z.T
    small = min(np.linalg.norm(model.X[i] - model.X[k]) for i in range(N) for k in range(i))
    f = 0.01 * small / model.ell  # ℓ a hundredth of the closest pair's distance: exp(−5000) is 0
    rows = lengthscale.lengthscale_rows(model, G, "m1", "m4", factors=(f,), steps=20)
    ends, inner = [r for r in rows if r["t"] in (0.0, 1.0)], [r for r in rows if 0.0 < r["t"] < 1.0]
    tol = 4 * math.sqrt(np.finfo(float).eps) * 2 * float(np.linalg.norm(Z, axis=1).max())  # as above, Σ|w| = 1
    for r in inner:
        assert r["from_mean"] == pytest.approx(0.0, abs=tol)
        j = NAMES.index(r["nearest"])
        assert r["deviation"] == pytest.approx(np.linalg.norm(Z[j]), rel=1e-9)  # ‖z̄ − z_j‖, z̄ = 0
        assert r["kappa"] == pytest.approx(1.0, abs=1e-12)
    for r in ends:
        assert r["deviation"] == pytest.approx(0.0, abs=tol) and r["bound"] == 0.0


def test_workflow_entry_writes_the_table_and_the_figure_its_note(fitted, tmp_path: Path) -> None:
    _, Z, mpath, gpath = fitted
    G = Z @ Z.T
    out = tmp_path / "lengthscales.csv"
    rows = lengthscale.measure_lengthscales(model=mpath, gram=gpath, path=["m2", "m7"], out=out, database="synthetic")
    assert len(rows) == len(lengthscale.LENGTH_SCALE_FACTORS) * (lengthscale.PROFILE_STEPS + 1)
    tab = read_lengthscales(out)
    assert (tab.material_a, tab.material_b, tab.q) == ("m2", "m7", 2)
    np.testing.assert_allclose(tab.factors, sorted(lengthscale.LENGTH_SCALE_FACTORS))
    fig = draw_lengthscale_figure(out, tmp_path / "fig06")
    assert [p.name for p in fig.files] == ["fig06.png", "fig06.pdf", "fig06.json"]
    note = read_note(tmp_path / "fig06.json")
    assert note == fig.note and "m2 → m7 (q = 2" in note
    fit_row = [r for r in rows if r["ell_factor"] == 1.0 and 0 < r["t"] < 1]
    biggest = max(r["deviation"] for r in fit_row) / rows[0]["z_norm"]
    assert f"largest deviation {biggest:.3g}" in note
    worst = max(r["deviation"] / r["bound"] for r in rows if r["bound"] > 0)
    assert f"(largest ratio {worst:.3g})" in note and ("below" in note) == (worst <= 1)
    integrity.write_csv(tmp_path / "bad.csv", "\n".join(out.read_text().splitlines()[1:-3]) + "\n")  # rows missing
    with pytest.raises(FigureInputError, match="one row per length scale"):
        read_lengthscales(tmp_path / "bad.csv")
    with pytest.raises(ValueError, match="differ"):
        other = tmp_path / "gram2.npz"
        gram.save_gram(other, G, D, gram.GramInfo(NAMES[::-1], "raw", Z.sum(axis=1), G, "mean subtracted"))
        lengthscale.measure_lengthscales(model=mpath, gram=other, path=["m2", "m7"], out=tmp_path / "x.csv",
                                         database="synthetic")
