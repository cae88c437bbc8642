// Stage 9, sort_trihit: sorting network layer 2; the triangle hit test.
//   QUADBOX   sorting network layer 2 (last)
//   TRIANGLE  hit test of docs/datapath.md#triangle, both faces when the ray's NO_CULL flag is set (NaN misses)
module rf_s09_sort_trihit import rf_pkg::*; (
  input  stage_t st_i,
  output stage_t st_o
);
  box_sort_t  v_box;
  tri_edge_t  v_tri;
  assign v_box = st_i.pl.box_sort;
  assign v_tri = st_i.pl.tri_edge;

  box_sort_t box_sorted;
  rf_sort_layer #(.LAYER(2)) u_sort (.box_i(v_box), .box_o(box_sorted));

  // Signs against zero (IEEE compares: false on NaN, -0 == +0).
  //   x >= 0 and x <= 0 for x = U, V, W, t_num;  t_den > 0 and t_den == 0.
  fp32_t [3:0] x;
  logic  [3:0] ge0, le0;
  logic        den_pos, den_zero;
  assign x = {v_tri.num, v_tri.w, v_tri.v, v_tri.u};
  for (genvar k = 0; k < 4; k++) begin : g_sign
    logic unused_gt, unused_ge_eq, unused_ge_unord, unused_lt, unused_le_eq, unused_le_unord;
    rf_fp_cmp u_ge (.a_i(FP_POS_ZERO), .b_i(x[k]), .lt_o(unused_gt), .le_o(ge0[k]),
                    .eq_o(unused_ge_eq), .unord_o(unused_ge_unord));
    rf_fp_cmp u_le (.a_i(x[k]), .b_i(FP_POS_ZERO), .lt_o(unused_lt), .le_o(le0[k]),
                    .eq_o(unused_le_eq), .unord_o(unused_le_unord));
  end
  logic unused_den_le, unused_den_unord;
  rf_fp_cmp u_den (.a_i(FP_POS_ZERO), .b_i(v_tri.den), .lt_o(den_pos), .le_o(unused_den_le),
                   .eq_o(den_zero), .unord_o(unused_den_unord));

  // docs/datapath.md#triangle. Front face: U, V, W >= 0; with NO_CULL also the back face: U, V, W <= 0. Then
  // t_den != 0 and t_num on the side of t_den: t_num >= 0 if t_den > 0, else t_num <= 0.
  // Without NO_CULL this is the paper's rule (U, V, W >= 0, t_num >= 0, t_den != 0): with U, V,
  // W >= 0 (so none is NaN) the sum t_den is >= 0 and not NaN, so t_den != 0 means t_den > 0.
  logic front, back, tri_hit;
  assign front   = &ge0[2:0];
  assign back    = &le0[2:0] & v_tri.no_cull;
  assign tri_hit = (front | back) & ~den_zero & (den_pos ? ge0[3] : le0[3]);

  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX:  st_o.pl.box_sort = box_sorted;
      OP_TRIANGLE: st_o.pl.tri_edge.hit = tri_hit;
      default: ;
    endcase
  end

endmodule
