// rf_fp_add: IEEE-754 binary32 addition, y = a + b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a + b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and inf + (-inf), give the canonical quiet NaN 32'h7FC00000;
//   * inf + finite = that inf;
//   * an exact zero sum is +0, except (-0) + (-0) = -0 (the RNE rule);
//   * subtraction is a + {~b[31], b[30:0]}: callers flip the sign of b.
//
// Structure: order the operands by magnitude (|A| >= |B|) -> classify -> special cases (NaN, inf,
// a zero operand) -> align B -> add/subtract magnitudes -> normalise (rf_fp_normalize) -> round
// (rf_fp_round) -> select.
//
// Ordering first makes classification cheap: the 31-bit {exponent, fraction} field is monotonic in
// |x|, so a NaN or inf operand is always A and a zero operand is always B.
//
// The significands sit in a 32-bit frame: bit 31 takes the carry of an addition, bits 30:7 hold
// the 24-bit significand, bits 6:0 are guard, round and sticky space.  Aligning B shifts it right
// and ORs everything shifted out into bit 0 (sticky).  That is exact enough: bits are only lost
// when the exponent difference is >= 8, and then an effective subtraction cancels at most one
// leading bit, so the sticky bit stays below the round position.  Massive cancellation only happens
// for exponent differences 0 and 1, where the aligned operands are exact.
//
// The special cases and the datapath are the two branches of one always_comb; in hardware both
// exist and the final select picks one.  The simulation evaluates only the branch taken, and the
// datapath branch leaves zeros for the normaliser and rounder, which then skip their work: a unit
// fed +0 + +0 (operand isolation of an idle unit in a pool) costs little to simulate.
module rf_fp_add (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  // ---------------------------------------------------------------------------------------------
  // Order, classify, special cases, align and add
  logic              special;
  logic [31:0]       special_result;
  logic [31:0]       sum;       // sum[30] has the weight of A's integer bit
  logic              sum_sign;
  logic signed [9:0] sum_exp;   // biased exponent of sum[31]

  always_comb begin
    logic [31:0] big_op, small_op;
    logic [7:0]  big_exp, small_exp, exp_diff;
    logic [31:0] big_w, small_w;
    logic [63:0] aligned;       // {small_w, 32 bits catching what is shifted out}

    big_op         = (b_i[30:0] > a_i[30:0]) ? b_i : a_i;
    small_op       = (b_i[30:0] > a_i[30:0]) ? a_i : b_i;
    special        = (big_op[30:23] == 8'hFF) | (small_op[30:0] == 31'd0);
    special_result = '0;
    big_exp        = '0;
    small_exp      = '0;
    exp_diff       = '0;
    big_w          = '0;
    small_w        = '0;
    aligned        = '0;
    sum            = '0;
    sum_sign       = 1'b0;
    sum_exp        = '0;

    if (special) begin
      // A is a NaN or inf, or B is a zero
      if (big_op[30:0] == 31'd0) begin
        special_result = {a_i[31] & b_i[31], 31'd0};    // zero + zero: -0 only for (-0) + (-0)
      end else if ((big_op[30:0] > InfMagnitude)
                   | ((small_op[30:0] == InfMagnitude) & (small_op[31] != big_op[31]))) begin
        special_result = CanonicalNaN;                  // NaN operand, or inf - inf
      end else begin
        special_result = big_op;                        // inf + x, or x + zero
      end
    end else begin
      // Datapath: finite non-zero operands; subnormals have exponent 1 and no hidden bit
      big_exp   = (big_op[30:23] == 8'd0) ? 8'd1 : big_op[30:23];
      small_exp = (small_op[30:23] == 8'd0) ? 8'd1 : small_op[30:23];
      exp_diff  = big_exp - small_exp;
      big_w     = {1'b0, big_op[30:23] != 8'd0, big_op[22:0], 7'd0};
      small_w   = {1'b0, small_op[30:23] != 8'd0, small_op[22:0], 7'd0};
      aligned   = {small_w, 32'd0} >> ((exp_diff > 8'd31) ? 5'd31 : exp_diff[4:0]);
      if (big_op[31] != small_op[31]) begin             // never negative: |A| >= |B|
        sum = big_w - {aligned[63:33], aligned[32] | (aligned[31:0] != 32'd0)};
      end else begin
        sum = big_w + {aligned[63:33], aligned[32] | (aligned[31:0] != 32'd0)};
      end
      sum_sign = (sum == 32'd0) ? 1'b0 : big_op[31];    // exact cancellation gives +0
      sum_exp  = $signed({2'b00, big_exp}) + 10'sd1;
    end
  end

  // ---------------------------------------------------------------------------------------------
  // Normalise, round (the shared rounding module) and select the result
  logic [31:0] sum_norm;
  logic [4:0]  lzc;             // leading zeros of sum (0 for sum == 0: the rounder's zero case)
  logic [31:0] rounded;

  rf_fp_normalize #(.W(32)) u_norm (.x_i(sum), .y_o(sum_norm), .count_o(lzc));

  rf_fp_round u_round (
    .sign_i (sum_sign),
    .exp_i  (sum_exp - $signed({5'd0, lzc})),
    .sig_i  (sum_norm),
    .y_o    (rounded)
  );

  assign y_o = special ? special_result : rounded;

endmodule
