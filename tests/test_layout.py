"""driver/core/wire.py and driver/core/layout.py against the RTL: every wire field's bit position and width, the structs' $bits,
the opcodes and lane counts, as Verilator elaborates rtl/rf_pkg.sv; and the Python side of the
table (pack/unpack round trips, node dtypes, NodeRef, the generated C header)."""

import re
import subprocess
import sys

import numpy as np
import pytest

from driver.core import layout
from driver.core import wire as wires
from driver.backends import verilate
from driver.backends.build import RTL_DIR

PKG = RTL_DIR / "rf_pkg.sv"
Q8_MEMBERS = ("origin", "exp", "count", "child", "q", "parent")   # rf_pkg::q8_node_t


def _check_module() -> str:
    """A SystemVerilog test bench that prints, for every field of the table, the lowest bit and
    the number of bits it sets when the field alone is all ones."""
    lines = ["module rf_layout_check;", "  import rf_pkg::*;"]
    for wire in (wires.REQUEST, wires.RESPONSE):
        t = wire.sv_type
        lines += [f"  function automatic int lowest_{t}(input {t} v);",
                  f"    for (int i = 0; i < $bits({t}); i++) if (v[i]) return i;",
                  "    return -1;", "  endfunction"]
    lines += ["  function automatic int lowest_q8(input q8_node_t v);",
              "    for (int i = 0; i < $bits(q8_node_t); i++) if (v[i]) return i;",
              "    return -1;", "  endfunction"]
    lines += ["  req_t r;", "  rsp_t s;", "  initial begin",
              '    $display("bits req_t %0d", $bits(req_t));',
              '    $display("bits rsp_t %0d", $bits(rsp_t));']
    for wire, var in ((wires.REQUEST, "r"), (wires.RESPONSE, "s")):
        for f in wire.fields:
            member = f.sv or f.name
            if f.overlays is not None:        # a view of the overlaid member's low bits
                base = wire.field[f.overlays]
                member = base.sv or base.name
                set_ones = (f"    {var}.{member} = {base.total_bits}'({{{f.total_bits}{{1'b1}}}}) "
                            f"<< {f.first_bit - base.first_bit};")
            else:
                set_ones = f"    {var}.{member} = '1;"
            lines += [f"    {var} = '0;", set_ones,
                      f'    $display("field {wire.sv_type}.{f.name} %0d %0d", '
                      f"lowest_{wire.sv_type}({var}), $countones({var}));"]
    lines.insert(lines.index("  initial begin"), "  q8_node_t n;")
    for member in Q8_MEMBERS:
        lines += ["    n = '0;", f"    n.{member} = '1;",
                  f'    $display("q8 {member} %0d %0d", lowest_q8(n), $countones(n));']
    for name in wires.OPCODES:
        lines.append(f'    $display("opcode {name} %0d", OP_{name});')
    lines += ['    $display("lanes EUC %0d", EUC_LANES);', '    $display("lanes ANG %0d", ANG_LANES);',
              "    $finish;", "  end", "endmodule", ""]
    return "\n".join(lines)


@pytest.fixture(scope="module")
def rtl_layout(tmp_path_factory):
    """What the RTL says: {('bits', type): n, ('field', type.name): (lsb, ones), ...}."""
    work = tmp_path_factory.mktemp("layout")
    (work / "rf_layout_check.sv").write_text(_check_module())
    vbin = verilate.verilator_bin()
    build = subprocess.run(
        [str(vbin), "--binary", "--no-timing", "-O0", "-Wno-ENUMVALUE", "--Mdir", str(work / "obj"), "--top-module",
         "rf_layout_check", "-MAKEFLAGS", f"PYTHON3={sys.executable} CXX={verilate.find_cxx()} "
         "LINK=" + verilate.find_cxx() + " CFG_CXXFLAGS_STD=-std=c++17", str(PKG),
         str(work / "rf_layout_check.sv")], capture_output=True, text=True, cwd=work)
    assert build.returncode == 0, build.stdout + build.stderr
    run = subprocess.run([str(work / "obj" / "Vrf_layout_check")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    out = {}
    for line in run.stdout.splitlines():
        kind, key, *vals = line.split() + ["", ""]
        vals = [v for v in vals if v]
        if kind not in ("bits", "field", "opcode", "lanes", "q8"):
            continue                                  # Verilator's own $finish message
        out[(kind, key)] = tuple(int(v) for v in vals) if len(vals) > 1 else int(vals[0])
    return out


def test_struct_widths_match_the_table(rtl_layout):
    assert rtl_layout[("bits", "req_t")] == 32 * wires.REQ_WORDS
    assert rtl_layout[("bits", "rsp_t")] == 32 * wires.RSP_WORDS


@pytest.mark.parametrize("wire", [wires.REQUEST, wires.RESPONSE], ids=lambda w: w.sv_type)
def test_every_field_sits_where_the_table_says(rtl_layout, wire):
    for f in wire.fields:
        assert rtl_layout[("field", f"{wire.sv_type}.{f.name}")] == (f.first_bit, f.total_bits), f


def test_q8_node_struct_matches_the_table(rtl_layout):
    """rf_pkg::q8_node_t (the node a COMPRESSED build decodes from the box words) against
    layout.Q8_NODE: bit position and width of every member."""
    want = {}
    for name in ("origin", "child", "q", "parent"):
        sub, off = layout.Q8_NODE.fields[name][:2]
        want[name] = (8 * off, 8 * sub.itemsize)
    exp_off = 8 * layout.Q8_NODE.fields["exp"][1]
    want["exp"] = (exp_off, 24)                                   # exp_x, exp_y, exp_z
    want["count"] = (exp_off + layout.Q8_COUNT_LSB, 3)
    for name in Q8_MEMBERS:
        assert rtl_layout[("q8", name)] == want[name], name
    assert wires.REQUEST.field["qnode"].total_bits == 8 * layout.Q8_NODE.itemsize


def test_opcodes_and_lanes_match_the_package(rtl_layout):
    for name, code in wires.OPCODES.items():
        assert rtl_layout[("opcode", name)] == code
    assert rtl_layout[("lanes", "EUC")] == wires.EUC_LANES
    assert rtl_layout[("lanes", "ANG")] == wires.ANG_LANES


def test_the_fields_cover_the_struct_but_its_reserved_bits():
    """Every bit of req_t/rsp_t is a field of the table except the ``rsvd`` members."""
    structs = {name: body for body, name in
               re.findall(r"typedef struct packed \{([^{}]*)\}\s*(\w+);", PKG.read_text())}
    for wire in (wires.REQUEST, wires.RESPONSE):
        body = structs[wire.sv_type]
        rsvd = sum(int(m.group(1)) + 1 for m in re.finditer(r"logic\s*\[(\d+):0\]\s*rsvd", body))
        own = [f for f in wire.fields if f.overlays is None]
        assert sum(f.total_bits for f in own) + rsvd == 32 * wire.words


@pytest.mark.parametrize("wire", [wires.REQUEST, wires.RESPONSE], ids=lambda w: w.sv_type)
def test_pack_unpack_round_trip(wire):
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 256, (500, wire.dtype.itemsize), dtype=np.uint8).view(wire.dtype)[:, 0]
    for f in wire.fields:                     # sub-word fields hold only their width
        if f.kind != "f32":
            rows[f.name] &= (1 << f.bits) - 1
    if "opcode" in wire.field and wire.overlay_rows:
        rows["opcode"][::3] = wires.QUADBOX      # some rows that carry an overlay
        rows["opcode"][1::3] = wires.TRANSFORM
    words = wire.pack(rows)
    assert words.shape == (500, wire.words)
    back = wire.unpack(words)
    none = np.zeros(len(rows), bool)
    sel = {name: rule(rows) for name, rule in wire.overlay_rows.items()}
    for f in wire.fields:
        if f.overlays is None:
            # a field an overlay shares: exact where no overlay of it is on the wire
            mine = [sel[o.name] for o in wire.fields if o.overlays == f.name]
            rows_f = ~np.logical_or.reduce([none, *mine])
            assert back[f.name][rows_f].tobytes() == rows[f.name][rows_f].tobytes(), f.name
            continue
        # an overlay: on the rows its rule selects, it is what went onto the wire; on the others,
        # it reads the overlaid field's bits
        s = sel[f.name]
        assert 0 < s.sum() < len(rows)
        assert back[f.name][s].tobytes() == rows[f.name][s].tobytes(), f.name
        span = words[:, f.word:f.word + f.count]
        assert np.array_equal(back[f.name].reshape(len(rows), -1).view(np.uint32), span)
        base = wire.field[f.overlays]
        tail = slice(f.word + f.count - base.word, None)     # the overlaid field's other words
        assert np.array_equal(back[base.name][s].reshape(s.sum(), -1).view(np.uint32)[:, tail],
                              rows[base.name][s].reshape(s.sum(), -1).view(np.uint32)[:, tail])
    assert np.array_equal(wire.pack(wire.unpack(words)), words)


def test_ray_words_are_the_leading_request_words():
    rng = np.random.default_rng(4)
    rows = rng.integers(0, 256, (50, wires.REQUEST_DTYPE.itemsize), dtype=np.uint8)
    req = rows.view(wires.REQUEST_DTYPE)[:, 0]
    for f in wires.REQUEST.fields:
        if f.kind != "f32":
            req[f.name] &= (1 << f.bits) - 1
    assert np.array_equal(wires.ray_words(req), wires.pack_requests(req)[:, :wires.RAY_WORDS])
    assert wires.RAY_WORDS <= wires.REQUEST.field["box"].word      # operands follow the ray


def test_node_ref_and_node_dtypes():
    off = np.array([0, 64, 128, 64 * 12345], np.int64)
    ptr = layout.NodeRef.encode(off, [layout.BOX_TYPE, layout.TRI_TYPE, layout.BOX_TYPE,
                                      layout.TRI_TYPE])
    # docs/datapath.md#bvh4-image: the root box node's pointer
    assert ptr[0] == 5
    assert np.array_equal(layout.NodeRef.offset(ptr), off)
    assert np.array_equal(layout.NodeRef.is_box(ptr), [True, False, True, False])
    assert layout.NodeRef.type(layout.NO_CHILD) not in (layout.BOX_TYPE, layout.TRI_TYPE)
    with pytest.raises(ValueError):
        layout.NodeRef.encode(32, layout.BOX_TYPE)
    assert layout.BOX_NODE.itemsize == 128 and layout.TRI_NODE.itemsize == 64
    image = np.zeros(2 * 128 // 4, np.uint32)
    node = np.zeros(1, layout.BOX_NODE)
    node["box"] = np.arange(24, dtype=np.float32).reshape(4, 6)
    node["child"] = [5, 21, layout.NO_CHILD, layout.NO_CHILD]
    image[32:64] = node.view(np.uint32)
    got = layout.read_nodes(image, layout.NodeRef.encode([128], [layout.BOX_TYPE]), layout.BOX_NODE)
    assert got.tobytes() == node.tobytes()


def test_c_header_has_every_constant_the_harness_uses():
    from driver.backends.rtunit import stats_header
    header = layout.c_header()
    # the RT unit's generated statistics header (rf_rtunit_stats.h) defines its own constants
    names = set(re.findall(r"constexpr \w+ (k\w+)(?:\[\d*\])? =", header + stats_header()))
    names |= set(re.findall(r"\b(kLevel\w+) = \d+", header))       # the memory levels' enum
    sim = RTL_DIR.parent / "sim"
    src = "".join(p.read_text() for p in sorted(sim.glob("r*.cpp")) + sorted(sim.glob("rf_*.h")))
    # constants the harness defines for itself (kPrefetchAhead, kOpcodeMask)
    own = set(re.findall(r"\b(k[A-Z]\w+)(?:\[\d*\])?\s*=", src))
    assert {"kPrefetchAhead", "kOpcodeMask"} <= own and not {"kLevelDram", "kMemoryLevels"} & own
    assert {"kLevelDram", "kMemoryLevels"} <= names
    used = set(re.findall(r"\bk[A-Z]\w+", src)) - own
    assert used and used <= names, used - names
    assert "struct ReplayStats" in header
    for name in layout.REPLAY_STATS:
        assert f"int64_t {name};" in header


def test_q8_node_words_and_decode():
    """The q8 box node's words (origin 0-2, exponents + count in word 3, children 4-7, planes at
    byte 32 + 6i + j, parent 14) and its decode: exact product, one float32 add, unused = +inf."""
    from driver.core.layout import Q8_NODE, decode_q8
    n = np.zeros(1, Q8_NODE)
    n["origin"] = [1.0, 2.0, 3.0]
    n["exp"][0, :3] = np.array([-2, 0, 3], np.int8).view(np.uint8)
    n["exp"][0, 3] = 2
    n["child"] = [8, 16, 0xFFFFFFFF, 0xFFFFFFFF]
    n["q"][0, 1] = [0, 1, 2, 255, 254, 253]
    n["parent"] = 77
    w = n.view(np.uint32)
    assert w[3] == (0x02 << 24) | (0x03 << 16) | (0x00 << 8) | 0xFE
    assert list(w[4:8]) == [8, 16, 0xFFFFFFFF, 0xFFFFFFFF] and w[14] == 77
    assert n.view(np.uint8)[32 + 6 * 1 + 3] == 255
    b = decode_q8(n)[0]
    assert b[1].tolist() == [1.0, 3.0, 19.0, 1.0 + 255 * 0.25, 256.0, 3.0 + 253 * 8]
    assert b[0].tolist() == [1.0, 2.0, 3.0] * 2 and np.isinf(b[2:]).all()
    # the add rounds once, to nearest even: 2**24 + 1 is not a float32
    n["origin"] = [2.0 ** 24, 0, 0]
    n["exp"][0, :3] = 0
    n["q"][0, 0, 0] = 1
    assert decode_q8(n)[0, 0, 0] == np.float32(2.0 ** 24)
