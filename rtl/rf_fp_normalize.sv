// rf_fp_normalize: shift x left until its top bit is set, and count the shift (leading zeros).
//
// A cascade of conditional shifts, widest step first (a binary search for the leading one), as a
// normalisation shifter is built in hardware: log2(W) levels of muxes. The common cases of a
// leading one in the top two bits (the result of an addition, a product of normal numbers) are
// selected first, so the simulation skips the cascade for them. x == 0 has no leading one: the
// result is 0 with count 0 (callers treat a zero value separately).
module rf_fp_normalize #(
  parameter  int unsigned W  = 28,
  localparam int unsigned CW = $clog2(W)
) (
  input  logic [W-1:0]  x_i,
  output logic [W-1:0]  y_o,
  output logic [CW-1:0] count_o
);
  always_comb begin
    y_o     = x_i;
    count_o = '0;
    if (!x_i[W-1]) begin
      if (x_i[W-2]) begin
        y_o     = x_i << 1;
        count_o = CW'(1);
      end else if (x_i != '0) begin
        for (int unsigned s = CW; s > 0; s--) begin
          if ((y_o >> (W - (1 << (s - 1)))) == '0) begin
            y_o     = y_o << (1 << (s - 1));
            count_o = count_o | CW'(1 << (s - 1));
          end
        end
      end
    end
  end
endmodule
