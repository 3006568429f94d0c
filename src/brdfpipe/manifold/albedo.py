"""The white-sky albedo of MERL tables and of a store's materials (Soler et al. 2018 §4.2, Fig. 7).

The albedo of a BRDF is the ratio of the radiance it reflects under a
uniform incident distribution to that distribution's irradiance:
``A = (1/π) ∫∫ f(ωi, ωo) cos θi cos θo dωi dωo`` (the white-sky albedo).
With the directional albedo ``a(θi) = ∫ f cos θo dωo``
(:func:`brdfpipe.data.merl.directional_albedo`) and ``u = sin²θi``,
``A = ∫₀¹ a(θi(u)) du``; :func:`material_albedo` takes the midpoint rule with
:data:`ALBEDO_NODES` nodes in ``u``.  Used by the manifold's analyses
(:mod:`brdfpipe.manifold.analysis`), its latent-space tools
(:mod:`brdfpipe.manifold.latent`) and the fidelity measurements.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.data import merl
from brdfpipe.data.store import BrdfStore, iter_column_blocks, open_store

__all__ = ["ALBEDO_NODES", "material_albedo", "material_albedos", "write_material_albedos",
           "read_material_albedos", "MaterialAlbedoError"]

logger = logging.getLogger("brdfpipe.manifold.albedo")

#: Midpoint nodes in u = sin²θi for the albedo integral.
ALBEDO_NODES: Final = 16
#: Format tag of the material-albedo file (:func:`write_material_albedos`).
ALBEDO_FORMAT: Final = "brdfpipe.material-albedo/1"


class MaterialAlbedoError(ValueError):
    """A material-albedo file that is damaged, of another store, or lacks a material asked for."""




def material_albedo(table: ArrayLike, nodes: int = ALBEDO_NODES) -> NDArray[np.float64]:
    """White-sky albedo ``(1/π)∬ f cosθi cosθo`` of a MERL table (physical units), per channel ``(3,)``."""
    if nodes < 1:
        raise ValueError(f"nodes must be >= 1, got {nodes}")
    u = (np.arange(nodes) + 0.5) / nodes
    theta_i = np.arcsin(np.sqrt(u))
    return merl.directional_albedo(table, theta_i).mean(axis=0)


def _read_tables(st: BrdfStore, rows: NDArray[np.intp]) -> NDArray[np.float64]:
    """Tables of store rows (ascending), ``(n, 3, 90, 90, 180)`` float64; unmeasured cells negative as stored."""
    out = np.empty((rows.size, 3 * merl.N_CELLS))
    for start, stop, block in iter_column_blocks(st, rows=rows):
        out[:, start:stop] = block
    return out.reshape((rows.size, *merl.SHAPE))


def material_albedos(store: BrdfStore | str | os.PathLike[str], materials: Sequence[str]) -> NDArray[np.float64]:
    """Albedo ``(N, 3)`` of each named material of the store (read a few materials at a time)."""
    st = store if isinstance(store, BrdfStore) else open_store(store)
    index = {m: i for i, m in enumerate(st.materials)}
    unknown = [m for m in materials if m not in index]
    if unknown:
        raise ValueError(f"{st.path}: unknown material(s) {', '.join(unknown)}")
    rows = np.array([index[m] for m in materials], dtype=np.intp)
    out = np.empty((rows.size, 3))
    order = np.argsort(rows, kind="stable")
    batch = 8
    for b0 in range(0, rows.size, batch):
        pick = order[b0 : b0 + batch]
        tables = _read_tables(st, rows[pick])
        for k, i in enumerate(pick):
            out[i] = material_albedo(tables[k])
        logger.info("albedo: %d / %d materials", min(b0 + batch, rows.size), rows.size)
    return out


def write_material_albedos(*, store: BrdfStore | str | os.PathLike[str], out: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Albedo ``(N, 3)`` of every material of ``store`` (:func:`material_albedos`), written to ``out``.

    The workflow's ``measure_material_albedos`` job: the albedos every GPLVM
    candidate's measurement and the manifold's analyses need, computed once.
    The npz (digest-checked, :func:`brdfpipe.core.integrity.save_npz`) holds
    the material names, the albedos, the database and each store row's
    digest, so :func:`read_material_albedos` can refuse a file of another
    store.  Returns the albedos.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    names = list(st.materials)
    A = material_albedos(st, names)
    integrity.save_npz(out, {
        "format": np.array(ALBEDO_FORMAT), "names": np.array(names), "albedo": A,
        "database": np.array(st.database), "row_digests": np.asarray(st.digests, dtype=np.int64),
    })
    return A


def read_material_albedos(path: str | os.PathLike[str], store: BrdfStore, names: Sequence[str]) -> NDArray[np.float64]:
    """The albedos ``(len(names), 3)`` of ``names`` from a :func:`write_material_albedos` file, checked.

    :class:`MaterialAlbedoError` naming ``path`` for a damaged file (digest),
    another format, a file written from another store (database or a row's
    digest differs: the store was ingested again) or a name it lacks; each
    says what to rerun.
    """
    hint = integrity.rerun_hint(path)
    doc = integrity.load_npz(path, kind="material-albedo file", error=MaterialAlbedoError)
    if "format" not in doc or str(doc["format"]) != ALBEDO_FORMAT:
        raise MaterialAlbedoError(f"{path}: not a material-albedo file ({ALBEDO_FORMAT}); {hint}")
    stored = [str(n) for n in doc["names"]]
    A, digests = np.asarray(doc["albedo"], dtype=np.float64), np.asarray(doc["row_digests"], dtype=np.int64)
    if A.shape != (len(stored), 3) or digests.shape != (len(stored),):
        raise MaterialAlbedoError(f"{path}: albedo array of shape {A.shape} for {len(stored)} materials; {hint}")
    if str(doc["database"]) != store.database:
        raise MaterialAlbedoError(f"{path}: written from a {doc['database']} store, but {store.path} holds "
                                  f"{store.database}; {hint}")
    index = {m: i for i, m in enumerate(stored)}
    rows = {m: i for i, m in enumerate(store.materials)}
    out = np.empty((len(names), 3))
    for k, name in enumerate(names):
        if name not in index:
            raise MaterialAlbedoError(f"{path}: no albedo of material {name!r}; {hint}")
        if name not in rows or int(store.digests[rows[name]]) != int(digests[index[name]]):
            raise MaterialAlbedoError(f"{path}: the albedo of {name!r} was computed from other data than the "
                                      f"store {store.path} holds (its row's digest differs); {hint}")
        out[k] = A[index[name]]
    return out
