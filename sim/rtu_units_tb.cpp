// Test benches of the RT unit's modules alone, driven cycle by cycle from stimulus arrays that the
// Python test writes (tests/test_rtunit_modules.py: its reference models and scoreboards). The
// model is rtu_units_tb_top (sim/rtu_units_tb_top.sv): the modules side by side, one build; each
// function below drives one of them and leaves the others idle.
//
// The handshake ports follow one pattern: a driver offers the next transaction of its stream
// after a random gap and holds it (valid and data stable) until it is taken; the consumer's ready
// is a random bit per cycle; a monitor records every transaction that moves (cycle and payload)
// and the inputs the Python reference needs; the scoreboard is in Python.
#include <cstdint>
#include <cstring>
#include <vector>

#include "Vrtu_units_tb_top.h"
#include "verilated.h"
using Top = Vrtu_units_tb_top;

namespace {
void tick(Top& t) {
  t.clk_i = 1;
  t.eval();
  t.clk_i = 0;
  t.eval();
}
void reset(Top& t) {
  t.clk_i = 0;
  t.rst_ni = 0;
  t.eval();
  tick(t);
  tick(t);
  t.rst_ni = 1;
  t.eval();
}

constexpr int kRays = 4;        // rtu_units_tb_top's RAYS
constexpr int kNodeWords = 32;  // rf_rtu_pkg::NODE_W / 32
constexpr int kRayWords = 14;   // ray_t: request words 1..14
constexpr int kReqWords = 81;   // rf_pkg::req_t
constexpr int kRspWords = 17;   // rf_pkg::rsp_t

// The memory's data for a node request at byte address addr: word i of a deterministic hash
// (tests/test_rtunit_modules.py computes the same words).
uint32_t mem_word(uint64_t addr, uint32_t i) {
  return (static_cast<uint32_t>(addr) * 0x9E3779B1u + i * 0x85EBCA77u +
          static_cast<uint32_t>(addr >> 32) * 0xC2B2AE3Du) ^ (i << 16);
}
}  // namespace

#pragma GCC visibility push(default)
extern "C" {

// ---- rf_rtu_stack ----
// Per cycle k: inputs ctl[k] (bit 0 clear, 1 push, 2 pop, 3 refill), clear/push/pop slots, the
// pushed pointer; outputs sampled before the clock edge: top, empty | spilled << 1 | spill << 2,
// the spilled pointer, and the depth output.
void stack_run(int64_t n, const uint8_t* ctl, const uint32_t* clear_slot, const uint32_t* push_slot,
               const uint32_t* push_ptr, const uint32_t* pop_slot, uint32_t* top, uint8_t* flags,
               uint32_t* spill_ptr, uint32_t* depth) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.k_clear_i = t.k_push_i = t.k_pop_i = t.k_refill_i = 0;
  reset(t);
  for (int64_t k = 0; k < n; k++) {
    t.k_clear_i = ctl[k] & 1;
    t.k_push_i = (ctl[k] >> 1) & 1;
    t.k_pop_i = (ctl[k] >> 2) & 1;
    t.k_refill_i = (ctl[k] >> 3) & 1;
    t.k_clear_slot_i = clear_slot[k];
    t.k_push_slot_i = push_slot[k];
    t.k_push_ptr_i = push_ptr[k];
    t.k_pop_slot_i = pop_slot[k];
    t.eval();
    top[k] = t.k_top_o;
    flags[k] = t.k_empty_o | t.k_spilled_o << 1 | t.k_spill_o << 2;
    spill_ptr[k] = t.k_spill_ptr_o;
    depth[k] = t.k_depth_o;
    tick(t);
  }
}

// ---- rf_rtu_fetch ----
// Driver (in): command j (slot, pointer, refill) after a gap (in_gap[k]) once no fetch of its
// slot is outstanding (the caller's rule: one per slot), held until taken; in_cycle[j] records
// the handshake. mem_req: ready req_ready[k]; each request taken is recorded (req_*; its cycle)
// and the memory answers it after lat[r] cycles or more, in any order: each cycle with
// rsp_go[k], the due request number rsp_pick[k] % due of those outstanding (rsp_req[e]: which
// request, rsp_cycle[e]) with mem_word data, or for a refill word 0 = refill_val of the command
// in flight for the slot. Monitor: done pulses (done_*), node_a/node_b of rd_a[k]/rd_b[k] each
// cycle (nodes (cycles, 2, 32)), in_bad_o for probe_ptr[k] (bad: bit 0 with Q8, bit 1 without),
// and errs[0] the cycles where in_ready_o or mem_req_valid_o and its data moved with in_valid_i
// or mem_req_ready_i (they are register outputs), errs[1] the cycles mem_rsp_ready_o was low.
// counts: commands taken, requests, responses, done pulses.
void fetch_run(int64_t cycles, int64_t n, const uint8_t* slot, const uint32_t* ptr,
               const uint8_t* refill, const uint32_t* refill_val, const uint8_t* in_gap,
               const uint8_t* req_ready, const int64_t* lat, const uint8_t* rsp_go,
               const uint32_t* rsp_pick, const uint32_t* probe_ptr, const uint8_t* rd_a,
               const uint8_t* rd_b, int64_t* in_cycle, int64_t* req_cycle, uint64_t* req_addr,
               uint32_t* req_size, uint8_t* req_tag, uint8_t* req_refill, int64_t* rsp_cycle,
               int64_t* rsp_req, int64_t* done_cycle, uint8_t* done_slot, uint8_t* done_refill,
               uint32_t* done_ptr, uint32_t* nodes, uint8_t* bad, int64_t* errs,
               int64_t* counts) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.f_in_valid_i = t.f_mem_req_ready_i = t.f_mem_rsp_valid_i = 0;
  reset(t);
  struct Out { int64_t req, due; uint8_t tag; bool refill; uint64_t addr; };
  std::vector<Out> out;                 // requests the memory holds
  int64_t busy_cmd[kRays];              // the command in flight per slot, or -1
  for (auto& b : busy_cmd) b = -1;
  int64_t next = 0, reqs = 0, rsps = 0, dones = 0;
  bool offering = false;
  for (int64_t k = 0; k < cycles; k++) {
    // register outputs: not moved by this cycle's valid or ready
    t.f_in_valid_i = 0;
    t.f_mem_req_ready_i = 0;
    t.f_in_ptr_i = probe_ptr[k];
    t.eval();
    bad[k] = t.f_in_bad_o | t.f_in_bad_box32_o << 1;
    const uint32_t r0 = t.f_in_ready_o, v0 = t.f_mem_req_valid_o, s0 = t.f_mem_req_size_o,
                   g0 = t.f_mem_req_tag_o << 1 | t.f_mem_req_refill_o;
    const uint64_t a0 = t.f_mem_req_addr_o;
    t.f_in_valid_i = 1;
    t.f_mem_req_ready_i = 1;
    t.eval();
    errs[0] += r0 != t.f_in_ready_o || v0 != t.f_mem_req_valid_o || a0 != t.f_mem_req_addr_o ||
               s0 != t.f_mem_req_size_o || g0 != (t.f_mem_req_tag_o << 1 | t.f_mem_req_refill_o);
    // driver
    if (!offering && next < n && in_gap[k] && busy_cmd[slot[next]] < 0) offering = true;
    t.f_in_valid_i = offering;
    t.f_in_slot_i = offering ? slot[next] : 0;
    t.f_in_ptr_i = offering ? ptr[next] : 0;
    t.f_in_refill_i = offering ? refill[next] : 0;
    t.f_mem_req_ready_i = req_ready[k];
    // the memory's response, if one is due and this cycle answers
    t.f_mem_rsp_valid_i = 0;
    int64_t due = 0;
    for (const Out& o : out) due += o.due <= k;
    if (rsp_go[k] && due > 0) {
      int64_t pick = rsp_pick[k] % due, i = 0;
      for (; i < static_cast<int64_t>(out.size()); i++)
        if (out[i].due <= k && pick-- == 0) break;
      const Out o = out[i];
      out.erase(out.begin() + i);
      t.f_mem_rsp_valid_i = 1;
      t.f_mem_rsp_tag_i = o.tag;
      for (int w = 0; w < kNodeWords; w++) t.f_mem_rsp_data_i[w] = mem_word(o.addr, w);
      if (o.refill) t.f_mem_rsp_data_i[0] = busy_cmd[o.tag] >= 0 ? refill_val[busy_cmd[o.tag]] : 0;
      rsp_cycle[rsps] = k;
      rsp_req[rsps++] = o.req;
      busy_cmd[o.tag] = -1;
    }
    t.f_rd_a_i = rd_a[k];
    t.f_rd_b_i = rd_b[k];
    t.eval();
    errs[1] += !t.f_mem_rsp_ready_o;
    // monitors
    for (int w = 0; w < kNodeWords; w++) {
      nodes[(k * 2 + 0) * kNodeWords + w] = t.f_node_a_o[w];
      nodes[(k * 2 + 1) * kNodeWords + w] = t.f_node_b_o[w];
    }
    if (t.f_done_o) {
      done_cycle[dones] = k;
      done_slot[dones] = t.f_done_slot_o;
      done_refill[dones] = t.f_done_refill_o;
      done_ptr[dones++] = t.f_done_ptr_o;
    }
    if (t.f_mem_req_valid_o && t.f_mem_req_ready_i) {
      req_cycle[reqs] = k;
      req_addr[reqs] = t.f_mem_req_addr_o;
      req_size[reqs] = t.f_mem_req_size_o;
      req_tag[reqs] = t.f_mem_req_tag_o;
      req_refill[reqs] = t.f_mem_req_refill_o;
      out.push_back({reqs, k + 1 + lat[reqs], req_tag[reqs], req_refill[reqs] != 0,
                     req_addr[reqs]});
      reqs++;
    }
    if (offering && t.f_in_ready_o) {
      in_cycle[next] = k;
      busy_cmd[slot[next]] = next;
      next++;
      offering = false;
    }
    tick(t);
  }
  counts[0] = next;
  counts[1] = reqs;
  counts[2] = rsps;
  counts[3] = dones;
}

// ---- rf_rtu_sched ----
// Per slot a job's buffers (kind, ray words, nearest t, node words) and its ready bit. Driver:
// job j is loaded into slot job_slot[j] after a gap (arm[k]) once that slot is not ready (it
// was issued), and the slot is ready from that cycle (load_cycle[j]). dp_ready_i = dp_ready[k].
// The read ports answer rd_o. Monitor: each cycle ready_i (ready_log), dp_valid_o, rd_o
// (pick_log: valid << 7 | rd); each request taken (issue_cycle, issue_slot, issue_box, the
// request's words issue_req (m, 81)); errs: the cycles issue_o was not dp_valid_o & dp_ready_i
// or issue_slot_o not rd_o. Returns the requests taken.
int64_t sched_run(int64_t cycles, int64_t n, const uint8_t* job_slot, const uint8_t* job_kind,
                  const uint32_t* job_ray, const uint32_t* job_nearest, const uint32_t* job_node,
                  const uint8_t* arm, const uint8_t* dp_ready, int64_t* load_cycle,
                  uint8_t* ready_log, uint8_t* pick_log, int64_t* issue_cycle,
                  uint8_t* issue_slot, uint8_t* issue_box, uint32_t* issue_req, int64_t* errs) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.s_ready_i = 0;
  t.s_dp_ready_i = 0;
  reset(t);
  int64_t held[kRays] = {-1, -1, -1, -1};   // the job in each slot's buffers
  uint32_t ready = 0, kinds = 0;
  int64_t next = 0, issued = 0;
  for (int64_t k = 0; k < cycles; k++) {
    if (next < n && arm[k] && !(ready >> job_slot[next] & 1)) {
      const int s = job_slot[next];
      held[s] = next;
      ready |= 1u << s;
      kinds = (kinds & ~(7u << 3 * s)) | static_cast<uint32_t>(job_kind[next]) << 3 * s;
      load_cycle[next++] = k;
    }
    t.s_ready_i = ready;
    t.s_kind_i = kinds;
    t.s_dp_ready_i = dp_ready[k];
    t.eval();
    const int rd = t.s_rd_o;
    const int64_t j = held[rd];
    for (int w = 0; w < kRayWords; w++) t.s_ray_i[w] = j >= 0 ? job_ray[j * kRayWords + w] : 0;
    t.s_nearest_i = j >= 0 ? job_nearest[j] : 0;
    for (int w = 0; w < kNodeWords; w++)
      t.s_node_i[w] = j >= 0 ? job_node[j * kNodeWords + w] : 0;
    t.eval();
    ready_log[k] = static_cast<uint8_t>(ready);
    pick_log[k] = static_cast<uint8_t>(t.s_dp_valid_o << 7 | t.s_rd_o);
    const bool take = t.s_dp_valid_o && t.s_dp_ready_i;
    errs[0] += take != static_cast<bool>(t.s_issue_o) || t.s_issue_slot_o != t.s_rd_o;
    if (take) {
      issue_cycle[issued] = k;
      issue_slot[issued] = t.s_issue_slot_o;
      issue_box[issued] = t.s_issue_box_o;
      for (int w = 0; w < kReqWords; w++) issue_req[issued * kReqWords + w] = t.s_dp_req_o[w];
      issued++;
      ready &= ~(1u << t.s_issue_slot_o);      // the caller moves the slot on
    }
    tick(t);
  }
  return issued;
}

// ---- rf_rtu_resp ----
// Per slot a node buffer entry and kind. Driver (dp): response j (rsp words (n, 17)) after a gap
// (in_gap[k]), its slot's node (node (n, 32)) and kind loaded when it is first offered, held
// until taken (take_cycle[j]). div_ready_i = div_ready[k]. The read port answers rd_o. Monitor:
// pushes (push_cycle, push_slot, push_ptr), next_o and div_o pulses (evt_cycle, evt_slot,
// evt_div), divisions taken (div_cycle, div_num, div_den, div_tag). errs[0]: the cycles
// dp_ready_o moved with dp_valid_i. counts: responses taken, pushes, events, divisions.
void resp_run(int64_t cycles, int64_t n, const uint32_t* rsp, const uint8_t* slot,
              const uint8_t* kind, const uint32_t* node, const uint8_t* in_gap,
              const uint8_t* div_ready, int64_t* take_cycle, int64_t* push_cycle,
              uint8_t* push_slot, uint32_t* push_ptr, int64_t* evt_cycle, uint8_t* evt_slot,
              uint8_t* evt_div, int64_t* div_cycle, uint32_t* div_num, uint32_t* div_den,
              uint64_t* div_tag, int64_t* errs, int64_t* counts) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.r_dp_valid_i = 0;
  t.r_div_ready_i = 0;
  reset(t);
  int64_t held[kRays] = {-1, -1, -1, -1};
  int64_t next = 0, pushes = 0, evts = 0, divs = 0;
  bool offering = false;
  for (int64_t k = 0; k < cycles; k++) {
    if (!offering && next < n && in_gap[k]) {
      offering = true;
      held[slot[next]] = next;
    }
    for (int w = 0; w < kRspWords; w++) t.r_dp_rsp_i[w] = offering ? rsp[next * kRspWords + w] : 0;
    t.r_div_ready_i = div_ready[k];
    // dp_ready_o with and without dp_valid_i
    t.r_dp_valid_i = !offering;
    t.eval();
    const uint32_t ready_other = t.r_dp_ready_o;
    t.r_dp_valid_i = offering;
    t.eval();
    const int64_t j = held[t.r_rd_o];
    for (int w = 0; w < kNodeWords; w++) t.r_node_i[w] = j >= 0 ? node[j * kNodeWords + w] : 0;
    t.r_kind_i = j >= 0 ? kind[j] : 0;
    t.eval();
    errs[0] += ready_other != t.r_dp_ready_o;
    if (t.r_push_o) {
      push_cycle[pushes] = k;
      push_slot[pushes] = t.r_push_slot_o;
      push_ptr[pushes++] = t.r_push_ptr_o;
    }
    if (t.r_next_o || t.r_div_o) {
      evt_cycle[evts] = k;
      evt_slot[evts] = t.r_evt_slot_o;
      evt_div[evts++] = t.r_div_o | t.r_next_o << 1;
    }
    if (t.r_div_valid_o && t.r_div_ready_i) {
      div_cycle[divs] = k;
      div_num[divs] = t.r_div_num_o;
      div_den[divs] = t.r_div_den_o;
      div_tag[divs++] = t.r_div_tag_o;
    }
    if (offering && t.r_dp_ready_o) {
      take_cycle[next++] = k;
      offering = false;
    }
    tick(t);
  }
  counts[0] = next;
  counts[1] = pushes;
  counts[2] = evts;
  counts[3] = divs;
}

// ---- rf_rtu_ray_buffer ----
// Per cycle k: ctl[k] (bit 0 load, 1 hit, 2 box_inc, 3 tri_inc, 4 ovf_inc, 5 rst_inc), the
// ports' slots slots[k] (load, hit, issue, ovf, rst, rd_a, rd_b, rd_c), the load's ray words,
// id and any-hit flag, the hit's t and prim; outputs sampled before the clock edge: ray_a
// (cycles, 14), and words (cycles, 10): nearest_a, nearest_b, any_hit_b, id_c, hit_c, prim_c,
// nearest_c, box_ops_c, tri_ops_c, overflows_c | refills_c << 16.
void raybuf_run(int64_t cycles, const uint8_t* ctl, const uint8_t* slots, const uint32_t* ray,
                const uint32_t* id, const uint8_t* any_hit, const uint32_t* hit_t,
                const uint32_t* hit_prim, uint32_t* ray_a, uint32_t* words) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.b_load_i = t.b_hit_i = t.b_box_inc_i = t.b_tri_inc_i = t.b_ovf_inc_i = t.b_rst_inc_i = 0;
  reset(t);
  for (int64_t k = 0; k < cycles; k++) {
    const uint8_t c = ctl[k];
    const uint8_t* s = slots + 8 * k;
    t.b_load_i = c & 1;
    t.b_hit_i = c >> 1 & 1;
    t.b_box_inc_i = c >> 2 & 1;
    t.b_tri_inc_i = c >> 3 & 1;
    t.b_ovf_inc_i = c >> 4 & 1;
    t.b_rst_inc_i = c >> 5 & 1;
    t.b_load_slot_i = s[0];
    t.b_hit_slot_i = s[1];
    t.b_issue_slot_i = s[2];
    t.b_ovf_slot_i = s[3];
    t.b_rst_slot_i = s[4];
    t.b_rd_a_i = s[5];
    t.b_rd_b_i = s[6];
    t.b_rd_c_i = s[7];
    for (int w = 0; w < kRayWords; w++) t.b_load_ray_i[w] = ray[k * kRayWords + w];
    t.b_load_id_i = id[k];
    t.b_load_any_hit_i = any_hit[k];
    t.b_hit_t_i = hit_t[k];
    t.b_hit_prim_i = hit_prim[k];
    t.eval();
    for (int w = 0; w < kRayWords; w++) ray_a[k * kRayWords + w] = t.b_ray_a_o[w];
    uint32_t* o = words + 10 * k;
    o[0] = t.b_nearest_a_o;
    o[1] = t.b_nearest_b_o;
    o[2] = t.b_any_hit_b_o;
    o[3] = t.b_id_c_o;
    o[4] = t.b_hit_c_o;
    o[5] = t.b_prim_c_o;
    o[6] = t.b_nearest_c_o;
    o[7] = t.b_box_ops_c_o;
    o[8] = t.b_tri_ops_c_o;
    o[9] = t.b_overflows_c_o | static_cast<uint32_t>(t.b_refills_c_o) << 16;
    tick(t);
  }
}

// ---- rf_rtu_hit (combinational) ----
// Per cycle k: a division's result offered when valid[k] (t[k], tag[k] = prim << 2 | slot); the
// read port answers rd_o from nearest (cycles, 4) and any_hit (cycles, 4). Outputs per cycle:
// out[k] = div_ready | hit << 1 | next << 2 | finish << 3 | rd << 4 | hit_slot << 6, and the
// hit's t and prim (hit_t, hit_prim).
void hit_run(int64_t cycles, const uint8_t* valid, const uint32_t* t_bits, const uint64_t* tag,
             const uint32_t* nearest, const uint8_t* any_hit, uint8_t* out, uint32_t* hit_t,
             uint32_t* hit_prim) {
  VerilatedContext ctx;
  Top t{&ctx};
  for (int64_t k = 0; k < cycles; k++) {
    t.h_div_valid_i = valid[k];
    t.h_div_t_i = t_bits[k];
    t.h_div_tag_i = tag[k];
    t.eval();
    const int rd = t.h_rd_o;
    t.h_nearest_i = nearest[k * kRays + rd];
    t.h_any_hit_i = any_hit[k * kRays + rd];
    t.eval();
    out[k] = static_cast<uint8_t>(t.h_div_ready_o | t.h_hit_o << 1 | t.h_next_o << 2 |
                                  t.h_finish_o << 3 | rd << 4 | t.h_hit_slot_o << 6);
    hit_t[k] = t.h_hit_t_o;
    hit_prim[k] = t.h_hit_prim_o;
  }
}

// ---- rf_rtu_divs ----
// Per cycle k: in_valid[k] (offer the next division a[i], b[i], tag i while any is left) and
// out_ready[k]; each result taken is written to q[tag] and its cycle to taken[tag]. Returns the
// results taken.
int64_t divs_run(int64_t cycles, const uint8_t* in_valid, const uint8_t* out_ready, int64_t n,
                 const uint32_t* a, const uint32_t* b, uint32_t* q, int64_t* taken) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.d_in_valid_i = t.d_out_ready_i = 0;
  reset(t);
  int64_t next = 0, got = 0;
  for (int64_t k = 0; k < cycles; k++) {
    t.d_in_valid_i = next < n && in_valid[k];
    if (t.d_in_valid_i) {
      t.d_a_i = a[next];
      t.d_b_i = b[next];
      t.d_tag_i = static_cast<uint32_t>(next);
    }
    t.d_out_ready_i = out_ready[k];
    t.eval();
    if (t.d_in_valid_i && t.d_in_ready_o) next++;
    if (t.d_out_valid_o && t.d_out_ready_i) {
      const uint32_t tag = t.d_tag_o;
      if (tag < n) {
        q[tag] = t.d_q_o;
        taken[tag] = k;
      }
      got++;
    }
    tick(t);
  }
  return got;
}

// ---- rf_rtu_pipes ----
// pipes: 2 (u_pipes2) or 1 (u_pipes1, port 0 only); rays: the slots (PIPE_RAYS). Job j goes to
// pipeline job_pipe[j]: its request words req (n, 81), whose tag word the driver sets to the slot,
// and its node buffer entry node (n, 32) and kind. Driver p: its jobs in order, each offered
// after a gap (gap (2, cycles)) once a slot is free (the lowest free one: a slot holds one job
// from its offer to its last event, next_o, div_o or xf_o), held until taken (in_cycle[j],
// in_slot[j]). div_ready_i = div_ready[k], xf_ready_i = xf_ready[k]; the read ports answer rd_o[p]
// with its slot's job's node and kind. Monitor: per cycle flags[k] = div_want | xf_want << 2 |
// div_valid_o << 4 | xf_valid_o << 5; events (evt_cycle, evt_pipe, evt_job, evt_what: 1 div_o,
// 2 next_o, 4 xf_o; evt_job: the job its slot holds); pushes (push_cycle, push_pipe, push_job,
// push_ptr); divisions taken (div_cycle, div_words (m, 4): num, den, tag words 0..1) and setups
// taken (xf_cycle, xf_words (m, 9): origin, dir, tag words 0..2). errs[0]: cycles
// in_ready_o moved with in_valid_i; errs[1]: cycles div_valid_o or xf_valid_o moved with their
// ready inputs (register outputs and the arbiters' picks); errs[2]: an event or push naming a
// slot that holds no job. counts: jobs taken, events, pushes, divisions, setups.
void pipes_run(int64_t cycles, int64_t pipes, int64_t rays, int64_t n, const uint8_t* job_pipe,
               const uint32_t* req, const uint32_t* node, const uint8_t* kind, const uint8_t* gap,
               const uint8_t* div_ready, const uint8_t* xf_ready, int64_t* in_cycle,
               uint8_t* in_slot, uint8_t* flags, int64_t* evt_cycle, uint8_t* evt_pipe,
               int64_t* evt_job, uint8_t* evt_what, int64_t* push_cycle, uint8_t* push_pipe,
               int64_t* push_job, uint32_t* push_ptr, int64_t* div_cycle, uint32_t* div_words,
               int64_t* xf_cycle, uint32_t* xf_words, int64_t* errs, int64_t* counts) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.p_one_i = pipes == 1;
  t.p_in_valid_i = 0;
  t.p_div_ready_i = t.p_xf_ready_i = 0;
  reset(t);
  std::vector<int64_t> held(rays, -1);   // the job in each slot
  int sw = 0;                            // the slot fields' width: $clog2(PIPE_RAYS)
  while ((int64_t{1} << sw) < rays) sw++;
  const uint32_t slot_mask = (1u << sw) - 1;
  int64_t next[2] = {0, 0}, offer[2] = {-1, -1};   // per driver: its next job, the one offered
  int64_t taken = 0, evts = 0, pushes = 0, divs = 0, xfs = 0;
  auto find = [&](int p, int64_t from) {   // driver p's next job at or after from
    while (from < n && job_pipe[from] != p) from++;
    return from;
  };
  for (int p = 0; p < 2; p++) next[p] = find(p, 0);
  auto set_valid = [&](bool probe) {
    uint32_t v = 0;
    for (int p = 0; p < 2; p++) v |= static_cast<uint32_t>((offer[p] >= 0) != probe) << p;
    t.p_in_valid_i = v;
  };
  for (int64_t k = 0; k < cycles; k++) {
    // drivers: the next job into the lowest free slot, after a gap
    for (int p = 0; p < pipes; p++) {
      if (offer[p] >= 0 || next[p] >= n || !gap[p * cycles + k]) continue;
      int64_t s = 0;
      while (s < rays && held[s] >= 0) s++;
      if (s == rays) continue;
      offer[p] = next[p];
      held[s] = next[p];
      in_slot[next[p]] = static_cast<uint8_t>(s);
      for (int w = 0; w < kReqWords; w++)
        t.p_req_i[p * kReqWords + w] =
            w == 0 ? static_cast<uint32_t>(s) : req[next[p] * kReqWords + w];
      next[p] = find(p, next[p] + 1);
    }
    // the ready outputs with the valid inputs flipped, the valid outputs with the readies
    // flipped: register outputs move with neither
    set_valid(true);
    t.p_div_ready_i = !div_ready[k];
    t.p_xf_ready_i = !xf_ready[k];
    t.eval();
    const uint32_t ready_probe = t.p_in_ready_o;
    const uint32_t valid_probe = t.p_div_valid_o | t.p_xf_valid_o << 1;
    set_valid(false);
    t.p_div_ready_i = div_ready[k];
    t.p_xf_ready_i = xf_ready[k];
    t.eval();
    for (int p = 0; p < 2; p++) {   // the read ports
      const int64_t j = held[(t.p_rd_o >> (sw * p)) & slot_mask];
      for (int w = 0; w < kNodeWords; w++)
        t.p_node_i[p * kNodeWords + w] = j >= 0 ? node[j * kNodeWords + w] : 0;
      t.p_kind_i = (t.p_kind_i & ~(7u << 3 * p)) | (j >= 0 ? kind[j] : 0u) << 3 * p;
    }
    t.eval();
    errs[0] += ready_probe != t.p_in_ready_o;
    errs[1] += valid_probe != (t.p_div_valid_o | t.p_xf_valid_o << 1u);
    flags[k] = static_cast<uint8_t>(t.p_div_want_o | t.p_xf_want_o << 2 | t.p_div_valid_o << 4 |
                                    t.p_xf_valid_o << 5);
    // monitors
    std::vector<uint32_t> freed;
    for (int p = 0; p < 2; p++) {
      if (t.p_push_o >> p & 1) {
        const int64_t j = held[(t.p_push_slot_o >> (sw * p)) & slot_mask];
        errs[2] += j < 0;
        push_cycle[pushes] = k;
        push_pipe[pushes] = static_cast<uint8_t>(p);
        push_job[pushes] = j;
        push_ptr[pushes++] = static_cast<uint32_t>(t.p_push_ptr_o >> (32 * p));
      }
      const uint32_t what = (t.p_div_o >> p & 1) | (t.p_next_o >> p & 1) << 1 |
                            (t.p_xf_o >> p & 1) << 2;
      if (what) {
        const uint32_t s = (t.p_evt_slot_o >> (sw * p)) & slot_mask;
        errs[2] += held[s] < 0;
        evt_cycle[evts] = k;
        evt_pipe[evts] = static_cast<uint8_t>(p);
        evt_job[evts] = held[s];
        evt_what[evts++] = static_cast<uint8_t>(what);
        freed.push_back(s);
      }
    }
    if (t.p_div_valid_o && t.p_div_ready_i) {
      div_cycle[divs] = k;
      div_words[divs * 4 + 0] = t.p_div_num_o;
      div_words[divs * 4 + 1] = t.p_div_den_o;
      div_words[divs * 4 + 2] = static_cast<uint32_t>(t.p_div_tag_o);
      div_words[divs * 4 + 3] = static_cast<uint32_t>(t.p_div_tag_o >> 32);
      divs++;
    }
    if (t.p_xf_valid_o && t.p_xf_ready_i) {
      xf_cycle[xfs] = k;
      for (int i = 0; i < 3; i++) {
        xf_words[xfs * 9 + i] = t.p_xf_origin_o[i];
        xf_words[xfs * 9 + 3 + i] = t.p_xf_dir_o[i];
        xf_words[xfs * 9 + 6 + i] = t.p_xf_tag_o[i];
      }
      xfs++;
    }
    for (int p = 0; p < 2; p++) {
      if (offer[p] >= 0 && (t.p_in_ready_o >> p & 1)) {
        in_cycle[offer[p]] = k;
        offer[p] = -1;
        taken++;
      }
    }
    for (uint32_t s : freed) held[s] = -1;
    tick(t);
  }
  counts[0] = taken;
  counts[1] = evts;
  counts[2] = pushes;
  counts[3] = divs;
  counts[4] = xfs;
}

}  // extern "C"
#pragma GCC visibility pop
