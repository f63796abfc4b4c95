// bvh/pairs.h — all overlapping pairs of one tree.
//
// for_each_overlapping_pair: a walk over pairs of subtrees, leaf pairs
// decided by box then intersect(), each pair once; wide leaves read
// through the leaf-summary test (each_candidate). Includes
// leaf_summary.h.
#ifndef BVH_PAIRS_H
#define BVH_PAIRS_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "leaf_summary.h"

namespace bvh {
namespace detail {

/// Leaves of up to kPlainPairs shapes (the course's) pair their shapes by
/// plain loops; up to kBoxedPairs, boxed_leaf_pairs() does (two leaves: if
/// either is over kPlainPairs); larger leaves, at a depth limit, by the
/// plain loops again.
constexpr std::size_t kPlainPairs = 4, kBoxedPairs = 64;
/// kPlainPairs < n <= kBoxedPairs, in one compare.
inline bool boxed_size(std::size_t n) { return n - (kPlainPairs + 1) < kBoxedPairs - kPlainPairs; }

/// for_each_overlapping_pair() on the shapes of one leaf (`b` is `a`, both
/// `within` null) or of two leaves, each shape of `a` taken only if its box
/// meets *within_a (the other leaf's box), and likewise for `b`: each
/// shape's box is computed once, not once a pair, and at wide leaves most
/// of a leaf lies outside the other's box. False when f stopped. (Out of
/// line: the loop over node pairs stays as small as the course's leaves
/// need.)
template <class T, class Tr, int W, class F>
#if defined(__GNUC__)
__attribute__((noinline))
#endif
bool boxed_leaf_pairs(const Core<T, Tr, W> &core, const Node<W> &leaf_a, const Box *within_a, const Node<W> &leaf_b,
                      const Box *within_b, F &f) {
  struct Boxed {
    const T *shape;
    Box box;
  };
  Boxed in_a[kBoxedPairs], in_b[kBoxedPairs];
  // With a summary in use, only the shapes whose code box meets `within`
  // are read.
  auto collect = [&](const Node<W> &leaf, const Box *within, Boxed *out) {
    const Span<const T> v = core.leaves.shapes(leaf);
    std::size_t n = 0;
    auto take = [&](std::size_t i) {
      out[n].shape = &v[i];
      out[n].box = box_of(core.traits, v[i]);
      n += !within || out[n].box.overlaps(*within);
      return true;
    };
    if (within) each_candidate(leaf, v.size(), *within, take);
    else
      for (std::size_t i = 0; i < v.size(); ++i) take(i);
    return n;
  };
  auto pair = [&](const Boxed &s, const Boxed &u) {
    return s.box.overlaps(u.box) && core.traits.intersect(*s.shape, *u.shape);
  };
  const std::size_t n = collect(leaf_a, within_a, in_a);
  if (!within_a) { // one leaf: shape i against the later ones that may meet its box
    for (std::size_t i = 0; i + 1 < n; ++i)
      if (!each_candidate(leaf_a, n, in_a[i].box, [&](std::size_t j) {
            return !pair(in_a[i], in_a[j]) || keep_going(f, *in_a[i].shape, *in_a[j].shape);
          }, i + 1))
        return false;
    return true;
  }
  const std::size_t m = n ? collect(leaf_b, within_b, in_b) : 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < m; ++j)
      if (pair(in_a[i], in_b[j]) && !keep_going(f, *in_a[i].shape, *in_b[j].shape)) return false;
  return true;
}

/// for_each_overlapping_pair(): the walk, with leaves that may hold more
/// than kPlainPairs shapes (kMayBeWide) or not; in the second, the
/// course's tree's, the leaves pair up by plain loops alone. Its own
/// traversal, not search()'s: it walks pairs of nodes, and its stack
/// holds pairs; its leaves are read through the one leaf-summary test
/// (boxed_leaf_pairs).
template <bool kMayBeWide, class T, class Tr, int W, class F> void overlapping_pairs(const Core<T, Tr, W> &core, F &f) {
  const NodeStore<W> &nodes = core.nodes;
  auto pair = [&](const T &s, const T &u) {
    return box_of(core.traits, s).overlaps(box_of(core.traits, u)) && core.traits.intersect(s, u);
  };
  std::vector<std::pair<int, int>> stack{{core.root, core.root}};
  while (!stack.empty()) {
    auto [a, b] = stack.back();
    stack.pop_back();
    const Node<W> &na = nodes.node(a);
    if (a == b) {
      if (na.is_leaf()) {
        const Span<const T> v = core.leaves.shapes(na);
        if (kMayBeWide && boxed_size(v.size())) {
          if (!boxed_leaf_pairs(core, na, nullptr, na, nullptr, f)) return;
          continue;
        }
        for (std::size_t i = 0; i < v.size(); ++i)
          for (std::size_t j = i + 1; j < v.size(); ++j)
            if (pair(v[i], v[j]) && !keep_going(f, v[i], v[j])) return;
        continue;
      }
      for (int c = 0; c < na.num_children; ++c) {
        stack.push_back({na.child(c), na.child(c)});
        for (int d = c + 1; d < na.num_children; ++d)
          if (nodes.box(na.child(c)).overlaps(nodes.box(na.child(d)))) stack.push_back({na.child(c), na.child(d)});
      }
      continue;
    }
    const Node<W> &nb = nodes.node(b);
    if (na.is_leaf() && nb.is_leaf()) {
      if (kMayBeWide && boxed_size(std::max(na.leaf().count, nb.leaf().count))) {
        if (!boxed_leaf_pairs(core, na, &nodes.box(b), nb, &nodes.box(a), f))
          return;
        continue;
      }
      for (const T &s : core.leaves.shapes(na))
        for (const T &u : core.leaves.shapes(nb))
          if (pair(s, u) && !keep_going(f, s, u)) return;
      continue;
    }
    // Open the inner node of the two, the larger box when both are.
    if (na.is_leaf() || (!nb.is_leaf() && nodes.box(b).area() > nodes.box(a).area())) std::swap(a, b);
    const Node<W> &open = nodes.node(a);
    for (int c = 0; c < open.num_children; ++c)
      if (nodes.box(open.child(c)).overlaps(nodes.box(b))) stack.push_back({open.child(c), b});
  }
}

/// Calls f(a, b) once for every unordered pair of stored shapes that
/// intersect; if f returns bool, false stops. A simultaneous traversal of
/// the tree against itself: a pair of nodes is opened only when their boxes
/// overlap, so the cost is O(n log n + k) for k pairs on well-spread
/// scenes, against O(n^2) for a scan.
template <class T, class Tr, int W, class F> void for_each_overlapping_pair(const Core<T, Tr, W> &core, F &&f) {
  if (core.root < 0) return;
  // (Leaves outgrow split_threshold only at a depth limit.)
  if (core.split_threshold > int(kPlainPairs) || core.depth_limit > 0) overlapping_pairs<true>(core, f);
  else overlapping_pairs<false>(core, f);
}
} // namespace detail
} // namespace bvh

#endif // BVH_PAIRS_H
