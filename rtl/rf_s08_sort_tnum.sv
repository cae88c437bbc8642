// Stage 8, sort_tnum: sorting network layer 1; t_num.
//   QUADBOX   sorting network layer 1
//   TRIANGLE   1 x  t_num = (U*Az + V*Bz) + W*Cz
//   TRANSFORM  3 x  o'[r] = (..) + m[r][3]   (2 adders beyond the triangle's 1)
module rf_s08_sort_tnum import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0
) (
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NX = TRANSFORM ? 3 : 0;

  box_sort_t  v_box;
  tri_edge_t  v_tri;
  xfm_t       v_xfm;
  assign v_xfm = st_i.pl.xfm;
  assign v_box = st_i.pl.box_sort;
  assign v_tri = st_i.pl.tri_edge;

  box_sort_t box_sorted;
  rf_sort_layer #(.LAYER(1)) u_sort (.box_i(v_box), .box_o(box_sorted));

  fp32_t tri_y, unused_box_y, unused_euc_y, unused_ang_y;
  fp32_t [(NX > 0 ? NX : 1)-1:0] xfm_a, xfm_b, xfm_y;
  always_comb begin
    xfm_a = '0;
    xfm_b = '0;
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        xfm_a[r] = v_xfm.po[r][0];
        xfm_b[r] = v_xfm.t[r];
      end
    end
  end
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(1), .N_BOX(0), .N_EUC(0), .N_ANG(0),
               .N_XFM(NX))
    u_add (.op_i(st_i.op),
           .tri_a_i(v_tri.num_part), .tri_b_i(v_tri.uvw_z[2]), .tri_y_o(tri_y),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_y),
           .euc_a_i(FP_POS_ZERO), .euc_b_i(FP_POS_ZERO), .euc_y_o(unused_euc_y),
           .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_y),
           .xfm_a_i(xfm_a), .xfm_b_i(xfm_b), .xfm_y_o(xfm_y));

  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX:  st_o.pl.box_sort = box_sorted;
      OP_TRIANGLE: st_o.pl.tri_edge.num = tri_y;
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) st_o.pl.xfm.po[r][0] = xfm_y[r];
        end
      end
      default: ;
    endcase
  end

  logic unused_extended;
  assign unused_extended = EXTENDED;

endmodule
