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

  // ---------------------------------------------------------------------------------------------
  // The FUSED build's one-rounding operations (rf_fp_dot2, rf_fp_slab): an exact product, and the
  // sum of two exact products rounded once.
  // ---------------------------------------------------------------------------------------------

  // An exact product of two binary32 numbers: its class and, finite and non-zero, the value
  // (-1)^sign * sig * 2^(exp - 300) with sig[47] = 1 (exp = the operands' biased exponents added,
  // a subnormal operand normalised first, minus 1 when the product's leading one is bit 46).
  typedef struct packed {
    logic               nan;      // a NaN operand, or 0 * inf
    logic               inf;
    logic               zero;
    logic               sign;
    logic signed [10:0] exp;
    logic [47:0]        sig;
  } fp_xprod_t;

  // A finite non-zero binary32 operand as {24-bit significand with bit 23 set, biased exponent
  // (below 1 for a subnormal, normalised by its leading-zero count)}.
  function automatic logic [34:0] fp_unpack(input logic [30:0] x);
    logic [4:0] lzc;
    if (x[30:23] != 8'd0) return {1'b1, x[22:0], 3'b000, x[30:23]};
    lzc = fp_lzc32({1'b0, x[22:0], 8'd0});                       // 1..23
    return {24'({1'b0, x[22:0]} << lzc), 11'(11'sd1 - $signed({6'd0, lzc}))};
  endfunction

  function automatic fp_xprod_t fp_xprod(input logic [31:0] a, input logic [31:0] b);
    fp_xprod_t p;
    logic [34:0] ua, ub;
    logic [47:0] prod;
    logic        a_nan, b_nan, a_inf, b_inf, a_zero, b_zero;
    a_nan  = a[30:0] > 31'h7F80_0000;
    b_nan  = b[30:0] > 31'h7F80_0000;
    a_inf  = a[30:0] == 31'h7F80_0000;
    b_inf  = b[30:0] == 31'h7F80_0000;
    a_zero = a[30:0] == 31'd0;
    b_zero = b[30:0] == 31'd0;
    p.sign = a[31] ^ b[31];
    p.nan  = a_nan | b_nan | (a_inf & b_zero) | (a_zero & b_inf);
    p.inf  = ~p.nan & (a_inf | b_inf);
    p.zero = ~p.nan & ~p.inf & (a_zero | b_zero);
    ua     = fp_unpack(a[30:0]);
    ub     = fp_unpack(b[30:0]);
    prod   = 48'(ua[34:11]) * 48'(ub[34:11]);
    p.exp  = $signed(ua[10:0]) + $signed(ub[10:0]) - (prod[47] ? 11'sd0 : 11'sd1);
    p.sig  = prod[47] ? prod : prod << 1;
    return p;
  endfunction

  // Leading zeros of a 64-bit x != 0.
  function automatic logic [5:0] fp_lzc64(input logic [63:0] x);
    if (x[63:32] != 32'd0) return {1'b0, fp_lzc32(x[63:32])};
    return {1'b1, fp_lzc32(x[31:0])};
  endfunction

  // p + q rounded once to binary32 (nearest even), IEEE specials of the exact sum: a NaN product
  // or inf + (-inf) is the canonical NaN, an inf wins, two zeros give -0 only if both are -0, an
  // exact cancellation +0.
  // The significands sit in a 64-bit frame: bit 63 takes an addition's carry, bits 62:15 the
  // 48-bit product, 14:0 guard and sticky space. The smaller operand is aligned with its
  // shifted-out bits OR-ed into bit 0 (sticky); bits are lost only for an exponent difference of
  // at least 16, and then a subtraction cancels at most one leading bit, so the sticky bit stays
  // far below the result's round bit (bit 39 of the normalised frame); a difference of 0 or 1 is
  // exact (massive cancellation counts leading zeros). The value of the normalised frame norm
  // (leading one in bit 63, shifted by lzc) is norm / 2^63 * 2^(exp_big - 252 - lzc), i.e. the
  // rounder's biased exponent is exp_big - 125 - lzc.
  /* verilator lint_off UNUSEDSIGNAL */   // hi, lo: the class bits are read from p and q
  function automatic logic [31:0] fp_sum_round(input fp_xprod_t p, input fp_xprod_t q);
    fp_xprod_t         hi, lo;        // the larger and the smaller magnitude
    logic              swap, sub;
    logic [10:0]       diff;
    logic [5:0]        shift, lzc;
    logic [63:0]       lo_w, aligned, sum, norm;
    logic signed [9:0] exp;
    if (p.nan | q.nan | (p.inf & q.inf & (p.sign != q.sign))) return 32'h7FC0_0000;
    if (p.inf) return {p.sign, 31'h7F80_0000};
    if (q.inf) return {q.sign, 31'h7F80_0000};
    if (p.zero & q.zero) return {p.sign & q.sign, 31'd0};
    // order by magnitude (a zero is the smaller operand)
    swap    = p.zero | (~q.zero & ((q.exp > p.exp) | ((q.exp == p.exp) & (q.sig > p.sig))));
    hi      = swap ? q : p;
    lo      = swap ? p : q;
    sub     = hi.sign ^ lo.sign;
    diff    = 11'(hi.exp - lo.exp);
    shift   = (diff > 11'd63) ? 6'd63 : diff[5:0];
    lo_w    = lo.zero ? 64'd0 : {1'b0, lo.sig, 15'd0};
    aligned = (lo_w >> shift) | 64'((lo_w & ~(64'hFFFF_FFFF_FFFF_FFFF << shift)) != 64'd0);
    sum     = sub ? {1'b0, hi.sig, 15'd0} - aligned : {1'b0, hi.sig, 15'd0} + aligned;
    if (sum == 64'd0) return 32'd0;                                 // exact cancellation: +0
    lzc     = fp_lzc64(sum);
    norm    = sum << lzc;
    exp     = 10'(hi.exp - 11'sd125 - $signed({5'd0, lzc}));
    return fp_round(hi.sign, exp, {norm[63:33], norm[32:0] != 33'd0});
  endfunction
  /* verilator lint_on UNUSEDSIGNAL */

endpackage
