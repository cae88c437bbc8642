// Stage 0, q8_decode (COMPRESSED builds only, between the input register and stage 1): a QUADBOX
// with flags[FLAG_DECODE_Q8_BIT] carries a q8 box node on its first 16 box words; this stage
// replaces them with the four decoded child boxes, so stage 1 onwards see an ordinary QUADBOX.
// Every other request passes unchanged.
//
// Decode of used child i (i < count), bound j, axis a = j % 3:
//   box[i][j] = origin[a] + q[i][j] * 2^exp[a]          (one binary32 round-to-nearest-even add)
// Unused slots (i >= count) get the unused box: six +inf.
//
// The 24 adds are not general adds: the addend q * 2^e (q 0..255, e = exp[a] in [-126, 119]) is
// never negative and has 8 significant bits, and the 8 bounds of an axis share the origin and e.
// So the work that depends on the origin and e is done once per axis (rf_s00_q8_axis), and each
// bound (rf_s00_q8_bound) keeps a narrow add, a short normalisation and the rounding
// (docs/q8_datapath.md, "The decode adder", has the design and the argument for exactness).
module rf_s00_q8_decode import rf_pkg::*; (
  input  req_t req_i,
  output req_t req_o
);

  logic [$bits(req_i.box)-1:0] box_words;
  q8_node_t stored;                           // the node as stored
  fp32_t [2:0]           origin;              // the fields the decode reads
  logic  [2:0][7:0]      exp;
  logic  [2:0]           count;
  logic  [3:0][5:0][7:0] q;
  logic     decode;

  // Operand isolation: a request that is not decoded feeds the decode a zero node (its box words
  // do not toggle the decode logic)
  assign box_words = req_i.box;
  assign stored    = q8_node_t'(box_words[QNODE_WORDS*32-1:0]);
  assign decode    = (req_i.opcode == OP_QUADBOX) && req_i.flags[FLAG_DECODE_Q8_BIT];
  assign origin    = decode ? stored.origin : '0;
  assign exp       = decode ? stored.exp    : '0;
  assign count     = decode ? stored.count  : '0;
  assign q         = decode ? stored.q      : '0;

  logic        sign   [3], special [3], nan [3], frac_nz [3];
  fp32_t       y_frac [3], y_nfrac [3];
  logic [35:0] a_add  [3];
  logic [4:0]  qshift [3];
  logic [7:0]  qmask  [3], exp_base [3];
  logic [25:0] nfrac  [3];
  fp32_t [3:0][5:0] y;

  for (genvar a = 0; a < 3; a++) begin : g_axis
    rf_s00_q8_axis u_axis (
      .origin_i(origin[a]), .exp_i(exp[a]),
      .sign_o(sign[a]), .special_o(special[a]), .nan_o(nan[a]), .a_o(a_add[a]),
      .qshift_o(qshift[a]), .qmask_o(qmask[a]), .exp_base_o(exp_base[a]), .nfrac_o(nfrac[a]),
      .frac_nz_o(frac_nz[a]), .y_frac_o(y_frac[a]), .y_nfrac_o(y_nfrac[a]));
  end

  for (genvar i = 0; i < 4; i++) begin : g_child
    for (genvar j = 0; j < 6; j++) begin : g_bound
      localparam int A = j % 3;
      rf_s00_q8_bound u_bound (
        .q_i(q[i][j]),
        .sign_i(sign[A]), .special_i(special[A]), .nan_i(nan[A]),
        .unused_i(3'(i) >= count), .a_i(a_add[A]),
        .qshift_i(qshift[A]), .qmask_i(qmask[A]), .exp_base_i(exp_base[A]), .nfrac_i(nfrac[A]),
        .frac_nz_i(frac_nz[A]), .y_frac_i(y_frac[A]), .y_nfrac_i(y_nfrac[A]), .y_o(y[i][j]));
    end
  end

  always_comb begin
    req_o = req_i;
    if (decode) req_o.box = y;
  end

endmodule
