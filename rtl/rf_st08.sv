// Stage 8.
//   QUADBOX   sorting network layer 1
//   TRIANGLE   1 x  t_num = (U*Az + V*Bz) + W*Cz
module rf_st08 import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0
) (
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
  rf_sort4 #(.LAYER(1)) u_sort (.tmin_i(v_box.tmin), .idx_i(v_box.idx), .hit_i(v_box.hit),
                                .tmin_o(tmin), .idx_o(idx), .hit_o(hit));

  fp32_t tri_y, unused_box_y, unused_euc_y, unused_ang_y;
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(1), .N_BOX(0), .N_EUC(0), .N_ANG(0))
    u_add (.op_i(st_i.op),
           .tri_a_i(v_tri.num_part), .tri_b_i(v_tri.uvw_z[2]), .tri_y_o(tri_y),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_y),
           .euc_a_i(FP_POS_ZERO), .euc_b_i(FP_POS_ZERO), .euc_y_o(unused_euc_y),
           .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_y));

  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX: begin
        st_o.pl.box_sort.tmin = tmin;
        st_o.pl.box_sort.idx  = idx;
        st_o.pl.box_sort.hit  = hit;
      end
      OP_TRIANGLE: st_o.pl.tri_edge.num = tri_y;
      default: ;
    endcase
  end

  logic unused_extended;
  assign unused_extended = EXTENDED;

endmodule
