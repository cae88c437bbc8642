// fpu_tb_top: combinational test wrapper around every binary32 unit, all fed the same a and b.
//
//   add_o = a + b            (rf_fp_add)
//   sub_o = a - b            (rf_fp_add with b's sign bit flipped)
//   mul_o = a * b            (rf_fp_mul)
//   lt_o, le_o, eq_o, unord_o: IEEE quiet comparisons of a and b (rf_fp_cmp)
//   min_o, max_o             IEEE 754-2019 minimum / maximum (rf_fp_minmax)
//
// Driven by sim/fpu_harness.cpp (one eval() per operand pair).
module fpu_tb_top (
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  output logic [31:0] add_o,
  output logic [31:0] sub_o,
  output logic [31:0] mul_o,
  output logic        lt_o,
  output logic        le_o,
  output logic        eq_o,
  output logic        unord_o,
  output logic [31:0] min_o,
  output logic [31:0] max_o
);

  rf_fp_add u_add (
    .a_i (a_i),
    .b_i (b_i),
    .y_o (add_o)
  );

  rf_fp_add u_sub (
    .a_i (a_i),
    .b_i ({~b_i[31], b_i[30:0]}),
    .y_o (sub_o)
  );

  rf_fp_mul u_mul (
    .a_i (a_i),
    .b_i (b_i),
    .y_o (mul_o)
  );

  rf_fp_cmp u_cmp (
    .a_i     (a_i),
    .b_i     (b_i),
    .lt_o    (lt_o),
    .le_o    (le_o),
    .eq_o    (eq_o),
    .unord_o (unord_o)
  );

  rf_fp_minmax u_minmax (
    .a_i   (a_i),
    .b_i   (b_i),
    .min_o (min_o),
    .max_o (max_o)
  );

endmodule
