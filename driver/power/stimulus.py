"""Random request streams for the power measurements: one stream per operation type.

The paper measured power on the activity of 100 random tests per operation; these are the
corresponding streams. Each request uses only the fields its opcode reads; every other field is
zero, as in a traversal (the RT-unit harness clears the other operation's operands too), so that
no activity comes from data the operation ignores.

``OPS`` is the one table of measured operation types: the name used in the JSON, the opcode, the
request flags and the build parameter the operation needs (``measurable``: the operations a
configuration runs). An entry whose value is a string is not measurable yet (the reason is
reported instead of a number). A stream's random numbers depend on the seed and the opcode only,
so the variants of one opcode draw the same rays and operands: ``triangle_no_cull`` is the
``triangle`` stream with the NO_CULL flag (docs/datapath.md#flags); ``box_q8`` is the ``box``
stream's rays and boxes with each request's first 1-4 boxes encoded as a q8 node (the QUADBOX
with DECODE_Q8 of a COMPRESSED build, docs/q8_datapath.md), and ``box_q8_host`` the same nodes
decoded on the host (plain QUADBOX requests with the decoded boxes: what a configuration without
the decode receives for a q8 image), so box_q8 and box_q8_host send the same boxes down the
pipeline from stage 1 on and differ only by where the decode runs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.datapath import (ANGULAR, EUCLIDEAN, QUADBOX, TRANSFORM, TRIANGLE, prepare_rays,
                             transform_requests)
from ..bvh4 import q8_request
from ..core.wire import FLAG_DECODE_Q8, FLAG_NO_CULL
from ..core.layout import Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE


class Op(NamedTuple):
    """An operation type: its opcode, request flags, the build parameter it needs (None: every
    configuration runs it), and whether its boxes are q8 nodes (the box stream's, quantized)."""
    opcode: int
    flags: int = 0
    needs: str | None = None
    q8: bool = False


OPS: dict[str, Op | str] = {
    "box": Op(QUADBOX),
    "box_q8": Op(QUADBOX, FLAG_DECODE_Q8, "COMPRESSED", q8=True),   # decoded by the datapath
    "box_q8_host": Op(QUADBOX, q8=True),                            # decoded by the host
    "triangle": Op(TRIANGLE),
    "triangle_no_cull": Op(TRIANGLE, FLAG_NO_CULL),        # the same triangles, both faces
    "euclidean": Op(EUCLIDEAN, needs="EXTENDED"),
    "cosine": Op(ANGULAR, needs="EXTENDED"),
    "transform": Op(TRANSFORM, needs="TRANSFORM"),
}
VECTOR_BEATS = 4          # a 64-dimensional vector is 4 beats of 16 lanes (as in driver/knn.py)


def measurable(params: dict) -> list[str]:
    """The operation names a configuration with build parameters ``params`` (``EXTENDED``,
    ``COMPRESSED``, ``TRANSFORM``: absent means 0) can run."""
    return [n for n, v in OPS.items() if not isinstance(v, str)
            and (v.needs is None or params.get(v.needs))]


def needs(op: str) -> str | None:
    """The build parameter operation ``op`` needs (None: any configuration)."""
    spec = OPS[op]
    return None if isinstance(spec, str) else spec.needs


def box_op(params: dict, q8_image: bool) -> str:
    """The operation a box node of a frame is on a configuration with build parameters
    ``params``: ``box`` for a box32 image; for a q8 image ``box_q8`` where the datapath decodes
    the node (COMPRESSED), else ``box_q8_host`` (the host decodes it, ``bvh4.q8_request``)."""
    if not q8_image:
        return "box"
    return "box_q8" if params.get("COMPRESSED") else "box_q8_host"


def pending() -> dict[str, str]:
    """Operation name -> why it is not measured."""
    return {n: v for n, v in OPS.items() if isinstance(v, str)}


def _rays(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d[np.abs(d).max(axis=1) < 1e-3] = (0, 0, 1)
    return prepare_rays(rng.uniform(-1, 1, (n, 3)), d, extent=rng.uniform(1, 100, n))


def q8_nodes(boxes: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``Q8_NODE`` rows holding the first ``count`` (1-4) of each row's ``boxes`` ((n, 4, 6)
    float32 xmin ymin zmin xmax ymax zmax), quantized as the q8 encoder does (docs/compressed.md,
    ``driver.bvh.q8``): per axis ``origin`` = the float32 minimum of the used lower bounds,
    ``exp`` = the smallest exponent in [Q8_EXP_MIN, Q8_EXP_MAX] with extent <= 255 * 2**exp,
    ``qlo`` = floor, ``qhi`` = ceil; then every bound the decode (a round-to-nearest add) puts
    inside its box moves out by one step (``verify_containment``), so each decoded box contains
    its box."""
    from ..bvh.q8_image import verify_containment
    n = len(boxes)
    used = np.arange(4)[None, :] < count[:, None]                      # (n, 4)
    ref = np.where(used[..., None], boxes, np.float32(np.inf)).astype(np.float32)
    lo = np.where(used[..., None], boxes[..., :3], np.inf).min(axis=1).astype(np.float32)
    hi = np.where(used[..., None], boxes[..., 3:], -np.inf).max(axis=1)
    ext = hi.astype(np.float64) - lo.astype(np.float64)                 # (n, 3)
    with np.errstate(divide="ignore"):
        e = np.ceil(np.log2(np.maximum(ext, 1e-300) / 255.0))
    e = np.clip(e, Q8_EXP_MIN, Q8_EXP_MAX).astype(np.int64)
    e += ext > 255.0 * np.ldexp(1.0, e)                                 # log2's rounding
    e -= (e > Q8_EXP_MIN) & (ext <= 255.0 * np.ldexp(1.0, e - 1))
    if (e > Q8_EXP_MAX).any():
        raise ValueError("q8 stimulus: a node extent needs an exponent above Q8_EXP_MAX")
    s = np.ldexp(1.0, e)[:, None, :]                                    # (n, 1, 3)
    rel = (ref.astype(np.float64) - np.tile(lo, 2)[:, None, :]) / np.tile(s, 2)
    q = np.concatenate([np.floor(rel[..., :3]), np.ceil(rel[..., 3:])], axis=2)
    node = np.zeros(n, Q8_NODE)
    node["origin"] = lo
    node["exp"][:, :3] = (e & 0xFF).astype(np.uint8)
    node["exp"][:, 3] = count
    node["q"] = np.where(used[..., None], np.clip(q, 0, 255), 0).astype(np.uint8)
    verify_containment(node, ref)
    return node


def _boxes(rng: np.random.Generator, req: np.ndarray) -> np.ndarray:
    """(n, 4, 6) random boxes placed near points along each request's ray."""
    n = len(req)
    t = rng.uniform(0.5, 20, (n, 4, 1))
    centre = req["origin"][:, None, :] + t * req["dir"][:, None, :] \
        + rng.normal(scale=0.6, size=(n, 4, 3))
    half = rng.uniform(0.1, 1.0, (n, 4, 3))
    return np.concatenate([centre - half, centre + half], axis=2).astype(np.float32)


def _matrices(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3, 4) random instance transforms: a rotation (QR of a normal matrix, half of them
    mirrored) times a scale in [0.25, 4], and a translation of about 10."""
    rot, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    rot[:, :, 0] *= np.where(rng.random(n) < 0.5, -1.0, 1.0)[:, None]
    scale = np.exp(rng.uniform(np.log(0.25), np.log(4.0), (n, 1, 1)))
    return np.concatenate([rot * scale, rng.normal(scale=10.0, size=(n, 3, 1))], axis=2)


def requests(op: str, n: int, seed=0) -> np.ndarray:
    """``n`` random requests of operation ``op`` (deterministic in ``seed``: an int or a list of
    ints, e.g. [seed, stream]).

    box: a random ray against four random boxes placed near points along it (about half hit);
    box_q8: the same rays and boxes, the first 1-4 of each request (uniform) as a q8 node;
    box_q8_host: those nodes decoded on the host (``bvh4.q8_request``), plain QUADBOX;
    triangle: a random ray against a random triangle placed along the ray (front and back faces);
    euclidean / cosine: random normal vectors, all 16 lanes, jobs of VECTOR_BEATS beats;
    transform: a random ray through a random rotation, scale and translation."""
    spec = OPS.get(op)
    if spec is None:
        raise ValueError(f"unknown operation {op!r}; choose from {', '.join(OPS)}")
    if isinstance(spec, str):
        raise ValueError(f"operation {op} cannot be measured: {spec}")
    rng = np.random.default_rng([*np.atleast_1d(seed).tolist(), spec.opcode])
    if spec.opcode == TRANSFORM:
        d = rng.normal(size=(n, 3))
        req = transform_requests(_matrices(rng, n), rng.uniform(-1, 1, (n, 3)), d)
    elif spec.opcode in (QUADBOX, TRIANGLE):
        req = _rays(rng, n)
    else:
        req = np.zeros(n, _rays(rng, 0).dtype)
    req["opcode"] = spec.opcode
    req["tag"] = np.arange(n, dtype=np.uint32)
    if spec.opcode == QUADBOX:
        boxes = _boxes(rng, req)
        if spec.q8:
            q8_request(req, q8_nodes(boxes, rng.integers(1, 5, n)),
                       compressed=bool(spec.flags & FLAG_DECODE_Q8))
        else:
            req["box"] = boxes
    elif spec.opcode == TRIANGLE:
        t = rng.uniform(0.5, 20, n)[:, None]
        centre = req["origin"] + t * req["dir"]
        req["tri"] = centre[:, None, :] + rng.normal(scale=1.0, size=(n, 3, 3))
    elif spec.opcode in (EUCLIDEAN, ANGULAR):
        req["vec_a"] = rng.normal(size=(n, 16))
        req["vec_b"] = rng.normal(size=(n, 16))
        req["vec_mask"] = 0xFFFF
        req["reset_accumulator"] = (np.arange(n) % VECTOR_BEATS) == VECTOR_BEATS - 1
    req["flags"] |= spec.flags
    return req
