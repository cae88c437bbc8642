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

  // ---- QUADBOX: bound - origin in the adder pool, or the whole slab value (FUSED) ----
  fp32_t [(NB > 0 ? NB : 1)-1:0] box_a, box_b, box_pool_y;
  fp32_t [23:0] box_y;                      // box_y[6*i+j]: box i, bound j
  if (FUSED) begin : g_fused
    logic en;                               // operand isolation: zeros unless a QUADBOX
    assign en    = req_i.opcode == OP_QUADBOX;
    fp32_t unused_pool_y;                   // the pool has no QUADBOX units
    assign box_a = '0;
    assign box_b = '0;
    assign unused_pool_y = box_pool_y[0];
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
    always_comb begin
      for (int i = 0; i < 4; i++) begin
        for (int j = 0; j < 6; j++) begin
          box_a[6*i+j] = req_i.box[i][j];
          box_b[6*i+j] = fp_neg(req_i.origin[j % 3]);
        end
      end
    end
    assign box_y = box_pool_y;
  end

  // ---- adder pool: operands per operation ----
  fp32_t [NT-1:0] tri_a, tri_b, tri_y;
  fp32_t [(NE > 0 ? NE : 1)-1:0] euc_a, euc_b, euc_y;
  fp32_t unused_ang_y, unused_xfm_y;

  always_comb begin
    for (int v = 0; v < 3; v++) begin
      for (int ax = 0; ax < 3; ax++) begin
        tri_a[3*v+ax] = req_i.triangle[v][ax];
        tri_b[3*v+ax] = fp_neg(req_i.origin[ax]);
      end
    end
    euc_a = '0;
    euc_b = '0;
    if (EXTENDED) begin
      for (int l = 0; l < int'(NE); l++) begin
        euc_a[l] = req_i.vec_a[l];
        euc_b[l] = fp_neg(req_i.vec_b[l]);
      end
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(NB), .N_EUC(NE), .N_ANG(0))
    u_add (.op_i(req_i.opcode),
           .tri_a_i(tri_a), .tri_b_i(tri_b), .tri_y_o(tri_y),
           .box_a_i(box_a), .box_b_i(box_b), .box_y_o(box_pool_y),
           .euc_a_i(euc_a), .euc_b_i(euc_b), .euc_y_o(euc_y),
           .ang_a_i(FP_POS_ZERO), .ang_b_i(FP_POS_ZERO), .ang_y_o(unused_ang_y),
           .xfm_a_i(FP_POS_ZERO), .xfm_b_i(FP_POS_ZERO), .xfm_y_o(unused_xfm_y));

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
          for (int ax = 0; ax < 3; ax++) st_o.pl.tri_vert.p[v][ax] = tri_y[3*v+ax];
        end
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          st_o.last        = req_i.reset_accumulator;
          st_o.pl.euc.mask = req_i.vec_mask;
          for (int l = 0; l < int'(NE); l++) st_o.pl.euc.e[l] = euc_y[l];
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
