// bvh/erase.h — erase, update and margins.
//
// erase (the leaf shrinks; an emptied or underfull subtree is mended by a
// rebuild in order), its undo (update's strong guarantee), update (in
// place while the shape stays inside its leaf's box) and set_margin.
// Includes insert.h.
#ifndef BVH_ERASE_H
#define BVH_ERASE_H

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "insert.h"

namespace bvh {
namespace detail {

/// What update() needs to undo an erase_at(): the leaf's old slot (kept
/// aside) and box, or the old subtree that a mend replaced (detached).
template <class T> struct EraseUndo {
  int leaf = -1;                        ///< the leaf erased from (no mend)
  typename LeafStore<T>::Kept old_slot; ///< its slot before, with the shape
  Box leaf_box;                         ///< its box before
  int old_root = -1;                    ///< the mended subtree, detached (a mend)
  int fresh = -1;                       ///< what was built in its place
};

/// Decrements the counts from node n up and refits the boxes, bottom-up
/// (above the first box that does not change, only the counts do).
template <class T, class Tr, int W> void uncount_up(Core<T, Tr, W> &core, int n) noexcept {
  bool refit = true;
  for (; n >= 0; n = core.nodes.info(n).parent) {
    --core.nodes.info(n).count;
    if (refit) {
      const Box box = core.fitted_box(n);
      refit = box != core.nodes.box(n);
      if (refit) core.nodes.set_box(n, box);
    }
  }
}

/// Removes shape `index` of leaf `leaf` and returns its id (still taken);
/// `*changed` gets the node where the balance check starts. It mends the
/// tree on the way:
///  1. counts and tight boxes are refitted from the leaf to the root;
///  2. the highest ancestor left with at most split_threshold shapes, or
///     else the parent of a leaf left empty, is rebuilt from its shapes
///     (a leaf, or kWidth children again): no empty leaf, no inner node
///     with too few children or too few shapes;
///  3. (erase_shape) the highest lopsided ancestor of what changed is
///     rebuilt (find_scapegoat), so depth stays O(log n) under any churn.
/// Rebuilds here cut the shapes as `how` says: in their leaf order
/// (Cut::in_order), so that iteration order survives an erase
/// (erase(iterator) promises it), or by the build rule (Cut::by_rule:
/// erase(handle), erase(value) and update(), which promise no order). An
/// in-order rebuild is balanced by count but not in space: where the old
/// children were lopsided its equal cuts mix them, and near the root,
/// after many moves, that has doubled the tree's SAH cost. A rebuild of m
/// shapes costs O(m log m) and, as for inserts, needs Omega(m) erases
/// below the node to recur.
/// Strong: the node to mend is found before anything changes and rebuilt
/// beside the old subtree from copies. With `undo` (update()), the old
/// slot or subtree is kept aside: undo_erase() puts it back,
/// commit_erase() gives it back. The tree must hold more than one shape.
template <class T, class Tr, int W>
std::uint32_t erase_at(Core<T, Tr, W> &core, int leaf, std::size_t index, Cut how, int *changed,
                       EraseUndo<T> *undo = nullptr) {
  NodeStore<W> &nodes = core.nodes;
  BVH_INVARIANT(core.size > 1, "erase_at() of the last shape");
  int mend = nodes.node(leaf).leaf().count == 1 ? nodes.info(leaf).parent : -1;
  for (int n = nodes.info(leaf).parent; n >= 0; n = nodes.info(n).parent)
    if (nodes.info(n).count - 1 <= std::size_t(core.split_threshold)) mend = n; // the highest wins
  std::uint32_t id;
  if (mend >= 0) {
    id = core.leaves.ids(nodes.node(leaf))[index];
    std::vector<Tagged<T>> shapes = copy_subtree(core, mend, leaf, index);
    const int fresh = build_beside(core, mend, shapes, how);
    // Nothing below throws.
    link_in(core, mend, fresh);
    if (undo) {
      undo->old_root = mend;
      undo->fresh = fresh;
    } else {
      free_subtree(core, mend);
    }
    uncount_up(core, nodes.info(fresh).parent);
    *changed = fresh;
  } else {
    if (undo) {
      undo->leaf = leaf;
      undo->leaf_box = nodes.box(leaf);
      id = core.leaves.ids(nodes.node(leaf))[index];
      undo->old_slot = core.leaves.erase_keeping(nodes.node(leaf), index);
    } else {
      id = core.leaves.erase(nodes.node(leaf), index);
    }
    uncount_up(core, leaf);
    *changed = leaf;
  }
  --core.size;
  return id;
}

/// Puts back what erase_at(..., undo) removed: the tree is as before it.
template <class T, class Tr, int W> void undo_erase(Core<T, Tr, W> &core, const EraseUndo<T> &undo) noexcept {
  NodeStore<W> &nodes = core.nodes;
  int from;
  if (undo.fresh >= 0) {
    link_in(core, undo.fresh, undo.old_root);
    nodes.set_box(undo.old_root, nodes.box(undo.old_root)); // (the parent's float copy)
    relocate_subtree(core, undo.old_root);
    free_subtree(core, undo.fresh);
    from = nodes.info(undo.old_root).parent;
  } else {
    core.leaves.restore(nodes.node(undo.leaf), undo.leaf, undo.old_slot);
    ++nodes.info(undo.leaf).count;
    nodes.set_box(undo.leaf, undo.leaf_box);
    from = nodes.info(undo.leaf).parent;
  }
  for (int n = from; n >= 0; n = nodes.info(n).parent) ++nodes.info(n).count;
  if (from >= 0) core.refit_up(from);
  ++core.size;
}

/// Confirms an erase_at(..., undo): the kept slot or subtree goes.
template <class T, class Tr, int W> void commit_erase(Core<T, Tr, W> &core, const EraseUndo<T> &undo) noexcept {
  if (undo.fresh >= 0)
    free_subtree(core, undo.old_root);
  else
    core.leaves.discard(undo.old_slot);
}

/// erase_at() and its rebalance, then the id is given back. Strong.
template <class T, class Tr, int W>
void erase_shape(Core<T, Tr, W> &core, int leaf, std::size_t index, Cut how) {
  core.leaves.reserve_id_back();
  std::uint32_t id;
  if (core.size == 1) {
    id = core.leaves.ids(core.nodes.node(leaf))[index];
    core.clear_nodes();
  } else {
    int changed;
    id = erase_at(core, leaf, index, how, &changed);
    rebalance(core, find_scapegoat(core, changed, -1, true), how);
  }
  core.leaves.free_erased_id(id, core.size == 0);
}

/// dst = src, strong when T's move assignment cannot throw (a copy, then
/// the move); otherwise T's own copy assignment.
template <class T> void assign(T &dst, const T &src) {
  if constexpr (std::is_nothrow_move_assignable<T>::value) {
    T copy(src);
    dst = std::move(copy);
  } else {
    dst = src;
  }
}

/// The shape of `id`, stored at `at`, becomes `moved`: in place while it
/// fits its leaf's box (refitting above when there is no margin), else
/// erased and inserted again under the same id. Strong (in place: when T's
/// move assignment cannot throw, else as strong as T's copy assignment):
/// if the insert throws, the erase is undone.
template <class T, class Tr, int W>
void update_shape(Core<T, Tr, W> &core, std::uint32_t id, typename LeafStore<T>::Loc at, const T &moved) {
  NodeStore<W> &nodes = core.nodes;
  const Box box = box_of(core.traits, moved);
  if (nodes.box(at.leaf).contains(box) || core.size == 1) {
    // (the shape's code, if it has one, is out of use while it changes)
    Node<W> &leaf = nodes.node(at.leaf);
    const int coded = leaf.coded(), i = int(at.index);
    if (coded > i) leaf.set_coded(i);
    assign(core.leaves.shapes(leaf)[at.index], moved);
    if (coded > i) {
      leaf.code(i, box);
      leaf.set_coded(coded);
    }
    if (core.size == 1) // the last shape: its leaf is the root, fitted to it
      nodes.set_box(at.leaf, core.fitted_box(at.leaf));
    else if (core.margin == 0)
      core.refit_up(at.leaf);
    return;
  }
  EraseUndo<T> undo;
  int changed;
  erase_at(core, at.leaf, at.index, Cut::by_rule, &changed, &undo);
  // The erase's rebalance comes before the insert, as erase() then insert()
  // would do it; the subtree it replaces is kept aside until the insert
  // has succeeded. If the rebuild throws, it is given up (as rebalance()).
  const int a = find_scapegoat(core, changed, -1, true);
  int a_fresh = -1;
  if (a >= 0) {
    try {
      std::vector<Tagged<T>> shapes = copy_subtree(core, a);
      a_fresh = build_beside(core, a, shapes, Cut::by_rule);
      const bool box_changed = nodes.box(a_fresh) != nodes.box(a);
      link_in(core, a, a_fresh);
      if (box_changed && nodes.info(a_fresh).parent >= 0) core.refit_up(nodes.info(a_fresh).parent);
    } catch (...) {
      a_fresh = -1;
    }
  }
  int n;
  try {
    n = insert_unbalanced(core, moved, id);
  } catch (...) {
    if (a_fresh >= 0) { // the erase's state again, then before it
      link_in(core, a_fresh, a);
      nodes.set_box(a, nodes.box(a)); // (the parent's float copy)
      relocate_subtree(core, a);
      free_subtree(core, a_fresh);
      if (nodes.info(a).parent >= 0) core.refit_up(nodes.info(a).parent);
    }
    undo_erase(core, undo);
    throw;
  }
  commit_erase(core, undo);
  if (a_fresh >= 0) free_subtree(core, a);
  rebalance(core, find_scapegoat(core, nodes.info(n).parent, n, false), Cut::by_rule);
}

/// Sets the margin and recomputes every box, bottom-up: O(n).
/// Strong: nothing changes before the pass that cannot throw.
template <class T, class Tr, int W> void set_margin(Core<T, Tr, W> &core, double m) {
  const double margin = m > 0 && m < std::numeric_limits<double>::infinity() ? m : 0;
  if (core.root < 0) {
    core.margin = margin;
    return;
  }
  core.margin = margin;
  // Bottom-up without a list of nodes: nothing to allocate.
  for_each_postorder(core.nodes, core.root, [&](int n) { core.nodes.set_box(n, core.fitted_box(n)); });
}
} // namespace detail
} // namespace bvh

#endif // BVH_ERASE_H
