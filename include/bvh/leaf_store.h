// bvh/leaf_store.h — LeafStore<T>: the pool, the leaves' records and the handles, in step.
//
// Ids (a handle is an id and a generation), the table from id to leaf and
// index (built lazily, under a lock, on the first handle lookup), and the
// leaf-level edits that keep pool, records and table consistent. Includes
// leaf_pool.h and node_store.h.
#ifndef BVH_LEAF_STORE_H
#define BVH_LEAF_STORE_H

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <utility>
#include <vector>

#include "leaf_pool.h"
#include "node_store.h"

namespace bvh {
namespace detail {

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
      : pool_(o.pool_), free_ids_(o.free_ids_), id_count_(o.id_count_), settled_count_(o.id_count_),
        generations_(o.generations_), fresh_generation_(o.fresh_generation_),
        constructed_generation_(o.constructed_generation_) {
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
  /// settle_ids(), every id it gives may be given back (unnew_id(), or
  /// free_erased_id() once stored and erased) without allocating: the free
  /// ids keep room for them all (disjoint.h takes many before inserting
  /// any).
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
  /// The one way to undo new_id(): gives back an id it gave that no
  /// shape stores and no handle carries (an insert that failed, or an id
  /// insert_disjoint took and did not use). Never throws (new_id() kept
  /// the room). The end state:
  ///  - the id is free and keeps its generation: no handle was given with
  ///    it, so no handle can become stale (an erase raises a generation,
  ///    free_erased_id());
  ///  - an id new_id() counted since settle_ids() (no id was free then)
  ///    that is still the last one and was never erased is counted no
  ///    more: the count, the table and the generations shrink back by it
  ///    (an erased id's raised generation must stay);
  ///  - any other goes back on top of the free ids, the next new_id()'s.
  /// So ids given back in the reverse order new_id() gave them, with no
  /// erase between, leave the ids exactly as they were (count, free ids
  /// and their order, generations, table): insert()'s strong guarantee,
  /// and an empty tree holds no id again.
  void unnew_id(std::uint32_t id) noexcept {
    BVH_INVARIANT(id < id_count_, "an id given back that new_id() did not give");
    if (built()) loc_[id].leaf = -1;
    if (id >= settled_count_ && id + std::size_t(1) == id_count_ &&
        (generations_.empty() || generations_[id] == fresh_generation_)) {
      if (built()) loc_.pop_back();
      if (!generations_.empty()) generations_.pop_back();
      --id_count_;
      return;
    }
    BVH_INVARIANT(free_ids_.size() < free_ids_.capacity(), "an id given back without room for it");
    free_ids_.push_back(id);
  }
  /// The ids handed out since the last call are all stored or given back:
  /// the room new_id() kept for them goes (returned to the allocator when
  /// it is much more than the free ids need). Never throws.
  void settle_ids() noexcept {
    pending_ = 0;
    settled_count_ = id_count_;
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
    settled_count_ = n;
    constructed_generation_ = fresh_generation_;
  }
  /// Room for giving one more id back (before an erase, whose
  /// free_erased_id() must not allocate), with every id's generation.
  /// Strong.
  void reserve_id_back() {
    reserve_for(free_ids_, std::min(id_count_, free_ids_.size() + pending_ + 1));
    if (generations_.empty()) generations_.assign(id_count_, fresh_generation_);
  }
  /// Gives back the id of an erased shape (after reserve_id_back()): its
  /// generation goes up, so that its handles are stale from now on, also
  /// once a later insert reuses the id; it goes on top of the free ids.
  /// `none_stored`: the tree is empty, so every id is forgotten instead.
  /// Never throws.
  void free_erased_id(std::uint32_t id, bool none_stored) noexcept {
    if (none_stored) {
      forget_ids();
      return;
    }
    BVH_INVARIANT(id < generations_.size(), "an id given back without its generation");
    ++generations_[id];
    if (built()) loc_[id].leaf = -1;
    BVH_INVARIANT(free_ids_.size() < free_ids_.capacity(), "an id given back without room for it");
    free_ids_.push_back(id);
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
  /// The pool's allocation side (LeafPool): reserve_spare, shrink_spare,
  /// set_allocator and, for an allocator in force, take_free, give_free.
  void reserve_spare(std::size_t spare, std::size_t largest) { pool_.reserve_spare(spare, largest); }
  void set_allocator(SlotAllocator *allocator) noexcept { pool_.set_allocator(allocator); }
  std::size_t class_count() const { return pool_.class_count(); }
  void shrink_spare() noexcept { pool_.shrink_spare(); }
  std::uint32_t take_free_slot(std::uint32_t cls) { return pool_.take_free(cls); }
  void give_free_slot(std::uint32_t cls, std::uint32_t index) noexcept { pool_.give_free(cls, index); }

  void swap(LeafStore &o) noexcept {
    std::swap(pool_, o.pool_);
    loc_.swap(o.loc_);
    free_ids_.swap(o.free_ids_);
    std::swap(id_count_, o.id_count_);
    std::swap(pending_, o.pending_);
    std::swap(settled_count_, o.settled_count_);
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
    settled_count_ = 0;
    located_.store(false, std::memory_order_relaxed);
  }

  LeafPool<T> pool_;
  std::vector<std::uint32_t> free_ids_; // ids given back, reused first
  std::size_t id_count_ = 0;            // ids in use or free: 0 .. id_count_ - 1
  std::size_t pending_ = 0;             // ids new_id() gave since settle_ids()
  std::size_t settled_count_ = 0;       // id_count_ at settle_ids(): ids from here up were counted since
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
} // namespace detail
} // namespace bvh

#endif // BVH_LEAF_STORE_H
