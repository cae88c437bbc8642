// Power measurement harness (driver/power/activity.py, level "signals"): streams request words
// back to back through the Verilated RTL built with --trace, writes a VCD of a run, and counts
// the bit toggles of every VCD identifier (pw_vcd_count, the counter of sim/rf_toggles.h).
// Verilator gives every net one identifier, shared by its aliases (the same net seen through
// ports and continuous assignments in several scopes), so counting per identifier counts each
// net once (Verilator's toggle coverage would count it once per scope it appears in). Counting
// in C++ keeps a run in fractions of a second (a 300-request run writes ~25 MB of VCD).
#include <cstdint>
#include <cstring>

#include "Vrayflex.h"
#include "verilated.h"
#include <cstdio>

#include "verilated_vcd_c.h"
#include "rf_toggles.h"

namespace {

// A context that allows tracing before the model (built from it) is constructed.
struct Context : VerilatedContext {
  Context() { traceEverOn(true); }
};

struct Sim {
  Context ctx;
  Vrayflex top{&ctx};
  VerilatedVcdC* vcd = nullptr;
  uint64_t time = 0;
};

void tick(Sim* s) {
  s->top.clk_i = 1;
  s->top.eval();
  s->top.clk_i = 0;
  s->top.eval();
  s->time++;
  if (s->vcd) s->vcd->dump(s->time);  // one sample per cycle: zero-delay, no glitches
}

constexpr int kReqWords = sizeof(Vrayflex::req_i) / 4;

}  // namespace

#pragma GCC visibility push(default)
extern "C" {

int pw_req_words() { return kReqWords; }

void* pw_new() {
  Sim* s = new Sim;
  s->top.clk_i = 0;
  s->top.rst_ni = 0;
  s->top.in_valid_i = 0;
  s->top.out_ready_i = 1;
  std::memset(s->top.req_i.data(), 0, kReqWords * 4);
  s->top.eval();
  for (int i = 0; i < 2; i++) tick(s);
  s->top.rst_ni = 1;
  s->top.eval();
  return s;
}

void pw_free(void* h) {
  Sim* s = static_cast<Sim*>(h);
  if (s->vcd) s->vcd->close();
  delete s->vcd;
  delete s;
}


// Stream n requests (n x kReqWords words) back to back with out_ready high, until every response
// has left, then clock `idle` more cycles with nothing valid (the inputs keep their last value).
// Returns the clock cycles run, or -1 if the pipeline stops making progress.
int64_t pw_stream(void* h, const uint32_t* req, int64_t n, int64_t idle) {
  Sim* s = static_cast<Sim*>(h);
  Vrayflex& t = s->top;
  int64_t sent = 0, taken = 0, cycles = 0, stuck = 0;
  t.out_ready_i = 1;
  while (taken < n) {
    t.in_valid_i = sent < n ? 1 : 0;
    if (t.in_valid_i) std::memcpy(t.req_i.data(), req + sent * kReqWords, kReqWords * 4);
    const bool in_fire = t.in_valid_i && t.in_ready_o;
    const bool out_fire = t.out_valid_o;
    sent += in_fire;
    taken += out_fire;
    stuck = (in_fire || out_fire) ? 0 : stuck + 1;
    if (stuck > 1000) return -1;
    tick(s);
    cycles++;
  }
  t.in_valid_i = 0;
  for (int64_t i = 0; i < idle; i++) tick(s);
  return cycles + idle;
}

// Start a VCD of every signal at `path` (its first sample is the current state).
void pw_trace_open(void* h, const char* path) {
  Sim* s = static_cast<Sim*>(h);
  if (!s->vcd) {
    s->vcd = new VerilatedVcdC;
    s->top.trace(s->vcd, 99);
  }
  s->vcd->open(path);
  s->vcd->dump(s->time);
}

void pw_trace_close(void* h) {
  Sim* s = static_cast<Sim*>(h);
  if (s->vcd) s->vcd->close();
}

// Count the bit toggles of every identifier in the VCD at `vcd` (after each identifier's first
// value; sim/rf_toggles.h) and write "identifier toggles" lines to `out`. Returns the number of
// identifiers, or -1 if a file cannot be opened.
int64_t pw_vcd_count(const char* vcd, const char* out) { return rf_toggles::count_file(vcd, out); }

}  // extern "C"
#pragma GCC visibility pop
