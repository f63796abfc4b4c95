// bvh/search.h — the depth-first searches: collision, box and shape queries, overlapping().
//
// collides, collides_each (several probes interleaved), visit_overlapping,
// visit_intersecting, OverlapSearch (a suspended walk, for iterators) and
// find_equal. Every query is const. Includes leaf_summary.h.
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
// run walk(); overlapping() runs walk()'s steps one at a time; the nearest
// searches and the ray run best_first().

/// collides()'s visit of inner node `node`: the children to enter, as
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

/// collides()'s visit of a summarized leaf of n disks (kDisksFromCodes,
/// the probe usable): true when one meets `shape`. (Not inlined: it runs on
/// large trees only, and inlined it made the search of small trees, which
/// never takes it, slower.)
template <class T, class Tr, int W>
BVH_NOINLINE bool disk_leaf_collides(const Tr &traits, const Node<W> &node, const T *v, int n, const Box &box,
                                     const DiskProbe &disk, const T &shape) {
  std::uint32_t unsure;
  if (disk_codes_hit(node, n, box, disk, unsure)) return true;
  for (; unsure != 0; unsure &= unsure - 1)
    if (traits.intersect(v[lowest_bit(unsure)], shape)) return true;
  return false;
}

/// True iff some stored shape intersects `shape` (touching counts).
/// Subtrees whose box misses the shape's box are never visited; the final
/// test is T's intersect().
template <class T, class Tr, int W> bool collides(const Core<T, Tr, W> &core, const T &shape) {
  if (core.root < 0) return false;
  const Box box = box_of(core.traits, shape);
  if (!core.nodes.box(core.root).overlaps(box)) return false;
  const Probe probe = Probe::around(box);
  const DiskProbe disk = disk_probe(core, box);
  return !walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      if constexpr (kDisksFromCodes<Tr, W>)
        if (disk.usable && node.coded() == int(v.size()))
          return disk_leaf_collides(core.traits, node, v.begin(), int(v.size()), box, disk, shape) ? kStop : 0;
      const bool missed =
          each_candidate(node, v.size(), box, [&](std::size_t i) { return !core.traits.intersect(v[i], shape); });
      return missed ? 0 : kStop;
    }
    return collision_children(node, probe);
  });
}

/// hit[j] = collides(core, shapes[j]) for each j < count, on one thread,
/// with kLanes of the searches interleaved. A search of a large tree
/// mostly waits for memory: each node and the shapes it reads are a miss
/// that depends on the one before. Here each step of a search asks the
/// cache for what its next step reads (the node it enters, or the leaf's
/// shapes whose code box meets the probe) and hands over to the next
/// search, so that the misses of kLanes searches overlap. Each search
/// makes collides()'s decisions: the same nodes, the same shapes tested
/// (a leaf's, after the prefetch), the same answer. If intersect() throws,
/// the exception passes on and hit[] is partly written.
template <class T, class Tr, int W>
void collides_each(const Core<T, Tr, W> &core, const T *shapes, std::size_t count, unsigned char *hit) {
  constexpr int kLanes = 8;
  constexpr std::size_t kDeferred = 32; // a leaf of at most this many shapes waits for their prefetch
  struct Search {
    const T *shape = nullptr; // null: the lane is idle
    unsigned char *hit = nullptr;
    Box box;
    Probe probe{0, 0, 0, 0, 0, 0};
    DiskProbe disk;              // (kDisksFromCodes)
    IndexStack stack;
    int node = -1;               // the node the next step visits,
    const T *leaf = nullptr;     // or, while `pending` is not 0, the leaf's shapes
    std::uint32_t pending = 0;   // whose bits are set here: the next step tests them
  };
  const auto enter = [&](Search &s, int n) BVH_LAMBDA_INLINE {
    s.node = n;
    prefetch_lines(&core.nodes.node(n), sizeof(Node<W>));
  };
  std::size_t next = 0;
  // Gives lane s the next search that needs the tree; false when none is left.
  const auto start = [&](Search &s) BVH_LAMBDA_INLINE {
    s.shape = nullptr;
    s.stack.clear();
    while (next < count) {
      const std::size_t j = next++;
      const Box box = box_of(core.traits, shapes[j]);
      if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) {
        hit[j] = 0;
        continue;
      }
      s.shape = &shapes[j];
      s.hit = &hit[j];
      s.box = box;
      s.probe = Probe::inline_around(box);
      if constexpr (kDisksFromCodes<Tr, W>) s.disk = disk_probe(core, box);
      enter(s, core.root);
      return true;
    }
    return false;
  };
  // One step of lane s's search; true when it has its answer.
  const auto step = [&](Search &s) BVH_LAMBDA_INLINE -> bool {
    if (s.pending != 0) {
      for (; s.pending != 0; s.pending &= s.pending - 1)
        if (core.traits.intersect(s.leaf[lowest_bit(s.pending)], *s.shape)) {
          s.pending = 0;
          return *s.hit = 1, true;
        }
    } else {
      const Node<W> &node = core.nodes.node(s.node);
      if (!node.is_leaf()) {
        const unsigned enter_bits = collision_children(node, s.probe);
        if (enter_bits != 0) {
          enter(s, enter_children(s.stack, node, enter_bits));
          return false;
        }
      } else {
        const Span<const T> v = core.leaves.shapes(node);
        if (v.size() <= kDeferred) {
          std::uint32_t bits = v.size() == 32 ? ~std::uint32_t(0) : (std::uint32_t(1) << v.size()) - 1;
          if constexpr (Node<W>::kCoded > 0) {
            if (node.coded() == int(v.size())) {
              if (!kDisksFromCodes<Tr, W> || !s.disk.usable) bits = node.meets(s.box, int(v.size()));
              else if (disk_codes_hit(node, int(v.size()), s.box, s.disk, bits)) return *s.hit = 1, true;
            }
          }
          if (bits != 0) {
            for (std::uint32_t b = bits; b != 0; b &= b - 1) prefetch_lines(v.begin() + lowest_bit(b), sizeof(T));
            s.leaf = v.begin();
            s.pending = bits;
            return false;
          }
        } else if (!each_candidate(node, v.size(), s.box, [&](std::size_t i) { return !core.traits.intersect(v[i], *s.shape); })) {
          return *s.hit = 1, true;
        }
      }
    }
    if (s.stack.empty()) return *s.hit = 0, true;
    enter(s, s.stack.pop());
    return false;
  };
  Search lanes[kLanes];
  int busy = 0;
  for (Search &s : lanes) busy += start(s) ? 1 : 0;
  while (busy > 0)
    for (Search &s : lanes)
      if (s.shape && step(s) && !start(s)) --busy;
}

/// Calls visit(shape) on each shape whose box overlaps `box`, until it
/// returns false.
template <class T, class Tr, int W, class V> void visit_overlapping(const Core<T, Tr, W> &core, const Box &box, V &&visit) {
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  const Probe probe = Probe::around(box);
  walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      const bool went_on = each_candidate(node, v.size(), box, [&](std::size_t i) {
        return !box_of(core.traits, v[i]).overlaps(box) || visit(v[i]);
      });
      return went_on ? 0 : kStop;
    }
    return child_hits(node, probe);
  });
}

/// Calls visit(s) on each stored shape s that intersects `shape` (T's
/// intersect(); only shapes whose box meets shape's are tested), in
/// visit_overlapping()'s order, until it returns false. Where disks are
/// decided from codes (disk_probe), a disk that surely misses is not read
/// and one that surely meets is not tested again.
template <class T, class Tr, int W, class V> void visit_intersecting(const Core<T, Tr, W> &core, const T &shape, V &&visit) {
  const Box box = box_of(core.traits, shape);
  if (core.root < 0 || !core.nodes.box(core.root).overlaps(box)) return;
  const Probe probe = Probe::around(box);
  const DiskProbe disk = disk_probe(core, box);
  walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      const Span<const T> v = core.leaves.shapes(node);
      const auto tested = [&](std::size_t i) {
        return !box_of(core.traits, v[i]).overlaps(box) || !core.traits.intersect(v[i], shape) || visit(v[i]);
      };
      if constexpr (kDisksFromCodes<Tr, W>) {
        if (disk.usable && node.coded() == int(v.size())) {
          const CodeFrame f = CodeFrame::of(node.frame());
          for (std::uint32_t bits = node.meets(box, int(v.size())); bits != 0; bits &= bits - 1) {
            const int i = lowest_bit(bits);
            const int sure = f.usable ? disk_decision(node, i, f, disk) : 0;
            if (sure < 0) continue;
            if (!(sure > 0 ? visit(v[i]) : tested(std::size_t(i)))) return kStop;
          }
          return 0;
        }
      }
      return each_candidate(node, v.size(), box, tested) ? 0 : kStop;
    }
    return child_hits(node, probe);
  });
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
        last_ = v.end();
        if constexpr (Node<W>::kCoded > 0) {
          if (node.coded() == int(v.size())) {
            bits_ = node.meets(box_, int(v.size()));
            last_ = next_;
          }
        }
        continue;
      }
      const unsigned hits = child_hits(node, probe_);
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
    if (!box_of(core_->traits, s).overlaps(box_) || (shape_ && !core_->traits.intersect(s, *shape_))) return false;
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

/// Finds a stored shape equal to `value`: its leaf and index. Only
/// subtrees whose box holds value's box are searched.
template <class T, class Tr, int W> bool find_equal(const Core<T, Tr, W> &core, const T &value, int &leaf, std::size_t &index) {
  const Box box = box_of(core.traits, value);
  if (core.root < 0 || !core.nodes.box(core.root).contains(box)) return false;
  // A float child box is its exact box rounded outwards: it holds `box`
  // whenever the exact one does.
  return !walk(core.nodes, core.root, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      // (an equal shape has the same box: its code box meets `box`)
      const Span<const T> v = core.leaves.shapes(node);
      const bool missed = each_candidate(node, v.size(), box, [&](std::size_t i) {
        if (!(v[i] == value)) return true;
        leaf = n;
        index = i;
        return false;
      });
      return missed ? 0 : kStop;
    }
    unsigned enter = 0;
    for (int c = 0; c < node.num_children; ++c)
      enter |= unsigned(node.lo_x[c] <= box.x0 && node.lo_y[c] <= box.y0 && box.x1 <= node.hi_x[c] &&
                        box.y1 <= node.hi_y[c])
               << c;
    return enter;
  });
}
} // namespace detail
} // namespace bvh

#endif // BVH_SEARCH_H
