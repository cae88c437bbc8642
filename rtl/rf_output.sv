// Output stage: the stage struct to the response format. Fields the beat's operation does not
// produce are driven to zero.
module rf_output import rf_pkg::*; #(
  parameter bit EXTENDED = 1'b0,
  parameter bit TRANSFORM = 1'b0
) (
  input  stage_t st_i,
  output rsp_t   rsp_o
);
  always_comb begin
    rsp_o        = '0;
    rsp_o.opcode = st_i.op;
    rsp_o.tag    = st_i.tag;
    unique case (st_i.op)
      OP_QUADBOX: begin
        rsp_o.box_index = st_i.pl.box_sort.idx;
        rsp_o.box_hit   = st_i.pl.box_sort.hit;
        rsp_o.box_tmin  = st_i.pl.box_sort.tmin;
      end
      OP_TRIANGLE: begin
        rsp_o.tri_hit = st_i.pl.tri_edge.hit;
        rsp_o.t_num   = st_i.pl.tri_edge.num;
        rsp_o.t_den   = st_i.pl.tri_edge.den;
      end
      OP_EUCLIDEAN: begin
        if (EXTENDED) begin
          rsp_o.euclid_acc  = st_i.pl.euc.acc;
          rsp_o.euclid_last = st_i.last;
        end
      end
      OP_ANGULAR: begin
        if (EXTENDED) begin
          rsp_o.angular_dot  = st_i.pl.ang.dot_acc;
          rsp_o.angular_norm = st_i.pl.ang.norm_acc;
          rsp_o.angular_last = st_i.last;
        end
      end
      OP_TRANSFORM: begin
        if (TRANSFORM) begin
          for (int r = 0; r < 3; r++) begin
            rsp_o.xf_origin[r] = st_i.pl.xfm.po[r][0];
            rsp_o.xf_dir[r]    = st_i.pl.xfm.pd[r][0];
          end
        end
      end
      default: ;
    endcase
  end
endmodule
