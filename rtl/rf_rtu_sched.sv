// Scheduler: each cycle picks up to PIPELINES ray slots whose node is in the node buffer, one per
// pipeline, no slot twice (round robin from the slot after the last one issued), and offers each
// pipeline its slot's request: the slot's prepared ray,
// extent = the ray's nearest t, tag = the slot, and by the node's kind (rf_rtu_pkg::kind_e):
// QUADBOX with a box32 node's four child boxes, or with a q8 node as stored (the request's qnode)
// and the flag DECODE_Q8; TRIANGLE with a triangle node's triangle, a pair leaf's triangle 0
// (v0, v1, v2) or its triangle 1 (v[i0], v[i1], v[i2], the selectors in idx bits 5:0);
// TRANSFORM of the ray (outside instances: its world ray) by an instance node's world_to_object
// (the request's matrix, box words 0..11).
//
// Contract (p < PIPELINES; with one pipeline every port is one wide):
//   * ready_i: one bit per slot whose request may issue; kind_i: per slot, its node's kind;
//   * the pipelines are served in turn, round robin too: from the pipeline after the last one
//     that took a request, each is offered the first ready slot (round robin from the slot after
//     the last one issued) that no pipeline served before it takes this cycle; rd_o[p] names
//     pipeline p's, and ray_i[p], nearest_i[p] and node_i[p] are that slot's ray, nearest t and
//     node (the buffers' combinational read ports, one per pipeline). Consecutive requests thus
//     go to different pipelines, and so to different response stages;
//   * dp[p] (valid/ready) drives pipeline p's input: dp_valid_o[p] = such a slot exists (it
//     depends on dp_ready_i of the pipelines served before p, never on its own: the datapath's
//     in_ready is a register output); a request moves when dp_ready_i[p] is high, and then
//     issue_o[p] pulses with issue_slot_o[p], issue_box_o[p] and issue_xf_o[p] (the caller moves
//     the slot on and counts the op). Both round robins start the next cycle after the last
//     slot issued and the last pipeline that took it.
module rf_rtu_sched import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS = 4,
  parameter int unsigned PIPELINES = 1,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1,
  localparam int unsigned PIPE_W = PIPELINES > 1 ? $clog2(PIPELINES) : 1
) (
  input  logic                 clk_i,
  input  logic                 rst_ni,
  input  logic [RAYS-1:0]      ready_i,
  input  kind_e [RAYS-1:0]     kind_i,
  output logic [PIPELINES-1:0][SLOT_W-1:0] rd_o,
  input  ray_t [PIPELINES-1:0] ray_i,
  input  logic [PIPELINES-1:0][31:0]       nearest_i,
  input  logic [PIPELINES-1:0][NODE_W-1:0] node_i,
  output logic [PIPELINES-1:0] dp_valid_o,
  input  logic [PIPELINES-1:0] dp_ready_i,
  output req_t [PIPELINES-1:0] dp_req_o,
  output logic [PIPELINES-1:0] issue_o,
  output logic [PIPELINES-1:0][SLOT_W-1:0] issue_slot_o,
  output logic [PIPELINES-1:0] issue_box_o,
  output logic [PIPELINES-1:0] issue_xf_o
);

  localparam int unsigned REQ_W = $bits(req_t);

  function automatic logic [SLOT_W-1:0] after(input logic [SLOT_W-1:0] slot);
    return (32'(slot) == RAYS - 1) ? '0 : slot + 1'b1;
  endfunction

  function automatic logic [PIPE_W-1:0] after_pipe(input logic [PIPE_W-1:0] p);
    return (32'(p) == PIPELINES - 1) ? '0 : p + 1'b1;
  endfunction

  logic [SLOT_W-1:0] next_q;      // round-robin start over the slots
  logic [PIPE_W-1:0] pipe_q;      // and over the pipelines
  // each pipeline's pick, in turn from pipe_q (the j-th served is pipeline q[j]): from the slots
  // the pipelines served before it left (left[j]), after the last one they took (start[j]);
  // pipe[j]: the pipeline after the last of them that took a request
  logic [PIPELINES-1:0][RAYS-1:0]   left  /*verilator split_var*/;
  logic [PIPELINES:0][SLOT_W-1:0]   start /*verilator split_var*/;
  logic [PIPELINES:0][PIPE_W-1:0]   pipe  /*verilator split_var*/;
  logic [PIPELINES-1:0]             found, took;
  logic [PIPELINES-1:0][SLOT_W-1:0] pick;
  logic [PIPELINES-1:0][PIPE_W-1:0] q;
  assign left[0]  = ready_i;
  assign start[0] = next_q;
  assign pipe[0]  = pipe_q;
  for (genvar j = 0; j < PIPELINES; j++) begin : g_pick
    assign q[j] = PIPE_W'(32'(pipe_q) + j >= PIPELINES ? 32'(pipe_q) + j - PIPELINES
                                                        : 32'(pipe_q) + j);
    rf_rr_pick #(.N(RAYS)) u_pick (
      .req_i(left[j]), .start_i(start[j]), .valid_o(found[j]), .idx_o(pick[j]));
    assign took[j]    = found[j] & dp_ready_i[q[j]];
    if (j + 1 < PIPELINES) begin : g_left
      assign left[j+1] = took[j] ? left[j] & ~(RAYS'(1) << pick[j]) : left[j];
    end
    assign start[j+1] = took[j] ? after(pick[j]) : start[j];
    assign pipe[j+1]  = took[j] ? after_pipe(q[j]) : pipe[j];
  end
  always_comb
    for (int unsigned j = 0; j < PIPELINES; j++) begin
      rd_o[q[j]]       = pick[j];
      dp_valid_o[q[j]] = found[j];
      issue_o[q[j]]    = took[j];
    end

  for (genvar p = 0; p < PIPELINES; p++) begin : g_req
    logic [REQ_W-1:0] w;
    logic             box, xf;
    kind_e            kind;
    logic [5:0]       sel;
    assign kind = kind_i[rd_o[p]];
    assign box  = kind == KIND_BOX32 || kind == KIND_Q8;
    assign xf   = kind == KIND_XF;
    assign sel  = node_i[p][PAIR_NODE_IDX_WORD*32 +: 6];
    always_comb begin
      w = '0;
      w[RAY_WORDS*32-1:32] = ray_i[p];
      w[31:0] = 32'(rd_o[p]);                                    // tag = slot
      w[32+:3] = box ? OP_QUADBOX : xf ? OP_TRANSFORM : OP_TRIANGLE;  // opcode (word 1 bits 2:0)
      w[REQ_EXTENT_WORD*32+:32] = nearest_i[p];
      unique case (kind)
        KIND_BOX32: w[REQ_BOX_WORD*32+:24*32] = node_i[p][BOX_NODE_BOX_WORD*32+:24*32];
        KIND_Q8: begin
          w[REQ_BOX_WORD*32+:Q8_NODE_WORDS*32] = node_i[p][0+:Q8_NODE_WORDS*32];
          w[REQ_FLAGS_LSB + FLAG_DECODE_Q8_BIT] = 1'b1;
        end
        KIND_XF:
          w[REQ_BOX_WORD*32+:MATRIX_WORDS*32] =
              node_i[p][INST_NODE_M_WORD*32+:MATRIX_WORDS*32];
        KIND_PAIR1:
          for (int j = 0; j < 3; j++)
            w[(REQ_TRI_WORD + 3*j)*32+:3*32] =
                node_i[p][(PAIR_NODE_V_WORD + 3*32'(sel[2*j+:2]))*32+:3*32];
        default: w[REQ_TRI_WORD*32+:9*32] = node_i[p][TRI_NODE_TRI_WORD*32+:9*32];  // v0..v2
      endcase
    end
    assign dp_req_o[p]     = req_t'(w);
    assign issue_slot_o[p] = rd_o[p];
    assign issue_box_o[p]  = box;
    assign issue_xf_o[p]   = xf;
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      next_q <= '0;
      pipe_q <= '0;
    end else begin
      next_q <= start[PIPELINES];
      pipe_q <= pipe[PIPELINES];
    end
  end

endmodule
