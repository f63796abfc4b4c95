// bvh/leaf_pool.h — LeafPool<T>: the leaves' shapes, in slots of size classes.
//
// Each leaf owns one slot, a contiguous run of shapes with their ids;
// slots come in capacity classes kept in blocks that never move. Only a
// slot's first size() elements are constructed. Slots come from the
// pool's own free lists, or through the allocator a caller puts in force
// (SlotAllocator). Includes containers.h.
#ifndef BVH_LEAF_POOL_H
#define BVH_LEAF_POOL_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "containers.h"

namespace bvh {
namespace detail {

/// Where a LeafPool's slots come from while a caller puts it in force
/// (LeafPool::set_allocator): insert_disjoint's lanes (lane_alloc.h). It
/// takes slots of a class from the pool by take_free() and gives them
/// back, emptied, by give_free(), at the times and in the ways it chooses.
class SlotAllocator {
public:
  /// The index of an empty slot of class `cls`, for LeafPool::allocate().
  /// Strong.
  virtual std::uint32_t allocate_slot(std::uint32_t cls) = 0;
  /// Takes back slot `index` of class `cls`, its shapes destroyed, for
  /// LeafPool::release(). Never allocates.
  virtual void release_slot(std::uint32_t cls, std::uint32_t index) noexcept = 0;

protected:
  ~SlotAllocator() = default;
};

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
    if (!allocator_.to) return Slot{take_free(cls), cls};
    return Slot{allocator_.to->allocate_slot(cls), cls};
  }
  /// Destroys the slot's shapes and gives the slot back (never throws).
  /// A class none of whose slots is in use any more then gives back its
  /// blocks too (not while an allocator is in force, which may hold its
  /// slots): a leaf grows through the small classes once, while the tree
  /// is young, and each would keep a block for one free slot.
  void release(Slot s) noexcept {
    Class &c = classes_[s.cls];
    if (!allocator_.to) {
      c.release(s.index);
      if (c.free_slots.size() == c.sizes.size()) c.drop();
    } else {
      c.clear(s.index);
      allocator_.to->release_slot(s.cls, s.index);
    }
  }
  /// An empty slot of class `cls` (the class made if missing), from its
  /// free slots first: what allocate() does, and where an allocator in
  /// force takes its slots. Strong.
  std::uint32_t take_free(std::uint32_t cls) {
    while (classes_.size() <= cls) classes_.emplace_back(std::uint32_t(classes_.size()));
    return classes_[cls].allocate();
  }
  /// Puts slot `index` of class `cls` (given by take_free, its shapes
  /// destroyed) on the class's free slots. Never allocates: take_free()
  /// made room.
  void give_free(std::uint32_t cls, std::uint32_t index) noexcept { classes_[cls].free_slots.push_back(index); }
  /// The number of classes.
  std::size_t class_count() const { return classes_.size(); }
  /// The classes reserve_spare(spare, largest) makes, at least.
  static std::size_t classes_for(std::size_t largest) { return std::size_t(class_for(largest)) + 2; }
  /// Every class's shrink_spare().
  void shrink_spare() noexcept {
    for (Class &c : classes_) c.shrink_spare();
  }
  /// Room for `spare` more slots in every class up to the one of
  /// `largest` shapes (made now if missing), so that allocating them never
  /// moves an array (an allocator in force relies on it: lane_alloc.h).
  void reserve_spare(std::size_t spare, std::size_t largest) {
    const std::uint32_t top = class_for(largest) + 1; // (a full slot of `largest` moves up one)
    classes_.reserve(std::max<std::size_t>(top + 1, 64)); // (never moved while an allocator is in force)
    while (classes_.size() <= top) classes_.emplace_back(std::uint32_t(classes_.size()));
    for (Class &c : classes_) c.reserve_spare(spare);
  }
  /// Makes allocate() and release() go through `allocator` (none:
  /// nullptr). A copy of the pool starts with none.
  void set_allocator(SlotAllocator *allocator) noexcept { allocator_.to = allocator; }

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

public:
  /// The highest bit of n >= 1 (lane_alloc.h sizes its chunks by it).
  static std::size_t log2_floor(std::size_t n) {
    std::size_t b = 0;
    while (n >> (b + 1)) ++b;
    return b;
  }
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
  Uncopied<SlotAllocator> allocator_; // the one in force, if any
};
} // namespace detail
} // namespace bvh

#endif // BVH_LEAF_POOL_H
