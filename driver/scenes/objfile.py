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
from typing import NamedTuple

import numpy as np
from numba import njit

from ..core.errors import SceneError
from ..core.words import plural

DEFAULT_DIFFUSE = (0.7, 0.7, 0.7)     # the benchmark's colour of a model without materials

# kernel status codes, each reported with its line, face and the text at fault (``_problem``)
_OK, _BAD_INDEX, _ZERO_INDEX, _BAD_NUMBER, _FEW_NUMBERS, _BEFORE_FIRST = 0, 1, 2, 3, 4, 5
_ERRORS = {_BAD_INDEX: "face {face}: {token!r} is not a vertex index",
           _ZERO_INDEX: "face {face}: vertex index 0 (OBJ indices start at 1)",
           _BAD_NUMBER: "vertex {vertex}: coordinate {token!r} is not a number",
           _FEW_NUMBERS: "vertex {vertex} has {token}; a vertex needs 3 (x y z)",
           _BEFORE_FIRST: "face {face}: vertex index {token} counts back past the first vertex "
                          "({read} read before it)"}
# the scan's counters (an int64 array the kernels update) and its error record
# (_NF: "f" lines read; _SHORT: the line, face number and corners of the first face of fewer
# than 3 corners, line 0 when there is none)
_NV, _NC, _NPOLY, _NU, _NL, _NF, _SHORT, _SHORT_FACE, _SHORT_CORNERS = range(9)
_STATUS, _LINE, _FACE, _TOKEN0, _TOKEN1 = range(5)
_V, _F, _USEMTL, _MTLLIB = (np.frombuffer(w, np.uint8) for w in (b"v", b"f", b"usemtl",
                                                                  b"mtllib"))
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
def _scan_vertex(buf, k, end, pow10, verts, slow, n, err):
    """Read a ``v`` line's three coordinates from ``k`` into vertex ``n``; False (and ``err``)
    when they are not three numbers (what follows them is ignored)."""
    for c in range(3):
        while k < end and _is_space(buf[k]):
            k += 1
        if k >= end:
            err[_STATUS], err[_TOKEN0] = _FEW_NUMBERS, c
            return False
        v, k2, st = _parse_float(buf, k, end, pow10)
        if st == 2:
            while k2 < end and not _is_space(buf[k2]):
                k2 += 1
            err[_STATUS], err[_TOKEN0], err[_TOKEN1] = _BAD_NUMBER, k, k2
            return False
        if st == 1:
            slow[n] = True
        verts[n, c] = v
        k = k2
    return True


@njit(cache=True, nogil=True)
def _scan_face(buf, k, end, corners, cnt, err):
    """Read an ``f`` line's corners from ``k`` into ``corners`` (0-based vertex indices; the
    ``/vt/vn`` parts read past): the number of corners read, or -1 (and ``err``) at a corner
    that is no vertex index."""
    nv = cnt[_NV]
    n = 0
    while True:
        while k < end and _is_space(buf[k]):
            k += 1
        if k >= end:
            return n
        t0 = k
        neg = buf[k] == 45
        if buf[k] == 45 or buf[k] == 43:
            k += 1
        val = 0
        seen = False
        while k < end and 48 <= buf[k] <= 57:
            seen = True
            if val < 1 << 40:
                val = val * 10 + (buf[k] - 48)
            k += 1
        status = _OK
        if not seen or (k < end and not _is_space(buf[k]) and buf[k] != 47):
            status = _BAD_INDEX
        elif val == 0:
            status = _ZERO_INDEX
        elif neg and val > nv:
            status = _BEFORE_FIRST
        while k < end and not _is_space(buf[k]):                            # /vt/vn
            k += 1
        if status != _OK:
            err[_STATUS], err[_TOKEN0], err[_TOKEN1] = status, t0, k
            return -1
        corners[cnt[_NC] + n] = nv - val if neg else val - 1
        n += 1


@njit(cache=True, nogil=True, inline="always")
def _starts(buf, j, end, word) -> bool:
    """The line from ``j`` starts with ``word`` and a space."""
    m = len(word)
    if end - j <= m or not _is_space(buf[j + m]):
        return False
    for q in range(m):
        if buf[j + q] != word[q]:
            return False
    return True


@njit(cache=True, nogil=True)
def _scan(buf, pow10):
    """One pass over an OBJ file's bytes. Returns (err: status, line, face, token span
    (``_STATUS`` ...), cnt: the counters (``_NV`` ...), vertices (nv, 3) float64, slow (nv,)
    bool: vertices to parse again in Python, vertex line spans (nv, 2), corners (total,) int64
    0-based vertex indices, polygon starts (np + 1,), polygon material segment (np,) (the
    number of ``usemtl`` lines before it, -1 before the first), polygon line and face number
    (np, 2), usemtl name spans (nu, 2), mtllib line spans (nl, 2))."""
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
    pline = np.empty((lines, 2), np.int64)
    uspan = np.empty((lines, 2), np.int64)
    lspan = np.empty((lines, 2), np.int64)
    cnt = np.zeros(9, np.int64)
    err = np.zeros(5, np.int64)
    out = (err, cnt, verts, slow, vspan, corners, pstart, pseg, pline, uspan, lspan)
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
        i = end + 1
        err[_LINE] = line
        if _starts(buf, j, end, _V):
            vspan[cnt[_NV], 0] = j + 1
            vspan[cnt[_NV], 1] = end
            if not _scan_vertex(buf, j + 1, end, pow10, verts, slow, cnt[_NV], err):
                return out
            cnt[_NV] += 1
        elif _starts(buf, j, end, _F):
            cnt[_NF] += 1
            err[_FACE] = cnt[_NF]
            got = _scan_face(buf, j + 1, end, corners, cnt, err)
            if got < 0:
                return out
            if got >= 3:
                pstart[cnt[_NPOLY]] = cnt[_NC]
                pseg[cnt[_NPOLY]] = cnt[_NU] - 1
                pline[cnt[_NPOLY], 0] = line
                pline[cnt[_NPOLY], 1] = cnt[_NF]
                cnt[_NPOLY] += 1
                cnt[_NC] += got
            elif cnt[_SHORT] == 0:
                cnt[_SHORT], cnt[_SHORT_FACE], cnt[_SHORT_CORNERS] = line, cnt[_NF], got
        elif _starts(buf, j, end, _USEMTL):
            uspan[cnt[_NU], 0] = j + 7
            uspan[cnt[_NU], 1] = end
            cnt[_NU] += 1
        elif _starts(buf, j, end, _MTLLIB):
            lspan[cnt[_NL], 0] = j + 7
            lspan[cnt[_NL], 1] = end
            cnt[_NL] += 1
    pstart[cnt[_NPOLY]] = cnt[_NC]
    err[_LINE] = 0
    return out


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


class _Scan(NamedTuple):
    """A checked scan of an OBJ file (``scan``): its bytes, float32 vertex positions, corners,
    polygon starts and material segments, usemtl and mtllib spans."""

    data: bytes
    pos: np.ndarray
    corners: np.ndarray
    pstart: np.ndarray
    pseg: np.ndarray
    uspan: np.ndarray
    lspan: np.ndarray


def _problem(path: Path, data: bytes, err, cnt) -> str:
    """The one line of a scan that stopped: file, line and what is wrong in OBJ's terms."""
    status = int(err[_STATUS])
    token = (plural(int(err[_TOKEN0]), "coordinate") if status == _FEW_NUMBERS else
             data[err[_TOKEN0]:err[_TOKEN1]].decode("utf-8", "replace"))
    what = _ERRORS[status].format(face=int(err[_FACE]), vertex=int(cnt[_NV]) + 1,
                                  read=plural(int(cnt[_NV]), "vertex", "vertices"), token=token)
    return f"{path}:{int(err[_LINE])}: {what}"


def scan(path, strict: bool = False) -> _Scan:
    """Read and check an OBJ file: SceneError (one line: the file, the line, the face or vertex
    number and what is wrong) for a coordinate that is no number, a vertex of fewer than 3, a
    face corner that is no vertex index or names no vertex of the file; ``strict``: also for a
    face of fewer than 3 corners (tinyobjloader, and so ``read_obj``, skips such faces)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SceneError(f"cannot read {path}: {e.strerror}") from None
    err, cnt, verts, slow, vspan, corners, pstart, pseg, pline, uspan, lspan = _scan(
        np.frombuffer(data, np.uint8), _POW10)
    if err[_STATUS] != _OK:
        raise SceneError(_problem(path, data, err, cnt))
    if strict and cnt[_SHORT]:
        raise SceneError(f"{path}:{cnt[_SHORT]}: face {cnt[_SHORT_FACE]} has "
                         f"{plural(int(cnt[_SHORT_CORNERS]), 'corner')}; a face needs at least 3")
    nv, nc, npoly = (int(cnt[k]) for k in (_NV, _NC, _NPOLY))
    verts = verts[:nv]
    for r in np.flatnonzero(slow[:nv]):                  # numbers beyond the exact fast path
        verts[r] = [float(x) for x in data[vspan[r, 0]:vspan[r, 1]].split()[:3]]
    with np.errstate(over="ignore"):
        pos = verts.astype(np.float32)
    if not np.isfinite(pos).all():
        r = int(np.flatnonzero(~np.isfinite(pos).all(1))[0])
        raise SceneError(f"{path}: vertex {r + 1} is not finite in float32")
    corners = corners[:nc]
    if nc and corners.max() >= nv:                     # negative ones are checked by the scan
        bad = int(np.flatnonzero(corners >= nv)[0])
        poly = int(np.searchsorted(pstart[:npoly], bad, side="right") - 1)
        line, face = pline[poly]
        raise SceneError(f"{path}:{line}: face {face}: vertex index {corners[bad] + 1} is "
                         f"beyond the file's {plural(nv, 'vertex', 'vertices')}")
    return _Scan(data, pos, corners, pstart[:npoly + 1], pseg[:npoly], uspan[:int(cnt[_NU])],
                 lspan[:int(cnt[_NL])])


def read_obj(path) -> ObjModel:
    """Read one OBJ file (module docstring). SceneError (one line) for an unreadable or
    malformed file (``scan``); MTL files it names that do not exist are listed in
    ``missing``."""
    path = Path(path)
    data, pos, corners, pstart, pseg, uspan, lspan = scan(path)
    text = lambda s: data[s[0]:s[1]].decode("utf-8", "replace").strip()  # noqa: E731
    libs = [path.parent / name for s in lspan for name in text(s).split()]
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
        seg_mat = np.array([index.get(text(s), 0) for s in uspan] + [0], np.int32)
    else:
        diffuse = np.array([DEFAULT_DIFFUSE], np.float32)
        names = ["(default)"]
        seg_mat = np.zeros(len(uspan) + 1, np.int32)
    tri, poly = _triangulate(pos, corners, pstart)
    material = seg_mat[pseg[poly]]              # segment -1 (before any usemtl) -> the last
    material = np.where(pseg[poly] < 0, 0, material).astype(np.int32)
    return ObjModel(path, pos[tri], material, diffuse, names, libs, missing)
