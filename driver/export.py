"""Request-stream export: a frame's datapath requests, in issue order, with the golden model's
responses, for testing another datapath (your own RTL) on the same work as RayFlex's.

``export(scene, width, height, ...)`` traces the frame on the golden model, recording every
request (``driver.tracer.trace(record=True)``), and streams it to any of:

- an **NPZ** file (``NpzSink``, ``rayflex render --dump-requests PATH.npz``), read with
  ``numpy.load``; arrays, one row per request:

  ``requests``  ``driver.REQUEST_DTYPE``, the request as the datapath received it (its ``tag`` is
                the ray's index within its wavefront, as issued);
  ``responses`` ``driver.RESPONSE_DTYPE``, the golden model's response;
  ``ray``       int64, the frame-wide ray index (rays numbered wavefront by wavefront in issue
                order);
  ``pixel``     int64, the pixel of that ray (row * width + column);
  ``ray_type``  str, the ray type (primary, shadow, ao, bounce1, ...);
  ``format_version`` a 0-d int64 array, ``FORMAT_VERSION``.

- **hex** files for ``$readmemh`` test benches (``HexSink``, ``--dump-hex DIR``):
  ``DIR/requests.hex`` and ``DIR/responses.hex``, one request (response) per line, and
  ``DIR/format.txt``, the bit position of every field (``hex_format``, generated from
  ``driver.core.wire``). A line is the packed ``rf_pkg::req_t`` (``rsp_t``) as one hexadecimal
  number of ``8 * REQ_WORDS`` (``8 * RSP_WORDS``) digits, most significant digit first: bit ``b``
  of that number is bit ``b`` of the struct, i.e. word ``w`` of ``driver.core.wire``'s
  little-endian word array is bits ``32w + 31 .. 32w``. ``decode_hex`` reads a line back.

- a **VCD** waveform (``write_vcd``, ``--vcd PATH --vcd-window FIRST:COUNT``): requests
  ``FIRST .. FIRST + COUNT - 1`` of the stream run back to back through the Verilated RTL on the
  cycle-by-cycle "pyverilator" backend, which writes every signal of the datapath; its responses
  are checked bit for bit against the golden ones.

Issue order: the frame is traced tile by tile (tiles row-major, as ``driver.tiles`` renders
them), within a tile one wavefront per ray type and bounce (``driver.workloads``), within a
wavefront traversal step by step with the rays in index order (``driver.tracing.issue``). Every
ray's own requests (its chain) do not depend on this order (``driver.rtunit``). Memory stays
bounded: one tile's record at a time; the NPZ is assembled from per-array temporary files at the
end.
"""

from __future__ import annotations

import binascii
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import backends
from .backends import resolve
from .bvh4 import build_scene
from .core.wire import REQUEST, REQUEST_DTYPE, RESPONSE, RESPONSE_DTYPE, Wire, unpack_responses
from .tiles import DEFAULT_TILE, plan
from .tracer import trace
from .workloads import run, setup_for

FORMAT_VERSION = 1
HEX_FILES = {"requests": "requests.hex", "responses": "responses.hex", "format": "format.txt"}
CHUNK = 1 << 16          # requests expanded to REQUEST_DTYPE at a time (324 bytes each)
MAX_VCD_REQUESTS = 100_000


@dataclass
class Chunk:
    """Consecutive requests of one wavefront, in issue order."""

    kind: str
    requests: np.ndarray           # REQUEST_DTYPE
    responses: np.ndarray          # RESPONSE_DTYPE
    ray: np.ndarray                # int64 frame-wide ray index
    pixel: np.ndarray              # int64


def stream(scene, width: int, height: int, workload: str = "primary", options: dict | None = None,
           tile: int | None = None, fill: int = 0, cull_stack: bool = False,
           backend="golden", progress=None, bvh_format: str = "box32"):
    """Yield the frame's requests as ``Chunk``s in issue order (see the module docstring), traced
    on ``backend`` (default the golden model). ``tile``: the tile size (default
    ``driver.tiles.DEFAULT_TILE``); ``options``: spp, bounces, ao_rays, seed;
    ``progress(done_tiles, total_tiles)``."""

    be = resolve(backend)[0]
    bvh = build_scene(scene, fill=fill, format=bvh_format)
    setup = setup_for(scene)
    tiles = plan(width, height, tile or DEFAULT_TILE)

    def tracer(bvh_, o, d, **kw):
        return trace(bvh_, o, d, backend=be, cull_stack=cull_stack, record=True, **kw)

    first_ray = 0
    for i, pixels in enumerate(tiles):
        res = run(setup, bvh, width, height, tracer, workload, pixels=pixels,
                  **(options or {}))
        for batch in res.batches:
            rec = batch.result.record
            batch.result = None                       # drop the batch's record once streamed
            # the ray of each request: its chain (a ray that enters an instance continues on
            # another row of the ray table, which rec.ray names)
            rays = rec.ray if rec.chain is None else rec.chain
            for lo in range(0, rec.ops, CHUNK):
                idx = np.arange(lo, min(lo + CHUNK, rec.ops))
                ray = rays[idx].astype(np.int64)
                yield Chunk(batch.kind, rec.requests(idx), unpack_responses(rec.responses[idx]),
                            first_ray + ray, batch.pixel[ray].astype(np.int64))
            first_ray += len(batch.pixel)
        if progress:
            progress(i + 1, len(tiles))


class NpzSink:
    """Writes the stream as an NPZ (module docstring) with bounded memory: each array goes to a
    raw temporary file beside the target while the frame runs; ``close`` writes the archive."""

    ARRAYS = {"requests": REQUEST_DTYPE, "responses": RESPONSE_DTYPE,
              "ray": np.dtype(np.int64), "pixel": np.dtype(np.int64)}

    def __init__(self, path):
        self.path = Path(path)
        self.tmp = Path(tempfile.mkdtemp(prefix=".rayflex-dump-", dir=self.path.parent))
        self.files = {k: open(self.tmp / k, "wb") for k in self.ARRAYS}
        self.kinds: list[str] = []
        self.kind_file = open(self.tmp / "kind", "wb")
        self.count = 0

    def add(self, c: Chunk) -> None:
        for k in self.ARRAYS:
            self.files[k].write(np.ascontiguousarray(getattr(c, k)).tobytes())
        if c.kind not in self.kinds:
            self.kinds.append(c.kind)
        code = np.full(len(c.ray), self.kinds.index(c.kind), np.uint8)
        self.kind_file.write(code.tobytes())
        self.count += len(c.ray)

    def close(self) -> None:
        for f in (*self.files.values(), self.kind_file):
            f.close()
        width = max((len(k) for k in self.kinds), default=1)
        names = np.array(self.kinds or [""], dtype=f"<U{width}")
        try:
            with zipfile.ZipFile(self.path, "w", zipfile.ZIP_DEFLATED, compresslevel=1,
                                 allowZip64=True) as z:
                for k, dtype in self.ARRAYS.items():
                    with open(self.tmp / k, "rb") as src:
                        _npy_member(z, k, dtype, (self.count,), _blocks(src, dtype))
                with open(self.tmp / "kind", "rb") as src:
                    _npy_member(z, "ray_type", names.dtype, (self.count,),
                                (names[np.frombuffer(b, np.uint8)].tobytes()
                                 for b in iter(lambda: src.read(CHUNK), b"")))
                _npy_member(z, "format_version", np.dtype(np.int64), (),
                            [np.int64(FORMAT_VERSION).tobytes()])
        finally:
            self.discard()

    def discard(self) -> None:
        for f in (*self.files.values(), self.kind_file):
            f.close()
        shutil.rmtree(self.tmp, ignore_errors=True)


def _blocks(src, dtype: np.dtype, rows: int = CHUNK):
    return iter(lambda: src.read(rows * dtype.itemsize), b"")


def _npy_member(z: zipfile.ZipFile, name: str, dtype: np.dtype, shape: tuple, blocks) -> None:
    """One ``name.npy`` member of an NPZ, its data streamed from ``blocks`` (bytes)."""
    with z.open(f"{name}.npy", "w", force_zip64=True) as f:
        np.lib.format.write_array_header_2_0(f, {"descr": np.lib.format.dtype_to_descr(dtype),
                                                 "fortran_order": False, "shape": shape})
        for b in blocks:
            f.write(b)


def load(path) -> dict:
    """An NPZ written by ``NpzSink`` as a dict of arrays (checks ``format_version``)."""
    with np.load(path, allow_pickle=False) as z:
        out = {k: z[k] for k in z.files}
    version = int(out.get("format_version", -1))
    if version != FORMAT_VERSION:
        raise ValueError(f"{path}: request dump format {version}, this version reads "
                         f"{FORMAT_VERSION}")
    return out


# ---------------------------------------------------------------------------------------------
# hex

def hex_lines(words: np.ndarray) -> bytes:
    """(n, k) uint32 little-endian words -> n lines of 8k hex digits, most significant first."""
    words = np.ascontiguousarray(words, np.uint32)
    n, k = words.shape
    digits = np.frombuffer(binascii.hexlify(words[:, ::-1].astype(">u4").tobytes()), np.uint8)
    out = np.empty((n, 8 * k + 1), np.uint8)
    out[:, :-1] = digits.reshape(n, 8 * k)
    out[:, -1] = ord("\n")
    return out.tobytes()


def decode_hex(line: str, wire: Wire = REQUEST) -> np.ndarray:
    """One line of ``requests.hex`` (or, with ``wire=RESPONSE``, ``responses.hex``) as a
    one-row array of the wire's dtype."""
    text = line.strip()
    if len(text) != 8 * wire.words:
        raise ValueError(f"a {wire.name} line has {8 * wire.words} hex digits, got {len(text)}")
    words = np.frombuffer(int(text, 16).to_bytes(4 * wire.words, "little"), "<u4")
    return wire.unpack(words.reshape(1, -1))


def hex_format(npz: str | None = None) -> str:
    """The text of ``format.txt``: the line format and every field's bits, from the wire table
    (``driver.core.wire``); ``npz``: the NPZ of the same stream (``--dump-requests``), as the
    folder of ``format.txt`` reaches it, or None when none is written with it."""
    where = (f"{npz} (--dump-requests) holds the ray and pixel of each." if npz else
             "the ray and pixel of each are in the NPZ of --dump-requests PATH.npz.")
    out = [f"RayFlex request stream, format {FORMAT_VERSION}",
           "",
           "requests.hex / responses.hex: one request (response) per line, in issue order; the",
           "packed rf_pkg::req_t (rsp_t) as one hexadecimal number, most significant digit first:",
           "bit b of the number is bit b of the struct (32-bit word w = bits 32w+31..32w).",
           "Read with $readmemh into  logic [WIDTH-1:0] mem [0:N-1]  (WIDTH below).",
           "f32 fields are IEEE binary32; array element j of a field starts at lsb + j * width.",
           "Line i of both files belongs together; " + where]
    for wire in (REQUEST, RESPONSE):
        out += ["", f"{wire.sv_type}: {wire.words} words, WIDTH = {32 * wire.words} bits, "
                    f"{8 * wire.words} hex digits",
                f"  {'field':<18} {'bits':>11}  {'width':>5}  {'count':>5}  kind"]
        for f in sorted(wire.fields, key=lambda f: -f.first_bit):
            hi = f.first_bit + f.total_bits - 1
            out.append(f"  {f.sv or f.name:<18} {f'[{hi}:{f.first_bit}]':>11}  {f.bits:>5}  "
                       f"{f.count:>5}  {'f32' if f.kind == 'f32' else 'uint'}")
    return "\n".join(out) + "\n"


class HexSink:
    """Writes ``requests.hex``, ``responses.hex`` and ``format.txt`` (paths given) as the frame
    runs; ``npz``: the NPZ written with them (``hex_format``)."""

    def __init__(self, requests, responses, fmt, npz: str | None = None):
        Path(fmt).write_text(hex_format(npz))
        self.req = open(requests, "wb")
        self.rsp = open(responses, "wb")

    def add(self, c: Chunk) -> None:
        self.req.write(hex_lines(REQUEST.pack(c.requests)))
        self.rsp.write(hex_lines(RESPONSE.pack(c.responses)))

    def close(self) -> None:
        self.req.close()
        self.rsp.close()

    discard = close


class WindowSink:
    """Keeps the requests and responses of stream positions ``first .. first + count - 1``."""

    def __init__(self, first: int, count: int):
        self.first, self.count, self.seen = int(first), int(count), 0
        self.req: list[np.ndarray] = []
        self.rsp: list[np.ndarray] = []

    def add(self, c: Chunk) -> None:
        lo = max(self.first - self.seen, 0)
        hi = min(self.first + self.count - self.seen, len(c.ray))
        if lo < hi:
            self.req.append(c.requests[lo:hi])
            self.rsp.append(c.responses[lo:hi])
        self.seen += len(c.ray)

    @property
    def done(self) -> bool:
        return self.seen >= self.first + self.count

    def window(self) -> tuple[np.ndarray, np.ndarray]:
        if self.first + self.count > self.seen:
            raise ValueError(f"--vcd-window {self.first}:{self.count} ends after the frame's "
                             f"{self.seen:,} requests")
        return np.concatenate(self.req), np.concatenate(self.rsp)

    def close(self) -> None:
        pass

    discard = close


def parse_window(text: str) -> tuple[int, int]:
    """``FIRST:COUNT`` -> (first, count); one-line ValueError if malformed or out of range."""
    first, sep, count = str(text).partition(":")
    try:
        a, b = int(first), int(count)
    except ValueError:
        a = b = -1
    if not sep or a < 0 or not 1 <= b <= MAX_VCD_REQUESTS:
        raise ValueError(f"--vcd-window must be FIRST:COUNT with FIRST >= 0 and COUNT in "
                         f"1..{MAX_VCD_REQUESTS:,}, got {text!r}")
    return a, b


def write_vcd(path, requests: np.ndarray, golden: np.ndarray, backend_options: dict | None = None):
    """Run ``requests`` back to back through the RTL on the "pyverilator" backend, writing the
    waveform of every datapath signal to ``path``; the responses must equal ``golden`` bit for
    bit (RuntimeError otherwise). Returns the cycles of the run."""
    be = backends.backend("pyverilator", vcd=os.fspath(path), **(backend_options or {}))
    rsp = be.run(requests)
    if not np.array_equal(RESPONSE.pack(rsp), RESPONSE.pack(golden)):
        bad = int(np.flatnonzero((RESPONSE.pack(rsp) != RESPONSE.pack(golden)).any(1))[0])
        raise RuntimeError(f"the RTL's response to request {bad} of the VCD window differs from "
                           "the golden model's")
    return int(be.cycles)


def export(scene, width: int, height: int, sinks: list, workload: str = "primary",
           options: dict | None = None, tile: int | None = None, fill: int = 0,
           cull_stack: bool = False, progress=None, bvh_format: str = "box32") -> int:
    """Trace the frame on the golden model and feed every ``Chunk`` to each sink (``add``),
    stopping early once every sink says it is ``done``; ``close`` each at the end (``discard`` on
    an error). Returns the number of requests streamed."""
    n = 0
    try:
        for c in stream(scene, width, height, workload, options, tile, fill, cull_stack,
                        progress=progress, bvh_format=bvh_format):
            for s in sinks:
                s.add(c)
            n += len(c.ray)
            if all(getattr(s, "done", False) for s in sinks):
                break                       # e.g. only a VCD window, and it is complete
    except BaseException:
        for s in sinks:
            s.discard()
        raise
    for s in sinks:
        s.close()
    return n
