"""Tests of :class:`brdfpipe.acquisition.metrics.FactoredSelection`: E(S) of many candidates by low-rank updates.

The property: for a base selection (G0, qsum0), an optional removed block
and any candidate block R (r rows, each with a multiplicity),
``candidate_errors`` equals ``expected_error(model, G, qsum)`` of the
resulting selection computed from scratch from its rows, to ≤ 1e-10
relative — for r = 1, a few, and r > k; β = 0 and β > 0; Σ-weighted and
QᵀQ-weighted norms; forced low-rank form and the automatic choice.  The
models are small random ones (k = 40, m = 30) with a spectrum spanning three
decades, like a PCA model's.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from brdfpipe.acquisition.metrics import ErrorModel, FactoredSelection, RowBlock, expected_error, selection_stats

K, M, P = 40, 30, 600
REL = 1e-10


def make(beta: float, qtq: bool = False, seed: int = 0) -> tuple[ErrorModel, NDArray[np.float64]]:
    """A random ErrorModel and a pool of P rows of Q (row norms² / η from ~0.01 to ~100)."""
    rng = np.random.default_rng(seed)
    sigma = np.geomspace(3000.0, 3.0, K)
    U = np.linalg.qr(rng.standard_normal((M, K)).T)[0].T  # (M, K), orthonormal rows
    Q = rng.standard_normal((P, K)) * sigma / 60.0 * rng.uniform(0.1, 1.5, (P, 1))
    gram = None
    if qtq:
        B = rng.standard_normal((K, K)) * 0.05 + np.eye(K)
        gram = (B * sigma) .T @ (B * sigma)
    return ErrorModel(sigma, U, eta=40.0, beta=beta, qtq=gram), Q


def reference(em: ErrorModel, rows: NDArray[np.float64], counts: NDArray[np.float64] | None = None) -> float:
    """E(S) from scratch of the selection with these rows (row i observed counts[i] times)."""
    if counts is not None:
        rows = np.repeat(rows, counts.astype(int), axis=0)
    return expected_error(em, *selection_stats(rows))


def rel_err(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


@pytest.mark.parametrize("beta", [0.0, 0.7])
@pytest.mark.parametrize("qtq", [False, True])
@pytest.mark.parametrize("n_remove", [0, 1, 3])
@pytest.mark.parametrize("method", ["lowrank", "auto"])
def test_candidates_equal_fresh_evaluation(beta: float, qtq: bool, n_remove: int, method: str) -> None:
    em, Q = make(beta, qtq)
    rng = np.random.default_rng(1)
    base_rows = Q[:12]
    fs = FactoredSelection(em, *selection_stats(base_rows))
    keep = base_rows[n_remove:]
    remove = RowBlock(base_rows[:n_remove]) if n_remove else None
    sizes = [1] * 25 + [2] * 5 + [3] * 5 + [5] * 3 + [9] * 2 + [K + 7] * 2  # r = 1, a few, > k
    blocks: list[RowBlock] = []
    expected: list[float] = []
    for r in sizes:
        rows = Q[rng.choice(np.arange(20, P), r, replace=False)]
        counts = rng.integers(1, 4, r).astype(np.float64) if rng.random() < 0.5 else None
        blocks.append(RowBlock(rows, counts))
        expected.append(reference(em, np.concatenate([keep, rows] if counts is None else
                                                     [keep, np.repeat(rows, counts.astype(int), axis=0)])))
    got = fs.candidate_errors(blocks, remove=remove, method=method)  # type: ignore[arg-type]
    assert got.shape == (len(blocks),)
    worst = max(rel_err(g, e) for g, e in zip(got, expected))
    assert worst <= REL, worst
    # one at a time, and in another order, gives the same numbers (to rounding)
    for i in (0, 30, len(blocks) - 1):
        single = fs.candidate_errors([blocks[i]], remove=remove, method=method)[0]  # type: ignore[arg-type]
        assert rel_err(single, expected[i]) <= REL


@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_plain_arrays_and_one_row(beta: float) -> None:
    em, Q = make(beta)
    fs = FactoredSelection(em, *selection_stats(Q[:5]))
    got = fs.candidate_errors([Q[7], Q[8:9], Q[9:12]], method="lowrank")
    want = [reference(em, np.concatenate([Q[:5], b])) for b in (Q[7:8], Q[8:9], Q[9:12])]
    assert np.all(np.abs(got - want) <= REL * np.abs(want))


@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_empty_base(beta: float) -> None:
    em, Q = make(beta)
    G, q = selection_stats(np.zeros((0, K)))
    fs = FactoredSelection(em, G, q)
    assert rel_err(fs.error(), expected_error(em, G, q)) <= 1e-14
    got = fs.candidate_errors([Q[i:i + 1] for i in range(50)], method="lowrank")
    want = [reference(em, Q[i:i + 1]) for i in range(50)]
    assert np.all(np.abs(got - want) <= REL * np.abs(want))


def strong_block(level: float, extra: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """k + extra rows with RᵀR ≈ level·η·(1 … 10) in every direction.

    E collapses by orders of magnitude, yet M = G + ηI stays well conditioned.
    """
    O = np.linalg.qr(rng.standard_normal((K, K)))[0]
    R = np.sqrt(level * 40.0 * rng.uniform(1.0, 10.0, K))[:, None] * O
    return np.concatenate([R, rng.standard_normal((extra, K))], axis=0)


@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_strong_blocks_stay_accurate(beta: float) -> None:
    """Blocks that cut E by orders of magnitude cancel in the expanded norm: recomputed from vectors.

    (The blocks keep κ(G + ηI) ≤ ~1e4, so that the fresh evaluation they are
    compared with is itself accurate to better than 1e-11.)
    """
    em, Q = make(beta)
    rng = np.random.default_rng(3)
    fs = FactoredSelection(em, *selection_stats(Q[:3]))
    blocks = [strong_block(level, extra, rng) for level, extra in ((1e2, 0), (1e3, 5), (1e4, 0))]
    blocks += [Q[10:11] * 10.0, Q[11:13] * 10.0]  # single strong rows: ‖q‖²/η up to ~1e4
    got = fs.candidate_errors(blocks, method="lowrank")
    want = [reference(em, np.concatenate([Q[:3], b])) for b in blocks]
    if beta == 0.0:
        assert want[2] < 1e-3 * reference(em, Q[:3])  # E really collapses (the noise term does not)
    assert np.all(np.abs(got - np.array(want)) <= REL * np.abs(want)), np.abs(got - want) / want
    assert fs.recomputed >= 2  # the collapsing candidates took the vector path


@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_removing_a_strong_row(beta: float) -> None:
    """A row with ‖q‖²/η ≈ 2e4 in the base: downdating it is ill-conditioned; result still exact."""
    em, Q = make(beta)
    base_rows = Q[:8].copy()
    base_rows[0] *= 60.0
    assert base_rows[0] @ base_rows[0] / em.eta > 1e3
    fs = FactoredSelection(em, *selection_stats(base_rows))
    blocks = [Q[20 + i:21 + i] for i in range(10)] + [Q[40:43]]
    got = fs.candidate_errors(blocks, remove=base_rows[:1], method="lowrank")
    want = [reference(em, np.concatenate([base_rows[1:], b])) for b in blocks]
    assert np.all(np.abs(got - np.array(want)) <= REL * np.abs(want))


@pytest.mark.parametrize("beta", [0.0, 0.7])
def test_updated_chain_matches_fresh(beta: float) -> None:
    em, Q = make(beta)
    rng = np.random.default_rng(4)
    rows = [Q[i:i + 1] for i in range(6)]
    fs = FactoredSelection(em, *selection_stats(np.concatenate(rows)))
    fs.error()  # computes the solve, so that updates derive theirs from it
    for step in range(40):
        j = int(rng.integers(len(rows)))
        new = Q[int(rng.integers(10, P))][None, :]
        counts = np.array([2.0]) if step % 3 == 0 else None
        fs = fs.updated(add=RowBlock(new, counts), remove=rows[j])
        rows[j] = np.repeat(new, 2, axis=0) if counts is not None else new
        assert fs.depth == step + 1
        want = reference(em, np.concatenate(rows))
        assert rel_err(fs.error(), want) <= REL
        G, q = selection_stats(np.concatenate(rows))
        assert np.allclose(fs.G, G, rtol=1e-12, atol=1e-9 * np.abs(G).max())
        assert np.allclose(fs.qsum, q, rtol=1e-12, atol=1e-9 * np.abs(q).max())
    # candidates of a derived selection are exact too
    got = fs.candidate_errors([Q[300:301], Q[301:304]], remove=rows[0], method="lowrank")
    want = [reference(em, np.concatenate(rows[1:] + [b])) for b in (Q[300:301], Q[301:304])]
    assert np.all(np.abs(got - np.array(want)) <= REL * np.abs(want))


def test_auto_picks_direct_for_large_blocks() -> None:
    """Same numbers whichever form is chosen; the inputs are not modified."""
    em, Q = make(0.0)
    G, q = selection_stats(Q[:10])
    G0, q0 = G.copy(), q.copy()
    fs = FactoredSelection(em, G, q)
    blocks = [Q[20:21], Q[30:30 + 2 * K]]
    a = fs.candidate_errors(blocks, method="auto")
    b = fs.candidate_errors(blocks, method="direct")
    c = fs.candidate_errors(blocks, method="lowrank")
    assert np.all(np.abs(a - b) <= REL * b) and np.all(np.abs(c - b) <= REL * b)
    assert a[1] == b[1]  # 80 rows at k = 40: the direct form was used
    assert np.array_equal(G, G0) and np.array_equal(q, q0)


def test_deterministic() -> None:
    em, Q = make(0.7)
    blocks = [Q[i:i + 1] for i in range(100, 200)] + [Q[200:203], Q[203:206]]
    a = FactoredSelection(em, *selection_stats(Q[:9])).candidate_errors(blocks, remove=Q[:1])
    b = FactoredSelection(em, *selection_stats(Q[:9])).candidate_errors(blocks, remove=Q[:1])
    assert np.array_equal(a, b)


def test_bad_arguments_raise() -> None:
    em, Q = make(0.0)
    fs = FactoredSelection(em, *selection_stats(Q[:4]))
    with pytest.raises(ValueError):
        fs.candidate_errors([Q[:2, :-1]])  # wrong k
    with pytest.raises(ValueError):
        fs.candidate_errors([RowBlock(Q[:2], np.array([1.0]))])  # counts of the wrong length
    with pytest.raises(ValueError):
        fs.candidate_errors([RowBlock(Q[:2], np.array([1.0, 0.0]))])  # a zero count
    with pytest.raises(ValueError):
        fs.candidate_errors([Q[:2]], method="fast")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        fs.candidate_errors([np.full((1, K), np.nan)])
    with pytest.raises(ValueError):
        FactoredSelection(em, np.eye(K + 1), np.zeros(K + 1))
    with pytest.raises(ValueError):
        FactoredSelection("model", np.eye(K), np.zeros(K))  # type: ignore[arg-type]
