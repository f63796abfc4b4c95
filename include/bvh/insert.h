// bvh/insert.h — the insertion strategy and its balance.
//
// choose_child (least growth, ties to the smaller area), the descent, the
// leaf's overflow split, and the scapegoat rebuilds that keep any insertion
// order at O(log n) depth. Includes build.h.
#ifndef BVH_INSERT_H
#define BVH_INSERT_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "build.h"

namespace bvh {
namespace detail {

/// choose_child's pick among its first n children: least growth, ties to
/// the smaller area, then the first. (Its callers have made NaNs
/// infinite.) Branch-free: which child wins is data, and mispredicts cost
/// more than the selects.
template <class F> inline int least_growth(int n, const F *growth, const F *area) {
  int best = 0;
  F best_growth = growth[0], best_area = area[0];
  for (int c = 1; c < n; ++c) {
    const bool better = growth[c] < best_growth || (growth[c] == best_growth && area[c] < best_area);
    best = better ? c : best;
    best_growth = better ? growth[c] : best_growth;
    best_area = better ? area[c] : best_area;
  }
  return best;
}

#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
/// Bit i set for each lane i (of 4 * G) equal to the least of `v`
/// (none when every lane is NaN).
template <int G> BVH_ALWAYS_INLINE unsigned lanes_at_min(const __m128 *v) {
  __m128 m = v[0];
  for (int g = 1; g < G; ++g) m = _mm_min_ps(m, v[g]);
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(2, 3, 0, 1)));
  m = _mm_min_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(1, 0, 3, 2)));
  unsigned bits = 0;
  for (int g = 0; g < G; ++g) bits |= unsigned(_mm_movemask_ps(_mm_cmpeq_ps(v[g], m))) << (4 * g);
  return bits;
}
#endif

/// The insertion strategy, part 1: the child of inner node n whose box
/// grows least in area when it takes `box`; ties go to the smaller child,
/// then the first. Boxes are the children's float boxes (rounded outwards)
/// kept in the parent, so the choice reads one cache line; areas are
/// computed in double from those floats.
template <int W> BVH_ALWAYS_INLINE int choose_child(const Node<W> &node, const Box &box) {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  if constexpr (W % 4 == 0) {
    // Widths 4 and 8: four children a pass in float. A near tie may then
    // go the other way than in double; either child is a valid choice,
    // and these widths promise no particular tree (the course's, width 3,
    // takes the double path below).
    // The pick is a reduction in registers, not a loop of compares: which
    // child wins is data, and the loop's branches mispredicted. A NaN
    // growth or area (a box with infinite or NaN sides) never wins unless
    // every child's is NaN; then the first child takes the shape.
    const __m128 bx0 = _mm_set1_ps(float(box.x0)), by0 = _mm_set1_ps(float(box.y0));
    const __m128 bx1 = _mm_set1_ps(float(box.x1)), by1 = _mm_set1_ps(float(box.y1));
    const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
    __m128 growth[W / 4], area[W / 4];
    for (int g = 0; g < W; g += 4) {
      const __m128 x0 = _mm_loadu_ps(node.lo_x + g), y0 = _mm_loadu_ps(node.lo_y + g);
      const __m128 x1 = _mm_loadu_ps(node.hi_x + g), y1 = _mm_loadu_ps(node.hi_y + g);
      const __m128 a = _mm_mul_ps(_mm_sub_ps(x1, x0), _mm_sub_ps(y1, y0));
      const __m128 grown = _mm_mul_ps(_mm_sub_ps(_mm_max_ps(bx1, x1), _mm_min_ps(bx0, x0)),
                                      _mm_sub_ps(_mm_max_ps(by1, y1), _mm_min_ps(by0, y0)));
      // Lanes past the last child (and NaNs: _mm_min_ps(x, inf) is inf
      // for a NaN x) lose.
      const __m128 live = _mm_castsi128_ps(
          _mm_cmplt_epi32(_mm_setr_epi32(g, g + 1, g + 2, g + 3), _mm_set1_epi32(node.num_children)));
      growth[g / 4] = _mm_or_ps(_mm_and_ps(live, _mm_min_ps(_mm_sub_ps(grown, a), inf)), _mm_andnot_ps(live, inf));
      area[g / 4] = _mm_or_ps(_mm_and_ps(live, _mm_min_ps(a, inf)), _mm_andnot_ps(live, inf));
    }
    const unsigned least = lanes_at_min<W / 4>(growth);
    if ((least & (least - 1)) == 0) return node.child(least ? lowest_bit(least) : 0);
    for (int g = 0; g < W / 4; ++g) { // a tie: the smaller area among the least growths
      const __m128 tied = _mm_castsi128_ps(_mm_setr_epi32(-int(least >> (4 * g) & 1u), -int(least >> (4 * g + 1) & 1u),
                                                          -int(least >> (4 * g + 2) & 1u), -int(least >> (4 * g + 3) & 1u)));
      area[g] = _mm_or_ps(_mm_and_ps(tied, area[g]), _mm_andnot_ps(tied, inf));
    }
    const unsigned smallest = lanes_at_min<W / 4>(area) & least;
    return node.child(lowest_bit(smallest ? smallest : least));
  }
#endif
  double growth[W + W % 2], area[W + W % 2]; // (even: the passes below take two)
  // A NaN growth or area counts as infinite, as in the float pick above.
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  // Two children a pass, in double: the same operations as the scalar
  // path, so the same choice. _mm_max_pd(b, x) is std::max(x, b) and
  // _mm_min_pd(b, x) is std::min(x, b), NaNs included; _mm_min_pd(v, inf)
  // is v, or inf for a NaN v. At odd widths the last pass reads one float
  // past the row, inside the node; its lane is never chosen (c <
  // num_children below).
  const __m128d bx0 = _mm_set1_pd(box.x0), by0 = _mm_set1_pd(box.y0), bx1 = _mm_set1_pd(box.x1), by1 = _mm_set1_pd(box.y1);
  const __m128d inf = _mm_set1_pd(std::numeric_limits<double>::infinity());
  for (int g = 0; g < W; g += 2) {
    const __m128d x0 = two_floats(node.lo_x + g), y0 = two_floats(node.lo_y + g);
    const __m128d x1 = two_floats(node.hi_x + g), y1 = two_floats(node.hi_y + g);
    const __m128d a = _mm_mul_pd(_mm_sub_pd(x1, x0), _mm_sub_pd(y1, y0));
    const __m128d grown = _mm_mul_pd(_mm_sub_pd(_mm_max_pd(bx1, x1), _mm_min_pd(bx0, x0)),
                                     _mm_sub_pd(_mm_max_pd(by1, y1), _mm_min_pd(by0, y0)));
    _mm_storeu_pd(area + g, _mm_min_pd(a, inf));
    _mm_storeu_pd(growth + g, _mm_min_pd(_mm_sub_pd(grown, a), inf));
  }
#else
  const double inf = std::numeric_limits<double>::infinity();
  for (int c = 0; c < W; ++c) {
    const double x0 = node.lo_x[c], y0 = node.lo_y[c], x1 = node.hi_x[c], y1 = node.hi_y[c];
    const double a = (x1 - x0) * (y1 - y0);
    const double g = (std::max(x1, box.x1) - std::min(x0, box.x0)) * (std::max(y1, box.y1) - std::min(y0, box.y0)) - a;
    area[c] = a == a ? a : inf;
    growth[c] = g == g ? g : inf;
  }
#endif
  return node.child(least_growth(node.num_children, growth, area));
}

/// A child holding more than this share of its parent's shapes makes
/// the parent lopsided (a balanced node gives each child 1 / kWidth).
constexpr double kLopsided = 0.6;
/// Subtrees smaller than this are never rebuilt for balance: their
/// imbalance costs less than the rebuild.
template <class T, class Tr, int W> std::size_t min_rebuild(const Core<T, Tr, W> &core) {
  return std::max<std::size_t>(16, 3 * (std::size_t(core.split_threshold) + 1));
}
/// The one lopsided test, of every balance check (find_scapegoat, the
/// descent's, insert_scapegoat, disjoint.h's routing): true when a node of
/// `count` shapes is worth rebuilding for balance, given that a child of
/// it holds `heaviest`: it has at least `smallest` shapes (min_rebuild)
/// and that child more than kLopsided of them.
BVH_ALWAYS_INLINE bool lopsided(std::size_t heaviest, std::size_t count, std::size_t smallest) {
  return count >= smallest && double(heaviest) > kLopsided * double(count);
}

/// The insertion strategy, part 2, and erase's balance: scapegoat-style
/// partial rebuilds. Least-growth descent alone grows worse trees than the
/// build rule and, under sorted input, a spine as deep as n / k. After each
/// change, the highest node on the path from `a` up to the root (of at
/// least min_rebuild() shapes) that is lopsided is rebuilt by the build
/// rule. A node is lopsided when its child on the path (insert: the one the
/// shape went down; `below` starts as a's) or, with `any_child` (erase,
/// where any child may have shrunk), its largest child holds more than
/// kLopsided of its shapes. A rebuilt subtree of m shapes is balanced by
/// count and needs Omega(m) changes to tip again, so rebuilds cost O(log n)
/// amortised per change per level, and every level shrinks the count by at
/// least 1 / kLopsided: depth O(log n) for any order of changes. Returns -1
/// when no node is lopsided. The walk ends below `stop` (-1: at the root).
template <class T, class Tr, int W> int find_scapegoat(const Core<T, Tr, W> &core, int a, int below, bool any_child, int stop = -1) {
  const NodeStore<W> &nodes = core.nodes;
  const std::size_t smallest = min_rebuild(core);
  int scapegoat = -1;
  for (; a != stop; below = a, a = nodes.info(a).parent) {
    const std::size_t count = nodes.info(a).count;
    if (count < smallest) continue; // (then lopsided() is false: no child need be read)
    std::size_t heaviest = 0;
    if (any_child) {
      const Node<W> &node = nodes.node(a);
      for (int c = 0; c < node.num_children; ++c) heaviest = std::max<std::size_t>(heaviest, nodes.info(node.child(c)).count);
    } else {
      heaviest = nodes.info(below).count; // (a is below's parent: an inner node)
    }
    if (lopsided(heaviest, count, smallest)) scapegoat = a; // the last found is the highest
  }
  return scapegoat;
}

/// The rebalance after a change that has succeeded: rebuilds the highest
/// lopsided node above `from` (find_scapegoat) if there is one. A rebuild
/// is strong and only improves the balance, so if it throws the subtree
/// simply stays as it was (the next change finds it again) and the change
/// is not undone: the exception is not passed on.
template <class T, class Tr, int W> void rebalance(Core<T, Tr, W> &core, int scapegoat, Cut how) noexcept {
  if (scapegoat < 0) return;
  try {
    rebuild(core, scapegoat, how);
  } catch (...) {
  }
}

/// One step of an insertion's descent at node n: the shape counted and
/// `box` added there; at an inner node, the lopsided test of the step
/// from `prev` (find_scapegoat's answer so far in `above`; before the
/// first step prev is -1 and prev_count 0) and n becomes
/// the child to go on to by least growth (choose_child); at a leaf,
/// `leaf_box` gets its box before (with a margin it may exceed its
/// shapes'). Returns true at a leaf. The one step of every descent that
/// inserts: insert_below's (insert_unbalanced's, the lanes') and
/// insert_pipelined's. (disjoint.h's routing descends by choose_child
/// alone: it tests its path before it changes anything.)
template <int W>
BVH_ALWAYS_INLINE bool descend_step(NodeStore<W> &nodes, int &n, int &prev, int &above, std::size_t &prev_count,
                                    Box &leaf_box, const Box &box, std::size_t smallest) {
  const std::size_t count = ++nodes.info(n).count;
  if (nodes.node(n).is_leaf()) {
    leaf_box = nodes.box(n);
    nodes.extend_box(n, box);
    return true;
  }
  // (Before the first step prev_count is 0, so the test is false there.
  // In this order GCC compiles the step shorter than with above < 0 first.)
  if (lopsided(count, prev_count, smallest) && above < 0) above = prev;
  nodes.extend_box(n, box);
  prev = n;
  prev_count = count;
  n = choose_child(nodes.node(n), box);
  return false;
}

/// Undoes a descent's steps from node `last` (the last it stepped at) up
/// to, not including, `stop`: the counts, the leaf's box (when `leaf_box`,
/// last being the leaf) and the boxes above refitted. Never throws.
template <class T, class Tr, int W>
void undo_descent(Core<T, Tr, W> &core, int last, int stop, const Box *leaf_box) noexcept {
  NodeStore<W> &nodes = core.nodes;
  for (int m = last; m != stop; m = nodes.info(m).parent) --nodes.info(m).count;
  if (leaf_box) {
    nodes.set_box(last, *leaf_box);
    if (nodes.info(last).parent != stop) core.refit_up(nodes.info(last).parent, stop);
  } else if (last != stop) {
    core.refit_up(last, stop);
  }
}

/// insert_below()'s second half: `shape` (its own box `own`, not grown
/// by the margin: the leaf's summary codes it; its id `id`) goes into
/// leaf n, whose count and box the descent from `top` has already raised
/// (its box was `leaf_box`), which splits by the build rule
/// when it then holds more than split_threshold shapes above depth_limit.
/// Returns the node the shape went to. Strong: if it throws, the counts
/// and boxes from `top` down are undone.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_at_leaf(Core<T, Tr, W> &core, int top, int n, const Box &leaf_box, const Box &own, const T &shape,
                                     std::uint32_t id) {
  NodeStore<W> &nodes = core.nodes;
  try {
    if (!core.is_leaf_size(nodes.info(n).count, nodes.info(n).depth)) {
      // The leaf splits: copies of its shapes and the new one go straight
      // to the build (pushing first could move the slot to a larger class
      // for nothing).
      std::vector<Tagged<T>> shapes;
      shapes.reserve(nodes.info(n).count);
      core.leaves.copy_out(nodes.node(n), shapes);
      shapes.push_back(Tagged<T>{shape, id});
      const int fresh = build_beside(core, n, shapes, Cut::by_rule);
      if (W != kCourseWidth && n != top && can_splice(core, n, fresh)) {
        n = splice(core, n, fresh);
      } else {
        replace_by(core, n, fresh);
        n = fresh;
      }
    } else {
      core.leaves.push(nodes.node(n), n, shape, id);
      extend_summary(core, n, own);
    }
  } catch (...) {
    undo_descent(core, n, nodes.info(top).parent, &leaf_box);
    throw;
  }
  return n;
}

/// The descent of insert_unbalanced() from node `top` down: by least area
/// growth (choose_child), adding the shape's own box `own` grown by the
/// margin to every box and the shape to every count on the way, then
/// adding the shape to the leaf reached (insert_at_leaf). Returns the node the shape went to
/// (the leaf, or the subtree its split made); nothing above `top` is read
/// or written (disjoint.h runs it on several subtrees at once). Strong: if
/// it throws, the counts and boxes from `top` down are undone (a split is
/// built beside the leaf, which goes only once the new subtree is
/// complete).
/// `*lopsided_above` gets find_scapegoat()'s answer for the path from
/// `top` down to the leaf's parent, read on the way down (the counts above
/// the leaf are final there): insert_scapegoat() completes it.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_below(Core<T, Tr, W> &core, int top, const Box &own, const T &shape, std::uint32_t id,
                                   int *lopsided_above = nullptr) {
  NodeStore<W> &nodes = core.nodes;
  const Box box = core.fat(own);
  const std::size_t smallest = min_rebuild(core);
  int n = top, above = -1, prev = -1;
  std::size_t prev_count = 0;
  Box leaf_box; // the leaf's box before: with a margin it may exceed its shapes'
  while (!descend_step(nodes, n, prev, above, prev_count, leaf_box, box, smallest)) {
  }
  if (lopsided_above) *lopsided_above = above;
  return insert_at_leaf(core, top, n, leaf_box, own, shape, id);
}

/// insert_shape() without its rebalance: insert_below() from the root (or
/// the first shape as the root leaf). Returns the node the shape went to.
/// Strong.
template <class T, class Tr, int W>
BVH_ALWAYS_INLINE int insert_unbalanced(Core<T, Tr, W> &core, const T &shape, std::uint32_t id, int *lopsided_above = nullptr) {
  if (lopsided_above) *lopsided_above = -1;
  NodeStore<W> &nodes = core.nodes;
  const Box own = box_of(core.traits, shape);
  if (core.root < 0) {
    const int root = core.new_node(0, -1, 0);
    try {
      core.leaves.push(nodes.node(root), root, shape, id);
      extend_summary(core, root, own);
    } catch (...) {
      core.free_node(root);
      throw;
    }
    core.root = root;
    // (fitted, not `own`: a NaN side stays out of a box, as in every union)
    nodes.set_box(root, core.fitted_box(root));
    nodes.info(root).count = 1;
    core.size = 1;
    return root;
  }
  const int n = insert_below(core, core.root, own, shape, id, lopsided_above);
  ++core.size;
  return n;
}

/// find_scapegoat(core, parent of n, n, false, stop) after an insert that
/// went to node `n` (insert_below's result), given insert_below's
/// `lopsided_above`: only the last step, from n's parent to n, is left to
/// test, since a split or splice changes n but no count above it. It
/// saves a second walk up the path per insert.
/// `checked`: the invariant below may compare with a walk up (false when
/// later insertions under way, insert_pipelined's, have raised counts on
/// the path above).
template <class T, class Tr, int W>
int insert_scapegoat(const Core<T, Tr, W> &core, int n, int lopsided_above, int stop = -1, bool checked = true) {
  const NodeStore<W> &nodes = core.nodes;
  int found = lopsided_above;
  if (found < 0) {
    const int a = nodes.info(n).parent;
    if (a != stop && a >= 0 && lopsided(nodes.info(n).count, nodes.info(a).count, min_rebuild(core))) found = a;
  }
  BVH_INVARIANT(!checked || found == find_scapegoat(core, nodes.info(n).parent, n, false, stop),
                "the scapegoat read on the way down differs from the walk up");
  (void)checked;
  return found;
}

/// Adds `shape` under an id already taken (insert_unbalanced), then
/// rebuilds the highest lopsided node on the path (find_scapegoat, read
/// on the way: insert_scapegoat; rebalance). Strong.
template <class T, class Tr, int W> void insert_shape(Core<T, Tr, W> &core, const T &shape, std::uint32_t id) {
  int above;
  const int n = insert_unbalanced(core, shape, id, &above);
  rebalance(core, insert_scapegoat(core, n, above), Cut::by_rule);
}
} // namespace detail
} // namespace bvh

#endif // BVH_INSERT_H
