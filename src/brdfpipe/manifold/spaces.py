"""The maps of the manifold's data spaces: how a block of stored values becomes what the GPLVM sees.

One :class:`SpaceMaps` per data space of :data:`brdfpipe.registry.manifold.DATA_SPACES`
(the records: name, linear or not), registered under the same name in
:data:`MAPS`.  A space maps in two steps, so the Gram matrix
(:func:`brdfpipe.manifold.gram.gram_matrix`) streams the store once:

* ``cell_maps(store, names, cells)`` → ``(a, b)``: per-cell arrays computed
  once over the materials used (``None`` where the space needs none);
* ``forward(x, a, b, train)``: a float64 block ``x`` (n, 3, cols) of values
  mapped with the block's ``a``, ``b``; ``train``, the same cells of the
  training materials (float32 or float64: the statistic is taken in float64), for spaces whose scale is a statistic over
  the materials (``standardised``: σ of each channel of each cell).

* ``inverse(y, a, b)``: for a space that is not linear and is invertible
  (the spec's ``invertible``), the map of a blend of mapped values back to
  values, with the same per-cell maps; ``None`` for the others.

Every map but ``log`` multiplies each value by a constant (the spec's
``linear``): the interpolant of such a space blends the raw BRDFs with the
same weights.  A space that is not linear blends mapped values, and the
interpolant and the blend pass (:func:`brdfpipe.manifold.gplvm.interpolate_tables`,
:mod:`brdfpipe.manifold.blendpass`) map the blend back with its ``inverse``:
both dispatch on these records alone (:func:`blend_block`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from brdfpipe.data import logmap, merl
from brdfpipe.data.store import BrdfStore
from brdfpipe.registry import manifold as manifold_spec

__all__ = [
    "RELATIVE_FLOOR",
    "STANDARDISED_FLOOR",
    "CellMaps",
    "SpaceMaps",
    "MAPS",
    "space_maps",
    "check_blendable",
    "blend_maps",
    "blend_block",
]

#: Floor of ρ_ref in the ``relative`` space (sr⁻¹) and of σ in the ``standardised`` space.
RELATIVE_FLOOR: Final = 1e-3
STANDARDISED_FLOOR: Final = 1e-6

F64 = NDArray[np.float64]
#: Per-cell maps of a space over the cells used: ``(a, b)``, either None when the space needs none.
CellMaps = tuple[F64 | None, F64 | None]


@dataclass(frozen=True)
class SpaceMaps:
    """The steps of one data space's map and, for a space that is not linear, its inverse (module docstring)."""

    cell_maps: Callable[[BrdfStore, Sequence[str], NDArray[np.int64]], CellMaps]
    forward: Callable[[F64, F64 | None, F64 | None, NDArray[Any]], F64]
    inverse: Callable[[F64, F64 | None, F64 | None], F64] | None = None


def _cosines(cells: NDArray[np.int64]) -> F64:
    """cos θi · cos θo of each cell's centre."""
    wi, wo = merl.cell_directions(cells)
    return wi[:, 2] * wo[:, 2]


def _no_maps(st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    return None, None


def _cosine_maps(st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    return _cosines(cells), None


def _relative_maps(st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    cos = _cosines(cells)
    ref = logmap.median_reference(st, list(names), cells)
    return cos / np.maximum(ref, RELATIVE_FLOOR), None


def _standardised_maps(st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    return np.sqrt(np.maximum(_cosines(cells), 0.0)), None


def _log_maps(st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    return logmap.median_reference(st, list(names), cells), logmap.cell_weights(cells, "product")


def _identity(x: F64, a: F64 | None, b: F64 | None, train: NDArray[Any]) -> F64:
    return x


def _scale(x: F64, a: F64 | None, b: F64 | None, train: NDArray[Any]) -> F64:
    assert a is not None
    x *= a
    return x


def _standardise(x: F64, a: F64 | None, b: F64 | None, train: NDArray[Any]) -> F64:
    # σ of each (channel, cell) over the training materials of the block: every row is in the block
    assert a is not None
    x *= a / np.maximum(np.asarray(train, dtype=np.float64).std(axis=0), STANDARDISED_FLOOR)
    return x


def _log_forward(x: F64, a: F64 | None, b: F64 | None, train: NDArray[Any]) -> F64:
    assert a is not None and b is not None
    return logmap.forward(x, a, b)


def _log_inverse(y: F64, a: F64 | None, b: F64 | None) -> F64:
    assert a is not None and b is not None
    return logmap.inverse(y, a, b)


#: Data space → its maps (the names of :data:`brdfpipe.registry.manifold.DATA_SPACES`; a test keeps them equal).
MAPS: dict[str, SpaceMaps] = {
    "raw": SpaceMaps(_no_maps, _identity),
    "cosine": SpaceMaps(_cosine_maps, _scale),
    "log": SpaceMaps(_log_maps, _log_forward, _log_inverse),
    "relative": SpaceMaps(_relative_maps, _scale),
    "standardised": SpaceMaps(_standardised_maps, _standardise),
}


def space_maps(space: str) -> SpaceMaps:
    """The maps of ``space``; ValueError naming the known spaces for an unknown one, or a registered space
    whose maps are missing here."""
    manifold_spec.data_space(space)
    try:
        return MAPS[space]
    except KeyError:
        raise ValueError(f"data space {space!r} has no maps in brdfpipe.manifold.spaces.MAPS") from None


def check_blendable(space: str) -> str:
    """``space``, if its blends can be turned into tables: linear, or with its inverse in its maps.

    ValueError otherwise (a space that is not linear and has no inverse):
    never a blend of mapped values read as raw values.  The config check
    refuses such a space at parse time from its record
    (:attr:`brdfpipe.registry.manifold.DataSpace.blendable`).
    """
    spec = manifold_spec.data_space(space)
    if not spec.linear and space_maps(space).inverse is None:
        raise ValueError(f"data space {space!r} is not linear and has no inverse in its maps "
                         f"(brdfpipe.manifold.spaces.MAPS): its blends cannot become tables")
    return space


def blend_maps(space: str, st: BrdfStore, names: Sequence[str], cells: NDArray[np.int64]) -> CellMaps:
    """The per-cell maps that :func:`blend_block` needs at ``cells``, over the blended materials ``names``.

    ``(None, None)`` for a linear space (its blends are of the values as they
    are); the space's ``cell_maps`` otherwise (e.g. ``log``: ρ_ref, the
    median of ``names``, one pass over the store, and the cell weights).
    """
    if manifold_spec.data_space(space).linear:
        return None, None
    return space_maps(space).cell_maps(st, names, cells)


def blend_block(space: str, weights: F64, block: NDArray[Any], a: F64 | None, b: F64 | None) -> F64:
    """The blends ``weights @ block`` of one block of values, as values: ``(P, cols)`` float64.

    ``block`` is ``(n, cols)`` (the blended materials' values at ``cols``
    channel-cells, float32 or float64), ``weights`` ``(P, n)``, ``a`` and
    ``b`` the space's per-cell maps at those columns.  A linear space blends
    the values as they are (its factor is per value: blending before or after
    it is the same); any other space blends its mapped values and maps the
    blend back with its inverse (:func:`check_blendable` first).
    """
    if manifold_spec.data_space(space).linear:
        return weights @ block.astype(np.float64)
    maps = space_maps(space)
    assert maps.inverse is not None, f"data space {space!r}: check_blendable first"
    x = np.asarray(block, dtype=np.float64)
    return maps.inverse(weights @ maps.forward(x, a, b, x), a, b)
