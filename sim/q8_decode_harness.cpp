// q8_decode_harness: batch driver for the Verilated q8_decode_tb_top (sim/q8_decode_tb_top.sv),
// loaded with ctypes.
//
// q8_decode_eval(nodes, n, boxes) decodes n q8 nodes in one call:
//   nodes : const uint32_t[n][16]  the nodes' words as stored
//   boxes : uint32_t[n][24]        box[i][j] at word 6i + j (binary32 bit patterns)
// The model is combinational: set the inputs, eval(), read the outputs.
#include <cstddef>
#include <cstdint>
#include <memory>

#include "Vq8_decode_tb_top.h"
#include "verilated.h"

namespace {

Vq8_decode_tb_top& model() {
  static std::unique_ptr<VerilatedContext> context{new VerilatedContext};
  static std::unique_ptr<Vq8_decode_tb_top> top{new Vq8_decode_tb_top{context.get()}};
  return *top;
}

}  // namespace

#pragma GCC visibility push(default)
extern "C" {

int q8_decode_eval(const uint32_t* nodes, size_t n, uint32_t* boxes) {
  Vq8_decode_tb_top& top = model();
  for (size_t k = 0; k < n; ++k) {
    for (int w = 0; w < 16; ++w) top.qnode_i[w] = nodes[16 * k + w];
    top.eval();
    for (int w = 0; w < 24; ++w) boxes[24 * k + w] = top.box_o[w];
  }
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop
