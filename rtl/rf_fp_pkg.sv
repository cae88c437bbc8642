// rf_fp_pkg: the shared binary32 helper functions of the arithmetic units (rf_fp_add, rf_fp_mul).
//
//   fp_round   the general rounding and packing step (round to nearest even, overflow to inf,
//              gradual underflow); rf_fp_round is a module wrapper around it
//   fp_lzc32   leading-zero count of a 32-bit value (the normalisation shift); rf_fp_normalize is a
//              module wrapper around it
//
// The functions are combinational and automatic: each call is one copy of the logic, inlined into
// the caller's always_comb.  Their if/else branches are result muxes in hardware; the simulation
// evaluates only the branch taken, so the common case (a normal result) is tested first.
// A Verilated model keeps the temporaries of a function called inside a branch as members, not as
// C++ locals, so the units call these at the top level of their always_comb or only on rare paths
// (the multiplier rounds a normal-range product inline, which synthesizes to the same cells, and
// calls fp_round for overflow and subnormal results).
package rf_fp_pkg;

  // Round and pack.  Input value (finite, not NaN/inf; special cases are selected by the caller):
  //
  //   |v| = 2^(exp - 127) * sig / 2^31,  where sig[6:0] may stand in for more bits below
  //
  //   * sig[31]    integer bit: MUST be 1 (normalised) unless the value is exactly zero (sig == 0),
  //                in which case the result is (-1)^sign * 0;
  //   * sig[30:8]  the 23 fraction bits of a normal number;
  //   * sig[7]     the first bit below the fraction (round bit);
  //   * sig[6:0]   sticky: non-zero iff anything below the round bit is non-zero;
  //   * exp        biased exponent of the integer bit, signed and wide: exp >= 255 overflows,
  //                exp <= 0 is the subnormal range (the value is shifted right by 1 - exp, and
  //                what falls out is OR-ed into the sticky bit).
  //
  // Output: the binary32 value of round_to_nearest_even(v), with
  //   * overflow (before or after rounding) -> +-inf (RNE never gives MAXFLOAT on overflow);
  //   * gradual underflow to subnormals, and to +-0 when the value rounds below 2^-150;
  //   * a carry out of the fraction increments the exponent (this also turns the largest
  //     subnormal into the smallest normal and the largest normal into inf) because exponent and
  //     fraction are rounded as one 31-bit integer.
  //
  // Branches: zero / normal range (1 <= exp <= 254, one unsigned compare) / overflow / subnormal
  // (one 32-bit right shifter with a sticky mask).  All share the one 31-bit incrementer.
  function automatic logic [31:0] fp_round(input logic sign, input logic signed [9:0] exp,
                                           input logic [31:0] sig);
    logic [4:0]  shift;
    logic [30:0] frac;       // [30:8] fraction, [7] round bit, [6:0] sticky, on the result's grid
    logic [7:0]  exp_field;
    shift     = 5'd0;
    frac      = sig[30:0];
    exp_field = exp[7:0];
    if (!sig[31]) begin
      return {sign, 31'd0};                                       // exact zero
    end else if (10'(exp - 10'sd1) >= 10'd254) begin
      if (!exp[9] && (exp != 10'sd0)) begin
        return {sign, 8'hFF, 23'd0};                              // exp >= 255: overflow
      end
      // Subnormal range: align to exponent 1 (what falls out goes to the sticky bit); the
      // integer bit moves into the fraction and the exponent field is 0
      shift     = (exp < -10'sd30) ? 5'd31 : 5'(10'sd1 - exp);
      frac      = 31'((sig >> shift) | 32'((sig & ~(32'hFFFF_FFFF << shift)) != 32'd0));
      exp_field = 8'd0;
    end
    return {sign, {exp_field, frac[30:8]} + {30'd0, frac[7] & (frac[8] | (frac[6:0] != 7'd0))}};
  endfunction

  // Leading zeros of x (x != 0; x == 0 gives 31): a cascade of conditional shifts, widest step
  // first (a binary search for the leading one), as a normalisation shifter is built: five
  // levels of muxes.  The caller shifts x left by the count.
  function automatic logic [4:0] fp_lzc32(input logic [31:0] x);
    logic [31:0] v;
    logic [4:0]  n;
    v = x;
    n = 5'd0;
    if (v[31:16] == 16'd0) begin v = v << 16; n[4] = 1'b1; end
    if (v[31:24] == 8'd0)  begin v = v << 8;  n[3] = 1'b1; end
    if (v[31:28] == 4'd0)  begin v = v << 4;  n[2] = 1'b1; end
    if (v[31:30] == 2'd0)  begin v = v << 2;  n[1] = 1'b1; end
    n[0] = ~v[31];
    return n;
  endfunction

endpackage
