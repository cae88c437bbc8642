"""A watchdog for the test run: work that could hang runs in a worker process, and a call that
runs past its time bound becomes a test failure naming the phase it was in, instead of a test
run that never ends.

Why a process: the BVH builder's kernels are native code that no signal interrupts, so a
runaway loop in one can only be stopped by ending the process that runs it. The worker is
started once (``spawn``: a clean interpreter that loads the numba kernels from their cache)
and serves calls ``fn(*args, on_phase=..., **kwargs)`` of module-level functions; ``on_phase``
records the current phase's name in shared memory, where the test process reads it when the
bound runs out. The worker is then killed and a new one started for the next call; an
exception in the worker is raised again in the test process with the worker's traceback.
"""

from __future__ import annotations

import multiprocessing
import time
import traceback

_PHASE_BYTES = 160


def _serve(conn, phase) -> None:
    import importlib

    def on_phase(name: str) -> None:
        phase.value = name.encode()[:_PHASE_BYTES - 1]

    while True:
        try:
            module, name, args, kwargs = conn.recv()
        except (EOFError, OSError):
            return
        on_phase("starting")
        try:
            fn = getattr(importlib.import_module(module), name)
            reply = ("ok", fn(*args, on_phase=on_phase, **kwargs))
        except BaseException as e:  # noqa: BLE001  (every failure goes back to the test)
            try:
                e.add_note("in the watchdog's worker:\n" + traceback.format_exc())
            except AttributeError:
                pass
            reply = ("error", e)
        on_phase("idle")
        conn.send(reply)


class Watchdog:
    """``Watchdog().call(bound_s, fn, *args, **kwargs)``: ``fn(*args, on_phase=..., **kwargs)``
    in the worker, its result returned; AssertionError naming the phase if it runs longer than
    ``bound_s`` seconds. ``close()`` ends the worker."""

    def __init__(self):
        self._ctx = multiprocessing.get_context("spawn")
        self._start()

    def _start(self) -> None:
        self.phase = self._ctx.Array("c", _PHASE_BYTES, lock=False)
        self.conn, child = self._ctx.Pipe()
        self.proc = self._ctx.Process(target=_serve, args=(child, self.phase), daemon=True,
                                      name="watchdog-worker")
        self.proc.start()
        child.close()

    def call(self, bound_s: float, fn, *args, **kwargs):
        self.conn.send((fn.__module__, fn.__name__, args, kwargs))
        t0 = time.monotonic()
        if not self.conn.poll(bound_s):
            phase = self.phase.value.decode(errors="replace")
            self.proc.kill()
            self.proc.join()
            self._start()
            raise AssertionError(f"{fn.__name__} still in phase {phase!r} after "
                                 f"{time.monotonic() - t0:.1f} s (bound {bound_s:.1f} s): a "
                                 "hang or a runaway loop")
        try:
            status, value = self.conn.recv()
        except (EOFError, OSError):
            phase = self.phase.value.decode(errors="replace")
            code = self.proc.exitcode
            self.proc.join()
            self._start()
            raise AssertionError(f"{fn.__name__}: the worker died (exit {code}) in phase "
                                 f"{phase!r}") from None
        if status == "error":
            raise value
        return value

    def close(self) -> None:
        self.conn.close()
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
