// RayFlex datapath top: an elastic pipeline of LATENCY skid-buffer registers with stage logic in
// front of each. It only wires stages.
//
//   req_i -> [R_in] -> S1 origin_sub -> [R1] -> S2 scale_mul -> [R2] -> ... -> S9 -> [R9]
//         -> (LATENCY - 11 pass-through registers) -> output format -> [R_out] -> rsp_o
//
// LATENCY 10 (the balanced pipeline, docs/timing.md): S9, the sort's last layer, and the output
// format share the last stage (no R9), a few ns of logic against the ~17 ns of S1..S8:
//   ... -> S8 -> [R8] -> S9 -> output format -> [R_out] -> rsp_o
//
// With COMPRESSED, the q8 decode stage S0 and its register (a req_t) come first:
//   req_i -> [R_in] -> S0 q8_decode -> [R_dec] -> S1 origin_sub -> ...
// one more cycle of latency (LATENCY >= 12), the same throughput.
//
// The request is registered as it arrives (the paper's input stage), so no logic sits between the
// ports and a register (except SHARED's repacking mux, one per box and triangle bit): every output is a register output and nothing combinational depends on
// the inputs, which also keeps the Verilated model's per-cycle work in the clocked region.
//
// One request per cycle; the response leaves LATENCY cycles after its input handshake when
// out_ready_i stays high; responses come back in request order.
// Parameters: EXTENDED adds EUCLIDEAN/ANGULAR, DISJOINT gives each operation private functional
// units, COMPRESSED adds the q8 decode stage (QUADBOX with FLAG_DECODE_Q8), TRANSFORM adds the
// ray transform by a 3x4 matrix (docs/transform.md: on S2's multipliers and the adders of S3 and
// S5..S8, two adders more in S8), FUSED rounds the box slab value (bound - origin) * inv and the
// triangle's edge functions once each (docs/tradeoffs.md: in S1 and S5), SHARED carries an
// extended beat's vectors on the box and triangle words of the request registers (R_in, R_dec;
// rf_pkg::req_share), LATENCY >= 10 + COMPRESSED (the paper's design has 11).
module rayflex import rf_pkg::*; #(
  parameter bit          EXTENDED   = 1'b0,
  parameter bit          DISJOINT   = 1'b0,
  parameter bit          COMPRESSED = 1'b0,
  parameter bit          TRANSFORM  = 1'b0,
  parameter bit          FUSED      = 1'b0,
  parameter bit          SHARED     = 1'b0,
  parameter int unsigned LATENCY    = 11 + 32'(COMPRESSED)
) (
  input  logic clk_i,
  input  logic rst_ni,
  input  logic in_valid_i,
  output logic in_ready_o,
  input  req_t req_i,
  output logic out_valid_o,
  input  logic out_ready_i,
  output rsp_t rsp_o
);

  localparam int unsigned NUM_STAGES = 9;                    // compute stages S1..S9
  localparam int unsigned NUM_DECODE = COMPRESSED ? 1 : 0;   // the decode register R_dec
  localparam int unsigned NUM_REGS   = LATENCY - 2 - NUM_DECODE;   // stage_t registers R1..
  localparam bit          MERGED_OUT = NUM_REGS < NUM_STAGES;   // no R9: S9 feeds the output

  if (LATENCY < 10 + NUM_DECODE) begin : g_bad_latency
    $error("rayflex: LATENCY must be >= 10 (+1 with COMPRESSED: the decode stage)");
  end

  // ---- input register ----
  req_t req_q, req_in;
  logic req_valid_q, req_ready;
  assign req_in = SHARED ? req_share(req_i) : req_i;
  rf_skid #(.T(req_t)) u_in_reg (
    .clk_i, .rst_ni,
    .valid_i(in_valid_i), .ready_o(in_ready_o), .data_i(req_in),
    .valid_o(req_valid_q), .ready_i(req_ready), .data_o(req_q));

  // ---- q8 decode stage (COMPRESSED) ----
  // req_s1 is the request stage 1 sees: the input register's, or the decode register's.
  req_t req_s1;
  logic req_s1_valid, req_s1_ready;
  if (COMPRESSED) begin : g_decode
    req_t dec_d;
    rf_s00_q8_decode u_s0 (.req_i(req_q), .req_o(dec_d));
    rf_skid #(.T(req_t)) u_dec_reg (
      .clk_i, .rst_ni,
      .valid_i(req_valid_q), .ready_o(req_ready), .data_i(dec_d),
      .valid_o(req_s1_valid), .ready_i(req_s1_ready), .data_o(req_s1));
  end else begin : g_no_decode
    assign req_s1       = req_q;
    assign req_s1_valid = req_valid_q;
    assign req_ready    = req_s1_ready;
  end

  req_t req_st1;                 // what stage 1 reads: the request unpacked (SHARED)
  assign req_st1 = SHARED ? req_unshare(req_s1) : req_s1;

  // d_*[k] is the input of stage_t register k (R(k+1)); q_*[k] its output.
  stage_t [NUM_REGS-1:0] d_st, q_st;
  logic   [NUM_REGS-1:0] d_valid, d_ready, q_valid, q_ready;

  // ---- compute stages ----
  rf_s01_origin_sub #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM),
                      .FUSED(FUSED)) u_s1 (
    .req_i(req_st1), .st_o(d_st[0]));
  rf_s02_scale_mul #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM),
                     .FUSED(FUSED)) u_s2 (
    .st_i(q_st[0]), .st_o(d_st[1]));
  rf_s03_nearfar_xy #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM)) u_s3 (
    .st_i(q_st[1]), .st_o(d_st[2]));
  rf_s04_nearfar_z #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .FUSED(FUSED)) u_s4 (
    .st_i(q_st[2]), .st_o(d_st[3]));
  rf_s05_clamp_uvw #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM),
                     .FUSED(FUSED)) u_s5 (
    .st_i(q_st[3]), .st_o(d_st[4]));
  rf_s06_slab_hit #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM)) u_s6 (
    .st_i(q_st[4]), .st_o(d_st[5]));
  rf_s07_sort_acc #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM)) u_s7 (
    .clk_i, .rst_ni, .fire_i(d_valid[6] & d_ready[6]), .st_i(q_st[5]), .st_o(d_st[6]));
  rf_s08_sort_tnum #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .TRANSFORM(TRANSFORM)) u_s8 (
    .st_i(q_st[6]), .st_o(d_st[7]));
  stage_t s9_st;                 // into R9, or with MERGED_OUT straight into the output format
  rf_s09_sort_trihit u_s9 (.st_i(q_st[7]), .st_o(s9_st));
  if (!MERGED_OUT) begin : g_r9
    assign d_st[NUM_STAGES-1] = s9_st;
  end

  // ---- pass-through stages (pad the latency) ----
  for (genvar k = NUM_STAGES; k < NUM_REGS; k++) begin : g_pass
    assign d_st[k] = q_st[k-1];
  end

  // ---- stage_t registers and their handshakes ----
  assign d_valid[0]   = req_s1_valid;
  assign req_s1_ready = d_ready[0];
  for (genvar k = 0; k < NUM_REGS; k++) begin : g_reg
    if (k > 0) begin : g_link
      assign d_valid[k]   = q_valid[k-1];
      assign q_ready[k-1] = d_ready[k];
    end
    rf_skid #(.T(stage_t)) u_reg (
      .clk_i, .rst_ni,
      .valid_i(d_valid[k]), .ready_o(d_ready[k]), .data_i(d_st[k]),
      .valid_o(q_valid[k]), .ready_i(q_ready[k]), .data_o(q_st[k]));
  end

  // ---- output stage ----
  rsp_t rsp_d;
  stage_t out_st;
  assign out_st = MERGED_OUT ? s9_st : q_st[NUM_REGS-1];
  rf_output #(.EXTENDED(EXTENDED), .TRANSFORM(TRANSFORM)) u_out (.st_i(out_st), .rsp_o(rsp_d));
  rf_skid #(.T(rsp_t)) u_out_reg (
    .clk_i, .rst_ni,
    .valid_i(q_valid[NUM_REGS-1]), .ready_o(q_ready[NUM_REGS-1]), .data_i(rsp_d),
    .valid_o(out_valid_o), .ready_i(out_ready_i), .data_o(rsp_o));

endmodule
