// rf_fp_round: the one shared IEEE-754 binary32 rounding and packing stage, as a module.
//
// A thin wrapper around rf_fp_pkg::fp_round (see there for the input format and the rounding
// contract): y = round_to_nearest_even((-1)^sign_i * 2^(exp_i - 127) * sig_i / 2^31), with
// sig_i[31] the integer bit (sig_i == 0 for an exact zero), sig_i[6:0] sticky, exp_i >= 255
// overflowing to inf and exp_i <= 0 the subnormal range.  The arithmetic units call the function
// directly (inlined in their always_comb); this module keeps it testable on its own.
module rf_fp_round
  import rf_fp_pkg::*;
(
  input  logic              sign_i,
  input  logic signed [9:0] exp_i,
  input  logic [31:0]       sig_i,
  output logic [31:0]       y_o
);

  assign y_o = fp_round(sign_i, exp_i, sig_i);

endmodule
