"""The GPLVM over measured materials (Soler et al. 2018, §2.1–§3): the fitted model, its file and interpolation.

Data
----
``Z`` has one row per material (``d`` columns: the R, G, B values of the
cells valid in every material of the store, mapped to a data space).  The
mean BRDF (column mean over the materials) is subtracted (Soler §3), so far
from the data the interpolant tends to the mean.  The optimisation needs
only the N × N Gram matrix ``(Z − 1μ̄ᵀ)(Z − 1μ̄ᵀ)ᵀ``: how it is streamed from
the store, the data spaces, and why the blend weights of every space but
``log`` apply to the raw BRDFs are in :mod:`brdfpipe.manifold.gram`
(:func:`~brdfpipe.manifold.gram.gram_matrix`, and the Gram file).  The kernel
and the likelihood are in :mod:`brdfpipe.manifold.likelihood`, the fit (its
start and its three optimisers) in :mod:`brdfpipe.manifold.fitting`; this
module holds what a fit leaves: the model (:class:`GplvmModel`), its file and
the interpolation between the materials.

Files and their data
--------------------
:func:`save_model` writes an npz file that carries its own digest
(:func:`brdfpipe.core.integrity.save_npz`; :func:`load_model` checks it, so
a truncated, corrupt or edited file is one :class:`GplvmFileError` naming it)
and the digests of the store rows the model was fitted on (``data_digests``,
carried from the Gram file's ``row_digests``:
:func:`brdfpipe.manifold.gram.save_gram`).  Every use of a model with a store
checks them (:func:`check_store`: :func:`interpolate_tables` given the model,
:func:`interpolate_to_file`, :mod:`brdfpipe.manifold.latent`,
:mod:`brdfpipe.manifold.analysis`, :mod:`brdfpipe.manifold.fidelity`, the
workflow's path points, the command line), so a store of the same names
whose rows differ — ingested from other files, rows swapped — is a
:class:`~brdfpipe.manifold.gram.DataMismatchError` naming the model, the
store and the material, never another material's BRDF under a name.

Interpolation
-------------
``b(x*) = K⁻¹ k(x*)`` (eq. 4) and the interpolated BRDF is
``z* = μ̄ + bᵀ(Z − 1μ̄ᵀ) = Σ w_i z_i`` with ``w_i = b_i + (1 − Σb)/N``
(:func:`blend_weights`; Σw = 1), so images rendered from the materials blend
with the same ``w``.  "Exact reproduction": ``k(x*)`` includes the μδ term
when ``x*`` coincides (bitwise) with a training point ``x_i``, so ``k(x_i)``
is column ``i`` of ``K`` and ``b(x_i) = e_i`` (to rounding); an ``x*`` a hair
away from ``x_i`` drops the δ term and gives ``b ≈ e_i·1/(1+μ)``-like
weights (the "negligible discontinuity" of Soler §3).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import integrity
from brdfpipe.core.threads import blas_threads
from brdfpipe.data import merl
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import DIGEST_ALGORITHM, BrdfStore, iter_column_blocks, open_store
from brdfpipe.manifold import derivation, spaces
from brdfpipe.manifold.fitting import FitResult, fit
from brdfpipe.manifold.gram import (
    MEAN_HANDLING,
    check_rows,
    check_space,
    digest_array,
    load_gram,
    select_materials,
)
from brdfpipe.manifold.likelihood import check_latents, gram_scale, kernel_matrix, kernel_vector
from brdfpipe.registry import tables

__all__ = [
    "MODEL_FORMAT",
    "GplvmFileError",
    "GplvmModel",
    "weights",
    "blend_weights",
    "interpolate_table",
    "interpolate_tables",
    "save_model",
    "load_model",
    "check_store",
    "fit_to_files",
    "write_trace",
    "interpolate_to_file",
]

logger = logging.getLogger("brdfpipe.manifold.gplvm")

#: /3: how it was fitted (``normalised``, ``init``) besides the digests of the store rows it was fitted on.
MODEL_FORMAT: Final = "brdfpipe.gplvm/3"
#: Earlier formats: refused with (why, what to do).
_RETIRED_FORMATS: Final = {
    "brdfpipe.gplvm/1": ("it records no digests of the store rows it was fitted on", "refit it"),
    "brdfpipe.gplvm/2": ("it records neither its normalisation nor its initialisation", "refit it"),
}


class GplvmFileError(ValueError):
    """A GPLVM model file is missing, damaged, of another format or inconsistent; names the file."""


# --------------------------------------------------------------------------
# Interpolation
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class GplvmModel:
    """A saved fit (:func:`save_model` / :func:`load_model`)."""

    names: tuple[str, ...]
    X: NDArray[np.float64]
    ell: float
    mu: float
    space: str
    mean_handling: str
    #: Lower Cholesky factor of K (for b = K⁻¹k).
    chol: NDArray[np.float64] = field(repr=False)
    log_likelihood: float
    d: float
    trace: NDArray[np.float64] = field(repr=False)
    #: The Gram matrix was divided by this before fitting (1.0: not normalised); L is of ``G/gram_scale``.
    gram_scale: float = 1.0
    method: str = "hooke-jeeves"
    #: Whether the Gram matrix was normalised (divided by its
    #: :func:`~brdfpipe.manifold.likelihood.gram_scale`) before fitting.
    normalised: bool = True
    #: The start asked for (``init_scale`` of :func:`~brdfpipe.manifold.fitting.fit`: ``best``, ``pca`` or a
    #: scale rule).
    init: str = "best"
    #: Digest of the store row each material was fitted on (:func:`brdfpipe.data.store.shard_digest`, in
    #: ``names`` order); empty: not tied to a store (it cannot be used with one, see :func:`check_store`).
    data_digests: tuple[int, ...] = field(default=(), repr=False)
    #: The file it was loaded from (for messages), if any.
    path: Path | None = field(default=None, repr=False, compare=False)


def weights(
    fit_or_X: FitResult | GplvmModel | ArrayLike,
    x_star: ArrayLike,
    ell: float | None = None,
    mu: float | None = None,
) -> NDArray[np.float64]:
    """``b = K⁻¹ k(x*)`` (N,) (eq. 4), with the δ convention of the module docstring (b(x_i) = e_i).

    ``fit_or_X``: a :class:`~brdfpipe.manifold.fitting.FitResult`, a
    :class:`GplvmModel` (ℓ, μ default to theirs) or an N × q latent matrix
    (ℓ, μ default to 1, 1e-4).  ValueError if ``x_star`` is not a length-q
    vector.
    """
    chol = None
    if isinstance(fit_or_X, (FitResult, GplvmModel)):
        X = fit_or_X.X
        ell = fit_or_X.ell if ell is None else ell
        mu = fit_or_X.mu if mu is None else mu
        if isinstance(fit_or_X, GplvmModel) and ell == fit_or_X.ell and mu == fit_or_X.mu:
            chol = fit_or_X.chol
    else:
        X = check_latents(fit_or_X)
        ell = 1.0 if ell is None else ell
        mu = 1e-4 if mu is None else mu
    k = kernel_vector(X, x_star, ell, mu)
    if chol is None:
        chol = np.linalg.cholesky(kernel_matrix(X, ell, mu))
    return scipy.linalg.cho_solve((chol, True), k)


def blend_weights(b: ArrayLike) -> NDArray[np.float64]:
    """``w_i = b_i + (1 − Σb)/N``: weights of the un-centred material rows, Σw = 1.

    ``z* = μ̄ + bᵀ(Z − 1μ̄ᵀ) = Σ_i w_i z_i``, so images of the materials blend
    with the same ``w``.
    """
    b64 = np.asarray(b, dtype=np.float64)
    if b64.ndim != 1 or b64.size == 0:
        raise ValueError(f"b must be a non-empty vector, got shape {b64.shape}")
    return b64 + (1.0 - b64.sum()) / b64.size


def interpolate_table(
    store_path: str | os.PathLike[str] | BrdfStore,
    weights: ArrayLike,
    *,
    materials: Sequence[str] | None = None,
    space: str = "raw",
    model: GplvmModel | None = None,
) -> tuple[NDArray[np.float64], int]:
    """``Σ_i w_i z_i`` as a MERL table ``(3, 90, 90, 180)`` float64 and the number of clamped values.

    ``weights``: blend weights (:func:`blend_weights`) of ``materials`` (in
    that order; default all of the store).  See :func:`interpolate_tables`
    (also for ``model``).
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1:
        raise ValueError(f"weights must be a vector (one per material), got shape {w.shape}")
    tables, clamped = interpolate_tables(store_path, w[None, :], materials=materials, space=space, model=model)
    return tables[0], int(clamped[0])


def interpolate_tables(
    store_path: str | os.PathLike[str] | BrdfStore,
    weights: ArrayLike,
    *,
    materials: Sequence[str] | None = None,
    space: str = "raw",
    model: GplvmModel | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Several blends ``W Z`` in one pass over the store: tables ``(P, 3, 90, 90, 180)`` and clamp counts ``(P,)``.

    ``model``: the model whose weights these are; the store is then checked
    to hold the rows it was fitted on (:func:`check_store`), ``materials``
    defaults to its materials and must be them, and ``space`` must be its
    space.

    ``weights`` is ``(P, N)``: one row of blend weights per output table,
    over ``materials`` (in that order; default all of the store).  In a
    linear space the blend is of the stored values (their factor is per
    value, so blending before or after it is the same); in any other the
    blend is of the mapped values, with the same per-cell maps (computed over
    ``materials``) as :func:`~brdfpipe.manifold.gram.gram_matrix`, mapped back
    with the space's inverse (:func:`brdfpipe.manifold.spaces.blend_block`).  Cells not valid in
    every material of the store are written as −1 (unmeasured, like MERL);
    values that come out negative in valid cells are clamped to 0 and
    counted (logged as a warning).  Streamed by column blocks of the store;
    the P output tables (8·4.37M bytes each) are the memory cost.
    """
    check_space(space)
    st = store_path if isinstance(store_path, BrdfStore) else open_store(store_path)
    if model is not None:
        check_store(model, st)
        materials = model.names if materials is None else materials
        if list(materials) != list(model.names) or space != model.space:
            raise ValueError(f"{model.path or 'the model'}: interpolate over its materials in its space "
                             f"({model.space!r}), got {len(list(materials))} materials in space {space!r}")
    spaces.check_blendable(space)
    idx = select_materials(st, materials)
    W = np.asarray(weights, dtype=np.float64)
    if W.ndim != 2 or W.shape[1] != idx.size:
        raise ValueError(f"weights must have shape (P, {idx.size}) (one per material), got {W.shape}")
    if not np.isfinite(W).all():
        raise ValueError("weights have non-finite entries")
    order = np.argsort(idx, kind="stable")
    rows, W_sorted = idx[order], W[:, order]
    valid = np.asarray(st.valid[:], dtype=bool)
    cells = np.flatnonzero(valid).astype(np.int64)
    a_all, b_all = spaces.blend_maps(space, st, [st.materials[i] for i in idx], cells)
    P = W.shape[0]
    out = np.full((P, 3 * N_CELLS), -1.0)
    clamped = np.zeros(P, dtype=np.int64)
    for start, stop, block in iter_column_blocks(st, rows=rows):
        cell = np.arange(start, stop) % N_CELLS
        keep = valid[cell]
        if not keep.any():
            continue
        pos = np.searchsorted(cells, cell[keep])
        vals = spaces.blend_block(space, W_sorted, block[:, keep],
                                  None if a_all is None else a_all[pos], None if b_all is None else b_all[pos])
        neg = vals < 0
        clamped += neg.sum(axis=1)
        vals[neg] = 0.0
        seg = out[:, start:stop]
        seg[:, keep] = vals
    if clamped.any():
        logger.warning("interpolated tables: %s negative values in measured cells clamped to 0", clamped.tolist())
    return out.reshape((P, *merl.SHAPE)), clamped



# --------------------------------------------------------------------------
# Saving a fit
# --------------------------------------------------------------------------


def save_model(
    path: str | os.PathLike[str],
    result: FitResult,
    names: Sequence[str],
    *,
    space: str = "raw",
    mean_handling: str = MEAN_HANDLING,
    gram_scale: float = 1.0,
    normalised: bool = True,
    init: str = "best",
    data_digests: Sequence[int] = (),
) -> None:
    """Write a fit to an npz file atomically, with its digest (:func:`brdfpipe.core.integrity.save_npz`).

    Arrays: names, X, ℓ, μ, space, mean handling, chol(K) (the factor that
    interpolation needs: ``b = K⁻¹k``), L, d, trace, gram scale, method,
    ``normalised`` (the Gram matrix divided by the gram scale), ``init`` (the
    start asked for) and ``data_digests``: the digests of the store rows the materials were fitted
    on (from the Gram file, :attr:`brdfpipe.manifold.gram.GramInfo.digests`; empty for a fit that
    did not come from a store), which every use with a store checks
    (:func:`check_store`).
    """
    check_space(space)
    names = [str(n) for n in names]
    if len(names) != result.X.shape[0]:
        raise ValueError(f"{len(names)} names for {result.X.shape[0]} latent points")
    chol = np.linalg.cholesky(kernel_matrix(result.X, result.ell, result.mu))
    integrity.save_npz(Path(path), {
        "format": np.array(MODEL_FORMAT),
        "names": np.array(names, dtype=str),
        "X": result.X,
        "ell": np.array(result.ell),
        "mu": np.array(result.mu),
        "space": np.array(space),
        "mean_handling": np.array(mean_handling),
        "chol": chol,
        "log_likelihood": np.array(result.log_likelihood),
        "d": np.array(result.d),
        "trace": np.array(result.trace, dtype=np.float64).reshape(-1, 2),
        "gram_scale": np.array(float(gram_scale)),
        "method": np.array(result.method),
        "normalised": np.array(bool(normalised)),
        "init": np.array(str(init)),
        "data_digests": digest_array(path, data_digests, len(names), "data_digests"),
        "digest_algorithm": np.array(DIGEST_ALGORITHM),
    })


def load_model(path: str | os.PathLike[str]) -> GplvmModel:
    """Read what :func:`save_model` wrote, its digest checked.

    :class:`GplvmFileError` (a ValueError) naming the file and what to rerun
    for a missing, truncated, corrupt, unverifiable or edited file, a retired
    or other format, or inconsistent arrays.
    """
    z = integrity.load_npz(path, kind="GPLVM model", error=GplvmFileError, fmt=MODEL_FORMAT,
                           retired=_RETIRED_FORMATS)
    try:
        names = tuple(str(n) for n in z["names"])
        X = np.asarray(z["X"], dtype=np.float64)
        digests = tuple(int(v) for v in z["data_digests"])
        if str(z["digest_algorithm"]) != DIGEST_ALGORITHM:
            raise ValueError(f"data digests of another kind ({str(z['digest_algorithm'])!r})")
        model = GplvmModel(
            names, X, float(z["ell"]), float(z["mu"]), str(z["space"]),
            str(z["mean_handling"]), z["chol"], float(z["log_likelihood"]), float(z["d"]), z["trace"],
            float(z["gram_scale"]), str(z["method"]), bool(z["normalised"]), str(z["init"]),
            data_digests=digests, path=Path(path),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise GplvmFileError(f"{path}: inconsistent GPLVM model ({type(exc).__name__}: {exc})") from None
    n = len(names)
    if X.ndim != 2 or X.shape[0] != n or model.chol.shape != (n, n) or (digests and len(digests) != n):
        raise GplvmFileError(f"{path}: inconsistent GPLVM model (X {X.shape}, chol {model.chol.shape} for "
                             f"{n} materials, {len(digests)} data digests)")
    return model


def check_store(model: GplvmModel, store: BrdfStore | str | os.PathLike[str]) -> BrdfStore:
    """Check that ``store`` holds the rows ``model`` was fitted on; returns the opened store.

    Every material of the model must be in the store with the row digest the
    model recorded (:attr:`GplvmModel.data_digests`), so a store of the same
    names whose rows differ (re-ingested from other files, rows swapped) is
    refused with a :class:`~brdfpipe.manifold.gram.DataMismatchError` naming the model, the store and
    the material, as is a model that records no digests.
    """
    st = store if isinstance(store, BrdfStore) else open_store(store)
    label = str(model.path) if model.path is not None else "the GPLVM model"
    hint = (f"refit the model ({integrity.rerun_hint(model.path)})" if model.path is not None
            else "refit the model on this store")
    check_rows(label, "model", model.names, model.data_digests, st, hint)
    return st


# --------------------------------------------------------------------------
# Workflow and command-line entry points
# --------------------------------------------------------------------------


def fit_to_files(
    gram_path: str | os.PathLike[str],
    model_out: str | os.PathLike[str],
    trace_out: str | os.PathLike[str],
    *,
    q: int,
    ell: float = 1.0,
    mu: float = 1e-4,
    seed: int = 0,
    max_sweeps: int = 200,
    normalise: bool = True,
    method: str = "newton",
    init: str = "best",
    threads: int | None = None,
) -> FitResult:
    """Fit a q-dimensional latent space to a saved Gram matrix; write the model and its trace.

    ``threads``: the BLAS threads to use (the rule's declared threads; None
    leaves them as they are).

    The workflow's ``fit_gplvm`` job.  ``normalise``: fit to ``G/s`` with
    ``s`` = :func:`~brdfpipe.manifold.likelihood.gram_scale` (stored in the
    model, with ``normalise``); ``init``: the start (``init_scale`` of
    :func:`~brdfpipe.manifold.fitting.fit`, recorded in the model).  ``trace_out`` is a CSV
    ``step,stage,log_likelihood`` (Soler Fig. 5; stage ``hooke-jeeves`` for
    the sweeps, ``lbfgs`` for L-BFGS iterations, ``newton`` for Newton
    steps), written atomically like the model.
    """
    gram, d, info = load_gram(gram_path)
    scale = gram_scale(gram, d) if normalise else 1.0
    with blas_threads(threads):
        result = fit(gram / scale, d, q=q, ell=ell, mu=mu, seed=seed, max_sweeps=max_sweeps, method=method,
                     init_scale=init)
    logger.info(
        "q = %d: Gram divided by %.6g; L %.6g -> %.6g in %d sweeps + %d L-BFGS iterations + %d Newton steps, "
        "%.2f s (start scale %s)",
        q, scale, result.initial_log_likelihood, result.log_likelihood, result.sweeps,
        result.polish_iterations, result.newton_iterations, result.seconds, result.init_scale,
    )
    save_model(model_out, result, info.materials, space=info.space, mean_handling=info.mean_handling,
               gram_scale=scale, normalised=normalise, init=init, data_digests=info.digests)
    write_trace(trace_out, result)
    return result


def write_trace(path: str | os.PathLike[str], result: FitResult) -> None:
    """The log-likelihood trace of a fit as CSV ``step,stage,log_likelihood`` (atomic, with its digest line)."""
    path = Path(path)
    lines = [",".join(tables.GPLVM_TRACE)]
    stages = result.stages or ["hooke-jeeves"] * len(result.trace)
    for (step, value), stage in zip(result.trace, stages):
        lines.append(f"{int(step)},{stage},{float(value)!r}")
    integrity.write_csv(path, "\n".join(lines) + "\n")


def interpolate_to_file(
    model_path: str | os.PathLike[str],
    store_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    at: Sequence[float] | None = None,
    between: tuple[str, str] | None = None,
    t: float = 0.5,
) -> int:
    """Write the BRDF at a latent point as a MERL file; returns the number of clamped values.

    The point is ``at`` (q coordinates) or the point a fraction ``t`` of the
    way from material A to material B of ``between`` (linear in the latent
    space).  The blend is Σ w_i z_i of the store's materials with the weights
    of :func:`blend_weights`, taken in the model's data space
    (:func:`interpolate_table`).  The file carries a ``derived`` provenance
    mark (:mod:`brdfpipe.manifold.derivation`: model and store digests, the
    latent point, ``between`` and ``t``).  ValueError for a point of the wrong
    length, an unknown material, both or neither of ``at`` / ``between``, a
    damaged model file (:class:`GplvmFileError`), or a store that does not
    hold the rows the model was fitted on (:class:`~brdfpipe.manifold.gram.DataMismatchError`, naming
    the model, the store and the material: :func:`check_store`).
    """
    model = load_model(model_path)
    st = check_store(model, store_path)
    if (at is None) == (between is None):
        raise ValueError("give exactly one of a latent point (at) or two materials (between)")
    if between is not None:
        missing = [m for m in between if m not in model.names]
        if missing:
            raise ValueError(f"{model_path}: unknown material(s) {', '.join(missing)}")
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        a, b = (model.X[model.names.index(m)] for m in between)
        with np.errstate(over="ignore", invalid="ignore"):  # an overflowing point is refused below
            x_star = (1.0 - t) * a + t * b
        where = f"t = {t:g}"
    else:
        x_star = np.asarray(at, dtype=np.float64)
        where = "at = " + ",".join(f"{v:g}" for v in np.ravel(x_star))
    with np.errstate(over="ignore", invalid="ignore"):
        far = not np.isfinite(x_star).all() or (
            x_star.shape == model.X.shape[1:] and not np.isfinite(((model.X - x_star) ** 2).sum(axis=1)).all())
    if far:
        raise ValueError(f"{where}: the latent distances overflow (beyond 1.8e308 in units of ℓ = {model.ell:.6g}); "
                         "give a point nearer the materials")
    w = blend_weights(weights(model, x_star))
    table, clamped = interpolate_table(st, w, materials=model.names, space=model.space, model=model)
    details: dict[str, Any] = {"between": list(between), "t": float(t)} if between is not None else {}
    mark = derivation.BlendSource.of(model_path, model, st).mark(
        out=out, operation="interpolate", point=x_star, weights=w, **details)
    merl.write_merl(out, table, mark=mark)
    logger.info("interpolated BRDF at x* = %s -> %s (%d clamped values)", np.round(x_star, 4).tolist(), out, clamped)
    return clamped
