// RT-unit replay of driver/rtunit (docs/rtunit.md): warps of threads issue their recorded rays
// as trace calls to N RT units, each unit P fresh model instances clocked together with a pool of
// ray slots, all units in front of one memory hierarchy (rf_memory.h). The requests are assembled
// by the same NodeSource as the streaming fast path (rf_sim.h).
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <queue>
#include <utility>
#include <vector>

#include "rf_memory.h"
#include "rf_sim.h"

using namespace rf;

namespace {

// A ray (or a trace call) waiting, earliest first, ties in the order they started waiting.
struct Ready {
  int64_t id, at, seq;
  bool operator>(const Ready& o) const { return at != o.at ? at > o.at : seq > o.seq; }
};
using MinQueue = std::priority_queue<Ready, std::vector<Ready>, std::greater<Ready>>;

// A pipeline as its handshakes (the unit costs with timing pipelines): a chain of `n` skid-buffer
// registers (rtl/rf_skid.sv), as rtl/rayflex.sv is, each a main and a skid slot. Only the valid
// bits are kept (the beats leave in order: the pipeline's in-flight queue names them). A beat
// moves one register per cycle while the next can take it; a stalled output backs the beats up
// into the skid slots, and the input stops taking beats when the first register's skid slot is
// full, cycle for cycle as the RTL.
struct Elastic {
  std::vector<char> main, skid;
  int64_t n = 0;

  void configure(int64_t stages) {
    n = stages;
    main.assign(n, 0);
    skid.assign(n, 0);
  }
  bool in_ready() const { return !skid[0]; }
  bool out_valid() const { return main[n - 1]; }
  // one clock edge: a beat offered at the input (in_valid), the output taken when out_ready
  void tick(bool in_valid, bool out_ready) {
    bool ready = out_ready;                       // the ready_i of register k (its consumer's)
    for (int64_t k = n - 1; k >= 0; k--) {
      const bool ready_o = !skid[k];
      const bool in_fire = (k ? main[k - 1] : in_valid) && ready_o;
      const bool out_fire = main[k] && ready;
      if (skid[k]) {
        if (out_fire) skid[k] = 0;
      } else if (in_fire) {
        if (main[k] && !ready) skid[k] = 1;
        else main[k] = 1;
      } else if (out_fire) {
        main[k] = 0;
      }
      ready = ready_o;
    }
  }
};

// What a response asks of the RT unit's response stage (rtl/rf_rtu_resp.sv): the hit children of
// a box response (pushed one per cycle), whether a triangle response hit (a division), or a
// TRANSFORM's (the ray enters an instance: the ray setup, rtl/rf_rtu_setup.sv) and whether its
// transformed ray is prepared (finite, with a non-zero direction) or skips the instance.
struct RspKind {
  bool box;
  int hits;        // box: hit children
  bool tri_hit;
  bool xf;
  bool xf_ok;
};

bool finite_word(uint32_t w) { return ((w >> 23) & 0xFF) != 0xFF; }

RspKind rsp_kind(const uint32_t* w) {
  const uint32_t op = (w[rf_layout::kRspOpcodeWord] >> rf_layout::kRspOpcodeLsb) &
                      ((1u << rf_layout::kRspOpcodeBits) - 1);
  RspKind k{op == rf_layout::kOpQuadbox, 0, false};
  for (int j = 0; j < rf_layout::kRspBoxHitCount; j++)
    k.hits += (w[rf_layout::kRspBoxHitWord] >> (rf_layout::kRspBoxHitLsb +
                                                j * rf_layout::kRspBoxHitBits)) & 1;
  k.tri_hit = op == rf_layout::kOpTriangle &&
              ((w[rf_layout::kRspTriHitWord] >> rf_layout::kRspTriHitLsb) & 1);
  k.xf = op == rf_layout::kOpTransform;
  if (k.xf) {
    bool finite = true, nonzero = false;
    for (int a = 0; a < rf_layout::kRspXfOriginCount; a++) {
      finite = finite && finite_word(w[rf_layout::kRspXfOriginWord + a]) &&
               finite_word(w[rf_layout::kRspXfDirWord + a]);
      nonzero = nonzero || (w[rf_layout::kRspXfDirWord + a] & 0x7FFFFFFFu) != 0;
    }
    k.xf_ok = finite && nonzero;
  }
  return k;
}

struct Unit {
  std::vector<std::unique_ptr<Sim>> sims;
  std::vector<std::deque<int64_t>> inflight;   // per pipeline: record indices, in request order
  std::vector<std::deque<int64_t>> due;        // timing model: the cycle each response is out
  std::vector<char> busy;
  MinQueue ready;      // rays whose next request is known, by the cycle its node is present
  MinQueue parked;     // affinity: rays without a slot, by the cycle their node arrives
  MinQueue waiting;    // trace calls issued by their warp, not yet admitted (id = call)
  std::deque<int64_t> fresh;                  // affinity: rays of admitted calls with no slot yet
  int64_t active = 0;                         // rays holding an issue slot
  int64_t held_calls = 0, held_rays = 0;      // admitted calls (and their rays) not done
  int64_t resident = 0;                       // warps resident
  // treelet scheduling: per treelet its queue (ray, cycle its next request is known), members
  // (rays in slots or parked), whether it is active; the active treelets in activation order
  std::vector<std::deque<std::pair<int64_t, int64_t>>> tq;
  std::vector<int64_t> tl_members;
  std::vector<char> tl_active;
  std::vector<int64_t> act;
  int64_t queued = 0;
  // the RT unit in RTL's costs (cfg.unit_costs): rays waiting for the pop port (by the cycle they
  // may pop) and node responses waiting for the memory port (by the cycle the node is present);
  // the next cycle the ray port and the result port are free; per pipeline its handshakes
  // (timing pipelines) and the next cycle its response stage is free; each divider's and ray
  // setup's next idle cycle (the unit's pools, shared by the pipelines' response stages through
  // one port each, granted round robin from div_next / xf_next); this cycle's grants (-1: none)
  MinQueue loadq, arrq;
  // per ray slot: its ray (-1: free), the cycle it may pop, issue, leave through the result port
  // (kNever: not waiting), the cycle it is free again; the round-robin starts
  std::vector<int64_t> slot_ray, pop_at, ready_at, done_at, free_at;
  int64_t pop_next = 0, sched_next = 0, res_next = 0;
  std::vector<Elastic> chain;
  std::vector<char> in_valid, out_ready;      // this cycle's handshakes of each pipeline
  std::vector<int64_t> resp_free;
  std::vector<int64_t> div_free, setup_free;
  int64_t div_next = 0, xf_next = 0, div_grant = -1, xf_grant = -1, pipe_next = 0;
};

struct Engine {
  // inputs
  const ReplayConfig& cfg;
  const uint32_t* ray;
  const uint32_t* ptr;
  const int64_t* chain_idx;
  const int64_t* chain_off;
  int64_t n_chains;
  const uint32_t* chain;
  const uint32_t* before;
  const int64_t* kernel_off;
  const int64_t* warp_call_off;
  const int64_t* call_ray_off;
  const int64_t* call_rays;
  const int32_t* treelet;
  int64_t n_treelets;
  const int64_t* tl_off;
  const int64_t* tl_node_off;
  const int64_t* tl_node_bytes;
  const uint32_t* responses;   // the functional run's responses (unit costs, timing pipelines)
  const uint8_t* any_hit;      // (n_chains,) or null: any-hit rays (unit costs)
  const int64_t* culls;        // (m + n_chains,) or null: culled pops (unit costs; pop())
  // outputs
  int64_t* ray_times;    // (n_chains, 3): call issued, call admitted, last response
  int64_t* ray_served;   // (n_chains, kMemoryLevels): node bytes supplied by each memory level
  int64_t* ray_wait;     // (n_chains,): cycles waited for nodes
  int64_t* call_times;   // (n_calls, 3): issued, admitted, done
  int64_t* call_unit;    // (n_calls,)
  // state
  NodeSource src;
  MemorySystem mem;
  std::vector<Unit> units;
  std::vector<int64_t> pos, call_of, warp_of, remaining, cur_tl;
  bool treelets = false, affinity = false, parking = false;
  int64_t calls_per_unit = 0, window_calls = 0, seq = 0, next_warp = 0, kernel_end = 0;
  int64_t kernel_calls_left = 0;
  int64_t node_wait = 0, level_wait[kMemoryLevels] = {};
  int64_t n_parked = 0, n_resumed = 0, max_parked = 0, max_held = 0;
  int64_t picks = 0, max_queued = 0, n_borrowed = 0;
  bool unit_costs = false;
  int64_t unit_last = -1;      // unit costs: the cycle the last result was taken
  // unit costs, per chain: entries on its stack and spilled, a refill under way, a refilled
  // entry held (popped next without the stack; 2: the return marker); instances: a return marker
  // on its stack, and the world ray's row (that of its TRANSFORM requests)
  std::vector<int64_t> depth, spilled, slot_of;
  std::vector<char> refilling, held, marker;
  std::vector<uint32_t> world_row;
  // distance-culled stack: entries culled at the chain's current request, and at which request
  std::vector<int64_t> culled_here, cull_pos;

  Engine(const ReplayConfig& c, NodeSource s) : cfg(c), src(s) {}

  int64_t index_of(int64_t r) const { return chain_idx[chain_off[r] + pos[r]]; }

  int64_t node_of(int64_t r, int64_t* off) const {     // ray r's next node: bytes, *off
    const uint32_t p = ptr[index_of(r)];
    *off = NodeSource::node_word(p) * 4;
    return static_cast<int64_t>(kNodeBytes[p & kTypeMask]);  // 0: the node the ray holds
  }

  // Ray r's next node (and, first, the instance node it reads on entering an instance) asked for
  // at cycle `at`: the cycle it is present (through the memory hierarchy; without one, at once,
  // or cfg.fixed_latency cycles later). *park (or null): whether the ray parks (its node is not in
  // its L1, the scheduler has parking on).
  int64_t fetch_node(int64_t uid, int64_t r, int64_t at, bool* park) {
    const uint32_t b = before[index_of(r)];
    int64_t* served = ray_served + r * kMemoryLevels;
    const int64_t fixed = mem.enabled() ? 0 : cfg.fixed_latency;
    Access ab{at, kLevelNone, kLevelNone};
    if (b != kNoChild)
      ab = fixed ? Access{at + fixed, kLevelNone, kLevelNone}
                 : mem.fetch(uid, NodeSource::node_word(b) * 4, kNodeBytes[b & kTypeMask], at,
                             served);
    const int64_t after = ab.ready;
    int64_t off;
    const int64_t bytes = node_of(r, &off);
    if (park) *park = parking && bytes && !mem.present(uid, off, bytes, after);
    Access an{after, kLevelNone, kLevelNone};
    if (bytes)
      an = fixed ? Access{after + fixed, kLevelNone, kLevelNone}
                 : mem.fetch(uid, off, bytes, after, served);
    const int64_t when = an.ready;
    const int level = when > after ? an.level : ab.level;
    node_wait += when - at;
    level_wait[level] += when - at;
    ray_wait[r] += when - at;
    return when;
  }

  // Ray r's next request is known at cycle `at`: its node is fetched; it becomes ready when the
  // node is present, or parks.
  void wait(Unit& u, int64_t uid, int64_t r, int64_t at) {
    bool park = false;
    const int64_t when = fetch_node(uid, r, at, &park);
    if (!park) {
      u.ready.push({r, when, seq++});
      return;
    }
    u.parked.push({r, when, seq++});
    u.active--;
    n_parked++;
    if (static_cast<int64_t>(u.parked.size()) > max_parked) max_parked = u.parked.size();
  }

  // ------------------------------------------------------------------ the RT unit's costs
  // (cfg.unit_costs; docs/rtunit_rtl.md#the-replay-against-the-unit). Each ray holds one of the
  // unit's `slots` ray slots, as in the RTL. A ray is taken through the ray port (one a cycle,
  // into the lowest free slot) and pops its root the cycle after; every pop goes through the pop
  // port (one a cycle, round robin over the slots from the one after the last popped); a pop with
  // a node to read sends the fetch request the cycle after (its register) and the node comes back
  // through the memory port (one response a cycle, the earliest first), the ray ready to issue
  // the cycle after; the scheduler issues the ready slots round robin, up to one slot per
  // pipeline whose input is ready, the pipelines in turn from the one after the last that took a
  // request (rtl/rf_rtu_sched.sv); a pop that finds the stack empty ends the ray. A
  // response is taken by its pipeline's response stage when it is free: a
  // box with h hit children holds it max(h, 1) cycles and the ray pops after them; a triangle
  // without a hit pops the cycle after; a triangle hit needs an idle divider and the divider
  // port's grant (one hit a cycle, round robin over the pipelines; else the response waits, and
  // the pipeline backs up behind it), which holds it div_cycles + 1 cycles, and the ray
  // pops div_cycles + 1 cycles later, or ends there when it is an any-hit ray with nothing more
  // to do. An ended ray's result leaves through the result port (one a cycle, round robin) the
  // cycle after, is taken the cycle after that, and its slot takes the next ray then.
  // Instances (TRANSFORM requests in the chain): a TRANSFORM response pushes the return marker (one
  // cycle of the response stage) and needs the ray setup idle and the setup port's grant (else it
  // waits, as for a divider; the lowest idle of cfg.setups takes it); the setup holds it div_cycles
  // + 1 cycles (its dividers) and the ray pops its BLAS root then, held, not from the stack; a
  // transformed ray that is not finite (or has a zero direction) skips the instance: the setup
  // holds it 2 cycles. The marker is popped (a pop of its own) before the ray's first request on
  // its world row after it, or before it ends. The distance-culled stack (in->culls): each entry
  // the traversal culled before a request (or before the ray ends) is a pop of its own, after
  // the marker's, the stack's entries first and then those read back.
  static constexpr int64_t kNever = INT64_MAX;

  // The first slot from `start` (round robin) whose time has come at cycle k, or -1.
  static int64_t rr(const std::vector<int64_t>& at, int64_t start, int64_t k) {
    const int64_t n = static_cast<int64_t>(at.size());
    for (int64_t i = start; i < n; i++)
      if (at[i] <= k) return i;
    for (int64_t i = 0; i < start; i++)
      if (at[i] <= k) return i;
    return -1;
  }

  void load(Unit& u, int64_t r, int64_t at) { u.loadq.push({r, at, seq++}); }

  void load_step(Unit& u, int64_t k) {          // the ray port
    if (u.loadq.empty() || u.loadq.top().at > k) return;
    for (size_t s = 0; s < u.slot_ray.size(); s++) {
      if (u.slot_ray[s] >= 0 || u.free_at[s] > k) continue;
      const int64_t r = u.loadq.top().id;
      u.loadq.pop();
      u.slot_ray[s] = r;
      slot_of[r] = static_cast<int64_t>(s);
      u.pop_at[s] = k + 1;
      return;
    }
  }

  void finish(Unit& u, int64_t r, int64_t done_at) { u.done_at[slot_of[r]] = done_at; }

  void result_step(Unit& u, int64_t uid, int64_t k) {   // the result port
    const int64_t s = rr(u.done_at, u.res_next, k);
    if (s < 0) return;
    u.res_next = s + 1 == static_cast<int64_t>(u.done_at.size()) ? 0 : s + 1;
    const int64_t r = u.slot_ray[s];
    u.done_at[s] = kNever;
    u.slot_ray[s] = -1;
    u.free_at[s] = k + 1;
    if (k + 1 > unit_last) unit_last = k + 1;
    u.active--;
    ray_done(u, uid, r, k + 1);
    if (!cfg.window) admit_waiting(u, uid, k + 1);
  }

  // With cfg.stack_depth S > 0 each ray's stack holds S entries: a push onto a full stack spills
  // the oldest entry to memory (at no cost: the spill port takes a write a cycle), and a pop that
  // finds the stack empty with entries spilled reads the last one back first: a request on the
  // memory port (served at the node cache's hit latency, or the fixed latency), the ray popping
  // again the cycle after the response. The order of the pops is that of an unbounded stack,
  // the recorded chain's.
  void refill(Unit& u, int64_t uid, int64_t r, int64_t k) {   // read the last spilled entry back
    spilled[r]--;
    refilling[r] = 1;
    const int64_t lat = mem.enabled() ? std::max<int64_t>(mem.l1[uid].latency, 1)
                                      : cfg.fixed_latency;
    u.arrq.push({r, k + 1 + lat, seq++});
  }

  void pop(Unit& u, int64_t uid, int64_t k) {
    const int64_t s = rr(u.pop_at, u.pop_next, k);
    if (s < 0) return;
    u.pop_next = s + 1 == static_cast<int64_t>(u.pop_at.size()) ? 0 : s + 1;
    u.pop_at[s] = kNever;
    const int64_t r = u.slot_ray[s];
    const bool more = pos[r] < chain_off[r + 1] - chain_off[r];
    int64_t off;
    const int64_t bytes = more ? node_of(r, &off) : 0;
    if (held[r] == 2) {                       // the return marker, read back from the spill area
      held[r] = 0;
      marker[r] = 0;
      u.pop_at[s] = k + 1;
      return;
    }
    if (marker[r] && !held[r] && (!more || ray[index_of(r)] == world_row[r])) {
      // the return marker: the ray goes back to its world ray and pops again
      if (cfg.stack_depth && depth[r] == 0 && spilled[r] > 0) {
        refill(u, uid, r, k);
        return;
      }
      if (depth[r] > 0) depth[r]--;
      marker[r] = 0;
      u.pop_at[s] = k + 1;
      return;
    }
    // the distance-culled stack (culls): the entries the traversal culled before this request
    // (or before the ray ends), each a pop of its own, from the stack or read back first
    if (culls) {
      if (cull_pos[r] != pos[r]) {
        cull_pos[r] = pos[r];
        culled_here[r] = 0;
      }
      if (culled_here[r] < culls[chain_off[r] + r + pos[r]]) {
        if (held[r] == 1) {
          held[r] = 0;
        } else if (cfg.stack_depth && depth[r] == 0 && spilled[r] > 0) {
          refill(u, uid, r, k);
          return;
        } else if (depth[r] > 0) {
          depth[r]--;
        }
        culled_here[r]++;
        u.pop_at[s] = k + 1;
        return;
      }
    }
    // the root, a refilled entry and a pair leaf's second triangle are not on the stack
    if (cfg.stack_depth && (!more || (pos[r] > 0 && bytes)) && !held[r]) {
      if (depth[r] > 0) {
        depth[r]--;
      } else if (spilled[r] > 0 && more) {
        refill(u, uid, r, k);
        return;
      }
    }
    held[r] = 0;
    if (!more) {
      finish(u, r, k + 1);
      return;
    }
    if (!bytes) {                             // a pair leaf's second triangle: no fetch
      u.ready_at[s] = k + 1;
      return;
    }
    const int64_t when = fetch_node(uid, r, k + 1, nullptr);
    u.arrq.push({r, std::max(when, k + 2), seq++});
  }

  void arrive(Unit& u, int64_t k) {
    if (u.arrq.empty() || u.arrq.top().at > k) return;
    const int64_t r = u.arrq.top().id;
    u.arrq.pop();
    if (refilling[r]) {                       // a spilled entry read back: the ray pops it
      refilling[r] = 0;
      const bool more = pos[r] < chain_off[r + 1] - chain_off[r];
      held[r] = marker[r] && (!more || ray[index_of(r)] == world_row[r]) ? 2 : 1;
      u.pop_at[slot_of[r]] = k + 1;
      return;
    }
    u.ready_at[slot_of[r]] = k + 1;
  }

  // the first unit of `free_at` (each one's next idle cycle) idle at cycle k, or -1
  static int64_t idle(const std::vector<int64_t>& free_at, int64_t k) {
    for (size_t j = 0; j < free_at.size(); j++)
      if (free_at[j] <= k) return static_cast<int64_t>(j);
    return -1;
  }

  // This cycle's grants of the divider port and the ray-setup port (rtl/rf_rtu_pipes.sv): among
  // the pipelines whose response stage is free with a triangle hit (a TRANSFORM) at its output
  // (w[p], null: none), the first from div_next (xf_next) round robin, when a divider (a ray
  // setup) is idle; -1: none.
  void grant(Unit& u, int64_t k, const std::vector<const uint32_t*>& w) const {
    const int64_t n = static_cast<int64_t>(w.size());
    u.div_grant = u.xf_grant = -1;
    const bool div_idle = idle(u.div_free, k) >= 0, xf_idle = idle(u.setup_free, k) >= 0;
    for (int64_t j = 0; j < n; j++) {
      const int64_t p = (u.div_next + j) % n;
      if (w[p] && k >= u.resp_free[p] && rsp_kind(w[p]).tri_hit) {
        if (div_idle) u.div_grant = p;
        break;
      }
    }
    for (int64_t j = 0; j < n; j++) {
      const int64_t p = (u.xf_next + j) % n;
      if (w[p] && k >= u.resp_free[p] && rsp_kind(w[p]).xf) {
        if (xf_idle) u.xf_grant = p;
        break;
      }
    }
  }

  bool can_take(const Unit& u, int64_t p, int64_t k, const uint32_t* w) const {
    const RspKind kind = rsp_kind(w);
    return k >= u.resp_free[p] && (!kind.tri_hit || u.div_grant == p) &&
           (!kind.xf || u.xf_grant == p);
  }

  // Pipeline p's response w to ray r's request is taken at cycle k (pos[r] already past it).
  void respond(Unit& u, int64_t uid, int64_t p, int64_t r, int64_t k, const uint32_t* w) {
    const RspKind kind = rsp_kind(w);
    int64_t next = k + 1;
    u.resp_free[p] = k + 1;
    if (kind.box) {
      next = k + std::max(kind.hits, 1);
      u.resp_free[p] = next;
      depth[r] += kind.hits;
      if (cfg.stack_depth && depth[r] > cfg.stack_depth) {
        spilled[r] += depth[r] - cfg.stack_depth;
        depth[r] = cfg.stack_depth;
      }
    } else if (kind.xf) {                     // the marker pushed; the ray setup
      depth[r] += 1;
      if (cfg.stack_depth && depth[r] > cfg.stack_depth) {
        spilled[r] += depth[r] - cfg.stack_depth;
        depth[r] = cfg.stack_depth;
      }
      marker[r] = 1;
      world_row[r] = ray[chain_idx[chain_off[r] + pos[r] - 1]];
      next = k + (kind.xf_ok ? cfg.div_cycles + 1 : 2);
      u.setup_free[idle(u.setup_free, k)] = next;
      u.xf_next = (p + 1) % static_cast<int64_t>(u.resp_free.size());
      held[r] = kind.xf_ok;                  // the BLAS root, popped next
    } else if (kind.tri_hit) {
      u.div_free[idle(u.div_free, k)] = k + cfg.div_cycles + 1;
      u.div_next = (p + 1) % static_cast<int64_t>(u.resp_free.size());
      next = k + cfg.div_cycles + 1;
      if (any_hit && any_hit[r] && pos[r] >= chain_off[r + 1] - chain_off[r]) {
        finish(u, r, next);                  // the any-hit ray ends at its accepted triangle
        return;
      }
    }
    u.pop_at[slot_of[r]] = next;
  }

  // ------------------------------------------------------------------ warps and trace calls
  void issue_call(Unit& u, int64_t c, int64_t at) {       // the warp issues call c at `at`
    call_times[c * 3] = at;
    u.waiting.push({c, at, seq++});
  }

  void make_resident(Unit& u, int64_t uid, int64_t w, int64_t at) {
    u.resident++;
    for (int64_t c = warp_call_off[w]; c < warp_call_off[w + 1]; c++) call_unit[c] = uid;
    issue_call(u, warp_call_off[w], at);
  }

  void tl_enqueue(Unit& u, int64_t r, int64_t at) {
    u.tq[treelet[index_of(r)]].push_back({r, at});
    if (++u.queued > max_queued) max_queued = u.queued;
  }

  void admit(Unit& u, int64_t uid, int64_t c, int64_t now) {
    call_times[c * 3 + 1] = now;
    u.held_calls++;
    for (int64_t j = call_ray_off[c]; j < call_ray_off[c + 1]; j++) {
      const int64_t r = call_rays[j];
      ray_times[r * 3] = call_times[c * 3];
      ray_times[r * 3 + 1] = now;
      if (++u.held_rays > max_held) max_held = u.held_rays;
      if (treelets) {
        tl_enqueue(u, r, now);
      } else if (affinity) {
        u.fresh.push_back(r);
      } else {
        u.active++;
        if (unit_costs) load(u, r, now);
        else wait(u, uid, r, now);
      }
    }
  }

  // Calls whose warp has issued them by `now` enter while the unit has room for their warp.
  void admit_waiting(Unit& u, int64_t uid, int64_t now) {
    while (u.held_calls < calls_per_unit && !u.waiting.empty() && u.waiting.top().at <= now) {
      const int64_t c = u.waiting.top().id;
      u.waiting.pop();
      admit(u, uid, c, now);
    }
  }

  void call_done(Unit& u, int64_t uid, int64_t c, int64_t k) {
    call_times[c * 3 + 2] = k;
    u.held_calls--;
    kernel_calls_left--;
    const int64_t w = warp_of[c];
    if (c + 1 < warp_call_off[w + 1]) {
      issue_call(u, c + 1, k + cfg.turnaround + cfg.shader_cycles);
      return;
    }
    u.resident--;                                     // the warp retires: the next one comes
    if (next_warp < kernel_end) make_resident(u, uid, next_warp++, k + cfg.turnaround);
  }

  void ray_done(Unit& u, int64_t uid, int64_t r, int64_t k) {
    ray_times[r * 3 + 2] = k;
    u.held_rays--;
    const int64_t c = call_of[r];
    if (--remaining[c] == 0) call_done(u, uid, c, k);
  }

  // ------------------------------------------------------------------ schedulers
  bool resume(Unit& u, int64_t uid, int64_t k) {          // a parked ray whose node arrived
    if (u.parked.empty() || u.parked.top().at > k) return false;
    const int64_t r = u.parked.top().id;
    u.parked.pop();
    n_resumed++;
    u.active++;
    int64_t off;
    const int64_t bytes = node_of(r, &off);
    if (bytes) mem.touch(uid, off, bytes);
    u.ready.push({r, k, seq++});
    return true;
  }

  // Affinity: free slots go to parked rays whose node has arrived, then to new rays.
  void fill(Unit& u, int64_t uid, int64_t k, int64_t new_at) {
    while (u.active < cfg.slots) {
      if (resume(u, uid, k)) continue;
      if (!u.fresh.empty()) {
        const int64_t r = u.fresh.front();
        u.fresh.pop_front();
        u.active++;
        wait(u, uid, r, new_at);
        continue;
      }
      if (u.held_calls >= window_calls || u.waiting.empty() || u.waiting.top().at > new_at)
        break;
      const int64_t c = u.waiting.top().id;
      u.waiting.pop();
      admit(u, uid, c, new_at);
    }
  }

  // Treelets: new rays join their queues; retired treelets leave the active set; free slots go
  // to rays queued on active treelets, activating the treelet with the most queued rays when no
  // active treelet has one.
  void fill_treelets(Unit& u, int64_t uid, int64_t k, int64_t new_at) {
    while (u.held_calls < window_calls && !u.waiting.empty() && u.waiting.top().at <= new_at) {
      const int64_t c = u.waiting.top().id;
      u.waiting.pop();
      admit(u, uid, c, new_at);
    }
    size_t j = 0;
    for (size_t a = 0; a < u.act.size(); a++) {
      const int64_t t = u.act[a];
      if (u.tq[t].empty() && u.tl_members[t] == 0) u.tl_active[t] = 0;
      else u.act[j++] = t;
    }
    u.act.resize(j);
    while (u.active < cfg.slots) {
      if (resume(u, uid, k)) continue;
      int64_t from = -1;
      for (const int64_t t : u.act)
        if (!u.tq[t].empty()) { from = t; break; }
      if (from < 0) {
        if (u.queued == 0) break;
        int64_t best = -1;
        for (int64_t t = 0; t < n_treelets; t++)
          if (!u.tl_active[t] && (best < 0 || u.tq[t].size() > u.tq[best].size())) best = t;
        if (best < 0 || u.tq[best].empty()) break;
        if (static_cast<int64_t>(u.act.size()) >= cfg.active_treelets) {
          if (!(cfg.treelet_flags & 2)) break;
          n_borrowed++;                         // a free slot serves the longest queue
        } else {
          u.tl_active[best] = 1;
          u.act.push_back(best);
          picks++;
          if (tl_off)
            for (int64_t e = tl_off[best]; e < tl_off[best + 1]; e++)
              mem.fetch(uid, tl_node_off[e], tl_node_bytes[e], k, nullptr);
        }
        from = best;
      }
      const auto [r, at] = u.tq[from].front();
      u.tq[from].pop_front();
      u.queued--;
      u.active++;
      u.tl_members[from]++;
      cur_tl[r] = from;
      wait(u, uid, r, at > k ? at : k);
    }
  }

  void start(Unit& u, int64_t uid, int64_t t) {           // a kernel's first admissions
    if (treelets) fill_treelets(u, uid, t, t);
    else if (affinity) fill(u, uid, t, t);
    else admit_waiting(u, uid, t);
  }
};

}  // namespace

#pragma GCC visibility push(default)
extern "C" {

// RT-unit replay (driver/rtunit, docs/rtunit.md).
//
// Requests and chains. The m recorded requests (ray[i], ptr[i], ext[i]) form one chain per world
// ray; chain_idx lists the record indices of chain r, in issue order, at
// chain_idx[chain_off[r] .. chain_off[r + 1]). chain[i] is the chain of request i (a ray that
// enters an instance continues its chain on another ray-table row, which ray[i] names and which
// is the response's tag); before[i] (kNoChild: none) is a node fetched before request i's own
// node: the instance node a ray reads on entering the instance.
//
// Warps and trace calls. The frame is n_kernels kernels run one after another (a barrier
// between them; cfg.flush: the caches are dropped there); kernel q's warps are
// [kernel_off[q], kernel_off[q + 1]), in launch order. Warp w's trace calls, in program order,
// are [warp_call_off[w], warp_call_off[w + 1]); call c's rays (chain indices, each non-empty and
// in exactly one call) are call_rays[call_ray_off[c] .. call_ray_off[c + 1]).
// At a kernel's start, warps become resident round robin over the units (unit 0, 1, .., N-1,
// then each unit's second warp, ..) up to cfg.resident per unit (0: every warp); a unit whose
// warp retires takes the next warp of the kernel, `turnaround` cycles later. A resident warp
// issues its first call at once and each next call `turnaround + shader_cycles` cycles after the
// previous call's last response; it retires after its last call.
// A call is admitted into its unit when the unit holds fewer than slots / warp_size calls
// (affinity and treelet scheduling: window / warp_size), earliest issued first; each of its rays
// then holds an issue slot (affinity: waits for one) and issues its chain one request at a time:
//
// Every cycle, for each unit in order: calls issued by then are admitted; each pipeline's
// response (if out_valid) is taken: its ray's next request becomes known `turnaround` cycles
// later (or the ray is done; when its call is done, the call's slots free, and waiting calls are
// admitted at once, at that cycle + turnaround). Then each pipeline, in order 0..P-1, whose input
// is ready accepts the next request of the ray that has been ready longest (rays ordered by
// ready time, then by the order in which they became waiting). Then all pipelines are clocked. A
// ray has at most one request in flight.
//
// Node memory (rf_memory.h; mc->l1_bytes < 0: off): when a ray's next request becomes known its
// node is fetched through its unit's L1, the shared L2 and DRAM; the ray is ready when the node is
// present. Returns -4 for a memory geometry it cannot model.
//
// Node-affinity scheduling (cfg.window > 0, >= slots, no treelets): a unit holds `window` rays
// (of admitted calls), of which at most `slots` hold an issue slot. A ray whose next node is not
// present in its L1 (a look at the tags, MemorySystem::present) does not wait in its slot: its
// fetch is started and the ray is parked; its slot goes to a held ray: first the parked rays whose
// node has arrived (earliest arrival first), then a ray of an admitted call (calls are admitted
// while the unit holds fewer than window / warp_size). A resumed ray takes the node its fetch
// delivered without a second cache access; its lines become the most recently used.
//
// Treelet scheduling (cfg.window > 0 and treelet != null; Aila & Karras, HPG 2010): the BVH is cut
// into n_treelets treelets; treelet[i] is the treelet of request i's node. Every held ray that
// holds no issue slot waits in the queue (FIFO) of the treelet of its next node; the rays of an
// admitted call join the queues of their first nodes' treelets. At most cfg.active_treelets
// treelets are active at once per unit. Free slots go to the parked rays whose node has arrived,
// then to the rays queued on active treelets (the earliest activated treelet first); when no
// active treelet has a queued ray and fewer than active_treelets are active, the unit picks the
// treelet with the most queued rays (ties: the lowest index) and activates it. A ray's node is
// fetched when it takes a slot. A ray in a slot keeps it while its next node is in an active
// treelet; otherwise it gives up its slot and joins that treelet's queue; a treelet with no ray
// queued, parked or in a slot is retired. treelet_flags bit 0 (park): a ray whose node misses
// parks as with node affinity and stays a member of its treelet; else it waits in its slot.
// Bit 1 (borrow): when no further treelet may be activated, a free slot takes the first ray of
// the longest queue without activating its treelet. Prefetch (tl_off != null): when a treelet is
// activated, every node of it (tl_node_off / tl_node_bytes; treelet t's nodes at [tl_off[t],
// tl_off[t + 1])) is fetched through the unit's L1 at once.
//
// skip_idle: a pipeline that holds no request at the start of a cycle and gets none is not
// evaluated in that cycle (clock gating: with nothing valid inside, a clock edge changes no state
// of the RayFlex pipeline, whose registers load only on a handshake); cycles still count.
//
// timing_latency D > 0: the pipelines are their handshake timing instead of Verilated models:
// each accepts a request every cycle and presents its response D cycles after the handshake, as
// the RTL does with out_ready_i held high (rtl/rayflex.sv; the caller measures D on the model,
// rf_latency). Nothing is evaluated and rsp is not written: the responses are the functional
// run's. Every count and time equals the evaluated replay's (tests compare the two).
//
// cfg.fixed_latency > 0 with no memory model (mc->l1_bytes < 0): every node fetch takes that
// many cycles (the RT unit in RTL's fixed-latency memory).
//
// cfg.unit_costs: the RT unit in RTL's costs (rtl/rf_rtunit.sv, docs/rtunit_rtl.md) replace the
// turnaround: the ray, pop, memory and result ports, the fetch request's register, the scheduler's
// cycle (up to P slots a cycle, one per pipeline, round robin), each pipeline as its chain of skid
// registers (Elastic) behind its response stage, which holds a box response one cycle per hit child
// and a triangle hit until one of cfg.dividers dividers (cfg.div_cycles latency, shared by the P
// stages through one port, granted round robin) is idle, cfg.stack_depth entries per stack (spills
// and refills), and any-hit rays (in->any_hit, per chain) ending at their hit (Engine: "the RT
// unit's costs"). Its response stages read the responses: the evaluated ones (D = 0) or the
// functional run's, in->responses (m, kRspWords), with D > 0. Needs no window or treelets. `cycles`
// then runs from a kernel's first ray taken to its last result taken.
//
// Outputs: rsp (m, kRspWords) at the record index (D = 0); stats (ReplayStats: `cycles` is the sum over
// kernels of first accept to last response, `frame_cycles` the frame's); per_pipe (units * P):
// requests per pipeline; sched (int64[7]): rays parked, resumed, most parked at once (one unit),
// most rays held at once (one unit), treelet picks, most rays queued at once, borrowed requests;
// ray_times (n_chains, 3), ray_served (n_chains, kMemoryLevels), ray_wait (n_chains),
// call_times (n_calls, 3),
// call_unit (n_calls) as named in Engine; series (cfg.series_capacity): rays held by all units,
// summed per bin of stats->series_bin_cycles cycles; kernel_times (n_kernels, 3): each kernel's
// first accept, last response (-1: none) and starved unit-cycles.
// Returns 0, -1 on a deadlock, -2 on a bad node pointer, -3 on bad arguments.
int64_t rf_replay(const ReplayConfig* cfg, const MemoryConfig* mc, const ReplayInputs* in,
                  ReplayStats* stats, const ReplayOutputs* out) {
  // the generated structs' fields (driver.core.layout.REPLAY_INPUTS, REPLAY_OUTPUTS) by name
  const uint32_t* rays = in->rays;
  const int64_t n_rays = in->n_rays;
  const uint32_t* image = in->image;
  const int64_t image_words = in->image_words;
  const uint32_t* ray = in->ray;
  const uint32_t* ptr = in->ptr;
  const uint32_t* ext = in->ext;
  const int64_t m = in->m;
  const int64_t* chain_idx = in->chain_idx;
  const int64_t* chain_off = in->chain_off;
  const int64_t n_chains = in->n_chains;
  const uint32_t* chain = in->chain;
  const uint32_t* before = in->before;
  const int64_t n_kernels = in->n_kernels;
  const int64_t* kernel_off = in->kernel_off;
  const int64_t* warp_call_off = in->warp_call_off;
  const int64_t* call_ray_off = in->call_ray_off;
  const int64_t* call_rays = in->call_rays;
  const int32_t* treelet = in->treelet;
  const int64_t n_treelets = in->n_treelets;
  const int64_t* tl_off = in->tl_off;
  const int64_t* tl_node_off = in->tl_node_off;
  const int64_t* tl_node_bytes = in->tl_node_bytes;
  uint32_t* rsp = out->rsp;
  int64_t* per_pipe = out->per_pipe;
  int64_t* sched = out->sched;
  int64_t* ray_times = out->ray_times;
  int64_t* ray_served = out->ray_served;
  int64_t* ray_wait = out->ray_wait;
  int64_t* call_times = out->call_times;
  int64_t* call_unit = out->call_unit;
  int64_t* series = out->series;
  int64_t* kernel_times = out->kernel_times;
  const ReplayConfig& c = *cfg;
  const int64_t P = c.pipelines, N = c.units;
  if (P < 1 || N < 1 || c.slots < 1 || c.warp_size < 1 || c.slots % c.warp_size ||
      c.turnaround < 0 || c.shader_cycles < 0 || c.resident < 0 || n_rays < 0 ||
      n_chains < 0 || m < 0 || n_kernels < 0 || c.series_capacity < 2 || c.series_capacity % 2)
    return -3;
  if (c.window < 0 || (c.window > 0 && (c.window < c.slots || c.window % c.warp_size)))
    return -3;
  if (c.timing_latency < 0 || c.fixed_latency < 0) return -3;
  // the unit's costs: no scheduler of its own, the dividers given, and the responses (the
  // functional run's when the pipelines are their timing)
  if (c.unit_costs && (c.window || treelet || c.dividers < 1 || c.setups < 1 ||
                       c.div_cycles < 1 ||
                       c.stack_depth < 0 ||
                       (c.timing_latency && !in->responses)))
    return -3;
  const int64_t D = c.timing_latency;     // > 0: the pipelines' timing, no model evaluated
  std::vector<uint32_t> scratch(kReqWords, 0);   // the timing model's request (checked, unused)
  if (D) NodeSource{rays, image, image_words, ray, ptr, ext}.begin(scratch.data());
  if (treelet && (c.window == 0 || n_treelets < 1 || c.active_treelets < 1)) return -3;
  for (int64_t i = 0; treelet && i < m; i++)
    if (treelet[i] < 0 || treelet[i] >= n_treelets) return -3;
  const int64_t n_warps = n_kernels ? kernel_off[n_kernels] : 0;
  const int64_t n_calls = n_warps ? warp_call_off[n_warps] : 0;
  Engine e(c, NodeSource{rays, image, image_words, ray, ptr, ext});
  e.ray = ray;
  e.ptr = ptr;
  e.chain_idx = chain_idx;
  e.chain_off = chain_off;
  e.n_chains = n_chains;
  e.chain = chain;
  e.before = before;
  e.kernel_off = kernel_off;
  e.warp_call_off = warp_call_off;
  e.call_ray_off = call_ray_off;
  e.call_rays = call_rays;
  e.treelet = treelet;
  e.n_treelets = n_treelets;
  e.tl_off = tl_off;
  e.tl_node_off = tl_node_off;
  e.tl_node_bytes = tl_node_bytes;
  e.responses = in->responses;
  e.any_hit = in->any_hit;
  e.culls = c.unit_costs ? in->culls : nullptr;
  e.unit_costs = c.unit_costs != 0;
  e.ray_times = ray_times;
  e.ray_served = ray_served;
  e.ray_wait = ray_wait;
  e.call_times = call_times;
  e.call_unit = call_unit;
  e.treelets = treelet != nullptr;
  e.affinity = c.window > 0 && !e.treelets;
  e.parking = e.affinity || (e.treelets && (c.treelet_flags & 1));
  e.calls_per_unit = c.slots / c.warp_size;
  e.window_calls = c.window / c.warp_size;
  if (!e.mem.configure(*mc, N)) return -4;

  // every request belongs to a chain of exactly one call
  e.call_of.assign(n_chains, -1);
  e.remaining.assign(n_calls, 0);
  e.warp_of.assign(n_calls, 0);
  int64_t called = 0;
  for (int64_t q = 0; q < n_kernels; q++)
    if (kernel_off[q + 1] < kernel_off[q]) return -3;
  for (int64_t w = 0; w < n_warps; w++) {
    if (warp_call_off[w + 1] <= warp_call_off[w]) return -3;
    for (int64_t k = warp_call_off[w]; k < warp_call_off[w + 1]; k++) {
      e.warp_of[k] = w;
      if (call_ray_off[k + 1] <= call_ray_off[k]) return -3;
      for (int64_t j = call_ray_off[k]; j < call_ray_off[k + 1]; j++) {
        const int64_t r = call_rays[j];
        if (r < 0 || r >= n_chains || e.call_of[r] >= 0 || chain_off[r + 1] == chain_off[r])
          return -3;
        e.call_of[r] = k;
        e.remaining[k]++;
        called += chain_off[r + 1] - chain_off[r];
      }
    }
  }
  if (called != m || (n_calls && call_ray_off[n_calls] > n_chains)) return -3;
  for (int64_t i = 0; i < m; i++)
    if (chain[i] >= static_cast<uint32_t>(n_chains)) return -3;
  for (int64_t r = 0; r < n_chains; r++)
    for (int64_t j = 0; j < 3; j++) ray_times[r * 3 + j] = -1;
  for (int64_t k = 0; k < n_calls; k++) {
    for (int64_t j = 0; j < 3; j++) call_times[k * 3 + j] = -1;
    call_unit[k] = -1;
  }
  std::memset(ray_served, 0, sizeof(int64_t) * kMemoryLevels * n_chains);
  std::memset(ray_wait, 0, sizeof(int64_t) * n_chains);
  std::memset(series, 0, sizeof(int64_t) * c.series_capacity);
  for (int64_t q = 0; q < n_kernels; q++) {
    kernel_times[q * 3] = kernel_times[q * 3 + 1] = -1;
    kernel_times[q * 3 + 2] = 0;
  }
  e.pos.assign(n_chains, 0);
  if (e.unit_costs) {
    e.depth.assign(n_chains, 0);
    e.spilled.assign(n_chains, 0);
    e.refilling.assign(n_chains, 0);
    e.held.assign(n_chains, 0);
    e.marker.assign(n_chains, 0);
    e.world_row.assign(n_chains, 0);
    e.slot_of.assign(n_chains, -1);
    e.culled_here.assign(n_chains, 0);
    e.cull_pos.assign(n_chains, -1);
  }
  if (e.treelets) e.cur_tl.assign(n_chains, -1);

  e.units = std::vector<Unit>(N);      // built in place: a Unit is not copyable
  for (int64_t uid = 0; uid < N; uid++) {
    Unit& u = e.units[uid];
    for (int64_t p = 0; p < P && !D; p++) {
      u.sims.emplace_back(new_sim());
      e.src.begin(u.sims.back()->top.req_i.data());
    }
    u.inflight.resize(P);
    u.due.resize(P);
    u.busy.assign(P, 0);
    if (e.unit_costs) {
      u.chain.resize(D ? P : 0);
      for (auto& ch : u.chain) ch.configure(D);
      u.resp_free.assign(P, 0);
      u.setup_free.assign(c.setups, 0);
      u.in_valid.assign(P, 0);
      u.slot_ray.assign(c.slots, -1);
      for (auto* v : {&u.pop_at, &u.ready_at, &u.done_at}) v->assign(c.slots, Engine::kNever);
      u.free_at.assign(c.slots, 0);
      u.out_ready.assign(P, 0);
      u.div_free.assign(c.dividers, 0);
    }
    if (e.treelets) {
      u.tq.resize(n_treelets);
      u.tl_members.assign(n_treelets, 0);
      u.tl_active.assign(n_treelets, 0);
    }
  }
  for (int64_t i = 0; i < N * P; i++) per_pipe[i] = 0;

  std::vector<const uint32_t*> outs(P, nullptr);   // unit costs: each pipeline's response out
  int64_t taken = 0, k = 0, first = -1, last = -1, idle = 0, evals = 0, starved = 0;
  int64_t full_cycles = 0, bad_tags = 0, accepts = 0, span_cycles = 0;
  int64_t kfirst = -1, klast = -1, kernel = -1, bin_cycles = 1, bin = 0, in_bin = 0;
  const int64_t cap = c.series_capacity;
  auto start_kernel = [&](int64_t q, int64_t t) {
    e.next_warp = kernel_off[q];
    e.kernel_end = kernel_off[q + 1];
    e.kernel_calls_left = (e.kernel_end > e.next_warp)
                              ? warp_call_off[e.kernel_end] - warp_call_off[e.next_warp] : 0;
    const int64_t per_unit = c.resident ? c.resident : (e.kernel_end - e.next_warp + N - 1) / N;
    for (int64_t s = 0; s < per_unit; s++)
      for (int64_t uid = 0; uid < N && e.next_warp < e.kernel_end; uid++)
        e.make_resident(e.units[uid], uid, e.next_warp++, t);
    for (int64_t uid = 0; uid < N; uid++) e.start(e.units[uid], uid, t);
  };
  while (true) {
    bool progress = false;
    if (kernel < 0 || e.kernel_calls_left == 0) {        // a kernel boundary
      if (e.unit_costs && kernel >= 0 && kfirst >= 0) last = klast = e.unit_last;
      if (kernel >= 0 && kfirst >= 0) {
        span_cycles += klast - kfirst + 1;
        kernel_times[kernel * 3] = kfirst;
        kernel_times[kernel * 3 + 1] = klast;
      }
      kfirst = klast = -1;
      do {                                                // (kernels without calls: none)
        if (++kernel >= n_kernels) break;
        if (kernel > 0 && c.flush) e.mem.flush();
        start_kernel(kernel, k);
        if (e.unit_costs) {                   // the unit's cycles start with its first ray
          kfirst = k;
          if (first < 0) first = k;
        }
      } while (e.kernel_calls_left == 0);
      if (kernel >= n_kernels) break;
      progress = true;
    }
    int64_t held_now = 0;
    for (int64_t uid = 0; uid < N; uid++) {
      Unit& u = e.units[uid];
      if (!c.window) e.admit_waiting(u, uid, k);
      if (e.unit_costs) {                  // the responses at the outputs: the ports' grants
        for (int64_t p = 0; p < P; p++) {
          outs[p] = nullptr;
          if (u.inflight[p].empty()) continue;
          if (D && u.chain[p].out_valid())
            outs[p] = e.responses + u.inflight[p].front() * kRspWords;
          else if (!D && u.sims[p]->top.out_valid_o)
            outs[p] = u.sims[p]->top.rsp_o.data();
        }
        e.grant(u, k, outs);
      }
      for (int64_t p = 0; p < P; p++) {
        u.busy[p] = !u.inflight[p].empty();
        const uint32_t* w = nullptr;               // the response at the output (unit costs)
        if (e.unit_costs) {
          bool out = false;
          if (D) {
            out = u.busy[p] && u.chain[p].out_valid();
            if (out) w = e.responses + u.inflight[p].front() * kRspWords;
          } else {
            Vrayflex& t = u.sims[p]->top;
            out = u.busy[p] && t.out_valid_o;
            if (out) w = t.rsp_o.data();
          }
          const bool take = out && e.can_take(u, p, k, w);
          if (!D) u.sims[p]->top.out_ready_i = take;
          u.out_ready[p] = take;
          if (!take) continue;
        } else if (D) {
          if (!(u.busy[p] && u.due[p].front() <= k)) continue;
          u.due[p].pop_front();
        } else {
          Vrayflex& t = u.sims[p]->top;
          t.out_ready_i = 1;
          if (!(u.busy[p] && t.out_valid_o)) continue;
        }
        const int64_t i = u.inflight[p].front();
        u.inflight[p].pop_front();
        if (!D) {
          std::memcpy(rsp + i * kRspWords, u.sims[p]->top.rsp_o.data(), kRspWords * 4);
          if (rsp[i * kRspWords] != ray[i]) bad_tags++;
        }
        taken++;
        if (!e.unit_costs) last = klast = k;
        progress = true;
        const int64_t r = chain[i];
        const bool more = ++e.pos[r] < chain_off[r + 1] - chain_off[r];
        if (e.unit_costs) {
          e.respond(u, uid, p, r, k, w);
        } else if (e.treelets) {
          u.tl_members[e.cur_tl[r]]--;
          const int64_t nt = more ? treelet[e.index_of(r)] : -1;
          if (more && u.tl_active[nt]) {              // stays in its slot
            e.cur_tl[r] = nt;
            u.tl_members[nt]++;
            e.wait(u, uid, r, k + c.turnaround);
          } else {
            u.active--;
            if (more) e.tl_enqueue(u, r, k + c.turnaround);
            else e.ray_done(u, uid, r, k);
          }
        } else if (more) {
          e.wait(u, uid, r, k + c.turnaround);
        } else {
          u.active--;
          e.ray_done(u, uid, r, k);
          if (!c.window) e.admit_waiting(u, uid, k + c.turnaround);
        }
      }
      if (e.treelets) e.fill_treelets(u, uid, k, k + c.turnaround);
      else if (e.affinity) e.fill(u, uid, k, k + c.turnaround);
      if (e.unit_costs) {
        e.result_step(u, uid, k);
        e.load_step(u, k);
        e.pop(u, uid, k);
        e.arrive(u, k);
      }
      int64_t issued = 0;
      bool none_ready = false;
      // the unit's costs: the pipelines in turn from the one after the last that took a request
      const int64_t p0 = e.unit_costs ? u.pipe_next : 0;
      for (int64_t j = 0; j < P; j++) {
        const int64_t p = (p0 + j) % P;
        Vrayflex* t = D ? nullptr : &u.sims[p]->top;
        if (t) t->in_valid_i = 0;
        if (D && e.unit_costs) u.in_valid[p] = 0;
        int64_t r = -1;
        if (e.unit_costs) {                   // the unit's scheduler: round robin over slots
          const int64_t s = Engine::rr(u.ready_at, u.sched_next, k);
          if (s < 0) none_ready = true;
          if (s < 0 || (t && !t->in_ready_o) || (D && !u.chain[p].in_ready())) continue;
          u.sched_next = s + 1 == c.slots ? 0 : s + 1;
          u.pipe_next = (p + 1) % P;
          u.ready_at[s] = Engine::kNever;
          r = u.slot_ray[s];
        } else {
          if (u.ready.empty() || u.ready.top().at > k || (t && !t->in_ready_o)) continue;
          r = u.ready.top().id;
          u.ready.pop();
        }
        const int64_t i = e.index_of(r);
        if (!e.src.fill(i, t ? t->req_i.data() : scratch.data())) return -2;
        if (t && !u.ready.empty()) {                // the next ray to issue, if it is known
          const int64_t nx = u.ready.top().id;
          if (e.pos[nx] < chain_off[nx + 1] - chain_off[nx]) e.src.prefetch(e.index_of(nx));
        }
        if (t) t->in_valid_i = 1;
        else if (e.unit_costs) u.in_valid[p] = 1;
        else u.due[p].push_back(k + D);
        u.inflight[p].push_back(i);
        per_pipe[uid * P + p]++;
        issued++;
        if (first < 0) first = k;
        if (kfirst < 0) kfirst = k;
        progress = true;
      }
      accepts += issued;
      if (issued == P) full_cycles++;
      if (issued < P && (e.unit_costs ? none_ready : u.ready.empty() || u.ready.top().at > k)) {
        starved++;
        kernel_times[kernel * 3 + 2]++;
      }
      for (int64_t p = 0; p < P && !D; p++) {
        if (c.skip_idle && !u.busy[p] && !u.sims[p]->top.in_valid_i) continue;
        tick(u.sims[p].get());
        evals++;
      }
      for (int64_t p = 0; p < P && D && e.unit_costs; p++)
        if (u.busy[p] || u.in_valid[p]) u.chain[p].tick(u.in_valid[p], u.out_ready[p]);
      if (e.unit_costs) {
        if (u.active || !u.loadq.empty() || !u.arrq.empty()) progress = true;
        for (int64_t p = 0; p < P; p++)
          if (!u.inflight[p].empty() || u.resp_free[p] > k) progress = true;
      }
      if (!u.ready.empty() && u.ready.top().at > k) progress = true;   // waiting on a fetch
      if (!u.parked.empty() && u.parked.top().at > k) progress = true;
      if (u.queued && u.active) progress = true;     // queued rays wait for their treelet
      if (!u.waiting.empty() && u.waiting.top().at > k) progress = true;  // warps shading
      held_now += u.held_rays;
    }
    series[bin] += held_now;                          // the rays-in-flight series
    if (++in_bin == bin_cycles) {
      in_bin = 0;
      if (++bin == cap) {                             // full: halve its resolution
        for (int64_t b = 0; b < cap / 2; b++) series[b] = series[2 * b] + series[2 * b + 1];
        std::memset(series + cap / 2, 0, sizeof(int64_t) * (cap / 2));
        bin = cap / 2;
        bin_cycles *= 2;
      }
    }
    idle = progress ? 0 : idle + 1;
    if (idle > c.max_idle + c.turnaround + c.shader_cycles) return -1;
    k++;
  }
  if (taken != m) return -1;
  stats->cycles = span_cycles;
  stats->model_evals = evals;
  stats->starved_cycles = starved;
  stats->full_cycles = full_cycles;
  stats->first_accept = first;
  stats->last_response = last;
  stats->bad_tags = bad_tags;
  stats->accepts = accepts;
  const Cache* l1 = e.mem.l1.empty() ? nullptr : e.mem.l1.data();
  LevelCounts a1;
  for (int64_t uid = 0; l1 && uid < N; uid++) {
    a1.accesses += l1[uid].n.accesses;
    a1.hits += l1[uid].n.hits;
    a1.merged += l1[uid].n.merged;
    a1.misses += l1[uid].n.misses;
    a1.bytes += l1[uid].n.bytes;
  }
  stats->line_accesses = a1.accesses;
  stats->line_hits = a1.hits + a1.merged;
  stats->line_misses = a1.misses;
  stats->bytes_from_memory = e.mem.dram.bytes;
  stats->node_wait_cycles = e.node_wait;
  stats->l1_accesses = a1.accesses;
  stats->l1_hits = a1.hits;
  stats->l1_merged = a1.merged;
  stats->l1_misses = a1.misses;
  stats->l1_bytes = a1.bytes;
  const LevelCounts& a2 = e.mem.l2.n;
  stats->l2_accesses = a2.accesses;
  stats->l2_hits = a2.hits;
  stats->l2_merged = a2.merged;
  stats->l2_misses = a2.misses;
  stats->l2_bytes = a2.bytes;
  stats->dram_transfers = e.mem.dram.accesses;
  stats->dram_bytes = e.mem.dram.bytes;
  stats->l1_wait_cycles = e.level_wait[kLevelL1];
  stats->l2_wait_cycles = e.level_wait[kLevelL2];
  stats->dram_wait_cycles = e.level_wait[kLevelDram];
  stats->mshr_stalls = e.mem.mshr_stalls;
  stats->mshr_stall_cycles = e.mem.mshr_stall_cycles;
  stats->frame_cycles = m ? last - first + 1 : 0;
  stats->max_rays_held = e.max_held;
  stats->series_bins = bin + (in_bin ? 1 : 0);
  stats->series_bin_cycles = bin_cycles;
  sched[0] = e.n_parked;
  sched[1] = e.n_resumed;
  sched[2] = e.max_parked;
  sched[3] = e.max_held;
  sched[4] = e.picks;
  sched[5] = e.max_queued;
  sched[6] = e.n_borrowed;
  return 0;
}

// The memory hierarchy alone, for tests: n transactions-worth of node fetches (unit, byte
// offset, bytes, cycle) in order; writes the cycle each node is present and the level it waited
// on, and returns 0 (-4 for a geometry it cannot model). counts (int64[14]): L1 accesses, hits,
// merged, misses, bytes (all units); L2 the same; DRAM transfers, bytes; MSHR stalls, stall
// cycles. flush_at >= 0: the caches are dropped before fetch number flush_at.
int64_t rf_memory_trace(const MemoryConfig* mc, int64_t units, int64_t n, const int64_t* unit,
                        const int64_t* offset, const int64_t* bytes, const int64_t* now,
                        int64_t flush_at, int64_t* ready, int64_t* level, int64_t* counts) {
  MemorySystem mem;
  if (!mem.configure(*mc, units)) return -4;
  for (int64_t i = 0; i < n; i++) {
    if (unit[i] < 0 || unit[i] >= units) return -3;
    if (i == flush_at) mem.flush();
    const Access a = mem.fetch(unit[i], offset[i], bytes[i], now[i], nullptr);
    ready[i] = a.ready;
    level[i] = a.level;
  }
  LevelCounts a1;
  for (const Cache& cache : mem.l1) {
    a1.accesses += cache.n.accesses;
    a1.hits += cache.n.hits;
    a1.merged += cache.n.merged;
    a1.misses += cache.n.misses;
    a1.bytes += cache.n.bytes;
  }
  const LevelCounts& a2 = mem.l2.n;
  const int64_t out[14] = {a1.accesses, a1.hits, a1.merged, a1.misses, a1.bytes,
                           a2.accesses, a2.hits, a2.merged, a2.misses, a2.bytes,
                           mem.dram.accesses, mem.dram.bytes, mem.mshr_stalls,
                           mem.mshr_stall_cycles};
  std::memcpy(counts, out, sizeof out);
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop
