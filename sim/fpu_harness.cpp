// fpu_harness: batch driver for the Verilated fpu_tb_top (sim/fpu_tb_top.sv), loaded with ctypes.
//
// fpu_eval(a, b, n, add, sub, mul, flags, mn, mx) evaluates n operand pairs in one call:
//   a, b           : const uint32_t[n]  binary32 bit patterns
//   add, sub, mul  : uint32_t[n]        a + b, a - b, a * b
//   flags          : uint8_t[n]         bit 0 lt, bit 1 le, bit 2 eq, bit 3 unord
//   mn, mx         : uint32_t[n]        minimum(a, b), maximum(a, b)
// The model is combinational: set the inputs, eval(), read the outputs.
#include <cstddef>
#include <cstdint>
#include <memory>

#include "Vfpu_tb_top.h"
#include "verilated.h"

namespace {

Vfpu_tb_top& model() {
  static std::unique_ptr<VerilatedContext> context{new VerilatedContext};
  static std::unique_ptr<Vfpu_tb_top> top{new Vfpu_tb_top{context.get()}};
  return *top;
}

}  // namespace

// The library is compiled with -fvisibility=hidden (driver/backends/verilate.py): only this API is exported,
// so the compiler may inline and call the model's functions directly.
#pragma GCC visibility push(default)
extern "C" {

int fpu_eval(const uint32_t* a, const uint32_t* b, size_t n, uint32_t* add, uint32_t* sub,
             uint32_t* mul, uint8_t* flags, uint32_t* mn, uint32_t* mx) {
  Vfpu_tb_top& top = model();
  for (size_t i = 0; i < n; ++i) {
    top.a_i = a[i];
    top.b_i = b[i];
    top.eval();
    add[i] = top.add_o;
    sub[i] = top.sub_o;
    mul[i] = top.mul_o;
    flags[i] = static_cast<uint8_t>((top.lt_o & 1u) | ((top.le_o & 1u) << 1) |
                                    ((top.eq_o & 1u) << 2) | ((top.unord_o & 1u) << 3));
    mn[i] = top.min_o;
    mx[i] = top.max_o;
  }
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop
