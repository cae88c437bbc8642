// Stage 6.
//   QUADBOX   hit = no NaN and tmin < tmax; tmin out = hit ? tmin : +inf; indices 0..3
//   TRIANGLE   3 x  U*Az, V*Bz, W*Cz (multipliers);  1 x  U + V (adder)
//   EUCLIDEAN  1 x  tree level 4 (last): esum[0] + esum[1]
module rf_st06 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned MT = 3;
  localparam int unsigned AT = 1, AE = EXTENDED ? 1 : 0;
  localparam int unsigned PA = max4(AT, 0, AE, 0);

  // ---- QUADBOX ----
  logic [3:0] lt;
  for (genvar i = 0; i < 4; i++) begin : g_box
    logic unused_le, unused_eq, unused_unord;
    rf_fp_cmp u_cmp (.a_i(st_i.bnear[i]), .b_i(st_i.bfar[i]), .lt_o(lt[i]), .le_o(unused_le),
                     .eq_o(unused_eq), .unord_o(unused_unord));
  end

  // ---- multiplier pool ----
  fp32_t [NUM_OPS-1:0][MT-1:0] ma, mb, my;
  always_comb begin
    ma = '0;
    mb = '0;
    ma[OP_TRIANGLE][0] = st_i.tu;  mb[OP_TRIANGLE][0] = st_i.tz[0];   // U*Az
    ma[OP_TRIANGLE][1] = st_i.tv;  mb[OP_TRIANGLE][1] = st_i.tz[1];   // V*Bz
    ma[OP_TRIANGLE][2] = st_i.tw;  mb[OP_TRIANGLE][2] = st_i.tz[2];   // W*Cz
  end
  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(MT), .N_BOX(0), .N_EUC(0), .N_ANG(0))
    u_mul (.sel_i(op_onehot(st_i.op)), .a_i(ma), .b_i(mb), .y_o(my));

  // ---- adder pool ----
  fp32_t [NUM_OPS-1:0][PA-1:0] aa, ab, ay;
  always_comb begin
    aa = '0;
    ab = '0;
    aa[OP_TRIANGLE][0] = st_i.tu;
    ab[OP_TRIANGLE][0] = st_i.tv;
    if (EXTENDED) begin
      aa[OP_EUCLIDEAN][0] = st_i.esum[0];
      ab[OP_EUCLIDEAN][0] = st_i.esum[1];
    end
  end
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(AT), .N_BOX(0), .N_EUC(AE), .N_ANG(0))
    u_add (.sel_i(op_onehot(st_i.op)), .a_i(aa), .b_i(ab), .y_o(ay));

  always_comb begin
    st_o = st_i;
    for (int i = 0; i < 4; i++) begin
      st_o.bhit[i]  = ~st_i.bnan[i] & lt[i];
      st_o.btmin[i] = st_o.bhit[i] ? st_i.bnear[i] : FP_POS_INF;
      st_o.bidx[i]  = 2'(i);
    end
    st_o.tuvw_z = my[OP_TRIANGLE];
    st_o.tuv    = ay[OP_TRIANGLE][0];
    if (EXTENDED) st_o.esum[0] = ay[OP_EUCLIDEAN][0];
  end

endmodule
