// rf_fp_minmax: IEEE 754-2019 minimum / maximum of two binary32 values.
//
// Contract:
//   * if a or b is a NaN (quiet or signalling): min_o = max_o = canonical NaN 32'h7FC00000;
//   * otherwise the smaller / larger value in IEEE order, and for a pair of zeros of opposite
//     sign -0 counts as smaller: min(-0, +0) = -0, max(-0, +0) = +0;
//   * equal operands are returned unchanged.
//
// Structure: classify (NaN) -> one unsigned compare of order keys -> result select.  The order key
// is the one of rf_fp_cmp (sign bit inverted for positive x, all bits inverted for negative x):
// unsigned key order is IEEE order with -0 just below +0, which is exactly the zero rule here.
module rf_fp_minmax (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] min_o,
  output logic [31:0] max_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  logic [31:0] a_key, b_key;
  logic        unord;    // a or b is a NaN
  logic        a_first;  // a is the minimum (a <= b in key order)

  assign unord   = (a_i[30:0] > InfMagnitude) | (b_i[30:0] > InfMagnitude);
  assign a_key   = a_i[31] ? ~a_i : {1'b1, a_i[30:0]};
  assign b_key   = b_i[31] ? ~b_i : {1'b1, b_i[30:0]};
  assign a_first = a_key <= b_key;
  assign min_o   = unord ? CanonicalNaN : a_first ? a_i : b_i;
  assign max_o   = unord ? CanonicalNaN : a_first ? b_i : a_i;

endmodule
