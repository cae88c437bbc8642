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
  fp32_t [5:0] tri_my;
  if (MT > 0) begin : g_xprod
    fp32_t [MT-1:0] tri_ma, tri_mb;
    fp32_t          unused_box_my, unused_euc_my, unused_ang_my, unused_xfm_my;
    always_comb begin
      tri_ma[0] = v_tri.x[2];  tri_mb[0] = v_tri.y[1];   // Cx*By
      tri_ma[1] = v_tri.y[2];  tri_mb[1] = v_tri.x[1];   // Cy*Bx
      tri_ma[2] = v_tri.x[0];  tri_mb[2] = v_tri.y[2];   // Ax*Cy
      tri_ma[3] = v_tri.y[0];  tri_mb[3] = v_tri.x[2];   // Ay*Cx
      tri_ma[4] = v_tri.x[1];  tri_mb[4] = v_tri.y[0];   // Bx*Ay
      tri_ma[5] = v_tri.y[1];  tri_mb[5] = v_tri.x[0];   // By*Ax
    end
    rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(MT), .N_BOX(0), .N_EUC(0), .N_ANG(0))
      u_mul (.op_i(st_i.op),
             .tri_a_i(tri_ma), .tri_b_i(tri_mb), .tri_y_o(tri_my),
             .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_my),
             .euc_a_i(FP_POS_ZERO), .euc_b_i(FP_POS_ZERO), .euc_y_o(unused_euc_my),
             .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_my),
             .xfm_a_i(FP_POS_ZERO), .xfm_b_i(FP_POS_ZERO), .xfm_y_o(unused_xfm_my));
  end else begin : g_no_xprod
    assign tri_my = '0;
  end

  // ---- adder pool: reduction trees (extended only) ----
  fp32_t [(AE > 0 ? AE : 1)-1:0] euc_ay;
  fp32_t [(AA > 0 ? AA : 1)-1:0] ang_ay;
  if (EXTENDED) begin : g_tree
    fp32_t [AE-1:0] euc_aa, euc_ab;
    fp32_t [AA-1:0] ang_aa, ang_ab;
    fp32_t          unused_tri_ay, unused_box_ay, unused_xfm_ay;
    always_comb begin
      for (int i = 0; i < 4; i++) begin
        euc_aa[i] = v_euc.e[i];
        euc_ab[i] = v_euc.e[i + 4];
      end
      for (int i = 0; i < 2; i++) begin
        ang_aa[i]     = v_ang.dot[i];
        ang_ab[i]     = v_ang.dot[i + 2];
        ang_aa[2 + i] = v_ang.norm[i];
        ang_ab[2 + i] = v_ang.norm[i + 2];
      end
    end
    rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(0), .N_BOX(0), .N_EUC(AE), .N_ANG(AA))
      u_add (.op_i(st_i.op),
             .tri_a_i(FP_POS_ZERO), .tri_b_i(FP_POS_ZERO), .tri_y_o(unused_tri_ay),
             .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_ay),
             .euc_a_i(euc_aa), .euc_b_i(euc_ab), .euc_y_o(euc_ay),
             .ang_a_i(ang_aa), .ang_b_i(ang_ab), .ang_y_o(ang_ay),
             .xfm_a_i(FP_POS_ZERO), .xfm_b_i(FP_POS_ZERO), .xfm_y_o(unused_xfm_ay));
  end else begin : g_no_tree
    assign euc_ay = '0;
    assign ang_ay = '0;
  end

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        st_o.pl.box_range.tnear = near;
        st_o.pl.box_range.tfar  = far;
      end
      OP_TRIANGLE: begin
        if (!FUSED) st_o.pl.tri_edge.xprod = tri_my;
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          for (int i = 0; i < 4; i++) st_o.pl.euc.e[i] = euc_ay[i];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          for (int i = 0; i < 2; i++) begin
            st_o.pl.ang.dot[i]  = ang_ay[i];
            st_o.pl.ang.norm[i] = ang_ay[2 + i];
          end
        end
      end
      default: ;
    endcase
  end

endmodule
