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
  localparam fu_count_t ADD = fu_count(.n_tri(NT), .n_euc(NE), .n_ang(NA), .n_xfm(NX));
  fp32_t [NUM_OPS-1:0][fu_width(ADD)-1:0] add_a, add_b, add_y;
  always_comb begin
    add_a = '0;
    add_b = '0;
    add_a[OP_TRIANGLE][0] = v_tri.uvw_z[0];
    add_b[OP_TRIANGLE][0] = v_tri.uvw_z[1];
    add_a[OP_TRIANGLE][1] = v_tri.uv;
    add_b[OP_TRIANGLE][1] = v_tri.w;
    add_a[OP_EUCLIDEAN][0] = euc_acc_q;
    add_b[OP_EUCLIDEAN][0] = EXTENDED ? v_euc.e[0] : FP_POS_ZERO;
    if (TRANSFORM) begin
      for (int k = 0; k < 2; k++) begin
        add_a[OP_TRANSFORM][k] = v_xfm.po[k+1][0];
        add_b[OP_TRANSFORM][k] = v_xfm.po[k+1][2];
      end
    end
    if (EXTENDED) begin
      add_a[OP_ANGULAR][0] = dot_acc_q;
      add_b[OP_ANGULAR][0] = v_ang.dot[0];
      add_a[OP_ANGULAR][1] = norm_acc_q;
      add_b[OP_ANGULAR][1] = v_ang.norm[0];
    end
  end

  rf_fu_pool #(.IS_MUL(1'b0), .DISJOINT(DISJOINT), .N(ADD))
    u_add (.op_i(st_i.op), .a_i(add_a), .b_i(add_b), .y_o(add_y));

  if (EXTENDED) begin : g_acc
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni) begin
        euc_acc_q  <= FP_POS_ZERO;
        dot_acc_q  <= FP_POS_ZERO;
        norm_acc_q <= FP_POS_ZERO;
      end else if (fire_i) begin
        if (st_i.op == OP_EUCLIDEAN) begin
          euc_acc_q <= st_i.last ? FP_POS_ZERO : add_y[OP_EUCLIDEAN][0];
        end
        if (st_i.op == OP_ANGULAR) begin
          dot_acc_q  <= st_i.last ? FP_POS_ZERO : add_y[OP_ANGULAR][0];
          norm_acc_q <= st_i.last ? FP_POS_ZERO : add_y[OP_ANGULAR][1];
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
        st_o.pl.tri_edge.num_part = add_y[OP_TRIANGLE][0];
        st_o.pl.tri_edge.den      = add_y[OP_TRIANGLE][1];
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) st_o.pl.euc.acc = add_y[OP_EUCLIDEAN][0];
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          st_o.pl.ang.dot_acc  = add_y[OP_ANGULAR][0];
          st_o.pl.ang.norm_acc = add_y[OP_ANGULAR][1];
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int k = 0; k < 2; k++) st_o.pl.xfm.po[k+1][0] = add_y[OP_TRANSFORM][k];
        end
      end
      default: ;
    endcase
  end

endmodule
