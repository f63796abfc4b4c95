// bvh/layout.h — Layout<W>: node counts of a tree cut by count, known before sorting.
//
// Lets construct() give every node its index in advance, so that deep
// subtrees build on several threads into their own places. Includes
// count_cut.h only.
#ifndef BVH_LAYOUT_H
#define BVH_LAYOUT_H

#include <cstddef>
#include <utility>
#include <vector>

#include "count_cut.h"

namespace bvh {
namespace detail {

/// Node counts of a tree cut by count (CountCut), as CourseRule and
/// InOrderRule cut: its shape depends on the counts alone, so the number
/// of nodes under every node is known before anything is sorted. At each
/// depth the splitting sizes differ by at most one, so every level of the
/// table holds at most a few sizes.
template <int W> class Layout {
public:
  /// The table for n shapes at depth 0 (depth_limit <= 0: none).
  Layout(std::size_t n, int split_threshold, int depth_limit)
      : split_threshold_(std::size_t(split_threshold)), depth_limit_(depth_limit) {
    const CountCut<W> counts{split_threshold_, depth_limit_};
    levels_.push_back({Entry{n, 0}});
    for (int d = 0; !levels_[std::size_t(d)].empty(); ++d) { // sizes met, top-down
      std::vector<Entry> next;
      for (const Entry &e : levels_[std::size_t(d)])
        if (splits(e.size, d)) {
          std::size_t size[W];
          counts.sizes(e.size, d, size);
          for (std::size_t g : size)
            if (g != 0 && std::none_of(next.begin(), next.end(), [&](const Entry &x) { return x.size == g; }))
              next.push_back(Entry{g, 0});
        }
      levels_.push_back(std::move(next));
    }
    for (std::size_t d = levels_.size(); d-- > 0;) // node counts, bottom-up
      for (Entry &e : levels_[d]) {
        e.nodes = 1;
        if (splits(e.size, int(d))) {
          std::size_t size[W];
          counts.sizes(e.size, int(d), size);
          for (std::size_t g : size)
            if (g != 0) e.nodes += nodes(g, int(d) + 1);
        }
      }
  }
  /// Nodes in the subtree of `size` shapes at `depth` (a size the build meets).
  std::size_t nodes(std::size_t size, int depth) const {
    for (const Entry &e : levels_[std::size_t(depth)])
      if (e.size == size) return e.nodes;
    return 0;
  }

private:
  struct Entry {
    std::size_t size, nodes;
  };
  bool splits(std::size_t m, int depth) const {
    return m > split_threshold_ && (depth_limit_ <= 0 || depth < depth_limit_);
  }
  std::size_t split_threshold_;
  int depth_limit_;
  std::vector<std::vector<Entry>> levels_;
};
} // namespace detail
} // namespace bvh

#endif // BVH_LAYOUT_H
