// bvh/build_items.h — what a build sorts: items, keys, tasks, selection.
//
// Item (a shape with its centre and input position), the build's
// allocator (huge pages for large builds), Key and Order (the course's
// comparison), BuildTask, cut_in_thirds, select_nth, CourseState,
// ShapesAsItems and BuildScratch. No tree here; includes box.h,
// containers.h, count_cut.h.
#ifndef BVH_BUILD_ITEMS_H
#define BVH_BUILD_ITEMS_H

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "box.h"
#include "containers.h"
#include "count_cut.h"

namespace bvh {
namespace detail {

// construct(), a leaf's split, and the partial rebuilds of insert and erase
// all run one loop, build_top_down(). Per node it computes the box and count
// of the node's items and makes a leaf when the course says so (at most
// split_threshold items, or at depth_limit); otherwise the rule cuts the
// items into kWidth consecutive groups and each non-empty group becomes a
// child, children built left to right. A rule supplies only its items,
// box(i), shape(i), id(i), order_leaf(task) (a leaf's shapes are then taken
// in item order) and cut(task, box, cut, child_state): CourseRule (the
// course's), SahRule (binned SAH) and InOrderRule (thirds in the given
// order, for erase). build_at() is the entry for a subtree, construct() for
// the whole tree; only construct() lays nodes out in advance and threads.

/// True when T stores its centre (the traits' center() returns a
/// reference, as Disk's getCenter() does) and the traits hold no state:
/// items then read the centre from the shape instead of caching a copy,
/// which makes the items the selections move smaller.
template <class T, class Tr>
constexpr bool kCenterStored =
    std::is_empty<Tr>::value && std::is_default_constructible<Tr>::value &&
    std::is_reference<decltype(std::declval<const Tr &>().center(std::declval<const T &>()))>::value;
/// One shape during a course build, with its centre computed once (a
/// triangle's or quad's centre is a sum).
template <class T, class Tr> struct CachedCenter {
  XY center;
  T shape;
  std::uint32_t index; // input position: the last tie-break
  const XY &centre() const { return center; }
};
/// One shape during a course build, whose centre it stores.
template <class T, class Tr> struct StoredCenter {
  T shape;
  std::uint32_t index;
  decltype(auto) centre() const { return Tr().center(shape); }
};
template <class T, class Tr> using Item = typename std::conditional<kCenterStored<T, Tr>, StoredCenter<T, Tr>, CachedCenter<T, Tr>>::type;
template <class T, class Tr> Item<T, Tr> make_item(const Tr &traits, const T &shape, std::uint32_t index) {
  if constexpr (kCenterStored<T, Tr>)
    return Item<T, Tr>{shape, index};
  else
    return Item<T, Tr>{XY::of(traits.center(shape)), shape, index};
}

/// The allocator of a build's items (BuildScratch). A large build writes
/// tens of megabytes of items that it frees when done, and on a host where
/// a page fault is dear, faulting them in 4 kB at a time costs as much as
/// the selections that use them. So where BVH_HUGE_PAGES (Linux, not
/// Android) an array of 8 MB or more is aligned to 2 MB and asked for
/// transparent huge pages (madvise: a hint, which a kernel with them turned
/// off ignores). BVH_NO_HUGE_PAGES turns this off; elsewhere it is
/// std::allocator.
template <class X> struct BuildAllocator {
  using value_type = X;
  BuildAllocator() = default;
  template <class Y> BuildAllocator(const BuildAllocator<Y> &) noexcept {}
  static constexpr std::size_t kHuge = std::size_t(1) << 21; // a huge page
  /// Whether an array of n takes the huge pages: 8 MB or more (counted in
  /// elements, so that no product overflows).
  static bool huge(std::size_t n) { return BVH_HUGE_PAGES && n >= (4 * kHuge + sizeof(X) - 1) / sizeof(X); }
  X *allocate(std::size_t n) {
    if (n > (std::size_t(-1) - kHuge) / sizeof(X)) throw std::bad_alloc(); // (before any product)
#if BVH_HUGE_PAGES
    if (huge(n)) {
      const std::size_t bytes = (n * sizeof(X) + kHuge - 1) & ~(kHuge - 1); // (aligned_alloc: a multiple)
      void *p = std::aligned_alloc(kHuge, bytes);
      if (!p) throw std::bad_alloc();
#if defined(MADV_HUGEPAGE)
      ::madvise(p, bytes, MADV_HUGEPAGE); // (a hint: if it fails, nothing changes)
#endif
      return static_cast<X *>(p);
    }
#endif
    return std::allocator<X>().allocate(n);
  }
  void deallocate(X *p, std::size_t n) noexcept {
    if (huge(n)) std::free(p);
    else std::allocator<X>().deallocate(p, n);
  }
  template <class Y> bool operator==(const BuildAllocator<Y> &) const noexcept { return true; }
  template <class Y> bool operator!=(const BuildAllocator<Y> &) const noexcept { return false; }
};
/// A build's items.
template <class T, class Tr> using Items = std::vector<Item<T, Tr>, BuildAllocator<Item<T, Tr>>>;

/// The order of one node: see CourseRule.
struct Key {
  int axis;       // 0: x, 1: y
  bool other_too; // compare the other axis before the input position
};
/// Key's order with the axis and the chain fixed at compile time: the
/// selections spend most of a build in this comparison, and a runtime
/// axis costs a branch per coordinate read.
template <int Axis, bool OtherToo> struct Order {
  template <class I> bool operator()(const I &a, const I &b) const {
    const auto &p = a.centre();
    const auto &q = b.centre();
    const double pa = Axis == 0 ? p.x : p.y, qa = Axis == 0 ? q.x : q.y;
    if (pa != qa) return pa < qa;
    if (OtherToo) {
      const double po = Axis == 0 ? p.y : p.x, qo = Axis == 0 ? q.y : q.x;
      if (po != qo) return po < qo;
    }
    return a.index < b.index;
  }
};
/// Calls f(Order<...>()) for `key`.
template <class F> void with_order(const Key &key, F &&f) {
  if (key.axis == 0) {
    if (key.other_too) f(Order<0, true>());
    else f(Order<0, false>());
  } else {
    if (key.other_too) f(Order<1, true>());
    else f(Order<1, false>());
  }
}

/// One node to build: its items [begin, end) in the rule's array, the
/// rule's state for it, and `block`: with a precomputed layout
/// (construct), the index where its children go; -1 when nodes come from
/// new_node().
template <class State> struct BuildTask {
  int node;
  std::size_t begin, end;
  int block;
  State state;
};

/// The course's cut of [begin, end) into thirds(): cut[g] .. cut[g + 1] is
/// group g.
inline void cut_in_thirds(std::size_t begin, std::size_t end, std::size_t cut[4]) {
  const std::array<std::size_t, 3> size = thirds(end - begin);
  cut[0] = begin;
  for (int g = 0; g < 3; ++g) cut[g + 1] = cut[g] + size[std::size_t(g)];
}


/// std::nth_element's result (the element at nth is the one sorted order
/// puts there; none before it is greater, none after it smaller) by Floyd
/// and Rivest's selection (CACM 18(3), 1975, algorithm 489): the pivot of
/// a large range is first selected within a sample of it around nth, so
/// one partition pass nearly finishes the job. That takes fewer
/// comparisons and far fewer moves than introselect, whose repeated
/// passes dominate a wide build. Small ranges, and any range that stops
/// halving (input ordered against the sample), go to std::nth_element, so
/// the worst case stays O(n log n). The recursion is on the sample, which
/// shrinks as n^(2/3): O(log log n) deep. `less`: a strict weak order.
template <class It, class Less> void select_nth(It first, It nth, It last, Less less) {
  using Diff = typename std::iterator_traits<It>::difference_type;
  constexpr Diff kSmall = 600;
  const Diff k = nth - first;
  Diff left = 0, right = (last - first) - 1;
  if (k < 0 || k > right) return;
  int stalls = 0;
  while (right - left > kSmall) {
    const double n = double(right - left + 1), i = double(k - left + 1);
    const double z = std::log(n), s = 0.5 * std::exp(2 * z / 3);
    const double sd = 0.5 * std::sqrt(z * s * (n - s) / n) * (i < n / 2 ? -1 : 1);
    const Diff sample_left = std::max(left, Diff(double(k) - i * s / n + sd));
    const Diff sample_right = std::min(right, Diff(double(k) + (n - i) * s / n + sd));
    select_nth(first + sample_left, first + k, first + sample_right + 1, less);
    // Partition [left, right] around the sample's choice; each end holds
    // a sentinel for the other's scan.
    const auto pivot = first[k];
    Diff lo = left, hi = right;
    std::iter_swap(first + left, first + k);
    if (less(pivot, first[right])) std::iter_swap(first + right, first + left);
    while (lo < hi) {
      std::iter_swap(first + lo, first + hi);
      ++lo;
      --hi;
      while (less(first[lo], pivot)) ++lo;
      while (less(pivot, first[hi])) --hi;
    }
    if (!less(first[left], pivot)) { // the pivot is at left
      std::iter_swap(first + left, first + hi);
    } else { // at right
      ++hi;
      std::iter_swap(first + hi, first + right);
    }
    const Diff before = right - left;
    if (hi <= k) left = hi + 1;
    if (k <= hi) right = hi - 1;
    if (2 * (right - left) > before && ++stalls > 3) break;
  }
  if (right > left) std::nth_element(first + left, first + k, first + right + 1, less);
}

/// What CourseRule carries down to a node.
struct CourseState {
  unsigned axes_used; // bit 0: x, bit 1: y, by the node's ancestors
  Key parent_key;     // the order the node's shapes arrive in
  bool has_parent_key;
};

/// The items of SahRule and InOrderRule: the shapes themselves, taken in
/// their current order at a leaf; no state carried down.
template <class T, class Tr> class ShapesAsItems {
public:
  struct State {};
  ShapesAsItems(const Tr &traits, std::vector<Tagged<T>> &shapes) : traits_(traits), v_(shapes) {}
  Box box(std::size_t i) const { return box_of(traits_, v_[i].shape); }
  T &shape(std::size_t i) { return v_[i].shape; }
  std::uint32_t id(std::size_t i) const { return v_[i].id; }
  void order_leaf(const BuildTask<State> &) {}
  static State root_state() { return State{}; }

protected:
  const Tr &traits_;
  std::vector<Tagged<T>> &v_;
};

/// The memory a course build reuses from one build to the next.
template <class T, class Tr> struct BuildScratch {
  Items<T, Tr> items;
  std::vector<BuildTask<CourseState>> tasks;
};
} // namespace detail
} // namespace bvh

#endif // BVH_BUILD_ITEMS_H
