// bvh/build.h — the one build loop and what runs on it.
//
// build_top_down (per node: a leaf by the course's rule, else the rule's
// cut), InOrderRule, build_at (a subtree, by rule or in order), split_in_two,
// the subtree moves of the rebuilds (splice, replace_by, copy_subtree) and
// construct (the threaded bulk build). Includes leaf_summary.h,
// course_rule.h, sah_rule.h, layout.h, parallel.h.
#ifndef BVH_BUILD_H
#define BVH_BUILD_H

#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "leaf_summary.h"
#include "course_rule.h"
#include "sah_rule.h"
#include "layout.h"
#include "parallel.h"

namespace bvh {
namespace detail {

/// Thirds (CountCut's groups at other widths) in the order given, without
/// sorting: where leaf order must survive (erase). Shapes that come out
/// of a subtree in leaf order are already spatially grouped.
template <class T, class Tr, int W> class InOrderRule : public ShapesAsItems<T, Tr> {
public:
  using State = typename ShapesAsItems<T, Tr>::State;
  InOrderRule(const Tr &traits, std::vector<Tagged<T>> &shapes, CountCut<W> counts)
      : ShapesAsItems<T, Tr>(traits, shapes), counts_(counts) {}
  void cut(const BuildTask<State> &t, int depth, const Box &, std::size_t cut[W + 1], State *) {
    counts_.cut(t.begin, t.end, depth, cut);
  }

private:
  CountCut<W> counts_;
};

/// `items` (a BuildScratch's), filled with shape(i) for i < n (input
/// position = i).
template <class T, class Tr, int W, class Shape>
Items<T, Tr> &fill_items(const Core<T, Tr, W> &core, Items<T, Tr> &items, std::size_t n, Shape &&shape) {
  // (clear and append, not resize: T need not be default-constructible)
  items.clear();
  items.reserve(n);
  for (std::size_t i = 0; i < n; ++i) items.push_back(make_item(core.traits, shape(i), std::uint32_t(i)));
  return items;
}

/// Gives leaf n (owning no slot) the rule's items [begin, end), moved.
template <class T, class Tr, int W, class Rule> void fill_leaf(Core<T, Tr, W> &core, int n, Rule &rule, std::size_t begin, std::size_t end) {
  core.leaves.fill(
      core.nodes.node(n), n, end - begin, [&](std::size_t i) -> T & { return rule.shape(begin + i); },
      [&](std::size_t i) { return rule.id(begin + i); });
  make_summary(core, n);
}

/// The shared loop: builds every task of `tasks` (and what they spawn) by
/// `rule`. Tasks whose node is at depth `defer_depth` are not built but
/// moved to `*deferred` (construct's parallel part builds them). With a
/// `layout`, children go where it says and leaves get their shapes later
/// (gather_leaves); without, nodes come from new_node().
template <class T, class Tr, int W, class Rule>
void build_top_down(Core<T, Tr, W> &core, std::vector<BuildTask<typename Rule::State>> &tasks, Rule &rule,
                    const typename std::common_type<Layout<W>>::type *layout, int defer_depth = -1,
                    std::vector<BuildTask<typename Rule::State>> *deferred = nullptr) {
  using Task = BuildTask<typename Rule::State>;
  NodeStore<W> &nodes = core.nodes;
  while (!tasks.empty()) {
    const Task t = tasks.back();
    tasks.pop_back();
    const int depth = nodes.info(t.node).depth;
    if (deferred && depth == defer_depth) {
      deferred->push_back(t);
      continue;
    }
    BVH_INVARIANT(nodes.node(t.node).is_leaf() && !nodes.node(t.node).leaf().has_slot(),
                  "a build starts at a leaf that owns no slot");
    Box box;
    for (std::size_t i = t.begin; i < t.end; ++i) box.extend(rule.box(i));
    box = core.fat(box); // (a grown union is the union of the grown boxes)
    const std::size_t n = t.end - t.begin;
    nodes.set_box(t.node, box);
    nodes.info(t.node).count = n;
    if (core.is_leaf_size(n, depth)) {
      rule.order_leaf(t);
      // A laid-out build (construct) gathers every leaf's shapes at the
      // end, in one pass, with no thread touching the pool.
      if (!layout) fill_leaf(core, t.node, rule, t.begin, t.end);
      continue;
    }
    std::size_t cut[W + 1];
    typename Rule::State state[W];
    rule.cut(t, depth, box, cut, state);
    Task child[W];
    int children = 0;
    int groups = 0;
    for (int g = 0; g < W; ++g) groups += cut[g + 1] > cut[g];
    int grandchildren = t.block + groups; // laid out: where the next child's children go
    for (int g = 0; g < W; ++g) {
      if (cut[g + 1] == cut[g]) continue;
      int c, block = -1;
      if (layout) {
        c = t.block + children;
        nodes.reset(c, depth + 1, t.node, children);
        block = grandchildren;
        grandchildren += int(layout->nodes(cut[g + 1] - cut[g], depth + 1)) - 1;
      } else {
        c = core.new_node(depth + 1, t.node, children);
      }
      nodes.node(t.node).set_child(children, c);
      child[children++] = Task{c, cut[g], cut[g + 1], block, state[g]};
      // (child by child: a build given up midway frees every node it made)
      nodes.node(t.node).num_children = children;
    }
    for (int c = children - 1; c >= 0; --c) tasks.push_back(child[c]); // built left to right
  }
}

/// How build_at() cuts.
enum class Cut {
  by_rule, ///< the tree's build rule
  in_order ///< InOrderRule: iteration order survives (erase(iterator)'s repairs)
};

/// build_at()'s course-rule build by the shared loop.
template <class T, class Tr, int W> void build_by_course_rule(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes) {
  // Threads inserting into disjoint subtrees at once (disjoint.h) cannot
  // share the tree's scratch memory.
  BuildScratch<T, Tr> own;
  BuildScratch<T, Tr> &scratch = core.nodes.shared() ? own : core.scratch.value;
  CourseRule<T, Tr, W> rule(core.traits,
                            fill_items(core, scratch.items, shapes.size(), [&](std::size_t i) -> const T & { return shapes[i].shape; }),
                            &shapes, core.counts());
  std::vector<BuildTask<CourseState>> &tasks = scratch.tasks;
  tasks.assign(1, {at, 0, shapes.size(), -1, CourseRule<T, Tr, W>::root_state()});
  build_top_down(core, tasks, rule, nullptr);
}

/// The course rule's build at widths other than 3 where it makes one node
/// over two leaves, as a leaf's overflow split does (build_at): the tree
/// the shared loop makes, node for node and shape for shape, without its
/// general machinery (the items' copies of the shapes, the task stack, a
/// box of every shape computed three times). The two groups come from the
/// same selection, on keys that hold a centre and an input position where
/// the loop's items hold the shape: the same comparisons, so the same
/// order. False, having done nothing, when the build is not of that form.
/// If it throws, the nodes and slots it made hang under `at`.
/// Why a second build of the loop's tree stays: at widths other than 3
/// nearly every insert that overflows a leaf builds exactly this, and
/// the loop pays its machinery per build, not per shape, so on small
/// builds it is most of the cost; without this function insert-heavy
/// work at width 8 runs measurably more instructions (docs/performance.txt,
/// "split_in_two").
/// What keeps the two in step is test_bvh's
/// split_in_two_builds_what_the_loop_builds (widths 2, 4, 8, random
/// scenes, node for node).
template <class T, class Tr, int W> bool split_in_two(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes) {
  NodeStore<W> &nodes = core.nodes;
  const std::size_t m = shapes.size();
  const int depth = nodes.info(at).depth;
  if (m < 2 || core.is_leaf_size(m, depth)) return false;
  std::size_t size[W];
  core.counts().sizes(m, depth, size);
  bool two_groups = true;
  if constexpr (W > 2) two_groups = size[2] == 0;
  if (!two_groups || !core.is_leaf_size(size[0], depth + 1) || !core.is_leaf_size(size[1], depth + 1)) return false;
  struct SplitKey {
    XY c;
    std::uint32_t index;
    const XY &centre() const { return c; }
  };
  InlineVector<SplitKey, 72> keys;
  InlineVector<Sides, 72> boxes;
  keys.reserve(m);
  boxes.reserve(m);
  Box all;
  for (std::size_t i = 0; i < m; ++i) {
    keys.push_back(SplitKey{XY::of(core.traits.center(shapes[i].shape)), std::uint32_t(i)});
    const Box b = box_of(core.traits, shapes[i].shape);
    boxes.push_back(Sides::of(b));
    all.extend(b);
  }
  all = core.fat(all);
  nodes.set_box(at, all);
  nodes.info(at).count = m;
  if (all.dx() >= all.dy())
    select_nth(keys.begin(), keys.begin() + long(size[0]), keys.end(), Order<0, true>());
  else
    select_nth(keys.begin(), keys.begin() + long(size[0]), keys.end(), Order<1, true>());
  int child[2];
  for (int g = 0; g < 2; ++g) {
    child[g] = core.new_node(depth + 1, at, g);
    nodes.node(at).set_child(g, child[g]);
    nodes.node(at).num_children = g + 1;
  }
  for (int g = 0; g < 2; ++g) {
    const SplitKey *first = keys.begin() + (g == 0 ? 0 : long(size[0]));
    Box group;
    for (std::size_t i = 0; i < size[g]; ++i) group.extend(boxes[first[i].index].box());
    nodes.set_box(child[g], core.fat(group));
    nodes.info(child[g]).count = size[g];
    core.leaves.fill(
        nodes.node(child[g]), child[g], size[g], [&](std::size_t i) -> T & { return shapes[first[i].index].shape; },
        [&](std::size_t i) { return shapes[first[i].index].id; });
    make_summary(core, child[g], [&](std::size_t i) { return boxes[first[i].index].box(); });
  }
  return true;
}

/// The one entry for building a subtree: at leaf `at` (owning no slot),
/// from `shapes` (reordered). If it throws, the nodes and slots it made
/// hang under `at` (free_subtree gives them back).
template <class T, class Tr, int W> void build_at(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes, Cut how) {
  if (how == Cut::in_order) {
    InOrderRule<T, Tr, W> rule(core.traits, shapes, core.counts());
    std::vector<BuildTask<typename InOrderRule<T, Tr, W>::State>> tasks{
        {at, 0, shapes.size(), -1, InOrderRule<T, Tr, W>::root_state()}};
    build_top_down(core, tasks, rule, nullptr);
  } else if (core.rule == BuildRule::sah) {
    SahRule<T, Tr, W> rule(core.traits, shapes, core.counts());
    std::vector<BuildTask<typename SahRule<T, Tr, W>::State>> tasks{{at, 0, shapes.size(), -1, SahRule<T, Tr, W>::root_state()}};
    build_top_down(core, tasks, rule, nullptr);
  } else {
    if constexpr (W != kCourseWidth) {
      if (split_in_two(core, at, shapes)) return;
    }
    build_by_course_rule(core, at, shapes);
  }
}

/// Gives back every node and slot of the subtree at `at` (its shapes are
/// destroyed). Never throws.
template <class T, class Tr, int W> void free_subtree(Core<T, Tr, W> &core, int at) noexcept {
  for_each_postorder(core.nodes, at, [&](int n) { core.free_node(n); });
}

/// Locates every id of the subtree at `at` in its leaves again. Never throws.
template <class T, class Tr, int W> void relocate_subtree(Core<T, Tr, W> &core, int at) noexcept {
  for_each_postorder(core.nodes, at, [&](int n) { core.leaves.relocate(core.nodes.node(n), n); });
}

/// Puts node `by` where node `at` is (root, or its parent's child): `at`'s
/// subtree is then detached, its ids still located in `by`'s. `by` must
/// have at's parent, child index and depth, and the parent's float copy
/// of the box must be by's (build_beside leaves it so). Never throws.
template <class T, class Tr, int W> void link_in(Core<T, Tr, W> &core, int at, int by) noexcept {
  const int parent = core.nodes.info(at).parent;
  if (parent < 0)
    core.root = by;
  else
    core.nodes.node(parent).set_child(core.nodes.info(at).child_index, by);
}

/// Builds, from `shapes` (reordered), a subtree to take the place of the
/// one at `at`, which stays as it is: the new subtree's root has at's
/// parent, child index and depth but is not linked in (link_in does that),
/// and the ids of `shapes` are located in it. Strong: if it throws,
/// everything it made is given back and the tree is as it was.
template <class T, class Tr, int W> int build_beside(Core<T, Tr, W> &core, int at, std::vector<Tagged<T>> &shapes, Cut how) {
  const Info in = core.nodes.info(at);
  const int fresh = core.new_node(in.depth, in.parent, in.child_index);
  try {
    build_at(core, fresh, shapes, how);
  } catch (...) {
    free_subtree(core, fresh);
    relocate_subtree(core, at);
    core.nodes.set_box(at, core.nodes.box(at)); // (the parent's float copy is at's again)
    throw;
  }
  return fresh;
}

/// True when leaf `at`'s split `fresh` (made by build_beside) may instead
/// give its children to at's parent (splice): at is not the root, fresh's
/// children are all leaves, and the parent has room for them.
template <class T, class Tr, int W> bool can_splice(const Core<T, Tr, W> &core, int at, int fresh) {
  const int parent = core.nodes.info(at).parent;
  const Node<W> &f = core.nodes.node(fresh);
  if (parent < 0 || f.is_leaf() || core.nodes.node(parent).num_children - 1 + f.num_children > W) return false;
  for (int c = 0; c < f.num_children; ++c)
    if (!core.nodes.node(f.child(c)).is_leaf()) return false;
  return true;
}

/// The R-tree's overflow split, for widths other than the course's: leaf
/// `at` gives way to the leaves of its split `fresh` (can_splice) as
/// siblings in its parent, in its place and order, so that a leaf that
/// overflows fills its parent instead of growing a level of nearly empty
/// nodes. Returns the first of those leaves. Never throws.
template <class T, class Tr, int W> int splice(Core<T, Tr, W> &core, int at, int fresh) noexcept {
  NodeStore<W> &nodes = core.nodes;
  const Info in = nodes.info(at);
  const int parent = in.parent, first = in.child_index;
  Node<W> &p = nodes.node(parent);
  const int k = nodes.node(fresh).num_children, m = p.num_children;
  const bool changed = nodes.box(fresh) != nodes.box(at);
  for (int c = m - 1; c > first; --c) { // the later siblings move right
    const int x = p.child(c);
    p.set_child(c + k - 1, x);
    nodes.info(x).child_index = c + k - 1;
    nodes.set_box(x, nodes.box(x));
  }
  for (int j = 0; j < k; ++j) {
    const int y = nodes.node(fresh).child(j);
    p.set_child(first + j, y);
    Info &yi = nodes.info(y);
    yi.parent = parent;
    yi.child_index = first + j;
    yi.depth = in.depth;
    nodes.set_box(y, nodes.box(y));
  }
  p.num_children = m + k - 1;
  const int leaf = p.child(first);
  core.free_node(at);
  core.free_node(fresh); // (an inner node: its children are the parent's now)
  BVH_INVARIANT(!changed || !nodes.shared(), "a refit above a subtree that threads share");
  if (changed) core.refit_up(parent);
  return leaf;
}

/// The subtree at `at` becomes `fresh` (made by build_beside): linked in,
/// the old one freed, the boxes above refitted if the box changed (with a
/// margin, leaves that update() left larger come out fitted again). Never
/// throws.
template <class T, class Tr, int W> void replace_by(Core<T, Tr, W> &core, int at, int fresh) noexcept {
  const bool changed = core.nodes.box(fresh) != core.nodes.box(at);
  link_in(core, at, fresh);
  if (core.nodes.node(at).is_leaf()) // (a split's)
    core.free_node(at);
  else
    free_subtree(core, at);
  const int parent = core.nodes.info(fresh).parent;
  BVH_INVARIANT(!changed || !core.nodes.shared(), "a refit above a subtree that threads share");
  if (changed && parent >= 0) core.refit_up(parent);
}

/// Copies the shapes of the subtree at `at`, in leaf order, but shape
/// `skip_index` of leaf `skip_leaf` (none when -1).
template <class T, class Tr, int W>
std::vector<Tagged<T>> copy_subtree(const Core<T, Tr, W> &core, int at, int skip_leaf = -1, std::size_t skip_index = 0) {
  std::vector<Tagged<T>> shapes;
  shapes.reserve(core.nodes.info(at).count);
  walk(core.nodes, at, [&](int n) BVH_LAMBDA_INLINE -> unsigned {
    const Node<W> &node = core.nodes.node(n);
    if (node.is_leaf()) {
      if (n != skip_leaf) {
        core.leaves.copy_out(node, shapes);
      } else {
        const Span<const T> v = core.leaves.shapes(node);
        const std::uint32_t *ids = core.leaves.ids(node);
        for (std::size_t i = 0; i < v.size(); ++i)
          if (i != skip_index) shapes.push_back(Tagged<T>{v[i], ids[i]});
      }
    }
    return all_children(node);
  });
  return shapes;
}

/// Rebuilds the subtree at `at` from copies of its own shapes, taken in
/// leaf order; returns the new subtree's root. Strong: the old subtree
/// goes only once the new one is complete.
template <class T, class Tr, int W> int rebuild(Core<T, Tr, W> &core, int at, Cut how) {
  std::vector<Tagged<T>> shapes = copy_subtree(core, at);
  const int fresh = build_beside(core, at, shapes, how);
  replace_by(core, at, fresh);
  return fresh;
}

/// construct()'s course build. The rule's tree shape depends on counts
/// alone, so every node gets its index in advance (Layout): in pre-order,
/// each node's children adjacent, each subtree contiguous; and subtrees far
/// enough down are independent, so threads can build them at once. Last,
/// the leaves, in pre-order, take consecutive ranges of the items.
template <class T, class Tr, int W> void construct_by_course_rule(Core<T, Tr, W> &core, const std::vector<T> &elements) {
  const Layout<W> layout(core.size, core.split_threshold, core.depth_limit);
  core.nodes.resize(layout.nodes(core.size, 0));
  core.root = 0;
  core.nodes.reset(0, 0, -1, 0);
  const unsigned threads = threads_for(core.build_threads);
  CourseRule<T, Tr, W> rule(core.traits, fill_items(core, core.scratch.value.items, elements.size(), [&](std::size_t i) -> const T & { return elements[i]; }),
                            nullptr, core.counts(), threads);
  using Task = BuildTask<CourseState>;
  std::vector<Task> tasks{{0, 0, core.size, 1, CourseRule<T, Tr, W>::root_state()}};
  if (threads <= 1 || core.size < kParallelMin) {
    build_top_down(core, tasks, rule, &layout);
  } else {
    int defer_depth = 1; // enough subtrees to keep every thread busy
    for (std::size_t subtrees = W; subtrees < 4 * std::size_t(threads); subtrees *= W) ++defer_depth;
    std::vector<Task> deferred;
    build_top_down(core, tasks, rule, &layout, defer_depth, &deferred);
    rule.set_threads(1); // (the subtrees are built on every thread already)
    parallel_for(deferred.size(), threads, [&](std::size_t i) {
      std::vector<Task> one{deferred[i]};
      build_top_down(core, one, rule, &layout);
    });
  }
  std::size_t next = 0;
  for_each_preorder(core.nodes, core.root, [&](int n) {
    if (!core.nodes.node(n).is_leaf()) return;
    const std::size_t count = core.nodes.info(n).count;
    fill_leaf(core, n, rule, next, next + count);
    next += count;
  });
  Items<T, Tr>().swap(core.scratch.value.items);
}

/// Replaces the contents with `elements` (elements[i] gets the id i), built
/// by the tree's rule. If it throws, the tree is left empty.
template <class T, class Tr, int W> void construct(Core<T, Tr, W> &core, const std::vector<T> &elements) {
  core.clear();
  if (elements.empty()) return;
  if (elements.size() > std::size_t(std::numeric_limits<std::uint32_t>::max()))
    throw std::length_error("BVH::construct: more shapes than 32-bit handles can name");
  try {
    core.size = elements.size();
    core.leaves.take_first_ids(core.size);
    if (core.rule == BuildRule::course) {
      construct_by_course_rule(core, elements);
      return;
    }
    std::vector<Tagged<T>> tagged;
    tagged.reserve(core.size);
    for (std::size_t i = 0; i < core.size; ++i) tagged.push_back(Tagged<T>{elements[i], std::uint32_t(i)});
    core.root = core.new_node(0, -1, 0);
    build_at(core, core.root, tagged, Cut::by_rule);
  } catch (...) {
    core.clear();
    throw;
  }
}
} // namespace detail
} // namespace bvh

#endif // BVH_BUILD_H
