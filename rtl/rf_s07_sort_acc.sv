// Stage 7, sort_acc: sorting network layer 0; the accumulators; t_den.
//   QUADBOX   sorting network layer 0
//   TRIANGLE   2 x  U*Az + V*Bz,  t_den = (U + V) + W
//   EUCLIDEAN  1 x  acc + beat  (accumulator)
//   ANGULAR    2 x  dot acc + beat, norm acc + beat  (accumulators)
//   TRANSFORM  2 x  (m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]   (r = 1, 2)
// The accumulators are the only state in the datapath. They change only when a beat of their
// operation is accepted into this stage's register (fire_i): bubbles, back-pressure and other
// operations never touch them. On a beat with `last` set the output carries the sum including this
// beat and the accumulator clears to +0 for the next job.
module rf_s07_sort_acc import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit DISJOINT = 1'b0,
  parameter bit TRANSFORM = 1'b0
) (
  input  logic   clk_i,
  input  logic   rst_ni,
  input  logic   fire_i,
  input  stage_t st_i,
  output stage_t st_o
);
  localparam int unsigned NT = 2, NE = EXTENDED ? 1 : 0, NA = EXTENDED ? 2 : 0;
  localparam int unsigned NX = TRANSFORM ? 2 : 0;

  box_sort_t  v_box;
  tri_edge_t  v_tri;
  euc_t       v_euc;
  ang_t       v_ang;
  xfm_t       v_xfm;
  assign v_xfm = st_i.pl.xfm;
  assign v_box = st_i.pl.box_sort;
  assign v_tri = st_i.pl.tri_edge;
  assign v_euc = st_i.pl.euc;
  assign v_ang = st_i.pl.ang;

  // ---- QUADBOX ----
  box_sort_t box_sorted;
  rf_sort_layer #(.LAYER(0)) u_sort (.box_i(v_box), .box_o(box_sorted));

  // ---- accumulator state ----
  fp32_t euc_acc_q, dot_acc_q, norm_acc_q;

  // ---- adder pool ----
  fp32_t [NT-1:0] tri_a, tri_b, tri_y;
  fp32_t [(NA > 0 ? NA : 1)-1:0] ang_a, ang_b, ang_y;
  fp32_t [(NX > 0 ? NX : 1)-1:0] xfm_a, xfm_b, xfm_y;
  fp32_t euc_a, euc_b, euc_y, unused_box_y;
  always_comb begin
    tri_a[0] = v_tri.uvw_z[0];
    tri_b[0] = v_tri.uvw_z[1];
    tri_a[1] = v_tri.uv;
    tri_b[1] = v_tri.w;
    euc_a    = euc_acc_q;
    euc_b    = EXTENDED ? v_euc.e[0] : FP_POS_ZERO;
    ang_a    = '0;
    ang_b    = '0;
    xfm_a    = '0;
    xfm_b    = '0;
    if (TRANSFORM) begin
      for (int k = 0; k < 2; k++) begin
        xfm_a[k] = v_xfm.po[k+1][0];
        xfm_b[k] = v_xfm.po[k+1][2];
      end
    end
    if (EXTENDED) begin
      ang_a[0] = dot_acc_q;
      ang_b[0] = v_ang.dot[0];
      ang_a[1] = norm_acc_q;
      ang_b[1] = v_ang.norm[0];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N_TRI(NT), .N_BOX(0), .N_EUC(NE), .N_ANG(NA),
               .N_XFM(NX))
    u_add (.op_i(st_i.op),
           .tri_a_i(tri_a), .tri_b_i(tri_b), .tri_y_o(tri_y),
           .box_a_i(FP_POS_ZERO), .box_b_i(FP_POS_ZERO), .box_y_o(unused_box_y),
           .euc_a_i(euc_a), .euc_b_i(euc_b), .euc_y_o(euc_y),
           .ang_a_i(ang_a), .ang_b_i(ang_b), .ang_y_o(ang_y),
           .xfm_a_i(xfm_a), .xfm_b_i(xfm_b), .xfm_y_o(xfm_y));

  if (EXTENDED) begin : g_acc
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni) begin
        euc_acc_q  <= FP_POS_ZERO;
        dot_acc_q  <= FP_POS_ZERO;
        norm_acc_q <= FP_POS_ZERO;
      end else if (fire_i) begin
        if (st_i.op == OP_EUCLIDEAN) begin
          euc_acc_q <= st_i.last ? FP_POS_ZERO : euc_y;
        end
        if (st_i.op == OP_ANGULAR) begin
          dot_acc_q  <= st_i.last ? FP_POS_ZERO : ang_y[0];
          norm_acc_q <= st_i.last ? FP_POS_ZERO : ang_y[1];
        end
      end
    end
  end else begin : g_no_acc
    assign euc_acc_q  = FP_POS_ZERO;
    assign dot_acc_q  = FP_POS_ZERO;
    assign norm_acc_q = FP_POS_ZERO;
    logic unused_fire;
    assign unused_fire = fire_i ^ clk_i ^ rst_ni;
  end

  // ---- stage struct ----
  always_comb begin
    st_o = st_i;
    unique case (st_i.op)
      OP_QUADBOX:  st_o.pl.box_sort = box_sorted;
      OP_TRIANGLE: begin
        st_o.pl.tri_edge.num_part = tri_y[0];
        st_o.pl.tri_edge.den      = tri_y[1];
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) st_o.pl.euc.acc = euc_y;
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          st_o.pl.ang.dot_acc  = ang_y[0];
          st_o.pl.ang.norm_acc = ang_y[1];
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int k = 0; k < 2; k++) st_o.pl.xfm.po[k+1][0] = xfm_y[k];
        end
      end
      default: ;
    endcase
  end

endmodule
