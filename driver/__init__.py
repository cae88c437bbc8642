"""RayFlex driver: BVH4, traversal, rendering and checks around the RayFlex datapath RTL.

The Python API (docs/api.md) is the names below: load a scene (``load_scene``), make its camera
rays (``primary_rays``), build its node image (``build_scene``, ``build``), trace rays with every
box and triangle test on a backend (``trace``, ``record=True`` keeps every request), replay the
record on an RT unit with a node memory (``replay``, ``MemoryModel``) and read the statistics
(``TraceResult.stats``, ``ReplayResult.stats()``). Whole workload frames (shadow, AO and
path rays, per ray type): ``driver.render.render`` of a ``driver.design.DesignPoint``.
"""

from .backends import BACKENDS, DEFAULT_BACKEND, BackendError, backend
from .bvh4 import BVH4, build, build_scene
from .core.datapath import (ANGULAR, EUCLIDEAN, LATENCY, QUADBOX, REQUEST_DTYPE, RESPONSE_DTYPE,
                            TRIANGLE, DatapathError, FLAG_NO_CULL, prepare_rays)
from .rtunit import MemoryModel, ReplayResult, replay
from .scenes.camera import Camera, primary_rays
from .tracer import TraceResult, trace
from .tracing.record import Record

__all__ = ["ANGULAR", "BACKENDS", "BVH4", "BackendError", "Camera", "DEFAULT_BACKEND",
           "DatapathError", "EUCLIDEAN", "FLAG_NO_CULL", "LATENCY",
           "MemoryModel", "QUADBOX", "REQUEST_DTYPE", "RESPONSE_DTYPE", "Record", "ReplayResult",
           "Scene", "TRIANGLE", "TraceResult", "backend", "build", "build_scene", "load_scene",
           "prepare_rays", "primary_rays", "replay", "trace"]

_SCENE_NAMES = ("Scene", "load_scene")      # their module loads trimesh: imported on first use


def __getattr__(name):
    if name in _SCENE_NAMES:
        from .scenes import scene
        return getattr(scene, name)
    raise AttributeError(f"module 'driver' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_SCENE_NAMES))
