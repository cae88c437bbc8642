"""The build cache of the Verilated models: one directory per entry under
``$RAYFLEX_CACHE/verilator`` (``RAYFLEX_CACHE`` defaults to ``~/.cache/rayflex``), built once
under an ``fcntl`` lock and renamed into place atomically.

``cached_build(entry, artifact, build, what)`` returns ``cache_dir()/entry/artifact``, building it
on a miss: ``build`` fills a fresh temporary directory inside the cache under the entry's lock
(a process that waits for another's build says so on stderr), and the directory becomes the
entry only when ``build`` returns. On SIGINT or SIGTERM the work directory is removed and every
process still working inside it killed; a process killed with SIGKILL cannot clean up, so the
next build of the same entry, holding its lock, kills any process still working inside a stale
temporary directory and removes it. ``driver.backends.verilate`` builds the models through it.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

from ..core.errors import Terminated
from ..core.progress import phase


class BuildError(RuntimeError):
    """A Verilator/C++ build or lint failed; the message is one line meant for the user."""


DEFAULT_CACHE = "~/.cache/rayflex"     # RAYFLEX_CACHE: every cache of the tool, one folder each


def cache_root() -> Path:
    """The tool's cache (``$RAYFLEX_CACHE`` or ``DEFAULT_CACHE``): Verilator models in
    ``verilator/`` (``cache_dir``), synthesized netlists in ``area/`` and ``power/``, LumiBench
    scenes and their BVHs in ``scenes/`` (``driver.scenes.lumibench``)."""
    env = os.environ.get("RAYFLEX_CACHE")
    return Path(env or DEFAULT_CACHE).expanduser()


def cache_dir() -> Path:
    """The Verilator build cache: ``cache_root() / "verilator"``."""
    return cache_root() / "verilator"


def _estimate(root: Path, top: str) -> float | None:
    """The last recorded build time of ``top`` in this cache, or None (never built here)."""
    try:
        return float(json.loads((root / "timings.json").read_text())[top])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _record_time(root: Path, top: str, seconds: float) -> None:
    path = root / "timings.json"
    try:
        data = json.loads(path.read_text())
        if not isinstance(data, dict):
            data = {}
    except (OSError, ValueError):
        data = {}
    data[top] = round(seconds, 1)
    tmp = path.with_name(f".timings.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
    os.replace(tmp, path)


@contextlib.contextmanager
def _sigterm_raises():
    """While building: SIGTERM raises ``Terminated`` (so the build is cleaned up) instead of
    ending the process at once; once the cleanup is done, the process ends by SIGTERM as it
    would have. Only in the main thread and only if nobody handles SIGTERM (the command line
    does: it reports and exits 143)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return

    def handler(signum, frame):
        raise Terminated()
    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    except Terminated:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTERM)
        raise
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _open_lock(root: Path, entry: str):
    try:
        root.mkdir(parents=True, exist_ok=True)
        return open(root / f".{entry}.lock", "w")
    except OSError as e:
        raise BuildError(f"cannot write the build cache {root}: {e.strerror} (set RAYFLEX_CACHE "
                         "to a writable directory)") from None


def _lock(lock, root: Path, what: str) -> None:
    """Take the entry's lock; if another process holds it, say so on stderr while waiting."""
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return
    except BlockingIOError:
        pass
    with phase(f"waiting for the {what} build in {root} (another process holds the lock)",
               delay=0):
        fcntl.flock(lock, fcntl.LOCK_EX)


def _clean_stale(root: Path, entry: str) -> None:
    """Remove temporary build directories of ``entry`` (stale: we hold its lock, so their builder
    is dead) and kill processes still working inside them (make/g++ orphaned by a SIGKILL)."""
    for tmp in root.glob(f".tmp-{entry}-*"):
        _kill_inside(tmp)
        shutil.rmtree(tmp, ignore_errors=True)


def _kill_inside(directory: Path) -> None:
    """SIGKILL every process whose working directory is ``directory`` or below (Linux /proc; a
    dozen lines, so no psutil dependency). Every build tool runs inside its build directory, so
    this finds exactly the orphans of a dead build, whatever process group they ended up in."""
    prefix = str(directory.resolve())
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cwd = os.readlink(proc / "cwd")
        except OSError:
            continue
        if cwd == prefix or cwd.startswith(prefix + os.sep):
            with contextlib.suppress(OSError):
                os.kill(int(proc.name), signal.SIGKILL)


def cached_build(entry: str, artifact: str, build: Callable[[Path], None], what: str,
                 estimate_key: str | None = None) -> Path:
    """``cache_dir()/entry/artifact``, built by ``build(work)`` on a miss.

    ``build`` fills a fresh temporary directory ``work`` inside the cache (raising BuildError on
    failure); it runs under the entry's lock and the directory is renamed to ``entry`` only when
    it returns. On a BuildError the directory is kept as ``entry.failed`` (its log); on an
    interrupt it is removed. ``estimate_key`` names the entry in ``timings.json`` (time shown).
    """
    root = cache_dir()
    final = root / entry
    out = final / artifact
    if out.is_file():
        return out
    with _open_lock(root, entry) as lock:
        _lock(lock, root, what)
        if out.is_file():  # another process built it while we waited
            return out
        _clean_stale(root, entry)
        last = _estimate(root, estimate_key) if estimate_key else None
        est = f", the last build took {last:.0f} s" if last is not None else ""
        print(f"building {what} (first time{est})\u2026", file=sys.stderr, flush=True)
        t0 = time.monotonic()
        work = Path(tempfile.mkdtemp(prefix=f".tmp-{entry}-", dir=root))
        failed = root / f"{entry}.failed"
        with _sigterm_raises():
            try:
                build(work)
                work.chmod(0o755)  # mkdtemp makes it private; the cache may be shared
                try:
                    os.rename(work, final)
                except OSError:  # a stale entry without the artifact (e.g. removed by hand)
                    shutil.rmtree(final, ignore_errors=True)
                    os.rename(work, final)
            except BuildError:
                shutil.rmtree(failed, ignore_errors=True)
                try:
                    os.rename(work, failed)
                except OSError:
                    shutil.rmtree(work, ignore_errors=True)
                raise
            except BaseException:
                _kill_inside(work)
                shutil.rmtree(work, ignore_errors=True)
                raise
        elapsed = time.monotonic() - t0
        print(f"built {what} in {elapsed:.0f} s (cached in {final})", file=sys.stderr,
              flush=True)
        if estimate_key:
            _record_time(root, estimate_key, elapsed)
    return out
