"""Progress on stderr: a counting bar (``bar``) and a timer for phases without a count (``phase``).

``bar(total, desc, unit, enabled)`` returns an object with ``hook(done, total)`` (the progress
callback the traversal, the RT-unit replay and the kNN search call) and ``close()``; disabled, it
does nothing. ``phase(desc, enabled)`` is a context manager for work that reports no count (BVH
build, mesh loading, the Embree check, a model build's steps, waiting for a lock): after a second,
a tqdm line whose elapsed time ticks every half second from a background thread, finished with
the phase's duration, so a long phase never looks like a hang (and a short one prints nothing).
The thread is hand-written because tqdm redraws only when it is updated, and such a phase has no
updates.

On a terminal both redraw their line in place; on anything else (a log file, a pipe, CI) a
redraw would be a ``\r`` repaint in the file, so each bar and each phase writes exactly one line
when it ends: what it did, how much and how long it took.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time

from tqdm import tqdm


class _NoBar:
    """The bar interface: ``hook(done, total)`` (absolute), ``update(n)`` (relative, as tqdm),
    ``set_postfix_str(text)``, ``close()``; a context manager that closes it."""

    def hook(self, done, total):
        pass

    def update(self, n=1):
        pass

    def set_postfix_str(self, text):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class _Bar(_NoBar):
    def __init__(self, total, desc, unit, leave):
        self.bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=leave,
                        dynamic_ncols=True, mininterval=0.2)

    def hook(self, done, total):
        if total != self.bar.total:
            self.bar.total = total
        self.bar.update(max(0, int(done) - self.bar.n))

    def update(self, n=1):
        self.bar.update(n)

    def set_postfix_str(self, text):
        self.bar.set_postfix_str(text)

    def close(self):
        self.bar.close()


class _LineBar(_NoBar):
    """A bar on a non-terminal: one line when it is closed."""

    def __init__(self, total, desc, unit):
        self.total, self.desc, self.unit, self.done = total, desc, unit, 0
        self.t0 = time.monotonic()

    def hook(self, done, total):
        self.done, self.total = int(done), total

    def update(self, n=1):
        self.done += int(n)

    def close(self):
        if self.desc is None:
            return
        total = f"/{self.total:,}" if self.total else ""
        print(f"{self.desc}: {self.done:,}{total} {self.unit}s in "
              f"{time.monotonic() - self.t0:.1f} s", file=sys.stderr, flush=True)
        self.desc = None


def interactive() -> bool:
    """Whether stderr is a terminal (progress redraws in place) rather than a file or pipe."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def bar(total, desc: str, unit: str = "ray", enabled: bool | None = True, leave: bool = True):
    """A progress bar on stderr fed by ``hook(done, total)`` or ``update(n)``; a no-op when not
    ``enabled`` (None: only on a terminal); one line at the end when stderr is not a
    terminal."""
    if enabled is None:
        enabled = interactive()
    if not enabled:
        return _NoBar()
    return _Bar(total, desc, unit, leave) if interactive() else _LineBar(total, desc, unit)


@contextlib.contextmanager
def phase(desc: str, enabled: bool = True, delay: float = 1.0, interval: float = 0.5):
    """Show ``desc`` with a ticking elapsed time on stderr while the block runs, once it has run
    for ``delay`` seconds (a quick phase prints nothing); then end the line with its duration.
    Not on a terminal: one line ``desc: done in T s`` at the end (if it ran ``delay`` seconds)."""
    if not enabled:
        yield
        return
    if not interactive():
        t0 = time.monotonic()
        yield
        elapsed = time.monotonic() - t0
        if elapsed >= delay:
            print(f"{desc}: done in {elapsed:.1f} s", file=sys.stderr, flush=True)
        return
    stop = threading.Event()
    shown = []

    def tick():
        if stop.wait(delay):
            return
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


def iterate(items, desc: str, unit: str = "item", enabled: bool | None = True):
    """Yield ``items`` with a ``bar`` advanced after each."""
    items = list(items)
    with bar(len(items), desc, unit, enabled) as b:
        for x in items:
            yield x
            b.update(1)
