// q8 decode, the work shared by the 8 bounds of one axis (rf_s00_q8_decode): everything that
// depends only on the origin A and the exponent e of the axis. Each bound (rf_s00_q8_bound) adds
// q * 2^e, q = 0..255, to A in one 36-bit adder; this module chooses how A and q line up in that
// adder. docs/q8_datapath.md, "The decode adder", has the design and the argument for exactness.
//
// A = sig * 2^(dp + e): sig the 24-bit significand, dp the weight of its last bit in units of
// 2^e. Two alignments (the "path" of the axis):
//   far  (A normal and dp >= -14: A >= 2^9 * 2^e > 2 * q * 2^e): A's significand at bits 34:11
//        of the adder, q right-shifted below it by qshift_o (clamped to 31: q is then far below
//        the rounding position); bits of q shifted out of bit 0 (qmask_o) make a sticky bit 0.
//        The sum's leading one is at bit 35, 34 or 33; its biased exponent is that of A, + 1 - the
//        leading zeros;
//   near (A < 2^9 * 2^e: zero, subnormal or normal): A / 2^e as 9.26 fixed point at bits 34:0
//        (the last bit sticky: A's bits below 2^(e - 26) are OR-ed into it) and q at bits
//        33:26, unshifted. The sum's leading one is anywhere in bits 35:26 (the integer part), or
//        the integer part is zero and the sum is frac(A) or 1 - frac(A): y_frac_o = -frac * 2^e
//        (+0 for frac = 0) and y_nfrac_o = (1 - frac) * 2^e, rounded once per axis (subnormal
//        results included). nfrac_o = 1 - frac (mod 1) is the fraction of q - A.
//   exp_base_o  the biased exponent of a sum whose leading one is bit 35 (255: it overflows)
//   special_o   A is NaN or inf: every sum is A (inf) or the canonical NaN (nan_o; sign_o is then
//               0); such an axis takes the far path, and the bounds replace the rounded sum
// A sum for q = 0 needs no case of its own: it is A, exactly, through the far path and through the
// near path with int(A) >= 1; with int(A) = 0 the near sum's integer part is zero and y_frac_o is
// then A + (+0) (A; +0 for -0).
module rf_s00_q8_axis import rf_pkg::*; (
  input  fp32_t       origin_i,
  input  logic [7:0]  exp_i,         // e, int8, in [-126, 119]
  output logic        sign_o,
  output logic        special_o,
  output logic        nan_o,
  output logic [35:0] a_o,           // A in the adder
  output logic [4:0]  qshift_o,
  output logic [7:0]  qmask_o,
  output logic [7:0]  exp_base_o,
  output logic [25:0] nfrac_o,
  output logic        frac_nz_o,
  output fp32_t       y_frac_o,
  output fp32_t       y_nfrac_o
);

  // v * 2^(e - 26) for a 26-bit v whose last bit may be sticky, rounded to nearest even. v's
  // leading one is shifted to bit 32 of g, but no further than the subnormal range allows (the
  // bit weighing 2^-149 at bit 9): then g[32] is 0 and the exponent field 0. A subnormal result is
  // exact (both addends are multiples of 2^-149); a rounded one (a sticky v) is normal.
  function automatic fp32_t frac_to_fp(input logic sign, input logic [25:0] v,
                                       input logic signed [9:0] e);
    logic [4:0]        lz, sh;
    logic signed [9:0] lim;
    logic [32:0]       g;
    logic [7:0]        ef;
    lz  = rf_fp_pkg::fp_lzc32({v, 6'd0});
    lim = e + 10'sd126;                                   // the shift that puts 2^-149 at bit 9
    sh  = ($signed({5'd0, lz}) + 10'sd1 <= lim) ? lz + 5'd1 : 5'(lim);
    g   = {1'b0, v, 6'd0} << sh;
    ef  = g[32] ? 8'(lim + 10'sd1 - $signed({5'd0, sh})) : 8'd0;
    return (v == 26'd0) ? FP_POS_ZERO
         : {sign, {ef, g[31:9]} + {30'd0, g[8] & (g[9] | (g[7:0] != 8'd0))}};
  endfunction

  logic [7:0]        ea;
  logic [23:0]       sig;
  logic signed [9:0] e, dp, t;
  logic              far;
  logic [5:0]        tc;
  logic [34:0]       xw, x;          // near: A / 2^e, 9.26 fixed point

  assign ea        = origin_i[30:23];
  assign sig       = {ea != 8'd0, origin_i[22:0]};
  assign e         = 10'($signed(exp_i));
  assign special_o = (ea == 8'hFF);
  assign nan_o     = special_o && (origin_i[22:0] != 23'd0);
  assign sign_o    = origin_i[31] && !nan_o;

  // dp: A's last significand bit weighs 2^(dp + e) (a subnormal's exponent is that of 1)
  assign dp  = $signed({2'b00, (ea == 8'd0) ? 8'd1 : ea}) - 10'sd150 - e;
  assign far = special_o || ((ea != 8'd0) && (dp >= -10'sd14));

  // near: a right shift t = -dp - 15 >= 0 of A's significand (bits shifted out: sticky bit 0)
  assign t  = -dp - 10'sd15;
  assign tc = (t < 10'sd0) ? 6'd0 : (t > 10'sd35) ? 6'd35 : 6'(t);
  assign xw = {sig, 11'd0};
  assign x  = (xw >> tc) | 35'((xw & ~({35{1'b1}} << tc)) != 35'd0);

  assign a_o        = far ? {1'b0, sig, 11'd0} : {1'b0, x};
  // far: q's last bit lands on bit 11 - dp = 26 - qshift
  assign qshift_o   = !far ? 5'd0 : (dp >= 10'sd17) ? 5'd31 : 5'(dp + 10'sd15);
  for (genvar k = 0; k < 8; k++) begin : g_qmask
    if (26 + k < 31) begin : g_out                    // q[k] is shifted out of bit 0
      assign qmask_o[k] = 5'(26 + k) < qshift_o;
    end else begin : g_kept                           // never: the shift is at most 31
      assign qmask_o[k] = 1'b0;
    end
  end
  assign exp_base_o = far ? ea + 8'd1 : 8'(e + 10'sd136);
  assign nfrac_o    = -x[25:0];
  assign frac_nz_o  = (x[25:0] != 26'd0);
  assign y_frac_o   = (x[34:26] != 9'd0)      ? frac_to_fp(1'b1, x[25:0], e)
                    : (origin_i[30:0] == 31'd0) ? FP_POS_ZERO
                    :                             origin_i;
  assign y_nfrac_o  = frac_to_fp(1'b0, nfrac_o, e);

endmodule
