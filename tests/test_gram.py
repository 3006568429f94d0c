"""brdfpipe.manifold.gram: the streamed Gram matrix against a dense computation in every data space, subsets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brdfpipe.data import logmap, merl, store
from brdfpipe.manifold import gram
from brdfpipe.registry.manifold import SPACE_NAMES
from gram_fixture import dense, small_store  # noqa: F401 (pytest fixtures)


# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------


# small_store, dense: tests/gram_fixture.py


# --------------------------------------------------------------------------
# Gram matrix
# --------------------------------------------------------------------------


@pytest.mark.parametrize("space", SPACE_NAMES)
def test_gram_matrix_equals_dense_computation(small_store: Path, dense: dict, space: str) -> None:
    G, d, info = gram.gram_matrix(small_store, space=space)
    data = dense["data"].astype(np.float64)
    cells = dense["cells"]
    wi, wo = merl.cell_directions(cells)
    cos = wi[:, 2] * wo[:, 2]
    if space == "cosine":
        data = data * cos
    elif space == "relative":  # cos θi cos θo over the per-cell median of every channel of every material
        ref = np.median(dense["data"].transpose(1, 0, 2).reshape(-1, cells.size).astype(np.float64), axis=0)
        data = data * cos / np.maximum(ref, 1e-3)
    elif space == "standardised":  # each (channel, cell) over its standard deviation across the materials
        sd = data.std(axis=0)
        data = data * np.sqrt(np.maximum(cos, 0.0)) / np.maximum(sd, 1e-6)
    elif space == "log":
        ref = np.median(dense["data"].reshape(-1, cells.size).astype(np.float64), axis=0)
        data = logmap.forward(data, ref, logmap.cell_weights(cells, "product"))
    Z = data.reshape(data.shape[0], -1)
    Zc = Z - Z.mean(axis=0)
    expected = Zc @ Zc.T
    assert d == Z.shape[1] == 3 * cells.size
    assert info.space == space and len(info.materials) == 6
    assert np.allclose(G, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    assert np.allclose(info.row_sums, Z.sum(axis=1), rtol=1e-9)
    assert np.allclose(G, G.T)


def test_gram_material_subset_order_and_save_load(small_store: Path, tmp_path: Path) -> None:
    st = store.open_store(small_store)
    names = [st.materials[4], st.materials[1], st.materials[2]]
    G, d, info = gram.gram_matrix(small_store, materials=names)
    Gall, _, info_all = gram.gram_matrix(small_store)
    idx = [4, 1, 2]
    raw = info_all.raw_gram[np.ix_(idx, idx)]
    assert info.materials == tuple(names)
    assert np.allclose(info.raw_gram, raw, rtol=1e-12)
    assert np.allclose(G, gram.centre_gram(raw), rtol=0, atol=1e-9 * np.abs(G).max())
    path = tmp_path / "g" / "gram.npz"
    gram.save_gram(path, G, d, info)
    G2, d2, info2 = gram.load_gram(path)
    assert np.array_equal(G2, G) and d2 == d and info2.materials == info.materials
    assert [p.name for p in path.parent.iterdir()] == ["gram.npz"]  # no temporary left
    with pytest.raises(ValueError, match="unknown data space"):
        gram.gram_matrix(small_store, space="sqrt")
