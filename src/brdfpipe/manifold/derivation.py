"""The provenance marks of materials blended from a store with a GPLVM model.

Every MERL file the manifold track writes (``brdfpipe interpolate``,
``sample``, ``extrapolate`` and the workflow's latent-path points) is a blend
``Σ wᵢ zᵢ`` of the store's materials, not a measurement.  It is written with
a ``derived`` mark (:mod:`brdfpipe.data.provenance`) that records

* ``operation`` (``interpolate``, ``sample``, ``extrapolate``, ``path-point``)
  and ``source_database`` (the store's label);
* ``inputs.model``: the sha256 of the model file, its data space, q and
  number of materials;
* ``inputs.store``: :func:`brdfpipe.data.provenance.store_identity` (label,
  number of rows, sha256 of the rows' name-bound digests);
* ``inputs.latent`` (the latent point), ``inputs.weights_sha256`` (sha256 of
  the blend weights as little-endian float64, in the model's material order)
  and the operation's own details (the two materials and t of a path, the
  seed and index of a sample, …).

The mark's bytes depend only on these, so the same model, store and point
give the same file.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from brdfpipe.data import provenance

__all__ = ["BlendSource"]


@dataclass(frozen=True)
class BlendSource:
    """What every blend of one model and one store comes from (digests computed once)."""

    database: str
    model: dict[str, Any]
    store: dict[str, Any]
    names: tuple[str, ...]

    @classmethod
    def of(cls, model_path: str | os.PathLike[str], model: Any, store: Any) -> BlendSource:
        """From a model file, the model loaded from it and the open store.

        ``model``: a :class:`brdfpipe.manifold.gplvm.GplvmModel` (its
        ``space``, ``X`` and ``names``); ``store``: a
        :class:`brdfpipe.data.store.BrdfStore`.
        """
        ident = provenance.store_identity(store)
        info = {"sha256": provenance.file_sha256(model_path), "space": str(model.space),
                "q": int(np.asarray(model.X).shape[1]), "materials": len(model.names)}
        return cls(str(store.database), info, ident, tuple(model.names))

    def mark(
        self, *, out: str | os.PathLike[str], operation: str, point: ArrayLike, weights: ArrayLike, **details: Any
    ) -> provenance.Mark:
        """The ``derived`` mark of the blend written to ``out``.

        ``weights``: one per model material (in the model's order);
        ``point``: the latent point; ``details``: the operation's own inputs.
        """
        w = np.ascontiguousarray(weights, dtype="<f8")
        if w.shape != (len(self.names),):
            raise ValueError(f"weights have shape {w.shape}, expected ({len(self.names)},)")
        inputs = {
            "model": self.model,
            "store": self.store,
            "latent": [float(v) for v in np.asarray(point, dtype=np.float64).ravel()],
            "weights_sha256": hashlib.sha256(w.tobytes()).hexdigest(),
            **details,
        }
        return provenance.derived_mark(name=provenance.output_name(out), operation=operation,
                                       source_database=self.database, inputs=inputs)
