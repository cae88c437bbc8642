"""Energy of the memory side of the RT unit: node fetches per memory level (docs/rtunit.md).

The datapath's energy per op is measured on our RTL (``rayflex power``); the caches and DRAM
are not RTL here, so their energy is an access count times a published energy per byte:

- SRAM: Horowitz, "Computing's energy problem (and what we can do about it)", ISSCC 2014
  (45 nm): a 64-bit read costs 10 pJ from an 8 KB SRAM, 20 pJ from 32 KB, 100 pJ from 1 MB,
  i.e. 1.25, 2.5 and 12.5 pJ per byte: about the square root of the capacity (the wires a read
  drives grow with the array's side). ``sram_pj_per_byte`` is that fit, anchored at 32 KiB:
  2.5 pJ/B x sqrt(capacity / 32 KiB) (8 KB: 1.25, 1 MB: 14.1 against the measured 12.5).
- DRAM: 14 pJ per bit for GDDR5 (O'Connor et al., "Fine-Grained DRAM: Energy-Efficient DRAM for
  Extreme Bandwidth Systems", MICRO 2017), i.e. 112 pJ per byte moved.

Each transaction looked up in a cache costs the bytes of a transaction at that cache's energy
per byte (tags and replacement state are left out); each byte transferred from DRAM costs the
DRAM's. A level that is absent (0 KiB) costs nothing. The figures are in pJ at 45 nm-class
technology, not in the units of the datapath's energy levels: the two are reported side by
side, not added.
"""

from __future__ import annotations

import math

SRAM_PJ_PER_BYTE_32KIB = 2.5      # Horowitz ISSCC 2014: 20 pJ per 64-bit read of 32 KB
SRAM_REFERENCE_BYTES = 32 * 1024
DRAM_PJ_PER_BYTE = 14.0 * 8       # O'Connor et al. MICRO 2017: GDDR5 14 pJ/bit
UNIT = "pJ"


def sram_pj_per_byte(capacity_bytes: int) -> float:
    """Energy per byte read from an SRAM of this capacity (0: no SRAM)."""
    if capacity_bytes <= 0:
        return 0.0
    return SRAM_PJ_PER_BYTE_32KIB * math.sqrt(capacity_bytes / SRAM_REFERENCE_BYTES)


def memory_energy(memory, l1_accesses: int, l2_accesses: int, dram_bytes: int,
                  rays: int) -> dict:
    """Energy of node fetches: L1 and L2 transactions looked up, DRAM bytes moved
    (``memory``: the ``driver.rtunit.MemoryModel``); per level, in total and per ray."""
    tx = memory.transaction_bytes
    l1 = l1_accesses * tx * sram_pj_per_byte(memory.cache_bytes)
    l2 = l2_accesses * tx * sram_pj_per_byte(memory.l2_bytes)
    dram = dram_bytes * DRAM_PJ_PER_BYTE
    total = l1 + l2 + dram
    return {"l1": l1, "l2": l2, "dram": dram, "total": total,
            "per_ray": total / rays if rays else 0.0, "unit": UNIT}


def assumptions(memory) -> dict:
    """The energies per byte used for ``memory`` (for the JSON and the docs)."""
    return {"l1_pj_per_byte": sram_pj_per_byte(memory.cache_bytes),
            "l2_pj_per_byte": sram_pj_per_byte(memory.l2_bytes),
            "dram_pj_per_byte": DRAM_PJ_PER_BYTE}
