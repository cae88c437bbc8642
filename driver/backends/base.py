"""The backend protocol and its error, apart from the package so that every backend module can
import them without importing the package (no import cycle)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

BACKENDS = ("golden", "rtl", "pyverilator", "rtunit")
DEFAULT_BACKEND = "rtl"     # of the command line and of every API call that takes a backend


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
    compressed: bool        # decodes q8 nodes (a QUADBOX with FLAG_DECODE_Q8)
    transform: bool         # has the TRANSFORM operation
    latency: int
    params: dict            # its build parameters (driver.backends.build.rtl_params)
    cycles: int

    def run(self, req: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class NodeBackend(Backend, Protocol):
    """A backend that also assembles traversal requests itself from (ray, node pointer, extent)
    triples, the packed ray table and the BVH4 image (the "rtl" harness; see
    ``driver.backends.harness.HarnessBackend.run_nodes``)."""

    def run_nodes(self, ray_words: np.ndarray, image_words: np.ndarray, ray: np.ndarray,
                  ptr: np.ndarray, extent: np.ndarray) -> np.ndarray: ...
