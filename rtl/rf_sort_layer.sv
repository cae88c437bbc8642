// One layer of the 5-comparator sorting network for the four (tmin, index, hit) entries of a
// QUADBOX beat; stages 7, 8 and 9 each hold one layer (the LAYER parameter), on the box_sort view.
//   LAYER 0: (0,1) (2,3)    LAYER 1: (0,2) (1,3)    LAYER 2: (1,2)
// Keys compare lexicographically: tmin first, then the box index. Every tmin here is +0..+inf
// (a hit's tmin is finite and non-negative, a miss is +inf, never NaN or -0), and non-negative
// binary32 values order like their bit patterns as unsigned integers, so the compare is an integer
// compare. All keys differ (indices differ), so the network sorts them totally.
module rf_sort_layer import rf_pkg::*; #(
  parameter int unsigned LAYER = 0
) (
  input  box_sort_t box_i,
  output box_sort_t box_o
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
    box_o = box_i;
    if (key_less(box_i.tmin[HI0], box_i.idx[HI0], box_i.tmin[LO0], box_i.idx[LO0])) begin
      box_o.tmin[LO0] = box_i.tmin[HI0];  box_o.tmin[HI0] = box_i.tmin[LO0];
      box_o.idx[LO0]  = box_i.idx[HI0];   box_o.idx[HI0]  = box_i.idx[LO0];
      box_o.hit[LO0]  = box_i.hit[HI0];   box_o.hit[HI0]  = box_i.hit[LO0];
    end
    if (LO1 != HI1 && key_less(box_i.tmin[HI1], box_i.idx[HI1], box_i.tmin[LO1], box_i.idx[LO1]))
    begin
      box_o.tmin[LO1] = box_i.tmin[HI1];  box_o.tmin[HI1] = box_i.tmin[LO1];
      box_o.idx[LO1]  = box_i.idx[HI1];   box_o.idx[HI1]  = box_i.idx[LO1];
      box_o.hit[LO1]  = box_i.hit[HI1];   box_o.hit[HI1]  = box_i.hit[LO1];
    end
  end

endmodule
