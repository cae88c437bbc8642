// Stage 0, q8_decode (COMPRESSED builds only, between the input register and stage 1): a QUADBOX
// with flags[FLAG_DECODE_Q8_BIT] carries a q8 box node on its first 16 box words; this stage
// replaces them with the four decoded child boxes, so stage 1 onwards see an ordinary QUADBOX.
// Every other request passes unchanged.
//
// Decode of used child i (i < count), bound j, axis a = j % 3:
//   box[i][j] = origin[a] + float32(q[i][j]) * 2^exp[a]          (24 adders, one RNE add each)
// The product needs no multiplier: q is an 8-bit integer and exp is in [-126, 119], so q * 2^exp
// is 0 or a normal binary32 number (2^-126 <= q * 2^exp <= 255 * 2^119 < 2^127), exactly: its
// significand is q shifted to put its leading one in the hidden bit, its biased exponent is
// exp + 127 + (position of q's leading one). The add is the datapath's one adder (rf_fp_add):
// subnormal, zero, inf and NaN origins are handled as by any add. Unused slots (i >= count) get
// the unused box: six +inf.
// Operand isolation: a request that is not decoded feeds the adders +0 + +0.
module rf_s00_q8_decode import rf_pkg::*; (
  input  req_t req_i,
  output req_t req_o
);
  localparam int unsigned NB = 24;

  logic [$bits(req_i.box)-1:0] box_words;
  q8_node_t node;
  logic     decode;
  fp32_t [NB-1:0] add_a, add_b, add_y;

  assign box_words = req_i.box;
  assign node      = q8_node_t'(box_words[QNODE_WORDS*32-1:0]);
  assign decode = (req_i.opcode == OP_QUADBOX) && req_i.flags[FLAG_DECODE_Q8_BIT];

  // float32(q) * 2^exp for exp in [-126, 119] (a normal number, or +0 for q = 0)
  function automatic fp32_t q8_scaled(input logic [7:0] q, input logic [7:0] exp);
    logic [2:0] lz;
    logic [6:0] frac;
    if (q == 8'd0) return FP_POS_ZERO;
    lz   = 3'(rf_fp_pkg::fp_lzc32({q, 24'd0}));         // 0..7
    frac = 7'(q << lz);                                  // below the leading one
    // biased exponent exp + 127 + (7 - lz), in [1, 253]: modulo-256 arithmetic is exact here
    return {1'b0, exp + 8'd134 - {5'd0, lz}, frac, 16'd0};
  endfunction

  always_comb begin
    for (int i = 0; i < 4; i++) begin
      for (int j = 0; j < 6; j++) begin
        add_a[6*i+j] = decode ? node.origin[j % 3] : FP_POS_ZERO;
        add_b[6*i+j] = decode ? q8_scaled(node.q[i][j], node.exp[j % 3]) : FP_POS_ZERO;
      end
    end
  end

  for (genvar k = 0; k < NB; k++) begin : g_add
    rf_fu #(.IS_MUL(1'b0)) u_add (.a_i(add_a[k]), .b_i(add_b[k]), .y_o(add_y[k]));
  end

  always_comb begin
    req_o = req_i;
    if (decode) begin
      for (int i = 0; i < 4; i++) begin
        for (int j = 0; j < 6; j++) begin
          req_o.box[i][j] = (3'(i) < node.count) ? add_y[6*i+j] : FP_POS_INF;
        end
      end
    end
  end

endmodule
