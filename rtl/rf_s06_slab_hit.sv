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
  localparam fu_count_t MUL = fu_count(.n_tri(MT));
  fp32_t [NUM_OPS-1:0][fu_width(MUL)-1:0] mul_a, mul_b, mul_y;
  always_comb begin
    mul_a = '0;
    mul_b = '0;
    mul_a[OP_TRIANGLE][0] = v_tri.u;  mul_b[OP_TRIANGLE][0] = v_tri.z[0];   // U*Az
    mul_a[OP_TRIANGLE][1] = v_tri.v;  mul_b[OP_TRIANGLE][1] = v_tri.z[1];   // V*Bz
    mul_a[OP_TRIANGLE][2] = v_tri.w;  mul_b[OP_TRIANGLE][2] = v_tri.z[2];   // W*Cz
  end
  rf_fu_pool #(.IS_MUL(1'b1), .DISJOINT(DISJOINT), .N(MUL))
    u_mul (.op_i(st_i.op), .a_i(mul_a), .b_i(mul_b), .y_o(mul_y));

  // ---- adder pool ----
  localparam fu_count_t ADD = fu_count(.n_tri(AT), .n_euc(AE), .n_xfm(AX));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    add_a[OP_TRIANGLE][0]  = v_tri.u;                                  // U + V
    add_b[OP_TRIANGLE][0]  = v_tri.v;
    add_a[OP_EUCLIDEAN][0] = EXTENDED ? v_euc.e[0] : FP_POS_ZERO;
    add_b[OP_EUCLIDEAN][0] = EXTENDED ? v_euc.e[1] : FP_POS_ZERO;
    add_a[OP_TRANSFORM][0] = v_xfm.po[0][0];
    add_b[OP_TRANSFORM][0] = v_xfm.po[0][2];
  end
  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));

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
        st_o.pl.tri_edge.uvw_z = mul_y[OP_TRIANGLE][2:0];
        st_o.pl.tri_edge.uv    = add_y[OP_TRIANGLE][0];
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) st_o.pl.euc.e[0] = add_y[OP_EUCLIDEAN][0];
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) st_o.pl.xfm.po[0][0] = add_y[OP_TRANSFORM][0];
      end
      default: ;
    endcase
  end

endmodule
