"""The Gram matrices of the GPLVM's data, streamed from the store in a data space.

Data
----
``Z`` has one row per material: the concatenated R, G, B values of the cells
valid (measured) in every material of the store, so ``d = 3 × valid cells``
(:func:`gram_matrix`).  The GPLVM (:mod:`brdfpipe.manifold.gplvm`) subtracts
the mean BRDF (column mean over the materials, Soler §3) and needs only the
N × N Gram matrix ``(Z − 1μ̄ᵀ)(Z − 1μ̄ᵀ)ᵀ``, streamed from the store by
blocks of cells and accumulated in float64 (the N × d matrix is never held in
float64), then centred (:func:`centre_gram`).  :func:`cross_gram` makes the
same pass over the store and over materials of other stores, mapped into the
store's data space and centred by its mean (the materials outside the
training set, :mod:`brdfpipe.manifold.unseen`).

Data spaces
-----------
``Z`` holds the stored values mapped to one data space (:data:`~brdfpipe.registry.manifold.SPACE_NAMES`):

* ``raw``: the stored values (the paper);
* ``cosine``: each cell × cos θi · cos θo of its centre (``merl.cell_directions``);
* ``log``: ``ln((ρw + ε)/(ρ_ref w + ε))`` like the acquisition track
  (:func:`brdfpipe.data.logmap.forward`, ``w`` = :func:`brdfpipe.data.logmap.cell_weights`
  "product", ρ_ref = per-cell median over all channels of the materials used);
* ``relative``: each cell × ``cos θi · cos θo / max(ρ_ref, 1e-3)`` (ρ_ref as
  for ``log``): a per-cell weighted inner product on the raw values;
* ``standardised``: each value × ``√(cos θi · cos θo) / σ`` with σ the
  standard deviation of that channel of that cell over the materials used
  (floored at 1e-6 sr⁻¹): every cell carries the same variance, weighted by
  the cosines.

Every space but ``log`` is a fixed per-value scaling ``z̃ = D z`` of the raw
values (:data:`~brdfpipe.registry.manifold.LINEAR_SPACES`): the fit sees ``D z``, but the interpolant
``Σ wᵢ D zᵢ = D Σ wᵢ zᵢ``, so the blend weights apply to the raw BRDFs — and
to images rendered from them (Soler §5.2) — unchanged.  ``log`` is not
linear in the BRDF: its interpolant is a blend of log-mapped values.

Where each part lives: the spaces' names and records (linear or not) in
:data:`brdfpipe.registry.manifold.DATA_SPACES`; their maps — the per-cell maps
computed once over the materials used, and the map of a block of values — in
:mod:`brdfpipe.manifold.spaces`; this module streams the store's cell blocks
through them.  The fit and the interpolation (which maps a ``log`` blend
back) are the GPLVM's: :mod:`brdfpipe.manifold.fitting`,
:mod:`brdfpipe.manifold.gplvm`.

The Gram file
-------------
:func:`save_gram` writes an npz that carries its own digest
(:func:`brdfpipe.core.integrity.save_npz`; :func:`load_gram` checks it, so a
truncated, corrupt or edited file is one :class:`GramFileError` naming it)
and the digests of the store rows it was computed from (the store's
name-bound CRC-32C per row, :func:`brdfpipe.data.store.shard_digest`;
``row_digests``), which a fit carries into its model.  A use of the Gram
matrix with a store checks them (:func:`check_gram_store`), so a store of
the same names whose rows differ is a :class:`DataMismatchError` naming the
file, the store and the material.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.data.store import DIGEST_ALGORITHM, BrdfStore, iter_cell_blocks, material_indices, open_store
from brdfpipe.manifold import spaces
from brdfpipe.registry import manifold as manifold_spec

__all__ = [
    "MEAN_HANDLING",
    "GramInfo",
    "CrossGram",
    "check_space",
    "select_materials",
    "gram_matrix",
    "cross_gram",
    "centre_gram",
    "GRAM_FORMAT",
    "GramFileError",
    "DataMismatchError",
    "digest_array",
    "save_gram",
    "load_gram",
    "write_gram",
    "check_rows",
    "check_gram_store",
]

logger = logging.getLogger("brdfpipe.manifold.gram")

#: How the data are centred: the column mean over the materials is subtracted (:attr:`GramInfo.mean_handling`).
MEAN_HANDLING: Final = "mean subtracted"
#: Cells mapped to float64 at a time within a cell block of the store.
_SUB_COLS: Final = 16384
#: /2: the digests of the store rows (``row_digests``) and the file's digest.
GRAM_FORMAT: Final = "brdfpipe.manifold.gplvm.gram/2"
#: Earlier formats: refused with (why, what to do).
_RETIRED_GRAM_FORMATS: Final = {
    "brdfpipe.manifold.gplvm.gram/1": ("it records no digests of the store rows it was computed from",
                                       "compute it again"),
}


class GramFileError(ValueError):
    """A Gram file is missing, damaged, of another format or inconsistent; names the file."""


class DataMismatchError(ValueError):
    """A Gram file or GPLVM model used with a store whose rows are not the data it was computed from (fitted on)."""


def check_space(space: str) -> str:
    """``space`` if it is a data space (:func:`brdfpipe.registry.manifold.data_space`); otherwise a ValueError listing them."""
    return manifold_spec.data_space(space).name


def select_materials(st: BrdfStore, materials: Sequence[str] | None) -> NDArray[np.intp]:
    """The store rows of ``materials``, in the order given (``None``: every row, in store order).

    ValueError for bad names — not a list, empty, repeated or not in the store
    (:func:`brdfpipe.data.store.material_indices`, under the label ``materials``).
    """
    if materials is None:
        return np.arange(st.n_materials, dtype=np.intp)
    return material_indices(st, materials, "materials")


@dataclass(frozen=True)
class GramInfo:
    """What :func:`gram_matrix` computed besides the centred Gram matrix."""

    materials: tuple[str, ...]
    space: str
    #: Row sums of the (mapped, un-centred) data, ``Z 1`` (N,): the row means are ``row_sums / d``.
    row_sums: NDArray[np.float64] = field(repr=False)
    #: The un-centred Gram matrix ``Z Zᵀ``.
    raw_gram: NDArray[np.float64] = field(repr=False)
    mean_handling: str = MEAN_HANDLING
    #: Digest of each material's store row (:func:`brdfpipe.data.store.shard_digest`, in ``materials`` order);
    #: empty when not computed from a store.
    digests: tuple[int, ...] = field(default=(), repr=False)


def _space_maps(
    st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64], space: str
) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """Per-cell maps of a space over ``cells`` (:mod:`brdfpipe.manifold.spaces`)."""
    return spaces.space_maps(space).cell_maps(st, names, cells)


def _map_block(
    data: NDArray[np.float32], space: str, a: NDArray[np.float64] | None, b: NDArray[np.float64] | None
) -> NDArray[np.float64]:
    """Map a float32 ``(n, 3, cols)`` block to float64 in ``space`` (a, b: the block's per-cell maps)."""
    x = data.astype(np.float64)
    return spaces.space_maps(space).forward(x, a, b, x)


def gram_matrix(
    store_path: str | os.PathLike[str] | BrdfStore,
    *,
    space: str = "raw",
    materials: Sequence[str] | None = None,
) -> tuple[NDArray[np.float64], int, GramInfo]:
    """Centred Gram matrix ``(Z − 1μ̄ᵀ)(Z − 1μ̄ᵀ)ᵀ`` (N × N float64), ``d`` and a :class:`GramInfo`.

    ``Z``: one row per material (``materials`` in the order given, default all
    of the store), the R, G, B values of the cells valid in every material of
    the store, mapped to ``space`` (one of :data:`~brdfpipe.registry.manifold.SPACE_NAMES`, see the module
    docstring); ``d`` = 3 × valid cells.  Streamed by blocks of 145,800
    cells, each mapped to float64 in sub-blocks of 16,384 cells and
    accumulated as ``G += B Bᵀ`` and ``s += B 1``; then centred with
    ``C = I − 11ᵀ/N``: ``Gc = C G C`` equals the Gram matrix of the
    mean-subtracted rows exactly (in exact arithmetic).  ValueError for an
    unknown space or bad material names.
    """
    check_space(space)
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    idx = select_materials(st, materials)
    names = [st.materials[i] for i in idx]
    order = np.argsort(idx, kind="stable")
    rows = idx[order]  # ascending store rows
    cells = np.flatnonzero(np.asarray(st.valid[:], dtype=bool)).astype(np.int64)
    if cells.size == 0:
        raise ValueError(f"{st.path}: no cell is valid in every material")
    a_all, b_all = _space_maps(st, names, cells, space)
    n = rows.size
    G = np.zeros((n, n), dtype=np.float64)
    s = np.zeros(n, dtype=np.float64)
    for j0, j1, data in iter_cell_blocks(st, rows, cells):
        for a0 in range(0, j1 - j0, _SUB_COLS):
            a1 = min(a0 + _SUB_COLS, j1 - j0)
            sa = None if a_all is None else a_all[j0 + a0 : j0 + a1]
            sb = None if b_all is None else b_all[j0 + a0 : j0 + a1]
            B = _map_block(data[:, :, a0:a1], space, sa, sb).reshape(n, -1)
            G += B @ B.T
            s += B.sum(axis=1)
    inv = np.empty_like(order)
    inv[order] = np.arange(n)
    G = G[np.ix_(inv, inv)]
    s = s[inv]
    d = 3 * int(cells.size)
    Gc = centre_gram(G)
    return Gc, d, GramInfo(tuple(names), space, s, G, digests=tuple(int(st.digests[i]) for i in idx))


@dataclass(frozen=True)
class CrossGram:
    """Materials outside a store in its data space: their products with the store's materials (:func:`cross_gram`).

    ``materials``: the store's materials (rows of ``gram``), ``others``:
    ``(database, material)`` of each outside material (columns of
    ``cross``).  With ``Z`` the store's mapped rows, ``μ̄`` their column
    mean and ``o_j`` an outside material mapped the same way: ``gram`` =
    ``(Z − 1μ̄ᵀ)(Z − 1μ̄ᵀ)ᵀ`` (as :func:`gram_matrix`), ``cross[:, j]`` =
    ``(Z − 1μ̄ᵀ)(o_j − μ̄)``, ``norms2[j]`` = ``‖o_j − μ̄‖²`` and
    ``raw_norms2[j]`` = ``‖o_j‖²``; ``d`` = 3 × cells.
    """

    materials: tuple[str, ...]
    others: tuple[tuple[str, str], ...]
    space: str
    gram: NDArray[np.float64] = field(repr=False)
    cross: NDArray[np.float64] = field(repr=False)
    norms2: NDArray[np.float64] = field(repr=False)
    raw_norms2: NDArray[np.float64] = field(repr=False)
    d: int


def cross_gram(
    store_path: str | os.PathLike[str] | BrdfStore,
    others: Sequence[str | os.PathLike[str] | BrdfStore],
    *,
    space: str = "raw",
    materials: Sequence[str] | None = None,
) -> CrossGram:
    """The store's centred Gram matrix and its products with every material of ``others`` (:class:`CrossGram`).

    One streamed pass over the store's rows (``materials``, default all, in
    that order) and the rows of every store of ``others`` (all of theirs),
    cell block by cell block.  Each outside material is mapped to ``space``
    with the *store's* maps — ρ_ref (median of ``materials``) for ``log`` and
    ``relative``, σ of each cell and channel over ``materials`` for
    ``standardised`` — and centred by the store's mean, so that it lies in
    the data space the GPLVM of those materials was fitted in; the Gram
    matrix is computed exactly as :func:`gram_matrix` does (the caller can
    compare it with the one a model was fitted to).  ValueError for a cell
    valid in every material of the store that is not measured in an outside
    material (naming that store), or bad material names.
    """
    check_space(space)
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    outs = [o if isinstance(o, BrdfStore) else open_store(o) for o in others]
    idx = select_materials(st, materials)
    names = [st.materials[i] for i in idx]
    order = np.argsort(idx, kind="stable")
    rows = idx[order]
    cells = np.flatnonzero(np.asarray(st.valid[:], dtype=bool)).astype(np.int64)
    if cells.size == 0:
        raise ValueError(f"{st.path}: no cell is valid in every material")
    for o in outs:
        missing = int((~np.asarray(o.valid[:], dtype=bool)[cells]).sum())
        if missing:
            raise ValueError(f"{o.path}: {missing} cell(s) valid in every material of {st.path} are not measured in "
                             f"every material of {o.path}; its materials cannot be mapped to that data space")
    a_all, b_all = _space_maps(st, names, cells, space)
    n = rows.size
    m_each = [o.n_materials for o in outs]
    m = sum(m_each)
    G = np.zeros((n, n))
    C = np.zeros((n, m))
    norms2 = np.zeros(m)
    raw2 = np.zeros(m)
    blocks = [iter_cell_blocks(o, np.arange(o.n_materials, dtype=np.intp), cells) for o in outs]
    for j0, j1, data in iter_cell_blocks(st, rows, cells):
        other = []
        for o, it in zip(outs, blocks):
            k0, k1, od = next(it)
            if (k0, k1) != (j0, j1):
                raise AssertionError(f"{o.path}: cell blocks out of step")
            other.append(od)
        od_all = np.concatenate(other, axis=0) if other else np.zeros((0, 3, j1 - j0), dtype=np.float32)
        for a0 in range(0, j1 - j0, _SUB_COLS):
            a1 = min(a0 + _SUB_COLS, j1 - j0)
            sa = None if a_all is None else a_all[j0 + a0 : j0 + a1]
            sb = None if b_all is None else b_all[j0 + a0 : j0 + a1]
            train = data[:, :, a0:a1]
            B = _map_block(train, space, sa, sb)
            O = spaces.space_maps(space).forward(od_all[:, :, a0:a1].astype(np.float64), sa, sb, train)
            B = B.reshape(n, -1)
            O = O.reshape(m, -1)
            G += B @ B.T
            mean = B.mean(axis=0)
            Oc = O - mean
            C += (B - mean) @ Oc.T
            norms2 += np.einsum("ij,ij->i", Oc, Oc)
            raw2 += np.einsum("ij,ij->i", O, O)
    inv = np.empty_like(order)
    inv[order] = np.arange(n)
    G = G[np.ix_(inv, inv)]
    C = C[inv]
    others_names = tuple((o.database, name) for o in outs for name in o.materials)
    return CrossGram(tuple(names), others_names, space, centre_gram(G), C, norms2, raw2, 3 * int(cells.size))


def centre_gram(G: ArrayLike) -> NDArray[np.float64]:
    """``C G C`` with ``C = I − 11ᵀ/N`` (double centring), symmetrised."""
    g = np.asarray(G, dtype=np.float64)
    r = g.mean(axis=1, keepdims=True)
    c = g.mean(axis=0, keepdims=True)
    out = g - r - c + g.mean()
    return 0.5 * (out + out.T)


# --------------------------------------------------------------------------
# The Gram file
# --------------------------------------------------------------------------


def digest_array(path: str | os.PathLike[str], digests: Sequence[int], n: int, what: str) -> NDArray[np.uint32]:
    """``digests`` (one 32-bit store-row digest per material, or none) as the uint32 array a file records.

    ValueError naming ``path`` and ``what`` for another count or a value out of range.
    """
    d = np.asarray(list(digests), dtype=np.int64)
    if d.size and (d.shape != (n,) or d.min() < 0 or d.max() >= 2**32):
        raise ValueError(f"{path}: {what} must give one 32-bit digest per material ({n}), got shape {d.shape}")
    return d.astype(np.uint32)


def save_gram(path: str | os.PathLike[str], gram: ArrayLike, d: int, info: GramInfo) -> None:
    """Write a Gram matrix, ``d`` and its :class:`GramInfo` (with the store rows' digests) to an npz, atomically.

    The file carries its own digest (:func:`brdfpipe.core.integrity.save_npz`).
    """
    integrity.save_npz(Path(path), {
        "format": np.array(GRAM_FORMAT),
        "gram": np.asarray(gram, dtype=np.float64),
        "d": np.array(int(d)),
        "materials": np.array(info.materials, dtype=str),
        "space": np.array(info.space),
        "mean_handling": np.array(info.mean_handling),
        "row_sums": info.row_sums,
        "raw_gram": info.raw_gram,
        "row_digests": digest_array(path, info.digests, len(info.materials), "the row digests"),
        "digest_algorithm": np.array(DIGEST_ALGORITHM),
    })


def load_gram(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], int, GramInfo]:
    """Read what :func:`save_gram` wrote, its digest checked.

    :class:`GramFileError` (a ValueError) naming the file and what to rerun
    for a missing, truncated, corrupt, unverifiable or edited file, another
    format or inconsistent arrays.
    """
    z = integrity.load_npz(path, kind="GPLVM Gram file", error=GramFileError, fmt=GRAM_FORMAT,
                           retired=_RETIRED_GRAM_FORMATS)
    try:
        materials = tuple(str(m) for m in z["materials"])
        digests = tuple(int(v) for v in z["row_digests"])
        if str(z["digest_algorithm"]) != DIGEST_ALGORITHM or (digests and len(digests) != len(materials)):
            raise ValueError("row digests of another kind or count")
        info = GramInfo(materials, str(z["space"]), z["row_sums"], z["raw_gram"], str(z["mean_handling"]),
                        digests=digests)
        gram, d = z["gram"], int(z["d"])
    except (KeyError, TypeError, ValueError) as exc:
        raise GramFileError(f"{path}: inconsistent GPLVM Gram file ({type(exc).__name__}: {exc})") from None
    if gram.shape != (len(materials), len(materials)):
        raise GramFileError(f"{path}: Gram matrix of shape {gram.shape} for {len(materials)} materials")
    return gram, d, info


def write_gram(store_path: str | os.PathLike[str], out: str | os.PathLike[str], *, space: str = "raw") -> None:
    """Stream the centred Gram matrix of every material of a store and save it (one pass, float64).

    The workflow's ``compute_gram`` job: every GPLVM fit of that data space
    shares this one file.
    """
    gram, d, info = gram_matrix(store_path, space=space)
    save_gram(out, gram, d, info)
    logger.info("Gram matrix of %d materials over %d columns (%s space) -> %s", gram.shape[0], d, space, out)


def check_rows(label: str, kind: str, names: Sequence[str], digests: Sequence[int], st: BrdfStore, hint: str) -> None:
    """Check that the rows of ``names`` in store ``st`` have the ``digests`` a file recorded for them.

    :class:`DataMismatchError` naming ``label`` (the file), the store and the
    material, ending in ``hint`` (what to do), for no recorded digests, a
    material not in the store or a row whose digest differs.
    """
    if not digests:
        raise DataMismatchError(
            f"{label}: the {kind} records no digests of the store rows it was fitted on, so it cannot be checked "
            f"against the store {st.path}; {hint}"
        )
    index = {m: i for i, m in enumerate(st.materials)}
    missing = [m for m in names if m not in index]
    if missing:
        raise DataMismatchError(
            f"{label}: material(s) {', '.join(missing[:5])}{' …' if len(missing) > 5 else ''} of the {kind} "
            f"are not in the store {st.path}; use the store it was fitted on, or {hint}"
        )
    for name, digest in zip(names, digests):
        if int(st.digests[index[name]]) != int(digest):
            raise DataMismatchError(
                f"{label}: material {name!r} of the store {st.path} is not the data the {kind} was fitted on "
                f"(the row's digest differs: the store was ingested from other files, or its rows were "
                f"swapped); use the store it was fitted on, or {hint}"
            )


def check_gram_store(info: GramInfo, store: BrdfStore | str | os.PathLike[str],
                     path: str | os.PathLike[str] | None = None) -> BrdfStore:
    """Check that ``store`` holds the rows a Gram file was computed from (:func:`check_rows`); returns it opened.

    ``path`` names the file in messages.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    label = str(path) if path is not None else "the Gram matrix"
    hint = (f"compute it again ({integrity.rerun_hint(path)})" if path is not None
            else "compute it again from this store")
    check_rows(label, "Gram matrix", info.materials, info.digests, st, hint)
    return st
