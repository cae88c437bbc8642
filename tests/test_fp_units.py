"""Bit-exact tests of the binary32 units (rtl/rf_fp_*.sv) against numpy float32, plus the
Verilator build system (driver/backends/verilate.py) they run on.

Every unit sees the same operand mix (tests/support/fpu.py: random bits, subnormals, specials,
rounding ties and near-ties, overflow, underflow, cancellation, exponent differences 20..29,
compare edges).
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from driver.backends import verilate
from driver.backends.verilate import BuildError, build_library, find_cxx, lint
from support.fpu import (FPU_HARNESS, FPU_TB_SOURCES, OUTPUTS, UNIT_SOURCES, FpuModel,
                        exact_tie_fraction, gen_add_ties, gen_mul_ties, operand_mix, reference)

DEFAULT_PER_CATEGORY = 16384     # 12 categories -> 196,608 pairs per unit (~0.2 s)
SLOW_PAIRS = 16_000_000          # per unit, in chunks of 12 * 131,072 (~10 s)
MAX_REPORTED = 8


@pytest.fixture(scope="module")
def fpu():
    return FpuModel()


def check(fpu: FpuModel, a: np.ndarray, b: np.ndarray, cat: np.ndarray,
          outputs=OUTPUTS) -> None:
    """Run the RTL and the reference on (a, b); fail listing the first mismatches in hex."""
    got = fpu.run(a, b)
    want = reference(a, b)
    errors = []
    for name in outputs:
        bad = np.flatnonzero(got[name] != want[name])
        if bad.size:
            fmt = (lambda v: f"0x{int(v):08x}") if got[name].dtype == np.uint32 else bool
            rows = [f"  a=0x{int(a[i]):08x} b=0x{int(b[i]):08x} rtl={fmt(got[name][i])} "
                    f"numpy={fmt(want[name][i])} [{cat[i]}]" for i in bad[:MAX_REPORTED]]
            errors.append(f"{name}: {bad.size} of {a.size} pairs differ, first ones:\n"
                          + "\n".join(rows))
    if errors:
        pytest.fail("\n".join(errors), pytrace=False)


# ------------------------------------------------------------------------------------------------
# Bit-exact checks


@pytest.fixture(scope="module")
def mix():
    return operand_mix(np.random.default_rng(20240601), DEFAULT_PER_CATEGORY)


@pytest.mark.parametrize("unit,outputs", [
    ("add", ("add",)), ("sub", ("sub",)), ("mul", ("mul",)),
    ("cmp", ("lt", "le", "eq", "unord")), ("minmax", ("min", "max")),
])
def test_unit_matches_numpy(fpu, mix, unit, outputs):
    a, b, cat = mix
    assert a.size >= 50_000
    check(fpu, a, b, cat, outputs)


def test_exhaustive_special_pairs(fpu):
    """Every pair of a list of special and boundary values, in both orders."""
    from support.fpu import SPECIALS
    a, b = np.meshgrid(SPECIALS, SPECIALS)
    a, b = a.ravel().astype(np.uint32), b.ravel().astype(np.uint32)
    check(fpu, a, b, np.full(a.size, "special_pairs"))


def test_generators_make_real_ties():
    """The tie categories really are exact halfway cases (so the RNE tie path is exercised)."""
    rng = np.random.default_rng(7)
    assert exact_tie_fraction(*gen_add_ties(rng, 20000), "add") > 0.9
    assert exact_tie_fraction(*gen_mul_ties(rng, 20000), "mul") > 0.99


@pytest.mark.slow
def test_slow_many_pairs(fpu):
    rng = np.random.default_rng(99)
    per_cat = 1 << 17
    done = 0
    while done < SLOW_PAIRS:
        a, b, cat = operand_mix(rng, per_cat)
        check(fpu, a, b, cat)
        done += a.size
    assert done >= 1_000_000


# ------------------------------------------------------------------------------------------------
# Lint


@pytest.mark.parametrize("unit", sorted(UNIT_SOURCES))
def test_unit_lint_clean(unit):
    assert lint(unit, UNIT_SOURCES[unit]) == ""


def test_tb_top_lint_clean():
    assert lint("fpu_tb_top", FPU_TB_SOURCES) == ""


def test_lint_reports_errors(tmp_path):
    bad = tmp_path / "bad.sv"
    bad.write_text("module bad (input logic a_i, output logic [1:0] y_o);\n"
                   "  assign y_o = a_i;\nendmodule\n")   # WIDTH warning under -Wall
    with pytest.raises(BuildError, match="WIDTH"):
        lint("bad", [bad])


# ------------------------------------------------------------------------------------------------
# Build system

TINY_SV = """module tiny #(parameter int unsigned K = 1) (
  input  logic [31:0] a_i,
  output logic [31:0] y_o
);
  assign y_o = a_i + K;
endmodule
"""
TINY_CPP = """#include <cstdint>
#include "Vtiny.h"
extern "C" __attribute__((visibility("default"))) uint32_t tiny_eval(uint32_t a) {
  static Vtiny* top = new Vtiny;
  top->a_i = a;
  top->eval();
  return top->y_o;
}
"""


def test_missing_compiler_raises(monkeypatch, tmp_path):
    monkeypatch.setenv("CXX", str(tmp_path / "no-such-c++"))
    with pytest.raises(BuildError, match="no C\\+\\+ compiler found"):
        find_cxx()
    with pytest.raises(BuildError, match="no C\\+\\+ compiler found"):
        build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS)
    monkeypatch.delenv("CXX")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(BuildError, match="apt-get install g\\+\\+"):
        find_cxx()


def test_cache_key_depends_on_inputs(tmp_path):
    sv = tmp_path / "tiny.sv"
    sv.write_text(TINY_SV)
    vbin, cxx = verilate.verilator_bin(), find_cxx()
    key = lambda params, vargs, train=None: verilate._cache_key(  # noqa: E731
        "tiny", [sv], [], params, vargs, vbin, cxx, train)
    base = key({}, [])
    assert key({}, []) == base
    assert key({"K": 2}, []) != base
    assert key({}, ["-Wno-WIDTH"]) != base
    assert key({}, [], ["python", "-m", "train"]) != base        # a profile-guided build
    # the same Verilator installed elsewhere (another venv) keys the same builds; another doesn't
    other = tmp_path / "elsewhere" / "bin"
    other.mkdir(parents=True)
    for f in ("verilator", "verilator_bin"):
        shutil.copy2(vbin.resolve().parent / f, other / f)
    moved = lambda: verilate._cache_key("tiny", [sv], [], {}, [], other / "verilator", cxx,  # noqa: E731
                                        None)
    assert moved() == base
    with open(other / "verilator_bin", "ab") as f:
        f.write(b"\0")
    assert moved() != base
    sv.write_text(TINY_SV + "// changed\n")
    assert key({}, []) != base


def test_build_is_cached_and_locked(tmp_path, monkeypatch, capfd):
    """Two processes build the same model at once: one builds, the other waits and reuses it.
    A later call is a cache hit that runs no subprocess at all and prints nothing."""
    sv, cpp = tmp_path / "tiny.sv", tmp_path / "tiny.cpp"
    sv.write_text(TINY_SV)
    cpp.write_text(TINY_CPP)
    cache = tmp_path / "cache"
    monkeypatch.setenv("RAYFLEX_CACHE", str(cache))
    script = ("import sys; from pathlib import Path; from driver.backends.verilate import build_library;"
              f"print(build_library('tiny', [Path({str(sv)!r})], [Path({str(cpp)!r})], "
              "params={'K': 5}))")
    procs = [subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), results
    paths = {out.strip() for out, _ in results}
    assert len(paths) == 1
    messages = [err for _, err in results if "building Verilator model tiny" in err]
    assert len(messages) == 1, results          # built exactly once

    def no_subprocess(*args, **kwargs):
        raise AssertionError("cache hit must not run Verilator or the compiler")

    monkeypatch.setattr(subprocess, "run", no_subprocess)
    monkeypatch.setattr(subprocess, "Popen", no_subprocess)
    capfd.readouterr()
    t0 = time.perf_counter()
    lib = build_library("tiny", [sv], [cpp], params={"K": 5})
    elapsed = time.perf_counter() - t0
    assert str(lib) == paths.pop()
    assert elapsed < 0.5
    assert capfd.readouterr() == ("", "")
    dll = ctypes.CDLL(str(lib))
    dll.tiny_eval.restype = ctypes.c_uint32
    dll.tiny_eval.argtypes = [ctypes.c_uint32]
    assert dll.tiny_eval(37) == 42
    assert not list(cache.glob(".tmp-*"))        # temporary build dirs are gone


def test_fpu_model_second_build_is_cache_hit(fpu, monkeypatch):
    def no_subprocess(*args, **kwargs):
        raise AssertionError("cache hit must not run Verilator or the compiler")

    monkeypatch.setattr(subprocess, "run", no_subprocess)
    t0 = time.perf_counter()
    assert build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS) == fpu.library
    assert time.perf_counter() - t0 < 0.5


def test_build_error_is_one_line_with_log(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path / "cache"))
    sv = tmp_path / "broken.sv"
    sv.write_text("module broken (input logic a_i, output logic y_o);\n"
                  "  assign y_o = a_i +;\nendmodule\n")
    with pytest.raises(BuildError) as info:
        build_library("broken", [sv], [])
    msg = str(info.value)
    assert "\n" not in msg and "syntax error" in msg and "broken.sv" in msg
    log = Path(msg.rsplit("(log: ", 1)[1].rstrip(")"))
    assert log.is_file() and "syntax error" in log.read_text()
