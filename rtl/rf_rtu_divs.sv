// Divider pool: DIVIDERS binary32 dividers (rf_fp_div: iterative, one division at a time,
// DIV_CYCLES from its input handshake to its result) behind one valid/ready port, for the RT
// unit's t = t_num / t_den.
//
// Contract: in (valid/ready, a_i / b_i, tag_i): a division goes to the lowest-numbered idle
// divider; in_ready_o is high while one is idle (from the dividers' registers only). out
// (valid/ready, q_o, tag_o): the results of finished divisions, the lowest-numbered divider's
// first; results may leave in another order than the divisions came (the tag names each one).
// Every quotient is rf_fp_div's: numpy's float32 a / b, bit for bit. busy_o: dividers holding a
// division (started, finished or waiting to be taken) this cycle.
module rf_rtu_divs #(
  parameter int unsigned DIVIDERS = 2,
  parameter int unsigned TAG_W    = 8,
  localparam int unsigned COUNT_W = $clog2(DIVIDERS + 1)
) (
  input  logic               clk_i,
  input  logic               rst_ni,
  input  logic               in_valid_i,
  output logic               in_ready_o,
  input  logic [31:0]        a_i,
  input  logic [31:0]        b_i,
  input  logic [TAG_W-1:0]   tag_i,
  output logic               out_valid_o,
  input  logic               out_ready_i,
  output logic [31:0]        q_o,
  output logic [TAG_W-1:0]   tag_o,
  output logic [COUNT_W-1:0] busy_o
);

  if (DIVIDERS < 1) begin : g_bad_dividers
    $error("rf_rtu_divs: DIVIDERS must be at least 1");
  end

  logic [DIVIDERS-1:0] ready, valid, take_in, take_out;
  logic [31:0]         q     [DIVIDERS];
  logic [TAG_W-1:0]    tag   [DIVIDERS];

  for (genvar k = 0; k < DIVIDERS; k++) begin : g_div
    rf_fp_div #(.TAG_W(TAG_W)) u_div (
      .clk_i, .rst_ni,
      .in_valid_i(take_in[k]), .in_ready_o(ready[k]), .a_i, .b_i, .tag_i,
      .out_valid_o(valid[k]), .out_ready_i(take_out[k]), .q_o(q[k]), .tag_o(tag[k]));
  end

  // the lowest idle divider takes the division; the lowest finished one gives its result
  always_comb begin
    take_in  = '0;
    take_out = '0;
    q_o      = q[0];
    tag_o    = tag[0];
    for (int k = DIVIDERS - 1; k >= 0; k--) begin
      if (ready[k]) take_in = DIVIDERS'(in_valid_i) << k;
      if (valid[k]) begin
        take_out = DIVIDERS'(out_ready_i) << k;
        q_o      = q[k];
        tag_o    = tag[k];
      end
    end
    busy_o = '0;
    for (int k = 0; k < DIVIDERS; k++) busy_o = busy_o + COUNT_W'(!ready[k]);
  end
  assign in_ready_o  = |ready;
  assign out_valid_o = |valid;

endmodule
