// Stage 5, clamp_uvw: the interval clamped to [+0, extent]; the edge functions U, V, W.
//   QUADBOX   tmin = max(.., +0), tmax = min(.., extent)
//   TRIANGLE   3 x  U = Cx*By - Cy*Bx,  V = Ax*Cy - Ay*Cx,  W = Bx*Ay - By*Ax
//   EUCLIDEAN  2 x  tree level 3: e[i] + e[i+2]
//   ANGULAR    2 x  tree level 3 (last): dot[0] + dot[1], norm[0] + norm[1]
//   TRANSFORM  3 x  d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]
// FUSED: U, V, W from X and Y, each a product difference with one rounding (rf_fp_dot2, private).
module rf_s05_clamp_uvw import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0,
  parameter bit FUSED = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = FUSED ? 0 : 3, NE = EXTENDED ? 2 : 0, NA = EXTENDED ? 2 : 0;
  localparam int unsigned NX = TRANSFORM ? 3 : 0;

  box_range_t v_box;
  tri_edge_t  v_tri;
  euc_t       v_euc;
  ang_t       v_ang;
  xfm_t       v_xfm;
  assign v_xfm = st_i.pl.xfm;
  assign v_box = st_i.pl.box_range;
  assign v_tri = st_i.pl.tri_edge;
  assign v_euc = st_i.pl.euc;
  assign v_ang = st_i.pl.ang;

  // ---- QUADBOX ----
  fp32_t [3:0] tmin, tmax;
  for (genvar i = 0; i < 4; i++) begin : g_box
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(v_box.tnear[i]), .b_i(FP_POS_ZERO),
                         .min_o(unused_min), .max_o(tmin[i]));
    rf_fp_minmax u_far  (.a_i(v_box.tfar[i]), .b_i(v_box.extent),
                         .min_o(tmax[i]), .max_o(unused_max));
  end

  // ---- TRIANGLE: U, V, W (FUSED: one rounding each; else from the adder pool below) ----
  fp32_t [(NT > 0 ? NT : 1)-1:0] tri_a, tri_b, tri_y;
  fp32_t [2:0] uvw;
  if (FUSED) begin : g_fused
    logic en;                               // operand isolation: zeros unless a TRIANGLE
    fp32_t [2:0] x, y;
    fp32_t unused_pool_y;                   // the pool has no TRIANGLE units
    assign unused_pool_y = tri_y[0];
    assign en = st_i.op == OP_TRIANGLE;
    assign x  = en ? v_tri.x : '0;
    assign y  = en ? v_tri.y : '0;
    rf_fp_dot2 u_u (.a_i(x[2]), .b_i(y[1]), .c_i(fp_neg(y[2])), .d_i(x[1]), .y_o(uvw[0]));
    rf_fp_dot2 u_v (.a_i(x[0]), .b_i(y[2]), .c_i(fp_neg(y[0])), .d_i(x[2]), .y_o(uvw[1]));
    rf_fp_dot2 u_w (.a_i(x[1]), .b_i(y[0]), .c_i(fp_neg(y[1])), .d_i(x[0]), .y_o(uvw[2]));
  end else begin : g_plain
    assign uvw = tri_y;
  end

  // ---- adder pool: operands per operation ----
  fp32_t [(NE > 0 ? NE : 1)-1:0] euc_a, euc_b, euc_y;
  fp32_t [(NA > 0 ? NA : 1)-1:0] ang_a, ang_b, ang_y;
  fp32_t [(NX > 0 ? NX : 1)-1:0] xfm_a, xfm_b, xfm_y;
  fp32_t unused_box_y;
  always_comb begin
    tri_a = '0;
    tri_b = '0;
    for (int k = 0; k < int'(NT); k++) begin
      tri_a[k] = v_tri.xprod[2*k];
      tri_b[k] = fp_neg(v_tri.xprod[2*k+1]);
    end
    euc_a = '0;
    euc_b = '0;
    ang_a = '0;
    ang_b = '0;
    xfm_a = '0;
    xfm_b = '0;
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        xfm_a[r] = v_xfm.pd[r][0];
        xfm_b[r] = v_xfm.pd[r][2];
      end
    end
    if (EXTENDED) begin
      for (int i = 0; i < 2; i++) begin
        euc_a[i] = v_euc.e[i];
        euc_b[i] = v_euc.e[i + 2];
      end
      ang_a[0] = v_ang.dot[0];
      ang_b[0] = v_ang.dot[1];
      ang_a[1] = v_ang.norm[0];
      ang_b[1] = v_ang.norm[1];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(0), .N_EUC(NE), .N_ANG(NA),
               .N_XFM(NX))
    u_add (.op_i(st_i.op),
           .tri_a_i(tri_a), .tri_b_i(tri_b), .tri_y_o(tri_y),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_y),
           .euc_a_i(euc_a), .euc_b_i(euc_b), .euc_y_o(euc_y),
           .ang_a_i(ang_a), .ang_b_i(ang_b), .ang_y_o(ang_y),
           .xfm_a_i(xfm_a), .xfm_b_i(xfm_b), .xfm_y_o(xfm_y));

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        st_o.pl.box_range.tnear = tmin;
        st_o.pl.box_range.tfar  = tmax;
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_edge.u = uvw[0];
        st_o.pl.tri_edge.v = uvw[1];
        st_o.pl.tri_edge.w = uvw[2];
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          st_o.pl.euc.e[0] = euc_y[0];
          st_o.pl.euc.e[1] = euc_y[1];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          st_o.pl.ang.dot[0]  = ang_y[0];
          st_o.pl.ang.norm[0] = ang_y[1];
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) st_o.pl.xfm.pd[r][0] = xfm_y[r];
        end
      end
      default: ;
    endcase
  end

endmodule
