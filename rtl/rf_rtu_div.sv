// rf_rtu_div: IEEE-754 binary32 division q = a / b, round to nearest even, behind one elastic
// register (rf_skid): the RT unit's t = t_num / t_den.
//
// Handshake contract: in (valid/ready, a_i, b_i, tag_i) and out (valid/ready, q_o, tag_o) as
// rf_skid: one division per cycle, the result one cycle after the input handshake while
// out_ready_i is high, in order; in_ready_o and every output are register outputs.
//
// Numbers: subnormal operands and results are kept; x / 0 = inf, 0 / 0 and inf / inf give the
// canonical quiet NaN 0x7FC00000, as does any NaN operand (docs/datapath.md#numbers); otherwise the
// correctly rounded quotient, which is numpy's float32 division. The quotient of the 24-bit
// significands is one wide integer division (a combinational divider: the unit's own interim
// unit, documented in docs/rtunit_rtl.md; an iterative divider would take more cycles).
module rf_rtu_div #(
  parameter int unsigned TAG_W = 1
) (
  input  logic             clk_i,
  input  logic             rst_ni,
  input  logic             in_valid_i,
  output logic             in_ready_o,
  input  logic [31:0]      a_i,
  input  logic [31:0]      b_i,
  input  logic [TAG_W-1:0] tag_i,
  output logic             out_valid_o,
  input  logic             out_ready_i,
  output logic [31:0]      q_o,
  output logic [TAG_W-1:0] tag_o
);

  typedef struct packed {
    logic [31:0]      q;
    logic [TAG_W-1:0] tag;
  } out_t;

  // significand (24 bits, leading one at bit 23) and unbiased-plus-127 exponent of a finite,
  // non-zero operand, subnormals normalised
  function automatic logic [35:0] unpack(input logic [31:0] x);
    logic [23:0]        m;
    logic signed [11:0] e;
    m = {x[30:23] != 8'd0, x[22:0]};
    e = x[30:23] == 8'd0 ? 12'sd1 : 12'(x[30:23]);
    for (int k = 0; k < 24; k++) begin
      if (!m[23]) begin
        m = m << 1;
        e = e - 12'sd1;
      end
    end
    return {e, m};
  endfunction

  logic [31:0] q;
  always_comb begin
    logic sign, a_nan, b_nan, a_inf, b_inf, a_zero, b_zero, up;
    logic [35:0] ua, ub;
    logic [63:0] num, quo, rem, mant, low, half;
    logic signed [11:0] e;
    logic [5:0] sh;
    logic [63:0] bits;
    sign   = a_i[31] ^ b_i[31];
    a_nan  = a_i[30:23] == 8'hFF && a_i[22:0] != 0;
    b_nan  = b_i[30:23] == 8'hFF && b_i[22:0] != 0;
    a_inf  = a_i[30:0] == 31'h7F80_0000;
    b_inf  = b_i[30:0] == 31'h7F80_0000;
    a_zero = a_i[30:0] == 31'd0;
    b_zero = b_i[30:0] == 31'd0;
    ua = unpack(a_i);
    ub = unpack(b_i);
    // quotient of the significands with 26 fraction bits: in (2^25, 2^27)
    num = 64'(ua[23:0]) << 26;
    quo = num / 64'(ub[23:0]);
    rem = num % 64'(ub[23:0]);
    e = ua[35:24] - ub[35:24] + 12'sd127;
    if (!quo[26]) begin
      quo = quo << 1;           // a whole bit more of quotient: the remainder stays sticky
      e = e - 12'sd1;
    end
    // quo: 27 bits, leading one at bit 26; keep 24 (3 more below them), more for a subnormal
    sh = e >= 12'sd1 ? 6'd3 : (12'sd4 - e > 12'sd40 ? 6'd40 : 6'(12'sd4 - e));
    mant = quo >> sh;
    low  = quo & ((64'd1 << sh) - 64'd1);
    half = 64'd1 << (sh - 6'd1);
    up   = low > half || (low == half && (rem != 0 || mant[0]));
    bits = (64'(e >= 12'sd1 ? 12'(e - 12'sd1) : 12'sd0) << 23) + mant + 64'(up);
    if (a_nan || b_nan || (a_inf && b_inf) || (a_zero && b_zero)) q = 32'h7FC0_0000;
    else if (a_inf || b_zero)                                      q = {sign, 31'h7F80_0000};
    else if (a_zero || b_inf)                                      q = {sign, 31'd0};
    else if (bits >= 64'h7F80_0000)                                q = {sign, 31'h7F80_0000};
    else                                                           q = {sign, bits[30:0]};
  end

  out_t out_d, out_q;
  assign out_d = '{q: q, tag: tag_i};
  rf_skid #(.T(out_t)) u_out (
    .clk_i, .rst_ni,
    .valid_i(in_valid_i), .ready_o(in_ready_o), .data_i(out_d),
    .valid_o(out_valid_o), .ready_i(out_ready_i), .data_o(out_q));
  assign q_o   = out_q.q;
  assign tag_o = out_q.tag;

endmodule
