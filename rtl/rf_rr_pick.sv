// Round-robin pick over N request bits: the first set bit of req_i at or after start_i, else the
// first set bit below it (a scan start_i..N-1, then 0..start_i-1), and whether any bit is set.
//
// Contract (combinational): valid_o = |req_i; idx_o = the picked bit's index when valid_o, 0
// otherwise; start_i < N. Written as word operations (mask, lowest set bit, one-hot encode) so
// that a simulator evaluates a few machine words per pick instead of a loop over N bits.
module rf_rr_pick #(
  parameter int unsigned N = 4,
  localparam int unsigned IDX_W = N > 1 ? $clog2(N) : 1
) (
  input  logic [N-1:0]     req_i,
  input  logic [IDX_W-1:0] start_i,
  output logic             valid_o,
  output logic [IDX_W-1:0] idx_o
);

  // ENC[b]: the bits whose index has bit b set (the one-hot encoder's OR masks)
  typedef logic [IDX_W-1:0][N-1:0] enc_t;
  function automatic enc_t enc_masks();
    enc_t m;
    for (int unsigned b = 0; b < IDX_W; b++)
      for (int unsigned i = 0; i < N; i++) m[b][i] = 1'((i >> b) & 1);
    return m;
  endfunction
  localparam enc_t ENC = enc_masks();

  logic [N-1:0] upper, sel, low;
  assign upper   = req_i & ~((N'(1) << start_i) - N'(1));   // requests at or after start_i
  assign sel     = upper != '0 ? upper : req_i;
  assign low     = sel & (~sel + N'(1));                    // its lowest set bit (one-hot)
  assign valid_o = req_i != '0;
  always_comb
    for (int unsigned b = 0; b < IDX_W; b++) idx_o[b] = (low & ENC[b]) != '0;

endmodule
