// bvh/core.h — Core<T, Tr, W>: the state every operation shares, and Tuning.
//
// The nodes, the leaves, the root, the parameters (split threshold, depth
// limit, margin, build rule, threads) and Tuning (the sizes from which the
// large-tree paths switch on; they change speed, never an answer). Each
// part keeps its own invariants; Core keeps those that span them. Includes
// node_store.h, leaf_store.h, build_items.h, count_cut.h, walk.h.
#ifndef BVH_CORE_H
#define BVH_CORE_H

#include <cstddef>
#include <cstdint>
#include <utility>

#include "node_store.h"
#include "leaf_store.h"
#include "build_items.h"
#include "count_cut.h"
#include "walk.h"

namespace bvh {
namespace detail {

/// How construct() and the splits and rebuilds of insert() cut a node.
enum class BuildRule {
  course, ///< the course's rule (CourseRule): thirds by count along the longer side
  sah     ///< binned surface area heuristic (SahRule): the cut of least area cost
};

/// The sizes from which a tree takes the paths that pay only when it is
/// large (BVH::Tuning, set_tuning()). They change speed only, never an
/// answer: each path gives what the plain one gives. A tree starts with
/// default_tuning<T>() (below); tests lower the sizes through set_tuning(),
/// as a user would, so that small trees take every path.
struct Tuning {
  /// Stored shapes from which collision(), collisions() and query(shape)
  /// decide disks from their leaves' codes (kDisksFromCodes; default:
  /// kDiskCodesMinBytes of shapes). 0: at every size.
  std::size_t disk_codes_min_shapes;
  /// Stored shapes from which insert_disjoint's step 1 interleaves its
  /// searches, and one thread decides in batches (default
  /// kDisjointInterleaveMin).
  std::size_t disjoint_interleave_min;
  /// Stored shapes from which insert_disjoint's step 4 inserts on every
  /// thread, the lanes (default kDisjointLanesMin).
  std::size_t disjoint_lanes_min;
  /// A batch's survivors from which insert_disjoint's step 2 sweeps on
  /// every thread (default kDisjointSweepMin).
  std::size_t disjoint_sweep_min;
  /// The fewest threads on which insert_disjoint's step 4 takes the lanes
  /// (never fewer than 2); 0, the default: by the tree's shape
  /// (disjoint_lanes_threads() in disjoint.h). With fewer threads the
  /// driver inserts alone, pipelined, while steps 1 and 2 still run on
  /// every thread.
  unsigned disjoint_lanes_threads;
};
/// A tree of T's Tuning until set_tuning() (below).
template <class T> Tuning default_tuning() noexcept;

/// The state every operation shares: the nodes, the leaves' shapes and
/// ids, the root, and the parameters of the tree. The rooms that include this one work on
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

// The tuning macros of earlier versions changed template bodies, so two
// translation units that defined them differently broke the one-definition
// rule: they are gone, and defining one is an error that names the
// replacement.
#if defined(BVH_DISK_CODES_MIN_BYTES) || defined(BVH_DISJOINT_LANES_THREADS) || defined(BVH_DISJOINT_LANES_MIN) || \
    defined(BVH_DISJOINT_SWEEP_MIN) || defined(BVH_DISJOINT_INTERLEAVE_MIN)
#error "bvh: the BVH_DISK_CODES_MIN_BYTES and BVH_DISJOINT_* macros are gone: set a tree's sizes with BVH::set_tuning()"
#endif
#if defined(BVH_DISJOINT_PROFILE) || defined(BVH_DISJOINT_PROFILE_ON)
#error "bvh: BVH_DISJOINT_PROFILE is gone: pass a bvh::DisjointSteps to insert_disjoint() for its step timings"
#endif

/// The stored shapes' bytes from which collision searches decide disks
/// from their codes by default: a decision costs more than reading a disk
/// the caches hold, and saves a miss only when the disks are many more
/// than a core's own caches keep.
constexpr std::size_t kDiskCodesMinBytes = std::size_t(4) << 20;
/// The size of tree from which insert_disjoint's step 4 inserts on every
/// thread (the lanes) by default; a smaller tree is not worth splitting.
constexpr std::size_t kDisjointLanesMin = 4096;
/// The number of a batch's survivors from which step 2's sweep runs on
/// every thread by default.
constexpr std::size_t kDisjointSweepMin = 4096;
/// The size of tree from which insert_disjoint's step 1 interleaves its
/// searches (collides_each), and from which one thread decides in batches
/// at all: on a smaller tree, which the caches hold, the interleaving and
/// the batches cost more than they save, and one thread runs the loop
/// itself.
constexpr std::size_t kDisjointInterleaveMin = 32768;

template <class T> Tuning default_tuning() noexcept {
  Tuning t;
  t.disk_codes_min_shapes = kDiskCodesMinBytes / sizeof(T);
  t.disjoint_interleave_min = kDisjointInterleaveMin;
  t.disjoint_lanes_min = kDisjointLanesMin;
  t.disjoint_sweep_min = kDisjointSweepMin;
  t.disjoint_lanes_threads = 0;
  return t;
}
} // namespace detail
} // namespace bvh

#endif // BVH_CORE_H
