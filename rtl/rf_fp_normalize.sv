// rf_fp_normalize: shift x left until its top bit is set, and count the shift (leading zeros).
//
// A thin wrapper around rf_fp_pkg::fp_lzc32 (a cascade of conditional shifts, widest step first:
// a binary search for the leading one, log2 levels of muxes) for widths W <= 32: x is left-aligned
// to 32 bits, counted and shifted.  x == 0 has no leading one: the result is 0 with count 0
// (callers treat a zero value separately).  The arithmetic units call the function directly.
module rf_fp_normalize
  import rf_fp_pkg::*;
#(
  parameter  int unsigned W  = 28,
  localparam int unsigned CW = $clog2(W)
) (
  input  logic [W-1:0]  x_i,
  output logic [W-1:0]  y_o,
  output logic [CW-1:0] count_o
);

  if (W > 32 || W < 2) begin : g_bad_width
    $error("rf_fp_normalize: W must be 2..32");
  end

  logic [4:0] count;

  assign count   = (x_i == '0) ? 5'd0 : fp_lzc32(32'(x_i) << (32 - W));
  assign y_o     = x_i << count;
  assign count_o = CW'(count);

endmodule
