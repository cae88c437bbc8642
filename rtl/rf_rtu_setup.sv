// Ray setup: prepares a ray that enters an instance from its TRANSFORM response (o', d'), as the
// host prepares every ray (docs/datapath.md#ray-preparation, driver.core.datapath.prepare_rays):
// inv = 1 / d' per component; kz = the index of the largest |d'| (ties: the lowest), kx = kz + 1,
// ky = kx + 1 (mod 3), kx and ky swapped when d'[kz] < 0; shear = (d'[kx] / d'[kz],
// d'[ky] / d'[kz], 1 / d'[kz]). Five binary32 dividers (rf_fp_div, bit-exact to numpy's float32
// division) run side by side; shear[2] is inv[kz] (the same division). A ray whose o' or d' is not
// finite, or whose d' is zero, is not prepared: ok_o is low and the ray skips the instance
// (docs/instances.md#traversal), one cycle after it came.
//
// Contract:
//   * in (valid/ready, origin_i, dir_i, tag_i): one ray at a time; in_ready_o is high while the
//     unit holds none (a register output). Operands are read only in the handshake cycle;
//   * out (valid/ready): out_valid_o rises DIV_CYCLES (rf_fp_div_pkg) cycles after the input
//     handshake for a ray that is prepared, 1 cycle after it for one that is not, and holds with
//     ok_o, ray_o and tag_o stable until out_ready_i takes it (from registers only). ray_o is the
//     prepared ray's request words 1..14 with opcode, flags and extent 0 (the ray buffer keeps
//     the world ray's flags; the extent of a request is always the ray's nearest t);
//   * busy_o: the unit holds a ray (for the statistics).
module rf_rtu_setup import rf_rtu_pkg::*; #(
  parameter int unsigned TAG_W = 8
) (
  input  logic              clk_i,
  input  logic              rst_ni,
  input  logic              in_valid_i,
  output logic              in_ready_o,
  input  logic [2:0][31:0]  origin_i,
  input  logic [2:0][31:0]  dir_i,
  input  logic [TAG_W-1:0]  tag_i,
  output logic              out_valid_o,
  input  logic              out_ready_i,
  output logic              ok_o,
  output ray_t              ray_o,
  output logic [TAG_W-1:0]  tag_o,
  output logic              busy_o
);

  localparam logic [31:0] One = 32'h3F80_0000;
  localparam int unsigned DIVS = 5;     // inv x, y, z; shear x, y

  // ---- classify the input: finite, non-zero direction, the largest |d'| ----
  logic       finite, nonzero, ok, take;
  logic [1:0] kx, ky, kz, kx_s, ky_s;
  always_comb begin
    finite  = 1'b1;
    nonzero = 1'b0;
    for (int a = 0; a < 3; a++) begin
      finite  &= origin_i[a][30:23] != 8'hFF && dir_i[a][30:23] != 8'hFF;
      nonzero |= dir_i[a][30:0] != '0;
    end
    // finite magnitudes compare as unsigned integers; strictly greater keeps the lowest on ties
    kz = 2'd0;
    if (dir_i[1][30:0] > dir_i[0][30:0]) kz = 2'd1;
    if (dir_i[2][30:0] > dir_i[kz][30:0]) kz = 2'd2;
    kx_s = kz == 2'd2 ? 2'd0 : kz + 2'd1;
    ky_s = kx_s == 2'd2 ? 2'd0 : kx_s + 2'd1;
    kx = dir_i[kz][31] ? ky_s : kx_s;
    ky = dir_i[kz][31] ? kx_s : ky_s;
  end
  assign ok   = finite & nonzero;
  assign take = in_valid_i & in_ready_o;

  // ---- the dividers ----
  logic [DIVS-1:0]   div_in_ready, div_valid;
  logic [31:0]       num [DIVS];
  logic [31:0]       den [DIVS];
  logic [31:0]       q   [DIVS];
  always_comb begin
    for (int a = 0; a < 3; a++) begin
      num[a] = One;
      den[a] = dir_i[a];
    end
    num[3] = dir_i[kx];
    den[3] = dir_i[kz];
    num[4] = dir_i[ky];
    den[4] = dir_i[kz];
  end
  for (genvar k = 0; k < DIVS; k++) begin : g_div
    logic unused_tag;
    rf_fp_div #(.TAG_W(1)) u_div (
      .clk_i, .rst_ni,
      .in_valid_i(take & ok), .in_ready_o(div_in_ready[k]), .a_i(num[k]), .b_i(den[k]),
      .tag_i(1'b0),
      .out_valid_o(div_valid[k]), .out_ready_i(out_valid_o & out_ready_i), .q_o(q[k]),
      .tag_o(unused_tag));
  end

  // ---- the ray held ----
  logic             busy_q, ok_q;
  logic [1:0]       kx_q, ky_q, kz_q;
  logic [2:0][31:0] origin_q, dir_q;
  logic [TAG_W-1:0] tag_q;
  assign in_ready_o  = ~busy_q;
  assign out_valid_o = busy_q & (~ok_q | &div_valid);
  assign busy_o      = busy_q;
  assign ok_o        = ok_q;
  assign tag_o       = tag_q;

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      busy_q <= 1'b0;
    end else if (take) begin
      busy_q <= 1'b1;
    end else if (out_valid_o && out_ready_i) begin
      busy_q <= 1'b0;
    end
  end

  always_ff @(posedge clk_i) begin
    if (take) begin
      ok_q     <= ok;
      kx_q     <= kx;
      ky_q     <= ky;
      kz_q     <= kz;
      origin_q <= origin_i;
      dir_q    <= dir_i;
      tag_q    <= tag_i;
    end
  end

  always_comb begin
    ray_o = '0;
    ray_o[1][4:3] = kx_q;
    ray_o[1][6:5] = ky_q;
    ray_o[1][8:7] = kz_q;
    for (int a = 0; a < 3; a++) begin
      ray_o[2 + a]  = origin_q[a];
      ray_o[5 + a]  = dir_q[a];
      ray_o[8 + a]  = q[a];
    end
    ray_o[12] = q[3];
    ray_o[13] = q[4];
    ray_o[14] = q[3'(kz_q)];
  end

  // the dividers are idle whenever the unit is (they start together and finish together)
  logic unused;
  assign unused = ^div_in_ready;

endmodule
