"""Progress on stderr: a counting bar (``bar``) and a timer for phases without a count (``phase``).

``bar(total, desc, unit, enabled)`` returns an object with ``hook(done, total)`` (the progress
callback the traversal, the RT-unit replay and the kNN search call) and ``close()``; disabled, it
does nothing. ``phase(desc, enabled)`` is a context manager for work that reports no count (BVH
build, mesh loading, the Embree check, waiting for a lock): after a second, a tqdm line whose
elapsed time ticks every half second from a background thread, finished with the phase's
duration, so a long phase never looks like a hang (and a short one prints nothing). The thread
is hand-written because tqdm redraws only when it is updated, and such a phase has no updates.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time


class _NoBar:
    def hook(self, done, total):
        pass

    def close(self):
        pass


class _Bar(_NoBar):
    def __init__(self, total, desc, unit, leave):
        from tqdm import tqdm
        self.bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=leave,
                        dynamic_ncols=True, mininterval=0.2)

    def hook(self, done, total):
        if total != self.bar.total:
            self.bar.total = total
        self.bar.update(max(0, int(done) - self.bar.n))

    def close(self):
        self.bar.close()


def bar(total, desc: str, unit: str = "ray", enabled: bool = True, leave: bool = True):
    """A progress bar on stderr fed by ``hook(done, total)``; a no-op when not ``enabled``."""
    return _Bar(total, desc, unit, leave) if enabled else _NoBar()


@contextlib.contextmanager
def phase(desc: str, enabled: bool = True, delay: float = 1.0, interval: float = 0.5):
    """Show ``desc`` with a ticking elapsed time on stderr while the block runs, once it has run
    for ``delay`` seconds (a quick phase prints nothing); then end the line with its duration."""
    if not enabled:
        yield
        return
    stop = threading.Event()
    shown = []

    def tick():
        if stop.wait(delay):
            return
        from tqdm import tqdm
        t = tqdm(total=None, desc=desc, file=sys.stderr, bar_format="{desc}: {elapsed}",
                 dynamic_ncols=True, leave=True, initial=0)
        shown.append(t)
        while not stop.wait(interval):
            t.refresh()

    th = threading.Thread(target=tick, daemon=True)
    t0 = time.monotonic()
    th.start()
    try:
        yield
    finally:
        stop.set()
        th.join()
        if shown:
            t = shown[0]
            t.bar_format = "{desc}: " + f"done in {time.monotonic() - t0:.1f} s"
            t.refresh()
            t.close()
