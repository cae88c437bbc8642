"""Built-in rendering scenes with materials and lights: the Cornell box, the bunny on a floor,
and a large instanced scene (a grid of rotated, scaled bunnies on a plane: 21 instances of one
bunny and one of the floor, traced through a two-level BVH; docs/instances.md).

The Cornell box is the published geometry of the Cornell Program of Computer Graphics ("Cornell
Box Data": floor, ceiling, back wall, red left wall, green right wall, a short and a tall block,
a 130 x 105 quad light under the ceiling; millimetres, y up; camera at (278, 273, -800) looking
down +z with a 35 mm lens on a 25 mm film, i.e. a vertical field of view of 39.31 degrees). The
reflectances are the usual RGB reductions of its measured spectra; the light sits 0.1 below the
ceiling (the data puts both in one plane, which would make the light and the ceiling overlap).
Its triangles are double-sided (NO_CULL), as the data's walls are single quads seen from inside.
"""

from __future__ import annotations


import numpy as np

from ..instances import Instances
from .camera import frame
from .city import city
from .materials import Built, QuadLight

WHITE = (0.73, 0.73, 0.73)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
LIGHT_RADIANCE = (17.0, 12.0, 4.0)

# (name, reflectance, quads: 4 corners each, in the data's order)
_CORNELL = (
    ("floor", WHITE, [[(552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2)]]),
    ("ceiling", WHITE, [[(556, 548.8, 0), (556, 548.8, 559.2), (0, 548.8, 559.2),
                         (0, 548.8, 0)]]),
    ("back", WHITE, [[(549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556, 548.8, 559.2)]]),
    ("right", GREEN, [[(0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2)]]),
    ("left", RED, [[(552.8, 0, 0), (549.6, 0, 559.2), (556, 548.8, 559.2), (556, 548.8, 0)]]),
    ("short block", WHITE, [[(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)],
                            [(290, 0, 114), (290, 165, 114), (240, 165, 272), (240, 0, 272)],
                            [(130, 0, 65), (130, 165, 65), (290, 165, 114), (290, 0, 114)],
                            [(82, 0, 225), (82, 165, 225), (130, 165, 65), (130, 0, 65)],
                            [(240, 0, 272), (240, 165, 272), (82, 165, 225), (82, 0, 225)]]),
    ("tall block", WHITE, [[(423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)],
                           [(423, 0, 247), (423, 330, 247), (472, 330, 406), (472, 0, 406)],
                           [(472, 0, 406), (472, 330, 406), (314, 330, 456), (314, 0, 456)],
                           [(314, 0, 456), (314, 330, 456), (265, 330, 296), (265, 0, 296)],
                           [(265, 0, 296), (265, 330, 296), (423, 330, 247), (423, 0, 247)]]),
)
_LIGHT_Y = 548.7
_LIGHT = ((343.0, _LIGHT_Y, 227.0), (0.0, 0.0, 105.0), (-130.0, 0.0, 0.0))  # corner, u, v: u x v = -y


def _quads(quads) -> np.ndarray:
    q = np.asarray(quads, np.float64).reshape(-1, 4, 3)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def cornell(bunny=None) -> Built:
    """The Cornell box (see the module docstring); ``bunny`` is not used (the ``BUILT``
    signature)."""
    tris, albedo = [], []
    for _, refl, quads in _CORNELL:
        t = _quads(quads)
        tris.append(t)
        albedo.append(np.broadcast_to(refl, (len(t), 3)))
    c, u, v = (np.asarray(x) for x in _LIGHT)
    light_tris = _quads([[c, c + u, c + u + v, c + v]])
    tris.append(light_tris)
    albedo.append(np.full((2, 3), 0.78))
    emission = np.zeros((sum(len(t) for t in tris), 3))
    emission[-2:] = LIGHT_RADIANCE
    light = QuadLight(tuple(c), tuple(u), tuple(v), LIGHT_RADIANCE)
    camera = {"position": (278.0, 273.0, -800.0), "look_at": (278.0, 273.0, 0.0),
              "up": (0.0, 1.0, 0.0), "fov_deg": float(np.degrees(2 * np.arctan(12.5 / 35.0)))}
    return Built(np.concatenate(tris).astype(np.float32), np.concatenate(albedo), emission,
                 [light], camera, True)


def floor_under(triangles: np.ndarray, margin: float = 1.5):
    """Two triangles of a floor (normal +z) just under z-up ``triangles``, ``margin`` times their
    footprint on each side, and a quad light above them (emitting downwards)."""
    pts = triangles.reshape(-1, 3).astype(np.float64)
    lo, hi = pts.min(0), pts.max(0)
    size = hi - lo
    c = (lo + hi) / 2
    r = margin * max(size[0], size[1])
    z = lo[2] - 1e-3 * max(size)
    a, b = (c[0] - r, c[1] - r, z), (c[0] + r, c[1] - r, z)
    cc, d = (c[0] + r, c[1] + r, z), (c[0] - r, c[1] + r, z)
    floor = _quads([[a, b, cc, d]])                  # counter-clockwise seen from above: +z
    s = 0.4 * max(size[0], size[1])
    corner = (c[0] - s / 2 - 0.3 * size[0], c[1] - s / 2 - 0.3 * size[1], hi[2] + 1.2 * size[2])
    light = QuadLight(corner, (0.0, s, 0.0), (s, 0.0, 0.0), (12.0, 11.0, 10.0))  # u x v = -z
    return floor, light


def bunny_floor(bunny) -> Built:
    """The Stanford bunny (``bunny``: a callable returning its (m, 3, 3) triangles, z up) on a
    floor, lit by a quad light above it; single-sided."""
    bunny = bunny()
    floor, light = floor_under(bunny)
    tris = np.concatenate([bunny.astype(np.float64), floor]).astype(np.float32)
    albedo = np.concatenate([np.full((len(bunny), 3), (0.80, 0.76, 0.70)),
                             np.full((2, 3), (0.55, 0.60, 0.65))])
    return Built(tris, albedo, np.zeros((len(tris), 3)), [light], _framing(bunny), False)


def bunny_placements(bunny: np.ndarray, count: int, seed: int = 0) -> np.ndarray:
    """(count, 3, 4) float64 transforms placing ``count`` copies of the ``bunny`` triangles (z up)
    on a square grid in the plane z = 0, feet at z = 0, each turned about z by a random angle and
    scaled by a random factor in [0.6, 1.4], deterministic in ``seed``. Neighbouring copies may
    touch but do not interpenetrate much (grid pitch = 1.5 x the largest bunny's footprint)."""
    if int(count) < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    count = int(count)
    pts = np.asarray(bunny, np.float64).reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    feet = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    pitch = 1.5 * 1.4 * float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, count)
    scale = rng.uniform(0.6, 1.4, count)
    side = int(np.ceil(np.sqrt(count)))
    c, s = np.cos(angle), np.sin(angle)
    rot = np.zeros((count, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c, -s, s, c
    rot[:, 2, 2] = 1.0
    rot *= scale[:, None, None]
    i = np.arange(count)
    shift = np.stack([(i % side) * pitch, (i // side) * pitch, np.zeros(count)], axis=1)
    return np.concatenate([rot, (shift - rot @ feet)[:, :, None]], axis=2)


def instanced_bunnies(bunny: np.ndarray, count: int, seed: int = 0):
    """``driver.instances.Instances``: ``count`` instances of the ``bunny`` triangles placed by
    ``bunny_placements``."""
    return Instances([np.asarray(bunny, np.float32)], np.zeros(int(count), np.int64),
                     bunny_placements(bunny, count, seed))


def bunny_grid(bunny, count: int = 21) -> Built:
    """``instanced_bunnies`` of ``bunny()`` on one floor (an instance of its own, identity
    transform) with one quad light; single-sided."""
    grid = instanced_bunnies(bunny(), count)
    bunnies = grid.flatten()
    floor, light = floor_under(bunnies, margin=0.6)
    identity = np.eye(3, 4)[None]
    inst = Instances(grid.meshes + [floor.astype(np.float32)], np.append(grid.mesh, 1),
                     np.concatenate([grid.object_to_world, identity]))
    tris = np.concatenate([bunnies, inst.meshes[-1]])    # inst.flatten(): the floor's is identity
    albedo = np.full((len(tris), 3), (0.80, 0.76, 0.70))
    albedo[-2:] = (0.55, 0.60, 0.65)
    return Built(tris, albedo, np.zeros((len(tris), 3)), [light], _framing(bunnies), False,
                 inst)


def _framing(tris: np.ndarray) -> dict:
    cam = frame(tris.reshape(-1, 3), up=(0.0, 0.0, 1.0), fill=0.7)
    return {"position": cam.position, "look_at": cam.look_at, "up": cam.up,
            "fov_deg": cam.fov_deg}


def _city(bunny) -> Built:
    return city(bunny)


BUILT = {"cornell": cornell, "bunny_floor": bunny_floor, "bunny_grid": bunny_grid, "city": _city}
