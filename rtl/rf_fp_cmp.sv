// rf_fp_cmp: IEEE-754 binary32 quiet comparisons of a and b.
//
// Contract (the same as numpy float32 <, <=, == and isnan(a) | isnan(b)):
//   * unord_o = a or b is a NaN (quiet or signalling); then lt_o, le_o and eq_o are all 0;
//   * -0 == +0 (eq_o = 1, lt_o = 0, le_o = 1);
//   * otherwise lt_o/le_o/eq_o follow numeric order, with -inf < finite < +inf.
//
// Structure: classify -> one unsigned compare of order keys -> zero and NaN rules.  The key of x
// is x with the sign bit inverted for positive x and all bits inverted for negative x: as 32-bit
// unsigned integers the keys of non-NaN values are in the order of the values (the 31-bit
// {exponent, fraction} field is monotonic in |x|, subnormals included), with -0 just below +0.
module rf_fp_cmp (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic        lt_o,
  output logic        le_o,
  output logic        eq_o,
  output logic        unord_o
);

  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  logic        both_zero;
  logic [31:0] a_key, b_key;

  // Classify
  assign unord_o   = (a_i[30:0] > InfMagnitude) | (b_i[30:0] > InfMagnitude);
  assign both_zero = (a_i[30:0] | b_i[30:0]) == 31'd0;

  // Order keys
  assign a_key = a_i[31] ? ~a_i : {1'b1, a_i[30:0]};
  assign b_key = b_i[31] ? ~b_i : {1'b1, b_i[30:0]};

  // -0 == +0; unordered operands compare false
  assign eq_o = ~unord_o & ((a_i == b_i) | both_zero);
  assign lt_o = ~unord_o & ~both_zero & (a_key < b_key);
  assign le_o = lt_o | eq_o;

endmodule
