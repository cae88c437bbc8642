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
  fp32_t [NT-1:0] tri_a, tri_b, tri_y;
  fp32_t [(NB > 0 ? NB : 1)-1:0] box_a, box_b, box_y;
  fp32_t [(NE > 0 ? NE : 1)-1:0] euc_a, euc_b, euc_y;
  fp32_t [(NA > 0 ? NA : 1)-1:0] ang_a, ang_b, ang_y;
  fp32_t [(NX > 0 ? NX : 1)-1:0] xfm_a, xfm_b, xfm_y;

  always_comb begin
    box_a = '0;
    box_b = '0;
    for (int k = 0; k < int'(NB); k++) begin
      box_a[k] = v_box.slab[k / 6][k % 6];
      box_b[k] = v_box.inv[(k % 6) % 3];
    end
    for (int v = 0; v < 3; v++) begin
      for (int s = 0; s < 3; s++) begin
        tri_a[3*v+s] = v_tri.shear[s];
        tri_b[3*v+s] = pick(v_tri.p[v], v_tri.kz);
      end
    end
    euc_a = '0;
    euc_b = '0;
    ang_a = '0;
    ang_b = '0;
    xfm_a = '0;
    xfm_b = '0;
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        for (int c = 0; c < 3; c++) begin
          xfm_a[3*r+c]     = v_xfm.m[r][c];
          xfm_b[3*r+c]     = v_xfm.origin[c];
          xfm_a[9 + 3*r+c] = v_xfm.m[r][c];
          xfm_b[9 + 3*r+c] = v_xfm.dir[c];
        end
      end
    end
    if (EXTENDED) begin
      for (int l = 0; l < int'(EUC_LANES); l++) begin
        euc_a[l] = v_euc.e[l];
        euc_b[l] = v_euc.e[l];
      end
      for (int l = 0; l < int'(ANG_LANES); l++) begin
        ang_a[l]             = v_ang.dot[l];
        ang_b[l]             = v_ang.norm[l];
        ang_a[ANG_LANES + l] = v_ang.norm[l];
        ang_b[ANG_LANES + l] = v_ang.norm[l];
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(NA),
               .N_XFM(NX))
    u_mul (.op_i(st_i.op),
           .tri_a_i(tri_a), .tri_b_i(tri_b), .tri_y_o(tri_y),
           .box_a_i(box_a), .box_b_i(box_b), .box_y_o(box_y),
           .euc_a_i(euc_a), .euc_b_i(euc_b), .euc_y_o(euc_y),
           .ang_a_i(ang_a), .ang_b_i(ang_b), .ang_y_o(ang_y),
           .xfm_a_i(xfm_a), .xfm_b_i(xfm_b), .xfm_y_o(xfm_y));

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        for (int k = 0; k < int'(NB); k++) st_o.pl.box_slab.slab[k / 6][k % 6] = box_y[k];
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_shear.no_cull = v_tri.no_cull;
        for (int v = 0; v < 3; v++) begin
          st_o.pl.tri_shear.px[v] = pick(v_tri.p[v], v_tri.kx);
          st_o.pl.tri_shear.py[v] = pick(v_tri.p[v], v_tri.ky);
          st_o.pl.tri_shear.sx[v] = tri_y[3*v+0];
          st_o.pl.tri_shear.sy[v] = tri_y[3*v+1];
          st_o.pl.tri_shear.z[v]  = tri_y[3*v+2];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int l = 0; l < int'(EUC_LANES); l++) begin
            st_o.pl.euc.e[l] = v_euc.mask[l] ? euc_y[l] : FP_POS_ZERO;
          end
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int l = 0; l < int'(ANG_LANES); l++) begin
            st_o.pl.ang.dot[l]  = v_ang.mask[l] ? ang_y[l]             : FP_POS_ZERO;
            st_o.pl.ang.norm[l] = v_ang.mask[l] ? ang_y[ANG_LANES + l] : FP_POS_ZERO;
          end
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) begin
            for (int c = 0; c < 3; c++) begin
              st_o.pl.xfm.po[r][c] = xfm_y[3*r+c];
              st_o.pl.xfm.pd[r][c] = xfm_y[9 + 3*r+c];
            end
            st_o.pl.xfm.t[r] = v_xfm.m[r][3];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
