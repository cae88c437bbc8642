// Stage 4.
//   QUADBOX   max(.., near_z), min(.., far_z)
//   TRIANGLE   6 x  Cx*By, Cy*Bx, Ax*Cy, Ay*Cx, Bx*Ay, By*Ax   (multipliers)
//   EUCLIDEAN  4 x  tree level 2: esum[i] + esum[i+4]            (adders)
//   ANGULAR    4 x  tree level 2 on dot and norm                  (adders)
module rf_st04 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned MT = 6;
  localparam int unsigned AE = EXTENDED ? 4 : 0, AA = EXTENDED ? 4 : 0;
  localparam int unsigned PM = MT;
  localparam int unsigned PA = (max4(0, 0, AE, AA) > 0) ? max4(0, 0, AE, AA) : 1;

  // ---- QUADBOX ----
  fp32_t [3:0] near, far;
  for (genvar i = 0; i < 4; i++) begin : g_box
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(st_i.bnear[i]), .b_i(st_i.bnear_z[i]),
                         .min_o(unused_min), .max_o(near[i]));
    rf_fp_minmax u_far  (.a_i(st_i.bfar[i]),  .b_i(st_i.bfar_z[i]),
                         .min_o(far[i]), .max_o(unused_max));
  end

  // ---- multiplier pool: the 2-D cross products (vertex index 0, 1, 2 = A, B, C) ----
  fp32_t [NUM_OPS-1:0][PM-1:0] ma, mb, my;
  always_comb begin
    ma = '0;
    mb = '0;
    ma[OP_TRIANGLE][0] = st_i.tx[2];  mb[OP_TRIANGLE][0] = st_i.ty[1];   // Cx*By
    ma[OP_TRIANGLE][1] = st_i.ty[2];  mb[OP_TRIANGLE][1] = st_i.tx[1];   // Cy*Bx
    ma[OP_TRIANGLE][2] = st_i.tx[0];  mb[OP_TRIANGLE][2] = st_i.ty[2];   // Ax*Cy
    ma[OP_TRIANGLE][3] = st_i.ty[0];  mb[OP_TRIANGLE][3] = st_i.tx[2];   // Ay*Cx
    ma[OP_TRIANGLE][4] = st_i.tx[1];  mb[OP_TRIANGLE][4] = st_i.ty[0];   // Bx*Ay
    ma[OP_TRIANGLE][5] = st_i.ty[1];  mb[OP_TRIANGLE][5] = st_i.tx[0];   // By*Ax
  end
  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(MT), .N_BOX(0), .N_EUC(0), .N_ANG(0))
    u_mul (.sel_i(op_onehot(st_i.op)), .a_i(ma), .b_i(mb), .y_o(my));

  // ---- adder pool: reduction trees (extended only) ----
  fp32_t [NUM_OPS-1:0][PA-1:0] ay;
  if (EXTENDED) begin : g_tree
    fp32_t [NUM_OPS-1:0][PA-1:0] aa, ab;
    always_comb begin
      aa = '0;
      ab = '0;
      for (int i = 0; i < 4; i++) begin
        aa[OP_EUCLIDEAN][i] = st_i.esum[i];
        ab[OP_EUCLIDEAN][i] = st_i.esum[i + 4];
      end
      for (int i = 0; i < 2; i++) begin
        aa[OP_ANGULAR][i]     = st_i.adot[i];
        ab[OP_ANGULAR][i]     = st_i.adot[i + 2];
        aa[OP_ANGULAR][2 + i] = st_i.anorm[i];
        ab[OP_ANGULAR][2 + i] = st_i.anorm[i + 2];
      end
    end
    rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(0), .N_BOX(0), .N_EUC(AE), .N_ANG(AA))
      u_add (.sel_i(op_onehot(st_i.op)), .a_i(aa), .b_i(ab), .y_o(ay));
  end else begin : g_no_tree
    assign ay = '0;
  end

  always_comb begin
    st_o = st_i;
    st_o.bnear  = near;
    st_o.bfar   = far;
    st_o.tcross = my[OP_TRIANGLE];
    if (EXTENDED) begin
      for (int i = 0; i < 4; i++) st_o.esum[i] = ay[OP_EUCLIDEAN][i];
      for (int i = 0; i < 2; i++) begin
        st_o.adot[i]  = ay[OP_ANGULAR][i];
        st_o.anorm[i] = ay[OP_ANGULAR][2 + i];
      end
    end
  end

endmodule
