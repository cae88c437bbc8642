// Scheduler: each cycle picks one ray slot whose node is in the node buffer (round robin from the
// slot after the last one issued) and offers the datapath its request: the slot's prepared ray,
// extent = the ray's nearest t, tag = the slot, and by the node's kind (rf_rtu_pkg::kind_e):
// QUADBOX with a box32 node's four child boxes, or with a q8 node as stored (the request's qnode)
// and the flag DECODE_Q8; TRIANGLE with a triangle node's triangle, a pair leaf's triangle 0
// (v0, v1, v2) or its triangle 1 (v[i0], v[i1], v[i2], the selectors in idx bits 5:0);
// TRANSFORM of the ray (outside instances: its world ray) by an instance node's world_to_object
// (the request's matrix, box words 0..11).
//
// Contract:
//   * ready_i: one bit per slot whose request may issue; kind_i: per slot, its node's kind;
//   * rd_o names the slot offered this cycle; ray_i, nearest_i and node_i are that slot's ray,
//     nearest t and node (the buffers' combinational read ports);
//   * dp (valid/ready) drives the datapath's input: dp_valid_o = some slot is ready; a request
//     moves when dp_ready_i is high, and then issue_o pulses with issue_slot_o, issue_box_o and
//     issue_xf_o (the caller moves the slot on and counts the op).
module rf_rtu_sched import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS = 4,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic [RAYS-1:0]   ready_i,
  input  kind_e [RAYS-1:0]  kind_i,
  output logic [SLOT_W-1:0] rd_o,
  input  ray_t              ray_i,
  input  logic [31:0]       nearest_i,
  input  logic [NODE_W-1:0] node_i,
  output logic              dp_valid_o,
  input  logic              dp_ready_i,
  output req_t              dp_req_o,
  output logic              issue_o,
  output logic [SLOT_W-1:0] issue_slot_o,
  output logic              issue_box_o,
  output logic              issue_xf_o
);

  localparam int unsigned REQ_W = $bits(req_t);

  logic [SLOT_W-1:0] next_q;      // round-robin start
  rf_rr_pick #(.N(RAYS)) u_pick (
    .req_i(ready_i), .start_i(next_q), .valid_o(dp_valid_o), .idx_o(rd_o));

  logic [REQ_W-1:0] w;
  logic             box, xf;
  kind_e            kind;
  logic [5:0]       sel;
  assign kind = kind_i[rd_o];
  assign box  = kind == KIND_BOX32 || kind == KIND_Q8;
  assign xf   = kind == KIND_XF;
  assign sel  = node_i[PAIR_NODE_IDX_WORD*32 +: 6];
  always_comb begin
    w = '0;
    w[RAY_WORDS*32-1:32] = ray_i;
    w[31:0] = 32'(rd_o);                                       // tag = slot
    w[32+:3] = box ? OP_QUADBOX : xf ? OP_TRANSFORM : OP_TRIANGLE;  // opcode (word 1 bits 2:0)
    w[REQ_EXTENT_WORD*32+:32] = nearest_i;
    unique case (kind)
      KIND_BOX32: w[REQ_BOX_WORD*32+:24*32] = node_i[BOX_NODE_BOX_WORD*32+:24*32];
      KIND_Q8: begin
        w[REQ_BOX_WORD*32+:Q8_NODE_WORDS*32] = node_i[0+:Q8_NODE_WORDS*32];
        w[REQ_FLAGS_LSB + FLAG_DECODE_Q8_BIT] = 1'b1;
      end
      KIND_XF:
        w[REQ_BOX_WORD*32+:MATRIX_WORDS*32] =
            node_i[INST_NODE_M_WORD*32+:MATRIX_WORDS*32];
      KIND_PAIR1:
        for (int j = 0; j < 3; j++)
          w[(REQ_TRI_WORD + 3*j)*32+:3*32] =
              node_i[(PAIR_NODE_V_WORD + 3*32'(sel[2*j+:2]))*32+:3*32];
      default: w[REQ_TRI_WORD*32+:9*32] = node_i[TRI_NODE_TRI_WORD*32+:9*32];  // = v0, v1, v2
    endcase
  end
  assign dp_req_o = req_t'(w);

  assign issue_o      = dp_valid_o & dp_ready_i;
  assign issue_slot_o = rd_o;
  assign issue_box_o  = box;
  assign issue_xf_o   = xf;

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) next_q <= '0;
    else if (issue_o) next_q <= (32'(rd_o) == RAYS - 1) ? '0 : rd_o + 1'b1;
  end

endmodule
