// Stage 9, sort_trihit: sorting network layer 2; the triangle hit test.
//   QUADBOX   sorting network layer 2 (last)
//   TRIANGLE  hit = U >= 0 and V >= 0 and W >= 0 and t_num >= 0 and t_den != 0 (IEEE: NaN misses)
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

  // 0 <= U, V, W, t_num (IEEE: false on NaN) and t_den == 0
  fp32_t [3:0] x;
  logic  [3:0] nonneg;
  logic        den_zero;
  assign x = {v_tri.num, v_tri.w, v_tri.v, v_tri.u};
  for (genvar k = 0; k < 4; k++) begin : g_sign
    logic unused_lt, unused_eq, unused_unord;
    rf_fp_cmp u_cmp (.a_i(FP_POS_ZERO), .b_i(x[k]), .lt_o(unused_lt), .le_o(nonneg[k]),
                     .eq_o(unused_eq), .unord_o(unused_unord));
  end
  logic unused_den_lt, unused_den_le, unused_den_unord;
  rf_fp_cmp u_den (.a_i(v_tri.den), .b_i(FP_POS_ZERO), .lt_o(unused_den_lt), .le_o(unused_den_le),
                   .eq_o(den_zero), .unord_o(unused_den_unord));

  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX:  st_o.pl.box_sort = box_sorted;
      OP_TRIANGLE: st_o.pl.tri_edge.hit = &nonneg & ~den_zero;
      default: ;
    endcase
  end

endmodule
