"""Independent reference implementation of the MERL BRDF binary format.

This module is used ONLY by the test-suite, as an oracle against which the
library implementation in ``brdfpipe.data.merl`` is checked.  It was written from
the published format description (the MERL BRDF database documentation and
its reference reader ``BRDFRead.cpp``), without looking at the library code,
and it is deliberately written in a different style: slow, scalar,
per-direction pure Python using only the ``math`` and ``struct`` modules (no
numpy), so that a mistake shared by a vectorised implementation is unlikely
to be repeated here.  Speed is irrelevant; do not use it outside tests.

Format summary
--------------
* 12-byte header: three little-endian int32 dimensions ``(90, 90, 180)``.
* then ``3 * 90 * 90 * 180`` little-endian float64 values, channel-major
  (all red, then all green, then all blue).  Within a channel the flat index
  of cell ``(i_theta_h, i_theta_d, i_phi_d)`` is
  ``i_theta_h * (90 * 180) + i_theta_d * 180 + i_phi_d``.
* physical value = raw value * scale, with scales ``1/1500``,
  ``1.15/1500`` and ``1.66/1500`` for R, G, B.  Unmeasured cells are
  negative.
"""

import array
import math
import struct

RES_THETA_H = 90
RES_THETA_D = 90
RES_PHI_D = 180  # MERL's code uses 360 and divides by 2 (reciprocity fold)

DIMS = (RES_THETA_H, RES_THETA_D, RES_PHI_D)
N_PER_CHANNEL = RES_THETA_H * RES_THETA_D * RES_PHI_D  # 1,458,000
N_VALUES = 3 * N_PER_CHANNEL  # 4,374,000
HEADER_FORMAT = "<3i"
HEADER_BYTES = struct.calcsize(HEADER_FORMAT)  # 12
FILE_SIZE = HEADER_BYTES + 8 * N_VALUES  # 34,992,012

RED_SCALE = 1.0 / 1500.0
GREEN_SCALE = 1.15 / 1500.0
BLUE_SCALE = 1.66 / 1500.0
SCALES = (RED_SCALE, GREEN_SCALE, BLUE_SCALE)


class ReferenceFormatError(ValueError):
    """Raised by :func:`ref_read` for a file that is not a valid MERL file."""


# --------------------------------------------------------------------------
# File I/O (struct based)
# --------------------------------------------------------------------------

def ref_read(path):
    """Read a MERL file and return the RAW (unscaled) values.

    Returns an ``array.array('d')`` of length 4,374,000 in file order
    (channel-major, then theta_h, theta_d, phi_d).  The header dimensions
    and the total file size are checked.
    """
    with open(path, "rb") as fh:
        data = fh.read()
    if len(data) < HEADER_BYTES:
        raise ReferenceFormatError(f"{path}: file too short for header ({len(data)} bytes)")
    dims = struct.unpack_from(HEADER_FORMAT, data, 0)
    if tuple(dims) != DIMS:
        raise ReferenceFormatError(f"{path}: header dims {dims} != {DIMS}")
    if len(data) != FILE_SIZE:
        raise ReferenceFormatError(f"{path}: file size {len(data)} != {FILE_SIZE}")
    out = array.array("d")
    # unpack one channel at a time to keep the temporary tuples smallish
    fmt = "<%dd" % N_PER_CHANNEL
    for c in range(3):
        offset = HEADER_BYTES + c * 8 * N_PER_CHANNEL
        out.extend(struct.unpack_from(fmt, data, offset))
    return out


def ref_write(path, raw_values):
    """Write RAW (unscaled) values, in file order, as a MERL file."""
    values = [float(v) for v in raw_values]
    if len(values) != N_VALUES:
        raise ValueError(f"expected {N_VALUES} raw values, got {len(values)}")
    fmt = "<%dd" % N_PER_CHANNEL
    with open(path, "wb") as fh:
        fh.write(struct.pack(HEADER_FORMAT, *DIMS))
        for c in range(3):
            chunk = values[c * N_PER_CHANNEL:(c + 1) * N_PER_CHANNEL]
            fh.write(struct.pack(fmt, *chunk))


# --------------------------------------------------------------------------
# Geometry (transcription of BRDFRead.cpp, scalar math)
# --------------------------------------------------------------------------

def _cross(a, b):
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def _rotate_vector(vector, axis, angle):
    """Rodrigues' rotation of ``vector`` about unit ``axis`` by ``angle``."""
    cos_ang = math.cos(angle)
    sin_ang = math.sin(angle)
    out = [vector[0] * cos_ang, vector[1] * cos_ang, vector[2] * cos_ang]
    temp = axis[0] * vector[0] + axis[1] * vector[1] + axis[2] * vector[2]
    temp = temp * (1.0 - cos_ang)
    out[0] += axis[0] * temp
    out[1] += axis[1] * temp
    out[2] += axis[2] * temp
    cross = _cross(axis, vector)
    out[0] += cross[0] * sin_ang
    out[1] += cross[1] * sin_ang
    out[2] += cross[2] * sin_ang
    return tuple(out)


def _safe_acos(x):
    # math.acos raises for |x| > 1 by a rounding ulp; clamp instead.
    return math.acos(max(-1.0, min(1.0, x)))


def ref_coords(wi, wo):
    """Rusinkiewicz half/difference angles ``(theta_h, theta_d, phi_d)``.

    ``phi_d`` is returned as computed by ``atan2`` (range ``(-pi, pi]``),
    before the reciprocity fold.
    """
    wi = (float(wi[0]), float(wi[1]), float(wi[2]))
    wo = (float(wo[0]), float(wo[1]), float(wo[2]))
    hx = wi[0] + wo[0]
    hy = wi[1] + wo[1]
    hz = wi[2] + wo[2]
    norm = math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / norm, hy / norm, hz / norm
    theta_h = _safe_acos(hz)
    phi_h = math.atan2(hy, hx)

    normal = (0.0, 0.0, 1.0)
    bi_normal = (0.0, 1.0, 0.0)
    temp = _rotate_vector(wi, normal, -phi_h)
    diff = _rotate_vector(temp, bi_normal, -theta_h)
    theta_d = _safe_acos(diff[2])
    phi_d = math.atan2(diff[1], diff[0])
    return theta_h, theta_d, phi_d


def ref_theta_half_index(theta_half):
    """Square-root binning of theta_h (as in BRDFRead.cpp)."""
    if theta_half <= 0.0:
        return 0
    theta_half_deg = (theta_half / (math.pi / 2.0)) * RES_THETA_H
    temp = math.sqrt(theta_half_deg * RES_THETA_H)
    idx = int(temp)
    if idx < 0:
        idx = 0
    if idx >= RES_THETA_H:
        idx = RES_THETA_H - 1
    return idx


def ref_theta_diff_index(theta_diff):
    idx = int(theta_diff / (math.pi * 0.5) * RES_THETA_D)
    if idx < 0:
        return 0
    if idx >= RES_THETA_D:
        return RES_THETA_D - 1
    return idx


def ref_phi_diff_index(phi_diff):
    # reciprocity: phi_d and phi_d + pi are the same cell
    if phi_diff < 0.0:
        phi_diff += math.pi
    idx = int(phi_diff / math.pi * RES_PHI_D)
    if idx < 0:
        return 0
    if idx >= RES_PHI_D:
        return RES_PHI_D - 1
    return idx


def ref_cell(wi, wo):
    """Table cell ``(i_theta_h, i_theta_d, i_phi_d)`` for directions wi, wo."""
    theta_h, theta_d, phi_d = ref_coords(wi, wo)
    return (
        ref_theta_half_index(theta_h),
        ref_theta_diff_index(theta_d),
        ref_phi_diff_index(phi_d),
    )


def ref_flat_index(cell):
    """Flat in-channel index of a cell."""
    ith, itd, ipd = cell
    return ith * (RES_THETA_D * RES_PHI_D) + itd * RES_PHI_D + ipd


def ref_lookup(raw_values, wi, wo):
    """Physical ``(r, g, b)`` BRDF value for wi, wo from RAW file-order values."""
    flat = ref_flat_index(ref_cell(wi, wo))
    return tuple(
        raw_values[c * N_PER_CHANNEL + flat] * SCALES[c] for c in range(3)
    )

