// Test benches of two RT-unit modules alone, driven cycle by cycle from stimulus arrays that the
// Python test writes with its reference model (tests/test_rtunit_rtl.py); each library is built
// with one of the two tops (RTU_TB_STACK: rf_rtu_stack; RTU_TB_DIVS: rf_rtu_divs).
#include <cstdint>

#include "verilated.h"
#if defined(RTU_TB_STACK)
#include "Vrf_rtu_stack.h"
using Top = Vrf_rtu_stack;
#else
#include "Vrf_rtu_divs.h"
using Top = Vrf_rtu_divs;
#endif

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
}  // namespace

#pragma GCC visibility push(default)
extern "C" {

#if defined(RTU_TB_STACK)
// Per cycle k: inputs ctl[k] (bit 0 clear, 1 push, 2 pop, 3 refill), clear/push/pop slots, the
// pushed pointer; outputs sampled before the clock edge: top, empty | spilled << 1 | spill << 2,
// the spilled pointer, and the depth output.
void stack_run(int64_t n, const uint8_t* ctl, const uint32_t* clear_slot, const uint32_t* push_slot,
               const uint32_t* push_ptr, const uint32_t* pop_slot, uint32_t* top, uint8_t* flags,
               uint32_t* spill_ptr, uint32_t* depth) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.clear_i = t.push_i = t.pop_i = t.refill_i = 0;
  reset(t);
  for (int64_t k = 0; k < n; k++) {
    t.clear_i = ctl[k] & 1;
    t.push_i = (ctl[k] >> 1) & 1;
    t.pop_i = (ctl[k] >> 2) & 1;
    t.refill_i = (ctl[k] >> 3) & 1;
    t.clear_slot_i = clear_slot[k];
    t.push_slot_i = push_slot[k];
    t.push_ptr_i = push_ptr[k];
    t.pop_slot_i = pop_slot[k];
    t.eval();
    top[k] = t.top_o;
    flags[k] = t.empty_o | t.spilled_o << 1 | t.spill_o << 2;
    spill_ptr[k] = t.spill_ptr_o;
    depth[k] = t.depth_o;
    tick(t);
  }
}
#else
// Per cycle k: in_valid[k] (offer the next division a[i], b[i], tag i while any is left) and
// out_ready[k]; each result taken is written to q[tag] and its cycle to taken[tag]. Returns the
// results taken.
int64_t divs_run(int64_t cycles, const uint8_t* in_valid, const uint8_t* out_ready, int64_t n,
                 const uint32_t* a, const uint32_t* b, uint32_t* q, int64_t* taken) {
  VerilatedContext ctx;
  Top t{&ctx};
  t.in_valid_i = t.out_ready_i = 0;
  reset(t);
  int64_t next = 0, got = 0;
  for (int64_t k = 0; k < cycles; k++) {
    t.in_valid_i = next < n && in_valid[k];
    if (t.in_valid_i) {
      t.a_i = a[next];
      t.b_i = b[next];
      t.tag_i = static_cast<uint32_t>(next);
    }
    t.out_ready_i = out_ready[k];
    t.eval();
    if (t.in_valid_i && t.in_ready_o) next++;
    if (t.out_valid_o && t.out_ready_i) {
      const uint32_t tag = t.tag_o;
      if (tag < n) {
        q[tag] = t.q_o;
        taken[tag] = k;
      }
      got++;
    }
    tick(t);
  }
  return got;
}
#endif

}  // extern "C"
#pragma GCC visibility pop
