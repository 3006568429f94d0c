"""Materials at random latent points of the manifold, written for rendering (Soler et al. 2018 §4.3, Fig. 1).

"Figure 1 shows images rendered using 11 materials chosen from randomly
sampled points in the latent space and 4 images corresponding to actual
BRDFs."  The workflow's ``sample_latent_materials`` job
(:func:`sample_to_files`) draws its points exactly as ``brdfpipe sample``
does (:func:`brdfpipe.manifold.latent.sample_material`: uniform in the convex
hull of the materials' latent points, kept when the interpolated material's
albedo is in [0, 1]; the same seed and count give the same points), writes
each material as a MERL table with its ``derived`` provenance mark
(:func:`brdfpipe.manifold.latent.write_blends`, operation ``sample``) and a
JSON file saying what each one is (:data:`SAMPLES_FORMAT`); the rendering
track renders them in the pre-renders' scene and settings.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from typing import Any, Final

import numpy as np

from brdfpipe.core import integrity
from brdfpipe.data.provenance import output_name
from brdfpipe.data.store import open_store
from brdfpipe.manifold import gplvm, latent
from brdfpipe.manifold.albedo import read_material_albedos
from brdfpipe.registry.manifold import LINEAR_SPACES

__all__ = ["SAMPLES_FORMAT", "sample_to_files", "read_samples"]

logger = logging.getLogger("brdfpipe.manifold.samples")

#: ``format`` of the samples JSON written by :func:`sample_to_files`.
SAMPLES_FORMAT: Final = "brdfpipe.latent-samples/1"


def sample_to_files(
    *,
    model: str | os.PathLike[str],
    store: str | os.PathLike[str],
    albedos: str | os.PathLike[str],
    seed: int,
    merl_outs: Sequence[str | os.PathLike[str]],
    json_out: str | os.PathLike[str],
) -> dict[str, Any]:
    """Draw ``len(merl_outs)`` materials at random latent points of ``model``; write their tables and ``json_out``.

    ``albedos``: the materials' albedo file (:func:`brdfpipe.manifold.albedo.write_material_albedos`,
    checked against the store), the albedos :func:`~brdfpipe.manifold.latent.sample_material`
    accepts a point by in a linear data space (in the others the blended
    tables' own, from the store, as ``brdfpipe sample``).  The tables
    written are blended in one pass over the store.
    ``json_out`` (with its digest) holds ``format``, ``seed``, ``count``,
    ``q``, ``space``, ``candidates_drawn`` and per sample its ``file`` (the
    table's name), ``latent`` point, ``albedo`` (RGB), ``weights``
    {material: wᵢ}, ``sum_abs_w`` (Σ|wᵢ|), ``clamped`` (negative values of
    measured cells written as 0) and ``measured_values``.  Returns that
    document.
    """
    count = len(merl_outs)
    if count < 1:
        raise ValueError("need at least one output table")
    m = gplvm.load_model(model)
    st = gplvm.check_store(m, open_store(store))
    # the albedo a point is accepted by: w·A in the linear spaces, the blended table's in the others (as the CLI)
    source = read_material_albedos(albedos, st, m.names) if m.space in LINEAR_SPACES else st
    drawn = latent.sample_material(m, source, np.random.default_rng(int(seed)), count)
    details = [{"seed": int(seed), "count": count, "index": i} for i in range(count)]
    clamped = latent.write_blends(model, m, st, drawn.points, merl_outs, operation="sample", details=details,
                                  batch=count)
    measured = 3 * int(np.count_nonzero(st.valid))  # values of the measured cells in each table (R, G, B)
    samples = []
    for i, out in enumerate(merl_outs):
        w = drawn.weights[i]
        samples.append({
            "file": output_name(out), "latent": [float(v) for v in drawn.points[i]],
            "albedo": [float(v) for v in drawn.albedos[i]],
            "weights": {n: float(v) for n, v in zip(m.names, w)},
            "sum_abs_w": float(np.abs(w).sum()), "clamped": int(clamped[i]), "measured_values": measured,
        })
    doc = {"format": SAMPLES_FORMAT, "seed": int(seed), "count": count, "q": int(m.X.shape[1]), "space": m.space,
           "candidates_drawn": int(drawn.tries), "samples": samples}
    integrity.write_json(json_out, doc)
    logger.info("%d materials at random latent points (seed %d, %d candidates drawn) -> %s", count, seed,
                drawn.tries, json_out)
    return doc


def read_samples(path: str | os.PathLike[str], error: type[Exception] = ValueError) -> dict[str, Any]:
    """The samples JSON of :func:`sample_to_files`, its digest and format checked (``error`` naming the file)."""
    doc = integrity.read_json(path, kind="latent samples file", error=error)
    try:
        ok = doc["format"] == SAMPLES_FORMAT and len(doc["samples"]) == int(doc["count"]) and all(
            isinstance(s["file"], str) and len(s["latent"]) == int(doc["q"]) for s in doc["samples"])
    except (KeyError, TypeError, ValueError):
        ok = False
    if not ok:
        raise error(f"{path}: not a latent samples file (format {SAMPLES_FORMAT})")
    return doc
