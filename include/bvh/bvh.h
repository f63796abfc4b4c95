// bvh.h — BVH<T>: a bounding volume hierarchy over 2D shapes (Disk,
// Triangle, Quad from shapes.h, Shape for mixed scenes, or a shape type of
// your own), built in bulk or one shape at a time, answering "does this
// shape touch anything stored?" with the shapes' own intersect().
//
// One self-contained header: it includes only the standard library and
// "shapes.h", so it also compiles as a homework submission next to the
// course's own shapes.h and utils.h (README.txt, "Submitting bvh.h").
//
//   BVH<Disk> tree(/*split_threshold=*/4, /*depth_limit=*/0);  // 0: unlimited
//   tree.construct(disks);                   // bulk build, the course's rule
//   for (const Disk &d : more) if (!tree.collision(d)) tree.insert(d);
//   for (const Disk &d : tree) std::cout << d.getBox() << "\n";
//   tree.statistics(/*print_tree=*/true);    // the course's report, to stdout
//   auto h = tree.insert(d);  tree.update(h, moved);  // handles for moving shapes
//
// Complexity (n shapes, k = split_threshold): construct O(n log n)
// (selection, not sorting, at every level; subtrees on several threads for
// large scenes, the same tree whatever their number); insert O(log n)
// amortised, including the partial rebuilds that keep the tree balanced
// under any insertion order; collision O(log n + shapes whose boxes touch
// the probe); iteration O(1) amortised per step; update(handle, moved)
// O(depth) while the shape stays inside its leaf's box (set_margin makes
// those boxes fat), else an erase and an insert; nearest(p, k) O(log n + k)
// typically. Copy, destruction and every traversal are iterative, so no
// input can overflow the stack.
//
// The file, in reading order (docs/design.txt: what each section owns, its
// invariants, and what it may touch):
//   1. Primitives     box arithmetic, rounding to float, stacks, the block
//                     vector, parallel_for, thirds(), the assertions
//   2. Node storage   Node (what queries read, one cache line), Info (the
//                     rest), NodeStore: the one writer of both copies of a
//                     box; the node test (child_masks); walk(), the one
//                     depth-first traversal
//   3. Leaf store     LeafPool (the shapes) and LeafStore (the pool, the
//                     leaves' records and the handle table, kept in step)
//   4. Tree core      Core: the state every operation shares
//   5. Builders       the build rules (CourseRule, SahRule, InOrderRule),
//                     the one build loop, the threaded bulk plan, build_at()
//   6. Changes        the insertion strategy (choose_child and the scapegoat
//                     rebuilds), erase and its repairs, update, margins
//   7. Queries        collision, box and shape queries, the suspended search
//                     of overlapping(), the best-first engine (nearest(p),
//                     nearest(p, k), first_hit), all pairs
//   8. Diagnostics    the course's statistics report, its picture, validate
//   8b. Disjoint      insert_disjoint: discard-overlap sampling on several
//                     threads, exactly the sequential loop's tree
//   9. BVH<T>         the public facade: each member a few lines over 2-8
// The intersection predicates are the free intersect() of the shape type,
// found by argument-dependent lookup (this project's exact ones are in
// intersect.h, which shapes.h brings in).
#ifndef BVH_BVH_H
#define BVH_BVH_H

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <iterator>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
#include <emmintrin.h>
#endif
// A build's large scratch arrays in transparent huge pages (BuildAllocator),
// and the tree's new blocks faulted in by one call each (populate): Linux
// only (not Android, whose aligned_alloc depends on the API level).
#if defined(__linux__) && !defined(__ANDROID__) && !defined(BVH_NO_HUGE_PAGES)
#define BVH_HUGE_PAGES 1
#include <sys/mman.h>
#else
#define BVH_HUGE_PAGES 0
#endif
// The leaf pool's large bookkeeping arrays mapped on their own
// (MappedAllocator): Linux, whose glibc keeps a freed large array's pages;
// BVH_NO_MAPPED_ARRAYS turns it off.
#if defined(__linux__) && !defined(BVH_NO_MAPPED_ARRAYS)
#define BVH_MAPPED_ARRAYS 1
#include <sys/mman.h>
#else
#define BVH_MAPPED_ARRAYS 0
#endif

// The library's own headers: its version, and its shapes (which bring in
// the exact intersect.h and distance.h).
#include "version.h"
#include "shapes.h"

// ===========================================================================
// 1. Primitives
// ===========================================================================

// BVH_ASSERT(condition, message): checks of the caller's preconditions
// (iterators past the ends, erasing end() or another tree's iterator). On
// unless NDEBUG is defined; then a failed check prints the message and
// aborts. Define BVH_ASSERT before including bvh.h to handle misuse your own
// way (throw, log), or as ((void)0) to drop the checks.
#ifndef BVH_ASSERT
#ifdef NDEBUG
#define BVH_ASSERT(condition, message) ((void)0)
#else
#define BVH_ASSERT(condition, message)                                                                                \
  ((condition) ? (void)0 : ::bvh::detail::assertion_failed(message, #condition, __FILE__, __LINE__))
#endif
#endif

// BVH_INVARIANT(condition, message): the tree's own invariants, checked
// where one component hands over to another. A failure is a bug in bvh.h,
// never the caller's: it aborts with the message. Off under NDEBUG.
#ifdef NDEBUG
#define BVH_INVARIANT(condition, message) ((void)0)
#else
#define BVH_INVARIANT(condition, message)                                                                             \
  ((condition) ? (void)0 : ::bvh::detail::invariant_failed(message, #condition, __FILE__, __LINE__))
#endif

// The one traversal routine is inlined into each query that uses it, so
// that its visit's state (a query's probe) stays in registers.
// BVH_NOINLINE keeps a small function out of the queries that call it
// once each, where inlining it only crowds their loops' registers.
// Unoptimized builds (-O0: debugging, sanitizers) inline nothing: there
// forced inlining buys no speed and copies each instrumented body into
// every caller, which makes such builds compile far longer.
#if defined(__GNUC__) && defined(__OPTIMIZE__)
#define BVH_ALWAYS_INLINE inline __attribute__((always_inline))
#define BVH_LAMBDA_INLINE __attribute__((always_inline))
#else
#define BVH_ALWAYS_INLINE inline
#define BVH_LAMBDA_INLINE
#endif
#if defined(__GNUC__)
#define BVH_NOINLINE __attribute__((noinline))
#else
#define BVH_NOINLINE
#endif

namespace bvh {
namespace detail {

/// BVH_ASSERT's report: what was misused, where, then abort().
[[noreturn]] inline void assertion_failed(const char *message, const char *condition, const char *file, int line) {
  std::fprintf(stderr, "%s:%d: BVH misuse: %s (%s)\n", file, line, message, condition);
  std::abort();
}

/// BVH_INVARIANT's report, then abort().
[[noreturn]] inline void invariant_failed(const char *message, const char *condition, const char *file, int line) {
  std::fprintf(stderr, "%s:%d: BVH internal error: %s (%s)\n", file, line, message, condition);
  std::abort();
}

/// intersect(a, b) as the shape type's own (found by argument-dependent
/// lookup): shape_traits's default. (A function of its own, so that the
/// call does not find shape_traits's member of the same name.)
template <class A, class B> bool intersect_adl(const A &a, const B &b) { return intersect(a, b); }

/// True for a shape type that is the closed disk inscribed in its box and
/// whose intersect() is exact: this project's Disk (intersect.h defines
/// BVH_EXACT_DISKS beside its predicate). The course's own Disk is not: its
/// intersect() has a tolerance, which only it can apply.
template <class T> inline constexpr bool kExactDisk = false;
#if defined(BVH_EXACT_DISKS)
template <> inline constexpr bool kExactDisk<Disk> = true; // (inline: one definition in every translation unit)
#endif

} // namespace detail

// ---- How the tree reads your types: the customization points ------------

/// The four sides of an axis-aligned box, as the tree reads every box.
struct bounds {
  double min_x, min_y, max_x, max_y;
};

/// How the tree reads a box type B. The default reads getMin() and getMax(),
/// points with x and y (this project's BoundingBox and the course's).
/// Specialize it for your own box type, e.g. Box2D's b2AABB:
///   template <> struct bvh::box_traits<b2AABB> {
///     static bvh::bounds get(const b2AABB &b) {
///       return {b.lowerBound.x, b.lowerBound.y, b.upperBound.x, b.upperBound.y}; } };
/// Every box type box_traits understands can be a shape's box and the
/// argument of query() and overlapping().
template <class B> struct box_traits {
  static bounds get(const B &b) {
    const auto &lo = b.getMin();
    const auto &hi = b.getMax();
    return bounds{double(lo.x), double(lo.y), double(hi.x), double(hi.y)};
  }
};
/// bounds itself.
template <> struct box_traits<bounds> {
  static bounds get(const bounds &b) { return b; }
};

/// How the tree reads a stored value of type T: its box, its centre and
/// whether two of them intersect. The default reads the members getBox()
/// and getCenter() and calls the free intersect(a, b) found by
/// argument-dependent lookup, as the course's shapes have them. For a type
/// of your own, specialize shape_traits<YourType> (static members), or pass
/// an adaptor type as BVH's second template argument: the tree keeps a copy
/// of it (given to its constructor), so it may hold state, e.g. pointers to
/// the arrays that stored ids index (examples/ids_into_arrays.cpp).
template <class T> struct shape_traits {
  /// Its box: any type box_traits understands.
  static decltype(auto) box(const T &s) { return s.getBox(); }
  /// Its centre, anything with x and y: the build rules sort by it.
  static decltype(auto) center(const T &s) { return s.getCenter(); }
  /// True when a and b share a point (touching counts).
  static bool intersect(const T &a, const T &b) { return detail::intersect_adl(a, b); }
  /// A promise that each shape is the closed disk inscribed in its box
  /// (up to the rounding of the box's sides to double or float) and that
  /// intersect() is exactly "the closed disks share a point". Collision
  /// searches of trees with leaf summaries (widths 4 to 8) then decide
  /// most shapes from the summary alone, without reading them; the answers
  /// are the same. True for this project's Disk; an adaptor of your own
  /// may declare it too.
  static constexpr bool inscribed_disks = detail::kExactDisk<T>;
};

namespace detail {
/// Tr::inscribed_disks, or false when Tr has no such member.
template <class Tr, class = void> struct InscribedDisks : std::false_type {};
template <class Tr>
struct InscribedDisks<Tr, std::void_t<decltype(Tr::inscribed_disks)>>
    : std::integral_constant<bool, bool(Tr::inscribed_disks)> {};
} // namespace detail

namespace detail {

/// A stack of node indices that lives on the call stack until it outgrows
/// its inline space: traversals of shallow trees never allocate, deep ones
/// still work.
class IndexStack {
public:
  // (forced inline: in a large translation unit gcc stops inlining these,
  // and every traversal calls them once per node)
  BVH_ALWAYS_INLINE void push(int v) {
    if (size_ < kInline) {
      inline_[size_++] = v;
    } else {
      spill_.push_back(v);
      ++size_;
    }
  }
  BVH_ALWAYS_INLINE int pop() {
    --size_;
    if (size_ < kInline) return inline_[size_];
    int v = spill_.back();
    spill_.pop_back();
    return v;
  }
  BVH_ALWAYS_INLINE bool empty() const { return size_ == 0; }
  /// Drops every entry (keeps the heap part's room).
  void clear() noexcept {
    size_ = 0;
    spill_.clear();
  }

  /// Entries held without allocating.
  static constexpr std::size_t kInline = 96;

private:
  int inline_[kInline];
  std::size_t size_ = 0;
  std::vector<int> spill_;
};

/// A vector of up to N elements on the call stack, moved to the heap when
/// it outgrows them: best_first's heaps, so that a query of a few answers
/// never allocates. E: default-constructible and copyable.
template <class E, std::size_t N> class InlineVector {
public:
  InlineVector() = default;
  InlineVector(const InlineVector &) = delete;
  InlineVector &operator=(const InlineVector &) = delete;
  void clear() { size_ = 0; }
  void reserve(std::size_t n) {
    if (n <= capacity_) return;
    std::vector<E> bigger(std::max(n, 2 * capacity_));
    std::copy(begin(), end(), bigger.begin());
    spill_.swap(bigger);
    data_ = spill_.data();
    capacity_ = spill_.size();
  }
  void push_back(const E &e) {
    if (size_ == capacity_) reserve(size_ + 1);
    data_[size_++] = e;
  }
  void pop_back() { --size_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  E &front() { return data_[0]; }
  const E &front() const { return data_[0]; }
  E &back() { return data_[size_ - 1]; }
  const E &operator[](std::size_t i) const { return data_[i]; }
  E *begin() { return data_; }
  E *end() { return data_ + size_; }
  const E *begin() const { return data_; }
  const E *end() const { return data_ + size_; }

private:
  E inline_[N];
  std::vector<E> spill_;
  E *data_ = inline_;
  std::size_t size_ = 0, capacity_ = N;
};

/// Faults in the whole pages of [p, p + bytes), a block just allocated,
/// in one call where the kernel can (madvise MADV_POPULATE_WRITE, Linux
/// 5.14; elsewhere, or if it fails, nothing happens): a tree writes a new
/// block's pages soon, one by one, and where a page fault is dear (a
/// virtual machine's) one call for them all costs much less than a fault
/// each. An array's first block is left to fill page by page: a small
/// tree, which never fills it, then holds only the pages it uses.
/// memory() counts whole blocks either way. BVH_NO_HUGE_PAGES turns it
/// off.
inline void populate(void *p, std::size_t bytes) noexcept {
#if BVH_HUGE_PAGES && defined(MADV_POPULATE_WRITE)
  // (4 kB pages; where the kernel's are larger, as on some ARM64 kernels,
  // a start that is not on one of its pages makes the call fail: no hint)
  const std::uintptr_t a = reinterpret_cast<std::uintptr_t>(p), page = 4096;
  const std::uintptr_t lo = (a + page - 1) & ~(page - 1), hi = (a + bytes) & ~(page - 1);
  if (hi > lo) ::madvise(reinterpret_cast<void *>(lo), hi - lo, MADV_POPULATE_WRITE); // (only pages inside the block)
#else
  (void)p;
  (void)bytes;
#endif
}

/// The node arrays: a vector's interface (index, size, emplace_back) over
/// fixed blocks of kBlock elements. Growing never moves or copies what is
/// stored, so a growing tree never holds two copies of its nodes at once,
/// as std::vector's doubling would, and the slack is at most one block.
/// Each block starts on a cache line (malloc promises only 16 bytes), so
/// that a ternary Node, 64 bytes, is one line and not two. Elements are
/// constructed as they are appended: a small tree's copy copies its
/// nodes, not whole blocks. A new block's pages are faulted in at once
/// (populate).
template <class X> class BlockVector {
  static_assert(std::is_trivially_destructible<X>::value && std::is_trivially_copyable<X>::value,
                "blocks are copied and freed without running element code");

public:
  /// Empty, no block.
  BlockVector() = default;
  /// Deep copy.
  BlockVector(const BlockVector &other) : size_(other.size_) {
    reserve_blocks(other.items_.size());
    std::size_t left = other.size_;
    for (const X *b : other.items_) {
      const std::size_t n = std::min(left, kBlock);
      std::uninitialized_copy_n(b, n, add_block());
      left -= n;
    }
  }
  /// Takes `other`'s blocks; `other` is left empty.
  BlockVector(BlockVector &&other) noexcept
      : items_(std::move(other.items_)), raw_(std::move(other.raw_)), size_(other.size_) {
    other.clear();
  }
  /// Deep copy; self-assignment is safe.
  BlockVector &operator=(const BlockVector &other) {
    if (this != &other) *this = BlockVector(other);
    return *this;
  }
  /// Takes `other`'s blocks; `other` is left empty.
  BlockVector &operator=(BlockVector &&other) noexcept {
    if (this != &other) {
      items_ = std::move(other.items_);
      raw_ = std::move(other.raw_);
      size_ = other.size_;
      other.clear();
    }
    return *this;
  }
  /// Exchanges the contents.
  void swap(BlockVector &other) noexcept {
    items_.swap(other.items_);
    raw_.swap(other.raw_);
    std::swap(size_, other.size_);
  }

  /// Element i (< size()).
  X &operator[](std::size_t i) { return items_[i >> kShift][i & kMask]; }
  /// Element i (< size()).
  const X &operator[](std::size_t i) const { return items_[i >> kShift][i & kMask]; }
  /// The last element (not empty()).
  X &back() { return (*this)[size_ - 1]; }
  /// Number of elements.
  std::size_t size() const { return size_; }
  /// True when there is no element.
  bool empty() const { return size_ == 0; }
  /// Drops every element and block.
  void clear() noexcept {
    items_.clear();
    raw_.clear();
    size_ = 0;
  }
  /// Makes room in the block table only: blocks come one at a time.
  void reserve(std::size_t n) { reserve_blocks((n + kMask) >> kShift); }
  /// Grows to n elements (n >= size()), the new ones value-initialized.
  void resize(std::size_t n) {
    reserve(n);
    while (size_ < n) emplace_back();
  }
  /// Makes room for one more element: after it, emplace_back() cannot
  /// throw. Strong.
  void reserve_one() {
    if (size_ == items_.size() << kShift) {
      reserve_blocks(items_.size() + 1);
      add_block();
    }
  }
  /// Appends a value-initialized element (strong: if it throws, nothing
  /// changed).
  void emplace_back() {
    reserve_one();
    ::new (static_cast<void *>(items_[size_ >> kShift] + (size_ & kMask))) X();
    ++size_;
  }
  /// Removes the last element.
  void pop_back() { --size_; }
  /// Bytes held: the blocks, whole, and the block table.
  std::size_t bytes() const {
    return raw_.size() * kBlockBytes + items_.capacity() * sizeof(X *) + raw_.capacity() * sizeof(raw_[0]);
  }

private:
  static constexpr std::size_t kShift = 9, kBlock = std::size_t(1) << kShift, kMask = kBlock - 1;
  static constexpr std::size_t kLine = 64, kBlockBytes = kBlock * sizeof(X) + kLine - 1;
  /// Room in both tables for n blocks (then add_block cannot throw there).
  void reserve_blocks(std::size_t n) {
    if (n <= items_.capacity() && n <= raw_.capacity()) return;
    const std::size_t room = std::max(n, 2 * items_.size());
    items_.reserve(room);
    raw_.reserve(room);
  }
  /// A new block, room for kBlock elements not yet constructed; the
  /// tables have room for it (reserve_blocks).
  X *add_block() {
    std::unique_ptr<unsigned char[]> raw(new unsigned char[kBlockBytes]);
    if (!raw_.empty()) populate(raw.get(), kBlockBytes); // (not the first: see populate)
    const std::size_t skip = (kLine - reinterpret_cast<std::uintptr_t>(raw.get()) % kLine) % kLine;
    raw_.push_back(std::move(raw)); // (no throw: reserved)
    items_.push_back(reinterpret_cast<X *>(raw_.back().get() + skip));
    return items_.back();
  }
  std::vector<X *> items_;                           // each block's first element, on a cache line
  std::vector<std::unique_ptr<unsigned char[]>> raw_; // what each block's allocation returned
  std::size_t size_ = 0;
};

/// Makes room in `v` for n elements, growing geometrically: the free lists
/// keep room for every index they may be given back, so that giving one
/// back (in an undo, or freeing a replaced subtree) never allocates.
template <class I, class A> void reserve_for(std::vector<I, A> &v, std::size_t n) {
  if (v.capacity() < n) v.reserve(std::max(n, 2 * v.capacity()));
}

/// The allocator of the leaf pool's per-class arrays (slot sizes, free
/// slots, block tables), which insert_disjoint's lanes reserve far beyond
/// their use, in every class, and give back when the call ends. Where
/// BVH_MAPPED_ARRAYS (Linux) an array of kMapped bytes or more is mapped
/// on its own (mmap) and unmapped when freed: the pages of the reserve it
/// never touches take no memory, and all of its pages go back to the
/// system when it is freed. From malloc, such arrays would stay in its
/// heap once freed (glibc raises its mmap threshold to the size of a
/// mapped block freed, so the next ones come from the heap), resident in
/// every page a later allocation touched in them, and sampling on several
/// threads would peak far above one thread. Elsewhere it is
/// std::allocator.
template <class X> struct MappedAllocator {
  using value_type = X;
  MappedAllocator() = default;
  template <class Y> MappedAllocator(const MappedAllocator<Y> &) noexcept {}
  static constexpr std::size_t kMapped = std::size_t(1) << 17;
  /// Whether an array of n is mapped (counted in elements: no overflow).
  static bool mapped(std::size_t n) { return BVH_MAPPED_ARRAYS && n >= (kMapped + sizeof(X) - 1) / sizeof(X); }
  X *allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(X)) throw std::bad_alloc();
#if BVH_MAPPED_ARRAYS
    if (mapped(n)) {
      void *p = ::mmap(nullptr, n * sizeof(X), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      return static_cast<X *>(p);
    }
#endif
    return std::allocator<X>().allocate(n);
  }
  void deallocate(X *p, std::size_t n) noexcept {
#if BVH_MAPPED_ARRAYS
    if (mapped(n)) {
      ::munmap(static_cast<void *>(p), n * sizeof(X));
      return;
    }
#endif
    std::allocator<X>().deallocate(p, n);
  }
  template <class Y> bool operator==(const MappedAllocator<Y> &) const noexcept { return true; }
  template <class Y> bool operator!=(const MappedAllocator<Y> &) const noexcept { return false; }
};
/// A vector of MappedAllocator.
template <class X> using MappedVector = std::vector<X, MappedAllocator<X>>;

/// The float next to `f` towards -infinity (towards +infinity when `up`),
/// by stepping its bit pattern: std::nextafter is a library call, and this
/// sits on every insert and query.
inline float float_step(float f, bool up) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  if (f == 0) {
    bits = up ? 0x00000001u : 0x80000001u; // the smallest subnormal
  } else if ((f > 0) == up) {
    ++bits;
  } else {
    --bits;
  }
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
/// The largest float <= d: boxes rounded outwards stay conservative.
inline float float_down(double d) {
  const float f = static_cast<float>(d);
  return static_cast<double>(f) > d ? float_step(f, false) : f;
}
/// The smallest float >= d.
inline float float_up(double d) {
  const float f = static_cast<float>(d);
  return static_cast<double>(f) < d ? float_step(f, true) : f;
}

/// An axis-aligned box in double: the tree's own box arithmetic (union,
/// containment, overlap, area), so that a shape's box need offer only
/// getMin() and getMax(), as the course's BoundingBox does (it has no empty
/// box, no union operator, no containment and no comparison). The default
/// box is empty: it contains nothing, and extending it gives the other box.
struct Box {
  double x0 = std::numeric_limits<double>::infinity(), y0 = std::numeric_limits<double>::infinity();
  double x1 = -std::numeric_limits<double>::infinity(), y1 = -std::numeric_limits<double>::infinity();

  /// The box of `b`.
  static Box of(const bounds &b) { return Box{b.min_x, b.min_y, b.max_x, b.max_y}; }
  /// The box of `b`, any type box_traits understands.
  template <class B> static Box from(const B &b) { return of(box_traits<B>::get(b)); }
  /// The box of one point (anything with x and y).
  template <class P> static Box at(const P &p) { return Box{p.x, p.y, p.x, p.y}; }

  /// True for the box that contains nothing.
  bool empty() const { return x0 > x1 || y0 > y1; }
  /// Width (0 when empty).
  double dx() const { return empty() ? 0 : x1 - x0; }
  /// Height (0 when empty).
  double dy() const { return empty() ? 0 : y1 - y0; }
  /// Area (0 when empty).
  double area() const { return dx() * dy(); }
  /// True when the boxes share a point: touching counts.
  bool overlaps(const Box &o) const { return x0 <= o.x1 && o.x0 <= x1 && y0 <= o.y1 && o.y0 <= y1; }
  /// True when `o` lies inside this box, boundaries included.
  bool contains(const Box &o) const { return x0 <= o.x0 && y0 <= o.y0 && o.x1 <= x1 && o.y1 <= y1; }
  /// This box with every side pushed out by m >= 0 (an empty box stays empty).
  Box grown(double m) const { return empty() ? *this : Box{x0 - m, y0 - m, x1 + m, y1 + m}; }
  /// Grows to include `o` (an empty `o` changes nothing).
  void extend(const Box &o) {
    x0 = std::min(x0, o.x0);
    y0 = std::min(y0, o.y0);
    x1 = std::max(x1, o.x1);
    y1 = std::max(y1, o.y1);
  }
  /// Where the ray (ox, oy) + t (dx, dy), t >= 0, enters the box: 0 when it
  /// starts inside, +inf when it misses (slab test).
  double ray_entry(double ox, double oy, double dx, double dy) const {
    const double inf = std::numeric_limits<double>::infinity();
    double t0 = 0, t1 = inf;
    const double o[2] = {ox, oy}, d[2] = {dx, dy}, lo[2] = {x0, y0}, hi[2] = {x1, y1};
    for (int k = 0; k < 2; ++k) {
      if (d[k] == 0) {
        if (o[k] < lo[k] || o[k] > hi[k]) return inf;
        continue;
      }
      double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
      if (t0 > t1) return inf;
    }
    return t0;
  }
  friend bool operator==(const Box &a, const Box &b) {
    return a.x0 == b.x0 && a.y0 == b.y0 && a.x1 == b.x1 && a.y1 == b.y1;
  }
  friend bool operator!=(const Box &a, const Box &b) { return !(a == b); }
};

/// {float_down(b.x0), float_down(b.y0), float_up(b.x1), float_up(b.y1)}
/// into out: `b` rounded outwards to float.
/// With SSE2 the four at once and without branches: every box a node
/// stores and every query's box is rounded, and the scalar steps' branches
/// go either way at random.
BVH_ALWAYS_INLINE void round_out(const Box &b, float out[4]) {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  const __m128d lo = _mm_set_pd(b.y0, b.x0), hi = _mm_set_pd(b.y1, b.x1);
  const __m128 f = _mm_movelh_ps(_mm_cvtpd_ps(lo), _mm_cvtpd_ps(hi));
  // Lanes whose conversion went the wrong way (NaN never does).
  const __m128d wrong_lo = _mm_cmpgt_pd(_mm_cvtps_pd(f), lo);
  const __m128d wrong_hi = _mm_cmplt_pd(_mm_cvtps_pd(_mm_movehl_ps(f, f)), hi);
  const __m128i wrong = _mm_castps_si128(
      _mm_shuffle_ps(_mm_castpd_ps(wrong_lo), _mm_castpd_ps(wrong_hi), _MM_SHUFFLE(2, 0, 2, 0)));
  // float_step on the bit patterns: +1 (away from zero) when the float's
  // sign is the direction's, -1 otherwise; from +-0 to the smallest
  // subnormal of the direction's sign.
  const __m128i bits = _mm_castps_si128(f), down = _mm_set_epi32(0, 0, -1, -1);
  const __m128i one = _mm_set1_epi32(1);
  const __m128i stepped = _mm_add_epi32(bits, _mm_or_si128(_mm_xor_si128(_mm_srai_epi32(bits, 31), down), one));
  const __m128i zero = _mm_castps_si128(_mm_cmpeq_ps(f, _mm_setzero_ps()));
  const __m128i smallest = _mm_or_si128(_mm_slli_epi32(down, 31), one);
  const __m128i step = _mm_or_si128(_mm_and_si128(zero, smallest), _mm_andnot_si128(zero, stepped));
  _mm_storeu_ps(out, _mm_castsi128_ps(_mm_or_si128(_mm_and_si128(wrong, step), _mm_andnot_si128(wrong, bits))));
#else
  out[0] = float_down(b.x0);
  out[1] = float_down(b.y0);
  out[2] = float_up(b.x1);
  out[3] = float_up(b.y1);
#endif
}

/// A point in double, from anything with x and y.
struct XY {
  double x, y;
  template <class P> static XY of(const P &p) { return XY{p.x, p.y}; }
};

/// The box of a stored shape, as `traits` (its shape_traits) reads it.
template <class Tr, class T> BVH_ALWAYS_INLINE Box box_of(const Tr &traits, const T &shape) {
  const auto &b = traits.box(shape);
  return Box::from(b);
}

// ---- Supported values (docs/library.txt, SUPPORTED VALUES) ----------------
// intersect.h is exact, and distance.h and the nearest searches' squared
// distances stay finite, for numbers that are 0 or of magnitude in
// [2^-200, 2^200]. The tree stores only such numbers (construct, insert,
// update and insert_disjoint refuse others) and a query outside them finds
// nothing, so that no answer is silently wrong.

/// The least and the greatest supported magnitude besides 0.
constexpr double kLeastSupported = 0x1p-200, kMostSupported = 0x1p200;

/// 1 unless v is 0 or of magnitude in [2^-200, 2^200] (NaN and the
/// infinities give 1), without a branch. (A double's bits without the
/// sign order as its magnitude does, NaNs above the infinities.)
BVH_ALWAYS_INLINE unsigned unsupported_bit(double v) {
  std::uint64_t u;
  std::memcpy(&u, &v, sizeof u);
  u <<= 1; // the sign dropped
  constexpr std::uint64_t least = std::uint64_t(1023 - 200) << 53, most = std::uint64_t(1023 + 200) << 53;
  return unsigned(u - least > most - least) & unsigned(u != 0);
}

/// Whether any of the numbers it is given is unsupported (or a radius
/// negative, or a box's min above its max): every number of a shape is
/// checked, without a branch, and the answer read once. Two at a time with
/// SSE2.
class UnsupportedAny {
public:
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  BVH_ALWAYS_INLINE void pair(double a, double b) { bad_ = _mm_or_pd(bad_, lanes(_mm_set_pd(b, a))); }
  BVH_ALWAYS_INLINE void radius(double r) {
    const __m128d v = _mm_set1_pd(r);
    bad_ = _mm_or_pd(bad_, _mm_or_pd(lanes(v), _mm_cmplt_pd(v, _mm_setzero_pd())));
  }
  BVH_ALWAYS_INLINE void box(const Box &b) {
    const __m128d lo = _mm_set_pd(b.y0, b.x0), hi = _mm_set_pd(b.y1, b.x1);
    bad_ = _mm_or_pd(bad_, _mm_or_pd(_mm_or_pd(lanes(lo), lanes(hi)), _mm_cmpnle_pd(lo, hi)));
  }
  BVH_ALWAYS_INLINE bool any() const { return _mm_movemask_pd(bad_) != 0; }

private:
  /// All ones in each lane of v that is unsupported (NaN included: the
  /// "not less or equal" compare is true for it).
  static BVH_ALWAYS_INLINE __m128d lanes(__m128d v) {
    const __m128d a = _mm_andnot_pd(_mm_set1_pd(-0.0), v);
    const __m128d big = _mm_cmpnle_pd(a, _mm_set1_pd(kMostSupported));
    const __m128d tiny = _mm_and_pd(_mm_cmplt_pd(a, _mm_set1_pd(kLeastSupported)), _mm_cmpneq_pd(a, _mm_setzero_pd()));
    return _mm_or_pd(big, tiny);
  }
  __m128d bad_ = _mm_setzero_pd();
#else
  BVH_ALWAYS_INLINE void pair(double a, double b) { bad_ |= unsupported_bit(a) | unsupported_bit(b); }
  BVH_ALWAYS_INLINE void radius(double r) { bad_ |= unsupported_bit(r) | unsigned(!(r >= 0)); }
  BVH_ALWAYS_INLINE void box(const Box &b) {
    bad_ |= unsupported_bit(b.x0) | unsupported_bit(b.y0) | unsupported_bit(b.x1) | unsupported_bit(b.y1) |
            unsigned(!(b.x0 <= b.x1)) | unsigned(!(b.y0 <= b.y1));
  }
  BVH_ALWAYS_INLINE bool any() const { return bad_ != 0; }

private:
  unsigned bad_ = 0;
#endif
};

/// Every side supported, and min <= max on both axes.
BVH_ALWAYS_INLINE bool supported(const Box &b) {
  UnsupportedAny bad;
  bad.box(b);
  return !bad.any();
}
/// A side of `b` is NaN.
inline bool has_nan(const Box &b) { return std::isnan(b.x0) || std::isnan(b.y0) || std::isnan(b.x1) || std::isnan(b.y1); }

// What a shape type shows of its own numbers: points (numPoints() and
// getPoint(i), as the course's polygons and this project's shapes), a
// centre (getCenter()), a radius (getRadius(), or disk()->getRadius() for
// a mixed Shape holding a disk).
template <class S, class = void> struct ShowsPoints : std::false_type {};
template <class S>
struct ShowsPoints<S, std::void_t<decltype(int(std::declval<const S &>().numPoints()) +
                                           double(std::declval<const S &>().getPoint(0).x))>> : std::true_type {};
template <class S, class = void> struct ShowsCenter : std::false_type {};
template <class S>
struct ShowsCenter<S, std::void_t<decltype(double(std::declval<const S &>().getCenter().x))>> : std::true_type {};
template <class S, class = void> struct ShowsRadius : std::false_type {};
template <class S>
struct ShowsRadius<S, std::void_t<decltype(double(std::declval<const S &>().getRadius()))>> : std::true_type {};
template <class S, class = void> struct HoldsDisk : std::false_type {};
template <class S>
struct HoldsDisk<S, std::void_t<decltype(double(std::declval<const S &>().disk()->getRadius()))>> : std::true_type {};

/// Adds the numbers a shape shows besides its box (above) to `bad`: a
/// type that shows none (an id an adaptor reads) is judged by its box
/// alone.
template <class S> BVH_ALWAYS_INLINE void add_numbers(UnsupportedAny &bad, const S &s) {
  if constexpr (ShowsPoints<S>::value) {
    for (int i = 0, n = int(s.numPoints()); i < n; ++i) {
      const auto &p = s.getPoint(i);
      bad.pair(double(p.x), double(p.y));
    }
  } else if constexpr (ShowsRadius<S>::value && ShowsCenter<S>::value) {
    bad.pair(double(s.getCenter().x), double(s.getCenter().y));
  }
  if constexpr (ShowsRadius<S>::value) {
    bad.radius(double(s.getRadius()));
  } else if constexpr (HoldsDisk<S>::value) {
    if (const auto *d = s.disk()) bad.radius(double(d->getRadius()));
  }
}

/// The tree may store `shape`, and answers a query by it: its box as the
/// traits read it and its own numbers are supported.
template <class Tr, class T> BVH_ALWAYS_INLINE bool supported_shape(const Tr &traits, const T &shape) {
  UnsupportedAny bad;
  bad.box(box_of(traits, shape));
  add_numbers(bad, shape);
  return !bad.any();
}

/// Throws std::invalid_argument for the shape `which` (e.g.
/// "elements[37]") of `call`, naming its box. (Out of line: the message is
/// built only on the error.)
[[noreturn]]
#if defined(__GNUC__)
__attribute__((noinline, cold))
#endif
inline void refuse_unsupported(const char *call, const std::string &which, const Box &b) {
  char box[160];
  std::snprintf(box, sizeof box, "[<%.17g %.17g> <%.17g %.17g>]", b.x0, b.y0, b.x1, b.y1);
  throw std::invalid_argument(std::string("bvh::BVH::") + call + ": " + which + " (box " + box +
                              ") has a coordinate, radius or box side outside the supported range: each must "
                              "be 0 or of magnitude in [2^-200, 2^200], and a radius not negative");
}

/// refuse_unsupported() unless supported_shape(traits, shape).
template <class Tr, class T> void require_supported(const Tr &traits, const T &shape, const char *call) {
  if (!supported_shape(traits, shape)) refuse_unsupported(call, "the shape", box_of(traits, shape));
}

/// refuse_unsupported() for the first of `shapes` that is not supported,
/// named `what`[i].
template <class Tr, class T>
void require_supported(const Tr &traits, const std::vector<T> &shapes, const char *call, const char *what) {
  for (std::size_t i = 0; i < shapes.size(); ++i)
    if (!supported_shape(traits, shapes[i]))
      refuse_unsupported(call, std::string(what) + "[" + std::to_string(i) + "]", box_of(traits, shapes[i]));
}

/// Appends `[<x0 y0> <x1 y1>]` with every number as %5.1f: the course's
/// listing of a box, written here so that neither the stream's flags nor
/// the shape library's printing can change it.
inline void append_box(std::string &out, const Box &b) {
  char buf[1400]; // four %5.1f doubles of any magnitude fit
  std::snprintf(buf, sizeof buf, "[<%5.1f %5.1f> <%5.1f %5.1f>]", b.x0, b.y0, b.x1, b.y1);
  out += buf;
}

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

/// Scenes smaller than this are built without threads, and ranges smaller
/// than this are not split between threads.
constexpr std::size_t kParallelMin = std::size_t(1) << 16;

/// Calls f(0) ... f(count - 1), spread over `threads` threads (the caller
/// is one of them). If a thread cannot be started (no thread left, or no
/// memory for it), the others do its share; the first exception thrown by
/// f is rethrown once all have finished.
template <class F> void parallel_for(std::size_t count, unsigned threads, F &&f) {
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_lock;
  auto work = [&] {
    for (std::size_t i; (i = next++) < count;) {
      try {
        f(i);
      } catch (...) {
        std::lock_guard<std::mutex> hold(error_lock);
        if (!error) error = std::current_exception();
      }
    }
  };
  // The pool's room first, so that starting a thread is the only step
  // that can fail once one runs: whatever it throws (system_error,
  // bad_alloc), no thread is left running past an exception, and the
  // threads started and the caller do the work.
  std::vector<std::thread> pool;
  try {
    pool.reserve(std::min<std::size_t>(threads, count));
    for (unsigned k = 1; k < threads && k < count; ++k) pool.emplace_back(work);
  } catch (...) {
  }
  work();
  for (std::thread &t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// A view of n contiguous X: a leaf's shapes.
template <class X> struct Span {
  X *first;
  std::size_t count;
  X *begin() const { return first; }
  X *end() const { return first + count; }
  std::size_t size() const { return count; }
  bool empty() const { return count == 0; }
  X &operator[](std::size_t i) const { return first[i]; }
};

/// A shape on its way from one leaf to others (a split, a rebuild), with its
/// id.
template <class T> struct Tagged {
  T shape;
  std::uint32_t id;
};

/// Working memory reused from one build to the next. Copies of a tree do
/// not copy it: it holds nothing between calls.
template <class X> struct Scratch {
  X value;
  Scratch() = default;
  Scratch(const Scratch &) {}
  Scratch &operator=(const Scratch &) { return *this; }
};

/// The lock that node and slot allocation take while several threads
/// change disjoint subtrees of one tree at once (insert_disjoint's parallel
/// inserts, section 8b), mostly a chunk at a time for a LaneCache, and the
/// count of nodes and slots taken under it: the stores' arrays were
/// reserved beforehand, and a thread starts an insert only while that count
/// leaves room for every thread's worst case, so no array is reallocated
/// under another thread's reads.
struct SharedAlloc {
  std::mutex lock;
  std::atomic<std::size_t> taken{0};
};

/// One lane's own nodes and slots while lanes share a tree (section 8b):
/// taken from the stores a chunk at a time under SharedAlloc's lock, and
/// those the lane gives back, reused first, so that a lane seldom takes
/// the lock and its subtree's nodes lie near each other. What is left goes
/// back to the stores when the lanes end. Its lists' room is reserved
/// before the lanes start, so giving back never allocates.
struct LaneCache {
  /// Nodes or slots taken under the lock at a time.
  static constexpr std::size_t kChunk = 32;
  std::vector<int> nodes;                        ///< free nodes of the lane's
  std::vector<std::vector<std::uint32_t>> slots; ///< free slots of the lane's, by class
  /// Room for the chunks of nodes and of slots of `classes` classes.
  void reserve(std::size_t classes) {
    nodes.reserve(2 * kChunk);
    slots.resize(classes);
    for (std::vector<std::uint32_t> &c : slots) c.reserve(2 * kChunk);
  }
  /// The cache of the lane this thread runs (none outside a lane).
  static LaneCache *&current() noexcept {
    static thread_local LaneCache *lane = nullptr;
    return lane;
  }
};

/// A store's link to the SharedAlloc in force, none outside those inserts;
/// a copy of a store links to none.
struct Sharing {
  SharedAlloc *to = nullptr;
  Sharing() = default;
  Sharing(const Sharing &) noexcept {}
  Sharing &operator=(const Sharing &) noexcept { return *this; }
  /// f(), under the lock while shared; `take` counts an allocation.
  template <class F> decltype(auto) locked(bool take, F &&f) {
    if (!to) return f();
    std::lock_guard<std::mutex> hold(to->lock);
    if (take) to->taken.fetch_add(1, std::memory_order_relaxed);
    return f();
  }
  /// The running lane's list `own` (LaneCache) refilled, when empty, with
  /// up to `most` (<= kChunk) items of take() under the lock: the first may
  /// throw (then nothing changed), the others stop at a throw.
  template <class Item, class F> void refill(std::vector<Item> &own, F &&take, std::size_t most = LaneCache::kChunk) {
    if (!own.empty()) return;
    std::lock_guard<std::mutex> hold(to->lock);
    own.push_back(take());
    try {
      while (own.size() < most) own.push_back(take());
    } catch (...) {
    }
    to->taken.fetch_add(own.size(), std::memory_order_relaxed);
  }
  /// `item` onto the running lane's list `own`; a list of 2 * `keep` (<=
  /// kChunk) items first gives all but `keep` back through give(item)
  /// under the lock.
  template <class Item, class F>
  void give_back(std::vector<Item> &own, Item item, F &&give, std::size_t keep = LaneCache::kChunk) noexcept {
    if (own.size() >= 2 * keep) {
      std::lock_guard<std::mutex> hold(to->lock);
      while (own.size() > keep) {
        give(own.back());
        own.pop_back();
      }
    }
    own.push_back(item); // (never allocates: room made above)
  }
};

/// f(args...) as "go on?": true unless f returns a bool false.
template <class F, class... A> bool keep_going(F &f, const A &...args) {
  if constexpr (std::is_same<decltype(f(args...)), bool>::value)
    return f(args...);
  else {
    f(args...);
    return true;
  }
}

/// Areas are reported relative to the course's 1000 x 1000 canvas.
constexpr double kCanvasArea = 1000.0 * 1000.0;

// ===========================================================================
// 2. Node storage
// ===========================================================================
//
// Nodes live in two parallel arrays. `Node` is what a query reads, one
// cache line: an inner node's children's boxes in float, rounded outwards,
// and their indices, so one line decides every child; a leaf's record of
// where its shapes are. `Info` is the rest: the exact double box, parent,
// depth and the subtree's shape count. A box is thus stored twice, the
// exact one in the node's Info and its float copy in the parent's Node;
// NodeStore::set_box is the only writer of both (section 8b's routing
// alone writes a float copy ahead of its box: set_parent_copy).

/// Children per inner node of the course's ternary tree, the default
/// width (BVH<T, Traits, Width>).
constexpr int kCourseWidth = 3;
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
  /// set when shape i's code box meets box `b`'s.
  BVH_ALWAYS_INLINE std::uint32_t meets(const Box &b, int n) const {
    const std::uint32_t c = codes_of(b, frame());
    const std::uint32_t live = n >= 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << n) - 1;
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    // (a <= b for bytes: min(a, b) == a; lanes past the row are masked off)
    const __m128i qx = _mm_set1_epi8(char(c & 255u)), qy = _mm_set1_epi8(char(c >> 8 & 255u));
    const __m128i px = _mm_set1_epi8(char(c >> 16 & 255u)), py = _mm_set1_epi8(char(c >> 24));
    std::uint32_t bits = 0;
    for (int g = 0; g < n; g += 16) {
      const auto load = [&](int r) { return _mm_loadu_si128(reinterpret_cast<const __m128i *>(row(r) + g)); };
      const __m128i x0 = load(0), y0 = load(1), x1 = load(2), y1 = load(3);
      const __m128i ok = _mm_and_si128(
          _mm_and_si128(_mm_cmpeq_epi8(_mm_min_epu8(x0, px), x0), _mm_cmpeq_epi8(_mm_min_epu8(y0, py), y0)),
          _mm_and_si128(_mm_cmpeq_epi8(_mm_max_epu8(x1, qx), x1), _mm_cmpeq_epi8(_mm_max_epu8(y1, qy), y1)));
      bits |= std::uint32_t(_mm_movemask_epi8(ok)) << g;
    }
    return bits & live;
#else
    const unsigned lx = c & 255u, ly = c >> 8 & 255u, hx = c >> 16 & 255u, hy = c >> 24;
    std::uint32_t bits = 0;
    for (int i = 0; i < n; ++i)
      bits |= std::uint32_t(row(0)[i] <= hx && row(1)[i] <= hy && lx <= row(2)[i] && ly <= row(3)[i]) << i;
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

/// The node arrays and the list of free nodes of a tree of width W. Owns
/// both copies of every box: set_box() writes a node's exact box and its
/// parent's float copy together, so they never disagree.
template <int W> class NodeStore {
public:
  using Node = bvh::detail::Node<W>;
  /// Children per inner node, at most.
  static constexpr int kWidth = W;
  /// Node n's hot part.
  Node &node(int n) { return nodes_[std::size_t(n)]; }
  const Node &node(int n) const { return nodes_[std::size_t(n)]; }
  /// Node n's cold part (its box through set_box only).
  Info &info(int n) { return info_[std::size_t(n)]; }
  const Info &info(int n) const { return info_[std::size_t(n)]; }
  /// Node n's exact box.
  const Box &box(int n) const { return info_[std::size_t(n)].box_; }

  /// Sets node n's box: its exact box and, below the root, the float copy
  /// in its parent, `b` rounded outwards.
  BVH_ALWAYS_INLINE void set_box(int n, const Box &b) {
    Info &in = info(n);
    in.box_ = b;
    if (in.parent >= 0) set_parent_copy(n, b);
  }
  /// Sets only the parent's float copy of node n's box (n below the root),
  /// ahead of n's own: section 8b's routing, whose lanes then grow n's box
  /// to `b`, which puts the two copies in step again. Nothing else may
  /// let them differ.
  BVH_ALWAYS_INLINE void set_parent_copy(int n, const Box &b) {
    const Info &in = info(n);
    Node &p = node(in.parent);
    float f[4];
    round_out(b, f);
    const int c = in.child_index;
    p.lo_x[c] = f[0];
    p.lo_y[c] = f[1];
    p.hi_x[c] = f[2];
    p.hi_y[c] = f[3];
  }
  /// Grows node n's box to hold `b`; true when it grew.
  BVH_ALWAYS_INLINE bool extend_box(int n, const Box &b) {
    if (box(n).contains(b)) return false;
    Box grown = box(n);
    grown.extend(b);
    set_box(n, grown);
    return true;
  }

  NodeStore() = default;
  /// Deep copy, with the free list's room for every node.
  NodeStore(const NodeStore<W> &o) : nodes_(o.nodes_), info_(o.info_) {
    free_.reserve(o.nodes_.size());
    free_ = o.free_;
  }
  NodeStore(NodeStore<W> &&) noexcept = default;
  NodeStore<W> &operator=(const NodeStore<W> &o) {
    NodeStore copy(o);
    swap(copy);
    return *this;
  }
  NodeStore<W> &operator=(NodeStore<W> &&) noexcept = default;

  /// A node index, from the free list first; reset() must follow. Strong:
  /// if it throws, nothing changed.
  int allocate() {
    if (!sharing_.to) return allocate_here();
    LaneCache *own = LaneCache::current();
    if (!own) return sharing_.locked(true, [&] { return allocate_here(); });
    sharing_.refill(own->nodes, [&] { return allocate_here(); }, LaneCache::kChunk / (W > 4 ? 4 : 2));
    const int n = own->nodes.back();
    own->nodes.pop_back();
    return n;
  }
  /// Room for `spare` more nodes in the block tables, so that allocating
  /// them never moves a table (the blocks themselves come one at a time).
  void reserve_spare(std::size_t spare) {
    nodes_.reserve(nodes_.size() + spare);
    info_.reserve(info_.size() + spare);
  }
  /// Gives back the free list's room beyond one place a node (what
  /// release() needs); nothing changes if memory runs out.
  void shrink_spare() noexcept {
    try {
      std::vector<int> free;
      free.reserve(nodes_.size());
      free.assign(free_.begin(), free_.end());
      free_.swap(free);
    } catch (...) {
    }
  }
  /// Makes allocate() and release() take `shared`'s lock (none: nullptr).
  void share(SharedAlloc *shared) noexcept { sharing_.to = shared; }
  /// True while allocation is shared among threads.
  bool shared() const { return sharing_.to != nullptr; }
  /// Grows the arrays to `total` nodes (a laid-out build's).
  void resize(std::size_t total) {
    reserve_for(free_, total);
    nodes_.resize(total);
    info_.resize(total);
  }
  /// Node n as a fresh leaf with no slot and an empty box, at `depth`,
  /// child `child_index` of `parent`. Its old slot must have been given
  /// back.
  void reset(int n, int depth, int parent, int child_index) {
    BVH_INVARIANT(!node(n).is_leaf() || !node(n).leaf().has_slot(), "a reset leaf still owns a slot");
    nodes_[std::size_t(n)] = Node();
    Info &in = info(n);
    in.box_ = Box();
    in.depth = depth;
    in.parent = parent;
    in.child_index = child_index;
    in.count = 0;
  }
  /// Puts node n on the free list (its slot given back); its children
  /// links stay readable until it is reused.
  void release(int n) noexcept {
    BVH_INVARIANT(!node(n).is_leaf() || !node(n).leaf().has_slot(), "a freed leaf still owns a slot");
    // (free_ never allocates: allocate() made room)
    if (LaneCache *own = sharing_.to ? LaneCache::current() : nullptr)
      sharing_.give_back(own->nodes, n, [&](int m) { free_.push_back(m); });
    else
      sharing_.locked(false, [&] { free_.push_back(n); });
  }
  /// Takes back the nodes a lane's cache holds, when its lane ends (under
  /// the lock while shared).
  void take_back(std::vector<int> &own) noexcept {
    if (own.empty()) return;
    sharing_.locked(false, [&] {
      for (int n : own) free_.push_back(n); // (never allocates: allocate() made room)
    });
    own.clear();
  }

  /// Nodes in the arrays, live or free.
  std::size_t capacity() const { return nodes_.size(); }
  /// Live nodes.
  std::size_t live() const { return nodes_.size() - free_.size(); }
  /// The free nodes.
  const std::vector<int> &free_list() const { return free_; }
  /// Bytes held: both arrays' blocks and the free list's room.
  std::size_t bytes() const { return nodes_.bytes() + info_.bytes() + free_.capacity() * sizeof(int); }
  /// Drops every node.
  void clear() noexcept {
    nodes_.clear();
    info_.clear();
    free_.clear();
  }
  void swap(NodeStore<W> &o) noexcept {
    nodes_.swap(o.nodes_);
    info_.swap(o.info_);
    free_.swap(o.free_);
  }

  /// The leftmost leaf under n.
  int leftmost_leaf(int n) const {
    while (!node(n).is_leaf()) n = node(n).child(0);
    return n;
  }
  /// The rightmost leaf under n.
  int rightmost_leaf(int n) const {
    while (!node(n).is_leaf()) n = node(n).child(node(n).num_children - 1);
    return n;
  }
  /// The leaf after `n` in left-to-right order, -1 after the last.
  int next_leaf(int n) const {
    for (int parent; (parent = info(n).parent) >= 0; n = parent) {
      const int c = info(n).child_index;
      if (c + 1 < node(parent).num_children) return leftmost_leaf(node(parent).child(c + 1));
    }
    return -1;
  }
  /// The leaf before `n`, -1 before the first.
  int prev_leaf(int n) const {
    for (int parent; (parent = info(n).parent) >= 0; n = parent) {
      const int c = info(n).child_index;
      if (c > 0) return rightmost_leaf(node(parent).child(c - 1));
    }
    return -1;
  }

private:
  int allocate_here() {
    if (!free_.empty()) {
      const int n = free_.back();
      free_.pop_back();
      return n;
    }
    reserve_for(free_, nodes_.size() + 1);
    nodes_.reserve_one(); // (then neither emplace_back throws)
    info_.reserve_one();
    nodes_.emplace_back();
    info_.emplace_back();
    return int(nodes_.size() - 1);
  }
  BlockVector<Node> nodes_;
  BlockVector<Info> info_;
  std::vector<int> free_; // indices of unused nodes, reused first
  Sharing sharing_;
};

/// A query box rounded outwards to float, and its centre, as child_masks
/// reads them.
struct Probe {
  /// The probe of `box` (once per query: out of line, see BVH_NOINLINE).
  static BVH_NOINLINE Probe around(const Box &box) { return inline_around(box); }
  /// around(), inlined: for a caller that keeps the probe in memory
  /// anyway (collides_each's lanes), where the call costs more than it saves.
  static BVH_ALWAYS_INLINE Probe inline_around(const Box &box) {
    float f[4];
    round_out(box, f);
    return Probe(f[0], f[1], f[2], f[3], 0.5f * (f[0] + f[2]), 0.5f * (f[1] + f[3]));
  }
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  // Broadcast to 4 lanes once per query, not once per node.
  Probe(float lx, float ly, float hx, float hy, float mx, float my)
      : lo_x(_mm_set1_ps(lx)), lo_y(_mm_set1_ps(ly)), hi_x(_mm_set1_ps(hx)), hi_y(_mm_set1_ps(hy)),
        mid_x(_mm_set1_ps(mx)), mid_y(_mm_set1_ps(my)) {}
  __m128 lo_x, lo_y, hi_x, hi_y, mid_x, mid_y;
#else
  Probe(float lx, float ly, float hx, float hy, float mx, float my)
      : lo_x(lx), lo_y(ly), hi_x(hx), hi_y(hy), mid_x(mx), mid_y(my) {}
  float lo_x, lo_y, hi_x, hi_y, mid_x, mid_y;
#endif
};

#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
/// f[0] and f[1] widened to two doubles: a node's row read two children
/// at a time (choose_child, the nearest searches' bounds).
inline __m128d two_floats(const float *f) {
  return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i *>(f))));
}
#endif

/// The node test. For inner node `node`: bit c of `hits` is set when child
/// c's box meets the probe's box, bit c of `near` when it also holds the
/// probe's centre (a hit there is likely, so collision() visits those
/// first). With SSE2 every child is tested in one 4-lane compare per bound
/// (the fourth lane reads the next field of the node and is masked off).
/// BVH_NO_SIMD forces the scalar path.
template <int W, bool kNear = true>
BVH_ALWAYS_INLINE void child_masks(const Node<W> &node, const Probe &p, unsigned &hits, unsigned &near) {
  const unsigned live = (1u << node.num_children) - 1;
  hits = 0;
  near = 0;
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  // Four children a pass; the lanes past W read the next row (or, after
  // hi_y, the links) and are masked off.
  for (int g = 0; g < W; g += 4) {
    const __m128 lx = _mm_loadu_ps(node.lo_x + g), ly = _mm_loadu_ps(node.lo_y + g);
    const __m128 hx = _mm_loadu_ps(node.hi_x + g), hy = _mm_loadu_ps(node.hi_y + g);
    const __m128 meets = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.hi_x), _mm_cmple_ps(p.lo_x, hx)),
                                    _mm_and_ps(_mm_cmple_ps(ly, p.hi_y), _mm_cmple_ps(p.lo_y, hy)));
    hits |= unsigned(_mm_movemask_ps(meets)) << g;
    if constexpr (kNear) {
      const __m128 holds = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.mid_x), _mm_cmple_ps(p.mid_x, hx)),
                                      _mm_and_ps(_mm_cmple_ps(ly, p.mid_y), _mm_cmple_ps(p.mid_y, hy)));
      near |= unsigned(_mm_movemask_ps(holds)) << g;
    }
  }
#else
  for (int c = 0; c < W; ++c) {
    hits |= unsigned((node.lo_x[c] <= p.hi_x) & (p.lo_x <= node.hi_x[c]) & (node.lo_y[c] <= p.hi_y) &
                     (p.lo_y <= node.hi_y[c]))
            << c;
    if constexpr (kNear)
      near |= unsigned((node.lo_x[c] <= p.mid_x) & (p.mid_x <= node.hi_x[c]) & (node.lo_y[c] <= p.mid_y) &
                       (p.mid_y <= node.hi_y[c]))
              << c;
  }
#endif
  hits &= live;
  near &= hits;
}

/// The index of the lowest set bit of `bits` (not 0).
inline int lowest_bit(std::uint32_t bits) {
#if defined(__GNUC__)
  return __builtin_ctz(bits);
#else
  int i = 0;
  while (!(bits >> i & 1u)) ++i;
  return i;
#endif
}

/// Asks the cache for the `bytes` bytes at `p`, which a step soon reads:
/// a hint, without effect on what the program computes (none without GCC
/// or clang).
BVH_ALWAYS_INLINE void prefetch_lines(const void *p, std::size_t bytes) {
#if defined(__GNUC__)
  const char *c = static_cast<const char *>(p);
  for (std::size_t o = 0; o < bytes; o += 64) __builtin_prefetch(c + o);
  __builtin_prefetch(c + bytes - 1);
#else
  (void)p;
  (void)bytes;
#endif
}

/// child_masks' `hits` alone: bit c set when child c's box meets the
/// probe's box.
template <int W> BVH_ALWAYS_INLINE unsigned child_hits(const Node<W> &node, const Probe &p) {
  unsigned hits, near;
  child_masks<W, false>(node, p, hits, near);
  return hits;
}

/// walk()'s visit result: bit c enters child c (c < num_children); bit
/// kFirst + c enters it before every child of the low bits; kStop ends
/// the walk.
constexpr unsigned kFirst = 8u, kStop = 1u << 16;
static_assert(kMaxWidth <= int(kFirst), "the 'first' bits sit above the child bits");

/// Pushes child c of `node` for each bit c of `bits`, highest first (so
/// that they pop left to right): one step a set bit, not one a child.
template <int W> BVH_ALWAYS_INLINE void push_bits(IndexStack &stack, const Node<W> &node, unsigned bits) {
#if defined(__GNUC__)
  for (; bits != 0; bits &= ~(1u << (31 - __builtin_clz(bits)))) stack.push(node.child(31 - __builtin_clz(bits)));
#else
  for (int c = W - 1; c >= 0; --c)
    if (bits >> c & 1u) stack.push(node.child(c));
#endif
}

/// Of the children `enter` names (walk()'s visit result, at least one),
/// returns the one to visit next and pushes the others so that they pop in
/// order: the "first" group, then the rest, each left to right. The next
/// child skips the stack: most steps of a query enter one child.
template <int W> BVH_ALWAYS_INLINE int enter_children(IndexStack &stack, const Node<W> &node, unsigned enter) {
  unsigned first = enter >> kFirst, later = enter & ~first & child_bits(W);
  if (first == 0) {
    first = later;
    later = 0;
  }
  const int next = node.child(lowest_bit(first));
  first &= first - 1;
  if constexpr (W == 3) { // unrolled: this is collision()'s inner loop
    if (later & 4u) stack.push(node.child(2));
    if (later & 2u) stack.push(node.child(1));
    if (later & 1u) stack.push(node.child(0));
    if (first & 4u) stack.push(node.child(2));
    if (first & 2u) stack.push(node.child(1));
  } else {
    push_bits(stack, node, later);
    push_bits(stack, node, first);
  }
  return next;
}

/// Asks the cache for the nodes of the children that enter_children() left
/// on the stack (all those `enter` names but `next`) at widths 4 to 8:
/// their misses do not depend on the subtree entered first, so they
/// overlap with it. (At the course's width 3 a node is one line, and the
/// walk stays as it was.)
template <int W>
BVH_ALWAYS_INLINE void prefetch_stacked(const NodeStore<W> &nodes, const Node<W> &node, unsigned enter, int next) {
  if constexpr (W >= 4) {
    for (unsigned b = (enter | enter >> kFirst) & child_bits(W); b != 0; b &= b - 1) {
      const int c = node.child(lowest_bit(b));
      if (c != next) prefetch_lines(&nodes.node(c), sizeof(Node<W>));
    }
  } else {
    (void)nodes, (void)node, (void)enter, (void)next;
  }
}

/// The one depth-first traversal (collision, the queries, find_equal, the
/// rebuilds' gathering, every pre-order pass): from node `from`, each node
/// visited before its children. visit(n) returns which children of n to
/// enter (0 for a leaf) or kStop. Returns false when a visit stopped it.
/// overlapping()'s iterator runs the same steps with its stack kept between
/// calls.
template <int W, class Visit> BVH_ALWAYS_INLINE bool walk(const NodeStore<W> &nodes, int from, Visit &&visit) {
  IndexStack stack;
  int n = from;
  for (;;) {
    const unsigned enter = visit(n);
    if (enter & kStop) return false;
    if (enter != 0) {
      BVH_INVARIANT(!nodes.node(n).is_leaf(), "walk(): a leaf's visit enters children");
      const Node<W> &node = nodes.node(n);
      n = enter_children(stack, node, enter);
      prefetch_stacked(nodes, node, enter, n);
      continue;
    }
    if (stack.empty()) return true;
    n = stack.pop();
  }
}

/// walk()'s visit result that enters every child of `node`.
template <int W> inline unsigned all_children(const Node<W> &node) { return (1u << node.num_children) - 1; }

/// Calls f(n) on every node under `from` in pre-order (children left to
/// right).
template <int W, class F> void for_each_preorder(const NodeStore<W> &nodes, int from, F &&f) {
  if (from < 0) return;
  walk(nodes, from, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    f(n);
    return all_children(nodes.node(n));
  });
}

/// Calls f(n) on every node under `from`, children (left to right) before
/// their parent. Without a stack: it climbs by the nodes' parent links,
/// so it allocates nothing and never throws; f may free the node it is
/// given (a freed node's links stay readable until it is reused).
template <int W, class F> void for_each_postorder(const NodeStore<W> &nodes, int from, F &&f) noexcept {
  int n = nodes.leftmost_leaf(from);
  for (;;) {
    if (n == from) {
      f(n);
      return;
    }
    const int parent = nodes.info(n).parent, c = nodes.info(n).child_index;
    f(n);
    if (c + 1 < nodes.node(parent).num_children)
      n = nodes.leftmost_leaf(nodes.node(parent).child(c + 1));
    else
      n = parent;
  }
}

// ===========================================================================
// 3. Leaf store
// ===========================================================================

/// The leaves' shapes: each leaf owns one slot, a contiguous run of shapes.
/// Slot capacities are 1, 2, 4, ..., 8, then 8 steps from each power of
/// two to the next (capacity_of()), so that a slot of more than 4 holds at
/// most one eighth more places than shapes: leaves grow one shape at a
/// time, and with powers of two alone a leaf of 17 shapes would take 32
/// places. There is one pool per capacity (a "class"); a pool stores its
/// slots in fixed blocks, so growing never moves what is stored and there
/// is no allocation per leaf; a bulk build's
/// leaves of one class lie side by side in leaf order. Only a slot's first
/// size() elements are constructed, so T needs no default constructor.
/// Beside each shape the pool keeps its id (the tree's handle for it),
/// moved with it. Slots given back are reused first. Copies are deep.
template <class T> class LeafPool {
public:
  /// A slot: its class (capacity capacity_of(cls)) and its index in that class.
  struct Slot {
    std::uint32_t index = 0;
    std::uint32_t cls = 0;
  };

  /// An empty slot for at least `capacity` (>= 1) shapes.
  Slot allocate(std::size_t capacity) {
    const std::uint32_t cls = class_for(capacity);
    if (!sharing_.to) return allocate_here(cls);
    LaneCache *own = LaneCache::current();
    if (!own || cls >= own->slots.size()) return sharing_.locked(true, [&] { return allocate_here(cls); });
    std::vector<std::uint32_t> &list = own->slots[cls];
    sharing_.refill(list, [&] { return classes_[cls].allocate(); }, chunk_of(cls));
    const Slot s{list.back(), cls};
    list.pop_back();
    return s;
  }
  /// Destroys the slot's shapes and gives the slot back (never throws).
  /// A class none of whose slots is in use any more then gives back its
  /// blocks too (not while threads share the pool, whose lanes may hold
  /// its slots): a leaf grows through the small classes once, while the
  /// tree is young, and each would keep a block for one free slot.
  void release(Slot s) noexcept {
    LaneCache *own = sharing_.to ? LaneCache::current() : nullptr;
    if (own && s.cls < own->slots.size()) {
      Class &c = classes_[s.cls];
      c.clear(s.index);
      sharing_.give_back(own->slots[s.cls], s.index, [&](std::uint32_t i) { c.free_slots.push_back(i); },
                         chunk_of(s.cls));
    } else if (!sharing_.to) {
      Class &c = classes_[s.cls];
      c.release(s.index);
      if (c.free_slots.size() == c.sizes.size()) c.drop();
    } else {
      sharing_.locked(false, [&] { classes_[s.cls].release(s.index); });
    }
  }
  /// The number of classes (a LaneCache's lists of slots).
  std::size_t class_count() const { return classes_.size(); }
  /// The classes reserve_spare(spare, largest) makes, at least.
  static std::size_t classes_for(std::size_t largest) { return std::size_t(class_for(largest)) + 2; }
  /// Every class's shrink_spare().
  void shrink_spare() noexcept {
    for (Class &c : classes_) c.shrink_spare();
  }
  /// Takes back the slots a lane's cache holds, when its lane ends (under
  /// the lock while shared): a lane that has ended keeps nothing, since a
  /// cached slot of every class a leaf grew through, in every lane, is
  /// slack.
  void take_back(std::vector<std::vector<std::uint32_t>> &own) noexcept {
    sharing_.locked(false, [&] {
      for (std::size_t cls = 0; cls < own.size(); ++cls) {
        for (std::uint32_t i : own[cls]) classes_[cls].free_slots.push_back(i); // (never allocates)
        own[cls].clear();
      }
    });
  }
  /// Room for `spare` more slots in every class up to the one of
  /// `largest` shapes (made now if missing), so that allocating them never
  /// moves an array that other threads read.
  void reserve_spare(std::size_t spare, std::size_t largest) {
    const std::uint32_t top = class_for(largest) + 1; // (a full slot of `largest` moves up one)
    classes_.reserve(std::max<std::size_t>(top + 1, 64)); // (never moved while shared)
    while (classes_.size() <= top) classes_.emplace_back(std::uint32_t(classes_.size()));
    for (Class &c : classes_) c.reserve_spare(spare);
  }
  /// Makes allocate() and release() take `shared`'s lock (none: nullptr).
  void share(SharedAlloc *shared) noexcept { sharing_.to = shared; }

  /// The pool's bytes by use: the stored shapes and their ids, the places
  /// that hold neither (room in slots, free slots, unfilled blocks) and the
  /// bookkeeping (slot sizes, free-slot lists, block tables).
  struct Bytes {
    std::size_t shapes = 0, ids = 0, slack = 0, index = 0;
  };
  /// The pool's bytes. O(slots).
  Bytes bytes() const {
    Bytes b;
    b.index = classes_.capacity() * sizeof(Class);
    for (const Class &c : classes_) c.add_bytes(b);
    return b;
  }

  /// The slot's first shape.
  T *data(Slot s) { return classes_[s.cls].data(s.index); }
  const T *data(Slot s) const { return classes_[s.cls].data(s.index); }
  /// The ids of the slot's shapes, in the same order.
  std::uint32_t *ids(Slot s) { return classes_[s.cls].ids(s.index); }
  const std::uint32_t *ids(Slot s) const { return classes_[s.cls].ids(s.index); }
  /// The number of shapes in the slot.
  std::size_t size(Slot s) const { return classes_[s.cls].sizes[s.index]; }

  /// Appends a shape with its id; a full slot first moves to one of the
  /// next class (`s` then names the new slot). Strong: if it throws, the slot
  /// and its shapes are as they were (they move to the larger slot by
  /// std::move_if_noexcept, and the old slot goes only once all are there).
  template <class V> void push_back(Slot &s, V &&shape, std::uint32_t id) {
    if (size(s) == capacity_of(s.cls)) {
      T extra(std::forward<V>(shape)); // (first: `shape` may be one of the slot's)
      const Slot bigger = allocate(capacity_of(s.cls) + 1);
      try {
        classes_[bigger.cls].append_all(bigger.index, data(s), ids(s), size(s));
        classes_[bigger.cls].construct(bigger.index, std::move_if_noexcept(extra), id);
      } catch (...) {
        release(bigger);
        throw;
      }
      release(s);
      s = bigger;
      return;
    }
    classes_[s.cls].construct(s.index, std::forward<V>(shape), id);
  }
  /// Appends `count` shapes moved from take(i) (a T&) with ids id(i) to
  /// slot s, which has room for them; a throw leaves those moved so far.
  template <class Take, class Id> void append(Slot s, std::size_t count, Take &take, Id &id) {
    BVH_INVARIANT(size(s) + count <= capacity_of(s.cls), "appending past a slot's capacity");
    Class &c = classes_[s.cls];
    T *d = c.data(s.index);
    std::uint32_t *ids = c.ids(s.index);
    std::uint32_t &size = c.sizes[s.index];
    for (std::size_t i = 0; i < count; ++i) {
      ::new (static_cast<void *>(d + size)) T(std::move(take(i)));
      ids[size] = id(i);
      ++size;
    }
  }
  /// True when removing a shape shifts the others in place, which cannot
  /// throw; otherwise erase() copies the others to a new slot first.
  static constexpr bool kShiftsInPlace = std::is_nothrow_move_assignable<T>::value;
  /// Removes shape i, keeping the order of the others (`s` may then name a
  /// new slot). Strong.
  void erase(Slot &s, std::size_t i) {
    if constexpr (!kShiftsInPlace) {
      const Slot fresh = copy_without(s, i);
      release(s);
      s = fresh;
    } else {
      T *d = data(s);
      std::uint32_t *id = ids(s);
      const std::size_t n = size(s);
      std::move(d + i + 1, d + n, d + i);
      std::move(id + i + 1, id + n, id + i);
      d[n - 1].~T();
      --classes_[s.cls].sizes[s.index];
    }
  }
  /// A new slot of s's class holding copies of s's shapes but shape i, in
  /// order, with their ids; `s` is untouched. Strong.
  Slot copy_without(Slot s, std::size_t i) {
    const Slot fresh = allocate(capacity_of(s.cls));
    try {
      const T *d = data(s);
      const std::uint32_t *id = ids(s);
      for (std::size_t k = 0, n = size(s); k < n; ++k)
        if (k != i) classes_[fresh.cls].construct(fresh.index, d[k], id[k]);
    } catch (...) {
      release(fresh);
      throw;
    }
    return fresh;
  }

private:
  static constexpr std::size_t kBlockBytes = 32768;

  /// The slots of one capacity.
  class Class {
  public:
    explicit Class(std::uint32_t cls) : capacity_(capacity_of(cls)) {
      // Slots per block: a power of two, so that finding a slot shifts.
      while ((std::size_t(2) << block_shift_) * capacity_ * sizeof(T) <= kBlockBytes) ++block_shift_;
      per_block_ = std::size_t(1) << block_shift_;
    }
    Class(const Class &o)
        : capacity_(o.capacity_), block_shift_(o.block_shift_), per_block_(o.per_block_) {
      free_slots.reserve(o.sizes.size()); // (room for every slot: release() never allocates)
      free_slots = o.free_slots;
      sizes.reserve(o.sizes.size());
      try {
        for (std::uint32_t i = 0; i < o.sizes.size(); ++i) {
          if (i % per_block_ == 0) add_block();
          sizes.push_back(0);
          for (std::uint32_t j = 0; j < o.sizes[i]; ++j) construct(i, o.data(i)[j], o.ids(i)[j]);
        }
      } catch (...) {
        destroy();
        throw;
      }
    }
    Class(Class &&o) noexcept
        : capacity_(o.capacity_), block_shift_(o.block_shift_), per_block_(o.per_block_),
          sizes(std::move(o.sizes)), free_slots(std::move(o.free_slots)), blocks_(std::move(o.blocks_)),
          id_blocks_(std::move(o.id_blocks_)) {
      o.sizes.clear();
      o.free_slots.clear();
      o.blocks_.clear();
      o.id_blocks_.clear();
    }
    Class &operator=(Class o) noexcept { // copy or move, then swap
      std::swap(capacity_, o.capacity_);
      std::swap(block_shift_, o.block_shift_);
      std::swap(per_block_, o.per_block_);
      sizes.swap(o.sizes);
      free_slots.swap(o.free_slots);
      blocks_.swap(o.blocks_);
      id_blocks_.swap(o.id_blocks_);
      return *this;
    }
    ~Class() { destroy(); }

    std::uint32_t allocate() {
      if (!free_slots.empty()) {
        const std::uint32_t i = free_slots.back();
        free_slots.pop_back();
        return i;
      }
      // Strong: room in both lists first, then the block, then the slot.
      const std::uint32_t i = std::uint32_t(sizes.size());
      reserve_for(free_slots, sizes.size() + 1);
      reserve_for(sizes, sizes.size() + 1);
      if (i % per_block_ == 0) add_block();
      sizes.push_back(0);
      return i;
    }
    void reserve_spare(std::size_t spare) {
      reserve_for(sizes, sizes.size() + spare);
      const std::size_t blocks = (sizes.size() + spare) / per_block_ + 1;
      reserve_for(blocks_, blocks);
      reserve_for(id_blocks_, blocks);
    }
    /// Gives back the room reserve_spare() made beyond what is used (the
    /// free slots keep room for every slot). Nothing changes if memory
    /// for the smaller copies runs out.
    void shrink_spare() noexcept {
      try {
        MappedVector<std::uint32_t> free;
        free.reserve(sizes.size());
        free.assign(free_slots.begin(), free_slots.end());
        MappedVector<std::uint32_t> used(sizes.begin(), sizes.end());
        MappedVector<T *> blocks(blocks_.begin(), blocks_.end());
        MappedVector<std::uint32_t *> id_blocks(id_blocks_.begin(), id_blocks_.end());
        free_slots.swap(free);
        sizes.swap(used);
        blocks_.swap(blocks);
        id_blocks_.swap(id_blocks);
      } catch (...) {
      }
    }
    void release(std::uint32_t i) noexcept {
      clear(i);
      free_slots.push_back(i); // (never allocates: allocate() made room)
    }
    /// Gives back every block and list of a class whose slots are all
    /// free: it is then as new.
    void drop() noexcept {
      BVH_INVARIANT(free_slots.size() == sizes.size(), "dropping a class with slots in use");
      destroy();
      MappedVector<std::uint32_t>().swap(sizes);
      MappedVector<std::uint32_t>().swap(free_slots);
      MappedVector<T *>().swap(blocks_);
      MappedVector<std::uint32_t *>().swap(id_blocks_);
    }
    /// Destroys slot i's shapes.
    void clear(std::uint32_t i) noexcept {
      T *d = data(i);
      for (std::uint32_t j = 0; j < sizes[i]; ++j) d[j].~T();
      sizes[i] = 0;
    }
    template <class V> void construct(std::uint32_t i, V &&v, std::uint32_t id) {
      ::new (static_cast<void *>(data(i) + sizes[i])) T(std::forward<V>(v));
      ids(i)[sizes[i]] = id;
      ++sizes[i];
    }
    /// Moves (or copies) n shapes and their ids to the end of slot i;
    /// strong, as construct() one by one.
    void append_all(std::uint32_t i, T *from, const std::uint32_t *from_ids, std::size_t n) {
      if constexpr (std::is_trivially_copyable<T>::value) {
        // (one copy of each array, not a slot lookup per shape)
        std::memcpy(static_cast<void *>(data(i) + sizes[i]), from, n * sizeof(T));
        std::memcpy(ids(i) + sizes[i], from_ids, n * sizeof(std::uint32_t));
        sizes[i] += std::uint32_t(n);
      } else {
        for (std::size_t k = 0; k < n; ++k) construct(i, std::move_if_noexcept(from[k]), from_ids[k]);
      }
    }
    std::uint32_t *ids(std::uint32_t i) {
      return id_blocks_[i >> block_shift_] + std::size_t(i & (per_block_ - 1)) * capacity_;
    }
    const std::uint32_t *ids(std::uint32_t i) const {
      return id_blocks_[i >> block_shift_] + std::size_t(i & (per_block_ - 1)) * capacity_;
    }
    T *data(std::uint32_t i) { return blocks_[i >> block_shift_] + std::size_t(i & (per_block_ - 1)) * capacity_; }
    const T *data(std::uint32_t i) const {
      return blocks_[i >> block_shift_] + std::size_t(i & (per_block_ - 1)) * capacity_;
    }
    void add_bytes(Bytes &b) const {
      std::size_t stored = 0;
      for (std::uint32_t n : sizes) stored += n;
      const std::size_t places = blocks_.size() * per_block_ * capacity_;
      b.shapes += stored * sizeof(T);
      b.ids += stored * sizeof(std::uint32_t);
      b.slack += (places - stored) * (sizeof(T) + sizeof(std::uint32_t));
      b.index += (sizes.capacity() + free_slots.capacity()) * sizeof(std::uint32_t) +
                 (blocks_.capacity() + id_blocks_.capacity()) * sizeof(void *);
    }

  private:
    std::size_t capacity_;
    std::uint32_t block_shift_ = 0;
    std::size_t per_block_;

  public:
    MappedVector<std::uint32_t> sizes; ///< shapes in each slot (0 when free)
    MappedVector<std::uint32_t> free_slots; ///< slots given back

  private:
    MappedVector<T *> blocks_;
    MappedVector<std::uint32_t *> id_blocks_; // parallel to blocks_
    void add_block() {
      const std::size_t n = per_block_ * capacity_;
      reserve_for(blocks_, blocks_.size() + 1);
      reserve_for(id_blocks_, id_blocks_.size() + 1);
      T *b = std::allocator<T>().allocate(n);
      const bool first = blocks_.empty(); // (see populate)
      if (!first) populate(b, n * sizeof(T));
      try {
        id_blocks_.push_back(std::allocator<std::uint32_t>().allocate(n));
        if (!first) populate(id_blocks_.back(), n * sizeof(std::uint32_t));
      } catch (...) {
        std::allocator<T>().deallocate(b, n);
        throw;
      }
      blocks_.push_back(b);
    }
    void destroy() {
      for (std::uint32_t i = 0; i < sizes.size(); ++i)
        for (std::uint32_t j = 0; j < sizes[i]; ++j) data(i)[j].~T();
      for (T *b : blocks_) std::allocator<T>().deallocate(b, per_block_ * capacity_);
      for (std::uint32_t *b : id_blocks_) std::allocator<std::uint32_t>().deallocate(b, per_block_ * capacity_);
      blocks_.clear();
      id_blocks_.clear();
      sizes.clear();
    }
  };

  /// The slots of class cls a lane takes at a time, and keeps when it
  /// gives slots back: fewer of the larger, since what a lane keeps is
  /// slack.
  static std::size_t chunk_of(std::uint32_t cls) {
    return LaneCache::kChunk >> std::min<std::size_t>(log2_floor(capacity_of(cls)), 5);
  }
  /// The highest bit of n >= 1.
  static std::size_t log2_floor(std::size_t n) {
    std::size_t b = 0;
    while (n >> (b + 1)) ++b;
    return b;
  }

public:
  /// Steps a class's capacity takes from one power of two to the next
  /// (kSteps = 2^kStepBits).
  static constexpr std::uint32_t kStepBits = 3;
  static constexpr std::size_t kSteps = std::size_t(1) << kStepBits;
  /// The capacity of class cls: 1, 2, 4, then every count up to kSteps,
  /// then kSteps steps from each power of two to the next (at 8 steps: 1,
  /// 2, 4, 5, ..., 8, 9, ..., 16, 18, ..., 32, 36, ...). There is no slot
  /// of 3: the course's leaves, of at most 4, then move as often as they
  /// did in powers of two.
  static constexpr std::size_t capacity_of(std::uint32_t cls) {
    return cls < 2 ? cls + 1 : cls + 1 < kSteps ? cls + 2 : (kSteps + (cls + 2) % kSteps) << ((cls + 2) / kSteps - 1);
  }
  /// The smallest class holding `capacity` shapes.
  static std::uint32_t class_for(std::size_t capacity) {
    if (capacity <= 2) return capacity == 2 ? 1 : 0;
    if (capacity <= kSteps) return capacity == 3 ? 2 : std::uint32_t(capacity - 2);
    const std::size_t x = capacity - 1;
    std::uint32_t shift = std::uint32_t(log2_floor(x)) - kStepBits;
    std::size_t steps = (x >> shift) + 1; // the fewest steps of 2^shift holding `capacity`
    if (steps == 2 * kSteps) steps = kSteps, ++shift;
    return std::uint32_t(kSteps * (shift + 1) - 2 + (steps - kSteps));
  }

private:
  Slot allocate_here(std::uint32_t cls) {
    while (classes_.size() <= cls) classes_.emplace_back(std::uint32_t(classes_.size()));
    return Slot{classes_[cls].allocate(), cls};
  }

  /// The classes, copied one by one: libc++ 14 (as on this machine) leaks a
  /// vector's buffer when an element's copy throws inside the vector's copy
  /// constructor (Class's copy allocates), and copies must not leak.
  struct Classes : std::vector<Class> {
    Classes() = default;
    Classes(const Classes &o) : std::vector<Class>() {
      this->reserve(o.size());
      for (const Class &c : o) this->push_back(c);
    }
    Classes(Classes &&) noexcept = default;
    Classes &operator=(const Classes &o) {
      Classes copy(o);
      this->swap(copy);
      return *this;
    }
    Classes &operator=(Classes &&) noexcept = default;
    ~Classes() = default;
  };
  Classes classes_;
  Sharing sharing_;
};

/// The shapes of every leaf, their ids and the handle table, kept in step:
/// each operation on a leaf's shapes also rewrites the leaf's record (its
/// LeafSlot, in its Node) and, once the table is built, the location of
/// every id it moves, so no caller fixes either. A handle's id names one
/// stored shape; find() gives its leaf and position.
///
/// The table (id -> leaf, position) is built on the first lookup of an id,
/// by one pass over the leaves, and kept in step from then on until every
/// id is forgotten (clear(), or the last shape given back): a tree whose
/// handles are never looked up never holds it. Ids are given out the same
/// way with or without it: from a count, the ids given back first (the
/// last given back first).
template <class T> class LeafStore {
public:
  /// Where the shape of one id is.
  struct Loc {
    std::int32_t leaf = -1; ///< -1: the id is free
    std::uint32_t index = 0;
  };

  /// The shapes of `leaf` (a leaf that owns a slot).
  template <int W> BVH_ALWAYS_INLINE Span<const T> shapes(const Node<W> &leaf) const {
    const LeafSlot s = leaf.leaf();
    BVH_INVARIANT(leaf.is_leaf() && s.has_slot(), "shapes of a node that owns none");
    return {pool_.data(pool_slot(s)), s.count};
  }
  template <int W> BVH_ALWAYS_INLINE Span<T> shapes(Node<W> &leaf) {
    const LeafSlot s = leaf.leaf();
    BVH_INVARIANT(leaf.is_leaf() && s.has_slot(), "shapes of a node that owns none");
    return {pool_.data(pool_slot(s)), s.count};
  }
  /// The ids of `leaf`'s shapes, in the same order.
  template <int W> const std::uint32_t *ids(const Node<W> &leaf) const { return pool_.ids(pool_slot(leaf.leaf())); }
  /// The number of shapes in the slot itself (validate compares it with
  /// the leaf's record).
  template <int W> std::size_t slot_size(const Node<W> &leaf) const { return pool_.size(pool_slot(leaf.leaf())); }
  /// Asks the cache for where leaf `leaf` (with a slot) appends its next
  /// shape and id.
  template <int W> void prefetch_end(const Node<W> &leaf) const {
    const typename LeafPool<T>::Slot s = pool_slot(leaf.leaf());
    const std::size_t n = pool_.size(s);
    prefetch_lines(pool_.data(s) + n, sizeof(T));
    prefetch_lines(pool_.ids(s) + n, sizeof(std::uint32_t));
  }

  LeafStore() = default;
  /// Deep copy, with the table if it is built.
  LeafStore(const LeafStore &o)
      : pool_(o.pool_), free_ids_(o.free_ids_), id_count_(o.id_count_), generations_(o.generations_),
        fresh_generation_(o.fresh_generation_), constructed_generation_(o.constructed_generation_) {
    if (o.located()) {
      loc_ = o.loc_;
      located_.store(true, std::memory_order_relaxed);
    }
  }
  /// Takes o's contents; o is left with none.
  LeafStore(LeafStore &&o) noexcept { swap(o); }
  LeafStore &operator=(const LeafStore &o) {
    LeafStore copy(o);
    swap(copy);
    return *this;
  }
  LeafStore &operator=(LeafStore &&o) noexcept {
    LeafStore taken(std::move(o));
    swap(taken);
    return *this;
  }

  /// Appends `shape` with `id` to leaf n (node `leaf`), giving the leaf a
  /// slot first if it has none; the id is located there. Strong.
  template <int W, class V> BVH_ALWAYS_INLINE void push(Node<W> &leaf, int n, V &&shape, std::uint32_t id) {
    const LeafSlot had = leaf.leaf();
    typename LeafPool<T>::Slot s;
    if (had.has_slot()) {
      s = pool_slot(had);
      pool_.push_back(s, std::forward<V>(shape), id);
    } else {
      s = pool_.allocate(1);
      try {
        pool_.push_back(s, std::forward<V>(shape), id);
      } catch (...) {
        pool_.release(s);
        throw;
      }
    }
    if (built()) loc_[id] = Loc{n, std::uint32_t(pool_.size(s) - 1)};
    leaf.set_leaf(record(s));
  }
  /// Gives leaf n (node `leaf`, owning no slot) `count` shapes, moved from
  /// take(i) (a T&) with ids id(i), in one slot of their size.
  template <int W, class Take, class Id> void fill(Node<W> &leaf, int n, std::size_t count, Take &&take, Id &&id) {
    BVH_INVARIANT(!leaf.leaf().has_slot(), "filling a leaf that owns a slot");
    typename LeafPool<T>::Slot s = pool_.allocate(count);
    leaf.set_leaf(record(s));
    leaf.set_coded(0);
    pool_.append(s, count, take, id);
    if (built())
      for (std::size_t i = 0; i < count; ++i) loc_[id(i)] = Loc{n, std::uint32_t(i)};
    leaf.set_leaf(record(s));
  }
  /// Removes shape i of `leaf`, keeping the others' order (and their ids
  /// located); returns its id, which stays taken. Strong.
  template <int W> std::uint32_t erase(Node<W> &leaf, std::size_t i) {
    typename LeafPool<T>::Slot s = pool_slot(leaf.leaf());
    const std::uint32_t id = pool_.ids(s)[i];
    pool_.erase(s, i);
    leaf.set_leaf(record(s));
    leaf.uncode(int(i));
    if (built()) {
      const std::uint32_t *ids = pool_.ids(s);
      for (std::size_t k = i, n = pool_.size(s); k < n; ++k) loc_[ids[k]].index = std::uint32_t(k);
    }
    return id;
  }
  /// A leaf's slot set aside by erase_keeping(), for restore() or
  /// discard().
  using Kept = typename LeafPool<T>::Slot;
  /// erase(), but leaf n's old slot, with every shape, is kept aside
  /// (returned): restore() undoes the erase, discard() confirms it. Strong.
  template <int W> Kept erase_keeping(Node<W> &leaf, std::size_t i) {
    const Kept old = pool_slot(leaf.leaf());
    const typename LeafPool<T>::Slot fresh = pool_.copy_without(old, i);
    leaf.set_leaf(record(fresh));
    leaf.uncode(int(i));
    if (built()) {
      const std::uint32_t *ids = pool_.ids(fresh);
      for (std::size_t k = i, n = pool_.size(fresh); k < n; ++k) loc_[ids[k]].index = std::uint32_t(k);
    }
    return old;
  }
  /// Leaf n (node `leaf`) gets its kept slot back; the one it had goes.
  template <int W> void restore(Node<W> &leaf, int n, Kept old) noexcept {
    release(leaf);
    leaf.set_leaf(record(old));
    leaf.set_coded(0);
    relocate(leaf, n);
  }
  /// Destroys a kept slot's shapes and gives it back.
  void discard(Kept old) noexcept { pool_.release(old); }
  /// Appends copies of `node`'s shapes, with their ids, to `out` (nothing
  /// for an inner node or a leaf without slot); `node` is untouched.
  template <int W> void copy_out(const Node<W> &node, std::vector<Tagged<T>> &out) const {
    if (!node.is_leaf() || !node.leaf().has_slot()) return;
    const Span<const T> v = shapes(node);
    const std::uint32_t *ids = this->ids(node);
    for (std::size_t i = 0; i < v.size(); ++i) out.push_back(Tagged<T>{v[i], ids[i]});
  }
  /// Locates every id of leaf n (node `leaf`) there again (after a build
  /// that had located them elsewhere was given up).
  template <int W> void relocate(const Node<W> &leaf, int n) noexcept {
    if (!built() || !leaf.is_leaf() || !leaf.leaf().has_slot()) return;
    const std::uint32_t *ids = this->ids(leaf);
    for (std::uint32_t i = 0, k = leaf.leaf().count; i < k; ++i) loc_[ids[i]] = Loc{n, i};
  }
  /// Destroys `node`'s shapes and gives its slot back (nothing for an inner
  /// node or a leaf without slot).
  template <int W> void release(Node<W> &node) noexcept {
    if (!node.is_leaf() || !node.leaf().has_slot()) return;
    pool_.release(pool_slot(node.leaf()));
    node.set_leaf(LeafSlot{});
    node.set_coded(0);
  }

  /// A free id (one given back first), not yet located. Strong. Until
  /// settle_ids(), every id it gives may be given back by free_id()
  /// without allocating: the free ids keep room for them all (section 8b
  /// takes many before inserting any).
  std::uint32_t new_id() {
    if (!free_ids_.empty()) {
      const std::uint32_t id = free_ids_.back();
      free_ids_.pop_back();
      ++pending_;
      return id;
    }
    if (id_count_ == std::size_t(std::numeric_limits<std::uint32_t>::max()))
      throw std::length_error("BVH::insert: more shapes than 32-bit handles can name");
    reserve_for(free_ids_, std::min(id_count_ + 1, free_ids_.size() + pending_ + 1));
    if (!generations_.empty()) reserve_for(generations_, id_count_ + 1);
    if (built()) loc_.push_back(Loc{});
    if (!generations_.empty()) generations_.push_back(fresh_generation_); // (room reserved: never throws)
    ++pending_;
    return std::uint32_t(id_count_++);
  }
  /// Undoes new_id() (of an insert that failed): the id is free again, as
  /// it was. `reused`: new_id() took it from the free ids (they were not
  /// empty), else it was the last one.
  void unnew_id(std::uint32_t id, bool reused) noexcept {
    if (built()) loc_[id].leaf = -1;
    if (reused) {
      free_ids_.push_back(id); // (never allocates: new_id() took it from there)
    } else {
      if (built()) loc_.pop_back();
      if (!generations_.empty()) generations_.pop_back();
      --id_count_;
    }
  }
  /// The ids handed out since the last call are all stored or given back:
  /// the room new_id() kept for them goes (returned to the allocator when
  /// it is much more than the free ids need). Never throws.
  void settle_ids() noexcept {
    pending_ = 0;
    if (free_ids_.capacity() > 2 * free_ids_.size() + 64) {
      try {
        free_ids_.shrink_to_fit();
      } catch (...) { // (then the room stays)
      }
    }
  }
  /// Ids 0 .. n - 1 taken, for construct() (the store holds no id).
  void take_first_ids(std::size_t n) {
    BVH_INVARIANT(id_count_ == 0 && generations_.empty(), "construct() over ids in use");
    if (built()) loc_.resize(n);
    id_count_ = n;
    constructed_generation_ = fresh_generation_;
  }
  /// Room for giving one more id back (before an erase, whose
  /// free_erased_id() must not allocate), with every id's generation.
  /// Strong.
  void reserve_id_back() {
    reserve_for(free_ids_, std::min(id_count_, free_ids_.size() + pending_ + 1));
    if (generations_.empty()) generations_.assign(id_count_, fresh_generation_);
  }
  /// Gives `id` back (room for it was made: new_id(), reserve_id_back());
  /// `none_stored`: the tree is empty, so every id is forgotten. Only for
  /// an id no handle was given for (an insert that failed, or one
  /// insert_disjoint took but did not use): its generation stays.
  void free_id(std::uint32_t id, bool none_stored) noexcept {
    if (none_stored) {
      forget_ids();
      return;
    }
    if (built()) loc_[id].leaf = -1;
    BVH_INVARIANT(free_ids_.size() < free_ids_.capacity(), "an id given back without room for it");
    free_ids_.push_back(id);
  }
  /// free_id() for the id of an erased shape (after reserve_id_back()):
  /// its generation goes up, so that its handles are stale from now on,
  /// also once a later insert reuses the id.
  void free_erased_id(std::uint32_t id, bool none_stored) noexcept {
    if (!none_stored) {
      BVH_INVARIANT(id < generations_.size(), "an id given back without its generation");
      ++generations_[id];
    }
    free_id(id, none_stored);
  }
  /// The generation of `id` (one in use or free): a handle carries its
  /// id's generation when given, and names no shape once they differ.
  std::uint32_t generation(std::uint32_t id) const noexcept {
    return generations_.empty() ? fresh_generation_ : generations_[id];
  }
  /// The generation construct() gave ids 0 .. n - 1 (take_first_ids).
  std::uint32_t constructed_generation() const noexcept { return constructed_generation_; }
  /// True when `id` with `generation` names a stored shape (find()).
  template <int W>
  bool find(const NodeStore<W> &nodes, int root, std::uint32_t id, std::uint32_t generation, Loc *at) const noexcept {
    if (id >= id_count_ || this->generation(id) != generation) return false;
    return find(nodes, root, id, at);
  }

  /// True once the table is built: then contains() and locate() answer.
  /// (validate checks the table only then.)
  bool located() const noexcept { return located_.load(std::memory_order_acquire); }
  /// Builds the table if it is not built, by one pass over the leaves of
  /// the tree at `root` in `nodes` (what this store's records describe).
  /// Const, and safe while other threads call it or read the tree: the
  /// first builds under a lock, the others wait for it; the table is
  /// published only when complete. False when memory for it ran out (it
  /// stays unbuilt). Never throws.
  template <int W> bool locate_all(const NodeStore<W> &nodes, int root) const noexcept {
    if (located()) return true;
    try {
      std::lock_guard<std::mutex> hold(build_lock_);
      if (located_.load(std::memory_order_relaxed)) return true;
      std::vector<Loc> loc(id_count_);
      for (int n = root < 0 ? -1 : nodes.leftmost_leaf(root); n >= 0; n = nodes.next_leaf(n)) {
        const Node<W> &leaf = nodes.node(n);
        if (!leaf.leaf().has_slot()) continue;
        const std::uint32_t *ids = this->ids(leaf);
        for (std::uint32_t i = 0, k = leaf.leaf().count; i < k; ++i) loc[ids[i]] = Loc{n, i};
      }
      loc_.swap(loc);
      located_.store(true, std::memory_order_release);
      return true;
    } catch (...) { // (std::bad_alloc, or the lock's std::system_error)
      return false;
    }
  }
  /// True when `id` names a stored shape, whose place then goes to *at
  /// (when given). By the table, built first if need be (locate_all, so
  /// also safe on several threads at once); without memory for it, by a
  /// walk over the leaves. Never throws.
  template <int W> bool find(const NodeStore<W> &nodes, int root, std::uint32_t id, Loc *at) const noexcept {
    if (root < 0) return false; // (an empty tree builds no table)
    if (locate_all(nodes, root)) {
      if (!contains(id)) return false;
      if (at) *at = loc_[id];
      return true;
    }
    for (int n = nodes.leftmost_leaf(root); n >= 0; n = nodes.next_leaf(n)) {
      const Node<W> &leaf = nodes.node(n);
      if (!leaf.leaf().has_slot()) continue;
      const std::uint32_t *ids = this->ids(leaf);
      for (std::uint32_t i = 0, k = leaf.leaf().count; i < k; ++i)
        if (ids[i] == id) {
          if (at) *at = Loc{n, i};
          return true;
        }
    }
    return false;
  }
  /// By the table (located()): true when `id` names a stored shape.
  bool contains(std::uint32_t id) const { return id < loc_.size() && loc_[id].leaf >= 0; }
  /// By the table (located()): where id's shape is (contains(id)).
  const Loc &locate(std::uint32_t id) const { return loc_[id]; }
  /// Ids in use or free.
  std::size_t id_count() const { return id_count_; }
  /// Ids in the table (located(): id_count()).
  std::size_t table_size() const { return loc_.size(); }
  /// The ids given back.
  const std::vector<std::uint32_t> &free_ids() const { return free_ids_; }
  /// Bytes of the table (0 while it is not built) and of the free ids.
  std::size_t table_bytes() const noexcept { return located() ? loc_.capacity() * sizeof(Loc) : 0; }
  std::size_t free_id_bytes() const noexcept {
    return (free_ids_.capacity() + generations_.capacity()) * sizeof(std::uint32_t);
  }
  /// The generation by id (empty while every id's is the same).
  const std::vector<std::uint32_t> &generations() const { return generations_; }
  /// The pool's bytes (LeafPool::bytes).
  typename LeafPool<T>::Bytes pool_bytes() const { return pool_.bytes(); }

  /// Destroys every shape; the ids stay taken (update() of the last shape
  /// inserts it again under its id).
  void clear_shapes() noexcept { pool_ = LeafPool<T>(); }
  /// Destroys every shape and forgets every id.
  void clear() noexcept {
    clear_shapes();
    forget_ids();
  }
  /// The pool's reserve_spare() and share() (LeafPool).
  void reserve_spare(std::size_t spare, std::size_t largest) { pool_.reserve_spare(spare, largest); }
  void share(SharedAlloc *shared) noexcept { pool_.share(shared); }
  std::size_t class_count() const { return pool_.class_count(); }
  void shrink_spare() noexcept { pool_.shrink_spare(); }
  void take_back(std::vector<std::vector<std::uint32_t>> &own) noexcept { pool_.take_back(own); }

  void swap(LeafStore &o) noexcept {
    std::swap(pool_, o.pool_);
    loc_.swap(o.loc_);
    free_ids_.swap(o.free_ids_);
    std::swap(id_count_, o.id_count_);
    std::swap(pending_, o.pending_);
    generations_.swap(o.generations_);
    std::swap(fresh_generation_, o.fresh_generation_);
    std::swap(constructed_generation_, o.constructed_generation_);
    const bool was = built();
    located_.store(o.built(), std::memory_order_relaxed);
    o.located_.store(was, std::memory_order_relaxed);
  }

private:
  static typename LeafPool<T>::Slot pool_slot(const LeafSlot &s) { return {s.index, s.cls}; }
  LeafSlot record(const typename LeafPool<T>::Slot &s) const {
    return LeafSlot{s.index, s.cls, std::uint32_t(pool_.size(s))};
  }
  /// The table is built (for the changes, which no reader runs beside).
  bool built() const noexcept { return located_.load(std::memory_order_relaxed); }
  /// Every id forgotten, the table unbuilt, their memory given back. The
  /// ids given from now on start at a generation above every one given
  /// before, so that no old handle names a shape stored later.
  void forget_ids() noexcept {
    if (id_count_ != 0) {
      std::uint32_t newest = fresh_generation_;
      for (std::uint32_t g : generations_) newest = std::max(newest, g);
      fresh_generation_ = newest + 1;
    }
    std::vector<std::uint32_t>().swap(generations_);
    std::vector<Loc>().swap(loc_);
    std::vector<std::uint32_t>().swap(free_ids_);
    id_count_ = 0;
    pending_ = 0;
    located_.store(false, std::memory_order_relaxed);
  }

  LeafPool<T> pool_;
  std::vector<std::uint32_t> free_ids_; // ids given back, reused first
  std::size_t id_count_ = 0;            // ids in use or free: 0 .. id_count_ - 1
  std::size_t pending_ = 0;             // ids new_id() gave since settle_ids()
  // Each id's generation (what its handles carry), raised when its shape is
  // erased; empty until an id is given back after an erase (every id's is
  // then fresh_generation_), so a tree never erased from keeps none.
  std::vector<std::uint32_t> generations_;
  std::uint32_t fresh_generation_ = 0;       // of the ids not given back since all were last forgotten
  std::uint32_t constructed_generation_ = 0; // of the ids construct() gave last
  // The table: by id, where its shape is; built by a const lookup, hence
  // mutable, and published by located_ (release) once complete.
  mutable std::vector<Loc> loc_;
  mutable std::atomic<bool> located_{false};
  mutable std::mutex build_lock_;
};

// ===========================================================================
// 4. Tree core
// ===========================================================================

/// How construct() and the splits and rebuilds of insert() cut a node.
enum class BuildRule {
  course, ///< the course's rule (CourseRule): thirds by count along the longer side
  sah     ///< binned surface area heuristic (SahRule): the cut of least area cost
};

template <class T, class Tr> struct BuildScratch;

/// The sizes from which a tree takes the paths that pay only when it is
/// large (BVH::Tuning, set_tuning()). They change speed only, never an
/// answer: each path gives what the plain one gives.
struct Tuning {
  /// Stored shapes from which collision(), collisions() and query(shape)
  /// decide disks from their leaves' codes (kDisksFromCodes; default:
  /// BVH_DISK_CODES_MIN_BYTES of shapes). 0: at every size.
  std::size_t disk_codes_min_shapes;
  /// Stored shapes from which insert_disjoint's step 1 interleaves its
  /// searches, and one thread decides in batches (default
  /// BVH_DISJOINT_INTERLEAVE_MIN).
  std::size_t disjoint_interleave_min;
  /// Stored shapes from which insert_disjoint's step 4 inserts on every
  /// thread, the lanes (default BVH_DISJOINT_LANES_MIN).
  std::size_t disjoint_lanes_min;
  /// A batch's survivors from which insert_disjoint's step 2 sweeps on
  /// every thread (default BVH_DISJOINT_SWEEP_MIN).
  std::size_t disjoint_sweep_min;
};
/// A tree of T's Tuning until set_tuning() (section 8b, after the macros
/// that set it).
template <class T> Tuning default_tuning() noexcept;

/// The state every operation shares: the nodes, the leaves' shapes and
/// ids, the root, and the parameters of the tree. Sections 5 to 8 work on
/// it; the facade BVH<T> owns one. Each part keeps its own invariants
/// (NodeStore the two copies of a box, LeafStore the records and ids); the
/// operations here keep what spans them: a node is reset or freed only
/// with its slot given back, and a node's box is its subtree's.
template <class T, class Tr, int W> struct Core {
  static constexpr int kWidth = W; ///< children per inner node, at most
  Tr traits; ///< how shapes are read (shape_traits<T> or the user's adaptor)
  NodeStore<W> nodes;
  LeafStore<T> leaves;
  int root = -1;         ///< -1: empty
  std::size_t size = 0;  ///< shapes stored
  int split_threshold;   ///< at least 1
  int depth_limit;       ///< 0: unlimited
  BuildRule rule = BuildRule::course;
  unsigned build_threads = 0; ///< 0: hardware concurrency
  double margin = 0;          ///< leaves' boxes are their shapes' grown by this
  Tuning tuning = default_tuning<T>(); ///< sizes from which the paths for large trees run
  Scratch<BuildScratch<T, Tr>> scratch;

  Core(Tr traits_, int split_threshold_, int depth_limit_)
      : traits(std::move(traits_)), split_threshold(split_threshold_), depth_limit(depth_limit_) {}

  /// Exchanges everything but the scratch memory.
  void swap(Core &o) noexcept {
    std::swap(traits, o.traits);
    nodes.swap(o.nodes);
    leaves.swap(o.leaves);
    std::swap(root, o.root);
    std::swap(size, o.size);
    std::swap(split_threshold, o.split_threshold);
    std::swap(depth_limit, o.depth_limit);
    std::swap(rule, o.rule);
    std::swap(build_threads, o.build_threads);
    std::swap(margin, o.margin);
    std::swap(tuning, o.tuning);
  }

  /// Drops every node and shape but keeps the ids.
  void clear_nodes() noexcept {
    nodes.clear();
    leaves.clear_shapes();
    root = -1;
    size = 0;
  }
  /// Drops everything stored; the parameters stay.
  void clear() noexcept {
    clear_nodes();
    leaves.clear();
  }

  /// Where the shape of `id` (a stored one) is: LeafStore::find, which
  /// builds the handle table on first use. Never throws.
  typename LeafStore<T>::Loc locate(std::uint32_t id) const noexcept {
    typename LeafStore<T>::Loc at;
    leaves.find(nodes, root, id, &at);
    return at;
  }

  /// True when a node at `depth` may split.
  bool may_split_at(int depth) const { return depth_limit == 0 || depth < depth_limit; }
  /// True when a node of `count` shapes at `depth` becomes a leaf.
  /// How cuts by count share a node's shapes at this width.
  CountCut<W> counts() const { return CountCut<W>{std::size_t(split_threshold), depth_limit}; }
  bool is_leaf_size(std::size_t count, int depth) const {
    return count <= std::size_t(split_threshold) || !may_split_at(depth);
  }

  /// A fresh leaf at `depth`, child `child_index` of `parent`.
  int new_node(int depth, int parent, int child_index) {
    const int n = nodes.allocate();
    nodes.reset(n, depth, parent, child_index);
    return n;
  }
  /// Gives node n's slot back and puts it on the free list.
  void free_node(int n) noexcept {
    leaves.release(nodes.node(n));
    nodes.release(n);
  }

  /// A leaf's box for shapes whose box is `tight`: grown by the margin.
  Box fat(const Box &tight) const { return margin > 0 ? tight.grown(margin) : tight; }
  /// Node n's box recomputed from its shapes (leaf) or its children's boxes.
  Box fitted_box(int n) const {
    Box box;
    const Node<W> &node = nodes.node(n);
    if (node.is_leaf()) {
      for (const T &s : leaves.shapes(node)) box.extend(box_of(traits, s));
      return fat(box);
    }
    for (int c = 0; c < node.num_children; ++c)
      if (nodes.info(node.child(c)).count != 0) box.extend(nodes.box(node.child(c)));
    return box;
  }
  /// Refits the boxes from node n up, stopping where a box is unchanged
  /// or at `stop` (not refitted; -1: above the root).
  void refit_up(int n, int stop = -1) noexcept {
    for (; n != stop; n = nodes.info(n).parent) {
      const Box box = fitted_box(n);
      if (box == nodes.box(n)) return;
      nodes.set_box(n, box);
    }
  }
};

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
#ifdef BVH_COUNT_SUMMARIES
      ++bvh_summaries_redone;
#endif
      make_summary(core, n);
    }
  }
}

// ===========================================================================
// 5. Builders
// ===========================================================================
//
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

/// Bins per axis of the SAH build.
constexpr int kSahBins = 16;

/// The alternative build rule, binned SAH for a ternary tree. Leaves are
/// where the course's rule makes them. Otherwise the shapes' centres are
/// binned into kSahBins slots along each axis, and the node is cut at the
/// two bin boundaries, on the axis, that minimise the surface area
/// heuristic sum over the 3 groups of (box area x shape count), the
/// quantity the statistics print; every group must be non-empty. When the
/// centres fill fewer than 3 bins on both axes (clusters, duplicates), it
/// falls back to the course's cut into thirds by count on the longer side.
/// O(n) per level plus O(kSahBins^2) per node: O(n log n) for a balanced
/// result. At widths other than 3 the node is cut by binary SAH cuts: the
/// largest group that would still split is cut in two where the binned
/// cost is least, until there are W groups or none would split.
template <class T, class Tr, int W> class SahRule : public ShapesAsItems<T, Tr> {
public:
  using State = typename ShapesAsItems<T, Tr>::State;
  SahRule(const Tr &traits, std::vector<Tagged<T>> &shapes, CountCut<W> counts)
      : ShapesAsItems<T, Tr>(traits, shapes), counts_(counts) {}
  void cut(const BuildTask<State> &t, int depth, const Box &box, std::size_t cut[W + 1], State *) {
    if constexpr (W == 3) {
      cut_in_three(t, box, cut);
    } else {
      // At the depth limit's last level the children are leaves of any size.
      const bool last = counts_.depth_limit > 0 && depth + 1 >= counts_.depth_limit;
      const std::size_t most = last ? 1 : counts_.split_threshold;
      std::size_t bounds[W + 1] = {t.begin, t.end};
      int groups = 1;
      while (groups < W) {
        int widest = 0;
        for (int g = 1; g < groups; ++g)
          if (bounds[g + 1] - bounds[g] > bounds[widest + 1] - bounds[widest]) widest = g;
        if (bounds[widest + 1] - bounds[widest] <= most) break;
        const std::size_t mid = cut_in_two(bounds[widest], bounds[widest + 1]);
        for (int g = groups; g > widest; --g) bounds[g + 1] = bounds[g];
        bounds[widest + 1] = mid;
        ++groups;
      }
      for (int g = 0; g <= W; ++g) cut[g] = g <= groups ? bounds[g] : t.end;
    }
  }

private:
  CountCut<W> counts_;
  /// Cuts [begin, end) (at least 2 shapes) in two non-empty parts by the
  /// binned SAH over both axes, or at the median of the longer side of the
  /// centres when no bin boundary separates them; returns where.
  std::size_t cut_in_two(std::size_t begin, std::size_t end) {
    std::vector<Tagged<T>> &v = this->v_;
    const Box centres = centres_of(begin, end);
    double best_cost = std::numeric_limits<double>::infinity();
    int best_axis = -1, best_i = 0;
    for (int axis = 0; axis < 2; ++axis) {
      double lo, extent;
      if (!span(centres, axis, lo, extent)) continue;
      Box bin_box[kSahBins];
      std::size_t bin_count[kSahBins] = {};
      fill_bins(begin, end, axis, lo, extent, bin_box, bin_count);
      Box suffix[kSahBins + 1];
      std::size_t suffix_n[kSahBins + 1] = {};
      for (int b = kSahBins - 1; b >= 0; --b) {
        suffix[b] = suffix[b + 1];
        suffix[b].extend(bin_box[b]);
        suffix_n[b] = suffix_n[b + 1] + bin_count[b];
      }
      Box prefix;
      std::size_t prefix_n = 0;
      for (int i = 1; i < kSahBins; ++i) {
        prefix.extend(bin_box[i - 1]);
        prefix_n += bin_count[i - 1];
        if (prefix_n == 0 || suffix_n[i] == 0) continue;
        const double cost = prefix.area() * double(prefix_n) + suffix[i].area() * double(suffix_n[i]);
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_i = i;
        }
      }
    }
    const auto first = v.begin() + long(begin), last = v.begin() + long(end);
    if (best_axis >= 0) {
      double lo, extent;
      span(centres, best_axis, lo, extent);
      const auto mid =
          std::partition(first, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_i; });
      return std::size_t(mid - v.begin());
    }
    const std::size_t mid = begin + (end - begin + 1) / 2;
    std::nth_element(first, v.begin() + long(mid), last, centre_less(centres.dx() >= centres.dy() ? 0 : 1));
    return mid;
  }
  /// The ternary cut (W = 3).
  void cut_in_three(const BuildTask<State> &t, const Box &box, std::size_t cut[4]) {
    std::vector<Tagged<T>> &v = this->v_; // (a dependent base: named through this)
    const Box centres = centres_of(t.begin, t.end);
    int best_axis = -1, best_i = 0, best_j = 0;
    best_cut(t, centres, best_axis, best_i, best_j);
    const auto first = v.begin() + long(t.begin), last = v.begin() + long(t.end);
    if (best_axis >= 0) {
      double lo, extent;
      span(centres, best_axis, lo, extent);
      const auto mid1 =
          std::partition(first, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_i; });
      const auto mid2 =
          std::partition(mid1, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_j; });
      cut[0] = t.begin;
      cut[1] = std::size_t(mid1 - v.begin());
      cut[2] = std::size_t(mid2 - v.begin());
      cut[3] = t.end;
    } else {
      // Fallback: thirds by count along the longer side of the box.
      const auto less = centre_less(box.dx() >= box.dy() ? 0 : 1);
      cut_in_thirds(t.begin, t.end, cut);
      std::nth_element(first, v.begin() + long(cut[1]), last, less);
      std::nth_element(v.begin() + long(cut[1]), v.begin() + long(cut[2]), last, less);
    }
  }

  /// The (axis, first cut, second cut) of least SAH cost over both axes:
  /// groups are bins [0, i), [i, j), [j, kSahBins); axis -1 when no cut
  /// leaves every group non-empty.
  void best_cut(const BuildTask<State> &t, const Box &centres, int &best_axis, int &best_i, int &best_j) const {
    double best_cost = std::numeric_limits<double>::infinity();
    for (int axis = 0; axis < 2; ++axis) {
      double lo, extent;
      if (!span(centres, axis, lo, extent)) continue;
      Box bin_box[kSahBins];
      std::size_t bin_count[kSahBins] = {};
      fill_bins(t.begin, t.end, axis, lo, extent, bin_box, bin_count);
      Box prefix[kSahBins + 1], suffix[kSahBins + 1];
      std::size_t prefix_n[kSahBins + 1] = {}, suffix_n[kSahBins + 1] = {};
      for (int b = 0; b < kSahBins; ++b) {
        prefix[b + 1] = prefix[b];
        prefix[b + 1].extend(bin_box[b]);
        prefix_n[b + 1] = prefix_n[b] + bin_count[b];
      }
      for (int b = kSahBins - 1; b >= 0; --b) {
        suffix[b] = suffix[b + 1];
        suffix[b].extend(bin_box[b]);
        suffix_n[b] = suffix_n[b + 1] + bin_count[b];
      }
      for (int i = 1; i < kSahBins - 1; ++i) {
        if (prefix_n[i] == 0) continue;
        Box middle;
        std::size_t middle_n = 0;
        for (int j = i + 1; j < kSahBins; ++j) {
          middle.extend(bin_box[j - 1]);
          middle_n += bin_count[j - 1];
          if (middle_n == 0 || suffix_n[j] == 0) continue;
          const double cost = prefix[i].area() * double(prefix_n[i]) + middle.area() * double(middle_n) +
                              suffix[j].area() * double(suffix_n[j]);
          if (cost < best_cost) {
            best_cost = cost;
            best_axis = axis;
            best_i = i;
            best_j = j;
          }
        }
      }
    }
  }
  /// The box of the centres of shapes [begin, end).
  Box centres_of(std::size_t begin, std::size_t end) const {
    Box centres;
    for (std::size_t i = begin; i < end; ++i) centres.extend(Box::at(this->traits_.center(this->v_[i].shape)));
    return centres;
  }
  /// The centres' range on `axis` (its low end and extent); false when it
  /// is empty (every centre on one line across the axis).
  static bool span(const Box &centres, int axis, double &lo, double &extent) {
    lo = axis ? centres.y0 : centres.x0;
    extent = (axis ? centres.y1 : centres.x1) - lo;
    return extent > 0;
  }
  /// Bins shapes [begin, end) by centre on `axis`: each bin's box and count.
  void fill_bins(std::size_t begin, std::size_t end, int axis, double lo, double extent, Box bin_box[kSahBins],
                 std::size_t bin_count[kSahBins]) const {
    for (std::size_t i = begin; i < end; ++i) {
      const int b = bin_of(this->v_[i], axis, lo, extent);
      bin_box[b].extend(box_of(this->traits_, this->v_[i].shape));
      ++bin_count[b];
    }
  }
  /// The order of shapes by centre on `axis` (the fallback cut's).
  auto centre_less(int axis) const {
    const Tr &traits = this->traits_;
    return [axis, &traits](const Tagged<T> &a, const Tagged<T> &b) {
      return axis ? traits.center(a.shape).y < traits.center(b.shape).y
                  : traits.center(a.shape).x < traits.center(b.shape).x;
    };
  }
  int bin_of(const Tagged<T> &s, int axis, double lo, double extent) const {
    const double c = axis ? this->traits_.center(s.shape).y : this->traits_.center(s.shape).x;
    return std::min(kSahBins - 1, int(double(kSahBins) * (c - lo) / extent));
  }
};

/// Thirds (CountCut's groups at other widths) in the order given, without
/// sorting: where leaf order must survive (erase). Shapes that come out
/// of a subtree in leaf order are already spatially grouped.
template <class T, class Tr, int W> class InOrderRule : public ShapesAsItems<T, Tr> {
public:
  using State = typename ShapesAsItems<T, Tr>::State;
  InOrderRule(const Tr &traits, std::vector<Tagged<T>> &shapes, CountCut<W> counts)
      : ShapesAsItems<T, Tr>(traits, shapes), counts_(counts) {}
  void cut(const BuildTask<State> &t, int depth, const Box &, std::size_t cut[W + 1], State *) {
    counts_.cut(t.begin, t.end, depth, cut);
  }

private:
  CountCut<W> counts_;
};

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

/// The memory a course build reuses from one build to the next.
template <class T, class Tr> struct BuildScratch {
  Items<T, Tr> items;
  std::vector<BuildTask<CourseState>> tasks;
};

/// `items` (a BuildScratch's), filled with shape(i) for i < n (input
/// position = i).
template <class T, class Tr, int W, class Shape>
Items<T, Tr> &fill_items(const Core<T, Tr, W> &core, Items<T, Tr> &items, std::size_t n, Shape &&shape) {
  // (clear and append, not resize: T need not be default-constructible)
  items.clear();
  items.reserve(n);
  for (std::size_t i = 0; i < n; ++i) items.push_back(make_item(core.traits, shape(i), std::uint32_t(i)));
  return items;
}

/// Gives leaf n (owning no slot) the rule's items [begin, end), moved.
template <class T, class Tr, int W, class Rule> void fill_leaf(Core<T, Tr, W> &core, int n, Rule &rule, std::size_t begin, std::size_t end) {
  core.leaves.fill(
      core.nodes.node(n), n, end - begin, [&](std::size_t i) -> T & { return rule.shape(begin + i); },
      [&](std::size_t i) { return rule.id(begin + i); });
  make_summary(core, n);
}

/// The shared loop: builds every task of `tasks` (and what they spawn) by
/// `rule`. Tasks whose node is at depth `defer_depth` are not built but
/// moved to `*deferred` (construct's parallel part builds them). With a
/// `layout`, children go where it says and leaves get their shapes later
/// (gather_leaves); without, nodes come from new_node().
template <class T, class Tr, int W, class Rule>
void build_top_down(Core<T, Tr, W> &core, std::vector<BuildTask<typename Rule::State>> &tasks, Rule &rule,
                    const typename std::common_type<Layout<W>>::type *layout, int defer_depth = -1,
                    std::vector<BuildTask<typename Rule::State>> *deferred = nullptr) {
  using Task = BuildTask<typename Rule::State>;
  NodeStore<W> &nodes = core.nodes;
  while (!tasks.empty()) {
    const Task t = tasks.back();
    tasks.pop_back();
    const int depth = nodes.info(t.node).depth;
    if (deferred && depth == defer_depth) {
      deferred->push_back(t);
      continue;
    }
    BVH_INVARIANT(nodes.node(t.node).is_leaf() && !nodes.node(t.node).leaf().has_slot(),
                  "a build starts at a leaf that owns no slot");
    Box box;
    for (std::size_t i = t.begin; i < t.end; ++i) box.extend(rule.box(i));
    box = core.fat(box); // (a grown union is the union of the grown boxes)
    const std::size_t n = t.end - t.begin;
    nodes.set_box(t.node, box);
    nodes.info(t.node).count = n;
    if (core.is_leaf_size(n, depth)) {
      rule.order_leaf(t);
      // A laid-out build (construct) gathers every leaf's shapes at the
      // end, in one pass, with no thread touching the pool.
      if (!layout) fill_leaf(core, t.node, rule, t.begin, t.end);
      continue;
    }
    std::size_t cut[W + 1];
    typename Rule::State state[W];
    rule.cut(t, depth, box, cut, state);
    Task child[W];
    int children = 0;
    int groups = 0;
    for (int g = 0; g < W; ++g) groups += cut[g + 1] > cut[g];
    int grandchildren = t.block + groups; // laid out: where the next child's children go
    for (int g = 0; g < W; ++g) {
      if (cut[g + 1] == cut[g]) continue;
      int c, block = -1;
      if (layout) {
        c = t.block + children;
        nodes.reset(c, depth + 1, t.node, children);
        block = grandchildren;
        grandchildren += int(layout->nodes(cut[g + 1] - cut[g], depth + 1)) - 1;
      } else {
        c = core.new_node(depth + 1, t.node, children);
      }
      nodes.node(t.node).set_child(children, c);
      child[children++] = Task{c, cut[g], cut[g + 1], block, state[g]};
      // (child by child: a build given up midway frees every node it made)
      nodes.node(t.node).num_children = children;
    }
    for (int c = children - 1; c >= 0; --c) tasks.push_back(child[c]); // built left to right
  }
}

/// How build_at() cuts.
enum class Cut {
  by_rule, ///< the tree's build rule
  in_order ///< InOrderRule: iteration order survives (erase(iterator)'s repairs)
};

/// build_at()'s course-rule build by the shared loop.
template <class T, class Tr, int W> void build_by_course_rule(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes) {
  // Threads inserting into disjoint subtrees at once (section 8b) cannot
  // share the tree's scratch memory.
  BuildScratch<T, Tr> own;
  BuildScratch<T, Tr> &scratch = core.nodes.shared() ? own : core.scratch.value;
  CourseRule<T, Tr, W> rule(core.traits,
                            fill_items(core, scratch.items, shapes.size(), [&](std::size_t i) -> const T & { return shapes[i].shape; }),
                            &shapes, core.counts());
  std::vector<BuildTask<CourseState>> &tasks = scratch.tasks;
  tasks.assign(1, {at, 0, shapes.size(), -1, CourseRule<T, Tr, W>::root_state()});
  build_top_down(core, tasks, rule, nullptr);
}

/// The course rule's build at widths other than 3 where it makes one node
/// over two leaves, as a leaf's overflow split does (build_at): the tree
/// the shared loop makes, node for node and shape for shape, without its
/// general machinery (the items' copies of the shapes, the task stack, a
/// box of every shape computed three times). The two groups come from the
/// same selection, on keys that hold a centre and an input position where
/// the loop's items hold the shape: the same comparisons, so the same
/// order. False, having done nothing, when the build is not of that form.
/// If it throws, the nodes and slots it made hang under `at`.
template <class T, class Tr, int W> bool split_in_two(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes) {
  NodeStore<W> &nodes = core.nodes;
  const std::size_t m = shapes.size();
  const int depth = nodes.info(at).depth;
  if (m < 2 || core.is_leaf_size(m, depth)) return false;
  std::size_t size[W];
  core.counts().sizes(m, depth, size);
  bool two_groups = true;
  if constexpr (W > 2) two_groups = size[2] == 0;
  if (!two_groups || !core.is_leaf_size(size[0], depth + 1) || !core.is_leaf_size(size[1], depth + 1)) return false;
  struct SplitKey {
    XY c;
    std::uint32_t index;
    const XY &centre() const { return c; }
  };
  InlineVector<SplitKey, 72> keys;
  InlineVector<Sides, 72> boxes;
  keys.reserve(m);
  boxes.reserve(m);
  Box all;
  for (std::size_t i = 0; i < m; ++i) {
    keys.push_back(SplitKey{XY::of(core.traits.center(shapes[i].shape)), std::uint32_t(i)});
    const Box b = box_of(core.traits, shapes[i].shape);
    boxes.push_back(Sides::of(b));
    all.extend(b);
  }
  all = core.fat(all);
  nodes.set_box(at, all);
  nodes.info(at).count = m;
  if (all.dx() >= all.dy())
    select_nth(keys.begin(), keys.begin() + long(size[0]), keys.end(), Order<0, true>());
  else
    select_nth(keys.begin(), keys.begin() + long(size[0]), keys.end(), Order<1, true>());
  int child[2];
  for (int g = 0; g < 2; ++g) {
    child[g] = core.new_node(depth + 1, at, g);
    nodes.node(at).set_child(g, child[g]);
    nodes.node(at).num_children = g + 1;
  }
  for (int g = 0; g < 2; ++g) {
    const SplitKey *first = keys.begin() + (g == 0 ? 0 : long(size[0]));
    Box group;
    for (std::size_t i = 0; i < size[g]; ++i) group.extend(boxes[first[i].index].box());
    nodes.set_box(child[g], core.fat(group));
    nodes.info(child[g]).count = size[g];
    core.leaves.fill(
        nodes.node(child[g]), child[g], size[g], [&](std::size_t i) -> T & { return shapes[first[i].index].shape; },
        [&](std::size_t i) { return shapes[first[i].index].id; });
    make_summary(core, child[g], [&](std::size_t i) { return boxes[first[i].index].box(); });
  }
  return true;
}

/// The one entry for building a subtree: at leaf `at` (owning no slot),
/// from `shapes` (reordered). If it throws, the nodes and slots it made
/// hang under `at` (free_subtree gives them back).
template <class T, class Tr, int W> void build_at(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes, Cut how) {
  if (how == Cut::in_order) {
    InOrderRule<T, Tr, W> rule(core.traits, shapes, core.counts());
    std::vector<BuildTask<typename InOrderRule<T, Tr, W>::State>> tasks{
        {at, 0, shapes.size(), -1, InOrderRule<T, Tr, W>::root_state()}};
    build_top_down(core, tasks, rule, nullptr);
  } else if (core.rule == BuildRule::sah) {
    SahRule<T, Tr, W> rule(core.traits, shapes, core.counts());
    std::vector<BuildTask<typename SahRule<T, Tr, W>::State>> tasks{{at, 0, shapes.size(), -1, SahRule<T, Tr, W>::root_state()}};
    build_top_down(core, tasks, rule, nullptr);
  } else {
    if constexpr (W != kCourseWidth) {
      if (split_in_two(core, at, shapes)) return;
    }
    build_by_course_rule(core, at, shapes);
  }
}

/// Gives back every node and slot of the subtree at `at` (its shapes are
/// destroyed). Never throws.
template <class T, class Tr, int W> void free_subtree(Core<T, Tr, W> &core, int at) noexcept {
  for_each_postorder(core.nodes, at, [&](int n) { core.free_node(n); });
}

/// Locates every id of the subtree at `at` in its leaves again. Never throws.
template <class T, class Tr, int W> void relocate_subtree(Core<T, Tr, W> &core, int at) noexcept {
  for_each_postorder(core.nodes, at, [&](int n) { core.leaves.relocate(core.nodes.node(n), n); });
}

/// Puts node `by` where node `at` is (root, or its parent's child): `at`'s
/// subtree is then detached, its ids still located in `by`'s. `by` must
/// have at's parent, child index and depth, and the parent's float copy
/// of the box must be by's (build_beside leaves it so). Never throws.
template <class T, class Tr, int W> void link_in(Core<T, Tr, W> &core, int at, int by) noexcept {
  const int parent = core.nodes.info(at).parent;
  if (parent < 0)
    core.root = by;
  else
    core.nodes.node(parent).set_child(core.nodes.info(at).child_index, by);
}

/// Builds, from `shapes` (reordered), a subtree to take the place of the
/// one at `at`, which stays as it is: the new subtree's root has at's
/// parent, child index and depth but is not linked in (link_in does that),
/// and the ids of `shapes` are located in it. Strong: if it throws,
/// everything it made is given back and the tree is as it was.
template <class T, class Tr, int W> int build_beside(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes, Cut how) {
  const Info in = core.nodes.info(at);
  const int fresh = core.new_node(in.depth, in.parent, in.child_index);
  try {
    build_at(core, fresh, shapes, how);
  } catch (...) {
    free_subtree(core, fresh);
    relocate_subtree(core, at);
    core.nodes.set_box(at, core.nodes.box(at)); // (the parent's float copy is at's again)
    throw;
  }
  return fresh;
}

/// True when leaf `at`'s split `fresh` (made by build_beside) may instead
/// give its children to at's parent (splice): at is not the root, fresh's
/// children are all leaves, and the parent has room for them.
template <class T, class Tr, int W> bool can_splice(const Core<T, Tr, W> &core, int at, int fresh) {
  const int parent = core.nodes.info(at).parent;
  const Node<W> &f = core.nodes.node(fresh);
  if (parent < 0 || f.is_leaf() || core.nodes.node(parent).num_children - 1 + f.num_children > W) return false;
  for (int c = 0; c < f.num_children; ++c)
    if (!core.nodes.node(f.child(c)).is_leaf()) return false;
  return true;
}

/// The R-tree's overflow split, for widths other than the course's: leaf
/// `at` gives way to the leaves of its split `fresh` (can_splice) as
/// siblings in its parent, in its place and order, so that a leaf that
/// overflows fills its parent instead of growing a level of nearly empty
/// nodes. Returns the first of those leaves. Never throws.
template <class T, class Tr, int W> int splice(Core<T, Tr, W> &core, int at, int fresh) noexcept {
  NodeStore<W> &nodes = core.nodes;
  const Info in = nodes.info(at);
  const int parent = in.parent, first = in.child_index;
  Node<W> &p = nodes.node(parent);
  const int k = nodes.node(fresh).num_children, m = p.num_children;
  const bool changed = nodes.box(fresh) != nodes.box(at);
  for (int c = m - 1; c > first; --c) { // the later siblings move right
    const int x = p.child(c);
    p.set_child(c + k - 1, x);
    nodes.info(x).child_index = c + k - 1;
    nodes.set_box(x, nodes.box(x));
  }
  for (int j = 0; j < k; ++j) {
    const int y = nodes.node(fresh).child(j);
    p.set_child(first + j, y);
    Info &yi = nodes.info(y);
    yi.parent = parent;
    yi.child_index = first + j;
    yi.depth = in.depth;
    nodes.set_box(y, nodes.box(y));
  }
  p.num_children = m + k - 1;
  const int leaf = p.child(first);
  core.free_node(at);
  core.free_node(fresh); // (an inner node: its children are the parent's now)
  BVH_INVARIANT(!changed || !nodes.shared(), "a refit above a subtree that threads share");
  if (changed) core.refit_up(parent);
  return leaf;
}

/// The subtree at `at` becomes `fresh` (made by build_beside): linked in,
/// the old one freed, the boxes above refitted if the box changed (with a
/// margin, leaves that update() left larger come out fitted again). Never
/// throws.
template <class T, class Tr, int W> void replace_by(Core<T, Tr, W> &core, int at, int fresh) noexcept {
  const bool changed = core.nodes.box(fresh) != core.nodes.box(at);
  link_in(core, at, fresh);
  if (core.nodes.node(at).is_leaf()) // (a split's)
    core.free_node(at);
  else
    free_subtree(core, at);
  const int parent = core.nodes.info(fresh).parent;
  BVH_INVARIANT(!changed || !core.nodes.shared(), "a refit above a subtree that threads share");
  if (changed && parent >= 0) core.refit_up(parent);
}

/// Copies the shapes of the subtree at `at`, in leaf order, but shape
/// `skip_index` of leaf `skip_leaf` (none when -1).
template <class T, class Tr, int W>
std::vector<Tagged<T>> copy_subtree(const Core<T, Tr, W> &core, int at, int skip_leaf = -1, std::size_t skip_index = 0) {
  std::vector<Tagged<T>> shapes;
  shapes.reserve(core.nodes.info(at).count);
  walk(core.nodes, at, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      if (n != skip_leaf) {
        core.leaves.copy_out(node, shapes);
      } else {
        const Span<const T> v = core.leaves.shapes(node);
        const std::uint32_t *ids = core.leaves.ids(node);
        for (std::size_t i = 0; i < v.size(); ++i)
          if (i != skip_index) shapes.push_back(Tagged<T>{v[i], ids[i]});
      }
    }
    return all_children(node);
  });
  return shapes;
}

/// Rebuilds the subtree at `at` from copies of its own shapes, taken in
/// leaf order; returns the new subtree's root. Strong: the old subtree
/// goes only once the new one is complete.
template <class T, class Tr, int W> int rebuild(Core<T, Tr, W> &core, int at, Cut how) {
  std::vector<Tagged<T>> shapes = copy_subtree(core, at);
  const int fresh = build_beside(core, at, shapes, how);
  replace_by(core, at, fresh);
  return fresh;
}

/// The most threads any call starts. A larger request gets this many: the
/// batch sizes scale with the thread count (64 * threads and more), which
/// past this would overflow or reserve more threads than a system has.
constexpr unsigned kMaxThreads = 1024;

/// The threads a build may use: `wanted`, or with 0 the hardware's, at
/// most kMaxThreads.
inline unsigned threads_for(unsigned wanted) {
  if (wanted != 0) return std::min(wanted, kMaxThreads);
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : std::min(hw, kMaxThreads);
}

/// construct()'s course build. The rule's tree shape depends on counts
/// alone, so every node gets its index in advance (Layout): in pre-order,
/// each node's children adjacent, each subtree contiguous; and subtrees far
/// enough down are independent, so threads can build them at once. Last,
/// the leaves, in pre-order, take consecutive ranges of the items.
template <class T, class Tr, int W> void construct_by_course_rule(Core<T, Tr, W> &core, const std::vector<T> &elements) {
  const Layout<W> layout(core.size, core.split_threshold, core.depth_limit);
  core.nodes.resize(layout.nodes(core.size, 0));
  core.root = 0;
  core.nodes.reset(0, 0, -1, 0);
  const unsigned threads = threads_for(core.build_threads);
  CourseRule<T, Tr, W> rule(core.traits, fill_items(core, core.scratch.value.items, elements.size(), [&](std::size_t i) -> const T & { return elements[i]; }),
                            nullptr, core.counts(), threads);
  using Task = BuildTask<CourseState>;
  std::vector<Task> tasks{{0, 0, core.size, 1, CourseRule<T, Tr, W>::root_state()}};
  if (threads <= 1 || core.size < kParallelMin) {
    build_top_down(core, tasks, rule, &layout);
  } else {
    int defer_depth = 1; // enough subtrees to keep every thread busy
    for (std::size_t subtrees = W; subtrees < 4 * std::size_t(threads); subtrees *= W) ++defer_depth;
    std::vector<Task> deferred;
    build_top_down(core, tasks, rule, &layout, defer_depth, &deferred);
    rule.set_threads(1); // (the subtrees are built on every thread already)
    parallel_for(deferred.size(), threads, [&](std::size_t i) {
      std::vector<Task> one{deferred[i]};
      build_top_down(core, one, rule, &layout);
    });
  }
  std::size_t next = 0;
  for_each_preorder(core.nodes, core.root, [&](int n) {
    if (!core.nodes.node(n).is_leaf()) return;
    const std::size_t count = core.nodes.info(n).count;
    fill_leaf(core, n, rule, next, next + count);
    next += count;
  });
  Items<T, Tr>().swap(core.scratch.value.items);
}

/// Replaces the contents with `elements` (elements[i] gets the id i), built
/// by the tree's rule. If it throws, the tree is left empty.
template <class T, class Tr, int W> void construct(Core<T, Tr, W> &core, const std::vector<T> &elements) {
  core.clear();
  if (elements.empty()) return;
  if (elements.size() > std::size_t(std::numeric_limits<std::uint32_t>::max()))
    throw std::length_error("BVH::construct: more shapes than 32-bit handles can name");
  try {
    core.size = elements.size();
    core.leaves.take_first_ids(core.size);
    if (core.rule == BuildRule::course) {
      construct_by_course_rule(core, elements);
      return;
    }
    std::vector<Tagged<T>> tagged;
    tagged.reserve(core.size);
    for (std::size_t i = 0; i < core.size; ++i) tagged.push_back(Tagged<T>{elements[i], std::uint32_t(i)});
    core.root = core.new_node(0, -1, 0);
    build_at(core, core.root, tagged, Cut::by_rule);
  } catch (...) {
    core.clear();
    throw;
  }
}

// ===========================================================================
// 6. Changes: the insertion strategy, erase, update, margins
// ===========================================================================

/// choose_child's pick among its first n children: least growth, ties to
/// the smaller area, then the first. (Its callers have made NaNs
/// infinite.) Branch-free: which child wins is data, and mispredicts cost
/// more than the selects.
template <class F> inline int least_growth(int n, const F *growth, const F *area) {
  int best = 0;
  F best_growth = growth[0], best_area = area[0];
  for (int c = 1; c < n; ++c) {
    const bool better = growth[c] < best_growth || (growth[c] == best_growth && area[c] < best_area);
    best = better ? c : best;
    best_growth = better ? growth[c] : best_growth;
    best_area = better ? area[c] : best_area;
  }
  return best;
}

#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
/// Bit i set for each lane i (of 4 * G) equal to the least of `v`
/// (none when every lane is NaN).
template <int G> BVH_ALWAYS_INLINE unsigned lanes_at_min(const __m128 *v) {
  __m128 m = v[0];
  for (int g = 1; g < G; ++g) m = _mm_min_ps(m, v[g]);
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(2, 3, 0, 1)));
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(1, 0, 3, 2)));
  unsigned bits = 0;
  for (int g = 0; g < G; ++g) bits |= unsigned(_mm_movemask_ps(_mm_cmpeq_ps(v[g], m))) << (4 * g);
  return bits;
}
#endif

/// The insertion strategy, part 1: the child of inner node n whose box
/// grows least in area when it takes `box`; ties go to the smaller child,
/// then the first. Boxes are the children's float boxes (rounded outwards)
/// kept in the parent, so the choice reads one cache line; areas are
/// computed in double from those floats.
template <int W> BVH_ALWAYS_INLINE int choose_child(const Node<W> &node, const Box &box) {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  if constexpr (W % 4 == 0) {
    // Widths 4 and 8: four children a pass in float. A near tie may then
    // go the other way than in double; either child is a valid choice,
    // and these widths promise no particular tree (the course's, width 3,
    // takes the double path below).
    // The pick is a reduction in registers, not a loop of compares: which
    // child wins is data, and the loop's branches mispredicted. A NaN
    // growth or area (a box with infinite or NaN sides) never wins unless
    // every child's is NaN; then the first child takes the shape.
    const __m128 bx0 = _mm_set1_ps(float(box.x0)), by0 = _mm_set1_ps(float(box.y0));
    const __m128 bx1 = _mm_set1_ps(float(box.x1)), by1 = _mm_set1_ps(float(box.y1));
    const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
    __m128 growth[W / 4], area[W / 4];
    for (int g = 0; g < W; g += 4) {
      const __m128 x0 = _mm_loadu_ps(node.lo_x + g), y0 = _mm_loadu_ps(node.lo_y + g);
      const __m128 x1 = _mm_loadu_ps(node.hi_x + g), y1 = _mm_loadu_ps(node.hi_y + g);
      const __m128 a = _mm_mul_ps(_mm_sub_ps(x1, x0), _mm_sub_ps(y1, y0));
      const __m128 grown = _mm_mul_ps(_mm_sub_ps(_mm_max_ps(bx1, x1), _mm_min_ps(bx0, x0)),
                                      _mm_sub_ps(_mm_max_ps(by1, y1), _mm_min_ps(by0, y0)));
      // Lanes past the last child (and NaNs: _mm_min_ps(x, inf) is inf
      // for a NaN x) lose.
      const __m128 live = _mm_castsi128_ps(
          _mm_cmplt_epi32(_mm_setr_epi32(g, g + 1, g + 2, g + 3), _mm_set1_epi32(node.num_children)));
      growth[g / 4] = _mm_or_ps(_mm_and_ps(live, _mm_min_ps(_mm_sub_ps(grown, a), inf)), _mm_andnot_ps(live, inf));
      area[g / 4] = _mm_or_ps(_mm_and_ps(live, _mm_min_ps(a, inf)), _mm_andnot_ps(live, inf));
    }
    const unsigned least = lanes_at_min<W / 4>(growth);
    if ((least & (least - 1)) == 0) return node.child(least ? lowest_bit(least) : 0);
    for (int g = 0; g < W / 4; ++g) { // a tie: the smaller area among the least growths
      const __m128 tied = _mm_castsi128_ps(_mm_setr_epi32(-int(least >> (4 * g) & 1u), -int(least >> (4 * g + 1) & 1u),
                                                          -int(least >> (4 * g + 2) & 1u), -int(least >> (4 * g + 3) & 1u)));
      area[g] = _mm_or_ps(_mm_and_ps(tied, area[g]), _mm_andnot_ps(tied, inf));
    }
    const unsigned smallest = lanes_at_min<W / 4>(area) & least;
    return node.child(lowest_bit(smallest ? smallest : least));
  }
#endif
  double growth[W + W % 2], area[W + W % 2]; // (even: the passes below take two)
  // A NaN growth or area counts as infinite, as in the float pick above.
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  // Two children a pass, in double: the same operations as the scalar
  // path, so the same choice. _mm_max_pd(b, x) is std::max(x, b) and
  // _mm_min_pd(b, x) is std::min(x, b), NaNs included; _mm_min_pd(v, inf)
  // is v, or inf for a NaN v. At odd widths the last pass reads one float
  // past the row, inside the node; its lane is never chosen (c <
  // num_children below).
  const __m128d bx0 = _mm_set1_pd(box.x0), by0 = _mm_set1_pd(box.y0), bx1 = _mm_set1_pd(box.x1), by1 = _mm_set1_pd(box.y1);
  const __m128d inf = _mm_set1_pd(std::numeric_limits<double>::infinity());
  for (int g = 0; g < W; g += 2) {
    const __m128d x0 = two_floats(node.lo_x + g), y0 = two_floats(node.lo_y + g);
    const __m128d x1 = two_floats(node.hi_x + g), y1 = two_floats(node.hi_y + g);
    const __m128d a = _mm_mul_pd(_mm_sub_pd(x1, x0), _mm_sub_pd(y1, y0));
    const __m128d grown = _mm_mul_pd(_mm_sub_pd(_mm_max_pd(bx1, x1), _mm_min_pd(bx0, x0)),
                                     _mm_sub_pd(_mm_max_pd(by1, y1), _mm_min_pd(by0, y0)));
    _mm_storeu_pd(area + g, _mm_min_pd(a, inf));
    _mm_storeu_pd(growth + g, _mm_min_pd(_mm_sub_pd(grown, a), inf));
  }
#else
  const double inf = std::numeric_limits<double>::infinity();
  for (int c = 0; c < W; ++c) {
    const double x0 = node.lo_x[c], y0 = node.lo_y[c], x1 = node.hi_x[c], y1 = node.hi_y[c];
    const double a = (x1 - x0) * (y1 - y0);
    const double g = (std::max(x1, box.x1) - std::min(x0, box.x0)) * (std::max(y1, box.y1) - std::min(y0, box.y0)) - a;
    area[c] = a == a ? a : inf;
    growth[c] = g == g ? g : inf;
  }
#endif
  return node.child(least_growth(node.num_children, growth, area));
}

/// A child holding more than this share of its parent's shapes makes
/// the parent lopsided (a balanced node gives each child 1 / kWidth).
constexpr double kLopsided = 0.6;
/// True when a child of `heaviest` shapes makes its parent of `count`
/// lopsided.
inline bool lopsided(std::size_t heaviest, std::size_t count) { return double(heaviest) > kLopsided * double(count); }
/// Subtrees smaller than this are never rebuilt for balance: their
/// imbalance costs less than the rebuild.
template <class T, class Tr, int W> std::size_t min_rebuild(const Core<T, Tr, W> &core) {
  return std::max<std::size_t>(16, 3 * (std::size_t(core.split_threshold) + 1));
}

/// The insertion strategy, part 2, and erase's balance: scapegoat-style
/// partial rebuilds. Least-growth descent alone grows worse trees than the
/// build rule and, under sorted input, a spine as deep as n / k. After each
/// change, the highest node on the path from `a` up to the root (of at
/// least min_rebuild() shapes) that is lopsided is rebuilt by the build
/// rule. A node is lopsided when its child on the path (insert: the one the
/// shape went down; `below` starts as a's) or, with `any_child` (erase,
/// where any child may have shrunk), its largest child holds more than
/// kLopsided of its shapes. A rebuilt subtree of m shapes is balanced by
/// count and needs Omega(m) changes to tip again, so rebuilds cost O(log n)
/// amortised per change per level, and every level shrinks the count by at
/// least 1 / kLopsided: depth O(log n) for any order of changes. Returns -1
/// when no node is lopsided. The walk ends below `stop` (-1: at the root).
template <class T, class Tr, int W> int find_scapegoat(const Core<T, Tr, W> &core, int a, int below, bool any_child, int stop = -1) {
  const NodeStore<W> &nodes = core.nodes;
  const std::size_t smallest = min_rebuild(core);
  int scapegoat = -1;
  for (; a != stop; below = a, a = nodes.info(a).parent) {
    const std::size_t count = nodes.info(a).count;
    if (count < smallest) continue;
    std::size_t heaviest = 0;
    if (any_child) {
      const Node<W> &node = nodes.node(a);
      for (int c = 0; c < node.num_children; ++c) heaviest = std::max<std::size_t>(heaviest, nodes.info(node.child(c)).count);
    } else {
      heaviest = nodes.info(below).count; // (a is below's parent: an inner node)
    }
    if (lopsided(heaviest, count)) scapegoat = a; // the last found is the highest
  }
  return scapegoat;
}

/// The rebalance after a change that has succeeded: rebuilds the highest
/// lopsided node above `from` (find_scapegoat) if there is one. A rebuild
/// is strong and only improves the balance, so if it throws the subtree
/// simply stays as it was (the next change finds it again) and the change
/// is not undone: the exception is not passed on.
template <class T, class Tr, int W> void rebalance(Core<T, Tr, W> &core, int scapegoat, Cut how) noexcept {
  if (scapegoat < 0) return;
  try {
    rebuild(core, scapegoat, how);
  } catch (...) {
  }
}

/// One step of an insertion's descent at node n: the shape counted and
/// `box` added there; at an inner node, the lopsided test of the step
/// from `prev` (find_scapegoat's answer so far in `above`) and n becomes
/// the child to go on to by least growth (choose_child); at a leaf,
/// `leaf_box` gets its box before (with a margin it may exceed its
/// shapes'). Returns true at a leaf. insert_pipelined's step; insert_below
/// keeps the same loop written out, which GCC compiles shorter
/// for the course's tree than a loop over this function.
template <int W>
BVH_ALWAYS_INLINE bool descend_step(NodeStore<W> &nodes, int &n, int &prev, int &above, std::size_t &prev_count,
                                    Box &leaf_box, const Box &box, std::size_t smallest) {
  const std::size_t count = ++nodes.info(n).count;
  if (nodes.node(n).is_leaf()) {
    leaf_box = nodes.box(n);
    nodes.extend_box(n, box);
    return true;
  }
  if (above < 0 && prev >= 0 && prev_count >= smallest && lopsided(count, prev_count)) above = prev;
  nodes.extend_box(n, box);
  prev = n;
  prev_count = count;
  n = choose_child(nodes.node(n), box);
  return false;
}

/// Undoes a descent's steps from node `last` (the last it stepped at) up
/// to, not including, `stop`: the counts, the leaf's box (when `leaf_box`,
/// last being the leaf) and the boxes above refitted. Never throws.
template <class T, class Tr, int W>
void undo_descent(Core<T, Tr, W> &core, int last, int stop, const Box *leaf_box) noexcept {
  NodeStore<W> &nodes = core.nodes;
  for (int m = last; m != stop; m = nodes.info(m).parent) --nodes.info(m).count;
  if (leaf_box) {
    nodes.set_box(last, *leaf_box);
    if (nodes.info(last).parent != stop) core.refit_up(nodes.info(last).parent, stop);
  } else if (last != stop) {
    core.refit_up(last, stop);
  }
}

/// insert_below()'s second half: `shape` (its own box `own`, not grown
/// by the margin: the leaf's summary codes it; its id `id`) goes into
/// leaf n, whose count and box the descent from `top` has already raised
/// (its box was `leaf_box`), which splits by the build rule
/// when it then holds more than split_threshold shapes above depth_limit.
/// Returns the node the shape went to. Strong: if it throws, the counts
/// and boxes from `top` down are undone.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_at_leaf(Core<T, Tr, W> &core, int top, int n, const Box &leaf_box, const Box &own, const T &shape,
                                     std::uint32_t id) {
  NodeStore<W> &nodes = core.nodes;
  try {
    if (!core.is_leaf_size(nodes.info(n).count, nodes.info(n).depth)) {
      // The leaf splits: copies of its shapes and the new one go straight
      // to the build (pushing first could move the slot to a larger class
      // for nothing).
      std::vector<Tagged<T>> shapes;
      shapes.reserve(nodes.info(n).count);
      core.leaves.copy_out(nodes.node(n), shapes);
      shapes.push_back(Tagged<T>{shape, id});
      const int fresh = build_beside(core, n, shapes, Cut::by_rule);
      if (W != kCourseWidth && n != top && can_splice(core, n, fresh)) {
        n = splice(core, n, fresh);
      } else {
        replace_by(core, n, fresh);
        n = fresh;
      }
    } else {
      core.leaves.push(nodes.node(n), n, shape, id);
      extend_summary(core, n, own);
    }
  } catch (...) {
    undo_descent(core, n, nodes.info(top).parent, &leaf_box);
    throw;
  }
  return n;
}

/// The descent of insert_unbalanced() from node `top` down: by least area
/// growth (choose_child), adding the shape's own box `own` grown by the
/// margin to every box and the shape to every count on the way, then
/// adding the shape to the leaf reached (insert_at_leaf). Returns the node the shape went to
/// (the leaf, or the subtree its split made); nothing above `top` is read
/// or written (section 8b runs it on several subtrees at once). Strong: if
/// it throws, the counts and boxes from `top` down are undone (a split is
/// built beside the leaf, which goes only once the new subtree is
/// complete).
/// `*lopsided_above` gets find_scapegoat()'s answer for the path from
/// `top` down to the leaf's parent, read on the way down (the counts above
/// the leaf are final there): insert_scapegoat() completes it.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_below(Core<T, Tr, W> &core, int top, const Box &own, const T &shape, std::uint32_t id,
                                   int *lopsided_above = nullptr) {
  NodeStore<W> &nodes = core.nodes;
  const Box box = core.fat(own);
  const std::size_t smallest = min_rebuild(core);
  int n = top, above = -1, prev = -1;
  std::size_t prev_count = 0;
  Box leaf_box; // the leaf's box before: with a margin it may exceed its shapes'
  for (;;) {
    const std::size_t count = ++nodes.info(n).count;
    if (nodes.node(n).is_leaf()) {
      leaf_box = nodes.box(n);
      nodes.extend_box(n, box);
      break;
    }
    if (above < 0 && prev >= 0 && prev_count >= smallest && lopsided(count, prev_count)) above = prev;
    nodes.extend_box(n, box);
    prev = n;
    prev_count = count;
    n = choose_child(nodes.node(n), box);
  }
  if (lopsided_above) *lopsided_above = above;
  return insert_at_leaf(core, top, n, leaf_box, own, shape, id);
}

/// insert_shape() without its rebalance: insert_below() from the root (or
/// the first shape as the root leaf). Returns the node the shape went to.
/// Strong.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_unbalanced(Core<T, Tr, W> &core, const T &shape, std::uint32_t id, int *lopsided_above = nullptr) {
  if (lopsided_above) *lopsided_above = -1;
  NodeStore<W> &nodes = core.nodes;
  const Box own = box_of(core.traits, shape);
  if (core.root < 0) {
    const int root = core.new_node(0, -1, 0);
    try {
      core.leaves.push(nodes.node(root), root, shape, id);
      extend_summary(core, root, own);
    } catch (...) {
      core.free_node(root);
      throw;
    }
    core.root = root;
    // (fitted, not `own`: a NaN side stays out of a box, as in every union)
    nodes.set_box(root, core.fitted_box(root));
    nodes.info(root).count = 1;
    core.size = 1;
    return root;
  }
  const int n = insert_below(core, core.root, own, shape, id, lopsided_above);
  ++core.size;
  return n;
}

/// find_scapegoat(core, parent of n, n, false, stop) after an insert that
/// went to node `n` (insert_below's result), given insert_below's
/// `lopsided_above`: only the last step, from n's parent to n, is left to
/// test, since a split or splice changes n but no count above it. It
/// saves a second walk up the path per insert.
/// `checked`: the invariant below may compare with a walk up (false when
/// later insertions under way, insert_pipelined's, have raised counts on
/// the path above).
template <class T, class Tr, int W>
int insert_scapegoat(const Core<T, Tr, W> &core, int n, int lopsided_above, int stop = -1, bool checked = true) {
  const NodeStore<W> &nodes = core.nodes;
  int found = lopsided_above;
  if (found < 0) {
    const int a = nodes.info(n).parent;
    if (a != stop && a >= 0 && nodes.info(a).count >= min_rebuild(core) && lopsided(nodes.info(n).count, nodes.info(a).count))
      found = a;
  }
  BVH_INVARIANT(!checked || found == find_scapegoat(core, nodes.info(n).parent, n, false, stop),
                "the scapegoat read on the way down differs from the walk up");
  (void)checked;
  return found;
}

/// Adds `shape` under an id already taken (insert_unbalanced), then
/// rebuilds the highest lopsided node on the path (find_scapegoat, read
/// on the way: insert_scapegoat; rebalance). Strong.
template <class T, class Tr, int W> void insert_shape(Core<T, Tr, W> &core, const T &shape, std::uint32_t id) {
  int above;
  const int n = insert_unbalanced(core, shape, id, &above);
  rebalance(core, insert_scapegoat(core, n, above), Cut::by_rule);
}

/// What update() needs to undo an erase_at(): the leaf's old slot (kept
/// aside) and box, or the old subtree that a mend replaced (detached).
template <class T> struct EraseUndo {
  int leaf = -1;                        ///< the leaf erased from (no mend)
  typename LeafStore<T>::Kept old_slot; ///< its slot before, with the shape
  Box leaf_box;                         ///< its box before
  int old_root = -1;                    ///< the mended subtree, detached (a mend)
  int fresh = -1;                       ///< what was built in its place
};

/// Decrements the counts from node n up and refits the boxes, bottom-up
/// (above the first box that does not change, only the counts do).
template <class T, class Tr, int W> void uncount_up(Core<T, Tr, W> &core, int n) noexcept {
  bool refit = true;
  for (; n >= 0; n = core.nodes.info(n).parent) {
    --core.nodes.info(n).count;
    if (refit) {
      const Box box = core.fitted_box(n);
      refit = box != core.nodes.box(n);
      if (refit) core.nodes.set_box(n, box);
    }
  }
}

/// Removes shape `index` of leaf `leaf` and returns its id (still taken);
/// `*changed` gets the node where the balance check starts. It mends the
/// tree on the way:
///  1. counts and tight boxes are refitted from the leaf to the root;
///  2. the highest ancestor left with at most split_threshold shapes, or
///     else the parent of a leaf left empty, is rebuilt from its shapes
///     (a leaf, or kWidth children again): no empty leaf, no inner node
///     with too few children or too few shapes;
///  3. (erase_shape) the highest lopsided ancestor of what changed is
///     rebuilt (find_scapegoat), so depth stays O(log n) under any churn.
/// Rebuilds here cut the shapes as `how` says: in their leaf order
/// (Cut::in_order), so that iteration order survives an erase
/// (erase(iterator) promises it), or by the build rule (Cut::by_rule:
/// erase(handle), erase(value) and update(), which promise no order). An
/// in-order rebuild is balanced by count but not in space: where the old
/// children were lopsided its equal cuts mix them, and near the root,
/// after many moves, that has doubled the tree's SAH cost. A rebuild of m
/// shapes costs O(m log m) and, as for inserts, needs Omega(m) erases
/// below the node to recur.
/// Strong: the node to mend is found before anything changes and rebuilt
/// beside the old subtree from copies. With `undo` (update()), the old
/// slot or subtree is kept aside: undo_erase() puts it back,
/// commit_erase() gives it back. The tree must hold more than one shape.
template <class T, class Tr, int W>
std::uint32_t erase_at(Core<T, Tr, W> &core, int leaf, std::size_t index, Cut how, int *changed,
                       EraseUndo<T> *undo = nullptr) {
  NodeStore<W> &nodes = core.nodes;
  BVH_INVARIANT(core.size > 1, "erase_at() of the last shape");
  int mend = nodes.node(leaf).leaf().count == 1 ? nodes.info(leaf).parent : -1;
  for (int n = nodes.info(leaf).parent; n >= 0; n = nodes.info(n).parent)
    if (nodes.info(n).count - 1 <= std::size_t(core.split_threshold)) mend = n; // the highest wins
  std::uint32_t id;
  if (mend >= 0) {
    id = core.leaves.ids(nodes.node(leaf))[index];
    std::vector<Tagged<T>> shapes = copy_subtree(core, mend, leaf, index);
    const int fresh = build_beside(core, mend, shapes, how);
    // Nothing below throws.
    link_in(core, mend, fresh);
    if (undo) {
      undo->old_root = mend;
      undo->fresh = fresh;
    } else {
      free_subtree(core, mend);
    }
    uncount_up(core, nodes.info(fresh).parent);
    *changed = fresh;
  } else {
    if (undo) {
      undo->leaf = leaf;
      undo->leaf_box = nodes.box(leaf);
      id = core.leaves.ids(nodes.node(leaf))[index];
      undo->old_slot = core.leaves.erase_keeping(nodes.node(leaf), index);
    } else {
      id = core.leaves.erase(nodes.node(leaf), index);
    }
    uncount_up(core, leaf);
    *changed = leaf;
  }
  --core.size;
  return id;
}

/// Puts back what erase_at(..., undo) removed: the tree is as before it.
template <class T, class Tr, int W> void undo_erase(Core<T, Tr, W> &core, const EraseUndo<T> &undo) noexcept {
  NodeStore<W> &nodes = core.nodes;
  int from;
  if (undo.fresh >= 0) {
    link_in(core, undo.fresh, undo.old_root);
    nodes.set_box(undo.old_root, nodes.box(undo.old_root)); // (the parent's float copy)
    relocate_subtree(core, undo.old_root);
    free_subtree(core, undo.fresh);
    from = nodes.info(undo.old_root).parent;
  } else {
    core.leaves.restore(nodes.node(undo.leaf), undo.leaf, undo.old_slot);
    ++nodes.info(undo.leaf).count;
    nodes.set_box(undo.leaf, undo.leaf_box);
    from = nodes.info(undo.leaf).parent;
  }
  for (int n = from; n >= 0; n = nodes.info(n).parent) ++nodes.info(n).count;
  if (from >= 0) core.refit_up(from);
  ++core.size;
}

/// Confirms an erase_at(..., undo): the kept slot or subtree goes.
template <class T, class Tr, int W> void commit_erase(Core<T, Tr, W> &core, const EraseUndo<T> &undo) noexcept {
  if (undo.fresh >= 0)
    free_subtree(core, undo.old_root);
  else
    core.leaves.discard(undo.old_slot);
}

/// erase_at() and its rebalance, then the id is given back. Strong.
template <class T, class Tr, int W>
void erase_shape(Core<T, Tr, W> &core, int leaf, std::size_t index, Cut how) {
  core.leaves.reserve_id_back();
  std::uint32_t id;
  if (core.size == 1) {
    id = core.leaves.ids(core.nodes.node(leaf))[index];
    core.clear_nodes();
  } else {
    int changed;
    id = erase_at(core, leaf, index, how, &changed);
    rebalance(core, find_scapegoat(core, changed, -1, true), how);
  }
  core.leaves.free_erased_id(id, core.size == 0);
}

/// dst = src, strong when T's move assignment cannot throw (a copy, then
/// the move); otherwise T's own copy assignment.
template <class T> void assign(T &dst, const T &src) {
  if constexpr (std::is_nothrow_move_assignable<T>::value) {
    T copy(src);
    dst = std::move(copy);
  } else {
    dst = src;
  }
}

/// The shape of `id`, stored at `at`, becomes `moved`: in place while it
/// fits its leaf's box (refitting above when there is no margin), else
/// erased and inserted again under the same id. Strong (in place: when T's
/// move assignment cannot throw, else as strong as T's copy assignment):
/// if the insert throws, the erase is undone.
template <class T, class Tr, int W>
void update_shape(Core<T, Tr, W> &core, std::uint32_t id, typename LeafStore<T>::Loc at, const T &moved) {
  NodeStore<W> &nodes = core.nodes;
  const Box box = box_of(core.traits, moved);
  if (nodes.box(at.leaf).contains(box) || core.size == 1) {
    // (the shape's code, if it has one, is out of use while it changes)
    Node<W> &leaf = nodes.node(at.leaf);
    const int coded = leaf.coded(), i = int(at.index);
    if (coded > i) leaf.set_coded(i);
    assign(core.leaves.shapes(leaf)[at.index], moved);
    if (coded > i) {
      leaf.code(i, box);
      leaf.set_coded(coded);
    }
    if (core.size == 1) // the last shape: its leaf is the root, fitted to it
      nodes.set_box(at.leaf, core.fitted_box(at.leaf));
    else if (core.margin == 0)
      core.refit_up(at.leaf);
    return;
  }
  EraseUndo<T> undo;
  int changed;
  erase_at(core, at.leaf, at.index, Cut::by_rule, &changed, &undo);
  // The erase's rebalance comes before the insert, as erase() then insert()
  // would do it; the subtree it replaces is kept aside until the insert
  // has succeeded. If the rebuild throws, it is given up (as rebalance()).
  const int a = find_scapegoat(core, changed, -1, true);
  int a_fresh = -1;
  if (a >= 0) {
    try {
      std::vector<Tagged<T>> shapes = copy_subtree(core, a);
      a_fresh = build_beside(core, a, shapes, Cut::by_rule);
      const bool box_changed = nodes.box(a_fresh) != nodes.box(a);
      link_in(core, a, a_fresh);
      if (box_changed && nodes.info(a_fresh).parent >= 0) core.refit_up(nodes.info(a_fresh).parent);
    } catch (...) {
      a_fresh = -1;
    }
  }
  int n;
  try {
    n = insert_unbalanced(core, moved, id);
  } catch (...) {
    if (a_fresh >= 0) { // the erase's state again, then before it
      link_in(core, a_fresh, a);
      nodes.set_box(a, nodes.box(a)); // (the parent's float copy)
      relocate_subtree(core, a);
      free_subtree(core, a_fresh);
      if (nodes.info(a).parent >= 0) core.refit_up(nodes.info(a).parent);
    }
    undo_erase(core, undo);
    throw;
  }
  commit_erase(core, undo);
  if (a_fresh >= 0) free_subtree(core, a);
  rebalance(core, find_scapegoat(core, nodes.info(n).parent, n, false), Cut::by_rule);
}

/// Sets the margin and recomputes every box, bottom-up: O(n).
/// Strong: nothing changes before the pass that cannot throw.
template <class T, class Tr, int W> void set_margin(Core<T, Tr, W> &core, double m) {
  const double margin = m > 0 && m < std::numeric_limits<double>::infinity() ? m : 0;
  if (core.root < 0) {
    core.margin = margin;
    return;
  }
  core.margin = margin;
  // Bottom-up without a list of nodes: nothing to allocate.
  for_each_postorder(core.nodes, core.root, [&](int n) { core.nodes.set_box(n, core.fitted_box(n)); });
}

// ===========================================================================
// 7. Queries
// ===========================================================================
//
// Every query is const and reads the tree only, so any number of threads
// may query one tree at once while none changes it. The depth-first ones
// run walk(); overlapping() runs walk()'s steps one at a time; the nearest
// searches and the ray run best_first().

/// Calls f(i) for each index i of leaf `node`'s n shapes whose box may
/// meet `box`, ascending, until f returns false (then returns false): with
/// the leaf's summary in use, the shapes whose code box meets it; else
/// every shape.
template <int W, class F> BVH_ALWAYS_INLINE bool each_candidate(const Node<W> &node, std::size_t n, const Box &box, F &&f) {
  if constexpr (Node<W>::kCoded > 0) {
    if (node.coded() == int(n)) {
      for (std::uint32_t bits = node.meets(box, int(n)); bits != 0; bits &= bits - 1)
        if (!f(std::size_t(lowest_bit(bits)))) return false;
      return true;
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!f(i)) return false;
  return true;
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

/// For a summarized leaf of inscribed disks (n shapes, all coded): true
/// when one whose code box meets `box` surely meets probe `p`; otherwise
/// `unsure` gets those whose code box meets `box` that the codes cannot
/// decide (all of them when the frame or the probe is unusable).
template <int W>
BVH_ALWAYS_INLINE bool disk_codes_hit(const Node<W> &node, int n, const Box &box, const DiskProbe &p, std::uint32_t &unsure) {
  const std::uint32_t bits = node.meets(box, n);
  unsure = bits;
  if (bits == 0 || !p.usable) return false;
  const CodeFrame f = CodeFrame::of(node.frame());
  if (!f.usable) return false;
  for (std::uint32_t b = bits; b != 0; b &= b - 1) {
    const int i = lowest_bit(b);
    const int d = disk_decision(node, i, f, p);
    if (d > 0) return true;
    if (d < 0) unsure &= ~(std::uint32_t(1) << i);
  }
  return false;
}

/// True when collision searches may decide a summarized leaf's disks from
/// their codes (widths with summaries, traits that promise inscribed
/// disks).
template <class Tr, int W> constexpr bool kDisksFromCodes = Node<W>::kCoded > 0 && InscribedDisks<Tr>::value;

/// The stored shapes' bytes from which they do by default
/// (Tuning::disk_codes_min_shapes): a decision costs more than reading a
/// disk the caches hold, and saves a miss only when the disks are many
/// more than a core's own caches keep. Defining it before bvh.h changes
/// the default only; set_tuning() changes a tree's.
#ifndef BVH_DISK_CODES_MIN_BYTES
#define BVH_DISK_CODES_MIN_BYTES (std::size_t(4) << 20)
#endif
/// The probe as collision searches of `core` read it: a DiskProbe, usable
/// when core's disks are decided from codes.
template <class T, class Tr, int W> BVH_ALWAYS_INLINE DiskProbe disk_probe(const Core<T, Tr, W> &core, const Box &box) {
  if constexpr (kDisksFromCodes<Tr, W>)
    if (core.size >= core.tuning.disk_codes_min_shapes) return DiskProbe::of(box);
  return DiskProbe{};
}

/// collides()'s visit of inner node `node`: the children to enter, as
/// walk()'s visit result. Children holding the probe's centre go first
/// where leaves have no summary: there a leaf visit reads every shape, and
/// a hit is likely in those. A summarized leaf is cheap to visit, and the
/// second test a node would cost more than the order saves.
template <int W> BVH_ALWAYS_INLINE unsigned collision_children(const Node<W> &node, const Probe &probe) {
  if constexpr (Node<W>::kCoded > 0) {
    return child_hits(node, probe);
  } else {
    unsigned hits, near;
    child_masks(node, probe, hits, near);
    return hits | near << kFirst; // near is a subset of hits
  }
}

/// collides()'s visit of a summarized leaf of n disks (kDisksFromCodes,
/// the probe usable): true when one meets `shape`. (Not inlined: it runs on
/// large trees only, and inlined it made the search of small trees, which
/// never takes it, slower.)
template <class T, class Tr, int W>
BVH_NOINLINE bool disk_leaf_collides(const Tr &traits, const Node<W> &node, const T *v, int n, const Box &box,
                                     const DiskProbe &disk, const T &shape) {
  std::uint32_t unsure;
  if (disk_codes_hit(node, n, box, disk, unsure)) return true;
  for (; unsure != 0; unsure &= unsure - 1)
    if (traits.intersect(v[lowest_bit(unsure)], shape)) return true;
  return false;
}

/// True iff some stored shape intersects `shape` (touching counts).
/// Subtrees whose box misses the shape's box are never visited; the final
/// test is T's intersect().
template <class T, class Tr, int W> bool collides(const Core<T, Tr, W> &core, const T &shape) {
  if (core.root < 0) return false;
  const Box box = box_of(core.traits, shape);
  if (!core.nodes.box(core.root).overlaps(box)) return false;
  const Probe probe = Probe::around(box);
  const DiskProbe disk = disk_probe(core, box);
  return !walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      if constexpr (kDisksFromCodes<Tr, W>)
        if (disk.usable && node.coded() == int(v.size()))
          return disk_leaf_collides(core.traits, node, v.begin(), int(v.size()), box, disk, shape) ? kStop : 0;
      const bool missed =
          each_candidate(node, v.size(), box, [&](std::size_t i) { return !core.traits.intersect(v[i], shape); });
      return missed ? 0 : kStop;
    }
    return collision_children(node, probe);
  });
}

/// hit[j] = collides(core, shapes[j]) for each j < count, on one thread,
/// with kLanes of the searches interleaved. A search of a large tree
/// mostly waits for memory: each node and the shapes it reads are a miss
/// that depends on the one before. Here each step of a search asks the
/// cache for what its next step reads (the node it enters, or the leaf's
/// shapes whose code box meets the probe) and hands over to the next
/// search, so that the misses of kLanes searches overlap. Each search
/// makes collides()'s decisions: the same nodes, the same shapes tested
/// (a leaf's, after the prefetch), the same answer. If intersect() throws,
/// the exception passes on and hit[] is partly written.
template <class T, class Tr, int W>
void collides_each(const Core<T, Tr, W> &core, const T *shapes, std::size_t count, unsigned char *hit) {
  constexpr int kLanes = 8;
  constexpr std::size_t kDeferred = 32; // a leaf of at most this many shapes waits for their prefetch
  struct Search {
    const T *shape = nullptr; // null: the lane is idle
    unsigned char *hit = nullptr;
    Box box;
    Probe probe{0, 0, 0, 0, 0, 0};
    DiskProbe disk;              // (kDisksFromCodes)
    IndexStack stack;
    int node = -1;               // the node the next step visits,
    const T *leaf = nullptr;     // or, while `pending` is not 0, the leaf's shapes
    std::uint32_t pending = 0;   // whose bits are set here: the next step tests them
  };
  const auto enter = [&](Search &s, int n) BVH_LAMBDA_INLINE {
    s.node = n;
    prefetch_lines(&core.nodes.node(n), sizeof(Node<W>));
  };
  std::size_t next = 0;
  // Gives lane s the next search that needs the tree; false when none is left.
  const auto start = [&](Search &s) BVH_LAMBDA_INLINE {
    s.shape = nullptr;
    s.stack.clear();
    while (next < count) {
      const std::size_t j = next++;
      const Box box = box_of(core.traits, shapes[j]);
      if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) {
        hit[j] = 0;
        continue;
      }
      s.shape = &shapes[j];
      s.hit = &hit[j];
      s.box = box;
      s.probe = Probe::inline_around(box);
      if constexpr (kDisksFromCodes<Tr, W>) s.disk = disk_probe(core, box);
      enter(s, core.root);
      return true;
    }
    return false;
  };
  // One step of lane s's search; true when it has its answer.
  const auto step = [&](Search &s) BVH_LAMBDA_INLINE -> bool {
    if (s.pending != 0) {
      for (; s.pending != 0; s.pending &= s.pending - 1)
        if (core.traits.intersect(s.leaf[lowest_bit(s.pending)], *s.shape)) {
          s.pending = 0;
          return *s.hit = 1, true;
        }
    } else {
      const Node<W> &node = core.nodes.node(s.node);
      if (!node.is_leaf()) {
        const unsigned enter_bits = collision_children(node, s.probe);
        if (enter_bits != 0) {
          enter(s, enter_children(s.stack, node, enter_bits));
          return false;
        }
      } else {
        const Span<const T> v = core.leaves.shapes(node);
        if (v.size() <= kDeferred) {
          std::uint32_t bits = v.size() == 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << v.size()) - 1;
          if constexpr (Node<W>::kCoded > 0) {
            if (node.coded() == int(v.size())) {
              if (!kDisksFromCodes<Tr, W> || !s.disk.usable) bits = node.meets(s.box, int(v.size()));
              else if (disk_codes_hit(node, int(v.size()), s.box, s.disk, bits)) return *s.hit = 1, true;
            }
          }
          if (bits != 0) {
            for (std::uint32_t b = bits; b != 0; b &= b - 1) prefetch_lines(v.begin() + lowest_bit(b), sizeof(T));
            s.leaf = v.begin();
            s.pending = bits;
            return false;
          }
        } else if (!each_candidate(node, v.size(), s.box, [&](std::size_t i) { return !core.traits.intersect(v[i], *s.shape); })) {
          return *s.hit = 1, true;
        }
      }
    }
    if (s.stack.empty()) return *s.hit = 0, true;
    enter(s, s.stack.pop());
    return false;
  };
  Search lanes[kLanes];
  int busy = 0;
  for (Search &s : lanes) busy += start(s) ? 1 : 0;
  while (busy > 0)
    for (Search &s : lanes)
      if (s.shape && step(s) && !start(s)) --busy;
}

/// Calls visit(shape) on each shape whose box overlaps `box`, until it
/// returns false.
template <class T, class Tr, int W, class V> void visit_overlapping(const Core<T, Tr, W> &core, const Box &box, V &&visit) {
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  const Probe probe = Probe::around(box);
  walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      const bool went_on = each_candidate(node, v.size(), box, [&](std::size_t i) {
        return !box_of(core.traits, v[i]).overlaps(box) || visit(v[i]);
      });
      return went_on ? 0 : kStop;
    }
    return child_hits(node, probe);
  });
}

/// Calls visit(s) on each stored shape s that intersects `shape` (T's
/// intersect(); only shapes whose box meets shape's are tested), in
/// visit_overlapping()'s order, until it returns false. Where disks are
/// decided from codes (disk_probe), a disk that surely misses is not read
/// and one that surely meets is not tested again.
template <class T, class Tr, int W, class V> void visit_intersecting(const Core<T, Tr, W> &core, const T &shape, V &&visit) {
  const Box box = box_of(core.traits, shape);
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  const Probe probe = Probe::around(box);
  const DiskProbe disk = disk_probe(core, box);
  walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      const auto tested = [&](std::size_t i) {
        return !box_of(core.traits, v[i]).overlaps(box) || !core.traits.intersect(v[i], shape) || visit(v[i]);
      };
      if constexpr (kDisksFromCodes<Tr, W>) {
        if (disk.usable && node.coded() == int(v.size())) {
          const CodeFrame f = CodeFrame::of(node.frame());
          for (std::uint32_t bits = node.meets(box, int(v.size())); bits != 0; bits &= bits - 1) {
            const int i = lowest_bit(bits);
            const int sure = f.usable ? disk_decision(node, i, f, disk) : 0;
            if (sure < 0) continue;
            if (!(sure > 0 ? visit(v[i]) : tested(std::size_t(i)))) return kStop;
          }
          return 0;
        }
      }
      return each_candidate(node, v.size(), box, tested) ? 0 : kStop;
    }
    return child_hits(node, probe);
  });
}

/// visit_overlapping() suspended between the shapes it finds: walk()'s
/// stack and steps, kept between calls, and the current leaf's shapes not
/// yet looked at. With `shape`, only shapes that intersect it are found.
/// The stack is on the call stack for trees up to IndexStack::kInline deep.
template <class T, class Tr, int W> class OverlapSearch {
public:
  /// The end of every search.
  OverlapSearch() = default;
  /// The search of `core` for `box` (and `shape`, when not null), at its
  /// first shape.
  OverlapSearch(const Core<T, Tr, W> &core, const Box &box, const T *shape)
      : core_(&core), box_(box), probe_(Probe::around(box)) {
    if (shape) shape_.emplace(*shape);
    if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
    stack_.push(core.root);
    next();
  }
  /// The shape found, nullptr at the end.
  const T *at() const { return at_; }
  /// On to the next shape found.
  void next() {
    at_ = nullptr;
    for (;;) {
      while (bits_ != 0) { // a summarized leaf: the shapes whose code box meets the box
        const T *s = next_ + lowest_bit(bits_);
        bits_ &= bits_ - 1;
        if (found(*s)) return;
      }
      while (next_ != last_) {
        const T *s = next_++;
        if (found(*s)) return;
      }
      if (stack_.empty()) return;
      const Node<W> &node = core_->nodes.node(stack_.pop());
      if (node.is_leaf()) {
        const Span<const T> v = core_->leaves.shapes(node);
        next_ = v.begin();
        last_ = v.end();
        if constexpr (Node<W>::kCoded > 0) {
          if (node.coded() == int(v.size())) {
            bits_ = node.meets(box_, int(v.size()));
            last_ = next_;
          }
        }
        continue;
      }
      const unsigned hits = child_hits(node, probe_);
      if (hits != 0) {
        const int next = enter_children(stack_, node, hits);
        prefetch_stacked(core_->nodes, node, hits, next);
        stack_.push(next); // (it pops first)
      }
    }
  }

private:
  /// True, with at_ set, when `s` is a shape the search finds.
  bool found(const T &s) {
    if (!box_of(core_->traits, s).overlaps(box_) || (shape_ && !core_->traits.intersect(s, *shape_))) return false;
    at_ = &s;
    return true;
  }
  const Core<T, Tr, W> *core_ = nullptr;
  Box box_;
  Probe probe_ = Probe(0, 0, 0, 0, 0, 0);
  std::optional<T> shape_; // a copy: the probe may be a temporary
  IndexStack stack_;
  // The current leaf's shapes not yet looked at: [next_, last_), or with a
  // summary in use, next_ + each set bit of bits_ (last_ == next_).
  const T *next_ = nullptr, *last_ = nullptr;
  std::uint32_t bits_ = 0;
  const T *at_ = nullptr;
};

/// Finds a stored shape equal to `value`: its leaf and index. Only
/// subtrees whose box holds value's box are searched.
template <class T, class Tr, int W> bool find_equal(const Core<T, Tr, W> &core, const T &value, int &leaf, std::size_t &index) {
  const Box box = box_of(core.traits, value);
  if (core.root < 0 || !core.nodes.box(core.root).contains(box)) return false;
  // A float child box is its exact box rounded outwards: it holds `box`
  // whenever the exact one does.
  return !walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      // (an equal shape has the same box: its code box meets `box`)
      const Span<const T> v = core.leaves.shapes(node);
      const bool missed = each_candidate(node, v.size(), box, [&](std::size_t i) {
        if (!(v[i] == value)) return true;
        leaf = n;
        index = i;
        return false;
      });
      return missed ? 0 : kStop;
    }
    unsigned enter = 0;
    for (int c = 0; c < node.num_children; ++c)
      enter |= unsigned(node.lo_x[c] <= box.x0 && node.lo_y[c] <= box.y0 && box.x1 <= node.hi_x[c] &&
                        box.y1 <= node.hi_y[c])
               << c;
    return enter;
  });
}

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
  auto bound = [&] { return found.size() < k ? inf : metric.beyond(found.front().key); };
  auto visit_leaf = [&](const Node<W> &node) {
    // The ids only once a shape is near enough to need its tie-break.
    const Span<const T> v = core.leaves.shapes(node);
    const std::uint32_t *ids = nullptr;
    double limit = bound(); // (it changes only when `found` does)
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
      limit = bound();
    }
  };
  // First a dive along the nearest boxes to one leaf: its shapes bound
  // the search, which would otherwise push every child it passes on its
  // way to the first leaf (the bound is +inf until k shapes are found).
  // (A leaf may fill all k only when k <= split_threshold.)
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
  if (dive >= 0 && core.nodes.node(dive).is_leaf()) visit_leaf(core.nodes.node(dive));
  else dive = -1;
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
    if (e.key > bound()) break;
    const Node<W> &node = core.nodes.node(e.node);
    if (node.is_leaf()) {
      if (e.node != dive) visit_leaf(node); // (the dive's leaf is done)
      continue;
    }
    const double limit = bound();
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
  if (!within_a) { // one leaf: shape i against the later shapes whose code box meets its box
    if constexpr (Node<W>::kCoded > 0) {
      if (leaf_a.coded() == int(n)) {
        for (std::size_t i = 0; i + 1 < n; ++i)
          for (std::uint32_t bits = leaf_a.meets(in_a[i].box, int(n)) & (~std::uint32_t(1) << i); bits != 0;
               bits &= bits - 1) {
            const std::size_t j = std::size_t(lowest_bit(bits));
            if (pair(in_a[i], in_a[j]) && !keep_going(f, *in_a[i].shape, *in_a[j].shape)) return false;
          }
        return true;
      }
    }
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j)
        if (pair(in_a[i], in_a[j]) && !keep_going(f, *in_a[i].shape, *in_a[j].shape)) return false;
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
/// course's tree's, the leaves pair up by plain loops alone.
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

// ===========================================================================
// 8. Diagnostics: the course's report and picture, validate
// ===========================================================================

/// What the course's report sums: node count, max depth, and the two area
/// sums of the surface area heuristic (areas in units of the canvas).
struct Summary {
  long nodes = 0;
  int max_depth = 0;
  double inner_area = 0, leaf_area = 0;
};

/// The one pass behind statistics(), sah_cost() and height(): every node in
/// pre-order, f(n, its area in canvas units) called on each.
template <class T, class Tr, int W, class F> Summary summarize(const Core<T, Tr, W> &core, F &&f) {
  Summary s;
  for_each_preorder(core.nodes, core.root, [&](int n) {
    const Info &in = core.nodes.info(n);
    const double area = in.box().area() / kCanvasArea;
    ++s.nodes;
    s.max_depth = std::max(s.max_depth, in.depth);
    if (core.nodes.node(n).is_leaf())
      s.leaf_area += area * double(in.count);
    else
      s.inner_area += area;
    f(n, area);
  });
  return s;
}
template <class T, class Tr, int W> Summary summarize(const Core<T, Tr, W> &core) {
  return summarize(core, [](int, double) {});
}

/// The course's report: with `print_tree`, one line per node in pre-order,
/// then node count, max depth and the two area sums.
template <class T, class Tr, int W> void print_statistics(const Core<T, Tr, W> &core, std::ostream &ostr, bool print_tree) {
  std::string line;
  char buf[64];
  const Summary s = summarize(core, [&](int n, double area) {
    if (!print_tree) return;
    const Info &in = core.nodes.info(n);
    const Node<W> &node = core.nodes.node(n);
    // The course's stream is not yet in fixed mode when it prints the
    // root, so the root's area shows 3 significant digits, the rest 3
    // decimals.
    std::snprintf(buf, sizeof buf, n == core.root ? "%.3g" : "%.3f", area);
    line.assign(std::size_t(3) * std::size_t(in.depth), ' ');
    line += node.is_leaf() ? "leaf area=" : "inner area=";
    line += buf;
    line += ' ';
    append_box(line, in.box());
    if (node.is_leaf()) {
      line += " elements:";
      for (const T &shape : core.leaves.shapes(node)) {
        line += ' ';
        append_box(line, box_of(core.traits, shape));
      }
    }
    line += '\n';
    ostr << line;
  });
  std::snprintf(buf, sizeof buf, "node count:      %7ld\n", s.nodes);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "max depth:       %7d\n", s.max_depth);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "inner node area: %7.3f\n", s.inner_area);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "leaf node area:  %7.3f\n", s.leaf_area);
  ostr << buf;
  ostr.flush();
}

/// The course's picture: every node's box drawn translucently (root grey,
/// its children red, green and blue, deeper children blended 2/3 parent
/// and 1/3 their own primary), every shape recoloured to its leaf's colour.
/// Boxes are drawn by the shape library's BoundingBox::render; colours are
/// made with Color(r, g, b) and given to T::setColor.
template <class T, class Tr, int W> void render_recolor(Core<T, Tr, W> &core, std::ostream &ostr) {
  if (core.root < 0) return;
  struct Rgb {
    int r, g, b;
  };
  // The course's three first, then one more hue per child up to kMaxWidth.
  static const Rgb primary[kMaxWidth] = {{255, 0, 0},   {0, 255, 0},   {0, 0, 255}, {255, 255, 0},
                                         {0, 255, 255}, {255, 0, 255}, {255, 128, 0}, {128, 0, 255}};
  // Channels mixed here, as Color::mix would (the course's mix returns
  // nothing and this project's returns the mix: neither is relied on).
  auto blend = [](const Rgb &parent, const Rgb &own) {
    const float f = 2.0f / 3.0f;
    return Rgb{int(parent.r * f + own.r * (1 - f)), int(parent.g * f + own.g * (1 - f)),
               int(parent.b * f + own.b * (1 - f))};
  };
  std::vector<Rgb> rgb(core.nodes.capacity());
  rgb[std::size_t(core.root)] = Rgb{128, 128, 128};
  for_each_preorder(core.nodes, core.root, [&](int n) {
    const Info &in = core.nodes.info(n);
    Rgb &own = rgb[std::size_t(n)];
    if (in.parent >= 0)
      own = in.parent == core.root ? primary[in.child_index]
                                   : blend(rgb[std::size_t(in.parent)], primary[in.child_index]);
    const Color color(own.r, own.g, own.b);
    const Box &b = in.box();
    BoundingBox(Point(b.x0, b.y0), Point(b.x1, b.y1)).render(ostr, color);
    Node<W> &node = core.nodes.node(n);
    if (node.is_leaf())
      for (T &s : core.leaves.shapes(node)) s.setColor(color);
  });
}

/// Checks node n's own invariants (not its subtree's: validate() does
/// that); false with *why set on the first failure.
template <class T, class Tr, int W> bool validate_node(const Core<T, Tr, W> &core, int n, std::string &why) {
  const NodeStore<W> &nodes = core.nodes;
  const Node<W> &node = nodes.node(n);
  const Info &in = nodes.info(n);
  if (n == core.root) {
    if (in.parent != -1 || in.depth != 0) return why = "root has a parent or depth != 0", false;
  } else {
    const Node<W> &p = nodes.node(in.parent);
    const int c = in.child_index;
    if (in.depth != nodes.info(in.parent).depth + 1) return why = "depth is not parent's + 1", false;
    if (c < 0 || c >= p.num_children || p.child(c) != n) return why = "parent does not list it in its slot", false;
    if (p.lo_x[c] != float_down(in.box().x0) || p.lo_y[c] != float_down(in.box().y0) ||
        p.hi_x[c] != float_up(in.box().x1) || p.hi_y[c] != float_up(in.box().y1))
      return why = "parent's float box for it is not its box rounded outwards", false;
  }
  if (core.depth_limit != 0 && in.depth > core.depth_limit) return why = "deeper than depth_limit", false;
  Box tight;
  std::size_t count = 0;
  if (node.is_leaf()) {
    const LeafSlot slot = node.leaf();
    if (!slot.has_slot() || slot.count == 0) return why = "empty leaf", false;
    if (core.leaves.slot_size(node) != slot.count) return why = "leaf's record disagrees with its slot", false;
    if (!core.is_leaf_size(slot.count, in.depth)) return why = "leaf over split_threshold above depth_limit", false;
    const Span<const T> shapes = core.leaves.shapes(node);
    for (const T &s : shapes) tight.extend(box_of(core.traits, s));
    count = shapes.size();
    for (std::size_t i = 0; i < shapes.size(); ++i)
      if (!supported_shape(core.traits, shapes[i]))
        return why = "shape " + std::to_string(i) + " is outside the supported values", false;
    const int coded = node.coded();
    if (coded > int(count) || coded > Node<W>::kCoded) return why = "summary of more shapes than the leaf holds", false;
    // Exactly its own box's codes, not a box holding it: a disk's code
    // box is read back as the disk itself (disk_decision).
    for (int i = 0; i < coded; ++i) {
      const std::uint32_t want = Node<W>::codes_of(box_of(core.traits, shapes[std::size_t(i)]), node.frame());
      if (node.codes(i) != want) {
        const auto sides = [](std::uint32_t c) {
          std::string t;
          for (int r = 0; r < 4; ++r) t += (r ? " " : "") + std::to_string(c >> (8 * r) & 255u);
          return t;
        };
        return why = "shape " + std::to_string(i) + "'s summary codes (low x, low y, high x, high y) are " +
                     sides(node.codes(i)) + ", not its own box's " + sides(want),
               false;
      }
    }
    const std::uint32_t *ids = core.leaves.ids(node);
    for (std::size_t i = 0; i < shapes.size() && core.leaves.located(); ++i)
      if (!core.leaves.contains(ids[i]) || core.leaves.locate(ids[i]).leaf != n ||
          core.leaves.locate(ids[i]).index != i)
        return why = "shape " + std::to_string(i) + "'s id does not locate it", false;
    // With a margin a leaf's box may be larger than fat(tight): update()
    // leaves it as it is while the shapes stay inside.
    if (core.margin > 0 && in.box().contains(tight)) tight = in.box();
  } else {
    if (node.num_children < 2 || node.num_children > W)
      return why = "inner node without 2 to " + std::to_string(W) + " children", false;
    // (the course's thirds give 2 children only to nodes of 2 shapes)
    if (W == 3 && node.num_children == 2 && core.split_threshold != 1)
      return why = "2 children although split_threshold > 1", false;
    for (int c = 0; c < node.num_children; ++c) {
      tight.extend(nodes.box(node.child(c)));
      count += nodes.info(node.child(c)).count;
    }
  }
  if (tight != in.box()) return why = "box is not the tight box of its subtree", false;
  if (count != in.count) return why = "shape count is not its subtree's", false;
  return true;
}

/// Checks every invariant of the tree; false with *why (when given) naming
/// the node and what it broke. O(n log n).
template <class T, class Tr, int W> bool validate(const Core<T, Tr, W> &core, std::string *why) {
  const NodeStore<W> &nodes = core.nodes;
  std::string what;
  int bad = -1;
  auto fail = [&](int n, const std::string &w) {
    if (why) *why = "node " + std::to_string(n) + ": " + w;
    return false;
  };
  if (core.root < 0) {
    if (core.size != 0) return fail(-1, "empty tree with size " + std::to_string(core.size));
    if (nodes.live() != 0) return fail(-1, "empty tree with live nodes");
    if (core.leaves.id_count() != 0 || !core.leaves.free_ids().empty() || !core.leaves.generations().empty())
      return fail(-1, "empty tree with ids");
    if (core.leaves.located()) return fail(-1, "empty tree with a handle table");
    return true;
  }
  // Every id below the count is stored exactly once or free (listed once).
  std::vector<char> id_seen(core.leaves.id_count(), 0);
  std::vector<char> is_free(nodes.capacity(), 0);
  for (int f : nodes.free_list()) {
    if (f < 0 || std::size_t(f) >= nodes.capacity() || is_free[std::size_t(f)]) return fail(f, "bad free-list entry");
    is_free[std::size_t(f)] = 1;
  }
  std::size_t counted = 0, reached = 0;
  walk(nodes, core.root, [&](int n) -> unsigned {
    ++reached;
    if (is_free[std::size_t(n)]) what = "reachable node on the free list";
    else if (validate_node(core, n, what)) what.clear();
    if (!what.empty()) {
      bad = n;
      return kStop;
    }
    if (nodes.node(n).is_leaf()) {
      counted += nodes.info(n).count;
      const std::uint32_t *ids = core.leaves.ids(nodes.node(n));
      for (std::size_t i = 0; i < nodes.info(n).count; ++i) {
        if (ids[i] >= id_seen.size() || id_seen[ids[i]]) {
          what = "id " + std::to_string(ids[i]) + " of shape " + std::to_string(i) + " is out of range or stored twice";
          bad = n;
          return kStop;
        }
        id_seen[ids[i]] = 1;
      }
    }
    return all_children(nodes.node(n));
  });
  if (bad >= 0) return fail(bad, what);
  if (reached + nodes.free_list().size() != nodes.capacity()) return fail(core.root, "unreachable nodes off the free list");
  if (counted != core.size) return fail(core.root, "size() disagrees with the shapes stored");
  if (core.leaves.id_count() != core.size + core.leaves.free_ids().size())
    return fail(-1, "ids in use and free do not add up");
  const bool located = core.leaves.located();
  for (std::uint32_t id : core.leaves.free_ids()) {
    if (id >= id_seen.size() || id_seen[id] || (located && core.leaves.contains(id)))
      return fail(-1, "free id " + std::to_string(id) + " is in use or listed twice");
    id_seen[id] = 1;
  }
  if (located && core.leaves.table_size() != core.leaves.id_count())
    return fail(-1, "the handle table's length is not the ids'");
  if (!core.leaves.generations().empty() && core.leaves.generations().size() != core.leaves.id_count())
    return fail(-1, "the generations' length is not the ids'");
  return true;
}

// ===========================================================================
// 8b. Disjoint insertion: insert_disjoint, a change built on the queries
// ===========================================================================
//
// Discard-overlap sampling, `for (i) if (!collides(c[i])) insert c[i]`, on
// several threads with exactly that loop's result. (Placed after the
// queries because it uses them; it changes Core only through section 6's
// insert_shape and LeafStore's ids, as BVH::insert does.) The candidates go
// in batches, each in three steps:
//  1. parallel: every candidate of the batch is tested against the tree as
//     it stood at the batch's start (collides() is const: the workers share
//     the tree, which nobody changes meanwhile). The tree only grows, so a
//     candidate that hits it is rejected by the loop too; the others are the
//     batch's survivors.
//  2. parallel when there are many survivors: every pair of survivors whose
//     boxes (rounded outwards to float, as collides()'s are) overlap, found
//     by a sweep along x, is tested by intersect(earlier, later), the
//     argument order of collides().
//  3. serial, in input order: a survivor is kept iff no earlier kept
//     survivor of the batch intersects it (step 2's pairs, or with few
//     survivors a direct box-then-intersect test);
//  4. the kept ones are inserted as the loop inserts them, with their ids
//     taken as BVH::insert takes them: on a large tree, routed through
//     its top in order and then inserted into disjoint subtrees by
//     several threads at once (insert_in_order), else one by one.
// A survivor misses the tree as it was at the batch's start, and since then
// only the batch's earlier kept survivors were added: step 3 decides what
// the loop decides, and step 4 makes the loop's insertions with its ids. (This relies on what collides() itself relies on: shapes
// that intersect have overlapping boxes.) The batch adapts: it doubles
// while few candidates survive the tree (the steps' fixed costs spread over
// more) and halves while many do (step 2's pairs grow with its square).
// The threads are started once per call (parallel_for) and wait between
// batches (Crew), so a batch never waits for a thread to start or for one
// the system has not yet woken.

/// The fewest threads on which insert_disjoint's step 4 takes the lanes
/// (0: by the tree's shape, disjoint_lanes_threads(); never fewer than 2).
/// With fewer, the driver inserts alone by the pipeline (insert_pipelined)
/// while steps 1 and 2 still run on every thread.
#ifndef BVH_DISJOINT_LANES_THREADS
#define BVH_DISJOINT_LANES_THREADS 0
#endif
/// The size of tree from which insert_disjoint's step 4 inserts on every
/// thread (the lanes) by default (Tuning::disjoint_lanes_min); a smaller
/// tree is not worth splitting. Tests define it lower before bvh.h, so
/// that small trees (and their runs under valgrind and the sanitizers)
/// take the lanes too; set_tuning() changes one tree's.
#ifndef BVH_DISJOINT_LANES_MIN
#define BVH_DISJOINT_LANES_MIN 4096
#endif
/// The number of a batch's survivors from which step 2's sweep runs on
/// every thread by default (Tuning::disjoint_sweep_min; lowered by the
/// tests, as BVH_DISJOINT_LANES_MIN).
#ifndef BVH_DISJOINT_SWEEP_MIN
#define BVH_DISJOINT_SWEEP_MIN 4096
#endif

/// The size of tree from which insert_disjoint's step 1 interleaves its
/// searches (collides_each), and from which one thread decides in batches
/// at all: on a smaller tree, which the caches hold, the interleaving and
/// the batches cost more than they save, and one thread runs the loop
/// itself. The default of Tuning::disjoint_interleave_min; tests define it
/// lower, as BVH_DISJOINT_LANES_MIN.
#ifndef BVH_DISJOINT_INTERLEAVE_MIN
#define BVH_DISJOINT_INTERLEAVE_MIN 32768
#endif

/// The macros above and BVH_DISK_CODES_MIN_BYTES set only these defaults.
template <class T> Tuning default_tuning() noexcept {
  Tuning t;
  t.disk_codes_min_shapes = std::size_t(BVH_DISK_CODES_MIN_BYTES) / sizeof(T);
  t.disjoint_interleave_min = BVH_DISJOINT_INTERLEAVE_MIN;
  t.disjoint_lanes_min = BVH_DISJOINT_LANES_MIN;
  t.disjoint_sweep_min = BVH_DISJOINT_SWEEP_MIN;
  return t;
}

/// Step timings of insert_disjoint, for bench/bench.cpp's serial-fraction
/// figures: compiled in only when BVH_DISJOINT_PROFILE names a function
/// void(int step, double seconds) declared before bvh.h (step 1 and 2: the
/// parallel steps, 3: the serial one, 0: the rest, i.e. gathering
/// survivors and the sweep's sort). When BVH_DISJOINT_PROFILE_ON is defined
/// too, as an expression, a call whose value is false reads no clock: a
/// program that times some calls and profiles others does not pay for the
/// clock in the calls it times (a clock read per batch is a visible part
/// of a call on a virtual machine, where reading the CPU-time clock is a
/// system call).
struct DisjointClock {
#ifdef BVH_DISJOINT_PROFILE
#ifdef BVH_DISJOINT_PROFILE_ON
  bool on = bool(BVH_DISJOINT_PROFILE_ON);
#else
  bool on = true;
#endif
  std::chrono::steady_clock::time_point last = on ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point();
  void lap(int step) {
    if (!on) return;
    const auto now = std::chrono::steady_clock::now();
    BVH_DISJOINT_PROFILE(step, std::chrono::duration<double>(now - last).count());
    last = now;
  }
#else
  void lap(int) {}
#endif
};

/// Threads kept for a run of parallel loops: one driver calls run() for
/// each loop, the others sit in help() between loops. run(chunks, job) calls
/// job(0) ... job(chunks - 1) on the driver and on whichever helpers are
/// awake, returns once every call has returned, and then rethrows the first
/// exception of any (the remaining chunks are skipped after one). A helper
/// woken late finds the loop closed and waits for the next; finish() sends
/// every helper home. All shared state is under the mutex but the chunk
/// counter; a helper's writes reach the driver through the mutex (busy_).
class Crew {
public:
  template <class F> void run(std::size_t chunks, F &job) {
    {
      std::lock_guard<std::mutex> hold(lock_);
      call_ = [](void *f, std::size_t i) { (*static_cast<F *>(f))(i); };
      job_ = &job;
      chunks_ = chunks;
      next_ = 0;
      failed_ = false;
      error_ = nullptr;
      open_ = true;
      ++generation_;
    }
    wake_.notify_all();
    work();
    std::exception_ptr error;
    {
      std::unique_lock<std::mutex> hold(lock_);
      open_ = false;
      idle_.wait(hold, [&] { return busy_ == 0; });
      std::swap(error, error_);
    }
    if (error) std::rethrow_exception(error);
  }
  void help() {
    std::unique_lock<std::mutex> hold(lock_);
    for (std::size_t seen = 0;;) {
      wake_.wait(hold, [&] { return done_ || (open_ && generation_ != seen); });
      if (done_) return;
      seen = generation_;
      ++busy_;
      hold.unlock();
      work();
      hold.lock();
      if (--busy_ == 0) idle_.notify_all();
    }
  }
  void finish() {
    {
      std::lock_guard<std::mutex> hold(lock_);
      done_ = true;
    }
    wake_.notify_all();
  }

private:
  void work() {
    for (std::size_t i; !failed_.load(std::memory_order_relaxed) && (i = next_++) < chunks_;) {
      try {
        call_(job_, i);
      } catch (...) {
        std::lock_guard<std::mutex> hold(lock_);
        if (!error_) error_ = std::current_exception();
        failed_ = true;
      }
    }
  }
  std::mutex lock_;
  std::condition_variable wake_, idle_;
  void (*call_)(void *, std::size_t) = nullptr;
  void *job_ = nullptr;
  std::size_t chunks_ = 0, generation_ = 0, busy_ = 0;
  std::atomic<std::size_t> next_{0};
  std::atomic<bool> failed_{false};
  std::exception_ptr error_;
  bool open_ = false, done_ = false;
};

/// BVH::insert's id handling around insert_shape: the next id, given back
/// if the insertion throws.
template <class T, class Tr, int W> void insert_new(Core<T, Tr, W> &core, const T &shape) {
  const std::uint32_t id = core.leaves.new_id();
  try {
    insert_shape(core, shape, id);
  } catch (...) {
    core.leaves.free_id(id, core.size == 0);
    throw;
  }
}

/// The loop's step for candidate i: inserted (and i kept) unless it
/// intersects a stored shape.
template <class T, class Tr, int W>
void decide_as_the_loop(Core<T, Tr, W> &core, const std::vector<T> &candidates, std::size_t i,
                        std::vector<std::size_t> &kept) {
  if (collides(core, candidates[i])) return;
  insert_new(core, candidates[i]);
  kept.push_back(i);
}

/// A survivor of step 1 for step 2's sweep: its box rounded outwards to
/// float and its rank among the batch's survivors.
struct SweepBox {
  float lo_x, lo_y, hi_x, hi_y;
  std::uint32_t rank;
};

/// Step 3's kept survivors of a batch, as float boxes in rows of four, so
/// that one SIMD pass tests a survivor's box against four of them.
class KeptBoxes {
public:
  void clear() { size_ = 0; }
  /// Adds box b (lo x, lo y, hi x, hi y) as box size().
  void push_back(const float b[4]) {
    // The rows keep their length between batches (clear() leaves it): a
    // batch's pushes then write, without resizing four vectors every
    // fourth box. hi_y_ grows last: if a resize throws, the rows before it
    // are only longer, and the next push grows them all again.
    if (size_ + 4 > hi_y_.size()) {
      const std::size_t length = 2 * hi_y_.size() + 64;
      for (std::vector<float> *row : {&lo_x_, &lo_y_, &hi_x_, &hi_y_}) row->resize(std::max(length, row->size()));
    }
    lo_x_[size_] = b[0];
    lo_y_[size_] = b[1];
    hi_x_[size_] = b[2];
    hi_y_[size_] = b[3];
    ++size_;
  }
  /// False when exact(i) is true for some box i that meets box b (in
  /// ascending i, stopping there); else true.
  template <class Exact> BVH_ALWAYS_INLINE bool none_meets(const float b[4], Exact &&exact) const {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    const __m128 bx0 = _mm_set1_ps(b[0]), by0 = _mm_set1_ps(b[1]), bx1 = _mm_set1_ps(b[2]), by1 = _mm_set1_ps(b[3]);
    for (std::size_t g = 0; g < size_; g += 4) {
      const __m128 meets = _mm_and_ps(
          _mm_and_ps(_mm_cmple_ps(_mm_loadu_ps(&lo_x_[g]), bx1), _mm_cmple_ps(bx0, _mm_loadu_ps(&hi_x_[g]))),
          _mm_and_ps(_mm_cmple_ps(_mm_loadu_ps(&lo_y_[g]), by1), _mm_cmple_ps(by0, _mm_loadu_ps(&hi_y_[g]))));
      unsigned bits = unsigned(_mm_movemask_ps(meets));
      if (size_ - g < 4) bits &= (1u << (size_ - g)) - 1;
      for (; bits != 0; bits &= bits - 1)
        if (exact(g + std::size_t(lowest_bit(bits)))) return false;
    }
#else
    for (std::size_t i = 0; i < size_; ++i)
      if (lo_x_[i] <= b[2] && b[0] <= hi_x_[i] && lo_y_[i] <= b[3] && b[1] <= hi_y_[i] && exact(i)) return false;
#endif
    return true;
  }

private:
  std::vector<float> lo_x_, lo_y_, hi_x_, hi_y_; // (lengths: at least size_ rounded up to 4)
  std::size_t size_ = 0;
};

/// Step 2: the pairs (earlier, later) of survivors, by rank, that
/// intersect, sorted by the later one. The sweep sorts the boxes by their
/// left side; each box then meets only the boxes after it that start before
/// its right side ends, scanned in chunks (on the crew from `crew_min`
/// survivors: below, waking it costs more than it saves).
template <class T, class Tr>
std::vector<std::pair<std::uint32_t, std::uint32_t>> surviving_pairs(const Tr &traits, const std::vector<T> &candidates,
                                                                    const std::vector<std::size_t> &survivors,
                                                                    Crew &crew, unsigned threads, std::size_t crew_min,
                                                                    DisjointClock &clock) {
  std::vector<SweepBox> boxes(survivors.size());
  for (std::size_t r = 0; r < survivors.size(); ++r) {
    float f[4];
    round_out(box_of(traits, candidates[survivors[r]]), f);
    // A NaN side sorts first; it overlaps nothing, as in collides().
    if (!(f[0] == f[0])) f[0] = -std::numeric_limits<float>::infinity();
    boxes[r] = SweepBox{f[0], f[1], f[2], f[3], std::uint32_t(r)};
  }
  // Sorted by left side: on keys of 8 bytes (the side's bits made
  // unsigned-ordered, then the rank), cheaper to compare and move than
  // the boxes.
  std::vector<std::uint64_t> keys(boxes.size());
  for (std::size_t r = 0; r < boxes.size(); ++r) {
    std::uint32_t bits;
    std::memcpy(&bits, &boxes[r].lo_x, sizeof bits);
    bits = bits >> 31 ? ~bits : bits | 0x80000000u; // (-0 before +0: equal sides, either order will do)
    keys[r] = std::uint64_t(bits) << 32 | r;
  }
  std::sort(keys.begin(), keys.end());
  {
    std::vector<SweepBox> sorted(boxes.size());
    for (std::size_t i = 0; i < keys.size(); ++i) sorted[i] = boxes[std::size_t(keys[i] & 0xffffffffu)];
    boxes.swap(sorted);
  }
  clock.lap(0);
  const std::size_t chunk = std::max<std::size_t>(1, std::min<std::size_t>(256, boxes.size() / (4 * threads)));
  const std::size_t chunks = (boxes.size() + chunk - 1) / chunk;
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> found(chunks);
  auto sweep = [&](std::size_t k) {
    const std::size_t end = std::min(boxes.size(), (k + 1) * chunk);
    for (std::size_t p = k * chunk; p < end; ++p) {
      const SweepBox &a = boxes[p];
      for (std::size_t q = p + 1; q < boxes.size() && boxes[q].lo_x <= a.hi_x; ++q) {
        const SweepBox &b = boxes[q];
        if (!(a.lo_y <= b.hi_y && b.lo_y <= a.hi_y && b.lo_x <= a.hi_x && a.lo_x <= b.hi_x)) continue;
        const std::uint32_t early = std::min(a.rank, b.rank), late = std::max(a.rank, b.rank);
        if (traits.intersect(candidates[survivors[early]], candidates[survivors[late]])) found[k].push_back({early, late});
      }
    }
  };
  if (boxes.size() >= crew_min) {
    crew.run(chunks, sweep);
    clock.lap(2);
  } else {
    for (std::size_t k = 0; k < chunks; ++k) sweep(k);
    clock.lap(0);
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (const auto &v : found) pairs.insert(pairs.end(), v.begin(), v.end());
  std::sort(pairs.begin(), pairs.end(), [](const std::pair<std::uint32_t, std::uint32_t> &a,
                                           const std::pair<std::uint32_t, std::uint32_t> &b) {
    return a.second < b.second || (a.second == b.second && a.first < b.first);
  });
  return pairs;
}

/// Step 4's share of the tree for one thread at a time: the subtree at
/// child `child_index` of top node `parent`, and the kept candidates routed
/// to it (positions in step 4's list, ascending).
struct Lane {
  int parent;
  int child_index;
  std::size_t count;                ///< the subtree's count once its routed candidates are in
  Box box;                          ///< its box then
  std::vector<std::size_t> items;   ///< routed, in input order
  std::size_t done = 0;             ///< items inserted
  std::exception_ptr error;         ///< thrown by items[done]
  LaneCache cache;                  ///< its own nodes and slots while shared
};

/// The top of the tree for step 4: the inner nodes above depth `depth`
/// (pre-order) and, below them, the subtrees (one Lane each) that threads
/// insert into at once. Every descent from the root passes top nodes only
/// until it enters exactly one lane's subtree.
struct Frontier {
  std::vector<int> top;
  std::vector<Lane> lanes;
  std::vector<std::pair<int, std::size_t>> lane_of; ///< (subtree root, lane), by node

  template <class T, class Tr, int W> Frontier(const Core<T, Tr, W> &core, int depth) {
    const NodeStore<W> &nodes = core.nodes;
    std::vector<int> stack{core.root};
    while (!stack.empty()) {
      const int n = stack.back();
      stack.pop_back();
      const Node<W> &node = nodes.node(n);
      if (nodes.info(n).depth < depth && !node.is_leaf()) {
        top.push_back(n);
        for (int c = node.num_children - 1; c >= 0; --c) stack.push_back(node.child(c));
      } else {
        lane_of.push_back({n, lanes.size()});
        lanes.push_back(Lane{nodes.info(n).parent, nodes.info(n).child_index, nodes.info(n).count, nodes.box(n), {}, 0, nullptr, {}});
      }
    }
    std::sort(lane_of.begin(), lane_of.end());
  }
  /// The lane whose subtree root is n.
  Lane &lane(int n) { return lanes[std::lower_bound(lane_of.begin(), lane_of.end(), std::make_pair(n, std::size_t(0)))->second]; }
};

/// Step 4, serial: keep[i] inserted for each i, in order, as the loop does.
template <class T, class Tr, int W>
void insert_serially(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                     std::size_t from, std::vector<std::size_t> &kept) {
  for (std::size_t i = from; i < keep.size(); ++i) {
    insert_new(core, candidates[keep[i]]);
    kept.push_back(keep[i]);
  }
}

/// Step 4 on one thread: keep[i] for each i >= from inserted in order, as
/// insert_new() one by one inserts them (the same tree, ids and
/// statistics), with up to kPipe insertions under way at once so that the
/// cache misses of their descents overlap. An insertion writes a node's
/// count and box (and its parent's copy of the box) when it steps there,
/// and reads the node's copies of its children's boxes; a later one steps
/// at depth D only while every earlier one under way is at depth D + 2 or
/// deeper, so it reads nothing they have yet to write and writes nothing
/// they have yet to read. A leaf split changes nothing above the leaf's
/// parent (margin 0: no box changes), and a later insertion is never that
/// deep while the split waits. Each insertion finishes at its leaf (push
/// or split, then its rebalance) only as the oldest under way, and before
/// a rebuild the later ones are rolled back (their counts and boxes) and
/// start again. Needs margin 0 and an inner root. If an insertion throws,
/// the later ones are rolled back and the exception passes on: the tree
/// then holds the candidates before it, as the loop's does.
template <class T, class Tr, int W>
void insert_pipelined(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                      std::size_t from, std::vector<std::size_t> &kept) {
  BVH_INVARIANT(core.margin == 0 && core.root >= 0 && !core.nodes.node(core.root).is_leaf(),
                "insert_pipelined() needs margin 0 and an inner root");
  constexpr int kPipe = 4;
  struct Cursor {
    std::size_t item;   // in keep
    Box box;            // the shape's own (at margin 0 also what it adds to boxes)
    int n;              // the node of its next step, or (at_leaf) the leaf it stepped at
    int depth;          // n's
    int prev, above;    // as in insert_below
    std::size_t prev_count;
    Box leaf_box;       // (at_leaf) the leaf's box before
    bool at_leaf;
  };
  NodeStore<W> &nodes = core.nodes;
  const std::size_t smallest = min_rebuild(core);
  Cursor ring[kPipe];
  int head = 0, size = 0;
  const auto at = [&](int k) -> Cursor & { return ring[(head + k) % kPipe]; };
  const auto start = [&](Cursor &c, std::size_t item) {
    c.item = item;
    c.box = box_of(core.traits, candidates[keep[item]]);
    c.n = core.root;
    c.depth = 0;
    c.prev = c.above = -1;
    c.prev_count = 0;
    c.at_leaf = false;
  };
  const auto roll_back = [&](const Cursor &c) noexcept {
    undo_descent(core, c.at_leaf ? c.n : nodes.info(c.n).parent, -1, c.at_leaf ? &c.leaf_box : nullptr);
  };
  // One step, and a prefetch of what the cursor's next step reads.
  const auto step = [&](Cursor &c) BVH_LAMBDA_INLINE {
    if (descend_step(nodes, c.n, c.prev, c.above, c.prev_count, c.leaf_box, c.box, smallest)) {
      c.at_leaf = true;
      const Node<W> &leaf = nodes.node(c.n);
      if (leaf.leaf().has_slot()) core.leaves.prefetch_end(leaf);
      return;
    }
    ++c.depth;
    prefetch_lines(&nodes.node(c.n), sizeof(Node<W>));
    prefetch_lines(&nodes.info(c.n), sizeof(Info));
  };
  std::size_t next = from;
  while (size > 0 || next < keep.size()) {
    int shallowest = std::numeric_limits<int>::max(); // of the earlier ones under way
    for (int k = 0; k < size; ++k) {
      Cursor &c = at(k);
      if (c.at_leaf && k == 0) { // the oldest finishes
        const std::uint32_t id = core.leaves.new_id();
        int n;
        try {
          n = insert_at_leaf(core, core.root, c.n, c.leaf_box, c.box, candidates[keep[c.item]], id);
        } catch (...) {
          core.leaves.free_id(id, core.size == 0);
          for (int j = size - 1; j >= 1; --j) roll_back(at(j));
          throw;
        }
        ++core.size;
        kept.push_back(keep[c.item]);
        const int scapegoat = insert_scapegoat(core, n, c.above, -1, size == 1);
        if (scapegoat >= 0) { // the later ones start again on the rebuilt tree
          for (int j = size - 1; j >= 1; --j) roll_back(at(j));
          rebalance(core, scapegoat, Cut::by_rule);
          for (int j = 1; j < size; ++j) start(at(j), at(j).item);
        }
        head = (head + 1) % kPipe;
        --size;
        --k;
        continue;
      }
      if (!c.at_leaf && shallowest >= c.depth + 2) step(c);
      shallowest = std::min(shallowest, c.depth);
    }
    if (next < keep.size() && size < kPipe && shallowest >= 2) {
      start(at(size), next++);
      ++size;
    }
  }
}

/// The most nodes and slots one insertion into a subtree of m shapes may
/// allocate: a split of at most m + 1 shapes and a rebuild of as many
/// (a build of k shapes makes fewer than 2k nodes and at most k slots).
inline std::size_t insertion_allocations(std::size_t m) { return 6 * (m + 1) + 8; }

/// Step 4 after an insertion in a lane threw: brings the tree to what the
/// loop holds when the first candidate (in input order) whose insertion
/// throws does so, then rethrows that exception. The routed candidates
/// not inserted are taken out of the top's counts and boxes and give their
/// ids back; those of them before the first failure are inserted now, in
/// order; those inserted after it are erased again. The tree is then valid
/// and holds exactly the kept candidates before the failure, though not in
/// the loop's shape (the erases mend it their own way) and not with the
/// loop's ids. If an erase here throws too, that candidate stays.
template <class T, class Tr, int W>
[[noreturn]] void finish_failed_lanes(Core<T, Tr, W> &core, const std::vector<T> &candidates,
                                      const std::vector<std::size_t> &keep, Frontier &frontier,
                                      const std::vector<std::uint32_t> &ids, std::size_t next) {
  NodeStore<W> &nodes = core.nodes;
  std::size_t first = keep.size();
  std::exception_ptr error;
  for (const Lane &lane : frontier.lanes)
    if (lane.error && lane.items[lane.done] < first) {
      first = lane.items[lane.done];
      error = lane.error;
    }
  std::vector<std::size_t> missing, unused;
  for (const Lane &lane : frontier.lanes)
    for (std::size_t k = lane.done; k < lane.items.size(); ++k) {
      for (int a = lane.parent; a >= 0; a = nodes.info(a).parent) --nodes.info(a).count;
      --core.size;
      unused.push_back(lane.items[k]);
      if (lane.items[k] < first) missing.push_back(lane.items[k]);
    }
  for (const Lane &lane : frontier.lanes) {
    const int root = nodes.node(lane.parent).child(lane.child_index);
    nodes.set_box(root, core.fitted_box(root));
  }
  for (auto a = frontier.top.rbegin(); a != frontier.top.rend(); ++a) nodes.set_box(*a, core.fitted_box(*a));
  std::sort(unused.rbegin(), unused.rend());
  for (std::size_t i : unused) core.leaves.free_id(ids[i - next], false);
  std::sort(missing.begin(), missing.end());
  for (std::size_t i : missing) {
    try {
      insert_new(core, candidates[keep[i]]);
    } catch (...) {
      first = i;
      error = std::current_exception();
      break;
    }
  }
  for (const Lane &lane : frontier.lanes)
    for (std::size_t k = 0; k < lane.done; ++k) {
      if (lane.items[k] < first) continue;
      const typename LeafStore<T>::Loc at = core.locate(ids[lane.items[k] - next]);
      try {
        erase_shape(core, at.leaf, at.index, Cut::in_order);
      } catch (...) {
      }
    }
  std::rethrow_exception(error);
}

/// The fewest threads worth the lanes at width W with leaves of up to
/// `split_threshold` shapes. Two lanes beat the pipeline on deep trees
/// (narrow nodes or small leaves), where each insertion's descent is long;
/// on a wide tree of large leaves, a few levels deep, one pipelined thread
/// inserts faster than two lanes, which each descend one insertion at a
/// time behind the driver's routing (docs/performance.txt, NODE WIDTH).
template <int W> constexpr unsigned disjoint_lanes_threads(int split_threshold) {
  if (BVH_DISJOINT_LANES_THREADS > 0) return std::max(2u, unsigned(BVH_DISJOINT_LANES_THREADS));
  return W > kCourseWidth && split_threshold >= 16 ? 3u : 2u;
}

/// Step 4: keep[i] inserted, in order, for every i, with exactly the loop's
/// tree (insert_new one by one), on the crew's threads. A candidate's
/// descent first passes the top of the tree (Frontier), then stays in one
/// subtree below it; what it changes at the top (counts and boxes), and
/// so which subtree it enters, depends only on the candidates before it, so
/// the driver routes every candidate through the top in order ("routing"),
/// and then the threads insert each subtree's candidates into it, in
/// order, one thread per subtree at a time ("lanes"). Insertions into
/// different subtrees touch disjoint nodes, slots and ids, and their order
/// relative to one another changes nothing; allocation takes a lock
/// (SharedAlloc). Where the loop would change the top itself (a rebuild of
/// a lopsided top node), routing stops: the lanes catch up, that
/// candidate is inserted alone, and routing starts again from a new
/// frontier. Lanes run only on a tree without margin (boxes are then always
/// their contents' union, so nothing in a subtree refits the top) and
/// large enough to be worth it.
template <class T, class Tr, int W>
void insert_in_order(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                     unsigned threads, Crew &crew, DisjointClock &clock, std::vector<std::size_t> &kept) {
  const std::size_t lanes_min = core.tuning.disjoint_lanes_min; // a smaller tree: serially
  NodeStore<W> &nodes = core.nodes;
  const bool lanes_pay = threads >= disjoint_lanes_threads<W>(core.split_threshold);
  if (!lanes_pay && core.margin == 0 && core.root >= 0 && !nodes.node(core.root).is_leaf()) {
    insert_pipelined(core, candidates, keep, 0, kept);
    clock.lap(3);
    return;
  }
  int depth = 0; // the frontier's: about 16 subtrees a thread
  for (std::size_t lanes = 1; lanes < 16 * std::size_t(threads); lanes *= std::size_t(W)) ++depth;
  for (std::size_t next = 0; next < keep.size();) {
    if (!lanes_pay || core.margin != 0 || core.root < 0 || nodes.node(core.root).is_leaf() || core.size < lanes_min ||
        keep.size() - next < 64) {
      insert_serially(core, candidates, keep, next, kept);
      clock.lap(3);
      return;
    }
    Frontier frontier(core, depth);
    // Routing, until a candidate would change the top or all are routed.
    const std::size_t smallest = min_rebuild(core);
    std::vector<std::uint32_t> ids;
    std::size_t end = next; // candidates [next, end) are routed
    std::exception_ptr routing_error;
    int path[32];
    for (; end < keep.size(); ++end) {
      try {
        const Box box = core.fat(box_of(core.traits, candidates[keep[end]]));
        int d = 0, n = core.root;
        while (nodes.info(n).depth < depth && !nodes.node(n).is_leaf()) {
          path[d++] = n;
          n = choose_child(nodes.node(n), box);
        }
        Lane &lane = frontier.lane(n);
        // A subtree that is one leaf and overflows would give its split
        // to its parent, a top node (splice): the loop's change of the top.
        bool top_lopsided = W != kCourseWidth && nodes.node(n).is_leaf() && d > 0 &&
                            !core.is_leaf_size(lane.count + 1, nodes.info(n).depth);
        for (int i = d - 1; i >= 0 && !top_lopsided; --i) {
          const std::size_t count = nodes.info(path[i]).count + 1;
          const std::size_t below = i == d - 1 ? lane.count + 1 : nodes.info(path[i + 1]).count + 1;
          top_lopsided = count >= smallest && lopsided(below, count);
        }
        if (top_lopsided) break;
        ids.push_back(core.leaves.new_id());
        for (int i = 0; i < d; ++i) {
          ++nodes.info(path[i]).count;
          nodes.extend_box(path[i], box);
        }
        // The subtree's count and box are the lane's to change; routing
        // needs only the parent's copy of the box.
        ++lane.count;
        lane.box.extend(box);
        nodes.set_parent_copy(n, lane.box);
        lane.items.push_back(end);
        ++core.size;
      } catch (...) {
        routing_error = std::current_exception();
        break;
      }
    }
    clock.lap(3);
    // The lanes. The stores get room for every thread's worst insertion
    // and for the usual allocations of all (`slack`); a lane stops when
    // allocations have used up the slack, and finishes serially.
    std::size_t largest = 0;
    for (const Lane &lane : frontier.lanes) largest = std::max(largest, lane.count);
    // Lane caches hold up to two chunks of nodes and of each class's slots.
    // Leaves hold at most split_threshold shapes, except at a depth limit.
    const std::size_t largest_leaf = core.depth_limit > 0 ? largest + 1 : std::size_t(core.split_threshold) + 1;
    const std::size_t kinds = 1 + std::max(LeafPool<T>::classes_for(largest_leaf), core.leaves.class_count());
    const std::size_t cached = 2 * LaneCache::kChunk * kinds;
    const std::size_t slack = 16 * (end - next) + frontier.lanes.size() * cached + 1024;
    const std::size_t room = std::size_t(threads) * (insertion_allocations(largest) + cached) + slack;
    SharedAlloc shared;
    std::atomic<bool> failed{false};
    bool shareable = true;
    try {
      nodes.reserve_spare(room);
      core.leaves.reserve_spare(room, largest_leaf);
      for (Lane &lane : frontier.lanes) lane.cache.reserve(core.leaves.class_count());
    } catch (...) {
      shareable = false; // (then the lanes run on this thread alone)
    }
    auto run_lane = [&](std::size_t k) {
      Lane &lane = frontier.lanes[k];
      struct InLane { // (this thread's allocations go to the lane's cache meanwhile)
        Lane &lane;
        Core<T, Tr, W> &core;
        InLane(Lane &l, Core<T, Tr, W> &c) : lane(l), core(c) { LaneCache::current() = &lane.cache; }
        ~InLane() {
          LaneCache::current() = nullptr;
          core.nodes.take_back(lane.cache.nodes);
          core.leaves.take_back(lane.cache.slots);
        }
      } in_lane(lane, core);
      for (; lane.done < lane.items.size(); ++lane.done) {
        if (failed.load(std::memory_order_relaxed)) return;
        if (nodes.shared() && shared.taken.load(std::memory_order_relaxed) > slack) return;
        const std::size_t i = lane.items[lane.done];
        try {
          const T &shape = candidates[keep[i]];
          const int top = nodes.node(lane.parent).child(lane.child_index);
          int above;
          const int n = insert_below(core, top, box_of(core.traits, shape), shape, ids[i - next], &above);
          rebalance(core, insert_scapegoat(core, n, above, lane.parent), Cut::by_rule);
        } catch (...) {
          lane.error = std::current_exception();
          failed = true;
          return;
        }
      }
    };
    if (shareable && threads > 1) {
      nodes.share(&shared);
      core.leaves.share(&shared);
      crew.run(frontier.lanes.size(), run_lane);
      nodes.share(nullptr);
      core.leaves.share(nullptr);
      for (Lane &lane : frontier.lanes) {
        nodes.take_back(lane.cache.nodes);
        core.leaves.take_back(lane.cache.slots);
      }
      clock.lap(4);
    }
    for (std::size_t k = 0; k < frontier.lanes.size() && !failed; ++k) run_lane(k); // what is left
    clock.lap(3);
    if (failed) finish_failed_lanes(core, candidates, keep, frontier, ids, next);
    for (std::size_t i = next; i < end; ++i) kept.push_back(keep[i]);
    next = end;
    if (routing_error) std::rethrow_exception(routing_error);
    if (next < keep.size()) { // it changes the top
      insert_new(core, candidates[keep[next]]);
      kept.push_back(keep[next]);
      ++next;
      clock.lap(3);
    }
  }
}

/// The batches of insert_disjoint (run by the crew's driver).
template <class T, class Tr, int W>
void insert_disjoint_batches(Core<T, Tr, W> &core, const std::vector<T> &candidates, unsigned threads, Crew &crew,
                             std::vector<std::size_t> &kept) {
  const std::size_t n = candidates.size();
  // Batch sizes: starting small (on an empty tree all of the first batch
  // survives), within [kMin, kMax]; step 2 runs from kPairwise survivors.
  // On one thread a batch is only there so that its searches can run
  // interleaved (collides_each), and steps 2 and 3 are one: each survivor
  // is tested against the batch's kept ones (KeptBoxes), which costs the
  // square of the survivors, with no sort and no pair list. A small batch
  // keeps that short and the nodes its searches brought in still cached
  // when step 4 inserts.
  const bool serial = threads == 1;
  const std::size_t kSerialBatch = 128;
  const std::size_t kMin = serial ? kSerialBatch : 64 * std::size_t(threads);
  const std::size_t kMax = serial ? kSerialBatch : std::size_t(1) << 17, kPairwise = 32;
  const std::size_t target = 2048 * std::size_t(threads); // survivors a batch aims at
  std::size_t batch = kMin;
  std::vector<unsigned char> hit;
  std::vector<std::size_t> survivors, keep;
  std::vector<unsigned char> survivor_kept;
  KeptBoxes kept_boxes; // keep[i]'s box, rounded once
  DisjointClock clock;
  const std::size_t interleave_min = core.tuning.disjoint_interleave_min;
  for (std::size_t start = 0; start < n;) {
    if (serial && core.size < interleave_min) { // the loop itself
      decide_as_the_loop(core, candidates, start++, kept);
      continue;
    }
    const std::size_t m = std::min(batch, n - start);
    std::size_t s = 0; // the batch's survivors
    try {
      // 1. Against the tree as it stands (read only).
      hit.assign(m, 0);
      const std::size_t chunk = serial ? m : std::max<std::size_t>(1, std::min<std::size_t>(128, m / (4 * threads)));
      const bool interleave = core.size >= interleave_min;
      auto query = [&](std::size_t k) {
        const std::size_t end = std::min(m, (k + 1) * chunk);
        if (interleave)
          collides_each(core, candidates.data() + start + k * chunk, end - k * chunk, hit.data() + k * chunk);
        else
          for (std::size_t j = k * chunk; j < end; ++j) hit[j] = collides(core, candidates[start + j]) ? 1 : 0;
      };
      crew.run((m + chunk - 1) / chunk, query);
      clock.lap(1);
      survivors.clear();
      for (std::size_t j = 0; j < m; ++j)
        if (!hit[j]) survivors.push_back(start + j);
      s = survivors.size();
      // 2. and 3. Among themselves, in input order.
      survivor_kept.assign(s, 0);
      keep.clear();
      if (s < kPairwise || serial) {
        clock.lap(0);
        kept_boxes.clear();
        for (std::size_t r = 0; r < s; ++r) {
          const T &c = candidates[survivors[r]];
          float b[4];
          round_out(box_of(core.traits, c), b);
          const bool free =
              kept_boxes.none_meets(b, [&](std::size_t i) { return core.traits.intersect(candidates[keep[i]], c); });
          if (!free) continue;
          keep.push_back(survivors[r]);
          kept_boxes.push_back(b);
        }
      } else {
        const auto pairs =
            surviving_pairs(core.traits, candidates, survivors, crew, threads, core.tuning.disjoint_sweep_min, clock);
        std::size_t p = 0;
        for (std::uint32_t r = 0; r < s; ++r) {
          bool free = true;
          for (; p < pairs.size() && pairs[p].second == r; ++p) free = free && !survivor_kept[pairs[p].first];
          if (!free) continue;
          survivor_kept[r] = 1;
          keep.push_back(survivors[r]);
        }
      }
    } catch (...) {
      if (!serial) throw;
      // One thread keeps the loop's behaviour exactly: the batch is decided
      // again as the loop decides it, one candidate at a time, so that the
      // loop's candidate throws (or, if nothing throws again, the batch
      // completes). Nothing of the batch was inserted yet.
      for (std::size_t i = start; i < start + m; ++i) decide_as_the_loop(core, candidates, i, kept);
      start += m;
      continue;
    }
    clock.lap(3);
    // 4. Inserted, in input order.
    insert_in_order(core, candidates, keep, threads, crew, clock, kept);
    start += m;
    if (2 * s < target) batch = std::min(kMax, 2 * batch);
    else if (s > 2 * target) batch = std::max(kMin, batch / 2);
  }
}

/// Inserts, in order, each candidate that intersects no stored shape and no
/// candidate inserted before it, as the loop above does, on `threads`
/// threads (0: the hardware's; 1: one thread, whose batches only let the
/// searches run interleaved). Returns the indices of those inserted,
/// ascending. If a worker or an insertion throws, the first exception is
/// rethrown and the tree holds what the loop holds after candidates [0,
/// k), with k the first candidate of the batch in progress (a throw in
/// step 1 or 2) or the first whose insertion threw (step 4; with 1 thread,
/// the candidate whose decision or insertion the loop's throw comes from);
/// after a throw in a lane, in another shape and with other ids than the
/// loop's (finish_failed_lanes).
template <class T, class Tr, int W>
std::vector<std::size_t> insert_disjoint(Core<T, Tr, W> &core, const std::vector<T> &candidates, unsigned threads) {
  std::vector<std::size_t> kept;
  threads = threads_for(threads);
  if (candidates.empty()) return kept;
  if (threads == 1) {
    Crew crew; // (no helper: the driver runs every chunk)
    insert_disjoint_batches(core, candidates, 1, crew, kept);
    return kept;
  }
  // The first thread to arrive drives, the others help until it is done
  // (also when it throws). If threads cannot be started, parallel_for runs
  // the driver alone and then the helpers, which find it done.
  // The lanes reserve room for their worst case in the stores' arrays;
  // what is left of it goes back at the end, also after a throw.
  struct Shrink {
    Core<T, Tr, W> &core;
    ~Shrink() {
      core.nodes.shrink_spare();
      core.leaves.shrink_spare();
    }
  } shrink{core};
  Crew crew;
  std::atomic<bool> driving{false};
  parallel_for(threads, threads, [&](std::size_t) {
    if (driving.exchange(true)) {
      crew.help();
      return;
    }
    struct Finish {
      Crew &crew;
      ~Finish() { crew.finish(); }
    } finish{crew};
    insert_disjoint_batches(core, candidates, threads, crew, kept);
  });
  return kept;
}

} // namespace detail

// ===========================================================================
// 9. BVH<T>: the facade
// ===========================================================================

/// A bounding volume hierarchy (ternary, the course's, unless Width says
/// otherwise) over values of type T: shapes, or
/// anything a Traits adaptor can read (ids into the user's own arrays).
///
/// What T must provide: copy construction and assignment, and what Traits
/// reads. With the default Traits, shape_traits<T> (the course's shapes
/// provide exactly this):
///  - `getBox()`, any box type box_traits understands (by default one with
///    `getMin()` and `getMax()`, points with `x` and `y`);
///  - `getCenter()`, with `x` and `y` (the build rule sorts by it);
///  - a free `intersect(const T&, const T&)` found by argument-dependent
///    lookup (collision, query by shape, all pairs).
/// A few members need more, say so, and compile only when used:
/// erase(value) needs `==`, nearest() a free `distance(const Point&, const
/// T&)`, first_hit() a free `ray_hit(const Point&, const Point&, const
/// T&)`, render_recolor() `setColor(const Color&)`. Shapes live only in
/// leaves, each exactly once; every node knows the tight box of its
/// subtree. The const members only read the tree: any number of threads may
/// call them at once while no thread changes the tree (the first handle
/// lookup builds the handle table, under a lock: see contains()).
///
/// Exceptions (docs/library.txt, EXCEPTIONS): T's copy and move may throw,
/// its destructor must not (static_assert); where stored shapes move the
/// tree uses std::move_if_noexcept, so a T whose move may throw is copied
/// there. Each member's comment states its guarantee: strong for insert,
/// erase(handle), erase(iterator), update, set_margin and copy assignment;
/// basic for construct (left empty) and erase(value); never throwing for
/// moves, swap, clear. A Traits adaptor's copy and move must not throw.
///
/// Width: children per inner node, 2 to 8; 3 is the course's tree. At
/// other widths the build rules fill nodes (CountCut: the course's rule
/// halves by median, SAH cuts in two where cheapest, until W groups).
template <class T, class Traits = shape_traits<T>, int Width = detail::kCourseWidth> class BVH {
  static_assert(Width >= detail::kMinWidth && Width <= detail::kMaxWidth, "BVH<T, Traits, Width>: Width is 2 to 8");
  static_assert(std::is_nothrow_destructible<T>::value, "BVH<T>: T's destructor must not throw");
  static_assert(std::is_nothrow_copy_constructible<Traits>::value && std::is_nothrow_move_assignable<Traits>::value,
                "BVH<T, Traits>: the traits' copy and move must not throw (moves and swap rely on it)");
  using Box = detail::Box;
  using Core = detail::Core<T, Traits, Width>;
  /// Box types other than T: what query(box, f) and overlapping(box) take.
  template <class B>
  using if_box = typename std::enable_if<!std::is_convertible<const B &, const T &>::value, int>::type;

public:
  /// `depth_limit` value meaning "no limit" (the course's default of 0).
  static constexpr int unlimited = 0;
  /// Scenes smaller than this are built without threads.
  static constexpr std::size_t kParallelMin = detail::kParallelMin;
  /// How construct() and the splits and rebuilds of insert() cut a node.
  using BuildRule = detail::BuildRule;

  /// An empty tree. A node holding more than `split_threshold` shapes is
  /// split unless it is at depth `depth_limit` (root = depth 0;
  /// `depth_limit <= 0` means unlimited). A `split_threshold` below 1 is
  /// taken as 1 (every leaf then holds one shape, above the depth limit).
  explicit BVH(int split_threshold = 4, int depth_limit = unlimited, Traits traits = Traits())
      : core_(std::move(traits), split_threshold < 1 ? 1 : split_threshold,
              depth_limit <= 0 ? unlimited : depth_limit) {}

  /// Deep copy (nothing recurses: every part lives in arrays). If it
  /// throws, what it had made is given back (the source is untouched).
  BVH(const BVH &) = default;
  /// Deep copy; self-assignment is safe. Strong: copy, then swap.
  BVH &operator=(const BVH &other) {
    if (this != &other) {
      BVH copy(other);
      this->swap(copy);
    }
    return *this;
  }
  /// Takes `other`'s shapes and parameters; `other` is left a valid empty
  /// tree with its split_threshold and depth_limit. Never throws.
  BVH(BVH &&other) noexcept : core_(other.core_.traits, other.core_.split_threshold, other.core_.depth_limit) {
    take(other);
  }
  /// Takes `other`'s shapes and parameters; `other` is left a valid empty
  /// tree. Never throws.
  BVH &operator=(BVH &&other) noexcept {
    if (this != &other) take(other);
    return *this;
  }
  ~BVH() = default;
  /// Exchanges the shapes and parameters of two trees. Never throws.
  void swap(BVH &other) noexcept { core_.swap(other.core_); }
  /// a.swap(b).
  friend void swap(BVH &a, BVH &b) noexcept { a.swap(b); }

  /// A stored shape's name: an id and that id's generation, as Box2D's
  /// shape ids carry a revision. insert() returns it; construct(elements)
  /// names elements[i] constructed(i), which on a tree that never held a
  /// shape before is `handle{std::uint32_t(i)}` (generation 0). It stays
  /// valid until that shape is erased, whatever else is inserted, erased,
  /// updated or rebuilt. Then it is stale: a later insert() may reuse its
  /// id (the last freed first), but with a newer generation, so the old
  /// handle never names the new shape. (Generations are 32-bit: an id
  /// reused 2^32 times would come back to an old handle's.) contains() is
  /// false for a stale handle, or for one that never named a shape of this
  /// tree. get(), find(), erase() and update() with such a handle fail a
  /// BVH_ASSERT (a debug build aborts); with the checks off (NDEBUG) they
  /// do nothing and say so: get() throws std::out_of_range, find() returns
  /// end(), erase() and update() return false.
  struct handle {
    std::uint32_t id;             ///< the id, reused once its shape is erased
    std::uint32_t generation = 0; ///< the id's generation when it was given
    friend bool operator==(handle a, handle b) { return a.id == b.id && a.generation == b.generation; }
    friend bool operator!=(handle a, handle b) { return !(a == b); }
  };

  /// A bidirectional iterator over every stored shape, leaf by leaf from
  /// left to right. Shapes are read-only through it (changing one could
  /// break its node's box).
  class iterator {
  public:
    using iterator_category = std::bidirectional_iterator_tag;
    using value_type = T;
    using difference_type = std::ptrdiff_t;
    using pointer = const T *;
    using reference = const T &;

    /// A singular iterator; only assignment and comparison are valid.
    iterator() = default;

    /// The shape it points to (not end()).
    reference operator*() const {
      BVH_ASSERT(tree_ != nullptr && leaf_ >= 0, "dereferencing end() or a singular iterator");
      return shapes()[index_];
    }
    /// Member access on the shape it points to.
    pointer operator->() const { return &**this; }
    /// The handle of the shape it points to (not end()).
    handle id() const {
      BVH_ASSERT(tree_ != nullptr && leaf_ >= 0, "id() of end() or a singular iterator");
      const std::uint32_t id = tree_->core_.leaves.ids(tree_->core_.nodes.node(leaf_))[index_];
      return handle{id, tree_->core_.leaves.generation(id)};
    }

    /// Next shape (end() after the last; not from end()).
    iterator &operator++() {
      BVH_ASSERT(tree_ != nullptr && leaf_ >= 0, "incrementing end() or a singular iterator");
      if (++index_ == shapes().size()) {
        leaf_ = tree_->core_.nodes.next_leaf(leaf_);
        index_ = 0;
      }
      return *this;
    }
    /// Previous shape (from end(): the last shape; not from begin()).
    iterator &operator--() {
      BVH_ASSERT(tree_ != nullptr, "decrementing a singular iterator");
      if (leaf_ >= 0 && index_ > 0) {
        --index_;
        return *this;
      }
      BVH_ASSERT(leaf_ >= 0 || tree_->core_.root >= 0, "decrementing end() of an empty tree");
      leaf_ = leaf_ < 0 ? tree_->core_.nodes.rightmost_leaf(tree_->core_.root) : tree_->core_.nodes.prev_leaf(leaf_);
      BVH_ASSERT(leaf_ >= 0, "decrementing begin()");
      index_ = shapes().size() - 1;
      return *this;
    }
    /// Post-increment: steps forward, returns the old position.
    iterator operator++(int) {
      iterator old = *this;
      ++*this;
      return old;
    }
    /// Post-decrement: steps back, returns the old position.
    iterator operator--(int) {
      iterator old = *this;
      --*this;
      return old;
    }
    friend bool operator==(const iterator &a, const iterator &b) {
      return a.tree_ == b.tree_ && a.leaf_ == b.leaf_ && a.index_ == b.index_;
    }
    friend bool operator!=(const iterator &a, const iterator &b) { return !(a == b); }

  private:
    friend class BVH;
    iterator(const BVH *tree, int leaf, std::size_t index) : tree_(tree), leaf_(leaf), index_(index) {}
    detail::Span<const T> shapes() const { return tree_->core_.leaves.shapes(tree_->core_.nodes.node(leaf_)); }
    const BVH *tree_ = nullptr;
    int leaf_ = -1; // -1: end()
    std::size_t index_ = 0;
  };
  /// The same iterator: shapes are never writable through iteration.
  using const_iterator = iterator;

  /// First shape in leaf order (end() when empty).
  iterator begin() const noexcept {
    return core_.root < 0 ? end() : iterator(this, core_.nodes.leftmost_leaf(core_.root), 0);
  }
  /// One past the last shape.
  iterator end() const noexcept { return iterator(this, -1, 0); }

  /// Number of stored shapes.
  std::size_t size() const noexcept { return core_.size; }
  /// True when no shape is stored.
  bool empty() const noexcept { return core_.size == 0; }
  /// The traits (the adaptor given at construction).
  const Traits &traits() const noexcept { return core_.traits; }
  /// The split threshold given at construction (at least 1).
  int split_threshold() const noexcept { return core_.split_threshold; }
  /// The depth limit (`unlimited`, i.e. 0, for none).
  int depth_limit() const noexcept { return core_.depth_limit; }
  /// The box of everything stored, grown by margin() as the leaves' boxes
  /// are; a default BoundingBox when empty (with this project's shapes.h an
  /// empty box, with the course's the origin).
  BoundingBox bounds() const {
    if (core_.root < 0) return BoundingBox();
    const Box &b = core_.nodes.box(core_.root);
    return BoundingBox(Point(b.x0, b.y0), Point(b.x1, b.y1));
  }
  /// Number of nodes, inner and leaf.
  std::size_t node_count() const noexcept { return core_.nodes.live(); }

  /// The tree's memory by part, in bytes (memory()). Only what the tree
  /// holds between calls is counted, plus build_transient, what a build
  /// holds while it runs.
  struct memory_use {
    std::size_t nodes = 0;      ///< the node arrays (Node and Info, in whole blocks) and the free-node list
    std::size_t shapes = 0;     ///< the stored shapes: size() * sizeof(T)
    std::size_t shape_ids = 0;  ///< the id kept beside each stored shape: size() * 4
    std::size_t leaf_slack = 0; ///< leaf pool places holding no shape (room in slots, free slots, blocks not yet filled), with their ids' places
    std::size_t pool_index = 0; ///< the leaf pool's bookkeeping: slot sizes, free-slot lists, block tables
    std::size_t handles = 0;    ///< the handle table (id -> leaf and position), 0 until a handle is first looked up
    std::size_t free_ids = 0;   ///< the ids given back, with their room, and each id's generation once a shape is erased
    std::size_t scratch = 0;    ///< build memory kept for the next split or rebuild (the largest one's)
    /// Not held now: what construct() of size() shapes holds besides the
    /// finished tree while it runs, and gives back when it returns: a copy
    /// of every shape (the course rule's items with their centre and input
    /// position; the SAH rule's shapes with their ids).
    std::size_t build_transient = 0;
    /// Everything held now (build_transient is not).
    std::size_t total() const noexcept {
      return nodes + shapes + shape_ids + leaf_slack + pool_index + handles + free_ids + scratch;
    }
  };
  /// The bytes the tree holds, by part. O(leaves).
  memory_use memory() const noexcept {
    memory_use m;
    m.nodes = core_.nodes.bytes();
    const auto pool = core_.leaves.pool_bytes();
    m.shapes = pool.shapes;
    m.shape_ids = pool.ids;
    m.leaf_slack = pool.slack;
    m.pool_index = pool.index;
    m.handles = core_.leaves.table_bytes();
    m.free_ids = core_.leaves.free_id_bytes();
    const auto &scratch = core_.scratch.value;
    m.scratch = scratch.items.capacity() * sizeof(scratch.items[0]) + scratch.tasks.capacity() * sizeof(scratch.tasks[0]);
    m.build_transient =
        core_.size * (core_.rule == BuildRule::course ? sizeof(detail::Item<T, Traits>) : sizeof(detail::Tagged<T>));
    return m;
  }

  /// How full the nodes are: inner nodes and leaves, and their mean
  /// fill, children over Width and shapes over split_threshold (a leaf at
  /// the depth limit may hold more: its fill is then above 1).
  struct fill_factor {
    std::size_t inner = 0;    ///< inner nodes
    std::size_t leaves = 0;   ///< leaves
    double children = 0;      ///< mean children of an inner node / Width
    double shapes = 0;        ///< mean shapes of a leaf / split_threshold
  };
  /// The fill factor of the nodes. O(nodes).
  fill_factor fill() const {
    fill_factor f;
    std::size_t children = 0;
    detail::for_each_preorder(core_.nodes, core_.root, [&](int n) {
      const auto &node = core_.nodes.node(n);
      if (node.is_leaf()) {
        ++f.leaves;
      } else {
        ++f.inner;
        children += std::size_t(node.num_children);
      }
    });
    if (f.inner) f.children = double(children) / double(f.inner) / Width;
    if (f.leaves) f.shapes = double(core_.size) / double(f.leaves) / core_.split_threshold;
    return f;
  }

  /// Chooses the build rule for later builds (course by default: the
  /// course's expected output follows it).
  void set_build_rule(BuildRule rule) noexcept { core_.rule = rule; }
  /// The build rule in use.
  BuildRule build_rule() const noexcept { return core_.rule; }
  /// Threads construct() may use: 0 (the default) for
  /// std::thread::hardware_concurrency(), 1 for none besides the caller.
  /// The tree built is the same whatever the number; scenes under
  /// kParallelMin shapes are always built by the caller alone.
  void set_build_threads(unsigned threads) noexcept { core_.build_threads = threads; }
  /// The threads construct() uses for large scenes (at least 1).
  unsigned build_threads() const { return detail::threads_for(core_.build_threads); }

  /// Removes every shape; every handle becomes invalid. Never throws.
  void clear() noexcept { core_.clear(); }

  /// Replaces the contents with `elements`, built top-down by the build
  /// rule (the course's: see detail::CourseRule); elements[i] gets the
  /// handle constructed(i), of id i. Basic guarantee: if it throws (a copy
  /// of a shape, or memory), the tree is left empty and valid, its
  /// parameters kept, and every old handle is invalid. An element outside
  /// the supported values (docs/library.txt, SUPPORTED VALUES) throws
  /// std::invalid_argument naming the first one, before anything changes.
  void construct(const std::vector<T> &elements) {
    detail::require_supported(core_.traits, elements, "construct", "elements");
    detail::construct(core_, elements);
  }
  /// The handle the last construct(elements) gave elements[i] (i below
  /// elements.size()): id i, and a generation above every handle's the tree
  /// gave before (0 when it never held a shape). Stale, as any handle, once
  /// that shape is erased. O(1), never throws.
  handle constructed(std::size_t i) const noexcept {
    return handle{std::uint32_t(i), core_.leaves.constructed_generation()};
  }

  /// Adds one shape (the insertion strategy: detail::insert_shape) and
  /// returns its handle. Strong: if it throws, the tree is as it was (its
  /// shapes, their order, every handle). A rebuild for balance after the
  /// insert that throws is given up: the shape is in, the subtree stays as
  /// it was, and the exception is not passed on. A shape outside the
  /// supported values throws std::invalid_argument.
  handle insert(const T &shape) {
    detail::require_supported(core_.traits, shape, "insert");
    const bool reused = !core_.leaves.free_ids().empty();
    const std::uint32_t id = core_.leaves.new_id();
    try {
      detail::insert_shape(core_, shape, id);
    } catch (...) {
      core_.leaves.unnew_id(id, reused);
      core_.leaves.settle_ids();
      throw;
    }
    core_.leaves.settle_ids();
    return handle{id, core_.leaves.generation(id)};
  }

  /// Discard-overlap (Poisson-disk) sampling on `threads` threads (0, the
  /// default: std::thread::hardware_concurrency(); 1: no other thread):
  /// does exactly what `for (i) if (!collision(c[i])) insert(c[i]);` does,
  /// and returns the indices of the candidates inserted, ascending. The tree
  /// is then the one that loop builds, whatever the thread count: the same
  /// insertions with the same handles in the same order, hence the same
  /// iteration order and statistics. The candidates are tested in batches
  /// against the tree as it stood at each batch's start, in parallel, then
  /// among themselves (detail::insert_disjoint); on a large tree each
  /// thread's searches run interleaved (collisions()), so that even one
  /// thread is faster than the loop there. An exception from
  /// intersect() (which may be called on pairs the loop would not compare)
  /// or from an allocation reaches the caller as itself; the tree is then
  /// valid and holds what the loop holds after some first k candidates: k
  /// is the first candidate of the batch in progress, or the candidate whose
  /// insertion threw (with threads = 1: the candidate being decided). After
  /// a throw while several threads insert at once, it holds those shapes,
  /// but not in the loop's shape or with the loop's handles. A candidate
  /// outside the supported values throws std::invalid_argument naming the
  /// first one, before anything is inserted.
  std::vector<std::size_t> insert_disjoint(const std::vector<T> &candidates, unsigned threads = 0) {
    detail::require_supported(core_.traits, candidates, "insert_disjoint", "candidates");
    struct Settle { // (the ids' room goes, also after a throw)
      detail::LeafStore<T> &leaves;
      ~Settle() { leaves.settle_ids(); }
    } settle{core_.leaves};
    return detail::insert_disjoint(core_, candidates, threads);
  }

  /// True when `h` names a stored shape. The first lookup of any handle
  /// (contains, get, find, erase, update) builds the table that locates
  /// them all, in one O(n) pass, kept from then on until the tree is
  /// emptied; before, the tree holds none (docs/library.txt, HANDLES).
  /// Like every const member it may run on several threads at once: the
  /// first builds the table under a lock and the others wait. Never
  /// throws: without memory for the table, it walks the leaves instead.
  bool contains(handle h) const noexcept { return locate(h, nullptr); }
  /// The stored shape named by `h` (valid: see contains(); a stale handle
  /// fails a BVH_ASSERT, or with the checks off throws std::out_of_range).
  const T &get(handle h) const {
    Loc at;
    const bool named = locate(h, &at);
    BVH_ASSERT(named, "get() with a handle that names no stored shape");
    if (!named) throw std::out_of_range("BVH::get: a handle that names no stored shape");
    return core_.leaves.shapes(core_.nodes.node(at.leaf))[at.index];
  }
  /// An iterator to the shape named by `h` (valid; a stale handle fails a
  /// BVH_ASSERT, or with the checks off gives end()).
  iterator find(handle h) const {
    Loc at;
    const bool named = locate(h, &at);
    BVH_ASSERT(named, "find() with a handle that names no stored shape");
    return named ? iterator(this, at.leaf, at.index) : end();
  }

  /// Removes the shape named by `h` (valid) and returns true; `h` becomes
  /// stale, and iterators invalid. Strong (a rebuild for balance after it:
  /// by the build rule, as for insert(); erase(iterator) instead keeps the
  /// iteration order). A stale handle fails a BVH_ASSERT, or with the
  /// checks off changes nothing and returns false.
  bool erase(handle h) {
    Loc at;
    const bool named = locate(h, &at);
    BVH_ASSERT(named, "erase() with a handle that names no stored shape");
    if (!named) return false;
    detail::erase_shape(core_, at.leaf, at.index, detail::Cut::by_rule);
    return true;
  }
  /// Removes the shape at `pos` and returns the iterator to the shape that
  /// followed it (end() after the last). Every other iterator is
  /// invalidated, but the remaining shapes keep their iteration order, so
  /// erasing while iterating (`it = tree.erase(it)`) visits each shape once.
  /// O(log n) amortized (detail::erase_at has the repairs). Strong.
  iterator erase(iterator pos) {
    BVH_ASSERT(pos.tree_ == this, "erase() with an iterator of another tree (or a singular one)");
    BVH_ASSERT(pos.leaf_ >= 0, "erase(end())");
    // Catches most stale iterators (changes invalidate them), not all.
    BVH_ASSERT(std::size_t(pos.leaf_) < core_.nodes.capacity() && core_.nodes.node(pos.leaf_).is_leaf() &&
                   core_.nodes.node(pos.leaf_).leaf().has_slot() && pos.index_ < pos.shapes().size(),
               "erase() with an invalidated iterator");
    const std::size_t rank = rank_of(pos.leaf_, pos.index_);
    detail::erase_shape(core_, pos.leaf_, pos.index_, detail::Cut::in_order);
    return iterator_at(rank);
  }
  /// Removes every stored shape equal to `value` and returns how many there
  /// were. Only subtrees whose box holds value's box are searched. Needs
  /// `operator==` on T (the course's shapes have none: there, erase by
  /// iterator), and compiles only when used. Basic guarantee: one erase at
  /// a time, each strong, so if it throws, some of the equal shapes are gone
  /// (their handles invalid) and the tree is otherwise as it was.
  std::size_t erase(const T &value) {
    std::size_t removed = 0;
    int leaf;
    std::size_t index;
    for (; detail::find_equal(core_, value, leaf, index); ++removed)
      detail::erase_shape(core_, leaf, index, detail::Cut::by_rule);
    return removed;
  }

  /// The shape named by `h` (valid) becomes `moved`, and it returns true;
  /// its handle stays. (A stale handle fails a BVH_ASSERT, or with the
  /// checks off changes nothing and returns false.)
  /// When moved's box lies inside its leaf's box, the shape is replaced in
  /// place and, with margin 0, the boxes above are shrunk to fit again:
  /// O(depth), and every iterator stays valid. Otherwise the shape is
  /// erased and inserted again, as erase(h) and insert() would (iterators
  /// are invalidated), so the tree keeps insert()'s quality under any run
  /// of moves. A margin (set_margin) makes leaves' boxes larger than their
  /// shapes, so that small moves stay inside them. Strong, h kept: if it
  /// throws, the shape and the tree are as they were (moving out, the erase
  /// is undone; in place, T's copy then its move assignment, so strong when
  /// that move cannot throw, else as strong as T's copy assignment). A
  /// `moved` outside the supported values throws std::invalid_argument,
  /// the tree unchanged.
  bool update(handle h, const T &moved) {
    Loc at;
    const bool named = locate(h, &at);
    BVH_ASSERT(named, "update() with a handle that names no stored shape");
    if (!named) return false;
    detail::require_supported(core_.traits, moved, "update");
    detail::update_shape(core_, h.id, at, moved);
    return true;
  }

  /// Leaves' boxes are their shapes' box grown by `m` on every side (m < 0,
  /// NaN or infinite is taken as 0; the default is 0, the course's tight boxes):
  /// Box2D's "fat" boxes, which let update() absorb moves smaller than m
  /// without touching the tree, at the cost of looser boxes for queries
  /// (and larger areas in statistics()). Every box is recomputed: O(n).
  /// Never throws (nothing is allocated or copied).
  void set_margin(double m) noexcept { detail::set_margin(core_, m); }
  /// The margin of leaves' boxes (0 unless set_margin() said otherwise).
  double margin() const noexcept { return core_.margin; }

  /// The sizes from which the tree takes the paths that pay only on large
  /// trees (docs/library.txt, TUNING): they change speed, never an
  /// answer. A tree starts with default_tuning(); copies and moves take
  /// the source's.
  using Tuning = detail::Tuning;
  /// The defaults for T: disks decided from codes from 4 MB of shapes
  /// (BVH_DISK_CODES_MIN_BYTES), insert_disjoint's interleaved searches
  /// from 32,768 shapes, its lanes and parallel sweep from 4,096 (the
  /// macros BVH_DISJOINT_INTERLEAVE_MIN, _LANES_MIN, _SWEEP_MIN; defining
  /// one before bvh.h changes the default).
  static Tuning default_tuning() noexcept { return detail::default_tuning<T>(); }
  /// This tree's sizes from now on. Never throws; O(1).
  void set_tuning(const Tuning &t) noexcept { core_.tuning = t; }
  /// This tree's sizes.
  const Tuning &tuning() const noexcept { return core_.tuning; }

  /// True iff some stored shape intersects `shape` (touching counts).
  /// Subtrees whose box misses the shape's box are never visited; the final
  /// test is T's intersect() (for this project's shapes, intersect.h's
  /// exact predicate; on the course's server, the course's own). False for
  /// a shape outside the supported values.
  bool collision(const T &shape) const {
    return detail::supported_shape(core_.traits, shape) && detail::collides(core_, shape);
  }
  /// collision() of each of `shapes`: element i is collision(shapes[i]).
  /// Faster than one call per shape on a tree larger than the caches: the
  /// searches run interleaved, so that their cache misses overlap
  /// (detail::collides_each).
  std::vector<bool> collisions(const std::vector<T> &shapes) const {
    std::vector<unsigned char> hit(shapes.size());
    bool all_supported = true;
    for (const T &s : shapes) all_supported &= detail::supported_shape(core_.traits, s);
    if (all_supported) detail::collides_each(core_, shapes.data(), shapes.size(), hit.data());
    else
      for (std::size_t i = 0; i < shapes.size(); ++i) hit[i] = collision(shapes[i]);
    return std::vector<bool>(hit.begin(), hit.end());
  }

  /// Calls f(shape) for every stored shape whose box overlaps `box`, of
  /// any type box_traits understands (touching counts; infinite sides
  /// too, a NaN side meets nothing). If f returns bool, returning false
  /// stops the search.
  template <class B, class F, if_box<B> = 0> void query(const B &box, F &&f) const {
    const Box b = Box::from(box);
    if (detail::has_nan(b)) return;
    detail::visit_overlapping(core_, b, [&](const T &s) { return detail::keep_going(f, s); });
  }
  /// Calls f(shape) for every stored shape that intersects `shape` (by T's
  /// intersect(): exact, touching counts, for this project's shapes); none
  /// for a shape outside the supported values. If f returns bool,
  /// returning false stops the search.
  template <class F> void query(const T &shape, F &&f) const {
    if (!detail::supported_shape(core_.traits, shape)) return;
    detail::visit_intersecting(core_, shape, [&](const T &s) { return detail::keep_going(f, s); });
  }
  /// Copies every stored shape that intersects `shape` to `out` (an output
  /// iterator, e.g. std::back_inserter(vector)) and returns its end.
  template <class Out> Out query_into(const T &shape, Out out) const {
    query(shape, [&](const T &s) { *out++ = s; });
    return out;
  }

  /// An input iterator over the shapes a query finds, in the order query()
  /// calls f on them: the search itself, suspended between steps. Valid
  /// while the tree does not change.
  class overlap_iterator {
  public:
    using iterator_category = std::input_iterator_tag;
    using value_type = T;
    using difference_type = std::ptrdiff_t;
    using pointer = const T *;
    using reference = const T &;

    /// The end of every search.
    overlap_iterator() = default;
    /// The shape found (not at the end).
    reference operator*() const {
      BVH_ASSERT(search_.at() != nullptr, "dereferencing the end of an overlapping() range");
      return *search_.at();
    }
    pointer operator->() const { return &**this; }
    /// The next shape found (the end after the last).
    overlap_iterator &operator++() {
      BVH_ASSERT(search_.at() != nullptr, "incrementing the end of an overlapping() range");
      search_.next();
      return *this;
    }
    /// Steps on; returns nothing (an input iterator's post-increment).
    void operator++(int) { ++*this; }
    /// Equal when both are at the end or at the same shape.
    friend bool operator==(const overlap_iterator &a, const overlap_iterator &b) {
      return a.search_.at() == b.search_.at();
    }
    friend bool operator!=(const overlap_iterator &a, const overlap_iterator &b) { return !(a == b); }

  private:
    friend class BVH;
    overlap_iterator(const Core &core, const Box &box, const T *shape) : search_(core, box, shape) {}
    detail::OverlapSearch<T, Traits, Width> search_;
  };

  /// What overlapping() returns: a range for range-for.
  class overlap_range {
  public:
    overlap_iterator begin() const { return first_; }
    overlap_iterator end() const { return overlap_iterator(); }

  private:
    friend class BVH;
    explicit overlap_range(overlap_iterator first) : first_(std::move(first)) {}
    overlap_iterator first_;
  };

  /// The shapes query(shape, f) would pass to f, as a lazy range:
  /// `for (const T &s : tree.overlapping(shape))`, stoppable by break. The
  /// search starts at once and each step runs on ++; nothing is allocated
  /// unless the tree is deeper than detail::IndexStack::kInline levels.
  overlap_range overlapping(const T &shape) const {
    if (!detail::supported_shape(core_.traits, shape)) return overlap_range(overlap_iterator());
    return overlap_range(overlap_iterator(core_, detail::box_of(core_.traits, shape), &shape));
  }
  /// The shapes query(box, f) would pass to f (boxes that meet `box`, of
  /// any type box_traits understands).
  template <class B, if_box<B> = 0> overlap_range overlapping(const B &box) const {
    const Box b = Box::from(box);
    if (detail::has_nan(b)) return overlap_range(overlap_iterator());
    return overlap_range(overlap_iterator(core_, b, nullptr));
  }

  /// A stored shape at the least distance from `p` (by a free
  /// `distance(p, shape)`, as distance.h gives this project's shapes: 0 when
  /// p is inside or on it; needed only when this is used), or nullptr when
  /// the tree is empty or p is outside the supported values (a NaN, an
  /// infinity, 1e300: docs/library.txt, SUPPORTED VALUES); `*dist` gets the
  /// distance (+inf when none). Among equally near shapes, the one of the
  /// smallest handle id. O(log n) typically (detail::best_first).
  const T *nearest(const Point &p, double *dist = nullptr) const {
    return best_one(detail::PointMetric<Point>{p}, dist);
  }

  /// One answer of nearest(p, k, out).
  struct neighbor {
    const T *shape;  ///< the stored shape (valid until the tree changes)
    double distance; ///< distance(p, *shape): 0 when p is inside or on it
    handle id;       ///< its handle
  };
  /// Writes to `out` (an output iterator of neighbor, e.g.
  /// std::back_inserter(vector)) the min(k, size()) stored shapes nearest
  /// to `p`, by increasing distance(p, shape) (as nearest(p) measures it);
  /// among equally distant shapes the smaller handle id comes first, so the
  /// answer is one definite list (none when p is outside the supported
  /// values). Returns out's end. O(log n + k) typically.
  template <class Out> Out nearest(const Point &p, std::size_t k, Out out) const {
    detail::InlineVector<detail::Found<T>, 16> found;
    detail::best_first(core_, detail::PointMetric<Point>{p}, k, found);
    for (const auto &f : found) *out++ = neighbor{f.shape, f.key, handle{f.id, core_.leaves.generation(f.id)}};
    return out;
  }

  /// The first stored shape met by the ray origin + t * direction, t >= 0
  /// (t = 0 when the origin lies inside or on a shape), or nullptr when the
  /// ray meets none or the origin or direction is outside the supported
  /// values; `*t` gets the ray parameter of the hit (+inf for none). Among
  /// shapes met at the same t, the one of the smallest handle id. Needs a free `ray_hit(origin, direction, shape)` (distance.h), only
  /// when used.
  const T *first_hit(const Point &origin, const Point &direction, double *t = nullptr) const {
    return best_one(detail::RayMetric<Point>{origin, direction}, t);
  }

  /// Calls f(a, b) once for every unordered pair of stored shapes that
  /// intersect (by T's intersect(); exact, touching counts, for this
  /// project's shapes); if f returns bool, false stops. O(n log n + pairs)
  /// on well-spread scenes.
  template <class F> void for_each_overlapping_pair(F &&f) const { detail::for_each_overlapping_pair(core_, f); }
  /// The number of unordered pairs of stored shapes that intersect.
  std::size_t count_overlapping_pairs() const {
    std::size_t k = 0;
    for_each_overlapping_pair([&](const T &, const T &) { ++k; });
    return k;
  }

  /// The course's report on stdout: with `print_tree`, one line per node in
  /// pre-order, then node count, max depth and the two area sums of the
  /// surface area heuristic (areas in units of the 1000x1000 canvas).
  void statistics(bool print_tree) const { statistics(std::cout, print_tree); }
  /// The same report, to any stream.
  void statistics(std::ostream &ostr, bool print_tree) const { detail::print_statistics(core_, ostr, print_tree); }
  /// The surface area heuristic cost that statistics() prints, unrounded:
  /// the inner nodes' box areas plus each leaf's box area times its shape
  /// count, in units of the 1000 x 1000 canvas (0 for an empty tree).
  double sah_cost() const {
    const detail::Summary s = detail::summarize(core_);
    return s.inner_area + s.leaf_area;
  }
  /// Depth of the deepest node (0 for a single leaf or an empty tree).
  int height() const { return detail::summarize(core_).max_depth; }

  /// Draws every node's box translucently and recolours every shape to the
  /// colour of its leaf (the course's picture: detail::render_recolor).
  void render_recolor(std::ostream &ostr) { detail::render_recolor(core_, ostr); }

  /// Checks every invariant; on failure returns false and, when `why` is
  /// given, says which node broke what. Meant for tests: O(n log n).
  bool validate(std::string *why = nullptr) const { return detail::validate(core_, why); }

private:
  using Loc = typename detail::LeafStore<T>::Loc;
  /// True when `h` names a stored shape (its id stored, its generation the
  /// id's), whose place then goes to *at (when given). Never throws.
  bool locate(handle h, Loc *at) const noexcept {
    return core_.leaves.find(core_.nodes, core_.root, h.id, h.generation, at);
  }

  /// The move: `other`'s state for ours, then `other` emptied.
  void take(BVH &other) noexcept {
    core_.swap(other.core_);
    other.core_.clear();
  }

  /// best_first() for one answer: its shape, with its key in *key.
  template <class Metric> const T *best_one(const Metric &metric, double *key) const {
    detail::InlineVector<detail::Found<T>, 1> found;
    detail::best_first(core_, metric, 1, found);
    if (key) *key = found.empty() ? std::numeric_limits<double>::infinity() : found[0].key;
    return found.empty() ? nullptr : found[0].shape;
  }

  /// Shapes before shape `index` of `leaf` in iteration order.
  std::size_t rank_of(int leaf, std::size_t index) const {
    std::size_t rank = index;
    for (int n = leaf, parent; (parent = core_.nodes.info(n).parent) >= 0; n = parent)
      for (int c = 0; c < core_.nodes.info(n).child_index; ++c)
        rank += core_.nodes.info(core_.nodes.node(parent).child(c)).count;
    return rank;
  }
  /// The iterator to the shape of rank `rank` (end() past the last).
  iterator iterator_at(std::size_t rank) const {
    if (rank >= core_.size) return end();
    int n = core_.root;
    while (!core_.nodes.node(n).is_leaf()) {
      const detail::Node<Width> &node = core_.nodes.node(n);
      int c = 0;
      while (rank >= core_.nodes.info(node.child(c)).count) rank -= core_.nodes.info(node.child(c)).count, ++c;
      n = node.child(c);
    }
    return iterator(this, n, rank);
  }

  Core core_;
};

} // namespace bvh


#endif // BVH_BVH_H
