"""Measures of many interpolated materials in one pass over the store (issue 23).

The fidelity measurements (:mod:`brdfpipe.manifold.fidelity`) and the latent
paths (:func:`brdfpipe.manifold.analysis.paths_analysis`) need, for many blends
``W`` (P × N weights over the materials), two things of each interpolated table:
its white-sky albedo and its PR12 perceptual distance to other interpolated
tables.  Both are sums over cells:

* the albedo (:func:`brdfpipe.manifold.albedo.material_albedo`) is a linear
  functional of the table with its negative values set to 0: per-cell
  weights (:func:`brdfpipe.data.merl.mean_directional_albedo_weights`), the
  same for the three channels;
* the squared PR12 distance is a sum of per-cell squared feature differences
  (:class:`brdfpipe.manifold.perceptual.StreamedDistances`).

So :func:`measure_blends` forms the blends a block of cells at a time, exactly
as :func:`brdfpipe.manifold.gplvm.interpolate_tables` does (both call
:func:`brdfpipe.manifold.spaces.blend_block`: in a space that is not linear,
such as ``log``, the blend of the mapped values, mapped back with the space's
inverse; negative values in valid cells clamped to 0, cells not valid in
every material of the store unmeasured), and accumulates the sums: one pass
over the store for all P blends (and, in a space whose maps are statistics
of the materials, one before it: ``log``'s median reference), no table ever
held whole.  ``interpolate_tables`` followed by ``material_albedo`` and
``pr12_distance`` per table gives the same numbers up to the order of
summation (tested to 1e-9 relative in ``tests/test_blendpass.py``); it holds
its P output tables (35 MB each), so callers batched a few points per pass.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.data import merl
from brdfpipe.data.store import BrdfStore, iter_cell_blocks, material_indices, open_store
from brdfpipe.manifold import gplvm, spaces
from brdfpipe.manifold.albedo import ALBEDO_NODES
from brdfpipe.manifold.perceptual import StreamedDistances

__all__ = ["BlendMeasures", "POINT_CELLS", "albedo_cell_weights", "measure_blends"]

logger = logging.getLogger("brdfpipe.manifold.blendpass")

#: Blend values formed at once, points × cells (at most a third of a store chunk of cells): bounds the
#: working arrays (values, PR12 features, their differences: ~150 bytes per point and cell, 0.3 GB)
#: whatever the number of points.
POINT_CELLS = 2_000_000
_MAX_SUB_CELLS = 48_600
_MIN_SUB_CELLS = 256


@dataclass(frozen=True)
class BlendMeasures:
    """What :func:`measure_blends` measured of P interpolated tables."""

    #: White-sky albedo per table and channel ``(P, 3)`` (as :func:`brdfpipe.manifold.albedo.material_albedo`).
    albedo: NDArray[np.float64]
    #: Negative values in valid cells clamped to 0, per table ``(P,)``.
    clamped: NDArray[np.int64]
    #: PR12 distance of each requested pair ``(len(pairs),)``.
    distances: NDArray[np.float64]
    #: ``‖table − z_m‖ / ‖z_m‖`` over the valid cells, z_m the material of ``targets`` (NaN without one) ``(P,)``.
    to_target: NDArray[np.float64]


@lru_cache(maxsize=1)
def albedo_cell_weights(nodes: int = ALBEDO_NODES) -> NDArray[np.float64]:
    """Per-cell weights ``(N_CELLS,)`` of :func:`brdfpipe.manifold.albedo.material_albedo` (read-only)."""
    u = (np.arange(nodes) + 0.5) / nodes
    w = merl.mean_directional_albedo_weights(np.arcsin(np.sqrt(u)))
    w.setflags(write=False)
    return w


def _per_channel(maps: NDArray[np.float64] | None, a: int, b: int) -> NDArray[np.float64] | None:
    """Per-cell maps of cells ``a:b`` repeated for the three channels of a ``(n, 3·m)`` block."""
    return None if maps is None else np.tile(maps[a:b], 3)


def measure_blends(
    store: BrdfStore | str | os.PathLike[str],
    weights: ArrayLike,
    *,
    materials: Sequence[str] | None = None,
    space: str | None = None,
    model: gplvm.GplvmModel | None = None,
    pairs: Sequence[tuple[int, int]] = (),
    albedo_only: bool = False,
    targets: Sequence[int] | None = None,
) -> BlendMeasures:
    """Albedo of each blend ``weights`` ``(P, N)`` and the PR12 distances of ``pairs``, in one pass over the store.

    ``weights``, ``materials``, ``space`` and ``model`` as for
    :func:`brdfpipe.manifold.gplvm.interpolate_tables` (with ``model`` the store
    is checked to hold its rows and ``materials``/``space`` default to its
    own; ``space`` None: the model's, or ``raw`` without one).  ``pairs``:
    ``(i, j)`` row indices of ``weights`` whose tables' distance is wanted
    (only the rows in a pair get PR12 features).  Working memory is bounded
    by :data:`POINT_CELLS`, whatever P.  ``albedo_only`` (no ``pairs``): blend
    only the cells the albedo reads (a fifth of the valid ones: the same
    albedo for a fifth of the work; ``clamped`` then counts those cells).
    ``targets``: per blend, the index (in ``materials``' order) of a material
    whose table's distance from the blend's is wanted, relative to its norm
    (raw units, the clamped blend, as :func:`~brdfpipe.manifold.gplvm.interpolate_tables`
    writes it), or −1.  See the module docstring.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    if model is not None:
        gplvm.check_store(model, st)
        materials = model.names if materials is None else materials
        space = model.space if space is None else space
        if list(materials) != list(model.names) or space != model.space:
            raise ValueError(f"{model.path or 'the model'}: blend over its materials in its space "
                             f"({model.space!r}), got {len(list(materials))} materials in space {space!r}")
    space = "raw" if space is None else space
    spaces.check_blendable(space)
    idx = (np.arange(st.n_materials, dtype=np.intp) if materials is None
           else material_indices(st, materials, "materials"))
    W = np.asarray(weights, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != idx.size:
        raise ValueError(f"weights must have shape (P, {idx.size}) (one per material), got {W.shape}")
    if not np.isfinite(W).all():
        raise ValueError("weights have non-finite entries")
    order = np.argsort(idx, kind="stable")
    rows, W_sorted = idx[order], W[:, order]
    P = W.shape[0]
    tgt = np.full(P, -1, dtype=np.intp) if targets is None else np.asarray(targets, dtype=np.intp)
    if tgt.shape != (P,) or tgt.min(initial=0) < -1 or tgt.max(initial=-1) >= idx.size:
        raise ValueError(f"targets must give one material index in [0, {idx.size}) or -1 per blend")
    aimed = np.flatnonzero(tgt >= 0)
    at_sorted = np.argsort(order)[tgt[aimed]]  # the target materials' rows in the block (store order)
    d2, n2 = np.zeros(P), np.zeros(P)

    if albedo_only and (pairs or targets is not None):
        raise ValueError("albedo_only blends the cells the albedo reads: no distance (pairs, targets) then")
    use = np.asarray(st.valid[:], dtype=bool) & (albedo_cell_weights() != 0 if albedo_only else True)
    cells = np.flatnonzero(use).astype(np.int64)
    a_w = albedo_cell_weights()[cells]
    a_all, b_all = spaces.blend_maps(space, st, [st.materials[i] for i in idx], cells)
    paired = sorted({int(k) for pair in pairs for k in pair})
    if paired and (paired[0] < 0 or paired[-1] >= P):
        raise ValueError(f"pairs must index the {P} blends, got {paired[0]} … {paired[-1]}")
    at = {k: n for n, k in enumerate(paired)}
    dist = StreamedDistances(len(paired), [(at[int(i)], at[int(j)]) for i, j in pairs])

    albedo = np.zeros((P, 3))
    clamped = np.zeros(P, dtype=np.int64)
    sub = int(np.clip(POINT_CELLS // max(P, 1), _MIN_SUB_CELLS, _MAX_SUB_CELLS))
    for j0, j1, data in iter_cell_blocks(st, rows, cells):
        for a in range(0, j1 - j0, sub):
            b = min(a + sub, j1 - j0)
            block = data[:, :, a:b]
            n, m = rows.size, b - a
            vals = spaces.blend_block(space, W_sorted, block.reshape(n, 3 * m),
                                      _per_channel(a_all, j0 + a, j0 + b), _per_channel(b_all, j0 + a, j0 + b))
            neg = vals < 0
            clamped += neg.sum(axis=1)
            vals[neg] = 0.0
            if aimed.size:
                own = block[at_sorted].reshape(aimed.size, 3 * m).astype(np.float64)
                d2[aimed] += np.einsum("ij,ij->i", vals[aimed] - own, vals[aimed] - own)
                n2[aimed] += np.einsum("ij,ij->i", own, own)
            vals = vals.reshape(P, 3, m)
            albedo += vals @ a_w[j0 + a : j0 + b]
            if paired:
                dist.add(cells[j0 + a : j0 + b], vals[paired])
    if clamped.any():
        logger.warning("blends: negative values in measured cells clamped to 0 in %d of %d tables (up to %d values)",
                       int((clamped > 0).sum()), P, int(clamped.max()))
    to_target = np.full(P, np.nan)
    to_target[aimed] = np.sqrt(d2[aimed] / np.where(n2[aimed] > 0, n2[aimed], 1.0))
    return BlendMeasures(albedo=albedo, clamped=clamped, distances=dist.distances(), to_target=to_target)
