// rf_fp_mul: IEEE-754 binary32 multiplication, y = a * b, round to nearest even.
//
// Contract (bit-exact with numpy float32 a * b):
//   * subnormal inputs and outputs fully supported (no flush to zero);
//   * any NaN input, and 0 * inf, give the canonical quiet NaN 32'h7FC00000;
//   * the sign of every non-NaN result (zeros and infinities included) is sign(a) xor sign(b).
//
// Structure: classify -> special cases -> exact 24x24-bit product -> normalise (leading-zero
// count over the full 48-bit product, so subnormal operands need no separate pre-normalisation)
// -> rf_fp_round.  The product is exact up to the rounder: the low bits are only OR-ed into
// the sticky bit after normalisation.
module rf_fp_mul (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;

  // ---------------------------------------------------------------------------------------------
  // Classify
  logic a_nan, b_nan, a_inf, b_inf, a_zero, b_zero;
  logic sign;

  always_comb begin
    a_nan  = (a_i[30:23] == 8'hFF) & (a_i[22:0] != 23'd0);
    b_nan  = (b_i[30:23] == 8'hFF) & (b_i[22:0] != 23'd0);
    a_inf  = (a_i[30:23] == 8'hFF) & (a_i[22:0] == 23'd0);
    b_inf  = (b_i[30:23] == 8'hFF) & (b_i[22:0] == 23'd0);
    a_zero = (a_i[30:0] == 31'd0);
    b_zero = (b_i[30:0] == 31'd0);
    sign   = a_i[31] ^ b_i[31];
  end

  // ---------------------------------------------------------------------------------------------
  // Special cases: NaN, 0 * inf, infinities, zeros
  logic        special;
  logic [31:0] special_result;

  always_comb begin
    special        = a_nan | b_nan | a_inf | b_inf | a_zero | b_zero;
    special_result = CanonicalNaN;
    if (a_nan | b_nan | (a_inf & b_zero) | (a_zero & b_inf)) begin
      special_result = CanonicalNaN;
    end else if (a_inf | b_inf) begin
      special_result = {sign, 8'hFF, 23'd0};
    end else begin
      special_result = {sign, 31'd0};  // zero times finite
    end
  end

  // ---------------------------------------------------------------------------------------------
  // Exact product of the significands (hidden bit set for normals, exponent 1 for subnormals)
  logic [47:0]       prod;  // prod[46] has weight 2^(exp_a + exp_b - 254)
  logic [5:0]        lzc;  // leading zeros of prod (never 0 here: zeros are special cases)
  logic [47:0]       prod_norm;
  logic signed [9:0] prod_exp;

  rf_fp_normalize #(.W(48)) u_norm (.x_i(prod), .y_o(prod_norm), .count_o(lzc));

  always_comb begin
    logic [23:0] a_sig, b_sig;
    logic [7:0]  a_exp, b_exp;
    a_sig = {a_i[30:23] != 8'd0, a_i[22:0]};
    b_sig = {b_i[30:23] != 8'd0, b_i[22:0]};
    a_exp = (a_i[30:23] == 8'd0) ? 8'd1 : a_i[30:23];
    b_exp = (b_i[30:23] == 8'd0) ? 8'd1 : b_i[30:23];
    prod  = a_sig * b_sig;

    // prod_norm[47] has weight 2^(exp_a + exp_b - 254 + 1 - lzc): biased exponent below.
    prod_exp  = $signed({2'b00, a_exp}) + $signed({2'b00, b_exp}) - 10'sd126
              - $signed({4'd0, lzc});
  end

  // ---------------------------------------------------------------------------------------------
  // Round (the shared rounding module) and select the result
  logic [31:0] rounded;

  rf_fp_round u_round (
    .sign_i   (sign),
    .exp_i    (prod_exp),
    .sig_i    (prod_norm[47:23]),
    .sticky_i (|prod_norm[22:0]),
    .y_o      (rounded)
  );

  assign y_o = special ? special_result : rounded;

endmodule
