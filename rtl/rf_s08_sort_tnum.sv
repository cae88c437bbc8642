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

  // ---- adder pool ----
  localparam fu_count_t ADD = fu_count(.n_tri(1), .n_xfm(NX));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    add_a[OP_TRIANGLE][0] = v_tri.num_part;
    add_b[OP_TRIANGLE][0] = v_tri.uvw_z[2];
    if (TRANSFORM) begin
      for (int r = 0; r < 3; r++) begin
        add_a[OP_TRANSFORM][r] = v_xfm.po[r][0];
        add_b[OP_TRANSFORM][r] = v_xfm.t[r];
      end
    end
  end
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));

  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX:  st_o.pl.box_sort = box_sorted;
      OP_TRIANGLE: st_o.pl.tri_edge.num = add_y[OP_TRIANGLE][0];
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) st_o.pl.xfm.po[r][0] = add_y[OP_TRANSFORM][r];
        end
      end
      default: ;
    endcase
  end

  logic unused_extended;
  assign unused_extended = EXTENDED;

endmodule
