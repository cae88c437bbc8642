"""driver.prepare_rays (docs/datapath.md#ray-preparation) against the scalar reference and the
special cases of docs/datapath.md#ray-preparation."""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import REQUEST_DTYPE
from support import scalar_ref

F32 = np.float32
INF = np.inf
RAY_FIELDS = ("origin", "dir", "inv", "extent", "kx", "ky", "kz", "shear")


def bits(x):
    x = np.ascontiguousarray(x)
    return x.view(np.uint32) if x.dtype.kind == "f" else x


def assert_same_rays(got, want):
    assert got.dtype == REQUEST_DTYPE == want.dtype and len(got) == len(want)
    for name in RAY_FIELDS:
        g, w = bits(got[name]), bits(want[name])
        bad = (g != w).reshape(len(g), -1).any(axis=1)
        assert not bad.any(), (name, np.flatnonzero(bad)[:5], got[bad][:3], want[bad][:3])


def one(direction, origin=(0, 0, 0), extent=INF):
    r = driver.prepare_rays([origin], [direction], extent)
    assert_same_rays(r, scalar_ref.prepare_rays([origin], [direction], extent))
    return r[0]


def signbits(x):
    return np.signbit(np.asarray(x, F32)).tolist()


# (direction, kz, kx, ky)
AXES = [((1, 0, 0), 0, 1, 2), ((-1, 0, 0), 0, 2, 1),
        ((0, 1, 0), 1, 2, 0), ((0, -1, 0), 1, 0, 2),
        ((0, 0, 1), 2, 0, 1), ((0, 0, -1), 2, 1, 0)]


@pytest.mark.parametrize("d,kz,kx,ky", AXES, ids=["+x", "-x", "+y", "-y", "+z", "-z"])
def test_axis_parallel(d, kz, kx, ky):
    r = one(d, origin=(1, 2, 3), extent=7)
    assert (r["kx"], r["ky"], r["kz"]) == (kx, ky, kz)
    s = d[kz]
    for a in range(3):
        if a == kz:
            assert r["inv"][a] == s
        else:
            assert r["inv"][a] == INF and not np.signbit(r["inv"][a])       # 1/+0 = +inf
    # shear: (d[kx]/d[kz], d[ky]/d[kz], 1/d[kz]) = (+-0, +-0, +-1); 0/-1 = -0
    assert list(r["shear"]) == [0, 0, s]
    assert signbits(r["shear"]) == [s < 0, s < 0, s < 0]
    assert list(r["origin"]) == [1, 2, 3] and r["extent"] == 7 and list(r["dir"]) == list(d)


@pytest.mark.parametrize("d,kz,kx,ky", AXES, ids=["+x", "-x", "+y", "-y", "+z", "-z"])
def test_axis_parallel_minus_zero(d, kz, kx, ky):
    dm = tuple(-0.0 if v == 0 else v for v in d)
    r = one(dm)
    assert (r["kx"], r["ky"], r["kz"]) == (kx, ky, kz)        # -0 never changes kz or the swap
    for a in range(3):
        if a != kz:
            assert r["inv"][a] == -INF                           # 1/-0 = -inf
            assert np.signbit(r["dir"][a])
    s = d[kz]
    # -0 / s: sign is the xor of the signs
    assert signbits(r["shear"][:2]) == [s > 0, s > 0]
    assert r["shear"][2] == s


def test_minus_zero_components_mixed():
    r = one((-0.0, 2, 0.0))
    assert list(r["inv"]) == [-INF, 0.5, INF]
    assert (r["kz"], r["kx"], r["ky"]) == (1, 2, 0)
    assert signbits(r["shear"]) == [False, True, False]        # 0/2, -0/2, 1/2
    r = one((-0.0, -2, 0.0))
    assert (r["kz"], r["kx"], r["ky"]) == (1, 0, 2)            # d[kz] < 0: swapped
    assert signbits(r["shear"]) == [False, True, True]         # -0/-2 = +0, 0/-2 = -0, 1/-2


def test_swap_when_dz_negative():
    for d, k in [((1, 2, 5), (0, 1, 2)), ((1, 2, -5), (1, 0, 2)),
                 ((5, 1, 2), (1, 2, 0)), ((-5, 1, 2), (2, 1, 0)),
                 ((1, 5, 2), (2, 0, 1)), ((1, -5, 2), (0, 2, 1))]:
        r = one(d)
        assert (r["kx"], r["ky"], r["kz"]) == k, d
        kx, ky, kz = k
        assert r["shear"][0] == F32(d[kx]) / F32(d[kz])
        assert r["shear"][1] == F32(d[ky]) / F32(d[kz])
        assert r["shear"][2] == F32(1) / F32(d[kz])


def test_ties_lowest_index_wins():
    for d, kz in [((1, 1, 1), 0), ((-1, 1, 1), 0), ((1, -1, 1), 0), ((0.5, 2, -2), 1),
                  ((0, 3, -3), 1), ((-2, 1, 2), 0), ((1, 1, 0), 0), ((0, 0, -4), 2),
                  ((1.0, 1.00000001, 0), 0)]:                  # equal after the float32 cast
        r = one(d)
        assert r["kz"] == kz, d
    r = one((-2, 2, 2))
    assert (r["kz"], r["kx"], r["ky"]) == (0, 2, 1)


def test_tiny_and_subnormal_components():
    # 1e-40 and 1e-39 are subnormal: 1/x overflows to inf; 3e-39 gives a finite 3.3e38
    r = one((1e-40, 1, -1e-39))
    assert r["inv"][0] == INF and r["inv"][2] == -INF and r["inv"][1] == 1
    assert r["kz"] == 1
    assert r["shear"][0] in (F32(1e-40), F32(-1e-39))          # subnormal shear kept, not flushed
    assert (np.abs(r["shear"][:2]) > 0).all()
    r = one((3e-39, 1, 0))
    assert np.isfinite(r["inv"][0]) and r["inv"][0] > 3e38
    # whole direction tiny: kz still picks the largest, shear can overflow
    r = one((2.0 ** -149, -(2.0 ** -148), 0))                  # 1 and 2 units of the last subnormal
    assert r["kz"] == 1 and r["inv"][2] == INF and r["shear"][2] == -INF
    assert (r["kx"], r["ky"]) == (0, 2) and r["shear"][0] == F32(-0.5)
    r = one((1e-30, 1e-32, 1e-31))
    assert r["kz"] == 0 and r["shear"][2] == F32(1) / F32(1e-30)


def test_shear_random_vs_scalar_reference():
    rng = np.random.default_rng(3)
    n = 3000
    d = rng.normal(size=(n, 3)).astype(F32)
    d[:300] *= rng.choice([1e-30, 1e-38, 1e30, 1e-42], (300, 1)).astype(F32)
    z = rng.random((n, 3)) < 0.15
    d[z] = rng.choice([0.0, -0.0], z.sum())
    d[(d == 0).all(axis=1)] = [0, -1, 0]
    d[300:600] = np.round(d[300:600])                         # many |d| ties
    d[(d == 0).all(axis=1)] = [1, -1, 1]
    o = rng.uniform(-10, 10, (n, 3)).astype(F32)
    ext = rng.uniform(0, 100, n).astype(F32)
    with np.errstate(all="ignore"):
        got = driver.prepare_rays(o, d, ext)
    assert_same_rays(got, scalar_ref.prepare_rays(o, d, ext))
    assert set(np.unique(got["kz"])) == {0, 1, 2}


def test_input_converted_to_float32_first():
    r = one((0.3, 0.6, 2.3))                                  # float64 in
    d = np.array([0.3, 0.6, 2.3], np.float32)
    assert r["inv"].tolist() == (F32(1) / d).tolist()
    assert r["shear"][0] == d[0] / d[2] and r["shear"][1] == d[1] / d[2]
    assert r["shear"][0] != F32(0.3 / 2.3)                   # not divided in float64
    assert r["shear"][2] != F32(1 / 2.3)


def test_extent_broadcast_and_other_fields_zero():
    o = np.zeros((5, 3))
    d = np.tile([0, 0, 1.0], (5, 1))
    assert np.isposinf(driver.prepare_rays(o, d)["extent"]).all()
    r = driver.prepare_rays(o, d, 2.5)
    assert (r["extent"] == F32(2.5)).all()
    r = driver.prepare_rays(o, d, np.arange(5))
    assert r["extent"].tolist() == [0, 1, 2, 3, 4] and r["extent"].dtype == np.float32
    with pytest.raises(ValueError):
        driver.prepare_rays(o, d, np.arange(4))
    for name in REQUEST_DTYPE.names:
        if name not in RAY_FIELDS:
            assert not np.ascontiguousarray(r[name]).view(np.uint8).any(), name
    assert r.dtype == REQUEST_DTYPE and r.shape == (5,)
    # a fresh array every call
    r2 = driver.prepare_rays(o, d, 2.5)
    r2["extent"] = 9
    assert (r["extent"] != 9).all()
    # a single ray given as flat 3-vectors
    r = driver.prepare_rays((1, 2, 3), (0, 1, 0))
    assert r.shape == (1,) and r["kz"][0] == 1
    assert len(driver.prepare_rays(np.zeros((0, 3)), np.zeros((0, 3)))) == 0


@pytest.mark.parametrize("o,d", [
    ((0, 0, 0), (np.nan, 1, 0)),
    ((0, 0, 0), (0, np.inf, 0)),
    ((0, 0, 0), (0, 0, -np.inf)),
    ((np.nan, 0, 0), (0, 0, 1)),
    ((0, np.inf, 0), (0, 0, 1)),
    ((0, 0, 0), (0, 0, 0)),
    ((0, 0, 0), (-0.0, -0.0, -0.0)),
    ((0, 0, 0), (0.0, -0.0, 0.0)),
    ((0, 0, 0), (1e39, 0, 0)),                                # overflows float32 -> inf
], ids=["nan_dir", "inf_dir", "-inf_dir", "nan_origin", "inf_origin", "zero", "minus_zero",
        "mixed_zero", "overflow_dir"])
def test_value_errors(o, d):
    with pytest.raises(ValueError), np.errstate(over="ignore"):
        driver.prepare_rays([o, (0, 0, 0)], [d, (1, 0, 0)])


def test_shape_mismatch():
    with pytest.raises(ValueError):
        driver.prepare_rays(np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError):
        driver.prepare_rays(np.zeros((1, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError):
        driver.prepare_rays(np.zeros((2, 3)), np.ones((2, 2)))


@pytest.mark.parametrize("o, d, extent, message", [
    (np.zeros((32, 4)), np.ones((32, 4)), 1.0,
     "origins must be an (n, 3) array, one x, y, z row per ray; got shape (32, 4)"),
    (np.zeros((2, 3)), np.ones(6), 1.0,
     "directions must be an (n, 3) array, one x, y, z row per ray; got shape (6,)"),
    (np.zeros((2, 3)), 1.0, 1.0,
     "directions must be an (n, 3) array, one x, y, z row per ray; got shape ()"),
    ([[0, 0], [0, 0, 0]], np.ones((2, 3)), 1.0,
     "origins must be an (n, 3) array of numbers, one x, y, z row per ray (got rows of unequal "
     "length, or values that are not numbers)"),
    (np.zeros((4, 3)), np.ones((4, 3)), np.ones(5),
     "extent must be a scalar or one value per ray, shape (4,); got shape (5,)"),
    (np.zeros((4, 3)), np.ones((4, 3)), "far",
     "extent must be a number or one number per ray, shape (4,)"),
])
def test_a_bad_shape_names_the_argument_and_the_shape_it_wants(o, d, extent, message):
    """Rays of the wrong shape gave numpy's "cannot reshape array of size 128 into shape (3)"
    (and (2, 6) was silently read as 4 rays)."""
    with pytest.raises(ValueError) as e:
        driver.prepare_rays(o, d, extent)
    assert str(e.value) == message
    with pytest.raises(ValueError) as e:
        driver.trace(np.eye(3, dtype=np.float32)[None], o, d, backend="golden", extent=extent)
    assert str(e.value) == message


def test_trace_checks_the_rays_before_it_builds_the_bvh(monkeypatch):
    """Bad rays are refused before a scene's BVH is built (which takes seconds on a big mesh)."""
    import driver.tracer

    def no_build(*args, **kwargs):
        raise AssertionError("the BVH was built before the rays were checked")

    monkeypatch.setattr(driver.tracer, "_set_up", no_build)
    with pytest.raises(ValueError, match="directions must be an"):
        driver.trace("bunny", np.zeros((2, 3)), np.ones((2, 2)), backend="golden")


def test_rays_of_any_leading_shape_are_rows():
    """(h, w, 3) rays (an image's) are h * w rows in C order."""
    d = np.random.default_rng(1).normal(size=(2, 5, 3))
    assert (driver.prepare_rays(np.zeros_like(d), d)["dir"] == d.reshape(-1, 3).astype(F32)).all()
