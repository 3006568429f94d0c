"""Tests of :mod:`brdfpipe.acquisition.metrics` (Xu et al. 2016, eqs. 4–15).

The reference problem is a small synthetic low-rank "database": m = 12 rows,
p = 3000 smooth-but-random columns (a 1-D stand-in for the cell space, so
neighbouring columns are correlated like neighbouring pixels of a near-field
image), rank 11 after centring.  U, Σ, V come from numpy's SVD of the centred
matrix and Q = VΣ; the model keeps k = m = 12 components as in the paper (the
last singular value is ~1e-14: the direction removed by centring), or k = 11
(the rank), or a truncated k = 5.

The fast O(k³) formula is checked against the literal p-space formula of
eq. 15, which is itself checked against a dense construction with an explicit
selection matrix S and ``numpy.linalg.pinv(Q)``, and against the direct
reconstruction of every training row from its own observations.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from brdfpipe.acquisition import metrics
from brdfpipe.acquisition.metrics import ErrorModel, condition_number, condition_number_first_n, empty_stats, expected_error, expected_error_terms, reconstruct_coefficients, selection_stats
from pspace_reference import direct_training_error, expected_error_literal

M_ROWS = 12
P_COLS = 3000
RTOL = 1e-8


@dataclass(frozen=True)
class Problem:
    """A centred low-rank training set and its SVD."""

    X: NDArray[np.float64]  # (m, p) raw rows
    mean: NDArray[np.float64]  # (p,)
    U: NDArray[np.float64]  # (m, m)
    sigma: NDArray[np.float64]  # (m,)
    Q: NDArray[np.float64]  # (p, m) = V Σ

    def model(self, k: int, eta: float = 40.0, beta: float = 0.0) -> ErrorModel:
        return ErrorModel(self.sigma[:k], self.U[:, :k], eta=eta, beta=beta)


def make_problem(m: int = M_ROWS, p: int = P_COLS, seed: int = 0) -> Problem:
    """Rows = random mixtures of smooth modes of increasing frequency + a little noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, p)
    r = m + 4
    modes = np.array(
        [(j + 1.0) ** -1.2 * np.cos(2 * np.pi * (j + 1) * t + rng.uniform(0, 2 * np.pi)) for j in range(r)]
    )
    X = 2.0 + rng.standard_normal((m, r)) @ modes + 0.02 * rng.standard_normal((m, p))
    mean = X.mean(axis=0)
    U, sigma, Vt = np.linalg.svd(X - mean, full_matrices=False)
    return Problem(X=X, mean=mean, U=U, sigma=sigma, Q=Vt.T * sigma)


@functools.lru_cache(maxsize=None)
def problem() -> Problem:
    return make_problem()


def rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def test_problem_is_as_described() -> None:
    pb = problem()
    assert pb.sigma[-1] < 1e-10 * pb.sigma[0]  # centring removes one direction
    assert pb.sigma[-2] > 1e-3 * pb.sigma[0]  # rank m − 1 = 11
    np.testing.assert_allclose(pb.Q.T @ pb.Q, np.diag(pb.sigma**2), atol=1e-9 * pb.sigma[0] ** 2)
    np.testing.assert_allclose(pb.U @ pb.Q.T, pb.X - pb.mean, atol=1e-10)  # y_i = Q u_i


# --------------------------------------------------------------------------
# Fast formula = literal p-space formula = direct recomputation
# --------------------------------------------------------------------------

SELECTIONS = {
    "empty": np.array([], dtype=np.int64),
    "one": np.array([17]),
    "n<k, repeated": np.array([5, 900, 5, 2100, 2999]),
    "n=k": np.arange(100, 3000, 250),
    "n>k, repeated": np.concatenate([np.arange(1000, 1040), np.arange(1000, 1010), [0, 0, 0]]),
    "near-field-like block": np.arange(1500, 1900, 2),
}


@pytest.mark.parametrize("beta", [0.0, 0.3])
@pytest.mark.parametrize("k", [12, 11, 5])
@pytest.mark.parametrize("name", list(SELECTIONS))
def test_fast_equals_literal_coefficients(name: str, k: int, beta: float) -> None:
    """E from (G, qsum) equals eq. 15 in p-space with y_i = Q u_i, for any k."""
    pb = problem()
    rows = SELECTIONS[name]
    model = pb.model(k, beta=beta)
    fast = expected_error(model, *selection_stats(pb.Q[rows, :k]))
    literal = expected_error_literal(pb.Q[:, :k], pb.U[:, :k], rows, 40.0, beta)
    assert fast > 0
    assert rel(fast, literal) < RTOL


@pytest.mark.parametrize("beta", [0.0, 0.3])
@pytest.mark.parametrize("k", [12, 11])
@pytest.mark.parametrize("name", list(SELECTIONS))
def test_fast_equals_literal_on_training_rows(name: str, k: int, beta: float) -> None:
    """With k = rank, eq. 15 on the actual rows x_i − μ equals the fast form."""
    pb = problem()
    rows = SELECTIONS[name]
    fast = expected_error(pb.model(k, beta=beta), *selection_stats(pb.Q[rows, :k]))
    from_x = expected_error_literal(pb.Q[:, :k], pb.X, rows, 40.0, beta, mean=pb.mean)
    from_y = expected_error_literal(pb.Q[:, :k], pb.X - pb.mean, rows, 40.0, beta)
    assert rel(fast, from_x) < RTOL
    assert rel(fast, from_y) < RTOL


@pytest.mark.parametrize("k", [12, 11])
@pytest.mark.parametrize("name", list(SELECTIONS))
def test_fast_equals_direct_training_error(name: str, k: int) -> None:
    """β = 0: E equals the mean error of reconstructing each training row from S x_i."""
    pb = problem()
    rows = SELECTIONS[name]
    fast = expected_error(pb.model(k), *selection_stats(pb.Q[rows, :k]))
    direct = direct_training_error(pb.Q[:, :k], pb.U[:, :k], pb.sigma[:k], pb.mean, pb.X, rows, 40.0)
    assert rel(fast, direct) < RTOL


def test_truncated_model_direct_error_includes_deviation() -> None:
    """k < rank: the direct error also sees the out-of-subspace part (documented)."""
    pb = problem()
    k = 5
    rows = SELECTIONS["n>k, repeated"]
    fast = expected_error(pb.model(k), *selection_stats(pb.Q[rows, :k]))
    direct = direct_training_error(pb.Q[:, :k], pb.U[:, :k], pb.sigma[:k], pb.mean, pb.X, rows, 40.0)
    assert rel(fast, direct) > 1e-3


@settings(max_examples=40, deadline=None)
@given(
    rows=st.lists(st.integers(0, P_COLS - 1), min_size=0, max_size=30),
    beta=st.sampled_from([0.0, 0.3, 2.0]),
    eta=st.sampled_from([0.5, 40.0, 1e3]),
)
def test_fast_equals_literal_property(rows: list[int], beta: float, eta: float) -> None:
    pb = problem()
    idx = np.array(rows, dtype=np.int64)
    model = pb.model(12, eta=eta, beta=beta)
    fast = expected_error(model, *selection_stats(pb.Q[idx]))
    assert rel(fast, expected_error_literal(pb.Q, pb.U, idx, eta, beta)) < RTOL


def test_literal_matches_dense_reference() -> None:
    """The literal formula against S as an explicit (n, p) matrix and pinv(Q) (p small)."""
    pb = make_problem(m=8, p=400, seed=3)
    p, k = pb.Q.shape
    rows = np.array([3, 77, 77, 150, 399, 0, 210])
    eta, beta = 40.0, 0.7
    S = np.zeros((rows.size, p))
    S[np.arange(rows.size), rows] = 1.0
    Q = pb.Q
    SQ = S @ Q
    reg = np.linalg.inv(SQ.T @ SQ + eta * np.eye(k)) @ SQ.T
    op = Q @ (np.linalg.pinv(Q) - reg @ S)  # (p, p)
    Y = pb.X - pb.mean
    ref = np.mean([np.linalg.norm(op @ y) for y in Y]) + beta * np.linalg.norm(Q @ reg @ S @ np.ones(p))
    assert rel(expected_error_literal(Q, Y, rows, eta, beta), ref) < 1e-10
    assert rel(expected_error_literal(Q, pb.U, rows, eta, beta), ref) < 1e-10
    assert rel(expected_error(pb.model(k, eta, beta), *selection_stats(Q[rows])), ref) < 1e-10


def test_terms_and_linearity_in_beta() -> None:
    pb = problem()
    G, q = selection_stats(pb.Q[SELECTIONS["n<k, repeated"]])
    recon, noise = expected_error_terms(pb.model(12), G, q)
    assert recon == pytest.approx(expected_error(pb.model(12, beta=0.0), G, q), rel=1e-14)
    for beta in (0.1, 1.0, 5.0):
        assert expected_error(pb.model(12, beta=beta), G, q) == pytest.approx(recon + beta * noise, rel=1e-14)
    assert noise > 0


def test_empty_selection_error_is_mean_residual_norm() -> None:
    """No observations: the reconstruction is μ, so E = mean ‖y_i‖ (and the noise term is 0)."""
    pb = problem()
    recon, noise = expected_error_terms(pb.model(12), *empty_stats(12))
    assert recon == pytest.approx(np.mean(np.linalg.norm(pb.X - pb.mean, axis=1)), rel=1e-12)
    assert noise == 0.0


@pytest.mark.parametrize("k", [11, 12])
def test_all_rows_small_eta_error_vanishes(k: int) -> None:
    pb = problem()
    G, q = selection_stats(pb.Q[:, :k])
    e_all = expected_error(pb.model(k, eta=1e-8), G, q)
    e_none = expected_error(pb.model(k, eta=1e-8), *empty_stats(k))
    assert e_all < 1e-7 * e_none
    # ... and with η = 40 it is the closed form η‖Σ(Σ² + η)⁻¹u_i‖ (G = QᵀQ = Σ²).
    s = pb.sigma[:k]
    closed = np.mean(np.linalg.norm(40.0 * s / (s**2 + 40.0) * pb.U[:, :k], axis=1))
    assert expected_error(pb.model(k), G, q) == pytest.approx(closed, rel=1e-9)


def test_invariant_to_row_order() -> None:
    pb = problem()
    rows = SELECTIONS["n>k, repeated"]
    perm = np.random.default_rng(1).permutation(rows)
    model = pb.model(12, beta=0.3)
    a = expected_error(model, *selection_stats(pb.Q[rows]))
    b = expected_error(model, *selection_stats(pb.Q[perm]))
    assert a == pytest.approx(b, rel=1e-12)


def test_float32_q_and_qtq_option() -> None:
    """Q stored as float32: QᵀQ = Σ² only to ~1e-7; passing qtq restores float64 agreement."""
    pb = problem()
    Q32 = pb.Q.astype(np.float32)
    rows = SELECTIONS["near-field-like block"]
    literal = expected_error_literal(Q32, pb.U, rows, 40.0, 0.3)
    G, q = selection_stats(Q32[rows])
    plain = expected_error(pb.model(12, beta=0.3), G, q)
    Q64 = Q32.astype(np.float64)
    exact = expected_error(ErrorModel(pb.sigma, pb.U, beta=0.3, qtq=Q64.T @ Q64), G, q)
    assert rel(plain, literal) < 1e-7  # ~4e-10 here
    assert rel(exact, literal) < 1e-10


# --------------------------------------------------------------------------
# Monotonicity (adding observations)
# --------------------------------------------------------------------------


def test_adding_blocks_reduces_error_on_reference_problem() -> None:
    """Near-field-like blocks added one after another on the reference problem."""
    pb = problem()
    model = pb.model(12)
    errors = [expected_error(model, *empty_stats(12))]
    blocks = []
    for start in (200, 1400, 2600, 800):
        blocks.append(pb.Q[start : start + 150 : 3])
        errors.append(expected_error(model, *selection_stats(np.vstack(blocks))))
    assert all(b <= a for a, b in zip(errors, errors[1:]))
    assert errors[-1] < 0.5 * errors[0]


def _disjoint_support_q(sigma: NDArray[np.float64], p: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """Q = VΣ with orthonormal V whose columns have disjoint supports (every G is diagonal)."""
    k = sigma.size
    owner = np.arange(p) % k
    V = np.zeros((p, k))
    V[np.arange(p), owner] = rng.standard_normal(p)
    V /= np.linalg.norm(V, axis=0)
    return V * sigma


@settings(max_examples=60, deadline=None)
@given(
    sigma=st.lists(st.floats(0.0, 1e3), min_size=1, max_size=6),
    seed=st.integers(0, 2**32 - 1),
    before=st.lists(st.integers(0, 59), max_size=20),
    added=st.lists(st.integers(0, 59), min_size=1, max_size=10),
    eta=st.floats(1e-3, 1e3),
)
def test_error_weakly_decreases_when_rows_added_commuting_case(
    sigma: list[float], seed: int, before: list[int], added: list[int], eta: float
) -> None:
    """β = 0, Q with disjoint-support columns (all Gram matrices diagonal): E(S ∪ B) ≤ E(S).

    Here ηM⁻¹ = diag(η/(g_j + η)) shrinks entrywise as rows are added, so every
    ‖Σ ηM⁻¹ u_i‖ decreases, for any coefficients u_i.  (For general Q this is
    *not* a theorem: see the next test.)
    """
    rng = np.random.default_rng(seed)
    s = np.array(sigma)
    Q = _disjoint_support_q(s, 60, rng)
    model = ErrorModel(s, rng.standard_normal((5, s.size)), eta=eta)
    G, q = selection_stats(Q[np.array(before, dtype=np.int64)])
    e0 = expected_error(model, G, q)
    e1 = expected_error(model, *selection_stats(Q[np.array(before + added, dtype=np.int64)]))
    assert e1 <= e0 * (1 + 1e-12) + 1e-300


def test_error_can_increase_when_a_row_is_added() -> None:
    """E(S) is not monotone in S in general (a property of eq. 15, not a bug).

    k = m = 2, Σ = diag(30, 1), U = I (orthonormal training coefficients),
    η → 0.  One observation q = r·(c, s) with s ≫ c mostly measures the
    low-variance coefficient: the minimum-‖c‖ solution then puts a
    (c/s)-sized share of it into the high-variance coefficient, whose error
    is weighted by σ = 30.  E goes from (30 + 1)/2 = 15.5 to
    (s + c)·sqrt(900 s² + c²)/2 ≈ 17.96 (c = 0.3).
    An optimiser must therefore not assume that adding an image lowers E.
    """
    sigma = np.array([30.0, 1.0])
    c = 0.3
    s = np.sqrt(1 - c**2)
    r = 0.5
    first = np.array([r * c / sigma[0], r * s / sigma[1]])  # row 0 of V
    # An orthonormal V (p = 20) with that first row: rest = Z Lᵀ, LLᵀ = I − v0 v0ᵀ.
    L = np.linalg.cholesky(np.eye(2) - np.outer(first, first))
    Z = np.linalg.qr(np.random.default_rng(0).standard_normal((19, 2)))[0]
    V = np.vstack([first, Z @ L.T])
    np.testing.assert_allclose(V.T @ V, np.eye(2), atol=1e-14)
    Q = V * sigma
    eta = 1e-6
    model = ErrorModel(sigma, np.eye(2), eta=eta)
    e_empty = expected_error(model, *empty_stats(2))
    e_one = expected_error(model, *selection_stats(Q[[0]]))
    assert e_empty == pytest.approx(15.5, rel=1e-12)
    assert e_one == pytest.approx((s + c) * np.sqrt(900 * s**2 + c**2) / 2, rel=1e-4)
    assert e_one > 1.15 * e_empty
    assert rel(e_one, expected_error_literal(Q, np.eye(2), [0], eta, 0.0)) < 1e-8


# --------------------------------------------------------------------------
# Reconstruction (eq. 4)
# --------------------------------------------------------------------------


def test_reconstruct_coefficients_matches_augmented_least_squares() -> None:
    pb = problem()
    rows = SELECTIONS["n<k, repeated"]
    Qt = pb.Q[rows]
    Y = (pb.X[:, rows] - pb.mean[rows]).T  # (n, m)
    eta = 40.0
    A = np.vstack([Qt, np.sqrt(eta) * np.eye(12)])
    ref = np.linalg.lstsq(A, np.vstack([Y, np.zeros((12, Y.shape[1]))]), rcond=None)[0]
    np.testing.assert_allclose(reconstruct_coefficients(Qt, Y, eta), ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(reconstruct_coefficients(Qt, Y[:, 3], eta), ref[:, 3], rtol=1e-9, atol=1e-12)
    assert reconstruct_coefficients(Qt, Y[:, 3], eta).shape == (12,)


def test_reconstruction_with_all_rows_recovers_training_rows() -> None:
    pb = problem()
    c = reconstruct_coefficients(pb.Q[:, :11], (pb.X - pb.mean).T, eta=1e-9)
    np.testing.assert_allclose(pb.Q[:, :11] @ c + pb.mean[:, None], pb.X.T, atol=1e-6)


# --------------------------------------------------------------------------
# Condition number (eq. 6)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(12, 12), (40, 12), (5, 12), (1, 12), (3000, 12)])
def test_condition_number_matches_numpy(shape: tuple[int, int]) -> None:
    n, k = shape
    A = np.random.default_rng(n).standard_normal(shape)
    ref = np.linalg.cond(A)
    assert condition_number(A, method="svd") == pytest.approx(ref, rel=1e-10)
    assert condition_number(A) == pytest.approx(ref, rel=1e-8)
    assert condition_number(A.T @ A, n=n) == pytest.approx(ref, rel=1e-8)


def test_condition_number_on_q_rows() -> None:
    pb = problem()
    Qt = pb.Q[SELECTIONS["n=k"], :11]
    assert condition_number(Qt) == pytest.approx(np.linalg.cond(Qt), rel=1e-8)


@pytest.mark.parametrize("rows", [[5, 900, 5], list(range(100, 111)) + [100]])
def test_condition_number_inf_for_duplicated_rows(rows: list[int]) -> None:
    """n ≤ k with a repeated cell: Q̃ is rank deficient, κ = inf (paper §3.1)."""
    pb = problem()
    Qt = pb.Q[rows, :12]
    assert condition_number(Qt) == np.inf
    assert condition_number(Qt, method="svd") == np.inf
    assert condition_number(Qt.T @ Qt, n=len(rows)) == np.inf
    # ... while the expected error is finite, and a repeat can only sharpen c̄.
    assert np.isfinite(expected_error(pb.model(12), *selection_stats(Qt)))


def test_condition_number_near_duplicates_and_tolerance() -> None:
    rng = np.random.default_rng(2)
    A = rng.standard_normal((6, 12))
    A[5] = A[4] + 1e-9 * rng.standard_normal(12)
    kappa_svd = condition_number(A, method="svd")
    assert 1e8 < kappa_svd < 1e11  # resolved by the SVD ...
    assert condition_number(A) == np.inf  # ... beyond the Gram route's documented tolerance
    # A moderate near-duplicate (κ ~ 1e4) is within both routes' reach.
    A[5] = A[4] + 1e-4 * rng.standard_normal(12)
    kappa = condition_number(A, method="svd")
    assert 1e3 < kappa < 1e6
    assert condition_number(A) == pytest.approx(kappa, rel=1e-6)
    assert condition_number(A, rtol=0.1 / kappa) == pytest.approx(kappa, rel=1e-6)
    assert condition_number(A, rtol=10.0 / kappa) == np.inf


def test_condition_number_edge_cases() -> None:
    assert condition_number(np.zeros((0, 4))) == np.inf
    assert condition_number(np.zeros((4, 4)), n=0) == np.inf
    assert condition_number(np.zeros((3, 4))) == np.inf
    assert condition_number(np.array([[3.0, 4.0]])) == pytest.approx(1.0)


def test_nielsens_kappa_conditions_the_first_n_components_only() -> None:
    """Nielsen 2015's κ as released: the n × n block of the rows and the first n components (analytic basis)."""
    e1, e2, e3 = np.eye(4)[:3]
    golden = (3 + np.sqrt(5)) / 2  # κ of rows (1, 0, 0, 0), (1, 0, 1, 0): Gram [[1, 1], [1, 2]], λ = (3 ± √5) / 2
    # rows equal in their first 2 components: singular for Nielsen's κ, finite over all k (eq. 6)
    A = np.array([e1, e1 + e3])
    assert condition_number_first_n(A) == np.inf
    assert condition_number(A, method="svd") == pytest.approx(golden, rel=1e-12)
    # a row that is large only past component n: ignored by Nielsen's κ, dominant over all k
    B = np.array([e1 + 5 * e3, e2])
    assert condition_number_first_n(B) == pytest.approx(1.0, rel=1e-12)
    assert condition_number(B, method="svd") == pytest.approx(np.sqrt(26.0), rel=1e-12)
    # where the first n components carry everything, the two agree
    C = np.array([2 * e1, e1 + e2])
    assert condition_number_first_n(C) == pytest.approx(condition_number(C, method="svd"), rel=1e-12)
    # one sample: the released code's 1 / |q11|; more rows than components: all k columns (eq. 6)
    assert condition_number_first_n(np.array([[-4.0, 1.0, 9.0]])) == pytest.approx(0.25)
    assert condition_number_first_n(np.array([[0.0, 1.0, 9.0]])) == np.inf
    D = np.random.default_rng(3).standard_normal((7, 4))
    assert condition_number_first_n(D) == pytest.approx(np.linalg.cond(D), rel=1e-10)
    # n ≤ k: numpy's κ of the square block
    F = np.random.default_rng(4).standard_normal((3, 6))
    assert condition_number_first_n(F) == pytest.approx(np.linalg.cond(F[:, :3]), rel=1e-10)
    assert condition_number_first_n(np.zeros((0, 3))) == np.inf
    with pytest.raises(ValueError, match="finite"):
        condition_number_first_n(np.array([[np.nan, 1.0]]))


# --------------------------------------------------------------------------
# Bad inputs
# --------------------------------------------------------------------------


def test_error_model_validation() -> None:
    s, U = np.ones(3), np.ones((4, 3))
    ErrorModel(s, U)  # fine
    with pytest.raises(ValueError, match="eta"):
        ErrorModel(s, U, eta=0.0)
    with pytest.raises(ValueError, match="eta"):
        ErrorModel(s, U, eta=float("nan"))
    with pytest.raises(ValueError, match="beta"):
        ErrorModel(s, U, beta=-1.0)
    with pytest.raises(ValueError, match="sigma"):
        ErrorModel(-s, U)
    with pytest.raises(ValueError, match="sigma"):
        ErrorModel(np.ones((3, 1)), U)
    with pytest.raises(ValueError, match="U"):
        ErrorModel(s, np.ones((4, 2)))
    with pytest.raises(ValueError, match="U"):
        ErrorModel(s, np.full((4, 3), np.inf))
    with pytest.raises(ValueError, match="qtq"):
        ErrorModel(s, U, qtq=np.ones((2, 2)))
    with pytest.raises(ValueError, match="symmetric"):
        ErrorModel(s, U, qtq=np.triu(np.ones((3, 3))))
    with pytest.raises(ValueError, match="semi-definite"):
        ErrorModel(s, U, qtq=-np.eye(3))


def test_error_model_is_immutable() -> None:
    s = np.ones(3)
    model = ErrorModel(s, np.ones((4, 3)))
    s[0] = 5.0  # the model holds its own copy
    assert model.sigma[0] == 1.0
    with pytest.raises(ValueError):
        model.sigma[0] = 2.0  # read-only
    with pytest.raises(AttributeError):
        model.eta = 1.0  # type: ignore[misc]


def test_metric_input_validation() -> None:
    pb = problem()
    model = pb.model(12)
    G, q = selection_stats(pb.Q[:20])
    with pytest.raises(ValueError, match="G"):
        expected_error(model, G[:5, :5], q[:5])
    with pytest.raises(ValueError, match="qsum"):
        expected_error(model, G, q[:5])
    with pytest.raises(ValueError, match="positive definite"):
        expected_error(model, G - 1e6 * np.eye(12), q)
    with pytest.raises(ValueError):
        expected_error(model, np.full((12, 12), np.nan), q)
    with pytest.raises(ValueError):
        selection_stats(np.ones((2, 3, 4)))
    with pytest.raises(ValueError, match="range"):
        expected_error_literal(pb.Q, pb.U, [P_COLS], 40.0, 0.0)
    with pytest.raises(ValueError, match="integers"):
        expected_error_literal(pb.Q, pb.U, [1.5], 40.0, 0.0)
    with pytest.raises(ValueError, match="mean"):
        expected_error_literal(pb.Q, pb.U, [1], 40.0, 0.0, mean=pb.mean)
    with pytest.raises(ValueError, match="ambiguous"):
        expected_error_literal(np.eye(4), np.eye(4), [1], 40.0, 0.0)
    with pytest.raises(ValueError, match="columns"):
        expected_error_literal(pb.Q, np.ones((3, 7)), [1], 40.0, 0.0)
    with pytest.raises(ValueError, match="y_obs"):
        reconstruct_coefficients(pb.Q[:4], np.ones(5))
    with pytest.raises(ValueError, match="eta"):
        reconstruct_coefficients(pb.Q[:4], np.ones(4), eta=-1.0)
    with pytest.raises(ValueError, match="U"):
        direct_training_error(pb.Q, pb.U[:, :5], pb.sigma, pb.mean, pb.X, [1], 40.0)
    with pytest.raises(ValueError, match="X_train"):
        direct_training_error(pb.Q, pb.U, pb.sigma, pb.mean, pb.X[:, :10], [1], 40.0)
    with pytest.raises(ValueError, match="method"):
        condition_number(pb.Q[:4], method="qr")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="Gram"):
        condition_number(pb.Q[:4], n=4)
    with pytest.raises(ValueError, match="2-D"):
        condition_number(np.ones(3))
    with pytest.raises(ValueError, match="k"):
        empty_stats(0)


def test_default_eta_is_papers() -> None:
    assert metrics.DEFAULT_ETA == 40.0
    assert ErrorModel(np.ones(2), np.ones((1, 2))).eta == 40.0
