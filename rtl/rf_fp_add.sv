// rf_fp_add: IEEE-754 binary32 addition, y = a + b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a + b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and inf + (-inf), give the canonical quiet NaN 32'h7FC00000;
//   * inf + finite = that inf;
//   * an exact zero sum is +0, except (-0) + (-0) = -0 (the RNE rule);
//   * subtraction is a + {~b[31], b[30:0]}: callers flip the sign of b.
//
// Structure: order the operands by magnitude (|A| >= |B|) -> classify into
//   * both normal (the common case, two compares) -> datapath;
//   * special cases: A is NaN or inf, B is zero (NaN, inf, A, or the signed zero sum);
//   * B subnormal, A normal or subnormal (exponent 1, no hidden bit) -> datapath;
// datapath: align B -> add/subtract the magnitudes -> normalise: a carry out, the leading one in
// place or one bit cancelled are selected directly; only massive cancellation (exponent
// difference 0 or 1) counts leading zeros (rf_fp_pkg::fp_lzc32) -> round (rf_fp_pkg::fp_round,
// the one rounder; it tests the normal result range first).
//
// Ordering first makes classification cheap: the 31-bit {exponent, fraction} field is monotonic in
// |x|, so a NaN or inf operand is always A and a zero operand is always B.
//
// The significands sit in a 32-bit frame: bit 31 takes the carry of an addition, bits 30:7 hold
// the 24-bit significand, bits 6:0 are guard, round and sticky space.  Aligning B shifts it right
// and ORs everything shifted out into bit 0 (sticky, a mask of the shifted-out bits).  That is
// exact enough: bits are only lost when the exponent difference is >= 8, and then an effective
// subtraction cancels at most one leading bit, so the sticky bit stays below the round position.
// Massive cancellation only happens for exponent differences 0 and 1, where the aligned operands
// are exact.
//
// Everything is one always_comb computing y_o; in hardware its branches all exist and the result
// select picks one.  The simulation evaluates only the branch taken: a unit fed +0 + +0 (operand
// isolation of an idle unit in a pool) costs a few compares, a normal sum skips the leading-zero
// count.  Verilator note: a block variable is a C++ local only if it is assigned at the top level
// of the block (hence the defaults below), and a function called inside a branch keeps its
// temporaries in the model; so the rounder is called at the top level (for a special case it
// sees sig == 0 and returns at once) and fp_lzc32 only on the rare massive-cancellation path.
module rf_fp_add
  import rf_fp_pkg::*;
(
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  always_comb begin
    logic [31:0]       big_op, small_op;
    logic              sub;              // effective subtraction
    logic              datapath;         // else y_o is set by a special case
    logic [7:0]        big_exp, small_exp;        // exponents (1 for a subnormal)
    logic              big_hidden, small_hidden;  // hidden bits (0 for a subnormal)
    logic [7:0]        exp_diff;
    logic [4:0]        shift, lzc;
    logic [31:0]       big_w, small_w, aligned, sum, sig;
    logic signed [9:0] exp;
    logic [31:0]       rounded;

    big_op       = (b_i[30:0] > a_i[30:0]) ? b_i : a_i;
    small_op     = (b_i[30:0] > a_i[30:0]) ? a_i : b_i;
    sub          = big_op[31] ^ small_op[31];
    datapath     = 1'b0;
    big_exp      = big_op[30:23];
    big_hidden   = 1'b1;
    small_exp    = '0;
    small_hidden = 1'b0;
    exp_diff     = '0;
    shift        = '0;
    lzc          = '0;
    big_w        = '0;
    small_w      = '0;
    aligned      = '0;
    sum          = '0;
    sig          = '0;
    exp          = '0;
    y_o          = '0;

    if ((small_op[30:23] != 8'd0) && (big_op[30:23] != 8'hFF)) begin
      // Both normal (the common case: two compares)
      datapath     = 1'b1;
      small_exp    = small_op[30:23];
      small_hidden = 1'b1;
    end else if (big_op[30:23] == 8'hFF) begin
      // A is NaN or inf
      y_o = ((big_op[30:0] > InfMagnitude) | ((small_op[30:0] == InfMagnitude) & sub))
          ? CanonicalNaN                                    // NaN operand, or inf - inf
          : big_op;                                         // inf + x
    end else if (small_op[30:0] == 31'd0) begin
      // B is a zero
      y_o = (big_op[30:0] == 31'd0) ? {a_i[31] & b_i[31], 31'd0}  // -0 only for (-0) + (-0)
                                    : big_op;                     // x + zero
    end else begin
      // B subnormal (exponent 1, no hidden bit), and A normal or subnormal too
      datapath     = 1'b1;
      small_exp    = 8'd1;
      small_hidden = 1'b0;
      if (big_op[30:23] == 8'd0) begin
        big_exp    = 8'd1;
        big_hidden = 1'b0;
      end
    end

    if (datapath) begin
      // Align B (sticky: a mask of the bits shifted out), add or subtract (never negative:
      // |A| >= |B|), and normalise so that bit 31 of sig is the leading one, of exponent exp
      exp_diff = big_exp - small_exp;
      shift    = (exp_diff > 8'd31) ? 5'd31 : exp_diff[4:0];
      big_w    = {1'b0, big_hidden, big_op[22:0], 7'd0};
      small_w  = {1'b0, small_hidden, small_op[22:0], 7'd0};
      aligned  = (small_w >> shift) | 32'((small_w & ~(32'hFFFF_FFFF << shift)) != 32'd0);
      sum      = sub ? big_w - aligned : big_w + aligned;
      if (sum[31]) begin                                   // carry out of an addition
        sig = sum;
        exp = $signed({2'b00, big_exp}) + 10'sd1;
      end else if (sum[30]) begin                          // leading one in place
        sig = sum << 1;
        exp = $signed({2'b00, big_exp});
      end else if (sum[29]) begin                          // one bit cancelled (any subtraction)
        sig = sum << 2;
        exp = $signed({2'b00, big_exp}) - 10'sd1;
      end else begin
        // Massive cancellation (exponent difference 0 or 1: exact); sum == 0 gives sig == 0
        lzc = fp_lzc32(sum);
        sig = sum << lzc;
        exp = $signed({2'b00, big_exp}) + 10'sd1 - $signed({5'd0, lzc});
      end
    end
    // The one rounder (exact cancellation, sig == 0, gives +0); idle for the special cases
    rounded = fp_round(big_op[31] & (sig != 32'd0), exp, sig);
    if (datapath) y_o = rounded;
  end

endmodule
