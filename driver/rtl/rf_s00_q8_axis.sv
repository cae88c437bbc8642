// q8 decode, the work shared by the 8 bounds of one axis (rf_s00_q8_decode): everything that
// depends only on the origin A and the exponent e of the axis. The bounds (rf_s00_q8_bound) add
// q * 2^e, q = 0..255, to A; docs/q8_datapath.md, "The decode adder", has the design and the
// argument for exactness.
//
//   far_o    the path of the axis: "far" if A is normal and A >= 2^9 * 2^e (A's last significand
//            bit weighs 2^(dp + e) with dp >= -14), else "near" (A < 2^9 * 2^e: zero, subnormal or
//            normal)
//   far:     A's sign, significand and exponent (and exponent +-1, the normalised sum's);
//            qshift_o/qmask_o align q to A's significand (right shift of {q, 21'b0}, clamped to
//            31; the bits of q shifted out, which become the sticky bit)
//   near:    A / 2^e as fixed point: int_o (9 bits) . frac_o (26 bits, the last one sticky),
//            nfrac_o = 1 - frac (mod 1); exp_near_o = e + 136, the biased exponent of a sum's
//            integer bit 9; y_frac_o = -frac * 2^e (+0 for frac = 0) and y_nfrac_o =
//            (1 - frac) * 2^e, the sums whose integer part is zero, rounded (subnormal included)
//   plus0_o  A + (+0): the sum for q = 0 (A, with -0 -> +0 and NaN -> the canonical NaN); and the
//            sum for every q if A is NaN or inf (special_o)
module rf_s00_q8_axis import rf_pkg::*; (
  input  fp32_t       origin_i,
  input  logic [7:0]  exp_i,         // e, int8, in [-126, 119]
  output logic        sign_o,
  output logic        special_o,
  output fp32_t       plus0_o,
  output logic        far_o,
  output logic [23:0] sig_o,
  output logic [7:0]  exp_o,
  output logic [7:0]  exp_inc_o,
  output logic [7:0]  exp_dec_o,
  output logic [4:0]  qshift_o,
  output logic [7:0]  qmask_o,
  output logic [7:0]  exp_near_o,
  output logic [8:0]  int_o,
  output logic [25:0] frac_o,
  output logic [25:0] nfrac_o,
  output logic        frac_nz_o,
  output fp32_t       y_frac_o,
  output fp32_t       y_nfrac_o
);

  localparam fp32_t CanonicalNaN = 32'h7FC0_0000;

  // v * 2^(e - 26) for a 26-bit v whose last bit is sticky, rounded (subnormal results included)
  function automatic fp32_t frac_to_fp(input logic sign, input logic [25:0] v,
                                       input logic signed [9:0] e);
    logic [4:0]  lz;
    logic [31:0] sig;
    lz  = rf_fp_pkg::fp_lzc32({v, 6'd0});
    sig = {v, 6'd0} << lz;
    return (v == 26'd0) ? FP_POS_ZERO
                        : rf_fp_pkg::fp_round(sign, e + 10'sd126 - $signed({5'd0, lz}), sig);
  endfunction

  logic [7:0]        ea;
  logic signed [9:0] e, dp, t;
  logic [5:0]        tc;
  logic [34:0]       xw, x;

  assign ea        = origin_i[30:23];
  assign e         = 10'($signed(exp_i));
  assign sign_o    = origin_i[31];
  assign special_o = (ea == 8'hFF);
  assign plus0_o   = (special_o && origin_i[22:0] != 23'd0) ? CanonicalNaN
                   : (origin_i[30:0] == 31'd0)               ? FP_POS_ZERO
                   :                                           origin_i;
  assign sig_o     = {ea != 8'd0, origin_i[22:0]};
  assign exp_o     = ea;
  assign exp_inc_o = ea + 8'd1;
  assign exp_dec_o = ea - 8'd1;

  // dp: A's last significand bit weighs 2^(dp + e) (a subnormal's exponent is that of 1)
  assign dp    = $signed({2'b00, (ea == 8'd0) ? 8'd1 : ea}) - 10'sd150 - e;
  assign far_o = (ea != 8'd0) && !special_o && (dp >= -10'sd14);

  // far: q's last bit lands on bit 21 - (dp + 14) of A's frame (A's significand at bits 30:7)
  assign qshift_o = (dp >= 10'sd17) ? 5'd31 : 5'(dp + 10'sd14);
  for (genvar k = 0; k < 8; k++) begin : g_qmask
    assign qmask_o[k] = 5'(21 + k) < qshift_o;
  end

  // near: A / 2^e in 9.26 fixed point, by a right shift t = -dp - 15 >= 0 of A's significand
  // (bits shifted out become the sticky bit 0)
  assign t          = -dp - 10'sd15;
  assign tc         = (t < 10'sd0) ? 6'd0 : (t > 10'sd35) ? 6'd35 : 6'(t);
  assign xw         = {sig_o, 11'd0};
  assign x          = (xw >> tc) | 35'((xw & ~({35{1'b1}} << tc)) != 35'd0);
  assign int_o      = x[34:26];
  assign frac_o     = x[25:0];
  assign nfrac_o    = -x[25:0];
  assign frac_nz_o  = (x[25:0] != 26'd0);
  assign exp_near_o = 8'(e + 10'sd136);
  assign y_frac_o   = frac_to_fp(1'b1, frac_o, e);
  assign y_nfrac_o  = frac_to_fp(1'b0, nfrac_o, e);

endmodule
