// bvh/course_rule.h — CourseRule: the course's build rule.
//
// Order by centre on the longer side, ties kept, cut in thirds: done by
// selection on a strict total order equal to the stable one, O(n log n).
// Includes build_items.h, node.h, parallel.h.
#ifndef BVH_COURSE_RULE_H
#define BVH_COURSE_RULE_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "build_items.h"
#include "node.h"
#include "parallel.h"

namespace bvh {
namespace detail {

/// The build rule (the course's, which its expected output follows). A
/// node's shapes are ordered by their centre on the longer side of its box
/// (x when dx >= dy), ties kept in their current order, and cut in thirds
/// (cut_in_thirds); a leaf keeps its shapes in its parent's order.
///
/// Doing this with a stable sort at every node costs O(n log^2 n). The
/// same groups come from selection (nth_element) if the comparison is a
/// strict total order equal to the stable one. The stable order at a node
/// compares centres on its axis, then on its parent's axis, its
/// grandparent's, ..., then the input position; with only two axes, every
/// repeat of an axis in that chain compares coordinates already found
/// equal, so the chain shrinks to (this axis, the other axis if any
/// ancestor used it, input position). Selection gives O(n log n) overall.
/// Each shape travels with its centre and input position (Item), so the
/// selections, box scans and the final copy into the leaves stream through
/// memory instead of chasing indices.
///
/// At widths other than 3 the groups are CountCut's, and they are made by
/// halving: the range of groups is cut in two at a group boundary, by
/// selection on the longer side of the centres of the shapes in it, and
/// each half again, so W children collapse log2(W) levels of a median
/// tree.
template <class T, class Tr, int W> class CourseRule {
public:
  using State = CourseState;
  /// `src`: the shapes the items were made from, for their ids; nullptr
  /// when the ids are the input positions (construct).
  /// `threads`: how many may halve a node's range at once (construct's
  /// top nodes; W != 3).
  CourseRule(const Tr &traits, Items<T, Tr> &items, const std::vector<Tagged<T>> *src,
             CountCut<W> counts, unsigned threads = 1)
      : traits_(traits), items_(items), src_(src), counts_(counts), threads_(threads) {}
  Box box(std::size_t i) const { return box_of(traits_, items_[i].shape); }
  T &shape(std::size_t i) { return items_[i].shape; }
  std::uint32_t id(std::size_t i) const { return src_ ? (*src_)[items_[i].index].id : items_[i].index; }
  void order_leaf(const BuildTask<State> &t) {
    // Selection left the range unordered; restore the parent's order. (The
    // course's order in a leaf is its tree's alone: at other widths the
    // selections' order stays, as determined by the input.)
    if constexpr (W != kCourseWidth) return;
    const auto first = items_.begin() + long(t.begin), last = items_.begin() + long(t.end);
    if (t.state.has_parent_key)
      with_order(t.state.parent_key, [&](auto order) { std::sort(first, last, order); });
    else
      std::sort(first, last, [](const Item<T, Tr> &a, const Item<T, Tr> &b) { return a.index < b.index; });
  }
  void cut(const BuildTask<State> &t, int depth, const Box &box, std::size_t cut[W + 1], State child[W]) {
    const int axis = box.dx() >= box.dy() ? 0 : 1;
    const auto first = items_.begin();
    if constexpr (W == 3) {
      const Key key{axis, (t.state.axes_used & (2u >> axis)) != 0};
      cut_in_thirds(t.begin, t.end, cut);
      with_order(key, [&](auto order) {
        std::nth_element(first + long(cut[0]), first + long(cut[1]), first + long(cut[3]), order);
        std::nth_element(first + long(cut[1]), first + long(cut[2]), first + long(cut[3]), order);
      });
      for (int g = 0; g < 3; ++g) child[g] = State{t.state.axes_used | (1u << axis), key, true};
    } else {
      counts_.cut(t.begin, t.end, depth, cut);
      int groups = 0;
      while (groups < W && cut[groups + 1] > cut[groups]) ++groups;
      // Halving groups [g0, g1) on `axis` (the recursion is at most log2(W)
      // deep); the two halves of a large range on two threads at once.
      auto halve = [&](auto &self, int g0, int g1, int on) -> void {
        if (g1 - g0 < 2) {
          for (int g = g0; g < g1; ++g) child[g] = State{3u, Key{on, true}, true};
          return;
        }
        const int mid = (g0 + g1) / 2;
        with_order(Key{on, true}, [&](auto order) {
          select_nth(first + long(cut[g0]), first + long(cut[mid]), first + long(cut[g1]), order);
        });
        auto half = [&](std::size_t right) {
          if (right) self(self, mid, g1, longer_axis(cut[mid], cut[g1], on));
          else self(self, g0, mid, longer_axis(cut[g0], cut[mid], on));
        };
        if (threads_ > 1 && cut[g1] - cut[g0] >= kParallelMin) {
          parallel_for(2, 2, half);
        } else {
          half(0);
          half(1);
        }
      };
      halve(halve, 0, groups, axis);
    }
  }
  static State root_state() { return State{0u, Key{0, false}, false}; }
  void set_threads(unsigned threads) { threads_ = threads; }

private:
  /// The longer side of the centres of items [begin, end); `ties` when
  /// they span no area (one centre, or on a line both ways).
  int longer_axis(std::size_t begin, std::size_t end, int ties) const {
    if (end - begin < 2) return ties;
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (std::size_t i = begin; i < end; ++i) {
      const auto &c = items_[i].centre();
      x0 = std::min(x0, double(c.x));
      x1 = std::max(x1, double(c.x));
      y0 = std::min(y0, double(c.y));
      y1 = std::max(y1, double(c.y));
    }
    if (x1 - x0 == y1 - y0) return ties;
    return x1 - x0 > y1 - y0 ? 0 : 1;
  }
  const Tr &traits_;
  Items<T, Tr> &items_;
  const std::vector<Tagged<T>> *src_;
  CountCut<W> counts_;
  unsigned threads_;
};
} // namespace detail
} // namespace bvh

#endif // BVH_COURSE_RULE_H
