// Fast path: stream requests through the Verilated RayFlex model in one call, and the RT-unit
// replay (several pipelines, a pool of rays in flight).
//
// Requests and responses travel as arrays of little-endian uint32 words in the wire format of
// rtl/rf_pkg.sv (req_t: REQ_WORDS words per request, rsp_t: RSP_WORDS words per response; word 0
// holds bits [31:0]). See driver/wire.py for the field layout.
//
// rf_run streams ready-made request words. rf_run_nodes streams traversal requests that it
// assembles itself, as an RT unit would, from a ray table (the first RAY_WORDS wire words of each
// prepared ray) and the BVH4 memory image (SPEC section 8): QUADBOX for a box-node pointer (the
// four child boxes), TRIANGLE for a triangle-node pointer (A, B, C). Both drive in_valid/out_ready
// from two repeating 0/1 patterns (input gaps and output stalls), so a Python cycle-by-cycle
// driver given the same patterns sees the same cycles. Cycles are counted from the cycle in which
// the first request is accepted to the cycle in which the last response is taken, inclusive: N
// back-to-back requests take N + LATENCY cycles.
//
// rf_replay is the RT-unit model of driver/rtunit.py: P fresh model instances clocked together, a
// pool of R ray slots, each ray's recorded request chain issued one request at a time.
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <vector>

#include "Vrayflex.h"
#include "verilated.h"

namespace {

constexpr int kReqWords = 80;
constexpr int kRspWords = 11;
constexpr int kRayWords = 15;   // tag, control, origin, dir, inv, extent, shear
constexpr int kBoxWord = 15;    // request words 15..38: box[4][6]
constexpr int kTriWord = 39;    // request words 39..47: tri[3][3]
constexpr uint32_t kBoxType = 5, kTriType = 0;

struct Sim {
  VerilatedContext ctx;
  Vrayflex top{&ctx};
  uint64_t cycles_total = 0;  // clock cycles simulated by the streaming calls (counted as above)
  uint64_t clocks = 0;        // every rising edge, including reset
};

void tick(Sim* s) {
  s->top.clk_i = 1;
  s->top.eval();
  s->top.clk_i = 0;
  s->top.eval();
  s->clocks++;
}

Sim* new_sim() {
  Sim* s = new Sim;
  s->top.clk_i = 0;
  s->top.rst_ni = 0;
  s->top.in_valid_i = 0;
  s->top.out_ready_i = 0;
  s->top.eval();
  for (int i = 0; i < 2; i++) tick(s);
  s->top.rst_ni = 1;
  s->top.eval();
  return s;
}

// Ready-made request words.
struct WordSource {
  const uint32_t* req;
  bool fill(int64_t i, uint32_t* dst) const {
    std::memcpy(dst, req + i * kReqWords, kReqWords * 4);
    return true;
  }
  void prefetch(int64_t) const {}  // sequential: the hardware prefetcher sees it
  void begin(uint32_t*) const {}
};

// A traversal request: ray `ray[i]` against node `ptr[i]` with extent bits `ext[i]`.
struct NodeSource {
  const uint32_t* rays;   // (n_rays, kRayWords)
  const uint32_t* image;  // BVH4 image as uint32 words
  int64_t image_words;
  const uint32_t* ray;
  const uint32_t* ptr;
  const uint32_t* ext;

  // The words after the ray's are zero except the box or the triangle: begin() clears them once
  // per stream, and each fill() writes its own operand and clears the other one's.
  void begin(uint32_t* dst) const {
    std::memset(dst + kRayWords, 0, (kReqWords - kRayWords) * 4);
  }

  // Returns false for a pointer that is neither a box nor a triangle node inside the image.
  bool fill(int64_t i, uint32_t* dst) const {
    const uint32_t r = ray[i], p = ptr[i], type = p & 7u;
    const int64_t word = static_cast<int64_t>(p & ~7u) << 1;  // byte offset (p & ~7) << 3, / 4
    std::memcpy(dst, rays + static_cast<int64_t>(r) * kRayWords, kRayWords * 4);
    dst[0] = r;                                          // tag = ray index
    dst[11] = ext[i];                                    // extent = the ray's nearest t so far
    if (type == kBoxType) {
      if (word + 28 > image_words) return false;
      dst[1] = (dst[1] & ~3u) | 1u;                       // QUADBOX
      std::memcpy(dst + kBoxWord, image + word + 4, 24 * 4);
      std::memset(dst + kTriWord, 0, 9 * 4);
    } else if (type == kTriType) {
      if (word + 9 > image_words) return false;
      dst[1] = dst[1] & ~3u;                              // TRIANGLE
      std::memcpy(dst + kTriWord, image + word, 9 * 4);
      std::memset(dst + kBoxWord, 0, 24 * 4);
    } else {
      return false;
    }
    return true;
  }

  // Request i's ray and node are scattered over the ray table and the image (a cache miss
  // each); fetching them a few requests ahead hides that behind the model's evaluation.
  void prefetch(int64_t i) const {
    const uint32_t* r = rays + static_cast<int64_t>(ray[i]) * kRayWords;
    const uint32_t* node = image + (static_cast<int64_t>(ptr[i] & ~7u) << 1);
    __builtin_prefetch(r);
    __builtin_prefetch(r + kRayWords - 1);
    __builtin_prefetch(node);
    __builtin_prefetch(node + 27);   // a box node's last word (a triangle node is shorter)
  }
};

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
  s->cycles_total += cycles;
  return cycles;
}

}  // namespace

// The library is compiled with -fvisibility=hidden (driver/verilate.py): only this API is exported,
// so the compiler may inline and call the model's functions directly.
#pragma GCC visibility push(default)
extern "C" {

int rf_req_words() { return kReqWords; }
int rf_rsp_words() { return kRspWords; }
int rf_ray_words() { return kRayWords; }
int rf_req_bits() { return static_cast<int>(sizeof(Vrayflex::req_i) * 8); }

void* rf_new() { return new_sim(); }

void rf_free(void* h) { delete static_cast<Sim*>(h); }

uint64_t rf_cycles(void* h) { return static_cast<Sim*>(h)->cycles_total; }

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

// RT-unit replay (driver/rtunit.py). The m recorded requests (ray[i], ptr[i], ext[i]) form one
// chain per ray; chain_idx lists the record indices of ray r's chain, in issue order, at
// chain_idx[chain_off[r] .. chain_off[r + 1]). Rays enter a pool of `slots` ray slots in index
// order (rays with an empty chain are skipped) and leave it when their chain is done.
//
// Every cycle, first each pipeline's response (if out_valid) is taken: its ray becomes ready
// `turnaround` cycles later (or leaves the pool, and the next ray enters, ready `turnaround`
// cycles later). Then each pipeline, in order 0..P-1, whose input is ready accepts the next
// request of the oldest ready ray (FIFO of rays by ready time; a new ray ready at cycle 0
// initially). Then all pipelines are clocked. A ray has at most one request in flight.
//
// skip_idle: a pipeline that holds no request at the start of a cycle and gets none is not
// evaluated in that cycle (clock gating: with nothing valid inside, a clock edge changes no state
// of the RayFlex pipeline, whose registers load only on a handshake); cycles still count.
//
// rsp: (m, RSP_WORDS), written at the record index. stats (int64[8]): cycles (first accept to
// last response, inclusive), model evaluations (pipeline-cycles clocked), starved cycles (a
// pipeline issued nothing because no ray was ready: latency not hidden), cycles with every
// pipeline issuing, first accept cycle, last response cycle, tag
// mismatches, pipeline-cycles with a request accepted. per_pipe (int64[P]): requests per pipeline.
// Returns 0, -1 on a deadlock, -2 on a bad node pointer, -3 on bad arguments.
int64_t rf_replay(int64_t pipelines, int64_t slots, int64_t turnaround, int64_t skip_idle,
                  const uint32_t* rays, int64_t n_rays, const uint32_t* image,
                  int64_t image_words, const uint32_t* ray, const uint32_t* ptr,
                  const uint32_t* ext, int64_t m, const int64_t* chain_idx,
                  const int64_t* chain_off, uint32_t* rsp, int64_t* stats, int64_t* per_pipe,
                  int64_t max_idle) {
  if (pipelines < 1 || slots < 1 || turnaround < 0 || n_rays < 0 || m < 0) return -3;
  const NodeSource src{rays, image, image_words, ray, ptr, ext};
  std::vector<std::unique_ptr<Sim>> sims;
  for (int64_t p = 0; p < pipelines; p++) {
    sims.emplace_back(new_sim());
    src.begin(sims.back()->top.req_i.data());
  }
  std::vector<std::deque<int64_t>> inflight(pipelines);   // record indices, in request order
  std::vector<int64_t> pos(n_rays, 0);                     // next chain position of each ray
  struct Ready { int64_t ray, at; };
  std::deque<Ready> ready;
  int64_t next_ray = 0;
  auto enter = [&](int64_t at) {                           // next ray with a non-empty chain
    while (next_ray < n_rays && chain_off[next_ray + 1] == chain_off[next_ray]) next_ray++;
    if (next_ray < n_rays) {
      ready.push_back({next_ray++, at});
    }
  };
  for (int64_t s = 0; s < slots && next_ray < n_rays; s++) enter(0);

  int64_t taken = 0, k = 0, first = -1, last = -1, idle = 0, evals = 0, starved = 0;
  int64_t full_cycles = 0, bad_tags = 0, accepts = 0;
  std::vector<char> busy(pipelines);
  for (int64_t p = 0; p < pipelines; p++) per_pipe[p] = 0;
  while (taken < m) {
    bool progress = false;
    for (int64_t p = 0; p < pipelines; p++) {
      Vrayflex& t = sims[p]->top;
      busy[p] = !inflight[p].empty();
      t.out_ready_i = 1;
      if (!(busy[p] && t.out_valid_o)) continue;
      const int64_t i = inflight[p].front();
      inflight[p].pop_front();
      std::memcpy(rsp + i * kRspWords, t.rsp_o.data(), kRspWords * 4);
      if (rsp[i * kRspWords] != ray[i]) bad_tags++;
      taken++;
      last = k;
      progress = true;
      const int64_t r = ray[i];
      if (++pos[r] < chain_off[r + 1] - chain_off[r]) {
        ready.push_back({r, k + turnaround});
      } else {
        enter(k + turnaround);
      }
    }
    int64_t issued = 0;
    for (int64_t p = 0; p < pipelines; p++) {
      Vrayflex& t = sims[p]->top;
      t.in_valid_i = 0;
      if (ready.empty() || ready.front().at > k || !t.in_ready_o) continue;
      const int64_t r = ready.front().ray;
      ready.pop_front();
      const int64_t i = chain_idx[chain_off[r] + pos[r]];
      if (!src.fill(i, t.req_i.data())) return -2;
      if (!ready.empty()) {                       // the next ray to issue, if it is known
        const Ready& nx = ready.front();
        if (pos[nx.ray] < chain_off[nx.ray + 1] - chain_off[nx.ray])
          src.prefetch(chain_idx[chain_off[nx.ray] + pos[nx.ray]]);
      }
      t.in_valid_i = 1;
      inflight[p].push_back(i);
      per_pipe[p]++;
      issued++;
      if (first < 0) first = k;
      progress = true;
    }
    accepts += issued;
    if (issued == pipelines) full_cycles++;
    if (issued < pipelines && (ready.empty() || ready.front().at > k)) starved++;
    for (int64_t p = 0; p < pipelines; p++) {
      if (skip_idle && !busy[p] && !sims[p]->top.in_valid_i) continue;
      tick(sims[p].get());
      evals++;
    }
    idle = progress ? 0 : idle + 1;
    if (idle > max_idle + turnaround) return -1;
    k++;
  }
  stats[0] = m ? last - first + 1 : 0;
  stats[1] = evals;
  stats[2] = starved;
  stats[3] = full_cycles;
  stats[4] = first;
  stats[5] = last;
  stats[6] = bad_tags;
  stats[7] = accepts;
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop
