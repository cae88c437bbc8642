"""What the two RTL backends share: parameters, request checks, input-gap/output-stall patterns."""

from __future__ import annotations

import numpy as np

from ..core.datapath import check_requests
from .build import rtl_params

PATTERN_LEN = 4099        # length of the repeating gap/stall patterns (prime: no beat with stages)


def pattern(probability: float, seed: int, length: int = PATTERN_LEN) -> np.ndarray | None:
    """A repeating 0/1 pattern: 1 marks a cycle with an input gap (or an output stall)."""
    if not probability:
        return None
    if not 0 <= probability < 1:
        raise ValueError(f"gap/stall probability {probability} must be in [0, 1)")
    return (np.random.default_rng(seed).random(length) < probability).astype(np.uint8)


class RtlBackendBase:
    """Options of both RTL backends: ``extended``, ``disjoint``, ``compressed`` (the q8 decode
    stage), ``transform`` (the TRANSFORM operation), ``fused`` (one rounding in the box slab and
    the edge functions), ``shared`` (the vectors on the request registers' box and triangle bits;
    both docs/tradeoffs.md), ``latency`` (build parameters; None: the least, 11 or 12 with ``compressed``),
    ``gaps``/``stalls`` (probability of an input bubble / output back-pressure per cycle, as
    repeating patterns from ``seed``). Given the same requests and patterns both return identical
    responses and cycle counts."""

    name = "rtl"

    def __init__(self, extended=False, disjoint=False, latency=None, gaps=0.0, stalls=0.0,
                 seed=0, compressed=False, transform=False, fused=False, shared=False):
        self.params = rtl_params(extended, disjoint, latency, compressed, transform, fused,
                                 shared)
        self.extended = bool(extended)
        self.disjoint = bool(disjoint)
        self.compressed = bool(compressed)
        self.transform = bool(transform)
        self.fused = bool(fused)
        self.shared = bool(shared)
        self.latency = self.params["LATENCY"]
        self.gap = pattern(gaps, seed)
        self.stall = pattern(stalls, seed + 1)
        self.cycles = 0
        self.requests = 0

    def _check(self, req: np.ndarray) -> None:
        check_requests(req, self.extended, self.compressed, self.transform)

    def _max_idle(self) -> int:
        return 64 * PATTERN_LEN + 100 * self.latency
