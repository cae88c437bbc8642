"""RayFlex driver: BVH4, traversal, rendering and checks around the RayFlex datapath RTL."""

from .backends import BACKENDS, BackendError, backend
from .core.datapath import (ANGULAR, EUCLIDEAN, LATENCY, QUADBOX, REQUEST_DTYPE, RESPONSE_DTYPE,
                            TRIANGLE, DatapathError, FLAG_NO_CULL, prepare_rays)
from .tracer import trace as _trace

__all__ = ["ANGULAR", "BACKENDS", "BackendError", "DatapathError", "EUCLIDEAN", "FLAG_NO_CULL",
           "LATENCY", "QUADBOX", "REQUEST_DTYPE", "RESPONSE_DTYPE", "TRIANGLE", "backend",
           "prepare_rays", "trace"]


def trace(scene, origins, directions, backend="rtl", **options):
    """Trace rays through a scene (name, path, trimesh mesh or built BVH4) with every box and
    triangle test run on ``backend``: closest hit, or ``any_hit=True`` (occlusion), with
    ``double_sided=True`` for NO_CULL; see ``driver.tracer.trace``."""
    return _trace(scene, origins, directions, backend=backend, **options)
