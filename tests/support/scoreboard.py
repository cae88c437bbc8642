"""Bit-exact comparison of two response arrays: the scoreboard of every datapath test.

    assert_bit_equal(req, got, want, name="rtl", ref="golden")

Every field of every response must be equal bit for bit (floats compared as their uint32 patterns,
so NaN payloads, -0 and subnormals count); a failure names the first bad request and shows the
two responses and the request with every float as its hex bit pattern.
"""

from __future__ import annotations

import numpy as np
import pytest

from driver import RESPONSE_DTYPE


def bits(a) -> np.ndarray:
    """Floats as their uint32 bit patterns; other arrays unchanged."""
    a = np.ascontiguousarray(a)
    return a.view(np.uint32) if a.dtype.kind == "f" else a


def hexrow(row) -> str:
    """A request/response row with every float shown as its uint32 hex pattern."""
    parts = []
    for name in row.dtype.names:
        v = np.asarray(row[name])
        if v.dtype.kind == "f":
            v = np.vectorize(lambda x: f"0x{x:08x}")(bits(v))
        parts.append(f"{name}={v.tolist()}")
    return " ".join(parts)


def assert_bit_equal(req, got, want, name: str = "rtl", ref: str = "golden") -> None:
    """Every field of every response in ``got`` (from ``name``) equal bit for bit to ``want`` (from
    ``ref``); on failure name the first bad request."""
    assert got.dtype == RESPONSE_DTYPE and want.dtype == RESPONSE_DTYPE
    assert len(got) == len(want) == len(req)
    for field in RESPONSE_DTYPE.names:
        g, w = bits(got[field]), bits(want[field])
        bad = g != w
        if bad.ndim > 1:
            bad = bad.reshape(len(bad), int(np.prod(bad.shape[1:]))).any(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            width = max(len(name), len(ref)) + 1
            pytest.fail(f"{name} vs {ref}: {int(bad.sum())} mismatches in field {field!r}; "
                        f"first at request {i}:\n  {name + ':':{width}} {hexrow(got[i])}\n"
                        f"  {ref + ':':{width}} {hexrow(want[i])}\n"
                        f"  {'request:':{width}} {hexrow(req[i])}")
