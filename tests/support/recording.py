"""A backend wrapper that records every ``run()`` call (a generic backend: no ``run_nodes``, so the
tracer issues plain request arrays through it).

Named ``RecordingBackend`` rather than ``Recorder``: ``driver.tracing.issue.Recorder`` is the tracer's
issue recorder, a different thing.
"""

from __future__ import annotations

import numpy as np


class RecordingBackend:
    """Wraps ``inner``; ``calls`` holds a copy of every request array given to ``run()``. With
    ``corrupt=True`` every other response's tag is changed (a backend that loses track of tags)."""

    name = "recorder"

    def __init__(self, inner, corrupt: bool = False):
        self.inner, self.corrupt = inner, corrupt
        self.calls: list[np.ndarray] = []

    @property
    def cycles(self) -> int:
        return self.inner.cycles

    @property
    def latency(self) -> int:
        return self.inner.latency

    def run(self, req: np.ndarray) -> np.ndarray:
        self.calls.append(req.copy())
        rsp = self.inner.run(req)
        if self.corrupt:
            rsp["tag"][::2] += 1
        return rsp
