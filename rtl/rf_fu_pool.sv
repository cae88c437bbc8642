// A stage's pool of floating-point adders or multipliers, shared or private per operation.
//
// Each operation o (indexed by its opcode) presents P operand pairs a_i[o][k], b_i[o][k]; it uses
// the first N_OP[o] of them (the rest are tied to zero by the stage). sel_i is the one-hot opcode
// of the beat in the stage.
//   DISJOINT = 0 (unified, the paper's baseline): max(N_OP) units; the selected operation's operands
//     reach them through an AND-OR mux (unselected operations feed zero), and every operation reads
//     the same results.
//   DISJOINT = 1: each operation has N_OP[o] private units whose inputs are gated to zero unless the
//     operation is selected; operation o reads its own units' results.
// Results of the units are y_o[o][k]; entries an operation does not use are zero.
module rf_fu_pool import rf_pkg::*; #(
  parameter bit          IS_MUL   = 1'b0,
  parameter bit          DISJOINT = 1'b0,
  parameter int unsigned N_TRI    = 0,
  parameter int unsigned N_BOX    = 0,
  parameter int unsigned N_EUC    = 0,
  parameter int unsigned N_ANG    = 0,
  localparam int unsigned P       = (max4(N_TRI, N_BOX, N_EUC, N_ANG) > 0)
                                    ? max4(N_TRI, N_BOX, N_EUC, N_ANG) : 1
) (
  input  logic  [NUM_OPS-1:0]        sel_i,
  input  fp32_t [NUM_OPS-1:0][P-1:0] a_i,
  input  fp32_t [NUM_OPS-1:0][P-1:0] b_i,
  output fp32_t [NUM_OPS-1:0][P-1:0] y_o
);

  localparam int unsigned N_OP [NUM_OPS] = '{N_TRI, N_BOX, N_EUC, N_ANG};

  if (!DISJOINT) begin : g_unified
    fp32_t [P-1:0] a, b, y;
    always_comb begin
      a = '0;
      b = '0;
      for (int unsigned o = 0; o < NUM_OPS; o++) begin
        if (sel_i[o]) begin
          a = a | a_i[o];
          b = b | b_i[o];
        end
      end
    end
    for (genvar k = 0; k < P; k++) begin : g_unit
      if (k < max4(N_TRI, N_BOX, N_EUC, N_ANG)) begin : g_used
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(a[k]), .b_i(b[k]), .y_o(y[k]));
      end else begin : g_unused
        assign y[k] = FP_POS_ZERO;
      end
    end
    for (genvar o = 0; o < NUM_OPS; o++) begin : g_out
      assign y_o[o] = y;
    end
  end else begin : g_disjoint
    for (genvar o = 0; o < NUM_OPS; o++) begin : g_op
      for (genvar k = 0; k < P; k++) begin : g_unit
        if (k < N_OP[o]) begin : g_used
          fp32_t a, b;
          assign a = sel_i[o] ? a_i[o][k] : FP_POS_ZERO;
          assign b = sel_i[o] ? b_i[o][k] : FP_POS_ZERO;
          rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(a), .b_i(b), .y_o(y_o[o][k]));
        end else begin : g_unused
          assign y_o[o][k] = FP_POS_ZERO;
        end
      end
    end
  end

endmodule
