// Stage 6, slab_hit: the box hit flags; the depth products U*Az, V*Bz, W*Cz.
//   QUADBOX   hit = no NaN and tmin < tmax; tmin out = hit ? tmin : +inf; indices 0..3
//   TRIANGLE   3 x  U*Az, V*Bz, W*Cz (multipliers);  1 x  U + V (adder)
//   EUCLIDEAN  1 x  tree level 4 (last): e[0] + e[1]
//   TRANSFORM  1 x  (m[0][0]*o[0] + m[0][1]*o[1]) + m[0][2]*o[2]
module rf_s06_slab_hit import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned MT = 3, AT = 1, AE = EXTENDED ? 1 : 0, AX = TRANSFORM ? 1 : 0;

  box_range_t v_box;
  tri_edge_t  v_tri;
  euc_t       v_euc;
  xfm_t       v_xfm;
  assign v_xfm = st_i.pl.xfm;
  assign v_box = st_i.pl.box_range;
  assign v_tri = st_i.pl.tri_edge;
  assign v_euc = st_i.pl.euc;

  // ---- QUADBOX ----
  logic [3:0] lt;
  for (genvar i = 0; i < 4; i++) begin : g_box
    logic unused_le, unused_eq, unused_unord;
    rf_fp_cmp u_cmp (.a_i(v_box.tnear[i]), .b_i(v_box.tfar[i]), .lt_o(lt[i]), .le_o(unused_le),
                     .eq_o(unused_eq), .unord_o(unused_unord));
  end

  // ---- multiplier pool ----
  fp32_t [MT-1:0] tri_ma, tri_mb, tri_my;
  fp32_t          unused_box_my, unused_euc_my, unused_ang_my, unused_xfm_my;
  always_comb begin
    tri_ma[0] = v_tri.u;  tri_mb[0] = v_tri.z[0];   // U*Az
    tri_ma[1] = v_tri.v;  tri_mb[1] = v_tri.z[1];   // V*Bz
    tri_ma[2] = v_tri.w;  tri_mb[2] = v_tri.z[2];   // W*Cz
  end
  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N_TRI(MT), .N_BOX(0), .N_EUC(0), .N_ANG(0))
    u_mul (.op_i(st_i.op),
           .tri_a_i(tri_ma), .tri_b_i(tri_mb), .tri_y_o(tri_my),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_my),
           .euc_a_i(FP_POS_ZERO), .euc_b_i(FP_POS_ZERO), .euc_y_o(unused_euc_my),
           .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_my),
           .xfm_a_i(FP_POS_ZERO), .xfm_b_i(FP_POS_ZERO), .xfm_y_o(unused_xfm_my));

  // ---- adder pool ----
  fp32_t tri_ay, euc_aa, euc_ab, euc_ay;
  fp32_t unused_box_ay, unused_ang_ay, xfm_ay;
  assign euc_aa = EXTENDED ? v_euc.e[0] : FP_POS_ZERO;
  assign euc_ab = EXTENDED ? v_euc.e[1] : FP_POS_ZERO;
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(AT), .N_BOX(0), .N_EUC(AE), .N_ANG(0),
               .N_XFM(AX))
    u_add (.op_i(st_i.op),
           .tri_a_i(v_tri.u), .tri_b_i(v_tri.v), .tri_y_o(tri_ay),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_ay),
           .euc_a_i(euc_aa), .euc_b_i(euc_ab), .euc_y_o(euc_ay),
           .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_ay),
           .xfm_a_i(v_xfm.po[0][0]), .xfm_b_i(v_xfm.po[0][2]), .xfm_y_o(xfm_ay));

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        for (int i = 0; i < 4; i++) begin
          st_o.pl.box_sort.hit[i]  = ~v_box.nan[i] & lt[i];
          st_o.pl.box_sort.tmin[i] = st_o.pl.box_sort.hit[i] ? v_box.tnear[i] : FP_POS_INF;
          st_o.pl.box_sort.idx[i]  = 2'(i);
        end
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_edge.uvw_z = tri_my;
        st_o.pl.tri_edge.uv    = tri_ay;
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) st_o.pl.euc.e[0] = euc_ay;
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) st_o.pl.xfm.po[0][0] = xfm_ay;
      end
      default: ;
    endcase
  end

endmodule
