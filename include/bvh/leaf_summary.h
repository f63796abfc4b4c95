// bvh/leaf_summary.h — a leaf's summary: its shapes' boxes in bytes, and the decisions read from it.
//
// make_summary and extend_summary (the writers of a leaf's codes: a code
// is always its shape's own box, never a margin's), the leaf-summary test
// every search reads a leaf through (with_candidates, each_candidate: the
// shapes of a leaf whose box may meet a query's; with_box_candidates:
// also those whose box surely meets it), and the disk fast
// path (DiskProbe, CodeFrame, disk_decision, each_disk_candidate,
// disk_codes_hit): disks decided from their codes alone where the traits
// promise inscribed disks.
// Includes core.h.
#ifndef BVH_LEAF_SUMMARY_H
#define BVH_LEAF_SUMMARY_H

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "core.h"

namespace bvh {
namespace detail {

/// A box's four sides without Box's constructor, which starts empty: for
/// arrays of boxes that are written before they are read.
struct Sides {
  double x0, y0, x1, y1;
  static Sides of(const Box &b) { return Sides{b.x0, b.y0, b.x1, b.y1}; }
  Box box() const { return Box{x0, y0, x1, y1}; }
};

/// Recomputes leaf n's summary (Node::coded()) from its shapes: the frame
/// is their boxes' union with an eighth of its size to spare on each side,
/// so that most later appends fit in it. A leaf of more shapes than a
/// summary holds gets none. `box_at(i)`: the box of the leaf's shape i,
/// when the caller has it (box_of() of the shape by default).
template <class T, class Tr, int W, class BoxAt> void make_summary(Core<T, Tr, W> &core, int n, BoxAt &&box_at) {
  constexpr int kCoded = Node<W>::kCoded;
  if constexpr (kCoded > 0) {
    Node<W> &leaf = core.nodes.node(n);
    leaf.set_coded(0);
    if (!leaf.is_leaf() || !leaf.leaf().has_slot() || leaf.leaf().count > std::uint32_t(kCoded)) return;
    const std::size_t count = leaf.leaf().count;
    Sides boxes[kCoded];
    Box all;
    for (std::size_t i = 0; i < count; ++i) {
      const Box b = box_at(i);
      boxes[i] = Sides::of(b);
      all.extend(b);
    }
    typename Node<W>::Frame f;
    const double sx = all.x1 - all.x0, sy = all.y1 - all.y0;
    f.ox = float(all.x0 - sx / 8);
    f.oy = float(all.y0 - sy / 8);
    // (scale 0 when the frame has no size or none that is finite: every
    // code is then 0 or 255, which holds every box)
    const double kx = 255 / (double(all.x1 + sx / 8) - f.ox), ky = 255 / (double(all.y1 + sy / 8) - f.oy);
    f.sx = kx > 0 && kx < 1e30 ? float(kx) * (1 - 1e-6f) : 0;
    f.sy = ky > 0 && ky < 1e30 ? float(ky) * (1 - 1e-6f) : 0;
    leaf.set_frame(f);
    for (std::size_t i = 0; i < count; ++i)
      leaf.set_codes(int(i), Node<W>::codes_of(boxes[i].box(), f));
    leaf.set_coded(int(count));
  } else {
    (void)core;
    (void)n;
    (void)box_at;
  }
}
/// make_summary() from the leaf's shapes' boxes.
template <class T, class Tr, int W> void make_summary(Core<T, Tr, W> &core, int n) {
  if constexpr (Node<W>::kCoded > 0) {
    const Node<W> &leaf = core.nodes.node(n);
    // (box_at is called only for a leaf with a slot)
    const T *v = leaf.is_leaf() && leaf.leaf().has_slot() ? core.leaves.shapes(leaf).begin() : nullptr;
    make_summary(core, n, [&](std::size_t i) { return box_of(core.traits, v[i]); });
  } else {
    (void)core;
    (void)n;
  }
}

/// Leaf n's summary after its last shape, whose own box is `b`, was
/// appended: coded too if it fits the frame, else make_summary(). `b` is
/// box_of() the shape, never a box holding it (a fat one): the disk
/// decisions read a code as the disk inscribed in it (disk_decision).
template <class T, class Tr, int W> BVH_ALWAYS_INLINE void extend_summary(Core<T, Tr, W> &core, int n, const Box &b) {
  if constexpr (Node<W>::kCoded > 0) {
    Node<W> &leaf = core.nodes.node(n);
    const int count = int(leaf.leaf().count);
    if (count > Node<W>::kCoded) return;
    bool inside;
    const std::uint32_t codes = Node<W>::codes_of(b, leaf.frame(), &inside);
    if (inside && leaf.coded() == count - 1) {
      leaf.set_codes(count - 1, codes);
      leaf.set_coded(count);
    } else {
      make_summary(core, n);
    }
  }
}

/// Calls f(i) for each set bit i of `bits`, ascending, until f returns
/// false (then returns false).
template <class F> BVH_ALWAYS_INLINE bool each_bit(std::uint32_t bits, F &&f) {
  for (; bits != 0; bits &= bits - 1)
    if (!f(std::size_t(lowest_bit(bits)))) return false;
  return true;
}
/// Calls f(i) for each i in [first, n), until f returns false (then
/// returns false).
template <class F> BVH_ALWAYS_INLINE bool each_index(std::size_t first, std::size_t n, F &&f) {
  for (std::size_t i = first; i < n; ++i)
    if (!f(i)) return false;
  return true;
}

/// The leaf-summary test, the only one: which of leaf `node`'s n shapes
/// may meet box `box`. With the summary in use (coded() is n), returns
/// coded(bits), bits the shapes whose code box meets it; else plain()
/// (every shape may).
template <int W, class Coded, class Plain>
BVH_ALWAYS_INLINE bool with_candidates(const Node<W> &node, std::size_t n, const Box &box, Coded &&coded, Plain &&plain) {
  if constexpr (Node<W>::kCoded > 0)
    if (node.coded() == int(n)) return coded(node.meets(box, int(n)));
  (void)box, (void)coded;
  return plain();
}

/// with_candidates() for a question about boxes alone (query(box)): with
/// the summary in use, returns coded(bits, sure), bits as there and sure
/// those of them whose box surely meets `box` (Node::meets), which need
/// not be read; else plain().
template <int W, class Coded, class Plain>
BVH_ALWAYS_INLINE bool with_box_candidates(const Node<W> &node, std::size_t n, const Box &box, Coded &&coded,
                                           Plain &&plain) {
  if constexpr (Node<W>::kCoded > 0)
    if (node.coded() == int(n)) {
      std::uint32_t sure = 0;
      const std::uint32_t bits = node.meets(box, int(n), &sure);
      return coded(bits, sure);
    }
  (void)box, (void)coded;
  return plain();
}

/// Calls f(i) for each index i of leaf `node`'s n shapes whose box may
/// meet `box` (with_candidates()), ascending from `first`, until f returns
/// false (then returns false).
template <int W, class F>
BVH_ALWAYS_INLINE bool each_candidate(const Node<W> &node, std::size_t n, const Box &box, F &&f, std::size_t first = 0) {
  return with_candidates(
      node, n, box,
      [&](std::uint32_t bits) BVH_LAMBDA_INLINE {
        // (first < 32 here: a summary holds at most 32 shapes)
        return each_bit(bits & ~((std::uint32_t(1) << first) - 1), f);
      },
      [&]() BVH_LAMBDA_INLINE { return each_index(first, n, f); });
}

/// A collision probe read as a disk (InscribedDisks): the disk inscribed
/// in its box, with `slack` covering the rounding of the box's sides (to
/// double or to float: 2^-22 of the largest side is four times float's).
/// Unusable (no decision from codes) unless the box is square up to that
/// rounding and its sides are finite and below 1e100.
struct DiskProbe {
  double x = 0, y = 0, r_lo = 0, r_hi = 0, slack = 0;
  bool usable = false;
  static DiskProbe of(const Box &b) {
    DiskProbe p;
    const double m = std::max(std::max(std::fabs(b.x0), std::fabs(b.y0)), std::max(std::fabs(b.x1), std::fabs(b.y1)));
    if (!(m < 1e100) || !(b.x0 <= b.x1) || !(b.y0 <= b.y1)) return p; // (NaN fails these too)
    p.slack = 0x1p-22 * m;
    const double wx = 0.5 * (b.x1 - b.x0), wy = 0.5 * (b.y1 - b.y0);
    p.x = 0.5 * (b.x0 + b.x1);
    p.y = 0.5 * (b.y0 + b.y1);
    p.r_lo = std::min(wx, wy) - p.slack;
    p.r_hi = std::max(wx, wy) + p.slack;
    p.usable = p.r_lo >= 0 && p.r_hi - p.r_lo <= 1e-6 * (p.r_hi + m);
    return p;
  }
};

/// A summarized leaf's frame, inverted: code k of a side that was not
/// clamped (1 <= k <= 254) puts the side in [o + k q - d, o + (k + 1) q +
/// d], q = 1 / scale. The codes are computed in float (codes_of): float(v)
/// and the subtraction and product each round by at most 2^-24 relative,
/// which moves the side by less than 2^-21 (|o| + 512 q); d is four times
/// that, and also covers the rounding of a disk's box to double or float
/// (2^-24 of its sides, which lie within 256 q of o).
struct CodeFrame {
  double ox = 0, oy = 0, qx = 0, qy = 0, dx = 0, dy = 0;
  bool usable = false;
  template <class F> static CodeFrame of(const F &f) {
    CodeFrame c;
    c.ox = f.ox;
    c.oy = f.oy;
    c.qx = 1.0 / double(f.sx);
    c.qy = 1.0 / double(f.sy);
    c.usable = c.qx >= 1e-100 && c.qx <= 1e100 && c.qy >= 1e-100 && c.qy <= 1e100 && std::fabs(c.ox) < 1e100 &&
               std::fabs(c.oy) < 1e100; // (a scale of 0 gives q = inf; NaN fails)
    c.dx = 0x1p-19 * (std::fabs(c.ox) + 512 * c.qx);
    c.dy = 0x1p-19 * (std::fabs(c.oy) + 512 * c.qy);
    return c;
  }
};

/// Shape i of a summarized leaf, a disk inscribed in its box (its code
/// box read through `f`), against probe `p`: +1 when they surely meet, -1
/// when they surely do not, 0 when only the exact test can tell (a side
/// clamped, or the probe within a few quanta of tangency). Sure means for
/// every disk whose box the codes allow: the centre lies in a rectangle
/// and the radius in [r_lo, r_hi], and the closed disks meet iff the
/// centres are at most the radii's sum apart (intersect.h's disks_meet,
/// which this needs both radii >= 0 for). The distances are computed in
/// double, whose relative error (about 1e-15) the factors 1 -+ 1e-9 cover.
template <int W> BVH_ALWAYS_INLINE int disk_decision(const Node<W> &node, int i, const CodeFrame &f, const DiskProbe &p) {
  const unsigned a0 = node.row(0)[i], b0 = node.row(1)[i], a1 = node.row(2)[i], b1 = node.row(3)[i];
  if (a0 - 1u > 253u || b0 - 1u > 253u || a1 - 1u > 253u || b1 - 1u > 253u) return 0; // (0 or 255: maybe clamped)
  const double x0l = f.ox + a0 * f.qx - f.dx, x0h = f.ox + (a0 + 1) * f.qx + f.dx;
  const double x1l = f.ox + a1 * f.qx - f.dx, x1h = f.ox + (a1 + 1) * f.qx + f.dx;
  const double y0l = f.oy + b0 * f.qy - f.dy, y0h = f.oy + (b0 + 1) * f.qy + f.dy;
  const double y1l = f.oy + b1 * f.qy - f.dy, y1h = f.oy + (b1 + 1) * f.qy + f.dy;
  const double r_lo = 0.5 * std::max(x1l - x0h, y1l - y0h), r_hi = 0.5 * std::min(x1h - x0l, y1h - y0l);
  if (!(r_lo >= 0)) return 0;
  // The centre's rectangle, widened by the probe's own rounding.
  const double cxl = 0.5 * (x0l + x1l) - p.slack, cxh = 0.5 * (x0h + x1h) + p.slack;
  const double cyl = 0.5 * (y0l + y1l) - p.slack, cyh = 0.5 * (y0h + y1h) + p.slack;
  const double fx = std::max(p.x - cxl, cxh - p.x), fy = std::max(p.y - cyl, cyh - p.y); // farthest
  const double hit = p.r_lo + r_lo;
  if (fx * fx + fy * fy < hit * hit * (1 - 1e-9)) return 1;
  const double ex = std::max(std::max(cxl - p.x, p.x - cxh), 0.0), ey = std::max(std::max(cyl - p.y, p.y - cyh), 0.0);
  const double miss = p.r_hi + r_hi;
  if (ex * ex + ey * ey > miss * miss * (1 + 1e-9)) return -1;
  return 0;
}

/// The disk fast path, the only one. For candidates `bits` of a leaf of
/// inscribed disks with its summary in use: calls f(i, sure) for each,
/// ascending, but those whose codes show they surely miss probe `p`; sure
/// when they show it surely meets. Stops when f returns false (then
/// returns false). Every candidate is unsure when the frame or the probe
/// is unusable.
template <int W, class F>
BVH_ALWAYS_INLINE bool each_disk_candidate(const Node<W> &node, std::uint32_t bits, const DiskProbe &p, F &&f) {
  if (bits == 0) return true;
  const CodeFrame frame = p.usable ? CodeFrame::of(node.frame()) : CodeFrame{};
  for (; bits != 0; bits &= bits - 1) {
    const int i = lowest_bit(bits);
    const int d = frame.usable ? disk_decision(node, i, frame, p) : 0;
    if (d < 0) continue;
    if (!f(i, d > 0)) return false;
  }
  return true;
}

/// Collision's use of the fast path: true when one of the candidates
/// `bits` surely meets probe `p`; otherwise `unsure` gets those the codes
/// cannot decide.
template <int W>
BVH_ALWAYS_INLINE bool disk_codes_hit(const Node<W> &node, std::uint32_t bits, const DiskProbe &p, std::uint32_t &unsure) {
  unsure = 0;
  return !each_disk_candidate(node, bits, p, [&](int i, bool sure) {
    unsure |= std::uint32_t(1) << i;
    return !sure;
  });
}
/// disk_codes_hit() of the shapes of a summarized leaf of n disks whose
/// code box meets `box`.
template <int W>
BVH_ALWAYS_INLINE bool disk_codes_hit(const Node<W> &node, int n, const Box &box, const DiskProbe &p, std::uint32_t &unsure) {
  return disk_codes_hit(node, node.meets(box, n), p, unsure);
}

/// True when collision searches may decide a summarized leaf's disks from
/// their codes (widths with summaries, traits that promise inscribed
/// disks).
template <class Tr, int W> constexpr bool kDisksFromCodes = Node<W>::kCoded > 0 && InscribedDisks<Tr>::value;

/// The probe as collision searches of `core` read it: a DiskProbe, usable
/// when core's disks are decided from codes.
template <class T, class Tr, int W> BVH_ALWAYS_INLINE DiskProbe disk_probe(const Core<T, Tr, W> &core, const Box &box) {
  if constexpr (kDisksFromCodes<Tr, W>)
    if (core.size >= core.tuning.disk_codes_min_shapes) return DiskProbe::of(box);
  return DiskProbe{};
}
} // namespace detail
} // namespace bvh

#endif // BVH_LEAF_SUMMARY_H
