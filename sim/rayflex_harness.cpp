// Fast path: stream requests through the Verilated RayFlex model in one call.
//
// Requests and responses travel as arrays of little-endian uint32 words in the wire format of
// rtl/rf_pkg.sv (req_t: kReqWords words per request, rsp_t: kRspWords words per response; word 0
// holds bits [31:0]); the layout constants come from rf_layout.h, generated from driver/core/layout.py.
//
// rf_run streams ready-made request words. rf_run_nodes streams traversal requests that it
// assembles itself, as an RT unit would, from a ray table (the first kRayWords wire words of each
// prepared ray) and the BVH4 memory image (docs/datapath.md#bvh4-image): QUADBOX for a box-node pointer (the
// four child boxes), TRIANGLE for a triangle-node pointer (A, B, C). Both drive in_valid/out_ready
// from two repeating 0/1 patterns (input gaps and output stalls), so a Python cycle-by-cycle
// driver given the same patterns sees the same cycles. Cycles are counted from the cycle in which
// the first request is accepted to the cycle in which the last response is taken, inclusive: N
// back-to-back requests take N + LATENCY cycles.
//
// The RT-unit replay (several pipelines, a pool of rays in flight) is rtunit_scheduler.cpp.
#include <cstdint>
#include <cstring>
#include <thread>
#include <vector>

#include "rf_sim.h"

namespace {

using namespace rf;

constexpr int64_t kPrefetchAhead = 8;  // requests

// Returns the cycles of this run, -1 on a deadlock, -2 on a bad request (bad node pointer).
template <typename Source>
int64_t stream(Sim* s, const Source& src, uint32_t* rsp, int64_t n, const uint8_t* gap,
               int64_t gap_len, const uint8_t* stall, int64_t stall_len, int64_t max_idle) {
  Vrayflex& t = s->top;
  int64_t sent = 0, taken = 0, k = 0, first = -1, last = -1, idle = 0, loaded = -1;
  src.begin(t.req_i.data());
  while (taken < n) {
    const bool hold = gap && gap[k % gap_len];
    const bool stall_now = stall && stall[k % stall_len];
    t.in_valid_i = (sent < n && !hold) ? 1 : 0;
    if (t.in_valid_i && loaded != sent) {   // a request held back by in_ready stays loaded
      if (!src.fill(sent, t.req_i.data())) return -2;
      if (sent + kPrefetchAhead < n) src.prefetch(sent + kPrefetchAhead);
      loaded = sent;
    }
    t.out_ready_i = stall_now ? 0 : 1;
    // in_ready_o, out_valid_o and rsp_o are register outputs (no combinational path from any
    // input), so they are sampled without an extra eval before the clock edge.
    const bool in_fire = t.in_valid_i && t.in_ready_o;
    const bool out_fire = t.out_valid_o && t.out_ready_i;
    if (out_fire) {
      std::memcpy(rsp + taken * kRspWords, t.rsp_o.data(), kRspWords * 4);
      taken++;
      last = k;
    }
    if (in_fire) {
      if (first < 0) first = k;
      sent++;
    }
    idle = (in_fire || out_fire) ? 0 : idle + 1;
    if (idle > max_idle) return -1;
    tick(s);
    k++;
  }
  t.in_valid_i = 0;
  t.out_ready_i = 0;
  const int64_t cycles = n ? last - first + 1 : 0;
  return cycles;
}

}  // namespace

// The library is compiled with -fvisibility=hidden (driver/backends/verilate.py): only this API is exported,
// so the compiler may inline and call the model's functions directly.
#pragma GCC visibility push(default)
extern "C" {


void* rf_new() { return new_sim(); }

void rf_free(void* h) { delete static_cast<Sim*>(h); }

// Stream n requests. gap/stall: patterns of length gap_len / stall_len; cycle k of this run has
// in_valid withheld when gap[k % gap_len] != 0 and out_ready low when stall[k % stall_len] != 0
// (a null pattern means never). Returns the cycles of this run (0 for n == 0), or -1 if the
// pipeline made no progress for max_idle cycles (a deadlock: responses lost).
int64_t rf_run(void* h, const uint32_t* req, uint32_t* rsp, int64_t n,
               const uint8_t* gap, int64_t gap_len, const uint8_t* stall, int64_t stall_len,
               int64_t max_idle) {
  return stream(static_cast<Sim*>(h), WordSource{req}, rsp, n, gap, gap_len, stall, stall_len,
                max_idle);
}

// Stream n traversal requests assembled from (ray[i], ptr[i], ext[i]) (see NodeSource). Same
// return values as rf_run, plus -2 for a pointer that is not a node of the image.
int64_t rf_run_nodes(void* h, const uint32_t* rays, const uint32_t* image, int64_t image_words,
                     const uint32_t* ray, const uint32_t* ptr, const uint32_t* ext,
                     uint32_t* rsp, int64_t n, const uint8_t* gap, int64_t gap_len,
                     const uint8_t* stall, int64_t stall_len, int64_t max_idle) {
  const NodeSource src{rays, image, image_words, ray, ptr, ext};
  return stream(static_cast<Sim*>(h), src, rsp, n, gap, gap_len, stall, stall_len, max_idle);
}

// rf_run_nodes split over `parts` models (each its own VerilatedContext, e.g. a pool of rf_new
// handles), one thread each: part j streams requests [n j / parts, n (j + 1) / parts) on model
// hs[j] with no gaps and no stalls, writes its responses in place and its cycles (as rf_run_nodes
// returns them) into part_cycles[j]. Returns 0, or the first part's negative error.
int64_t rf_run_nodes_split(void** hs, int64_t parts, const uint32_t* rays, const uint32_t* image,
                           int64_t image_words, const uint32_t* ray, const uint32_t* ptr,
                           const uint32_t* ext, uint32_t* rsp, int64_t n, int64_t max_idle,
                           int64_t* part_cycles) {
  if (parts < 1) return -3;
  auto part = [&](int64_t j) {
    const int64_t lo = n * j / parts, hi = n * (j + 1) / parts;
    const NodeSource src{rays, image, image_words, ray + lo, ptr + lo, ext + lo};
    part_cycles[j] = stream(static_cast<Sim*>(hs[j]), src, rsp + lo * kRspWords, hi - lo,
                            nullptr, 1, nullptr, 1, max_idle);
  };
  std::vector<std::thread> threads;
  for (int64_t j = 1; j < parts; j++) threads.emplace_back(part, j);
  part(0);
  for (auto& t : threads) t.join();
  for (int64_t j = 0; j < parts; j++)
    if (part_cycles[j] < 0) return part_cycles[j];
  return 0;
}

// The model's latency as the RT-unit replay sees it: the cycles from a request's input
// handshake to its response's out_valid with out_ready held high (a fresh model, one request of
// zero words). Returns -1 if no response comes within 1,000 cycles.
int64_t rf_latency() {
  Sim* s = new_sim();
  Vrayflex& t = s->top;
  std::memset(t.req_i.data(), 0, kReqWords * 4);
  t.out_ready_i = 1;
  t.in_valid_i = 1;
  int64_t k = -1;
  if (t.in_ready_o) {
    tick(s);
    t.in_valid_i = 0;
    for (k = 1; k <= 1000 && !t.out_valid_o; k++) tick(s);
    if (!t.out_valid_o) k = -1;
  }
  delete s;
  return k;
}

// The request words rf_run_nodes would send (for tests and the cycle-by-cycle backend).
// Returns 0, or -2 for a bad node pointer.
int64_t rf_build_requests(const uint32_t* rays, const uint32_t* image, int64_t image_words,
                          const uint32_t* ray, const uint32_t* ptr, const uint32_t* ext,
                          uint32_t* req, int64_t n) {
  const NodeSource src{rays, image, image_words, ray, ptr, ext};
  for (int64_t i = 0; i < n; i++) {
    src.begin(req + i * kReqWords);
    if (!src.fill(i, req + i * kReqWords)) return -2;
  }
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop
