// bvh/node_store.h — NodeStore<W>: the two arrays of nodes and the one writer of a box.
//
// Allocation and release of nodes (free list reused first, or through the
// allocator a caller puts in force: NodeAllocator), and set_box, the only
// writer of both copies of a box (the exact one in Info, the float one in
// the parent's Node). Includes node.h.
#ifndef BVH_NODE_STORE_H
#define BVH_NODE_STORE_H

#include <cstddef>
#include <vector>

#include "node.h"

namespace bvh {
namespace detail {

/// Where a NodeStore's nodes come from while a caller puts it in force
/// (NodeStore::set_allocator): insert_disjoint's lanes (lane_alloc.h).
/// It takes nodes from the store by take_free() and gives them back by
/// give_free(), at the times and in the ways it chooses.
class NodeAllocator {
public:
  /// A node index, for NodeStore::allocate(). Strong.
  virtual int allocate_node() = 0;
  /// Takes node n back, for NodeStore::release(). Never allocates.
  virtual void release_node(int n) noexcept = 0;

protected:
  ~NodeAllocator() = default;
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
    if (in.parent < 0) return;
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
  NodeStore(NodeStore<W> &&) noexcept = default; // (the allocator in force stays behind: Uncopied)
  NodeStore<W> &operator=(const NodeStore<W> &o) {
    NodeStore copy(o);
    swap(copy);
    return *this;
  }
  NodeStore<W> &operator=(NodeStore<W> &&) noexcept = default;

  /// A node index, from the free list first (or from the allocator in
  /// force); reset() must follow. Strong: if it throws, nothing changed.
  int allocate() {
    if (!allocator_.to) return take_free();
    return allocator_.to->allocate_node();
  }
  /// A node from the free list, else a new one at the arrays' end: what
  /// allocate() does, and where an allocator in force takes its nodes.
  /// Strong.
  int take_free() {
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
  /// Puts node n (given by take_free) on the free list. Never allocates:
  /// take_free() made room.
  void give_free(int n) noexcept { free_.push_back(n); }
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
  /// Makes allocate() and release() go through `allocator` (none:
  /// nullptr). A copy of the store starts with none.
  void set_allocator(NodeAllocator *allocator) noexcept { allocator_.to = allocator; }
  /// True while an allocator is in force: its callers insert into
  /// subtrees of their own (disjoint.h), so a build takes no scratch memory
  /// of the tree's and nothing refits above such a subtree.
  bool shared() const { return allocator_.to != nullptr; }
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
    if (!allocator_.to)
      give_free(n);
    else
      allocator_.to->release_node(n);
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
  BlockVector<Node> nodes_;
  BlockVector<Info> info_;
  std::vector<int> free_; // indices of unused nodes, reused first
  Uncopied<NodeAllocator> allocator_; // the one in force, if any
};
} // namespace detail
} // namespace bvh

#endif // BVH_NODE_STORE_H
