// bvh/count_cut.h — how a cut by count shares shapes among W children.
//
// thirds() (the course's split: sizes differing by at most one, larger
// first) and CountCut<W> (the same at other widths, so that nodes come out
// full). Pure arithmetic on counts; includes config.h only.
#ifndef BVH_COUNT_CUT_H
#define BVH_COUNT_CUT_H

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>

#include "config.h"

namespace bvh {
namespace detail {

/// The course's split of m shapes into three groups: sizes that differ by
/// at most one, larger first (empty groups when m < 3).
inline std::array<std::size_t, 3> thirds(std::size_t m) {
  const std::size_t base = m / 3, extra = m % 3;
  return {base + (extra > 0), base + (extra > 1), base};
}

/// How a cut by count (CourseRule, InOrderRule, Layout) shares a node's
/// shapes among its children at width W. At the course's width 3: thirds.
/// At other widths, so that nodes come out full: with c the capacity of
/// the smallest subtree that holds m / W shapes (split_threshold shapes a
/// leaf, W children a node, within the depth limit), the node gets
/// ceil(m / c) children (at least 2, at most W), their sizes differing by
/// at most one, larger first.
template <int W> struct CountCut {
  std::size_t split_threshold;
  int depth_limit; ///< <= 0: none
  /// The group sizes of m shapes at a node at `depth` into size[0 .. W)
  /// (zeros past the last group).
  void sizes(std::size_t m, int depth, std::size_t size[W]) const {
    if constexpr (W == 3) {
      const std::array<std::size_t, 3> t = thirds(m);
      for (int g = 0; g < 3; ++g) size[g] = t[std::size_t(g)];
    } else {
      // The least capacity c >= m / W of a child's subtree (the child at
      // `level`, its leaves at most as deep as the limit).
      std::size_t c = split_threshold;
      for (int level = depth + 1; c < (m + W - 1) / W && (depth_limit <= 0 || level < depth_limit); ++level)
        c = c > std::numeric_limits<std::size_t>::max() / W ? std::numeric_limits<std::size_t>::max() : c * W;
      std::size_t groups = std::min<std::size_t>(W, (m + c - 1) / c);
      groups = std::max<std::size_t>(std::min<std::size_t>(groups, m), m > 1 ? 2 : 1);
      const std::size_t base = m / groups, extra = m % groups;
      for (std::size_t g = 0; g < std::size_t(W); ++g) size[g] = g < groups ? base + (g < extra) : 0;
    }
  }
  /// The cut of [begin, end) at `depth`: cut[g] .. cut[g + 1] is group g.
  void cut(std::size_t begin, std::size_t end, int depth, std::size_t cut[W + 1]) const {
    std::size_t size[W];
    sizes(end - begin, depth, size);
    cut[0] = begin;
    for (int g = 0; g < W; ++g) cut[g + 1] = cut[g] + size[g];
  }
};
} // namespace detail
} // namespace bvh

#endif // BVH_COUNT_CUT_H
