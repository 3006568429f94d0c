"""Principal components of a log-map (Xu et al. 2016 eq. 1), streamed scatter/gather.

With X the m × p log-map (:mod:`brdfpipe.data.logmap`: rows = material-channels,
columns = cells), μ its column mean over the m rows (a p-vector; μ̂ repeats μᵀ
over the rows) and the thin SVD of the centred matrix

    X − μ̂ = U Σ Vᵀ,        Q = V Σ        (p × k),

every row is reproduced as x_r = μ + Q u_r (u_r = row r of U), and a BRDF is
x = μ + Q c (eq. 2).

How it is computed
------------------
Centring is over rows, X − μ̂ = C X with C = I − 11ᵀ/m, so the centred Gram
matrix is (X − μ̂)(X − μ̂)ᵀ = C G C with G = X Xᵀ (m × m).  G is a sum over
column blocks, which is what makes the computation spread:

1. scatter – :func:`gram_partial` computes G and the row sums of one of
   ``n_blocks`` contiguous column ranges (:func:`block_range`), accumulating
   float32 chunks in float64; :func:`save_partial` stores it (``.npz``);
   :func:`write_partial` does both for a Snakemake scatter item ``"i-of-n"``;
2. gather – :func:`combine` adds the partials; :func:`decompose` takes the
   eigen-decomposition of C G C: U (m × k) and σ = √λ (k,);
3. :func:`write_model` streams X once more and writes Q = (X − μ̂)ᵀ U chunk by
   chunk (= V Σ, since (X − μ̂)ᵀ U = V Σ UᵀU), together with μ: one GEMM per
   chunk, Xᵀ [C U, 1/m], whose last column is μ.  V is never formed and no
   m × p float64 matrix is ever held.

Both passes read X one chunk ahead in a thread (decode and float64 cast
overlap the BLAS work) and the Q chunks are written by another thread, so a
pass costs little more than its BLAS calls; memory is a few chunks (≈ 0.5 GB
peak RSS at m = 270, see ``benches/bench_svd.py``).

:func:`fit` does all of it in one process.  Cost: two reads of X and
≈ 3·m²·p flops (m²·p for G via a symmetric rank-k update, 2·m·k·p for Q),
all in cache-friendly GEMMs, against ≈ 6·m²·p for a dense LAPACK SVD
(gesdd: LQ factorisation, generation of the orthogonal factor, product),
much of it memory-bound on a 270 × 1.1 M matrix, which it also holds in
float64 with copies (≈ 7 GB).

Rank and tolerance
------------------
The centred matrix has rank ≤ m − 1: 1 is always in the null space of C G C.
That direction is removed exactly, not by a threshold: the eigen-problem is
solved in an orthonormal basis of 1⊥ (the last m − 1 columns of the
Householder reflector that maps e₁ to 1/√m), so every column of U is
orthogonal to 1 to machine precision and k ≤ m − 1.  Of the remaining
directions those with σ ≤ ``tol``·σ₁ are dropped (duplicate materials, or
p < m − 1), and so are those with σ² ≤ 16·m·2⁻⁵³·trace(G), the rounding
level of the Gram matrix (this only matters when the mean dwarfs the spread;
log-relative data, centred on the median, never do).

Default :data:`TOL` = 1e-5.  The Gram matrix's rounding error
(≈ m·2⁻⁵³·σ₁² ≈ 3e-14·σ₁² for m = 270) puts a numerically null direction
at σ ≈ 2e-7·σ₁, far below the cut; a kept σ has a relative error of at most
≈ 1e-4 (≈ 1e-10 for σ ≥ 1e-2·σ₁).  On the default synthetic database
(90 training materials, m = 270) all 269 components are kept
(σ_k/σ₁ ≈ 3e-4) and agree with a dense SVD to 1.5e-10.

Partial file (``.npz``, written atomically)
------------------------------------------
Arrays ``gram`` float64 (m, m), ``colsum`` float64 (m,) (the sum of each row
over the block's columns), ``ncols``, ``block``, ``n_blocks``, ``start``,
``stop`` (the column range), ``m``, ``p`` and ``logmap_id`` (the log-map's
completion-marker id), ``format`` = ``"brdfpipe.gram-partial/1"``, and the
file's digest (:func:`brdfpipe.core.integrity.save_npz`; checked on load, so
an edited, truncated or foreign partial is a :class:`ModelError` naming it).
:func:`write_model` refuses partials of another log-map, of mixed
``n_blocks``, missing or repeated blocks.

Model format (:func:`write_model` / :func:`fit`, read with :func:`open_model`)
-----------------------------------------------------------------------------
A Zarr v3 group holding

* ``Q`` – float32 ``(p, k)``, dimensions ``("column", "component")``, chunks
  ``(36_450, k)`` (the log-map's column chunks), uncompressed (lz4 + shuffle
  saves only 7 % on Q, for CPU time on every fit and read);
* ``mean`` – float64 ``(p,)``: μ;
* ``sigma`` – float64 ``(k,)``: singular values, descending, all > tol·σ₁;
* ``U`` – float64 ``(m, k)``: left singular vectors (sign: the entry of
  largest magnitude of each column is positive), UᵀU = I, 1ᵀU = 0 (to rounding);
* ``cells`` int32, ``reference`` float64, ``weight`` float64 ``(p,)``: copied
  from the log-map, so the model alone maps observations to x and back
  (:func:`brdfpipe.data.logmap.forward` / :func:`~brdfpipe.data.logmap.inverse`).

Attributes: ``format`` (``"brdfpipe.pca-model/1"``), ``rows``, ``materials``,
``train_materials``, ``split``, ``weighting``, ``epsilon``, ``database``
(from the log-map), ``k``, ``tolerance``, ``brdfpipe_version`` and, last,
the completion marker ``brdfpipe_complete`` = ``{"rows": m, "columns": p,
"k": k, "logmap_id": …, "id": <hex digest>}`` (the id: sha256 of the
log-map's id, the tolerance and Σ, so the same inputs give the same bytes),
written together with the integrity record ``brdfpipe_digests`` (CRC-32C of
every file of the group, digest of the attributes;
:func:`brdfpipe.core.zgroup.finish_group`).  :func:`open_model` checks the
record and reads every chunk of ``Q`` against it before any consumer uses
the model (the direction optimiser, the evaluations, the closed loop,
``brdfpipe reconstruct`` and ``capture --model``).  Atomic like the log-map: built
in a temporary sibling and swapped into place (:func:`brdfpipe.core.atomic.atomic_dir`);
after any error an earlier model at ``out`` is left as it was, and an ``out``
holding anything but a model is refused before any work.
"""

from __future__ import annotations

import hashlib

import logging
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, NamedTuple

import numpy as np
import zarr
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core.atomic import atomic_dir, check_replaceable
from brdfpipe.core.integrity import GroupDigests, load_npz, save_npz
from brdfpipe.core.version import full_version
from brdfpipe.core.zgroup import COMPLETE_ATTR, create_array, finish_group, format_predicate, open_sealed_group
from brdfpipe.data.logmap import iter_columns, Logmap, open_logmap
from brdfpipe.data.merl import N_CELLS
from brdfpipe.data.store import read_ahead

__all__ = [
    "TOL",
    "MODEL_FORMAT",
    "PARTIAL_FORMAT",
    "ModelError",
    "is_model",
    "GramPartial",
    "PartialInfo",
    "Model",
    "block_range",
    "gram_partial",
    "save_partial",
    "write_partial",
    "parse_scatteritem",
    "read_partial",
    "combine",
    "decompose",
    "write_model",
    "fit",
    "open_model",
]

logger = logging.getLogger("brdfpipe.acquisition.svd")

#: Relative singular-value tolerance: components with σ ≤ TOL·σ₁ are dropped.
TOL: Final = 1e-5
MODEL_FORMAT: Final = "brdfpipe.pca-model/1"
PARTIAL_FORMAT: Final = "brdfpipe.gram-partial/1"
#: σ² must exceed this × m × 2⁻⁵³ × trace(G) (the rounding level of the centred Gram matrix).
_FLOOR_FACTOR: Final = 16.0
#: ``replaceable`` predicate of :func:`brdfpipe.core.atomic.atomic_dir`: an earlier model (and nothing else).
is_model: Final = format_predicate((MODEL_FORMAT,))


class ModelError(ValueError):
    """A model or Gram partial is missing, incomplete or inconsistent; names the path."""


class GramPartial(NamedTuple):
    """Gram matrix, row sums and column count of one column block of X (float64)."""

    gram: NDArray[np.float64]
    colsum: NDArray[np.float64]
    ncols: int


@dataclass(frozen=True)
class PartialInfo:
    """Where a saved partial comes from (see :func:`read_partial`)."""

    logmap_id: str
    block: int
    n_blocks: int
    start: int
    stop: int
    m: int
    p: int


# --------------------------------------------------------------------------
# Scatter: Gram partials
# --------------------------------------------------------------------------


def block_range(p: int, n_blocks: int, block: int, chunk: int) -> tuple[int, int]:
    """Columns ``[start, stop)`` of block ``block`` of ``n_blocks`` contiguous ranges of ``p``.

    With ``n_blocks`` ≤ the number of chunks (``ceil(p / chunk)``) the
    boundaries fall on chunk boundaries (``floor(k·n_chunks/n_blocks)``
    chunks), so no chunk is decoded by two blocks; with more blocks than
    chunks they are ``floor(k·p/n_blocks)``.  The ranges cover ``[0, p)``
    exactly once.
    """
    if n_blocks < 1:
        raise ValueError(f"n_blocks must be >= 1, got {n_blocks}")
    if not 0 <= block < n_blocks:
        raise ValueError(f"block must lie in [0, {n_blocks}), got {block}")
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    n_chunks = -(-p // chunk)
    if n_blocks <= n_chunks:
        def edge(k: int) -> int:
            return min(k * n_chunks // n_blocks * chunk, p)
    else:
        def edge(k: int) -> int:
            return k * p // n_blocks
    return edge(block), edge(block + 1)


def _as_logmap(logmap_path: Logmap | str | os.PathLike[str]) -> Logmap:
    return logmap_path if isinstance(logmap_path, Logmap) else open_logmap(logmap_path)


def _float64_blocks(lm: Logmap, start: int, stop: int) -> Iterator[tuple[int, int, NDArray[np.float64]]]:
    """:func:`~brdfpipe.data.logmap.iter_columns` cast to float64, read one chunk ahead in a thread.

    Decoding (single-threaded Blosc) and the cast overlap the BLAS work on the
    previous chunk (:func:`brdfpipe.data.store.read_ahead`).
    """
    return read_ahead((a, b, x32.astype(np.float64)) for a, b, x32 in iter_columns(lm, start, stop))


def gram_partial(logmap_path: Logmap | str | os.PathLike[str], block: int, n_blocks: int) -> GramPartial:
    """G = X_b X_bᵀ (m × m), row sums X_b·1 (m,) and the column count of block ``block``.

    X_b is columns :func:`block_range` ``(p, n_blocks, block, chunk)`` of the
    log-map, read chunk by chunk (float32) and accumulated in float64.
    """
    lm = _as_logmap(logmap_path)
    start, stop = block_range(lm.p, n_blocks, block, lm.chunk_cols)
    gram = np.zeros((lm.m, lm.m), dtype=np.float64)
    colsum = np.zeros(lm.m, dtype=np.float64)
    for _, _, x in _float64_blocks(lm, start, stop):
        gram += x @ x.T  # numpy uses a symmetric rank-k update (syrk) for x @ x.T
        colsum += x.sum(axis=1)
    return GramPartial(gram, colsum, stop - start)


def save_partial(
    path: str | os.PathLike[str],
    partial: GramPartial,
    *,
    logmap_path: Logmap | str | os.PathLike[str],
    block: int,
    n_blocks: int,
) -> None:
    """Save a partial of block ``block`` of ``n_blocks`` of a log-map as ``.npz`` (atomically).

    The log-map's id and the block's column range are recorded, and the
    partial's shape and column count are checked against them.
    """
    lm = _as_logmap(logmap_path)
    start, stop = block_range(lm.p, n_blocks, block, lm.chunk_cols)
    gram = np.asarray(partial.gram, dtype=np.float64)
    colsum = np.asarray(partial.colsum, dtype=np.float64)
    if gram.shape != (lm.m, lm.m) or colsum.shape != (lm.m,):
        raise ValueError(f"partial has shapes {gram.shape}, {colsum.shape}; the log-map has m = {lm.m}")
    if int(partial.ncols) != stop - start:
        raise ValueError(f"partial has {partial.ncols} columns; block {block}/{n_blocks} has {stop - start}")
    save_npz(
        path,
        {
            "format": np.array(PARTIAL_FORMAT),
            "gram": gram,
            "colsum": colsum,
            "ncols": np.int64(partial.ncols),
            "block": np.int64(block),
            "n_blocks": np.int64(n_blocks),
            "start": np.int64(start),
            "stop": np.int64(stop),
            "m": np.int64(lm.m),
            "p": np.int64(lm.p),
            "logmap_id": np.array(lm.id),
        },
    )


def parse_scatteritem(scatteritem: str) -> tuple[int, int]:
    """``(block, n_blocks)`` of a Snakemake scatter item ``"i-of-n"`` (1-based ``i``)."""
    match = re.fullmatch(r"(\d+)-of-(\d+)", str(scatteritem))
    if not match or not 1 <= int(match[1]) <= int(match[2]):
        raise ValueError(f"scatter item must be 'i-of-n' with 1 <= i <= n, got {scatteritem!r}")
    return int(match[1]) - 1, int(match[2])


def write_partial(
    path: str | os.PathLike[str],
    *,
    logmap_path: Logmap | str | os.PathLike[str],
    scatteritem: str | None = None,
    block: int | None = None,
    n_blocks: int | None = None,
) -> None:
    """:func:`gram_partial` + :func:`save_partial` for one block (the workflow's scatter job).

    The block is given either as a Snakemake ``scatteritem`` ``"i-of-n"``
    (block ``i − 1`` of ``n``) or as ``block`` and ``n_blocks``.
    """
    if scatteritem is not None:
        if block is not None or n_blocks is not None:
            raise ValueError("give either scatteritem or block and n_blocks, not both")
        block, n_blocks = parse_scatteritem(scatteritem)
    if block is None or n_blocks is None:
        raise ValueError("give scatteritem, or block and n_blocks")
    lm = _as_logmap(logmap_path)
    part = gram_partial(lm, block, n_blocks)
    save_partial(path, part, logmap_path=lm, block=block, n_blocks=n_blocks)
    logger.info("Gram partial of block %d/%d of %s (%d columns) -> %s", block + 1, n_blocks, lm.path, part.ncols, path)


def read_partial(path: str | os.PathLike[str]) -> tuple[GramPartial, PartialInfo]:
    """A partial written by :func:`save_partial` and where it comes from; :class:`ModelError` if unreadable."""
    path = Path(path)
    z = load_npz(path, kind="Gram partial", error=ModelError)  # checks the digest
    try:
        if str(z["format"]) != PARTIAL_FORMAT:
            raise ModelError(f"{path}: not a Gram partial (format {str(z['format'])!r})")
        info = PartialInfo(
            logmap_id=str(z["logmap_id"]),
            block=int(z["block"]),
            n_blocks=int(z["n_blocks"]),
            start=int(z["start"]),
            stop=int(z["stop"]),
            m=int(z["m"]),
            p=int(z["p"]),
        )
        part = GramPartial(np.asarray(z["gram"], dtype=np.float64),
                           np.asarray(z["colsum"], dtype=np.float64), int(z["ncols"]))
    except ModelError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: unreadable Gram partial ({type(exc).__name__}: {exc})") from exc
    if part.gram.shape != (info.m, info.m) or part.colsum.shape != (info.m,) or part.ncols != info.stop - info.start:
        raise ModelError(f"{path}: Gram partial is inconsistent (shapes {part.gram.shape}, {part.colsum.shape})")
    return part, info


# --------------------------------------------------------------------------
# Gather: combine and decompose
# --------------------------------------------------------------------------


def combine(partials: Iterable[GramPartial | tuple[ArrayLike, ArrayLike, int]]) -> tuple[
    NDArray[np.float64], NDArray[np.float64], int
]:
    """Sum partials: ``(G, colsum, p)``.  ValueError for no partials or mismatched shapes."""
    gram: NDArray[np.float64] | None = None
    colsum: NDArray[np.float64] | None = None
    p = 0
    for g, s, n in partials:
        g64 = np.asarray(g, dtype=np.float64)
        s64 = np.asarray(s, dtype=np.float64)
        if gram is None or colsum is None:
            gram, colsum = g64.copy(), s64.copy()
        else:
            if g64.shape != gram.shape or s64.shape != colsum.shape:
                raise ValueError(f"partials disagree in shape: {g64.shape} vs {gram.shape}")
            gram += g64
            colsum += s64
        p += int(n)
    if gram is None or colsum is None:
        raise ValueError("no partials to combine")
    return gram, colsum, p


def _complement_basis(m: int) -> NDArray[np.float64]:
    """Orthonormal basis (m × (m−1)) of the complement of 1: columns 2… of a Householder reflector."""
    v = np.full(m, -1.0 / np.sqrt(m))
    v[0] += 1.0  # v = e1 − 1/√m; H = I − 2vvᵀ/vᵀv maps e1 to 1/√m
    h = np.eye(m) - (2.0 / (v @ v)) * np.outer(v, v)
    return h[:, 1:]


def decompose(
    G: ArrayLike, colsum: ArrayLike, p: int, tol: float = TOL
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """U (m × k) and σ (k,) of the row-centred matrix from its Gram matrix G = X Xᵀ.

    Eigen-decomposition of C G C (C = I − 11ᵀ/m) restricted to 1⊥, so the
    null direction 1 is excluded exactly; σ = √λ, descending; components
    with σ ≤ ``tol``·σ₁, or with σ² at the rounding level of the Gram matrix
    (≤ 16·m·2⁻⁵³·trace G), are dropped (k ≤ m − 1).  Signs: the entry of
    largest magnitude of each column of U is positive.  ``colsum`` (the row
    sums X·1) and ``p`` are checked for shape / consistency only: row
    centring does not need them (C G C = (X − μ̂)(X − μ̂)ᵀ).  ValueError for
    bad shapes, non-finite input, ``tol`` outside (0, 1), m < 2, p < 1 or an
    all-zero centred matrix (identical rows).
    """
    g = np.asarray(G, dtype=np.float64)
    s = np.asarray(colsum, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] != g.shape[1]:
        raise ValueError(f"G must be square, got shape {g.shape}")
    m = g.shape[0]
    if s.shape != (m,):
        raise ValueError(f"colsum has shape {s.shape}, expected ({m},)")
    if m < 2:
        raise ValueError(f"need at least 2 rows to centre, got m = {m}")
    if int(p) < 1:
        raise ValueError(f"p must be >= 1, got {p}")
    if not (np.isfinite(g).all() and np.isfinite(s).all()):
        raise ValueError("G or colsum contains NaN or Inf")
    if not 0.0 < float(tol) < 1.0:
        raise ValueError(f"tol must lie in (0, 1), got {tol}")
    g = 0.5 * (g + g.T)
    basis = _complement_basis(m)
    gc = basis.T @ g @ basis
    lam, w = np.linalg.eigh(0.5 * (gc + gc.T))
    order = np.argsort(lam)[::-1]
    sigma = np.sqrt(np.clip(lam[order], 0.0, None))
    # Rounding floor of C G C: an eigenvalue below ~m·2⁻⁵³·trace(G) is indistinguishable from 0.
    floor = np.sqrt(_FLOOR_FACTOR * m * np.finfo(np.float64).eps * max(float(np.trace(g)), 0.0))
    if sigma[0] <= floor:
        raise ValueError("the centred matrix is zero to rounding (all rows identical): no principal component")
    keep = (sigma > float(tol) * sigma[0]) & (sigma > floor)
    u = basis @ w[:, order[keep]]
    big = np.argmax(np.abs(u), axis=0)
    u *= np.where(u[big, np.arange(u.shape[1])] < 0, -1.0, 1.0)
    return u, sigma[keep]


# --------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------


def _write_model(
    lm: Logmap, gram: NDArray[np.float64], colsum: NDArray[np.float64], p: int, out: Path, tol: float
) -> None:
    """Decompose and write the model of ``lm`` at ``out`` (:func:`brdfpipe.core.atomic.atomic_dir`:
    an earlier model at ``out`` is replaced only on success)."""
    if gram.shape != (lm.m, lm.m) or p != lm.p:
        raise ModelError(f"{lm.path}: Gram matrix {gram.shape} over {p} columns does not match X {lm.X.shape}")
    u, sigma = decompose(gram, colsum, p, tol)
    k = int(sigma.size)
    # (X − μ̂)ᵀU = Xᵀ C U: one GEMM per chunk with [C U, 1/m], whose last column is μ.
    u_ext = np.empty((lm.m, k + 1), dtype=np.float64)
    u_ext[:, :k] = u - u.mean(axis=0)
    u_ext[:, k] = 1.0 / lm.m
    logger.info("PCA of %s: m = %d, p = %d, k = %d (tol %g) -> %s", lm.path, lm.m, p, k, tol, out)
    with atomic_dir(out, replaceable=is_model) as tmp:
        group = zarr.open_group(tmp, mode="w-", zarr_format=3)
        q_arr = create_array(group, "Q", (p, k), (lm.chunk_cols, k), "float32", ("column", "component"),
                        compress=False)
        mean = np.empty(p, dtype=np.float64)
        # Q chunks are written by a second thread while the next chunk is multiplied.
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdfpipe-svd-writer") as writer:
            pending: Future[None] | None = None
            for a, b, x in _float64_blocks(lm, 0, p):
                q = x.T @ u_ext
                mean[a:b] = q[:, k]
                q32 = q[:, :k].astype(np.float32)
                if pending is not None:
                    pending.result()
                pending = writer.submit(q_arr.__setitem__, (slice(a, b), slice(None)), q32)
            if pending is not None:
                pending.result()
        # Cheap consistency check of the partials against the data: 1ᵀ(X·1) = m·Σμ.
        if not np.isclose(lm.m * mean.sum(), colsum.sum(), rtol=1e-6, atol=1e-6 * lm.m * p):
            raise ModelError(f"{lm.path}: the Gram partials' row sums disagree with the log-map's data")
        create_array(group, "mean", mean, (p,), "float64", ("column",))
        create_array(group, "sigma", sigma, (k,), "float64", ("component",))
        create_array(group, "U", u, (lm.m, k), "float64", ("row", "component"))
        create_array(group, "cells", lm.cells, (p,), "int32", ("column",))
        create_array(group, "reference", lm.reference, (p,), "float64", ("column",))
        create_array(group, "weight", lm.weight, (p,), "float64", ("column",))
        group.attrs.update(
            {
                "format": MODEL_FORMAT,
                "rows": [[name, c] for name, c in lm.rows],
                "materials": list(lm.materials),
                "train_materials": list(lm.train_materials),
                "split": lm.split,
                "weighting": lm.weighting,
                "epsilon": lm.epsilon,
                "database": lm.database,
                "k": k,
                "tolerance": float(tol),
                "brdfpipe_version": full_version(),
            }
        )
        digest = hashlib.sha256(f"{lm.id}:{float(tol)!r}:{k}".encode())
        digest.update(np.ascontiguousarray(sigma, dtype=np.float64).tobytes())
        finish_group(group, tmp, {"rows": lm.m, "columns": p, "k": k, "logmap_id": lm.id,
                                  "id": digest.hexdigest()[:16]})
        open_model(tmp, verify=False)  # checks what was written (the digests were just computed from it)
    logger.info("wrote model %s (sigma[0] = %.4g, sigma[-1] = %.4g)", out, sigma[0], sigma[-1])


def write_model(
    logmap_path: str | os.PathLike[str],
    partial_paths: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    tol: float = TOL,
) -> None:
    """Combine saved partials, decompose and write the model (see the module docstring).

    The partials must all come from this log-map (same id), share one
    ``n_blocks`` and cover each block exactly once; :class:`ModelError`
    otherwise (raised before ``out`` is touched).  An ``out`` holding anything
    but a model is refused (:class:`brdfpipe.core.atomic.OutputError`) before any
    work.  Atomic: after any error or interrupt an earlier model at ``out``
    is left exactly as it was.
    """
    out = Path(out)
    check_replaceable(out, replaceable=is_model)
    lm = open_logmap(logmap_path)
    if not partial_paths:
        raise ValueError("no partials given")
    loaded = [read_partial(pth) for pth in partial_paths]
    n_blocks = {info.n_blocks for _, info in loaded}
    if len(n_blocks) != 1:
        raise ModelError(f"partials mix different block counts {sorted(n_blocks)}")
    n = n_blocks.pop()
    for pth, (_, info) in zip(partial_paths, loaded):
        if info.logmap_id != lm.id or info.m != lm.m or info.p != lm.p:
            raise ModelError(f"{pth}: partial was computed from another log-map than {lm.path}")
        if (info.start, info.stop) != block_range(lm.p, n, info.block, lm.chunk_cols):
            raise ModelError(f"{pth}: column range [{info.start}, {info.stop}) is not block {info.block}/{n}")
    blocks = sorted(info.block for _, info in loaded)
    if blocks != list(range(n)):
        missing = sorted(set(range(n)) - set(blocks))
        repeated = sorted({b for b in blocks if blocks.count(b) > 1})
        raise ModelError(f"partials must cover blocks 0..{n - 1} once each (missing {missing}, repeated {repeated})")
    gram, colsum, p = combine(part for part, _ in loaded)
    _write_model(lm, gram, colsum, p, out, tol)


def fit(
    logmap_path: str | os.PathLike[str], out: str | os.PathLike[str], n_blocks: int = 1, tol: float = TOL
) -> None:
    """All of it in this process: Gram partials over ``n_blocks`` blocks, combine, decompose, write.

    An ``out`` holding anything but a model is refused
    (:class:`brdfpipe.core.atomic.OutputError`) before any work.  Atomic: after
    any error or interrupt an earlier model at ``out`` is left exactly as it
    was.
    """
    out = Path(out)
    check_replaceable(out, replaceable=is_model)
    lm = open_logmap(logmap_path)
    block_range(lm.p, n_blocks, 0, lm.chunk_cols)  # validates n_blocks
    gram, colsum, p = combine(gram_partial(lm, b, n_blocks) for b in range(n_blocks))
    _write_model(lm, gram, colsum, p, out, tol)


@dataclass
class Model:
    """An opened, checked model (see :func:`open_model`); ``Q`` is read lazily, the rest is loaded."""

    path: Path
    group: zarr.Group
    Q: zarr.Array
    mean: NDArray[np.float64] = field(repr=False)
    sigma: NDArray[np.float64] = field(repr=False)
    U: NDArray[np.float64] = field(repr=False)
    cells: NDArray[np.int32] = field(repr=False)
    reference: NDArray[np.float64] = field(repr=False)
    weight: NDArray[np.float64] = field(repr=False)
    rows: tuple[tuple[str, int], ...] = field(repr=False)
    materials: tuple[str, ...]
    train_materials: tuple[str, ...] = field(repr=False)
    split: str
    weighting: str
    epsilon: float
    database: str
    id: str
    logmap_id: str
    digests: GroupDigests | None = field(default=None, repr=False, compare=False)

    @property
    def k(self) -> int:
        """Number of components."""
        return int(self.sigma.size)

    @property
    def m(self) -> int:
        """Number of rows the model was fitted to."""
        return int(self.U.shape[0])

    @property
    def p(self) -> int:
        """Number of columns (cells)."""
        return int(self.Q.shape[0])


def open_model(path: str | os.PathLike[str], *, verify: bool = True) -> Model:
    """Open a finished model after checking it; :class:`ModelError` naming ``path`` if not.

    Refuses a missing group, one without the completion marker, of another
    format, or with arrays / attributes that disagree in shape or dtype, and
    one whose integrity record (:mod:`brdfpipe.core.integrity`) does not match:
    attributes, files missing, extra or resized, and — with ``verify``
    (the default) — any file of any array (every chunk of ``Q`` is read and
    checked against its CRC-32C here, before a consumer uses it).  The
    message names the model and the file and says what to rerun.
    ``verify=False`` (the writer's own check) skips reading the chunks.
    """
    path = Path(path)
    group, attrs, digests = open_sealed_group(path, fmt=MODEL_FORMAT, what="model", kind="brdfpipe model",
                                              error=ModelError)
    if verify:
        digests.verify()
    marker = attrs[COMPLETE_ATTR]
    m, p, k = marker.get("rows"), marker.get("columns"), marker.get("k")
    if not all(isinstance(v, int) for v in (m, p, k)) or attrs.get("k") != k:
        raise ModelError(f"{path}: completion marker {marker} disagrees with attribute k = {attrs.get('k')}")
    expect: dict[str, tuple[Any, tuple[int, ...]]] = {
        "Q": (np.float32, (p, k)),
        "mean": (np.float64, (p,)),
        "sigma": (np.float64, (k,)),
        "U": (np.float64, (m, k)),
        "cells": (np.int32, (p,)),
        "reference": (np.float64, (p,)),
        "weight": (np.float64, (p,)),
    }
    arrays: dict[str, zarr.Array] = {}
    for name, (dtype, shape) in expect.items():
        arr = group.get(name)
        if not isinstance(arr, zarr.Array):
            raise ModelError(f"{path}: model lacks array {name!r}")
        if arr.dtype != dtype or tuple(arr.shape) != shape:
            raise ModelError(f"{path}: {name!r} is {arr.dtype} {arr.shape}, expected {np.dtype(dtype)} {shape}")
        arrays[name] = arr
    rows = attrs.get("rows")
    materials = attrs.get("materials")
    expected_rows = [[n, c] for n in materials for c in range(3)] if isinstance(materials, list) else None
    if expected_rows is None or rows != expected_rows or len(expected_rows) != m:
        raise ModelError(f"{path}: attributes 'rows' / 'materials' do not match the {m} rows of U")
    sigma = np.asarray(arrays["sigma"][:], dtype=np.float64)
    if k and not (np.all(sigma > 0) and np.all(np.diff(sigma) <= 0)):
        raise ModelError(f"{path}: 'sigma' must be positive and descending")
    cells = np.asarray(arrays["cells"][:], dtype=np.int32)
    if p and (cells.min() < 0 or cells.max() >= N_CELLS):
        raise ModelError(f"{path}: 'cells' out of range")
    return Model(
        path=path,
        group=group,
        Q=arrays["Q"],
        mean=np.asarray(arrays["mean"][:], dtype=np.float64),
        sigma=sigma,
        U=np.asarray(arrays["U"][:], dtype=np.float64),
        cells=cells,
        reference=np.asarray(arrays["reference"][:], dtype=np.float64),
        weight=np.asarray(arrays["weight"][:], dtype=np.float64),
        rows=tuple((str(a), int(c)) for a, c in rows),
        materials=tuple(materials),
        train_materials=tuple(attrs.get("train_materials") or ()),
        split=str(attrs.get("split")),
        weighting=str(attrs.get("weighting")),
        epsilon=float(attrs.get("epsilon", 0.0)),
        database=str(attrs.get("database")),
        id=str(marker.get("id")),
        logmap_id=str(marker.get("logmap_id")),
        digests=digests,
    )
