// rf_fp_div_pkg: the constants of the binary32 divider (rf_fp_div) that its users build on.
//
// The divider computes a quotient of DIV_QUOTIENT_BITS bits, DIV_DIGIT_BITS bits a cycle (one
// radix-4 digit), so its iteration takes DIV_ITER_CYCLES cycles; one cycle before (the input
// handshake, which unpacks the operands) and one after (rounding into the output register) make
// DIV_CYCLES, the constant latency from an input handshake to the result's out_valid_o.
package rf_fp_div_pkg;

  // 2 ma / mb lies in (1, 4) for significands ma, mb in [1, 2): 26 quotient bits hold its 25 or
  // 26 significant bits, enough for the 24-bit significand and the round bit (the remainder gives
  // the sticky bit).
  localparam int unsigned DIV_QUOTIENT_BITS = 26;
  localparam int unsigned DIV_DIGIT_BITS    = 2;
  localparam int unsigned DIV_ITER_CYCLES   = DIV_QUOTIENT_BITS / DIV_DIGIT_BITS;

  // Cycles from the input handshake (cycle 0) to the first cycle with out_valid_o high.  The unit
  // takes its next division at the earliest one cycle after its result is taken.
  localparam int unsigned DIV_CYCLES        = DIV_ITER_CYCLES + 2;

endpackage
