// bvh/best_first.h — best_first: nearest(p), nearest(p, k) and first_hit.
//
// One engine, a priority queue of nodes by a lower bound, with a metric per
// question (PointMetric, RayMetric). Includes core.h.
#ifndef BVH_BEST_FIRST_H
#define BVH_BEST_FIRST_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>

#include "core.h"

namespace bvh {
namespace detail {

/// One answer of best_first(): a shape, its key and its id. Answers are
/// ordered by key, then id.
template <class T> struct Found {
  double key;
  std::uint32_t id;
  const T *shape;
  friend bool operator<(const Found &a, const Found &b) { return a.key < b.key || (a.key == b.key && a.id < b.id); }
};

/// The key of nearest(p) and nearest(p, k): distance(p, shape), bounded
/// below by the squared distance to a child's float box (rounded outwards,
/// so never farther than the exact box).
template <class P> struct PointMetric {
  const P &p;
  /// p is supported: then every key is finite.
  bool supported() const {
    UnsupportedAny bad;
    bad.pair(double(p.x), double(p.y));
    return !bad.any();
  }
  template <int W> double box_key(const Node<W> &node, int c) const {
    return box_key(Box{node.lo_x[c], node.lo_y[c], node.hi_x[c], node.hi_y[c]});
  }
  /// box_key(node, c) of every child c < W, into key[] (W rounded up to
  /// even); lanes past num_children are garbage.
  template <int W> void box_keys(const Node<W> &node, double *key) const {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    // Two children a pass, in double, as box_key: _mm_max_pd(b, a) is
    // std::max(a, b), NaNs included, so the keys are the same bits.
    const __m128d px = _mm_set1_pd(double(p.x)), py = _mm_set1_pd(double(p.y)), zero = _mm_setzero_pd();
    for (int g = 0; g < W; g += 2) {
      const __m128d dx =
          _mm_max_pd(_mm_sub_pd(px, two_floats(node.hi_x + g)), _mm_max_pd(zero, _mm_sub_pd(two_floats(node.lo_x + g), px)));
      const __m128d dy =
          _mm_max_pd(_mm_sub_pd(py, two_floats(node.hi_y + g)), _mm_max_pd(zero, _mm_sub_pd(two_floats(node.lo_y + g), py)));
      _mm_storeu_pd(key + g, _mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)));
    }
#else
    for (int c = 0; c < W; ++c) key[c] = box_key(node, c);
#endif
  }
  double box_key(const Box &b) const {
    const double px = p.x, py = p.y;
    // (std::max of a list runs a loop: two calls, the same result)
    const double dx = std::max(std::max(b.x0 - px, 0.0), px - b.x1);
    const double dy = std::max(std::max(b.y0 - py, 0.0), py - b.y1);
    return dx * dx + dy * dy;
  }
  template <class T> double shape_key(const T &s) const { return distance(p, s); }
  // (a relative margin covers the rounding of squares)
  static double beyond(double worst) { return worst * worst * (1 + 1e-9) + 1e-300; }
};

/// The key of first_hit(): where the ray meets the shape (+inf: it
/// misses), bounded below by where it enters a child's float box.
template <class P> struct RayMetric {
  const P &origin, &direction;
  /// The origin and direction are supported: then a ray parameter is
  /// finite or +inf for a miss.
  bool supported() const {
    UnsupportedAny bad;
    bad.pair(double(origin.x), double(origin.y));
    bad.pair(double(direction.x), double(direction.y));
    return !bad.any();
  }
  template <int W> double box_key(const Node<W> &node, int c) const {
    return box_key(Box{node.lo_x[c], node.lo_y[c], node.hi_x[c], node.hi_y[c]});
  }
  /// box_key(node, c) of every child c < num_children, into key[].
  template <int W> void box_keys(const Node<W> &node, double *key) const {
    for (int c = 0; c < node.num_children; ++c) key[c] = box_key(node, c);
  }
  double box_key(const Box &b) const { return b.ray_entry(origin.x, origin.y, direction.x, direction.y); }
  template <class T> double shape_key(const T &s) const { return ray_hit(origin, direction, s); }
  static double beyond(double worst) { return worst * (1 + 1e-12) + 1e-300; }
};

/// best_first()'s bound: a node or shape whose key is past it cannot be
/// among the k best, `found` (a max-heap of the best min(k, seen) so far).
template <class Metric, class Answers>
BVH_ALWAYS_INLINE double answer_bound(const Metric &metric, std::size_t k, const Answers &found) {
  return found.size() < k ? std::numeric_limits<double>::infinity() : metric.beyond(found.front().key);
}

/// best_first()'s visit of leaf `node`: its shapes of finite key offered to
/// the k best in `found`. The ids are read only once a shape is near
/// enough to need its tie-break.
template <class T, class Tr, int W, class Metric, class Answers>
BVH_ALWAYS_INLINE void offer_leaf(const Core<T, Tr, W> &core, const Metric &metric, std::size_t k, const Node<W> &node,
                                  Answers &found) {
  const double inf = std::numeric_limits<double>::infinity();
  const Span<const T> v = core.leaves.shapes(node);
  const std::uint32_t *ids = nullptr;
  double limit = answer_bound(metric, k, found); // (it changes only when `found` does)
  for (std::size_t i = 0; i < v.size(); ++i) {
    // (once k are found, a shape whose box is beyond the k-th needs no
    // exact key: the box costs a few compares, the key a square root)
    if (found.size() == k && metric.box_key(box_of(core.traits, v[i])) > limit) continue;
    const double d = metric.shape_key(v[i]);
    if (!(d < inf) || (found.size() == k && d > found.front().key)) continue;
    if (!ids) ids = core.leaves.ids(node);
    const Found<T> f{d, ids[i], &v[i]};
    if (found.size() < k) {
      found.push_back(f);
      std::push_heap(found.begin(), found.end());
    } else if (f < found.front()) {
      std::pop_heap(found.begin(), found.end());
      found.back() = f;
      std::push_heap(found.begin(), found.end());
    }
    limit = answer_bound(metric, k, found);
  }
}

/// best_first()'s first dive, along the nearest boxes from the root to one
/// leaf: its shapes bound the search, which would otherwise push every
/// child it passes on its way to the first leaf (the bound is +inf until k
/// shapes are found). The leaf, or -1 when the dive is not worth it (a
/// leaf may fill all k only when k <= split_threshold) or finds no child
/// of finite key.
template <class T, class Tr, int W, class Metric>
BVH_ALWAYS_INLINE int dive_leaf(const Core<T, Tr, W> &core, const Metric &metric, std::size_t k) {
  const double inf = std::numeric_limits<double>::infinity();
  int dive = k <= std::size_t(core.split_threshold) ? core.root : -1;
  while (dive >= 0 && !core.nodes.node(dive).is_leaf()) {
    const Node<W> &node = core.nodes.node(dive);
    double least = inf, key[W + W % 2];
    int next = -1;
    metric.box_keys(node, key);
    for (int c = 0; c < node.num_children; ++c)
      if (key[c] < least) least = key[c], next = node.child(c);
    if (next < 0) break; // (no child has a finite key)
    dive = next;
  }
  return dive >= 0 && core.nodes.node(dive).is_leaf() ? dive : -1;
}

/// The one best-first search: the min(k, size) shapes of least finite
/// metric.shape_key, in increasing (key, id) order, into `found`. Nodes
/// are taken in order of metric.box_key, a lower bound on the keys of the
/// shapes under a child; the search stops when the next node's bound is
/// past metric.beyond(the k-th key so far). O(log n + k) typically. None
/// when the metric's point or ray is not supported; when it is, every key
/// of a supported tree is finite (the float boxes of the nodes, fat or
/// not, are bounded by float's range; a shape's own box by 2^201), so no
/// shape is lost to an overflow.
template <class T, class Tr, int W, class Metric, class Answers>
void best_first(const Core<T, Tr, W> &core, const Metric &metric, std::size_t k, Answers &found) {
  found.clear();
  if (k == 0 || core.root < 0 || !metric.supported()) return;
  const double inf = std::numeric_limits<double>::infinity();
  found.reserve(std::min(k, core.size) + 1); // a max-heap of the best min(k, seen) so far
  const int dive = dive_leaf(core, metric, k);
  if (dive >= 0) offer_leaf(core, metric, k, core.nodes.node(dive), found);
  // (a trivial struct, not a std::pair: the heap's inline room is then
  // left uninitialised, not zeroed on every query)
  struct Entry {
    double key;
    int node;
  };
  // std::greater<std::pair<double, int>>, NaN keys included: a min-heap.
  const auto later = [](const Entry &a, const Entry &b) { return b.key < a.key || (!(a.key < b.key) && b.node < a.node); };
  InlineVector<Entry, 128> heap;
  heap.push_back(Entry{0.0, core.root});
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), later);
    const Entry e = heap.back();
    heap.pop_back();
    if (e.key > answer_bound(metric, k, found)) break;
    const Node<W> &node = core.nodes.node(e.node);
    if (node.is_leaf()) {
      if (e.node != dive) offer_leaf(core, metric, k, node, found); // (the dive's leaf is done)
      continue;
    }
    const double limit = answer_bound(metric, k, found);
    double keys[W + W % 2];
    metric.box_keys(node, keys);
    for (int c = 0; c < node.num_children; ++c) {
      const double key = keys[c];
      if (key > limit || key == inf) continue;
#if defined(__GNUC__)
      // Best-first reaches most pushed nodes soon, but only after the
      // heap reorders: fetching them now hides the miss behind that work.
      __builtin_prefetch(&core.nodes.node(node.child(c)));
#endif
      heap.push_back(Entry{key, node.child(c)});
      std::push_heap(heap.begin(), heap.end(), later);
    }
  }
  std::sort_heap(found.begin(), found.end());
}
} // namespace detail
} // namespace bvh

#endif // BVH_BEST_FIRST_H
