// A stage's pool of floating-point adders or multipliers, shared or private per operation.
//
// The one way a stage asks for units (rf_pkg: fu_count, fu_width):
//   localparam fu_count_t ADD = fu_count(.n_tri(6), .n_euc(NE));   // units per operation
//   fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;   // [opcode][unit]
//   rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
//     u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));
// Operation o's unit k adds (multiplies) a_i[o][k] and b_i[o][k] into y_o[o][k], for k < N[o]; the
// other entries of a_i and b_i are not read (the stage ties them to zero) and y_o's are +0.
// op_i is the opcode of the beat in the stage.
//   DISJOINT = 0 (unified, the paper's baseline): max(N[o]) units shared by all operations. Unit k
//     takes operand pair k of the beat's operation through an input mux.
//   DISJOINT = 1: each operation has its own private units, fed only while op_i selects it.
// Operand isolation: a unit that the beat's operation does not use is fed +0 + +0 (or +0 * +0), so
// it does not toggle in hardware, and its result is not read. The FP units resolve zero operands in
// their special-case path, so in simulation an idle unit costs only its classification.
module rf_fu_pool import rf_pkg::*; #(
  parameter bit           IS_MUL   = 1'b0,
  parameter bit           DISJOINT = 1'b0,
  parameter fu_count_t    N        = '0,
  localparam int unsigned W        = fu_width(N)
) (
  input  opcode_e                    op_i,
  input  fp32_t [NUM_OPS-1:0][W-1:0] a_i,
  input  fp32_t [NUM_OPS-1:0][W-1:0] b_i,
  output fp32_t [NUM_OPS-1:0][W-1:0] y_o
);

  localparam int unsigned P = fu_units(N);

  if (P == 0) begin : g_empty           // a pool no operation uses (e.g. S5's adders, FUSED)
    opcode_e unused_op;
    assign unused_op = op_i;
    assign y_o = '0;
  end else if (!DISJOINT) begin : g_unified
    for (genvar k = 0; k < P; k++) begin : g_unit
      fp32_t a, b, y;
      always_comb begin                 // operand pair k of the beat's operation, if it has one
        a = FP_POS_ZERO;
        b = FP_POS_ZERO;
        for (int o = 0; o < int'(NUM_OPS); o++) begin
          if (op_i == opcode_e'(o) && k < int'(N[o])) begin
            a = a_i[o][k];
            b = b_i[o][k];
          end
        end
      end
      rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(a), .b_i(b), .y_o(y));
      for (genvar o = 0; o < NUM_OPS; o++) begin : g_op
        assign y_o[o][k] = (k < N[o]) ? y : FP_POS_ZERO;
      end
    end
  end else begin : g_disjoint
    // Private units: operation o's units see its operands only while op_i == o, zeros otherwise.
    for (genvar o = 0; o < NUM_OPS; o++) begin : g_op
      for (genvar k = 0; k < W; k++) begin : g_slot
        if (k < N[o]) begin : g_unit
          logic en;
          assign en = (op_i == opcode_e'(o));
          rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? a_i[o][k] : FP_POS_ZERO),
                                         .b_i(en ? b_i[o][k] : FP_POS_ZERO), .y_o(y_o[o][k]));
        end else begin : g_none
          assign y_o[o][k] = FP_POS_ZERO;
        end
      end
    end
  end

endmodule
