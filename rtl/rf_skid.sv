// Skid buffer: one elastic pipeline register with a second "skid" slot.
//
// Handshake contract: a beat moves when valid and ready are both high on a rising edge. valid_o
// never depends on ready_i, and ready_o is a register output (it is low only while the skid slot is
// full), so no combinational path crosses the stage in either direction. Throughput is one beat per
// cycle while the consumer is ready; the latency from input handshake to valid_o is one cycle.
// When the consumer stalls with a full main register, the beat in flight lands in the skid slot
// and ready_o drops on the next cycle. Beats are never dropped, duplicated or reordered.
module rf_skid #(
  parameter type T = logic
) (
  input  logic clk_i,
  input  logic rst_ni,
  input  logic valid_i,
  output logic ready_o,
  input  T     data_i,
  output logic valid_o,
  input  logic ready_i,
  output T     data_o
);

  T     main_q, skid_q;
  logic main_valid_q, skid_valid_q;

  logic in_fire, out_fire;
  assign in_fire  = valid_i & ready_o;
  assign out_fire = main_valid_q & ready_i;

  assign ready_o = ~skid_valid_q;
  assign valid_o = main_valid_q;
  assign data_o  = main_q;

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      main_valid_q <= 1'b0;
      skid_valid_q <= 1'b0;
    end else if (skid_valid_q) begin
      // Not accepting: drain the skid slot into the main register once the consumer takes.
      if (out_fire) skid_valid_q <= 1'b0;
    end else if (in_fire) begin
      // Accepting: go straight to the main register if it is free or being emptied, else skid.
      if (main_valid_q && !ready_i) skid_valid_q <= 1'b1;
      else                          main_valid_q <= 1'b1;
    end else if (out_fire) begin
      main_valid_q <= 1'b0;
    end
  end

  // Data registers carry no reset: they are only observed while their valid bit is set.
  always_ff @(posedge clk_i) begin
    if (skid_valid_q) begin
      if (out_fire) main_q <= skid_q;
    end else if (in_fire) begin
      if (main_valid_q && !ready_i) skid_q <= data_i;
      else                          main_q <= data_i;
    end
  end

`ifdef RF_ASSERTIONS
  // Protocol check (simulation builds with +define+RF_ASSERTIONS and --assert): a raised valid_o
  // holds, with stable data, until it is taken.
  hold_valid_o : assert property (@(posedge clk_i) disable iff (!rst_ni)
      valid_o && !ready_i |=> valid_o && $stable(data_o));
`endif

endmodule
