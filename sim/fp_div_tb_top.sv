// fp_div_tb_top: test wrapper around the binary32 divider (rtl/rf_fp_div.sv) with a 32-bit tag,
// exposing the latency it promises (rf_fp_div_pkg::DIV_CYCLES) so that the bench measures the
// latency against the RTL's own constant.
//
// Driven by sim/fp_div_harness.cpp (a driver and a monitor under random back-pressure).
module fp_div_tb_top
  import rf_fp_div_pkg::*;
(
  input  logic        clk_i,
  input  logic        rst_ni,
  input  logic        in_valid_i,
  output logic        in_ready_o,
  input  logic [31:0] a_i,
  input  logic [31:0] b_i,
  input  logic [31:0] tag_i,
  output logic        out_valid_o,
  input  logic        out_ready_i,
  output logic [31:0] q_o,
  output logic [31:0] tag_o,
  output logic [31:0] div_cycles_o
);

  rf_fp_div #(
    .TAG_W (32)
  ) u_div (
    .clk_i       (clk_i),
    .rst_ni      (rst_ni),
    .in_valid_i  (in_valid_i),
    .in_ready_o  (in_ready_o),
    .a_i         (a_i),
    .b_i         (b_i),
    .tag_i       (tag_i),
    .out_valid_o (out_valid_o),
    .out_ready_i (out_ready_i),
    .q_o         (q_o),
    .tag_o       (tag_o)
  );

  assign div_cycles_o = DIV_CYCLES;

endmodule
