"""BVH4 for the RayFlex datapath: the entry point of the BVH build and of its memory image.

The build is one pipeline (``driver.bvh.pipeline``), entered here once: ``build`` runs it on a
mesh or triangles (binary build -> collapse to 4-wide -> the format's image writer: box32, q8 or
q8g), and ``build_scene`` builds a scene's BVH: the two-level image of an instanced scene
(``driver.bvh.instances``, which runs the same pipeline for every BLAS and the TLAS) or ``build``
of its mesh. The stages, bottom up:

- ``driver.bvh.image``: ``BVH4``, the built memory image with the decoders that read it like an
  RT unit, and the request operands a node pointer becomes (the layout:
  docs/datapath.md#bvh4-image, docs/compressed.md; the structs are ``driver.core.layout``'s);
- ``driver.bvh.build`` (numba) and ``driver.bvh.reference`` (numpy): the binary SAH build;
- ``driver.bvh.collapse``: the SAH-optimal (or greedy) collapse to 4-wide box nodes;
- ``driver.bvh.box32``, ``driver.bvh.q8_image``: the image writers; ``driver.bvh.q8`` pairs the
  q8 formats' triangles before the build, ``driver.bvh.q8g`` picks the q8g group leaves;
- ``driver.bvh.pipeline``: ``build``, the stages in order; ``driver.bvh.instances``: the
  two-level image.

Code above the BVH layer imports this module; nothing in ``driver/bvh/`` does.
"""

from __future__ import annotations

from .bvh.image import BVH4, box_operands, q8_request, request_operands, tri_operands
from .bvh.instances import TwoLevelBVH, build_two_level, tlas_format
from .bvh.pipeline import (BUILDERS, COLLAPSES, PAD_REL, PROGRESS_MIN, as_triangles, build,
                           warm_up)
# the node image's layout is driver.core.layout's (docs/datapath.md#bvh4-image,
# docs/compressed.md); the names are re-exported for users
from .core.layout import (BOX_BYTES, BOX_NODE, BOX_TYPE, IMAGE_FORMATS, NO_CHILD,  # noqa: F401
                          DEFAULT_FORMAT, FORMATS,
                          GROUP_BYTES, GROUP_NODE, GROUP_TYPE, INSTANCE_NODE, INSTANCE_TYPE,
                          LEAF_NEXT_TYPE, LEAF_OFFSET_LIMIT, PAIR_BYTES, PAIR_NODE, PAIR_TYPE,
                          Q8_BYTES, Q8_NODE, Q8_TYPE, TRI_BYTES, TRI_NODE, TRI_TYPE, NodeRef,
                          decode_q8, leaf_triangles, node_word, read_nodes)
from .core.wire import FLAG_DECODE_Q8, QNODE_WORDS, QUADBOX, TRANSFORM, TRIANGLE
from .instances import check_transform

__all__ = ["BUILDERS", "BVH4", "COLLAPSES", "PAD_REL", "PROGRESS_MIN", "TwoLevelBVH",
           "as_triangles", "box_operands", "build", "build_label", "build_scene",
           "build_two_level", "q8_request", "request_operands", "tlas_format", "tri_operands",
           "warm_up"]


def build_scene(scene, fill: int = 0, format: str = DEFAULT_FORMAT, transform: str = "driver"):
    """The BVH of a ``driver.scenes.scene.Scene``: the two-level image of its ``instances``
    (``fill`` applies to the BLASes; ``transform``: where its traversals run the instance
    transform, ``driver.instances.TRANSFORMS``) or, for a one-mesh scene, ``build``
    of its mesh."""
    check_transform(transform)
    if getattr(scene, "instances", None) is not None:
        bvh = build_two_level(scene.instances, format=format, fill=fill)
        bvh.transform = transform
        return bvh
    return build(scene.mesh, fill=fill, format=format)


def build_label(scene) -> str:
    """What ``build_scene`` builds, for progress messages."""
    c = scene.counts()
    if getattr(scene, "instances", None) is None:
        return f"the BVH4 of {c['instanced_triangles']:,} triangles"
    return (f"the two-level BVH4 of {c['instances']:,} instances ({c['blas_triangles']:,} "
            f"triangles in {len(scene.instances.meshes)} meshes)")
