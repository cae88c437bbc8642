// rf_fp_div: IEEE-754 binary32 division, q = a / b, round to nearest even; iterative (one radix-4
// quotient digit a cycle), one division at a time, constant latency.
//
// Contract (bit-exact with numpy float32 a / b):
//   * subnormal inputs and outputs fully supported (no flush to zero); a quotient above the
//     largest finite value is +-inf, one below the normal range rounds into the subnormals (or to
//     +-0 below half the smallest subnormal);
//   * any NaN input, 0 / 0 and inf / inf give the canonical quiet NaN 32'h7FC00000;
//   * x / 0 for x non-zero (inf included) and inf / finite are +-inf; 0 / x for x non-zero (inf
//     included) and finite / inf are +-0;
//   * the sign of every non-NaN result (zeros and infinities included) is sign(a) xor sign(b).
//
// Handshake (valid/ready on both ports; a beat moves on a rising clock edge with valid and ready
// both high; tag_i travels with its operands to tag_o unchanged):
//   * in_ready_o is high exactly while the unit holds no division (decoded from the state
//     register alone).
//   * A division taken in cycle 0 has out_valid_o high from cycle DIV_CYCLES
//     (rf_fp_div_pkg::DIV_CYCLES), for every operand pair, special cases included.  out_valid_o
//     then holds, with q_o and tag_o stable, until out_ready_i takes the result; in_ready_o is high
//     from the next cycle.  With out_ready_i held high a division starts every DIV_CYCLES + 1
//     cycles.
//   * No combinational path from an input to an output: in_ready_o, out_valid_o, q_o and tag_o
//     come from registers only.  a_i, b_i and tag_i are read only in the handshake cycle.
//
// Structure (classify -> special result or datapath -> the one shared rounder, as the other units):
//   * cycle 0, the input handshake: classify the operands (the special cases choose the result
//     and the datapath runs on regardless, so the latency stays constant); pre-normalise a
//     subnormal significand (leading-zero count, rf_fp_pkg::fp_lzc32) so both significands ma, mb
//     have their leading one in bit 23; load the partial remainder w = 2 ma (< 4 mb), the divisor
//     mb, its multiple 3 mb and the exponent ea - eb + 126;
//   * cycles 1 .. DIV_ITER_CYCLES (= DIV_CYCLES - 2): radix-4 restoring division, one quotient
//     digit a cycle: the digit is the largest d in 0..3 with d mb <= w (three subtractions side
//     by side, no chain), w <- 4 (w - d mb);
//   * cycle DIV_CYCLES - 1: the quotient Q = floor(2 ma / mb * 4^12) has its leading one in bit
//     25 or 24 (a one-bit normalisation, no leading-zero count); with the sticky bit (the
//     remainder is not zero) it goes through rf_fp_pkg::fp_round (overflow, gradual underflow,
//     RNE) into the output register, unless a special case chose the result.
module rf_fp_div
  import rf_fp_pkg::*;
  import rf_fp_div_pkg::*;
#(
  parameter int unsigned TAG_W = 8
) (
  input  logic             clk_i,
  input  logic             rst_ni,

  input  logic             in_valid_i,
  output logic             in_ready_o,
  input  logic [31:0]      a_i,
  input  logic [31:0]      b_i,
  input  logic [TAG_W-1:0] tag_i,

  output logic             out_valid_o,
  input  logic             out_ready_i,
  output logic [31:0]      q_o,
  output logic [TAG_W-1:0] tag_o
);

  localparam logic [31:0] CanonicalNaN = 32'h7FC0_0000;
  localparam logic [30:0] InfMagnitude = 31'h7F80_0000;
  localparam int unsigned QW           = DIV_QUOTIENT_BITS;
  localparam int unsigned CountW       = $clog2(DIV_CYCLES);

  if (QW != 26 || DIV_DIGIT_BITS != 2 || DIV_CYCLES != DIV_ITER_CYCLES + 2) begin : g_bad_radix
    $error("rf_fp_div: the datapath below is written for 13 radix-4 digits and one rounding cycle");
  end

  typedef enum logic [1:0] {
    StIdle,      // no division: in_ready_o
    StBusy,      // cycles 1 .. DIV_CYCLES - 1 after the handshake: digits, then rounding
    StDone       // out_valid_o until the result is taken
  } state_e;

  // What the result is: the rounded quotient, or a special value.
  typedef enum logic [1:0] {
    KindQuotient,
    KindZero,
    KindInf,
    KindNaN
  } kind_e;

  state_e            state_q, state_d;
  logic [CountW-1:0] cycle_q;          // cycles since the handshake, while StBusy
  kind_e             kind_q, kind_d;
  logic              sign_q;
  logic signed [9:0] exp_q, exp_d;     // biased exponent of quotient bit 24
  logic [23:0]       div_q, div_d;     // divisor significand mb, leading one in bit 23
  logic [25:0]       div3_q;           // 3 mb
  logic [25:0]       rem_q, rem_d;     // partial remainder w (< 4 mb)
  logic [QW-1:0]     quot_q, quot_d;   // quotient digits so far
  logic [31:0]       res_q, res_d;     // the result
  logic [TAG_W-1:0]  tag_q;

  logic in_fire, out_fire, round_cycle;
  assign in_fire     = in_valid_i & in_ready_o;
  assign out_fire    = out_valid_o & out_ready_i;
  assign round_cycle = cycle_q == CountW'(DIV_CYCLES - 1);

  assign in_ready_o  = state_q == StIdle;
  assign out_valid_o = state_q == StDone;
  assign q_o         = res_q;
  assign tag_o       = tag_q;

  // ---------------------------------------------------------------------------------------------
  // Cycle 0: classify and unpack the operands.
  // ---------------------------------------------------------------------------------------------
  always_comb begin
    logic       a_zero, b_zero, a_inf, b_inf, a_nan, b_nan;
    logic [4:0] lzc_a, lzc_b;
    logic [23:0] sig_a;

    a_zero = a_i[30:0] == 31'd0;
    b_zero = b_i[30:0] == 31'd0;
    a_inf  = a_i[30:0] == InfMagnitude;
    b_inf  = b_i[30:0] == InfMagnitude;
    a_nan  = a_i[30:0] > InfMagnitude;
    b_nan  = b_i[30:0] > InfMagnitude;

    if (a_nan || b_nan || (a_zero && b_zero) || (a_inf && b_inf)) begin
      kind_d = KindNaN;
    end else if (a_inf || b_zero) begin
      kind_d = KindInf;
    end else if (a_zero || b_inf) begin
      kind_d = KindZero;
    end else begin
      kind_d = KindQuotient;
    end

    // A subnormal significand (exponent field 0, no hidden bit) is shifted up until its leading
    // one reaches bit 23 (1..23 places), its exponent becoming 1 - shift.  (A zero operand gives
    // garbage here: its result is a special case.)
    lzc_a = fp_lzc32({1'b0, a_i[22:0], 8'd0});
    lzc_b = fp_lzc32({1'b0, b_i[22:0], 8'd0});
    if (a_i[30:23] != 8'd0) begin
      sig_a = {1'b1, a_i[22:0]};
      exp_d = $signed({2'b00, a_i[30:23]});
    end else begin
      sig_a = {1'b0, a_i[22:0]} << lzc_a;
      exp_d = 10'sd1 - $signed({5'd0, lzc_a});
    end
    if (b_i[30:23] != 8'd0) begin
      div_d = {1'b1, b_i[22:0]};
      exp_d = exp_d - $signed({2'b00, b_i[30:23]});
    end else begin
      div_d = {1'b0, b_i[22:0]} << lzc_b;
      exp_d = exp_d - (10'sd1 - $signed({5'd0, lzc_b}));
    end
    // 2 ma / mb is in (1, 4); quotient bit 24 stands for 2^(ea - eb - 1)
    exp_d = exp_d + 10'sd126;
    rem_d = {1'b0, sig_a, 1'b0};
  end

  // ---------------------------------------------------------------------------------------------
  // Cycles 1 .. DIV_ITER_CYCLES: one radix-4 quotient digit a cycle.
  // ---------------------------------------------------------------------------------------------
  logic [25:0] rem_next;
  logic [1:0]  digit;

  always_comb begin
    logic [26:0] sub1, sub2, sub3;     // w - d mb with a borrow bit
    sub1 = {1'b0, rem_q} - {3'b000, div_q};
    sub2 = {1'b0, rem_q} - {2'b00, div_q, 1'b0};
    sub3 = {1'b0, rem_q} - {1'b0, div3_q};
    if (!sub3[26]) begin
      digit    = 2'd3;
      rem_next = sub3[25:0] << 2;      // (< 4 mb: bits 25:24 of w - d mb are 0)
    end else if (!sub2[26]) begin
      digit    = 2'd2;
      rem_next = sub2[25:0] << 2;
    end else if (!sub1[26]) begin
      digit    = 2'd1;
      rem_next = sub1[25:0] << 2;
    end else begin
      digit    = 2'd0;
      rem_next = rem_q << 2;
    end
    quot_d = {quot_q[QW-3:0], digit};
  end

  // ---------------------------------------------------------------------------------------------
  // Round: normalise by one bit, append the sticky bit, round (or select the special result).
  // ---------------------------------------------------------------------------------------------
  always_comb begin
    logic              sticky;
    logic [31:0]       sig;
    logic signed [9:0] exp;
    sticky = rem_q != 26'd0;
    if (quot_q[25]) begin
      sig = {quot_q[25:0], sticky, 5'd0};
      exp = exp_q + 10'sd1;
    end else begin
      sig = {quot_q[24:0], sticky, 6'd0};
      exp = exp_q;
    end
    unique case (kind_q)
      KindQuotient: res_d = fp_round(sign_q, exp, sig);
      KindZero:     res_d = {sign_q, 31'd0};
      KindInf:      res_d = {sign_q, InfMagnitude};
      default:      res_d = CanonicalNaN;
    endcase
  end

  // ---------------------------------------------------------------------------------------------
  // Control
  // ---------------------------------------------------------------------------------------------
  always_comb begin
    state_d = state_q;
    unique case (state_q)
      StIdle:  if (in_fire)     state_d = StBusy;
      StBusy:  if (round_cycle) state_d = StDone;
      default: if (out_fire)    state_d = StIdle;
    endcase
  end

  always_ff @(posedge clk_i or negedge rst_ni) begin
    if (!rst_ni) begin
      state_q <= StIdle;
    end else begin
      state_q <= state_d;
    end
  end

  // Data registers carry no reset: each is written before it is read (the operands in the
  // handshake cycle, the result before out_valid_o rises).
  always_ff @(posedge clk_i) begin
    if (in_fire) begin
      cycle_q <= CountW'(1);
      kind_q  <= kind_d;
      sign_q  <= a_i[31] ^ b_i[31];
      exp_q   <= exp_d;
      div_q   <= div_d;
      div3_q  <= {2'b00, div_d} + {1'b0, div_d, 1'b0};
      rem_q   <= rem_d;
      quot_q  <= '0;
      tag_q   <= tag_i;
    end else if (state_q == StBusy) begin
      cycle_q <= cycle_q + CountW'(1);
      if (round_cycle) begin
        res_q <= res_d;
      end else begin
        rem_q  <= rem_next;
        quot_q <= quot_d;
      end
    end
  end

`ifdef RF_ASSERTIONS
  // Protocol check (simulation builds with +define+RF_ASSERTIONS and --assert): a raised
  // out_valid_o holds, with stable data, until it is taken.
  hold_out_valid_o : assert property (@(posedge clk_i) disable iff (!rst_ni)
      out_valid_o && !out_ready_i |=> out_valid_o && $stable(q_o) && $stable(tag_o));
`endif

endmodule
