// bvh.h: a ternary bounding volume hierarchy (BVH) of 2D shapes, the
// course's Homework 8 (CSCI-1200 Data Structures, "Bounding Volume
// Hierarchy Trees").
//
// This file needs only the standard library and the course's "shapes.h"
// (Point, Color, BoundingBox, Disk, Triangle, Quad and their intersect()).
// It uses of a shape T only what all three classes offer: getBox(),
// getCenter(), setColor() and the free function intersect(const T &,
// const T &). It needs no default constructor and no operator== of T.
//
// ---------------------------------------------------------------------
// THE TREE
// ---------------------------------------------------------------------
// Every node stores the bounding box of all the shapes below it. An inner
// node has three children (fewer only when it holds fewer than three
// shapes, which happens with --split_threshold 1); a leaf stores its
// shapes in a std::vector. Every shape is in exactly one leaf, no leaf is
// empty, and every node knows its parent, its depth (root = 0) and how
// many shapes its subtree holds (`count`). The counts are what make
// rebalancing, erase and finding "the k-th shape" cheap.
//
// A node stays a leaf when it holds at most split_threshold shapes, or
// when it is at depth depth_limit (depth_limit 0: no limit).
//
// ---------------------------------------------------------------------
// THE COURSE'S BUILD RULE (construct, and every split and rebuild)
// ---------------------------------------------------------------------
// To split a node's shapes into three groups:
//   1. take the longer side of the node's box: x when dx >= dy, else y;
//   2. sort the shapes by their centre's coordinate on that side with a
//      STABLE sort, so that shapes with equal coordinates keep the order
//      they arrived in (the parent's order; at the root, input order);
//   3. cut the sorted sequence into thirds by count: m shapes give groups
//      of m/3 rounded up, then the rest split the same way (10 -> 4, 3, 3;
//      11 -> 4, 4, 3), larger groups first.
// A leaf keeps its shapes in the order its parent's sort left them. That
// order is also the iteration order, and the order of the "elements:" in
// statistics(true), so it is part of the expected output. Each level
// sorts every shape once: O(n log n) per level, and the thirds make the
// tree O(log n) deep, so a build is O(n log^2 n).
//
// ---------------------------------------------------------------------
// THE SURFACE AREA HEURISTIC (statistics, and the extra-credit builder)
// ---------------------------------------------------------------------
// The handout measures a tree by the surface area heuristic (Bittner,
// Hapala and Havran, "Incremental BVH construction for ray tracing"):
//
//   cost = 1 / Area(scene) * [ sum over inner nodes I of Area(I)
//                              + sum over leaves L of Area(L) * ShapeCount(L) ]
//
// Area(I) / Area(scene) is roughly the chance that a random query point
// has to look inside node I; a leaf's term is weighted by its shapes
// because each of them must then be tested. statistics() prints the two
// sums separately ("inner node area", "leaf node area"), with the scene
// taken as the course's 1000 x 1000 canvas.
//
// The extra-credit builder (set_build_rule(BuildRule::sah)) chooses its
// cuts to make that sum small instead of cutting by count: at a node of m
// shapes sorted on one axis, cutting before position i costs
//   Area(box of shapes [0, i)) * i + Area(box of shapes [i, m)) * (m - i),
// and one sweep from each end computes all those boxes in O(m). The best
// cut on either axis is taken, then the more expensive of its two sides is
// cut again the same way, giving three groups. It spends more build time
// for a tree that answers queries by touching less area.
//
// ---------------------------------------------------------------------
// INSERTING ONE SHAPE (insert), AND KEEPING THE TREE BALANCED
// ---------------------------------------------------------------------
// 1. Descend from the root. Every node on the way counts the new shape and
//    grows its box to cover it. At an inner node go to the child whose box
//    would grow least in area; on a tie, the smaller child; then the first.
//    (The areas are compared on the children's boxes rounded outwards to
//    float, which is how the project's engine stores them, so that both
//    grow exactly the same tree.)
// 2. Add the shape at the end of the leaf reached. If the leaf now holds
//    more than split_threshold shapes and may split (above depth_limit),
//    its shapes, the new one last, are built into a subtree by the build
//    rule, in place of the leaf.
// 3. Rebalance. Least-growth descent alone can make long chains: shapes
//    inserted in sorted order keep going down the same side, and the tree
//    gets n / k deep. So, like a scapegoat tree, after each insert we look
//    at the nodes on the path, from the root down, and REBUILD the first
//    (highest) one that is LOPSIDED: it holds at least kMinRebuild shapes
//    (the larger of 16 and 3 * (split_threshold + 1): smaller subtrees are
//    cheaper to search than to rebuild) and its child on the path holds
//    more than kLopsided = 60% of them (a balanced node gives each child
//    a third). The rebuild collects the subtree's shapes in iteration
//    order and builds them again by the build rule.
//    Why that is cheap: a freshly rebuilt node of m shapes is balanced, so
//    it takes on the order of m more inserts below it before it can be
//    lopsided again; the O(m log m) rebuild is paid for by those inserts,
//    O(log n) amortised per level. And why it bounds the depth: along any
//    path, each node's child holds at most 60% of its shapes, so the depth
//    is at most log base 1/0.6 of n, plus the small subtrees at the bottom.
// insert is O(log n) amortised (times log n for the sorts of a rebuild).
//
// ---------------------------------------------------------------------
// ERASE (extra credit), AND WHY IT IS HARDER THAN IN A BINARY SEARCH TREE
// ---------------------------------------------------------------------
// A binary search tree finds a value by its key in O(log n) and unlinks
// one node; nothing else changes. A BVH has no key order: a shape could be
// in any subtree whose box contains its box, so finding it by value is a
// spatial search of possibly many subtrees (and needs an operator== that
// the course's shapes do not have). So erase here takes an iterator, which
// already knows the leaf. Then:
//   - every box above the leaf may now be too large: a box can only shrink
//     by recomputing it from the children, all the way up to the root;
//   - the tree's shape rules can break: a leaf may become empty, an inner
//     node may hold no more than split_threshold shapes (so it should be a
//     leaf). We rebuild the highest such node from its shapes;
//   - erases can make a node lopsided just as inserts do, so the highest
//     node whose largest child holds more than 60% is rebuilt, as above.
// All of erase's rebuilds cut the shapes in their current iteration order
// (thirds by count, no sorting), so erasing while iterating visits every
// other shape exactly once. Other iterators are invalidated.
// erase is O(log n) amortised, like insert.
//
// ---------------------------------------------------------------------
// MEMORY AND RECURSION
// ---------------------------------------------------------------------
// Nodes are allocated with new and owned by their parent (the root by the
// tree). No function here recurses: traversals keep their own stack of
// nodes (a std::vector), so even a deep tree (an SAH build without a depth
// limit may be) cannot overflow the call stack. The trees of the course's
// rule and of insert are O(log n) deep anyway (see above).
// If memory runs out (std::bad_alloc), every node allocated is still owned
// by the tree and freed by its destructor; the copy constructor and
// assignment then change nothing, while a build or insert that fails may
// leave the tree's contents incomplete.
#ifndef BVH_H
#define BVH_H

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "shapes.h"

template <class T> class BVH {
private:
  struct Node;

public:
  /// How construct(), and the splits and rebuilds of insert(), cut a node.
  enum class BuildRule { course, sah };

  class iterator;
  typedef iterator const_iterator;

  // ---- construction, copy, destruction --------------------------------

  /// An empty tree. A node holding more than split_threshold shapes splits
  /// unless it is at depth depth_limit (depth_limit <= 0: no limit). A
  /// split_threshold below 1 is taken as 1 (a leaf of 0 shapes could
  /// never stop splitting). O(1).
  explicit BVH(int split_threshold = 4, int depth_limit = 0)
      : split_threshold_(split_threshold < 1 ? 1 : split_threshold), depth_limit_(depth_limit < 0 ? 0 : depth_limit),
        rule_(BuildRule::course), root_(nullptr) {}
  /// A deep copy: every node and shape is copied. O(n).
  BVH(const BVH &other)
      : split_threshold_(other.split_threshold_), depth_limit_(other.depth_limit_), rule_(other.rule_),
        root_(copy_tree(other.root_)) {}
  /// Deep copy; assigning a tree to itself changes nothing. O(n + m).
  BVH &operator=(const BVH &other) {
    if (this != &other) {
      Node *copy = copy_tree(other.root_); // first: if it throws, *this is as it was
      destroy_tree(root_);
      root_ = copy;
      split_threshold_ = other.split_threshold_;
      depth_limit_ = other.depth_limit_;
      rule_ = other.rule_;
    }
    return *this;
  }
  /// Frees every node. O(n).
  ~BVH() { destroy_tree(root_); }

  // ---- the homework's operations ----------------------------------------

  /// Replaces the tree's contents by `elements`, built top-down by the
  /// build rule. O(n log^2 n) with the course's rule.
  void construct(const std::vector<T> &elements);
  /// Adds one shape (see INSERTING ONE SHAPE above). O(log n) amortised.
  void insert(const T &shape);
  /// True when some stored shape intersects `shape`, by the course's
  /// intersect(stored, shape). Subtrees whose box does not overlap the
  /// shape's box are skipped. O(log n + the shapes of the leaves reached)
  /// on a balanced tree of shapes that do not pile up.
  bool collision(const T &shape) const;

  /// The first shape: the first of the leftmost leaf. O(depth).
  iterator begin() const { return root_ ? iterator(this, leftmost_leaf(root_), 0) : end(); }
  /// One past the last shape. O(1).
  iterator end() const { return iterator(this, nullptr, 0); }
  /// The number of shapes. O(1).
  std::size_t size() const { return root_ ? root_->count : 0; }
  /// True when there are no shapes. O(1).
  bool empty() const { return root_ == nullptr; }

  /// The course's report on std::cout: with print_tree, one line per node
  /// in pre-order (indented 3 spaces a level: its area over the canvas's,
  /// its box and, for a leaf, its shapes' boxes), then the node count, the
  /// maximum depth and the two sums of the surface area heuristic. O(n).
  void statistics(bool print_tree) const;
  /// Draws every node's box (root grey; its children red, green, blue;
  /// deeper nodes a third of their own primary and two thirds of their
  /// parent's colour) and recolours every shape to its leaf's colour. O(n).
  void render_recolor(std::ostream &ostr);

  // ---- extra credit -------------------------------------------------------

  /// Removes the shape at `pos` (which must point at one) and returns the
  /// iterator to the shape that followed it (see ERASE above). O(log n)
  /// amortised.
  iterator erase(iterator pos);
  /// Selects the rule of later builds, splits and rebuilds. O(1).
  void set_build_rule(BuildRule rule) { rule_ = rule; }

private:
  /// How build_subtree cuts: by the tree's rule, or in iteration order.
  enum class Cut { by_rule, in_order };

  struct Node {
    Node(Node *parent_, int depth_, const BoundingBox &box_)
        : box(box_), parent(parent_), num_children(0), depth(depth_), count(0) {
      children[0] = children[1] = children[2] = nullptr;
    }
    bool is_leaf() const { return num_children == 0; }
    BoundingBox box;    // of every shape below
    Node *parent;       // nullptr at the root
    Node *children[3];  // the first num_children are used
    int num_children;   // 0 for a leaf
    int depth;          // root = 0
    std::size_t count;  // shapes in this subtree
    std::vector<T> shapes; // a leaf's shapes; empty at an inner node
  };

  // The balance rule of INSERTING ONE SHAPE (step 3).
  static constexpr double kLopsided = 0.6;
  std::size_t min_rebuild() const { return std::max<std::size_t>(16, 3 * (std::size_t(split_threshold_) + 1)); }
  static bool lopsided(std::size_t heaviest, std::size_t count) { return double(heaviest) > kLopsided * double(count); }
  bool stays_leaf(std::size_t count, int depth) const {
    return count <= std::size_t(split_threshold_) || (depth_limit_ > 0 && depth >= depth_limit_);
  }

  static BoundingBox box_of(const std::vector<T> &shapes);
  static void fit(Node *node);
  static std::vector<T> collect(const Node *node);
  static const Node *leftmost_leaf(const Node *node);
  static const Node *rightmost_leaf(const Node *node);
  static const Node *next_leaf(const Node *node);
  static const Node *previous_leaf(const Node *node);
  static int index_in_parent(const Node *node);
  static Node *copy_tree(const Node *from);
  static void destroy_tree(Node *node);
  static void free_children(Node *node);
  template <class P, class F> static void preorder(P from, F f); // P: Node * or const Node *

  void build_subtree(Node *node, std::vector<T> shapes, Cut how);
  static void thirds(std::size_t m, std::size_t cut[4]);
  static void sort_by_centre(std::vector<T> &shapes, bool by_x);
  static void cut_by_course_rule(std::vector<T> &shapes, const BoundingBox &box, std::size_t cut[4]);
  static double area_of(const std::vector<T> &shapes, std::size_t begin, std::size_t end);
  static std::size_t best_cut(const std::vector<T> &shapes, std::size_t begin, std::size_t end, double &cost);
  static double cut_by_sah_on(std::vector<T> &shapes, bool by_x, std::size_t cut[4]);
  static void cut_by_sah(std::vector<T> &shapes, std::size_t cut[4]);
  static double float_down(double d);
  static double float_up(double d);
  static Node *choose_child(const Node *node, const BoundingBox &box);
  static void print_node(std::ostream &out, const Node *node, double area);
  static Color child_colour(const Color &parent, int child, bool parent_is_root);
  void rebuild(Node *node, Cut how);
  Node *mend_after_erase(Node *leaf);
  void rebalance_after_erase(Node *from);
  iterator iterator_at(std::size_t rank) const;
  static std::size_t rank_of(const iterator &pos);

  int split_threshold_;
  int depth_limit_;
  BuildRule rule_;
  Node *root_;
};

// ===========================================================================
// The iterator: shape by shape, leaf by leaf, left to right
// ===========================================================================

/// A bidirectional iterator over the shapes, in leaf order: all shapes of
/// the leftmost leaf in their stored order, then those of the next leaf to
/// the right, and so on. It reads shapes only (operator* gives a const T&):
/// a shape cannot be changed in place, since its node's box would then be
/// wrong. ++ and -- are O(1) within a leaf and O(depth) between leaves,
/// O(1) amortised over a whole pass. Insert, construct and erase
/// invalidate iterators (erase returns a valid one).
template <class T> class BVH<T>::iterator {
public:
  typedef std::bidirectional_iterator_tag iterator_category;
  typedef T value_type;
  typedef std::ptrdiff_t difference_type;
  typedef const T *pointer;
  typedef const T &reference;

  iterator() : tree_(nullptr), leaf_(nullptr), index_(0) {}
  const T &operator*() const { return leaf_->shapes[index_]; }
  const T *operator->() const { return &leaf_->shapes[index_]; }
  bool operator==(const iterator &o) const { return leaf_ == o.leaf_ && index_ == o.index_; }
  bool operator!=(const iterator &o) const { return !(*this == o); }

  /// Pre-increment: to the next shape (end() after the last).
  iterator &operator++() {
    if (++index_ == leaf_->shapes.size()) {
      leaf_ = next_leaf(leaf_);
      index_ = 0;
    }
    return *this;
  }
  /// Post-increment: moves on, returns where it was.
  iterator operator++(int) {
    iterator old(*this);
    ++*this;
    return old;
  }
  /// Pre-decrement: to the previous shape (from end(): the last one).
  iterator &operator--() {
    if (leaf_ == nullptr || index_ == 0) {
      leaf_ = leaf_ == nullptr ? rightmost_leaf(tree_->root_) : previous_leaf(leaf_);
      index_ = leaf_->shapes.size();
    }
    --index_;
    return *this;
  }
  /// Post-decrement: moves back, returns where it was.
  iterator operator--(int) {
    iterator old(*this);
    --*this;
    return old;
  }

private:
  friend class BVH<T>;
  iterator(const BVH<T> *tree, const Node *leaf, std::size_t index) : tree_(tree), leaf_(leaf), index_(index) {}
  const BVH<T> *tree_; // for --end(), which starts from the root
  const Node *leaf_;   // nullptr: end()
  std::size_t index_;  // in leaf_->shapes
};

/// The leftmost leaf under `node`. O(depth).
template <class T> const typename BVH<T>::Node *BVH<T>::leftmost_leaf(const Node *node) {
  while (!node->is_leaf()) node = node->children[0];
  return node;
}
/// The rightmost leaf under `node`. O(depth).
template <class T> const typename BVH<T>::Node *BVH<T>::rightmost_leaf(const Node *node) {
  while (!node->is_leaf()) node = node->children[node->num_children - 1];
  return node;
}
/// Which child of its parent `node` is. O(1): at most three to look at.
template <class T> int BVH<T>::index_in_parent(const Node *node) {
  int c = 0;
  while (node->parent->children[c] != node) ++c;
  return c;
}
/// The leaf after `node` in leaf order, or nullptr: climb until a node has
/// a right sibling, then go down that sibling's left side. O(depth).
template <class T> const typename BVH<T>::Node *BVH<T>::next_leaf(const Node *node) {
  for (; node->parent != nullptr; node = node->parent) {
    const int c = index_in_parent(node);
    if (c + 1 < node->parent->num_children) return leftmost_leaf(node->parent->children[c + 1]);
  }
  return nullptr;
}
/// The leaf before `node` in leaf order (it must have one). O(depth).
template <class T> const typename BVH<T>::Node *BVH<T>::previous_leaf(const Node *node) {
  for (; node->parent != nullptr; node = node->parent) {
    const int c = index_in_parent(node);
    if (c > 0) return rightmost_leaf(node->parent->children[c - 1]);
  }
  return nullptr;
}

// ===========================================================================
// Small helpers: boxes, traversal, copying and freeing
// ===========================================================================

/// The bounding box of a non-empty group of shapes. (The course's
/// BoundingBox has no "empty" box, so we start from the first shape's.)
/// O(m).
template <class T> BoundingBox BVH<T>::box_of(const std::vector<T> &shapes) {
  BoundingBox box = shapes[0].getBox();
  for (std::size_t i = 1; i < shapes.size(); ++i) box.extend(shapes[i].getBox());
  return box;
}

/// Recomputes a node's box from its shapes, or from its non-empty
/// children. Leaves an empty leaf's box as it was. O(1) for an inner node,
/// O(shapes) for a leaf.
template <class T> void BVH<T>::fit(Node *node) {
  if (node->is_leaf()) {
    if (!node->shapes.empty()) node->box = box_of(node->shapes);
    return;
  }
  bool first = true;
  for (int c = 0; c < node->num_children; ++c) {
    const Node *child = node->children[c];
    if (child->count == 0) continue;
    if (first) node->box = child->box;
    else node->box.extend(child->box);
    first = false;
  }
}

/// Calls f(node) on every node under `from` (a Node * or a const Node *)
/// in pre-order (a node before its children, children left to right),
/// with a stack of our own instead of recursion. O(n).
template <class T> template <class P, class F> void BVH<T>::preorder(P from, F f) {
  std::vector<P> stack;
  if (from != nullptr) stack.push_back(from);
  while (!stack.empty()) {
    P node = stack.back();
    stack.pop_back();
    f(node);
    for (int c = node->num_children - 1; c >= 0; --c) stack.push_back(node->children[c]); // popped left first
  }
}

/// Copies of every shape under `node`, in iteration order. O(m).
template <class T> std::vector<T> BVH<T>::collect(const Node *node) {
  std::vector<T> shapes;
  shapes.reserve(node->count);
  preorder(node, [&shapes](const Node *n) { shapes.insert(shapes.end(), n->shapes.begin(), n->shapes.end()); });
  return shapes;
}

/// A deep copy of the subtree at `from` (nullptr for nullptr), node by node
/// from a stack of (original, copy) pairs. A copy counts only the children
/// copied so far (num_children), so if an allocation throws, destroy_tree
/// frees exactly what was copied. O(n).
template <class T> typename BVH<T>::Node *BVH<T>::copy_tree(const Node *from) {
  if (from == nullptr) return nullptr;
  Node *top = new Node(*from); // box, depth, count and shapes; children below
  top->parent = nullptr;
  top->num_children = 0;
  std::vector<std::pair<const Node *, Node *> > stack;
  try {
    stack.push_back(std::make_pair(from, top));
    while (!stack.empty()) {
      const Node *original = stack.back().first;
      Node *copy = stack.back().second;
      stack.pop_back();
      for (int c = 0; c < original->num_children; ++c) {
        Node *child = new Node(*original->children[c]);
        child->num_children = 0;
        child->parent = copy;
        copy->children[c] = child;
        copy->num_children = c + 1;
        stack.push_back(std::make_pair(original->children[c], child));
      }
    }
  } catch (...) {
    destroy_tree(top);
    throw;
  }
  return top;
}

/// Deletes every node under `node` (nothing for nullptr) without
/// allocating, so that it cannot fail: go down to a last child, taking it
/// off its parent's list on the way, delete a node once it has no children
/// left, then go back up by its parent link. O(n).
template <class T> void BVH<T>::destroy_tree(Node *node) {
  Node *const top = node;
  while (node != nullptr) {
    if (node->num_children > 0) {
      node = node->children[--node->num_children];
      continue;
    }
    Node *const parent = node == top ? nullptr : node->parent;
    delete node;
    node = parent;
  }
}

/// Deletes a node's subtrees; it becomes an (empty) leaf. O(its nodes).
template <class T> void BVH<T>::free_children(Node *node) {
  for (int c = 0; c < node->num_children; ++c) {
    destroy_tree(node->children[c]);
    node->children[c] = nullptr;
  }
  node->num_children = 0;
}

// ===========================================================================
// Building: the course's rule, the SAH rule, and the loop that uses them
// ===========================================================================

/// Builds `shapes` into the subtree at `node` (a leaf without shapes, whose
/// parent and depth are set): the node gets their box and count; it stays
/// a leaf if stays_leaf() says so, otherwise its shapes are cut into up to
/// three consecutive groups (by the rule, or in their given order) and each
/// non-empty group becomes a child, built the same way. A list of nodes to
/// build replaces recursion. O(m log^2 m) by the course's rule.
template <class T> void BVH<T>::build_subtree(Node *node, std::vector<T> shapes, Cut how) {
  std::vector<std::pair<Node *, std::vector<T> > > todo; // nodes still to build, with their shapes
  todo.emplace_back(node, std::move(shapes));
  while (!todo.empty()) {
    Node *n = todo.back().first;
    std::vector<T> group = std::move(todo.back().second);
    todo.pop_back();
    n->box = box_of(group);
    n->count = group.size();
    if (stays_leaf(group.size(), n->depth)) {
      n->shapes = std::move(group);
      continue;
    }
    std::size_t cut[4]; // group g is [cut[g], cut[g + 1])
    if (how == Cut::in_order) thirds(group.size(), cut);
    else if (rule_ == BuildRule::sah) cut_by_sah(group, cut);
    else cut_by_course_rule(group, n->box, cut);
    for (int g = 0; g < 3; ++g) {
      if (cut[g + 1] == cut[g]) continue;
      Node *child = new Node(n, n->depth + 1, n->box);
      n->children[n->num_children++] = child;
      todo.emplace_back(child, std::vector<T>(std::make_move_iterator(group.begin() + std::ptrdiff_t(cut[g])),
                                              std::make_move_iterator(group.begin() + std::ptrdiff_t(cut[g + 1]))));
    }
  }
}

/// The course's thirds of m shapes: sizes that differ by at most one,
/// larger first (m = 10: 4, 3, 3; m = 11: 4, 4, 3; m = 2: 1, 1, 0).
/// cut[g] .. cut[g + 1] is group g. O(1).
template <class T> void BVH<T>::thirds(std::size_t m, std::size_t cut[4]) {
  const std::size_t base = m / 3, extra = m % 3;
  cut[0] = 0;
  cut[1] = cut[0] + base + (extra > 0 ? 1 : 0);
  cut[2] = cut[1] + base + (extra > 1 ? 1 : 0);
  cut[3] = m;
}

/// Sorts shapes by their centre's x (or y), keeping the order of shapes
/// whose coordinates are equal (a stable sort). O(m log m).
template <class T> void BVH<T>::sort_by_centre(std::vector<T> &shapes, bool by_x) {
  std::stable_sort(shapes.begin(), shapes.end(), [by_x](const T &a, const T &b) {
    return by_x ? a.getCenter().x < b.getCenter().x : a.getCenter().y < b.getCenter().y;
  });
}

/// The course's rule (see THE COURSE'S BUILD RULE): a stable sort of the
/// shapes by centre on the longer side of `box` (x on a tie), then thirds.
/// O(m log m).
template <class T> void BVH<T>::cut_by_course_rule(std::vector<T> &shapes, const BoundingBox &box, std::size_t cut[4]) {
  const bool by_x = box.dx() >= box.dy();
  sort_by_centre(shapes, by_x);
  thirds(shapes.size(), cut);
}

/// The area of the box of shapes [begin, end) (non-empty). O(end - begin).
template <class T> double BVH<T>::area_of(const std::vector<T> &shapes, std::size_t begin, std::size_t end) {
  BoundingBox box = shapes[begin].getBox();
  for (std::size_t i = begin + 1; i < end; ++i) box.extend(shapes[i].getBox());
  return box.getArea();
}

/// The SAH's best place to cut shapes [begin, end) (at least two, in their
/// order) in two: the i in (begin, end) that minimises
///   Area([begin, i)) * (i - begin) + Area([i, end)) * (end - i),
/// which goes to `cost`. A sweep from the right records the area of every
/// right part, then a sweep from the left grows the left part's box and
/// compares. O(end - begin).
template <class T>
std::size_t BVH<T>::best_cut(const std::vector<T> &shapes, std::size_t begin, std::size_t end, double &cost) {
  std::vector<double> right_area(end - begin + 1, 0.0); // [i - begin]: Area([i, end))
  BoundingBox right = shapes[end - 1].getBox();
  for (std::size_t i = end - 1; i > begin; --i) {
    right.extend(shapes[i].getBox());
    right_area[i - begin] = right.getArea();
  }
  BoundingBox left = shapes[begin].getBox();
  std::size_t best = begin + 1;
  cost = std::numeric_limits<double>::infinity();
  for (std::size_t i = begin + 1; i < end; ++i) { // left: [begin, i)
    const double c = left.getArea() * double(i - begin) + right_area[i - begin] * double(end - i);
    if (c < cost) {
      cost = c;
      best = i;
    }
    left.extend(shapes[i].getBox());
  }
  return best;
}

/// The SAH's three groups with the shapes sorted by centre on one axis
/// (stably, as the course's rule does): the best cut in two, then the best
/// cut of whichever side gives the lower total. Returns that total. O(m log m).
template <class T> double BVH<T>::cut_by_sah_on(std::vector<T> &shapes, bool by_x, std::size_t cut[4]) {
  sort_by_centre(shapes, by_x);
  const std::size_t m = shapes.size();
  double total, left_cost = std::numeric_limits<double>::infinity(), right_cost = left_cost;
  const std::size_t i = best_cut(shapes, 0, m, total);
  std::size_t j_left = 0, j_right = m;
  const double left_area = area_of(shapes, 0, i) * double(i), right_area = area_of(shapes, i, m) * double(m - i);
  if (i >= 2) j_left = best_cut(shapes, 0, i, left_cost);     // [0, j) [j, i) [i, m)
  if (m - i >= 2) j_right = best_cut(shapes, i, m, right_cost); // [0, i) [i, j) [j, m)
  cut[0] = 0;
  cut[3] = m;
  if (i < 2 && m - i < 2) { // two shapes: two groups
    cut[1] = cut[2] = i;
    return total;
  }
  if (left_cost + right_area <= left_area + right_cost) {
    cut[1] = j_left;
    cut[2] = i;
    return left_cost + right_area;
  }
  cut[1] = i;
  cut[2] = j_right;
  return left_area + right_cost;
}

/// The extra-credit rule (see THE SURFACE AREA HEURISTIC): the SAH's groups
/// on x and on y, whichever costs less (x on a tie). O(m log m).
template <class T> void BVH<T>::cut_by_sah(std::vector<T> &shapes, std::size_t cut[4]) {
  std::vector<T> on_y(shapes);
  std::size_t cut_y[4];
  const double cost_x = cut_by_sah_on(shapes, true, cut);
  const double cost_y = cut_by_sah_on(on_y, false, cut_y);
  if (cost_y < cost_x) {
    shapes.swap(on_y);
    std::copy(cut_y, cut_y + 4, cut);
  }
}

/// Builds the whole tree from `elements` (what was stored before is gone).
template <class T> void BVH<T>::construct(const std::vector<T> &elements) {
  destroy_tree(root_);
  root_ = nullptr;
  if (elements.empty()) return;
  root_ = new Node(nullptr, 0, elements[0].getBox());
  build_subtree(root_, elements, Cut::by_rule);
}

/// Rebuilds the subtree at `node` from its own shapes, taken in iteration
/// order. O(m log^2 m) by the course's rule, O(m) in order.
template <class T> void BVH<T>::rebuild(Node *node, Cut how) {
  std::vector<T> shapes = collect(node);
  free_children(node);
  node->shapes.clear();
  build_subtree(node, std::move(shapes), how);
}

// ===========================================================================
// Inserting
// ===========================================================================

/// The largest float <= d, and the smallest float >= d, as doubles: a box
/// rounded outwards to float still contains the box.
template <class T> double BVH<T>::float_down(double d) {
  float f = static_cast<float>(d);
  if (static_cast<double>(f) > d) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
template <class T> double BVH<T>::float_up(double d) {
  float f = static_cast<float>(d);
  if (static_cast<double>(f) < d) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

/// The child of inner node `node` whose box grows least in area when it
/// takes `box`; on a tie the smaller child, then the first. (A NaN area
/// counts as infinite.) O(1).
template <class T> typename BVH<T>::Node *BVH<T>::choose_child(const Node *node, const BoundingBox &box) {
  const double inf = std::numeric_limits<double>::infinity();
  int best = 0;
  double best_growth = inf, best_area = inf;
  for (int c = 0; c < node->num_children; ++c) {
    const BoundingBox &b = node->children[c]->box;
    const double x0 = float_down(b.getMin().x), y0 = float_down(b.getMin().y);
    const double x1 = float_up(b.getMax().x), y1 = float_up(b.getMax().y);
    double area = (x1 - x0) * (y1 - y0);
    double growth = (std::max(x1, box.getMax().x) - std::min(x0, box.getMin().x)) *
                        (std::max(y1, box.getMax().y) - std::min(y0, box.getMin().y)) - area;
    if (area != area) area = inf; // (NaN is the only value unequal to itself)
    if (growth != growth) growth = inf;
    if (c == 0 || growth < best_growth || (growth == best_growth && area < best_area)) {
      best = c;
      best_growth = growth;
      best_area = area;
    }
  }
  return node->children[best];
}

/// See INSERTING ONE SHAPE at the top of this file.
template <class T> void BVH<T>::insert(const T &shape) {
  const BoundingBox box = shape.getBox();
  if (root_ == nullptr) {
    root_ = new Node(nullptr, 0, box);
    root_->shapes.push_back(shape);
    root_->count = 1;
    return;
  }
  std::vector<Node *> path; // from the root down to the leaf
  Node *node = root_;
  for (;;) { // step 1: count, grow, descend by least growth
    ++node->count;
    node->box.extend(box);
    path.push_back(node);
    if (node->is_leaf()) break;
    node = choose_child(node, box);
  }
  node->shapes.push_back(shape); // step 2: into the leaf; split if too full
  if (!stays_leaf(node->count, node->depth)) {
    std::vector<T> shapes;
    shapes.swap(node->shapes); // (the leaf's, the new one last)
    build_subtree(node, std::move(shapes), Cut::by_rule);
  }
  for (std::size_t i = 0; i + 1 < path.size(); ++i) // step 3: the highest lopsided node
    if (path[i]->count >= min_rebuild() && lopsided(path[i + 1]->count, path[i]->count)) {
      rebuild(path[i], Cut::by_rule);
      return;
    }
}

// ===========================================================================
// Queries and the course's report
// ===========================================================================

template <class T> bool BVH<T>::collision(const T &shape) const {
  const BoundingBox box = shape.getBox();
  std::vector<const Node *> stack;
  if (root_ != nullptr) stack.push_back(root_);
  while (!stack.empty()) {
    const Node *node = stack.back();
    stack.pop_back();
    if (!node->box.overlaps(box)) continue; // nothing below can touch it
    for (std::size_t i = 0; i < node->shapes.size(); ++i)
      if (intersect(node->shapes[i], shape)) return true;
    for (int c = node->num_children - 1; c >= 0; --c) stack.push_back(node->children[c]);
  }
  return false;
}

/// One line of statistics(true). The course's report prints the root's
/// area with 3 significant digits (its stream was not yet in fixed mode)
/// and every other area with 3 decimals.
template <class T> void BVH<T>::print_node(std::ostream &out, const Node *node, double area) {
  out << std::string(3 * std::size_t(node->depth), ' ') << (node->is_leaf() ? "leaf" : "inner") << " area=";
  if (node->depth == 0) out.unsetf(std::ios::floatfield);
  else out << std::fixed;
  out << std::setprecision(3) << area << ' ' << node->box;
  if (node->is_leaf()) {
    out << " elements:";
    for (std::size_t i = 0; i < node->shapes.size(); ++i) out << ' ' << node->shapes[i].getBox();
  }
  out << '\n';
}

template <class T> void BVH<T>::statistics(bool print_tree) const {
  std::ostream &out = std::cout;
  const std::ios::fmtflags flags = out.flags();
  const std::streamsize precision = out.precision();
  long nodes = 0;
  int max_depth = 0;
  double inner_area = 0, leaf_area = 0;
  preorder(static_cast<const Node *>(root_), [&](const Node *node) {
    const double area = node->box.getArea() / (1000.0 * 1000.0); // the canvas is 1000 x 1000
    ++nodes;
    max_depth = std::max(max_depth, node->depth);
    if (node->is_leaf()) leaf_area += area * double(node->count);
    else inner_area += area;
    if (print_tree) print_node(out, node, area);
  });
  out << std::fixed << std::setprecision(3);
  out << "node count:      " << std::setw(7) << nodes << '\n';
  out << "max depth:       " << std::setw(7) << max_depth << '\n';
  out << "inner node area: " << std::setw(7) << inner_area << '\n';
  out << "leaf node area:  " << std::setw(7) << leaf_area << std::endl;
  out.flags(flags);
  out.precision(precision);
}

/// The colour of child `child` of a node coloured `parent`: the root's
/// children are pure red, green and blue; deeper, the child's primary is
/// mixed with its parent's colour as the course's Color::mix(parent, 0.33)
/// does (a third of the primary, two thirds of the parent, truncated).
template <class T> Color BVH<T>::child_colour(const Color &parent, int child, bool parent_is_root) {
  const Color primary(child == 0 ? 255 : 0, child == 1 ? 255 : 0, child == 2 ? 255 : 0);
  if (parent_is_root) return primary;
  const float f = 0.33f;
  return Color(int(primary.r * f + parent.r * (1 - f)), int(primary.g * f + parent.g * (1 - f)),
               int(primary.b * f + parent.b * (1 - f)));
}

template <class T> void BVH<T>::render_recolor(std::ostream &ostr) {
  if (root_ == nullptr) return;
  std::vector<std::pair<Node *, Color> > stack(1, std::make_pair(root_, Color(128, 128, 128)));
  while (!stack.empty()) { // pre-order, with each node's colour
    Node *node = stack.back().first;
    const Color colour = stack.back().second;
    stack.pop_back();
    node->box.render(ostr, colour);
    for (std::size_t i = 0; i < node->shapes.size(); ++i) node->shapes[i].setColor(colour);
    for (int c = node->num_children - 1; c >= 0; --c)
      stack.push_back(std::make_pair(node->children[c], child_colour(colour, c, node == root_)));
  }
}

// ===========================================================================
// Erase (extra credit)
// ===========================================================================

/// How many shapes come before `pos` in iteration order: its index in its
/// leaf plus the counts of every subtree to the left of its path. O(depth).
template <class T> std::size_t BVH<T>::rank_of(const iterator &pos) {
  std::size_t rank = pos.index_;
  for (const Node *n = pos.leaf_; n->parent != nullptr; n = n->parent)
    for (int c = 0, me = index_in_parent(n); c < me; ++c) rank += n->parent->children[c]->count;
  return rank;
}

/// The iterator to the shape of rank `rank` (end() past the last): down
/// from the root by the counts, as in an order-statistics tree. O(depth).
template <class T> typename BVH<T>::iterator BVH<T>::iterator_at(std::size_t rank) const {
  if (rank >= size()) return end();
  const Node *node = root_;
  while (!node->is_leaf()) {
    int c = 0;
    while (rank >= node->children[c]->count) rank -= node->children[c++]->count;
    node = node->children[c];
  }
  return iterator(this, node, rank);
}

/// After a shape left `leaf` (counts and boxes already refitted): rebuilds
/// the highest ancestor that should now be a leaf (at most split_threshold
/// shapes), or else the parent of a leaf left empty, in iteration order.
/// Returns where the balance check starts (nullptr: the tree is empty).
template <class T> typename BVH<T>::Node *BVH<T>::mend_after_erase(Node *leaf) {
  if (root_->count == 0) {
    destroy_tree(root_);
    root_ = nullptr;
    return nullptr;
  }
  Node *mend = nullptr;
  for (Node *n = leaf->parent; n != nullptr; n = n->parent)
    if (stays_leaf(n->count, n->depth)) mend = n;
  if (mend == nullptr && leaf->count == 0) mend = leaf->parent;
  if (mend == nullptr) return leaf;
  rebuild(mend, Cut::in_order);
  return mend;
}

/// Rebuilds, in iteration order, the highest node at or above `from` whose
/// largest child holds more than kLopsided of its shapes (and which holds
/// at least min_rebuild()). O(depth) plus the rebuild.
template <class T> void BVH<T>::rebalance_after_erase(Node *from) {
  Node *scapegoat = nullptr;
  for (Node *n = from; n != nullptr; n = n->parent) {
    std::size_t heaviest = 0;
    for (int c = 0; c < n->num_children; ++c) heaviest = std::max(heaviest, n->children[c]->count);
    if (n->count >= min_rebuild() && lopsided(heaviest, n->count)) scapegoat = n;
  }
  if (scapegoat != nullptr) rebuild(scapegoat, Cut::in_order);
}

/// See ERASE at the top of this file. `pos` must point at a shape.
template <class T> typename BVH<T>::iterator BVH<T>::erase(iterator pos) {
  const std::size_t rank = rank_of(pos); // the next shape will have this rank
  Node *leaf = const_cast<Node *>(pos.leaf_);
  leaf->shapes.erase(leaf->shapes.begin() + std::ptrdiff_t(pos.index_));
  for (Node *n = leaf; n != nullptr; n = n->parent) {
    --n->count;
    fit(n); // boxes only shrink from their children: refit up to the root
  }
  Node *changed = mend_after_erase(leaf);
  if (changed != nullptr) rebalance_after_erase(changed);
  return iterator_at(rank);
}

#endif
