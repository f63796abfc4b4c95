// bvh/validate.h — validate(): every invariant of a tree, with the reason of the first broken.
//
// Boxes tight and both copies equal, counts, depths, parents, the leaf
// summaries' exact codes, the handle table. Includes leaf_summary.h.
#ifndef BVH_VALIDATE_H
#define BVH_VALIDATE_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "leaf_summary.h"

namespace bvh {
namespace detail {

/// Checks node n's own invariants (not its subtree's: validate() does
/// that); false with *why set on the first failure.
template <class T, class Tr, int W> bool validate_node(const Core<T, Tr, W> &core, int n, std::string &why) {
  const NodeStore<W> &nodes = core.nodes;
  const Node<W> &node = nodes.node(n);
  const Info &in = nodes.info(n);
  if (n == core.root) {
    if (in.parent != -1 || in.depth != 0) return why = "root has a parent or depth != 0", false;
  } else {
    const Node<W> &p = nodes.node(in.parent);
    const int c = in.child_index;
    if (in.depth != nodes.info(in.parent).depth + 1) return why = "depth is not parent's + 1", false;
    if (c < 0 || c >= p.num_children || p.child(c) != n) return why = "parent does not list it in its slot", false;
    if (p.lo_x[c] != float_down(in.box().x0) || p.lo_y[c] != float_down(in.box().y0) ||
        p.hi_x[c] != float_up(in.box().x1) || p.hi_y[c] != float_up(in.box().y1))
      return why = "parent's float box for it is not its box rounded outwards", false;
  }
  if (core.depth_limit != 0 && in.depth > core.depth_limit) return why = "deeper than depth_limit", false;
  Box tight;
  std::size_t count = 0;
  if (node.is_leaf()) {
    const LeafSlot slot = node.leaf();
    if (!slot.has_slot() || slot.count == 0) return why = "empty leaf", false;
    if (core.leaves.slot_size(node) != slot.count) return why = "leaf's record disagrees with its slot", false;
    if (!core.is_leaf_size(slot.count, in.depth)) return why = "leaf over split_threshold above depth_limit", false;
    const Span<const T> shapes = core.leaves.shapes(node);
    for (const T &s : shapes) tight.extend(box_of(core.traits, s));
    count = shapes.size();
    for (std::size_t i = 0; i < shapes.size(); ++i)
      if (!supported_shape(core.traits, shapes[i]))
        return why = "shape " + std::to_string(i) + " is outside the supported values", false;
    const int coded = node.coded();
    if (coded > int(count) || coded > Node<W>::kCoded) return why = "summary of more shapes than the leaf holds", false;
    // Exactly its own box's codes, not a box holding it: a disk's code
    // box is read back as the disk itself (disk_decision).
    for (int i = 0; i < coded; ++i) {
      const std::uint32_t want = Node<W>::codes_of(box_of(core.traits, shapes[std::size_t(i)]), node.frame());
      if (node.codes(i) != want) {
        const auto sides = [](std::uint32_t c) {
          std::string t;
          for (int r = 0; r < 4; ++r) t += (r ? " " : "") + std::to_string(c >> (8 * r) & 255u);
          return t;
        };
        return why = "shape " + std::to_string(i) + "'s summary codes (low x, low y, high x, high y) are " +
                     sides(node.codes(i)) + ", not its own box's " + sides(want),
               false;
      }
    }
    const std::uint32_t *ids = core.leaves.ids(node);
    for (std::size_t i = 0; i < shapes.size() && core.leaves.located(); ++i)
      if (!core.leaves.contains(ids[i]) || core.leaves.locate(ids[i]).leaf != n ||
          core.leaves.locate(ids[i]).index != i)
        return why = "shape " + std::to_string(i) + "'s id does not locate it", false;
    // With a margin a leaf's box may be larger than fat(tight): update()
    // leaves it as it is while the shapes stay inside.
    if (core.margin > 0 && in.box().contains(tight)) tight = in.box();
  } else {
    if (node.num_children < 2 || node.num_children > W)
      return why = "inner node without 2 to " + std::to_string(W) + " children", false;
    // (the course's thirds give 2 children only to nodes of 2 shapes)
    if (W == 3 && node.num_children == 2 && core.split_threshold != 1)
      return why = "2 children although split_threshold > 1", false;
    for (int c = 0; c < node.num_children; ++c) {
      tight.extend(nodes.box(node.child(c)));
      count += nodes.info(node.child(c)).count;
    }
  }
  if (tight != in.box()) return why = "box is not the tight box of its subtree", false;
  if (count != in.count) return why = "shape count is not its subtree's", false;
  return true;
}

/// Checks every invariant of the tree; false with *why (when given) naming
/// the node and what it broke. O(n log n).
template <class T, class Tr, int W> bool validate(const Core<T, Tr, W> &core, std::string *why) {
  const NodeStore<W> &nodes = core.nodes;
  std::string what;
  int bad = -1;
  auto fail = [&](int n, const std::string &w) {
    if (why) *why = "node " + std::to_string(n) + ": " + w;
    return false;
  };
  if (core.root < 0) {
    if (core.size != 0) return fail(-1, "empty tree with size " + std::to_string(core.size));
    if (nodes.live() != 0) return fail(-1, "empty tree with live nodes");
    if (core.leaves.id_count() != 0 || !core.leaves.free_ids().empty() || !core.leaves.generations().empty())
      return fail(-1, "empty tree with ids");
    if (core.leaves.located()) return fail(-1, "empty tree with a handle table");
    return true;
  }
  // Every id below the count is stored exactly once or free (listed once).
  std::vector<char> id_seen(core.leaves.id_count(), 0);
  std::vector<char> is_free(nodes.capacity(), 0);
  for (int f : nodes.free_list()) {
    if (f < 0 || std::size_t(f) >= nodes.capacity() || is_free[std::size_t(f)]) return fail(f, "bad free-list entry");
    is_free[std::size_t(f)] = 1;
  }
  std::size_t counted = 0, reached = 0;
  walk(nodes, core.root, [&](int n) -> unsigned {
    ++reached;
    if (is_free[std::size_t(n)]) what = "reachable node on the free list";
    else if (validate_node(core, n, what)) what.clear();
    if (!what.empty()) {
      bad = n;
      return kStop;
    }
    if (nodes.node(n).is_leaf()) {
      counted += nodes.info(n).count;
      const std::uint32_t *ids = core.leaves.ids(nodes.node(n));
      for (std::size_t i = 0; i < nodes.info(n).count; ++i) {
        if (ids[i] >= id_seen.size() || id_seen[ids[i]]) {
          what = "id " + std::to_string(ids[i]) + " of shape " + std::to_string(i) + " is out of range or stored twice";
          bad = n;
          return kStop;
        }
        id_seen[ids[i]] = 1;
      }
    }
    return all_children(nodes.node(n));
  });
  if (bad >= 0) return fail(bad, what);
  if (reached + nodes.free_list().size() != nodes.capacity()) return fail(core.root, "unreachable nodes off the free list");
  if (counted != core.size) return fail(core.root, "size() disagrees with the shapes stored");
  if (core.leaves.id_count() != core.size + core.leaves.free_ids().size())
    return fail(-1, "ids in use and free do not add up");
  const bool located = core.leaves.located();
  for (std::uint32_t id : core.leaves.free_ids()) {
    if (id >= id_seen.size() || id_seen[id] || (located && core.leaves.contains(id)))
      return fail(-1, "free id " + std::to_string(id) + " is in use or listed twice");
    id_seen[id] = 1;
  }
  if (located && core.leaves.table_size() != core.leaves.id_count())
    return fail(-1, "the handle table's length is not the ids'");
  if (!core.leaves.generations().empty() && core.leaves.generations().size() != core.leaves.id_count())
    return fail(-1, "the generations' length is not the ids'");
  return true;
}
} // namespace detail
} // namespace bvh

#endif // BVH_VALIDATE_H
