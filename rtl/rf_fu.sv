// One floating-point functional unit: an adder or a multiplier (binary32, round to nearest even).
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
