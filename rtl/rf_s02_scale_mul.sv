// Stage 2, scale_mul: the first multiplications (slab scaling, shear, lane products).
//   QUADBOX   24 x  (bound - origin) * inv[axis]
//   TRIANGLE   9 x  Sx*P'[kz], Sy*P'[kz], Sz*P'[kz] per vertex (and selects P'[kx], P'[ky])
//   EUCLIDEAN 16 x  (a - b)^2               masked lanes +0
//   ANGULAR   16 x  a*b and b*b over 8 lanes, masked lanes +0
//   TRANSFORM 18 x  m[r][c]*o[c], m[r][c]*d[c]   (r, c < 3; m[r][3] passes as t[r])
// FUSED: the QUADBOX's slab values come from S1 (one rounding) and pass through.
module rf_s02_scale_mul import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0,
  parameter bit FUSED = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 9, NB = FUSED ? 0 : 24;
  localparam int unsigned NE = EXTENDED ? EUC_LANES : 0, NA = EXTENDED ? 2 * ANG_LANES : 0;
  localparam int unsigned NX = TRANSFORM ? 18 : 0;

  // Component k (0, 1, 2 = x, y, z) of a 3-vector.
  function automatic fp32_t pick(fp32_t [2:0] v, logic [1:0] k);
    return (k == 2'd0) ? v[0] : (k == 2'd1) ? v[1] : v[2];
  endfunction

  box_slab_t  v_box;
  tri_vert_t  v_tri;
  euc_t       v_euc;
  ang_t       v_ang;
  xfm_in_t    v_xfm;
  assign v_xfm = st_i.pl.xfm_in;
  assign v_box = st_i.pl.box_slab;
  assign v_tri = st_i.pl.tri_vert;
  assign v_euc = st_i.pl.euc;
  assign v_ang = st_i.pl.ang;

  // ---- multiplier pool: operands per operation ----
  localparam fu_count_t MUL = fu_count(.n_tri(NT), .n_box(NB), .n_euc(NE), .n_ang(NA),
                                       .n_xfm(NX));
  fp32_t [NUM_OPS-1:0][fu_width(MUL)-1:0] mul_a, mul_b, mul_y;

  always_comb begin
    mul_a = '0;
    mul_b = '0;
    for (int k = 0; k < int'(NB); k++) begin
      mul_a[OP_QUADBOX][k] = v_box.slab[k / 6][k % 6];
      mul_b[OP_QUADBOX][k] = v_box.inv[(k % 6) % 3];
    end
    for (int v = 0; v < 3; v++) begin
      for (int s = 0; s < 3; s++) begin
        mul_a[OP_TRIANGLE][3*v+s] = v_tri.shear[s];
        mul_b[OP_TRIANGLE][3*v+s] = pick(v_tri.p[v], v_tri.kz);
      end
    end
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        for (int c = 0; c < 3; c++) begin
          mul_a[OP_TRANSFORM][3*r+c]     = v_xfm.m[r][c];
          mul_b[OP_TRANSFORM][3*r+c]     = v_xfm.origin[c];
          mul_a[OP_TRANSFORM][9 + 3*r+c] = v_xfm.m[r][c];
          mul_b[OP_TRANSFORM][9 + 3*r+c] = v_xfm.dir[c];
        end
      end
    end
    if (EXTENDED) begin
      for (int l = 0; l < int'(EUC_LANES); l++) begin
        mul_a[OP_EUCLIDEAN][l] = v_euc.e[l];
        mul_b[OP_EUCLIDEAN][l] = v_euc.e[l];
      end
      for (int l = 0; l < int'(ANG_LANES); l++) begin
        mul_a[OP_ANGULAR][l]             = v_ang.dot[l];
        mul_b[OP_ANGULAR][l]             = v_ang.norm[l];
        mul_a[OP_ANGULAR][ANG_LANES + l] = v_ang.norm[l];
        mul_b[OP_ANGULAR][ANG_LANES + l] = v_ang.norm[l];
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N(MUL))
    u_mul (.op_i(st_i.op), .a_i(mul_a), .b_i(mul_b), .y_o(mul_y));

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        for (int k = 0; k < int'(NB); k++) begin
          st_o.pl.box_slab.slab[k / 6][k % 6] = mul_y[OP_QUADBOX][k];
        end
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_shear.no_cull = v_tri.no_cull;
        for (int v = 0; v < 3; v++) begin
          st_o.pl.tri_shear.px[v] = pick(v_tri.p[v], v_tri.kx);
          st_o.pl.tri_shear.py[v] = pick(v_tri.p[v], v_tri.ky);
          st_o.pl.tri_shear.sx[v] = mul_y[OP_TRIANGLE][3*v+0];
          st_o.pl.tri_shear.sy[v] = mul_y[OP_TRIANGLE][3*v+1];
          st_o.pl.tri_shear.z[v]  = mul_y[OP_TRIANGLE][3*v+2];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int l = 0; l < int'(EUC_LANES); l++) begin
            st_o.pl.euc.e[l] = v_euc.mask[l] ? mul_y[OP_EUCLIDEAN][l] : FP_POS_ZERO;
          end
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int l = 0; l < int'(ANG_LANES); l++) begin
            st_o.pl.ang.dot[l]  = v_ang.mask[l] ? mul_y[OP_ANGULAR][l]             : FP_POS_ZERO;
            st_o.pl.ang.norm[l] = v_ang.mask[l] ? mul_y[OP_ANGULAR][ANG_LANES + l] : FP_POS_ZERO;
          end
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) begin
            for (int c = 0; c < 3; c++) begin
              st_o.pl.xfm.po[r][c] = mul_y[OP_TRANSFORM][3*r+c];
              st_o.pl.xfm.pd[r][c] = mul_y[OP_TRANSFORM][9 + 3*r+c];
            end
            st_o.pl.xfm.t[r] = v_xfm.m[r][3];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
