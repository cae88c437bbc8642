// rtu_units_tb_top: the RT unit's modules side by side, each alone (no wire between them), for
// their tests (tests/test_rtunit_modules.py, driven cycle by cycle by sim/rtu_units_tb.cpp; one
// build for all): traversal stacks (rf_rtu_stack), divider pool (rf_rtu_divs), node fetch
// (rf_rtu_fetch, with the q8 decode stage; a second one without it, of which only in_bad_o is
// read), scheduler (rf_rtu_sched), response processing (rf_rtu_resp), ray buffer
// (rf_rtu_ray_buffer), hit update (rf_rtu_hit) and the datapath pipelines (rf_rtu_pipes: two
// pipelines, and one on the same ports when p_one_i is set; PIPE_RAYS slots; its datapaths are
// the stand-in of sim/rtu_pipes_datapath.sv, which this build compiles in place of
// rtl/rayflex.sv). Each module's ports are the wrapper's under a prefix (k_, d_, f_, s_, r_, b_,
// h_, p_); the struct ports (req_t, rsp_t, kind_e) are flat bit vectors here, word 0 at the low
// end. The testbench assumes RAYS = 4.
module rtu_units_tb_top import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS        = 4,
  parameter int unsigned STACK_DEPTH = 3,
  parameter int unsigned DIVIDERS    = 3,
  parameter int unsigned PIPE_RAYS   = 16,
  localparam int unsigned DIV_TAG_W  = 16,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1,
  localparam int unsigned DEPTH_W = $clog2(STACK_DEPTH + 1),
  localparam int unsigned DIV_W   = $clog2(DIVIDERS + 1),
  localparam int unsigned PSLOT_W = $clog2(PIPE_RAYS),
  localparam int unsigned REQ_W  = $bits(req_t),
  localparam int unsigned RSP_W  = $bits(rsp_t),
  localparam int unsigned RAY_W  = $bits(ray_t)
) (
  input  logic               clk_i,
  input  logic               rst_ni,
  // ---- rf_rtu_stack ----
  input  logic               k_clear_i,
  input  logic [SLOT_W-1:0]  k_clear_slot_i,
  input  logic               k_push_i,
  input  logic [SLOT_W-1:0]  k_push_slot_i,
  input  logic [31:0]        k_push_ptr_i,
  input  logic [SLOT_W-1:0]  k_pop_slot_i,
  input  logic               k_pop_i,
  input  logic               k_refill_i,
  output logic [31:0]        k_top_o,
  output logic               k_empty_o,
  output logic               k_spilled_o,
  output logic               k_spill_o,
  output logic [31:0]        k_spill_ptr_o,
  output logic [DEPTH_W-1:0] k_depth_o,
  // ---- rf_rtu_divs ----
  input  logic               d_in_valid_i,
  output logic               d_in_ready_o,
  input  logic [31:0]        d_a_i,
  input  logic [31:0]        d_b_i,
  input  logic [DIV_TAG_W-1:0] d_tag_i,
  output logic               d_out_valid_o,
  input  logic               d_out_ready_i,
  output logic [31:0]        d_q_o,
  output logic [DIV_TAG_W-1:0] d_tag_o,
  output logic [DIV_W-1:0]   d_busy_o,
  // ---- rf_rtu_fetch (Q8) ----
  input  logic               f_in_valid_i,
  output logic               f_in_ready_o,
  input  logic [SLOT_W-1:0]  f_in_slot_i,
  input  logic [31:0]        f_in_ptr_i,
  input  logic               f_in_refill_i,
  output logic               f_in_bad_o,
  output logic               f_in_bad_box32_o,     // the same pointer, a fetch without Q8
  output logic               f_mem_req_valid_o,
  input  logic               f_mem_req_ready_i,
  output logic [ADDR_W-1:0]  f_mem_req_addr_o,
  output logic [SIZE_W-1:0]  f_mem_req_size_o,
  output logic [SLOT_W-1:0]  f_mem_req_tag_o,
  output logic               f_mem_req_refill_o,
  input  logic               f_mem_rsp_valid_i,
  output logic               f_mem_rsp_ready_o,
  input  logic [NODE_W-1:0]  f_mem_rsp_data_i,
  input  logic [SLOT_W-1:0]  f_mem_rsp_tag_i,
  output logic               f_done_o,
  output logic [SLOT_W-1:0]  f_done_slot_o,
  output logic               f_done_refill_o,
  output logic [31:0]        f_done_ptr_o,
  input  logic [SLOT_W-1:0]  f_rd_a_i,
  output logic [NODE_W-1:0]  f_node_a_o,
  input  logic [SLOT_W-1:0]  f_rd_b_i,
  output logic [NODE_W-1:0]  f_node_b_o,
  // ---- rf_rtu_sched ----
  input  logic [RAYS-1:0]    s_ready_i,
  input  logic [3*RAYS-1:0]  s_kind_i,
  output logic [SLOT_W-1:0]  s_rd_o,
  input  logic [RAY_W-1:0]   s_ray_i,
  input  logic [31:0]        s_nearest_i,
  input  logic [NODE_W-1:0]  s_node_i,
  output logic               s_dp_valid_o,
  input  logic               s_dp_ready_i,
  output logic [REQ_W-1:0]   s_dp_req_o,
  output logic               s_issue_o,
  output logic [SLOT_W-1:0]  s_issue_slot_o,
  output logic               s_issue_box_o,
  // ---- rf_rtu_resp ----
  input  logic               r_dp_valid_i,
  output logic               r_dp_ready_o,
  input  logic [RSP_W-1:0]   r_dp_rsp_i,
  output logic [SLOT_W-1:0]  r_rd_o,
  input  logic [NODE_W-1:0]  r_node_i,
  input  logic [2:0]         r_kind_i,
  output logic               r_push_o,
  output logic [SLOT_W-1:0]  r_push_slot_o,
  output logic [31:0]        r_push_ptr_o,
  output logic               r_next_o,
  output logic               r_div_o,
  output logic [SLOT_W-1:0]  r_evt_slot_o,
  output logic               r_div_valid_o,
  input  logic               r_div_ready_i,
  output logic [31:0]        r_div_num_o,
  output logic [31:0]        r_div_den_o,
  output logic [32+SLOT_W-1:0] r_div_tag_o,
  // ---- rf_rtu_ray_buffer ----
  input  logic               b_load_i,
  input  logic [SLOT_W-1:0]  b_load_slot_i,
  input  logic [RAY_W-1:0]   b_load_ray_i,
  input  logic [31:0]        b_load_id_i,
  input  logic               b_load_any_hit_i,
  input  logic               b_hit_i,
  input  logic [SLOT_W-1:0]  b_hit_slot_i,
  input  logic [31:0]        b_hit_t_i,
  input  logic [31:0]        b_hit_prim_i,
  input  logic [SLOT_W-1:0]  b_issue_slot_i,
  input  logic               b_box_inc_i,
  input  logic               b_tri_inc_i,
  input  logic               b_ovf_inc_i,
  input  logic [SLOT_W-1:0]  b_ovf_slot_i,
  input  logic               b_rst_inc_i,
  input  logic [SLOT_W-1:0]  b_rst_slot_i,
  input  logic [SLOT_W-1:0]  b_rd_a_i,
  output logic [RAY_W-1:0]   b_ray_a_o,
  output logic [31:0]        b_nearest_a_o,
  input  logic [SLOT_W-1:0]  b_rd_b_i,
  output logic [31:0]        b_nearest_b_o,
  output logic               b_any_hit_b_o,
  input  logic [SLOT_W-1:0]  b_rd_c_i,
  output logic [31:0]        b_id_c_o,
  output logic               b_hit_c_o,
  output logic [31:0]        b_prim_c_o,
  output logic [31:0]        b_nearest_c_o,
  output logic [31:0]        b_box_ops_c_o,
  output logic [31:0]        b_tri_ops_c_o,
  output logic [15:0]        b_overflows_c_o,
  output logic [15:0]        b_refills_c_o,
  // ---- rf_rtu_hit ----
  input  logic               h_div_valid_i,
  output logic               h_div_ready_o,
  input  logic [31:0]        h_div_t_i,
  input  logic [32+SLOT_W-1:0] h_div_tag_i,
  output logic [SLOT_W-1:0]  h_rd_o,
  input  logic [31:0]        h_nearest_i,
  input  logic               h_any_hit_i,
  output logic               h_hit_o,
  output logic [SLOT_W-1:0]  h_hit_slot_o,
  output logic [31:0]        h_hit_t_o,
  output logic [31:0]        h_hit_prim_o,
  output logic               h_next_o,
  output logic               h_finish_o,
  // ---- rf_rtu_pipes (port p: pipeline p; with p_one_i the one-pipeline unit's, on port 0) ----
  input  logic                    p_one_i,
  input  logic [1:0]              p_in_valid_i,
  output logic [1:0]              p_in_ready_o,
  input  logic [2*REQ_W-1:0]      p_req_i,
  output logic [1:0][PSLOT_W-1:0] p_rd_o,
  input  logic [2*NODE_W-1:0]     p_node_i,
  input  logic [5:0]              p_kind_i,
  output logic [1:0]              p_push_o,
  output logic [1:0][PSLOT_W-1:0] p_push_slot_o,
  output logic [1:0][31:0]        p_push_ptr_o,
  output logic [1:0]              p_next_o,
  output logic [1:0]              p_div_o,
  output logic [1:0]              p_xf_o,
  output logic [1:0][PSLOT_W-1:0] p_evt_slot_o,
  output logic                    p_div_valid_o,
  input  logic                    p_div_ready_i,
  output logic [31:0]             p_div_num_o,
  output logic [31:0]             p_div_den_o,
  output logic [32+PSLOT_W-1:0]   p_div_tag_o,
  output logic                    p_xf_valid_o,
  input  logic                    p_xf_ready_i,
  output logic [2:0][31:0]        p_xf_origin_o,
  output logic [2:0][31:0]        p_xf_dir_o,
  output logic [64+PSLOT_W-1:0]   p_xf_tag_o,
  // the response stages' requests to the two arbiters (inside rf_rtu_pipes: the monitor's view
  // of who waits)
  output logic [1:0]              p_div_want_o,
  output logic [1:0]              p_xf_want_o
);

  rf_rtu_stack #(.RAYS(RAYS), .STACK_DEPTH(STACK_DEPTH)) u_stack (
    .clk_i, .rst_ni,
    .clear_i(k_clear_i), .clear_slot_i(k_clear_slot_i), .push_i(k_push_i),
    .push_slot_i(k_push_slot_i), .push_ptr_i(k_push_ptr_i), .pop_slot_i(k_pop_slot_i),
    .pop_i(k_pop_i), .refill_i(k_refill_i), .top_o(k_top_o), .empty_o(k_empty_o),
    .spilled_o(k_spilled_o), .spill_o(k_spill_o), .spill_ptr_o(k_spill_ptr_o),
    .depth_o(k_depth_o),
    // the entry distances (CULL): tested with the whole unit (tests/test_rtunit_rtl.py)
    .push_dist_i('0), .top_dist_o(), .spill_dist_o());

  rf_rtu_divs #(.DIVIDERS(DIVIDERS), .TAG_W(DIV_TAG_W)) u_divs (
    .clk_i, .rst_ni,
    .in_valid_i(d_in_valid_i), .in_ready_o(d_in_ready_o), .a_i(d_a_i), .b_i(d_b_i),
    .tag_i(d_tag_i), .out_valid_o(d_out_valid_o), .out_ready_i(d_out_ready_i), .q_o(d_q_o),
    .tag_o(d_tag_o), .busy_o(d_busy_o));

  rf_rtu_fetch #(.RAYS(RAYS), .Q8(1'b1)) u_fetch (
    .clk_i, .rst_ni,
    .in_valid_i(f_in_valid_i), .in_ready_o(f_in_ready_o), .in_slot_i(f_in_slot_i),
    .in_ptr_i(f_in_ptr_i), .in_refill_i(f_in_refill_i), .in_bad_o(f_in_bad_o),
    .mem_req_valid_o(f_mem_req_valid_o), .mem_req_ready_i(f_mem_req_ready_i),
    .mem_req_addr_o(f_mem_req_addr_o), .mem_req_size_o(f_mem_req_size_o),
    .mem_req_tag_o(f_mem_req_tag_o), .mem_req_refill_o(f_mem_req_refill_o),
    .mem_rsp_valid_i(f_mem_rsp_valid_i), .mem_rsp_ready_o(f_mem_rsp_ready_o),
    .mem_rsp_data_i(f_mem_rsp_data_i), .mem_rsp_tag_i(f_mem_rsp_tag_i),
    .done_o(f_done_o), .done_slot_o(f_done_slot_o), .done_refill_o(f_done_refill_o),
    .done_ptr_o(f_done_ptr_o), .done_dist_o(),
    .rd_a_i(f_rd_a_i), .node_a_o(f_node_a_o), .rd_b_i(f_rd_b_i), .node_b_o(f_node_b_o));

  /* verilator lint_off PINCONNECTEMPTY */
  rf_rtu_fetch #(.RAYS(RAYS), .Q8(1'b0)) u_fetch_box32 (
    .clk_i, .rst_ni,
    .in_valid_i(1'b0), .in_ready_o(), .in_slot_i(f_in_slot_i), .in_ptr_i(f_in_ptr_i),
    .in_refill_i(1'b0), .in_bad_o(f_in_bad_box32_o),
    .mem_req_valid_o(), .mem_req_ready_i(1'b0), .mem_req_addr_o(), .mem_req_size_o(),
    .mem_req_tag_o(), .mem_req_refill_o(), .mem_rsp_valid_i(1'b0), .mem_rsp_ready_o(),
    .mem_rsp_data_i('0), .mem_rsp_tag_i('0), .done_o(), .done_slot_o(), .done_refill_o(),
    .done_ptr_o(), .done_dist_o(), .rd_a_i('0), .node_a_o(), .rd_b_i('0), .node_b_o());
  /* verilator lint_on PINCONNECTEMPTY */

  req_t s_req;
  rf_rtu_sched #(.RAYS(RAYS)) u_sched (
    .clk_i, .rst_ni,
    .ready_i(s_ready_i), .kind_i(kind_e [RAYS-1:0]'(s_kind_i)), .rd_o(s_rd_o),
    .ray_i(ray_t'(s_ray_i)), .nearest_i(s_nearest_i), .node_i(s_node_i),
    .dp_valid_o(s_dp_valid_o), .dp_ready_i(s_dp_ready_i), .dp_req_o(s_req),
    .issue_o(s_issue_o), .issue_slot_o(s_issue_slot_o), .issue_box_o(s_issue_box_o),
    .issue_xf_o());                           // instances: tested with the whole unit
  assign s_dp_req_o = s_req;

  rf_rtu_resp #(.RAYS(RAYS)) u_resp (
    .clk_i, .rst_ni,
    .dp_valid_i(r_dp_valid_i), .dp_ready_o(r_dp_ready_o), .dp_rsp_i(rsp_t'(r_dp_rsp_i)),
    .rd_o(r_rd_o), .node_i(r_node_i), .kind_i(kind_e'(r_kind_i)),
    .push_o(r_push_o), .push_slot_o(r_push_slot_o), .push_ptr_o(r_push_ptr_o),
    .push_dist_o(),
    .next_o(r_next_o), .div_o(r_div_o), .evt_slot_o(r_evt_slot_o),
    .div_valid_o(r_div_valid_o), .div_ready_i(r_div_ready_i), .div_num_o(r_div_num_o),
    .div_den_o(r_div_den_o), .div_tag_o(r_div_tag_o),
    // instances (TRANSFORM responses): tested with the whole unit (tests/test_rtunit_rtl.py)
    .xf_o(), .xf_valid_o(), .xf_ready_i(1'b1), .xf_origin_o(), .xf_dir_o(), .xf_tag_o());

  ray_t b_ray_a;
  rf_rtu_ray_buffer #(.RAYS(RAYS)) u_rays (
    .clk_i, .rst_ni,
    .load_i(b_load_i), .load_slot_i(b_load_slot_i), .load_ray_i(ray_t'(b_load_ray_i)),
    .load_id_i(b_load_id_i), .load_any_hit_i(b_load_any_hit_i),
    .hit_i(b_hit_i), .hit_slot_i(b_hit_slot_i), .hit_t_i(b_hit_t_i), .hit_prim_i(b_hit_prim_i),
    .enter_i(1'b0), .enter_slot_i('0), .enter_ray_i('0), .enter_inst_i('0),   // instances:
    .leave_i(1'b0), .leave_slot_i('0),                // tested with the whole unit
    .issue_slot_i(b_issue_slot_i), .box_inc_i(b_box_inc_i), .tri_inc_i(b_tri_inc_i),
    .xf_inc_i(1'b0),
    .ovf_inc_i(b_ovf_inc_i), .ovf_slot_i(b_ovf_slot_i),
    .rst_inc_i(b_rst_inc_i), .rst_slot_i(b_rst_slot_i),
    .rd_a_i(b_rd_a_i), .ray_a_o(b_ray_a), .nearest_a_o(b_nearest_a_o),
    .rd_b_i(b_rd_b_i), .nearest_b_o(b_nearest_b_o), .any_hit_b_o(b_any_hit_b_o),
    .rd_c_i(b_rd_c_i), .id_c_o(b_id_c_o), .hit_c_o(b_hit_c_o), .prim_c_o(b_prim_c_o),
    .inst_c_o(), .xf_ops_c_o(), .nearest_c_o(b_nearest_c_o), .box_ops_c_o(b_box_ops_c_o), .tri_ops_c_o(b_tri_ops_c_o),
    .overflows_c_o(b_overflows_c_o), .refills_c_o(b_refills_c_o),
    .cull_inc_i(1'b0), .rd_d_i('0), .nearest_d_o(), .culled_c_o());
  assign b_ray_a_o = b_ray_a;

  rf_rtu_hit #(.RAYS(RAYS)) u_hit (
    .div_valid_i(h_div_valid_i), .div_ready_o(h_div_ready_o), .div_t_i(h_div_t_i),
    .div_tag_i(h_div_tag_i), .rd_o(h_rd_o), .nearest_i(h_nearest_i), .any_hit_i(h_any_hit_i),
    .hit_o(h_hit_o), .hit_slot_o(h_hit_slot_o), .hit_t_o(h_hit_t_o), .hit_prim_o(h_hit_prim_o),
    .next_o(h_next_o), .finish_o(h_finish_o));

  // ---- rf_rtu_pipes: u_pipes2 (two pipelines) and u_pipes1 (one), p_one_i selects ----
  typedef struct packed {
    logic [1:0]              in_ready, push, next, div, xf;
    logic [1:0][PSLOT_W-1:0] rd, push_slot, evt_slot;
    logic [1:0][31:0]        push_ptr;
    logic                    div_valid, xf_valid;
    logic [31:0]             div_num, div_den;
    logic [32+PSLOT_W-1:0]   div_tag;
    logic [2:0][31:0]        xf_origin, xf_dir;
    logic [64+PSLOT_W-1:0]   xf_tag;
    logic [1:0]              div_want, xf_want;
  } pipes_out_t;
  pipes_out_t po2, po1, po;
  req_t  [1:0] p_req;
  kind_e [1:0] p_kind;
  assign p_req  = req_t [1:0]'(p_req_i);
  assign p_kind = kind_e [1:0]'(p_kind_i);

  rf_rtu_pipes #(.RAYS(PIPE_RAYS), .PIPELINES(2)) u_pipes2 (
    .clk_i, .rst_ni,
    .in_valid_i(p_one_i ? 2'b00 : p_in_valid_i), .in_ready_o(po2.in_ready), .req_i(p_req),
    .rd_o(po2.rd), .node_i(p_node_i), .kind_i(p_kind),
    .push_o(po2.push), .push_slot_o(po2.push_slot), .push_ptr_o(po2.push_ptr),
    .push_dist_o(),                      // the entry distances (CULL): tested with the whole unit
    .next_o(po2.next), .div_o(po2.div), .xf_o(po2.xf), .evt_slot_o(po2.evt_slot),
    .div_valid_o(po2.div_valid), .div_ready_i(p_div_ready_i & ~p_one_i),
    .div_num_o(po2.div_num), .div_den_o(po2.div_den), .div_tag_o(po2.div_tag),
    .xf_valid_o(po2.xf_valid), .xf_ready_i(p_xf_ready_i & ~p_one_i),
    .xf_origin_o(po2.xf_origin), .xf_dir_o(po2.xf_dir), .xf_tag_o(po2.xf_tag));
  assign po2.div_want = u_pipes2.s_div_valid;
  assign po2.xf_want  = u_pipes2.s_xf_valid;

  rf_rtu_pipes #(.RAYS(PIPE_RAYS), .PIPELINES(1)) u_pipes1 (
    .clk_i, .rst_ni,
    .in_valid_i(p_in_valid_i[0] & p_one_i), .in_ready_o(po1.in_ready[0]), .req_i(p_req[0]),
    .rd_o(po1.rd[0]), .node_i(p_node_i[NODE_W-1:0]), .kind_i(p_kind[0]),
    .push_o(po1.push[0]), .push_slot_o(po1.push_slot[0]), .push_ptr_o(po1.push_ptr[0]),
    .push_dist_o(),                      // the entry distances (CULL): tested with the whole unit
    .next_o(po1.next[0]), .div_o(po1.div[0]), .xf_o(po1.xf[0]), .evt_slot_o(po1.evt_slot[0]),
    .div_valid_o(po1.div_valid), .div_ready_i(p_div_ready_i & p_one_i),
    .div_num_o(po1.div_num), .div_den_o(po1.div_den), .div_tag_o(po1.div_tag),
    .xf_valid_o(po1.xf_valid), .xf_ready_i(p_xf_ready_i & p_one_i),
    .xf_origin_o(po1.xf_origin), .xf_dir_o(po1.xf_dir), .xf_tag_o(po1.xf_tag));
  assign po1.div_want = {1'b0, u_pipes1.s_div_valid};
  assign po1.xf_want  = {1'b0, u_pipes1.s_xf_valid};
  assign {po1.in_ready[1], po1.rd[1], po1.push[1], po1.push_slot[1], po1.push_ptr[1],
          po1.next[1], po1.div[1], po1.xf[1], po1.evt_slot[1]} = '0;

  assign po = p_one_i ? po1 : po2;
  assign p_in_ready_o  = po.in_ready;
  assign p_rd_o        = po.rd;
  assign p_push_o      = po.push;
  assign p_push_slot_o = po.push_slot;
  assign p_push_ptr_o  = po.push_ptr;
  assign p_next_o      = po.next;
  assign p_div_o       = po.div;
  assign p_xf_o        = po.xf;
  assign p_evt_slot_o  = po.evt_slot;
  assign p_div_valid_o = po.div_valid;
  assign p_div_num_o   = po.div_num;
  assign p_div_den_o   = po.div_den;
  assign p_div_tag_o   = po.div_tag;
  assign p_xf_valid_o  = po.xf_valid;
  assign p_xf_origin_o = po.xf_origin;
  assign p_xf_dir_o    = po.xf_dir;
  assign p_xf_tag_o    = po.xf_tag;
  assign p_div_want_o  = po.div_want;
  assign p_xf_want_o   = po.xf_want;

endmodule
