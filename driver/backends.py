"""One interface for every datapath model: ``backend(name, **options)``.

Each backend has ``run(requests) -> responses`` (``REQUEST_DTYPE`` in, ``RESPONSE_DTYPE`` out, same
length and order), ``cycles`` (datapath clock cycles simulated so far), ``latency``, ``extended``
and ``disjoint``.
"""

from __future__ import annotations

BACKENDS = ("golden", "rtl", "pyverilator")


class BackendError(ValueError):
    """Unknown backend name or a backend that cannot be built here (one-line message)."""


def backend(name: str, **options):
    """Return a datapath backend: "golden" (numpy model), "rtl" (fast C++ harness over the
    Verilated RTL) or "pyverilator" (cycle by cycle). Options: extended=, disjoint=, and for the
    RTL backends latency= (pipeline depth) and backend-specific ones (see their classes)."""
    if not isinstance(name, str) or name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    if name == "golden":
        from .golden import GoldenBackend
        return GoldenBackend(**options)
    from . import rtl  # noqa: PLC0415  (builds the Verilated model on first use)
    if name == "rtl":
        return rtl.HarnessBackend(**options)
    return rtl.PyverilatorBackend(**options)
