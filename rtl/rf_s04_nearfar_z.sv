// Stage 4, nearfar_z: the slab interval with the z axis; the 2-D cross products.
//   QUADBOX   max(.., near_z), min(.., far_z)
//   TRIANGLE   6 x  Cx*By, Cy*Bx, Ax*Cy, Ay*Cx, Bx*Ay, By*Ax   (multipliers)
//   EUCLIDEAN  4 x  tree level 2: e[i] + e[i+4]                  (adders)
//   ANGULAR    4 x  tree level 2 on dot and norm                  (adders)
// FUSED: no cross products (S5 computes U, V, W from X and Y with one rounding each).
module rf_s04_nearfar_z import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit FUSED = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned MT = FUSED ? 0 : 6;
  localparam int unsigned AE = EXTENDED ? 4 : 0, AA = EXTENDED ? 4 : 0;

  box_range_t v_box;
  tri_edge_t  v_tri;
  euc_t       v_euc;
  ang_t       v_ang;
  assign v_box = st_i.pl.box_range;
  assign v_tri = st_i.pl.tri_edge;
  assign v_euc = st_i.pl.euc;
  assign v_ang = st_i.pl.ang;

  // ---- QUADBOX ----
  fp32_t [3:0] near, far;
  for (genvar i = 0; i < 4; i++) begin : g_box
    fp32_t unused_min, unused_max;
    rf_fp_minmax u_near (.a_i(v_box.tnear[i]), .b_i(v_box.tnear_z[i]),
                         .min_o(unused_min), .max_o(near[i]));
    rf_fp_minmax u_far  (.a_i(v_box.tfar[i]), .b_i(v_box.tfar_z[i]),
                         .min_o(far[i]), .max_o(unused_max));
  end

  // ---- multiplier pool: the 2-D xprod products (vertex index 0, 1, 2 = A, B, C) ----
  localparam fu_count_t MUL = fu_count(.n_tri(MT));
  fp32_t [NUM_OPS-1:0][fu_width(MUL)-1:0] mul_a, mul_b, mul_y;
  fp32_t [5:0] xprod;
  if (MT > 0) begin : g_xprod
    always_comb begin
      mul_a = '0;
      mul_b = '0;
      mul_a[OP_TRIANGLE][0] = v_tri.x[2];  mul_b[OP_TRIANGLE][0] = v_tri.y[1];   // Cx*By
      mul_a[OP_TRIANGLE][1] = v_tri.y[2];  mul_b[OP_TRIANGLE][1] = v_tri.x[1];   // Cy*Bx
      mul_a[OP_TRIANGLE][2] = v_tri.x[0];  mul_b[OP_TRIANGLE][2] = v_tri.y[2];   // Ax*Cy
      mul_a[OP_TRIANGLE][3] = v_tri.y[0];  mul_b[OP_TRIANGLE][3] = v_tri.x[2];   // Ay*Cx
      mul_a[OP_TRIANGLE][4] = v_tri.x[1];  mul_b[OP_TRIANGLE][4] = v_tri.y[0];   // Bx*Ay
      mul_a[OP_TRIANGLE][5] = v_tri.y[1];  mul_b[OP_TRIANGLE][5] = v_tri.x[0];   // By*Ax
    end
    assign xprod = mul_y[OP_TRIANGLE][5:0];
  end else begin : g_no_xprod
    assign mul_a = '0;
    assign mul_b = '0;
    assign xprod = '0;
  end
  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N(MUL))
    u_mul (.op_i(st_i.op), .a_i(mul_a), .b_i(mul_b), .y_o(mul_y));

  // ---- adder pool: reduction trees (extended only) ----
  localparam fu_count_t ADD = fu_count(.n_euc(AE), .n_ang(AA));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    if (EXTENDED) begin
      for (int i = 0; i < 4; i++) begin
        add_a[OP_EUCLIDEAN][i] = v_euc.e[i];
        add_b[OP_EUCLIDEAN][i] = v_euc.e[i + 4];
      end
      for (int i = 0; i < 2; i++) begin
        add_a[OP_ANGULAR][i]     = v_ang.dot[i];
        add_b[OP_ANGULAR][i]     = v_ang.dot[i + 2];
        add_a[OP_ANGULAR][2 + i] = v_ang.norm[i];
        add_b[OP_ANGULAR][2 + i] = v_ang.norm[i + 2];
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
        st_o.pl.box_range.tnear = near;
        st_o.pl.box_range.tfar  = far;
      end
      OP_TRIANGLE: begin
        if (!FUSED) st_o.pl.tri_edge.xprod = xprod;
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int i = 0; i < 4; i++) st_o.pl.euc.e[i] = add_y[OP_EUCLIDEAN][i];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int i = 0; i < 2; i++) begin
            st_o.pl.ang.dot[i]  = add_y[OP_ANGULAR][i];
            st_o.pl.ang.norm[i] = add_y[OP_ANGULAR][2 + i];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
