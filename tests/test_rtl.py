"""The RTL datapath (baseline build) vs the golden model, bit for bit, through both RTL backends.

"rtl" is the fast C++ harness, "pyverilator" the cycle-by-cycle Python driver; every test runs
through ``support.testbench.Testbench`` (driver, monitor, golden reference, scoreboard), most of
them under random input gaps and output stalls as well as without. Each pyverilator testbench runs
in its own process (``run_isolated``: one pyverilator model per build and process). Also: cycle counts (N
back-to-back requests take N + LATENCY cycles), the two backends agreeing cycle for cycle, and the
backends' error paths.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys

import numpy as np
import pytest

import driver
from support.cases import CASES, all_requests
from support.streams import mixed_stream
from support.testbench import PRESSURE_IDS, PRESSURES, Testbench, run_isolated

HEAVY = [(0.1, 0.1), (0.5, 0.5), (0.9, 0.9)]


# ----------------------------------------------------------------------------------------------
# the paper's 20 directed cases (docs/datapath.md#directed-cases)

@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5), (0.9, 0.9)],
                         ids=["steady", "gaps0.5-stalls0.5", "gaps0.9-stalls0.9"])
@pytest.mark.parametrize("name,req,check", CASES, ids=[c[0] for c in CASES])
def test_directed_rtl(name, req, check, gaps, stalls):
    rsp = Testbench("rtl", gaps=gaps, stalls=stalls, seed=len(name)).run(req)
    check(rsp[0])


@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5)], ids=["steady", "gaps0.5-stalls0.5"])
def test_directed_pyverilator_one_stream(gaps, stalls):
    req = all_requests()
    (rsp,), _ = run_isolated("pyverilator", dict(gaps=gaps, stalls=stalls, seed=5), [req])
    for (name, _, check), row in zip(CASES, rsp):
        check(row)


# ----------------------------------------------------------------------------------------------
# random interleaved QUADBOX / TRIANGLE streams

def test_random_100k_rtl():
    req = mixed_stream(1, 60_000, 40_000)
    tb = Testbench("rtl")
    rsp = tb.run(req)
    assert tb.dut.cycles == 100_000 + 11
    assert 0.2 < rsp["box_hit"][req["opcode"] == driver.QUADBOX].mean() < 0.8   # both outcomes
    assert 0.1 < rsp["tri_hit"][req["opcode"] == driver.TRIANGLE].mean() < 0.7


@pytest.mark.parametrize("seed", [2, 3])
@pytest.mark.parametrize("gaps,stalls", PRESSURES[1:], ids=PRESSURE_IDS[1:])
def test_random_under_pressure_rtl(gaps, stalls, seed):
    """No response lost, duplicated or reordered; results unchanged (the testbench checks both)."""
    req = mixed_stream(seed, 6000, 4000)
    tb = Testbench("rtl", gaps=gaps, stalls=stalls, seed=seed)
    rsp = tb.run(req)
    assert tb.dut.cycles > len(req) + 11
    # the same stream without pressure gives the very same responses
    assert rsp.tobytes() == Testbench("rtl").run(req).tobytes()


@pytest.mark.parametrize("gaps,stalls", [(0, 0), *HEAVY], ids=["steady", *PRESSURE_IDS[1:4]])
def test_random_pyverilator(gaps, stalls):
    run_isolated("pyverilator", dict(gaps=gaps, stalls=stalls, seed=7), [mixed_stream(7, 180, 120)])


def test_chunked_runs_equal_one_run():
    req = mixed_stream(8, 3000, 2000)
    whole = Testbench("rtl").run(req)
    tb = Testbench("rtl", gaps=0.3, stalls=0.3, seed=8)
    cuts = np.sort(np.random.default_rng(8).choice(np.arange(1, len(req)), 20, replace=False))
    parts = np.concatenate([tb.run(chunk) for chunk in np.split(req, [0, 1, *cuts, len(req)])])
    assert parts.tobytes() == whole.tobytes()          # same stamped tags too (same sequence)


# ----------------------------------------------------------------------------------------------
# the two RTL backends agree response for response and cycle for cycle

@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("gaps,stalls", [(0, 0), *HEAVY, (0.9, 0.1), (0.1, 0.9)],
                         ids=["steady", *PRESSURE_IDS[1:]])
def test_rtl_and_pyverilator_agree(gaps, stalls, seed):
    req = mixed_stream(20 + seed, 120, 80)
    chunks = (req[:150], req[150:150], req[150:])          # two runs and an empty one
    fast = Testbench("rtl", gaps=gaps, stalls=stalls, seed=seed)
    fast_rsp = [fast.run(c) for c in chunks]
    slow_rsp, slow_runs = run_isolated("pyverilator", dict(gaps=gaps, stalls=stalls, seed=seed),
                                       chunks)
    for a, b in zip(fast_rsp, slow_rsp):
        assert a.tobytes() == b.tobytes()
    assert fast.runs == slow_runs


# ----------------------------------------------------------------------------------------------
# cycles: N back-to-back requests with the output always ready take N + LATENCY

@pytest.mark.parametrize("latency", [10, 11, 14])
def test_cycles_n_plus_latency(latency):
    req = mixed_stream(30, 700, 600)
    be = driver.backend("rtl", latency=latency)
    total = 0
    for n in (1, 2, 3, 10, 11, 12, 13, 100, 1000):
        rsp = be.run(req[:n])
        assert len(rsp) == n
        total += n + latency
        assert be.cycles == total, (n, be.cycles - total)
    assert len(be.run(req[:0])) == 0                    # an empty run adds 0
    assert be.cycles == total
    for n in (1, 5):                                     # a fresh backend counts from 0
        fresh = driver.backend("rtl", latency=latency)
        fresh.run(req[:n])
        assert fresh.cycles == n + latency


@pytest.mark.parametrize("n", [1, 2, 12, 40])
def test_cycles_pyverilator(n):
    req = mixed_stream(31, 30, 30)[:n]
    _, runs = run_isolated("pyverilator", {}, [req, req[:0], req])   # the testbench checks totals
    assert runs == [n + 11, 0, n + 11]


def test_cycles_under_pressure_add_up():
    """Every run's count is at least n + 11; the backend's total is the sum of its runs."""
    req = mixed_stream(32, 300, 200)
    tb = Testbench("rtl", gaps=0.5, stalls=0.5, seed=32)
    for chunk in np.split(req, [1, 2, 100, 100, 400]):
        tb.run(chunk)                                 # the monitor checks each run
    assert tb.dut.cycles == sum(tb.runs) > len(req) + 11 * 5


@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5)], ids=["steady", "gaps0.5-stalls0.5"])
@pytest.mark.parametrize("latency", [10, 14])
def test_other_latency_bit_exact(latency, gaps, stalls):
    """The balanced pipeline (10: S9 beside the output format) and pass-through stages (14)."""
    tb = Testbench("rtl", latency=latency, gaps=gaps, stalls=stalls, seed=latency)
    tb.run(mixed_stream(latency, 3000, 2000))


# ----------------------------------------------------------------------------------------------
# errors

@pytest.mark.parametrize("latency", [9, 5, 0, -1])
def test_latency_below_10_is_a_backend_error(latency, tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))   # a refused build leaves nothing behind
    with pytest.raises(driver.BackendError, match="(?i)latency") as e:
        driver.backend("rtl", latency=latency)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("name", ["rtl", "pyverilator"])
@pytest.mark.parametrize("op", [driver.EUCLIDEAN, driver.ANGULAR])
def test_extended_opcode_on_baseline_build_is_a_datapath_error(name, op):
    req = mixed_stream(40, 5, 5)
    bad = req.copy()
    bad["opcode"][4] = op
    with pytest.raises(driver.DatapathError, match=f"opcode {op}"):
        if name == "rtl":
            driver.backend(name).run(bad)
        else:
            run_isolated(name, {}, [bad])
    tb = Testbench("rtl")
    tb.run(req[:3])
    with pytest.raises(driver.DatapathError):
        tb.dut.run(bad)
    assert tb.dut.cycles == sum(tb.runs)           # nothing was simulated
    tb.run(req)                                        # and the backend still works


def test_missing_compiler_names_it(tmp_path):
    """CXX names a compiler that does not exist and the cache is empty: backend("rtl") cannot build
    and says so in one line naming the compiler. Checked in a fresh process, because a process
    loads each harness build once and keeps it."""
    missing = str(tmp_path / "no-such-g++")
    env = dict(os.environ, CXX=missing, RAYFLEX_CACHE=str(tmp_path / "cache"))
    probe = ("import driver\n"
             "for name in ('rtl', 'pyverilator'):\n"
             "    try:\n"
             "        driver.backend(name)\n"
             "        print(name, 'built')\n"
             "    except driver.BackendError as e:\n"
             "        print(name, 'BackendError', repr(str(e)))\n")
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    lines = dict(ln.split(" ", 1) for ln in out.stdout.splitlines())
    for name in ("rtl", "pyverilator"):
        assert lines[name].startswith("BackendError "), (name, lines[name])
        msg = ast.literal_eval(lines[name].split(" ", 1)[1])
        assert "\n" not in msg and "compiler" in msg, msg
    assert missing in ast.literal_eval(lines["rtl"].split(" ", 1)[1])
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").rglob("rayflex*"))


# ----------------------------------------------------------------------------------------------
# waveform

def test_pyverilator_vcd(tmp_path):
    path = tmp_path / "x.vcd"
    run_isolated("pyverilator", dict(vcd=path, gaps=0.3, stalls=0.3, seed=1), [all_requests()[:4]])
    text = path.read_text(errors="replace")
    assert text.strip() and "clk_i" in text
    assert "$enddefinitions" in text and "#" in text.split("$enddefinitions", 1)[1]


# ----------------------------------------------------------------------------------------------
# heavy variants

@pytest.mark.slow
def test_random_1m_rtl():
    tb = Testbench("rtl")
    for seed in range(10):
        tb.run(mixed_stream(100 + seed, 60_000, 40_000))
    assert tb.dut.cycles == 10 * (100_000 + 11)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("gaps,stalls", PRESSURES[1:], ids=PRESSURE_IDS[1:])
def test_random_under_pressure_rtl_many_seeds(gaps, stalls, seed):
    Testbench("rtl", gaps=gaps, stalls=stalls, seed=200 + seed).run(
        mixed_stream(200 + seed, 60_000, 40_000))


@pytest.mark.slow
@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
def test_rtl_and_pyverilator_agree_long(gaps, stalls):
    req = mixed_stream(300, 1800, 1200)
    fast = Testbench("rtl", gaps=gaps, stalls=stalls, seed=300)
    (slow,), runs = run_isolated("pyverilator", dict(gaps=gaps, stalls=stalls, seed=300), [req])
    assert fast.run(req).tobytes() == slow.tobytes()
    assert fast.runs == runs


# ----------------------------------------------------------------------------------------------
# the testbench itself catches what it is there to catch

class _Faulty:
    """Golden responses with one fault injected (a lost, duplicated, reordered or flipped one)."""

    def __init__(self, fault):
        self.golden, self.fault = driver.backend("golden"), fault
        self.cycles, self.gap, self.stall = 0, None, None

    def run(self, req):
        rsp = self.golden.run(req)
        self.cycles = self.golden.cycles
        if self.fault == "lost":
            rsp = np.delete(rsp, 3)
        elif self.fault == "duplicated":
            rsp[5] = rsp[4]
        elif self.fault == "reordered":
            rsp[[5, 6]] = rsp[[6, 5]]
        elif self.fault == "flipped":
            rsp["t_num"].view(np.uint32)[7] ^= 1
        elif self.fault == "slow":
            self.cycles += 1
        return rsp


@pytest.mark.parametrize("fault,message", [
    ("lost", "responses"), ("duplicated", "duplicated"), ("reordered", "reordered"),
    ("flipped", "t_num"), ("slow", "cycles")])
def test_testbench_catches(fault, message):
    tb = Testbench("golden")
    tb.dut = _Faulty(fault)
    with pytest.raises((AssertionError, pytest.fail.Exception), match=message):
        tb.run(mixed_stream(1, 10, 10))


@pytest.mark.parametrize("name", ["golden", "rtl"])
def test_axis_index_3_rejected_by_every_backend(name):
    """kx/ky/kz = 3 has no meaning (docs/datapath.md#ray-preparation); every backend refuses it
    before simulating."""
    import driver
    from support.cases import tri_request, FRONT
    req = tri_request(FRONT, (0, 0, -1))
    req["kx"] = 3
    with pytest.raises(driver.DatapathError, match="kx/ky/kz"):
        driver.backend(name).run(req)
