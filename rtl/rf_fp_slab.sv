// rf_fp_slab: y[k] = (bound[k] - origin) * inv with one rounding each (binary32, round to nearest
// even): the FUSED build's slab values of one axis of the box test.
//
// Contract (bit-exact with driver.core.golden.slab): the exact (unrounded) result rounded once,
// with the special values of the IEEE expression (bound - origin) * inv: a NaN operand,
// inf - inf and 0 * inf give the canonical quiet NaN; an infinity or a zero takes the sign IEEE
// gives it (bound - origin is -0 only for (-0) - (+0)).
//
// Structure: a finite non-zero value is bound*inv - origin*inv, mathematically the same value:
// the exact product origin*inv (rf_fp_pkg::fp_xprod) is formed once for the N bounds, each
// bound's exact product bound*inv is added to its negation and rounded once
// (rf_fp_pkg::fp_sum_round). The other classes (a non-finite operand, a zero difference or a
// zero inv) are selected from the operands' classes and signs, as the two-rounding datapath
// would produce them.
// Integer logic only: synthesizable (docs/tradeoffs.md counts its cells with Yosys).
module rf_fp_slab
  import rf_fp_pkg::*;
#(
  parameter int unsigned N = 8
) (
  input  logic [N-1:0][31:0] bound_i,
  input  logic [31:0]        origin_i,
  input  logic [31:0]        inv_i,
  output logic [N-1:0][31:0] y_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;

  fp_xprod_t o_inv;                        // -origin * inv, shared by the N bounds
  assign o_inv = fp_xprod({~origin_i[31], origin_i[30:0]}, inv_i);

  // The value when it is not finite and non-zero: {special, y}
  function automatic logic [32:0] special(input logic [31:0] b, input logic [31:0] o,
                                          input logic [31:0] m);
    logic b_inf, o_inf, m_inf, m_zero, b_zero, deq, dsign;
    b_inf  = b[30:0] == InfMagnitude;
    o_inf  = o[30:0] == InfMagnitude;
    m_inf  = m[30:0] == InfMagnitude;
    m_zero = m[30:0] == 31'd0;
    b_zero = b[30:0] == 31'd0;
    if ((b[30:0] > InfMagnitude) | (o[30:0] > InfMagnitude) | (m[30:0] > InfMagnitude))
      return {1'b1, CanonicalNaN};
    if (b_inf | o_inf) begin                                      // an infinite difference
      if ((b_inf & o_inf & (b[31] == o[31])) | m_zero) return {1'b1, CanonicalNaN};
      return {1'b1, (b_inf ? b[31] : ~o[31]) ^ m[31], InfMagnitude};
    end
    // finite operands: the difference's zero-ness and sign
    deq   = (b[30:0] == o[30:0]) & ((b[31] == o[31]) | b_zero);
    dsign = deq ? (b[31] & ~o[31])                                // -0 only for (-0) - (+0)
          : (b[31] != o[31]) ? (b_zero ? ~o[31] : b[31])
          : (b[30:0] > o[30:0]) ? b[31] : ~b[31];
    if (m_inf) return deq ? {1'b1, CanonicalNaN} : {1'b1, dsign ^ m[31], InfMagnitude};
    if (m_zero | deq) return {1'b1, dsign ^ m[31], 31'd0};
    return {1'b0, 32'd0};
  endfunction

  for (genvar k = 0; k < N; k++) begin : g_bound
    always_comb begin
      logic [32:0] s;
      s      = special(bound_i[k], origin_i, inv_i);
      y_o[k] = s[32] ? s[31:0] : fp_sum_round(fp_xprod(bound_i[k], inv_i), o_inv);
    end
  end

endmodule
