// Ray buffer: RAYS entries, one per ray slot, each holding the prepared ray (request words 1..14:
// control word with the flags such as NO_CULL, origin, direction, inverse, extent, shear), the
// ray's id and any-hit flag, its nearest t so far, its hit record (primitive id, instance, hit)
// and its counters (QUADBOX, TRIANGLE and TRANSFORM requests issued, stack overflows, refills;
// with CULL, the distance-culled stack's, box nodes culled).
// A second register set holds the object-space ray of the instance the ray is in (two-level
// images, docs/instances.md; built with XF, the datapath's TRANSFORM): while the slot is inside
// an instance, read port a gives that ray.
//
// Contract (write ports act on the rising edge; the caller never writes one field of the same
// slot from two ports in one cycle):
//   * load_i (slot load_slot_i): a new ray: its words, id and any-hit flag; nearest t = the ray's
//     extent (word 11), no hit, counters zero;
//   * hit_i (slot hit_slot_i): an accepted triangle: nearest t = hit_t_i, prim = hit_prim_i, hit,
//     and the hit's instance is the one the ray is in (none outside instances);
//   * enter_i (slot enter_slot_i): the ray enters instance enter_inst_i: its object-space ray is
//     enter_ray_i (rf_rtu_setup's words; the flags are kept from the world ray), read from then
//     on by port a;
//   * leave_i (slot leave_slot_i): the ray returns to its world ray (no instance);
//   * box_inc_i[p] / tri_inc_i[p] / xf_inc_i[p] (slot issue_slot_i[p], p < PORTS: one port per
//     pipeline, each its own slot): one more QUADBOX / TRIANGLE / TRANSFORM request;
//   * ovf_inc_i[p] (slot ovf_slot_i[p], p < PORTS, each its own slot), rst_inc_i (slot
//     rst_slot_i): one more stack overflow / refill;
//   * cull_inc_i (slot rd_d_i, CULL only): one more box node culled from the stack;
//   * read ports a[p] (the scheduler's, one per pipeline), b (hit update), c (result) and d (the
//     pop port's nearest t, for culling) are combinational.
module rf_rtu_ray_buffer import rf_rtu_pkg::*; #(
  parameter int unsigned RAYS = 4,
  parameter bit          XF   = 1'b0,
  parameter bit          CULL = 1'b0,
  parameter int unsigned PORTS = 1,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              load_i,
  input  logic [SLOT_W-1:0] load_slot_i,
  input  ray_t              load_ray_i,
  input  logic [31:0]       load_id_i,
  input  logic              load_any_hit_i,
  input  logic              hit_i,
  input  logic [SLOT_W-1:0] hit_slot_i,
  input  logic [31:0]       hit_t_i,
  input  logic [31:0]       hit_prim_i,
  input  logic              enter_i,
  input  logic [SLOT_W-1:0] enter_slot_i,
  input  ray_t              enter_ray_i,
  input  logic [31:0]       enter_inst_i,
  input  logic              leave_i,
  input  logic [SLOT_W-1:0] leave_slot_i,
  input  logic [PORTS-1:0][SLOT_W-1:0] issue_slot_i,
  input  logic [PORTS-1:0]  box_inc_i,
  input  logic [PORTS-1:0]  tri_inc_i,
  input  logic [PORTS-1:0]  xf_inc_i,
  input  logic [PORTS-1:0]  ovf_inc_i,
  input  logic [PORTS-1:0][SLOT_W-1:0] ovf_slot_i,
  input  logic              rst_inc_i,
  input  logic [SLOT_W-1:0] rst_slot_i,
  input  logic              cull_inc_i,
  input  logic [SLOT_W-1:0] rd_d_i,
  output logic [31:0]       nearest_d_o,
  input  logic [PORTS-1:0][SLOT_W-1:0] rd_a_i,
  output ray_t [PORTS-1:0]  ray_a_o,
  output logic [PORTS-1:0][31:0] nearest_a_o,
  input  logic [SLOT_W-1:0] rd_b_i,
  output logic [31:0]       nearest_b_o,
  output logic              any_hit_b_o,
  input  logic [SLOT_W-1:0] rd_c_i,
  output logic [31:0]       id_c_o,
  output logic              hit_c_o,
  output logic [31:0]       prim_c_o,
  output logic [31:0]       inst_c_o,
  output logic [31:0]       nearest_c_o,
  output logic [31:0]       box_ops_c_o,
  output logic [31:0]       tri_ops_c_o,
  output logic [31:0]       xf_ops_c_o,
  output logic [15:0]       overflows_c_o,
  output logic [15:0]       refills_c_o,
  output logic [31:0]       culled_c_o
);

  ray_t        ray_q      [RAYS];
  ray_t        obj_q      [RAYS];     // the object-space ray while inside an instance
  logic [31:0] inst_q     [RAYS];     // the instance the ray is in (NO_CHILD: none)
  logic [31:0] hit_inst_q [RAYS];
  logic [31:0] xf_q       [RAYS];
  logic [RAYS-1:0] inside_q;
  logic [31:0] id_q       [RAYS];
  logic [31:0] nearest_q  [RAYS];
  logic [31:0] prim_q     [RAYS];
  logic [31:0] box_q      [RAYS];
  logic [31:0] tri_q      [RAYS];
  logic [15:0] ovf_q      [RAYS];
  logic [15:0] rst_q      [RAYS];
  logic [RAYS-1:0] any_hit_q, hit_q;

  // Ray words and ids are only read while their slot holds a ray: no reset.
  always_ff @(posedge clk_i) begin
    if (load_i) begin
      ray_q[load_slot_i] <= load_ray_i;
      id_q[load_slot_i]  <= load_id_i;
    end
    if (XF && enter_i) begin
      obj_q[enter_slot_i] <= enter_ray_i;
      obj_q[enter_slot_i][1][16:9] <= ray_q[enter_slot_i][1][16:9];     // the ray's flags
    end
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      any_hit_q <= '0;
      hit_q     <= '0;
      inside_q  <= '0;
      for (int i = 0; i < RAYS; i++) begin
        inst_q[i]     <= NO_CHILD;
        hit_inst_q[i] <= NO_CHILD;
        xf_q[i]       <= '0;
        nearest_q[i] <= '0;
        prim_q[i]    <= NO_CHILD;
        box_q[i]     <= '0;
        tri_q[i]     <= '0;
        ovf_q[i]     <= '0;
        rst_q[i]     <= '0;
      end
    end else begin
      if (load_i) begin
        any_hit_q[load_slot_i] <= load_any_hit_i;
        hit_q[load_slot_i]     <= 1'b0;
        nearest_q[load_slot_i] <= load_ray_i[REQ_EXTENT_WORD];
        prim_q[load_slot_i]    <= NO_CHILD;
        box_q[load_slot_i]     <= '0;
        tri_q[load_slot_i]     <= '0;
        xf_q[load_slot_i]      <= '0;
        inside_q[load_slot_i]  <= 1'b0;
        inst_q[load_slot_i]    <= NO_CHILD;
        hit_inst_q[load_slot_i] <= NO_CHILD;
        ovf_q[load_slot_i]     <= '0;
        rst_q[load_slot_i]     <= '0;
      end
      if (hit_i) begin
        hit_q[hit_slot_i]     <= 1'b1;
        nearest_q[hit_slot_i] <= hit_t_i;
        prim_q[hit_slot_i]    <= hit_prim_i;
        hit_inst_q[hit_slot_i] <= inst_q[hit_slot_i];
      end
      if (enter_i) begin
        inside_q[enter_slot_i] <= 1'b1;
        inst_q[enter_slot_i]   <= enter_inst_i;
      end
      if (leave_i) begin
        inside_q[leave_slot_i] <= 1'b0;
        inst_q[leave_slot_i]   <= NO_CHILD;
      end
      for (int p = 0; p < PORTS; p++) begin
        if (box_inc_i[p]) box_q[issue_slot_i[p]] <= box_q[issue_slot_i[p]] + 1'b1;
        if (tri_inc_i[p]) tri_q[issue_slot_i[p]] <= tri_q[issue_slot_i[p]] + 1'b1;
        if (xf_inc_i[p])  xf_q[issue_slot_i[p]]  <= xf_q[issue_slot_i[p]] + 1'b1;
        if (ovf_inc_i[p] && ovf_q[ovf_slot_i[p]] != '1)
          ovf_q[ovf_slot_i[p]] <= ovf_q[ovf_slot_i[p]] + 1'b1;
      end
      if (rst_inc_i && rst_q[rst_slot_i] != '1) rst_q[rst_slot_i] <= rst_q[rst_slot_i] + 1'b1;
    end
  end

  for (genvar p = 0; p < PORTS; p++) begin : g_port_a
    assign ray_a_o[p]     = XF && inside_q[rd_a_i[p]] ? obj_q[rd_a_i[p]] : ray_q[rd_a_i[p]];
    assign nearest_a_o[p] = nearest_q[rd_a_i[p]];
  end
  assign nearest_b_o   = nearest_q[rd_b_i];
  assign any_hit_b_o   = any_hit_q[rd_b_i];
  assign id_c_o        = id_q[rd_c_i];
  assign hit_c_o       = hit_q[rd_c_i];
  assign prim_c_o      = prim_q[rd_c_i];
  assign nearest_c_o   = nearest_q[rd_c_i];
  assign box_ops_c_o   = box_q[rd_c_i];
  assign tri_ops_c_o   = tri_q[rd_c_i];
  assign xf_ops_c_o    = xf_q[rd_c_i];
  assign inst_c_o      = hit_inst_q[rd_c_i];
  assign overflows_c_o = ovf_q[rd_c_i];
  assign refills_c_o  = rst_q[rd_c_i];
  assign nearest_d_o  = nearest_q[rd_d_i];

  // box nodes culled from the stack (CULL only)
  if (CULL) begin : g_culled
    logic [31:0] culled_q [RAYS];
    always_ff @(posedge clk_i or negedge rst_ni) begin
      if (!rst_ni) begin
        for (int i = 0; i < RAYS; i++) culled_q[i] <= '0;
      end else begin
        if (load_i) culled_q[load_slot_i] <= '0;
        if (cull_inc_i) culled_q[rd_d_i] <= culled_q[rd_d_i] + 1'b1;
      end
    end
    assign culled_c_o = culled_q[rd_c_i];
  end else begin : g_no_culled
    assign culled_c_o = '0;
    logic unused_cull;
    assign unused_cull = cull_inc_i;
  end

endmodule
