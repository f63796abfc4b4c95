// bvh/node.h — Node<W> (what a query reads) and Info (the rest).
//
// A node is one cache line: an inner node's children's float boxes and
// indices, or a leaf's slot record and its summary (the leaf's shapes'
// boxes coded in bytes against a frame; Node::codes_of, set_codes, meets).
// Info holds the exact double box, parent, depth and count. Includes box.h,
// containers.h, simd.h.
#ifndef BVH_NODE_H
#define BVH_NODE_H

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "box.h"
#include "containers.h"
#include "defaults.h"
#include "simd.h"

namespace bvh {
namespace detail {

// Nodes live in two parallel arrays. `Node` is what a query reads, one
// cache line: an inner node's children's boxes in float, rounded outwards,
// and their indices, so one line decides every child; a leaf's record of
// where its shapes are. `Info` is the rest: the exact double box, parent,
// depth and the subtree's shape count. A box is thus stored twice, the
// exact one in the node's Info and its float copy in the parent's Node;
// NodeStore::set_box is the only writer of both.

/// Children per inner node of the course's ternary tree (defaults.h).
constexpr int kCourseWidth = course_width;
/// The widths a tree may have.
constexpr int kMinWidth = 2, kMaxWidth = 8;
/// Bits 0 .. w - 1: one per child.
constexpr unsigned child_bits(int w) { return (1u << w) - 1; }

/// Where a leaf's shapes are: a slot of the leaf store (its class, whose
/// capacity is LeafPool's capacity_of(cls), and its index in that class)
/// and how many shapes it holds. A leaf that owns no slot has cls ==
/// kNoSlot.
struct LeafSlot {
  static constexpr std::uint32_t kNoSlot = ~std::uint32_t(0);
  std::uint32_t index = 0;
  std::uint32_t cls = kNoSlot;
  std::uint32_t count = 0;
  /// True when the leaf owns a slot.
  bool has_slot() const { return cls != kNoSlot; }
};

/// A node as queries read it, of a tree of width W.
template <int W> struct Node {
  static_assert(W >= kMinWidth && W <= kMaxWidth, "a node has 2 to 8 children");
  float lo_x[W], lo_y[W], hi_x[W], hi_y[W]; // children's boxes, rounded outwards
  /// True for a leaf.
  bool is_leaf() const { return num_children == 0; }
  /// Inner node: the index of child c (< num_children).
  int child(int c) const { return link_[c]; }
  /// Leaf: where its shapes are.
  LeafSlot leaf() const { return LeafSlot{std::uint32_t(link_[0]), std::uint32_t(link_[1]), std::uint32_t(link_[2])}; }
  /// Makes the node a leaf whose shapes are at `s` (the leaf store's).
  /// An inner node made a leaf has no summary.
  void set_leaf(const LeafSlot &s) {
    if constexpr (kCoded > 0)
      if (num_children != 0) link_[3] = 0;
    num_children = 0;
    link_[0] = std::int32_t(s.index);
    link_[1] = std::int32_t(s.cls);
    link_[2] = std::int32_t(s.count);
  }
  /// Inner node: child c is node n (the builders').
  void set_child(int c, int n) { link_[c] = n; }

  // A leaf's summary. A leaf does not use its children's box rows, so at
  // widths 4 to 8 they hold its first shapes' boxes, each side quantized
  // to 8 bits within a frame that the leaf stores too: a query tests its
  // box against all of them in one SIMD pass and reads only the shapes
  // whose code box meets it. Codes come from one map that never
  // decreases (codes_of), so boxes that meet have code boxes that meet,
  // also outside the frame, where codes are clamped (the frame sets the
  // precision only). Queries use it only where shapes that intersect have
  // boxes that meet, which the whole tree relies on.
  // The first coded() shapes have right codes; the summary is in use when
  // that is all of them. Appending keeps it; erase shifts it; every other
  // change of a leaf's shapes sets coded() to 0 or recomputes it
  // (make_summary()). validate() checks every code.

  /// Shapes a leaf's summary holds at most (0: no summary at this width).
  static constexpr int kCoded = W >= 8 ? 4 * W : W >= 4 ? 4 * W - 4 : 0;
  /// The frame of a summary: a side v's code is (v - origin) * scale,
  /// clamped to 0..255 (codes_of).
  struct Frame {
    float ox = 0, oy = 0, sx = 0, sy = 0;
  };
  /// Leaf: how many of its first shapes have right codes.
  int coded() const {
    if constexpr (kCoded > 0) return link_[3] < 0 ? -(link_[3] + 1) : 0;
    else return 0;
  }
  /// Leaf: its first k shapes have right codes (k <= kCoded).
  void set_coded(int k) {
    if constexpr (kCoded > 0) link_[3] = -(k + 1);
    (void)k;
  }
  /// Leaf: code row r (0: low x, 1: low y, 2: high x, 3: high y), kCoded
  /// bytes. (Byte access to the box rows, the node's first 16 W bytes.)
  unsigned char *row(int r) { return reinterpret_cast<unsigned char *>(this) + r * kCoded; }
  const unsigned char *row(int r) const { return reinterpret_cast<const unsigned char *>(this) + r * kCoded; }
  /// Leaf: its summary's frame (in the free links at width 8, else after
  /// the code rows).
  Frame frame() const {
    Frame f;
    std::memcpy(&f, frame_bytes(), sizeof f);
    return f;
  }
  void set_frame(const Frame &f) {
    BVH_INVARIANT(static_cast<const void *>(lo_x) == static_cast<const void *>(this), "row() needs the box rows first");
    std::memcpy(frame_bytes(), &f, sizeof f);
  }
  /// The codes of box `b` in frame `f`, bytes 0 to 3 of the result: low x,
  /// low y, high x, high y. A side's code is the integer part of t =
  /// (float(v) - origin) * scale, in float, clamped to 0..255 (a NaN low
  /// side: 0, a NaN high one: 255). *inside: no side was clamped. Every
  /// code of a summary, and of every box tested against one, comes from
  /// here: one map that never decreases, so that a <= b gives code(a) <=
  /// code(b), and boxes that meet have code boxes that meet.
  static BVH_ALWAYS_INLINE std::uint32_t codes_of(const Box &b, const Frame &f, bool *inside = nullptr) {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    const __m128 v = _mm_movelh_ps(_mm_cvtpd_ps(_mm_set_pd(b.y0, b.x0)), _mm_cvtpd_ps(_mm_set_pd(b.y1, b.x1)));
    const __m128 t = _mm_mul_ps(_mm_sub_ps(v, _mm_set_ps(f.oy, f.ox, f.oy, f.ox)), _mm_set_ps(f.sy, f.sx, f.sy, f.sx));
    const __m128 zero = _mm_setzero_ps(), top = _mm_set1_ps(255.f);
    if (inside) *inside = _mm_movemask_ps(_mm_and_ps(_mm_cmpge_ps(t, zero), _mm_cmple_ps(t, top))) == 15;
    // (max and min return their second operand when the first is NaN)
    const __m128 lo = _mm_min_ps(_mm_max_ps(t, zero), top), hi = _mm_max_ps(_mm_min_ps(t, top), zero);
    const __m128 c = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 2, 1, 0));
    __m128i k = _mm_cvttps_epi32(c);
    k = _mm_packs_epi32(k, k);
    return std::uint32_t(_mm_cvtsi128_si32(_mm_packus_epi16(k, k)));
#else
    const float v[4] = {float(b.x0), float(b.y0), float(b.x1), float(b.y1)};
    const float o[4] = {f.ox, f.oy, f.ox, f.oy}, sc[4] = {f.sx, f.sy, f.sx, f.sy};
    std::uint32_t codes = 0;
    bool in = true;
    for (int i = 0; i < 4; ++i) {
      const float t = (v[i] - o[i]) * sc[i];
      in = in && t >= 0 && t <= 255;
      float c;
      if (i < 2) c = t >= 0 ? (t <= 255 ? t : 255) : 0;
      else c = t <= 255 ? (t >= 0 ? t : 0) : 255;
      codes |= std::uint32_t(c) << (8 * i);
    }
    if (inside) *inside = in;
    return codes;
#endif
  }
  /// Leaf: shape i's code box is `codes` (codes_of()).
  void set_codes(int i, std::uint32_t codes) {
    for (int r = 0; r < 4; ++r) row(r)[i] = static_cast<unsigned char>(codes >> (8 * r));
  }
  /// Leaf: writes shape i's code box from its box `b`.
  void code(int i, const Box &b) { set_codes(i, codes_of(b, frame())); }
  /// Leaf: shape i's codes, as codes_of() returns them.
  std::uint32_t codes(int i) const {
    std::uint32_t c = 0;
    for (int r = 0; r < 4; ++r) c |= std::uint32_t(row(r)[i]) << (8 * r);
    return c;
  }
  /// Leaf: shape i is gone and the ones after it moved down one place:
  /// their codes move with them.
  void uncode(int i) {
    const int k = coded();
    if (i >= k) return;
    for (int r = 0; r < 4; ++r) std::memmove(row(r) + i, row(r) + i + 1, std::size_t(k - i - 1));
    set_coded(k - 1);
  }
  /// Leaf with a summary in use (coded() == its count, n shapes): bit i
  /// set when shape i's code box meets box `b`'s. With `surely`, also
  /// *surely: bit i set when shape i's box surely meets `b`, its code box
  /// reaching strictly past b's on every side (a low code below b's high
  /// code, a high code above b's low code). As codes_of() never
  /// decreases, code(u) < code(v) gives u < v: then the boxes meet, an
  /// empty box's too, without reading the shape.
  BVH_ALWAYS_INLINE std::uint32_t meets(const Box &b, int n, std::uint32_t *surely = nullptr) const {
    const std::uint32_t c = codes_of(b, frame());
    const std::uint32_t live = n >= 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << n) - 1;
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    // (a <= b for bytes: min(a, b) == a; a < b: that, and not a == b;
    // lanes past the row are masked off)
    const __m128i qx = _mm_set1_epi8(char(c & 255u)), qy = _mm_set1_epi8(char(c >> 8 & 255u));
    const __m128i px = _mm_set1_epi8(char(c >> 16 & 255u)), py = _mm_set1_epi8(char(c >> 24));
    std::uint32_t bits = 0, sure = 0;
    for (int g = 0; g < n; g += 16) {
      const auto load = [&](int r) { return _mm_loadu_si128(reinterpret_cast<const __m128i *>(row(r) + g)); };
      const __m128i x0 = load(0), y0 = load(1), x1 = load(2), y1 = load(3);
      const __m128i ok = _mm_and_si128(
          _mm_and_si128(_mm_cmpeq_epi8(_mm_min_epu8(x0, px), x0), _mm_cmpeq_epi8(_mm_min_epu8(y0, py), y0)),
          _mm_and_si128(_mm_cmpeq_epi8(_mm_max_epu8(x1, qx), x1), _mm_cmpeq_epi8(_mm_max_epu8(y1, qy), y1)));
      bits |= std::uint32_t(_mm_movemask_epi8(ok)) << g;
      if (surely) {
        const __m128i touch = _mm_or_si128(_mm_or_si128(_mm_cmpeq_epi8(x0, px), _mm_cmpeq_epi8(y0, py)),
                                           _mm_or_si128(_mm_cmpeq_epi8(x1, qx), _mm_cmpeq_epi8(y1, qy)));
        sure |= std::uint32_t(_mm_movemask_epi8(_mm_andnot_si128(touch, ok))) << g;
      }
    }
    if (surely) *surely = sure & live;
    return bits & live;
#else
    const unsigned lx = c & 255u, ly = c >> 8 & 255u, hx = c >> 16 & 255u, hy = c >> 24;
    std::uint32_t bits = 0, sure = 0;
    for (int i = 0; i < n; ++i) {
      bits |= std::uint32_t(row(0)[i] <= hx && row(1)[i] <= hy && lx <= row(2)[i] && ly <= row(3)[i]) << i;
      sure |= std::uint32_t(row(0)[i] < hx && row(1)[i] < hy && lx < row(2)[i] && ly < row(3)[i]) << i;
    }
    if (surely) *surely = sure & live;
    return bits & live;
#endif
  }

  std::int32_t num_children = 0; // 0: a leaf

private:
  unsigned char *frame_bytes() {
    if constexpr (W >= 8) return reinterpret_cast<unsigned char *>(link_ + 4);
    else return row(4);
  }
  const unsigned char *frame_bytes() const { return const_cast<Node *>(this)->frame_bytes(); }
  // An inner node's children, or a leaf's LeafSlot (index, class, count)
  // and its summary's state (coded() in link_[3]): a leaf's shapes are
  // found from this line alone.
  std::int32_t link_[W < 3 ? 3 : W] = {0, std::int32_t(LeafSlot::kNoSlot), 0};
};
static_assert(Node<4>::kCoded * 4 + 16 <= int(sizeof(float)) * 16 && Node<7>::kCoded * 4 + 16 <= int(sizeof(float)) * 28 &&
                  Node<8>::kCoded * 4 <= int(sizeof(float)) * 32,
              "a summary fits in a leaf's box rows");
// (the fields are in this order so that a 4-lane load of a float row stays
// inside the node: child_masks masks the extra lanes off)
static_assert(sizeof(Node<kCourseWidth>) == 64, "a ternary Node is one 64-byte cache line");

/// The rest of a node: exact geometry and links.
class Info {
public:
  /// The node's exact box (NodeStore::set_box writes it).
  const Box &box() const { return box_; }
  std::int32_t parent = -1;     ///< -1 for the root
  std::int32_t child_index = 0; ///< its index among the parent's children
  std::int32_t depth = 0;       ///< the root's is 0
  std::uint32_t count = 0;      ///< shapes in the subtree (ids are 32-bit: so is a count)

private:
  template <int> friend class NodeStore;
  Box box_;
};
} // namespace detail
} // namespace bvh

#endif // BVH_NODE_H
