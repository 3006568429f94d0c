"""Tests of ``brdfpipe.data.merl`` against the independent reference implementation.

``tests/reference_merl.py`` is a slow, scalar re-implementation of the MERL
format written from the published description only; here the library's
reader, writer and lookup are checked against it, and the reader's error
handling is exercised on corrupted files.
"""

import math
import os
import random
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import reference_merl as ref
from brdfpipe.data import merl

N = ref.N_PER_CHANNEL
REF_SCALES = np.array(ref.SCALES, dtype=np.float64)
GOOD_HEADER = struct.pack("<3i", 90, 90, 180)

HYPO = settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

SIZE_WORDS = ("size", "byte", "truncat", "short", "long", "length", "expected", "extra", "trailing")
DIMS_WORDS = ("dim", "header", "shape", "90", "180")
NONFINITE_WORDS = ("nan", "inf", "finite")


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def sph(theta, phi):
    st_ = math.sin(theta)
    return (st_ * math.cos(phi), st_ * math.sin(phi), math.cos(theta))


def angle_between(a, b):
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    return math.acos(max(-1.0, min(1.0, dot)))


def from_half_diff(theta_h, theta_d, phi_d, phi_h=0.0):
    """Directions (wi, wo) whose half/difference angles are the given ones."""

    def rot_y(v, a):
        c, s = math.cos(a), math.sin(a)
        return (v[0] * c + v[2] * s, v[1], -v[0] * s + v[2] * c)

    def rot_z(v, a):
        c, s = math.cos(a), math.sin(a)
        return (v[0] * c - v[1] * s, v[0] * s + v[1] * c, v[2])

    d = sph(theta_d, phi_d)
    d_mirror = (-d[0], -d[1], d[2])
    wi = rot_z(rot_y(d, theta_h), phi_h)
    wo = rot_z(rot_y(d_mirror, theta_h), phi_h)
    return wi, wo


def direction_pairs(seed=20240611):
    """>= 300 (wi, wo) pairs on the upper hemisphere, with hard cases."""
    rng = random.Random(seed)
    pairs = []

    def uniform_dir():
        return sph(math.acos(rng.uniform(1e-6, 1.0)), rng.uniform(-math.pi, math.pi))

    def add(wi, wo):
        assert wi[2] > 0 and wo[2] > 0
        # wi == wo leaves phi_d undefined (atan2 of rounding noise): avoid it
        if angle_between(wi, wo) < 1e-4:
            return False
        pairs.append((wi, wo))
        return True

    # 1. uniform on the hemisphere
    while len(pairs) < 150:
        add(uniform_dir(), uniform_dir())
    # 2. near-grazing (one or both directions)
    while len(pairs) < 200:
        g1 = sph(math.radians(rng.uniform(85.0, 89.99)), rng.uniform(-math.pi, math.pi))
        g2 = sph(math.radians(rng.uniform(85.0, 89.99)), rng.uniform(-math.pi, math.pi))
        add(g1, g2 if rng.random() < 0.5 else uniform_dir())
    # 3. near-normal
    while len(pairs) < 240:
        n1 = sph(math.radians(rng.uniform(0.0, 3.0)), rng.uniform(-math.pi, math.pi))
        n2 = sph(math.radians(rng.uniform(0.0, 3.0)), rng.uniform(-math.pi, math.pi))
        add(n1, n2 if rng.random() < 0.7 else uniform_dir())
    # 4. exact mirror pairs (theta_h == 0)
    while len(pairs) < 260:
        wi = sph(math.radians(rng.uniform(1.0, 89.0)), rng.uniform(-math.pi, math.pi))
        add(wi, (-wi[0], -wi[1], wi[2]))
    # 5. near-mirror pairs (tiny theta_h, 1e-7 .. 1e-2 rad perturbation)
    while len(pairs) < 320:
        ti = math.radians(rng.uniform(1.0, 88.0))
        pi_ = rng.uniform(-math.pi, math.pi)
        eps_t = rng.choice((-1, 1)) * 10 ** rng.uniform(-7, -2)
        eps_p = rng.choice((-1, 1)) * 10 ** rng.uniform(-7, -2)
        add(sph(ti, pi_), sph(ti + eps_t, pi_ + math.pi + eps_p))
    # 6. near-retro-reflection (small but well-defined theta_d)
    while len(pairs) < 340:
        ti = math.radians(rng.uniform(1.0, 85.0))
        pi_ = rng.uniform(-math.pi, math.pi)
        add(sph(ti, pi_), sph(ti + rng.uniform(1e-3, 2e-2), pi_ + rng.uniform(-2e-2, 2e-2)))
    return pairs


def decode_cell(value, channel, inverse):
    """(channel, cell) that a value looked up in the distinct table came from.

    ``inverse[k]`` is the file-order position of raw magnitude ``k + 1``.
    """
    raw = abs(int(round(value / ref.SCALES[channel])))
    if not 1 <= raw <= ref.N_VALUES:
        return None
    pos = int(inverse[raw - 1])
    c, flat = divmod(pos, N)
    return (c, (flat // (90 * 180), (flat // 180) % 90, flat % 180))


# --------------------------------------------------------------------------
# fixtures
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def distinct_raw():
    """Raw values 1..4,374,000 in random order, ~10% negated (unmeasured).

    Every cell of every channel holds a different value, so a lookup that
    reads the wrong cell (or the wrong channel) cannot go unnoticed, and the
    cell that was read can be decoded from the value.
    """
    rng = np.random.default_rng(12345)
    raw = rng.permutation(ref.N_VALUES).astype(np.float64) + 1.0
    raw[rng.random(ref.N_VALUES) < 0.1] *= -1.0
    return raw


@pytest.fixture(scope="module")
def distinct_inverse(distinct_raw):
    magnitude = np.abs(distinct_raw).astype(np.int64)
    inverse = np.empty(ref.N_VALUES, dtype=np.int64)
    inverse[magnitude - 1] = np.arange(ref.N_VALUES)
    return inverse


@pytest.fixture(scope="module")
def distinct_table(distinct_raw):
    return distinct_raw.reshape(3, 90, 90, 180) * REF_SCALES[:, None, None, None]


@pytest.fixture(scope="module")
def distinct_raw_list(distinct_raw):
    return distinct_raw.tolist()


@pytest.fixture(scope="module")
def valid_bytes(tmp_path_factory):
    """Bytes of a valid MERL file, written by the reference writer."""
    rng = np.random.default_rng(7)
    raw = rng.uniform(0.0, 3000.0, ref.N_VALUES)
    raw[rng.random(ref.N_VALUES) < 0.05] = -1.0
    path = tmp_path_factory.mktemp("valid") / "valid.binary"
    ref.ref_write(path, raw)
    data = path.read_bytes()
    path.unlink()
    assert len(data) == ref.FILE_SIZE
    return data


@pytest.fixture(scope="module")
def corrupt_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("corrupt")


def assert_rejected(corrupt_dir, payload, words):
    """Write payload to a fresh file; read_merl must raise MerlFormatError."""
    with tempfile.TemporaryDirectory(dir=corrupt_dir) as d:
        path = Path(d) / "corrupt_merl_sample.binary"
        path.write_bytes(payload)
        with pytest.raises(merl.MerlFormatError) as excinfo:
            merl.read_merl(path)
        msg = str(excinfo.value)
        assert isinstance(excinfo.value, ValueError)
        assert path.name in msg, f"file name missing from message: {msg!r}"
        assert str(path) in msg, f"file path missing from message: {msg!r}"
        assert any(w in msg.lower() for w in words), (
            f"message does not say what is wrong (expected one of {words}): {msg!r}"
        )


# --------------------------------------------------------------------------
# constants
# --------------------------------------------------------------------------

def test_constants():
    assert merl.FILE_SIZE == ref.FILE_SIZE == 34_992_012
    scales = np.asarray(merl.SCALES, dtype=np.float64)
    assert scales.shape == (3,)
    np.testing.assert_allclose(scales, REF_SCALES, rtol=1e-15, atol=0)
    assert issubclass(merl.MerlFormatError, ValueError)


# --------------------------------------------------------------------------
# round trips between library and reference
# --------------------------------------------------------------------------

def test_library_write_reference_read(tmp_path):
    rng = np.random.default_rng(1)
    table = rng.uniform(0.0, 5.0, (3, 90, 90, 180))
    unmeasured = rng.random((3, 90, 90, 180)) < 0.05
    table[unmeasured] = -REF_SCALES[np.nonzero(unmeasured)[0]]  # raw -1
    table[0, 0, 0, :3] = 0.0
    path = tmp_path / "lib_written.binary"

    merl.write_merl(path, table)

    assert os.path.getsize(path) == 34_992_012
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name], "temp files left behind"
    with open(path, "rb") as fh:
        assert fh.read(12) == GOOD_HEADER
    raw = np.asarray(ref.ref_read(path), dtype=np.float64).reshape(3, N)
    np.testing.assert_allclose(raw * REF_SCALES[:, None], table.reshape(3, N), rtol=1e-12, atol=0)
    # unmeasured cells are stored as raw -1 (negative), measured as >= 0
    assert np.all(raw.reshape(table.shape)[unmeasured] < 0)
    assert np.all(raw.reshape(table.shape)[~unmeasured] >= 0)


def test_reference_write_library_read(tmp_path, distinct_raw):
    path = tmp_path / "ref_written.binary"
    ref.ref_write(path, distinct_raw)
    assert os.path.getsize(path) == 34_992_012

    table = merl.read_merl(str(path))

    assert isinstance(table, np.ndarray)
    assert table.shape == (3, 90, 90, 180)
    assert table.dtype == np.float64
    expected = distinct_raw.reshape(3, 90, 90, 180) * REF_SCALES[:, None, None, None]
    np.testing.assert_allclose(table, expected, rtol=1e-12, atol=0)
    # index order spot checks: (channel, theta_h, theta_d, phi_d)
    for c, ith, itd, ipd in [(0, 0, 0, 1), (1, 0, 1, 0), (2, 1, 0, 0), (2, 89, 89, 179), (1, 45, 3, 170)]:
        flat = c * N + ith * 16200 + itd * 180 + ipd
        assert table[c, ith, itd, ipd] == pytest.approx(distinct_raw[flat] * ref.SCALES[c], rel=1e-12)


def test_library_round_trip_and_overwrite(tmp_path):
    rng = np.random.default_rng(2)
    path = tmp_path / "rt.binary"
    for _ in range(2):  # second pass overwrites the existing file
        table = rng.uniform(-0.01, 3.0, (3, 90, 90, 180))
        merl.write_merl(path, table)
        back = merl.read_merl(path)
        np.testing.assert_allclose(back, table, rtol=1e-12, atol=0)
        assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


# --------------------------------------------------------------------------
# lookup
# --------------------------------------------------------------------------

def test_lookup_matches_reference(distinct_table, distinct_raw_list, distinct_inverse):
    pairs = direction_pairs()
    assert len(pairs) >= 300
    wi = np.array([p[0] for p in pairs], dtype=np.float64)
    wo = np.array([p[1] for p in pairs], dtype=np.float64)

    got = np.asarray(merl.lookup(distinct_table, wi, wo))
    assert got.shape == (len(pairs), 3)

    expected = np.array([ref.ref_lookup(distinct_raw_list, a, b) for a, b in pairs])
    bad = ~np.isclose(got, expected, rtol=1e-12, atol=0).all(axis=1)
    if bad.any():
        lines = []
        for k in np.nonzero(bad)[0][:15]:
            a, b = pairs[k]
            th, td, pd = ref.ref_coords(a, b)
            lines.append(
                f"pair {k}: wi={a} wo={b} theta_h={th!r} theta_d={td!r} phi_d={pd!r} "
                f"ref cell={ref.ref_cell(a, b)} library (channel, cell)={decode_cell(got[k, 0], 0, distinct_inverse)}"
            )
        pytest.fail(f"{bad.sum()} of {len(pairs)} lookups disagree:\n" + "\n".join(lines))


# (theta_h, theta_d, phi_d, phi_h) in degrees -> expected cell; values kept
# well away from bin edges.  theta_h index = floor(sqrt(theta_h_deg * 90)).
CONSTRUCTED = [
    ((10.5, 20.5, 90.5, 0.0), (30, 20, 90)),
    ((10.5, 20.5, -89.5, 0.0), (30, 20, 90)),     # reciprocity fold
    ((0.001, 45.3, 10.7, 37.0), (0, 45, 10)),
    ((2.0, 33.3, 100.2, -150.0), (13, 33, 100)),
    ((60.0, 25.5, 89.5, -120.0), (73, 25, 89)),
    ((60.0, 25.5, -90.7, 75.0), (73, 25, 89)),
    ((80.0, 5.2, 135.5, 10.0), (84, 5, 135)),
    ((89.0, 0.5, 90.5, 200.0), (89, 0, 90)),
    ((0.0, 89.9, 45.5, 0.0), (0, 89, 45)),
    ((25.0, 70.3, 0.4, 0.0), (47, 70, 0)),
    ((25.0, 70.3, 179.6, 0.0), (47, 70, 179)),
]


@pytest.mark.parametrize("angles, cell", CONSTRUCTED)
def test_reference_cell_from_constructed_angles(angles, cell):
    """Sanity check of the reference itself on directions built from angles."""
    wi, wo = from_half_diff(*(math.radians(a) for a in angles[:3]), phi_h=math.radians(angles[3]))
    assert ref.ref_cell(wi, wo) == cell
    assert ref.ref_cell(wo, wi) == cell  # reciprocity


def test_lookup_constructed_angles(distinct_table, distinct_inverse):
    dirs = [from_half_diff(*(math.radians(a) for a in angles[:3]), phi_h=math.radians(angles[3]))
            for angles, _ in CONSTRUCTED]
    wi = np.array([d[0] for d in dirs])
    wo = np.array([d[1] for d in dirs])
    for a, b in ((wi, wo), (wo, wi)):
        got = np.asarray(merl.lookup(distinct_table, a, b))
        for k, (_, cell) in enumerate(CONSTRUCTED):
            for c in range(3):
                assert decode_cell(got[k, c], c, distinct_inverse) == (c, cell), (k, c, CONSTRUCTED[k])


# --------------------------------------------------------------------------
# reader error handling (hypothesis, on corrupted copies of a valid file)
# --------------------------------------------------------------------------

def test_valid_bytes_are_accepted(valid_bytes, corrupt_dir):
    # guards the corruption tests: the uncorrupted bytes must read fine
    with tempfile.TemporaryDirectory(dir=corrupt_dir) as d:
        path = Path(d) / "ok.binary"
        path.write_bytes(valid_bytes)
        table = merl.read_merl(path)
    assert table.shape == (3, 90, 90, 180)
    assert (table < 0).any()  # unmeasured (negative) cells are not errors


@HYPO
@given(length=st.integers(min_value=0, max_value=ref.FILE_SIZE - 1))
@example(length=0)
@example(length=1)
@example(length=11)
@example(length=12)  # header only
@example(length=13)
@example(length=12 + 8 * N)  # exactly one channel
@example(length=ref.FILE_SIZE - 8)  # one value short
@example(length=ref.FILE_SIZE - 1)
def test_truncated_file_rejected(valid_bytes, corrupt_dir, length):
    assert_rejected(corrupt_dir, valid_bytes[:length], SIZE_WORDS)


@HYPO
@given(extra=st.one_of(
    st.binary(min_size=1, max_size=64),
    st.integers(min_value=1, max_value=1_000_000).map(lambda k: b"\x00" * k),
))
@example(extra=b"\x00")
@example(extra=b"\x00" * 8)  # one extra float64
@example(extra=b"\x00" * (8 * N))  # one extra channel
def test_trailing_bytes_rejected(valid_bytes, corrupt_dir, extra):
    assert_rejected(corrupt_dir, valid_bytes + extra, SIZE_WORDS)


INT32 = st.integers(min_value=-(2 ** 31), max_value=2 ** 31 - 1)


@HYPO
@given(dims=st.tuples(INT32, INT32, INT32).filter(lambda t: t != (90, 90, 180)))
@example(dims=(180, 90, 90))  # same product, wrong order
@example(dims=(90, 180, 90))
@example(dims=(90, 90, 360))
@example(dims=(91, 90, 180))
@example(dims=(0, 0, 0))
@example(dims=(-90, -90, -180))
@example(dims=struct.unpack("<3i", struct.pack(">3i", 90, 90, 180)))  # big-endian header
def test_wrong_header_dims_rejected(valid_bytes, corrupt_dir, dims):
    payload = struct.pack("<3i", *dims) + valid_bytes[12:]
    assert_rejected(corrupt_dir, payload, DIMS_WORDS)


NONFINITE = [
    struct.pack("<d", float("nan")),
    struct.pack("<d", float("inf")),
    struct.pack("<d", float("-inf")),
    struct.pack("<Q", 0xFFF8000000000000),  # negative quiet NaN
    struct.pack("<Q", 0x7FF0000000000001),  # signalling NaN
    struct.pack("<Q", 0xFFF0000000000001),  # negative signalling NaN
    struct.pack("<Q", 0x7FFFFFFFFFFFFFFF),  # NaN, all payload bits set
]


@HYPO
@given(position=st.integers(min_value=0, max_value=ref.N_VALUES - 1),
       bad=st.sampled_from(NONFINITE))
@example(position=0, bad=NONFINITE[0])
@example(position=ref.N_VALUES - 1, bad=NONFINITE[1])
@example(position=N, bad=NONFINITE[2])  # first green value
@example(position=2 * N - 1, bad=NONFINITE[3])  # last green value
def test_nonfinite_values_rejected(valid_bytes, corrupt_dir, position, bad):
    offset = 12 + 8 * position
    payload = valid_bytes[:offset] + bad + valid_bytes[offset + 8:]
    assert len(payload) == ref.FILE_SIZE
    assert_rejected(corrupt_dir, payload, NONFINITE_WORDS)


def test_missing_file(tmp_path):
    missing = tmp_path / "no_such_brdf.binary"
    with pytest.raises(FileNotFoundError):
        merl.read_merl(missing)
    with pytest.raises(FileNotFoundError):
        merl.read_merl(str(missing))


# --------------------------------------------------------------------------
# writer validation
# --------------------------------------------------------------------------

def _bad_tables():
    good = np.full((3, 90, 90, 180), 0.5)
    nan_first = good.copy()
    nan_first[0, 0, 0, 0] = np.nan
    nan_mid = good.copy()
    nan_mid[1, 44, 17, 99] = np.nan
    nan_last = good.copy()
    nan_last[2, 89, 89, 179] = np.nan
    return {
        "shape_phi179": np.full((3, 90, 90, 179), 0.5),
        "no_channel_axis": np.full((90, 90, 180), 0.5),
        "extra_axis": np.full((1, 3, 90, 90, 180), 0.5),
        "flat_right_size": np.full(ref.N_VALUES, 0.5),
        "transposed_same_size": np.full((3, 90, 180, 90), 0.5),
        "two_channels": np.full((2, 90, 90, 180), 0.5),
        "nan_first": nan_first,
        "nan_mid": nan_mid,
        "nan_last": nan_last,
    }


@pytest.mark.parametrize("name", list(_bad_tables()))
def test_write_rejects_bad_table(tmp_path, name):
    table = _bad_tables()[name]
    path = tmp_path / "should_not_exist.binary"
    with pytest.raises(ValueError):
        merl.write_merl(path, table)
    assert not path.exists()
    assert list(tmp_path.iterdir()) == [], "write_merl left a file behind"


@pytest.mark.parametrize("value", [np.inf, -np.inf])
def test_write_rejects_infinite(tmp_path, value):
    # not strictly in the brief (which names NaN), but a file containing
    # +-Inf would be rejected by read_merl, so write_merl must not produce it
    table = np.full((3, 90, 90, 180), 0.5)
    table[1, 2, 3, 4] = value
    path = tmp_path / "should_not_exist.binary"
    with pytest.raises(ValueError):
        merl.write_merl(path, table)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_existing_file(tmp_path):
    path = tmp_path / "existing.binary"
    merl.write_merl(path, np.full((3, 90, 90, 180), 0.25))
    before = path.read_bytes()
    bad = np.full((3, 90, 90, 180), 0.75)
    bad[0, 10, 10, 10] = np.nan
    with pytest.raises(ValueError):
        merl.write_merl(path, bad)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
