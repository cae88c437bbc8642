// One floating-point functional unit: an adder or a multiplier (binary32, round to nearest even).
//
// Simulation note: each unit is one always_comb (rf_fp_add, rf_fp_mul), which Verilator inlines
// into the stage's evaluation as one block with local temporaries. (When the units were several
// blocks, keeping each a separate Verilated module with `no_inline_module` was a quarter faster;
// with one block each, inlining them is a quarter faster than that.)
module rf_fu import rf_pkg::*; #(
  parameter bit IS_MUL = 1'b0
) (
  input  fp32_t a_i,
  input  fp32_t b_i,
  output fp32_t y_o
);
  if (IS_MUL) begin : g_mul
    rf_fp_mul u_mul (.a_i(a_i), .b_i(b_i), .y_o(y_o));
  end else begin : g_add
    rf_fp_add u_add (.a_i(a_i), .b_i(b_i), .y_o(y_o));
  end
endmodule
