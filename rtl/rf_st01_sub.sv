// Stage 1 (input): convert the request into the stage struct and do the first subtractions.
//   QUADBOX   24 x  bound - origin            (slab)
//   TRIANGLE   9 x  P - origin                (tp)
//   EUCLIDEAN 16 x  a - b                     (ediff)
module rf_st01_sub import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
  input  req_t   req_i,
  output stage_t st_o
);
  localparam int unsigned NT = 9, NB = 24, NE = EXTENDED ? EUC_LANES : 0, NA = 0;
  localparam int unsigned P = max4(NT, NB, NE, NA);

  fp32_t [NUM_OPS-1:0][P-1:0] a, b, y;

  always_comb begin
    a = '0;
    b = '0;
    for (int i = 0; i < 4; i++) begin
      for (int j = 0; j < 6; j++) begin
        a[OP_QUADBOX][6*i+j] = req_i.box[i][j];
        b[OP_QUADBOX][6*i+j] = fp_neg(req_i.origin[j % 3]);
      end
    end
    for (int v = 0; v < 3; v++) begin
      for (int ax = 0; ax < 3; ax++) begin
        a[OP_TRIANGLE][3*v+ax] = req_i.triangle[v][ax];
        b[OP_TRIANGLE][3*v+ax] = fp_neg(req_i.origin[ax]);
      end
    end
    if (EXTENDED) begin
      for (int l = 0; l < int'(EUC_LANES); l++) begin
        a[OP_EUCLIDEAN][l] = req_i.vec_a[l];
        b[OP_EUCLIDEAN][l] = fp_neg(req_i.vec_b[l]);
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA))
    u_add (.sel_i(op_onehot(req_i.opcode)), .a_i(a), .b_i(b), .y_o(y));

  always_comb begin
    st_o        = '0;
    st_o.op     = req_i.opcode;
    st_o.tag    = req_i.tag;
    st_o.dir    = req_i.dir;
    st_o.inv    = req_i.inv;
    st_o.extent = req_i.extent;
    st_o.kx     = req_i.kx;
    st_o.ky     = req_i.ky;
    st_o.kz     = req_i.kz;
    st_o.shear  = req_i.shear;
    for (int i = 0; i < 4; i++) begin
      for (int j = 0; j < 6; j++) st_o.slab[i][j] = y[OP_QUADBOX][6*i+j];
    end
    for (int v = 0; v < 3; v++) begin
      for (int ax = 0; ax < 3; ax++) st_o.tp[v][ax] = y[OP_TRIANGLE][3*v+ax];
    end
    if (EXTENDED) begin
      st_o.last = req_i.reset_accumulator;
      st_o.mask = req_i.vec_mask;
      for (int l = 0; l < int'(EUC_LANES); l++) st_o.ediff[l] = y[OP_EUCLIDEAN][l];
      for (int l = 0; l < int'(ANG_LANES); l++) begin
        st_o.va[l] = req_i.vec_a[l];
        st_o.vb[l] = req_i.vec_b[l];
      end
    end
  end

endmodule
