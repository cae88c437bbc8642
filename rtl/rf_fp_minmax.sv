// rf_fp_minmax: IEEE 754-2019 minimum / maximum of two binary32 values.
//
// Contract:
//   * if a or b is a NaN (quiet or signalling): min_o = max_o = canonical NaN 32'h7FC00000;
//   * otherwise the smaller / larger value by IEEE order (rf_fp_cmp), and for a pair of zeros
//     of opposite sign -0 counts as smaller: min(-0, +0) = -0, max(-0, +0) = +0.
//   * equal operands are returned unchanged.
//
// Structure: rf_fp_cmp for the order -> zero-sign rule -> result select.
module rf_fp_minmax (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] min_o,
  output logic [31:0] max_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;

  logic lt, eq, unord;

  rf_fp_cmp u_cmp (
    .a_i     (a_i),
    .b_i     (b_i),
    .lt_o    (lt),
    /* verilator lint_off PINCONNECTEMPTY */  // le is not needed: lt and eq decide
    .le_o    (),
    /* verilator lint_on PINCONNECTEMPTY */
    .eq_o    (eq),
    .unord_o (unord)
  );

  logic a_first;  // a is the minimum (a < b, or -0 against +0, or a == b)

  always_comb begin
    // eq with different bits can only be -0 versus +0: the negative zero is the minimum.
    a_first = lt | (eq & (a_i[31] | (a_i == b_i)));
    if (unord) begin
      min_o = CanonicalNaN;
      max_o = CanonicalNaN;
    end else begin
      min_o = a_first ? a_i : b_i;
      max_o = a_first ? b_i : a_i;
    end
  end

endmodule
