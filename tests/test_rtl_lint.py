"""``verilator --lint-only -Wall`` is clean on every build of the datapath (waivers with their
reasons in rtl/lint.vlt)."""

from __future__ import annotations

import re

import pytest

from driver.backends import verilate
from driver.backends import BackendError
from driver.backends import build as rtl
from driver.backends.verilate import BuildError


@pytest.mark.parametrize("extended,disjoint,latency,compressed", [
    (False, False, 11, False), (False, True, 11, False), (True, False, 11, False),
    (True, True, 11, False), (False, False, 14, False), (True, True, 14, False),
    (False, False, 12, True), (False, True, 12, True), (True, False, 12, True),
    (True, True, 14, True), (False, False, 10, False), (True, True, 11, True)],
    ids=["baseline-unified", "baseline-disjoint", "extended-unified", "extended-disjoint",
         "baseline-latency14", "extended-disjoint-latency14", "baseline-unified-q8",
         "baseline-disjoint-q8", "extended-unified-q8", "extended-disjoint-q8-latency14",
         "baseline-latency10", "extended-disjoint-q8-latency11"])
def test_lint_clean(extended, disjoint, latency, compressed):
    assert rtl.lint(extended, disjoint, latency, compressed) == ""


@pytest.mark.parametrize("extended,disjoint,compressed,transform", [
    (False, False, False, False), (False, True, False, False), (True, False, True, True),
    (True, True, False, True)],
    ids=["baseline-unified", "baseline-disjoint", "extended-unified-q8-xf",
         "extended-disjoint-xf"])
def test_lint_clean_fused(extended, disjoint, compressed, transform):
    """The FUSED build (one rounding in the box slab and the edge functions) is lint clean, and
    so is an extended one with SHARED request registers."""
    assert rtl.lint(extended, disjoint, None, compressed, transform, fused=True) == ""
    if extended:
        assert rtl.lint(extended, disjoint, None, compressed, transform, shared=True) == ""


def test_rtl_rejects_latency_below_11_with_the_decode():
    with pytest.raises(BackendError, match="at least 11"):
        rtl.lint(latency=10, compressed=True)
    params = {"EXTENDED": 0, "DISJOINT": 0, "COMPRESSED": 1, "LATENCY": 10}
    with pytest.raises(BuildError, match="(?i)latency"):
        verilate.lint(rtl.TOP, [rtl.RTL_DIR / rtl.LINT_WAIVERS, *rtl.rtl_sources()], params)


def test_rtl_rejects_latency_below_10():
    """The top's own elaboration check, independent of the driver's parameter check."""
    with pytest.raises(BackendError, match="at least 10"):
        rtl.lint(latency=9)                        # the driver's check
    params = {"EXTENDED": 0, "DISJOINT": 0, "LATENCY": 9}
    with pytest.raises(BuildError, match="(?i)latency"):   # the RTL's own elaboration check
        verilate.lint(rtl.TOP, [rtl.RTL_DIR / rtl.LINT_WAIVERS, *rtl.rtl_sources()], params)


def _waiver_lines() -> list[int]:
    lines = (rtl.RTL_DIR / rtl.LINT_WAIVERS).read_text().splitlines()
    return [i for i, ln in enumerate(lines) if ln.strip().startswith("lint_off")]


@pytest.mark.parametrize("line", _waiver_lines())
def test_every_waiver_is_needed(line, tmp_path):
    """Without any one waiver, lint of some build fails: no stale waivers (each lint_off names
    signals that exist and warn)."""
    lines = (rtl.RTL_DIR / rtl.LINT_WAIVERS).read_text().splitlines()
    del lines[line]
    vlt = tmp_path / rtl.LINT_WAIVERS
    vlt.write_text("\n".join(lines) + "\n")
    for extended, disjoint, compressed in ((False, False, False), (True, True, False),
                                           (False, True, False), (True, False, False),
                                           (False, False, True)):
        try:
            verilate.lint(rtl.TOP, [vlt, *rtl.rtl_sources()],
                          rtl.rtl_params(extended, disjoint, None, compressed))
        except BuildError:
            return
    pytest.fail(f"lint passes without waiver line {line + 1} of rtl/{rtl.LINT_WAIVERS}")


def test_every_waiver_has_a_reason():
    """Each lint_off in rtl/lint.vlt sits under a comment that says why."""
    lines = (rtl.RTL_DIR / rtl.LINT_WAIVERS).read_text().splitlines()
    waivers = [i for i, ln in enumerate(lines) if ln.strip().startswith("lint_off")]
    assert waivers
    for i in waivers:
        assert re.search(r"-rule \w+", lines[i]) and "-file" in lines[i], lines[i]  # no blanket
        j = i - 1
        while j >= 0 and lines[j].strip().startswith("lint_off"):
            j -= 1
        assert j >= 0 and lines[j].strip().startswith("//") and len(lines[j]) > 20, lines[i]
