// bvh/search.h — the depth-first searches: one engine, a question per query.
//
// search() (walk() from the root; the question decides the children to
// enter and each leaf) and its questions: CollisionQuestion (collides, and
// collides_each's interleaved lanes), OverlapQuestion (visit_overlapping,
// visit_intersecting; OverlapSearch, a suspended walk for iterators, shares
// its tests) and EqualQuestion (find_equal). Every query is const.
// Includes leaf_summary.h.
#ifndef BVH_SEARCH_H
#define BVH_SEARCH_H

#include <cstddef>
#include <cstdint>
#include <optional>

#include "leaf_summary.h"

namespace bvh {
namespace detail {

// Every query is const and reads the tree only, so any number of threads
// may query one tree at once while none changes it. The depth-first ones
// are one engine, search() (walk() from the root), with a question per
// query that decides the children to enter and each leaf, as best_first()
// has a metric per query: CollisionQuestion (collides, and each lane of
// collides_each), OverlapQuestion (visit_overlapping, visit_intersecting)
// and EqualQuestion (find_equal). overlapping() runs walk()'s steps one at
// a time with OverlapQuestion's tests (OverlapSearch). A leaf is read
// through the one leaf-summary test (with_candidates()) and, for disks,
// the one disk fast path (each_disk_candidate()), both in leaf_summary.h.
// collides_each, OverlapSearch and the pairs (pairs.h) keep stepping of
// their own: interleaved lanes, a walk suspended between calls, a walk
// over pairs of nodes; each decides with the same tests.

/// The one depth-first search: walk() from the root, where `question`
/// decides which children of an inner node to enter (children(node), as
/// walk()'s visit result) and each leaf (leaf(n, node, shapes): false
/// stops the search). False when a leaf stopped it. The caller has tested
/// the root's box, each question its own way.
template <class T, class Tr, int W, class Question>
BVH_ALWAYS_INLINE bool search(const Core<T, Tr, W> &core, Question &question) {
  return walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) return question.leaf(n, node, core.leaves.shapes(node)) ? 0 : kStop;
    return question.children(node);
  });
}

/// Collision's visit of inner node `node`: the children to enter, as
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

/// Collision's disk fast path on a summarized leaf of disks, for the
/// candidates `bits`: `hit` when one surely meets the probe; else `unsure`,
/// those the codes cannot decide. (Not inlined: it runs on large trees
/// only, and inlined it made the search of small trees, which never takes
/// it, slower. Its answer comes back by value, so that the caller's
/// candidates stay in registers.)
struct DiskScreen {
  std::uint32_t unsure;
  bool hit;
};
template <int W> BVH_NOINLINE DiskScreen disk_leaf_hit(const Node<W> &node, const DiskProbe &disk, std::uint32_t bits) {
  DiskScreen s{0, false};
  s.hit = disk_codes_hit(node, bits, disk, s.unsure);
  return s;
}

/// The collision question: does some stored shape intersect `shape`
/// (touching counts)? Subtrees whose box misses the shape's box are never
/// visited; the final test is T's intersect(). collides() asks it in one
/// search, collides_each() in interleaved steps.
template <class T, class Tr, int W> struct CollisionQuestion {
  const Core<T, Tr, W> *core = nullptr;
  const T *shape = nullptr; // (null: collides_each's lane is idle)
  Box box;                  // shape's box
  Probe probe{0, 0, 0, 0, 0, 0};
  DiskProbe disk; // disk_probe(*core, box)

  BVH_ALWAYS_INLINE unsigned children(const Node<W> &node) const { return collision_children(node, probe); }
  /// The candidates `bits` of a summarized leaf before any exact test:
  /// true when the disks' codes alone show that one meets `shape` (then
  /// `bits` is unchanged); else `bits` keeps those still to test.
  BVH_ALWAYS_INLINE bool screen(const Node<W> &node, std::uint32_t &bits) const {
    if constexpr (kDisksFromCodes<Tr, W>) {
      if (disk.usable) {
        const DiskScreen s = disk_leaf_hit(node, disk, bits);
        if (s.hit) return true;
        bits = s.unsure;
      }
    }
    (void)node, (void)bits;
    return false;
  }
  /// True when stored shape s intersects `shape`.
  BVH_ALWAYS_INLINE bool meets(const T &s) const { return core->traits.intersect(s, *shape); }
  /// search()'s leaf decision: false (stop) on a hit.
  BVH_ALWAYS_INLINE bool leaf(int, const Node<W> &node, const Span<const T> &v) const {
    const auto missed = [&](std::size_t i) BVH_LAMBDA_INLINE { return !meets(v[i]); };
    return with_candidates(
        node, v.size(), box,
        [&](std::uint32_t bits) BVH_LAMBDA_INLINE { return !screen(node, bits) && each_bit(bits, missed); },
        [&]() BVH_LAMBDA_INLINE { return each_index(0, v.size(), missed); });
  }
};

/// True iff some stored shape intersects `shape` (CollisionQuestion).
template <class T, class Tr, int W> bool collides(const Core<T, Tr, W> &core, const T &shape) {
  if (core.root < 0) return false;
  const Box box = box_of(core.traits, shape);
  if (!core.nodes.box(core.root).overlaps(box)) return false;
  const CollisionQuestion<T, Tr, W> question{&core, &shape, box, Probe::around(box), disk_probe(core, box)};
  return !search(core, question);
}

/// One of collides_each()'s interleaved searches: a CollisionQuestion and
/// walk()'s state, kept between steps. Each step asks the cache for what
/// the next one reads (the node it enters, or the leaf's shapes left to
/// test) and hands over to the next lane.
template <class T, class Tr, int W> struct CollisionLane {
  /// A leaf of at most this many shapes waits for their prefetch.
  static constexpr std::size_t kDeferred = 32;
  CollisionQuestion<T, Tr, W> question; // (question.shape null: idle)
  unsigned char *hit = nullptr;
  IndexStack stack;
  int node = -1;             // the node the next step visits,
  const T *leaf = nullptr;   // or, while `pending` is not 0, the leaf's shapes
  std::uint32_t pending = 0; // whose bits are set here: the next step tests them

  BVH_ALWAYS_INLINE void enter(int n) {
    node = n;
    prefetch_lines(&question.core->nodes.node(n), sizeof(Node<W>));
  }
  /// Starts the search for `shape`, whose box `box` meets the root's.
  BVH_ALWAYS_INLINE void start(const Core<T, Tr, W> &core, const T &shape, const Box &box, unsigned char *answer) {
    question.core = &core;
    question.shape = &shape;
    question.box = box;
    question.probe = Probe::inline_around(box);
    if constexpr (kDisksFromCodes<Tr, W>) question.disk = disk_probe(core, box);
    hit = answer;
    enter(core.root);
  }
  /// The leaf's step: true when it decided a hit; else the shapes left to
  /// test are prefetched and pending (unless there are too many: then
  /// tested now).
  BVH_ALWAYS_INLINE bool visit_leaf(const Node<W> &node_at) {
    const Span<const T> v = question.core->leaves.shapes(node_at);
    const auto missed = [&](std::size_t i) BVH_LAMBDA_INLINE { return !question.meets(v[i]); };
    const auto defer = [&](std::uint32_t bits) BVH_LAMBDA_INLINE {
      for (std::uint32_t b = bits; b != 0; b &= b - 1) prefetch_lines(v.begin() + lowest_bit(b), sizeof(T));
      leaf = v.begin();
      pending = bits;
      return false;
    };
    return with_candidates(
        node_at, v.size(), question.box,
        [&](std::uint32_t bits) BVH_LAMBDA_INLINE { return question.screen(node_at, bits) || defer(bits); },
        [&]() BVH_LAMBDA_INLINE {
          if (v.size() > kDeferred) return !each_index(0, v.size(), missed);
          return defer(v.size() == 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << v.size()) - 1);
        });
  }
  /// One step; true when the search has its answer (in *hit).
  BVH_ALWAYS_INLINE bool step() {
    if (pending != 0) {
      for (; pending != 0; pending &= pending - 1)
        if (question.meets(leaf[lowest_bit(pending)])) {
          pending = 0;
          return *hit = 1, true;
        }
    } else {
      const Node<W> &node_at = question.core->nodes.node(node);
      if (node_at.is_leaf()) {
        if (visit_leaf(node_at)) return *hit = 1, true;
        if (pending != 0) return false;
      } else if (const unsigned enter_bits = question.children(node_at)) {
        enter(enter_children(stack, node_at, enter_bits));
        return false;
      }
    }
    if (stack.empty()) return *hit = 0, true;
    enter(stack.pop());
    return false;
  }
};

/// hit[j] = collides(core, shapes[j]) for each j < count, on one thread,
/// with kLanes of the searches interleaved (CollisionLane). A search of a
/// large tree mostly waits for memory: each node and the shapes it reads
/// are a miss that depends on the one before; interleaved, the misses of
/// kLanes searches overlap. Each search makes collides()'s decisions: the
/// same nodes, the same shapes tested (a leaf's, after the prefetch), the
/// same answer. If intersect() throws, the exception passes on and hit[]
/// is partly written.
template <class T, class Tr, int W>
void collides_each(const Core<T, Tr, W> &core, const T *shapes, std::size_t count, unsigned char *hit) {
  constexpr int kLanes = 8;
  std::size_t next = 0;
  // Gives lane s the next search that needs the tree; false when none is left.
  const auto start = [&](CollisionLane<T, Tr, W> &s) BVH_LAMBDA_INLINE {
    s.question.shape = nullptr;
    s.stack.clear();
    while (next < count) {
      const std::size_t j = next++;
      const Box box = box_of(core.traits, shapes[j]);
      if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) {
        hit[j] = 0;
        continue;
      }
      s.start(core, shapes[j], box, &hit[j]);
      return true;
    }
    return false;
  };
  CollisionLane<T, Tr, W> lanes[kLanes];
  int busy = 0;
  for (CollisionLane<T, Tr, W> &s : lanes) busy += start(s) ? 1 : 0;
  while (busy > 0)
    for (CollisionLane<T, Tr, W> &s : lanes)
      if (s.question.shape && s.step() && !start(s)) --busy;
}

/// query(box)'s and query(shape)'s test of stored shape s: its box meets
/// `box`, and with `shape` (not null), s intersects it.
template <class T, class Tr> BVH_ALWAYS_INLINE bool overlap_found(const Tr &traits, const T &s, const Box &box, const T *shape) {
  return box_of(traits, s).overlaps(box) && (!shape || traits.intersect(s, *shape));
}

/// The question of query(box) (shape null) and query(shape): calls
/// visit(s) on each stored shape s that overlap_found(), until it returns
/// false. Without `shape`, a shape whose code box surely meets the box is
/// not read (with_box_candidates). With `shape`, where disks are decided
/// from codes (disk_probe), a disk that surely misses is not read and one
/// that surely meets is not tested again.
template <class T, class Tr, int W, class V> struct OverlapQuestion {
  const Core<T, Tr, W> &core;
  const Box &box;
  const T *shape;
  Probe probe;
  DiskProbe disk;
  V &visit;

  BVH_ALWAYS_INLINE unsigned children(const Node<W> &node) const { return child_hits(node, probe); }
  BVH_ALWAYS_INLINE bool leaf(int, const Node<W> &node, const Span<const T> &v) const {
    const auto tested = [&](std::size_t i) BVH_LAMBDA_INLINE {
      return !overlap_found(core.traits, v[i], box, shape) || visit(v[i]);
    };
    // query(box): a shape whose codes show that its box surely meets the
    // box is found without reading its box (through an adaptor, a read of
    // the program's own arrays), in the same order as the others.
    if (!shape)
      return with_box_candidates(
          node, v.size(), box,
          [&](std::uint32_t bits, std::uint32_t sure) BVH_LAMBDA_INLINE {
            return each_bit(bits, [&](std::size_t i) BVH_LAMBDA_INLINE {
              return (sure >> i & 1u) ? visit(v[i]) : tested(i);
            });
          },
          [&]() BVH_LAMBDA_INLINE { return each_index(0, v.size(), tested); });
    return with_candidates(
        node, v.size(), box,
        [&](std::uint32_t bits) BVH_LAMBDA_INLINE {
          if constexpr (kDisksFromCodes<Tr, W>)
            if (shape && disk.usable)
              return each_disk_candidate(node, bits, disk, [&](int i, bool sure) BVH_LAMBDA_INLINE {
                return sure ? visit(v[i]) : tested(std::size_t(i));
              });
          return each_bit(bits, tested);
        },
        [&]() BVH_LAMBDA_INLINE { return each_index(0, v.size(), tested); });
  }
};

/// Calls visit(shape) on each shape whose box overlaps `box`, until it
/// returns false.
template <class T, class Tr, int W, class V> void visit_overlapping(const Core<T, Tr, W> &core, const Box &box, V &&visit) {
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  OverlapQuestion<T, Tr, W, V> question{core, box, nullptr, Probe::around(box), DiskProbe{}, visit};
  search(core, question);
}

/// Calls visit(s) on each stored shape s that intersects `shape` (T's
/// intersect(); only shapes whose box meets shape's are tested), in
/// visit_overlapping()'s order, until it returns false.
template <class T, class Tr, int W, class V> void visit_intersecting(const Core<T, Tr, W> &core, const T &shape, V &&visit) {
  const Box box = box_of(core.traits, shape);
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  OverlapQuestion<T, Tr, W, V> question{core, box, &shape, Probe::around(box), disk_probe(core, box), visit};
  search(core, question);
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
        with_candidates(
            node, v.size(), box_,
            [&](std::uint32_t bits) BVH_LAMBDA_INLINE {
              bits_ = bits;
              last_ = next_;
              return true;
            },
            [&]() BVH_LAMBDA_INLINE {
              last_ = v.end();
              return true;
            });
        continue;
      }
      const unsigned hits = child_hits(node, probe_); // (OverlapQuestion's children())
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
    if (!overlap_found(core_->traits, s, box_, shape_ ? &*shape_ : nullptr)) return false;
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

/// find_equal()'s question: a stored shape equal to `value`, whose box
/// is `box`; its leaf and index when found. Only subtrees whose box holds
/// `box` are searched: a float child box is its exact box rounded
/// outwards, so it holds `box` whenever the exact one does.
template <class T, class Tr, int W> struct EqualQuestion {
  const T &value;
  const Box &box;
  int &found_leaf;
  std::size_t &found_index;

  BVH_ALWAYS_INLINE unsigned children(const Node<W> &node) const {
    unsigned enter = 0;
    for (int c = 0; c < node.num_children; ++c)
      enter |= unsigned(node.lo_x[c] <= box.x0 && node.lo_y[c] <= box.y0 && box.x1 <= node.hi_x[c] &&
                        box.y1 <= node.hi_y[c])
               << c;
    return enter;
  }
  BVH_ALWAYS_INLINE bool leaf(int n, const Node<W> &node, const Span<const T> &v) const {
    // (an equal shape has the same box: its code box meets `box`)
    return each_candidate(node, v.size(), box, [&](std::size_t i) BVH_LAMBDA_INLINE {
      if (!(v[i] == value)) return true;
      found_leaf = n;
      found_index = i;
      return false;
    });
  }
};

/// Finds a stored shape equal to `value`: its leaf and index
/// (EqualQuestion).
template <class T, class Tr, int W> bool find_equal(const Core<T, Tr, W> &core, const T &value, int &leaf, std::size_t &index) {
  const Box box = box_of(core.traits, value);
  if (core.root < 0 || !core.nodes.box(core.root).contains(box)) return false;
  EqualQuestion<T, Tr, W> question{value, box, leaf, index};
  return !search(core, question);
}
} // namespace detail
} // namespace bvh

#endif // BVH_SEARCH_H
