"""The Verilator builds the suite makes before its first test (``RTL_BUILDS`` in
tests/conftest.py), named by one string each:

  ``CONFIG``                    the "rtl" harness of configuration CONFIG (driver/core/configs.py;
                                ``CONFIG@N``: latency N), without profile guidance
  ``pgo:CONFIG``                the same with profile guidance (the build `rayflex` makes)
  ``pyverilator:CONFIG``        the pyverilator model of CONFIG
  ``signals:CONFIG``            the power flow's traced model of CONFIG (``rayflex power``)
  ``signals-all:CONFIG``        the same with every net traced (beside the traced RT unit)
  ``rtunit:CONFIG:RAYS:DEPTH``  the RT unit in RTL with RAYS slots and stacks of DEPTH entries
  ``rtunit:CONFIG:RAYS:DEPTH:P`` the same with P datapath pipelines (1 without the field)
  ``rtunit:CONFIG:RAYS:DEPTH:P:cull`` the same with the distance-culled stack (CULL)
  ``activity:CONFIG:RAYS:DEPTH`` the same traced, counting its switching activity
                                (``rayflex power --backend rtunit``)
  ``tb:NAME``                   a module testbench, ``TESTBENCHES[NAME]`` (rtu_units: the RT
                                unit's modules side by side, tests/test_rtunit_modules.py)

``build(spec)`` makes (or finds in the cache) exactly the library the tests then load, through
the same functions they use, so a spec that drifts from what a test asks for only costs time."""

from __future__ import annotations

import os

from driver.core.configs import parse_config

# The RT unit most of the suite's unit tests share (its ray slots and stack depth): one build,
# rtunit:CONFIG:SUITE_RAYS:SUITE_DEPTH (and :2 with two pipelines). 16 slots keep one pipeline
# busy at a short memory latency, which the pipelines' test needs.
SUITE_RAYS, SUITE_DEPTH = 16, 32
KINDS = ("harness", "pgo", "pyverilator", "signals", "signals-all", "rtunit", "activity", "tb")
UNIT_KINDS = ("rtunit", "activity")      # CONFIG:RAYS:DEPTH
# sim/rtu_units_tb_top.sv's parameters in tests/test_rtunit_modules.py (its testbench, sim/
# rtu_units_tb.cpp, assumes RAYS 4)
RTU_UNITS_PARAMS = {"RAYS": 4, "STACK_DEPTH": 3, "DIVIDERS": 3, "PIPE_RAYS": 16}


def rtu_units_library():
    """The path of the RT unit's modules side by side (sim/rtu_units_tb_top.sv) with their
    testbench (sim/rtu_units_tb.cpp), built on first use; the datapath (rtl/rayflex.sv) is
    replaced by the pipelines' stand-in (sim/rtu_pipes_datapath.sv): the datapath's arithmetic
    would make this build several times longer."""
    from driver.backends import verilate
    from driver.backends.build import SIM_DIR
    from driver.backends.rtunit import unit_sources
    sources = [p for p in unit_sources() if p.name != "rayflex.sv"]
    return verilate.build_library(
        "rtu_units_tb_top", [*sources, SIM_DIR / "rtu_pipes_datapath.sv",
                             SIM_DIR / "rtu_units_tb_top.sv"],
        [SIM_DIR / "rtu_units_tb.cpp"], params=RTU_UNITS_PARAMS, name="rtu_units_tb")


TESTBENCHES = {"rtu_units": rtu_units_library}


def split(spec: str) -> tuple[str, str, list[str]]:
    """``(kind, configuration, extra fields)`` of a build spec (a ``tb`` spec: the testbench's
    name for the configuration); ValueError if malformed."""
    head, sep, rest = spec.partition(":")
    kind, fields = (head, rest.split(":")) if sep else ("harness", [spec])
    if (kind not in KINDS
            or len(fields) not in ((3, 4, 5) if kind == "rtunit" else (3,) if kind in UNIT_KINDS
                                   else (1,))
            or (len(fields) == 5 and fields[4] != "cull")
            or (kind == "tb" and fields[0] not in TESTBENCHES)):
        raise ValueError(f"build spec {spec!r}: see tests/support/prebuild.py")
    return kind, fields[0], fields[1:]


def harness_params(config: str) -> dict:
    """The "rtl" harness build parameters of ``CONFIG`` or ``CONFIG@N``."""
    from driver.backends.build import rtl_params
    name, _, latency = config.partition("@")
    p = parse_config(name)
    return rtl_params(p["EXTENDED"], p["DISJOINT"], int(latency) if latency else None,
                      p.get("COMPRESSED", 0), p.get("TRANSFORM", 0), p.get("FUSED", 0),
                      p.get("SHARED", 0))


def build(spec: str) -> None:
    kind, config, extra = split(spec)
    if kind == "tb":
        TESTBENCHES[config]()
        return
    params = harness_params(config)
    if kind in ("harness", "pgo"):
        from driver.backends import build as harness_build
        os.environ["RAYFLEX_PGO"] = "1" if kind == "pgo" else "0"
        harness_build.build_harness(params)
    elif kind == "pyverilator":
        from driver.backends.pyverilator import _build_pyverilator
        _build_pyverilator(params)
    elif kind == "signals":
        from driver.power import activity, run
        activity.SignalModel.library(run.params_of(config.partition("@")[0]))
    elif kind == "signals-all":
        from driver.power import activity
        activity.SignalModel.library(params, every_net=True)
    else:
        from driver.backends.rtunit import unit_library, unit_params
        pipelines = int(extra[2]) if len(extra) > 2 else 1
        unit_library(unit_params(params, int(extra[0]), int(extra[1]), pipelines=pipelines,
                                 cull=len(extra) > 3),
                     kind == "activity")


if __name__ == "__main__":
    import sys
    build(sys.argv[1])
