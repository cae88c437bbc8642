// The RT unit in RTL (rtl/rf_rtunit.sv) driven by C++: a frame's prepared rays stream into its ray
// port, its memory port is served from the BVH image, its results are collected. No host work per
// traversal step: the unit pops, fetches, issues, pushes and divides by itself.
//
// Memory behind the port: with MemoryConfig.l1_bytes < 0 a fixed latency (`mem_latency` cycles
// from the request's handshake to its response; any number outstanding, at most `max_outstanding`,
// 0: no limit); otherwise the replay's hierarchy (rf_memory.h: L1, L2, DRAM, MSHRs; one unit), which
// gives each request the cycle its node's bytes are present. One response per cycle, earliest
// first (ties: request order).
//
// Stack spills: the unit writes a stack overflow's oldest entry on its spill port (one write per
// cycle and pipeline, always taken) and reads it back with a refill request on the memory port;
// here each ray slot's spill area is a LIFO of (pointer, entry distance) pairs (the distance is 0
// unless the unit is built with CULL, the distance-culled stack; a refill's response carries the
// pointer in data word 0 and the distance in word 1), and a refill is served after `mem_latency` cycles
// (fixed latency) or the node cache's hit latency (with the hierarchy: a ray's spill area stays in
// its L1).
//
// Cycles: cycle 0 is the first cycle a ray is offered (the unit takes one at once); `cycles` is
// the cycle after the last result is taken. While every ray waits for memory (the unit's wait_o)
// and no response or new ray is due, the unit's outputs cannot change: those cycles are counted
// (skipped_cycles; not in the RF_TOGGLES build) without clocking the model. Every run has a cycle budget: a corrupt image (a loop
// of pointers) stops with an error instead of hanging. Statistics: RtuStats (rf_rtunit_stats.h,
// generated from driver/backends/rtunit.py's UNIT_STATS).
//
// Switching activity (the power flow's level "signals", docs/power.md): built with RF_TOGGLES
// (Verilator --trace, driver/backends/rtunit.py's traced build, made only for rayflex power),
// rtu_toggles_start has every clock cycle's values streamed into the VCD toggle counter of
// sim/rf_toggles.h (no file is written) until rtu_toggles_write saves the counts.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <queue>
#include <string>
#include <utility>
#include <vector>

#include "Vrf_rtunit.h"
#include "rf_layout.h"
#include "rf_memory.h"
#include "rf_rtunit_stats.h"
#include "verilated.h"
#ifdef RF_TOGGLES
#include "verilated_vcd_c.h"
#include "rf_toggles.h"
#endif

namespace {

using rf_layout::kRayWords;

// The unit's pipelines (its PIPELINES parameter), read from the model: spill_ptr_o holds 32 bits
// per pipeline (IData, QData or VlWide<N>: 4 bytes each).
constexpr int kPipelines = static_cast<int>(sizeof(Vrf_rtunit::spill_ptr_o) / 4);
static_assert(kPipelines >= 1 && kPipelines <= rf_rtunit_stats::kMaxPipelines,
              "rf_rtunit: PIPELINES out of range");

// Bits [lsb, lsb + width) of a Verilated port (width <= 32, not crossing a 32-bit word).
template <typename T>
uint32_t port_bits(const T& v, int lsb, int width) {
  const uint64_t x = static_cast<uint64_t>(v) >> lsb;
  return static_cast<uint32_t>(width == 32 ? x : x & ((uint64_t{1} << width) - 1));
}
template <std::size_t N>
uint32_t port_bits(const VlWide<N>& v, int lsb, int width) {
  const uint32_t x = v[lsb / 32] >> (lsb % 32);
  return width == 32 ? x : x & ((1u << width) - 1);
}

#ifdef RF_TOGGLES
constexpr bool kCountsToggles = true;
#else
constexpr bool kCountsToggles = false;
#endif
constexpr int64_t kOps = rf_rtunit_stats::kUnitOps;   // per-ray counters in `ops`
constexpr int64_t kOk = 0, kBudget = -1, kBadAddress = -2, kBadArgs = -3, kBadGeometry = -4,
                  kRayError = -5;

struct Pending {
  int64_t ready, seq, addr, size;
  uint32_t tag;
  bool refill;
  uint32_t value, dist;                // a refill's pointer and its entry distance
  bool operator>(const Pending& o) const {
    return ready != o.ready ? ready > o.ready : seq > o.seq;
  }
};

// A context that allows tracing before the model (built from it) is constructed.
struct Context : VerilatedContext {
#ifdef RF_TOGGLES
  Context() { traceEverOn(true); }
#endif
};

struct Run {
  Context ctx;
  Vrf_rtunit top{&ctx};
  const uint32_t* rays = nullptr;      // (n, kRayWords)
  const uint8_t* any_hit = nullptr;    // (n,)
  int64_t n = 0;
  const uint32_t* image = nullptr;
  int64_t image_bytes = 0;
  int64_t mem_latency = 0, max_outstanding = 0;
  rf::MemorySystem mem;
  int64_t l1_latency = 0, dividers = 0;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> spill;   // per slot: a LIFO
  // results, per ray id
  uint32_t* prim = nullptr;
  uint32_t* inst = nullptr;            // the hit's instance (0xFFFFFFFF: none)
  uint32_t* t = nullptr;
  uint8_t* hit = nullptr;
  int64_t* ops = nullptr;              // (n, kOps): box, triangle, overflows, refills,
                                       // transform, culled
  std::priority_queue<Pending, std::vector<Pending>, std::greater<Pending>> queue;
  int64_t next_ray = 0, done = 0, cycle = 0, seq = 0, outstanding = 0;
  rf_rtunit_stats::RtuStats st{};
#ifdef RF_TOGGLES
  rf_toggles::Counter counter;
  rf_toggles::CountingFile* file = nullptr;
  VerilatedVcdC* vcd = nullptr;
  uint64_t time = 0;
  ~Run() {
    if (vcd) vcd->close();
    delete vcd;
    delete file;
  }
#endif
};

void tick(Run* r) {
  r->top.clk_i = 1;
  r->top.eval();
  r->top.clk_i = 0;
  r->top.eval();
#ifdef RF_TOGGLES
  if (r->vcd) r->vcd->dump(++r->time);  // one sample per cycle: zero-delay, no glitches
#endif
}

}  // namespace

#pragma GCC visibility push(default)
extern "C" {

// A unit for one frame: n rays (ray words (n, kRayWords), any_hit (n,) 0/1) through the BVH image
// (image_bytes bytes, root pointer `root`); results go to prim, inst, t, hit (n,) and ops
// (n, kOps). The
// arrays must outlive the handle. Returns null for inconsistent arguments or a memory geometry
// the hierarchy cannot model (*err: kBadArgs or kBadGeometry).
void* rtu_new(const uint32_t* rays, const uint8_t* any_hit, int64_t n, const uint32_t* image,
              int64_t image_bytes, uint32_t root, int64_t mem_latency, int64_t max_outstanding,
              int64_t dividers,
              const rf_layout::MemoryConfig* mc, uint32_t* prim, uint32_t* inst, uint32_t* t,
              uint8_t* hit,
              int64_t* ops, int64_t* err) {
  if (n < 0 || image_bytes < 0 || mem_latency < 1 || max_outstanding < 0) {
    *err = kBadArgs;
    return nullptr;
  }
  Run* r = new Run;
  if (!r->mem.configure(*mc, 1)) {
    delete r;
    *err = kBadGeometry;
    return nullptr;
  }
  r->rays = rays;
  r->any_hit = any_hit;
  r->n = n;
  r->image = image;
  r->image_bytes = image_bytes;
  r->mem_latency = mem_latency;
  r->max_outstanding = max_outstanding;
  r->l1_latency = mc->l1_latency;
  r->dividers = dividers;
  r->spill.resize(256);   // RAYS <= 256 (rf_rtunit)
  r->prim = prim;
  r->inst = inst;
  r->t = t;
  r->hit = hit;
  r->ops = ops;
  Vrf_rtunit& u = r->top;
  u.clk_i = 0;
  u.rst_ni = 0;
  u.root_i = root;
  u.ray_valid_i = 0;
  u.mem_req_ready_i = 0;
  u.mem_rsp_valid_i = 0;
  u.res_ready_i = 0;
  u.eval();
  for (int i = 0; i < 2; i++) tick(r);
  u.rst_ni = 1;
  u.eval();
  *err = kOk;
  return r;
}

void rtu_free(void* h) { delete static_cast<Run*>(h); }

// Run the unit for at most `cycles` more cycles. Returns 1 when every ray's result is in, 0 when
// the cycles ran out first, kBadAddress for a fetch outside the image, kRayError for a ray that met
// a pointer the unit cannot read (its result is written; *bad_ray is its id).
int64_t rtu_advance(void* h, int64_t cycles, int64_t* bad_ray) {
  Run* r = static_cast<Run*>(h);
  Vrf_rtunit& u = r->top;
  for (int64_t k = 0; k < cycles; k++) {
    if (r->done == r->n) return 1;
    // Every ray waits for memory (wait_o) and no response or new ray can come before the
    // earliest response is due: clocking the unit until then changes nothing it will show, so
    // those cycles are counted without being simulated (the statistics as if they had been).
    // The build that counts switching activity clocks every cycle (idle registers toggle too).
    if (!kCountsToggles && u.wait_o && !u.div_busy_o && !u.setup_busy_o && !r->queue.empty() &&
        r->queue.top().ready > r->cycle + 1 && !(r->next_ray < r->n && u.ray_ready_o)) {
      const int64_t skip = std::min(r->queue.top().ready - r->cycle - 1, cycles - k - 1);
      if (skip > 0) {
        r->st.mem_outstanding_cycles += skip * (r->outstanding > 0);
        r->st.busy_cycles += skip * u.busy_o;
        r->st.skipped_cycles += skip;
        r->cycle += skip;
        k += skip;
      }
    }
    // ---- inputs of this cycle ----
    u.ray_valid_i = r->next_ray < r->n;
    if (u.ray_valid_i) {
      const uint32_t* w = r->rays + r->next_ray * kRayWords;
      for (int j = 1; j < kRayWords; j++) u.ray_i[j - 1] = w[j];
      u.ray_id_i = static_cast<uint32_t>(r->next_ray);
      u.ray_any_hit_i = r->any_hit[r->next_ray] ? 1 : 0;
    }
    u.mem_req_ready_i = r->max_outstanding == 0 || r->outstanding < r->max_outstanding;
    u.mem_rsp_valid_i = 0;
    if (!r->queue.empty() && r->queue.top().ready <= r->cycle) {
      const Pending p = r->queue.top();
      r->queue.pop();
      u.mem_rsp_valid_i = 1;
      u.mem_rsp_tag_i = p.tag;
      std::memset(u.mem_rsp_data_i.data(), 0, sizeof(uint32_t) * u.mem_rsp_data_i.Words);
      if (p.refill) {
        u.mem_rsp_data_i[0] = p.value;
        u.mem_rsp_data_i[1] = p.dist;
      } else {
        std::memcpy(u.mem_rsp_data_i.data(), reinterpret_cast<const uint8_t*>(r->image) + p.addr,
                    p.size);
      }
      r->outstanding--;
    }
    u.res_ready_i = 1;
    // ---- handshakes (every output sampled here is a register output or derived from them) ----
    if (u.ray_valid_i && u.ray_ready_o) r->next_ray++;
    if (u.mem_req_valid_o && u.mem_req_ready_i) {
      const int64_t addr = static_cast<int64_t>(u.mem_req_addr_o), size = u.mem_req_size_o;
      const uint32_t tag = u.mem_req_tag_o;
      if (u.mem_req_refill_o) {
        auto& area = r->spill[tag];
        if (area.empty()) return kBadArgs;      // a refill of nothing: the unit is wrong
        const int64_t lat = r->mem.enabled() ? std::max<int64_t>(r->l1_latency, 1)
                                             : r->mem_latency;
        r->queue.push({r->cycle + lat, r->seq++, 0, size, tag, true, area.back().first,
                       area.back().second});
        area.pop_back();
        r->st.refill_reads++;
      } else {
        if (addr + size > r->image_bytes ||
            size > 4 * static_cast<int64_t>(u.mem_rsp_data_i.Words))
          return kBadAddress;
        int64_t ready = r->cycle + r->mem_latency;
        if (r->mem.enabled())
          ready = std::max(r->mem.fetch(0, addr, size, r->cycle, nullptr).ready, r->cycle + 1);
        r->queue.push({ready, r->seq++, addr, size, tag, false, 0, 0});
        r->st.mem_requests++;
        r->st.mem_bytes += size;
      }
      r->outstanding++;
    }
    for (int p = 0; p < kPipelines; p++) {
      if (port_bits(u.spill_valid_o, p, 1))
        r->spill[port_bits(u.spill_slot_o, 8 * p, 8)].emplace_back(
            port_bits(u.spill_ptr_o, 32 * p, 32), port_bits(u.spill_dist_o, 32 * p, 32));
      const uint32_t issued = port_bits(u.dp_issue_o, p, 1);
      r->st.dp_requests += issued;
      r->st.pipeline_requests[p] += issued;
      r->st.overflows += port_bits(u.overflow_o, p, 1);
    }
    r->st.mem_outstanding_cycles += r->outstanding > 0;
    r->st.busy_cycles += u.busy_o;
    r->st.divider_busy_cycles += u.div_busy_o;
    r->st.divider_full_cycles += u.div_busy_o == r->dividers;
    r->st.setup_busy_cycles += u.setup_busy_o;
    if (u.res_valid_o && u.res_ready_i) {
      const uint32_t id = u.res_id_o;
      if (id >= r->n) return kBadArgs;
      r->prim[id] = u.res_prim_o;
      r->inst[id] = u.res_inst_o;
      r->t[id] = u.res_t_o;
      r->hit[id] = u.res_hit_o;
      int64_t* o = r->ops + kOps * static_cast<int64_t>(id);
      o[0] = u.res_box_ops_o;
      o[1] = u.res_tri_ops_o;
      o[2] = u.res_overflows_o;
      o[3] = u.res_refills_o;
      o[4] = u.res_xf_ops_o;
      o[5] = u.res_culled_o;
      r->done++;
      r->st.cycles = r->cycle + 1;
      if (u.res_err_o) {
        *bad_ray = id;
        return kRayError;
      }
    }
    tick(r);
    r->cycle++;
  }
  r->st.max_stack_depth = u.max_depth_o;
  return r->done == r->n ? 1 : 0;
}

// Clock the unit `cycles` cycles with no ray offered, no memory response and results taken
// (an idle unit, or one draining).
void rtu_idle(void* h, int64_t cycles) {
  Run* r = static_cast<Run*>(h);
  Vrf_rtunit& u = r->top;
  u.ray_valid_i = 0;
  u.mem_req_ready_i = 0;
  u.mem_rsp_valid_i = 0;
  u.res_ready_i = 1;
  for (int64_t k = 0; k < cycles; k++) tick(r);
}

// Whether this build counts switching activity (RF_TOGGLES).
int64_t rtu_can_count() {
#ifdef RF_TOGGLES
  return 1;
#else
  return 0;
#endif
}

// Start counting bit toggles from the current state (sim/rf_toggles.h). Returns 0, or -1 in a
// build without RF_TOGGLES.
int64_t rtu_toggles_start(void* h) {
#ifdef RF_TOGGLES
  Run* r = static_cast<Run*>(h);
  if (!r->vcd) {
    r->file = new rf_toggles::CountingFile(&r->counter);
    r->vcd = new VerilatedVcdC(r->file);
    r->top.trace(r->vcd, 99);
    r->vcd->open("counted");
  } else {
    r->counter.reset_counts();
  }
  r->vcd->dump(r->time);
  return 0;
#else
  (void)h;
  return -1;
#endif
}

// Stop counting; write the declarations (the VCD header) to `decl` and "identifier toggles"
// lines to `counts`. Returns the number of identifiers, or -1 (a file, or no RF_TOGGLES).
int64_t rtu_toggles_write(void* h, const char* decl, const char* counts) {
#ifdef RF_TOGGLES
  Run* r = static_cast<Run*>(h);
  if (!r->vcd) return -1;
  r->vcd->flush();
  r->counter.finish();
  FILE* d = std::fopen(decl, "w");
  if (!d) return -1;
  const std::string& text = r->counter.declarations();
  const bool ok = std::fwrite(text.data(), 1, text.size(), d) == text.size();
  if (std::fclose(d) != 0 || !ok || !r->counter.write(counts)) return -1;
  return static_cast<int64_t>(r->counter.size());
#else
  (void)h;
  (void)decl;
  (void)counts;
  return -1;
#endif
}

// The run's statistics so far (RtuStats: cycles, requests, ...; docs/statistics.md, unit_rtl).
void rtu_stats(void* h, rf_rtunit_stats::RtuStats* out) {
  Run* r = static_cast<Run*>(h);
  r->st.max_stack_depth = r->top.max_depth_o;
  r->st.cycles_simulated = r->cycle;
  *out = r->st;
}

}  // extern "C"
#pragma GCC visibility pop
