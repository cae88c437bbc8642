"""The RT unit's modules alone (sim/rtu_units_tb.cpp drives them cycle by cycle), each against a
reference model of its header's contract: the traversal stacks (rf_rtu_stack) under random
pushes, pops, clears and refills against unbounded stacks with spills; the divider pool
(rf_rtu_divs) under random input gaps and output stalls against numpy, every division's result
taken exactly once; node fetch (rf_rtu_fetch), the scheduler (rf_rtu_sched) and response
processing (rf_rtu_resp) under random gaps on their inputs and random ready on their outputs,
every transaction checked, none lost or extra, and the cycles their headers promise; the ray
buffer (rf_rtu_ray_buffer) under random writes on all its ports, and the hit update (rf_rtu_hit)
on ties, NaNs, zeros and infinities."""

from __future__ import annotations

import ctypes
import re

import numpy as np
import pytest

from driver.backends.build import RTL_DIR
from driver.core import layout, wire
from driver.core.datapath import default_latency
from support.prebuild import RTU_UNITS_PARAMS, rtu_units_library

U8, U32, I64, U64 = (np.ctypeslib.ndpointer(t, flags="C")
                     for t in (np.uint8, np.uint32, np.int64, np.uint64))

RAYS, DEPTH = RTU_UNITS_PARAMS["RAYS"], RTU_UNITS_PARAMS["STACK_DEPTH"]   # the testbench's
_LIB = []


def _lib() -> ctypes.CDLL:
    """The modules side by side (sim/rtu_units_tb_top.sv) with the testbench: one build (made
    before the first test by the suite's prebuild, tests/conftest.py)."""
    if not _LIB:
        _LIB.append(ctypes.CDLL(str(rtu_units_library())))
    return _LIB[0]


class StackRef:
    """Per slot: the STACK_DEPTH newest entries (the RAM) and the older ones spilled from it (a
    LIFO), as rf_rtu_stack's contract says; ``depth``: the most entries a slot's RAM held."""

    def __init__(self):
        self.stack = [[] for _ in range(RAYS)]
        self.spilled = [[] for _ in range(RAYS)]
        self.depth = 0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_stack_against_its_reference(seed):
    lib = _lib()
    rng = np.random.default_rng(seed)
    n = 4000
    ref = StackRef()
    ctl = np.zeros(n, np.uint8)
    cs, ps, pp, qs = (np.zeros(n, np.uint32) for _ in range(4))
    exp_top = np.zeros(n, np.uint32)
    exp_flags = np.zeros(n, np.uint8)
    exp_spill = np.zeros(n, np.uint32)
    exp_depth = np.zeros(n, np.uint32)
    refills = 0
    for k in range(n):
        slots = rng.permutation(RAYS)
        c, p, q = (int(s) for s in slots[:3])
        cs[k], ps[k], qs[k], pp[k] = c, p, q, rng.integers(0, 2 ** 32)
        st, sp = ref.stack[q], ref.spilled[q]
        exp_top[k] = st[-1] if st else 0
        exp_depth[k] = ref.depth
        flags = int(not st) | int(bool(sp)) << 1
        full = len(ref.stack[p]) == DEPTH
        bits = 0
        if rng.random() < 0.6:                      # push onto slot p
            bits |= 2
            if full:
                flags |= 4
                exp_spill[k] = ref.stack[p][0]
        if st and rng.random() < 0.5:               # pop slot q
            bits |= 4
        elif not st and sp and rng.random() < 0.5:  # refill slot q
            bits |= 8
        if rng.random() < 0.05:                     # clear slot c
            bits |= 1
        ctl[k], exp_flags[k] = bits, flags
        # the reference's next state
        if bits & 2:
            if full:
                ref.spilled[p].append(ref.stack[p].pop(0))
            ref.stack[p].append(int(pp[k]))
            ref.depth = max(ref.depth, len(ref.stack[p]))
        if bits & 4:
            st.pop()
        if bits & 8:
            sp.pop()
            refills += 1
        if bits & 1:
            ref.stack[c], ref.spilled[c] = [], []
    top, spill, depth = (np.zeros(n, np.uint32) for _ in range(3))
    flags = np.zeros(n, np.uint8)
    lib.stack_run.argtypes = [ctypes.c_int64, U8, U32, U32, U32, U32, U32, U8, U32, U32]
    lib.stack_run(n, ctl, cs, ps, pp, qs, top, flags, spill, depth)
    assert refills > 50 and (exp_flags & 4).sum() > 100          # the stream spills and refills
    assert flags.tolist() == exp_flags.tolist()
    has = (exp_flags & 1) == 0
    assert top[has].tolist() == exp_top[has].tolist()
    spilt = (exp_flags & 4) != 0
    assert spill[spilt].tolist() == exp_spill[spilt].tolist()
    assert depth.tolist() == exp_depth.tolist()


@pytest.mark.parametrize("valid,ready", [(0.9, 0.9), (0.5, 0.3), (1.0, 0.1), (0.2, 1.0)])
def test_divider_pool_under_back_pressure(valid, ready):
    lib = _lib()
    rng = np.random.default_rng(int(10 * valid + 100 * ready))
    n = 600
    special = np.array([0, 0x80000000, 0x7F800000, 0xFF800000, 0x7FC00000, 1, 0x807FFFFF,
                        0x7F7FFFFF, 0x00800000, 0x3F800000], np.uint32)
    a = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    b = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    a[:100] = rng.choice(special, 100)
    b[50:150] = rng.choice(special, 100)
    cycles = n * 60
    in_valid = (rng.random(cycles) < valid).astype(np.uint8)
    out_ready = (rng.random(cycles) < ready).astype(np.uint8)
    q = np.zeros(n, np.uint32)
    taken = np.full(n, -1, np.int64)
    lib.divs_run.argtypes = [ctypes.c_int64, U8, U8, ctypes.c_int64, U32, U32, U32, I64]
    lib.divs_run.restype = ctypes.c_int64
    got = lib.divs_run(cycles, in_valid, out_ready, n, a, b, q, taken)
    assert got == n and (taken >= 0).all()                       # each result once
    with np.errstate(all="ignore"):
        want = (a.view(np.float32) / b.view(np.float32)).view(np.uint32)
    nan = np.isnan(want.view(np.float32))
    assert (q[nan] == 0x7FC00000).all()
    assert q[~nan].tolist() == want[~nan].tolist()


# ---- fetch, scheduler, response processing, ray buffer, hit update ----------------------------
# Each test drives one module through sim/rtu_units_tb.cpp: a driver per input stream (random
# gaps, each transaction held until taken), random ready on every output with a ready input, a
# monitor recording every transaction that moves; here a reference model of the module's header
# contract predicts them and a scoreboard compares: every transaction, none lost, none extra,
# within the cycles run.

NODE_WORDS = layout.BOX_BYTES // 4      # rf_rtu_pkg::NODE_W / 32: the widest node, one beat


def _kinds(xf: bool = False) -> dict:
    """rf_rtu_pkg::kind_e, read from the package: {name: value}; KIND_XF (an instance node's
    TRANSFORM) only with ``xf`` (the scheduler's and the response stage's tests leave it to the
    whole unit, tests/test_rtunit_rtl.py; the pipelines' test has it)."""
    text = (RTL_DIR / "rf_rtu_pkg.sv").read_text()
    kinds = {m[1]: int(m[2]) for m in re.finditer(r"(KIND_\w+)\s*=\s*3'd(\d+)", text)}
    assert set(kinds) == {"KIND_BOX32", "KIND_Q8", "KIND_TRI", "KIND_PAIR0", "KIND_PAIR1",
                          "KIND_XF"}
    if not xf:
        del kinds["KIND_XF"]
    return kinds


def _rand_u32(rng, shape) -> np.ndarray:
    return rng.integers(0, 2 ** 32, shape, dtype=np.uint64).astype(np.uint32)


def _f32(bits) -> np.ndarray:
    return np.ascontiguousarray(bits, np.uint32).view(np.float32)


def mem_words(addr) -> np.ndarray:
    """The testbench memory's NODE_WORDS data words for each byte address (its mem_word)."""
    a = np.asarray(addr, np.uint64).reshape(-1, 1)
    i = np.arange(NODE_WORDS, dtype=np.uint64)
    w = ((a & np.uint64(0xFFFFFFFF)) * np.uint64(0x9E3779B1) + i * np.uint64(0x85EBCA77)
         + (a >> np.uint64(32)) * np.uint64(0xC2B2AE3D)) & np.uint64(0xFFFFFFFF)
    return (w ^ (i << np.uint64(16))).astype(np.uint32)


def rr_pick(mask: int, start: int, n: int = RAYS) -> int | None:
    """The first set bit of mask at or after start, round robin over n bits (the slots)."""
    for i in [*range(start, n), *range(start)]:
        if mask >> i & 1:
            return i
    return None


@pytest.mark.parametrize("seed,valid,ready", [(1, 0.9, 0.9), (2, 0.5, 0.3), (3, 1.0, 0.1)])
def test_fetch_under_back_pressure(seed, valid, ready):
    lib = _lib()
    rng = np.random.default_rng(seed)
    n, cycles = 400, 12000
    readable = [layout.BOX_TYPE, layout.TRI_TYPE, layout.PAIR_TYPE, layout.Q8_TYPE]
    slot = rng.integers(0, RAYS, n).astype(np.uint8)
    refill = (rng.random(n) < 0.2).astype(np.uint8)
    typ = rng.choice(readable, n)
    ptr = (_rand_u32(rng, n) & np.uint32(~7 & 0xFFFFFFFF)) | typ.astype(np.uint32)
    refill_val = _rand_u32(rng, n)
    in_gap = (rng.random(cycles) < valid).astype(np.uint8)
    req_ready = (rng.random(cycles) < ready).astype(np.uint8)
    lat = rng.integers(0, 16, cycles).astype(np.int64)
    rsp_go = (rng.random(cycles) < 0.5).astype(np.uint8)
    rsp_pick = _rand_u32(rng, cycles)
    probe = _rand_u32(rng, cycles)
    rd = rng.integers(0, RAYS, (2, cycles)).astype(np.uint8)
    in_cycle, req_cycle, rsp_cycle, rsp_req, done_cycle = (np.full(n, -1, np.int64)
                                                           for _ in range(5))
    req_addr = np.zeros(n, np.uint64)
    req_size, done_ptr = np.zeros(n, np.uint32), np.zeros(n, np.uint32)
    req_tag, req_refill, done_slot, done_refill = (np.zeros(n, np.uint8) for _ in range(4))
    nodes = np.zeros((cycles, 2, NODE_WORDS), np.uint32)
    bad = np.zeros(cycles, np.uint8)
    errs, counts = np.zeros(2, np.int64), np.zeros(4, np.int64)
    lib.fetch_run.argtypes = [ctypes.c_int64, ctypes.c_int64, U8, U32, U8, U32, U8, U8, I64, U8,
                              U32, U32, U8, U8, I64, I64, U64, U32, U8, U8, I64, I64, I64, U8,
                              U8, U32, U32, U8, I64, I64]
    lib.fetch_run(cycles, n, slot, ptr, refill, refill_val, in_gap, req_ready, lat, rsp_go,
                  rsp_pick, probe, rd[0], rd[1], in_cycle, req_cycle, req_addr, req_size,
                  req_tag, req_refill, rsp_cycle, rsp_req, done_cycle, done_slot, done_refill,
                  done_ptr, nodes, bad, errs, counts)
    # every command taken, one request each, one response each, one done pulse each
    assert counts.tolist() == [n, n, n, n]
    assert errs.tolist() == [0, 0]      # register outputs; the response port always ready
    # reference: command j is request j: (pointer & ~7) << 3 and the node's size, or a 4-byte
    # spill-area read; tag = the slot; a register output, so a cycle after the command at least
    size = np.array([layout.NODE_BYTES.get(t, 0) for t in range(8)])
    assert req_addr.tolist() == np.where(refill, 0, layout.NodeRef.offset(ptr)).tolist()
    assert req_size.tolist() == np.where(refill, 4, size[typ]).tolist()
    assert req_tag.tolist() == slot.tolist() and req_refill.tolist() == refill.tolist()
    assert (req_cycle > in_cycle).all() and (in_cycle[1:] > in_cycle[:-1]).all()
    # a done pulse in the cycle of each response, naming its slot; a refill gives its pointer
    assert sorted(rsp_req.tolist()) == list(range(n))               # each request answered once
    assert (np.diff(rsp_req) < 0).sum() > 20 and refill.sum() > 40   # out of order; refills
    assert done_cycle.tolist() == rsp_cycle.tolist()
    assert done_slot.tolist() == slot[rsp_req].tolist()
    assert done_refill.tolist() == refill[rsp_req].tolist()
    got_refill = done_refill == 1
    assert done_ptr[got_refill].tolist() == refill_val[rsp_req[got_refill]].tolist()
    # the node buffer: each response's data in its slot's entry from the next cycle on
    data = mem_words(req_addr[rsp_req])
    data[got_refill, 0] = refill_val[rsp_req[got_refill]]
    entry, e, checked = {}, 0, 0
    for k in range(cycles):
        while e < n and rsp_cycle[e] < k:
            entry[int(slot[rsp_req[e]])] = data[e]
            e += 1
        for port in (0, 1):
            s = int(rd[port, k])
            if s in entry:
                assert (nodes[k, port] == entry[s]).all(), (k, port, s)
                checked += 1
    assert checked > cycles
    # in_bad_o: a type the fetch does not read (the q8 node only with Q8)
    t = layout.NodeRef.type(probe)
    assert (bad & 1).tolist() == (~np.isin(t, readable)).tolist()
    assert (bad >> 1).tolist() == (~np.isin(t, readable[:3])).tolist()


def _ray_rows(rng, n) -> np.ndarray:
    """n random prepared rays as REQUEST rows (the ray fields only; flags: NO_CULL or none)."""
    rows = np.zeros(n, wire.REQUEST_DTYPE)
    for f in ("origin", "dir", "inv", "shear"):
        rows[f] = rng.normal(size=rows[f].shape).astype(np.float32)
    rows["extent"] = rng.random(n).astype(np.float32) * 100
    for f in ("kx", "ky", "kz"):
        rows[f] = rng.integers(0, 3, n)
    rows["flags"] = rng.integers(0, 2, n) * wire.FLAG_NO_CULL
    rows["opcode"] = rng.integers(0, 8, n)        # the scheduler writes its own
    return rows


def scheduled_requests(rays, nearest, node, kind, kinds) -> np.ndarray:
    """The request rf_rtu_sched's header makes of each job (REQUEST rows; tag left as in rays):
    its ray, extent = its nearest t (bits), and by its node's kind (``kinds``: ``_kinds``) the
    op and its operands from the node's words (driver/core/wire.py, driver/core/layout.py)."""
    exp = rays.copy()
    box = np.isin(kind, [kinds["KIND_BOX32"], kinds["KIND_Q8"]])
    xf = kind == kinds.get("KIND_XF", -1)
    exp["opcode"] = np.select([box, xf], [wire.QUADBOX, wire.TRANSFORM], wire.TRIANGLE)
    exp["extent"] = _f32(nearest)
    b32, q8 = kind == kinds["KIND_BOX32"], kind == kinds["KIND_Q8"]
    exp["box"][b32] = node[b32].copy().view(layout.BOX_NODE)["box"][:, 0]
    exp["flags"][q8] |= wire.FLAG_DECODE_Q8
    exp["qnode"][q8] = node[q8, :wire.QNODE_WORDS]
    exp["matrix"][xf] = node[xf].copy().view(layout.INSTANCE_NODE)["world_to_object"][:, 0]
    tri = kind == kinds["KIND_TRI"]
    exp["tri"][tri] = node[tri, :16].copy().view(layout.TRI_NODE)["tri"][:, 0]
    pair = node[:, :16].copy().view(layout.PAIR_NODE)[:, 0]
    p0, p1 = kind == kinds["KIND_PAIR0"], kind == kinds["KIND_PAIR1"]
    exp["tri"][p0] = pair["v"][p0, :3]
    sel = (pair["idx"][:, None] >> np.array([0, 2, 4], np.uint32)) & 3
    exp["tri"][p1] = np.take_along_axis(pair["v"], sel[:, :, None].astype(np.int64), 1)[p1]
    return exp


@pytest.mark.parametrize("seed,valid,ready", [(4, 0.9, 0.9), (5, 0.5, 0.3), (6, 1.0, 0.1)])
def test_scheduler_under_back_pressure(seed, valid, ready):
    lib = _lib()
    kinds = _kinds()
    rng = np.random.default_rng(seed)
    n, cycles = 500, 12000
    job_slot = rng.integers(0, RAYS, n).astype(np.uint8)
    job_kind = rng.choice(list(kinds.values()), n).astype(np.uint8)
    rays = _ray_rows(rng, n)
    job_ray = np.ascontiguousarray(wire.REQUEST.pack(rays)[:, 1:wire.RAY_WORDS])
    job_nearest = _rand_u32(rng, n)
    job_node = _rand_u32(rng, (n, NODE_WORDS))
    arm = (rng.random(cycles) < valid).astype(np.uint8)
    dp_ready = (rng.random(cycles) < ready).astype(np.uint8)
    load_cycle = np.full(n, -1, np.int64)
    ready_log, pick_log = np.zeros(cycles, np.uint8), np.zeros(cycles, np.uint8)
    issue_cycle = np.full(n, -1, np.int64)
    issue_slot, issue_box = np.zeros(n, np.uint8), np.zeros(n, np.uint8)
    issue_req = np.zeros((n, wire.REQ_WORDS), np.uint32)
    errs = np.zeros(1, np.int64)
    lib.sched_run.argtypes = [ctypes.c_int64, ctypes.c_int64, U8, U8, U32, U32, U32, U8, U8,
                              I64, U8, U8, I64, U8, U8, U32, I64]
    lib.sched_run.restype = ctypes.c_int64
    issued = lib.sched_run(cycles, n, job_slot, job_kind, job_ray, job_nearest, job_node, arm,
                           dp_ready, load_cycle, ready_log, pick_log, issue_cycle, issue_slot,
                           issue_box, issue_req, errs)
    assert issued == n and (load_cycle >= 0).all() and errs[0] == 0
    # reference, cycle by cycle on the monitored ready bits: round robin from the slot after the
    # last one issued; a request moves when dp_ready_i is high
    held = [-1] * RAYS
    nxt, e, jobs, want = 0, 0, [], []
    for k in range(cycles):
        while e < n and load_cycle[e] == k:
            held[job_slot[e]] = e
            e += 1
        pick = rr_pick(int(ready_log[k]), nxt)
        assert bool(pick_log[k] >> 7) == (pick is not None), k
        if pick is None:
            continue
        assert pick_log[k] & 0x7F == pick, k
        if dp_ready[k]:
            want.append((k, pick))
            jobs.append(held[pick])
            nxt = (pick + 1) % RAYS
    assert list(zip(issue_cycle.tolist(), issue_slot.tolist())) == want
    assert ((pick_log >> 7 == 1) & (dp_ready == 0)).sum() > 50      # requests held back
    jobs = np.array(jobs)
    assert sorted(jobs.tolist()) == list(range(n))                  # each job issued once
    exp = scheduled_requests(rays[jobs], job_nearest[jobs], job_node[jobs], job_kind[jobs],
                             kinds)
    exp["tag"] = issue_slot
    assert issue_box.tolist() == (exp["opcode"] == wire.QUADBOX).tolist()
    assert (issue_req == wire.REQUEST.pack(exp)).all(axis=1).tolist() == [True] * n
    kind = job_kind[jobs]
    assert (kind == kinds["KIND_PAIR1"]).sum() > 50 and (kind == kinds["KIND_Q8"]).sum() > 50


def _pair_slots(rng, n) -> np.ndarray:
    """n slots, none the same as the one before (a slot has one response in flight)."""
    s = rng.integers(0, RAYS, n)
    for i in range(1, n):
        if s[i] == s[i - 1]:
            s[i] = (s[i] + rng.integers(1, RAYS)) % RAYS
    return s.astype(np.uint8)


def _bits(x) -> list[int]:
    return np.asarray(x, np.float32).reshape(-1).view(np.uint32).tolist()


def response_effects(rsp, node, kind, slot, kinds, slot_w):
    """What rf_rtu_resp's header says one response (a RESPONSE row) does to its slot, whose
    node buffer entry is ``node`` (words) of kind ``kind``: (the pointers pushed, in order; the
    event: 1 div_o, 2 next_o, 4 xf_o; the division (t_num bits, t_den bits, tag) or None; the
    ray setup (o' bits, d' bits, tag) or None). Tags: {prim, slot} and {instance, BLAS root,
    slot}, the slot ``slot_w`` bits wide."""
    op = int(rsp["opcode"])
    if op == wire.QUADBOX:
        child = layout.node_word(layout.Q8_NODE if kind == kinds["KIND_Q8"] else layout.BOX_NODE,
                                 "child")
        return ([int(node[child + rsp["box_index"][j]]) for j in (3, 2, 1, 0)
                 if rsp["box_hit"][j]], 2, None, None)
    if op == wire.TRANSFORM:
        inst = layout.INSTANCE_NODE
        tag = (int(node[layout.node_word(inst, "instance")]) << 32 + slot_w
               | int(node[layout.node_word(inst, "blas")]) << slot_w | slot)
        return [_return_ptr()], 4, None, (_bits(rsp["xf_origin"]), _bits(rsp["xf_dir"]), tag)
    if rsp["tri_hit"]:
        prim = layout.node_word(layout.PAIR_NODE, "prim") + (kind == kinds["KIND_PAIR1"])
        if kind == kinds["KIND_TRI"]:
            prim = layout.node_word(layout.TRI_NODE, "prim")
        return ([], 1, (*_bits(rsp["t_num"]), *_bits(rsp["t_den"]),
                        int(node[prim]) << slot_w | slot), None)
    return [], 2, None, None


def _return_ptr() -> int:
    """rf_rtu_pkg::RETURN_PTR, read from the package: the return marker's pointer (type bits
    RETURN_TYPE, offset 0)."""
    text = (RTL_DIR / "rf_rtu_pkg.sv").read_text()
    assert "RETURN_PTR     = {29'd0, RETURN_TYPE}" in text
    return int(re.search(r"RETURN_TYPE\s*=\s*3'd(\d+)", text)[1])


@pytest.mark.parametrize("seed,valid,ready", [(7, 0.9, 0.9), (8, 0.5, 0.3), (9, 1.0, 0.1)])
def test_response_processing_under_back_pressure(seed, valid, ready):
    lib = _lib()
    kinds = _kinds()
    rng = np.random.default_rng(seed)
    n, cycles = 600, 12000
    slot = _pair_slots(rng, n)
    kind = rng.choice(list(kinds.values()), n).astype(np.uint8)
    box = np.isin(kind, [kinds["KIND_BOX32"], kinds["KIND_Q8"]])
    rows = np.zeros(n, wire.RESPONSE_DTYPE)
    rows["opcode"] = np.where(box, wire.QUADBOX, wire.TRIANGLE)
    rows["box_hit"] = rng.integers(0, 2, (n, 4))          # a triangle's box fields: ignored
    rows["box_index"] = rng.integers(0, 4, (n, 4))
    rows["tri_hit"] = rng.integers(0, 2, n)               # a box's tri_hit: ignored
    rows["t_num"], rows["t_den"] = _f32(_rand_u32(rng, n)), _f32(_rand_u32(rng, n))
    rows["box_tmin"] = rng.random((n, 4))
    rows["tag"] = slot
    rsp = wire.RESPONSE.pack(rows)
    node = _rand_u32(rng, (n, NODE_WORDS))
    in_gap = (rng.random(cycles) < valid).astype(np.uint8)
    div_ready = (rng.random(cycles) < ready).astype(np.uint8)
    take = np.full(n, -1, np.int64)
    m = 4 * n
    push_cycle, evt_cycle, div_cycle = (np.full(m, -1, np.int64) for _ in range(3))
    push_slot, evt_slot, evt_what = (np.zeros(m, np.uint8) for _ in range(3))
    push_ptr, div_num, div_den = (np.zeros(m, np.uint32) for _ in range(3))
    div_tag = np.zeros(m, np.uint64)
    errs, counts = np.zeros(1, np.int64), np.zeros(4, np.int64)
    lib.resp_run.argtypes = [ctypes.c_int64, ctypes.c_int64, U32, U8, U8, U32, U8, U8, I64, I64,
                             U8, U32, I64, U8, U8, I64, U32, U32, U64, I64, I64]
    lib.resp_run(cycles, n, rsp, slot, kind, node, in_gap, div_ready, take, push_cycle,
                 push_slot, push_ptr, evt_cycle, evt_slot, evt_what, div_cycle, div_num, div_den,
                 div_tag, errs, counts)
    assert counts[0] == n and errs[0] == 0      # all taken; dp_ready_o not from dp_valid_i
    # reference: per response taken in cycle c, what its header says, cycle by cycle
    pushes, events, divs = [], [], []
    next_ok = 0
    for i in range(n):
        c, s = int(take[i]), int(slot[i])
        assert c >= next_ok, i                  # held back while the last one's pushes go out
        ptrs, what, div, _ = response_effects(rows[i], node[i], kind[i], s, kinds, 2)
        pushes += [(c + q, s, ptr) for q, ptr in enumerate(ptrs)]
        events.append((c + max(len(ptrs), 1) - 1, s, what))
        if div:
            divs.append((c, *div))
        next_ok = c + max(len(ptrs), 1)
    got_push = list(zip(push_cycle[:counts[1]].tolist(), push_slot[:counts[1]].tolist(),
                        push_ptr[:counts[1]].tolist()))
    got_evt = list(zip(evt_cycle[:counts[2]].tolist(), evt_slot[:counts[2]].tolist(),
                       evt_what[:counts[2]].tolist()))
    got_div = list(zip(div_cycle[:counts[3]].tolist(), div_num[:counts[3]].tolist(),
                       div_den[:counts[3]].tolist(), div_tag[:counts[3]].tolist()))
    assert got_push == pushes and got_evt == events and got_div == divs
    assert len(pushes) > n // 2 and len(divs) > 50 and max(c for c, *_ in events) < cycles - 1


def test_ray_buffer_against_its_reference():
    lib = _lib()
    rng = np.random.default_rng(10)
    cycles = 4000
    ctl = ((rng.random((cycles, 6)) < [0.15, 0.3, 0.3, 0.3, 0.2, 0.2]) << np.arange(6)).sum(1)
    ctl = ctl.astype(np.uint8)
    slots = rng.integers(0, RAYS, (cycles, 8))
    load = (ctl & 1) == 1
    for port in range(1, 5):            # a slot being loaded gets no other write this cycle
        same = load & (slots[:, port] == slots[:, 0])
        slots[same, port] = (slots[same, 0] + rng.integers(1, RAYS, same.sum())) % RAYS
    slots = np.ascontiguousarray(slots, np.uint8)
    ray = _rand_u32(rng, (cycles, wire.RAY_WORDS - 1))
    ids, hit_t, hit_prim = (_rand_u32(rng, cycles) for _ in range(3))
    any_hit = rng.integers(0, 2, cycles).astype(np.uint8)
    ray_a = np.zeros((cycles, wire.RAY_WORDS - 1), np.uint32)
    words = np.zeros((cycles, 10), np.uint32)
    lib.raybuf_run.argtypes = [ctypes.c_int64, U8, U8, U32, U32, U8, U32, U32, U32, U32]
    lib.raybuf_run(cycles, ctl, slots, ray, ids, any_hit, hit_t, hit_prim, ray_a, words)
    # reference: per slot the header's fields; reset: no hit, prim NO_CHILD, the rest zero; a
    # load: the ray, its id and any-hit flag, nearest = its extent, no hit, counters zero
    extent = wire.REQUEST.field["extent"].word - 1
    st = [dict(ray=None, id=None, any=0, near=0, prim=layout.NO_CHILD, hit=0, box=0, tri=0,
               ovf=0, rst=0) for _ in range(RAYS)]
    checked = 0
    for k in range(cycles):
        a, b, c = (st[int(s)] for s in slots[k, 5:8])
        want = [a["near"], b["near"], b["any"], c["id"], c["hit"], c["prim"], c["near"],
                c["box"], c["tri"], c["ovf"] | c["rst"] << 16]
        got = words[k].tolist()
        if c["id"] is None:             # ray words and ids: only read while a ray is there
            want[3] = got[3]
        assert got == want, k
        if a["ray"] is not None:
            assert ray_a[k].tolist() == a["ray"], k
            checked += 1
        bits = int(ctl[k])
        s = [int(x) for x in slots[k, :5]]
        if bits & 1:
            st[s[0]] = dict(ray=ray[k].tolist(), id=int(ids[k]), any=int(any_hit[k]),
                            near=int(ray[k, extent]), prim=layout.NO_CHILD, hit=0, box=0,
                            tri=0, ovf=0, rst=0)
        if bits & 2:
            st[s[1]].update(near=int(hit_t[k]), prim=int(hit_prim[k]), hit=1)
        for bit, port, field in ((4, 2, "box"), (8, 2, "tri"), (16, 3, "ovf"), (32, 4, "rst")):
            if bits & bit:
                st[s[port]][field] += 1
    assert checked > cycles // 2


F32_SPECIAL = np.array([0, 0x80000000, 0x7F800000, 0xFF800000, 0x7FC00000, 0xFFC00001,
                        0x7F800001, 1, 0x80000001, 0x007FFFFF, 0x00800000, 0x7F7FFFFF,
                        0x3F800000, 0xBF800000], np.uint32)


def test_hit_update_against_its_reference():
    lib = _lib()
    rng = np.random.default_rng(11)
    cycles = 6000
    valid = (rng.random(cycles) < 0.7).astype(np.uint8)
    slot = rng.integers(0, RAYS, cycles)
    prim = _rand_u32(rng, cycles)
    tag = np.ascontiguousarray(prim.astype(np.uint64) << np.uint64(2) | slot.astype(np.uint64))
    nearest = np.where(rng.random((cycles, RAYS)) < 0.2,
                       rng.choice(F32_SPECIAL, (cycles, RAYS)),
                       (rng.random((cycles, RAYS)) * 100).astype(np.float32).view(np.uint32))
    nearest = np.ascontiguousarray(nearest, np.uint32)
    near = nearest[np.arange(cycles), slot]
    # t: the ray's nearest t (a tie), one ulp either side, a special value, or anything
    way = rng.integers(0, 5, cycles)
    t = np.select([way == 0, way == 1, way == 2, way == 3],
                  [near, near + np.uint32(1), near - np.uint32(1),
                   rng.choice(F32_SPECIAL, cycles)],
                  (rng.random(cycles) * 100).astype(np.float32).view(np.uint32)).astype(np.uint32)
    any_hit = rng.integers(0, 2, (cycles, RAYS)).astype(np.uint8)
    out = np.zeros(cycles, np.uint8)
    hit_t, hit_prim = np.zeros(cycles, np.uint32), np.zeros(cycles, np.uint32)
    lib.hit_run.argtypes = [ctypes.c_int64, U8, U32, U64, U32, U8, U8, U32, U32]
    lib.hit_run(cycles, valid, t, tag, nearest, any_hit, out, hit_t, hit_prim)
    # reference: accepted when t < nearest (IEEE, strictly; NaN never); an accepted triangle of
    # an any-hit ray finishes it, anything else sends the ray on; always ready
    with np.errstate(invalid="ignore"):
        lt = _f32(t) < _f32(near)
    v = valid == 1
    hit = v & lt
    finish = hit & (any_hit[np.arange(cycles), slot] == 1)
    assert ((out & 1) == 1).all()
    assert ((out >> 1) & 1).tolist() == hit.tolist()
    assert ((out >> 2) & 1).tolist() == (v & ~finish).tolist()
    assert ((out >> 3) & 1).tolist() == finish.tolist()
    assert ((out[v] >> 4) & 3).tolist() == slot[v].tolist()
    assert ((out[hit] >> 6) & 3).tolist() == slot[hit].tolist()
    assert hit_t[hit].tolist() == t[hit].tolist() and hit_prim[hit].tolist() == prim[hit].tolist()
    assert hit.sum() > 500 and finish.sum() > 200 and (v & (way == 0) & ~hit).sum() > 300


# ---- the datapath pipelines (rf_rtu_pipes) ----------------------------------------------------
# rf_rtu_pipes with its response stages, two pipelines and one, under random gaps on every
# pipeline's input and random ready on the shared divider and ray-setup ports. Its datapaths are
# the testbench's stand-in (sim/rtu_pipes_datapath.sv: the datapath's handshake and latency, a
# response that is a fixed function of the request), so the reference is that function followed
# by the response stage's header (response_effects); the arbiters' reference is the round robin
# of rf_rtu_pipes' header, cycle by cycle, on the monitored requests of the stages.

PIPE_RAYS = RTU_UNITS_PARAMS["PIPE_RAYS"]
PIPE_SLOT_W = (PIPE_RAYS - 1).bit_length()


def standin_responses(req_words) -> np.ndarray:
    """The stand-in datapath's response to each request (sim/rtu_pipes_datapath.sv's header):
    RESPONSE rows from (n, 81) request words."""
    q = np.asarray(req_words, np.uint32)
    w = np.zeros((len(q), wire.RESPONSE.words), np.uint32)
    w[:, 0] = q[:, 0]
    i = np.arange(1, wire.RESPONSE.words)
    w[:, 1:] = q[:, i] ^ q[:, 15 + i] ^ q[:, 39 + i] ^ q[:, 55 + i]
    w[:, 1] = (w[:, 1] & ~np.uint32(7)) | (q[:, 1] & np.uint32(7))
    return wire.RESPONSE.unpack(w)


def _pipe_jobs(rng, n, kinds):
    """n jobs (node words, kind, request as the scheduler makes it): box32 nodes, triangle
    nodes, pair leaves (either triangle) and instance nodes (TRANSFORM), random words."""
    kind = rng.choice([kinds[k] for k in ("KIND_BOX32", "KIND_TRI", "KIND_PAIR0", "KIND_PAIR1",
                                          "KIND_XF")], n, p=[0.2, 0.2, 0.1, 0.1, 0.4])
    kind = kind.astype(np.uint8)
    node = _rand_u32(rng, (n, NODE_WORDS))
    req = scheduled_requests(_ray_rows(rng, n), _rand_u32(rng, n), node, kind, kinds)
    return node, kind, req


def _pipes_run(pipes, job_pipe, node, kind, req, gap, div_ready, xf_ready) -> dict:
    """Run the jobs through rf_rtu_pipes (sim/rtu_units_tb.cpp's pipes_run); what the
    monitors recorded, trimmed to what moved."""
    lib = _lib()
    n, cycles = len(job_pipe), len(div_ready)
    m = 4 * n
    r = dict(in_cycle=np.full(n, -1, np.int64), in_slot=np.zeros(n, np.uint8),
             flags=np.zeros(cycles, np.uint8),
             evt_cycle=np.full(n, -1, np.int64), evt_pipe=np.zeros(n, np.uint8),
             evt_job=np.full(n, -1, np.int64), evt_what=np.zeros(n, np.uint8),
             push_cycle=np.full(m, -1, np.int64), push_pipe=np.zeros(m, np.uint8),
             push_job=np.full(m, -1, np.int64), push_ptr=np.zeros(m, np.uint32),
             div_cycle=np.full(n, -1, np.int64), div_words=np.zeros((n, 4), np.uint32),
             xf_cycle=np.full(n, -1, np.int64), xf_words=np.zeros((n, 9), np.uint32),
             errs=np.zeros(3, np.int64), counts=np.zeros(5, np.int64))
    lib.pipes_run.argtypes = [ctypes.c_int64] * 4 + [U8, U32, U32, U8, U8, U8, U8, I64, U8, U8,
                                                     I64, U8, I64, U8, I64, U8, I64, U32, I64,
                                                     U32, I64, U32, I64, I64]
    lib.pipes_run(cycles, pipes, PIPE_RAYS, n, job_pipe, wire.REQUEST.pack(req), node, kind,
                  np.ascontiguousarray(gap, np.uint8), div_ready, xf_ready, *r.values())
    _, evts, pushes, divs, xfs = r["counts"].tolist()
    for key, count in (("evt", evts), ("push", pushes), ("div", divs), ("xf", xfs)):
        for name in [k for k in r if k.startswith(key + "_")]:
            r[name] = r[name][:count]
    return r


def _pipes_reference(r, job_pipe, node, kind, req, kinds):
    """Each job's response: the stand-in datapath's, then the response stage's header
    (response_effects); checks every job's event and pushes (one a cycle, ending with the
    event) and returns (the divisions, the ray setups) the stages must have handed on, by the
    cycle their event names them, and the cycle each response was taken."""
    n = len(job_pipe)
    rows = req.copy()
    rows["tag"] = r["in_slot"]
    rsp = standin_responses(wire.REQUEST.pack(rows))
    evt = {int(j): (int(c), int(w)) for j, c, w in zip(r["evt_job"], r["evt_cycle"],
                                                         r["evt_what"])}
    divs, xfs, take, pushes = {}, {}, np.zeros(n, np.int64), 0
    for j in range(n):
        ptrs, what, div, xf = response_effects(rsp[j], node[j], kind[j], int(r["in_slot"][j]),
                                               kinds, PIPE_SLOT_W)
        c, got_what = evt[j]
        assert got_what == what, j
        take[j] = c - max(len(ptrs), 1) + 1       # the response taken: its pushes, one a cycle
        mine = r["push_job"] == j
        assert r["push_ptr"][mine].tolist() == ptrs, j
        assert r["push_cycle"][mine].tolist() == list(range(take[j], take[j] + len(ptrs))), j
        assert (r["push_pipe"][mine] == job_pipe[j]).all()
        pushes += len(ptrs)
        if div:
            divs[c] = div
        if xf:
            xfs[c] = (*xf[0], *xf[1], xf[2])
    assert len(r["push_job"]) == pushes                                # none extra
    return divs, xfs, take


def _check_round_robin(r, pipes, port, ready_in, taken):
    """The arbiter of a shared port (0 divider, 1 ray setup) against rf_rtu_pipes' header, cycle
    by cycle on the stages' monitored requests: valid when any stage asks, the first asking at
    or after the one after the last served takes the port when it is ready (``taken``: the
    cycles it moved), and so no stage waits while another is served twice. Returns the grants
    made while both stages asked."""
    what = (1, 4)[port]                         # the event naming the stage served
    pipe_at = {int(c): int(p) for c, p, w in zip(r["evt_cycle"], r["evt_pipe"], r["evt_what"])
               if w == what}
    want, valid_o = r["flags"] >> 2 * port & 3, r["flags"] >> 4 + port & 1
    start, waited, contended = 0, [0] * pipes, 0
    for k in range(len(want)):
        pick = rr_pick(int(want[k]), start, pipes)
        assert valid_o[k] == (pick is not None), (port, k)
        assert (k in taken) == (pick is not None and ready_in[k] == 1), (port, k)
        if k not in taken:
            continue
        assert pipe_at[k] == pick, (port, k)
        start = (pick + 1) % pipes
        contended += int(want[k]) == 3
        for q in range(pipes):
            waited[q] = 0 if q == pick else waited[q] + (int(want[k]) >> q & 1)
            assert waited[q] < pipes, (port, k, q)
    return contended


@pytest.mark.parametrize("pipes,seed,valid,ready", [
    (2, 21, 0.9, (0.9, 0.9)), (2, 22, 0.5, (0.3, 0.3)), (2, 23, 1.0, (0.15, 0.9)),
    (2, 25, 1.0, (0.9, 0.15)), (1, 24, 0.3, (0.7, 0.7))])
def test_pipelines_under_back_pressure(pipes, seed, valid, ready):
    kinds = _kinds(xf=True)
    rng = np.random.default_rng(seed)
    n, cycles = 600, 8000
    node, kind, req = _pipe_jobs(rng, n, kinds)
    job_pipe = rng.integers(0, pipes, n).astype(np.uint8)
    gap = rng.random((2, cycles)) < valid
    div_ready, xf_ready = ((rng.random(cycles) < p).astype(np.uint8) for p in ready)
    r = _pipes_run(pipes, job_pipe, node, kind, req, gap, div_ready, xf_ready)
    # every job taken once, in its driver's order, and one event each, on its pipeline's ports,
    # in request order per pipeline; the ready and valid outputs are register outputs; no event
    # or push for an empty slot
    assert r["counts"][0] == n and r["errs"].tolist() == [0, 0, 0]
    assert sorted(r["evt_job"].tolist()) == list(range(n))
    assert r["evt_cycle"].max() < cycles - 1
    for p in range(pipes):
        jobs = np.flatnonzero(job_pipe == p)
        assert (np.diff(r["in_cycle"][jobs]) > 0).all()
        assert r["evt_job"][r["evt_pipe"] == p].tolist() == jobs.tolist()
    # each response bit-exact to the reference, its pushes and its event; a response is taken
    # LATENCY cycles after its request at the earliest, and some are
    want_divs, want_xfs, take = _pipes_reference(r, job_pipe, node, kind, req, kinds)
    assert (take - r["in_cycle"]).min() == default_latency()
    # each division and ray setup handed on once, in the cycle its stage names its job
    got_divs = {int(c): (int(w[0]), int(w[1]), int(w[2]) | int(w[3]) << 32)
                for c, w in zip(r["div_cycle"], r["div_words"])}
    got_xfs = {int(c): (*w[:6].tolist(), int(w[6]) | int(w[7]) << 32 | int(w[8]) << 64)
               for c, w in zip(r["xf_cycle"], r["xf_words"])}
    assert got_divs == want_divs and got_xfs == want_xfs
    assert len(want_divs) > 40 and len(want_xfs) > 40
    assert (np.bincount(r["push_job"], minlength=n) > 1).sum() > 30   # several pushes a response
    # the arbiters: round robin, bounded wait; a port that is often not ready has both stages
    # asking at once often enough
    for port, (ready_in, taken) in enumerate(((div_ready, got_divs), (xf_ready, got_xfs))):
        contended = _check_round_robin(r, pipes, port, ready_in, taken)
        assert pipes == 1 or ready[port] > 0.3 or contended >= 10, port
