"""Batches of the RT unit in RTL traced once per suite: a batch whose inputs equal one already
traced reuses its results.

A batch's results and cycles are a function of its inputs alone: the prepared rays and their
any-hit flags, the BVH image and its root, the unit's build (its RTL, harness and parameters: the
library's cache entry) and the memory behind its port. LumiBench's three shaders of a scene
trace the same camera rays first (a third of the spring's cycles, twice over), so a suite keeps
each batch's results in a folder (``memo(directory)``, around each run's work: worker processes
share it) and a batch found there is not simulated again. Its results, op counts and every
statistic are the stored batch's, bit for bit; ``unit_rtl.reused_batches`` counts the batches of
a frame that were found. With the traversal's check (``--unit-check traversal``) a reused batch
is checked against the traversal again, as a simulated one is.

Stored as one ``.npz`` per batch, named by the sha256 of the inputs, written to a temporary
file and renamed (a batch two processes trace at once is written twice, identically).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import threading
from pathlib import Path

import numpy as np

_DIRECTORY: list[Path | None] = [None]

ARRAYS = ("prim", "t", "hit", "box_ops", "tri_ops", "overflows", "refills", "instance",
          "xf_ops", "culled")


@contextlib.contextmanager
def memo(directory):
    """Within: batches of the RT unit are looked up in and stored to ``directory`` (made on
    first use). Process-wide (the tiles' threads of a frame share it)."""
    before = _DIRECTORY[0]
    _DIRECTORY[0] = Path(directory)
    try:
        yield
    finally:
        _DIRECTORY[0] = before


def directory() -> Path | None:
    """The folder batches are reused from, or None (no ``memo`` active)."""
    return _DIRECTORY[0]


def key(parts: list, arrays: list[np.ndarray]) -> str:
    """The sha256 (hex) of a batch's inputs: ``parts`` (JSON-able: the unit's library and memory)
    and ``arrays`` (rays, flags, the image digest's source), in order."""
    h = hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.view(np.uint8).reshape(-1).data)
    return h.hexdigest()


def load(name: str):
    """``({array: ndarray}, stats)`` of the stored batch ``name``, or None."""
    d = directory()
    path = None if d is None else d / f"{name}.npz"
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path) as z:
            arrays = {a: z[a] for a in ARRAYS}
            stats = json.loads(str(z["stats"]))
    except (OSError, ValueError, KeyError):
        return None                  # unreadable (a truncated file): traced again
    return arrays, stats


def store(name: str, arrays: dict, stats: dict) -> None:
    """Store batch ``name`` (all or nothing)."""
    d = directory()
    if d is None:
        return
    d.mkdir(parents=True, exist_ok=True)
    tmp = d / f".{name}.{os.getpid()}.{threading.get_ident()}.npz"
    with open(tmp, "wb") as f:
        np.savez(f, stats=np.array(json.dumps(stats)), **{a: arrays[a] for a in ARRAYS})
    os.replace(tmp, d / f"{name}.npz")
