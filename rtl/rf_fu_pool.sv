// A stage's pool of floating-point adders or multipliers, shared or private per operation.
//
// Each operation presents its own operand list (tri_*, box_*, euc_*, ang_*, xfm_*: N_TRI, N_BOX,
// N_EUC, N_ANG, N_XFM operand pairs; an operation that uses no unit has a one-entry list tied to zero) and reads
// its results from the list of the same name. op_i is the opcode of the beat in the stage.
//   DISJOINT = 0 (unified, the paper's baseline): max(N_*) units shared by all operations. Unit k
//     takes operand pair k of the beat's operation through an input mux.
//   DISJOINT = 1: each operation has its own private units, fed only while op_i selects it.
// Operand isolation: a unit that the beat's operation does not use is fed +0 + +0 (or +0 * +0), so
// it does not toggle in hardware, and its result is not read. The FP units resolve zero operands in
// their special-case path, so in simulation an idle unit costs only its classification.
module rf_fu_pool import rf_pkg::*; #(
  parameter bit          IS_MUL   = 1'b0,
  parameter bit          DISJOINT = 1'b0,
  parameter int unsigned N_TRI    = 0,
  parameter int unsigned N_BOX    = 0,
  parameter int unsigned N_EUC    = 0,
  parameter int unsigned N_ANG    = 0,
  parameter int unsigned N_XFM    = 0,
  localparam int unsigned W_TRI   = (N_TRI > 0) ? N_TRI : 1,
  localparam int unsigned W_BOX   = (N_BOX > 0) ? N_BOX : 1,
  localparam int unsigned W_EUC   = (N_EUC > 0) ? N_EUC : 1,
  localparam int unsigned W_ANG   = (N_ANG > 0) ? N_ANG : 1,
  localparam int unsigned W_XFM   = (N_XFM > 0) ? N_XFM : 1
) (
  input  opcode_e            op_i,
  input  fp32_t [W_TRI-1:0]  tri_a_i,
  input  fp32_t [W_TRI-1:0]  tri_b_i,
  output fp32_t [W_TRI-1:0]  tri_y_o,
  input  fp32_t [W_BOX-1:0]  box_a_i,
  input  fp32_t [W_BOX-1:0]  box_b_i,
  output fp32_t [W_BOX-1:0]  box_y_o,
  input  fp32_t [W_EUC-1:0]  euc_a_i,
  input  fp32_t [W_EUC-1:0]  euc_b_i,
  output fp32_t [W_EUC-1:0]  euc_y_o,
  input  fp32_t [W_ANG-1:0]  ang_a_i,
  input  fp32_t [W_ANG-1:0]  ang_b_i,
  output fp32_t [W_ANG-1:0]  ang_y_o,
  input  fp32_t [W_XFM-1:0]  xfm_a_i,
  input  fp32_t [W_XFM-1:0]  xfm_b_i,
  output fp32_t [W_XFM-1:0]  xfm_y_o
);

  localparam int unsigned P = max5(N_TRI, N_BOX, N_EUC, N_ANG, N_XFM);

  if (P == 0) begin : g_empty           // a pool no operation uses (e.g. S5's adders, FUSED)
    opcode_e unused_op;
    assign unused_op = op_i;
  end

  if (!DISJOINT) begin : g_unified
    fp32_t [(P > 0 ? P : 1)-1:0] y;
    for (genvar k = 0; k < P; k++) begin : g_unit
      // Clamped indices keep the selects in range; the branches of unused operations are dead.
      localparam int unsigned KT = (k < N_TRI) ? k : 0, KB = (k < N_BOX) ? k : 0;
      localparam int unsigned KE = (k < N_EUC) ? k : 0, KA = (k < N_ANG) ? k : 0;
      localparam int unsigned KX = (k < N_XFM) ? k : 0;
      fp32_t a, b;
      always_comb begin
        a = FP_POS_ZERO;
        b = FP_POS_ZERO;
        unique case (op_i)
          OP_TRIANGLE:  if (k < N_TRI) begin a = tri_a_i[KT]; b = tri_b_i[KT]; end
          OP_QUADBOX:   if (k < N_BOX) begin a = box_a_i[KB]; b = box_b_i[KB]; end
          OP_EUCLIDEAN: if (k < N_EUC) begin a = euc_a_i[KE]; b = euc_b_i[KE]; end
          OP_ANGULAR:   if (k < N_ANG) begin a = ang_a_i[KA]; b = ang_b_i[KA]; end
          OP_TRANSFORM: if (k < N_XFM) begin a = xfm_a_i[KX]; b = xfm_b_i[KX]; end
          default: ;
        endcase
      end
      rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(a), .b_i(b), .y_o(y[k]));
    end
    if (P == 0) begin : g_none
      assign y = FP_POS_ZERO;
    end
    assign tri_y_o = (N_TRI > 0) ? y[W_TRI-1:0] : '0;
    assign box_y_o = (N_BOX > 0) ? y[W_BOX-1:0] : '0;
    assign euc_y_o = (N_EUC > 0) ? y[W_EUC-1:0] : '0;
    assign ang_y_o = (N_ANG > 0) ? y[W_ANG-1:0] : '0;
    assign xfm_y_o = (N_XFM > 0) ? y[W_XFM-1:0] : '0;
  end else begin : g_disjoint
    // Private units: operation o's units see its operands only while op_i == o, zeros otherwise.
    for (genvar k = 0; k < W_TRI; k++) begin : g_tri
      if (k < N_TRI) begin : g_unit
        logic en;
        assign en = (op_i == OP_TRIANGLE);
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? tri_a_i[k] : FP_POS_ZERO),
                                       .b_i(en ? tri_b_i[k] : FP_POS_ZERO), .y_o(tri_y_o[k]));
      end else begin : g_none
        assign tri_y_o[k] = FP_POS_ZERO;
      end
    end
    for (genvar k = 0; k < W_BOX; k++) begin : g_box
      if (k < N_BOX) begin : g_unit
        logic en;
        assign en = (op_i == OP_QUADBOX);
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? box_a_i[k] : FP_POS_ZERO),
                                       .b_i(en ? box_b_i[k] : FP_POS_ZERO), .y_o(box_y_o[k]));
      end else begin : g_none
        assign box_y_o[k] = FP_POS_ZERO;
      end
    end
    for (genvar k = 0; k < W_EUC; k++) begin : g_euc
      if (k < N_EUC) begin : g_unit
        logic en;
        assign en = (op_i == OP_EUCLIDEAN);
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? euc_a_i[k] : FP_POS_ZERO),
                                       .b_i(en ? euc_b_i[k] : FP_POS_ZERO), .y_o(euc_y_o[k]));
      end else begin : g_none
        assign euc_y_o[k] = FP_POS_ZERO;
      end
    end
    for (genvar k = 0; k < W_ANG; k++) begin : g_ang
      if (k < N_ANG) begin : g_unit
        logic en;
        assign en = (op_i == OP_ANGULAR);
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? ang_a_i[k] : FP_POS_ZERO),
                                       .b_i(en ? ang_b_i[k] : FP_POS_ZERO), .y_o(ang_y_o[k]));
      end else begin : g_none
        assign ang_y_o[k] = FP_POS_ZERO;
      end
    end
    for (genvar k = 0; k < W_XFM; k++) begin : g_xfm
      if (k < N_XFM) begin : g_unit
        logic en;
        assign en = (op_i == OP_TRANSFORM);
        rf_fu #(.IS_MUL(IS_MUL)) u_fu (.a_i(en ? xfm_a_i[k] : FP_POS_ZERO),
                                       .b_i(en ? xfm_b_i[k] : FP_POS_ZERO), .y_o(xfm_y_o[k]));
      end else begin : g_none
        assign xfm_y_o[k] = FP_POS_ZERO;
      end
    end
  end

endmodule
