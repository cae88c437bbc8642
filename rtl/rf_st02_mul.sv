// Stage 2: the first multiplications.
//   QUADBOX   24 x  (bound - origin) * inv[axis]
//   TRIANGLE   9 x  Sx*P'[kz], Sy*P'[kz], Sz*P'[kz] per vertex (and selects P'[kx], P'[ky])
//   EUCLIDEAN 16 x  (a - b)^2               masked lanes +0
//   ANGULAR   16 x  a*b and b*b over 8 lanes, masked lanes +0
module rf_st02_mul import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 9, NB = 24;
  localparam int unsigned NE = EXTENDED ? EUC_LANES : 0, NA = EXTENDED ? 2 * ANG_LANES : 0;
  localparam int unsigned P = max4(NT, NB, NE, NA);

  // Component k (0, 1, 2 = x, y, z) of a 3-vector.
  function automatic fp32_t pick(fp32_t [2:0] v, logic [1:0] k);
    return (k == 2'd0) ? v[0] : (k == 2'd1) ? v[1] : v[2];
  endfunction

  fp32_t [NUM_OPS-1:0][P-1:0] a, b, y;

  always_comb begin
    a = '0;
    b = '0;
    for (int i = 0; i < 4; i++) begin
      for (int j = 0; j < 6; j++) begin
        a[OP_QUADBOX][6*i+j] = st_i.slab[i][j];
        b[OP_QUADBOX][6*i+j] = st_i.inv[j % 3];
      end
    end
    for (int v = 0; v < 3; v++) begin
      for (int s = 0; s < 3; s++) begin
        a[OP_TRIANGLE][3*v+s] = st_i.shear[s];
        b[OP_TRIANGLE][3*v+s] = pick(st_i.tp[v], st_i.kz);
      end
    end
    if (EXTENDED) begin
      for (int l = 0; l < int'(EUC_LANES); l++) begin
        a[OP_EUCLIDEAN][l] = st_i.ediff[l];
        b[OP_EUCLIDEAN][l] = st_i.ediff[l];
      end
      for (int l = 0; l < int'(ANG_LANES); l++) begin
        a[OP_ANGULAR][l]             = st_i.va[l];
        b[OP_ANGULAR][l]             = st_i.vb[l];
        a[OP_ANGULAR][ANG_LANES + l] = st_i.vb[l];
        b[OP_ANGULAR][ANG_LANES + l] = st_i.vb[l];
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA))
    u_mul (.sel_i(op_onehot(st_i.op)), .a_i(a), .b_i(b), .y_o(y));

  always_comb begin
    st_o = st_i;
    for (int i = 0; i < 4; i++) begin
      for (int j = 0; j < 6; j++) st_o.slab[i][j] = y[OP_QUADBOX][6*i+j];
    end
    for (int v = 0; v < 3; v++) begin
      st_o.tpx[v] = pick(st_i.tp[v], st_i.kx);
      st_o.tpy[v] = pick(st_i.tp[v], st_i.ky);
      st_o.tsx[v] = y[OP_TRIANGLE][3*v+0];
      st_o.tsy[v] = y[OP_TRIANGLE][3*v+1];
      st_o.tz[v]  = y[OP_TRIANGLE][3*v+2];
    end
    if (EXTENDED) begin
      for (int l = 0; l < int'(EUC_LANES); l++) begin
        st_o.esq[l] = st_i.mask[l] ? y[OP_EUCLIDEAN][l] : FP_POS_ZERO;
      end
      for (int l = 0; l < int'(ANG_LANES); l++) begin
        st_o.adot[l]  = st_i.mask[l] ? y[OP_ANGULAR][l]             : FP_POS_ZERO;
        st_o.anorm[l] = st_i.mask[l] ? y[OP_ANGULAR][ANG_LANES + l] : FP_POS_ZERO;
      end
    end
  end

endmodule
