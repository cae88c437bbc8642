// Hit update: a triangle hit's t from the divider against the ray's nearest t.
//
// Contract: div (valid/ready; always ready) carries t = t_num / t_den and the tag {prim, slot}.
// In the cycle it arrives: rd_o names the slot and nearest_i / any_hit_i are that ray's
// (combinational read port). The triangle is accepted when t < nearest (IEEE: strictly, so on an
// exact tie the triangle found first stays; a NaN t is never accepted): hit_o pulses with
// hit_slot_o, hit_t_o and hit_prim_o. Then, in the same cycle, finish_o pulses when the ray is an
// any-hit ray with an accepted triangle (it ends: its stack is dropped), and next_o otherwise
// (the ray pops its next node).
module rf_rtu_hit #(
  parameter int unsigned RAYS = 4,
  localparam int unsigned SLOT_W = RAYS > 1 ? $clog2(RAYS) : 1
) (
  input  logic              div_valid_i,
  output logic              div_ready_o,
  input  logic [31:0]       div_t_i,
  input  logic [32+SLOT_W-1:0] div_tag_i,
  output logic [SLOT_W-1:0] rd_o,
  input  logic [31:0]       nearest_i,
  input  logic              any_hit_i,
  output logic              hit_o,
  output logic [SLOT_W-1:0] hit_slot_o,
  output logic [31:0]       hit_t_o,
  output logic [31:0]       hit_prim_o,
  output logic              next_o,
  output logic              finish_o
);

  logic lt, le, eq, unord;
  rf_fp_cmp u_cmp (.a_i(div_t_i), .b_i(nearest_i), .lt_o(lt), .le_o(le), .eq_o(eq),
                   .unord_o(unord));

  assign div_ready_o = 1'b1;
  assign rd_o        = div_tag_i[SLOT_W-1:0];
  assign hit_slot_o  = rd_o;
  assign hit_t_o     = div_t_i;
  assign hit_prim_o  = div_tag_i[SLOT_W +: 32];
  assign hit_o       = div_valid_i & lt;
  assign finish_o    = hit_o & any_hit_i;
  assign next_o      = div_valid_i & ~finish_o;

  // le, eq and unord are not needed: lt alone is the rule
  logic unused;
  assign unused = le ^ eq ^ unord;

endmodule
