"""Test helpers shared by the test modules (no test module imports another one).

- ``testbench``: the RTL testbench (driver, monitor, golden reference, scoreboard; back-pressure
  patterns; runs in a fresh process for pyverilator).
- ``scoreboard``: bit-exact comparison of response arrays with hex failure reports.
- ``streams``: random request streams aimed at the corner cases (box/triangle, vector jobs, mixes).
- ``cases``: the paper's directed cases and single-request builders.
- ``scalar_ref``: the scalar (one float32 operation at a time) reference model of the datapath.
- ``meshes``: small procedural test meshes and the bunny.
- ``fpu``: the FP-unit testbench (Verilated model, numpy reference, operand generators).
- ``recording``: a backend wrapper that records every ``run()`` call.
"""
