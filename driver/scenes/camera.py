"""Pinhole camera and primary rays.

The camera looks from ``position`` towards ``look_at``; ``up`` fixes the roll; ``fov_deg`` is the
vertical field of view. Pixels are square; rays go through pixel centres, row-major, top row first.
Ray directions are normalised (so a hit's ``t`` is its distance from the camera).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import CameraError

MAX_SIZE = 8192
F32_MAX = float(np.finfo(np.float32).max)


def fmt_vec(v) -> str:
    """Plain numbers for messages: (1, 2.5, -3) (not np.float64(...))."""
    return "(" + ", ".join(f"{float(x):.9g}" for x in np.asarray(v).reshape(-1)) + ")"


@dataclass(frozen=True)
class Camera:
    """position, look_at, up : 3 floats each; fov_deg : vertical field of view in (0, 180)."""

    position: tuple = (0.0, 0.0, 0.0)
    look_at: tuple = (0.0, 0.0, -1.0)
    up: tuple = field(default=(0.0, 0.0, 1.0))
    fov_deg: float = 40.0

    def validate(self) -> "Camera":
        """Raise ``CameraError`` (one line) unless the camera defines a proper view; return self."""
        pos, at, up = (_vec3(getattr(self, k), k) for k in ("position", "look_at", "up"))
        check_fov(self.fov_deg)
        view = at - pos
        scale = max(np.abs(pos).max(), np.abs(at).max(), 1e-30)
        if np.linalg.norm(view) <= 1e-9 * scale:
            raise CameraError(f"camera position and look_at are the same point {fmt_vec(pos)}")
        if np.linalg.norm(up) == 0.0:
            raise CameraError("camera up vector is zero")
        f = view / np.linalg.norm(view)
        if np.linalg.norm(np.cross(f, up / np.linalg.norm(up))) < 1e-6:
            raise CameraError(f"camera up {fmt_vec(up)} is parallel to the view direction")
        if np.abs(pos).max() > F32_MAX:
            raise CameraError(f"camera position {fmt_vec(pos)} is beyond the float32 range of "
                              "the datapath (scene coordinates too large: scale the mesh down)")
        return self

    def basis(self):
        """(forward, right, up) unit vectors, float64: right-handed, ``up`` orthogonalised."""
        self.validate()
        pos, at, up = (np.asarray(v, np.float64) for v in (self.position, self.look_at, self.up))
        f = (at - pos) / np.linalg.norm(at - pos)
        r = np.cross(f, up)
        r /= np.linalg.norm(r)
        return f, r, np.cross(r, f)


def check_fov(fov_deg) -> float:
    """A vertical field of view in (0, 180) degrees, as a float; one-line CameraError if not."""
    fov = _number(fov_deg, "fov_deg")
    if not 0.0 < fov < 180.0:
        raise CameraError(f"camera fov_deg must be in (0, 180) degrees, got {fov:g}")
    return fov


def check_size(width, height) -> tuple[int, int]:
    """Validate an image size: integers in 1..8192. Returns (width, height) as ints."""
    out = []
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            if isinstance(v, (float, np.floating)) and float(v).is_integer():
                v = int(v)
            else:
                raise CameraError(f"image {name} must be an integer, got {v!r}")
        if not 1 <= v <= MAX_SIZE:
            raise CameraError(f"image {name} must be in 1..{MAX_SIZE}, got {v}")
        out.append(int(v))
    return out[0], out[1]


def primary_rays(camera: Camera, width: int, height: int):
    """One ray per pixel centre.

    Returns origins (n, 3) float32 (all the camera position) and unit directions (n, 3) float32,
    n = width * height, pixel (row i, column j) at index i * width + j, row 0 at the top.
    """
    width, height = check_size(width, height)
    f, r, u = camera.basis()
    half = math.tan(math.radians(float(camera.fov_deg)) / 2)
    xs = (2 * (np.arange(width) + 0.5) / width - 1) * half * (width / height)
    ys = (1 - 2 * (np.arange(height) + 0.5) / height) * half
    d = f + xs[None, :, None] * r + ys[:, None, None] * u          # (h, w, 3) float64
    d = (d / np.linalg.norm(d, axis=2, keepdims=True)).reshape(-1, 3).astype(np.float32)
    o = np.broadcast_to(np.asarray(camera.position, np.float32), d.shape).copy()
    return o, d


def frame(points, up=(0.0, 0.0, 1.0), towards=(1.0, -1.6, 0.7), fov_deg: float = 40.0,
          fill: float = 0.6) -> Camera:
    """A camera looking at the bounding-box centre of ``points`` ((k, 3), e.g. mesh vertices) from
    direction ``towards`` (given for a z-up world and rotated to ``up``), far enough that the
    points' bounding sphere about that centre spans about ``fill`` of the image height."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    centre = (pts.min(0) + pts.max(0)) / 2
    radius = max(float(np.linalg.norm(pts - centre, axis=1).max()), 1e-12)
    towards = np.asarray(towards, np.float64)
    up = np.asarray(up, np.float64)
    z = np.array([0.0, 0.0, 1.0])
    if not np.allclose(up / np.linalg.norm(up), z):
        towards = _rotation(z, up / np.linalg.norm(up)) @ towards
    towards /= np.linalg.norm(towards)
    dist = radius / (fill * math.tan(math.radians(fov_deg) / 2))
    pos = centre + dist * towards
    return Camera(tuple(pos.tolist()), tuple(centre.tolist()), tuple(up.tolist()), fov_deg)


def _rotation(a, b):
    """Rotation matrix taking unit vector a onto unit vector b (Rodrigues)."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1 + 1e-12:                                             # opposite: turn about x
        return np.diag([1.0, -1.0, -1.0])
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def _vec3(v, name) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise CameraError(f"camera {name} must be 3 numbers, got {v!r}") from None
    if a.shape != (3,):
        raise CameraError(f"camera {name} must be 3 numbers, got {v!r}")
    if not np.isfinite(a).all():
        raise CameraError(f"camera {name} must be finite, got {fmt_vec(a)}")
    return a


def _number(v, name) -> float:
    if isinstance(v, bool):
        raise CameraError(f"camera {name} must be a number, got {v!r}")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise CameraError(f"camera {name} must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise CameraError(f"camera {name} must be finite, got {x}")
    return x


def camera_rays(camera: Camera, width: int, height: int, pixels, jx=0.5, jy=0.5):
    """Rays through points of pixels: pixel index p = row * width + column (row 0 at the top), at
    offset (jx, jy) in [0, 1)^2 inside the pixel (0.5, 0.5 = the centre, as ``primary_rays``).
    Returns origins (k, 3) float32 and unit directions (k, 3) float32."""
    width, height = check_size(width, height)
    f, r, u = camera.basis()
    half = math.tan(math.radians(float(camera.fov_deg)) / 2)
    p = np.asarray(pixels, np.int64).reshape(-1)
    col, row = p % width, p // width
    xs = (2 * (col + np.broadcast_to(jx, p.shape)) / width - 1) * half * (width / height)
    ys = (1 - 2 * (row + np.broadcast_to(jy, p.shape)) / height) * half
    d = f + xs[:, None] * r + ys[:, None] * u
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    o = np.broadcast_to(np.asarray(camera.position, np.float32), d.shape).copy()
    return o, d


def parse_vec3(text: str | None, flag: str) -> tuple | None:
    """A command-line vector ``X,Y,Z`` as 3 finite floats (None stays None); one-line
    CameraError otherwise."""
    if text is None:
        return None
    parts = str(text).split(",")
    try:
        v = tuple(float(x) for x in parts)
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise CameraError(f"{flag} must be three finite numbers X,Y,Z, got {text!r}")
    return v


def parse_number(text: str | None, flag: str) -> float | None:
    """A finite command-line number (None stays None); one-line CameraError otherwise."""
    if text is None:
        return None
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise CameraError(f"{flag} must be a finite number, got {text!r}")
    return x
