"""A small synthetic explorer input: images, GPLVM fits (q = 1, 2, 5), albedos, two path points, a summary.

Used by tests/test_explorer.py and benches/bench_explorer.py (when no workflow results exist).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from brdfpipe.core import exr, integrity
from brdfpipe.manifold import fitting, gplvm, likelihood


def make_inputs(root: Path, *, n: int = 12, width: int = 48, height: int = 36, qs: tuple[int, ...] = (2, 5),
                space: str = "standardised", seed: int = 3, names: list[str] | None = None,
                database: str = "synthetic") -> dict[str, Any]:
    """Write a synthetic explorer input under ``root`` and return the write_explorer keyword arguments.

    ``names``: the ``n`` material names (default ``mat-00`` …); files are named by index, so any
    string works (hostile-name tests).  ``database``: the label passed on.
    """
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    names = [f"mat-{i:02d}" for i in range(n)] if names is None else list(names)
    if len(names) != n or len(set(names)) != n:
        raise ValueError(f"need {n} distinct names, got {names}")
    # images: a few smooth patterns mixed per material, plus noise: low rank + noise like pre-renders
    yy, xx = np.mgrid[0:height, 0:width] / max(width, height)
    patterns = np.stack([np.ones_like(xx), xx, yy, np.sin(6 * xx) ** 2, np.exp(-20 * ((xx - .5) ** 2 + (yy - .4) ** 2))])
    mix = rng.uniform(0.05, 1.0, size=(n, 3, patterns.shape[0]))
    images = np.einsum("ncp,phw->nhwc", mix, patterns) * (1 + 0.01 * rng.standard_normal((n, height, width, 3)))
    images = (0.3 * np.abs(images)).astype(np.float32)
    # a background the camera sees directly: the same in every image (the left 3/8, not on a tile edge)
    images[:, :, : width * 3 // 8] = images[0, :, : width * 3 // 8]
    prerenders = {}
    for i, (name, img) in enumerate(zip(names, images)):
        prerenders[name] = str(root / f"mat-{i:02d}.exr")
        exr.write_exr(prerenders[name], img)
    # GPLVM fits on a random structured Gram matrix
    Z = rng.standard_normal((n, 4)) @ rng.standard_normal((4, 400)) + 0.1 * rng.standard_normal((n, 400))
    Z -= Z.mean(axis=0)
    G = Z @ Z.T
    s = likelihood.gram_scale(G, 400)
    models = []
    for q in qs:
        res = fitting.fit(G / s, 400, q=q, mu=1e-4, seed=seed, max_sweeps=20, method="hooke-jeeves")
        path = root / f"q{q}.npz"
        gplvm.save_model(path, res, names, space=space, gram_scale=s)
        models.append(str(path))
    albedo = root / "albedo.csv"
    alb = rng.uniform(0.02, 0.9, size=(n, 3))
    # tables and weights as the workflow writes them: with their digests (brdfpipe.core.integrity)
    integrity.write_csv(albedo, [["database", "material", "r", "g", "b", "luminance"],
                                 *(["synthetic", name, *a, a.mean()] for name, a in zip(names, alb))])
    # two path points on the largest-q model, like manifold.path_points_to_files
    m = gplvm.load_model(models[-1])
    points, rows = [], []
    for t in (0.25, 0.5):
        a, b = names[0], names[1]
        x = (1.0 - t) * m.X[0] + t * m.X[1]
        wts = gplvm.blend_weights(gplvm.weights(m, x))
        doc = {"path": f"{a}--{b}", "material_a": a, "material_b": b, "t": t, "q": int(m.X.shape[1]),
               "x": [float(v) for v in x], "clamped": 0, "measured_values": 100,
               "weights": {nm: float(v) for nm, v in zip(names, wts)}}
        wpath = root / f"point-{t:g}-weights.json"
        integrity.write_json(wpath, doc)
        ref = np.abs(np.einsum("i,ihwc->hwc", wts, images) * (1 + 0.02 * rng.standard_normal(images.shape[1:])))
        ipath = root / f"point-{t:g}.exr"
        exr.write_exr(ipath, ref.astype(np.float32))
        points.append({"weights": str(wpath), "image": str(ipath)})
        rows.append({"path": f"{a}--{b}", "t": f"{t:g}", "rmse_noise": "0.05", "rmse_blend_seed2": "0.052",
                     "ratio_seed2": "1.04"})
    summary = root / "summary.csv"
    integrity.write_csv(summary, [list(rows[0]), *([r[k] for k in rows[0]] for r in rows)])
    return {"models": models, "prerenders": prerenders, "albedo": str(albedo), "path_points": points,
            "summary": str(summary), "database": database}
