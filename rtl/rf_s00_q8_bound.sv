// q8 decode, one bound: y = A + q * 2^e rounded to nearest even, from the per-axis terms of
// rf_s00_q8_axis (A the origin of the axis, e its exponent; docs/q8_datapath.md, "The decode
// adder"): q aligned by the axis's shift (an 8-bit value), one 36-bit add or subtract (A's sign),
// a negative difference made positive (its fraction is per axis), the leading one found in the
// top 10 bits and shifted to bit 35 (at most 9 places), one rounder (the sum is normal here, or
// overflows to inf). A sum with no leading one in the top 10 bits is per axis (y_frac, y_nfrac).
// Forced results replace the rounded sum: inf on overflow, the origin's inf or the canonical NaN
// (special_i, nan_i), +inf in an unused child slot (unused_i).
module rf_s00_q8_bound import rf_pkg::*; (
  input  logic [7:0]  q_i,
  input  logic        sign_i,
  input  logic        special_i,
  input  logic        nan_i,
  input  logic        unused_i,
  input  logic [35:0] a_i,
  input  logic [4:0]  qshift_i,
  input  logic [7:0]  qmask_i,
  input  logic [7:0]  exp_base_i,
  input  logic [25:0] nfrac_i,
  input  logic        frac_nz_i,
  input  fp32_t       y_frac_i,
  input  fp32_t       y_nfrac_i,
  output fp32_t       y_o
);

  logic [33:0] qa;
  logic [35:0] addend, s, m;
  logic        below;           // A - q * 2^e < 0 (near only): the sum is q * 2^e - A
  logic [3:0]  lz;
  logic [34:0] n;               // m normalised, its leading one (bit 35) dropped
  logic [30:0] frac, r;         // frac: fraction, round bit [7], sticky [6:0]
  logic [7:0]  ex;
  logic        sign, ovf, force_inf;

  assign qa     = {q_i, 26'd0} >> qshift_i;
  assign addend = {2'd0, qa[33:1], qa[0] | ((q_i & qmask_i) != 8'd0)};
  assign s      = a_i + (sign_i ? ~addend : addend) + {35'd0, sign_i};
  assign below  = sign_i & s[35];
  // q - A = (q - int(A) - (frac != 0)) . (1 - frac)
  assign m      = below ? {~s[35:26] + {9'd0, ~frac_nz_i}, nfrac_i} : s;
  assign lz     = 4'(rf_fp_pkg::fp_lzc32({m[35:26], 22'd0}));     // 0..9 (m[35:26] != 0)
  assign n      = 35'(m << lz);
  assign frac   = {n[34:11], 6'd0, n[10:0] != 11'd0};
  assign ex     = exp_base_i - {4'd0, lz};
  assign ovf    = (exp_base_i == 8'hFF) && (lz == 4'd0);
  assign sign   = sign_i & ~s[35];
  assign r      = {ex, frac[30:8]} + {30'd0, frac[7] & (frac[8] | (frac[6:0] != 7'd0))};

  assign force_inf = ovf | special_i | unused_i;

  assign y_o = (m[35:26] == 10'd0 && !unused_i) ? (s[35] ? y_nfrac_i : y_frac_i)
             : force_inf ? {sign & ~unused_i, 8'hFF, nan_i & ~unused_i, 22'd0}
             :             {sign, r};

endmodule
