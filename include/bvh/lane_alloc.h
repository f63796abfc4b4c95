// bvh/lane_alloc.h — nodes and slots shared by insert_disjoint's lanes.
//
// SharedAlloc (the lock and the count of what was taken), LaneCache (one
// lane's own free nodes and slots) and Sharing (a store's link to the
// SharedAlloc in force). While lanes run, NodeStore and LeafPool allocate
// through these; otherwise Sharing is unlinked and costs a test. Includes
// config.h only.
#ifndef BVH_LANE_ALLOC_H
#define BVH_LANE_ALLOC_H

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "config.h"

namespace bvh {
namespace detail {

/// The lock that node and slot allocation take while several threads
/// change disjoint subtrees of one tree at once (insert_disjoint's parallel
/// inserts, disjoint.h), mostly a chunk at a time for a LaneCache, and the
/// count of nodes and slots taken under it: the stores' arrays were
/// reserved beforehand, and a thread starts an insert only while that count
/// leaves room for every thread's worst case, so no array is reallocated
/// under another thread's reads.
struct SharedAlloc {
  std::mutex lock;
  std::atomic<std::size_t> taken{0};
};

/// One lane's own nodes and slots while lanes share a tree (disjoint.h):
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
} // namespace detail
} // namespace bvh

#endif // BVH_LANE_ALLOC_H
