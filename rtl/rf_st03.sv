// Stage 3.
//   QUADBOX   near/far per axis by the sign of dir, NaN flag, max(near_x, near_y), min(far_x, far_y)
//   TRIANGLE   6 x  X = P'[kx] - Sx*P'[kz],  Y = P'[ky] - Sy*P'[kz]
//   EUCLIDEAN  8 x  tree level 1: esq[i] + esq[i+8]
//   ANGULAR    8 x  tree level 1: adot[i] + adot[i+4], anorm[i] + anorm[i+4]
module rf_st03 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 6, NB = 0, NE = EXTENDED ? 8 : 0, NA = EXTENDED ? 8 : 0;
  localparam int unsigned P = max4(NT, NB, NE, NA);

  function automatic logic is_nan(logic [30:0] magnitude);
    return (magnitude[30:23] == 8'hFF) && (magnitude[22:0] != '0);
  endfunction

  // ---- QUADBOX: slab interval per axis ----
  fp32_t [3:0][2:0] near, far;
  logic  [3:0]      nan;
  always_comb begin
    for (int i = 0; i < 4; i++) begin
      nan[i] = 1'b0;
      for (int ax = 0; ax < 3; ax++) begin
        near[i][ax] = st_i.dir[ax][31] ? st_i.slab[i][3+ax] : st_i.slab[i][ax];
        far[i][ax]  = st_i.dir[ax][31] ? st_i.slab[i][ax]   : st_i.slab[i][3+ax];
        nan[i] = nan[i] | is_nan(near[i][ax][30:0]) | is_nan(far[i][ax][30:0]);
      end
    end
  end

  fp32_t [3:0] near_xy, far_xy;
  for (genvar i = 0; i < 4; i++) begin : g_box
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(near[i][0]), .b_i(near[i][1]), .min_o(unused_min), .max_o(near_xy[i]));
    rf_fp_minmax u_far  (.a_i(far[i][0]),  .b_i(far[i][1]),  .min_o(far_xy[i]),  .max_o(unused_max));
  end

  // ---- adder pool ----
  fp32_t [NUM_OPS-1:0][P-1:0] a, b, y;
  always_comb begin
    a = '0;
    b = '0;
    for (int v = 0; v < 3; v++) begin
      a[OP_TRIANGLE][v]     = st_i.tpx[v];
      b[OP_TRIANGLE][v]     = fp_neg(st_i.tsx[v]);
      a[OP_TRIANGLE][3 + v] = st_i.tpy[v];
      b[OP_TRIANGLE][3 + v] = fp_neg(st_i.tsy[v]);
    end
    if (EXTENDED) begin
      for (int i = 0; i < 8; i++) begin
        a[OP_EUCLIDEAN][i] = st_i.esq[i];
        b[OP_EUCLIDEAN][i] = st_i.esq[i + 8];
      end
      for (int i = 0; i < 4; i++) begin
        a[OP_ANGULAR][i]     = st_i.adot[i];
        b[OP_ANGULAR][i]     = st_i.adot[i + 4];
        a[OP_ANGULAR][4 + i] = st_i.anorm[i];
        b[OP_ANGULAR][4 + i] = st_i.anorm[i + 4];
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA))
    u_add (.sel_i(op_onehot(st_i.op)), .a_i(a), .b_i(b), .y_o(y));

  always_comb begin
    st_o = st_i;
    for (int i = 0; i < 4; i++) begin
      st_o.bnan[i]    = nan[i];
      st_o.bnear[i]   = near_xy[i];
      st_o.bfar[i]    = far_xy[i];
      st_o.bnear_z[i] = near[i][2];
      st_o.bfar_z[i]  = far[i][2];
    end
    for (int v = 0; v < 3; v++) begin
      st_o.tx[v] = y[OP_TRIANGLE][v];
      st_o.ty[v] = y[OP_TRIANGLE][3 + v];
    end
    if (EXTENDED) begin
      for (int i = 0; i < 8; i++) st_o.esum[i] = y[OP_EUCLIDEAN][i];
      for (int i = 0; i < 4; i++) begin
        st_o.adot[i]  = y[OP_ANGULAR][i];
        st_o.anorm[i] = y[OP_ANGULAR][4 + i];
      end
    end
  end

endmodule
