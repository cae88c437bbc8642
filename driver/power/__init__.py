"""Energy per operation and per ray, measured with open tools (``rayflex power``, whose command
line is ``driver.cli.power``).

The RayFlex paper's power study (Genus on VCD activity of 100 random tests at 1 GHz) reports
power per operation type at full throughput for the four configurations. This package measures
the same structure with open tools, for those four and each with the q8 decode (``-q8``) or the
TRANSFORM operation (``-xf``) (driver/area.py's configuration names), at three levels
(docs/power.md):

* ``signals``: bit toggles of every traced RTL net (Verilator ``--trace``), seconds;
* ``gates``: toggles of every gate output of a Yosys generic-gate netlist weighted by its
  fan-out (the netlist simulated by Verilator), a technology-independent switching proxy that
  includes the logic inside the FP units;
* ``liberty``: the gate netlist's toggles priced with a liberty library's internal-power tables
  plus ½·C·V² of the load, and its leakage: picojoules at that library's node.

Steady state: each operation type streams ``n`` and ``2n`` random requests back to back through
a fresh model; the difference is ``n`` operations with the pipeline full, so filling and draining
cancel. An idle run (the pipeline drained, nothing valid) gives the energy per idle cycle, which
is subtracted from each operation's cycles (it is reported, and is ~0: registers load only on a
handshake). Energy per ray: a frame's operation mix per ray type times energy per operation.

Modules: ``run`` (the measurements: ``measure``, ``run_level``, the configurations and the
models to build; its names are the package's), ``stimulus`` (request streams, the table of
operation types), ``activity`` (the
toggle-counting models), ``netlist`` (synthesis and the gate-level Verilog), ``liberty`` (the
liberty reader and per-net energies), ``report`` (JSON, tables, plot, per-ray energy).
"""

from . import activity, liberty, netlist, stimulus
from .run import (DEFAULT_OPS, IDLE_CYCLES, LEVELS, _have_yosys, _lanes, _measure_net,
                  _measure_nets, _netlists, all_configs, announce_builds, build_params,
                  check_ops, configs, own_latency, measure, netlist_cached, params_of,
                  parse_configs, run_level, uncached_models)
