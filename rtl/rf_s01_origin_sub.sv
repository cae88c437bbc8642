// Stage 1, origin_sub (the input stage): convert the request into the stage struct and subtract
// the origin (QUADBOX, TRIANGLE) or b (EUCLIDEAN).
//   TRANSFORM       matrix, origin, dir pass through (xfm_in)
//   QUADBOX   24 x  bound - origin            (box_slab.slab)
//   TRIANGLE   9 x  P - origin                (tri_vert.p)
//   EUCLIDEAN 16 x  a - b                     (euc.e)
//   ANGULAR         lanes a, b pass through   (ang.dot, ang.norm)
// FUSED: the QUADBOX computes (bound - origin) * inv here with one rounding (rf_fp_slab, 3 axes of
// 8 bounds, private units); S2 passes it on.
module rf_s01_origin_sub import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0,
  parameter bit FUSED = 1'b0
) (
  input  req_t   req_i,
  output stage_t st_o
);
  localparam int unsigned NT = 9, NB = FUSED ? 0 : 24, NE = EXTENDED ? EUC_LANES : 0;

  // ---- adder pool: operands per operation ----
  localparam fu_count_t ADD = fu_count(.n_tri(NT), .n_box(NB), .n_euc(NE));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    for (int v = 0; v < 3; v++) begin
      for (int ax = 0; ax < 3; ax++) begin
        add_a[OP_TRIANGLE][3*v+ax] = req_i.triangle[v][ax];
        add_b[OP_TRIANGLE][3*v+ax] = fp_neg(req_i.origin[ax]);
      end
    end
    for (int k = 0; k < int'(NB); k++) begin    // k = 6*i+j: box i, bound j
      add_a[OP_QUADBOX][k] = req_i.box[k / 6][k % 6];
      add_b[OP_QUADBOX][k] = fp_neg(req_i.origin[(k % 6) % 3]);
    end
    for (int l = 0; l < int'(NE); l++) begin
      add_a[OP_EUCLIDEAN][l] = req_i.vec_a[l];
      add_b[OP_EUCLIDEAN][l] = fp_neg(req_i.vec_b[l]);
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(req_i.opcode), .a_i(add_a), .b_i(add_b), .y_o(add_y));

  // ---- QUADBOX: bound - origin from the adder pool, or the whole slab value (FUSED) ----
  fp32_t [23:0] box_y;                      // box_y[6*i+j]: box i, bound j
  if (FUSED) begin : g_fused
    logic en;                               // operand isolation: zeros unless a QUADBOX
    assign en = req_i.opcode == OP_QUADBOX;
    for (genvar ax = 0; ax < 3; ax++) begin : g_axis
      fp32_t [7:0] bound, y;                // bound[2*i+hi]: box i, lower (hi 0) or upper bound
      for (genvar i = 0; i < 4; i++) begin : g_box
        for (genvar hi = 0; hi < 2; hi++) begin : g_bound
          assign bound[2*i+hi]      = en ? req_i.box[i][3*hi+ax] : FP_POS_ZERO;
          assign box_y[6*i+3*hi+ax] = y[2*i+hi];
        end
      end
      rf_fp_slab #(.N(8)) u_slab (.bound_i(bound), .origin_i(en ? req_i.origin[ax] : FP_POS_ZERO),
                                  .inv_i(en ? req_i.inv[ax] : FP_POS_ZERO), .y_o(y));
    end
  end else begin : g_plain
    assign box_y = add_y[OP_QUADBOX][23:0];
  end

  // ---- stage struct ----
  always_comb begin
    st_o     = '0;
    st_o.op  = req_i.opcode;
    st_o.tag = req_i.tag;
    unique case (req_i.opcode)
      OP_QUADBOX: begin
        for (int ax = 0; ax < 3; ax++) st_o.pl.box_slab.dir_neg[ax] = req_i.dir[ax][31];
        st_o.pl.box_slab.extent = req_i.extent;
        st_o.pl.box_slab.inv    = req_i.inv;
        for (int i = 0; i < 4; i++) begin
          for (int j = 0; j < 6; j++) st_o.pl.box_slab.slab[i][j] = box_y[6*i+j];
        end
      end
      OP_TRIANGLE: begin
        st_o.pl.tri_vert.no_cull = req_i.flags[FLAG_NO_CULL_BIT];
        st_o.pl.tri_vert.kx      = req_i.kx;
        st_o.pl.tri_vert.ky      = req_i.ky;
        st_o.pl.tri_vert.kz      = req_i.kz;
        st_o.pl.tri_vert.shear   = req_i.shear;
        for (int v = 0; v < 3; v++) begin
          for (int ax = 0; ax < 3; ax++) st_o.pl.tri_vert.p[v][ax] = add_y[OP_TRIANGLE][3*v+ax];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          st_o.last        = req_i.reset_accumulator;
          st_o.pl.euc.mask = req_i.vec_mask;
          for (int l = 0; l < int'(NE); l++) st_o.pl.euc.e[l] = add_y[OP_EUCLIDEAN][l];
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          st_o.last        = req_i.reset_accumulator;
          st_o.pl.ang.mask = req_i.vec_mask[ANG_LANES-1:0];
          for (int l = 0; l < int'(ANG_LANES); l++) begin
            st_o.pl.ang.dot[l]  = req_i.vec_a[l];
            st_o.pl.ang.norm[l] = req_i.vec_b[l];
          end
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          st_o.pl.xfm_in.m      = req_matrix(req_i.box);
          st_o.pl.xfm_in.origin = req_i.origin;
          st_o.pl.xfm_in.dir    = req_i.dir;
        end
      end
      default: ;
    endcase
  end

endmodule
