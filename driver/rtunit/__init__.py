"""The RT-unit timing model (docs/rtunit.md): a frame's recorded requests replayed through the
Verilated datapath pipelines of RT units, with rays in flight, warps and a memory hierarchy.

``unit`` replays one record on one RT unit (``replay``, ``sweep``; its docstring tells the design:
functional traversal first, timing by replay), ``gpu`` a whole frame on a GPU's RT units
(``replay_frame``), ``plan`` the frame schedule, ``order`` the ray-order policies, ``presets``
whole RT-unit configurations and ``energy`` the memory side's energy. The names below are the
package's API.
"""

from ..tracing.record import Record
from .gpu import ReplayMismatch, UnitCosts
from .unit import (DEFAULT_RAYS_IN_FLIGHT, DEFAULT_TURNAROUND, SWEEP_PIPELINES,
                   SWEEP_RAYS_IN_FLIGHT, MemoryModel, ReplayResult, plot_sweep, replay, sweep)

__all__ = ["Record", "MemoryModel", "ReplayResult", "ReplayMismatch", "UnitCosts", "replay",
           "sweep",
           "plot_sweep", "DEFAULT_RAYS_IN_FLIGHT", "DEFAULT_TURNAROUND", "SWEEP_RAYS_IN_FLIGHT",
           "SWEEP_PIPELINES"]
