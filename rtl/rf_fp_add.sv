// rf_fp_add: IEEE-754 binary32 addition, y = a + b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a + b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and inf + (-inf), give the canonical quiet NaN 32'h7FC00000;
//   * inf + finite = that inf;
//   * an exact zero sum is +0, except (-0) + (-0) = -0 (the RNE rule);
//   * subtraction is a + {~b[31], b[30:0]}: callers flip the sign of b.
//
// Structure: classify -> special cases -> swap so |A| >= |B| -> align B with guard, round and
// sticky bits -> add/subtract magnitudes -> normalise (leading-zero count) -> rf_fp_round.
//
// Alignment keeps three bits below the 24-bit significand: guard and round exactly, and a sticky
// bit that is the OR of everything shifted further out.  That is enough: bits are only lost when
// the exponent difference is >= 4, and then an effective subtraction cancels at most one leading
// bit, so the sticky bit always stays below the round position.  Massive cancellation only
// happens for exponent differences 0 and 1, where the aligned operands are exact.
module rf_fp_add (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;

  // ---------------------------------------------------------------------------------------------
  // Classify
  logic a_nan, b_nan, a_inf, b_inf;

  always_comb begin
    a_nan = (a_i[30:23] == 8'hFF) & (a_i[22:0] != 23'd0);
    b_nan = (b_i[30:23] == 8'hFF) & (b_i[22:0] != 23'd0);
    a_inf = (a_i[30:23] == 8'hFF) & (a_i[22:0] == 23'd0);
    b_inf = (b_i[30:23] == 8'hFF) & (b_i[22:0] == 23'd0);
  end

  // ---------------------------------------------------------------------------------------------
  // Special cases: NaN, infinities
  logic        special;
  logic [31:0] special_result;

  always_comb begin
    special        = a_nan | b_nan | a_inf | b_inf;
    special_result = CanonicalNaN;
    if (a_nan | b_nan | (a_inf & b_inf & (a_i[31] != b_i[31]))) begin
      special_result = CanonicalNaN;
    end else if (a_inf) begin
      special_result = a_i;
    end else if (b_inf) begin
      special_result = b_i;
    end
  end

  // ---------------------------------------------------------------------------------------------
  // Swap so that operand A has the larger magnitude; unpack (hidden bit, subnormal exponent 1)
  logic        big_sign, small_sign;
  logic [7:0]  big_exp, small_exp;
  logic [23:0] big_sig, small_sig;
  logic [7:0]  exp_diff;

  always_comb begin
    logic [31:0] big_op, small_op;
    if (b_i[30:0] > a_i[30:0]) begin
      big_op   = b_i;
      small_op = a_i;
    end else begin
      big_op   = a_i;
      small_op = b_i;
    end
    big_sign   = big_op[31];
    small_sign = small_op[31];
    big_exp    = (big_op[30:23] == 8'd0) ? 8'd1 : big_op[30:23];
    small_exp  = (small_op[30:23] == 8'd0) ? 8'd1 : small_op[30:23];
    big_sig    = {big_op[30:23] != 8'd0, big_op[22:0]};
    small_sig  = {small_op[30:23] != 8'd0, small_op[22:0]};
    exp_diff   = big_exp - small_exp;
  end

  // ---------------------------------------------------------------------------------------------
  // Align the smaller operand: {significand, guard, round} plus a sticky bit
  logic [26:0] big_ext, small_ext;

  always_comb begin
    logic [4:0]  align_shift;
    logic [50:0] aligned;  // {small_sig, 27 bits catching what is shifted out}
    align_shift = (exp_diff > 8'd27) ? 5'd27 : exp_diff[4:0];
    aligned     = {small_sig, 27'd0} >> align_shift;
    big_ext     = {big_sig, 3'b000};
    small_ext   = {aligned[50:25], |aligned[24:0]};
  end

  // ---------------------------------------------------------------------------------------------
  // Add or subtract magnitudes (never negative: |A| >= |B|), then normalise
  logic [27:0]       sum;  // sum[26] has the weight of big_sig's integer bit
  logic [4:0]        lzc;  // leading zeros of sum; irrelevant for sum == 0 (the rounder's case)
  logic [27:0]       sum_norm;
  logic              sum_sign;
  logic signed [9:0] sum_exp;

  rf_fp_normalize #(.W(28)) u_norm (.x_i(sum), .y_o(sum_norm), .count_o(lzc));

  always_comb begin
    if (big_sign != small_sign) begin
      sum = {1'b0, big_ext} - {1'b0, small_ext};
    end else begin
      sum = {1'b0, big_ext} + {1'b0, small_ext};
    end

    sum_exp  = $signed({2'b00, big_exp}) + 10'sd1 - $signed({5'd0, lzc});

    // Exact zero: +0 unless both operands are negative (only possible for (-0) + (-0)).
    sum_sign = (sum == 28'd0) ? (a_i[31] & b_i[31]) : big_sign;
  end

  // ---------------------------------------------------------------------------------------------
  // Round (the shared rounding module) and select the result
  logic [31:0] rounded;

  rf_fp_round u_round (
    .sign_i   (sum_sign),
    .exp_i    (sum_exp),
    .sig_i    (sum_norm[27:3]),
    .sticky_i (|sum_norm[2:0]),
    .y_o      (rounded)
  );

  assign y_o = special ? special_result : rounded;

endmodule
