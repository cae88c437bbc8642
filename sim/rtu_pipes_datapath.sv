// A stand-in for the datapath (module rayflex, same parameters and ports) in the module
// testbench (sim/rtu_units_tb_top.sv), so that rf_rtu_pipes is tested alone without compiling
// the datapath's arithmetic (tests/test_rtunit_modules.py; the datapath has its own tests).
//
// Contract, the datapath's as rf_rtu_pipes relies on it: valid/ready; in_ready_o a register
// output; responses in request order, LATENCY cycles after the input handshake while out_ready_i
// stays high (a chain of LATENCY skid buffers, rf_skid: no beat dropped, duplicated or
// reordered under back-pressure). The response is a fixed function of the request's words
// (word 0 at the low end): word 0 (the tag) as requested, word i = 1..16 the XOR of request
// words i, 15 + i, 39 + i and 55 + i (ray, box and triangle words: random bits for every kind
// of request), with the opcode field (word 1 bits 2:0) the request's.
module rayflex import rf_pkg::*; #(
  parameter bit          EXTENDED   = 1'b0,
  parameter bit          DISJOINT   = 1'b0,
  parameter bit          COMPRESSED = 1'b0,
  parameter bit          TRANSFORM  = 1'b0,
  parameter bit          FUSED      = 1'b0,
  parameter bit          SHARED     = 1'b0,
  parameter int unsigned LATENCY    = 11 + 32'(COMPRESSED)
) (
  input  logic clk_i,
  input  logic rst_ni,
  input  logic in_valid_i,
  output logic in_ready_o,
  input  req_t req_i,
  output logic out_valid_o,
  input  logic out_ready_i,
  output rsp_t rsp_o
);

  localparam int unsigned REQ_WORDS = $bits(req_t) / 32;
  localparam int unsigned RSP_WORDS = $bits(rsp_t) / 32;

  logic [REQ_WORDS-1:0][31:0] q;
  logic [RSP_WORDS-1:0][31:0] r;
  assign q = req_i;
  always_comb begin
    r[0] = q[0];
    for (int i = 1; i < RSP_WORDS; i++) r[i] = q[i] ^ q[15 + i] ^ q[39 + i] ^ q[55 + i];
    r[1][2:0] = q[1][2:0];
  end

  logic [LATENCY:0] valid, ready;
  rsp_t             data [LATENCY+1];
  assign valid[0]    = in_valid_i;
  assign in_ready_o  = ready[0];
  assign data[0]     = rsp_t'(r);
  assign out_valid_o = valid[LATENCY];
  assign ready[LATENCY] = out_ready_i;
  assign rsp_o       = data[LATENCY];
  for (genvar s = 0; s < LATENCY; s++) begin : g_reg
    rf_skid #(.T(rsp_t)) u_reg (
      .clk_i, .rst_ni,
      .valid_i(valid[s]), .ready_o(ready[s]), .data_i(data[s]),
      .valid_o(valid[s+1]), .ready_i(ready[s+1]), .data_o(data[s+1]));
  end

endmodule
