"""Switching activity from the harnesses' toggle counter (``sim/rf_toggles.h``, the power flow's
level ``signals``, docs/power.md): the build arguments of a traced model, the nets' names from
the VCD declarations, and the counted bit toggles per net.

Verilator gives a net one VCD identifier however many scopes it appears in (ports, continuous
assignments), so a net is one index here with every name it has.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .build import SIM_DIR

HEADER = SIM_DIR / "rf_toggles.h"
# Verilator traces arrays up to --trace-max-array elements and variables up to --trace-max-width
# bits (defaults 32 and 256; an array's width is all its elements' bits): the RT unit's stack
# RAM, ray records and node buffer are far bigger (RAYS 256 x STACK_DEPTH 4096 x 32 bits: 2**25)
TRACE_MAX_ARRAY = 1 << 20
TRACE_MAX_WIDTH = 1 << 26


def trace_args(every_net: bool = True) -> list[str]:
    """Verilator arguments of a traced model whose harness includes ``rf_toggles.h``: the
    header's directory and ``RF_TOGGLES`` defined as the header's hash (the build cache keys the
    arguments, so a changed counter is a new build); ``every_net``: every array and vector
    traced (the RT unit's measurement, and the datapath measured beside it); without it
    Verilator's default limits (the datapath's published figures, docs/power.md)."""
    digest = hashlib.sha256(HEADER.read_bytes()).hexdigest()[:16]
    wide = ["--trace-max-array", str(TRACE_MAX_ARRAY), "--trace-max-width",
            str(TRACE_MAX_WIDTH)] if every_net else []
    return ["--trace", *wide, "-CFLAGS", f"-I{SIM_DIR}", "-CFLAGS", f"-DRF_TOGGLES=0x{digest}"]


def declarations(lines) -> tuple[dict[str, int], list[list[str]]]:
    """(identifier -> net index, every net's names ``TOP.scope....name``) of VCD declaration
    lines (an iterable of text lines; reading stops at ``$enddefinitions``)."""
    codes: dict[str, int] = {}
    names: list[list[str]] = []
    scope: list[str] = []
    for line in lines:
        w = line.split()
        if not w:
            continue
        if w[0] == "$scope":
            scope.append(w[2])
        elif w[0] == "$upscope":
            scope.pop()
        elif w[0] == "$var":
            code, name = w[3], w[4]
            if code not in codes:
                codes[code] = len(codes)
                names.append([])
            names[codes[code]].append(".".join([*scope, name]))
        elif w[0] == "$enddefinitions":
            break
    return codes, names


def read_counts(path: Path, codes: dict[str, int]) -> np.ndarray:
    """The counter's "identifier toggles" lines at ``path`` as toggles per net (``codes``)."""
    out = np.zeros(len(codes))
    for line in Path(path).read_text().splitlines():
        code, n = line.rsplit(" ", 1)
        out[codes[code]] = float(n)
    return out
