// rf_fp_cmp: IEEE-754 binary32 quiet comparisons of a and b.
//
// Contract (the same as numpy float32 <, <=, == and isnan(a) | isnan(b)):
//   * unord_o = a or b is a NaN (quiet or signalling); then lt_o, le_o and eq_o are all 0;
//   * -0 == +0 (eq_o = 1, lt_o = 0, le_o = 1);
//   * otherwise lt_o/le_o/eq_o follow the order of the real numbers, with -inf < finite < +inf.
//
// Structure: classify -> order of the magnitudes (the 31-bit {exponent, fraction} field is
// monotonic in |x|, subnormals included) -> sign rules.
module rf_fp_cmp (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic        lt_o,
  output logic        le_o,
  output logic        eq_o,
  output logic        unord_o
);

  logic a_nan, b_nan, both_zero;
  logic mag_lt, mag_eq;
  logic ordered_lt, ordered_eq;

  always_comb begin
    // Classify
    a_nan     = (a_i[30:23] == 8'hFF) & (a_i[22:0] != 23'd0);
    b_nan     = (b_i[30:23] == 8'hFF) & (b_i[22:0] != 23'd0);
    both_zero = (a_i[30:0] == 31'd0) & (b_i[30:0] == 31'd0);

    // Order, assuming neither operand is a NaN
    mag_lt = a_i[30:0] < b_i[30:0];
    mag_eq = a_i[30:0] == b_i[30:0];
    ordered_eq = both_zero | (a_i == b_i);
    if (a_i[31] != b_i[31]) begin
      ordered_lt = a_i[31] & ~both_zero;       // negative < positive, but -0 == +0
    end else if (a_i[31]) begin
      ordered_lt = ~mag_lt & ~mag_eq;          // both negative: larger magnitude is smaller
    end else begin
      ordered_lt = mag_lt;                     // both positive
    end

    // Unordered operands compare false
    unord_o = a_nan | b_nan;
    lt_o    = ~unord_o & ordered_lt;
    eq_o    = ~unord_o & ordered_eq;
    le_o    = ~unord_o & (ordered_lt | ordered_eq);
  end

endmodule
