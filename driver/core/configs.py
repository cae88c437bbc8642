"""The datapath's configurations: the one table of their names and build parameters.

The paper's four (``CONFIGS``: EXTENDED x DISJOINT), each with the q8 node decode (the name +
``Q8_SUFFIX``: build parameter COMPRESSED) and each of those with the TRANSFORM operation (+
``XF_SUFFIX``). The design point's ``--config``, ``rayflex power`` and ``python -m driver.area``
all take their names from here.
"""

from __future__ import annotations

# name -> (EXTENDED, DISJOINT); the first is the baseline every ratio refers to
CONFIGS = {
    "baseline-unified": (0, 0),
    "baseline-disjoint": (0, 1),
    "extended-unified": (1, 0),
    "extended-disjoint": (1, 1),
}
BASELINE = "baseline-unified"
# each configuration with the q8 decode stage (build parameter COMPRESSED = 1): its name + "-q8"
Q8_SUFFIX = "-q8"
ALL_CONFIGS = [*CONFIGS, *(n + Q8_SUFFIX for n in CONFIGS)]
# each of those with the TRANSFORM operation (build parameter TRANSFORM = 1): its name + "-xf"
XF_SUFFIX = "-xf"
XF_CONFIGS = [n + XF_SUFFIX for n in ALL_CONFIGS]


def build_params(extended=0, disjoint=0, compressed=0, transform=0) -> dict[str, int]:
    """The ``-G`` parameters of a configuration (COMPRESSED and TRANSFORM only when set)."""
    return {"EXTENDED": int(extended), "DISJOINT": int(disjoint),
            **({"COMPRESSED": 1} if compressed else {}), **({"TRANSFORM": 1} if transform else {})}
