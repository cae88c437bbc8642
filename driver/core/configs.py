"""The datapath's configurations: the one table of their names and build parameters.

The paper's four (``CONFIGS``: EXTENDED x DISJOINT), each with the q8 node decode (the name +
``Q8_SUFFIX``: build parameter COMPRESSED) and each of those with the TRANSFORM operation (+
``XF_SUFFIX``); the extended ones with their vectors on the request registers' box and triangle
bits (+ ``SHARED_SUFFIX``: build parameter SHARED); and each of them with one rounding in the box
slab and the triangle's edge functions (+ ``FUSED_SUFFIX``, last: build parameter FUSED). The two
trade-offs: docs/tradeoffs.md. ``DESIGN_CONFIGS``: the names ``--config`` takes. The design point's ``--config``, ``rayflex power`` and ``python -m driver.area``
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
# the extended ones with shared request registers (build parameter SHARED = 1): name + "-shared"
SHARED_SUFFIX = "-shared"
SHARED_CONFIGS = [n + SHARED_SUFFIX for n in ALL_CONFIGS if CONFIGS[n.removesuffix(Q8_SUFFIX)][0]]
# each of those with the FUSED rounding (build parameter FUSED = 1): its name + "-fused"
FUSED_SUFFIX = "-fused"
FUSED_CONFIGS = [n + FUSED_SUFFIX for n in ALL_CONFIGS]
DESIGN_CONFIGS = [*ALL_CONFIGS, *FUSED_CONFIGS, *SHARED_CONFIGS,
                  *(n + FUSED_SUFFIX for n in SHARED_CONFIGS)]


def build_params(extended=0, disjoint=0, compressed=0, transform=0, fused=0,
                 shared=0) -> dict[str, int]:
    """The ``-G`` parameters of a configuration (COMPRESSED, TRANSFORM, FUSED and SHARED only
    when set)."""
    return {"EXTENDED": int(extended), "DISJOINT": int(disjoint),
            **({"COMPRESSED": 1} if compressed else {}), **({"TRANSFORM": 1} if transform else {}),
            **({"FUSED": 1} if fused else {}), **({"SHARED": 1} if shared else {})}


def parse_config(name: str) -> dict[str, int] | None:
    """The build parameters (``build_params``) of a configuration name: one of ``CONFIGS``, then
    optionally ``Q8_SUFFIX``, ``XF_SUFFIX``, ``SHARED_SUFFIX`` (extended ones only: a baseline
    build has no vectors to share) and ``FUSED_SUFFIX`` in that order; None for any other
    name."""
    if not isinstance(name, str):
        return None
    fused = name.endswith(FUSED_SUFFIX)
    plain = name.removesuffix(FUSED_SUFFIX)
    shared = plain.endswith(SHARED_SUFFIX)
    plain = plain.removesuffix(SHARED_SUFFIX)
    transform = plain.endswith(XF_SUFFIX)
    plain = plain.removesuffix(XF_SUFFIX)
    compressed = plain.endswith(Q8_SUFFIX)
    base = plain.removesuffix(Q8_SUFFIX)
    if base not in CONFIGS or (shared and not CONFIGS[base][0]):
        return None
    return build_params(*CONFIGS[base], compressed, transform, fused, shared)


def config_name(params: dict[str, int]) -> str:
    """The configuration name of build parameters (``build_params``): ``parse_config``'s
    inverse (``LATENCY`` and other keys are ignored)."""
    base = next(n for n, (e, d) in CONFIGS.items()
                if (e, d) == (params.get("EXTENDED", 0), params.get("DISJOINT", 0)))
    suffixes = ((Q8_SUFFIX, "COMPRESSED"), (XF_SUFFIX, "TRANSFORM"), (SHARED_SUFFIX, "SHARED"),
                (FUSED_SUFFIX, "FUSED"))
    return base + "".join(s for s, key in suffixes if params.get(key))
