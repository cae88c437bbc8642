"""A cycle-based, levelized, 64-lane bit-parallel simulator of the generic-gate netlist.

Every net holds a uint64: bit ``k`` is its value in lane ``k``, 64 independent copies of the
datapath clocked together, each fed its own request stream. A clock cycle evaluates the
combinational gates level by level (one numpy operation per gate type and level), then loads the
flip-flops; toggles are counted per net and per lane group with ``np.bitwise_count``.

Why not Verilator, as for the RTL: the generic-gate netlist has ~5 x 10^5 gates; Verilator
turns it (with ``--coverage-toggle`` to count its toggles) into ~700 MB of C++ in ~1,000 files,
whose compilation takes far longer than the whole gate-level budget (docs/power.md has the
measurement). Evaluating the same gates as numpy vector operations needs no compilation, and the
64 lanes make one pass measure 64 streams.
"""

from __future__ import annotations

import numpy as np

# comb gate codes (netlist.py writes them); the MUX output is S ? B : A
BUF, NOT, AND, OR, XOR, NAND, NOR, XNOR, ANDNOT, ORNOT, MUX, NMUX = range(12)
LANES = 64
ONES = np.uint64(0xFFFF_FFFF_FFFF_FFFF)


class GateSim:
    """Simulate ``net`` (a netlist.Netlist with its gate arrays) on 64 lanes."""

    def __init__(self, net):
        g = net.gates
        self.n = len(net.driver)
        self.a, self.b, self.s, self.y = g["a"], g["b"], g["s"], g["y"]
        self.groups = [tuple(x) for x in g["groups"]]       # (code, start, end) in eval order
        self.d, self.e, self.q = g["ff_d"], g["ff_e"], g["ff_q"]
        self.e_inv = g["ff_e_inv"].astype(bool)
        self.r, self.r_inv, self.r_val = g["ff_r"], g["ff_r_inv"].astype(bool), g["ff_r_val"]
        self.ports = net.ports
        # the multiplexers netlist.py cut out of a loop: (output, select, looped pin: 0 A, 1 B)
        loops = g.get("loops", np.zeros((0, 3), np.int32))
        self.loop_s = loops[:, 1]
        self.loop_b = loops[:, 2].astype(bool)
        self.v = np.zeros(self.n, np.uint64)
        self.v[1] = ONES                                       # net 1: constant 1

    def set_input(self, name: str, lanes_bits: np.ndarray) -> None:
        """Drive input port ``name``: ``lanes_bits`` is (LANES, width) bool/uint8."""
        bits = self.ports[name]
        packed = np.packbits(np.asarray(lanes_bits, np.uint8), axis=0, bitorder="little")
        word = np.zeros((8, packed.shape[1]), np.uint8)
        word[:packed.shape[0]] = packed
        self.v[bits] = word.T.copy().view(np.uint64).reshape(-1)

    def output(self, name: str) -> np.ndarray:
        """(LANES, width) bool values of output port ``name``."""
        words = self.v[self.ports[name]]
        return ((words[:, None] >> np.arange(LANES, dtype=np.uint64)) & np.uint64(1)).T \
            .astype(bool)

    def settle(self) -> None:
        """Evaluate every combinational gate in level order."""
        v, a, b, s, y = self.v, self.a, self.b, self.s, self.y
        for code, i, j in self.groups:
            A = v[a[i:j]]
            if code == BUF:
                r = A
            elif code == NOT:
                r = ~A
            elif code == MUX or code == NMUX:
                S = v[s[i:j]]
                r = (A & ~S) | (v[b[i:j]] & S)
                if code == NMUX:
                    r = ~r
            else:
                B = v[b[i:j]]
                if code == AND:
                    r = A & B
                elif code == OR:
                    r = A | B
                elif code == XOR:
                    r = A ^ B
                elif code == NAND:
                    r = ~(A & B)
                elif code == NOR:
                    r = ~(A | B)
                elif code == XNOR:
                    r = ~(A ^ B)
                elif code == ANDNOT:
                    r = A & ~B
                else:
                    r = A | ~B
            v[y[i:j]] = r

    def loops_held(self, lanes: np.uint64 = ONES) -> bool:
        """Whether no cut multiplexer selects its looped input in ``lanes`` (a bit mask) after
        ``settle``: then the cut changed no value."""
        sel = self.v[self.loop_s]
        picked = np.where(self.loop_b, sel, ~sel) & lanes
        return not picked.any()

    def clock(self) -> None:
        """Rising edge: every flip-flop loads D where enabled, its reset value where reset."""
        v = self.v
        en = v[self.e]
        en = np.where(self.e_inv, ~en, en)
        new = (v[self.d] & en) | (v[self.q] & ~en)
        rst = v[self.r]
        rst = np.where(self.r_inv, ~rst, rst)
        val = np.where(self.r_val.astype(bool), ONES, np.uint64(0))
        v[self.q] = (new & ~rst) | (val & rst)
