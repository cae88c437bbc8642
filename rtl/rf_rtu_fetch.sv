// Node fetch: turns a ray slot's node pointer into a memory request and keeps the node that
// comes back in the slot's entry of the node buffer (RAYS x 128 bytes) until the slot's next
// fetch.
//
// Contract:
//   * in (valid/ready, slot in_slot_i, pointer in_ptr_i): a pointer of a node type the unit reads
//     (box32 box node: 128 bytes; triangle node, pair leaf: 64 bytes; with Q8, the datapath's
//     decode stage being there, a q8 box node: 64 bytes; with XF, the datapath's TRANSFORM being
//     there, an instance node: 128 bytes) is accepted when in_ready_o is high and
//     becomes one memory request; in_bad_o is high, combinationally, while in_ptr_i names no such
//     type (the caller must not then raise in_valid_i: it finishes the ray with an error). With
//     in_refill_i the request is instead a read of the slot's last spilled stack entry (4 bytes
//     of the slot's spill area, 8 with CULL: the pointer and its entry distance; in_ptr_i is
//     not used);
//   * mem_req (valid/ready): byte address (pointer & ~7) << 3, size in bytes, tag = the slot,
//     refill (a spill-area read: the memory side knows each slot's spill area).
//     mem_req_valid_o and its data are register outputs (rf_skid); in_ready_o is a register
//     output too. Any number of requests may be outstanding (one per slot at most);
//   * mem_rsp (valid/ready, always ready): data (node word 0 at the low end; the words past the
//     node's size are ignored) for the request tagged mem_rsp_tag_i, in any order. It is written
//     into the slot's node buffer entry and done_o pulses with done_slot_o in the same cycle, with
//     done_refill_o, done_ptr_o (data word 0: the spilled pointer) and done_dist_o (word 1: its
//     entry distance, with CULL) for a refill;
//   * node_a_o[p] / node_b_o[p]: the node buffer entries of slots rd_a_i[p] / rd_b_i[p], p < PORTS
//     (combinational read ports: per pipeline, for the scheduler and its response stage).
module rf_rtu_fetch import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS = 4,
  parameter bit          Q8   = 1'b0,
  parameter bit          XF   = 1'b0,
  parameter bit          CULL = 1'b0,
  parameter int unsigned PORTS = 1,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              in_valid_i,
  output logic              in_ready_o,
  input  logic [SLOT_W-1:0] in_slot_i,
  input  logic [31:0]       in_ptr_i,
  input  logic              in_refill_i,
  output logic              in_bad_o,
  output logic              mem_req_valid_o,
  input  logic              mem_req_ready_i,
  output logic [ADDR_W-1:0] mem_req_addr_o,
  output logic [SIZE_W-1:0] mem_req_size_o,
  output logic [SLOT_W-1:0] mem_req_tag_o,
  output logic              mem_req_refill_o,
  input  logic              mem_rsp_valid_i,
  output logic              mem_rsp_ready_o,
  input  logic [NODE_W-1:0] mem_rsp_data_i,
  input  logic [SLOT_W-1:0] mem_rsp_tag_i,
  output logic              done_o,
  output logic [SLOT_W-1:0] done_slot_o,
  output logic              done_refill_o,
  output logic [31:0]       done_ptr_o,
  output logic [31:0]       done_dist_o,
  input  logic [PORTS-1:0][SLOT_W-1:0] rd_a_i,
  output logic [PORTS-1:0][NODE_W-1:0] node_a_o,
  input  logic [PORTS-1:0][SLOT_W-1:0] rd_b_i,
  output logic [PORTS-1:0][NODE_W-1:0] node_b_o
);

  typedef struct packed {
    logic [ADDR_W-1:0] addr;
    logic [SIZE_W-1:0] size;
    logic [SLOT_W-1:0] tag;
    logic              refill;
  } mreq_t;

  logic [2:0] in_type;
  mreq_t      req_d, req_q;
  assign in_type  = in_ptr_i[2:0];
  assign in_bad_o = !(in_type == BOX_TYPE || in_type == TRI_TYPE || in_type == PAIR_TYPE
                     || (Q8 && in_type == Q8_TYPE) || (XF && in_type == INSTANCE_TYPE));
  assign req_d.addr = in_refill_i ? '0 : ADDR_W'({in_ptr_i[31:3], 3'b000}) << PTR_SHIFT;
  assign req_d.size = in_refill_i ? SIZE_W'(CULL ? 8 : 4)
                    : in_type == BOX_TYPE  ? SIZE_W'(BOX_NODE_WORDS * 4)
                    : in_type == Q8_TYPE   ? SIZE_W'(Q8_NODE_WORDS * 4)
                    : in_type == INSTANCE_TYPE ? SIZE_W'(INST_NODE_WORDS * 4)
                    : in_type == PAIR_TYPE ? SIZE_W'(PAIR_NODE_WORDS * 4)
                    :                        SIZE_W'(TRI_NODE_WORDS * 4);
  assign req_d.tag    = in_slot_i;
  assign req_d.refill = in_refill_i;

  rf_skid #(.T(mreq_t)) u_req (
    .clk_i, .rst_ni,
    .valid_i(in_valid_i), .ready_o(in_ready_o), .data_i(req_d),
    .valid_o(mem_req_valid_o), .ready_i(mem_req_ready_i), .data_o(req_q));
  assign mem_req_addr_o = req_q.addr;
  assign mem_req_size_o = req_q.size;
  assign mem_req_tag_o  = req_q.tag;
  assign mem_req_refill_o = req_q.refill;

  // which slots wait for a refill (a slot has one request outstanding at most)
  logic [RAYS-1:0] refill_q;
  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) refill_q <= '0;
    else if (in_valid_i && in_ready_o) refill_q[in_slot_i] <= in_refill_i;
  end
  assign done_refill_o = refill_q[mem_rsp_tag_i];
  assign done_ptr_o    = mem_rsp_data_i[31:0];
  assign done_dist_o   = CULL ? mem_rsp_data_i[63:32] : '0;

  // ---- node buffer ----
  logic [NODE_W-1:0] node_q [RAYS];
  assign mem_rsp_ready_o = 1'b1;
  assign done_o          = mem_rsp_valid_i;
  assign done_slot_o     = mem_rsp_tag_i;
  always_ff @(posedge clk_i) begin
    if (mem_rsp_valid_i) node_q[mem_rsp_tag_i] <= mem_rsp_data_i;
  end
  for (genvar p = 0; p < PORTS; p++) begin : g_read
    assign node_a_o[p] = node_q[rd_a_i[p]];
    assign node_b_o[p] = node_q[rd_b_i[p]];
  end

endmodule
