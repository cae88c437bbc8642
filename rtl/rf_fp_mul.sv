// rf_fp_mul: IEEE-754 binary32 multiplication, y = a * b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a * b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and 0 * inf, give the canonical quiet NaN 32'h7FC00000;
//   * the sign of every non-NaN result (zeros and infinities included) is sign(a) xor sign(b).
//
// Structure: classify -> one of
//   * both operands normal (the common case: two exponent range compares);
//   * special cases (NaN, inf, zero operands, two subnormals: the product is below 2^-252 and
//     rounds to zero);
//   * one subnormal operand: pre-normalise its significand (leading-zero count,
//     rf_fp_pkg::fp_lzc32) to a 24-bit significand with the leading one in bit 23 and an exponent
//     below 1;
// -> for the two datapath cases: exact 24x24-bit product of normalised significands, so its
// leading one is in bit 47 or 46 (a one-bit normalisation, no leading-zero count) -> round (the
// product's low bits are OR-ed into the sticky bit).
//
// The rounding of a result in the normal range is inline; the general rounder handles overflow and
// subnormal results.
//
// Everything is one always_comb computing y_o; in hardware its branches all exist and the result
// select picks one.  The simulation evaluates only the branch taken: a unit fed +0 * +0 (operand
// isolation of an idle unit in a pool) costs a few compares.  Verilator note: a block variable is a
// C++ local only if it is assigned at the top level of the block (hence the defaults below), and a
// function called inside a branch keeps its temporaries in the model, so the package functions are
// only called on the rare paths.
module rf_fp_mul
  import rf_fp_pkg::*;
(
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  always_comb begin
    logic              sign;
    logic              datapath;        // else the special-case result
    logic [31:0]       special_y;
    logic [23:0]       sig_a, sig_b;    // normalised significands (bit 23 set)
    logic signed [9:0] exp_a, exp_b;    // their biased exponents (below 1 for subnormals)
    logic [22:0]       frac;            // the fraction of a subnormal operand
    logic [4:0]        lzc;
    logic [47:0]       prod;
    logic [31:0]       sig;
    logic signed [9:0] exp;

    sign      = a_i[31] ^ b_i[31];
    datapath  = 1'b1;
    special_y = '0;
    sig_a     = '0;
    sig_b     = '0;
    exp_a     = '0;
    exp_b     = '0;
    frac      = '0;
    lzc       = '0;
    prod      = '0;
    sig       = '0;
    exp       = '0;
    if ((8'(a_i[30:23] - 8'd1) < 8'd254) && (8'(b_i[30:23] - 8'd1) < 8'd254)) begin
      // Both normal (the common case: two compares)
      sig_a = {1'b1, a_i[22:0]};
      sig_b = {1'b1, b_i[22:0]};
      exp_a = $signed({2'b00, a_i[30:23]});
      exp_b = $signed({2'b00, b_i[30:23]});
    end else if ((a_i[30:0] == 31'd0) || (b_i[30:0] == 31'd0)) begin
      datapath  = 1'b0;
      special_y = ((a_i[30:23] == 8'hFF) || (b_i[30:23] == 8'hFF))
                ? CanonicalNaN                                  // 0 * inf, 0 * NaN
                : {sign, 31'd0};                                // 0 * finite
    end else if ((a_i[30:0] > InfMagnitude) || (b_i[30:0] > InfMagnitude)) begin
      datapath  = 1'b0;
      special_y = CanonicalNaN;                                 // NaN operand
    end else if ((a_i[30:23] == 8'hFF) || (b_i[30:23] == 8'hFF)) begin
      datapath  = 1'b0;
      special_y = {sign, InfMagnitude};                         // inf * non-zero
    end else if ((a_i[30:23] == 8'd0) && (b_i[30:23] == 8'd0)) begin
      datapath  = 1'b0;
      special_y = {sign, 31'd0};                                // subnormal * subnormal
    end else begin
      // One subnormal operand (exponent 1, no hidden bit): normalise it as A (the product is
      // commutative); the other one, B, is normal
      frac  = (a_i[30:23] == 8'd0) ? a_i[22:0] : b_i[22:0];
      sig_b = (a_i[30:23] == 8'd0) ? {1'b1, b_i[22:0]} : {1'b1, a_i[22:0]};
      exp_b = $signed({2'b00, (a_i[30:23] == 8'd0) ? b_i[30:23] : a_i[30:23]});
      lzc   = fp_lzc32({1'b0, frac, 8'd0});                    // 1..23
      sig_a = {1'b0, frac} << lzc;
      exp_a = 10'sd1 - $signed({5'd0, lzc});
    end

    if (datapath) begin
      // Exact product; bit 46 has the biased exponent exp_a + exp_b - 127: normalise by one bit
      prod = 48'(sig_a) * 48'(sig_b);
      exp  = exp_a + exp_b - 10'sd127;
      if (prod[47]) begin
        sig = {prod[47:17], prod[16:0] != 17'd0};
        exp = exp + 10'sd1;
      end else begin
        sig = {prod[46:16], prod[15:0] != 16'd0};
      end
      if (10'(exp - 10'sd1) < 10'd254) begin
        // Normal result range: round inline (a rounding carry may still reach inf)
        y_o = {sign, {exp[7:0], sig[30:8]} + {30'd0, sig[7] & (sig[8] | (sig[6:0] != 7'd0))}};
      end else begin
        y_o = fp_round(sign, exp, sig);                         // overflow or subnormal range
      end
    end else begin
      y_o = special_y;
    end
  end

endmodule
