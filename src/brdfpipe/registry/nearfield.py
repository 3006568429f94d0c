"""The near-field camera of Xu et al. 2016 §5.2, shared by the acquisition geometry and the capture.

Pure math (the standard library; NumPy only inside :func:`camera_basis`), so both the acquisition track
(:mod:`brdfpipe.acquisition.geometry`: which MERL cells a configuration
predicts) and the rendering track (:mod:`brdfpipe.rendering.capture`: what
the camera of that configuration records) frame the same image from one
definition.  R = 1: the camera sits at C = wo looking at the origin; the
sample disk of radius ν = tan(α/2) lies in the plane z = 0.

* :func:`image_half_width`: h = ν/√(1 − ν²), the half-width of the image in
  tangent-plane coordinates; the disk lies inside the ball of radius ν, which
  subtends asin(ν) from C, so from every camera direction the disk's image
  lies in [−h, h]² (Xu: "the image always sees the full sample").
* :func:`pixel_pitch`: the pitch Δ of a grid × grid lattice of pixel centres
  u = (i − ⌊grid/2⌋)·Δ whose footprints cover [−h, h].
* :func:`image_frame`: the smallest odd, axis-centred image holding the
  lattice (what a renderer draws) and where the lattice sits in it.
* :func:`camera_basis`: right and up vectors of the camera at ``wo``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["nu", "image_half_width", "pixel_pitch", "image_frame", "camera_basis"]


def nu(fov_deg: float) -> float:
    """ν = r/R = tan(α/2) of a field of view α in degrees."""
    return math.tan(math.radians(float(fov_deg)) / 2.0)


def image_half_width(fov_deg: float) -> float:
    """Half-width h = ν/√(1 − ν²) of the image in tangent-plane coordinates (R = 1).

    h = tan(asin ν) bounds the image of the disk from any camera direction on
    the hemisphere of radius R.  ValueError unless 0 < fov_deg < 90 (ν < 1).
    """
    if not 0.0 < float(fov_deg) < 90.0:
        raise ValueError(f"an image frames the whole disk from every direction only for 0 < fov_deg < 90, got {fov_deg}")
    v = nu(fov_deg)
    return v / math.sqrt(1.0 - v * v)


def pixel_pitch(fov_deg: float, grid: int) -> float:
    """Pitch Δ of a grid × grid lattice whose pixel footprints cover [−h, h] (h = :func:`image_half_width`).

    Δ = 2h/grid for an odd grid; an even grid has one more column on the
    negative side than on the positive one, so Δ = 2h/(grid − 1) (grid 2:
    2h; its negative side reaches past −h).
    """
    grid = int(grid)
    if grid < 1:
        raise ValueError(f"grid must be ≥ 1, got {grid}")
    cols = grid if grid % 2 else max(grid - 1, 1)
    return 2.0 * image_half_width(fov_deg) / cols


def image_frame(grid: int) -> tuple[int, int]:
    """(size, offset) of the smallest symmetric image holding the lattice.

    An image of ``size`` × ``size`` pixels (``size`` odd) centred on the
    optical axis with the lattice's pitch: lattice index (a, b) — tangent
    coordinates (u, v) = ((a, b) − ⌊grid/2⌋)·Δ — is its column ``offset + a``
    and row ``size − 1 − offset − b`` (rows from the top, v up).  size = grid
    for an odd grid, grid + 1 for an even one (the lattice does not use its
    last column and top row).
    """
    grid = int(grid)
    if grid < 1:
        raise ValueError(f"grid must be ≥ 1, got {grid}")
    size = grid if grid % 2 else grid + 1
    return size, size // 2 - grid // 2


def camera_basis(wo: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(forward, right, up) of the camera at C = wo looking at the origin.

    forward f = −wo, right e_r = (−sin φo, cos φo, 0) (horizontal, normal to
    the camera's plane of incidence; φo = atan2(wo_y, wo_x), 0 at the
    zenith), up e_u = e_r × f.
    """
    import numpy as np

    wo = np.asarray(wo, dtype=np.float64)
    phi = math.atan2(wo[1], wo[0]) if (wo[0] != 0.0 or wo[1] != 0.0) else 0.0
    e_r = np.array([-math.sin(phi), math.cos(phi), 0.0])
    f = -wo
    return f, e_r, np.cross(e_r, f)
