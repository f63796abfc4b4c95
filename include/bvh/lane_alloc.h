// bvh/lane_alloc.h — LaneAlloc: the nodes and slots of insert_disjoint's lanes.
//
// While lanes insert into disjoint subtrees of one tree at once
// (disjoint.h), they put a LaneAlloc in force in the stores
// (NodeStore::set_allocator, LeafStore::set_allocator): each lane takes
// nodes and slots a chunk at a time, under the allocator's lock, into a
// cache of its own (LaneCache). Before the lanes start it reserves the
// stores' room for them, by a bound computed here, and it checks every
// allocation against that bound, so that no store array moves while a
// lane reads it. The stores know nothing of threads: the lock, the count
// of what was taken and the lane each thread runs are here. Includes
// leaf_store.h.
#ifndef BVH_LANE_ALLOC_H
#define BVH_LANE_ALLOC_H

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "leaf_store.h"

namespace bvh {
namespace detail {

/// One lane's own nodes and slots: taken from the stores a chunk at a time
/// under LaneAlloc's lock, and those the lane gives back, reused first, so
/// that a lane seldom takes the lock and its subtree's nodes lie near each
/// other. What is left goes back to the stores when the lane ends. Its
/// lists' room is reserved before the lanes start, so giving back never
/// allocates.
struct LaneCache {
  /// Nodes or slots taken under the lock at a time.
  static constexpr std::size_t kChunk = 32;
  std::vector<int> nodes;                        ///< free nodes of the lane's
  std::vector<std::vector<std::uint32_t>> slots; ///< free slots of the lane's, by class
  std::size_t allocations = 0;                   ///< by the lane's insertion under way
  /// Room for the chunks of nodes and of slots of `classes` classes.
  void reserve(std::size_t classes) {
    nodes.reserve(2 * kChunk);
    slots.resize(classes);
    for (std::vector<std::uint32_t> &c : slots) c.reserve(2 * kChunk);
  }
};

/// The allocator insert_disjoint's lanes put in force in a tree's stores
/// (one per round of lanes). reserve() gives the stores room for every
/// lane's worst case; then, while in force, every node and slot the lanes
/// allocate is taken from the stores under its lock (mostly a chunk at a
/// time, into the running lane's LaneCache) and counted, and each lane
/// starts an insertion only while that count leaves room for every
/// thread's worst case (slack_used()): no array of the stores is
/// reallocated under another lane's reads. Which lane a thread runs is
/// InLane's (a thread-local pointer to the lane's cache).
template <class T, int W> class LaneAlloc final : public NodeAllocator, public SlotAllocator {
public:
  LaneAlloc(NodeStore<W> &nodes, LeafStore<T> &leaves) noexcept : nodes_(nodes), leaves_(leaves) {}
  LaneAlloc(const LaneAlloc &) = delete;
  LaneAlloc &operator=(const LaneAlloc &) = delete;
  ~LaneAlloc() { withdraw(); }

  /// The most nodes and slots one insertion into a subtree of m shapes may
  /// allocate: a split of at most m + 1 shapes and a rebuild of as many
  /// (a build of k shapes makes fewer than 2k nodes and at most k slots),
  /// and a leaf's slot moving to a larger class.
  static std::size_t insertion_allocations(std::size_t m) { return 6 * (m + 1) + 8; }

  /// Before the lanes start: room in the stores for `threads` threads'
  /// worst insertions into subtrees of up to `largest` shapes (once their
  /// candidates are in), with leaves of up to `largest_leaf` shapes, plus
  /// what the caches of `lanes` lanes hold and the usual allocations of
  /// `routed` insertions (the slack, after which lanes stop); and each
  /// lane's cache. False when memory for it ran out: then the lanes must
  /// run on one thread, without this allocator.
  bool reserve(std::size_t lanes, unsigned threads, std::size_t largest, std::size_t largest_leaf,
               std::size_t routed) noexcept {
    // A lane's cache holds up to two chunks of nodes and of each class's
    // slots.
    const std::size_t kinds = 1 + std::max(LeafPool<T>::classes_for(largest_leaf), leaves_.class_count());
    const std::size_t cached = 2 * LaneCache::kChunk * kinds;
    insertion_bound_ = insertion_allocations(largest);
    slack_ = 16 * routed + lanes * cached + 1024;
    room_ = std::size_t(threads) * (insertion_bound_ + cached) + slack_;
    try {
      nodes_.reserve_spare(room_);
      leaves_.reserve_spare(room_, largest_leaf);
      caches_.resize(lanes);
      for (LaneCache &cache : caches_) cache.reserve(leaves_.class_count());
    } catch (...) {
      return false;
    }
    return true;
  }
  /// Makes the stores allocate through this allocator.
  void put_in_force() noexcept {
    nodes_.set_allocator(this);
    leaves_.set_allocator(this);
    in_force_ = true;
  }
  /// The stores allocate on their own again; what the caches hold goes
  /// back to them.
  void withdraw() noexcept {
    nodes_.set_allocator(nullptr);
    leaves_.set_allocator(nullptr);
    in_force_ = false;
    for (LaneCache &cache : caches_) empty_cache(cache);
  }
  /// True when, in force, the lanes have taken more than the slack: a lane
  /// then starts no more insertions (they are made on one thread
  /// afterwards, without this allocator).
  bool slack_used() const noexcept { return in_force_ && taken_.load(std::memory_order_relaxed) > slack_; }

  /// While it lives, the calling thread runs lane `k`: the lane's
  /// allocations go through its cache, which goes back to the stores when
  /// it ends.
  class InLane {
  public:
    InLane(LaneAlloc &alloc, std::size_t k) noexcept
        : alloc_(alloc), cache_(k < alloc.caches_.size() ? &alloc.caches_[k] : nullptr) {
      current() = cache_;
    }
    InLane(const InLane &) = delete;
    InLane &operator=(const InLane &) = delete;
    ~InLane() {
      current() = nullptr;
      if (cache_) alloc_.empty_cache(*cache_);
    }
    /// The lane starts an insertion: its allocations are counted (and
    /// checked against the bound reserved for one) from zero.
    void begin_insertion() noexcept {
      if (cache_) cache_->allocations = 0;
    }

  private:
    LaneAlloc &alloc_;
    LaneCache *cache_;
  };

  int allocate_node() override {
    LaneCache *own = current();
    if (!own) return locked_take([&] { return nodes_.take_free(); });
    count(*own);
    refill(own->nodes, [&] { return nodes_.take_free(); }, LaneCache::kChunk / (W > 4 ? 4 : 2));
    const int n = own->nodes.back();
    own->nodes.pop_back();
    return n;
  }
  void release_node(int n) noexcept override {
    if (LaneCache *own = current()) {
      give_back(own->nodes, n, [&](int m) { nodes_.give_free(m); }, LaneCache::kChunk);
    } else {
      std::lock_guard<std::mutex> hold(lock_);
      nodes_.give_free(n);
    }
  }
  std::uint32_t allocate_slot(std::uint32_t cls) override {
    LaneCache *own = current();
    if (own) count(*own);
    if (!own || cls >= own->slots.size()) return locked_take([&] { return leaves_.take_free_slot(cls); });
    std::vector<std::uint32_t> &list = own->slots[cls];
    refill(list, [&] { return leaves_.take_free_slot(cls); }, chunk_of(cls));
    const std::uint32_t i = list.back();
    list.pop_back();
    return i;
  }
  void release_slot(std::uint32_t cls, std::uint32_t index) noexcept override {
    LaneCache *own = current();
    if (own && cls < own->slots.size()) {
      give_back(own->slots[cls], index, [&](std::uint32_t i) { leaves_.give_free_slot(cls, i); }, chunk_of(cls));
    } else {
      std::lock_guard<std::mutex> hold(lock_);
      leaves_.give_free_slot(cls, index);
    }
  }

private:
  /// The cache of the lane this thread runs (none outside a lane).
  static LaneCache *&current() noexcept {
    static thread_local LaneCache *lane = nullptr;
    return lane;
  }
  /// The slots of class cls a lane takes at a time, and keeps when it
  /// gives slots back: fewer of the larger, since what a lane keeps is
  /// slack.
  static std::size_t chunk_of(std::uint32_t cls) {
    return LaneCache::kChunk >> std::min<std::size_t>(LeafPool<T>::log2_floor(LeafPool<T>::capacity_of(cls)), 5);
  }
  /// One more allocation by the running lane's insertion, which the room
  /// reserved for it must hold.
  void count(LaneCache &own) noexcept {
    ++own.allocations;
    BVH_INVARIANT(own.allocations <= insertion_bound_, "an insertion in a lane allocated more than the bound reserved");
  }
  /// `taken` more items taken from the stores, which their reserved room
  /// must hold (under the lock).
  void taking(std::size_t taken) noexcept {
    const std::size_t now = taken_.fetch_add(taken, std::memory_order_relaxed) + taken;
    BVH_INVARIANT(now <= room_, "the lanes took more from the stores than the room reserved: an array would move");
    (void)now;
  }
  /// take() under the lock, counted.
  template <class F> decltype(auto) locked_take(F &&take) {
    std::lock_guard<std::mutex> hold(lock_);
    taking(1);
    return take();
  }
  /// The running lane's list `own` refilled, when empty, with up to `most`
  /// (<= kChunk) items of take() under the lock: the first may throw (then
  /// nothing changed), the others stop at a throw.
  template <class Item, class F> void refill(std::vector<Item> &own, F &&take, std::size_t most) {
    if (!own.empty()) return;
    std::lock_guard<std::mutex> hold(lock_);
    own.push_back(take());
    try {
      while (own.size() < most) own.push_back(take());
    } catch (...) {
    }
    taking(own.size());
  }
  /// `item` onto the running lane's list `own`; a list of 2 * `keep` (<=
  /// kChunk) items first gives all but `keep` back through give(item)
  /// under the lock.
  template <class Item, class F> void give_back(std::vector<Item> &own, Item item, F &&give, std::size_t keep) noexcept {
    if (own.size() >= 2 * keep) {
      std::lock_guard<std::mutex> hold(lock_);
      while (own.size() > keep) {
        give(own.back());
        own.pop_back();
      }
    }
    own.push_back(item); // (never allocates: room made above)
  }
  /// Everything `cache` holds, back to the stores (when its lane ends): a
  /// lane that has ended keeps nothing, since a cached slot of every class
  /// a leaf grew through, in every lane, is slack.
  void empty_cache(LaneCache &cache) noexcept {
    std::lock_guard<std::mutex> hold(lock_);
    for (int n : cache.nodes) nodes_.give_free(n);
    cache.nodes.clear();
    for (std::size_t cls = 0; cls < cache.slots.size(); ++cls) {
      for (std::uint32_t i : cache.slots[cls]) leaves_.give_free_slot(std::uint32_t(cls), i);
      cache.slots[cls].clear();
    }
  }

  NodeStore<W> &nodes_;
  LeafStore<T> &leaves_;
  std::vector<LaneCache> caches_; // by lane
  std::mutex lock_;
  std::atomic<std::size_t> taken_{0}; // nodes and slots taken from the stores while in force
  std::size_t insertion_bound_ = 0;   // insertion_allocations() of the largest subtree
  std::size_t slack_ = 0, room_ = 0;  // room_: what reserve() made in the stores
  bool in_force_ = false;
};
} // namespace detail
} // namespace bvh

#endif // BVH_LANE_ALLOC_H
