"""Build phases: the wall and CPU time of each (``driver.bvh4.build``'s ``stats["phase_s"]`` and
``stats["phase_cpu_s"]``: the process's CPU time, all threads, which other jobs on the machine
do not inflate as they do the wall time) and a hook
called as each starts (``on_phase(name)``), with which a caller watching a build from another
thread or process can tell which phase is running (the test suite's watchdog names the phase
of a build that overruns its time bound)."""

from __future__ import annotations

import contextlib
import time


class Phases:
    """``with phases("matching"): ...`` times the block into ``phases.seconds["matching"]``
    (wall) and ``phases.cpu_seconds["matching"]`` (added up if a phase runs twice) after calling
    ``on_phase("matching")``."""

    def __init__(self, on_phase=None):
        self.seconds: dict[str, float] = {}
        self.cpu_seconds: dict[str, float] = {}
        self.on_phase = on_phase

    @contextlib.contextmanager
    def __call__(self, name: str):
        if self.on_phase is not None:
            self.on_phase(name)
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
            self.cpu_seconds[name] = self.cpu_seconds.get(name, 0.0) + time.process_time() - c0
