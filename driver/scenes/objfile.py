"""Wavefront OBJ and MTL files read as LumiBench's application reads them (docs/lumibench.md).

``read_obj(path)`` returns an ``ObjModel``: its triangles (float32, in the file's face order,
each polygon triangulated where it stands), the material of every triangle, the MTL files it
names and their diffuse colours. The rules are those of tinyobjloader, which the benchmark's
application uses:

- vertices ``v x y z`` (extra numbers, a ``w`` or a colour, are ignored); face indices are
  1-based, negative ones count back from the last vertex read (``-1`` = the latest); ``vt`` and
  ``vn`` parts of a face corner (``i/j/k``, ``i//k``) are read past;
- a quad is split along its shorter diagonal (squared lengths in float32: ``[0, 1, 2], [0, 2, 3]``
  when ``|v2 - v0|^2 < |v3 - v1|^2``, else ``[0, 1, 3], [1, 2, 3]``); a polygon of 5 or more
  corners is cut as a fan from its first corner (tinyobjloader clips ears; such polygons are
  rare in the benchmark's scenes: 62 of 535,067 faces); faces of fewer than 3 corners, lines
  (``l``) and points (``p``) are not triangles and are skipped;
- materials: every ``mtllib`` file (relative to the OBJ) in order, each ``newmtl`` a material
  with its ``Kd`` diffuse colour (black when it has none); a face takes the material of the last
  ``usemtl`` before it; a face before any ``usemtl``, or whose ``usemtl`` names no material, takes
  the first material; an OBJ with no material at all is grey 0.7 (``DEFAULT_DIFFUSE``).

Why hand-written: trimesh's OBJ loader merges and regroups faces by material (so primitive ids
are no longer the file's face order), triangulates quads as a fan, and takes about a minute for
the 981 files of LumiBench's Spring scene; this reader scans the bytes in a numba kernel that
releases the GIL, so a folder of files is read on all cores by threads. Numbers are parsed
exactly when they have at most 15 significant digits and a decimal exponent of at most 22 (the
digits as an integer, then one correctly rounded division or multiplication by a power of ten,
then float32, as tinyobjloader parses a double and stores a float); any other number (more
digits, a larger exponent) is parsed by Python's ``float``. A malformed file is a one-line
``SceneError`` naming the file and line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

from ..core.errors import SceneError

DEFAULT_DIFFUSE = (0.7, 0.7, 0.7)     # the benchmark's colour of a model without materials

# kernel status codes (line numbers are reported with them)
_OK, _BAD_INDEX, _ZERO_INDEX, _BAD_NUMBER, _FEW_NUMBERS = 0, 1, 2, 3, 4
_ERRORS = {_BAD_INDEX: "a face corner is not an integer vertex index",
           _ZERO_INDEX: "a face corner has vertex index 0 (OBJ indices start at 1)",
           _BAD_NUMBER: "a vertex coordinate is not a number",
           _FEW_NUMBERS: "a vertex has fewer than 3 coordinates"}
_POW10 = np.array([10.0 ** k for k in range(23)])      # exact in float64


@dataclass
class ObjModel:
    """One OBJ file: ``triangles`` (m, 3, 3) float32 in face order; ``material`` (m,) int32,
    the index into ``diffuse`` of each triangle; ``diffuse`` (k, 3) float32 colours of the
    materials (``DEFAULT_DIFFUSE`` alone when the file has none); ``material_names`` (k,);
    ``mtllib`` the MTL files the OBJ names (paths), ``missing`` those that do not exist."""

    path: Path
    triangles: np.ndarray
    material: np.ndarray
    diffuse: np.ndarray
    material_names: list = field(default_factory=list)
    mtllib: list = field(default_factory=list)
    missing: list = field(default_factory=list)

    @property
    def albedo(self) -> np.ndarray:
        """(m, 3) float32 diffuse colour of every triangle."""
        return self.diffuse[self.material]


@njit(cache=True, nogil=True, inline="always")
def _is_space(c) -> bool:
    return c == 32 or c == 9 or c == 13 or c == 11 or c == 12


@njit(cache=True, nogil=True)
def _parse_float(buf, i, end, pow10):
    """(value, next index, status): 0 exact, 1 needs Python's float, 2 not a number."""
    neg = False
    if i < end and (buf[i] == 45 or buf[i] == 43):
        neg = buf[i] == 45
        i += 1
    mant = 0
    digits = 0              # significant digits kept in mant
    scale = 0               # decimal exponent of mant's last digit
    seen = False
    while i < end and 48 <= buf[i] <= 57:
        seen = True
        if mant != 0 or buf[i] != 48:
            if digits < 18:
                mant = mant * 10 + (buf[i] - 48)
                digits += 1
            else:
                scale += 1
                digits += 1
        i += 1
    if i < end and buf[i] == 46:
        i += 1
        while i < end and 48 <= buf[i] <= 57:
            seen = True
            if mant != 0 or buf[i] != 48:
                if digits < 18:
                    mant = mant * 10 + (buf[i] - 48)
                    scale -= 1
                digits += 1
            else:
                scale -= 1
            i += 1
    if not seen:
        return 0.0, i, 2
    if i < end and (buf[i] == 101 or buf[i] == 69):
        j = i + 1
        eneg = False
        if j < end and (buf[j] == 45 or buf[j] == 43):
            eneg = buf[j] == 45
            j += 1
        e = 0
        eseen = False
        while j < end and 48 <= buf[j] <= 57:
            eseen = True
            if e < 100000:
                e = e * 10 + (buf[j] - 48)
            j += 1
        if not eseen:
            return 0.0, j, 2
        scale += -e if eneg else e
        i = j
    if i < end and not _is_space(buf[i]):
        return 0.0, i, 2
    status = 0
    if mant == 0:
        v = 0.0
    elif digits > 15 or scale > 22 or scale < -22:
        v = 0.0
        status = 1
    elif scale >= 0:
        v = float(mant) * pow10[scale]
    else:
        v = float(mant) / pow10[-scale]
    return (-v if neg else v), i, status


@njit(cache=True, nogil=True)
def _scan(buf, pow10):
    """One pass over an OBJ file's bytes. Returns (status, line of the error, vertices (nv, 3)
    float64, slow (nv,) bool: vertices to parse again in Python, vertex line spans (nv, 2),
    corners (total,) int64 0-based vertex indices, polygon starts (np + 1,), polygon material
    segment (np,) (the number of ``usemtl`` lines before it, -1 before the first), usemtl name
    spans (nu, 2), mtllib line spans (nl, 2))."""
    n = len(buf)
    lines = 1
    for k in range(n):
        if buf[k] == 10:
            lines += 1
    verts = np.empty((lines, 3), np.float64)
    slow = np.zeros(lines, np.bool_)
    vspan = np.empty((lines, 2), np.int64)
    corners = np.empty(n // 2 + 1, np.int64)
    pstart = np.empty(lines + 1, np.int64)
    pseg = np.empty(lines, np.int64)
    uspan = np.empty((lines, 2), np.int64)
    lspan = np.empty((lines, 2), np.int64)
    nv = 0
    nc = 0
    npoly = 0
    nu = 0
    nl = 0
    i = 0
    line = 0
    while i < n:
        line += 1
        end = i
        while end < n and buf[end] != 10:
            end += 1
        j = i
        while j < end and _is_space(buf[j]):
            j += 1
        if j + 1 < end and buf[j] == 118 and _is_space(buf[j + 1]):          # "v "
            vspan[nv, 0] = j + 1
            vspan[nv, 1] = end
            k = j + 1
            for c in range(3):
                while k < end and _is_space(buf[k]):
                    k += 1
                if k >= end:
                    return _FEW_NUMBERS, line, verts, slow, vspan, corners, pstart, pseg, \
                        uspan, lspan, nv, nc, npoly, nu, nl
                v, k, st = _parse_float(buf, k, end, pow10)
                if st == 2:
                    return _BAD_NUMBER, line, verts, slow, vspan, corners, pstart, pseg, \
                        uspan, lspan, nv, nc, npoly, nu, nl
                if st == 1:
                    slow[nv] = True
                verts[nv, c] = v
            nv += 1
        elif j + 1 < end and buf[j] == 102 and _is_space(buf[j + 1]):        # "f "
            start = nc
            k = j + 1
            while True:
                while k < end and _is_space(buf[k]):
                    k += 1
                if k >= end:
                    break
                neg = False
                if buf[k] == 45:
                    neg = True
                    k += 1
                elif buf[k] == 43:
                    k += 1
                val = 0
                seen = False
                while k < end and 48 <= buf[k] <= 57:
                    seen = True
                    if val < 1 << 40:
                        val = val * 10 + (buf[k] - 48)
                    k += 1
                if not seen or (k < end and not _is_space(buf[k]) and buf[k] != 47):
                    return _BAD_INDEX, line, verts, slow, vspan, corners, pstart, pseg, \
                        uspan, lspan, nv, nc, npoly, nu, nl
                if val == 0:
                    return _ZERO_INDEX, line, verts, slow, vspan, corners, pstart, pseg, \
                        uspan, lspan, nv, nc, npoly, nu, nl
                corners[nc] = nv - val if neg else val - 1
                nc += 1
                while k < end and not _is_space(buf[k]):                    # /vt/vn
                    k += 1
            if nc - start >= 3:
                pstart[npoly] = start
                pseg[npoly] = nu - 1
                npoly += 1
            else:
                nc = start
        elif end - j > 7 and buf[j] == 117 and buf[j + 1] == 115 and buf[j + 2] == 101 \
                and buf[j + 3] == 109 and buf[j + 4] == 116 and buf[j + 5] == 108 \
                and _is_space(buf[j + 6]):                                   # "usemtl "
            uspan[nu, 0] = j + 7
            uspan[nu, 1] = end
            nu += 1
        elif end - j > 7 and buf[j] == 109 and buf[j + 1] == 116 and buf[j + 2] == 108 \
                and buf[j + 3] == 108 and buf[j + 4] == 105 and buf[j + 5] == 98 \
                and _is_space(buf[j + 6]):                                   # "mtllib "
            lspan[nl, 0] = j + 7
            lspan[nl, 1] = end
            nl += 1
        i = end + 1
    pstart[npoly] = nc
    return _OK, 0, verts, slow, vspan, corners, pstart, pseg, uspan, lspan, nv, nc, npoly, nu, nl


def _triangulate(pos: np.ndarray, corners: np.ndarray, pstart: np.ndarray):
    """(tri (m, 3) vertex indices, poly (m,) the polygon of each triangle), in polygon order."""
    count = np.diff(pstart)
    first = pstart[:-1]
    ntri = np.where(count == 4, 2, count - 2)
    poly = np.repeat(np.arange(len(count)), ntri)
    k = np.arange(len(poly)) - np.repeat(np.cumsum(ntri) - ntri, ntri)   # triangle within poly
    base = first[poly]
    # fan: (0, k + 1, k + 2)
    tri = np.stack([corners[base], corners[base + k + 1], corners[base + k + 2]], axis=1)
    quads = np.flatnonzero(count == 4)
    if len(quads):
        c = corners[first[quads][:, None] + np.arange(4)]                    # (q, 4)
        p = pos[c]
        d02 = p[:, 2] - p[:, 0]
        d13 = p[:, 3] - p[:, 1]
        short02 = (np.einsum("ij,ij->i", d02, d02, dtype=np.float32)
                   < np.einsum("ij,ij->i", d13, d13, dtype=np.float32))
        rows = np.flatnonzero(count[poly] == 4)
        t0, t1 = rows[k[rows] == 0], rows[k[rows] == 1]
        tri[t0] = np.where(short02[:, None], c[:, [0, 1, 2]], c[:, [0, 1, 3]])
        tri[t1] = np.where(short02[:, None], c[:, [0, 2, 3]], c[:, [1, 2, 3]])
    return tri, poly


def read_mtl(path: Path) -> list[tuple[str, tuple]]:
    """(name, Kd) of every ``newmtl`` of an MTL file, in order (Kd black when not given)."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise SceneError(f"cannot read {path}: {e.strerror}") from None
    out: list = []
    for number, raw in enumerate(text.splitlines(), 1):
        parts = raw.split()
        if not parts:
            continue
        if parts[0] == "newmtl":
            out.append([" ".join(parts[1:]), (0.0, 0.0, 0.0)])
        elif parts[0] == "Kd" and out:
            try:
                kd = tuple(float(x) for x in parts[1:4])
            except ValueError:
                kd = ()
            if len(kd) != 3:
                raise SceneError(f"{path}:{number}: Kd needs three numbers, got {raw.strip()!r}")
            out[-1][1] = kd
    return [(n, kd) for n, kd in out]


def read_obj(path) -> ObjModel:
    """Read one OBJ file (module docstring). SceneError (one line) for an unreadable or
    malformed file; MTL files it names that do not exist are listed in ``missing``."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SceneError(f"cannot read {path}: {e.strerror}") from None
    buf = np.frombuffer(data, np.uint8)
    (status, line, verts, slow, vspan, corners, pstart, pseg, uspan, lspan,
     nv, nc, npoly, nu, nl) = _scan(buf, _POW10)
    if status != _OK:
        raise SceneError(f"{path}:{line}: {_ERRORS[status]}")
    verts = verts[:nv]
    for r in np.flatnonzero(slow[:nv]):                  # numbers beyond the exact fast path
        verts[r] = [float(x) for x in data[vspan[r, 0]:vspan[r, 1]].split()[:3]]
    with np.errstate(over="ignore"):
        pos = verts.astype(np.float32)
    if not np.isfinite(pos).all():
        r = int(np.flatnonzero(~np.isfinite(pos).all(1))[0])
        raise SceneError(f"{path}: vertex {r + 1} is not finite in float32")
    corners = corners[:nc]
    pstart = pstart[:npoly + 1]
    if nc and (corners.min() < 0 or corners.max() >= nv):
        bad = int(np.flatnonzero((corners < 0) | (corners >= nv))[0])
        poly = int(np.searchsorted(pstart, bad, side="right") - 1)
        raise SceneError(f"{path}: face {poly + 1} names a vertex outside the {nv} read before it")
    text = lambda s: data[s[0]:s[1]].decode("utf-8", "replace").strip()  # noqa: E731
    libs = [path.parent / name for s in lspan[:nl] for name in text(s).split()]
    materials: list = []
    missing = []
    for lib in libs:
        if lib.is_file():
            materials += read_mtl(lib)
        else:
            missing.append(lib)
    names = [m[0] for m in materials]
    if materials:
        diffuse = np.array([m[1] for m in materials], np.float32)
        index = {}
        for i, n in enumerate(names):
            index.setdefault(n, i)
        seg_mat = np.array([index.get(text(s), 0) for s in uspan[:nu]] + [0], np.int32)
    else:
        diffuse = np.array([DEFAULT_DIFFUSE], np.float32)
        names = ["(default)"]
        seg_mat = np.zeros(nu + 1, np.int32)
    tri, poly = _triangulate(pos, corners, pstart)
    material = seg_mat[pseg[:npoly][poly]]      # segment -1 (before any usemtl) -> the last
    material = np.where(pseg[:npoly][poly] < 0, 0, material).astype(np.int32)
    return ObjModel(path, pos[tri], material, diffuse, names, libs, missing)
