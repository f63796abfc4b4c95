// bvh.h — BVH<T>: a ternary bounding volume hierarchy over 2D shapes
// (Disk, Triangle, Quad from shapes.h), built in bulk or one shape at a time,
// answering "does this shape touch anything stored?" exactly.
//
//   BVH<Disk> tree(/*split_threshold=*/4, /*depth_limit=*/0);  // 0: unlimited
//   tree.construct(disks);                   // bulk build, the course's rule
//   for (const Disk &d : more) if (!tree.collision(d)) tree.insert(d);
//   for (const Disk &d : tree) std::cout << d.getBox() << "\n";
//   tree.statistics(/*print_tree=*/true);    // the course's report, to stdout
//
// Complexity (n shapes): construct O(n log n) (selection, not sorting, at
// every level); insert O(depth) plus an O(k log k) leaf split; collision
// O(log n + hits) on a balanced tree; iteration O(1) amortised per step;
// copy, destruction and every traversal are iterative (no recursion), so a
// degenerate, very deep tree cannot overflow the stack.
//
// Where to look: the build rule is `build_subtree`, the incremental
// insertion strategy is `choose_child` (one replaceable place), the
// intersection predicates are in intersect.h.
#ifndef BVH_BVH_H
#define BVH_BVH_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "intersect.h"
#include "shapes.h"

namespace bvh_detail {

/// A stack of node indices that lives on the call stack until it outgrows
/// its inline space: traversals of shallow trees never allocate, deep ones
/// still work.
class IndexStack {
public:
  void push(int v) {
    if (size_ < kInline) {
      inline_[size_++] = v;
    } else {
      spill_.push_back(v);
      ++size_;
    }
  }
  int pop() {
    --size_;
    if (size_ < kInline) return inline_[size_];
    int v = spill_.back();
    spill_.pop_back();
    return v;
  }
  bool empty() const { return size_ == 0; }

private:
  static constexpr std::size_t kInline = 96;
  int inline_[kInline];
  std::size_t size_ = 0;
  std::vector<int> spill_;
};

} // namespace bvh_detail

/// A ternary bounding volume hierarchy over shapes of type T.
///
/// T needs `getBox()`, `getCenter()`, `setColor()` and a free
/// `intersect(const T&, const T&)`. Shapes live only in leaves, each exactly
/// once; every node holds the tight box of its subtree.
template <class T> class BVH {
  struct Node;

public:
  /// `depth_limit` value meaning "no limit" (the course's default of 0).
  static constexpr int unlimited = 0;

  /// An empty tree. A node holding more than `split_threshold` (>= 1)
  /// shapes is split unless it is at depth `depth_limit` (root = depth 0;
  /// `depth_limit <= 0` means unlimited).
  explicit BVH(int split_threshold = 4, int depth_limit = unlimited)
      : split_threshold_(split_threshold < 1 ? 1 : split_threshold),
        depth_limit_(depth_limit <= 0 ? unlimited : depth_limit) {}

  // Copying and destruction are the defaults: the nodes and their shapes
  // live in vectors, so copies are deep and independent, and no recursion
  // is involved however deep the tree. Moves are written out only so that
  // the moved-from tree is a valid empty tree.

  /// Deep copy.
  BVH(const BVH &) = default;
  /// Deep copy; self-assignment is safe.
  BVH &operator=(const BVH &) = default;
  /// Takes `other`'s shapes; `other` is left empty (same parameters).
  BVH(BVH &&other) noexcept
      : nodes_(std::move(other.nodes_)), root_(other.root_), size_(other.size_),
        split_threshold_(other.split_threshold_), depth_limit_(other.depth_limit_) {
    other.clear();
  }
  /// Takes `other`'s shapes and parameters; `other` is left empty.
  BVH &operator=(BVH &&other) noexcept {
    if (this != &other) {
      nodes_ = std::move(other.nodes_);
      root_ = other.root_;
      size_ = other.size_;
      split_threshold_ = other.split_threshold_;
      depth_limit_ = other.depth_limit_;
      other.clear();
    }
    return *this;
  }
  ~BVH() = default;

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

    /// The shape it points to.
    reference operator*() const { return tree_->nodes_[leaf_].shapes[index_]; }
    /// Member access on the shape it points to.
    pointer operator->() const { return &**this; }

    /// Next shape (end() after the last).
    iterator &operator++() {
      if (++index_ == tree_->nodes_[leaf_].shapes.size()) {
        leaf_ = tree_->next_leaf(leaf_);
        index_ = 0;
      }
      return *this;
    }
    /// Previous shape (from end(): the last shape).
    iterator &operator--() {
      if (leaf_ < 0) {
        leaf_ = tree_->last_leaf();
        index_ = tree_->nodes_[leaf_].shapes.size() - 1;
      } else if (index_ > 0) {
        --index_;
      } else {
        leaf_ = tree_->prev_leaf(leaf_);
        index_ = tree_->nodes_[leaf_].shapes.size() - 1;
      }
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
    const BVH *tree_ = nullptr;
    int leaf_ = -1; // -1: end()
    std::size_t index_ = 0;
  };
  /// The same iterator: shapes are never writable through iteration.
  using const_iterator = iterator;

  /// First shape in leaf order (end() when empty).
  iterator begin() const { return root_ < 0 ? end() : iterator(this, leftmost_leaf(root_), 0); }
  /// One past the last shape.
  iterator end() const { return iterator(this, -1, 0); }

  /// Number of stored shapes.
  std::size_t size() const { return size_; }
  /// True when no shape is stored.
  bool empty() const { return size_ == 0; }
  /// The split threshold given at construction (at least 1).
  int split_threshold() const { return split_threshold_; }
  /// The depth limit (`unlimited`, i.e. 0, for none).
  int depth_limit() const { return depth_limit_; }
  /// The box of everything stored (an empty box when empty).
  BoundingBox bounds() const { return root_ < 0 ? BoundingBox() : nodes_[root_].box; }

  /// Removes every shape.
  void clear() {
    nodes_.clear();
    root_ = -1;
    size_ = 0;
  }

  /// Replaces the contents with `elements`, built top-down by the course's
  /// rule (see build_subtree).
  void construct(const std::vector<T> &elements) {
    clear();
    if (elements.empty()) return;
    root_ = new_node(0, -1, 0);
    size_ = elements.size();
    build_subtree(root_, std::vector<T>(elements));
  }

  /// Adds one shape: descend by least area growth, add to that leaf, split
  /// the leaf by the bulk rule when it holds more than split_threshold
  /// shapes and may still grow deeper. Boxes are kept tight on the way.
  void insert(const T &shape) {
    const BoundingBox box = shape.getBox();
    ++size_;
    if (root_ < 0) {
      root_ = new_node(0, -1, 0);
      nodes_[root_].box = box;
      nodes_[root_].shapes.push_back(shape);
      return;
    }
    int n = root_;
    for (;;) {
      nodes_[n].box.extend(box);
      if (nodes_[n].is_leaf()) break;
      n = choose_child(n, box);
    }
    Node &leaf = nodes_[n];
    leaf.shapes.push_back(shape);
    if (int(leaf.shapes.size()) > split_threshold_ && may_split_at(leaf.depth)) {
      std::vector<T> shapes = std::move(leaf.shapes);
      leaf.shapes.clear();
      build_subtree(n, std::move(shapes));
    }
  }

  /// True iff some stored shape intersects `shape` (touching counts).
  /// Subtrees whose box misses the shape's box are never visited; the final
  /// test is the exact predicate of intersect.h.
  bool collision(const T &shape) const {
    if (root_ < 0) return false;
    const BoundingBox box = shape.getBox();
    bvh_detail::IndexStack stack;
    stack.push(root_);
    while (!stack.empty()) {
      const Node &node = nodes_[stack.pop()];
      if (!node.box.overlaps(box)) continue;
      if (node.is_leaf()) {
        for (const T &s : node.shapes)
          if (s.getBox().overlaps(box) && intersect(s, shape)) return true;
      } else {
        for (int c = node.num_children - 1; c >= 0; --c) stack.push(node.child[c]);
      }
    }
    return false;
  }

  /// The course's report on stdout: with `print_tree`, one line per node in
  /// pre-order, then node count, max depth and the two area sums of the
  /// surface area heuristic (areas in units of the 1000x1000 canvas).
  void statistics(bool print_tree) const { statistics(std::cout, print_tree); }

  /// The same report, to any stream.
  void statistics(std::ostream &ostr, bool print_tree) const {
    long node_count = 0;
    int max_depth = 0;
    double inner_area = 0, leaf_area = 0;
    std::string line;
    char buf[64];
    for_each_preorder([&](int n) {
      const Node &node = nodes_[n];
      const double area = node.box.getArea() / kCanvasArea;
      ++node_count;
      max_depth = std::max(max_depth, node.depth);
      if (node.is_leaf())
        leaf_area += area * double(node.shapes.size());
      else
        inner_area += area;
      if (!print_tree) return;
      // The course's stream is not yet in fixed mode when it prints the
      // root, so the root's area shows 3 significant digits, the rest 3
      // decimals.
      std::snprintf(buf, sizeof buf, n == root_ ? "%.3g" : "%.3f", area);
      line.assign(std::size_t(3) * std::size_t(node.depth), ' ');
      ostr << line << (node.is_leaf() ? "leaf area=" : "inner area=") << buf << " " << node.box;
      if (node.is_leaf()) {
        ostr << " elements:";
        for (const T &s : node.shapes) ostr << " " << s.getBox();
      }
      ostr << "\n";
    });
    std::snprintf(buf, sizeof buf, "node count:      %7ld\n", node_count);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "max depth:       %7d\n", max_depth);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "inner node area: %7.3f\n", inner_area);
    ostr << buf;
    std::snprintf(buf, sizeof buf, "leaf node area:  %7.3f\n", leaf_area);
    ostr << buf;
    ostr.flush();
  }

  /// Draws every node's box translucently (root grey, its children red,
  /// green and blue, deeper children blended 2/3 parent and 1/3 their own
  /// primary) and recolours every shape to the colour of its leaf.
  void render_recolor(std::ostream &ostr) {
    if (root_ < 0) return;
    static const Color primary[3] = {Color(255, 0, 0), Color(0, 255, 0), Color(0, 0, 255)};
    std::vector<Color> color(nodes_.size());
    color[root_] = Color(128, 128, 128);
    for_each_preorder([&](int n) {
      Node &node = nodes_[n];
      if (node.parent >= 0)
        color[n] = node.parent == root_ ? primary[node.slot]
                                        : color[node.parent].mix(primary[node.slot], 2.0f / 3.0f);
      node.box.render(ostr, color[n]);
      for (T &s : node.shapes) s.setColor(color[n]);
    });
  }

  /// Checks every invariant; on failure returns false and, when `why` is
  /// given, says which node broke what. Meant for tests: O(n log n).
  bool validate(std::string *why = nullptr) const {
    auto fail = [&](int n, const std::string &what) {
      if (why) *why = "node " + std::to_string(n) + ": " + what;
      return false;
    };
    if (root_ < 0) {
      if (size_ != 0) return fail(-1, "empty tree with size " + std::to_string(size_));
      return true;
    }
    std::size_t counted = 0, reached = 0;
    bool ok = true;
    for_each_preorder([&](int n) {
      if (!ok) return;
      ++reached;
      const Node &node = nodes_[n];
      BoundingBox tight;
      if (n == root_) {
        if (node.parent != -1 || node.depth != 0) ok = fail(n, "root has a parent or depth != 0");
      } else {
        const Node &p = nodes_[node.parent];
        if (node.depth != p.depth + 1) ok = fail(n, "depth is not parent's + 1");
        if (node.slot < 0 || node.slot >= p.num_children || p.child[node.slot] != n)
          ok = fail(n, "parent does not list it in its slot");
      }
      if (depth_limit_ != unlimited && node.depth > depth_limit_) ok = fail(n, "deeper than depth_limit");
      if (node.is_leaf()) {
        if (node.shapes.empty()) ok = fail(n, "empty leaf");
        if (int(node.shapes.size()) > split_threshold_ && may_split_at(node.depth))
          ok = fail(n, "leaf over split_threshold above depth_limit");
        for (const T &s : node.shapes) tight.extend(s.getBox());
        counted += node.shapes.size();
      } else {
        if (!node.shapes.empty()) ok = fail(n, "inner node holds shapes");
        if (node.num_children < 2) ok = fail(n, "inner node with fewer than 2 children");
        if (node.num_children == 2 && split_threshold_ != 1)
          ok = fail(n, "2 children although split_threshold > 1");
        for (int c = 0; c < node.num_children; ++c) tight.extend(nodes_[node.child[c]].box);
      }
      if (ok && tight != node.box) ok = fail(n, "box is not the tight box of its subtree");
    });
    if (!ok) return false;
    if (reached != nodes_.size()) return fail(root_, "unreachable nodes in storage");
    if (counted != size_) return fail(root_, "size() disagrees with the shapes stored");
    return true;
  }

  /// Depth of the deepest node (0 for a single leaf or an empty tree).
  int height() const {
    int h = 0;
    for (const Node &n : nodes_) h = std::max(h, n.depth);
    return h;
  }

  /// Number of nodes, inner and leaf.
  std::size_t node_count() const { return nodes_.size(); }

private:
  // Areas are reported relative to the course's 1000 x 1000 canvas.
  static constexpr double kCanvasArea = 1000.0 * 1000.0;

  struct Node {
    BoundingBox box;
    int depth = 0;
    int parent = -1;      // -1 for the root
    int slot = 0;         // index in the parent's child[]
    int num_children = 0; // 0: leaf
    int child[3] = {-1, -1, -1};
    std::vector<T> shapes; // leaves only, in leaf order
    bool is_leaf() const { return num_children == 0; }
  };

  bool may_split_at(int depth) const { return depth_limit_ == unlimited || depth < depth_limit_; }

  int new_node(int depth, int parent, int slot) {
    nodes_.emplace_back();
    Node &n = nodes_.back();
    n.depth = depth;
    n.parent = parent;
    n.slot = slot;
    return int(nodes_.size()) - 1;
  }

  /// The insertion strategy: the child whose box grows least in area when
  /// it takes `box`; ties go to the smaller child, then the first.
  int choose_child(int n, const BoundingBox &box) const {
    const Node &node = nodes_[n];
    int best = node.child[0];
    double best_growth = 0, best_area = 0;
    for (int c = 0; c < node.num_children; ++c) {
      const BoundingBox &cb = nodes_[node.child[c]].box;
      BoundingBox grown = cb;
      grown.extend(box);
      const double area = cb.getArea(), growth = grown.getArea() - area;
      if (c == 0 || growth < best_growth || (growth == best_growth && area < best_area)) {
        best = node.child[c];
        best_growth = growth;
        best_area = area;
      }
    }
    return best;
  }

  /// The build rule (the course's, which its expected output follows). A
  /// node with n shapes is a leaf when n <= split_threshold or it is at
  /// depth_limit. Otherwise its shapes are ordered by their centre on the
  /// longer side of its box (x when dx >= dy), ties kept in their current
  /// order, and cut into 3 consecutive groups whose sizes differ by at most
  /// one, larger groups first; empty groups are dropped. A leaf keeps its
  /// shapes in its parent's order.
  ///
  /// Doing this with a stable sort at every node costs O(n log^2 n). The
  /// same groups come from selection (nth_element) if the comparison is a
  /// strict total order equal to the stable one. The stable order at a node
  /// compares centres on its axis, then on its parent's axis, its
  /// grandparent's, ..., then the input position; with only two axes, every
  /// repeat of an axis in that chain compares coordinates already found
  /// equal, so the chain shrinks to (this axis, the other axis if any
  /// ancestor used it, input position). Selection gives O(n log n) overall.
  ///
  /// Builds in place at leaf `at` (depth taken from it) from `shapes`,
  /// whose order is the "input position" for ties.
  void build_subtree(int at, std::vector<T> &&shapes) {
    const std::size_t count = shapes.size();
    std::vector<Point> center(count);
    std::vector<BoundingBox> box(count);
    std::vector<std::uint32_t> order(count);
    for (std::size_t i = 0; i < count; ++i) {
      center[i] = shapes[i].getCenter();
      box[i] = shapes[i].getBox();
      order[i] = std::uint32_t(i);
    }
    struct Key { // the order of one node: see above
      const std::vector<Point> *center;
      int axis;       // 0: x, 1: y
      bool other_too; // compare the other axis before the input position
      bool operator()(std::uint32_t a, std::uint32_t b) const {
        const Point &p = (*center)[a], &q = (*center)[b];
        const double pa = axis == 0 ? p.x : p.y, qa = axis == 0 ? q.x : q.y;
        if (pa != qa) return pa < qa;
        if (other_too) {
          const double po = axis == 0 ? p.y : p.x, qo = axis == 0 ? q.y : q.x;
          if (po != qo) return po < qo;
        }
        return a < b;
      }
    };
    struct Task {
      int node;
      std::size_t begin, end;
      unsigned axes_used; // bit 0: x, bit 1: y, by the node's ancestors
      Key parent_key;     // the order the node's shapes arrive in
      bool has_parent_key;
    };
    std::vector<Task> tasks;
    tasks.push_back({at, 0, count, 0u, Key{&center, 0, false}, false});
    while (!tasks.empty()) {
      const Task t = tasks.back();
      tasks.pop_back();
      BoundingBox node_box;
      for (std::size_t i = t.begin; i < t.end; ++i) node_box.extend(box[order[i]]);
      nodes_[t.node].box = node_box;
      const std::size_t n = t.end - t.begin;
      const int depth = nodes_[t.node].depth;
      if (n <= std::size_t(split_threshold_) || !may_split_at(depth)) {
        // Selection left the range unordered; restore the parent's order.
        if (t.has_parent_key) std::sort(order.begin() + t.begin, order.begin() + t.end, t.parent_key);
        else std::sort(order.begin() + t.begin, order.begin() + t.end);
        std::vector<T> &leaf = nodes_[t.node].shapes;
        leaf.reserve(n);
        for (std::size_t i = t.begin; i < t.end; ++i) leaf.push_back(std::move(shapes[order[i]]));
        continue;
      }
      const int axis = node_box.dx() >= node_box.dy() ? 0 : 1;
      const Key key{&center, axis, (t.axes_used & (2u >> axis)) != 0};
      const std::size_t base = n / 3, extra = n % 3;
      std::size_t cut[4];
      cut[0] = t.begin;
      for (int g = 0; g < 3; ++g) cut[g + 1] = cut[g] + base + (std::size_t(g) < extra ? 1 : 0);
      std::nth_element(order.begin() + cut[0], order.begin() + cut[1], order.begin() + cut[3], key);
      std::nth_element(order.begin() + cut[1], order.begin() + cut[2], order.begin() + cut[3], key);
      int children = 0;
      int child_index[3];
      for (int g = 0; g < 3; ++g) {
        if (cut[g + 1] == cut[g]) continue;
        child_index[children] = new_node(depth + 1, t.node, children);
        nodes_[t.node].child[children] = child_index[children];
        ++children;
      }
      nodes_[t.node].num_children = children;
      // Push in reverse so children are processed left to right.
      int pushed = children;
      for (int g = 2; g >= 0; --g) {
        if (cut[g + 1] == cut[g]) continue;
        --pushed;
        tasks.push_back({child_index[pushed], cut[g], cut[g + 1], t.axes_used | (1u << axis), key, true});
      }
    }
  }

  /// Calls f(node index) on every node in pre-order (children left to right).
  template <class F> void for_each_preorder(F &&f) const {
    if (root_ < 0) return;
    bvh_detail::IndexStack stack;
    stack.push(root_);
    while (!stack.empty()) {
      const int n = stack.pop();
      f(n);
      const Node &node = nodes_[n];
      for (int c = node.num_children - 1; c >= 0; --c) stack.push(node.child[c]);
    }
  }
  template <class F> void for_each_preorder(F &&f) {
    static_cast<const BVH &>(*this).for_each_preorder(std::forward<F>(f));
  }

  int leftmost_leaf(int n) const {
    while (!nodes_[n].is_leaf()) n = nodes_[n].child[0];
    return n;
  }
  int rightmost_leaf(int n) const {
    while (!nodes_[n].is_leaf()) n = nodes_[n].child[nodes_[n].num_children - 1];
    return n;
  }
  int last_leaf() const { return rightmost_leaf(root_); }
  /// The leaf after `n` in left-to-right order, -1 after the last.
  int next_leaf(int n) const {
    while (n != root_) {
      const Node &p = nodes_[nodes_[n].parent];
      const int slot = nodes_[n].slot;
      if (slot + 1 < p.num_children) return leftmost_leaf(p.child[slot + 1]);
      n = nodes_[n].parent;
    }
    return -1;
  }
  /// The leaf before `n` (undefined before the first, as for any iterator).
  int prev_leaf(int n) const {
    while (n != root_) {
      const Node &p = nodes_[nodes_[n].parent];
      const int slot = nodes_[n].slot;
      if (slot > 0) return rightmost_leaf(p.child[slot - 1]);
      n = nodes_[n].parent;
    }
    return -1;
  }

  std::vector<Node> nodes_;
  int root_ = -1;
  std::size_t size_ = 0;
  int split_threshold_;
  int depth_limit_;
};

#endif // BVH_BVH_H
