"""Random request streams for the power measurements: one stream per operation type.

The paper measured power on the activity of 100 random tests per operation; these are the
corresponding streams. Each request uses only the fields its opcode reads; every other field is
zero, as in a traversal (the RT-unit harness clears the other operation's operands too), so that
no activity comes from data the operation ignores.

``OPS`` is the one table of measured operation types: the name used in the JSON, the opcode and
the request flags. An entry whose value is a string is not measurable yet (the reason is reported
instead of a number). ``triangle_no_cull`` draws the same random triangles as ``triangle`` (the
stream's seed depends on the opcode only) with the NO_CULL flag (docs/datapath.md) set.
"""

from __future__ import annotations

import numpy as np

from ..datapath import ANGULAR, EUCLIDEAN, QUADBOX, TRIANGLE, prepare_rays
from ..layout import FLAG_NO_CULL

# name -> (opcode, extra request fields) or a string: why it cannot be measured yet
OPS: dict[str, tuple[int, dict] | str] = {
    "box": (QUADBOX, {}),
    "triangle": (TRIANGLE, {}),
    "triangle_no_cull": (TRIANGLE, {"flags": FLAG_NO_CULL}),   # the same triangles, both faces
    "euclidean": (EUCLIDEAN, {}),
    "cosine": (ANGULAR, {}),
}
EXTENDED_OPCODES = (EUCLIDEAN, ANGULAR)
VECTOR_BEATS = 4          # a 64-dimensional vector is 4 beats of 16 lanes (as in driver/knn.py)


def measurable(extended: bool) -> list[str]:
    """The operation names a configuration can run (extended ones only on an EXTENDED build)."""
    return [n for n, v in OPS.items() if not isinstance(v, str)
            and (extended or v[0] not in EXTENDED_OPCODES)]


def pending() -> dict[str, str]:
    """Operation name -> why it is not measured."""
    return {n: v for n, v in OPS.items() if isinstance(v, str)}


def _rays(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d[np.abs(d).max(axis=1) < 1e-3] = (0, 0, 1)
    return prepare_rays(rng.uniform(-1, 1, (n, 3)), d, extent=rng.uniform(1, 100, n))


def requests(op: str, n: int, seed=0) -> np.ndarray:
    """``n`` random requests of operation ``op`` (deterministic in ``seed``: an int or a list of
    ints, e.g. [seed, stream]).

    box: a random ray against four random boxes placed near points along it (about half hit);
    triangle: a random ray against a random triangle placed along the ray (front and back faces);
    euclidean / cosine: random normal vectors, all 16 lanes, jobs of VECTOR_BEATS beats."""
    spec = OPS.get(op)
    if spec is None:
        raise ValueError(f"unknown operation {op!r}; choose from {', '.join(OPS)}")
    if isinstance(spec, str):
        raise ValueError(f"operation {op} cannot be measured: {spec}")
    opcode, extra = spec
    rng = np.random.default_rng([*np.atleast_1d(seed).tolist(), opcode])
    if opcode in (QUADBOX, TRIANGLE):
        req = _rays(rng, n)
    else:
        req = np.zeros(n, _rays(rng, 0).dtype)
    req["opcode"] = opcode
    req["tag"] = np.arange(n, dtype=np.uint32)
    if opcode == QUADBOX:
        t = rng.uniform(0.5, 20, (n, 4, 1))
        centre = req["origin"][:, None, :] + t * req["dir"][:, None, :] \
            + rng.normal(scale=0.6, size=(n, 4, 3))
        half = rng.uniform(0.1, 1.0, (n, 4, 3))
        req["box"] = np.concatenate([centre - half, centre + half], axis=2)
    elif opcode == TRIANGLE:
        t = rng.uniform(0.5, 20, n)[:, None]
        centre = req["origin"] + t * req["dir"]
        req["tri"] = centre[:, None, :] + rng.normal(scale=1.0, size=(n, 3, 3))
    else:
        req["vec_a"] = rng.normal(size=(n, 16))
        req["vec_b"] = rng.normal(size=(n, 16))
        req["vec_mask"] = 0xFFFF
        req["reset_accumulator"] = (np.arange(n) % VECTOR_BEATS) == VECTOR_BEATS - 1
    for field, value in extra.items():
        req[field] = value
    return req
