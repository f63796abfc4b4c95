// bvh/containers.h — the small containers every room uses.
//
// IndexStack (a traversal stack that lives on the call stack until it
// outgrows it), InlineVector, BlockVector (blocks that never move), the
// mapped allocator of large bookkeeping arrays, Span, Tagged (a shape with
// its id), Scratch (memory a copy does not copy), Uncopied (a pointer a
// copy does not take), keep_going. Knows nothing of trees. Includes
// config.h only.
#ifndef BVH_CONTAINERS_H
#define BVH_CONTAINERS_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "config.h"

namespace bvh {
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

/// A pointer that copies and moves of its owner do not take: they start
/// null (a store's allocator in force is its caller's, for that store).
template <class P> struct Uncopied {
  P *to = nullptr;
  Uncopied() = default;
  Uncopied(const Uncopied &) noexcept {}
  Uncopied &operator=(const Uncopied &) noexcept { return *this; }
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
} // namespace detail
} // namespace bvh

#endif // BVH_CONTAINERS_H
