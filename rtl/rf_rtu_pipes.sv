// The RT unit's datapath pipelines: PIPELINES instances of the datapath (rayflex, unchanged), each
// followed by its own response stage (rf_rtu_resp), and the two round-robin arbiters by which the
// response stages share the unit's one divider port (rf_rtu_divs) and one ray-setup port
// (rf_rtu_setups).
//
//   req_i[0] ──► rayflex 0 ──► rf_rtu_resp 0 ──► push 0, next/div/xf 0 ──┐
//   req_i[1] ──► rayflex 1 ──► rf_rtu_resp 1 ──► push 1, next/div/xf 1   │ (per pipeline)
//      ..                            │ t_num, t_den / o', d'            │
//                                    └──► round robin ──► div port, setup port
//
// Contract (p < PIPELINES; with one pipeline every per-pipeline port is one wide and the
// arbiters are wires: the unit is the one-pipeline unit, cycle for cycle):
//   * in[p] (valid/ready, req_i[p]): pipeline p's input (the datapath's: in_ready_o[p] is a
//     register output); tag = the ray's slot;
//   * response stage p (rf_rtu_resp's contract): rd_o[p] names the slot whose node_i[p] (node
//     buffer entry) and kind_i[p] (node kind) it reads; push_o[p]/push_slot_o[p]/push_ptr_o[p]
//     and push_dist_o[p] (the entry distance) drive stack push port p; next_o[p]/div_o[p]/xf_o[p] name the slot in evt_slot_o[p]. A slot
//     has one request in the unit at a time, so the stages' slots differ;
//   * div (valid/ready, one port): the response stages whose response is a triangle hit ask for
//     it; the first asking at or after the pipeline after the last one served (round robin)
//     offers its (t_num, t_den, tag); the others wait, holding their response (their pipelines
//     back up behind it). div_valid_o depends only on registers (the datapaths' outputs and the
//     stages' state); a stage's ready is div_ready_i and its grant;
//   * xf (valid/ready, one port): the same for TRANSFORM responses and the ray setups.
module rf_rtu_pipes import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS       = 4,
  parameter int unsigned PIPELINES  = 1,
  parameter bit          EXTENDED   = 1'b0,
  parameter bit          DISJOINT   = 1'b0,
  parameter bit          COMPRESSED = 1'b0,
  parameter bit          TRANSFORM  = 1'b0,
  parameter bit          CULL       = 1'b0,
  parameter bit          FUSED      = 1'b0,
  parameter bit          SHARED     = 1'b0,
  parameter int unsigned LATENCY    = 11 + 32'(COMPRESSED),
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1,
  localparam int unsigned PIPE_W = PIPELINES > 1 ? $clog2(PIPELINES) : 1
) (
  input  logic                             clk_i,
  input  logic                             rst_ni,
  input  logic [PIPELINES-1:0]             in_valid_i,
  output logic [PIPELINES-1:0]             in_ready_o,
  input  req_t [PIPELINES-1:0]             req_i,
  output logic [PIPELINES-1:0][SLOT_W-1:0] rd_o,
  input  logic [PIPELINES-1:0][NODE_W-1:0] node_i,
  input  kind_e [PIPELINES-1:0]            kind_i,
  output logic [PIPELINES-1:0]             push_o,
  output logic [PIPELINES-1:0][SLOT_W-1:0] push_slot_o,
  output logic [PIPELINES-1:0][31:0]       push_ptr_o,
  output logic [PIPELINES-1:0][31:0]       push_dist_o,
  output logic [PIPELINES-1:0]             next_o,
  output logic [PIPELINES-1:0]             div_o,
  output logic [PIPELINES-1:0]             xf_o,
  output logic [PIPELINES-1:0][SLOT_W-1:0] evt_slot_o,
  output logic                             div_valid_o,
  input  logic                             div_ready_i,
  output logic [31:0]                      div_num_o,
  output logic [31:0]                      div_den_o,
  output logic [32+SLOT_W-1:0]             div_tag_o,
  output logic                             xf_valid_o,
  input  logic                             xf_ready_i,
  output logic [2:0][31:0]                 xf_origin_o,
  output logic [2:0][31:0]                 xf_dir_o,
  output logic [64+SLOT_W-1:0]             xf_tag_o
);

  if (PIPELINES < 1 || PIPELINES > 4) begin : g_bad_pipelines
    $error("rf_rtu_pipes: PIPELINES must be in 1..4");
  end

  logic [PIPELINES-1:0]                  s_div_valid, s_div_ready, s_xf_valid, s_xf_ready;
  logic [PIPELINES-1:0][31:0]            s_div_num, s_div_den;
  logic [PIPELINES-1:0][32+SLOT_W-1:0]   s_div_tag;
  logic [PIPELINES-1:0][2:0][31:0]       s_xf_origin, s_xf_dir;
  logic [PIPELINES-1:0][64+SLOT_W-1:0]   s_xf_tag;

  for (genvar p = 0; p < PIPELINES; p++) begin : g_pipe
    logic dp_out_valid, dp_out_ready;
    rsp_t dp_rsp;
    rayflex #(.EXTENDED(EXTENDED), .DISJOINT(DISJOINT), .COMPRESSED(COMPRESSED),
              .TRANSFORM(TRANSFORM), .FUSED(FUSED), .SHARED(SHARED), .LATENCY(LATENCY))
    u_datapath (
      .clk_i, .rst_ni,
      .in_valid_i(in_valid_i[p]), .in_ready_o(in_ready_o[p]), .req_i(req_i[p]),
      .out_valid_o(dp_out_valid), .out_ready_i(dp_out_ready), .rsp_o(dp_rsp));

    rf_rtu_resp #(.RAYS(RAYS), .CULL(CULL)) u_resp (
      .clk_i, .rst_ni,
      .dp_valid_i(dp_out_valid), .dp_ready_o(dp_out_ready), .dp_rsp_i(dp_rsp),
      .rd_o(rd_o[p]), .node_i(node_i[p]), .kind_i(kind_i[p]),
      .push_o(push_o[p]), .push_slot_o(push_slot_o[p]), .push_ptr_o(push_ptr_o[p]),
      .push_dist_o(push_dist_o[p]),
      .next_o(next_o[p]), .div_o(div_o[p]), .evt_slot_o(evt_slot_o[p]),
      .div_valid_o(s_div_valid[p]), .div_ready_i(s_div_ready[p]), .div_num_o(s_div_num[p]),
      .div_den_o(s_div_den[p]), .div_tag_o(s_div_tag[p]),
      .xf_o(xf_o[p]), .xf_valid_o(s_xf_valid[p]), .xf_ready_i(s_xf_ready[p]),
      .xf_origin_o(s_xf_origin[p]), .xf_dir_o(s_xf_dir[p]), .xf_tag_o(s_xf_tag[p]));
  end

  if (PIPELINES == 1) begin : g_wires
    assign div_valid_o    = s_div_valid[0];
    assign s_div_ready[0] = div_ready_i;
    assign div_num_o      = s_div_num[0];
    assign div_den_o      = s_div_den[0];
    assign div_tag_o      = s_div_tag[0];
    assign xf_valid_o     = s_xf_valid[0];
    assign s_xf_ready[0]  = xf_ready_i;
    assign xf_origin_o    = s_xf_origin[0];
    assign xf_dir_o       = s_xf_dir[0];
    assign xf_tag_o       = s_xf_tag[0];
  end else begin : g_arbiters
    logic [PIPE_W-1:0] div_next_q, xf_next_q, div_g, xf_g;
    rf_rr_pick #(.N(PIPELINES)) u_div_pick (
      .req_i(s_div_valid), .start_i(div_next_q), .valid_o(div_valid_o), .idx_o(div_g));
    rf_rr_pick #(.N(PIPELINES)) u_xf_pick (
      .req_i(s_xf_valid), .start_i(xf_next_q), .valid_o(xf_valid_o), .idx_o(xf_g));
    assign div_num_o   = s_div_num[div_g];
    assign div_den_o   = s_div_den[div_g];
    assign div_tag_o   = s_div_tag[div_g];
    assign xf_origin_o = s_xf_origin[xf_g];
    assign xf_dir_o    = s_xf_dir[xf_g];
    assign xf_tag_o    = s_xf_tag[xf_g];
    for (genvar p = 0; p < PIPELINES; p++) begin : g_grant
      assign s_div_ready[p] = div_ready_i & div_valid_o & (32'(div_g) == p);
      assign s_xf_ready[p]  = xf_ready_i & xf_valid_o & (32'(xf_g) == p);
    end
    function automatic logic [PIPE_W-1:0] after(input logic [PIPE_W-1:0] p);
      return (32'(p) == PIPELINES - 1) ? '0 : p + 1'b1;
    endfunction
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni) begin
        div_next_q <= '0;
        xf_next_q  <= '0;
      end else begin
        if (div_valid_o && div_ready_i) div_next_q <= after(div_g);
        if (xf_valid_o && xf_ready_i)   xf_next_q  <= after(xf_g);
      end
    end
  end

endmodule
