// RT unit: RAYS ray slots traversing a BVH4 image through PIPELINES RayFlex datapaths
// (docs/rtunit_rtl.md).
//
//   ray_i ──► ray buffer ◄──────────────── hit update ◄── divider ◄──┐
//               │  slot control (below)                              │ t_num, t_den
//               ▼                                                    │
//   stack ──► pop ──► node fetch ──► mem_req / mem_rsp ──► node buffer
//     ▲                                                    │
//     │                        scheduler ◄─────────────────┘
//     │                            │ req_t (tag = slot), one per pipeline
//     └── response processing ◄── rayflex (the datapath, unchanged)   } PIPELINES times
//          (one per pipeline)     (rf_rtu_pipes)                      }
//                 │ TRANSFORM: o', d'
//                 └──► ray setups ──► ray buffer (object-space ray), BLAS root held
//
// Each slot holds one ray and is in one state (rf_rtu_pkg::slot_e): FREE -> (ray_i) POP ->
// (pop: the root first, then a held pointer, then the stack's top) FETCH -> (node arrives)
// READY -> (scheduler) DP ->
// (response: children pushed or triangle missed) POP, or (triangle hit) DIV -> (hit update) POP,
// or DONE when an any-hit ray accepts its triangle. A POP slot with an empty stack reads its last
// spilled entry back (FETCH, then POP with that pointer held) when its stack has overflowed, else
// goes DONE; a DONE slot leaves through res_o and is FREE again. A pointer of a type the unit
// cannot read ends its ray with res_err_o. A pair leaf (q8 images) with two triangles holds the
// pointer of its triangle 1 after its triangle 0 (unless an any-hit ray ended there): that pop
// needs no fetch (the leaf is in the node buffer) and goes straight to READY.
// Instances (two-level images, TRANSFORM built in): an instance node popped is fetched and
// becomes a TRANSFORM request of the world ray (KIND_XF); its response pushes the return marker
// (RETURN_PTR) and goes to the ray setup (SETUP), which prepares the object-space ray into the
// ray buffer's second set and holds the BLAS root as the next pop; a ray whose transformed ray is
// not finite skips the instance (nothing held). Popping the marker returns the ray to its world
// ray and pops again. The nearest t is the ray's in both spaces (directions are not normalised).
// The distance-culled stack (CULL, docs/rtunit_rtl.md#the-culling-stack): every stack entry keeps
// its entry distance (the box response's tmin of the child; the root's is 0), and a pop whose
// entry is a box node (box32 or q8) at a distance not below the ray's nearest t (IEEE >=) culls
// it: the entry leaves the stack without a fetch or a request, the ray's culled count goes up and
// the slot stays in POP (one pop-port cycle per culled entry). Never culled: triangle nodes, pair
// leaves' second triangles, instance nodes and the return marker, the BLAS root a ray enters
// (issued as the traversal issues it, at once), and the first pop after a skipped instance (the
// traversal issues that entry without a cull check too). A refilled entry comes back with its
// distance and is culled like any other.
//
// Handshake contract of the ports (valid/ready, a beat moves when both are high on a rising edge):
//   * ray (in): a prepared ray (request words 1..14 of docs/datapath.md, ray_i[k] is word k), its
//     id and any-hit flag; ray_ready_o is high while a slot is free (from registers only);
//   * mem_req (out) / mem_rsp (in): node fetches and spill-area reads, see rf_rtu_fetch (byte
//     address, size, tag, refill; responses in any order, always accepted); several outstanding,
//     one per slot at most;
//   * spill (out, valid only: the memory takes PIPELINES writes per cycle, one per response
//     stage p, each for its own slot): with spill_valid_o[p] a stack overflow's oldest entry
//     spill_ptr_o[p] goes to the spill area of slot spill_slot_o[p] (a per-slot LIFO in memory,
//     read back by the refill requests), with CULL its entry distance spill_dist_o[p] too (0
//     without; a refill response carries the pointer in data word 0 and the distance in word 1);
//   * res (out): a finished ray: id, hit, prim (0xFFFFFFFF without a hit: the primitive id in its
//     BLAS), instance (of the hit; 0xFFFFFFFF: none), t bits (the nearest t: the ray's extent
//     without a hit), its QUADBOX, TRIANGLE and TRANSFORM requests, stack overflows and refills,
//     culled (box nodes the distance-culled stack dropped; 0 without CULL), and err (its traversal met a pointer the unit cannot fetch). Register outputs.
//   * root_i: the root node pointer, constant while rays are in the unit.
//   * status: busy_o (some slot holds a ray), dp_issue_o[p] (a request entered pipeline p this
//     cycle), max_depth_o (most stack entries any ray held), overflow_o[p] (response stage p's
//     push spilled) / refill_o (pulses), div_busy_o (dividers holding a division), setup_busy_o
//     (ray setups holding a ray), wait_o (every ray in the unit waits for its node from memory,
//     its request sent, and nothing else is in flight: no request in a datapath or a response
//     stage, no division, no ray setup, no result; until a memory response or a new ray comes,
//     no register that a later output depends on changes). All from registers only.
// Parameters: RAYS (slots), STACK_DEPTH (entries per stack), CULL (the distance-culled stack),
// DIVIDERS (binary32 dividers,
// rf_fp_div), SETUPS (ray setups, rf_rtu_setup), PIPELINES (datapaths, each with its response
// stage: rf_rtu_pipes; the pop port, the fetch, the memory port, the divider and setup ports and
// the result port stay one each), and the datapath's own, passed through.
module rf_rtunit import rf_pkg::*; import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS        = 16,
  parameter int unsigned STACK_DEPTH = 32,
  parameter int unsigned DIVIDERS    = 2,
  parameter int unsigned SETUPS      = 2,
  parameter int unsigned PIPELINES   = 1,
  parameter bit          CULL        = 1'b0,
  parameter bit          EXTENDED    = 1'b0,
  parameter bit          DISJOINT    = 1'b0,
  parameter bit          COMPRESSED  = 1'b0,
  parameter bit          TRANSFORM   = 1'b0,
  parameter bit          FUSED       = 1'b0,
  parameter bit          SHARED      = 1'b0,
  parameter int unsigned LATENCY     = 11 + 32'(COMPRESSED),
  localparam int unsigned SLOT_W  = RAYS > 1 ? $clog2(RAYS) : 1,
  localparam int unsigned COUNT_W = $clog2(STACK_DEPTH + 1),
  localparam int unsigned DIV_W   = $clog2(DIVIDERS + 1),
  localparam int unsigned SETUP_W = $clog2(SETUPS + 1)
) (
  input  logic               clk_i,
  input  logic               rst_ni,
  input  logic [31:0]        root_i,
  input  logic               ray_valid_i,
  output logic               ray_ready_o,
  input  ray_t               ray_i,
  input  logic [31:0]        ray_id_i,
  input  logic               ray_any_hit_i,
  output logic               mem_req_valid_o,
  input  logic               mem_req_ready_i,
  output logic [ADDR_W-1:0]  mem_req_addr_o,
  output logic [SIZE_W-1:0]  mem_req_size_o,
  output logic [SLOT_W-1:0]  mem_req_tag_o,
  output logic               mem_req_refill_o,
  input  logic               mem_rsp_valid_i,
  output logic               mem_rsp_ready_o,
  input  logic [NODE_W-1:0]  mem_rsp_data_i,
  input  logic [SLOT_W-1:0]  mem_rsp_tag_i,
  output logic [PIPELINES-1:0]       spill_valid_o,
  output logic [PIPELINES-1:0][7:0]  spill_slot_o,
  output logic [PIPELINES-1:0][31:0] spill_ptr_o,
  output logic [PIPELINES-1:0][31:0] spill_dist_o,
  output logic               res_valid_o,
  input  logic               res_ready_i,
  output logic [31:0]        res_id_o,
  output logic               res_hit_o,
  output logic [31:0]        res_prim_o,
  output logic [31:0]        res_t_o,
  output logic [31:0]        res_box_ops_o,
  output logic [31:0]        res_tri_ops_o,
  output logic [31:0]        res_inst_o,
  output logic [31:0]        res_xf_ops_o,
  output logic [15:0]        res_overflows_o,
  output logic [15:0]        res_refills_o,
  output logic [31:0]        res_culled_o,
  output logic               res_err_o,
  output logic               busy_o,
  output logic [PIPELINES-1:0] dp_issue_o,
  output logic [COUNT_W-1:0] max_depth_o,
  output logic [PIPELINES-1:0] overflow_o,
  output logic               refill_o,
  output logic [DIV_W-1:0]   div_busy_o,
  output logic [SETUP_W-1:0] setup_busy_o,
  output logic               wait_o
);

  if (RAYS < 1 || RAYS > 256) begin : g_bad_rays
    $error("rf_rtunit: RAYS must be in 1..256");
  end
  if (STACK_DEPTH < 2) begin : g_bad_depth
    $error("rf_rtunit: STACK_DEPTH must be at least 2");
  end
  if (PIPELINES < 1 || PIPELINES > 4) begin : g_bad_pipelines
    $error("rf_rtunit: PIPELINES must be in 1..4");
  end
  localparam int unsigned P = PIPELINES;

  // The slots' states (slot_e) as three bit planes, RAYS bits each: slot i is in state
  // {st_q[2][i], st_q[1][i], st_q[0][i]}, so that the masks of the slots in one state are a few
  // word operations. STATE(i) is slot i's state, written as one value.
  logic [2:0][RAYS-1:0] st_q;
`define STATE(i) {st_q[2][i], st_q[1][i], st_q[0][i]}
  kind_e [RAYS-1:0] kind_q;
  logic  [RAYS-1:0] second_q;              // the slot's pair leaf holds a triangle 1
  logic  [31:0]     leaf_q [RAYS];         // the pointer the slot popped last
  logic  [RAYS-1:0] at_root_q, err_q, held_q;
  logic  [31:0]     held_ptr_q [RAYS];     // a refilled pointer, popped next
  logic  [31:0]     held_dist_q [RAYS];    // CULL: its entry distance
  logic  [RAYS-1:0] held_cull_q;           // CULL: the held pointer may be culled (refilled)
  logic  [RAYS-1:0] nocull_q;              // CULL: the next node popped is not culled

  // ---- per-slot state in masks ----
  logic [RAYS-1:0] free_m, pop_m, ready_m, done_m, fetch_m;
  function automatic logic [RAYS-1:0] in_state(input logic [2:0][RAYS-1:0] p, input slot_e s);
    return (s[2] ? p[2] : ~p[2]) & (s[1] ? p[1] : ~p[1]) & (s[0] ? p[0] : ~p[0]);
  endfunction
  assign free_m  = in_state(st_q, SLOT_FREE);
  assign pop_m   = in_state(st_q, SLOT_POP);
  assign ready_m = in_state(st_q, SLOT_READY);
  assign done_m  = in_state(st_q, SLOT_DONE);
  assign fetch_m = in_state(st_q, SLOT_FETCH);
  assign busy_o = ~&free_m;

  // ---- load: the lowest free slot takes the next ray ----
  logic [SLOT_W-1:0] load_slot;
  logic              load;
  rf_rr_pick #(.N(RAYS)) u_load_pick (
    .req_i(free_m), .start_i('0), .valid_o(ray_ready_o), .idx_o(load_slot));
  assign load        = ray_valid_i & ray_ready_o;

  // ---- pop: one POP slot per cycle (round robin) ----
  logic [SLOT_W-1:0] pop_next_q, pop_slot;
  logic              pop_any;
  rf_rr_pick #(.N(RAYS)) u_pop_pick (
    .req_i(pop_m), .start_i(pop_next_q), .valid_o(pop_any), .idx_o(pop_slot));

  logic [31:0] stk_top, pop_ptr, stk_top_dist, pop_dist, nearest_d;
  logic        stk_empty, stk_spilled;
  logic [P-1:0] stk_spill;
  logic        fetch_ready, fetch_bad;
  logic        pop_root, pop_held, pop_stack, pop_refill, pop_node, pop_fetch, pop_finish, pop_err;
  logic        pop_ret;
  assign pop_root   = at_root_q[pop_slot];
  assign pop_held   = ~pop_root & held_q[pop_slot];
  assign pop_stack  = ~pop_root & ~pop_held & ~stk_empty;
  assign pop_refill = ~pop_root & ~pop_held & stk_empty & stk_spilled;
  assign pop_node   = pop_root | pop_held | pop_stack;
  assign pop_ptr    = pop_stack ? stk_top : pop_held ? held_ptr_q[pop_slot] : root_i;
  assign pop_dist   = pop_stack ? stk_top_dist : pop_held ? held_dist_q[pop_slot] : '0;
  // the distance-culled stack: a box node popped at an entry distance >= the nearest t is dropped
  logic pop_cull;
  if (CULL) begin : g_cull
    logic cull_ge, cmp_lt, cmp_eq, cmp_unord;
    rf_fp_cmp u_cull_cmp (.a_i(nearest_d), .b_i(pop_dist), .lt_o(cmp_lt), .le_o(cull_ge),
                          .eq_o(cmp_eq), .unord_o(cmp_unord));
    logic unused_cmp;
    assign unused_cmp = cmp_lt ^ cmp_eq ^ cmp_unord;
    assign pop_cull = pop_any & pop_node & cull_ge & ~nocull_q[pop_slot]
                      & (pop_ptr[2:0] == BOX_TYPE | pop_ptr[2:0] == Q8_TYPE)
                      & ~(pop_held & ~held_cull_q[pop_slot]);
  end else begin : g_no_cull
    assign pop_cull = 1'b0;
    logic unused_cull;
    assign unused_cull = ^{pop_dist, nearest_d, nocull_q, held_cull_q};
  end
  // a leaf's triangle 1 needs no fetch; the return marker brings the ray back to its world ray
  // (and it pops again); any other node waits for the fetch unit; a bad pointer, or an empty
  // stack with nothing spilled, ends the ray
  logic pop_leaf_next;
  assign pop_leaf_next = pop_any & pop_node & pop_ptr[2:0] == LEAF_NEXT_TYPE;
  assign pop_ret    = pop_any & pop_node & pop_ptr[2:0] == RETURN_TYPE;
  assign pop_err    = pop_any & pop_node & ~pop_leaf_next & ~pop_ret & ~pop_cull & fetch_bad;
  assign pop_fetch  = pop_any & ((pop_node & ~pop_leaf_next & ~pop_ret & ~pop_cull & ~fetch_bad)
                                 | pop_refill) & fetch_ready;
  assign pop_finish = pop_any & ~pop_node & ~pop_refill;
  kind_e pop_kind;
  always_comb begin
    unique case (pop_ptr[2:0])
      BOX_TYPE:       pop_kind = KIND_BOX32;
      Q8_TYPE:        pop_kind = KIND_Q8;
      PAIR_TYPE:      pop_kind = KIND_PAIR0;
      LEAF_NEXT_TYPE: pop_kind = KIND_PAIR1;
      INSTANCE_TYPE:  pop_kind = KIND_XF;
      default:        pop_kind = KIND_TRI;
    endcase
  end
  logic pop_moves;
  assign pop_moves = pop_fetch | pop_leaf_next | pop_ret | pop_err | pop_finish | pop_cull;

  // ---- the blocks ----
  logic              fetch_done, fetch_done_refill;
  logic [31:0]       fetch_done_ptr, fetch_done_dist;
  logic [SLOT_W-1:0] fetch_done_slot;
  logic [P-1:0][SLOT_W-1:0] sched_rd, resp_rd;
  logic [P-1:0][NODE_W-1:0] node_a, node_b;
  rf_rtu_fetch #(.RAYS(RAYS), .Q8(COMPRESSED), .XF(TRANSFORM), .CULL(CULL), .PORTS(P)) u_fetch (
    .clk_i, .rst_ni,
    .in_valid_i(pop_fetch), .in_ready_o(fetch_ready), .in_slot_i(pop_slot), .in_ptr_i(pop_ptr),
    .in_refill_i(pop_refill), .in_bad_o(fetch_bad),
    .mem_req_valid_o, .mem_req_ready_i, .mem_req_addr_o, .mem_req_size_o, .mem_req_tag_o,
    .mem_req_refill_o, .mem_rsp_valid_i, .mem_rsp_ready_o, .mem_rsp_data_i, .mem_rsp_tag_i,
    .done_o(fetch_done), .done_slot_o(fetch_done_slot), .done_refill_o(fetch_done_refill),
    .done_ptr_o(fetch_done_ptr), .done_dist_o(fetch_done_dist),
    .rd_a_i(sched_rd), .node_a_o(node_a), .rd_b_i(resp_rd), .node_b_o(node_b));

  logic [P-1:0]              push;
  logic [P-1:0][SLOT_W-1:0]  push_slot;
  logic [P-1:0][31:0]        push_ptr, push_dist;
  logic              hit_finish;
  rf_rtu_stack #(.RAYS(RAYS), .STACK_DEPTH(STACK_DEPTH), .PUSHES(P), .CULL(CULL)) u_stack (
    .clk_i, .rst_ni,
    .clear_i(load), .clear_slot_i(load_slot),
    .push_i(push), .push_slot_i(push_slot), .push_ptr_i(push_ptr), .push_dist_i(push_dist),
    .pop_slot_i(pop_slot), .pop_i((pop_fetch | pop_ret | pop_cull) & pop_stack),
    .refill_i(pop_fetch & pop_refill),
    .top_o(stk_top), .top_dist_o(stk_top_dist), .empty_o(stk_empty), .spilled_o(stk_spilled),
    .spill_o(stk_spill), .spill_ptr_o(spill_ptr_o), .spill_dist_o(spill_dist_o),
    .depth_o(max_depth_o));
  assign spill_valid_o = stk_spill;
  for (genvar p = 0; p < P; p++) begin : g_spill_slot
    assign spill_slot_o[p] = 8'(push_slot[p]);
  end

  ray_t [P-1:0]       ray_a;
  logic [P-1:0][31:0] nearest_a;
  logic [31:0] nearest_b;
  logic        any_hit_b;
  logic [SLOT_W-1:0] hit_rd, res_rd;
  logic [P-1:0]      issue, issue_box, issue_xf;
  logic [P-1:0][SLOT_W-1:0] issue_slot;
  logic              hit_acc;
  logic [SLOT_W-1:0] hit_slot;
  logic [31:0]       hit_t, hit_prim;
  logic [31:0] res_id_c, res_prim_c, res_t_c, res_box_c, res_tri_c, res_inst_c, res_xf_c;
  logic [31:0] res_cull_c;
  logic              setup_valid, setup_ok;
  ray_t              setup_ray;
  logic [64+SLOT_W-1:0] setup_tag;
  logic [SLOT_W-1:0] setup_slot;
  assign setup_slot = setup_tag[SLOT_W-1:0];
  logic [15:0] res_ovf_c, res_rst_c;
  logic        res_hit_c;
  rf_rtu_ray_buffer #(.RAYS(RAYS), .XF(TRANSFORM), .CULL(CULL), .PORTS(P)) u_rays (
    .clk_i, .rst_ni,
    .load_i(load), .load_slot_i(load_slot), .load_ray_i(ray_i), .load_id_i(ray_id_i),
    .load_any_hit_i(ray_any_hit_i),
    .hit_i(hit_acc), .hit_slot_i(hit_slot), .hit_t_i(hit_t), .hit_prim_i(hit_prim),
    .enter_i(setup_valid & setup_ok), .enter_slot_i(setup_slot), .enter_ray_i(setup_ray),
    .enter_inst_i(setup_tag[SLOT_W+32 +: 32]),
    .leave_i(pop_ret), .leave_slot_i(pop_slot),
    .issue_slot_i(issue_slot), .box_inc_i(issue & issue_box),
    .tri_inc_i(issue & ~issue_box & ~issue_xf), .xf_inc_i(issue & issue_xf),
    .ovf_inc_i(stk_spill), .ovf_slot_i(push_slot),
    .rst_inc_i(pop_fetch & pop_refill), .rst_slot_i(pop_slot),
    .cull_inc_i(pop_cull), .rd_d_i(pop_slot), .nearest_d_o(nearest_d),
    .rd_a_i(sched_rd), .ray_a_o(ray_a), .nearest_a_o(nearest_a),
    .rd_b_i(hit_rd), .nearest_b_o(nearest_b), .any_hit_b_o(any_hit_b),
    .rd_c_i(res_rd), .id_c_o(res_id_c), .hit_c_o(res_hit_c), .prim_c_o(res_prim_c),
    .inst_c_o(res_inst_c), .nearest_c_o(res_t_c), .box_ops_c_o(res_box_c),
    .tri_ops_c_o(res_tri_c), .xf_ops_c_o(res_xf_c),
    .overflows_c_o(res_ovf_c), .refills_c_o(res_rst_c), .culled_c_o(res_cull_c));

  logic [P-1:0] dp_in_valid, dp_in_ready;
  req_t [P-1:0] dp_req;
  rf_rtu_sched #(.RAYS(RAYS), .PIPELINES(P)) u_sched (
    .clk_i, .rst_ni,
    .ready_i(ready_m), .kind_i(kind_q), .rd_o(sched_rd), .ray_i(ray_a),
    .nearest_i(nearest_a), .node_i(node_a),
    .dp_valid_o(dp_in_valid), .dp_ready_i(dp_in_ready), .dp_req_o(dp_req),
    .issue_o(issue), .issue_slot_o(issue_slot), .issue_box_o(issue_box),
    .issue_xf_o(issue_xf));
  assign dp_issue_o = issue;

  logic [P-1:0]      resp_next, resp_div, resp_xf;
  logic              xf_valid, xf_ready;
  logic [2:0][31:0]  xf_origin, xf_dir;
  logic [64+SLOT_W-1:0] xf_tag;
  logic [P-1:0][SLOT_W-1:0] resp_slot;
  kind_e [P-1:0]     resp_kind;
  logic              div_in_valid, div_in_ready, div_out_valid, div_out_ready;
  logic [31:0]       div_num, div_den, div_q;
  logic [32+SLOT_W-1:0] div_tag_in, div_tag_out;
  for (genvar p = 0; p < P; p++) begin : g_resp_kind
    assign resp_kind[p] = kind_q[resp_rd[p]];
  end
  rf_rtu_pipes #(.RAYS(RAYS), .PIPELINES(P), .EXTENDED(EXTENDED), .DISJOINT(DISJOINT),
                 .COMPRESSED(COMPRESSED), .TRANSFORM(TRANSFORM), .CULL(CULL), .FUSED(FUSED),
                 .SHARED(SHARED),
                 .LATENCY(LATENCY)) u_pipes (
    .clk_i, .rst_ni,
    .in_valid_i(dp_in_valid), .in_ready_o(dp_in_ready), .req_i(dp_req),
    .rd_o(resp_rd), .node_i(node_b), .kind_i(resp_kind),
    .push_o(push), .push_slot_o(push_slot), .push_ptr_o(push_ptr), .push_dist_o(push_dist),
    .next_o(resp_next), .div_o(resp_div), .evt_slot_o(resp_slot),
    .div_valid_o(div_in_valid), .div_ready_i(div_in_ready), .div_num_o(div_num),
    .div_den_o(div_den), .div_tag_o(div_tag_in),
    .xf_o(resp_xf), .xf_valid_o(xf_valid), .xf_ready_i(xf_ready), .xf_origin_o(xf_origin),
    .xf_dir_o(xf_dir), .xf_tag_o(xf_tag));

  // the ray setups exist with TRANSFORM only (without it no instance node is fetched, so no
  // TRANSFORM response ever comes)
  if (TRANSFORM) begin : g_setups
    rf_rtu_setups #(.SETUPS(SETUPS), .TAG_W(64 + SLOT_W)) u_setup (
      .clk_i, .rst_ni,
      .in_valid_i(xf_valid), .in_ready_o(xf_ready), .origin_i(xf_origin), .dir_i(xf_dir),
      .tag_i(xf_tag),
      .out_valid_o(setup_valid), .out_ready_i(1'b1), .ok_o(setup_ok), .ray_o(setup_ray),
      .tag_o(setup_tag), .busy_o(setup_busy_o));
  end else begin : g_no_setups
    assign xf_ready     = 1'b0;
    assign setup_valid  = 1'b0;
    assign setup_ok     = 1'b0;
    assign setup_ray    = '0;
    assign setup_tag    = '0;
    assign setup_busy_o = '0;
    logic unused_xf;
    assign unused_xf = ^{xf_valid, xf_origin, xf_dir, xf_tag};
  end

  rf_rtu_divs #(.DIVIDERS(DIVIDERS), .TAG_W(32 + SLOT_W)) u_div (
    .clk_i, .rst_ni,
    .in_valid_i(div_in_valid), .in_ready_o(div_in_ready), .a_i(div_num), .b_i(div_den),
    .tag_i(div_tag_in),
    .out_valid_o(div_out_valid), .out_ready_i(div_out_ready), .q_o(div_q), .tag_o(div_tag_out),
    .busy_o(div_busy_o));

  logic hit_next;
  rf_rtu_hit #(.RAYS(RAYS)) u_hit (
    .div_valid_i(div_out_valid), .div_ready_o(div_out_ready), .div_t_i(div_q),
    .div_tag_i(div_tag_out), .rd_o(hit_rd), .nearest_i(nearest_b), .any_hit_i(any_hit_b),
    .hit_o(hit_acc), .hit_slot_o(hit_slot), .hit_t_o(hit_t), .hit_prim_o(hit_prim),
    .next_o(hit_next), .finish_o(hit_finish));

  // ---- result: one DONE slot per cycle (round robin) into the result register ----
  typedef struct packed {
    logic [31:0] id;
    logic        hit;
    logic [31:0] prim;
    logic [31:0] t;
    logic [31:0] box_ops;
    logic [31:0] tri_ops;
    logic [31:0] inst;
    logic [31:0] xf_ops;
    logic [15:0] overflows;
    logic [15:0] refills;
    logic [31:0] culled;
    logic        err;
  } res_t;
  logic [SLOT_W-1:0] res_next_q;
  logic              res_any, res_in_ready, res_take;
  res_t              res_d, res_q;
  rf_rr_pick #(.N(RAYS)) u_res_pick (
    .req_i(done_m), .start_i(res_next_q), .valid_o(res_any), .idx_o(res_rd));
  assign res_take = res_any & res_in_ready;
  assign res_d = '{id: res_id_c, hit: res_hit_c, prim: res_prim_c, t: res_t_c,
                   box_ops: res_box_c, tri_ops: res_tri_c, inst: res_inst_c, xf_ops: res_xf_c,
                   overflows: res_ovf_c,
                   refills: res_rst_c, culled: res_cull_c, err: err_q[res_rd]};
  rf_skid #(.T(res_t)) u_res (
    .clk_i, .rst_ni,
    .valid_i(res_any), .ready_o(res_in_ready), .data_i(res_d),
    .valid_o(res_valid_o), .ready_i(res_ready_i), .data_o(res_q));
  assign res_id_o        = res_q.id;
  assign res_hit_o       = res_q.hit;
  assign res_prim_o      = res_q.prim;
  assign res_t_o         = res_q.t;
  assign res_box_ops_o   = res_q.box_ops;
  assign res_tri_ops_o   = res_q.tri_ops;
  assign res_inst_o      = res_q.inst;
  assign res_xf_ops_o    = res_q.xf_ops;
  assign res_overflows_o = res_q.overflows;
  assign res_refills_o   = res_q.refills;
  assign res_culled_o    = res_q.culled;
  assign res_err_o       = res_q.err;
  // a slot in DP, DIV or SETUP has its request, division or ray setup in flight
  assign wait_o          = (free_m | fetch_m) == '1 && !mem_req_valid_o && !res_valid_o;
  assign overflow_o      = stk_spill;
  assign refill_o        = pop_fetch & pop_refill;

  // ---- slot control ----
  always_ff @(posedge clk_i) begin
    if (fetch_done && fetch_done_refill) begin
      held_ptr_q[fetch_done_slot]  <= fetch_done_ptr;
      held_dist_q[fetch_done_slot] <= fetch_done_dist;
    end
    for (int p = 0; p < P; p++)
      if (resp_next[p]) held_ptr_q[resp_slot[p]] <= {leaf_q[resp_slot[p]][31:3], LEAF_NEXT_TYPE};
    if (hit_next)  held_ptr_q[hit_rd]    <= {leaf_q[hit_rd][31:3], LEAF_NEXT_TYPE};
    if (setup_valid) held_ptr_q[setup_slot] <= setup_tag[SLOT_W +: 32];     // the BLAS root
    if (pop_moves) leaf_q[pop_slot] <= pop_ptr;
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      st_q <= '0;                                  // every slot SLOT_FREE
      for (int i = 0; i < RAYS; i++) kind_q[i] <= KIND_BOX32;
      second_q   <= '0;
      at_root_q  <= '0;
      err_q      <= '0;
      held_q     <= '0;
      held_cull_q <= '0;
      nocull_q   <= '0;
      pop_next_q <= '0;
      res_next_q <= '0;
    end else begin
      if (load) begin
        `STATE(load_slot)   <= SLOT_POP;
        at_root_q[load_slot] <= 1'b1;
        err_q[load_slot]     <= 1'b0;
        nocull_q[load_slot]  <= 1'b0;
      end
      if (pop_moves) begin
        pop_next_q <= (32'(pop_slot) == RAYS - 1) ? '0 : pop_slot + 1'b1;
        at_root_q[pop_slot] <= 1'b0;
        if (pop_held) held_q[pop_slot] <= 1'b0;
        // a node popped (not the return marker, not a refill read) ends a skip's no-cull pop
        if (pop_node & ~pop_ret) nocull_q[pop_slot] <= 1'b0;
        if (pop_fetch & pop_refill) begin
          `STATE(pop_slot) <= SLOT_FETCH;
        end else if (pop_ret | pop_cull) begin
          `STATE(pop_slot) <= SLOT_POP;
        end else if (pop_fetch | pop_leaf_next) begin
          `STATE(pop_slot) <= pop_leaf_next ? SLOT_READY : SLOT_FETCH;
          kind_q[pop_slot]  <= pop_kind;
        end else begin
          `STATE(pop_slot) <= SLOT_DONE;
          err_q[pop_slot]   <= pop_err;
        end
      end
      if (fetch_done) begin
        `STATE(fetch_done_slot) <= fetch_done_refill ? SLOT_POP : SLOT_READY;
        if (fetch_done_refill) held_q[fetch_done_slot] <= 1'b1;
        held_cull_q[fetch_done_slot] <= fetch_done_refill;
        second_q[fetch_done_slot] <=
            mem_rsp_data_i[(PAIR_NODE_PRIM_WORD + 1)*32 +: 32] != NO_CHILD;
      end
      // a pair leaf's triangle 0 done (and the ray goes on): its triangle 1 is popped next
      for (int p = 0; p < P; p++)
        if (resp_next[p] && kind_q[resp_slot[p]] == KIND_PAIR0 && second_q[resp_slot[p]])
          held_q[resp_slot[p]] <= 1'b1;
      if (hit_next && kind_q[hit_rd] == KIND_PAIR0 && second_q[hit_rd])
        held_q[hit_rd] <= 1'b1;
      for (int p = 0; p < P; p++) begin
        if (issue[p])     `STATE(issue_slot[p]) <= SLOT_DP;
        if (resp_next[p]) `STATE(resp_slot[p])  <= SLOT_POP;
        if (resp_div[p])  `STATE(resp_slot[p])  <= SLOT_DIV;
        if (resp_xf[p])   `STATE(resp_slot[p])  <= SLOT_SETUP;
      end
      if (hit_next)   `STATE(hit_rd)          <= SLOT_POP;
      if (hit_finish) `STATE(hit_rd)          <= SLOT_DONE;
      // the ray setup done: the BLAS root is popped next, or (not prepared) the marker
      if (setup_valid) begin
        `STATE(setup_slot) <= SLOT_POP;
        held_q[setup_slot]  <= setup_ok;
        held_cull_q[setup_slot] <= 1'b0;
        nocull_q[setup_slot]    <= ~setup_ok;
      end
      if (res_take) begin
        `STATE(res_rd) <= SLOT_FREE;
        res_next_q <= (32'(res_rd) == RAYS - 1) ? '0 : res_rd + 1'b1;
      end
    end
  end

endmodule

`undef STATE
