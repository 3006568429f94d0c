"""A live material explorer in the browser (Soler et al. 2018, §5.2 and Fig. 12).

:func:`brdfpipe.explorer.export.write_explorer` writes a static page
(``results/explorer/``) that works from ``file://`` and from any static web
server: the latent map of the fitted GPLVM with the materials and their hull;
moving the pointer blends the pre-rendered images live on the GPU (WebGL2),
with the weights ``b = K⁻¹k`` computed in the page from the exported model;
a panel with the largest weights, the interpolated albedo and a warning
outside the hull; an exposure slider; a path mode between two materials side
by side with the rendered reference where one exists; slices of every other
latent dimension.  See ``export`` (the data) and ``static/explorer.js`` (the
page).  :mod:`brdfpipe.explorer.chromium` drives headless Chromium for the
tests, the benchmark and the screenshots.

This module imports only the standard library (the workflow imports it at
parse time for :func:`assets_digest`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Final

__all__ = ["STATIC_DIR", "ASSETS", "assets_digest"]

#: The page's static files, shipped as package data.
STATIC_DIR: Final = Path(__file__).resolve().parent / "static"
#: Files copied verbatim into every explorer folder.
ASSETS: Final = ("index.html", "explorer.js", "style.css")


def assets_digest() -> str:
    """sha256 of the static files: the rule passes it as a parameter, so editing the page reruns the job."""
    h = hashlib.sha256()
    for name in ASSETS:
        h.update(name.encode() + b"\0" + (STATIC_DIR / name).read_bytes() + b"\0")
    return h.hexdigest()
