// One floating-point functional unit: an adder or a multiplier (binary32, round to nearest even).
//
// Simulation note: the Verilator metacomment below keeps each unit a module instance of its own
// in the Verilated model instead of flattening it into the top. Verilator then evaluates a unit's
// logic (classify, special cases, datapath, normalisation, rounding, select) as one function with
// local temporaries, instead of interleaving the steps of all units of a stage; that is about a
// quarter faster. It has no meaning for synthesis.
module rf_fu import rf_pkg::*; #(
  parameter bit IS_MUL = 1'b0
) (
  input  fp32_t a_i,
  input  fp32_t b_i,
  output fp32_t y_o
);
  /* verilator no_inline_module */
  if (IS_MUL) begin : g_mul
    rf_fp_mul u_mul (.a_i(a_i), .b_i(b_i), .y_o(y_o));
  end else begin : g_add
    rf_fp_add u_add (.a_i(a_i), .b_i(b_i), .y_o(y_o));
  end
endmodule
