// Stage 9.
//   QUADBOX   sorting network layer 2 (last)
//   TRIANGLE  hit = U >= 0 and V >= 0 and W >= 0 and t_num >= 0 and t_den != 0 (IEEE: NaN misses)
module rf_st09 import rf_pkg::*; (
  input  stage_t st_i,
  output stage_t st_o
);
  box_sort_t  v_box;
  tri_edge_t  v_tri;
  assign v_box = st_i.pl.box_sort;
  assign v_tri = st_i.pl.tri_edge;

  fp32_t [3:0]      tmin;
  logic  [3:0][1:0] idx;
  logic  [3:0]      hit;
  rf_sort4 #(.LAYER(2)) u_sort (.tmin_i(v_box.tmin), .idx_i(v_box.idx), .hit_i(v_box.hit),
                                .tmin_o(tmin), .idx_o(idx), .hit_o(hit));

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
      OP_QUADBOX: begin
        st_o.pl.box_sort.tmin = tmin;
        st_o.pl.box_sort.idx  = idx;
        st_o.pl.box_sort.hit  = hit;
      end
      OP_TRIANGLE: st_o.pl.tri_edge.hit = &nonneg & ~den_zero;
      default: ;
    endcase
  end

endmodule
