// RT-unit package: the node-image layout the unit reads (docs/datapath.md#bvh4-image, the host's
// definition is driver/core/layout.py; tests/test_rtunit_rtl.py checks every constant here
// against it), the memory-port widths and the ray-slot states shared by the unit's modules
// (docs/rtunit_rtl.md).
package rf_rtu_pkg;

  // ---- node pointers: (byte offset >> PTR_SHIFT) | type ----
  localparam int unsigned PTR_SHIFT = 3;
  localparam logic [2:0]  BOX_TYPE  = 3'd5;   // box32 box node, 128 bytes
  localparam logic [2:0]  TRI_TYPE  = 3'd0;   // triangle node, 64 bytes
  localparam logic [2:0]  Q8_TYPE   = 3'd4;   // q8 box node, 64 bytes (docs/compressed.md)
  localparam logic [2:0]  PAIR_TYPE = 3'd1;   // triangle-pair leaf, 64 bytes
  localparam logic [2:0]  LEAF_NEXT_TYPE = 3'd3;  // a leaf's next triangle (bits 31:29: k - 1)
  localparam logic [2:0]  INSTANCE_TYPE  = 3'd6;  // instance node, 128 bytes (docs/instances.md)
  // The unit's own stack entry, never in an image: pushed below a BLAS when a ray enters an
  // instance; popping it returns the ray to its world ray (the TLAS).
  localparam logic [2:0]  RETURN_TYPE    = 3'd7;
  localparam logic [31:0] RETURN_PTR     = {29'd0, RETURN_TYPE};
  localparam logic [31:0] NO_CHILD  = 32'hFFFF_FFFF;

  // ---- node layouts (32-bit words, word 0 at the lowest address) ----
  localparam int unsigned BOX_NODE_WORDS      = 32;
  localparam int unsigned BOX_NODE_CHILD_WORD = 0;    // 4 node pointers
  localparam int unsigned BOX_NODE_BOX_WORD   = 4;    // 4 x 6 float32: the request's box field
  localparam int unsigned TRI_NODE_WORDS      = 16;
  localparam int unsigned TRI_NODE_TRI_WORD   = 0;    // 3 x 3 float32: the request's triangle
  localparam int unsigned TRI_NODE_PRIM_WORD  = 9;    // primitive id
  localparam int unsigned Q8_NODE_WORDS       = 16;   // the request's qnode (box words 0..15)
  localparam int unsigned Q8_NODE_CHILD_WORD  = 4;    // 4 node pointers
  localparam int unsigned PAIR_NODE_WORDS     = 16;
  localparam int unsigned PAIR_NODE_V_WORD    = 0;    // 4 x 3 float32: v0..v3
  localparam int unsigned PAIR_NODE_PRIM_WORD = 12;   // 2 primitive ids (the second NO_CHILD: one)
  localparam int unsigned PAIR_NODE_IDX_WORD  = 14;   // bits 5:0: triangle 1's vertex selectors
  localparam int unsigned INST_NODE_WORDS     = 32;
  localparam int unsigned INST_NODE_M_WORD    = 0;    // world_to_object, 3 x 4 row-major
  localparam int unsigned INST_NODE_BLAS_WORD = 24;   // pointer to the BLAS root
  localparam int unsigned INST_NODE_ID_WORD   = 25;   // the instance's index

  // ---- the request words the unit fills (rf_pkg::req_t; word 0 at the low end) ----
  localparam int unsigned RAY_WORDS      = 15;   // tag .. shear: the prepared ray
  localparam int unsigned REQ_EXTENT_WORD = 11;
  localparam int unsigned REQ_BOX_WORD    = 15;
  localparam int unsigned REQ_TRI_WORD    = 39;
  localparam int unsigned REQ_FLAGS_LSB   = 32 + 9;   // the flags field: word 1 bits 16:9

  // What a slot's node is (the request it becomes): chosen by the pointer type at the pop.
  typedef enum logic [2:0] {
    KIND_BOX32 = 3'd0,   // QUADBOX on the box node's four boxes
    KIND_Q8    = 3'd1,   // QUADBOX on the q8 node, decoded by the datapath (DECODE_Q8)
    KIND_TRI   = 3'd2,   // TRIANGLE on the triangle node
    KIND_PAIR0 = 3'd3,   // TRIANGLE on a pair leaf's triangle 0 (v0, v1, v2)
    KIND_PAIR1 = 3'd4,   // TRIANGLE on its triangle 1 (the selected vertices; no fetch)
    KIND_XF    = 3'd5    // TRANSFORM of the world ray by an instance node's world_to_object
  } kind_e;

  // ---- memory port ----
  localparam int unsigned NODE_W = BOX_NODE_WORDS * 32;   // widest node: one response beat
  localparam int unsigned ADDR_W = 32 + PTR_SHIFT;        // byte address of a node
  localparam int unsigned SIZE_W = 8;                     // bytes per request (64 or 128)

  typedef logic [RAY_WORDS-1:1][31:0] ray_t;   // a prepared ray without its tag word

  // ---- the state of a ray slot (rf_rtunit's control) ----
  typedef enum logic [2:0] {
    SLOT_FREE  = 3'd0,   // no ray
    SLOT_POP   = 3'd1,   // waits to pop its next node (or to finish)
    SLOT_FETCH = 3'd2,   // its node is being fetched
    SLOT_READY = 3'd3,   // its node is in the node buffer: waits for the datapath
    SLOT_DP    = 3'd4,   // its request is in the datapath or in response processing
    SLOT_DIV   = 3'd5,   // its triangle hit's t is in the divider
    SLOT_DONE  = 3'd6,   // finished: waits for the result port
    SLOT_SETUP = 3'd7    // its transformed ray is being prepared (rf_rtu_setup)
  } slot_e;

endpackage
