// rf_fp_round: the one shared IEEE-754 binary32 rounding and packing stage.
//
// Every arithmetic unit (rf_fp_add, rf_fp_mul) computes a normalised, sticky-compressed unrounded
// magnitude and hands it here.  This module is the only place that rounds.
//
// Input value (finite, not NaN/inf; special cases are selected by the caller):
//
//   |v| = 2^(exp_i - 127) * sig_i / 2^31,  where sig_i[6:0] may stand in for more bits below
//
//   * sig_i[31]    integer bit: MUST be 1 (normalised) unless the value is exactly zero
//                  (sig_i == 0), in which case the result is (-1)^sign_i * 0;
//   * sig_i[30:8]  the 23 fraction bits of a normal number;
//   * sig_i[7]     the first bit below the fraction (round bit);
//   * sig_i[6:0]   sticky: non-zero iff anything below the round bit is non-zero;
//   * exp_i        biased exponent of the integer bit, signed and wide: exp_i >= 255 overflows,
//                  exp_i <= 0 is the subnormal range (the value is shifted right by 1 - exp_i
//                  here, and what falls out is OR-ed into the sticky bit).
//
// Output: the binary32 value of round_to_nearest_even(v), with
//   * overflow (before or after rounding) -> +-inf (RNE never gives MAXFLOAT on overflow);
//   * gradual underflow to subnormals, and to +-0 when the value rounds below 2^-150;
//   * a carry out of the fraction increments the exponent (this also turns the largest subnormal
//     into the smallest normal and the largest normal into inf) because exponent and fraction are
//     rounded as one 31-bit integer.
//
// The datapath is 32 bits wide: one right shifter (subnormal alignment) and one incrementer.  It
// is written as zero / overflow / round branches, which in hardware are a result mux; the
// simulation only evaluates the branch taken (a zero input, e.g. from an idle unit, costs a test).
module rf_fp_round (
  input  logic              sign_i,
  input  logic signed [9:0] exp_i,
  input  logic [31:0]       sig_i,
  output logic [31:0]       y_o
);

  always_comb begin
    logic [63:0] shifted;    // subnormal alignment: {sig_i, 32 bits catching what is shifted out}
    logic [30:0] frac;       // [30:8] fraction, [7] round bit, [6:0] sticky, on the result's grid
    logic [7:0]  exp_field;
    logic        overflow;
    logic        round_up;

    shifted   = '0;
    frac      = sig_i[30:0];
    exp_field = exp_i[7:0];
    overflow  = 1'b0;
    round_up  = 1'b0;
    if (!sig_i[31]) begin
      y_o = {sign_i, 31'd0};                                   // exact zero
    end else begin
      // Normal range 1 <= exp_i <= 254 (one unsigned compare); else overflow or subnormal
      if (10'(exp_i - 10'sd1) >= 10'd254) begin
        if (exp_i[9] || exp_i == 10'sd0) begin
          // Subnormal range: align to exponent 1 (shift 1 - exp_i, at most 31: beyond that
          // only sticky information survives); the integer bit moves into the fraction and the
          // exponent field is 0.
          shifted   = {sig_i, 32'd0} >> ((exp_i < -10'sd30) ? 5'd31 : 5'(10'sd1 - exp_i));
          frac      = 31'({shifted[63:33], shifted[32] | (shifted[31:0] != 32'd0)});
          exp_field = 8'd0;
        end else begin
          overflow  = 1'b1;                                    // exp_i >= 255
        end
      end
      // Round to nearest, ties to even, on {exponent field, fraction} as one integer; a carry
      // into the exponent field is correct (up to inf).
      round_up = frac[7] & (frac[8] | (frac[6:0] != 7'd0));
      y_o      = overflow ? {sign_i, 8'hFF, 23'd0}
                          : {sign_i, {exp_field, frac[30:8]} + 31'(round_up)};
    end
  end

endmodule
