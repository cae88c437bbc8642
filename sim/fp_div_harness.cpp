// fp_div_harness: driver and monitor for the Verilated fp_div_tb_top (sim/fp_div_tb_top.sv), loaded
// with ctypes.
//
// fp_div_run(a, b, tag, n, gap, gap_len, stall, stall_len, q, tag_out, latency, stats, max_cycles)
// resets the divider and streams n divisions through it, one clock cycle at a time:
//   a, b, tag   : const uint32_t[n]  operands (binary32 bit patterns) and the tag of each division
//   gap, stall  : repeating 0/1 patterns (nullptr: none); in cycle k a new division is offered
//                 only if gap[k % gap_len] == 0 (an offered one stays offered, operands unchanged,
//                 until taken, as valid/ready requires), and out_ready_i is low if
//                 stall[k % stall_len] != 0
//   q, tag_out  : uint32_t[n]        the results and their tags, in the order they were taken
//   latency     : int32_t[n]         cycles from the j-th input handshake to the first cycle of
//                                    the j-th result's out_valid_o
//   stats       : int64_t[4]         [0] cycles of the run, [1] protocol errors (a raised
//                                    out_valid_o dropped or its q_o/tag_o changed before it was
//                                    taken), [2] cycles with in_ready_o high while a division was
//                                    in the unit, [3] the RTL's DIV_CYCLES
//   max_cycles  : stop after this many cycles (0: no bound), whatever is inside the unit
// Returns the cycles, -1 if the unit stopped (no handshake for a bound of cycles), or -2 when
// max_cycles ran out first.
// While no division is offered, a_i, b_i and tag_i carry garbage.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "Vfp_div_tb_top.h"
#include "verilated.h"

namespace {

Vfp_div_tb_top& model() {
  static std::unique_ptr<VerilatedContext> context{new VerilatedContext};
  static std::unique_ptr<Vfp_div_tb_top> top{new Vfp_div_tb_top{context.get()}};
  return *top;
}

void tick(Vfp_div_tb_top& t) {
  t.clk_i = 1;
  t.eval();
  t.clk_i = 0;
  t.eval();
}

uint32_t xorshift(uint32_t& s) {
  s ^= s << 13;
  s ^= s >> 17;
  s ^= s << 5;
  return s;
}

constexpr int64_t kMaxIdle = 1000;   // cycles without a handshake: the unit has stopped

}  // namespace

#pragma GCC visibility push(default)
extern "C" {

int64_t fp_div_run(const uint32_t* a, const uint32_t* b, const uint32_t* tag, int64_t n,
                   const uint8_t* gap, int64_t gap_len, const uint8_t* stall, int64_t stall_len,
                   uint32_t* q, uint32_t* tag_out, int32_t* latency, int64_t* stats,
                   int64_t max_cycles) {
  Vfp_div_tb_top& t = model();
  stats[0] = stats[1] = stats[2] = 0;
  t.in_valid_i = 0;
  t.out_ready_i = 0;
  t.clk_i = 0;
  t.rst_ni = 0;
  t.eval();
  tick(t);
  t.rst_ni = 1;
  t.eval();
  stats[3] = t.div_cycles_o;

  std::vector<int64_t> fired(static_cast<size_t>(n));
  uint32_t garbage = 0x2545F491u;
  int64_t sent = 0, taken = 0, k = 0, idle = 0;
  bool offered = false;
  bool held = false;            // out_valid_o was high and not taken in the previous cycle
  uint32_t held_q = 0, held_tag = 0;
  int64_t rise = -1;            // first cycle of the current result's out_valid_o
  while (taken < n) {
    if (max_cycles > 0 && k >= max_cycles) return -2;
    if (!offered && sent < n && !(gap && gap[k % gap_len])) offered = true;
    t.in_valid_i = offered ? 1 : 0;
    if (offered) {
      t.a_i = a[sent];
      t.b_i = b[sent];
      t.tag_i = tag[sent];
    } else {
      t.a_i = xorshift(garbage);
      t.b_i = xorshift(garbage);
      t.tag_i = xorshift(garbage);
    }
    t.out_ready_i = (stall && stall[k % stall_len]) ? 0 : 1;
    t.eval();
    const bool in_fire = t.in_valid_i && t.in_ready_o;
    const bool out_fire = t.out_valid_o && t.out_ready_i;
    if (held && (!t.out_valid_o || t.q_o != held_q || t.tag_o != held_tag)) stats[1]++;
    if (t.in_ready_o && sent > taken) stats[2]++;
    if (t.out_valid_o && rise < 0) rise = k;
    if (out_fire) {
      if (taken < sent) {
        q[taken] = t.q_o;
        tag_out[taken] = t.tag_o;
        latency[taken] = static_cast<int32_t>(rise - fired[taken]);
      } else {
        stats[1]++;             // a result without a division
      }
      taken++;
      rise = -1;
    }
    held = t.out_valid_o && !t.out_ready_i;
    held_q = t.q_o;
    held_tag = t.tag_o;
    if (in_fire) {
      fired[sent++] = k;
      offered = false;
    }
    idle = (in_fire || out_fire) ? 0 : idle + 1;
    if (idle > kMaxIdle) return -1;
    tick(t);
    k++;
  }
  t.in_valid_i = 0;
  t.out_ready_i = 0;
  stats[0] = k;
  return k;
}

}  // extern "C"
#pragma GCC visibility pop
