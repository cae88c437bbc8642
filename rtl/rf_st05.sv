// Stage 5.
//   QUADBOX   tmin = max(.., +0), tmax = min(.., extent)
//   TRIANGLE   3 x  U = Cx*By - Cy*Bx,  V = Ax*Cy - Ay*Cx,  W = Bx*Ay - By*Ax
//   EUCLIDEAN  2 x  tree level 3: esum[i] + esum[i+2]
//   ANGULAR    2 x  tree level 3 (last): adot[0] + adot[1], anorm[0] + anorm[1]
module rf_st05 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 3, NB = 0, NE = EXTENDED ? 2 : 0, NA = EXTENDED ? 2 : 0;
  localparam int unsigned P = max4(NT, NB, NE, NA);

  // ---- QUADBOX ----
  fp32_t [3:0] tmin, tmax;
  for (genvar i = 0; i < 4; i++) begin : g_box
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(st_i.bnear[i]), .b_i(FP_POS_ZERO),
                         .min_o(unused_min), .max_o(tmin[i]));
    rf_fp_minmax u_far  (.a_i(st_i.bfar[i]), .b_i(st_i.extent),
                         .min_o(tmax[i]), .max_o(unused_max));
  end

  // ---- adder pool ----
  fp32_t [NUM_OPS-1:0][P-1:0] a, b, y;
  always_comb begin
    a = '0;
    b = '0;
    for (int k = 0; k < 3; k++) begin
      a[OP_TRIANGLE][k] = st_i.tcross[2*k];
      b[OP_TRIANGLE][k] = fp_neg(st_i.tcross[2*k+1]);
    end
    if (EXTENDED) begin
      for (int i = 0; i < 2; i++) begin
        a[OP_EUCLIDEAN][i] = st_i.esum[i];
        b[OP_EUCLIDEAN][i] = st_i.esum[i + 2];
      end
      a[OP_ANGULAR][0] = st_i.adot[0];
      b[OP_ANGULAR][0] = st_i.adot[1];
      a[OP_ANGULAR][1] = st_i.anorm[0];
      b[OP_ANGULAR][1] = st_i.anorm[1];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA))
    u_add (.sel_i(op_onehot(st_i.op)), .a_i(a), .b_i(b), .y_o(y));

  always_comb begin
    st_o = st_i;
    st_o.bnear = tmin;
    st_o.bfar  = tmax;
    st_o.tu    = y[OP_TRIANGLE][0];
    st_o.tv    = y[OP_TRIANGLE][1];
    st_o.tw    = y[OP_TRIANGLE][2];
    if (EXTENDED) begin
      st_o.esum[0]  = y[OP_EUCLIDEAN][0];
      st_o.esum[1]  = y[OP_EUCLIDEAN][1];
      st_o.adot[0]  = y[OP_ANGULAR][0];
      st_o.anorm[0] = y[OP_ANGULAR][1];
    end
  end

endmodule
