// The Verilated RayFlex model as the harness drives it, and the request sources shared by the
// streaming calls (rayflex_harness.cpp) and the RT-unit scheduler (rtunit_scheduler.cpp).
//
// Every word index, bit position, opcode and node-layout constant comes from rf_layout.h, which
// driver/core/layout.py generates at build time from its tables (docs/datapath.md: requests and responses, BVH4 image).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "Vrayflex.h"
#include "rf_layout.h"
#include "verilated.h"

namespace rf {

using namespace rf_layout;

// The generated layout and the Verilated ports must agree on the wire widths.
static_assert(sizeof(Vrayflex::req_i) == kReqWords * 4, "req_t width differs from layout.py");
static_assert(sizeof(Vrayflex::rsp_o) == kRspWords * 4, "rsp_t width differs from layout.py");

struct Sim {
  VerilatedContext ctx;
  Vrayflex top{&ctx};
};

inline void tick(Sim* s) {
  s->top.clk_i = 1;
  s->top.eval();
  s->top.clk_i = 0;
  s->top.eval();
}

inline Sim* new_sim() {
  Sim* s = new Sim;
  s->top.clk_i = 0;
  s->top.rst_ni = 0;
  s->top.in_valid_i = 0;
  s->top.out_ready_i = 0;
  s->top.eval();
  for (int i = 0; i < 2; i++) tick(s);
  s->top.rst_ni = 1;
  s->top.eval();
  return s;
}

// Ready-made request words.
struct WordSource {
  const uint32_t* req;
  bool fill(int64_t i, uint32_t* dst) const {
    std::memcpy(dst, req + i * kReqWords, kReqWords * 4);
    return true;
  }
  void prefetch(int64_t) const {}  // sequential: the hardware prefetcher sees it
  void begin(uint32_t*) const {}
};

constexpr uint32_t kOpcodeMask = (1u << kReqOpcodeBits) - 1u;

// A traversal request: ray `ray[i]` against node `ptr[i]` with extent bits `ext[i]`, assembled as
// an RT unit would: the ray's words from the ray table, the node's box or triangle from the image.
struct NodeSource {
  const uint32_t* rays;   // (n_rays, kRayWords)
  const uint32_t* image;  // BVH4 image as uint32 words
  int64_t image_words;
  const uint32_t* ray;
  const uint32_t* ptr;
  const uint32_t* ext;

  static int64_t node_word(uint32_t p) {   // word offset of a node: byte offset / 4
    return static_cast<int64_t>(p & ~kTypeMask) << (kPtrShift - 2);
  }

  // The words after the ray's are zero except the box or the triangle: begin() clears them once
  // per stream, and each fill() writes its own operand and clears the other one's.
  void begin(uint32_t* dst) const {
    std::memset(dst + kRayWords, 0, (kReqWords - kRayWords) * 4);
  }

  // The operand of a QUADBOX request for a q8 box node (docs/compressed.md): the one place the
  // harness turns a q8 node into a request (driver.bvh4.q8_request is the host's). A model built
  // with the decode (RF_COMPRESSED, the build parameter COMPRESSED) gets the node as stored in
  // `qnode` with the request flag DECODE_Q8 and decodes it itself; any other gets the decoded
  // boxes: child i, axis a: origin[a] + float(q) * 2^exp[a] (the product is exact, the sum one
  // float add, round to nearest even, as driver.core.layout.decode_q8); unused slots (i >= count) the
  // unused box, six +inf.
  static void q8_request(const uint32_t* node, uint32_t* req) {
#if defined(RF_COMPRESSED) && RF_COMPRESSED
    std::memcpy(req + kReqQnodeWord, node, kReqQnodeCount * 4);
    req[kReqFlagsWord] |= kFlagDecodeQ8 << kReqFlagsLsb;
    return;
#endif
    uint32_t* box = req + kReqBoxWord;
    const uint32_t ew = node[kQ8NodeExpWord];
    const uint32_t count = (ew >> kQ8CountLsb) & 7u;
    const uint8_t* q = reinterpret_cast<const uint8_t*>(node + kQ8NodeQWord);
    float origin[3], scale[3];
    std::memcpy(origin, node + kQ8NodeOriginWord, sizeof origin);
    for (int a = 0; a < 3; a++) scale[a] = std::ldexp(1.0f, static_cast<int8_t>(ew >> (8 * a)));
    const float inf = INFINITY;
    for (uint32_t c = 0; c < 4; c++) {
      for (int j = 0; j < 6; j++) {
        // exact product, so a fused multiply-add would round the same
        const float prod = static_cast<float>(q[6 * c + j]) * scale[j % 3];
        const float v = c < count ? origin[j % 3] + prod : inf;
        std::memcpy(box + 6 * c + j, &v, 4);
      }
    }
  }

  // The leaf and the triangle index k of a triangle request pointer of a pair or group leaf:
  // k = 0 for the leaf's own pointer, bits 31:29 + 1 for kLeafNextType
  // (driver.core.layout.leaf_request).
  static uint32_t leaf_index(uint32_t p, uint32_t* leaf) {
    if ((p & kTypeMask) != kLeafNextType) {
      *leaf = p;
      return 0;
    }
    *leaf = p & ((1u << kLeafIndexLsb) - 1u);
    return (p >> kLeafIndexLsb) + 1u;
  }

  // Triangle k of a pair or group leaf (driver.core.layout.leaf_triangles): (v0, v1, v2) for k = 0;
  // (v[i0], v[i1], v[i2]) with 2-bit selectors in idx bits 5:0 for k = 1; 3-bit selectors at idx
  // bits kGroupSelLsb + kGroupSelBits (k - 2) for k >= 2 (a group leaf, whose vertices v4..v7
  // are in its second 64 bytes).
  static void leaf_triangle(const uint32_t* node, uint32_t k, uint32_t* tri) {
    const uint64_t sel = static_cast<uint64_t>(node[kGroupNodeIdxWord]) |
                         static_cast<uint64_t>(node[kGroupNodeIdxWord + 1]) << 32;
    for (uint32_t j = 0; j < 3; j++) {
      uint32_t v = j;
      if (k == 1) v = (sel >> (2 * j)) & 3u;
      if (k >= 2) v = (sel >> (kGroupSelLsb + kGroupSelBits * (k - 2) + 3 * j)) & 7u;
      const uint32_t w = v < 4 ? kGroupNodeVWord + 3 * v : kGroupNodeV2Word + 3 * (v - 4);
      std::memcpy(tri + 3 * j, node + w, 12);
    }
  }

  // Returns false for a pointer that is neither a box node, a triangle request's node nor an
  // instance node inside the image. An instance node becomes a TRANSFORM of the ray by the
  // node's world_to_object matrix (docs/instances.md: the transform on the datapath).
  bool fill(int64_t i, uint32_t* dst) const {
    const uint32_t r = ray[i], type = ptr[i] & kTypeMask;
    uint32_t p;
    const uint32_t k = leaf_index(ptr[i], &p);
    const int64_t word = node_word(p);
    uint32_t& ctrl = dst[kReqOpcodeWord];
    std::memcpy(dst, rays + static_cast<int64_t>(r) * kRayWords, kRayWords * 4);
    dst[kReqTagWord] = r;                              // tag = ray index
    dst[kReqExtentWord] = ext[i];                      // extent = the ray's nearest t so far
    const bool box = type == kBoxType || type == kQ8Type;
    // the words the request reads: a leaf's later triangle is in the node fetched for its first
    const int64_t words = type != kLeafNextType ? kNodeBytes[type] / 4
                          : k >= 2              ? kGroupNodeWords
                                                : kPairNodeWords;
    const bool xf = type == kInstanceType;
    if (words == 0 || word + words > image_words) return false;
    const uint32_t op = box ? kOpQuadbox : xf ? kOpTransform : kOpTriangle;
    ctrl = (ctrl & ~(kOpcodeMask << kReqOpcodeLsb)) | (op << kReqOpcodeLsb);
    if (xf) {
      std::memset(dst + kReqBoxWord, 0, kReqBoxCount * 4);
      std::memset(dst + kReqTriWord, 0, kReqTriCount * 4);
      std::memcpy(dst + kReqMatrixWord, image + word + kInstanceNodeMatrixWord,
                  kReqMatrixCount * 4);
      return true;
    }
    std::memset(dst + (box ? kReqTriWord : kReqBoxWord), 0,
                (box ? kReqTriCount : kReqBoxCount) * 4);
    if (type == kBoxType) {
      std::memcpy(dst + kReqBoxWord, image + word + kBoxNodeBoxWord, kReqBoxCount * 4);
    } else if (type == kQ8Type) {
      q8_request(image + word, dst);
    } else if (type == kTriType) {
      std::memcpy(dst + kReqTriWord, image + word + kTriNodeTriWord, kReqTriCount * 4);
    } else if (type == kPairType || type == kGroupType || type == kLeafNextType) {
      leaf_triangle(image + word, k, dst + kReqTriWord);
    } else {
      return false;
    }
    return true;
  }

  // Request i's ray and node are scattered over the ray table and the image (a cache miss
  // each); fetching them a few requests ahead hides that behind the model's evaluation.
  void prefetch(int64_t i) const {
    const uint32_t* r = rays + static_cast<int64_t>(ray[i]) * kRayWords;
    uint32_t p;
    leaf_index(ptr[i], &p);
    const uint32_t* node = image + node_word(p);
    __builtin_prefetch(r);
    __builtin_prefetch(r + kRayWords - 1);
    __builtin_prefetch(node);
    __builtin_prefetch(node + kBoxNodeWords - 1);   // a box node spans two cache lines
  }
};

}  // namespace rf
