"""Fault injection with real processes (issue 11): builds killed half way, concurrent cold-cache
builds, a lock held by another process, unwritable outputs and cache, a full disk, missing tools.

Every case must end with a one-line message, the exit code of the documented table
(``driver.cli.EXIT_CODES``, docs/faults.md) and no partial file: no output, no ``.tmp-*`` build
directory, no compiler left running. The cold builds (RAYFLEX_PGO=0, ~20-40 s each) are
``slow``; each kind has a fast representative in the default suite.
"""

from __future__ import annotations

import contextlib
import errno
import json
import fcntl
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from driver.cli import EXIT_CODES, main
from driver.cli.common import EXIT_OK, EXIT_TERMINATED, EXIT_USAGE

ROOT = Path(__file__).resolve().parent.parent


def env_for(cache: Path, **extra) -> dict:
    env = dict(os.environ, RAYFLEX_CACHE=str(cache), RAYFLEX_PGO="0",
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.update(extra)
    return env


def rayflex(*args, cwd, env, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "driver.cli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def build_dirs(cache: Path) -> list[Path]:
    """The temporary build directories in the Verilator cache under ``cache``
    (RAYFLEX_CACHE)."""
    return list((cache / "verilator").glob(".tmp-*"))


def last_line(stderr: str) -> str:
    lines = [ln for ln in stderr.replace("\r", "\n").splitlines() if ln.strip()]
    assert lines, "no message on stderr"
    assert "Traceback" not in stderr, stderr
    return lines[-1]


def processes_inside(directory: Path) -> list[int]:
    prefix = str(directory.resolve())
    pids = []
    for proc in Path("/proc").glob("[0-9]*"):
        with contextlib.suppress(OSError):
            cwd = os.readlink(proc / "cwd")
            if cwd == prefix or cwd.startswith(prefix + os.sep):
                pids.append(int(proc.name))
    return pids


def wait_for(cond, timeout: float, what: str):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_exit_table_is_documented():
    doc = (ROOT / "docs" / "faults.md").read_text()
    for code in EXIT_CODES:
        assert f"| {code} |" in doc, code


# ---------------------------------------------------------------------------------------------
# a build killed half way

def test_sigterm_during_a_build_kills_the_compilers_and_leaves_nothing(tmp_path):
    """Issue 11 #6: SIGTERM during a build left make/g++ running and a .tmp-* directory."""
    cache, work = tmp_path / "cache", tmp_path / "work"
    work.mkdir()
    p = rayflex("render", "sphere", "--size", "4", "--backend", "rtl", "--no-progress",
                cwd=work, env=env_for(cache))
    try:
        tmp = wait_for(lambda: next(iter(build_dirs(cache)), None), 60, "the build to start")
        wait_for(lambda: processes_inside(tmp), 60, "a build tool to run")
        time.sleep(0.5)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == EXIT_TERMINATED
    assert last_line(err) == "rayflex: terminated"
    assert not build_dirs(cache) and not processes_inside(cache)
    assert not list(work.iterdir())


_SLEEPING_BUILD = textwrap.dedent("""
    from driver.backends import verilate
    def build(work):
        with open(work / "build.log", "w") as log:
            verilate._run(["sleep", "600"], work, log, "sleeping", work / "build.log", {})
    verilate.cached_build("model-s", "lib.so", build, "test model")
""")


def test_sigterm_during_a_build_in_a_library_user_cleans_up_then_dies_by_sigterm(tmp_path):
    """Outside the command line (driver used as a library, SIGTERM unhandled): the build's
    process group and directory are cleaned up, then the process ends by SIGTERM as before."""
    cache = tmp_path / "cache"
    p = subprocess.Popen([sys.executable, "-c", _SLEEPING_BUILD], env=env_for(cache),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        tmp = wait_for(lambda: next(iter(build_dirs(cache)), None), 60, "the build to start")
        sleeper = wait_for(lambda: processes_inside(tmp), 60, "the tool to run")
        p.send_signal(signal.SIGTERM)
        p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == -signal.SIGTERM
    assert not build_dirs(cache) and not processes_inside(cache)
    assert not Path(f"/proc/{sleeper[0]}").exists() or \
        Path(f"/proc/{sleeper[0]}/status").read_text().find("State:\tZ") >= 0


def test_next_build_kills_what_a_sigkilled_build_left(tmp_path):
    """SIGKILL cannot be handled: the next build of the entry (holding its lock) kills processes
    still working inside the stale temporary directory and removes it."""
    from driver.backends import verilate
    cache = tmp_path / "cache"
    stale = cache / "verilator" / ".tmp-model-abc-x1y2"
    (stale / "obj").mkdir(parents=True)
    orphan = subprocess.Popen(["sleep", "600"], cwd=stale / "obj", start_new_session=True)
    other = subprocess.Popen(["sleep", "600"], cwd=tmp_path)      # not inside: must survive
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("RAYFLEX_CACHE", str(cache))
            out = verilate.cached_build("model-abc", "lib.so",
                                        lambda w: (w / "lib.so").write_bytes(b"x"), "test model")
        assert out.read_bytes() == b"x"
        assert orphan.wait(timeout=10) == -signal.SIGKILL
        assert not stale.exists() and other.poll() is None
    finally:
        orphan.kill()
        other.kill()


@pytest.mark.slow
def test_sigkill_during_a_build_then_rebuild(tmp_path):
    cache, work = tmp_path / "cache", tmp_path / "work"
    work.mkdir()
    p = rayflex("render", "sphere", "--size", "4", "--backend", "rtl", "--no-progress",
                cwd=work, env=env_for(cache))
    tmp = wait_for(lambda: next(iter(build_dirs(cache)), None), 60, "the build to start")
    wait_for(lambda: processes_inside(tmp), 60, "a build tool to run")
    time.sleep(2)
    p.kill()
    p.communicate()
    q = rayflex("render", "sphere", "--size", "4", "--backend", "rtl", "--no-progress",
                cwd=work, env=env_for(cache))
    out, err = q.communicate(timeout=900)
    assert q.returncode == EXIT_OK, err
    assert not tmp.exists() and not build_dirs(cache) and not processes_inside(cache)
    assert (work / "sphere.png").is_file()


# ---------------------------------------------------------------------------------------------
# Ctrl-C and SIGTERM inside native code

_NATIVE_SPIN = textwrap.dedent("""
    from numba import njit
    from driver.cli.interrupt import watch

    @njit(nogil=True)
    def spin(n):
        x = 0.0
        for i in range(n):
            x += (i % 7) * 1e-9
        return x

    class Stop(BaseException):
        pass

    spin(10)
    print("ready", flush=True)
    with watch("spinner", {2: ("interrupted", 130), 15: ("terminated", 143)}, Stop):
        spin(10 ** 13)                           # hours of native code
""")


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                             (signal.SIGTERM, 143, "terminated")])
def test_a_signal_ends_a_native_kernel_within_a_second(tmp_path, sig, code, word):
    """Python's handler cannot run while the main thread is inside a numba kernel (the q8
    encoder's matching once looped there and only SIGKILL ended it): ``driver.cli.interrupt``
    ends the process from its own thread."""
    p = subprocess.Popen([sys.executable, "-c", _NATIVE_SPIN], env=env_for(tmp_path),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "ready"
        time.sleep(0.5)
        t0 = time.monotonic()
        p.send_signal(sig)
        _, err = p.communicate(timeout=30)
        latency = time.monotonic() - t0
    finally:
        p.kill()
    assert p.returncode == code
    assert last_line(err) == f"spinner: {word}"
    assert latency < 3.0                      # 0.5 s grace, then the exit (~0.6 s measured)


def test_sigint_during_a_large_q8_build_ends_the_command_at_once(tmp_path):
    """``rayflex render`` of a 600,000-triangle mesh in q8: Ctrl-C during the build (native
    kernels) ends it within about a second, exit 130, nothing written."""
    import trimesh
    rng = np.random.default_rng(0)
    n = 600_000
    c = rng.uniform(-1, 1, (n, 1, 3))
    tris = (c + 0.01 * rng.normal(size=(n, 3, 3))).astype(np.float32).reshape(-1, 3)
    trimesh.Trimesh(tris, np.arange(3 * n).reshape(-1, 3), process=False).export(
        tmp_path / "big.ply")
    work = tmp_path / "work"
    work.mkdir()
    p = rayflex("render", str(tmp_path / "big.ply"), "--bvh-format", "q8", "--backend",
                "golden", "--size", "8", "--out", "x.png", cwd=work, env=env_for(tmp_path))
    try:
        wait_for(lambda: _cpu_seconds(p.pid) > 4.0, 120, "the command to load and build")
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=30)
        latency = time.monotonic() - t0
    finally:
        p.kill()
    assert p.returncode == 130, err
    assert last_line(err) == "rayflex: interrupted"
    assert latency < 3.0
    assert not list(work.iterdir())


def test_an_interrupt_raised_in_a_c_callback_prints_no_traceback(monkeypatch):
    """Ctrl-C while numba compiles raises KeyboardInterrupt inside llvmlite's ctypes callback,
    where it cannot propagate: Python printed "Exception ignored ... Traceback" through
    ``sys.unraisablehook``. Inside ``watch`` that hook hears nothing of it (the watcher ends the
    process with its one line); another exception from a callback still reaches it."""
    import ctypes
    import sys

    from driver.cli.interrupt import watch
    heard = []
    monkeypatch.setattr(sys, "unraisablehook", lambda info: heard.append(type(info.exc_value)))

    def raising(exc):
        return ctypes.CFUNCTYPE(None)(lambda: (_ for _ in ()).throw(exc()))

    with watch("callback", {2: ("interrupted", 130)}, SystemExit):
        raising(KeyboardInterrupt)()
        raising(ZeroDivisionError)()
    raising(KeyboardInterrupt)()                 # outside the block: the hook hears it again
    assert heard == [ZeroDivisionError, KeyboardInterrupt]


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


# ---------------------------------------------------------------------------------------------
# concurrent processes and the build lock

_BUILD = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from driver.backends.verilate import cached_build
    def build(work):
        time.sleep(1.0)
        with open(sys.argv[1], "a") as f:
            f.write("built\\n")
        (work / "lib.so").write_text("ok")
    print(cached_build("model-k", "lib.so", build, "test model").read_text())
""")


def test_lock_wait_is_announced_and_concurrent_builds_build_once(tmp_path):
    """Issue 11 #4: a wait on another process's build lock printed nothing; issue 11 #2: two
    concurrent builds both built (pyverilator had no lock). All builds share cached_build."""
    cache = tmp_path / "cache"
    (cache / "verilator").mkdir(parents=True)
    log = tmp_path / "builds.txt"
    with open(cache / "verilator" / ".model-k.lock", "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)             # another process holds the lock
        procs = [subprocess.Popen([sys.executable, "-c", _BUILD, str(log)], env=env_for(cache),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for _ in range(3)]
        # Wait until all three block on the held lock (the kernel lists each blocked flock in
        # /proc/locks), however long their imports take on a busy machine.
        inode = os.fstat(held.fileno()).st_ino
        pids = {str(p.pid) for p in procs}

        def blocked():
            lines = Path("/proc/locks").read_text().splitlines()
            return {f.split()[5] for f in lines
                    if "->" in f and f.split()[6].endswith(f":{inode}")} & pids
        wait_for(lambda: blocked() == pids or None, 120, "three builds waiting on the lock")
        assert all(p.poll() is None for p in procs)  # all waiting
    results = [p.communicate(timeout=60) for p in procs]
    assert all(p.returncode == 0 and out.strip() == "ok" for p, (out, _) in zip(procs, results))
    assert log.read_text() == "built\n"              # built once
    assert all("(another process holds the lock)" in err for _, err in results)
    assert not build_dirs(cache)


@pytest.mark.slow
def test_concurrent_cold_cache_renders_with_both_backends(tmp_path):
    """Issue 11 #2: --backend pyverilator failed on a fresh cache; concurrent builds all built."""
    cache = tmp_path / "cache"
    procs = []
    for i, be in enumerate(("rtl", "pyverilator", "rtl", "pyverilator")):
        d = tmp_path / f"w{i}"
        d.mkdir()
        procs.append((d, rayflex("render", "sphere", "--size", "6", "--backend", be,
                                 "--no-progress", cwd=d, env=env_for(cache))))
    errs = []
    for d, p in procs:
        out, err = p.communicate(timeout=1800)
        assert p.returncode == EXIT_OK, err
        assert (d / "sphere.png").is_file()
        errs.append(err)
    text = "".join(errs)
    assert text.count("building Verilator model rayflex") == 1
    assert text.count("building pyverilator model rayflex") == 1
    assert not build_dirs(cache) and not processes_inside(cache)


# ---------------------------------------------------------------------------------------------
# outputs, cache and tools that cannot be used

@contextlib.contextmanager
def read_only_dir(path: Path):
    """A directory that cannot be written: chmod 555, or for root (who ignores modes) a
    read-only tmpfs mounted on it; where root cannot mount either, sysfs's /sys/kernel, in which
    no one can create a file (so the test never skips)."""
    path.mkdir()
    if os.geteuid() != 0:
        path.chmod(0o555)
        try:
            yield path
        finally:
            path.chmod(0o755)
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(path)],
                       capture_output=True)
    if r.returncode != 0:
        yield Path("/sys/kernel")
        return
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], check=False)


def test_read_only_output_dir_fails_before_any_work(tmp_path):
    """Issue 11 #3: an output in a read-only directory (or under /proc) failed after the whole
    render."""
    with read_only_dir(tmp_path / "ro") as ro:
        for out in (str(ro / "x.png"), "/proc/x.png"):
            t0 = time.monotonic()
            p = rayflex("render", "bunny", "--backend", "golden", "--out", out,
                        cwd=tmp_path, env=env_for(tmp_path / "cache"))
            _, err = p.communicate(timeout=120)
            assert p.returncode == EXIT_USAGE
            assert last_line(err).startswith(f"rayflex: error: --out {out}: cannot write in")
            assert len(err.strip().splitlines()) == 1
            assert time.monotonic() - t0 < 30                # no 256 x 256 bunny render first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ro"]


def test_full_disk_on_an_output_write_leaves_nothing(capsys, tmp_path, monkeypatch):
    """A full disk (a write raising ENOSPC) on the last output: exit 2, one line, no file (an
    existing image untouched). Before: a failing --stats-json left the PNGs behind."""
    from driver.core import outputs
    monkeypatch.chdir(tmp_path)
    (tmp_path / "img.png").write_bytes(b"old image")

    def full(doc, path):
        with open(path, "w") as f:
            f.write("{")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    monkeypatch.setattr(outputs, "write_json", full)
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", "--no-progress",
                 "--out", "img.png", "--json", "s.json"]) == EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert err.startswith("rayflex: error: No space left on device") and "\n" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["img.png"]
    assert (tmp_path / "img.png").read_bytes() == b"old image"


def test_read_only_cold_cache_names_rayflex_cache(tmp_path):
    """Issue 11 #6: a read-only cold cache named the lock file but not RAYFLEX_CACHE."""
    for cache in (Path("/proc/rayflex-cache"),):
        p = rayflex("render", "sphere", "--size", "4", "--backend", "rtl", cwd=tmp_path,
                    env=env_for(cache))
        _, err = p.communicate(timeout=120)
        assert p.returncode == EXIT_USAGE
        line = last_line(err)
        assert f"cannot write the build cache {cache}" in line and "RAYFLEX_CACHE" in line
    assert not list(tmp_path.iterdir())


def test_missing_make_gives_the_install_hint(tmp_path):
    """Issue 11 #6: a missing make said "No such file or directory: make"."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in ("g++", "perl", "sh"):                  # everything but make
        found = shutil.which(tool)
        if found:
            (bin_dir / tool).symlink_to(found)
    work = tmp_path / "w"
    work.mkdir()
    p = rayflex("render", "sphere", "--size", "4", "--backend", "rtl", cwd=work,
                env=env_for(tmp_path / "cache", PATH=str(bin_dir)))
    _, err = p.communicate(timeout=120)
    assert p.returncode == EXIT_USAGE
    assert "make not found: install make (Debian: apt-get install make)" in last_line(err)
    assert not list(work.iterdir())


# ---------------------------------------------------------------------------------------------
# a signal once the outputs are written

_LATE_SIGNAL = textwrap.dedent("""
    import os, sys
    import driver.cli.render as render
    import driver.core.outputs as outputs
    where, signum = sys.argv[1], int(sys.argv[2])
    if where == "rename":              # between the renames of the outputs (the first is done)
        replace = os.replace
        def replace_then_signal(a, b):
            replace(a, b)
            if str(b) == "sphere.png":
                os.kill(os.getpid(), signum)
        outputs.os.replace = replace_then_signal
    else:                              # every output in place, the summary not yet printed
        wrote = render.wrote
        def signal_then_wrote(paths):
            os.kill(os.getpid(), signum)
            wrote(paths)
        render.wrote = signal_then_wrote
    from driver.cli import main
    sys.exit(main(sys.argv[3:]))
""")


# each signal and each moment once by default (a render in a fresh process each, ~30 s on a
# loaded 2-core machine); the other two pairings under -m slow
@pytest.mark.parametrize("where, sig, word", [
    ("printing", signal.SIGINT, "interrupted"), ("rename", signal.SIGTERM, "terminated"),
    pytest.param("rename", signal.SIGINT, "interrupted", marks=pytest.mark.slow),
    pytest.param("printing", signal.SIGTERM, "terminated", marks=pytest.mark.slow)])
def test_a_signal_after_the_outputs_are_written_does_not_call_them_lost(tmp_path, where, sig,
                                                                        word):
    """A Ctrl-C that arrived just after ``wrote ...`` exited 130 ("nothing written") though every
    file was complete. The signal is sent from inside the process at that point: while the
    outputs are renamed into place (held back until all are) or once they are all in place."""
    work = tmp_path / "work"
    work.mkdir()
    p = subprocess.run([sys.executable, "-c", _LATE_SIGNAL, where, str(int(sig)), "render",
                        "sphere", "--size", "4", "--backend", "golden", "--no-progress",
                        "--json", "f.json"], cwd=work, env=env_for(tmp_path),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == EXIT_OK, p.stderr
    assert last_line(p.stderr) == (f"rayflex: {word} after the outputs were written: they "
                                   "are complete")
    assert sorted(f.name for f in work.iterdir()) == ["f.json", "sphere.png",
                                                      "sphere_heatmap.png"]
    assert "wrote sphere.png, sphere_heatmap.png, f.json" in p.stdout
    assert json.loads((work / "f.json").read_text())["width"] == 4


_SIGNAL_WHILE_WRITING = textwrap.dedent("""
    import os, signal, sys
    import driver.core.outputs as outputs
    write_json = outputs.write_json
    def write_then_signal(doc, path):
        write_json(doc, path)
        os.kill(os.getpid(), signal.SIGINT)
    outputs.write_json = write_then_signal
    from driver.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_a_signal_while_the_outputs_are_written_leaves_none(tmp_path):
    """The other side of the line: a Ctrl-C while the outputs are being written (the JSON is,
    the renames have not begun) leaves no file and exits 130."""
    work = tmp_path / "work"
    work.mkdir()
    p = subprocess.run([sys.executable, "-c", _SIGNAL_WHILE_WRITING, "render", "sphere",
                        "--size", "4", "--backend", "golden", "--no-progress", "--json",
                        "f.json"], cwd=work, env=env_for(tmp_path), capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 130, p.stderr
    assert last_line(p.stderr) == "rayflex: interrupted"
    assert not list(work.iterdir())
