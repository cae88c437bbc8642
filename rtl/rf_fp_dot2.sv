// rf_fp_dot2: y = a*b + c*d with one rounding (binary32, round to nearest even): the FUSED
// build's edge functions of the triangle test (U = Cx*By - Cy*Bx: c = -Cy).
//
// Contract (bit-exact with driver.core.golden.sum_of_products): the exact (unrounded) a*b + c*d
// rounded once; subnormals kept; a NaN operand, 0 * inf and inf - inf give the canonical quiet NaN
// 32'h7FC00000; an infinite product wins over a finite one; a zero sum is -0 only when both
// products are -0 (an exact cancellation gives +0).
//
// Structure: two exact 24x24-bit products (rf_fp_pkg::fp_xprod, no rounding), one aligned
// addition in a 64-bit frame, one normalisation and the one rounder (rf_fp_pkg::fp_sum_round).
// Integer logic only: synthesizable (docs/tradeoffs.md counts its cells with Yosys).
module rf_fp_dot2
  import rf_fp_pkg::*;
(
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  input  logic [31:0] c_i,
  input  logic [31:0] d_i,
  output logic [31:0] y_o
);

  always_comb begin
    fp_xprod_t p, q;
    p   = fp_xprod(a_i, b_i);
    q   = fp_xprod(c_i, d_i);
    y_o = fp_sum_round(p, q);
  end

endmodule
