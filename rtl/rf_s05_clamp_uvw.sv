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

  // ---- adder pool: operands per operation ----
  localparam fu_count_t ADD = fu_count(.n_tri(NT), .n_euc(NE), .n_ang(NA), .n_xfm(NX));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    for (int k = 0; k < int'(NT); k++) begin
      add_a[OP_TRIANGLE][k] = v_tri.xprod[2*k];
      add_b[OP_TRIANGLE][k] = fp_neg(v_tri.xprod[2*k+1]);
    end
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        add_a[OP_TRANSFORM][r] = v_xfm.pd[r][0];
        add_b[OP_TRANSFORM][r] = v_xfm.pd[r][2];
      end
    end
    if (EXTENDED) begin
      for (int i = 0; i < 2; i++) begin
        add_a[OP_EUCLIDEAN][i] = v_euc.e[i];
        add_b[OP_EUCLIDEAN][i] = v_euc.e[i + 2];
      end
      add_a[OP_ANGULAR][0] = v_ang.dot[0];
      add_b[OP_ANGULAR][0] = v_ang.dot[1];
      add_a[OP_ANGULAR][1] = v_ang.norm[0];
      add_b[OP_ANGULAR][1] = v_ang.norm[1];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));

  // ---- TRIANGLE: U, V, W (FUSED: one rounding each; else from the adder pool) ----
  fp32_t [2:0] uvw;
  if (FUSED) begin : g_fused
    logic en;                               // operand isolation: zeros unless a TRIANGLE
    fp32_t [2:0] x, y;
    assign en = st_i.op == OP_TRIANGLE;
    assign x  = en ? v_tri.x : '0;
    assign y  = en ? v_tri.y : '0;
    rf_fp_dot2 u_u (.a_i(x[2]), .b_i(y[1]), .c_i(fp_neg(y[2])), .d_i(x[1]), .y_o(uvw[0]));
    rf_fp_dot2 u_v (.a_i(x[0]), .b_i(y[2]), .c_i(fp_neg(y[0])), .d_i(x[2]), .y_o(uvw[1]));
    rf_fp_dot2 u_w (.a_i(x[1]), .b_i(y[0]), .c_i(fp_neg(y[1])), .d_i(x[0]), .y_o(uvw[2]));
  end else begin : g_plain
    assign uvw = add_y[OP_TRIANGLE][2:0];
  end

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
          st_o.pl.euc.e[0] = add_y[OP_EUCLIDEAN][0];
          st_o.pl.euc.e[1] = add_y[OP_EUCLIDEAN][1];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          st_o.pl.ang.dot[0]  = add_y[OP_ANGULAR][0];
          st_o.pl.ang.norm[0] = add_y[OP_ANGULAR][1];
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) st_o.pl.xfm.pd[r][0] = add_y[OP_TRANSFORM][r];
        end
      end
      default: ;
    endcase
  end

endmodule
