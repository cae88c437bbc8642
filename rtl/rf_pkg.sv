// RayFlex package: opcodes, IO structs, the shared stage struct and the stage/FU-pool plan.
//
// Everything the pipeline carries is defined here once (the paper's "Shared RayFlex Data
// Structure"): the input stage turns a req_t into a stage_t, every inner stage reads a stage_t and
// writes a stage_t (copying it and overwriting the fields it produces), the output stage turns a
// stage_t into a rsp_t. Unused fields are dead logic and fall away in synthesis.
//
// Numbers are IEEE-754 binary32 throughout (fp32_t); every add/multiply rounds to nearest-even.
package rf_pkg;

  typedef logic [31:0] fp32_t;

  localparam fp32_t FP_POS_ZERO  = 32'h0000_0000;
  localparam fp32_t FP_POS_INF   = 32'h7F80_0000;

  // ---------------------------------------------------------------------------------------------
  // Opcodes (SPEC section 3). The opcode value is also the index of the operation's operand slot in
  // a functional-unit pool (see rf_fu_pool).
  // ---------------------------------------------------------------------------------------------
  typedef enum logic [1:0] {
    OP_TRIANGLE  = 2'd0,
    OP_QUADBOX   = 2'd1,
    OP_EUCLIDEAN = 2'd2,
    OP_ANGULAR   = 2'd3
  } opcode_e;

  localparam int unsigned NUM_OPS   = 4;
  localparam int unsigned EUC_LANES = 16;
  localparam int unsigned ANG_LANES = 8;

  // Negate a binary32 value (a - b is computed as a + (-b), which IEEE defines identically).
  function automatic fp32_t fp_neg(fp32_t x);
    return {~x[31], x[30:0]};
  endfunction

  // ---------------------------------------------------------------------------------------------
  // IO structs: a word-aligned wire format, word 0 at the least significant bits, so that a host
  // packs a request as an array of little-endian uint32 words (driver/wire.py mirrors this).
  // Packed arrays put element 0 at the low end: box[i][j] is word 15 + 6*i + j.
  // ---------------------------------------------------------------------------------------------
  typedef struct packed {
    fp32_t [15:0]     vec_b;              // words 64..79  (extended)
    fp32_t [15:0]     vec_a;              // words 48..63  (extended)
    fp32_t [2:0][2:0] triangle;              // words 39..47  [vertex A,B,C][axis]
    fp32_t [3:0][5:0] box;                // words 15..38  box[i] = xmin ymin zmin xmax ymax zmax
    fp32_t [2:0]      shear;              // words 12..14  Sx Sy Sz
    fp32_t            extent;             // word  11
    fp32_t [2:0]      inv;                // words  8..10  1/dir
    fp32_t [2:0]      dir;                // words  5..7
    fp32_t [2:0]      origin;             // words  2..4
    logic  [15:0]     vec_mask;           // word 1 [31:16] (extended)
    logic  [6:0]      rsvd;               // word 1 [15:9]
    logic             reset_accumulator;  // word 1 [8]     (extended)
    logic  [1:0]      kz;                 // word 1 [7:6]
    logic  [1:0]      ky;                 // word 1 [5:4]
    logic  [1:0]      kx;                 // word 1 [3:2]
    opcode_e          opcode;             // word 1 [1:0]
    logic  [31:0]     tag;                // word 0, carried through unchanged
  } req_t;

  typedef struct packed {
    fp32_t            angular_norm;       // word 10
    fp32_t            angular_dot;        // word 9
    fp32_t            euclid_acc;         // word 8
    fp32_t            t_den;              // word 7
    fp32_t            t_num;              // word 6
    fp32_t [3:0]      box_tmin;           // words 2..5, sorted
    logic  [14:0]     rsvd;               // word 1 [31:17]
    logic             angular_last;       // word 1 [16]
    logic             euclid_last;        // word 1 [15]
    logic             tri_hit;            // word 1 [14]
    logic  [3:0]      box_hit;            // word 1 [13:10], sorted
    logic  [3:0][1:0] box_index;          // word 1 [9:2], sorted
    opcode_e          opcode;             // word 1 [1:0]
    logic  [31:0]     tag;                // word 0
  } rsp_t;

  // ---------------------------------------------------------------------------------------------
  // The shared stage struct. Comments name the stage that writes each field (S1 = input stage).
  // ---------------------------------------------------------------------------------------------
  typedef struct packed {
    // common
    opcode_e          op;
    logic  [31:0]     tag;
    logic             last;          // reset_accumulator of an extended beat
    // ray (from the request)
    fp32_t [2:0]      dir;
    fp32_t [2:0]      inv;
    fp32_t            extent;
    logic  [1:0]      kx, ky, kz;
    fp32_t [2:0]      shear;
    // QUADBOX
    fp32_t [3:0][5:0] slab;          // S1: bound - origin; S2: (bound - origin) * inv
    logic  [3:0]      bnan;          // S3: some near/far value is NaN
    fp32_t [3:0]      bnear;         // S3: max(near_x, near_y); S4: with near_z; S5: with +0 = tmin
    fp32_t [3:0]      bfar;          // S3: min(far_x, far_y);   S4: with far_z;  S5: with extent
    fp32_t [3:0]      bnear_z;       // S3
    fp32_t [3:0]      bfar_z;        // S3
    logic  [3:0]      bhit;          // S6 (then permuted by the sort, S7-S9)
    fp32_t [3:0]      btmin;         // S6: tmin on a hit, +inf on a miss (then sorted)
    logic  [3:0][1:0] bidx;          // S6: 0,1,2,3 (then sorted)
    // TRIANGLE
    fp32_t [2:0][2:0] tp;            // S1: P - origin, [vertex][axis]
    fp32_t [2:0]      tpx, tpy;      // S2: P'[kx], P'[ky] per vertex
    fp32_t [2:0]      tsx, tsy;      // S2: Sx*P'[kz], Sy*P'[kz]
    fp32_t [2:0]      tz;            // S2: Z = Sz*P'[kz]
    fp32_t [2:0]      tx, ty;        // S3: X, Y per vertex
    fp32_t [5:0]      tcross;        // S4: Cx*By, Cy*Bx, Ax*Cy, Ay*Cx, Bx*Ay, By*Ax
    fp32_t            tu, tv, tw;    // S5: U, V, W
    fp32_t [2:0]      tuvw_z;        // S6: U*Az, V*Bz, W*Cz
    fp32_t            tuv;           // S6: U + V
    fp32_t            tnum_part;     // S7: U*Az + V*Bz
    fp32_t            t_den;         // S7: (U + V) + W
    fp32_t            t_num;         // S8: (U*Az + V*Bz) + W*Cz
    logic             tri_hit;       // S9
    // EUCLIDEAN / ANGULAR (extended)
    logic  [15:0]     mask;
    fp32_t [ANG_LANES-1:0] va, vb;   // S1: query / candidate lanes for ANGULAR
    fp32_t [EUC_LANES-1:0] ediff;    // S1: a - b
    fp32_t [EUC_LANES-1:0] esq;      // S2: (a - b)^2, masked lanes +0
    fp32_t [7:0]      esum;          // S3..S6: reduction tree, level k keeps 16 >> k sums
    fp32_t [ANG_LANES-1:0] adot;     // S2: a*b, masked +0;  S3..S5: tree
    fp32_t [ANG_LANES-1:0] anorm;    // S2: b*b, masked +0;  S3..S5: tree
    fp32_t            euclid_acc;    // S7: accumulator value after this beat
    fp32_t            angular_dot;   // S7
    fp32_t            angular_norm;  // S7
  } stage_t;

  // One-hot operation select for the FU pools.
  function automatic logic [NUM_OPS-1:0] op_onehot(opcode_e op);
    return NUM_OPS'(1) << op;
  endfunction

  // Maximum of four pool demands (one per operation).
  function automatic int unsigned max4(int unsigned a, int unsigned b, int unsigned c,
                                       int unsigned d);
    int unsigned m;
    m = a;
    if (b > m) m = b;
    if (c > m) m = c;
    if (d > m) m = d;
    return m;
  endfunction

endpackage
