"""One interface for every datapath model: ``backend(name, **options)``.

Layers: ``driver.core.datapath`` (dtypes, ray preparation) and ``driver.core.layout`` (wire words,
node image) are the core; this package holds the models behind one ``Backend`` protocol, one module
each (``golden``: numpy model; ``harness``: the "rtl" fast C++ harness over the Verilated RTL;
``pyverilator``: the same RTL cycle by cycle; ``rtunit``: the RT unit in RTL around the
datapath, which traverses whole batches itself), and ``build`` (RTL sources, parameters, the
Verilator build with its profile-guided policy). Nothing here imports the traversal or the
application; the PGO training workload (``driver.pgo``) runs in a separate process.
"""

from __future__ import annotations

from .base import BACKENDS, DEFAULT_BACKEND, Backend, BackendError, NodeBackend
from .golden import GoldenBackend
from .harness import HarnessBackend
from .pyverilator import PyverilatorBackend
from .rtunit import RtUnitBackend

__all__ = ["BACKENDS", "DEFAULT_BACKEND", "Backend", "BackendError", "NodeBackend", "backend",
           "resolve"]


def backend(name: str, **options) -> Backend:
    """Return a datapath backend: "golden" (numpy model), "rtl" (fast C++ harness over the
    Verilated RTL), "pyverilator" (cycle by cycle) or "rtunit" (the RT unit in RTL:
    ``driver.backends.rtunit``). Options: extended=, disjoint=, and for the RTL backends
    latency= (pipeline depth) and backend-specific ones (see their classes)."""
    if not isinstance(name, str) or name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    try:
        if name == "golden":
            return GoldenBackend(**options)
        if name == "rtl":
            return HarnessBackend(**options)          # builds the Verilated model on first use
        if name == "rtunit":
            return RtUnitBackend(**options)
        return PyverilatorBackend(**options)
    except ImportError as e:
        raise BackendError(f"backend {name!r} is not available: {e}") from None


def resolve(spec, **options) -> tuple[Backend, str]:
    """(backend, its name) for a backend name (made by ``backend``) or a backend object (used as
    it is)."""
    if isinstance(spec, str):
        return backend(spec, **options), spec
    return spec, str(getattr(spec, "name", type(spec).__name__))
