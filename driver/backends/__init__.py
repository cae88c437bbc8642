"""One interface for every datapath model: ``backend(name, **options)``.

Layers: ``driver.datapath`` (dtypes, ray preparation) and ``driver.layout`` (wire words, node
image) are the core; this package holds the models behind one ``Backend`` protocol, one module
each (``golden``: numpy model; ``harness``: the "rtl" fast C++ harness over the Verilated RTL;
``pyverilator``: the same RTL cycle by cycle), and ``build`` (RTL sources, parameters, the
Verilator build with its profile-guided policy). Nothing here imports the traversal or the
application; the PGO training workload (``driver.pgo``) runs in a separate process.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

BACKENDS = ("golden", "rtl", "pyverilator")


class BackendError(ValueError):
    """Unknown backend name or a backend that cannot be built here (one-line message)."""


@runtime_checkable
class Backend(Protocol):
    """A datapath model. ``run`` takes a ``REQUEST_DTYPE`` array and returns the
    ``RESPONSE_DTYPE`` array of the same length and order; ``cycles`` counts the datapath clock
    cycles simulated so far (first request accepted to last response taken, per run)."""

    name: str
    extended: bool
    disjoint: bool
    latency: int
    cycles: int

    def run(self, req: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class NodeBackend(Backend, Protocol):
    """A backend that also assembles traversal requests itself from (ray, node pointer, extent)
    triples, the packed ray table and the BVH4 image (the "rtl" harness; see
    ``driver.backends.harness.HarnessBackend.run_nodes``)."""

    params: dict

    def run_nodes(self, ray_words: np.ndarray, image_words: np.ndarray, ray: np.ndarray,
                  ptr: np.ndarray, extent: np.ndarray) -> np.ndarray: ...


def backend(name: str, **options) -> Backend:
    """Return a datapath backend: "golden" (numpy model), "rtl" (fast C++ harness over the
    Verilated RTL) or "pyverilator" (cycle by cycle). Options: extended=, disjoint=, and for the
    RTL backends latency= (pipeline depth) and backend-specific ones (see their classes)."""
    if not isinstance(name, str) or name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    if name == "golden":
        from .golden import GoldenBackend
        return GoldenBackend(**options)
    if name == "rtl":
        from .harness import HarnessBackend       # builds the Verilated model on first use
        return HarnessBackend(**options)
    from .pyverilator import PyverilatorBackend
    return PyverilatorBackend(**options)
