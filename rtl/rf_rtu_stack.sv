// Traversal stacks: one circular stack of STACK_DEPTH node pointers per ray slot, in one RAM of
// RAYS x STACK_DEPTH entries (PUSHES write ports: push, one per response stage; one read port:
// the top of the slot being popped).
//
// Contract (all ports act on the rising edge; the caller never pushes and pops, or clears, the
// same slot in one cycle, nor pushes one slot on two push ports):
//   * clear_i (slot clear_slot_i): empties the slot's stack and forgets its spilled entries (a
//     new ray; a finished ray's stack is left as it is until then);
//   * push_i[p] (slot push_slot_i[p], pointer push_ptr_i[p]; p < PUSHES, each port its own
//     slot): the entry goes on top. When the stack already holds STACK_DEPTH entries it
//     overwrites the oldest (bottom) one, which leaves in the same cycle on spill_o[p] (overflow:
//     spill_ptr_o[p], for slot push_slot_i[p]) to the slot's spill area in memory; the slot's
//     count of spilled entries goes up by one;
//   * top_o / empty_o / spilled_o describe the slot pop_slot_i (combinational from the RAM and the
//     slot's pointers: a read port with no latency); pop_i removes that top entry;
//   * refill_i (slot pop_slot_i, only while its stack is empty and spilled_o): the caller reads
//     the most recently spilled entry back from memory; the count goes down by one;
//   * depth_o: the most entries any slot has held since reset (for max_stack_depth).
// The spilled entries are the oldest, so an empty stack's next entry is the last one spilled:
// the pops come in the order of an unbounded stack, and so do the requests and every hit
// (docs/rtunit_rtl.md#stack-overflow).
// With CULL (the distance-culled stack, docs/rtunit_rtl.md#the-culling-stack) every entry also
// holds its entry distance push_dist_i[p] (a binary32, in a second RAM of RAYS x STACK_DEPTH
// words): top_dist_o is the top entry's, and a spilled entry leaves with its distance on
// spill_dist_o[p]. Without CULL there is no distance RAM and both outputs are 0.
module rf_rtu_stack #(
  parameter int unsigned RAYS        = 4,
  parameter int unsigned STACK_DEPTH = 8,
  parameter int unsigned PUSHES      = 1,
  parameter bit          CULL        = 1'b0,
  localparam int unsigned SLOT_W  = RAYS > 1 ? $clog2(RAYS) : 1,
  localparam int unsigned IDX_W   = STACK_DEPTH > 1 ? $clog2(STACK_DEPTH) : 1,
  localparam int unsigned COUNT_W = $clog2(STACK_DEPTH + 1)
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              clear_i,
  input  logic [SLOT_W-1:0] clear_slot_i,
  input  logic [PUSHES-1:0]             push_i,
  input  logic [PUSHES-1:0][SLOT_W-1:0] push_slot_i,
  input  logic [PUSHES-1:0][31:0]       push_ptr_i,
  input  logic [PUSHES-1:0][31:0]       push_dist_i,
  input  logic [SLOT_W-1:0] pop_slot_i,
  input  logic              pop_i,
  input  logic              refill_i,
  output logic [31:0]       top_o,
  output logic [31:0]       top_dist_o,
  output logic              empty_o,
  output logic              spilled_o,
  output logic [PUSHES-1:0]       spill_o,
  output logic [PUSHES-1:0][31:0] spill_ptr_o,
  output logic [PUSHES-1:0][31:0] spill_dist_o,
  output logic [COUNT_W-1:0] depth_o
);

  logic [31:0]        ram_q   [RAYS][STACK_DEPTH];
  logic [IDX_W-1:0]   next_q  [RAYS];     // the entry the next push writes (top + 1, circular)
  logic [COUNT_W-1:0] count_q [RAYS];     // entries held, 0..STACK_DEPTH
  logic [31:0]        spilled_q [RAYS];   // entries in the slot's spill area
  logic [COUNT_W-1:0] depth_q;

  function automatic logic [IDX_W-1:0] wrap_inc(input logic [IDX_W-1:0] i);
    return (32'(i) == STACK_DEPTH - 1) ? '0 : i + 1'b1;
  endfunction
  function automatic logic [IDX_W-1:0] wrap_dec(input logic [IDX_W-1:0] i);
    return (i == '0) ? IDX_W'(STACK_DEPTH - 1) : i - 1'b1;
  endfunction

  logic [IDX_W-1:0] top_idx;
  assign top_idx    = wrap_dec(next_q[pop_slot_i]);
  assign top_o      = ram_q[pop_slot_i][top_idx];
  assign empty_o    = count_q[pop_slot_i] == '0;
  assign spilled_o  = spilled_q[pop_slot_i] != '0;
  for (genvar p = 0; p < PUSHES; p++) begin : g_spill
    assign spill_o[p]     = push_i[p] && 32'(count_q[push_slot_i[p]]) == STACK_DEPTH;
    assign spill_ptr_o[p] = ram_q[push_slot_i[p]][next_q[push_slot_i[p]]];
  end
  assign depth_o    = depth_q;

  // the deepest stack after this cycle's pushes (each onto its own slot)
  logic [COUNT_W-1:0] depth_d;
  always_comb begin
    depth_d = depth_q;
    for (int p = 0; p < PUSHES; p++)
      if (push_i[p] && !spill_o[p] && count_q[push_slot_i[p]] + 1'b1 > depth_d)
        depth_d = count_q[push_slot_i[p]] + 1'b1;
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      for (int i = 0; i < RAYS; i++) begin
        next_q[i]    <= '0;
        count_q[i]   <= '0;
        spilled_q[i] <= '0;
      end
      depth_q <= '0;
    end else begin
      if (clear_i) begin
        count_q[clear_slot_i]   <= '0;
        spilled_q[clear_slot_i] <= '0;
      end
      if (pop_i) begin
        next_q[pop_slot_i]  <= top_idx;
        count_q[pop_slot_i] <= count_q[pop_slot_i] - 1'b1;
      end
      if (refill_i) spilled_q[pop_slot_i] <= spilled_q[pop_slot_i] - 1'b1;
      for (int p = 0; p < PUSHES; p++) begin
        if (push_i[p]) begin
          next_q[push_slot_i[p]] <= wrap_inc(next_q[push_slot_i[p]]);
          if (spill_o[p]) spilled_q[push_slot_i[p]] <= spilled_q[push_slot_i[p]] + 1'b1;
          else            count_q[push_slot_i[p]]   <= count_q[push_slot_i[p]] + 1'b1;
        end
      end
      depth_q <= depth_d;
    end
  end

  always_ff @(posedge clk_i) begin
    for (int p = 0; p < PUSHES; p++)
      if (push_i[p]) ram_q[push_slot_i[p]][next_q[push_slot_i[p]]] <= push_ptr_i[p];
  end

  // ---- the entry distances (CULL only) ----
  if (CULL) begin : g_dist
    logic [31:0] dist_q [RAYS][STACK_DEPTH];
    assign top_dist_o = dist_q[pop_slot_i][top_idx];
    for (genvar p = 0; p < PUSHES; p++) begin : g_spill_dist
      assign spill_dist_o[p] = dist_q[push_slot_i[p]][next_q[push_slot_i[p]]];
    end
    always_ff @(posedge clk_i) begin
      for (int p = 0; p < PUSHES; p++)
        if (push_i[p]) dist_q[push_slot_i[p]][next_q[push_slot_i[p]]] <= push_dist_i[p];
    end
  end else begin : g_no_dist
    assign top_dist_o   = '0;
    assign spill_dist_o = '0;
    logic unused_dist;
    assign unused_dist = ^push_dist_i;
  end

endmodule
