"""The shared RTL testbench: driver + monitor + reference model + scoreboard in one small class.

    tb = Testbench("rtl", extended=True, gaps=0.5, stalls=0.5, seed=3)
    rsp = tb.run(requests)           # drives, monitors, checks; returns the DUT's responses

- driver: the backend under test (``driver.backend(name, ...)``), fed the request stream with the
  backend's own random input gaps and output stalls (``gaps=``/``stalls=`` probabilities,
  ``seed=``);
  every request gets a unique tag (a bijective scramble of its sequence number, so all 32 tag bits
  toggle) unless ``stamp=False``.
- monitor: one response per request, in request order: a response whose tag is not the next
  expected one is reported as lost, duplicated or reordered; every response's opcode is the
  request's; the cycles of a run are at least ``n + latency`` (exactly that with no gaps/stalls),
  0 for an empty run, and they add up in ``backend.cycles``.
- reference model: the golden numpy backend of the same configuration, fed the same runs (it keeps
  the EUCLIDEAN/ANGULAR accumulators across runs exactly as the datapath must).
- scoreboard: every field of every response bit for bit equal to the reference; a failure names
  the first bad request with every float as its hex bit pattern.

``run_isolated(name, options, chunks)`` runs a Testbench in a fresh Python process and returns its
responses: one process can hold only one pyverilator model of a given build (a second one aborts the
interpreter: Verilator's "Adding model 'TOP' when time is non-zero", because the pyverilator wrapper
keeps a global time that never resets), and other test files create pyverilator models too.

``PRESSURES`` are the (gaps, stalls) probability pairs tests run under: none, light, heavy, and the
two lopsided mixes.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing

import numpy as np
import pytest

import driver
from driver import RESPONSE_DTYPE
from driver.backends.rtlbase import PATTERN_LEN

from .scoreboard import assert_bit_equal

PRESSURES = [(0.0, 0.0), (0.1, 0.1), (0.5, 0.5), (0.9, 0.9), (0.9, 0.1), (0.1, 0.9)]
PRESSURE_IDS = [f"gaps{g}-stalls{s}" for g, s in PRESSURES]

_TAG_MUL = 0x9E3779B1          # odd: n -> n * _TAG_MUL mod 2^32 is a bijection


def tags_for(seq: np.ndarray) -> np.ndarray:
    """Unique 32-bit tags for sequence numbers (all bits toggle)."""
    return (seq.astype(np.uint64) * _TAG_MUL + 0x5A5A5A5A).astype(np.uint32)


def burst_pattern(on: int, off: int, phase: int = 0) -> np.ndarray:
    """A deterministic gap/stall pattern of the backends' length: ``on`` cycles 1, ``off`` 0."""
    k = (np.arange(PATTERN_LEN) + phase) % (on + off)
    return (k < on).astype(np.uint8)


class Testbench:
    """One DUT backend and its golden reference, checked on every run (see module docstring)."""

    __test__ = False                # a helper, not a test class for pytest to collect

    def __init__(self, name: str = "rtl", *, extended: bool = False, disjoint: bool = False,
                 latency: int | None = None, compressed: bool = False, transform: bool = False,
                 fused: bool = False, shared: bool = False, gaps: float = 0.0,
                 stalls: float = 0.0, seed: int = 0, stamp: bool = True, **options):
        if name != "golden":        # the golden model has no handshakes to pressure
            options.update(gaps=gaps, stalls=stalls, seed=seed)
        self.dut = driver.backend(name, extended=extended, disjoint=disjoint, latency=latency,
                                  compressed=compressed, transform=transform, fused=fused,
                                  **({"shared": True} if shared else {}), **options)
        self.ref = driver.backend("golden", extended=extended, disjoint=disjoint,
                                  latency=self.dut.latency, compressed=compressed,
                                  transform=transform, fused=fused)
        self.name = name
        self.latency = self.dut.latency
        self.stamp = stamp
        self.sent = 0               # requests driven so far (sequence numbers for the tags)
        self.runs = []              # cycles of each run

    @property
    def pressure_free(self) -> bool:
        return getattr(self.dut, "gap", None) is None and getattr(self.dut, "stall", None) is None

    def set_patterns(self, gap: np.ndarray | None = None, stall: np.ndarray | None = None):
        """Replace the random gap/stall patterns by explicit ones (PATTERN_LEN 0/1 cycles)."""
        for p in (gap, stall):
            assert p is None or (p.shape == (PATTERN_LEN,) and p.dtype == np.uint8)
        self.dut.gap, self.dut.stall = gap, stall

    # ---- driver ----
    def drive(self, req: np.ndarray) -> np.ndarray:
        req = np.array(req, copy=True)
        if self.stamp:
            req["tag"] = tags_for(np.arange(self.sent, self.sent + len(req)))
        self.sent += len(req)
        before = self.dut.cycles
        rsp = self.dut.run(req)
        self.runs.append(self.dut.cycles - before)
        return req, rsp

    # ---- monitor ----
    def monitor(self, req: np.ndarray, rsp: np.ndarray) -> None:
        n = len(req)
        assert rsp.dtype == RESPONSE_DTYPE
        assert len(rsp) == n, f"{self.name}: {n} requests but {len(rsp)} responses"
        want, got = req["tag"], rsp["tag"]
        bad = np.flatnonzero(want != got)
        if len(bad):
            i = int(bad[0])
            tag = int(got[i])
            pos = np.flatnonzero(want == tag)
            if not len(pos):
                what = "is not the tag of any request (corrupted)"
            elif pos[0] < i:
                what = f"repeats request {int(pos[0])} (duplicated)"
            else:
                what = f"belongs to request {int(pos[0])} (reordered, or request {i} lost)"
            missing = np.setdiff1d(want, got).size
            pytest.fail(f"{self.name}: response {i} has tag {tag:#010x}, expected "
                        f"{int(want[i]):#010x}: it {what}; {missing} request tags never came back")
        assert (rsp["opcode"] == req["opcode"]).all(), f"{self.name}: opcode changed"
        cycles = self.runs[-1]
        if n == 0:
            assert cycles == 0, f"{self.name}: an empty run took {cycles} cycles"
        elif self.pressure_free:
            assert cycles == n + self.latency, (f"{self.name}: {n} back-to-back requests took "
                                                f"{cycles} cycles, not n + {self.latency}")
        else:
            assert cycles >= n + self.latency, f"{self.name}: {n} requests in {cycles} cycles"
        assert self.dut.cycles == sum(self.runs)

    # ---- reference model + scoreboard ----
    def scoreboard(self, req: np.ndarray, rsp: np.ndarray) -> None:
        with np.errstate(all="ignore"):
            want = self.ref.run(req)
        assert_bit_equal(req, rsp, want, self.name)

    def run(self, req: np.ndarray) -> np.ndarray:
        """Drive one run, check it, return the DUT's responses (tags as stamped)."""
        req, rsp = self.drive(req)
        self.monitor(req, rsp)
        self.scoreboard(req, rsp)
        return rsp


def run_isolated(name: str, options: dict, chunks, patterns=None):
    """``Testbench(name, **options)`` run over each request array in ``chunks`` (all checks
    applied) in a fresh spawned Python process. Returns (responses per chunk, cycles per chunk). A
    failed check fails the calling test with the child's message; other exceptions are re-raised
    here."""
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx) as pool:
        status, payload = pool.submit(_isolated_child, name, options, list(chunks),
                                      patterns).result()
    if status == "failed":
        pytest.fail(payload, pytrace=False)
    if status == "raised":
        raise payload
    return payload


def _isolated_child(name, options, chunks, patterns):
    try:
        tb = Testbench(name, **options)
        if patterns is not None:
            tb.set_patterns(*patterns)
        out = [tb.run(c) for c in chunks]
        assert tb.dut.cycles == sum(tb.runs)
        return "ok", (out, tb.runs)
    except Exception as e:               # noqa: BLE001  (AssertionError included)
        if isinstance(e, AssertionError):
            return "failed", f"{name} (in a subprocess): AssertionError: {e}"
        return "raised", e
    except BaseException as e:           # pytest.fail's Failed is not an Exception
        return "failed", f"{name} (in a subprocess): {e}"


def assert_pyverilator_equals_rtl(req, options: dict, split: int) -> None:
    """``req`` in two chunks (at ``split``) on pyverilator, in its own process, and on the rtl
    fast path with the same ``options``: identical responses per chunk and identical cycles."""
    chunks = [req[:split], req[split:]]
    py, py_cycles = run_isolated("pyverilator", options, chunks)
    tb = Testbench("rtl", **options)
    for c, p in zip(chunks, py):
        assert tb.run(c).tobytes() == p.tobytes()
    assert tb.runs == py_cycles
