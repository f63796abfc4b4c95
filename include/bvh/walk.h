// bvh/walk.h — the node test (child_masks) and walk(), the depth-first traversal.
//
// child_masks (which children a probe's box meets, four at a time with
// SSE2), the stack steps (push_bits, enter_children, prefetch_stacked),
// walk() (the one depth-first loop; a visit decides which children to
// enter), and the pre- and post-order loops. Iterative: no recursion.
// Includes node_store.h.
#ifndef BVH_WALK_H
#define BVH_WALK_H

#include "node_store.h"

namespace bvh {
namespace detail {

/// The node test. For inner node `node`: bit c of `hits` is set when child
/// c's box meets the probe's box, bit c of `near` when it also holds the
/// probe's centre (a hit there is likely, so collision() visits those
/// first). With SSE2 every child is tested in one 4-lane compare per bound
/// (the fourth lane reads the next field of the node and is masked off).
/// BVH_NO_SIMD forces the scalar path.
template <int W, bool kNear = true>
BVH_ALWAYS_INLINE void child_masks(const Node<W> &node, const Probe &p, unsigned &hits, unsigned &near) {
  const unsigned live = (1u << node.num_children) - 1;
  hits = 0;
  near = 0;
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  // Four children a pass; the lanes past W read the next row (or, after
  // hi_y, the links) and are masked off.
  for (int g = 0; g < W; g += 4) {
    const __m128 lx = _mm_loadu_ps(node.lo_x + g), ly = _mm_loadu_ps(node.lo_y + g);
    const __m128 hx = _mm_loadu_ps(node.hi_x + g), hy = _mm_loadu_ps(node.hi_y + g);
    const __m128 meets = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.hi_x.get()), _mm_cmple_ps(p.lo_x.get(), hx)),
                                    _mm_and_ps(_mm_cmple_ps(ly, p.hi_y.get()), _mm_cmple_ps(p.lo_y.get(), hy)));
    hits |= unsigned(_mm_movemask_ps(meets)) << g;
    if constexpr (kNear) {
      const __m128 holds = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(lx, p.mid_x.get()), _mm_cmple_ps(p.mid_x.get(), hx)),
                                      _mm_and_ps(_mm_cmple_ps(ly, p.mid_y.get()), _mm_cmple_ps(p.mid_y.get(), hy)));
      near |= unsigned(_mm_movemask_ps(holds)) << g;
    }
  }
#else
  for (int c = 0; c < W; ++c) {
    hits |= unsigned((node.lo_x[c] <= p.hi_x.f[0]) & (p.lo_x.f[0] <= node.hi_x[c]) & (node.lo_y[c] <= p.hi_y.f[0]) &
                     (p.lo_y.f[0] <= node.hi_y[c]))
            << c;
    if constexpr (kNear)
      near |= unsigned((node.lo_x[c] <= p.mid_x.f[0]) & (p.mid_x.f[0] <= node.hi_x[c]) & (node.lo_y[c] <= p.mid_y.f[0]) &
                       (p.mid_y.f[0] <= node.hi_y[c]))
              << c;
  }
#endif
  hits &= live;
  near &= hits;
}

/// child_masks' `hits` alone: bit c set when child c's box meets the
/// probe's box.
template <int W> BVH_ALWAYS_INLINE unsigned child_hits(const Node<W> &node, const Probe &p) {
  unsigned hits, near;
  child_masks<W, false>(node, p, hits, near);
  return hits;
}

/// walk()'s visit result: bit c enters child c (c < num_children); bit
/// kFirst + c enters it before every child of the low bits; kStop ends
/// the walk.
constexpr unsigned kFirst = 8u, kStop = 1u << 16;
static_assert(kMaxWidth <= int(kFirst), "the 'first' bits sit above the child bits");

/// Pushes child c of `node` for each bit c of `bits`, highest first (so
/// that they pop left to right): one step a set bit, not one a child.
template <int W> BVH_ALWAYS_INLINE void push_bits(IndexStack &stack, const Node<W> &node, unsigned bits) {
#if defined(__GNUC__)
  for (; bits != 0; bits &= ~(1u << (31 - __builtin_clz(bits)))) stack.push(node.child(31 - __builtin_clz(bits)));
#else
  for (int c = W - 1; c >= 0; --c)
    if (bits >> c & 1u) stack.push(node.child(c));
#endif
}

/// Of the children `enter` names (walk()'s visit result, at least one),
/// returns the one to visit next and pushes the others so that they pop in
/// order: the "first" group, then the rest, each left to right. The next
/// child skips the stack: most steps of a query enter one child.
template <int W> BVH_ALWAYS_INLINE int enter_children(IndexStack &stack, const Node<W> &node, unsigned enter) {
  unsigned first = enter >> kFirst, later = enter & ~first & child_bits(W);
  if (first == 0) {
    first = later;
    later = 0;
  }
  const int next = node.child(lowest_bit(first));
  first &= first - 1;
  if constexpr (W == 3) { // unrolled: this is collision()'s inner loop
    if (later & 4u) stack.push(node.child(2));
    if (later & 2u) stack.push(node.child(1));
    if (later & 1u) stack.push(node.child(0));
    if (first & 4u) stack.push(node.child(2));
    if (first & 2u) stack.push(node.child(1));
  } else {
    push_bits(stack, node, later);
    push_bits(stack, node, first);
  }
  return next;
}

/// Asks the cache for the nodes of the children that enter_children() left
/// on the stack (all those `enter` names but `next`) at widths 4 to 8:
/// their misses do not depend on the subtree entered first, so they
/// overlap with it. (At the course's width 3 a node is one line, and the
/// walk stays as it was.)
template <int W>
BVH_ALWAYS_INLINE void prefetch_stacked(const NodeStore<W> &nodes, const Node<W> &node, unsigned enter, int next) {
  if constexpr (W >= 4) {
    for (unsigned b = (enter | enter >> kFirst) & child_bits(W); b != 0; b &= b - 1) {
      const int c = node.child(lowest_bit(b));
      if (c != next) prefetch_lines(&nodes.node(c), sizeof(Node<W>));
    }
  } else {
    (void)nodes, (void)node, (void)enter, (void)next;
  }
}

/// The one depth-first traversal (collision, the queries, find_equal, the
/// rebuilds' gathering, every pre-order pass): from node `from`, each node
/// visited before its children. visit(n) returns which children of n to
/// enter (0 for a leaf) or kStop. Returns false when a visit stopped it.
/// overlapping()'s iterator runs the same steps with its stack kept between
/// calls.
template <int W, class Visit> BVH_ALWAYS_INLINE bool walk(const NodeStore<W> &nodes, int from, Visit &&visit) {
  IndexStack stack;
  int n = from;
  for (;;) {
    const unsigned enter = visit(n);
    if (enter & kStop) return false;
    if (enter != 0) {
      BVH_INVARIANT(!nodes.node(n).is_leaf(), "walk(): a leaf's visit enters children");
      const Node<W> &node = nodes.node(n);
      n = enter_children(stack, node, enter);
      prefetch_stacked(nodes, node, enter, n);
      continue;
    }
    if (stack.empty()) return true;
    n = stack.pop();
  }
}

/// walk()'s visit result that enters every child of `node`.
template <int W> inline unsigned all_children(const Node<W> &node) { return (1u << node.num_children) - 1; }

/// Calls f(n) on every node under `from` in pre-order (children left to
/// right).
template <int W, class F> void for_each_preorder(const NodeStore<W> &nodes, int from, F &&f) {
  if (from < 0) return;
  walk(nodes, from, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    f(n);
    return all_children(nodes.node(n));
  });
}

/// Calls f(n) on every node under `from`, children (left to right) before
/// their parent. Without a stack: it climbs by the nodes' parent links,
/// so it allocates nothing and never throws; f may free the node it is
/// given (a freed node's links stay readable until it is reused).
template <int W, class F> void for_each_postorder(const NodeStore<W> &nodes, int from, F &&f) noexcept {
  int n = nodes.leftmost_leaf(from);
  for (;;) {
    if (n == from) {
      f(n);
      return;
    }
    const int parent = nodes.info(n).parent, c = nodes.info(n).child_index;
    f(n);
    if (c + 1 < nodes.node(parent).num_children)
      n = nodes.leftmost_leaf(nodes.node(parent).child(c + 1));
    else
      n = parent;
  }
}
} // namespace detail
} // namespace bvh

#endif // BVH_WALK_H
