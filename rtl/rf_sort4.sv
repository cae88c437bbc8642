// One layer of the 5-comparator sorting network for four (tmin, index) pairs.
//   LAYER 0: (0,1) (2,3)    LAYER 1: (0,2) (1,3)    LAYER 2: (1,2)
// Keys compare lexicographically: tmin first, then the box index. Every tmin here is +0..+inf
// (a hit's tmin is finite and non-negative, a miss is +inf, never NaN or -0), and non-negative
// binary32 values order like their bit patterns as unsigned integers, so the compare is an integer
// compare. All keys differ (indices differ), so the network sorts them totally.
module rf_sort4 import rf_pkg::*; #(
  parameter int unsigned LAYER = 0
) (
  input  fp32_t [3:0]      tmin_i,
  input  logic  [3:0][1:0] idx_i,
  input  logic  [3:0]      hit_i,
  output fp32_t [3:0]      tmin_o,
  output logic  [3:0][1:0] idx_o,
  output logic  [3:0]      hit_o
);

  function automatic logic key_less(fp32_t ta, logic [1:0] ia, fp32_t tb, logic [1:0] ib);
    return (ta < tb) || (ta == tb && ia < ib);
  endfunction

  // Compare-exchange pairs of this layer (lo gets the smaller key); a pair (k, k) is unused.
  localparam int unsigned LO0 = (LAYER == 0) ? 0 : (LAYER == 1) ? 0 : 1;
  localparam int unsigned HI0 = (LAYER == 0) ? 1 : (LAYER == 1) ? 2 : 2;
  localparam int unsigned LO1 = (LAYER == 0) ? 2 : (LAYER == 1) ? 1 : 0;
  localparam int unsigned HI1 = (LAYER == 0) ? 3 : (LAYER == 1) ? 3 : 0;

  always_comb begin
    tmin_o = tmin_i;
    idx_o  = idx_i;
    hit_o  = hit_i;
    if (key_less(tmin_i[HI0], idx_i[HI0], tmin_i[LO0], idx_i[LO0])) begin
      tmin_o[LO0] = tmin_i[HI0];  tmin_o[HI0] = tmin_i[LO0];
      idx_o[LO0]  = idx_i[HI0];   idx_o[HI0]  = idx_i[LO0];
      hit_o[LO0]  = hit_i[HI0];   hit_o[HI0]  = hit_i[LO0];
    end
    if (LO1 != HI1 && key_less(tmin_i[HI1], idx_i[HI1], tmin_i[LO1], idx_i[LO1])) begin
      tmin_o[LO1] = tmin_i[HI1];  tmin_o[HI1] = tmin_i[LO1];
      idx_o[LO1]  = idx_i[HI1];   idx_o[HI1]  = idx_i[LO1];
      hit_o[LO1]  = hit_i[HI1];   hit_o[HI1]  = hit_i[LO1];
    end
  end

endmodule
