// bvh.h — BVH<T>: a bounding volume hierarchy over 2D shapes (Disk,
// Triangle, Quad from shapes.h, Shape for mixed scenes, or a shape type of
// your own), built in bulk or one shape at a time, answering "does this
// shape touch anything stored?" with the shapes' own intersect().
//
// The one include a user writes: it brings the whole engine, whose rooms
// (one concept a header, each compiling alone, includes going one way) are
// listed below and mapped in docs/design.txt. A program that needs less may
// include a room by itself: <bvh/search.h> and what it includes, say,
// without insert_disjoint's threads.
//
//   BVH<Disk> tree;                          // width 8, up to 32 shapes a leaf
//   tree.construct(disks);                   // bulk build
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
// The two configurations (defaults.h): BVH<T> is the library's default,
// eight children a node and up to 32 shapes a leaf, the fastest and
// smallest measured; CourseBVH<T> is the course's tree (three children,
// up to four shapes a leaf, the course's rule), which bvh.out runs.
// BVHOfWidth<T, W> is another width without spelling the traits; the split
// threshold and the depth limit are the constructor's, the build rule
// set_build_rule()'s.
//
// The rooms, each including only rooms above it:
//   defaults.h     the default configuration and the course's
//   config.h       assertions, platform switches
//   traits.h       bounds, box_traits, shape_traits (the customization points)
//   containers.h   IndexStack, BlockVector, mapped arrays, Span, Tagged
//   box.h          Box, rounding to float, the supported range
//   count_cut.h    thirds() and CountCut<W>
//   parallel.h     parallel_for, Crew, threads_for
//   simd.h         Probe and the bit helpers
//   node.h         Node<W> (one cache line) and Info
//   node_store.h   NodeStore<W>, the one writer of a box
//   walk.h         child_masks and walk(), the depth-first traversal
//   leaf_pool.h    LeafPool<T>, the leaves' shapes
//   leaf_store.h   LeafStore<T>: the pool, leaf records, ids and handles
//   lane_alloc.h   LaneAlloc, the allocator insert_disjoint's lanes put in force
//   build_items.h  items, keys, tasks and selection of the builds
//   core.h         Core<T, Tr, W> and Tuning
//   leaf_summary.h leaf codes: their writers and the decisions read from them
//   course_rule.h  CourseRule       sah_rule.h  SahRule
//   layout.h       Layout<W>        build.h     the build loop, construct
//   insert.h       insertion and balance
//   erase.h        erase, update, margins
//   search.h       collision and the box and shape queries
//   best_first.h   nearest and first_hit
//   pairs.h        all overlapping pairs
//   report.h       the course's report and picture
//   validate.h     validate()
//   disjoint.h     insert_disjoint
//   bvh.h          BVH<T, Traits, Width>, the facade (this file)
// The intersection predicates are the free intersect() of the shape type,
// found by argument-dependent lookup (this project's exact ones are in
// intersect.h, which shapes.h brings in).
#ifndef BVH_BVH_H
#define BVH_BVH_H

#include <cstddef>
#include <cstdint>
#include <iostream>
#include <iterator>
#include <limits>
#include <ostream>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "version.h"
#include "erase.h"
#include "search.h"
#include "best_first.h"
#include "pairs.h"
#include "report.h"
#include "validate.h"
#include "disjoint.h"

namespace bvh {

/// A bounding volume hierarchy over values of type T: shapes, or
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
/// Width: children per inner node, 2 to 8; by default 8 (default_width),
/// and 3 is the course's tree (CourseBVH<T>). At widths other than 3 the
/// build rules fill nodes (CountCut: the course's rule halves by median,
/// SAH cuts in two where cheapest, until W groups).
template <class T, class Traits = shape_traits<T>, int Width = default_width> class BVH {
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

  /// The split threshold of a tree built without one: 32
  /// (default_split_threshold), and the course's 4 at the course's width 3.
  static constexpr int default_split = default_split_threshold_at(Width);

  /// An empty tree. A node holding more than `split_threshold` shapes is
  /// split unless it is at depth `depth_limit` (root = depth 0;
  /// `depth_limit <= 0` means unlimited). A `split_threshold` below 1 is
  /// taken as 1 (every leaf then holds one shape, above the depth limit).
  explicit BVH(int split_threshold = default_split, int depth_limit = unlimited, Traits traits = Traits())
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
    const std::uint32_t id = core_.leaves.new_id();
    try {
      detail::insert_shape(core_, shape, id);
    } catch (...) {
      core_.leaves.unnew_id(id);
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
  /// first one, before anything is inserted. With `steps`, each step's
  /// wall time is added to it (DisjointSteps); without, no clock is read.
  std::vector<std::size_t> insert_disjoint(const std::vector<T> &candidates, unsigned threads = 0,
                                           DisjointSteps *steps = nullptr) {
    detail::require_supported(core_.traits, candidates, "insert_disjoint", "candidates");
    struct Settle { // (the ids' room goes, also after a throw)
      detail::LeafStore<T> &leaves;
      ~Settle() { leaves.settle_ids(); }
    } settle{core_.leaves};
    return detail::insert_disjoint(core_, candidates, threads, steps);
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
  /// The defaults for T: disks decided from codes from 4 MB of shapes,
  /// insert_disjoint's interleaved searches from 32,768 shapes, its lanes
  /// and parallel sweep from 4,096, its lanes on threads by the tree's
  /// shape (core.h: kDiskCodesMinBytes, kDisjointInterleaveMin, ...).
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

/// The course's tree: three children a node, up to four shapes a leaf by
/// default, and the course's rule (defaults.h); what bvh.out runs and the
/// course's edition (the top-level bvh.h) builds, node for node.
template <class T, class Traits = shape_traits<T>> using CourseBVH = BVH<T, Traits, course_width>;

/// A tree of width W (2 to 8) without spelling the traits:
/// BVHOfWidth<Rect, 4> is BVH<Rect, shape_traits<Rect>, 4>.
template <class T, int W, class Traits = shape_traits<T>> using BVHOfWidth = BVH<T, Traits, W>;
} // namespace bvh

#endif // BVH_BVH_H
