"""GPLVM candidates that carry their own fit (issue 32 item 5): labels, the config, and the options reaching the fit.

A candidate is a data space and μ and how it is fitted — normalisation, optimiser, start — so the paper's recipe
(raw Gram without normalisation, Hooke–Jeeves from the truncated PCA, μ = 1e-4) is a candidate among the others.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfpipe import plan
from brdfpipe.core import integrity
from brdfpipe.manifold import fitting, gplvm, gram, likelihood
from brdfpipe.registry import manifold as man_spec
from brdfpipe.registry.errors import ConfigError


def test_a_label_names_what_differs_from_the_standard_fit() -> None:
    assert man_spec.candidate_label("raw", 1e-4) == "raw-mu0.0001"  # normalised, newton, best start
    assert man_spec.PAPER_RECIPE.label == "raw-mu0.0001-unnormalised-hooke-jeeves-init-pca"
    assert man_spec.candidate_label("standardised", 1e-5, True, "hybrid", "best") == "standardised-mu1e-05-hybrid"
    assert man_spec.candidate_label("log", 1e-4, True, "newton", "rms") == "log-mu0.0001-init-rms"
    assert man_spec.is_paper_recipe(*man_spec.PAPER_RECIPE)
    assert not man_spec.is_paper_recipe("raw", 1e-4, True, "hooke-jeeves", "pca")  # normalised: this project's
    assert not man_spec.is_paper_recipe(*man_spec.PAPER_RECIPE, ell=2.0)
    with pytest.raises(ValueError, match="unknown optimiser"):
        man_spec.candidate_label("raw", 1e-4, True, "adam")
    with pytest.raises(ValueError, match="unknown initialisation"):
        man_spec.candidate_label("raw", 1e-4, True, "newton", "random")


def test_candidates_take_their_own_fit_or_the_manifold_keys() -> None:
    man = {"space": "standardised", "mu": 1e-5, "normalise": True, "method": "newton", "init": "best",
           "candidates": [{"space": "raw", "mu": 1e-4},
                          {"space": "raw", "mu": 1e-4, "normalise": False, "method": "hooke-jeeves", "init": "pca"},
                          {"space": "standardised", "mu": 1e-5, "normalise": False}]}
    got = plan.manifold_candidates(man)
    assert list(got) == ["standardised-mu1e-05", "raw-mu0.0001", man_spec.PAPER_RECIPE.label,
                         "standardised-mu1e-05-unnormalised"]
    assert got[man_spec.PAPER_RECIPE.label] == man_spec.PAPER_RECIPE
    assert got["raw-mu0.0001"] == man_spec.GplvmCandidate("raw", 1e-4, True, "newton", "best")
    # the manifold keys are every candidate's default, the default candidate's own fit included
    hj = plan.manifold_candidates({**man, "method": "hooke-jeeves", "candidates": [{"space": "raw", "mu": 1e-4}]})
    assert list(hj) == ["standardised-mu1e-05-hooke-jeeves", "raw-mu0.0001-hooke-jeeves"]
    with pytest.raises(ConfigError, match=r"candidates\[1\]: raw-mu0.0001 is listed twice"):
        plan.manifold_candidates({**man, "candidates": [{"space": "raw", "mu": 1e-4}, {"space": "raw", "mu": 1e-4,
                                                                                      "normalise": True}]})


def test_a_space_whose_blends_cannot_become_tables_is_refused_at_parse_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every candidate's blends are measured as tables: a space neither linear nor invertible fails at parse time,
    naming its key, not in a job."""
    monkeypatch.setitem(man_spec.DATA_SPACES, "sqrt", man_spec.DataSpace("sqrt", False, "√ρ"))
    man = {"space": "raw", "mu": 1e-4, "candidates": [{"space": "log", "mu": 1e-4}, {"space": "sqrt", "mu": 1e-4}]}
    with pytest.raises(ConfigError, match=r"config manifold\.candidates\[1\]\.space: data space 'sqrt' is neither "
                                          r"linear nor invertible"):
        plan.manifold_candidates(man)
    with pytest.raises(ConfigError, match=r"config manifold\.space: data space 'sqrt'"):
        plan.manifold_candidates({**man, "space": "sqrt", "candidates": []})
    monkeypatch.setitem(man_spec.DATA_SPACES, "sqrt", man_spec.DataSpace("sqrt", False, "√ρ", invertible=True))
    assert "sqrt-mu0.0001" in plan.manifold_candidates(man)


def _gram_file(tmp_path: Path) -> tuple[Path, np.ndarray, int]:
    """A centred Gram matrix of 12 'materials' in units far from the kernel's amplitude (as raw BRDFs are)."""
    rng = np.random.default_rng(3)
    lat = rng.normal(size=(12, 2))
    Z = 30.0 * np.concatenate([np.sin(lat @ rng.normal(size=(2, 40))), 0.1 * rng.normal(size=(12, 20))], axis=1)
    raw = Z @ Z.T
    G = gram.centre_gram(raw)
    info = gram.GramInfo(tuple(f"m{i:02d}" for i in range(12)), "raw", Z.sum(axis=1), raw)
    path = tmp_path / "gram-raw.npz"
    gram.save_gram(path, G, Z.shape[1], info)
    return path, G, Z.shape[1]


def _stages(trace: Path) -> list[str]:
    return [r["stage"] for r in integrity.read_csv_rows(trace)[1]]


def test_the_candidates_options_reach_the_fit(tmp_path: Path) -> None:
    """fit_to_files (the rule fit_gplvm's job) with the paper's recipe: the trace is Hooke–Jeeves sweeps from the
    truncated PCA as it is, on the Gram matrix as it is; the model records it, so its label is the recipe's."""
    path, G, d = _gram_file(tmp_path)
    paper = man_spec.PAPER_RECIPE
    res = gplvm.fit_to_files(path, tmp_path / "paper.npz", tmp_path / "paper.csv", q=2, mu=paper.mu,
                             normalise=paper.normalise, method=paper.method, init=paper.init, max_sweeps=20)
    m = gplvm.load_model(tmp_path / "paper.npz")
    assert (m.normalised, m.method, m.init, m.gram_scale) == (False, "hooke-jeeves", "pca", 1.0)
    assert man_spec.candidate_label(m.space, m.mu, m.normalised, m.method, m.init) == paper.label
    assert set(_stages(tmp_path / "paper.csv")) == {"hooke-jeeves"}
    assert res.init_factor == 1.0 and res.initial_log_likelihood == pytest.approx(
        likelihood.log_likelihood(fitting.pca_init(G, 2), G, d, 1.0, paper.mu), rel=1e-12)  # the PCA scores themselves
    assert m.log_likelihood == pytest.approx(likelihood.log_likelihood(m.X, G, d, 1.0, paper.mu), rel=1e-8)  # raw units
    # the standard fit: normalised Gram, newton from the best-scaled start
    std = gplvm.fit_to_files(path, tmp_path / "std.npz", tmp_path / "std.csv", q=2, mu=1e-4)
    m = gplvm.load_model(tmp_path / "std.npz")
    s = likelihood.gram_scale(G, d)
    assert (m.normalised, m.method, m.init, m.gram_scale) == (True, "newton", "best", s) and s > 100
    assert "hooke-jeeves" not in _stages(tmp_path / "std.csv") and std.init_scale in fitting.NEWTON_TRIAL_SCALES
    assert m.log_likelihood == pytest.approx(likelihood.log_likelihood(m.X, G / s, d, 1.0, 1e-4), rel=1e-8)


def test_a_model_of_the_previous_format_is_refused(tmp_path: Path) -> None:
    """A /2 model records neither normalisation nor start: it cannot be told which candidate it is."""
    path, _, _ = _gram_file(tmp_path)
    gplvm.fit_to_files(path, tmp_path / "m.npz", tmp_path / "m.csv", q=2, mu=1e-4, max_sweeps=2)
    doc = integrity.load_npz(tmp_path / "m.npz")
    old = {k: v for k, v in doc.items() if k not in ("normalised", "init")}
    old["format"] = np.array("brdfpipe.gplvm/2")
    integrity.save_npz(tmp_path / "old.npz", old)
    with pytest.raises(gplvm.GplvmFileError, match="old.npz: .*no longer supported: it records neither its "
                                                   "normalisation nor its initialisation; refit it"):
        gplvm.load_model(tmp_path / "old.npz")
