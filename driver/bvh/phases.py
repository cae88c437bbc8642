"""Build phases: the wall time of each (``driver.bvh4.build``'s ``stats["phase_s"]``) and a hook
called as each starts (``on_phase(name)``), with which a caller watching a build from another
thread or process can tell which phase is running (the test suite's watchdog names the phase
of a build that overruns its time bound)."""

from __future__ import annotations

import contextlib
import time


class Phases:
    """``with phases("matching"): ...`` times the block into ``phases.seconds["matching"]``
    (added up if a phase runs twice) after calling ``on_phase("matching")``."""

    def __init__(self, on_phase=None):
        self.seconds: dict[str, float] = {}
        self.on_phase = on_phase

    @contextlib.contextmanager
    def __call__(self, name: str):
        if self.on_phase is not None:
            self.on_phase(name)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
