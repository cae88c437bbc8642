// Stage 8.
//   QUADBOX   sorting network layer 1
//   TRIANGLE   1 x  t_num = (U*Az + V*Bz) + W*Cz
module rf_st08 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 1;

  fp32_t [3:0]      tmin;
  logic  [3:0][1:0] idx;
  logic  [3:0]      hit;
  rf_sort4 #(.LAYER(1)) u_sort (.tmin_i(st_i.btmin), .idx_i(st_i.bidx), .hit_i(st_i.bhit),
                                .tmin_o(tmin), .idx_o(idx), .hit_o(hit));

  fp32_t [NUM_OPS-1:0][NT-1:0] a, b, y;
  always_comb begin
    a = '0;
    b = '0;
    a[OP_TRIANGLE][0] = st_i.tnum_part;
    b[OP_TRIANGLE][0] = st_i.tuvw_z[2];
  end
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(0), .N_EUC(0), .N_ANG(0))
    u_add (.sel_i(op_onehot(st_i.op)), .a_i(a), .b_i(b), .y_o(y));

  always_comb begin
    st_o       = st_i;
    st_o.btmin = tmin;
    st_o.bidx  = idx;
    st_o.bhit  = hit;
    st_o.t_num = y[OP_TRIANGLE][0];
  end

  logic unused_extended;
  assign unused_extended = EXTENDED;

endmodule
