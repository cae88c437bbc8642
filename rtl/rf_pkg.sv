// RayFlex package: opcodes, IO structs, the shared stage struct and the FU pools' operand tables.
//
// Everything the pipeline carries is defined here once (the paper's "Shared RayFlex Data
// Structure"): the input stage turns a req_t into a stage_t, every inner stage reads a stage_t and
// writes a stage_t (copying it and overwriting the fields it produces), the output stage turns a
// stage_t into a rsp_t. The operations share the payload bits (one view per operation and group of
// stages, see below): a stage register holds 4 + 32 + PAYLOAD_W = 964 bits, where the ten views
// side by side would need 5,688.
//
// Numbers are IEEE-754 binary32 throughout (fp32_t); every add/multiply rounds to nearest-even.
package rf_pkg;

  typedef logic [31:0] fp32_t;

  localparam fp32_t FP_POS_ZERO  = 32'h0000_0000;
  localparam fp32_t FP_POS_INF   = 32'h7F80_0000;

  // ---------------------------------------------------------------------------------------------
  // Opcodes (docs/datapath.md#requests-and-responses).
  // ---------------------------------------------------------------------------------------------
  typedef enum logic [2:0] {
    OP_TRIANGLE  = 3'd0,
    OP_QUADBOX   = 3'd1,
    OP_EUCLIDEAN = 3'd2,
    OP_ANGULAR   = 3'd3,
    OP_TRANSFORM = 3'd4     // build parameter TRANSFORM (docs/transform.md)
  } opcode_e;

  // Request flags (docs/datapath.md#flags): bit indices into req_t.flags; the other bits are reserved (0).
  localparam int unsigned FLAG_NO_CULL_BIT   = 0;  // TRIANGLE accepts both faces (docs/datapath.md#triangle)
  localparam int unsigned FLAG_DECODE_Q8_BIT = 1;  // QUADBOX: decode the q8 node req_qnode(req)

  localparam int unsigned EUC_LANES = 16;
  localparam int unsigned ANG_LANES = 8;

  // Negate a binary32 value (a - b is computed as a + (-b), which IEEE defines identically).
  function automatic fp32_t fp_neg(fp32_t x);
    return {~x[31], x[30:0]};
  endfunction

  // ---------------------------------------------------------------------------------------------
  // IO structs: a word-aligned wire format, word 0 at the least significant bits, so that a host
  // packs a request as an array of little-endian uint32 words (driver/core/layout.py mirrors this, and
  // tests/test_layout.py checks every field against it).
  // Packed arrays put element 0 at the low end: box[i][j] is word 15 + 6*i + j.
  // ---------------------------------------------------------------------------------------------
  typedef struct packed {
    logic  [15:0]     vec_mask;           // word 80 [31:16] (extended)
    logic  [14:0]     rsvd_80;            // word 80 [15:1]
    logic             reset_accumulator;  // word 80 [0]     (extended)
    fp32_t [15:0]     vec_b;              // words 64..79  (extended)
    fp32_t [15:0]     vec_a;              // words 48..63  (extended)
    fp32_t [2:0][2:0] triangle;           // words 39..47  [vertex A,B,C][axis]
    fp32_t [3:0][5:0] box;                // words 15..38  box[i] = xmin ymin zmin xmax ymax zmax
                                          //   (TRANSFORM: the matrix, req_matrix)
    fp32_t [2:0]      shear;              // words 12..14  Sx Sy Sz
    fp32_t            extent;             // word  11
    fp32_t [2:0]      inv;                // words  8..10  1/dir
    fp32_t [2:0]      dir;                // words  5..7
    fp32_t [2:0]      origin;             // words  2..4
    logic  [14:0]     rsvd_1;             // word 1 [31:17]
    logic  [7:0]      flags;              // word 1 [16:9]  FLAG_* bits, part of the ray
    logic  [1:0]      kz;                 // word 1 [8:7]
    logic  [1:0]      ky;                 // word 1 [6:5]
    logic  [1:0]      kx;                 // word 1 [4:3]
    opcode_e          opcode;             // word 1 [2:0]
    logic  [31:0]     tag;                // word 0, carried through unchanged
  } req_t;

  // A TRANSFORM's 3x4 matrix, row-major (m[r][c] is box word 4r + c): a TRANSFORM request carries
  // it on the first 12 box words (driver/core/layout.py: request field matrix overlays box), i.e. the
  // matrix is req_matrix(req.box).
  localparam int unsigned MATRIX_WORDS = 12;
  typedef fp32_t [2:0][3:0] matrix_t;
  /* verilator lint_off UNUSEDSIGNAL */   // box words 12..23
  function automatic matrix_t req_matrix(input fp32_t [3:0][5:0] box);
    logic [$bits(box)-1:0] words;
    words = box;
    return matrix_t'(words[MATRIX_WORDS*32-1:0]);
  endfunction
  /* verilator lint_on UNUSEDSIGNAL */

  // The SHARED build's request registers (the input register, and the decode register of a
  // COMPRESSED build; docs/tradeoffs.md#sharing-registers): an EUCLIDEAN or ANGULAR beat's vector
  // fields travel on its box and triangle words, which such a beat does not use, so the registers
  // before stage 1 keep no bits of their own for them (synthesis removes the unread ones).
  // req_share packs a request before the input register, req_unshare unpacks it for stage 1.
  localparam int unsigned VEC_FIELDS_W = 2 * 16 * 32 + 16 + 1;     // vec_a, vec_b, mask, reset
  localparam int unsigned SHARE_W      = (24 + 9) * 32;            // box and triangle words

  function automatic req_t req_share(input req_t r);
    req_t p;
    p = r;
    if ((r.opcode == OP_EUCLIDEAN) || (r.opcode == OP_ANGULAR))
      {p.triangle, p.box} = SHARE_W'({r.reset_accumulator, r.vec_mask, r.vec_b, r.vec_a});
    return p;
  endfunction

  /* verilator lint_off UNUSEDSIGNAL */   // the vector fields of p: unpacked from the box words
  function automatic req_t req_unshare(input req_t p);
    req_t r;
    logic [SHARE_W-1:0] w;
    r = p;
    w = {p.triangle, p.box};
    {r.reset_accumulator, r.vec_mask, r.vec_b, r.vec_a} = w[VEC_FIELDS_W-1:0];
    return r;
  endfunction
  /* verilator lint_on UNUSEDSIGNAL */

  // The q8 box node as stored in the compressed BVH image (driver/core/layout.py Q8_NODE; 16 words,
  // word 0 at the low end). A QUADBOX with flags[FLAG_DECODE_Q8_BIT] carries it on the first 16
  // box words (driver/core/layout.py: request field qnode overlays box), i.e. the node is
  // q8_node_t'(box words 0..15); a COMPRESSED build decodes it (rf_s00_q8_decode).
  localparam int unsigned QNODE_WORDS = 16;
  typedef struct packed {
    logic  [31:0]          rsvd_15;       // word 15
    logic  [31:0]          parent;        // word 14
    logic  [3:0][5:0][7:0] q;             // words 8..13: child i's qlo xyz, qhi xyz (uint8)
    logic  [3:0][31:0]     child;         // words 4..7: node pointers
    logic  [4:0]           rsvd_3;        // word 3 [31:27]
    logic  [2:0]           count;         // word 3 [26:24]: used children (used slots first)
    logic  [2:0][7:0]      exp;           // word 3 [23:0]: exp_x, exp_y, exp_z (int8)
    fp32_t [2:0]           origin;        // words 0..2
  } q8_node_t;

  typedef struct packed {
    fp32_t [2:0]      xf_dir;             // words 14..16  TRANSFORM: d'
    fp32_t [2:0]      xf_origin;          // words 11..13  TRANSFORM: o'
    fp32_t            angular_norm;       // word 10
    fp32_t            angular_dot;        // word 9
    fp32_t            euclid_acc;         // word 8
    fp32_t            t_den;              // word 7
    fp32_t            t_num;              // word 6
    fp32_t [3:0]      box_tmin;           // words 2..5, sorted
    logic  [13:0]     rsvd;               // word 1 [31:18]
    logic             angular_last;       // word 1 [17]
    logic             euclid_last;        // word 1 [16]
    logic             tri_hit;            // word 1 [15]
    logic  [3:0]      box_hit;            // word 1 [14:11], sorted
    logic  [3:0][1:0] box_index;          // word 1 [10:3], sorted
    opcode_e          opcode;             // word 1 [2:0]
    logic  [31:0]     tag;                // word 0
  } rsp_t;

  // ---------------------------------------------------------------------------------------------
  // The shared stage struct.
  //
  // A beat carries one operation, so the operations share the payload bits (a packed union), and
  // within an operation fields whose lifetimes do not overlap share bits too (the paper's reuse of
  // the shared structure): each operation has one "view" (struct) per group of stages. Rn is the
  // stage_t register after stage Sn (S1 = input stage); comments name the stage that writes a
  // field. Every view is PAYLOAD_W bits wide: 32-bit values sit at the low end, word aligned, the
  // few single-bit fields above them and the unused bits (rsvd) on top (the extended operations'
  // views are placed on the bits the box and triangle views use in the same register).
  // ---------------------------------------------------------------------------------------------
  localparam int unsigned PAYLOAD_W = 29 * 32;

  // QUADBOX, R1..R2
  typedef struct packed {
    logic [PAYLOAD_W-28*32-3-1:0] rsvd;
    logic  [2:0]      dir_neg;       // S1: sign bits of dir (S3 picks near/far with them)
    fp32_t            extent;        // S1
    fp32_t [2:0]      inv;           // S1
    fp32_t [3:0][5:0] slab;          // S1: bound - origin; S2: (bound - origin) * inv  [box][bound]
  } box_slab_t;

  // QUADBOX, R3..R5
  typedef struct packed {
    logic [PAYLOAD_W-17*32-4-1:0] rsvd;
    logic  [3:0]      nan;           // S3: some near/far value of the box is NaN
    fp32_t            extent;
    fp32_t [3:0]      tnear;         // S3: max(near_x, near_y); S4: with near_z; S5: with +0 = tmin
    fp32_t [3:0]      tfar;          // S3: min(far_x, far_y);   S4: with far_z;  S5: with extent
    fp32_t [3:0]      tnear_z;       // S3: near_z
    fp32_t [3:0]      tfar_z;        // S3: far_z
  } box_range_t;

  // QUADBOX, R6..R9
  typedef struct packed {
    logic [PAYLOAD_W-4*32-12-1:0] rsvd;
    logic  [3:0]      hit;           // S6 (then permuted by the sort, S7..S9)
    logic  [3:0][1:0] idx;           // S6: 0, 1, 2, 3 (then sorted)
    fp32_t [3:0]      tmin;          // S6: tmin on a hit, +inf on a miss (then sorted)
  } box_sort_t;

  // TRIANGLE, R1
  typedef struct packed {
    logic [PAYLOAD_W-12*32-7-1:0] rsvd;
    logic             no_cull;       // S1: flags[FLAG_NO_CULL_BIT]
    logic  [1:0]      kx, ky, kz;    // S1
    fp32_t [2:0]      shear;         // S1: Sx, Sy, Sz
    fp32_t [2:0][2:0] p;             // S1: P' = P - origin  [vertex A, B, C][axis]
  } tri_vert_t;

  // TRIANGLE, R2
  typedef struct packed {
    logic [PAYLOAD_W-15*32-1-1:0] rsvd;
    logic             no_cull;       // from S1
    fp32_t [2:0]      px, py;        // S2: P'[kx], P'[ky] per vertex
    fp32_t [2:0]      sx, sy;        // S2: Sx*P'[kz], Sy*P'[kz]
    fp32_t [2:0]      z;             // S2: Z = Sz*P'[kz]
  } tri_shear_t;

  // TRIANGLE, R3..R9
  typedef struct packed {
    logic [PAYLOAD_W-25*32-2-1:0] rsvd;
    logic             no_cull;       // from S1
    logic             hit;           // S9
    fp32_t [2:0]      z;             // from S2
    fp32_t [2:0]      x, y;          // S3: X, Y per vertex
    fp32_t [5:0]      xprod;         // S4: Cx*By, Cy*Bx, Ax*Cy, Ay*Cx, Bx*Ay, By*Ax
    fp32_t            u, v, w;       // S5: U, V, W
    fp32_t [2:0]      uvw_z;         // S6: U*Az, V*Bz, W*Cz
    fp32_t            uv;            // S6: U + V
    fp32_t            num_part;      // S7: U*Az + V*Bz
    fp32_t            den;           // S7: t_den = (U + V) + W
    fp32_t            num;           // S8: t_num = (U*Az + V*Bz) + W*Cz
  } tri_edge_t;

  // EUCLIDEAN and ANGULAR: their fields sit where a QUADBOX or TRIANGLE field lives in the same
  // register (the paper's "fields with the same lifetime at the same bits"), so that synthesis
  // keeps no stage-register bit for the extended operations alone: the reduction trees' live
  // lanes in words 8.. (the box's interval and the triangle's U, V, W at R4..R6), the
  // accumulators in words 0..1 (the box's sorted tmin at R7..R9), the masks above word 23 (R1
  // only: the box's inv and extent).
  localparam int unsigned VEC_BASE = 8;      // the word of lane 0

  // EUCLIDEAN, R1..R9
  typedef struct packed {
    logic [PAYLOAD_W-(VEC_BASE+16)*32-16-1:0] rsvd;
    logic  [15:0]     mask;          // S1
    fp32_t [EUC_LANES-1:0] e;        // S1: a - b; S2: (a - b)^2, masked lanes +0;
                                     // S3..S6: reduction tree, level k keeps e[0 .. (16 >> k) - 1]
    logic  [(VEC_BASE-1)*32-1:0] gap;
    fp32_t            acc;           // S7: accumulator value after this beat
  } euc_t;

  // ANGULAR, R1..R9
  typedef struct packed {
    logic [PAYLOAD_W-(VEC_BASE+16)*32-8-1:0] rsvd;
    logic  [ANG_LANES-1:0] mask;     // S1
    fp32_t [ANG_LANES-1:0] dot;      // S1: query lanes a; S2: a*b, masked +0; S3..S5: tree
    fp32_t [ANG_LANES-1:0] norm;     // S1: candidate lanes b; S2: b*b, masked +0; S3..S5: tree
    logic  [(VEC_BASE-2)*32-1:0] gap;
    fp32_t            dot_acc;       // S7: accumulator values after this beat
    fp32_t            norm_acc;
  } ang_t;

  // TRANSFORM, R1
  typedef struct packed {
    logic [PAYLOAD_W-18*32-1:0] rsvd;
    fp32_t [2:0]      dir;           // S1: d
    fp32_t [2:0]      origin;        // S1: o
    matrix_t          m;             // S1: m[r][c]
  } xfm_in_t;

  // TRANSFORM, R2..R9: the sums are written over their first operand, in the order of
  // docs/transform.md: o'[r] = ((m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]) + m[r][3],
  // d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]
  typedef struct packed {
    logic [PAYLOAD_W-21*32-1:0] rsvd;
    fp32_t [2:0]      t;             // S2: m[r][3]
    fp32_t [2:0][2:0] pd;            // S2: m[r][c]*d[c]; S3: pd[r][0] += pd[r][1];
                                     // S5: pd[r][0] += pd[r][2] = d'[r]
    fp32_t [2:0][2:0] po;            // S2: m[r][c]*o[c]; S3: po[r][0] += po[r][1];
                                     // S6 (r 0), S7 (r 1, 2): po[r][0] += po[r][2];
                                     // S8: po[r][0] += t[r] = o'[r]
  } xfm_t;

  typedef union packed {
    box_slab_t  box_slab;
    box_range_t box_range;
    box_sort_t  box_sort;
    tri_vert_t  tri_vert;
    tri_shear_t tri_shear;
    tri_edge_t  tri_edge;
    euc_t       euc;
    ang_t       ang;
    xfm_in_t    xfm_in;
    xfm_t       xfm;
  } payload_u;

  typedef struct packed {
    opcode_e          op;
    logic             last;          // reset_accumulator of an extended beat
    logic  [31:0]     tag;
    payload_u         pl;            // the view that the operation and stage select
  } stage_t;

  // ---------------------------------------------------------------------------------------------
  // Functional-unit pools (rf_fu_pool). A stage asks its pool for units with one operand table
  // indexed [opcode][unit]: operation o's unit k takes its operands from a[o][k] and b[o][k] and
  // gives its sum or product at y[o][k], for k < n[o]. fu_count(.n_tri(..), ..) says how many units
  // each operation uses (the operations it does not name, none); fu_width is a row's length.
  // ---------------------------------------------------------------------------------------------
  localparam int unsigned NUM_OPS = int'(OP_TRANSFORM) + 1;

  typedef logic [NUM_OPS-1:0][31:0] fu_count_t;    // units per operation, indexed by opcode

  function automatic fu_count_t fu_count(int unsigned n_tri = 0, int unsigned n_box = 0,
                                         int unsigned n_euc = 0, int unsigned n_ang = 0,
                                         int unsigned n_xfm = 0);
    fu_count_t n;
    n               = '0;
    n[OP_TRIANGLE]  = n_tri;
    n[OP_QUADBOX]   = n_box;
    n[OP_EUCLIDEAN] = n_euc;
    n[OP_ANGULAR]   = n_ang;
    n[OP_TRANSFORM] = n_xfm;
    return n;
  endfunction

  // The units a pool holds when shared: the largest demand of one operation (0: an empty pool).
  function automatic int unsigned fu_units(fu_count_t n);
    int unsigned m;
    m = 0;
    for (int o = 0; o < int'(NUM_OPS); o++) if (n[o] > m) m = n[o];
    return m;
  endfunction

  // The length of a row of the operand table (at least one entry, so that it can be declared).
  function automatic int unsigned fu_width(fu_count_t n);
    return (fu_units(n) > 0) ? fu_units(n) : 1;
  endfunction

endpackage
