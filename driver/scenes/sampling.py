"""Counter-based random numbers and the sampling a rendering workload needs (docs/workloads.md#ray-types).

Every random number is a pure function of (seed, pixel, sample, bounce, purpose, dimension):
``uniform`` hashes those integers, so a ray's numbers do not depend on which other rays are traced
with it, in what order, or in which tile or process; any tile of a frame computed alone gives
exactly the rays the whole frame gives. numpy's generators (PCG64, Philox) are streams held in an
object, one per stream: a vectorised pure function over millions of (pixel, sample) keys at once is
what they do not offer, so the hash is written here: SplitMix64's finaliser (Steele, Lea, Flood,
"Fast splittable pseudorandom number generators", OOPSLA 2014) applied to the running key after
each input word, a construction whose outputs pass BigCrush (tests check uniformity roughly).

Sampling: cosine-weighted hemisphere directions (Malley's method: a uniform disk point lifted to
the hemisphere), orthonormal bases (Duff et al. 2017, "Building an orthonormal basis,
revisited"), stratified sub-pixel jitter, and the self-intersection offset of secondary ray
origins: the hit point, first put back on its triangle's plane (``driver.workloads`` projects it,
removing the error of ``o + t d`` along the normal), moves along the geometric normal by
``OFFSET_REL`` (2^-14, 512 float32 ulps) of its largest coordinate. Why not Waechter and Binder's
per-coordinate ulp offset (Ray Tracing Gems, 2019, ch. 6): a coordinate near zero gets their
fixed absolute fallback (2^-16), which in a scene measured in hundreds of units is smaller than
the datapath's float32 rounding of ``P - o`` (relative to the triangle's distance from the
origin), so rays left an axis-aligned wall at x = 0 through the wall itself (measured on the
Cornell box: 1 % of its shadow rays).
"""

from __future__ import annotations

import numpy as np

# purposes: which decision a random number feeds (one hash domain each)
CAMERA = 0          # sub-pixel jitter
LIGHT = 1           # the point sampled on the light
AO = 2              # ambient-occlusion directions
BOUNCE = 3          # diffuse continuation directions

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser (a bijection of uint64)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def hash64(*words) -> np.ndarray:
    """A 64-bit hash of integer words (scalars or arrays, broadcast together)."""
    with np.errstate(over="ignore"):
        key = np.uint64(0x243F6A8885A308D3)
        for w in words:
            key = _mix(np.asarray(key, np.uint64) + _GOLDEN
                       + np.asarray(w, np.int64).astype(np.uint64))
        return np.asarray(key, np.uint64)


def uniform(seed, pixel, sample, bounce, purpose, dim) -> np.ndarray:
    """Uniform numbers in [0, 1) (float64, 53 bits), one per broadcast key."""
    h = hash64(seed, pixel, sample, bounce, purpose, dim)
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def uniform2(seed, pixel, sample, bounce, purpose):
    """Two independent uniform numbers (dimensions 0 and 1) per key."""
    return (uniform(seed, pixel, sample, bounce, purpose, 0),
            uniform(seed, pixel, sample, bounce, purpose, 1))


def jitter(seed, pixel, sample, spp: int):
    """Sub-pixel offsets in [0, 1)^2: the pixel centre for one sample, else stratified jitter
    (an m x m grid of strata, m = ceil(sqrt(spp)); sample s in stratum (s mod m, s div m) of the
    first spp strata, at a random point inside it)."""
    sample = np.asarray(sample)
    if spp == 1:
        half = np.full(np.broadcast(pixel, sample).shape, 0.5)
        return half, half.copy()
    m = int(np.ceil(np.sqrt(spp)))
    u, v = uniform2(seed, pixel, sample, 0, CAMERA)
    return ((sample % m) + u) / m, ((sample // m) + v) / m


def basis(n: np.ndarray):
    """Two unit tangents (t, b) completing unit normals n (k, 3) to right-handed bases."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = np.stack([1 + s * x * x * a, s * b, -s * x], axis=1)
    bt = np.stack([b, s + y * y * a, -y], axis=1)
    return t, bt


def cosine_hemisphere(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Cosine-distributed unit directions (k, 3) on the hemispheres of unit normals n (k, 3)."""
    r = np.sqrt(u1)
    phi = 2 * np.pi * u2
    x, y = r * np.cos(phi), r * np.sin(phi)
    z = np.sqrt(np.maximum(0.0, 1 - u1))
    t, b = basis(n)
    return x[:, None] * t + y[:, None] * b + z[:, None] * n


OFFSET_REL = 2.0 ** -14        # offset / the point's largest coordinate (512 float32 ulps)


def offset_origin(p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Secondary-ray origins: points p (k, 3) on their surface pushed off it along the unit
    geometric normal n (k, 3) (pointing to the side the new ray leaves) by ``OFFSET_REL`` times
    the point's largest coordinate, as float32."""
    p = np.asarray(p, np.float64)
    scale = np.maximum(np.abs(p).max(axis=1), 1e-30)
    return (p + (OFFSET_REL * scale)[:, None] * np.asarray(n, np.float64)).astype(np.float32)
