// q8 decode, one bound: y = A + q * 2^e rounded to nearest even, from the per-axis terms of
// rf_s00_q8_axis (A the origin of the axis, e its exponent; docs/q8_datapath.md, "The decode
// adder").
//
//   far  (A >= 2^9 * 2^e > 2 * q * 2^e): q aligned to A's significand (a right shift of an 8-bit
//        value, sticky bit from the per-axis mask), one add or subtract; at most one leading bit
//        cancels, so the sum is normalised by selecting one of three positions;
//   near (A < 2^9 * 2^e): the sum's integer part in units of 2^e is q +- int(A) (10 bits), its
//        fraction frac(A) or 1 - frac(A) (per axis); a non-zero integer part is normalised by a
//        shift of at most 9; a zero one leaves the per-axis sum y_frac or y_nfrac;
//   then one rounder (the sum is normal here, or overflows to inf).
module rf_s00_q8_bound import rf_pkg::*; (
  input  logic [7:0]  q_i,
  input  logic        sign_i,
  input  logic        special_i,
  input  fp32_t       plus0_i,
  input  logic        far_i,
  input  logic [23:0] sig_i,
  input  logic [7:0]  exp_i,
  input  logic [7:0]  exp_inc_i,
  input  logic [7:0]  exp_dec_i,
  input  logic [4:0]  qshift_i,
  input  logic [7:0]  qmask_i,
  input  logic [7:0]  exp_near_i,
  input  logic [8:0]  int_i,
  input  logic [25:0] frac_i,
  input  logic [25:0] nfrac_i,
  input  logic        frac_nz_i,
  input  fp32_t       y_frac_i,
  input  fp32_t       y_nfrac_i,
  output fp32_t       y_o
);

  // far: A's significand at bits 30:7, q aligned below it, one adder (subtract: A's sign)
  logic [28:0] qa;
  logic [31:0] aw, addend, s;
  logic [30:0] far_frac;        // the normalised sum below its leading one
  logic [7:0]  far_exp;
  logic        far_ovf;

  assign qa      = {q_i, 21'd0} >> qshift_i;
  assign aw      = {1'b0, sig_i, 7'd0};
  assign addend  = {3'd0, qa[28:1], qa[0] | ((q_i & qmask_i) != 8'd0)};
  assign s       = aw + (sign_i ? ~addend : addend) + {31'd0, sign_i};
  assign far_frac = s[31] ? s[30:0] : s[30] ? {s[29:0], 1'b0} : {s[28:0], 2'b0};
  assign far_exp  = s[31] ? exp_inc_i : s[30] ? exp_i : exp_dec_i;
  assign far_ovf  = s[31] & (exp_inc_i == 8'hFF);

  // near: |int(A) + frac(A) +- q| = ip . fp, one adder: d = int(A) -+ q
  logic [10:0] d;
  logic        below;           // A negative and int(A) < q: the sum is positive
  logic        neg;             // the sum is negative
  logic [9:0]  ip;
  logic [25:0] fp;
  logic [3:0]  lz;
  logic [34:0] n;               // {ip, fp} normalised, its leading one dropped
  logic [30:0] near_frac;
  logic [7:0]  near_exp;
  logic        near_ovf;

  assign d     = {2'd0, int_i} + (sign_i ? ~{3'd0, q_i} : {3'd0, q_i}) + {10'd0, sign_i};
  assign below = sign_i & d[10];
  assign neg   = sign_i & ~d[10];
  assign ip    = below ? ~d[9:0] + {9'd0, ~frac_nz_i} : d[9:0];    // q - int(A) - (frac != 0)
  assign fp    = below ? nfrac_i : frac_i;
  assign lz    = 4'(rf_fp_pkg::fp_lzc32({ip, 22'd0}));              // 0..9 (ip != 0)
  assign n     = 35'({ip, fp} << lz);
  assign near_frac = {n[34:11], 6'd0, n[10:0] != 11'd0};
  assign near_exp  = exp_near_i - {4'd0, lz};
  assign near_ovf  = (exp_near_i == 8'hFF) && (lz == 4'd0);

  // round to nearest even (a normal result, or an overflow to inf)
  logic [30:0] frac, r;
  logic [7:0]  ex;
  logic        sign, ovf;

  assign frac = far_i ? far_frac : near_frac;
  assign ex   = far_i ? far_exp : near_exp;
  assign ovf  = far_i ? far_ovf : near_ovf;
  assign sign = far_i ? sign_i : neg;
  assign r    = {ex, frac[30:8]} + {30'd0, frac[7] & (frac[8] | (frac[6:0] != 7'd0))};

  assign y_o = (special_i || q_i == 8'd0) ? plus0_i
             : (!far_i && ip == 10'd0)    ? (neg ? y_frac_i : y_nfrac_i)
             : ovf                        ? {sign, 8'hFF, 23'd0}
             :                              {sign, r};

endmodule
