"""Ctrl-C and SIGTERM end a command within about a second, even inside a native kernel.

Python runs a signal handler only in the main thread, between two of its bytecodes. While the
main thread is inside a native call (a numba kernel of the BVH builder, a Verilated model or the
RT-unit replay through ctypes) the handler waits until that call returns, which on a large mesh
or frame can be minutes. ``watch`` therefore also follows signals from a daemon thread: the
interpreter's C-level handler writes each signal's number to a pipe (``signal.set_wakeup_fd``),
the thread wakes on it, and

- if the main thread has not run its handler within ``GRACE`` seconds (it is inside native
  code), or has run it but the process has not ended within ``LIMIT`` seconds of the signal
  (a cleanup waiting on such code), the thread kills the process's child processes (Dask
  workers, build tools, each with its process group), prints the command's one line and ends
  the process with the exit status the handler would have given (``os._exit``);
- otherwise the handler's exception unwinds as usual (builds cleaned up, nothing written) and
  the process ends by itself.

Once the command's outputs are in place (``finished()`` true: ``driver.core.outputs.written``)
a signal no longer interrupts: the handler notes it (``Watch.late``) and the command ends as it
would have (what is left is printing its summary), its outputs complete; should the handler not
run within ``GRACE`` (native code), the thread ends the process with status 0 and a line saying
the outputs are complete.

The thread needs the GIL only for a moment; the native kernels release it while they run (the
builder's numba kernels are compiled ``nogil``, ctypes releases it around every call), so the
thread runs beside them. Nothing is half-written by the hard exit: the commands write their
outputs atomically when their work is done, and a model build's temporary directory left by
it is removed by the next build of that model (``driver.backends.cache``).

Only the command line installs it (``driver.cli.main``): a library user, or a notebook whose
interrupt should stop a cell rather than end the kernel, keeps Python's own behaviour.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from pathlib import Path

GRACE = 0.5     # s: a handler that has not run by then is waiting for native code
LIMIT = 1.0     # s: from the signal to the end of the process, at most (plus the exit itself)


class Watch:
    """What ``watch`` saw: ``late`` is the word ("interrupted", "terminated") of a signal that
    arrived after the outputs were written (then ignored), else None."""

    def __init__(self, finished):
        self.finished = finished
        self.late = None
        self.handled = threading.Event()       # the main thread ran a SIGINT/SIGTERM handler
        self.signalled = threading.Event()     # the thread saw SIGINT or SIGTERM


def _children(pid: int) -> list[int]:
    """The direct child processes of ``pid`` (Linux /proc; empty elsewhere)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _kill_children() -> None:
    """SIGKILL every descendant process, and the process group of each child that leads its
    own (a build tool's compilers)."""
    todo, seen = _children(os.getpid()), set()
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        todo += _children(pid)
    for pid in seen:
        with contextlib.suppress(OSError):
            if os.getpgid(pid) == pid:
                os.killpg(pid, signal.SIGKILL)
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)


def _hard_exit(signum: int, prog: str, codes: dict, finished=lambda: False) -> None:
    word, code = codes[signum]
    if finished():
        word, code = late_note(word), 0
    with contextlib.suppress(Exception):
        _kill_children()
    with contextlib.suppress(OSError):
        os.write(2, f"\n{prog}: {word}\n".encode())
    os._exit(code)


def late_note(word: str) -> str:
    """The line for a signal that came once the outputs were written."""
    return f"{word} after the outputs were written: they are complete"


def _follow(r: int, state: Watch, prog: str, codes: dict) -> None:
    while True:
        try:
            data = os.read(r, 64)
        except OSError:
            return
        if not data:                         # the block ended without a signal
            os.close(r)
            return
        for signum in data:
            if signum not in codes:
                continue
            state.signalled.set()
            t0 = time.monotonic()
            if not state.handled.wait(GRACE):
                _hard_exit(signum, prog, codes, state.finished)
            if state.late:                   # outputs written: the command ends as it would
                state.handled.clear()
                continue
            time.sleep(max(0.0, LIMIT - (time.monotonic() - t0)))
            _hard_exit(signum, prog, codes, state.finished)  # still running: stuck


@contextlib.contextmanager
def watch(prog: str, codes: dict, sigterm_exception: type[BaseException],
          finished=lambda: False):
    """While the block runs: SIGINT raises KeyboardInterrupt and SIGTERM
    ``sigterm_exception`` in the main thread as usual, and a daemon thread ends the process if
    that does not happen or does not finish in time (module docstring). ``codes``: signal
    number -> (word, exit status), e.g. ``{SIGINT: ("interrupted", 130)}``. ``finished()``
    true: the outputs are written, a signal is noted, not raised. Yields a ``Watch``. Outside
    the main thread, or where the handlers cannot be set, the block runs unwatched."""
    state = Watch(finished)
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(exception):
        def on_signal(signum, frame):
            if finished():
                state.late = codes[signum][0]
                state.handled.set()
                return
            state.handled.set()
            raise exception()
        return on_signal

    on_int, on_term = handler(KeyboardInterrupt), handler(sigterm_exception)

    r, w = os.pipe()
    os.set_blocking(w, False)
    try:
        old_int = signal.signal(signal.SIGINT, on_int)
        old_term = signal.signal(signal.SIGTERM, on_term)
        old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    except ValueError:
        os.close(r)
        os.close(w)
        yield state
        return
    threading.Thread(target=_follow, args=(r, state, prog, codes), name="rayflex-signals",
                     daemon=True).start()
    old_hook = sys.unraisablehook

    def unraisable(info):
        # the signal's exception raised inside a C callback (e.g. llvmlite's while numba
        # compiles) cannot propagate: Python would print it with a traceback. Say nothing: the
        # watcher thread ends the process with the signal's one line (``_follow``).
        if not isinstance(info.exc_value, (KeyboardInterrupt, sigterm_exception)):
            old_hook(info)

    sys.unraisablehook = unraisable
    try:
        yield state
    finally:
        sys.unraisablehook = old_hook
        signal.set_wakeup_fd(old_fd)
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
        if not (state.handled.is_set() or state.signalled.is_set()):
            os.close(w)                      # the thread reads the end of the pipe and returns
        # else the thread keeps its deadline until the process ends (the interpreter's exit
        # may still wait for native code)
