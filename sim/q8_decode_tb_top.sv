// q8_decode_tb_top: combinational test wrapper around the q8 decode stage (rtl/rf_s00_q8_decode.sv)
// on its own: a QUADBOX request with FLAG_DECODE_Q8 carrying qnode_i (the node's 16 words as
// stored, word 0 at the low end) goes in, the 24 box words (box[i][j] at word 6i + j) come out.
//
// Driven by sim/q8_decode_harness.cpp (one eval() per node).
module q8_decode_tb_top import rf_pkg::*; (
  input  logic [QNODE_WORDS*32-1:0] qnode_i,
  output fp32_t [3:0][5:0] box_o
);
  req_t req, dec;

  always_comb begin
    req        = '0;
    req.opcode = OP_QUADBOX;
    req.flags[FLAG_DECODE_Q8_BIT] = 1'b1;
    req.box    = $bits(req.box)'(qnode_i);
  end

  rf_s00_q8_decode u_dec (.req_i(req), .req_o(dec));

  assign box_o = dec.box;
endmodule
