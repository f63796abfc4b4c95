// bvh.h — BVH<T>: a ternary bounding volume hierarchy over 2D shapes
// (Disk, Triangle, Quad from shapes.h, Shape for mixed scenes, or a shape
// type of your own), built in bulk or one shape at a time, answering "does
// this shape touch anything stored?" with the shapes' own intersect().
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
// large scenes, the same tree whatever their number); insert O(log n) amortised,
// including the partial rebuilds that keep the tree balanced under any
// insertion order; collision O(log n + shapes whose boxes touch the probe);
// iteration O(1) amortised per step; update(handle, moved) O(depth) while
// the shape stays inside its leaf's box (set_margin makes those boxes fat),
// else an erase and an insert; nearest(p, k) O(log n + k) typically. Copy,
// destruction and every traversal are iterative, so no input can overflow
// the stack.
//
// Where to look: the build rule is `CourseRule` (`SahRule` the alternative),
// which plugs into the one build loop `build_top_down`; the insertion
// strategy is `choose_child` plus `rebalance_path`; every depth-first
// traversal is `walk` (the best-first searches and the suspended search of
// overlapping() keep their own order); the leaves' shapes are in `bvh_detail::LeafPool`, each with its
// handle's id, which `loc_` maps back to a leaf (insert, update, erase by
// handle); the tree's box arithmetic is
// `bvh_detail::Box`; the intersection predicates are the free intersect()
// of the shape type, found by argument-dependent lookup (this project's
// exact ones are in intersect.h, which shapes.h brings in).
#ifndef BVH_BVH_H
#define BVH_BVH_H

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
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
#include <queue>
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

// The only project header: with the course's shapes.h (the homework
// server's) or this project's (which brings in the exact intersect.h and
// distance.h), everything below compiles.
#include "shapes.h"

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
  ((condition) ? (void)0 : ::bvh_detail::assertion_failed(message, #condition, __FILE__, __LINE__))
#endif
#endif

// The one traversal routine is inlined into each query that uses it, so
// that its visit's state (a query's probe) stays in registers.
#if defined(__GNUC__)
#define BVH_ALWAYS_INLINE inline __attribute__((always_inline))
#define BVH_LAMBDA_INLINE __attribute__((always_inline))
#else
#define BVH_ALWAYS_INLINE inline
#define BVH_LAMBDA_INLINE
#endif

namespace bvh_detail {

/// BVH_ASSERT's report: what was misused, where, then abort().
[[noreturn]] inline void assertion_failed(const char *message, const char *condition, const char *file, int line) {
  std::fprintf(stderr, "%s:%d: BVH misuse: %s (%s)\n", file, line, message, condition);
  std::abort();
}

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

private:
  static constexpr std::size_t kInline = 96;
  int inline_[kInline];
  std::size_t size_ = 0;
  std::vector<int> spill_;
};

/// The node arrays: a vector's interface (index, size, emplace_back) over
/// fixed blocks of 512 elements. Growing never moves or copies what is
/// stored, so a growing tree never holds two copies of its nodes at once
/// (std::vector's doubling did: with its up to 2x capacity slack that was
/// most of W2's 6x memory over the shapes), and the slack is one block.
template <class X> class BlockVector {
public:
  /// Empty, no block.
  BlockVector() = default;
  /// Deep copy.
  BlockVector(const BlockVector &other) : size_(other.size_) {
    blocks_.reserve(other.blocks_.size());
    for (const auto &b : other.blocks_) {
      blocks_.emplace_back(new X[kBlock]);
      std::copy(b.get(), b.get() + kBlock, blocks_.back().get());
    }
  }
  /// Takes `other`'s blocks; `other` is left empty.
  BlockVector(BlockVector &&other) noexcept : blocks_(std::move(other.blocks_)), size_(other.size_) {
    other.blocks_.clear();
    other.size_ = 0;
  }
  /// Deep copy; self-assignment is safe.
  BlockVector &operator=(const BlockVector &other) {
    if (this != &other) *this = BlockVector(other);
    return *this;
  }
  /// Takes `other`'s blocks; `other` is left empty.
  BlockVector &operator=(BlockVector &&other) noexcept {
    if (this != &other) {
      blocks_ = std::move(other.blocks_);
      size_ = other.size_;
      other.blocks_.clear();
      other.size_ = 0;
    }
    return *this;
  }

  /// Element i (< size()).
  X &operator[](std::size_t i) { return blocks_[i >> kShift][i & kMask]; }
  /// Element i (< size()).
  const X &operator[](std::size_t i) const { return blocks_[i >> kShift][i & kMask]; }
  /// The last element (not empty()).
  X &back() { return (*this)[size_ - 1]; }
  /// Number of elements.
  std::size_t size() const { return size_; }
  /// True when there is no element.
  bool empty() const { return size_ == 0; }
  /// Drops every element and block.
  void clear() {
    blocks_.clear();
    size_ = 0;
  }
  /// Makes room in the block table only: blocks come one at a time.
  void reserve(std::size_t n) { blocks_.reserve((n + kMask) >> kShift); }
  /// Grows to n elements (n >= size()), the new ones default-constructed.
  void resize(std::size_t n) {
    reserve(n);
    while (size_ < n) emplace_back();
  }
  /// Appends a default-constructed element.
  void emplace_back() {
    if (size_ == blocks_.size() << kShift) blocks_.emplace_back(new X[kBlock]());
    ++size_;
  }
  /// Removes the last element (reset to its default, as the next
  /// emplace_back expects).
  void pop_back() { (*this)[--size_] = X(); }

private:
  static constexpr std::size_t kShift = 9, kBlock = std::size_t(1) << kShift, kMask = kBlock - 1;
  std::vector<std::unique_ptr<X[]>> blocks_;
  std::size_t size_ = 0;
};

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

  /// The box of `b`, anything with getMin() and getMax() (points with x, y).
  template <class B> static Box of(const B &b) {
    const auto &lo = b.getMin();
    const auto &hi = b.getMax();
    return Box{lo.x, lo.y, hi.x, hi.y};
  }
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
  /// Distance from (px, py) to the box: 0 inside or on it.
  double distance_to(double px, double py) const {
    return std::hypot(std::max({x0 - px, 0.0, px - x1}), std::max({y0 - py, 0.0, py - y1}));
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
inline void round_out(const Box &b, float out[4]) {
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

/// The box of a stored shape, read through getBox().getMin()/getMax().
template <class T> BVH_ALWAYS_INLINE Box box_of(const T &shape) { return Box::of(shape.getBox()); }

/// Appends `[<x0 y0> <x1 y1>]` with every number as %5.1f: the course's
/// listing of a box, written here so that neither the stream's flags nor
/// the shape library's printing can change it.
inline void append_box(std::string &out, const Box &b) {
  char buf[1400]; // four %5.1f doubles of any magnitude fit
  std::snprintf(buf, sizeof buf, "[<%5.1f %5.1f> <%5.1f %5.1f>]", b.x0, b.y0, b.x1, b.y1);
  out += buf;
}

/// Node counts of a tree cut in thirds by count, as the course's rule and
/// build_in_order cut: its shape depends on the counts alone, so the number
/// of nodes under every node is known before anything is sorted. At each
/// depth the splitting sizes differ by at most one, so every level of the
/// table holds at most a few sizes.
class Layout {
public:
  /// The table for n shapes at depth 0 (depth_limit <= 0: none).
  Layout(std::size_t n, int split_threshold, int depth_limit)
      : split_threshold_(std::size_t(split_threshold)), depth_limit_(depth_limit) {
    levels_.push_back({Entry{n, 0}});
    for (int d = 0; !levels_[std::size_t(d)].empty(); ++d) { // sizes met, top-down
      std::vector<Entry> next;
      for (const Entry &e : levels_[std::size_t(d)])
        if (splits(e.size, d))
          for (std::size_t g : thirds(e.size))
            if (g != 0 && std::none_of(next.begin(), next.end(), [&](const Entry &x) { return x.size == g; }))
              next.push_back(Entry{g, 0});
      levels_.push_back(std::move(next));
    }
    for (std::size_t d = levels_.size(); d-- > 0;) // node counts, bottom-up
      for (Entry &e : levels_[d]) {
        e.nodes = 1;
        if (splits(e.size, int(d)))
          for (std::size_t g : thirds(e.size))
            if (g != 0) e.nodes += nodes(g, int(d) + 1);
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
  static std::array<std::size_t, 3> thirds(std::size_t m) {
    const std::size_t base = m / 3, extra = m % 3;
    return {base + (extra > 0), base + (extra > 1), base};
  }
  std::size_t split_threshold_;
  int depth_limit_;
  std::vector<std::vector<Entry>> levels_;
};

/// Calls f(0) ... f(count - 1), spread over `threads` threads (the caller
/// is one of them). If a thread cannot be started, the others do its share;
/// the first exception thrown by f is rethrown once all have finished.
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
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < threads && k < count; ++k) {
    try {
      pool.emplace_back(work);
    } catch (const std::system_error &) {
      break;
    }
  }
  work();
  for (std::thread &t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// The leaves' shapes: each leaf owns one slot, a contiguous run of shapes.
/// Slot capacities are powers of two, with one pool per capacity (a
/// "class"); a pool stores its slots in fixed blocks, so growing never moves
/// what is stored and there is no allocation per leaf; a bulk build's
/// leaves of one class lie side by side in leaf order. Only a slot's first
/// size() elements are constructed, so T needs no default constructor.
/// Beside each shape the pool keeps its id (the tree's handle for it),
/// moved with it. Slots given back are reused first. Copies are deep.
template <class T> class LeafPool {
public:
  /// A slot: its class (capacity 1 << cls) and its index in that class.
  struct Slot {
    std::uint32_t index = 0;
    std::uint32_t cls = 0;
  };

  /// An empty slot for at least `capacity` (>= 1) shapes.
  Slot allocate(std::size_t capacity) {
    std::uint32_t cls = 0;
    while ((std::size_t(1) << cls) < capacity) ++cls;
    while (classes_.size() <= cls) classes_.emplace_back(std::uint32_t(classes_.size()));
    return Slot{classes_[cls].allocate(), cls};
  }
  /// Destroys the slot's shapes and gives the slot back.
  void release(Slot s) { classes_[s.cls].release(s.index); }

  /// The slot's first shape.
  T *data(Slot s) { return classes_[s.cls].data(s.index); }
  const T *data(Slot s) const { return classes_[s.cls].data(s.index); }
  /// The ids of the slot's shapes, in the same order.
  std::uint32_t *ids(Slot s) { return classes_[s.cls].ids(s.index); }
  const std::uint32_t *ids(Slot s) const { return classes_[s.cls].ids(s.index); }
  /// The number of shapes in the slot.
  std::size_t size(Slot s) const { return classes_[s.cls].sizes[s.index]; }

  /// Appends a shape with its id; a full slot first moves to one twice as
  /// large (`s` then names the new slot).
  template <class V> void push_back(Slot &s, V &&shape, std::uint32_t id) {
    if (size(s) == (std::size_t(1) << s.cls)) {
      const Slot bigger = allocate(std::size_t(2) << s.cls);
      T *from = data(s);
      const std::uint32_t *from_ids = ids(s);
      for (std::size_t i = 0, n = size(s); i < n; ++i)
        classes_[bigger.cls].construct(bigger.index, std::move(from[i]), from_ids[i]);
      release(s);
      s = bigger;
    }
    classes_[s.cls].construct(s.index, std::forward<V>(shape), id);
  }
  /// Removes shape i, keeping the order of the others.
  void erase(Slot s, std::size_t i) {
    T *d = data(s);
    std::uint32_t *id = ids(s);
    const std::size_t n = size(s);
    std::move(d + i + 1, d + n, d + i);
    std::move(id + i + 1, id + n, id + i);
    d[n - 1].~T();
    --classes_[s.cls].sizes[s.index];
  }

private:
  static constexpr std::size_t kBlockBytes = 32768;

  /// The slots of one capacity.
  class Class {
  public:
    explicit Class(std::uint32_t cls) : cls_(cls), capacity_(std::size_t(1) << cls) {
      // Slots per block: a power of two, so that finding a slot shifts.
      while ((std::size_t(2) << block_shift_) * capacity_ * sizeof(T) <= kBlockBytes) ++block_shift_;
      per_block_ = std::size_t(1) << block_shift_;
    }
    Class(const Class &o)
        : cls_(o.cls_), capacity_(o.capacity_), block_shift_(o.block_shift_), per_block_(o.per_block_),
          free_slots(o.free_slots) {
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
        : cls_(o.cls_), capacity_(o.capacity_), block_shift_(o.block_shift_), per_block_(o.per_block_),
          sizes(std::move(o.sizes)), free_slots(std::move(o.free_slots)), blocks_(std::move(o.blocks_)),
          id_blocks_(std::move(o.id_blocks_)) {
      o.sizes.clear();
      o.free_slots.clear();
      o.blocks_.clear();
      o.id_blocks_.clear();
    }
    Class &operator=(Class o) noexcept { // copy or move, then swap
      std::swap(cls_, o.cls_);
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
      const std::uint32_t i = std::uint32_t(sizes.size());
      if (i % per_block_ == 0) add_block();
      sizes.push_back(0);
      return i;
    }
    void release(std::uint32_t i) {
      T *d = data(i);
      for (std::uint32_t j = 0; j < sizes[i]; ++j) d[j].~T();
      sizes[i] = 0;
      free_slots.push_back(i);
    }
    template <class V> void construct(std::uint32_t i, V &&v, std::uint32_t id) {
      ::new (static_cast<void *>(data(i) + sizes[i])) T(std::forward<V>(v));
      ids(i)[sizes[i]] = id;
      ++sizes[i];
    }
    std::uint32_t *ids(std::uint32_t i) {
      return id_blocks_[i >> block_shift_] + (std::size_t(i & (per_block_ - 1)) << cls_);
    }
    const std::uint32_t *ids(std::uint32_t i) const {
      return id_blocks_[i >> block_shift_] + (std::size_t(i & (per_block_ - 1)) << cls_);
    }
    T *data(std::uint32_t i) { return blocks_[i >> block_shift_] + (std::size_t(i & (per_block_ - 1)) << cls_); }
    const T *data(std::uint32_t i) const {
      return blocks_[i >> block_shift_] + (std::size_t(i & (per_block_ - 1)) << cls_);
    }

  private:
    std::uint32_t cls_;
    std::size_t capacity_;
    std::uint32_t block_shift_ = 0;
    std::size_t per_block_;

  public:
    std::vector<std::uint32_t> sizes; ///< shapes in each slot (0 when free)
    std::vector<std::uint32_t> free_slots; ///< slots given back

  private:
    std::vector<T *> blocks_;
    std::vector<std::uint32_t *> id_blocks_; // parallel to blocks_
    void add_block() {
      const std::size_t n = per_block_ * capacity_;
      blocks_.reserve(blocks_.size() + 1);
      id_blocks_.reserve(id_blocks_.size() + 1);
      T *b = std::allocator<T>().allocate(n);
      try {
        id_blocks_.push_back(std::allocator<std::uint32_t>().allocate(n));
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

  std::vector<Class> classes_;
};

/// A query box rounded outwards to float, and its centre, as the node
/// tests (BVH::child_masks) read them.
struct Probe {
  /// The probe of `box`.
  static Probe around(const Box &box) {
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

} // namespace bvh_detail

/// A ternary bounding volume hierarchy over shapes of type T.
///
/// What T must provide (the course's shapes provide exactly this):
///  - copy construction and assignment;
///  - `getBox()`, whose `getMin()` and `getMax()` have double `x` and `y`;
///  - `getCenter()`, with double `x` and `y` (the build rule sorts by it);
///  - a free `intersect(const T&, const T&)` found by argument-dependent
///    lookup (collision, query by shape, all pairs).
/// A few members need more, say so, and compile only when used:
/// erase(value) needs `==`, nearest() a free `distance(const Point&, const
/// T&)`, first_hit() a free `ray_hit(const Point&, const Point&, const T&)`,
/// render_recolor() `setColor(const Color&)`. Shapes live only in leaves,
/// each exactly once; every node knows the tight box of its subtree.
///
/// Storage: nodes live in two parallel arrays (bvh_detail::BlockVector),
/// after construct() in pre-order with each node's children adjacent.
/// `nodes_` holds what queries read, 64 bytes a node (one cache line): an
/// inner node's children's boxes, in float rounded outwards, and their
/// indices, so a query decides all three children from one line; a leaf's
/// pool slot and shape count. `info_` holds the rest: the exact double box,
/// parent, depth, shape count and, for leaves, the slot that owns the
/// shapes. The shapes themselves live in one pool (bvh_detail::LeafPool),
/// each with its handle's id beside it; `loc_` maps an id back to its leaf
/// and position, and every change to a leaf rewrites the entries it moves.
template <class T> class BVH {
  using Box = bvh_detail::Box;
  using Probe = bvh_detail::Probe;

public:
  /// `depth_limit` value meaning "no limit" (the course's default of 0).
  static constexpr int unlimited = 0;

  /// An empty tree. A node holding more than `split_threshold` shapes is
  /// split unless it is at depth `depth_limit` (root = depth 0;
  /// `depth_limit <= 0` means unlimited). A `split_threshold` below 1 is
  /// taken as 1 (every leaf then holds one shape, above the depth limit).
  explicit BVH(int split_threshold = 4, int depth_limit = unlimited)
      : split_threshold_(split_threshold < 1 ? 1 : split_threshold),
        depth_limit_(depth_limit <= 0 ? unlimited : depth_limit) {}

  // Copying and destruction are the defaults: every part lives in vectors,
  // so copies are deep and independent and nothing recurses. Moves are
  // written out only so that a moved-from tree is a valid empty tree.

  /// Deep copy.
  BVH(const BVH &) = default;
  /// Deep copy; self-assignment is safe.
  BVH &operator=(const BVH &) = default;
  /// Takes `other`'s shapes; `other` is left empty (same parameters).
  BVH(BVH &&other) noexcept
      : nodes_(std::move(other.nodes_)), info_(std::move(other.info_)), free_(std::move(other.free_)),
        pool_(std::move(other.pool_)), loc_(std::move(other.loc_)), free_ids_(std::move(other.free_ids_)),
        root_(other.root_), size_(other.size_), split_threshold_(other.split_threshold_),
        depth_limit_(other.depth_limit_), build_rule_(other.build_rule_), build_threads_(other.build_threads_),
        margin_(other.margin_) {
    other.clear();
  }
  /// Takes `other`'s shapes and parameters; `other` is left empty.
  BVH &operator=(BVH &&other) noexcept {
    if (this != &other) {
      nodes_ = std::move(other.nodes_);
      info_ = std::move(other.info_);
      free_ = std::move(other.free_);
      pool_ = std::move(other.pool_);
      loc_ = std::move(other.loc_);
      free_ids_ = std::move(other.free_ids_);
      root_ = other.root_;
      size_ = other.size_;
      split_threshold_ = other.split_threshold_;
      depth_limit_ = other.depth_limit_;
      build_rule_ = other.build_rule_;
      build_threads_ = other.build_threads_;
      margin_ = other.margin_;
      other.clear();
    }
    return *this;
  }
  ~BVH() = default;

  /// A stored shape's name: given by insert() (construct() gives elements[i]
  /// the id i), valid until that shape is erased whatever else is
  /// inserted, erased, updated or rebuilt. Like Box2D's proxy ids, the id
  /// of an erased shape may be given again by a later insert().
  struct handle {
    std::uint32_t id;
    friend bool operator==(handle a, handle b) { return a.id == b.id; }
    friend bool operator!=(handle a, handle b) { return a.id != b.id; }
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
      return tree_->shapes_of(leaf_)[index_];
    }
    /// Member access on the shape it points to.
    pointer operator->() const { return &**this; }
    /// The handle of the shape it points to (not end()).
    handle id() const {
      BVH_ASSERT(tree_ != nullptr && leaf_ >= 0, "id() of end() or a singular iterator");
      return handle{tree_->pool_.ids(tree_->info_[leaf_].shapes)[index_]};
    }

    /// Next shape (end() after the last; not from end()).
    iterator &operator++() {
      BVH_ASSERT(tree_ != nullptr && leaf_ >= 0, "incrementing end() or a singular iterator");
      if (++index_ == tree_->shapes_of(leaf_).size()) {
        leaf_ = tree_->next_leaf(leaf_);
        index_ = 0;
      }
      return *this;
    }
    /// Previous shape (from end(): the last shape; not from begin()).
    iterator &operator--() {
      BVH_ASSERT(tree_ != nullptr, "decrementing a singular iterator");
      if (leaf_ < 0) {
        BVH_ASSERT(tree_->root_ >= 0, "decrementing end() of an empty tree");
        leaf_ = tree_->rightmost_leaf(tree_->root_);
        index_ = tree_->shapes_of(leaf_).size() - 1;
      } else if (index_ > 0) {
        --index_;
      } else {
        leaf_ = tree_->prev_leaf(leaf_);
        BVH_ASSERT(leaf_ >= 0, "decrementing begin()");
        index_ = tree_->shapes_of(leaf_).size() - 1;
      }
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
    const BVH *tree_ = nullptr;
    int leaf_ = -1; // -1: end()
    std::size_t index_ = 0;
  };
  /// The same iterator: shapes are never writable through iteration.
  using const_iterator = iterator;

  /// First shape in leaf order (end() when empty).
  iterator begin() const { return root_ < 0 ? end() : iterator(this, leftmost_leaf(root_), 0); }
  /// One past the last shape.
  iterator end() const { return iterator(this, -1, 0); }

  /// Number of stored shapes.
  std::size_t size() const { return size_; }
  /// True when no shape is stored.
  bool empty() const { return size_ == 0; }
  /// The split threshold given at construction (at least 1).
  int split_threshold() const { return split_threshold_; }
  /// The depth limit (`unlimited`, i.e. 0, for none).
  int depth_limit() const { return depth_limit_; }
  /// The box of everything stored; a default BoundingBox when empty (with
  /// this project's shapes.h an empty box, with the course's the origin).
  BoundingBox bounds() const {
    if (root_ < 0) return BoundingBox();
    const Box &b = info_[root_].box;
    return BoundingBox(Point(b.x0, b.y0), Point(b.x1, b.y1));
  }
  /// Number of nodes, inner and leaf.
  std::size_t node_count() const { return nodes_.size() - free_.size(); }

  /// How construct() and the splits and rebuilds of insert() cut a node.
  enum class BuildRule {
    course, ///< the course's rule (CourseRule): thirds by count along the longer side
    sah     ///< binned surface area heuristic (SahRule): the cut of least area cost
  };
  /// Chooses the build rule for later builds (course by default: the
  /// course's expected output follows it).
  void set_build_rule(BuildRule rule) { build_rule_ = rule; }
  /// The build rule in use.
  BuildRule build_rule() const { return build_rule_; }

  /// Removes every shape; every handle becomes invalid.
  void clear() {
    clear_nodes();
    loc_.clear();
    free_ids_.clear();
  }

  /// Replaces the contents with `elements`, built top-down by the course's
  /// rule (see CourseRule).
  void construct(const std::vector<T> &elements) {
    clear();
    if (elements.empty()) return;
    if (elements.size() > std::size_t(std::numeric_limits<std::uint32_t>::max()))
      throw std::length_error("BVH::construct: more shapes than 32-bit handles can name");
    size_ = elements.size();
    loc_.resize(size_);
    if (build_rule_ == BuildRule::sah) {
      std::vector<Tagged> tagged;
      tagged.reserve(size_);
      for (std::size_t i = 0; i < size_; ++i) tagged.push_back(Tagged{elements[i], std::uint32_t(i)});
      root_ = new_node(0, -1, 0);
      build(root_, tagged);
      return;
    }
    // The course rule's tree shape depends on counts alone, so every node
    // gets its index in advance (bvh_detail::Layout): in pre-order, each
    // node's children adjacent, each subtree contiguous; and subtrees far
    // enough down are independent, so threads can build them at once.
    try {
      const bvh_detail::Layout layout(size_, split_threshold_, depth_limit_);
      const std::size_t total = layout.nodes(size_, 0);
      nodes_.resize(total);
      info_.resize(total);
      root_ = 0;
      reset_node(root_, 0, -1, 0);
      CourseRule rule(fill_items(elements.size(), [&](std::size_t i) -> const T & { return elements[i]; }), nullptr);
      using Task = BuildTask<typename CourseRule::State>;
      std::vector<Task> tasks{{root_, 0, size_, 1, CourseRule::root_state()}};
      const unsigned threads = build_threads();
      if (threads <= 1 || size_ < kParallelMin) {
        build_top_down(tasks, rule, &layout);
        gather_leaves(rule);
        return;
      }
      int defer_depth = 1; // enough subtrees to keep every thread busy
      for (std::size_t subtrees = 3; subtrees < 4 * std::size_t(threads); subtrees *= 3) ++defer_depth;
      std::vector<Task> deferred;
      build_top_down(tasks, rule, &layout, defer_depth, &deferred);
      bvh_detail::parallel_for(deferred.size(), threads, [&](std::size_t i) {
        std::vector<Task> one{deferred[i]};
        build_top_down(one, rule, &layout);
      });
      gather_leaves(rule);
    } catch (...) {
      clear();
      throw;
    }
  }

  /// construct()'s last step: the leaves, in pre-order, own consecutive
  /// ranges of the rule's items; each takes its range into a pool slot.
  /// Then the items' memory is given back.
  template <class Rule> void gather_leaves(Rule &rule) {
    std::size_t next = 0;
    for_each_preorder([&](int n) {
      if (nodes_[n].num_children != 0) return;
      fill_leaf(n, rule, next, next + info_[n].count);
      next += info_[n].count;
    });
    std::vector<Item>().swap(scratch_.value.items);
  }

  /// Threads construct() may use: 0 (the default) for
  /// std::thread::hardware_concurrency(), 1 for none besides the caller.
  /// The tree built is the same whatever the number; scenes under
  /// kParallelMin shapes are always built by the caller alone.
  void set_build_threads(unsigned threads) { build_threads_ = threads; }
  /// The threads construct() uses for large scenes (at least 1).
  unsigned build_threads() const {
    if (build_threads_ != 0) return build_threads_;
    const unsigned hw = std::thread::hardware_concurrency();
    return hw == 0 ? 1 : hw;
  }
  /// Scenes smaller than this are built without threads.
  static constexpr std::size_t kParallelMin = std::size_t(1) << 16;

  /// Adds one shape: descend by least area growth (choose_child), add it to
  /// that leaf, split the leaf by the build rule when it holds more than
  /// split_threshold shapes above depth_limit, then rebuild the highest
  /// subtree on the path that has grown lopsided (rebalance_path).
  /// Returns the new shape's handle.
  handle insert(const T &shape) {
    const std::uint32_t id = new_id();
    try {
      insert_with_id(shape, id);
    } catch (...) {
      free_id(id);
      throw;
    }
    return handle{id};
  }

  /// The stored shape named by `h` (h must be valid: see contains()).
  const T &get(handle h) const {
    BVH_ASSERT(contains(h), "get() with a handle that names no stored shape");
    return shapes_of(loc_[h.id].leaf)[loc_[h.id].index];
  }
  /// True when `h` names a stored shape.
  bool contains(handle h) const { return h.id < loc_.size() && loc_[h.id].leaf >= 0; }
  /// An iterator to the shape named by `h` (valid).
  iterator find(handle h) const {
    BVH_ASSERT(contains(h), "find() with a handle that names no stored shape");
    return iterator(this, loc_[h.id].leaf, loc_[h.id].index);
  }

  /// Removes the shape named by `h` (valid); `h` becomes invalid, as do
  /// iterators.
  void erase(handle h) {
    BVH_ASSERT(contains(h), "erase() with a handle that names no stored shape");
    const Loc at = loc_[h.id];
    erase_at(at.leaf, at.index);
    free_id(h.id);
  }

  /// The shape named by `h` (valid) becomes `moved`; its handle stays.
  /// When moved's box lies inside its leaf's box, the shape is replaced in
  /// place and, with margin 0, the boxes above are shrunk to fit again:
  /// O(depth), and every iterator stays valid. Otherwise the shape is
  /// erased and inserted again, as erase(h) and insert() would (iterators
  /// are invalidated), so the tree keeps insert()'s quality under any run
  /// of moves. A margin (set_margin) makes leaves' boxes larger than their
  /// shapes, so that small moves stay inside them.
  void update(handle h, const T &moved) {
    BVH_ASSERT(contains(h), "update() with a handle that names no stored shape");
    const Loc at = loc_[h.id];
    if (info_[at.leaf].box.contains(bvh_detail::box_of(moved))) {
      shapes_of(at.leaf)[at.index] = moved;
      if (margin_ == 0) refit_up(at.leaf);
      return;
    }
    erase_at(at.leaf, at.index);
    insert_with_id(moved, h.id);
  }

  /// Leaves' boxes are their shapes' box grown by `m` on every side (m < 0
  /// or NaN is taken as 0; the default is 0, the course's tight boxes):
  /// Box2D's "fat" boxes, which let update() absorb moves smaller than m
  /// without touching the tree, at the cost of looser boxes for queries
  /// (and larger areas in statistics()). Every box is recomputed: O(n).
  void set_margin(double m) {
    margin_ = m > 0 && m < std::numeric_limits<double>::infinity() ? m : 0;
    if (root_ < 0) return;
    std::vector<int> order;
    order.reserve(node_count());
    for_each_preorder([&](int n) { order.push_back(n); });
    for (auto it = order.rbegin(); it != order.rend(); ++it) {
      info_[*it].box = fitted_box(*it);
      if (info_[*it].parent >= 0) set_child_box(info_[*it].parent, info_[*it].slot, info_[*it].box);
    }
  }
  /// The margin of leaves' boxes (0 unless set_margin() said otherwise).
  double margin() const { return margin_; }

private:
  /// insert()'s work, for a shape whose id is already taken.
  void insert_with_id(const T &shape, std::uint32_t id) {
    const Box box = fat(bvh_detail::box_of(shape));
    ++size_;
    if (root_ < 0) {
      root_ = new_node(0, -1, 0);
      info_[root_].box = box;
      info_[root_].count = 1;
      leaf_push(root_, shape, id);
      return;
    }
    bvh_detail::IndexStack path;
    int n = root_;
    for (;;) {
      Info &in = info_[n];
      ++in.count;
      if (!in.box.contains(box)) {
        in.box.extend(box);
        if (in.parent >= 0) set_child_box(in.parent, in.slot, in.box);
      }
      if (nodes_[n].num_children == 0) break;
      path.push(n);
      n = choose_child(n, box);
    }
    if (int(info_[n].count) > split_threshold_ && may_split_at(info_[n].depth)) {
      // The leaf splits: its shapes and the new one go straight to the build
      // (pushing first could move the slot to a larger class for nothing).
      std::vector<Tagged> shapes;
      shapes.reserve(info_[n].count);
      take_shapes(n, shapes);
      shapes.push_back(Tagged{shape, id});
      build(n, shapes);
    } else {
      leaf_push(n, shape, id);
    }
    rebalance_path(path, n);
  }

public:

  /// True iff some stored shape intersects `shape` (touching counts).
  /// Subtrees whose box misses the shape's box are never visited; the final
  /// test is T's intersect() (for this project's shapes, intersect.h's
  /// exact predicate; on the course's server, the course's own).
  bool collision(const T &shape) const {
    if (root_ < 0) return false;
    const Box box = bvh_detail::box_of(shape);
    if (!info_[root_].box.overlaps(box)) return false;
    const Probe probe = Probe::around(box);
    // Children holding the probe's centre first: a hit there is likely.
    return !walk(root_, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
      const Node &node = nodes_[n];
      if (node.num_children == 0) {
        for (const T &s : leaf_shapes(node))
          if (intersect(s, shape)) return kStop;
        return 0;
      }
      unsigned hits, near;
      child_masks(node, probe, hits, near);
      return hits | near << kFirst; // near is a subset of hits
    });
  }

  /// Removes the shape at `pos` and returns the iterator to the shape that
  /// followed it (end() after the last). Every other iterator is
  /// invalidated, but the remaining shapes keep their iteration order, so
  /// erasing while iterating (`it = tree.erase(it)`) visits each shape once.
  /// O(log n) amortized: see erase_at() for the repairs.
  iterator erase(iterator pos) {
    BVH_ASSERT(pos.tree_ == this, "erase() with an iterator of another tree (or a singular one)");
    BVH_ASSERT(pos.leaf_ >= 0, "erase(end())");
    // Catches most stale iterators (changes invalidate them), not all.
    BVH_ASSERT(std::size_t(pos.leaf_) < nodes_.size() && nodes_[pos.leaf_].num_children == 0 &&
                   pos.index_ < shapes_of(pos.leaf_).size(),
               "erase() with an invalidated iterator");
    const std::size_t rank = rank_of(pos);
    const std::uint32_t id = pool_.ids(info_[pos.leaf_].shapes)[pos.index_];
    erase_at(pos.leaf_, pos.index_);
    free_id(id);
    return iterator_at(rank);
  }

  /// Removes every stored shape equal to `value` and returns how many there
  /// were. Only subtrees whose box holds value's box are searched. Needs
  /// `operator==` on T (the course's shapes have none: there, erase by
  /// iterator), and compiles only when used.
  std::size_t erase(const T &value) {
    std::size_t removed = 0;
    int leaf;
    std::size_t index;
    while (find_equal(value, leaf, index)) {
      const std::uint32_t id = pool_.ids(info_[leaf].shapes)[index];
      erase_at(leaf, index);
      free_id(id);
      ++removed;
    }
    return removed;
  }

  /// Calls f(shape) for every stored shape whose box overlaps `box`
  /// (touching counts). If f returns bool, returning false stops the search.
  template <class F> void query(const BoundingBox &box, F &&f) const {
    visit_overlapping(Box::of(box), [&](const T &s) { return keep_going(f, s); });
  }

  /// Calls f(shape) for every stored shape that intersects `shape` (by T's
  /// intersect(): exact, touching counts, for this project's shapes). If f
  /// returns bool, returning false stops the search.
  template <class F> void query(const T &shape, F &&f) const {
    visit_overlapping(bvh_detail::box_of(shape), [&](const T &s) { return !intersect(s, shape) || keep_going(f, s); });
  }

  /// Copies every stored shape that intersects `shape` to `out` (an output
  /// iterator, e.g. std::back_inserter(vector)) and returns its end.
  template <class Out> Out query_into(const T &shape, Out out) const {
    query(shape, [&](const T &s) { *out++ = s; });
    return out;
  }

  /// An input iterator over the shapes a query finds, in the order query()
  /// calls f on them: the search itself, suspended between steps (its stack
  /// of nodes lives in the iterator, on the call stack for shallow trees).
  /// Valid while the tree does not change.
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
      BVH_ASSERT(at_ != nullptr, "dereferencing the end of an overlapping() range");
      return *at_;
    }
    pointer operator->() const { return &**this; }
    /// The next shape found (the end after the last).
    overlap_iterator &operator++() {
      BVH_ASSERT(at_ != nullptr, "incrementing the end of an overlapping() range");
      find_next();
      return *this;
    }
    /// Steps on; returns nothing (an input iterator's post-increment).
    void operator++(int) { ++*this; }
    /// Equal when both are at the end or at the same shape.
    friend bool operator==(const overlap_iterator &a, const overlap_iterator &b) { return a.at_ == b.at_; }
    friend bool operator!=(const overlap_iterator &a, const overlap_iterator &b) { return a.at_ != b.at_; }

  private:
    friend class BVH;
    overlap_iterator(const BVH *tree, const Box &box, const T *shape)
        : tree_(tree), box_(box), probe_(Probe::around(box)) {
      if (shape) shape_.emplace(*shape);
      if (tree->root_ < 0 || !tree->info_[tree->root_].box.overlaps(box)) return;
      stack_.push(tree->root_);
      find_next();
    }
    void find_next() {
      at_ = nullptr;
      for (;;) {
        while (next_ != last_) {
          const T *s = next_++;
          if (bvh_detail::box_of(*s).overlaps(box_) && (!shape_ || intersect(*s, *shape_))) {
            at_ = s;
            return;
          }
        }
        if (stack_.empty()) return;
        const int n = stack_.pop();
        const Node &node = tree_->nodes_[n];
        if (node.num_children == 0) {
          next_ = tree_->pool_.data(leaf_slot(node));
          last_ = next_ + node.child[2];
          continue;
        }
        unsigned hits, near;
        child_masks(node, probe_, hits, near);
        for (int c = node.num_children - 1; c >= 0; --c) // left child on top
          if (hits & (1u << c)) stack_.push(node.child[c]);
      }
    }
    const BVH *tree_ = nullptr;
    Box box_;
    Probe probe_ = Probe(0, 0, 0, 0, 0, 0);
    std::optional<T> shape_; // a copy: the probe may be a temporary
    bvh_detail::IndexStack stack_;
    const T *next_ = nullptr, *last_ = nullptr; // the current leaf's shapes not yet looked at
    const T *at_ = nullptr;                     // nullptr: the end
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
  /// unless the tree is over 96 levels deep.
  overlap_range overlapping(const T &shape) const {
    return overlap_range(overlap_iterator(this, bvh_detail::box_of(shape), &shape));
  }
  /// The shapes query(box, f) would pass to f (boxes that meet `box`).
  overlap_range overlapping(const BoundingBox &box) const {
    return overlap_range(overlap_iterator(this, Box::of(box), nullptr));
  }

  /// A stored shape at the least distance from `p` (by a free
  /// `distance(p, shape)`, as distance.h gives this project's shapes: 0 when
  /// p is inside or on it; needed only when this is used), or nullptr when
  /// the tree is empty; `*dist` gets the distance. Best-first: nodes in order of their box's distance, stopping
  /// when the next box is farther than the best shape. Among equally near
  /// shapes it returns one, not a particular one. O(log n) typically.
  const T *nearest(const Point &p, double *dist = nullptr) const {
    return best_first([&](const Box &b) { return b.distance_to(p.x, p.y); },
                      [&](const T &s) { return distance(p, s); }, dist);
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
  /// answer is one definite list. Returns out's end. Best-first over the
  /// nodes, nearest box first, stopping when the next box is farther than
  /// the k-th shape found: O(log n + k) typically.
  template <class Out> Out nearest(const Point &p, std::size_t k, Out out) const {
    if (k == 0 || root_ < 0) return out;
    const double px = p.x, py = p.y;
    // Squared distance from p to child c's float box (rounded outwards, so
    // never farther than the exact box: a valid bound).
    auto box_key = [&](const Node &node, int c) {
      const double dx = std::max({double(node.lo_x[c]) - px, 0.0, px - double(node.hi_x[c])});
      const double dy = std::max({double(node.lo_y[c]) - py, 0.0, py - double(node.hi_y[c])});
      return dx * dx + dy * dy;
    };
    using Found = std::pair<double, std::uint32_t>; // (distance, id): the order of the answer
    std::vector<Found> found; // a max-heap of the best min(k, seen) so far
    found.reserve(std::min(k, size_) + 1);
    // Past this squared distance nothing can enter the answer (+inf until
    // k shapes are found; a relative margin covers the rounding of squares).
    auto bound = [&] {
      if (found.size() < k) return std::numeric_limits<double>::infinity();
      const double worst = found.front().first;
      return worst * worst * (1 + 1e-9) + 1e-300;
    };
    using Entry = std::pair<double, int>; // (squared box distance, node)
    std::vector<Entry> heap;
    heap.reserve(64);
    heap.push_back({0.0, root_});
    while (!heap.empty()) {
      std::pop_heap(heap.begin(), heap.end(), std::greater<Entry>());
      const Entry e = heap.back();
      heap.pop_back();
      if (e.first > bound()) break;
      const Node &node = nodes_[e.second];
      if (node.num_children == 0) {
        // The leaf's slot from its hot node; the ids only once a shape is
        // near enough to need its tie-break.
        const bvh_detail::Span<const T> v = leaf_shapes(node);
        const std::uint32_t *ids = nullptr;
        for (std::size_t i = 0; i < v.size(); ++i) {
          const double d = distance(p, v[i]);
          if (found.size() == k && d > found.front().first) continue;
          if (!ids) ids = pool_.ids(leaf_slot(node));
          const Found f{d, ids[i]};
          if (found.size() < k) {
            found.push_back(f);
            std::push_heap(found.begin(), found.end());
          } else if (f < found.front()) {
            std::pop_heap(found.begin(), found.end());
            found.back() = f;
            std::push_heap(found.begin(), found.end());
          }
        }
        continue;
      }
      const double limit = bound();
      for (int c = 0; c < node.num_children; ++c) {
        const double key = box_key(node, c);
        if (key > limit) continue;
#if defined(__GNUC__)
        // Best-first reaches most pushed nodes soon, but only after the
        // heap reorders: fetching them now hides the miss behind that work.
        __builtin_prefetch(&nodes_[node.child[c]]);
#endif
        heap.push_back({key, node.child[c]});
        std::push_heap(heap.begin(), heap.end(), std::greater<Entry>());
      }
    }
    std::sort_heap(found.begin(), found.end());
    for (const Found &f : found) *out++ = neighbor{&get(handle{f.second}), f.first, handle{f.second}};
    return out;
  }

  /// The first stored shape met by the ray origin + t * direction, t >= 0
  /// (t = 0 when the origin lies inside or on a shape), or nullptr when the
  /// ray meets none; `*t` gets the ray parameter of the hit. Best-first by
  /// the ray's entry into each box, as nearest(). Needs a free
  /// `ray_hit(origin, direction, shape)` (distance.h), only when used.
  const T *first_hit(const Point &origin, const Point &direction, double *t = nullptr) const {
    return best_first([&](const Box &b) { return b.ray_entry(origin.x, origin.y, direction.x, direction.y); },
                      [&](const T &s) { return ray_hit(origin, direction, s); }, t);
  }

  /// Calls f(a, b) once for every unordered pair of stored shapes that
  /// intersect (by T's intersect(); exact, touching counts, for this
  /// project's shapes); if f returns bool, false stops.
  /// A simultaneous traversal of the tree against itself: a pair of nodes
  /// is opened only when their boxes overlap, so the cost is O(n log n + k)
  /// for k pairs on well-spread scenes, against O(n^2) for a scan.
  template <class F> void for_each_overlapping_pair(F &&f) const {
    if (root_ < 0) return;
    std::vector<std::pair<int, int>> stack{{root_, root_}};
    while (!stack.empty()) {
      auto [a, b] = stack.back();
      stack.pop_back();
      const Node &na = nodes_[a];
      if (a == b) {
        if (na.num_children == 0) {
          const bvh_detail::Span<const T> v = shapes_of(a);
          for (std::size_t i = 0; i < v.size(); ++i)
            for (std::size_t j = i + 1; j < v.size(); ++j)
              if (bvh_detail::box_of(v[i]).overlaps(bvh_detail::box_of(v[j])) && intersect(v[i], v[j]) &&
                  !keep_going(f, v[i], v[j]))
                return;
          continue;
        }
        for (int c = 0; c < na.num_children; ++c) {
          stack.push_back({na.child[c], na.child[c]});
          for (int d = c + 1; d < na.num_children; ++d)
            if (info_[na.child[c]].box.overlaps(info_[na.child[d]].box)) stack.push_back({na.child[c], na.child[d]});
        }
        continue;
      }
      const Node &nb = nodes_[b];
      if (na.num_children == 0 && nb.num_children == 0) {
        for (const T &s : shapes_of(a))
          for (const T &u : shapes_of(b))
            if (bvh_detail::box_of(s).overlaps(bvh_detail::box_of(u)) && intersect(s, u) && !keep_going(f, s, u))
              return;
        continue;
      }
      // Open the inner node of the two, the larger box when both are.
      if (na.num_children == 0 || (nb.num_children != 0 && info_[b].box.area() > info_[a].box.area()))
        std::swap(a, b);
      const Node &open = nodes_[a];
      for (int c = 0; c < open.num_children; ++c)
        if (info_[open.child[c]].box.overlaps(info_[b].box)) stack.push_back({open.child[c], b});
    }
  }

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
  void statistics(std::ostream &ostr, bool print_tree) const {
    long node_count = 0;
    int max_depth = 0;
    double inner_area = 0, leaf_area = 0;
    std::string line;
    char buf[64];
    for_each_preorder([&](int n) {
      const Info &in = info_[n];
      const bool leaf = nodes_[n].num_children == 0;
      const double area = in.box.area() / kCanvasArea;
      ++node_count;
      max_depth = std::max(max_depth, in.depth);
      if (leaf)
        leaf_area += area * double(in.count);
      else
        inner_area += area;
      if (!print_tree) return;
      // The course's stream is not yet in fixed mode when it prints the
      // root, so the root's area shows 3 significant digits, the rest 3
      // decimals.
      std::snprintf(buf, sizeof buf, n == root_ ? "%.3g" : "%.3f", area);
      line.assign(std::size_t(3) * std::size_t(in.depth), ' ');
      line += leaf ? "leaf area=" : "inner area=";
      line += buf;
      line += ' ';
      bvh_detail::append_box(line, in.box);
      if (leaf) {
        line += " elements:";
        for (const T &s : shapes_of(n)) {
          line += ' ';
          bvh_detail::append_box(line, bvh_detail::box_of(s));
        }
      }
      line += '\n';
      ostr << line;
    });
    std::snprintf(buf, sizeof buf, "node count:      %7ld\n", node_count);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "max depth:       %7d\n", max_depth);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "inner node area: %7.3f\n", inner_area);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "leaf node area:  %7.3f\n", leaf_area);
    ostr << buf;
    ostr.flush();
  }

  /// Draws every node's box translucently (root grey, its children red,
  /// green and blue, deeper children blended 2/3 parent and 1/3 their own
  /// primary) and recolours every shape to the colour of its leaf. Boxes
  /// are drawn by the shape library's BoundingBox::render; colours are
  /// made with Color(r, g, b) and given to T::setColor.
  void render_recolor(std::ostream &ostr) {
    if (root_ < 0) return;
    struct Rgb {
      int r, g, b;
    };
    static const Rgb primary[3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
    // Channels mixed here, as Color::mix would (the course's mix returns
    // nothing and this project's returns the mix: neither is relied on).
    auto blend = [](const Rgb &parent, const Rgb &own) {
      const float f = 2.0f / 3.0f;
      return Rgb{int(parent.r * f + own.r * (1 - f)), int(parent.g * f + own.g * (1 - f)),
                 int(parent.b * f + own.b * (1 - f))};
    };
    std::vector<Rgb> rgb(info_.size());
    rgb[root_] = Rgb{128, 128, 128};
    for_each_preorder([&](int n) {
      Info &in = info_[n];
      if (in.parent >= 0) rgb[n] = in.parent == root_ ? primary[in.slot] : blend(rgb[in.parent], primary[in.slot]);
      const Color color(rgb[n].r, rgb[n].g, rgb[n].b);
      BoundingBox(Point(in.box.x0, in.box.y0), Point(in.box.x1, in.box.y1)).render(ostr, color);
      for (T &s : shapes_of(n)) s.setColor(color);
    });
  }

  /// Checks every invariant; on failure returns false and, when `why` is
  /// given, says which node broke what. Meant for tests: O(n log n).
  bool validate(std::string *why = nullptr) const {
    auto fail = [&](int n, const std::string &what) {
      if (why) *why = "node " + std::to_string(n) + ": " + what;
      return false;
    };
    if (nodes_.size() != info_.size()) return fail(-1, "node arrays differ in size");
    if (root_ < 0) {
      if (size_ != 0) return fail(-1, "empty tree with size " + std::to_string(size_));
      if (node_count() != 0) return fail(-1, "empty tree with live nodes");
      if (!loc_.empty() || !free_ids_.empty()) return fail(-1, "empty tree with ids");
      return true;
    }
    std::vector<char> is_free(nodes_.size(), 0);
    for (int f : free_) {
      if (f < 0 || std::size_t(f) >= nodes_.size() || is_free[f]) return fail(f, "bad free-list entry");
      is_free[f] = 1;
    }
    std::size_t counted = 0, reached = 0;
    bool ok = true;
    for_each_preorder([&](int n) {
      if (!ok) return;
      ++reached;
      const Node &node = nodes_[n];
      const Info &in = info_[n];
      if (is_free[n]) ok = fail(n, "reachable node on the free list");
      Box tight;
      std::size_t count = 0;
      if (n == root_) {
        if (in.parent != -1 || in.depth != 0) ok = fail(n, "root has a parent or depth != 0");
      } else {
        const Node &p = nodes_[in.parent];
        if (in.depth != info_[in.parent].depth + 1) ok = fail(n, "depth is not parent's + 1");
        if (in.slot < 0 || in.slot >= p.num_children || p.child[in.slot] != n)
          ok = fail(n, "parent does not list it in its slot");
        else if (p.lo_x[in.slot] != bvh_detail::float_down(in.box.x0) ||
                 p.lo_y[in.slot] != bvh_detail::float_down(in.box.y0) ||
                 p.hi_x[in.slot] != bvh_detail::float_up(in.box.x1) ||
                 p.hi_y[in.slot] != bvh_detail::float_up(in.box.y1))
          ok = fail(n, "parent's float box for it is not its box rounded outwards");
      }
      if (depth_limit_ != unlimited && in.depth > depth_limit_) ok = fail(n, "deeper than depth_limit");
      if (node.num_children == 0) {
        const bvh_detail::Span<const T> shapes = shapes_of(n);
        if (shapes.empty()) ok = fail(n, "empty leaf");
        if (node.child[0] != std::int32_t(in.shapes.index) || node.child[1] != std::int32_t(in.shapes.cls) ||
            node.child[2] != std::int32_t(shapes.size()))
          ok = fail(n, "leaf's hot record disagrees with its slot");
        if (int(shapes.size()) > split_threshold_ && may_split_at(in.depth))
          ok = fail(n, "leaf over split_threshold above depth_limit");
        for (const T &s : shapes) tight.extend(bvh_detail::box_of(s));
        count = shapes.size();
        counted += count;
        const std::uint32_t *ids = shapes.empty() ? nullptr : pool_.ids(in.shapes);
        for (std::size_t i = 0; ok && i < shapes.size(); ++i)
          if (ids[i] >= loc_.size() || loc_[ids[i]].leaf != n || loc_[ids[i]].index != i)
            ok = fail(n, "shape " + std::to_string(i) + "'s id does not locate it");
        // With a margin a leaf's box may be larger than fat(tight): update()
        // leaves it as it is while the shapes stay inside.
        if (margin_ > 0 && in.box.contains(tight)) tight = in.box;
      } else {
        if (in.has_shapes) ok = fail(n, "inner node holds shapes");
        if (node.num_children < 2 || node.num_children > 3) ok = fail(n, "inner node without 2 or 3 children");
        if (node.num_children == 2 && split_threshold_ != 1)
          ok = fail(n, "2 children although split_threshold > 1");
        for (int c = 0; c < node.num_children; ++c) {
          tight.extend(info_[node.child[c]].box);
          count += info_[node.child[c]].count;
        }
      }
      if (ok && tight != in.box) ok = fail(n, "box is not the tight box of its subtree");
      if (ok && count != in.count) ok = fail(n, "shape count is not its subtree's");
    });
    if (!ok) return false;
    if (reached + free_.size() != nodes_.size()) return fail(root_, "unreachable nodes off the free list");
    if (counted != size_) return fail(root_, "size() disagrees with the shapes stored");
    if (loc_.size() != size_ + free_ids_.size()) return fail(-1, "ids in use and free do not add up");
    std::vector<char> id_free(loc_.size(), 0);
    for (std::uint32_t id : free_ids_) {
      if (id >= loc_.size() || loc_[id].leaf != -1 || id_free[id])
        return fail(-1, "free id " + std::to_string(id) + " is in use or listed twice");
      id_free[id] = 1;
    }
    return true;
  }

  /// The surface area heuristic cost that statistics() prints, unrounded:
  /// the inner nodes' box areas plus each leaf's box area times its shape
  /// count, in units of the 1000 x 1000 canvas (0 for an empty tree).
  double sah_cost() const {
    double cost = 0;
    for_each_preorder([&](int n) {
      const double area = info_[n].box.area() / kCanvasArea;
      cost += nodes_[n].num_children == 0 ? area * double(info_[n].count) : area;
    });
    return cost;
  }

  /// Depth of the deepest node (0 for a single leaf or an empty tree).
  int height() const {
    int h = 0;
    for_each_preorder([&](int n) { h = std::max(h, info_[n].depth); });
    return h;
  }

private:
  // Areas are reported relative to the course's 1000 x 1000 canvas.
  static constexpr double kCanvasArea = 1000.0 * 1000.0;

  struct Node { // hot: all a query reads
    float lo_x[3], lo_y[3], hi_x[3], hi_y[3]; // children's boxes, rounded outwards
    // Inner node: the children. Leaf: where its shapes are, copied from its
    // Info by sync_leaf (slot index, slot class, shape count), so that a
    // query reaches a leaf's shapes without reading the cold Info.
    std::int32_t child[3];
    std::int32_t num_children; // 0: leaf
  };
  /// The pool slot of leaf `node` (sync_leaf keeps it).
  static typename bvh_detail::LeafPool<T>::Slot leaf_slot(const Node &node) {
    return {std::uint32_t(node.child[0]), std::uint32_t(node.child[1])};
  }
  /// The shapes of leaf `node`, found from its hot record alone (queries
  /// never read the cold Info of a leaf).
  bvh_detail::Span<const T> leaf_shapes(const Node &node) const {
    return {pool_.data(leaf_slot(node)), std::size_t(node.child[2])};
  }
  struct Info { // cold: exact geometry, links, shapes
    Box box;
    std::int32_t parent = -1; // -1 for the root
    std::int32_t slot = 0;    // index in the parent's child[]
    std::int32_t depth = 0;
    std::size_t count = 0;    // shapes in the subtree
    typename bvh_detail::LeafPool<T>::Slot shapes; // leaves: their shapes, in leaf order
    bool has_shapes = false;                       // shapes names a slot of pool_
  };

  using Tagged = bvh_detail::Tagged<T>;
  struct Loc { // where the shape of one id is
    std::int32_t leaf = -1; // -1: the id is free
    std::uint32_t index = 0;
  };

  /// A free id (one given back first), its Loc not yet set.
  std::uint32_t new_id() {
    if (!free_ids_.empty()) {
      const std::uint32_t id = free_ids_.back();
      free_ids_.pop_back();
      return id;
    }
    if (loc_.size() == std::size_t(std::numeric_limits<std::uint32_t>::max()))
      throw std::length_error("BVH::insert: more shapes than 32-bit handles can name");
    loc_.push_back(Loc{});
    return std::uint32_t(loc_.size() - 1);
  }
  /// Gives `id` back; with nothing stored, forgets every id.
  void free_id(std::uint32_t id) {
    loc_[id].leaf = -1;
    if (size_ == 0) {
      loc_.clear();
      free_ids_.clear();
    } else {
      free_ids_.push_back(id);
    }
  }
  /// Drops every node and shape but keeps the ids (erase_at of the last
  /// shape, which update() inserts again under its id).
  void clear_nodes() {
    nodes_.clear();
    info_.clear();
    free_.clear();
    pool_ = bvh_detail::LeafPool<T>();
    root_ = -1;
    size_ = 0;
  }

  /// A leaf's box for shapes whose box is `tight`: grown by the margin.
  Box fat(const Box &tight) const { return margin_ > 0 ? tight.grown(margin_) : tight; }
  /// Node n's box recomputed from its shapes (leaf) or children's boxes.
  Box fitted_box(int n) const {
    Box box;
    const Node &node = nodes_[n];
    if (node.num_children == 0) {
      for (const T &s : shapes_of(n)) box.extend(bvh_detail::box_of(s));
      return fat(box);
    }
    for (int c = 0; c < node.num_children; ++c)
      if (info_[node.child[c]].count != 0) box.extend(info_[node.child[c]].box);
    return box;
  }
  /// Refits the boxes from node n up, stopping where a box is unchanged.
  void refit_up(int n) {
    for (; n >= 0; n = info_[n].parent) {
      const Box box = fitted_box(n);
      if (box == info_[n].box) return;
      info_[n].box = box;
      if (info_[n].parent >= 0) set_child_box(info_[n].parent, info_[n].slot, box);
    }
  }

  /// The shapes of node n (none for an inner node).
  bvh_detail::Span<const T> shapes_of(int n) const {
    const Info &in = info_[n];
    if (!in.has_shapes) return {nullptr, 0};
    return {pool_.data(in.shapes), pool_.size(in.shapes)};
  }
  bvh_detail::Span<T> shapes_of(int n) {
    const Info &in = info_[n];
    if (!in.has_shapes) return {nullptr, 0};
    return {pool_.data(in.shapes), pool_.size(in.shapes)};
  }
  /// Appends a shape with its id to leaf n (giving it a slot if it has none).
  template <class V> void leaf_push(int n, V &&shape, std::uint32_t id) {
    Info &in = info_[n];
    if (!in.has_shapes) {
      in.shapes = pool_.allocate(1);
      in.has_shapes = true;
    }
    pool_.push_back(in.shapes, std::forward<V>(shape), id);
    loc_[id] = Loc{n, std::uint32_t(pool_.size(in.shapes) - 1)};
    sync_leaf(n);
  }
  /// Copies leaf n's slot and count into its hot Node.
  void sync_leaf(int n) {
    const Info &in = info_[n];
    Node &node = nodes_[n];
    node.child[0] = in.has_shapes ? std::int32_t(in.shapes.index) : 0;
    node.child[1] = in.has_shapes ? std::int32_t(in.shapes.cls) : 0;
    node.child[2] = in.has_shapes ? std::int32_t(pool_.size(in.shapes)) : 0;
  }
  /// Gives leaf n (holding no shapes) the rule's items [begin, end), moved,
  /// in one slot of their size.
  template <class Rule> void fill_leaf(int n, Rule &rule, std::size_t begin, std::size_t end) {
    Info &in = info_[n];
    in.shapes = pool_.allocate(end - begin);
    in.has_shapes = true;
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t id = rule.id(i);
      pool_.push_back(in.shapes, std::move(rule.shape(i)), id);
      loc_[id] = Loc{n, std::uint32_t(i - begin)};
    }
    sync_leaf(n);
  }
  /// Moves leaf n's shapes, with their ids, to the end of `out` and gives
  /// its slot back.
  void take_shapes(int n, std::vector<Tagged> &out) {
    const bvh_detail::Span<T> v = shapes_of(n);
    if (v.empty()) return;
    const std::uint32_t *ids = pool_.ids(info_[n].shapes);
    for (std::size_t i = 0; i < v.size(); ++i) out.push_back(Tagged{std::move(v[i]), ids[i]});
    release_shapes(n);
  }
  void release_shapes(int n) {
    Info &in = info_[n];
    if (in.has_shapes) {
      pool_.release(in.shapes);
      in.has_shapes = false;
      if (nodes_[n].num_children == 0) sync_leaf(n);
    }
  }

  bool may_split_at(int depth) const { return depth_limit_ == unlimited || depth < depth_limit_; }

  int new_node(int depth, int parent, int slot) {
    int n;
    if (!free_.empty()) {
      n = free_.back();
      free_.pop_back();
    } else {
      n = int(nodes_.size());
      nodes_.emplace_back();
      info_.emplace_back();
    }
    reset_node(n, depth, parent, slot);
    return n;
  }

  /// Node n as a fresh leaf at `depth`, child `slot` of `parent`.
  void reset_node(int n, int depth, int parent, int slot) {
    nodes_[n] = Node();
    Info &in = info_[n];
    in.box = Box();
    in.depth = depth;
    in.parent = parent;
    in.slot = slot;
    in.count = 0;
    release_shapes(n);
  }

  void free_node(int n) {
    release_shapes(n);
    free_.push_back(n);
  }

  void set_child_box(int parent, int slot, const Box &box) {
    Node &p = nodes_[parent];
    float f[4];
    bvh_detail::round_out(box, f);
    p.lo_x[slot] = f[0];
    p.lo_y[slot] = f[1];
    p.hi_x[slot] = f[2];
    p.hi_y[slot] = f[3];
  }


  /// For inner node `node`: bit c of `hits` is set when child c's box meets
  /// the probe's box, bit c of `near` when it also holds the probe's centre
  /// (a hit there is likely, so collision() visits those first). With SSE2
  /// the three children are tested in one 4-lane compare per bound (lane 3
  /// reads the next field of the node and is masked off); W1's rejects spend
  /// most of their instructions here. BVH_NO_SIMD forces the scalar path.
  static void child_masks(const Node &node, const Probe &p, unsigned &hits, unsigned &near) {
    const unsigned live = (1u << node.num_children) - 1;
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    const __m128 lx = _mm_loadu_ps(node.lo_x), ly = _mm_loadu_ps(node.lo_y);
    const __m128 hx = _mm_loadu_ps(node.hi_x), hy = _mm_loadu_ps(node.hi_y);
    const __m128 meets = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.hi_x), _mm_cmple_ps(p.lo_x, hx)),
                                    _mm_and_ps(_mm_cmple_ps(ly, p.hi_y), _mm_cmple_ps(p.lo_y, hy)));
    const __m128 holds = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.mid_x), _mm_cmple_ps(p.mid_x, hx)),
                                    _mm_and_ps(_mm_cmple_ps(ly, p.mid_y), _mm_cmple_ps(p.mid_y, hy)));
    hits = unsigned(_mm_movemask_ps(meets)) & live;
    near = unsigned(_mm_movemask_ps(holds)) & hits;
#else
    hits = 0;
    near = 0;
    for (int c = 0; c < 3; ++c) {
      hits |= unsigned((node.lo_x[c] <= p.hi_x) & (p.lo_x <= node.hi_x[c]) & (node.lo_y[c] <= p.hi_y) &
                       (p.lo_y <= node.hi_y[c]))
              << c;
      near |= unsigned((node.lo_x[c] <= p.mid_x) & (p.mid_x <= node.hi_x[c]) & (node.lo_y[c] <= p.mid_y) &
                       (p.mid_y <= node.hi_y[c]))
              << c;
    }
    hits &= live;
    near &= hits;
#endif
  }

  /// The insertion strategy, part 1: the child whose box grows least in
  /// area when it takes `box`; ties go to the smaller child, then the first.
  /// Boxes are the children's float boxes (rounded outwards) kept in the
  /// parent, so the choice reads one cache line; areas are computed in
  /// double from those floats.
  int choose_child(int n, const Box &box) const {
    const Node &node = nodes_[n];
    const double bx0 = box.x0, by0 = box.y0, bx1 = box.x1, by1 = box.y1;
    int best = 0;
    double best_growth = 0, best_area = 0;
    for (int c = 0; c < node.num_children; ++c) {
      const double x0 = node.lo_x[c], y0 = node.lo_y[c], x1 = node.hi_x[c], y1 = node.hi_y[c];
      const double area = (x1 - x0) * (y1 - y0);
      const double grown = (std::max(x1, bx1) - std::min(x0, bx0)) * (std::max(y1, by1) - std::min(y0, by0));
      const double growth = grown - area;
      if (c == 0 || growth < best_growth || (growth == best_growth && area < best_area)) {
        best = c;
        best_growth = growth;
        best_area = area;
      }
    }
    return node.child[best];
  }

  /// A child holding more than this share of its parent's shapes makes
  /// the parent lopsided (a balanced ternary node gives each about 1/3).
  static constexpr double kLopsided = 0.6;
  /// Subtrees smaller than this are never rebuilt for balance: their
  /// imbalance costs less than the rebuild.
  std::size_t min_rebuild() const { return std::max<std::size_t>(16, 3 * std::size_t(split_threshold_ + 1)); }

  /// The insertion strategy, part 2 (scapegoat-style partial rebuilds).
  /// Least-growth descent alone grows worse trees than the build rule and,
  /// under sorted input, a spine as deep as n / k. After each insert, walk
  /// the path and rebuild, by the build rule, the highest node (of at least
  /// min_rebuild() shapes) whose child on the path holds more than
  /// kLopsided of its shapes. A rebuilt subtree of m shapes is balanced by
  /// count and needs Omega(m) inserts to tip again, so rebuilds cost
  /// O(log n) amortised per insert per level, and every level shrinks the
  /// count by at least 1/kLopsided: depth O(log n) for any insertion order.
  /// Measured on 100,000 disks (k = 4): SAH within 1.07x of the bulk build
  /// in random order and 1.16x in sorted order (README.txt).
  /// `path` holds the inner nodes from the root down to the leaf `last`.
  void rebalance_path(bvh_detail::IndexStack &path, int last) {
    int scapegoat = -1, below = last;
    while (!path.empty()) { // bottom-up; the last lopsided node found is the highest
      const int a = path.pop();
      const std::size_t count = info_[a].count;
      if (count >= min_rebuild() && double(info_[below].count) > kLopsided * double(count)) scapegoat = a;
      below = a;
    }
    if (scapegoat >= 0) rebuild(scapegoat);
  }

  /// f(args...) as "go on?": true unless f returns a bool false.
  template <class F, class... A> static bool keep_going(F &f, const A &...args) {
    if constexpr (std::is_same<decltype(f(args...)), bool>::value)
      return f(args...);
    else {
      f(args...);
      return true;
    }
  }

  /// Calls visit(shape) on each shape whose box overlaps `box`, until it
  /// returns false.
  template <class V> void visit_overlapping(const Box &box, V &&visit) const {
    if (root_ < 0 || !info_[root_].box.overlaps(box)) return;
    const Probe probe = Probe::around(box);
    walk(root_, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
      const Node &node = nodes_[n];
      if (node.num_children == 0) {
        for (const T &s : leaf_shapes(node))
          if (bvh_detail::box_of(s).overlaps(box) && !visit(s)) return kStop;
        return 0;
      }
      unsigned hits, near;
      child_masks(node, probe, hits, near);
      return hits;
    });
  }

  /// Best-first search for the shape of least `shape_key`, where
  /// box_key(node box) never exceeds the key of a shape inside the box (up
  /// to rounding, allowed for by a relative margin). +inf keys are misses.
  template <class BoxKey, class ShapeKey>
  const T *best_first(BoxKey &&box_key, ShapeKey &&shape_key, double *out) const {
    const double inf = std::numeric_limits<double>::infinity();
    const T *best = nullptr;
    double best_key = inf;
    if (root_ >= 0) {
      using Entry = std::pair<double, int>;
      std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
      const double k0 = box_key(info_[root_].box);
      if (k0 < inf) heap.push({k0, root_});
      while (!heap.empty()) {
        const auto [key, n] = heap.top();
        heap.pop();
        if (best && key > best_key * (1 + 1e-12) + 1e-300) break;
        const Node &node = nodes_[n];
        if (node.num_children == 0) {
          for (const T &s : shapes_of(n)) {
            const double k = shape_key(s);
            if (k < best_key) {
              best_key = k;
              best = &s;
            }
          }
          continue;
        }
        for (int c = 0; c < node.num_children; ++c) {
          const double k = box_key(info_[node.child[c]].box);
          if (k < inf) heap.push({k, node.child[c]});
        }
      }
    }
    if (out) *out = best_key;
    return best;
  }

  /// Shapes before `pos` in iteration order (size() for end()).
  std::size_t rank_of(const iterator &pos) const {
    if (pos.leaf_ < 0) return size_;
    std::size_t rank = pos.index_;
    for (int n = pos.leaf_; n != root_; n = info_[n].parent) {
      const Node &p = nodes_[info_[n].parent];
      for (int c = 0; c < info_[n].slot; ++c) rank += info_[p.child[c]].count;
    }
    return rank;
  }

  /// The iterator to the shape of rank `rank` (end() past the last).
  iterator iterator_at(std::size_t rank) const {
    if (rank >= size_) return end();
    int n = root_;
    while (nodes_[n].num_children != 0) {
      const Node &node = nodes_[n];
      int c = 0;
      while (rank >= info_[node.child[c]].count) rank -= info_[node.child[c]].count, ++c;
      n = node.child[c];
    }
    return iterator(this, n, rank);
  }

  /// Finds a stored shape equal to `value`: its leaf and index.
  bool find_equal(const T &value, int &leaf, std::size_t &index) const {
    const Box box = bvh_detail::box_of(value);
    if (root_ < 0 || !info_[root_].box.contains(box)) return false;
    // A float child box is its exact box rounded outwards: it holds `box`
    // whenever the exact one does.
    return !walk(root_, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
      const Node &node = nodes_[n];
      if (node.num_children == 0) {
        const bvh_detail::Span<const T> v = shapes_of(n);
        for (std::size_t i = 0; i < v.size(); ++i)
          if (v[i] == value) {
            leaf = n;
            index = i;
            return kStop;
          }
        return 0;
      }
      unsigned enter = 0;
      for (int c = 0; c < node.num_children; ++c)
        enter |= unsigned(node.lo_x[c] <= box.x0 && node.lo_y[c] <= box.y0 && box.x1 <= node.hi_x[c] &&
                          box.y1 <= node.hi_y[c])
                 << c;
      return enter;
    });
  }

  /// Removes shape `index` of leaf `leaf`, then mends the tree:
  ///  1. counts and tight boxes are refitted from the leaf to the root;
  ///  2. the highest ancestor left with at most split_threshold shapes, or
  ///     else the parent of a leaf left empty, is rebuilt from its shapes
  ///     (a leaf, or 3 children again): no empty leaf, no inner node with
  ///     too few children or too few shapes;
  ///  3. the highest ancestor whose largest child now holds more than
  ///     kLopsided of its shapes is rebuilt, as insert's rebalance_path
  ///     does, so depth stays O(log n) under any churn.
  /// Rebuilds here split the shapes in their leaf order (build_in_order), so
  /// iteration order survives an erase. A rebuild of m shapes costs O(m log
  /// m) and, as for inserts, needs Omega(m) erases below the node to recur.
  void erase_at(int leaf, std::size_t index) {
    pool_.erase(info_[leaf].shapes, index);
    sync_leaf(leaf);
    {
      const std::uint32_t *ids = pool_.ids(info_[leaf].shapes);
      for (std::size_t i = index, n = pool_.size(info_[leaf].shapes); i < n; ++i) loc_[ids[i]].index = std::uint32_t(i);
    }
    if (--size_ == 0) {
      clear_nodes();
      return;
    }
    // 1. Refit, bottom-up (above the first box that does not change, only
    // the counts do), and 2. find the node to mend on the way.
    int mend = shapes_of(leaf).empty() ? info_[leaf].parent : -1;
    bool refit = true;
    for (int n = leaf; n >= 0; n = info_[n].parent) {
      Info &in = info_[n];
      --in.count;
      if (refit) {
        const Box box = fitted_box(n);
        refit = box != in.box;
        in.box = box;
        if (refit && in.parent >= 0 && in.count != 0) set_child_box(in.parent, in.slot, box);
      }
      if (n != leaf && in.count <= std::size_t(split_threshold_)) mend = n; // the highest wins
    }
    if (mend >= 0) rebuild(mend, true);
    // 3. Balance: the highest lopsided ancestor of what changed.
    int scapegoat = -1;
    for (int a = mend >= 0 ? mend : leaf; a >= 0; a = info_[a].parent) {
      const Node &node = nodes_[a];
      if (node.num_children == 0 || info_[a].count < min_rebuild()) continue;
      std::size_t largest = 0;
      for (int c = 0; c < node.num_children; ++c) largest = std::max(largest, info_[node.child[c]].count);
      if (double(largest) > kLopsided * double(info_[a].count)) scapegoat = a;
    }
    if (scapegoat >= 0) rebuild(scapegoat, true);
  }

  // ---- Building: one top-down loop that every build rule plugs into -------
  //
  // construct(), a leaf's split, and the partial rebuilds of insert and
  // erase all run build_top_down(). Per node it computes the box and count
  // of the node's items and makes a leaf when the course says so (at most
  // split_threshold items, or at depth_limit); otherwise the rule cuts the
  // items into 3 consecutive groups and each non-empty group becomes a
  // child, children built left to right. A rule supplies only its items,
  // box(i), shape(i), order_leaf(task) (a leaf's shapes are then taken in
  // item order) and cut(task, box, cut, child_state):
  // CourseRule (the course's), SahRule (binned SAH) and InOrderRule (thirds
  // in the given order, for erase).

  /// True when T stores its centre (getCenter() returns a reference, as
  /// Disk's does): items then read it from the shape instead of caching a
  /// copy, 48 bytes instead of 64 for a disk, which the selections move.
  static constexpr bool kCenterStored = std::is_reference<decltype(std::declval<const T &>().getCenter())>::value;
  struct CachedCenter { // a triangle's or quad's centre is a sum: computed once
    bvh_detail::XY center;
    T shape;
    std::uint32_t index; // input position: the last tie-break
    const bvh_detail::XY &centre() const { return center; }
  };
  struct StoredCenter {
    T shape;
    std::uint32_t index;
    decltype(auto) centre() const { return shape.getCenter(); }
  };
  /// One shape during a course build.
  using Item = typename std::conditional<kCenterStored, StoredCenter, CachedCenter>::type;
  static Item make_item(const T &shape, std::uint32_t index) {
    if constexpr (kCenterStored)
      return Item{shape, index};
    else
      return Item{bvh_detail::XY::of(shape.getCenter()), shape, index};
  }
  struct Key { // the order of one node: see CourseRule
    int axis;       // 0: x, 1: y
    bool other_too; // compare the other axis before the input position
  };
  /// Key's order with the axis and the chain fixed at compile time: the
  /// selections spend most of a build in this comparison, and a runtime
  /// axis costs a branch per coordinate read.
  template <int Axis, bool OtherToo> struct Order {
    bool operator()(const Item &a, const Item &b) const {
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
  template <class F> static void with_order(const Key &key, F &&f) {
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

  /// The course's cut of [begin, end): 3 consecutive groups whose sizes
  /// differ by at most one, larger first (empty ones when fewer than 3).
  static void cut_in_thirds(std::size_t begin, std::size_t end, std::size_t cut[4]) {
    const std::size_t n = end - begin, base = n / 3, extra = n % 3;
    cut[0] = begin;
    for (int g = 0; g < 3; ++g) cut[g + 1] = cut[g] + base + (std::size_t(g) < extra ? 1 : 0);
  }

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
  class CourseRule {
  public:
    struct State {
      unsigned axes_used; // bit 0: x, bit 1: y, by the node's ancestors
      Key parent_key;     // the order the node's shapes arrive in
      bool has_parent_key;
    };
    /// `src`: the shapes the items were made from, for their ids; nullptr
    /// when the ids are the input positions (construct).
    CourseRule(std::vector<Item> &items, const std::vector<Tagged> *src) : items_(items), src_(src) {}
    Box box(std::size_t i) const { return bvh_detail::box_of(items_[i].shape); }
    T &shape(std::size_t i) { return items_[i].shape; }
    std::uint32_t id(std::size_t i) const { return src_ ? (*src_)[items_[i].index].id : items_[i].index; }
    void order_leaf(const BuildTask<State> &t) {
      // Selection left the range unordered; restore the parent's order.
      const auto first = items_.begin() + long(t.begin), last = items_.begin() + long(t.end);
      if (t.state.has_parent_key)
        with_order(t.state.parent_key, [&](auto order) { std::sort(first, last, order); });
      else
        std::sort(first, last, [](const Item &a, const Item &b) { return a.index < b.index; });
    }
    void cut(const BuildTask<State> &t, const Box &box, std::size_t cut[4], State child[3]) {
      const int axis = box.dx() >= box.dy() ? 0 : 1;
      const Key key{axis, (t.state.axes_used & (2u >> axis)) != 0};
      cut_in_thirds(t.begin, t.end, cut);
      const auto first = items_.begin();
      with_order(key, [&](auto order) {
        std::nth_element(first + long(cut[0]), first + long(cut[1]), first + long(cut[3]), order);
        std::nth_element(first + long(cut[1]), first + long(cut[2]), first + long(cut[3]), order);
      });
      for (int g = 0; g < 3; ++g) child[g] = State{t.state.axes_used | (1u << axis), key, true};
    }
    static State root_state() { return State{0u, Key{0, false}, false}; }

  private:
    std::vector<Item> &items_;
    const std::vector<Tagged> *src_;
  };

  /// The items of SahRule and InOrderRule: the shapes themselves, taken in
  /// their current order at a leaf; no state carried down.
  class ShapesAsItems {
  public:
    struct State {};
    explicit ShapesAsItems(std::vector<Tagged> &shapes) : v_(shapes) {}
    Box box(std::size_t i) const { return bvh_detail::box_of(v_[i].shape); }
    T &shape(std::size_t i) { return v_[i].shape; }
    std::uint32_t id(std::size_t i) const { return v_[i].id; }
    void order_leaf(const BuildTask<State> &) {}
    static State root_state() { return State{}; }

  protected:
    std::vector<Tagged> &v_;
  };

  /// The alternative build rule, binned SAH for a ternary tree. Leaves are
  /// where the course's rule makes them. Otherwise the shapes' centres are
  /// binned into kSahBins slots along each axis, and the node is cut at the
  /// two bin boundaries, on the axis, that minimise the surface area
  /// heuristic sum over the 3 groups of (box area x shape count), the
  /// quantity the statistics print; every group must be non-empty. When the
  /// centres fill fewer than 3 bins on both axes (clusters, duplicates), it
  /// falls back to the course's cut into thirds by count on the longer side.
  /// O(n) per level plus O(kSahBins^2) per node: O(n log n) for a balanced
  /// result.
  class SahRule : public ShapesAsItems {
  public:
    using State = typename ShapesAsItems::State;
    using ShapesAsItems::ShapesAsItems;
    void cut(const BuildTask<State> &t, const Box &box, std::size_t cut[4], State *) {
      std::vector<Tagged> &v = this->v_; // (a dependent base: named through this)
      Box centres;
      for (std::size_t i = t.begin; i < t.end; ++i) centres.extend(Box::at(v[i].shape.getCenter()));
      // Best (axis, first cut, second cut) over both axes.
      double best_cost = std::numeric_limits<double>::infinity();
      int best_axis = -1, best_i = 0, best_j = 0;
      for (int axis = 0; axis < 2; ++axis) {
        const double lo = axis ? centres.y0 : centres.x0;
        const double extent = (axis ? centres.y1 : centres.x1) - lo;
        if (!(extent > 0)) continue;
        Box bin_box[kSahBins];
        std::size_t bin_count[kSahBins] = {};
        for (std::size_t i = t.begin; i < t.end; ++i) {
          const int b = bin_of(v[i], axis, lo, extent);
          bin_box[b].extend(bvh_detail::box_of(v[i].shape));
          ++bin_count[b];
        }
        // Groups: bins [0, i), [i, j), [j, kSahBins).
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
      const auto first = v.begin() + long(t.begin), last = v.begin() + long(t.end);
      if (best_axis >= 0) {
        const double lo = best_axis ? centres.y0 : centres.x0;
        const double extent = (best_axis ? centres.y1 : centres.x1) - lo;
        const auto mid1 = std::partition(first, last, [&](const Tagged &s) { return bin_of(s, best_axis, lo, extent) < best_i; });
        const auto mid2 = std::partition(mid1, last, [&](const Tagged &s) { return bin_of(s, best_axis, lo, extent) < best_j; });
        cut[0] = t.begin;
        cut[1] = std::size_t(mid1 - v.begin());
        cut[2] = std::size_t(mid2 - v.begin());
        cut[3] = t.end;
      } else {
        // Fallback: thirds by count along the longer side of the box.
        const int axis = box.dx() >= box.dy() ? 0 : 1;
        cut_in_thirds(t.begin, t.end, cut);
        auto less = [axis](const Tagged &a, const Tagged &b) {
          return axis ? a.shape.getCenter().y < b.shape.getCenter().y : a.shape.getCenter().x < b.shape.getCenter().x;
        };
        std::nth_element(first, v.begin() + long(cut[1]), last, less);
        std::nth_element(v.begin() + long(cut[1]), v.begin() + long(cut[2]), last, less);
      }
    }

  private:
    static int bin_of(const Tagged &s, int axis, double lo, double extent) {
      const double c = axis ? s.shape.getCenter().y : s.shape.getCenter().x;
      return std::min(kSahBins - 1, int(double(kSahBins) * (c - lo) / extent));
    }
  };
  /// Bins per axis of the SAH build.
  static constexpr int kSahBins = 16;

  /// Thirds in the order given, without sorting: where leaf order must
  /// survive (erase). Shapes that come out of a subtree in leaf order are
  /// already spatially grouped.
  class InOrderRule : public ShapesAsItems {
  public:
    using State = typename ShapesAsItems::State;
    using ShapesAsItems::ShapesAsItems;
    void cut(const BuildTask<State> &t, const Box &, std::size_t cut[4], State *) { cut_in_thirds(t.begin, t.end, cut); }
  };

  /// The shared loop: builds every task of `tasks` (and what they spawn) by
  /// `rule`. Tasks whose node is at depth `defer_depth` are not built but
  /// moved to `*deferred` (construct's parallel part builds them).
  template <class Rule>
  void build_top_down(std::vector<BuildTask<typename Rule::State>> &tasks, Rule &rule, const bvh_detail::Layout *layout,
                      int defer_depth = -1, std::vector<BuildTask<typename Rule::State>> *deferred = nullptr) {
    using Task = BuildTask<typename Rule::State>;
    while (!tasks.empty()) {
      const Task t = tasks.back();
      tasks.pop_back();
      Info &in = info_[t.node];
      const int depth = in.depth;
      if (deferred && depth == defer_depth) {
        deferred->push_back(t);
        continue;
      }
      Box box;
      for (std::size_t i = t.begin; i < t.end; ++i) box.extend(rule.box(i));
      box = fat(box); // (a grown union is the union of the grown boxes)
      const std::size_t n = t.end - t.begin;
      in.box = box;
      in.count = n;
      if (in.parent >= 0) set_child_box(in.parent, in.slot, box);
      if (n <= std::size_t(split_threshold_) || !may_split_at(depth)) {
        rule.order_leaf(t);
        nodes_[t.node].num_children = 0;
        // A laid-out build (construct) gathers every leaf's shapes at the
        // end, in one pass, with no thread touching the pool.
        if (!layout) fill_leaf(t.node, rule, t.begin, t.end);
        continue;
      }
      std::size_t cut[4];
      typename Rule::State state[3];
      rule.cut(t, box, cut, state);
      Task child[3];
      int children = 0;
      const int groups = (cut[1] > cut[0]) + (cut[2] > cut[1]) + (cut[3] > cut[2]);
      int grandchildren = t.block + groups; // laid out: where the next child's children go
      for (int g = 0; g < 3; ++g) {
        if (cut[g + 1] == cut[g]) continue;
        int c, block = -1;
        if (layout) {
          c = t.block + children;
          reset_node(c, depth + 1, t.node, children);
          block = grandchildren;
          grandchildren += int(layout->nodes(cut[g + 1] - cut[g], depth + 1)) - 1;
        } else {
          c = new_node(depth + 1, t.node, children);
        }
        nodes_[t.node].child[children] = c;
        child[children++] = Task{c, cut[g], cut[g + 1], block, state[g]};
      }
      nodes_[t.node].num_children = children;
      for (int c = children - 1; c >= 0; --c) tasks.push_back(child[c]); // built left to right
    }
  }

  /// Builds at leaf `at` from `shapes` by the rule in use (a split or a
  /// partial rebuild: nodes from new_node()).
  void build(int at, const std::vector<Tagged> &shapes) {
    const Box before = info_[at].box;
    if (build_rule_ == BuildRule::sah) {
      std::vector<Tagged> v(shapes);
      SahRule rule(v);
      std::vector<BuildTask<typename SahRule::State>> tasks{{at, 0, v.size(), -1, SahRule::root_state()}};
      build_top_down(tasks, rule, nullptr);
      refit_above(at, before);
      return;
    }
    CourseRule rule(fill_items(shapes.size(), [&](std::size_t i) -> const T & { return shapes[i].shape; }), &shapes);
    std::vector<BuildTask<typename CourseRule::State>> &tasks = scratch_.value.tasks;
    tasks.assign(1, {at, 0, shapes.size(), -1, CourseRule::root_state()});
    build_top_down(tasks, rule, nullptr);
    refit_above(at, before);
  }

  /// Builds at leaf `at` from `shapes`, keeping their order (InOrderRule).
  void build_in_order(int at, std::vector<Tagged> &shapes) {
    const Box before = info_[at].box;
    InOrderRule rule(shapes);
    std::vector<BuildTask<typename InOrderRule::State>> tasks{{at, 0, shapes.size(), -1, InOrderRule::root_state()}};
    build_top_down(tasks, rule, nullptr);
    refit_above(at, before);
  }

  /// The reused item array, filled with shape(i) for i < n (input
  /// position = i).
  template <class Shape> std::vector<Item> &fill_items(std::size_t n, Shape &&shape) {
    std::vector<Item> &items = scratch_.value.items;
    // (clear and append, not resize: T need not be default-constructible)
    items.clear();
    items.reserve(n);
    for (std::size_t i = 0; i < n; ++i) items.push_back(make_item(shape(i), std::uint32_t(i)));
    return items;
  }

  struct BuildScratch {
    std::vector<Item> items;
    std::vector<BuildTask<typename CourseRule::State>> tasks;
  };

  /// Rebuilds the subtree at `at` from its own shapes, taken in leaf order:
  /// by the build rule, or with `keep_order` by build_in_order.
  void rebuild(int at, bool keep_order = false) {
    std::vector<Tagged> shapes;
    shapes.reserve(info_[at].count);
    // (free_node leaves a node's children in place, so the walk goes on.)
    walk(at, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
      take_shapes(n, shapes);
      if (n != at) free_node(n);
      return all_children(n);
    });
    nodes_[at].num_children = 0;
    if (keep_order)
      build_in_order(at, shapes);
    else
      build(at, shapes);
  }

  /// A build's last step. With a margin, leaves that update() left larger
  /// than their shapes come out of a build fitted again, so the node built
  /// at `at` may have shrunk: the boxes above it shrink too.
  void refit_above(int at, const Box &before) {
    if (info_[at].box != before && info_[at].parent >= 0) refit_up(info_[at].parent);
  }

  /// Calls f(node index) on every node in pre-order (children left to right).
  template <class F> void for_each_preorder(F &&f) const {
    if (root_ < 0) return;
    walk(root_, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
      f(n);
      return all_children(n);
    });
  }

  /// walk()'s visit result: bit c enters child c (c < num_children); bit
  /// kFirst + c enters it before every child of the low bits; kStop ends
  /// the walk.
  static constexpr unsigned kFirst = 4u, kStop = 1u << 8;
  /// walk()'s visit result that enters every child of node n.
  unsigned all_children(int n) const { return (1u << nodes_[n].num_children) - 1; }

  /// The one traversal that collision, query, find_equal, rebuild and
  /// for_each_preorder share: depth-first from node `from`, each node
  /// visited before its children. visit(n) returns which children of n to
  /// enter (none for a leaf) or kStop; within each group children are
  /// entered left to right. Returns false when a visit stopped it.
  template <class Visit> BVH_ALWAYS_INLINE bool walk(int from, Visit &&visit) const {
    bvh_detail::IndexStack stack;
    int n = from;
    for (;;) {
      const unsigned enter = visit(n);
      if (enter & kStop) return false;
      const Node &node = nodes_[n];
      if (node.num_children != 0) {
        const unsigned first = enter >> kFirst, later = enter & ~first & 7u;
        // Unrolled: this is collision()'s inner loop.
        if (later & 4u) stack.push(node.child[2]);
        if (later & 2u) stack.push(node.child[1]);
        if (later & 1u) stack.push(node.child[0]);
        if (first & 4u) stack.push(node.child[2]);
        if (first & 2u) stack.push(node.child[1]);
        if (first & 1u) stack.push(node.child[0]);
      }
      if (stack.empty()) return true;
      n = stack.pop();
    }
  }

  int leftmost_leaf(int n) const {
    while (nodes_[n].num_children != 0) n = nodes_[n].child[0];
    return n;
  }
  int rightmost_leaf(int n) const {
    while (nodes_[n].num_children != 0) n = nodes_[n].child[nodes_[n].num_children - 1];
    return n;
  }
  /// The leaf after `n` in left-to-right order, -1 after the last.
  int next_leaf(int n) const {
    while (n != root_) {
      const int parent = info_[n].parent, slot = info_[n].slot;
      if (slot + 1 < nodes_[parent].num_children) return leftmost_leaf(nodes_[parent].child[slot + 1]);
      n = parent;
    }
    return -1;
  }
  /// The leaf before `n` (undefined before the first, as for any iterator).
  int prev_leaf(int n) const {
    while (n != root_) {
      const int parent = info_[n].parent, slot = info_[n].slot;
      if (slot > 0) return rightmost_leaf(nodes_[parent].child[slot - 1]);
      n = parent;
    }
    return -1;
  }

  bvh_detail::BlockVector<Node> nodes_;
  bvh_detail::BlockVector<Info> info_;
  std::vector<int> free_; // indices of unused nodes, reused first
  bvh_detail::LeafPool<T> pool_; // every leaf's shapes
  std::vector<Loc> loc_;              // by id: where its shape is
  std::vector<std::uint32_t> free_ids_; // ids given back, reused first
  int root_ = -1;
  std::size_t size_ = 0;
  int split_threshold_;
  int depth_limit_;
  BuildRule build_rule_ = BuildRule::course;
  unsigned build_threads_ = 0; // 0: hardware concurrency
  double margin_ = 0;          // see set_margin()
  bvh_detail::Scratch<BuildScratch> scratch_;
};

#endif // BVH_BVH_H
