// Response processing: what a datapath response does to its ray (tag = the ray's slot); one
// per datapath pipeline (rf_rtu_pipes).
//
//   * QUADBOX: the hit children are pushed on the slot's stack farthest first, so that the
//     nearest is popped next: for j = 3 down to 0 with box_hit[j], the child pointer
//     child[box_index[j]] of the slot's node (a box32 or a q8 node: kind_i, the kind of slot rd_o).
//     With CULL each push carries the child's entry distance push_dist_o (its box_tmin[j],
//     for the distance-culled stack, rf_rtu_stack's CULL; 0 without, and no register for it).
//     One push per cycle (the stack RAM has one write port per response stage): a response with k
//     hit children takes max(k, 1) cycles; then next_o pulses (the ray pops its next node).
//   * TRIANGLE without a hit: next_o pulses in the cycle the response is taken.
//   * TRIANGLE with a hit: (t_num, t_den) go to the divider with tag {prim, slot} (prim: the
//     triangle's primitive id: a triangle node's, or prim[k] of a pair leaf), in the cycle the
//     response is taken; div_o pulses.
//   * TRANSFORM (the ray enters an instance): the return marker RETURN_PTR is pushed on the
//     slot's stack (below the BLAS, so that popping it brings the ray back to its world ray), and
//     (o', d') go to the ray setups (rf_rtu_setups) with tag {instance, BLAS root, slot} read
//     from the slot's instance node, in the cycle the response is taken; xf_o pulses.
//
// Contract: dp (valid/ready) is the datapath's output; dp_ready_o depends only on registers, on
// div_ready_i, on xf_ready_i and on the response's opcode and tri_hit (a triangle hit waits for
// the divider, a TRANSFORM for a ray setup; no path from dp_valid_i; the datapath's response is a
// register output). node_i is the node buffer entry of slot rd_o (combinational read port).
// push_o/push_slot_o/push_ptr_o drive the stack's push port; next_o/div_o/xf_o name the slot in
// evt_slot_o (at most one of them per cycle).
module rf_rtu_resp import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS = 4,
  parameter bit          CULL = 1'b0,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              dp_valid_i,
  output logic              dp_ready_o,
  input  rsp_t              dp_rsp_i,
  output logic [SLOT_W-1:0] rd_o,
  input  logic [NODE_W-1:0] node_i,
  input  kind_e             kind_i,
  output logic              push_o,
  output logic [SLOT_W-1:0] push_slot_o,
  output logic [31:0]       push_ptr_o,
  output logic [31:0]       push_dist_o,
  output logic              next_o,
  output logic              div_o,
  output logic [SLOT_W-1:0] evt_slot_o,
  output logic              div_valid_o,
  input  logic              div_ready_i,
  output logic [31:0]       div_num_o,
  output logic [31:0]       div_den_o,
  output logic [32+SLOT_W-1:0] div_tag_o,
  output logic              xf_o,
  output logic              xf_valid_o,
  input  logic              xf_ready_i,
  output logic [2:0][31:0]  xf_origin_o,
  output logic [2:0][31:0]  xf_dir_o,
  output logic [64+SLOT_W-1:0] xf_tag_o
);

  // A box response with more than one hit child is held here while its pushes go out.
  logic              busy_q;
  logic [3:0]        left_q;
  logic [3:0][1:0]   index_q;
  logic [SLOT_W-1:0] slot_q;

  logic              take, tri_op, tri_hit, xf_op;
  logic [SLOT_W-1:0] slot;
  logic [3:0]        left;
  logic [3:0][1:0]   index;
  logic [3:0][31:0]  tmin;
  assign tri_op  = dp_rsp_i.opcode == OP_TRIANGLE;
  assign tri_hit = tri_op & dp_rsp_i.tri_hit;
  assign xf_op   = dp_rsp_i.opcode == OP_TRANSFORM;
  assign dp_ready_o = ~busy_q & (div_ready_i | ~tri_hit) & (xf_ready_i | ~xf_op);
  assign take  = dp_valid_i & dp_ready_o;
  assign slot  = busy_q ? slot_q : SLOT_W'(dp_rsp_i.tag);
  assign left  = busy_q ? left_q : (tri_op | xf_op ? 4'b0 : dp_rsp_i.box_hit);
  assign index = busy_q ? index_q : dp_rsp_i.box_index;
  assign rd_o  = slot;

  // the farthest remaining hit child: the highest set bit of left
  logic [1:0] j;
  logic [3:0] rest;
  always_comb begin
    j = 2'd0;
    for (int k = 0; k < 4; k++) if (left[k]) j = 2'(k);
    rest = left & ~(4'b1 << j);
  end

  logic active;                          // a box response is being worked on this cycle
  assign active      = busy_q | (take & ~tri_op & ~xf_op);
  assign push_o      = (active & (left != 4'b0)) | (take & xf_op);
  assign push_slot_o = slot;
  logic [31:0] child_word, prim_word;
  assign child_word  = kind_i == KIND_Q8 ? Q8_NODE_CHILD_WORD : BOX_NODE_CHILD_WORD;
  assign prim_word   = kind_i == KIND_PAIR0 ? PAIR_NODE_PRIM_WORD
                     : kind_i == KIND_PAIR1 ? PAIR_NODE_PRIM_WORD + 1 : TRI_NODE_PRIM_WORD;
  assign push_ptr_o  = take & xf_op ? RETURN_PTR : node_i[(child_word + 32'(index[j])) * 32 +: 32];

  if (CULL) begin : g_tmin
    logic [3:0][31:0] tmin_q;
    assign tmin = busy_q ? tmin_q : dp_rsp_i.box_tmin;
    always_ff @(posedge clk_i) if (active) tmin_q <= tmin;
  end else begin : g_no_tmin
    assign tmin = '0;
  end
  assign push_dist_o = take & xf_op ? '0 : tmin[j];

  assign next_o     = (active & (rest == 4'b0)) | (take & tri_op & ~tri_hit);
  assign div_o      = take & tri_hit;
  assign xf_o       = take & xf_op;
  assign evt_slot_o = slot;

  assign div_valid_o = dp_valid_i & ~busy_q & tri_hit;
  assign div_num_o   = dp_rsp_i.t_num;
  assign div_den_o   = dp_rsp_i.t_den;
  assign div_tag_o   = {node_i[prim_word*32 +: 32], slot};

  assign xf_valid_o  = dp_valid_i & ~busy_q & xf_op;
  assign xf_origin_o = dp_rsp_i.xf_origin;
  assign xf_dir_o    = dp_rsp_i.xf_dir;
  assign xf_tag_o    = {node_i[INST_NODE_ID_WORD*32 +: 32], node_i[INST_NODE_BLAS_WORD*32 +: 32],
                        slot};

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      busy_q <= 1'b0;
    end else if (active) begin
      busy_q <= rest != 4'b0;
    end
  end

  always_ff @(posedge clk_i) begin
    if (active) begin
      left_q  <= rest;
      index_q <= index;
      slot_q  <= slot;
    end
  end

endmodule
