// Ray setup pool: SETUPS ray setups (rf_rtu_setup: one ray entering an instance at a time each,
// DIV_CYCLES to prepare it) behind one valid/ready port.
//
// Contract: in (valid/ready, origin_i, dir_i, tag_i): a ray goes to the lowest-numbered idle
// setup; in_ready_o is high while one is idle (from the setups' registers only). out
// (valid/ready, ok_o, ray_o, tag_o): the finished rays, the lowest-numbered setup's first; they
// may leave in another order than they came (the tag names each one). busy_o: setups holding a
// ray this cycle.
module rf_rtu_setups import rf_rtu_pkg::*; #(
  parameter int unsigned SETUPS = 1,
  parameter int unsigned TAG_W  = 8,
  localparam int unsigned COUNT_W = $clog2(SETUPS + 1)
) (
  input  logic               clk_i,
  input  logic               rst_ni,
  input  logic               in_valid_i,
  output logic               in_ready_o,
  input  logic [2:0][31:0]   origin_i,
  input  logic [2:0][31:0]   dir_i,
  input  logic [TAG_W-1:0]   tag_i,
  output logic               out_valid_o,
  input  logic               out_ready_i,
  output logic               ok_o,
  output ray_t               ray_o,
  output logic [TAG_W-1:0]   tag_o,
  output logic [COUNT_W-1:0] busy_o
);

  if (SETUPS < 1) begin : g_bad_setups
    $error("rf_rtu_setups: SETUPS must be at least 1");
  end

  logic [SETUPS-1:0] ready, valid, ok, busy, take_in, take_out;
  ray_t              ray [SETUPS];
  logic [TAG_W-1:0]  tag [SETUPS];

  for (genvar k = 0; k < SETUPS; k++) begin : g_setup
    rf_rtu_setup #(.TAG_W(TAG_W)) u_setup (
      .clk_i, .rst_ni,
      .in_valid_i(take_in[k]), .in_ready_o(ready[k]), .origin_i, .dir_i, .tag_i,
      .out_valid_o(valid[k]), .out_ready_i(take_out[k]), .ok_o(ok[k]), .ray_o(ray[k]),
      .tag_o(tag[k]), .busy_o(busy[k]));
  end

  // the lowest idle setup takes the ray; the lowest finished one gives its result
  always_comb begin
    take_in  = '0;
    take_out = '0;
    ok_o     = ok[0];
    ray_o    = ray[0];
    tag_o    = tag[0];
    for (int k = SETUPS - 1; k >= 0; k--) begin
      if (ready[k]) take_in = SETUPS'(in_valid_i) << k;
      if (valid[k]) begin
        take_out = SETUPS'(out_ready_i) << k;
        ok_o     = ok[k];
        ray_o    = ray[k];
        tag_o    = tag[k];
      end
    end
    busy_o = '0;
    for (int k = 0; k < SETUPS; k++) busy_o = busy_o + COUNT_W'(busy[k]);
  end
  assign in_ready_o  = |ready;
  assign out_valid_o = |valid;

endmodule
