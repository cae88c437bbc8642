// rf_fp_mul: IEEE-754 binary32 multiplication, y = a * b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a * b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and 0 * inf, give the canonical quiet NaN 32'h7FC00000;
//   * the sign of every non-NaN result (zeros and infinities included) is sign(a) xor sign(b).
//
// Structure: classify -> special cases (NaN, inf, zero operands) -> exact 24x24-bit product ->
// normalise (rf_fp_normalize: a leading-zero count over the whole product, so subnormal operands
// need no separate pre-normalisation) -> round (rf_fp_round) -> select.  The product is exact up
// to the rounder: its low 32 bits are only OR-ed into the sticky bit after normalisation.
//
// The special cases and the datapath are the two branches of one always_comb; in hardware both
// exist and the final select picks one.  The simulation evaluates only the branch taken, and the
// special branch leaves a zero product, for which the normaliser and rounder skip their work: a
// unit fed +0 * +0 (operand isolation of an idle unit in a pool) costs little to simulate.
module rf_fp_mul (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  // ---------------------------------------------------------------------------------------------
  // Classify, special cases and the exact product
  logic              sign;
  logic              special;
  logic [31:0]       special_result;
  logic [63:0]       prod;      // 48-bit product, left aligned: prod[62] has weight
                                //   2^(exp_a + exp_b - 254)
  logic signed [9:0] prod_exp;  // biased exponent of bit 63 of prod (before normalisation)

  always_comb begin
    logic a_zero, b_zero, a_max_exp, b_max_exp;
    a_zero    = (a_i[30:0] == 31'd0);
    b_zero    = (b_i[30:0] == 31'd0);
    a_max_exp = (a_i[30:23] == 8'hFF);                  // inf or NaN
    b_max_exp = (b_i[30:23] == 8'hFF);
    sign      = a_i[31] ^ b_i[31];
    special   = a_zero | b_zero | a_max_exp | b_max_exp;

    special_result = '0;
    prod           = '0;
    prod_exp       = '0;
    if (special) begin
      if (a_zero | b_zero) begin
        special_result = (a_max_exp | b_max_exp) ? CanonicalNaN       // 0 * inf, 0 * NaN
                                                 : {sign, 31'd0};     // 0 * finite
      end else if ((a_i[30:0] > InfMagnitude) | (b_i[30:0] > InfMagnitude)) begin
        special_result = CanonicalNaN;                                // NaN operand
      end else begin
        special_result = {sign, 8'hFF, 23'd0};                        // inf * non-zero
      end
    end else begin
      // Datapath: hidden bit set for normals; subnormals have exponent 1 and no hidden bit.
      // Bit 63 of prod has weight 2^(exp_a + exp_b - 254 + 1), i.e. biased exponent
      // exp_a + exp_b - 126. Normal operands leave the leading one in bit 63 or 62.
      prod     = {48'({a_i[30:23] != 8'd0, a_i[22:0]}) * 48'({b_i[30:23] != 8'd0, b_i[22:0]}),
                  16'd0};
      prod_exp = $signed({2'b00, a_i[30:23]}) + $signed({2'b00, b_i[30:23]})
               + $signed(10'(a_i[30:23] == 8'd0)) + $signed(10'(b_i[30:23] == 8'd0)) - 10'sd126;
    end
  end

  // ---------------------------------------------------------------------------------------------
  // Normalise, round (the shared rounding module) and select the result
  logic [63:0] prod_norm;
  logic [5:0]  lzc;             // leading zeros of prod (0 for the zero product)
  logic [31:0] rounded;

  rf_fp_normalize #(.W(64)) u_norm (.x_i(prod), .y_o(prod_norm), .count_o(lzc));

  rf_fp_round u_round (
    .sign_i (sign),
    .exp_i  (prod_exp - $signed({4'd0, lzc})),
    .sig_i  ({prod_norm[63:33], prod_norm[32] | (prod_norm[31:0] != 32'd0)}),
    .y_o    (rounded)
  );

  assign y_o = special ? special_result : rounded;

endmodule
