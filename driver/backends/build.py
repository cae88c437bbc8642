"""Building the RTL backends: the source list, the parameters, lint, and the harness library
(Verilator through ``driver.backends.verilate``, with the generated layout header and the
profile-guided policy).

The harness library is ``sim/rayflex_harness.cpp`` (streaming) + ``sim/rtunit_scheduler.cpp``
(the RT-unit replay) over the Verilated model, compiled with ``rf_layout.h``, which
``driver.core.layout.c_header()`` generates into the build cache (a directory named by the header's
hash, so a layout change is a new cache entry). Profile-guided optimisation is on unless
``RAYFLEX_PGO=0``: the training workload (``driver.pgo``) runs in a separate Python process on
the instrumented library, so this module does not import the application.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from ..core import layout
from . import verilate
from ..core.resources import ROOT, data_dir
from ..core.datapath import LEAST_LATENCY, default_latency, least_latency
from .base import BackendError

RTL_DIR = data_dir("rtl")
SIM_DIR = data_dir("sim")
TOP = "rayflex"
SOURCE_LIST = RTL_DIR / "sources.txt"
# The binary32 divider (rf_fp_div, with the FP package it imports) has a list of its own: the
# datapath does not use it, and every file of SOURCE_LIST is part of the datapath build's cache key.
DIV_SOURCE_LIST = RTL_DIR / "fp_div_sources.txt"
LINT_WAIVERS = "lint.vlt"
HARNESS_SOURCES = ("rayflex_harness.cpp", "rtunit_scheduler.cpp")
# included by the harness sources from their own directory: their text is hashed into the name of
# the generated header's directory, which is part of the build's cache key
HARNESS_HEADERS = ("rf_sim.h", "rf_memory.h")
MIN_LATENCY = LEAST_LATENCY           # input register, S1..S8, S9 with the output format


def source_names(list_file: Path = SOURCE_LIST) -> list[str]:
    """The RTL file names of ``rtl/sources.txt``, in compile order."""
    try:
        text = list_file.read_text()
    except OSError as e:
        raise BackendError(f"RTL source list {list_file} not readable ({e.strerror}): the RTL "
                           "backends need the project's source tree (pip install -e .)") from None
    return parse_source_list(text)


def parse_source_list(text: str) -> list[str]:
    """The file names of a ``sources.txt`` text (one a line; blank lines and # comments skipped)."""
    return [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def rtl_sources(list_file: Path = SOURCE_LIST) -> list[Path]:
    """The RTL files of a source list (default: the datapath's) in compile order; BackendError if
    the source tree is not there."""
    paths = [RTL_DIR / f for f in source_names(list_file)]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        raise BackendError(f"RTL source {missing[0]} not found: the RTL backends need the project's "
                           "source tree (install with pip install -e .)")
    return paths


def rtl_params(extended: bool, disjoint: bool, latency: int | None = None,
               compressed: bool = False, transform: bool = False,
               fused: bool = False, shared: bool = False) -> dict[str, int]:
    """The top-level parameters of a configuration (``-G`` overrides); ``latency`` None: the
    configuration's default (``driver.core.datapath.default_latency``; at least
    ``least_latency``); FUSED and SHARED only when set (the other builds keep their names in the
    build cache)."""
    least = least_latency(compressed)
    latency = default_latency(compressed) if latency is None else latency
    if int(latency) < least:
        raise BackendError(f"latency {latency}: the RTL needs at least {least} stages (the input "
                           "register, S1 to S8, S9 with the output format"
                           f"{', the q8 decode stage' if compressed else ''})")
    return {"EXTENDED": int(bool(extended)), "DISJOINT": int(bool(disjoint)),
            "COMPRESSED": int(bool(compressed)), "TRANSFORM": int(bool(transform)),
            "LATENCY": int(latency), **({"FUSED": 1} if fused else {}),
            **({"SHARED": 1} if shared else {})}


def backend_params(be) -> dict[str, int]:
    """The build parameters of the datapath backend ``be`` models: a ``Backend``'s ``params``;
    for an object with only ``run`` and ``cycles`` (e.g. a wrapper that records another
    backend's calls) those of the ``Backend`` attributes it has, the rest the baseline's."""
    params = getattr(be, "params", None)
    if isinstance(params, dict) and {"EXTENDED", "DISJOINT", "LATENCY"} <= set(params):
        return dict(params)
    lat = getattr(be, "latency", MIN_LATENCY)
    compressed = bool(getattr(be, "compressed", False))
    return rtl_params(getattr(be, "extended", False), getattr(be, "disjoint", False),
                      lat if isinstance(lat, int) and lat >= MIN_LATENCY + compressed else None,
                      compressed, bool(getattr(be, "transform", False)),
                      bool(getattr(be, "fused", False)), bool(getattr(be, "shared", False)))


def lint(extended=False, disjoint=False, latency=None, compressed=False, transform=False,
         fused=False, shared=False) -> str:
    """``verilator --lint-only -Wall`` of the whole datapath with the waivers in rtl/lint.vlt."""
    return verilate.lint(TOP, [RTL_DIR / LINT_WAIVERS, *rtl_sources()],
                         rtl_params(extended, disjoint, latency, compressed, transform, fused,
                                    shared))


def pgo_enabled() -> bool:
    """Whether the harness is built with profile-guided optimisation (``driver.pgo``): yes unless
    the environment sets ``RAYFLEX_PGO=0`` (a faster first build, a slower simulation)."""
    value = os.environ.get("RAYFLEX_PGO", "1").strip().lower()
    if value not in ("0", "1", "no", "yes", "off", "on", "false", "true", ""):
        raise BackendError(f"RAYFLEX_PGO={value!r}: use 1 (profile-guided build, the default) or 0")
    return value not in ("0", "no", "off", "false")


def layout_header_dir() -> Path:
    """A cache directory holding ``rf_layout.h`` as ``driver.core.layout`` generates it now (named
    by the header's hash; written atomically, so concurrent processes may race safely)."""
    text = layout.c_header()
    for name in HARNESS_HEADERS:
        text += (SIM_DIR / name).read_text()     # the shared harness header travels along
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    root = verilate.cache_dir()
    out = root / "gen" / f"layout-{digest}"
    header = out / "rf_layout.h"
    if not header.is_file():
        try:
            out.mkdir(parents=True, exist_ok=True)
            tmp = out / f".rf_layout.h.{os.getpid()}"
            tmp.write_text(layout.c_header())
            os.replace(tmp, header)
        except OSError as e:
            raise BackendError(f"cannot write the build cache {root}: {e.strerror} (set "
                               "RAYFLEX_CACHE to a writable directory)") from None
    return out


def build_harness(params: dict[str, int]) -> Path:
    """Build (or find in the cache) the harness library for ``params``; returns its path."""
    name = "rayflex_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
    train = train_env = None
    if pgo_enabled():
        train = [verilate.PYTHON, "-m", "driver.pgo", json.dumps(params, sort_keys=True)]
        train_env = {"PYTHONPATH": os.pathsep.join(
            [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    try:
        include = layout_header_dir()
        return verilate.build_library(
            TOP, rtl_sources(), [SIM_DIR / f for f in HARNESS_SOURCES], params=params, name=name,
            verilator_args=["-CFLAGS", f"-I{include}", "-CFLAGS",
                            f"-DRF_COMPRESSED={int(params.get('COMPRESSED', 0))}"], train=train,
            train_env=train_env)
    except verilate.BuildError as e:
        raise BackendError(f"cannot build the RTL backend: {e}") from None
