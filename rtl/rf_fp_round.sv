// rf_fp_round: the one shared IEEE-754 binary32 rounding and packing stage.
//
// Every arithmetic unit (rf_fp_add, rf_fp_mul) computes an exact or sticky-compressed unrounded
// magnitude and hands it here.  This module is the only place that rounds.
//
// Input value (finite, not NaN/inf; special cases are selected by the caller):
//
//   |v| = 2^(exp_i - 127) * (sig_i / 2^24)  +  (something in (0, 2^(exp_i-127-24)) if sticky_i)
//
//   * sig_i[24]    integer bit: MUST be 1 (normalised) unless the value is exactly zero
//                  (sig_i == 0 and sticky_i == 0), in which case the result is (-1)^sign_i * 0;
//   * sig_i[23:1]  the 23 fraction bits of a normal number;
//   * sig_i[0]     the first bit below the fraction (round bit);
//   * sticky_i     OR of all bits below sig_i[0];
//   * exp_i        biased exponent of the integer bit, signed and wide: exp_i >= 255 overflows,
//                  exp_i <= 0 is the subnormal range (the value is shifted right by 1 - exp_i
//                  here).
//
// Output: the binary32 value of round_to_nearest_even(v), with
//   * overflow (before or after rounding) -> +-inf (RNE never gives MAXFLOAT on overflow);
//   * gradual underflow to subnormals, and to +-0 when the value rounds below 2^-150;
//   * a carry out of the fraction increments the exponent (this also turns the largest subnormal
//     into the smallest normal and the largest normal into inf) because exponent and fraction are
//     rounded as one 31-bit integer.
module rf_fp_round (
  input  logic              sign_i,
  input  logic signed [9:0] exp_i,
  input  logic [24:0]       sig_i,
  input  logic              sticky_i,
  output logic [31:0]       y_o
);

  // Subnormal range: shift the significand right by 1 - exp_i (at most 26: beyond that every bit
  // is below the round position and only the sticky information survives).
  logic [4:0]  denorm_shift;
  logic [51:0] shifted;      // {sig(25), 27 bits that catch what is shifted out}
  logic [24:0] sig_sub;      // significand aligned to the subnormal grid (sig_sub[24] == 0)
  logic        sticky_sub;

  always_comb begin
    if (exp_i >= 10'sd1) begin
      denorm_shift = 5'd0;
    end else if (exp_i <= -10'sd25) begin
      denorm_shift = 5'd26;
    end else begin
      denorm_shift = 5'(10'sd1 - exp_i);
    end
    shifted    = {sig_i, 27'd0} >> denorm_shift;
    sig_sub    = shifted[51:27];
    sticky_sub = sticky_i | (|shifted[26:0]);
  end

  // Round to nearest, ties to even, on {exponent field, fraction} as one integer.
  logic        is_zero;
  logic [7:0]  exp_field;
  logic [22:0] frac;
  logic        round_bit;
  logic        sticky;
  logic        round_up;
  logic [30:0] magnitude;

  always_comb begin
    is_zero      = ~sig_i[24];
    // The exponent field is 0 exactly when the integer bit was shifted out (subnormal range).
    exp_field    = sig_sub[24] ? exp_i[7:0] : 8'd0;
    frac         = sig_sub[23:1];
    round_bit    = sig_sub[0];
    sticky       = sticky_sub;
    round_up     = round_bit & (sticky | frac[0]);
    magnitude    = {exp_field, frac} + {30'd0, round_up};

    if (is_zero) begin
      y_o = {sign_i, 31'd0};
    end else if (exp_i >= 10'sd255) begin
      y_o = {sign_i, 8'hFF, 23'd0};  // overflow before rounding
    end else begin
      y_o = {sign_i, magnitude};     // rounding carry may reach 8'hFF: exactly +-inf
    end
  end

endmodule
