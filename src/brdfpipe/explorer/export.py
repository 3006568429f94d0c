"""The explorer's data: models, hull, albedos, packed pre-renders, a reduced basis, path references.

:func:`write_explorer` writes the folder the page runs from::

    index.html  explorer.js  style.css     the page (copied from ``static/``)
    manifest.json                           what was exported (numbers, sizes, the basis' error)
    data/model.js                           the manifest, every GPLVM model, hulls, albedos, paths
    data/layers.js                          the N pre-renders, half floats packed for the GPU
    data/basis.js                           the reduced basis (mean + k SVD components)
    data/refs.js                            the reference renders of the path points

From ``file://`` a page may not ``fetch()`` local files nor upload ``<img>``
pixels to WebGL, so every data file is a script that assigns its payload to
``window.BRDF_EXPLORER_DATA[key]`` as ``{"crc32": "crc32:<8 hex>", "json":
"<the payload as JSON text>"}`` (binary arrays as base64 inside it).  The
page checks, for every file, that it loaded and that the CRC-32 of its JSON
text equals the recorded one (:func:`brdfpipe.core.integrity.text_crc32`)
before parsing it, and otherwise shows one message naming the file and what
to rerun instead of drawing anything (a truncated file does not parse, so
its key is missing; an edited one does not match).  ``manifest.json`` carries
its digest like every JSON file (:func:`brdfpipe.core.integrity.write_json`).
The inputs (models, pre-renders, references, weights, albedo and summary
tables) are verified when read.

Weights
-------
Each model is exported as its latent points ``X`` (N × q), ℓ, μ and the
lower Cholesky factor ``L`` of ``K`` exactly as saved by
:func:`brdfpipe.manifold.gplvm.save_model` (float64, little-endian).  The page solves
``b = L⁻ᵀ(L⁻¹k)`` with ``k`` of :func:`brdfpipe.manifold.likelihood.kernel_vector` (μ added
where the point equals a training point exactly) and blends with
``w = b + (1 − Σb)/N`` (:func:`brdfpipe.manifold.gplvm.blend_weights`): the same
arithmetic as :func:`brdfpipe.manifold.gplvm.weights` in float64.

Images on the GPU
-----------------
The pre-renders (N × H × W × RGB, float32) are rounded to half floats and
packed eight images per texel of an ``RGBA32UI`` texture array
(:func:`pack_halves`): layer ``c·G + g`` (channel ``c``, group ``g`` of eight
images, ``G = ⌈N/8⌉``) holds in component ``j`` of a texel the halves of
images ``8g + 2j`` (low 16 bits) and ``8g + 2j + 1`` (high 16 bits), which
``unpackHalf2x16`` returns as a pair.  One texel fetch thus brings eight
values where a half-float texture array brings one (RGB of one image):
3·G = 39 fetches per pixel for N = 100 instead of 100.

Tiles that need the blend
-------------------------
Where every pre-render has the same (half) value — the background the camera
sees directly, about a third of the preview scene — the blend is
``(Σw)·I₀``: one fetch.  :func:`blend_tiles` lists the :data:`TILE` × :data:`TILE`
tiles holding any pixel where the images differ; the page draws the whole
image with the one-fetch shader and then only those tiles with the full
blend.  For the reduced basis the same holds where every component after the
mean is zero (the blend is ``c₀·m``).  Both are exact: the skipped pixels'
full blend is the same sum of equal terms.

Reduced basis
-------------
``A`` (N × 3HW) = the pre-renders, ``m`` their mean, ``A − 1m = U S Vᵀ``.
With ``B_j = S_j V_j / √N`` and ``C = [1 | √N U]`` the blend is
``Σ wᵢ Iᵢ = (Σw) m + Σ_j (wᵀ√N U)_j B_j``: ``k`` components and the mean
give a blend of ``k + 1`` images with coefficients ``Cᵀw`` (computed in the
page).  ``k`` is the smallest rank whose truncation error — relative RMSE
(RMSE / mean of the exact image, as the noise floor of
:func:`brdfpipe.rendering.blend.relative_rmse`), the largest over every pre-render and
over ``blend_samples`` blends at uniform points of each model's hull — stays
at or below the Monte Carlo noise of one pre-render: ``rmse_noise / √2`` of
the errormaps summary (two independent renders of a path point differ by
``√2`` times the noise of one), the smallest over its path points.  Without
path points (no summary) the target is :data:`FALLBACK_TARGET`.  The
manifest records ``k``, the errors (measured again with the half-rounded
basis the page uses) and the floor.
"""

from __future__ import annotations

import base64
import json
import logging
import math
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import scipy.spatial
from numpy.typing import ArrayLike, NDArray

from brdfpipe.core import atomic, exr, integrity
from brdfpipe.manifold import gplvm, latent
from brdfpipe.registry.manifold import LINEAR_SPACES
from brdfpipe.explorer import ASSETS, STATIC_DIR
from brdfpipe.core.version import full_version

__all__ = [
    "FORMAT",
    "FALLBACK_TARGET",
    "ExplorerError",
    "pack_halves",
    "TILE",
    "blend_tiles",
    "reduced_basis",
    "truncation_errors",
    "noise_floor",
    "hull_data",
    "script_json",
    "write_explorer",
]

logger = logging.getLogger("brdfpipe.explorer")

#: ``format`` of manifest.json.
FORMAT: Final = "brdfpipe.explorer/1"
#: Truncation-error target (relative RMSE) of the reduced basis when no noise floor is known.
FALLBACK_TARGET: Final = 0.01
#: Half floats packed per RGBA32UI texel.
PER_TEXEL: Final = 8
#: Side (pixels) of the tiles the page blends in full or with one fetch (:func:`blend_tiles`).
TILE: Final = 8
_GLOBAL: Final = "BRDF_EXPLORER_DATA"
_HALF_MAX: Final = 65504.0
_ROWS: Final = 16


class ExplorerError(ValueError):
    """Bad input to the explorer export (the message names the file or key)."""


# --------------------------------------------------------------------------
# Packing
# --------------------------------------------------------------------------


def pack_halves(images: ArrayLike) -> NDArray[np.uint32]:
    """Half-float RGB images ``(N, H, W, 3)`` → ``RGBA32UI`` texture-array data ``(3·G, H, W, 4)`` uint32.

    ``G = ⌈N/8⌉``; layer ``c·G + g``, component ``j``: image ``8g + 2j`` in the
    low 16 bits, ``8g + 2j + 1`` in the high 16 bits (missing images are 0).
    """
    h = np.asarray(images)
    if h.dtype != np.float16 or h.ndim != 4 or h.shape[3] != 3:
        raise ValueError(f"images must be float16 (N, H, W, 3), got {h.dtype} {h.shape}")
    n, hh, ww, _ = h.shape
    g = -(-n // PER_TEXEL)
    bits = np.zeros((g * PER_TEXEL, hh, ww, 3), dtype=np.uint32)
    bits[:n] = h.view(np.uint16)
    bits = bits.reshape(g, 4, 2, hh, ww, 3)  # group, component j, low/high, H, W, channel
    words = bits[:, :, 0] | (bits[:, :, 1] << 16)  # (G, 4, H, W, 3)
    return np.ascontiguousarray(words.transpose(4, 0, 2, 3, 1).reshape(3 * g, hh, ww, 4))


def blend_tiles(images: ArrayLike, *, zero_after_first: bool = False) -> NDArray[np.uint32]:
    """Row-major indices of the :data:`TILE` × :data:`TILE` tiles of a stack ``(n, H, W, 3)`` that need the full blend.

    A pixel needs it unless every image equals image 0 there (the blend is
    then ``(Σw)·I₀``), or, with ``zero_after_first`` (a mean + components
    basis), unless every image after the first is zero there (the blend is
    ``c₀·I₀``).  Tiles are numbered from the image's top-left corner, ``⌈W/TILE⌉``
    per row; edge tiles may be partial.
    """
    a = np.asarray(images)
    if a.ndim != 4 or a.shape[-1] != 3 or a.shape[0] < 1:
        raise ExplorerError(f"blend_tiles: expected a stack (n, H, W, 3), got shape {a.shape}")
    n, h, w, _ = a.shape
    if zero_after_first:
        varies = np.any(a[1:] != 0, axis=(0, 3)) if n > 1 else np.zeros((h, w), dtype=bool)
    else:
        varies = np.any(a[1:] != a[:1], axis=(0, 3)) if n > 1 else np.zeros((h, w), dtype=bool)
    th, tw = -(-h // TILE), -(-w // TILE)
    padded = np.zeros((th * TILE, tw * TILE), dtype=bool)
    padded[:h, :w] = varies
    per_tile = padded.reshape(th, TILE, tw, TILE).any(axis=(1, 3))
    return np.flatnonzero(per_tile.reshape(-1)).astype(np.uint32)


def _to_half(images: NDArray[np.float64] | NDArray[np.float32], names: Sequence[str], what: str) -> NDArray[np.float16]:
    big = np.abs(images).reshape(len(images), -1).max(axis=1) > _HALF_MAX
    if big.any():
        raise ExplorerError(f"{what} {names[int(np.argmax(big))]}: values beyond the half-float range (±65504)")
    return images.astype(np.float16)


# --------------------------------------------------------------------------
# The reduced basis
# --------------------------------------------------------------------------


def reduced_basis(images: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The mean image and SVD basis of a stack ``(N, H, W, 3)``: ``(mean (3HW,), B (r, 3HW), Cu (N, r))``.

    ``Iᵢ = mean + Σ_j Cu[i, j] B[j]`` exactly with all ``r = min(N, 3HW)``
    components, ordered by singular value; ``B_j = S_j V_j / √N``, ``Cu = √N U``.
    """
    a = np.asarray(images, dtype=np.float64)
    n = a.shape[0]
    a = a.reshape(n, -1)
    mean = a.mean(axis=0)
    a = a - mean
    # through the N x N Gram matrix (N << 3HW): A = U S V^T, A A^T = U S^2 U^T, S V^T = U^T A
    lam, u = np.linalg.eigh(a @ a.T)
    order = np.argsort(lam)[::-1]
    u = u[:, order]
    root = math.sqrt(n)
    return mean, (u.T @ a) / root, u * root


def truncation_errors(
    images: ArrayLike, weights: ArrayLike, mean: ArrayLike, basis: ArrayLike, cu: ArrayLike, k: int
) -> NDArray[np.float64]:
    """Relative RMSE of the rank-``k`` blends against the exact ``Σ wᵢ Iᵢ`` for each row of ``weights`` (P, N).

    RMSE over pixels and channels divided by the exact image's mean
    (:func:`brdfpipe.rendering.blend.relative_rmse`).  ``basis`` may be half-rounded
    (what the page shows).
    """
    a = np.asarray(images, dtype=np.float32)
    a = a.reshape(a.shape[0], -1)
    W = np.atleast_2d(np.asarray(weights, dtype=np.float64))
    mean = np.asarray(mean, dtype=np.float64)
    B = np.asarray(basis)[:k]
    Cu = np.asarray(cu, dtype=np.float64)[:, :k]
    out = np.empty(W.shape[0])
    for r0 in range(0, W.shape[0], _ROWS):  # a few rows at a time: P x 3HW float64 would be GBs
        w = W[r0:r0 + _ROWS]
        exact = w @ a
        approx = w.sum(axis=1, keepdims=True) * mean + (w @ Cu) @ B
        rmse = np.sqrt(np.mean(np.square(approx - exact), axis=1))
        out[r0:r0 + _ROWS] = rmse / np.abs(exact.mean(axis=1))
    return out


def _choose_rank(
    images: NDArray[np.float32], W: NDArray[np.float64], basis: NDArray[np.float64], cu: NDArray[np.float64],
    target: float, max_rank: int,
) -> int:
    """Smallest k ≤ max_rank whose largest truncation error over ``W``'s blends is ≤ ``target`` (exact arithmetic).

    The residual of a blend is ``Σ_{j>k} (wᵀCu)_j B_j`` and the rows of ``B``
    are orthogonal, so its squared norm is ``Σ_{j>k} (wᵀCu)_j² ‖B_j‖²``.
    """
    a = images.reshape(images.shape[0], -1)
    means = np.abs(W @ a.mean(axis=1, dtype=np.float64))
    size = a.shape[1]
    norms2 = np.einsum("ij,ij->i", basis, basis)
    parts = np.square(W @ cu) * norms2  # (P, r)
    tail = np.cumsum(parts[:, ::-1], axis=1)[:, ::-1]  # tail[:, j] = Σ_{l ≥ j}
    tail = np.concatenate([tail, np.zeros((tail.shape[0], 1))], axis=1)
    for k in range(1, min(max_rank, basis.shape[0]) + 1):
        err = np.sqrt(np.maximum(tail[:, k], 0.0) / size) / means
        if float(err.max()) <= target:
            return k
    return min(max_rank, basis.shape[0])


def noise_floor(summary: str | os.PathLike[str] | None) -> tuple[float | None, str]:
    """Relative Monte Carlo noise of one render: min over path points of ``rmse_noise / √2`` of an errormaps summary.

    Returns ``(floor, source)``; ``(None, reason)`` without a summary.
    ExplorerError naming the file if it has no usable ``rmse_noise``.
    """
    if summary is None:
        return None, "no path points rendered: no two-seed noise floor"
    path = Path(summary)
    _, rows = integrity.read_csv_rows(path, kind="errormaps summary", error=ExplorerError)
    try:
        values = [float(r["rmse_noise"]) for r in rows]
    except (KeyError, ValueError) as err:
        raise ExplorerError(f"{path}: not an errormaps summary with rmse_noise ({type(err).__name__}: {err})") from None
    values = [v for v in values if math.isfinite(v) and v > 0]
    if not values:
        raise ExplorerError(f"{path}: no finite positive rmse_noise")
    return min(values) / math.sqrt(2.0), f"{path}: min over {len(values)} path points of rmse_noise / sqrt(2)"


# --------------------------------------------------------------------------
# Models, hulls, albedos
# --------------------------------------------------------------------------


def hull_data(X: ArrayLike) -> dict[str, Any] | None:
    """The convex hull of latent points for the page: half-spaces ``a·x + b ≤ tol`` (and the polygon for q = 2).

    q = 1: ``{"interval": [lo, hi]}``.  ``None`` when Qhull cannot build a
    full-dimensional hull (fewer than q + 1 points in general position).
    """
    x = np.asarray(X, dtype=np.float64)
    q = x.shape[1]
    scale = float(np.abs(x - x.mean(axis=0)).max()) or 1.0
    tol = 1e-9 * scale
    if q == 1:
        return {"interval": [float(x.min()), float(x.max())], "tol": tol}
    try:
        hull = scipy.spatial.ConvexHull(x)
    except scipy.spatial.QhullError:
        return None
    out: dict[str, Any] = {"equations": _b64(hull.equations.astype("<f8")), "facets": int(hull.equations.shape[0]),
                           "tol": tol}
    if q == 2:
        out["polygon"] = [int(v) for v in hull.vertices]  # counter-clockwise
    return out


def _read_albedos(path: Path, names: Sequence[str]) -> NDArray[np.float64]:
    _, table = integrity.read_csv_rows(path, kind="albedo table", error=ExplorerError)
    try:
        rows = {r["material"]: (float(r["r"]), float(r["g"]), float(r["b"])) for r in table}
    except (KeyError, TypeError, ValueError) as err:
        raise ExplorerError(f"{path}: not an albedo table with material, r, g, b ({type(err).__name__}: {err})") from None
    missing = [n for n in names if n not in rows]
    if missing:
        raise ExplorerError(f"{path}: no albedo for {', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}")
    return np.array([rows[n] for n in names], dtype=np.float64)


def _b64(a: NDArray[Any]) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _model_doc(model: gplvm.GplvmModel, path: Path) -> dict[str, Any]:
    X = np.ascontiguousarray(model.X, dtype="<f8")
    return {
        "q": int(X.shape[1]), "file": path.name, "ell": model.ell, "mu": model.mu, "space": model.space,
        "X": _b64(X), "chol": _b64(np.ascontiguousarray(model.chol, dtype="<f8")),
        "hull": hull_data(X), "linear": model.space in LINEAR_SPACES,
    }


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------


#: Characters a JSON text may hold that would end or alter a ``<script>`` (HTML parser) or a JS source
#: line, as ``\\uXXXX`` escapes, which JSON and JavaScript read back as the same characters.
_SCRIPT_UNSAFE: Final = str.maketrans({"<": "\\u003c", ">": "\\u003e", "&": "\\u0026",
                                        "\u2028": "\\u2028", "\u2029": "\\u2029"})


def script_json(value: Any) -> str:
    """``value`` as JSON (sorted keys, compact) that is safe inside a ``<script>`` element or a JS file.

    The one place where data becomes JavaScript source: ASCII only, and
    ``<``, ``>``, ``&``, U+2028 and U+2029 are ``\\u`` escapes, so no
    material, path or database name can close the script (``</script>``),
    open an HTML comment (``<!--``) or break a line of the source.  The
    value read back (``JSON.parse``) is unchanged.
    """
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return text.translate(_SCRIPT_UNSAFE)


def _script(key: str, value: Any) -> str:
    """A ``data/*.js`` file: ``value`` as JSON text in a string, with the text's CRC-32 (checked by the page).

    The record is written with :func:`script_json` (safe inside a script); the string the page reads back,
    and checks the CRC-32 of, is the JSON text itself.
    """
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    record = {"crc32": integrity.text_crc32(text), "json": text}
    return f"window.{_GLOBAL} = window.{_GLOBAL} || {{}};\nwindow.{_GLOBAL}[{script_json(key)}] = " \
           f"{script_json(record)};\n"


def _is_explorer(folder: Path) -> bool:
    try:
        return json.loads((folder / "manifest.json").read_text(encoding="utf-8")).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def _read_images(paths: Sequence[Path], names: Sequence[str], upsample: int) -> NDArray[np.float32]:
    first = exr.read_exr(paths[0])
    stack = np.empty((len(paths), *first.shape), dtype=np.float32)
    for i, p in enumerate(paths):
        img = first if i == 0 else exr.read_exr(p)
        if img.shape != first.shape:
            raise ExplorerError(f"{p}: image of {img.shape[1]} x {img.shape[0]} pixels, "
                                f"{paths[0]} has {first.shape[1]} x {first.shape[0]}")
        stack[i] = img
    if upsample > 1:
        stack = np.repeat(np.repeat(stack, upsample, axis=1), upsample, axis=2)
    return stack


def _path_points(points: Sequence[Mapping[str, Any]], names: Sequence[str], summary: Path | None,
                 shape: tuple[int, ...], upsample: int) -> tuple[list[dict[str, Any]], list[NDArray[np.float32]]]:
    rows: dict[tuple[str, str], dict[str, str]] = {}
    if summary is not None:
        _, table = integrity.read_csv_rows(summary, required=("path", "t"), kind="errormaps summary",
                                           error=ExplorerError)
        rows = {(r["path"], r["t"]): r for r in table}
    docs, refs = [], []
    for k, pt in enumerate(points):
        wpath = Path(pt["weights"])
        doc = integrity.read_json(wpath, kind="path-point weights file", error=ExplorerError)
        try:
            w = [float(doc["weights"][n]) for n in names]
            entry = {"path": str(doc["path"]), "a": str(doc["material_a"]), "b": str(doc["material_b"]),
                     "t": float(doc["t"]), "q": int(doc["q"]), "x": [float(v) for v in doc["x"]], "weights": w}
        except (ValueError, KeyError, TypeError) as err:
            raise ExplorerError(f"{wpath}: not a path-point weights file for these materials "
                                f"({type(err).__name__}: {err})") from None
        ref = _read_images([Path(pt["image"])], [entry["path"]], upsample)[0]
        if ref.shape != shape:
            raise ExplorerError(f"{pt['image']}: reference of shape {ref.shape}, the pre-renders have {shape}")
        t_text = f"{entry['t'] + 0.0:g}"
        row = rows.get((entry["path"], t_text))
        if row is not None:
            entry.update({key: float(row[key]) for key in ("rmse_blend_seed2", "rmse_noise", "ratio_seed2")
                          if row.get(key) not in (None, "")})
        entry["ref"] = k
        docs.append(entry)
        refs.append(ref)
    return docs, refs


def write_explorer(
    *,
    out: str | os.PathLike[str],
    models: Sequence[str | os.PathLike[str]],
    prerenders: Mapping[str, str | os.PathLike[str]],
    albedo: str | os.PathLike[str],
    path_points: Sequence[Mapping[str, Any]] = (),
    summary: str | os.PathLike[str] | None = None,
    database: str = "unknown",
    max_rank: int = 32,
    blend_samples: int = 256,
    seed: int = 0,
    upsample: int = 1,
) -> dict[str, Any]:
    """Write the explorer folder ``out`` (atomically) and return its manifest.

    ``models``: GPLVM model files (:func:`brdfpipe.manifold.gplvm.save_model`) of one
    candidate, one per latent dimension, all over the same materials (the map
    opens on q = 2 when present, else the smallest q).  ``prerenders``:
    material → pre-rendered EXR, for exactly the models' materials.
    ``albedo``: the materials' albedo CSV (``material, r, g, b``).
    ``path_points``: ``{"weights": JSON, "image": EXR}`` per rendered path
    point (:func:`brdfpipe.manifold.path_points_to_files` and its reference
    render); ``summary``: their errormaps summary CSV (the noise floor; the
    blend-vs-reference errors shown in path mode).  ``max_rank``: the most
    basis images of the reduced mode.  ``blend_samples``: uniform hull points
    per model at which the reduced basis' error is measured (with ``seed``).
    ``upsample``: repeat every pixel ``upsample`` × ``upsample`` times (for
    speed measurements at a larger size).  Bad input raises
    :class:`ExplorerError` naming the file; nothing is written then.
    """
    out = Path(out)
    if not models:
        raise ExplorerError("no GPLVM model given")
    if int(upsample) < 1 or int(max_rank) < 1:
        raise ExplorerError(f"upsample and max_rank must be >= 1, got {upsample}, {max_rank}")
    atomic.check_replaceable(out, replaceable=_is_explorer)
    loaded, names, qs = _load_models(models)
    _check_prerenders(prerenders, names)
    albedos = _read_albedos(Path(albedo), names)
    images = _read_images([Path(prerenders[n]) for n in names], names, int(upsample))
    n, hh, ww, _ = images.shape
    half = _to_half(images, names, "pre-render of")
    summary_path = None if summary is None else Path(summary)
    points, refs = _path_points(path_points, names, summary_path, images.shape[1:], int(upsample))
    for pt in points:
        if pt["q"] not in qs:
            raise ExplorerError(f"path {pt['path']}: its weights come from a q = {pt['q']} model, not exported")
    red = _reduced_mode(images, loaded, summary_path, blend_samples=int(blend_samples), seed=seed,
                        max_rank=int(max_rank))
    tiles_exact = blend_tiles(half)
    manifest = _manifest(loaded, qs, names, images.shape, red, points, tiles_exact, database=database,
                         upsample=int(upsample), max_rank=int(max_rank))
    files = _data_files(manifest, loaded, albedos, points, refs, half, tiles_exact, red)
    _write_folder(out, files, manifest)
    logger.info("explorer: %d materials, %d x %d, models q = %s, basis k = %d (errors %.3g / %.3g, target %.3g) -> %s",
                n, ww, hh, qs, red.k, red.err_pre.max(), red.err_blend.max(), red.target, out)
    return manifest


def _load_models(
    models: Sequence[str | os.PathLike[str]],
) -> tuple[list[tuple[Path, gplvm.GplvmModel]], list[str], list[int]]:
    """Read the GPLVM model files: ``(path, model)`` pairs, their common materials and their latent dimensions."""
    loaded = []
    for p in models:
        try:
            loaded.append((Path(p), gplvm.load_model(p)))
        except (OSError, ValueError, KeyError) as err:
            msg = str(err)
            raise ExplorerError(msg if msg.startswith(str(p)) else f"{p}: cannot read the GPLVM model ({msg})") from None
    names = list(loaded[0][1].names)
    for p, m in loaded[1:]:
        if list(m.names) != names:
            raise ExplorerError(f"{p}: materials differ from those of {loaded[0][0]}")
    qs = [int(m.X.shape[1]) for _, m in loaded]
    if len(set(qs)) != len(qs):
        raise ExplorerError(f"two models with the same latent dimension: q = {qs}")
    return loaded, names, qs


def _check_prerenders(prerenders: Mapping[str, str | os.PathLike[str]], names: Sequence[str]) -> None:
    """Refuse pre-renders that are not exactly one per model material."""
    extra, lacking = sorted(set(prerenders) - set(names)), [n for n in names if n not in prerenders]
    if extra or lacking:
        raise ExplorerError("pre-renders and model materials differ"
                            + (f"; no pre-render for {', '.join(lacking[:5])}" if lacking else "")
                            + (f"; not in the model: {', '.join(extra[:5])}" if extra else ""))


@dataclass(frozen=True)
class _Reduced:
    """The reduced mode: its basis (half-rounded) and coefficients, rank, target and measured errors."""

    k: int
    target: float
    floor: float | None
    floor_source: str
    basis_half: NDArray[np.float16]  # (k + 1, H, W, 3): the mean, then the components
    coef: NDArray[np.float64]  # (N, k + 1): Cᵀw = coefficients of [mean, B_1..B_k]
    tiles: NDArray[np.uint32]
    err_pre: NDArray[np.float64]
    err_blend: NDArray[np.float64]
    n_blends: int


def _reduced_mode(
    images: NDArray[np.float32], loaded: Sequence[tuple[Path, gplvm.GplvmModel]], summary: Path | None, *,
    blend_samples: int, seed: int, max_rank: int,
) -> _Reduced:
    """The reduced basis: rank chosen on blends at uniform hull points of every model, errors measured at that rank."""
    n, hh, ww, _ = images.shape
    mean, basis, cu = reduced_basis(images)
    rng = np.random.default_rng(seed)
    W = [np.eye(n)]
    for _, m in loaded:
        pts = latent.sample_in_hull(m.X, blend_samples, rng)
        W.append(np.array([gplvm.blend_weights(gplvm.weights(m, x)) for x in pts]).reshape(-1, n))
    Wall = np.concatenate(W)
    floor, floor_source = noise_floor(summary)
    target = FALLBACK_TARGET if floor is None else floor
    k = _choose_rank(images, Wall, basis, cu, target, max_rank)
    basis_half = _to_half(np.concatenate([mean[None], basis[:k]]).reshape(k + 1, hh, ww, 3),
                          ["mean", *(f"component {j + 1}" for j in range(k))], "basis image")
    bh = basis_half.reshape(k + 1, -1).astype(np.float64)
    err_pre = truncation_errors(images, np.eye(n), bh[0], bh[1:], cu, k)
    err_blend = truncation_errors(images, Wall[n:], bh[0], bh[1:], cu, k) if Wall.shape[0] > n else np.zeros(1)
    coef = np.concatenate([np.ones((n, 1)), cu[:, :k]], axis=1)  # Cᵀw = coefficients of [mean, B_1..B_k]
    return _Reduced(k=k, target=target, floor=floor, floor_source=floor_source, basis_half=basis_half, coef=coef,
                    tiles=blend_tiles(basis_half, zero_after_first=True), err_pre=err_pre, err_blend=err_blend,
                    n_blends=int(Wall.shape[0] - n))


def _manifest(
    loaded: Sequence[tuple[Path, gplvm.GplvmModel]], qs: Sequence[int], names: list[str], shape: tuple[int, ...],
    red: _Reduced, points: Sequence[Mapping[str, Any]], tiles_exact: NDArray[np.uint32], *,
    database: str, upsample: int, max_rank: int,
) -> dict[str, Any]:
    """The explorer's manifest (without the data files' sizes, which :func:`_data_files` adds)."""
    n, hh, ww, _ = shape
    default_q = 2 if 2 in qs else min(qs)
    m0 = loaded[0][1]
    return {
        "format": FORMAT,
        "brdfpipe_version": full_version(),
        "database": database,
        "space": m0.space,
        "mu": m0.mu,
        "ell": m0.ell,
        "linear": m0.space in LINEAR_SPACES,
        "materials": names,
        "n": n,
        "width": ww,
        "height": hh,
        "upsample": upsample,
        "models": [{"q": q, "file": p.name} for q, (p, _) in zip(qs, loaded)],
        "default_q": default_q,
        "basis": {
            "k": red.k,
            "max_rank": max_rank,
            "target": red.target,
            "floor": red.floor,
            "floor_source": red.floor_source,
            "error_prerenders_max": float(red.err_pre.max()),
            "error_blends_max": float(red.err_blend.max()),
            "error_blends_median": float(np.median(red.err_blend)),
            "blend_samples": red.n_blends,
            "below_floor": bool(max(red.err_pre.max(), red.err_blend.max()) <= red.target),
            "metric": "RMSE over pixels and channels / mean of the exact blend (brdfpipe.rendering.blend.relative_rmse)",
        },
        "paths": [{key: v for key, v in pt.items() if key != "weights"} for pt in points],
        "tiles": {
            "size": TILE,
            "total": (-(-hh // TILE)) * (-(-ww // TILE)),
            "exact_blended": int(tiles_exact.size),
            "reduced_blended": int(red.tiles.size),
        },
    }


def _data_files(
    manifest: dict[str, Any], loaded: Sequence[tuple[Path, gplvm.GplvmModel]], albedos: NDArray[np.float64],
    points: Sequence[Mapping[str, Any]], refs: Sequence[NDArray[np.float32]], half: NDArray[np.float16],
    tiles_exact: NDArray[np.uint32], red: _Reduced,
) -> dict[str, str]:
    """The ``data/*.js`` scripts by name; records their sizes and the folder's total in ``manifest`` (and model.js)."""
    n, k = len(half), red.k
    model_doc = {
        "manifest": manifest,
        "models": [_model_doc(m, p) for p, m in loaded],
        "albedo": _b64(albedos.astype("<f8")),
        "path_weights": [_b64(np.asarray(pt["weights"], dtype="<f8")) for pt in points],
    }
    ref_half = _to_half(np.stack(refs), [pt["path"] for pt in points], "reference of") if refs else None
    files = {
        "data/model.js": _script("model", model_doc),
        "data/layers.js": _script("layers", {"n": n, "layers": 3 * (-(-n // PER_TEXEL)), "data": _b64(pack_halves(half)),
                                              "tile": TILE, "tiles": _b64(tiles_exact.astype("<u4"))}),
        "data/basis.js": _script("basis", {"n": k + 1, "layers": 3 * (-(-(k + 1) // PER_TEXEL)),
                                            "data": _b64(pack_halves(red.basis_half)),
                                            "coef": _b64(red.coef.astype("<f8")),
                                            "tile": TILE, "tiles": _b64(red.tiles.astype("<u4"))}),
        "data/refs.js": _script("refs", {"n": len(refs), "data": "" if ref_half is None else _b64(ref_half.view("<u2"))}),
    }
    manifest["files"] = {name: len(text) for name, text in sorted(files.items())}
    manifest["bytes_total"] = sum(manifest["files"].values()) + sum((STATIC_DIR / a).stat().st_size for a in ASSETS)
    files["data/model.js"] = _script("model", model_doc)  # with the sizes (model.js's own: before this line)
    return files


def _write_folder(out: Path, files: Mapping[str, str], manifest: Mapping[str, Any]) -> None:
    """Write the explorer folder atomically: the static assets, the data files, then the manifest."""
    with atomic.atomic_dir(out, replaceable=_is_explorer) as tmp:
        (tmp / "data").mkdir()
        for asset in ASSETS:
            shutil.copyfile(STATIC_DIR / asset, tmp / asset)
        for name, text in files.items():
            (tmp / name).write_text(text, encoding="ascii")
        (tmp / "manifest.json").write_text(integrity.dumps_json(manifest, indent=1, sort_keys=True), encoding="utf-8")
