// Stage 7.
//   QUADBOX   sorting network layer 0
//   TRIANGLE   2 x  U*Az + V*Bz,  t_den = (U + V) + W
//   EUCLIDEAN  1 x  acc + beat  (accumulator)
//   ANGULAR    2 x  dot acc + beat, norm acc + beat  (accumulators)
// The accumulators are the only state in the datapath. They change only when a beat of their
// operation is accepted into this stage's register (fire_i): bubbles, back-pressure and other
// operations never touch them. On a beat with `last` set the output carries the sum including this
// beat and the accumulator clears to +0 for the next job.
module rf_st07 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  logic   clk_i,
  input  logic   rst_ni,
  input  logic   fire_i,
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 2, NB = 0, NE = EXTENDED ? 1 : 0, NA = EXTENDED ? 2 : 0;
  localparam int unsigned P = max4(NT, NB, NE, NA);

  // ---- QUADBOX ----
  fp32_t [3:0]      tmin;
  logic  [3:0][1:0] idx;
  logic  [3:0]      hit;
  rf_sort4 #(.LAYER(0)) u_sort (.tmin_i(st_i.btmin), .idx_i(st_i.bidx), .hit_i(st_i.bhit),
                                .tmin_o(tmin), .idx_o(idx), .hit_o(hit));

  // ---- accumulator state ----
  fp32_t euc_acc_q, dot_acc_q, norm_acc_q;

  // ---- adder pool ----
  fp32_t [NUM_OPS-1:0][P-1:0] a, b, y;
  always_comb begin
    a = '0;
    b = '0;
    a[OP_TRIANGLE][0] = st_i.tuvw_z[0];
    b[OP_TRIANGLE][0] = st_i.tuvw_z[1];
    a[OP_TRIANGLE][1] = st_i.tuv;
    b[OP_TRIANGLE][1] = st_i.tw;
    if (EXTENDED) begin
      a[OP_EUCLIDEAN][0] = euc_acc_q;
      b[OP_EUCLIDEAN][0] = st_i.esum[0];
      a[OP_ANGULAR][0]   = dot_acc_q;
      b[OP_ANGULAR][0]   = st_i.adot[0];
      a[OP_ANGULAR][1]   = norm_acc_q;
      b[OP_ANGULAR][1]   = st_i.anorm[0];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA))
    u_add (.sel_i(op_onehot(st_i.op)), .a_i(a), .b_i(b), .y_o(y));

  if (EXTENDED) begin : g_acc
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni) begin
        euc_acc_q  <= FP_POS_ZERO;
        dot_acc_q  <= FP_POS_ZERO;
        norm_acc_q <= FP_POS_ZERO;
      end else if (fire_i) begin
        if (st_i.op == OP_EUCLIDEAN) begin
          euc_acc_q <= st_i.last ? FP_POS_ZERO : y[OP_EUCLIDEAN][0];
        end
        if (st_i.op == OP_ANGULAR) begin
          dot_acc_q  <= st_i.last ? FP_POS_ZERO : y[OP_ANGULAR][0];
          norm_acc_q <= st_i.last ? FP_POS_ZERO : y[OP_ANGULAR][1];
        end
      end
    end
  end else begin : g_no_acc
    assign euc_acc_q  = FP_POS_ZERO;
    assign dot_acc_q  = FP_POS_ZERO;
    assign norm_acc_q = FP_POS_ZERO;
    logic unused_fire;
    assign unused_fire = fire_i ^ clk_i ^ rst_ni;
  end

  always_comb begin
    st_o           = st_i;
    st_o.btmin     = tmin;
    st_o.bidx      = idx;
    st_o.bhit      = hit;
    st_o.tnum_part = y[OP_TRIANGLE][0];
    st_o.t_den     = y[OP_TRIANGLE][1];
    if (EXTENDED) begin
      st_o.euclid_acc   = y[OP_EUCLIDEAN][0];
      st_o.angular_dot  = y[OP_ANGULAR][0];
      st_o.angular_norm = y[OP_ANGULAR][1];
    end
  end

endmodule
