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
  localparam fu_count_t ADD = fu_count(.n_tri(NT), .n_euc(NE), .n_ang(NA), .n_xfm(NX));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    for (int v = 0; v < 3; v++) begin
      add_a[OP_TRIANGLE][v]     = v_tri.px[v];
      add_b[OP_TRIANGLE][v]     = fp_neg(v_tri.sx[v]);
      add_a[OP_TRIANGLE][3 + v] = v_tri.py[v];
      add_b[OP_TRIANGLE][3 + v] = fp_neg(v_tri.sy[v]);
    end
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        add_a[OP_TRANSFORM][r]     = v_xfm.po[r][0];
        add_b[OP_TRANSFORM][r]     = v_xfm.po[r][1];
        add_a[OP_TRANSFORM][3 + r] = v_xfm.pd[r][0];
        add_b[OP_TRANSFORM][3 + r] = v_xfm.pd[r][1];
      end
    end
    if (EXTENDED) begin
      for (int i = 0; i < 8; i++) begin
        add_a[OP_EUCLIDEAN][i] = v_euc.e[i];
        add_b[OP_EUCLIDEAN][i] = v_euc.e[i + 8];
      end
      for (int i = 0; i < 4; i++) begin
        add_a[OP_ANGULAR][i]     = v_ang.dot[i];
        add_b[OP_ANGULAR][i]     = v_ang.dot[i + 4];
        add_a[OP_ANGULAR][4 + i] = v_ang.norm[i];
        add_b[OP_ANGULAR][4 + i] = v_ang.norm[i + 4];
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));

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
          st_o.pl.tri_edge.x[v] = add_y[OP_TRIANGLE][v];
          st_o.pl.tri_edge.y[v] = add_y[OP_TRIANGLE][3 + v];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int i = 0; i < 8; i++) st_o.pl.euc.e[i] = add_y[OP_EUCLIDEAN][i];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int i = 0; i < 4; i++) begin
            st_o.pl.ang.dot[i]  = add_y[OP_ANGULAR][i];
            st_o.pl.ang.norm[i] = add_y[OP_ANGULAR][4 + i];
          end
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) begin
            st_o.pl.xfm.po[r][0] = add_y[OP_TRANSFORM][r];
            st_o.pl.xfm.pd[r][0] = add_y[OP_TRANSFORM][3 + r];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
