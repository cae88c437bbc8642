// Stage 3, nearfar_xy: the slab interval of the x and y axes; the sheared 2-D vertices.
//   QUADBOX   near/far by the sign of dir, NaN flag, max(near_x, near_y), min(far_x, far_y)
//   TRIANGLE   6 x  X = P'[kx] - Sx*P'[kz],  Y = P'[ky] - Sy*P'[kz]
//   EUCLIDEAN  8 x  tree level 1: e[i] + e[i+8]
//   ANGULAR    8 x  tree level 1: dot[i] + dot[i+4], norm[i] + norm[i+4]
//   TRANSFORM  6 x  m[r][0]*o[0] + m[r][1]*o[1], m[r][0]*d[0] + m[r][1]*d[1]
module rf_s03_nearfar_xy import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 6, NE = EXTENDED ? 8 : 0, NA = EXTENDED ? 8 : 0;
  localparam int unsigned NX = TRANSFORM ? 6 : 0;

  function automatic logic is_nan(logic [30:0] magnitude);
    return magnitude > 31'h7F80_0000;
  endfunction

  box_slab_t  v_box;
  tri_shear_t v_tri;
  euc_t       v_euc;
  ang_t       v_ang;
  xfm_t       v_xfm;
  assign v_xfm = st_i.pl.xfm;
  assign v_box = st_i.pl.box_slab;
  assign v_tri = st_i.pl.tri_shear;
  assign v_euc = st_i.pl.euc;
  assign v_ang = st_i.pl.ang;

  // ---- QUADBOX: slab interval per axis (near/far chosen by the sign of dir), NaN flag ----
  fp32_t [3:0][2:0] near, far;
  logic  [3:0]      nan;
  fp32_t [3:0]      near_xy, far_xy;
  for (genvar i = 0; i < 4; i++) begin : g_box
    for (genvar ax = 0; ax < 3; ax++) begin : g_axis
      assign near[i][ax] = v_box.dir_neg[ax] ? v_box.slab[i][3+ax] : v_box.slab[i][ax];
      assign far[i][ax]  = v_box.dir_neg[ax] ? v_box.slab[i][ax]   : v_box.slab[i][3+ax];
    end
    assign nan[i] = is_nan(v_box.slab[i][0][30:0]) | is_nan(v_box.slab[i][1][30:0])
                  | is_nan(v_box.slab[i][2][30:0]) | is_nan(v_box.slab[i][3][30:0])
                  | is_nan(v_box.slab[i][4][30:0]) | is_nan(v_box.slab[i][5][30:0]);
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(near[i][0]), .b_i(near[i][1]),
                         .min_o(unused_min), .max_o(near_xy[i]));
    rf_fp_minmax u_far  (.a_i(far[i][0]), .b_i(far[i][1]),
                         .min_o(far_xy[i]), .max_o(unused_max));
  end

  // ---- adder pool: operands per operation ----
  fp32_t [NT-1:0] tri_a, tri_b, tri_y;
  fp32_t [(NE > 0 ? NE : 1)-1:0] euc_a, euc_b, euc_y;
  fp32_t [(NA > 0 ? NA : 1)-1:0] ang_a, ang_b, ang_y;
  fp32_t [(NX > 0 ? NX : 1)-1:0] xfm_a, xfm_b, xfm_y;
  fp32_t unused_box_y;
  always_comb begin
    for (int v = 0; v < 3; v++) begin
      tri_a[v]     = v_tri.px[v];
      tri_b[v]     = fp_neg(v_tri.sx[v]);
      tri_a[3 + v] = v_tri.py[v];
      tri_b[3 + v] = fp_neg(v_tri.sy[v]);
    end
    euc_a = '0;
    euc_b = '0;
    ang_a = '0;
    ang_b = '0;
    xfm_a = '0;
    xfm_b = '0;
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        xfm_a[r]     = v_xfm.po[r][0];
        xfm_b[r]     = v_xfm.po[r][1];
        xfm_a[3 + r] = v_xfm.pd[r][0];
        xfm_b[3 + r] = v_xfm.pd[r][1];
      end
    end
    if (EXTENDED) begin
      for (int i = 0; i < 8; i++) begin
        euc_a[i] = v_euc.e[i];
        euc_b[i] = v_euc.e[i + 8];
      end
      for (int i = 0; i < 4; i++) begin
        ang_a[i]     = v_ang.dot[i];
        ang_b[i]     = v_ang.dot[i + 4];
        ang_a[4 + i] = v_ang.norm[i];
        ang_b[4 + i] = v_ang.norm[i + 4];
      end
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
        st_o.pl.box_range.nan    = nan;
        st_o.pl.box_range.extent = v_box.extent;
        for (int i = 0; i < 4; i++) begin
          st_o.pl.box_range.tnear[i]   = near_xy[i];
          st_o.pl.box_range.tfar[i]    = far_xy[i];
          st_o.pl.box_range.tnear_z[i] = near[i][2];
          st_o.pl.box_range.tfar_z[i]  = far[i][2];
        end
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_edge.no_cull = v_tri.no_cull;
        st_o.pl.tri_edge.z       = v_tri.z;
        for (int v = 0; v < 3; v++) begin
          st_o.pl.tri_edge.x[v] = tri_y[v];
          st_o.pl.tri_edge.y[v] = tri_y[3 + v];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int i = 0; i < 8; i++) st_o.pl.euc.e[i] = euc_y[i];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int i = 0; i < 4; i++) begin
            st_o.pl.ang.dot[i]  = ang_y[i];
            st_o.pl.ang.norm[i] = ang_y[4 + i];
          end
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) begin
            st_o.pl.xfm.po[r][0] = xfm_y[r];
            st_o.pl.xfm.pd[r][0] = xfm_y[3 + r];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
