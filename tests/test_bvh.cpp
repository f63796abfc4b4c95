// tests/test_bvh.cpp — CourseBVH<T> against brute-force models: the bulk build
// against a literal (stable-sort, recursive) rendering of the course's rule,
// collision() and discard-overlap sampling against O(n^2) scans, iterators,
// copies and moves, validate() after every build and insert, deep trees.
//
// Seeds: BVH_SEED (default 12345) and BVH_TEST_SCALE (default 1; larger
// runs more random cases, 0.1 is for valgrind). Every randomized case prints
// its seed and case number with any failure.
// Collision searches of the wide trees decide disks from their leaves'
// codes at every size here (codes_at_every_size, tests/check.h: the
// library's default starts at 4 MB of disks), so that the model tests
// check those decisions.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <limits>
#include <new>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "check.h"
#include "scenes.h"

#if __cplusplus >= 202002L
#include <iterator>
static_assert(std::bidirectional_iterator<CourseBVH<Disk>::iterator>);
static_assert(std::bidirectional_iterator<CourseBVH<Triangle>::iterator>);
static_assert(std::bidirectional_iterator<CourseBVH<Quad>::iterator>);
static_assert(std::bidirectional_iterator<CourseBVH<Shape>::iterator>);
#endif

namespace {

std::string seed_note(unsigned seed, int round) {
  return "BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
}

// ---------------------------------------------------------------------------
// A literal, recursive rendering of the course's rule and report, written
// independently of bvh.h (std::stable_sort at every node, iostream
// formatting as the course's stream would do it). Used only on small trees.

struct RefStats {
  int nodes = 0, max_depth = 0;
  double inner = 0, leaf = 0;
};

std::string box_text(const BoundingBox &b) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1) << "[<" << std::setw(5) << b.getMin().x << " " << std::setw(5)
    << b.getMin().y << "> <" << std::setw(5) << b.getMax().x << " " << std::setw(5) << b.getMax().y << ">]";
  return s.str();
}

template <class T>
void ref_build(std::vector<T> shapes, int depth, int k, int limit, std::ostringstream &out, RefStats &st) {
  BoundingBox box;
  for (const T &s : shapes) box.extend(s.getBox());
  const double area = box.getArea() / 1e6;
  ++st.nodes;
  st.max_depth = std::max(st.max_depth, depth);
  out << std::string(std::size_t(3 * depth), ' ');
  std::ostringstream a;
  if (depth == 0)
    a << std::setprecision(3) << area; // the root: the stream is not fixed yet
  else
    a << std::fixed << std::setprecision(3) << area;
  const bool leaf = int(shapes.size()) <= k || (limit > 0 && depth == limit);
  if (leaf) {
    st.leaf += area * double(shapes.size());
    out << "leaf area=" << a.str() << " " << box_text(box) << " elements:";
    for (const T &s : shapes) out << " " << box_text(s.getBox());
    out << "\n";
    return;
  }
  st.inner += area;
  out << "inner area=" << a.str() << " " << box_text(box) << "\n";
  const bool by_x = box.dx() >= box.dy();
  std::stable_sort(shapes.begin(), shapes.end(), [by_x](const T &p, const T &q) {
    return by_x ? p.getCenter().x < q.getCenter().x : p.getCenter().y < q.getCenter().y;
  });
  const std::size_t n = shapes.size();
  std::size_t begin = 0;
  for (std::size_t g = 0; g < 3; ++g) {
    const std::size_t size = n / 3 + (g < n % 3 ? 1 : 0);
    if (size == 0) continue;
    ref_build(std::vector<T>(shapes.begin() + long(begin), shapes.begin() + long(begin + size)), depth + 1, k,
              limit, out, st);
    begin += size;
  }
}

template <class T> std::string ref_report(const std::vector<T> &shapes, int k, int limit) {
  std::ostringstream out;
  RefStats st;
  if (!shapes.empty()) ref_build(shapes, 0, k, limit, out, st);
  char buf[256];
  std::snprintf(buf, sizeof buf, "node count:      %7d\nmax depth:       %7d\ninner node area: %7.3f\nleaf node area:  %7.3f\n",
                st.nodes, st.max_depth, st.inner, st.leaf);
  return out.str() + buf;
}

template <class T> std::string report(const CourseBVH<T> &tree) {
  std::ostringstream out;
  tree.statistics(out, true);
  return out.str();
}

template <class T> bool brute_collision(const std::vector<T> &kept, const T &s) {
  for (const T &k : kept)
    if (model_intersect(k, s)) return true;
  return false;
}

template <class T> void check_build_against_reference(unsigned seed) {
  const int rounds = scaled(150);
  for (int round = 0; round < rounds; ++round) {
    note(seed_note(seed, round));
    Maker make(seed + unsigned(round) * 7919u, round % 3 == 0 ? 50.0 : (round % 3 == 1 ? 0.5 : 0.0));
    const int n = int(make.rng() % 200);
    const int k = 1 + int(make.rng() % 6);
    const int limit = int(make.rng() % 7); // 0: unlimited
    const std::vector<T> shapes = make.template scene<T>(n, 40);
    CourseBVH<T> tree(k, limit);
    tree.construct(shapes);
    std::string why;
    CHECK(tree.validate(&why));
    if (!why.empty()) note(seed_note(seed, round) + " " + why);
    CHECK_EQ(tree.size(), shapes.size());
    CHECK(report(tree) == ref_report(shapes, k, limit));
    CHECK(same_multiset(contents(tree), shapes));
  }
}

// validate() itself: every other test trusts it to notice a broken tree,
// so each kind of damage, done by hand to a copy of a sound tree, must be
// reported, with the node and what it broke.
template <int W> void validate_catches(unsigned seed) {
  using Core = bvh::detail::Core<Disk, bvh::shape_traits<Disk>, W>;
  Maker make(seed);
  Core sound(bvh::shape_traits<Disk>(), W == 8 ? 16 : 4, 0);
  bvh::detail::construct(sound, make.scene<Disk>(300, 20));
  std::string why;
  CHECK(bvh::detail::validate(sound, &why));
  const int root = sound.root, child = sound.nodes.node(root).child(1);
  const int leaf = sound.nodes.leftmost_leaf(root);
  const auto expect = [&](const std::string &damage, const std::string &message, auto &&harm) {
    Core broken = sound;
    harm(broken);
    std::string said;
    note("width " + std::to_string(W) + ": " + damage);
    CHECK(!bvh::detail::validate(broken, &said));
    CHECK(said.find(message) != std::string::npos);
    if (said.find(message) == std::string::npos) note("said: " + said);
  };
  expect("a count one too many", "shape count is not its subtree's",
         [&](Core &c) { c.nodes.info(child).count += 1; });
  expect("a depth off by one", "depth is not parent's + 1", [&](Core &c) { c.nodes.info(child).depth += 1; });
  expect("the parent's float copy of a box", "parent's float box for it",
         [&](Core &c) { c.nodes.node(root).lo_x[1] -= 1.0f; });
  expect("a child index", "parent does not list it", [&](Core &c) { c.nodes.info(child).child_index = 0; });
  expect("the root given a parent", "root has a parent", [&](Core &c) { c.nodes.info(root).parent = child; });
  expect("a leaf's box larger than its shapes'", "tight box", [&](Core &c) {
    bvh::detail::Box b = c.nodes.box(leaf);
    b.x1 += 1;
    c.nodes.set_box(leaf, b);
  });
  expect("size() one too many", "size() disagrees", [&](Core &c) { c.size += 1; });
  if (bvh::detail::Node<W>::kCoded > 0 && sound.nodes.node(leaf).coded() > 0) {
    expect("a leaf summary's code", "not its own box's", [&](Core &c) {
      c.nodes.node(leaf).set_codes(0, 0); // the code box of one corner
    });
    // A code box that holds the shape's box but is larger (as one made from
    // a margin-widened box is): queries would read a disk there as larger.
    expect("a leaf summary's code one step too wide", "not its own box's", [&](Core &c) {
      bvh::detail::Node<W> &node = c.nodes.node(leaf);
      const std::uint32_t k = node.codes(0);
      const std::uint32_t lx = k & 255u, hx = k >> 16 & 255u;
      node.set_codes(0, lx > 0 ? k - 1 : hx < 255 ? k + (1u << 16) : k ^ 1u);
    });
  } else
    CHECK(W < 4); // (at widths 4 and 8 the leaf must have a summary to damage)
}
TEST(validate_reports_each_kind_of_damage) {
  validate_catches<3>(base_seed() + 17);
  validate_catches<8>(base_seed() + 18);
}

} // namespace

// ---------------------------------------------------------------------------

TEST(course_example_matches_the_handout_shape) {
  // The handout's 36-triangle example, rebuilt from its own rule: 13 nodes,
  // depth 2, nine leaves of four.
  Maker make(base_seed());
  const std::vector<Triangle> shapes = make.scene<Triangle>(36, 40);
  CourseBVH<Triangle> tree(4, 2);
  tree.construct(shapes);
  CHECK(tree.validate());
  CHECK_EQ(tree.node_count(), std::size_t(13));
  CHECK_EQ(tree.height(), 2);
}

// The two configurations (defaults.h): BVH<T> is the default, width 8 and
// 32 shapes a leaf; CourseBVH<T> the course's, width 3 and 4; BVHOfWidth
// another width with the default traits. A default tree is the explicit
// width-8, k-32 tree node for node, and answers as a scan does.
static_assert(std::is_same<BVH<Disk>, BVH<Disk, bvh::shape_traits<Disk>, 8>>::value, "BVH<T> is width 8");
static_assert(std::is_same<CourseBVH<Triangle>, BVH<Triangle, bvh::shape_traits<Triangle>, 3>>::value,
              "CourseBVH<T> is width 3");
static_assert(std::is_same<BVHOfWidth<Quad, 4>, BVH<Quad, bvh::shape_traits<Quad>, 4>>::value, "BVHOfWidth<T, 4>");
TEST(default_tree_is_width_8_split_32_and_the_course_tree_is_named) {
  CHECK(BVH<Disk>().split_threshold() == 32);
  CHECK(BVH<Disk>::default_split == bvh::default_split_threshold);
  CHECK(CourseBVH<Disk>().split_threshold() == 4);
  CHECK((BVHOfWidth<Disk, 4>().split_threshold() == 32));
  CHECK((BVHOfWidth<Disk, 3>().split_threshold() == 4));
  const unsigned seed = base_seed() + 31;
  note("BVH_SEED=" + std::to_string(seed));
  Maker make(seed);
  const std::vector<Disk> disks = make.scene<Disk>(scaled(3000) + 100, 20);
  BVH<Disk> fast;
  BVH<Disk, bvh::shape_traits<Disk>, 8> spelled(32);
  fast.construct(disks);
  spelled.construct(disks);
  CHECK(fast.validate());
  CHECK(std::equal(fast.begin(), fast.end(), spelled.begin(), spelled.end()));
  CourseBVH<Disk> course;
  course.construct(disks);
  CHECK(fast.height() == spelled.height() && fast.height() < course.height());
  for (int q = 0; q < 200; ++q) {
    const Disk probe = make.scene<Disk>(1, 30)[0];
    CHECK(fast.collision(probe) == brute_collision(disks, probe));
  }
}

TEST(bulk_build_equals_literal_course_rule_disks) { check_build_against_reference<Disk>(base_seed()); }
TEST(bulk_build_equals_literal_course_rule_triangles) { check_build_against_reference<Triangle>(base_seed() + 1); }
TEST(bulk_build_equals_literal_course_rule_quads) { check_build_against_reference<Quad>(base_seed() + 2); }
TEST(bulk_build_equals_literal_course_rule_mixed) { check_build_against_reference<Shape>(base_seed() + 3); }

// construct() lays nodes out from counts alone (bvh::detail::Layout) and
// builds subtrees on several threads for scenes of kParallelMin shapes or
// more: whatever the thread count, the tree must be the one-thread tree, and
// every node laid out must be used (validate() counts them).
// construct() on several threads (tests/test_threads.cpp compares thread
// counts, here and under ThreadSanitizer): once against the literal rule
// itself, at a size that uses threads.
TEST(threaded_build_equals_the_literal_course_rule) {
  if (scale() < 1) return; // the literal rule is slow at this size
  Maker make(base_seed() + 12, 2.0);
  const std::vector<Disk> disks = make.scene<Disk>(int(CourseBVH<Disk>::kParallelMin + 4321), 6);
  CourseBVH<Disk> tree(4, 0);
  tree.set_build_threads(2);
  tree.construct(disks);
  CHECK(report(tree) == ref_report(disks, 4, 0));
}

TEST(bulk_build_with_all_centres_equal) {
  // Every centre ties on both axes: the order must be the input order.
  std::vector<Disk> shapes;
  for (int i = 0; i < 40; ++i) shapes.push_back(Disk(Point(500, 500), 1 + i % 7, Color(i, 0, 0)));
  for (int k = 1; k <= 5; ++k) {
    CourseBVH<Disk> tree(k, 0);
    tree.construct(shapes);
    CHECK(tree.validate());
    CHECK(report(tree) == ref_report(shapes, k, 0));
  }
}

TEST(statistics_of_an_empty_tree) {
  CourseBVH<Quad> tree(4, 3);
  std::ostringstream out;
  tree.statistics(out, true);
  CHECK_EQ(out.str(), std::string("node count:            0\nmax depth:             0\n"
                                  "inner node area:   0.000\nleaf node area:    0.000\n"));
  tree.construct({});
  CHECK(tree.empty());
  CHECK(tree.validate());
}

TEST(root_area_prints_three_significant_digits) {
  // 900 x 1000 = 0.9 of the canvas: the course prints the root as "0.9".
  std::vector<Quad> q = {Quad(Point(0, 0), Point(900, 0), Point(900, 1000), Point(0, 1000), Color(1, 2, 3))};
  CourseBVH<Quad> tree(4, 2);
  tree.construct(q);
  std::ostringstream out;
  tree.statistics(out, true);
  CHECK(out.str().rfind("leaf area=0.9 [<  0.0   0.0> <900.0 1000.0>] elements:", 0) == 0);
}

TEST(iterators_on_empty_and_one_shape_trees) {
  const CourseBVH<Disk> empty_tree;
  CHECK(empty_tree.begin() == empty_tree.end());
  CHECK(!(empty_tree.begin() != empty_tree.end()));
  CourseBVH<Disk> one(4, 0);
  const Disk d(Point(1, 2), 3, Color(4, 5, 6));
  one.insert(d);
  CourseBVH<Disk>::iterator it = one.begin();
  CHECK(*it == d);
  CHECK_EQ(it->getRadius(), 3.0);
  CourseBVH<Disk>::iterator old = it++;
  CHECK(old == one.begin());
  CHECK(it == one.end());
  old = it--;
  CHECK(old == one.end());
  CHECK(it == one.begin());
  CHECK(--one.end() == one.begin());
  CHECK(++one.begin() == one.end());
}

TEST(iterators_walk_both_ways_over_every_shape) {
  const unsigned seed = base_seed();
  for (int round = 0; round < scaled(40); ++round) {
    note(seed_note(seed, round));
    Maker make(seed + unsigned(round));
    const int n = 1 + int(make.rng() % 300);
    const std::vector<Triangle> shapes = make.scene<Triangle>(n, 30);
    CourseBVH<Triangle> tree(1 + int(make.rng() % 5), int(make.rng() % 6));
    if (round % 2)
      tree.construct(shapes);
    else
      for (const Triangle &t : shapes) tree.insert(t);
    const CourseBVH<Triangle> &view = tree;
    std::vector<Triangle> forward, backward, post_forward, post_backward;
    for (CourseBVH<Triangle>::iterator it = view.begin(); it != view.end(); ++it) forward.push_back(*it);
    for (CourseBVH<Triangle>::iterator it = view.begin(); it != view.end(); it++) post_forward.push_back(*it);
    for (CourseBVH<Triangle>::iterator it = view.end(); it != view.begin();) backward.push_back(*--it);
    for (CourseBVH<Triangle>::iterator it = view.end(); it != view.begin();) {
      it--;
      post_backward.push_back(*it);
    }
    CHECK_EQ(forward.size(), std::size_t(n));
    CHECK(same_multiset(forward, shapes));
    CHECK(post_forward == forward);
    std::reverse(backward.begin(), backward.end());
    std::reverse(post_backward.begin(), post_backward.end());
    CHECK(backward == forward);
    CHECK(post_backward == forward);
    CHECK(*--view.end() == forward.back());
    // Post-increment returns the old position, pre-increment the new one.
    CourseBVH<Triangle>::iterator a = view.begin();
    CourseBVH<Triangle>::iterator b = a++;
    CHECK(b == view.begin());
    CourseBVH<Triangle>::iterator c = view.begin();
    CHECK(++c == a);
  }
}

TEST(copies_are_deep_and_independent) {
  Maker make(base_seed());
  const std::vector<Disk> shapes = make.scene<Disk>(100, 20);
  CourseBVH<Disk> original(3, 4);
  original.construct(shapes);
  const std::string before = report(original);
  CourseBVH<Disk> copy(original);
  CHECK(copy.validate());
  CHECK(report(copy) == before);
  copy.insert(Disk(Point(1, 1), 1, Color(0, 0, 0)));
  std::ostringstream picture;
  copy.render_recolor(picture); // recolours copy's shapes only
  CHECK(report(original) == before);
  CHECK(contents(original) != contents(copy));
  CHECK(same_multiset(contents(original), shapes));
  CourseBVH<Disk> assigned(9, 9);
  assigned = original;
  CHECK(assigned.validate());
  CHECK_EQ(assigned.split_threshold(), 3);
  CHECK(report(assigned) == before);
  original.clear();
  CHECK(report(assigned) == before);
}

TEST(self_assignment_is_harmless) {
  Maker make(base_seed());
  CourseBVH<Quad> tree(2, 0);
  tree.construct(make.scene<Quad>(50, 20));
  const std::string before = report(tree);
  CourseBVH<Quad> &alias = tree;
  tree = alias;
  CHECK(tree.validate());
  CHECK(report(tree) == before);
  tree = std::move(alias);
  CHECK(tree.validate());
  CHECK(report(tree) == before);
}

TEST(moves_leave_a_valid_empty_tree) {
  Maker make(base_seed());
  CourseBVH<Triangle> a(4, 3);
  a.construct(make.scene<Triangle>(60, 20));
  const std::string before = report(a);
  CourseBVH<Triangle> b(std::move(a));
  CHECK(report(b) == before);
  CHECK(a.empty());
  CHECK(a.validate());
  CHECK(a.begin() == a.end());
  a.insert(Triangle(Point(0, 0), Point(1, 0), Point(0, 1), Color(1, 1, 1)));
  CHECK(a.validate());
  CHECK_EQ(a.size(), std::size_t(1));
  CourseBVH<Triangle> c;
  c = std::move(b);
  CHECK(report(c) == before);
  CHECK(b.empty() && b.validate());
}

TEST(insert_keeps_every_invariant) {
  const unsigned seed = base_seed();
  for (int round = 0; round < scaled(30); ++round) {
    note(seed_note(seed, round));
    Maker make(seed + 31u * unsigned(round), round % 2 ? 10.0 : 0.0);
    const int k = 1 + int(make.rng() % 5), limit = int(make.rng() % 8);
    CourseBVH<Quad> tree(k, limit);
    const std::vector<Quad> shapes = make.scene<Quad>(1 + int(make.rng() % 250), 30);
    bool all_valid = true;
    std::string why;
    for (std::size_t i = 0; i < shapes.size(); ++i) {
      tree.insert(shapes[i]);
      if (all_valid && !tree.validate(&why)) {
        all_valid = false;
        note(seed_note(seed, round) + " after insert " + std::to_string(i) + ": " + why);
      }
      if (tree.size() != i + 1) all_valid = false;
    }
    CHECK(all_valid);
    CHECK(same_multiset(contents(tree), shapes));
    if (limit > 0) CHECK(tree.height() <= limit);
  }
}

template <class T> void check_collision_and_discard(unsigned seed, double size) {
  for (int round = 0; round < scaled(12); ++round) {
    note(seed_note(seed, round));
    Maker make(seed + 101u * unsigned(round), round % 3 == 0 ? 5.0 : 0.0);
    const std::vector<T> candidates = make.template scene<T>(scaled(400), size);
    CourseBVH<T> tree(1 + int(make.rng() % 6), int(make.rng() % 9));
    std::vector<T> kept; // the brute-force model
    int disagreements = 0;
    for (const T &s : candidates) {
      const bool fast = tree.collision(s), slow = brute_collision(kept, s);
      if (fast != slow) ++disagreements;
      if (!slow) {
        kept.push_back(s);
        tree.insert(s);
      }
    }
    CHECK_EQ(disagreements, 0);
    CHECK(tree.validate());
    CHECK(same_multiset(contents(tree), kept));
    // Probes against a finished bulk-built tree of everything.
    CourseBVH<T> bulk(1 + int(make.rng() % 6), int(make.rng() % 9));
    bulk.construct(candidates);
    const std::vector<T> probes = make.template scene<T>(scaled(200), size);
    int wrong = 0;
    for (const T &p : probes)
      if (bulk.collision(p) != brute_collision(candidates, p)) ++wrong;
    CHECK_EQ(wrong, 0);
  }
}

TEST(collision_and_discard_overlap_equal_brute_force_disks) { check_collision_and_discard<Disk>(base_seed(), 40); }
TEST(collision_and_discard_overlap_equal_brute_force_triangles) {
  check_collision_and_discard<Triangle>(base_seed() + 1, 40);
}
TEST(collision_and_discard_overlap_equal_brute_force_quads) {
  check_collision_and_discard<Quad>(base_seed() + 2, 30);
}
TEST(collision_and_discard_overlap_equal_brute_force_mixed) {
  check_collision_and_discard<Shape>(base_seed() + 3, 35);
}

TEST(touching_shapes_collide) {
  CourseBVH<Disk> tree(4, 0);
  tree.insert(Disk(Point(100, 100), 10, Color()));
  CHECK(tree.collision(Disk(Point(120, 100), 10, Color())));  // tangent
  CHECK(!tree.collision(Disk(Point(121, 100), 10, Color()))); // 1 apart
  CourseBVH<Quad> quads(4, 0);
  quads.insert(Quad(Point(0, 0), Point(10, 0), Point(10, 10), Point(0, 10), Color()));
  CHECK(quads.collision(Quad(Point(10, 0), Point(20, 0), Point(20, 10), Point(10, 10), Color()))); // shared edge
  CHECK(!quads.collision(Quad(Point(11, 0), Point(20, 0), Point(20, 10), Point(11, 10), Color())));
}

TEST(split_threshold_one_makes_binary_splits_of_two) {
  CourseBVH<Disk> tree(1, 0);
  for (int i = 0; i < 50; ++i) {
    tree.insert(Disk(Point(10.0 * i, 5.0 * (i % 7)), 2, Color()));
    CHECK(tree.validate());
  }
  CourseBVH<Disk> bulk(1, 0);
  bulk.construct(contents(tree));
  CHECK(bulk.validate());
  CHECK_EQ(bulk.size(), std::size_t(50));
}

TEST(deep_trees_do_not_recurse) {
  // Sorted input with no depth limit drives insert into a long spine; copy,
  // iteration, statistics, validate and destruction must all cope.
  CourseBVH<Disk> tree(1, 0);
  const int n = scaled(5000);
  for (int i = 0; i < n; ++i) tree.insert(Disk(Point(0.01 * i, 0.01 * i), 0.001, Color()));
  CHECK_EQ(tree.size(), std::size_t(n));
  CourseBVH<Disk> copy = tree;
  std::size_t walked = 0;
  for (CourseBVH<Disk>::iterator it = copy.begin(); it != copy.end(); ++it) ++walked;
  CHECK_EQ(walked, std::size_t(n));
  std::ostringstream sink;
  copy.statistics(sink, true);
  CHECK(copy.validate());
  CHECK(copy.collision(Disk(Point(0.01 * (n / 2), 0.01 * (n / 2)), 0, Color())));
}

TEST(sorted_insert_of_200k_shapes_stays_shallow) {
  // The issue's hostile case: 200,000 shapes inserted in sorted order, no
  // depth limit, the most nodes (split_threshold 1). Partial rebuilds keep
  // the height logarithmic, so nothing below is quadratic; the copy,
  // assignment, both iteration directions, statistics and destruction are
  // iterative, so nothing can overflow the stack either.
  const int n = scaled(200000);
  CourseBVH<Disk> tree(1, CourseBVH<Disk>::unlimited);
  for (int i = 0; i < n; ++i) tree.insert(Disk(Point(0.004 * i, 0.004 * i), 0.001, Color(i % 256, 0, 0)));
  CHECK_EQ(tree.size(), std::size_t(n));
  const double log3n = std::log(double(n)) / std::log(3.0);
  note("height " + std::to_string(tree.height()) + " for " + std::to_string(n) + " shapes");
  CHECK(tree.height() <= int(3 * log3n) + 2);
  CHECK(tree.validate());
  CourseBVH<Disk> copy(tree);
  CourseBVH<Disk> assigned(4, 3);
  assigned = copy;
  std::size_t forward = 0, backward = 0;
  for (CourseBVH<Disk>::iterator it = assigned.begin(); it != assigned.end(); ++it) ++forward;
  for (CourseBVH<Disk>::iterator it = assigned.end(); it != assigned.begin();) {
    --it;
    ++backward;
  }
  CHECK_EQ(forward, std::size_t(n));
  CHECK_EQ(backward, std::size_t(n));
  std::ostringstream sink;
  assigned.statistics(sink, true);
  CHECK(sink.str().size() > std::size_t(n));
  CourseBVH<Disk> moved(std::move(copy));
  CHECK(moved.validate());
  CHECK(copy.empty());
  CHECK(moved.collision(Disk(Point(0.004 * (n / 3), 0.004 * (n / 3)), 0, Color())));
  CHECK(!moved.collision(Disk(Point(0.004 * (n / 3) + 0.01, 0.004 * (n / 3) - 0.01), 0.001, Color())));
}

TEST(depth_limit_leaves_grow_without_splitting) {
  CourseBVH<Triangle> tree(2, 1);
  Maker make(base_seed());
  for (const Triangle &t : make.scene<Triangle>(100, 20)) tree.insert(t);
  CHECK(tree.validate());
  CHECK(tree.height() <= 1);
  CHECK_EQ(tree.size(), std::size_t(100));
}

// round_out (SSE2 unless BVH_NO_SIMD) against float_down and float_up, bit
// for bit: zeros, subnormals, the float range's ends, infinities, NaN, and
// random doubles of every magnitude and sign.
TEST(round_out_equals_float_down_and_float_up) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> v = {0.0, -0.0, 1e-300, -1e-300, 1e-46, -1e-46, 1.5e-45, -1.5e-45, 3e-39, -3e-39, 0.1, -0.1, 1.0,
                           -1.0, 16777217.0, -16777217.0, 3.4028235e38, -3.4028235e38, 3.5e38, -3.5e38, 1e300, -1e300,
                           inf, -inf, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::denorm_min(), -std::numeric_limits<double>::denorm_min()};
  std::mt19937_64 rng(base_seed());
  for (int i = 0; i < scaled(20000); ++i)
    v.push_back(std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng), int(rng() % 300) - 150));
  int wrong = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double a = v[i], b = v[(i * 7 + 3) % v.size()], c = v[(i * 13 + 5) % v.size()], d = v[(i * 17 + 1) % v.size()];
    float got[4];
    bvh::detail::round_out(bvh::detail::Box{a, b, c, d}, got);
    const float want[4] = {bvh::detail::float_down(a), bvh::detail::float_down(b), bvh::detail::float_up(c),
                           bvh::detail::float_up(d)};
    if (std::memcmp(got, want, sizeof got) != 0) ++wrong;
  }
  CHECK_EQ(wrong, 0);
}

// A wide leaf's summary codes (Node<W>::codes_of): boxes that meet in
// double have code boxes that meet, in any frame (origins and scales of
// every size, scale 0, boxes far outside the frame), for the extreme values
// of round_out's test and random doubles of every magnitude; NaN sides give
// the widest codes.
TEST(leaf_summary_codes_keep_every_meeting_box) {
  using Node8 = bvh::detail::Node<8>;
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> v = {0.0, -0.0, 1e-300, -1e-300, 1e-46, 1.5e-45, 3e-39, 0.1, -0.1, 1.0, -1.0, 16777217.0,
                           -16777217.0, 3.4028235e38, -3.4028235e38, 3.5e38, -3.5e38, 1e300, -1e300, inf, -inf, nan};
  const unsigned seed = base_seed() + 11;
  note("seed " + std::to_string(seed));
  std::mt19937_64 rng(seed);
  for (int i = 0; i < scaled(4000); ++i)
    v.push_back(std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng), int(rng() % 260) - 130));
  const float scales[] = {0.f, 1e-30f, 1e-3f, 1.f, 255.f, 3e5f, 1e30f};
  auto pick = [&] { return v[std::size_t(rng() % v.size())]; };
  auto lo = [](std::uint32_t c, int axis) { return (c >> (8 * axis)) & 255u; };
  auto hi = [](std::uint32_t c, int axis) { return (c >> (8 * (axis + 2))) & 255u; };
  int wrong = 0, nan_wrong = 0, tested = 0;
  for (int i = 0; i < scaled(200000); ++i) {
    Node8::Frame f;
    f.ox = float(pick()), f.oy = float(pick());
    if (!std::isfinite(f.ox)) f.ox = 0;
    if (!std::isfinite(f.oy)) f.oy = 0;
    f.sx = scales[rng() % 7], f.sy = scales[rng() % 7];
    double a[4] = {pick(), pick(), pick(), pick()}, b[4] = {pick(), pick(), pick(), pick()};
    for (double *x : {a, b}) {
      if (x[0] > x[2]) std::swap(x[0], x[2]);
      if (x[1] > x[3]) std::swap(x[1], x[3]);
    }
    const bvh::detail::Box A{a[0], a[1], a[2], a[3]}, B{b[0], b[1], b[2], b[3]};
    const std::uint32_t ca = Node8::codes_of(A, f), cb = Node8::codes_of(B, f);
    for (int axis = 0; axis < 2; ++axis) {
      if (std::isnan(a[axis]) && lo(ca, axis) != 0) ++nan_wrong;
      if (std::isnan(a[axis + 2]) && hi(ca, axis) != 255) ++nan_wrong;
    }
    if (!A.overlaps(B)) continue;
    ++tested;
    for (int axis = 0; axis < 2; ++axis)
      if (lo(ca, axis) > hi(cb, axis) || lo(cb, axis) > hi(ca, axis) || lo(ca, axis) > hi(ca, axis)) ++wrong;
  }
  CHECK(tested > scaled(200000) / 20);
  CHECK_EQ(wrong, 0);
  CHECK_EQ(nan_wrong, 0);
}

// The summaries inside a tree, at width 8 (frame in the links) and 7 (frame
// after the code rows): disks at both ends of the supported values
// (magnitudes 0 or in [2^-200, 2^200]), with zero, tiny and huge radii and
// centres beyond float's range, inserted, erased and moved into leaves of
// ordinary disks; collision() and query() against a scan of the model,
// validate() (which checks every code) after each step. Disks outside the
// supported values (NaN, infinite, 1e300, 1e-300) are refused by insert()
// and update(), the tree unchanged, and as probes find nothing.
bool model_supported(double v) { return v == 0 || (std::fabs(v) >= std::ldexp(1.0, -200) && std::fabs(v) <= std::ldexp(1.0, 200)); }
bool model_supported(const Disk &d) {
  const double x = d.getCenter().x, y = d.getCenter().y, r = d.getRadius();
  return model_supported(x) && model_supported(y) && model_supported(r) && r >= 0 && model_supported(x - r) &&
         model_supported(x + r) && model_supported(y - r) && model_supported(y + r);
}
template <int W> void summaries_hold_extreme_disks(unsigned seed, int split) {
  const std::string where = "seed " + std::to_string(seed) + " width " + std::to_string(W);
  note(where);
  std::mt19937_64 rng(seed);
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const double big = std::ldexp(1.0, 200), small = std::ldexp(1.0, -200);
  const double coords[] = {0, small, -1e-46, 3.5e38, -3.5e38, 1e60, -big, big, 16777217.0, 0.1, 1e-300, 1e300, inf, nan};
  const double radii[] = {0, small, 0.5, 1e30, big, 1e-300, inf};
  auto disk = [&](bool wild) {
    if (wild && rng() % 2)
      return Disk(Point(coords[rng() % 14], coords[rng() % 14]), radii[rng() % 7], Color());
    std::uniform_real_distribution<double> xy(0, 100), r(0.1, 3);
    return Disk(Point(xy(rng), xy(rng)), r(rng), Color());
  };
  BVH<Disk, bvh::shape_traits<Disk>, W> tree(split);
  codes_at_every_size(tree);
  std::vector<Disk> model;
  std::vector<typename BVH<Disk, bvh::shape_traits<Disk>, W>::handle> handles;
  std::string why;
  for (int step = 0; step < scaled(600); ++step) {
    const unsigned op = unsigned(rng() % 10);
    std::size_t refused = 0;
    if (op < 6 || model.empty()) {
      const Disk d = disk(rng() % 8 == 0);
      try {
        handles.push_back(tree.insert(d));
        model.push_back(d);
      } catch (const std::invalid_argument &) {
        ++refused;
      }
      CHECK_EQ(refused, model_supported(d) ? 0u : 1u);
    } else if (op < 8) {
      const std::size_t i = std::size_t(rng() % model.size());
      tree.erase(handles[i]);
      model.erase(model.begin() + long(i));
      handles.erase(handles.begin() + long(i));
    } else {
      const std::size_t i = std::size_t(rng() % model.size());
      const Disk d = disk(rng() % 4 == 0);
      try {
        tree.update(handles[i], d);
        model[i] = d;
      } catch (const std::invalid_argument &) {
        ++refused;
      }
      CHECK_EQ(refused, model_supported(d) ? 0u : 1u);
      CHECK(tree.get(handles[i]) == model[i]);
    }
    CHECK_EQ(tree.size(), model.size());
    if (!tree.validate(&why)) {
      note(where + " step " + std::to_string(step) + ": " + why);
      CHECK(false);
      return;
    }
    const Disk probe = disk(rng() % 3 == 0);
    const bvh::detail::Box probe_box = bvh::detail::Box::from(probe.getBox());
    std::size_t found = 0, expected = 0, touching = 0;
    for (const Disk &d : model) {
      const bool meets = model_intersect(d, probe);
      touching += meets ? 1 : 0;
      expected += meets && bvh::detail::Box::from(d.getBox()).overlaps(probe_box) ? 1 : 0;
    }
    tree.query(probe, [&](const Disk &) { ++found; });
    if (!model_supported(probe)) expected = touching = 0;
    CHECK_EQ(found, expected);
    CHECK_EQ(found, touching); // (within the supported values intersecting disks' boxes meet)
    CHECK_EQ(tree.collision(probe), touching != 0);
  }
}
TEST(leaf_summaries_hold_extreme_disks) {
  summaries_hold_extreme_disks<8>(base_seed() + 12, 32);
  summaries_hold_extreme_disks<7>(base_seed() + 13, 24);
}

// Collision searches decide a summarized leaf's disks from their codes
// (bvh.h, disk_decision) when the traits promise inscribed disks. Each
// decision must be intersect()'s answer: leaves of up to 32 disks at
// offsets from 0 to 1e9 and spreads from 1e-4 to 1e5, their frames as
// make_summary() makes them and then perturbed (a frame that fits the
// disks badly, or not at all, must still give right decisions), probes at
// distances from tangency of 0 to 10% of the radii's sum, in both
// directions, exactly tangent ones on an axis among them. The share of
// decided pairs must be large, or the test would pass with no decisions.
TEST(disks_decided_from_codes_agree_with_intersect) {
  using Node8 = bvh::detail::Node<8>;
  using bvh::detail::Box;
  static_assert(bvh::detail::InscribedDisks<bvh::shape_traits<Disk>>::value, "this project's Disk promises it");
  static_assert(!bvh::detail::InscribedDisks<bvh::shape_traits<Triangle>>::value, "a triangle does not");
  const unsigned seed = base_seed() + 14;
  note("seed " + std::to_string(seed));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const double offsets[] = {0, 1, -37.5, 1e3, -2.5e5, 1e7, 1e9};
  const double rels[] = {0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 0.05, 0.1};
  long decided = 0, pairs = 0, wrong = 0, hit_wrong = 0, candidates = 0, candidates_decided = 0;
  std::string first_wrong;
  for (int round = 0; round < scaled(3000); ++round) {
    const double offset = offsets[rng() % 7] * (rng() % 2 ? 1 : -1);
    const double spread = std::ldexp(1.0, int(rng() % 30) - 13); // 1e-4 .. 1e5
    const int n = 1 + int(rng() % 32);
    // (float codes place sides to about 2^-21 of the offset: far from the
    // origin a small leaf's codes decide nothing, rightly; the shares below
    // are counted where they can decide)
    bool ordinary = std::fabs(offset) <= 1e3 * spread;
    std::vector<Disk> stored;
    Box all;
    for (int i = 0; i < n; ++i) {
      const Disk d(Point(offset + spread * unit(rng), offset + spread * unit(rng)), spread * (0.002 + 0.1 * unit(rng)),
                   Color());
      stored.push_back(d);
      all.extend(Box::from(d.getBox()));
    }
    // The frame as make_summary() computes it, then maybe perturbed.
    Node8 node;
    Node8::Frame f;
    const double sx = all.x1 - all.x0, sy = all.y1 - all.y0;
    f.ox = float(all.x0 - sx / 8);
    f.oy = float(all.y0 - sy / 8);
    const double kx = 255 / (double(all.x1 + sx / 8) - f.ox), ky = 255 / (double(all.y1 + sy / 8) - f.oy);
    f.sx = kx > 0 && kx < 1e30 ? float(kx) * (1 - 1e-6f) : 0; // (a scale is never negative)
    f.sy = ky > 0 && ky < 1e30 ? float(ky) * (1 - 1e-6f) : 0;
    const bool perturbed = rng() % 4 == 0;
    if (perturbed) {
      f.ox += float(sx * (unit(rng) - 0.5));
      f.sx *= float(0.25 + 4 * unit(rng));
      f.sy *= float(0.25 + 4 * unit(rng));
    }
    ordinary = ordinary && !perturbed;
    node.set_frame(f);
    for (int i = 0; i < n; ++i) node.set_codes(i, Node8::codes_of(Box::from(stored[std::size_t(i)].getBox()), f));
    node.set_coded(n);
    const bvh::detail::CodeFrame frame = bvh::detail::CodeFrame::of(node.frame());
    for (int k = 0; k < 24; ++k) {
      const Disk &d = stored[rng() % stored.size()];
      const double r = d.getRadius() * (rng() % 8 == 0 ? 0.0 : 0.05 + 3 * unit(rng));
      const double rel = rels[rng() % 10] * (rng() % 2 ? 1 : -1) * (rng() % 3 ? 1 : unit(rng));
      const double reach = (d.getRadius() + r) * (1 + rel);
      Point c;
      if (rng() % 4 == 0) { // on an axis: exactly tangent when rel is 0 and the sums are exact
        c = Point(d.getCenter().x + (rng() % 2 ? reach : -reach), d.getCenter().y);
      } else {
        const double a = 6.283185307179586 * unit(rng);
        c = Point(d.getCenter().x + reach * std::cos(a), d.getCenter().y + reach * std::sin(a));
      }
      const Disk probe(c, r, Color());
      const Box probe_box = Box::from(probe.getBox());
      const bvh::detail::DiskProbe p = bvh::detail::DiskProbe::of(probe_box);
      bool any = false;
      for (int i = 0; i < n; ++i) {
        const bool meets = intersect(stored[std::size_t(i)], probe);
        any = any || (meets && Box::from(stored[std::size_t(i)].getBox()).overlaps(probe_box));
        if (!p.usable || !frame.usable) continue;
        const int decision = bvh::detail::disk_decision(node, i, frame, p);
        if ((decision > 0 && !meets) || (decision < 0 && meets)) {
          if (wrong++ == 0)
            first_wrong = "disk " + std::to_string(i) + " of " + std::to_string(n) + " in round " +
                          std::to_string(round) + ", relative gap " + std::to_string(rel) + ", decision " +
                          std::to_string(decision);
        }
        if (!ordinary) continue;
        ++pairs;
        decided += decision != 0 ? 1 : 0;
        if (node.meets(probe_box, n) >> i & 1u) {
          ++candidates;
          candidates_decided += decision != 0 ? 1 : 0;
        }
      }
      // disk_codes_hit: true only when some shape meets; otherwise every
      // shape that meets is among the unsure ones
      std::uint32_t unsure = 0;
      const bool sure = bvh::detail::disk_codes_hit(node, n, probe_box, p, unsure);
      bool lost = sure && !any;
      for (int i = 0; i < n && !sure; ++i)
        lost = lost || (intersect(stored[std::size_t(i)], probe) &&
                        Box::from(stored[std::size_t(i)].getBox()).overlaps(probe_box) && !(unsure >> i & 1u));
      if (lost && hit_wrong++ == 0) first_wrong += " (disk_codes_hit: round " + std::to_string(round) + ")";
    }
  }
  note("pairs " + std::to_string(pairs) + " decided " + std::to_string(decided) + "; code boxes meet " +
       std::to_string(candidates) + ", decided " + std::to_string(candidates_decided) + "; first wrong: " + first_wrong);
  CHECK_EQ(wrong, 0L);
  CHECK_EQ(hit_wrong, 0L);
  CHECK(decided > pairs / 2);
  CHECK(candidates_decided > candidates / 3);
}

// The same through whole trees: collision(), collisions() and query(shape)
// at widths 4 and 8 against intersect() over every disk, with probes placed near
// tangency of a stored disk, and against a tree whose traits make no
// promise (every candidate read and tested) and one whose boxes are
// rounded to float.
struct NoPromise {
  static decltype(auto) box(const Disk &d) { return d.getBox(); }
  static decltype(auto) center(const Disk &d) { return d.getCenter(); }
  static bool intersect(const Disk &a, const Disk &b) { return ::intersect(a, b); }
};
// A disk whose box is rounded outwards to float, with the promise: its
// box is the disk's up to float's rounding, which the decisions allow for.
struct FloatBoxDisks {
  static float down(double v) {
    float f = float(v);
    return double(f) > v ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
  }
  static float up(double v) {
    float f = float(v);
    return double(f) < v ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
  }
  static bvh::bounds box(const Disk &d) {
    const BoundingBox b = d.getBox();
    return {down(b.getMin().x), down(b.getMin().y), up(b.getMax().x), up(b.getMax().y)};
  }
  static decltype(auto) center(const Disk &d) { return d.getCenter(); }
  static bool intersect(const Disk &a, const Disk &b) { return ::intersect(a, b); }
  static constexpr bool inscribed_disks = true;
};
template <int W> void collisions_near_tangency(unsigned seed) {
  note("seed " + std::to_string(seed) + " width " + std::to_string(W));
  static_assert(!bvh::detail::InscribedDisks<NoPromise>::value, "no member: no promise");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  BVH<Disk, bvh::shape_traits<Disk>, W> tree(W == 8 ? 32 : 16);
  codes_at_every_size(tree);
  BVH<Disk, NoPromise, W> plain(W == 8 ? 32 : 16);
  codes_at_every_size(plain);
  BVH<Disk, FloatBoxDisks, W> floats(W == 8 ? 32 : 16);
  codes_at_every_size(floats);
  std::vector<Disk> kept;
  const double offset = rng() % 2 ? 0 : 4096;
  for (int i = 0; i < scaled(4000); ++i) {
    const Disk d(Point(offset + 60 * unit(rng), offset + 60 * unit(rng)), 0.2 + 0.4 * unit(rng), Color());
    const bool hit = tree.collision(d);
    CHECK_EQ(hit, plain.collision(d));
    CHECK_EQ(hit, floats.collision(d));
    if (!hit) {
      tree.insert(d);
      plain.insert(d);
      floats.insert(d);
      kept.push_back(d);
    }
  }
  CHECK(tree.validate());
  std::vector<Disk> probes;
  const double rels[] = {0, 1e-12, 1e-9, 1e-6, 1e-3, 0.1};
  for (int k = 0; k < scaled(3000); ++k) {
    const Disk &d = kept[rng() % kept.size()];
    const double r = 0.2 + 0.4 * unit(rng), rel = rels[rng() % 6] * (rng() % 2 ? 1 : -1);
    const double a = 6.283185307179586 * unit(rng), reach = (d.getRadius() + r) * (1 + rel);
    probes.push_back(Disk(Point(d.getCenter().x + reach * std::cos(a), d.getCenter().y + reach * std::sin(a)), r, Color()));
  }
  const std::vector<bool> together = tree.collisions(probes);
  CHECK(floats.collisions(probes) == together);
  int wrong = 0;
  for (std::size_t k = 0; k < probes.size(); ++k) {
    bool expected = false;
    for (const Disk &d : kept) expected = expected || intersect(d, probes[k]);
    const bool one = tree.collision(probes[k]);
    if (one != expected || together[k] != expected || plain.collision(probes[k]) != expected ||
        floats.collision(probes[k]) != expected)
      ++wrong;
    // query(shape): the same shapes in the same order as the tree without
    // the promise (the same tree), each of them intersecting the probe
    std::vector<Disk> found, found_plain;
    tree.query_into(probes[k], std::back_inserter(found));
    plain.query_into(probes[k], std::back_inserter(found_plain));
    std::size_t meeting = 0;
    for (const Disk &d : kept) meeting += intersect(d, probes[k]) ? 1 : 0;
    if (!(found == found_plain) || found.size() != meeting) ++wrong;
  }
  CHECK_EQ(wrong, 0);
}
TEST(collisions_near_tangency_equal_brute_force) {
  collisions_near_tangency<8>(base_seed() + 15);
  collisions_near_tangency<4>(base_seed() + 16);
}

// A shape whose box has a NaN side is refused on every path that could
// have left it alone in a tree (inserted first, moved by update(), a
// sampling's first): the tree stays as it was and valid. (These paths
// once stored such a box as the root's.)
template <int W> void lone_shape_with_nan_side(double margin) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Disk odd(Point(nan, -1e300), 1e30), plain(Point(26, 22), 0.8), other(Point(60, 70), 2);
  using Tree = BVH<Disk, bvh::shape_traits<Disk>, W>;
  std::string why;
  const auto refused = [&](Tree &t, auto change, const char *how, std::size_t size) {
    note(std::string(how) + " width " + std::to_string(W) + " margin " + std::to_string(margin));
    bool threw = false;
    try {
      change(t);
    } catch (const std::invalid_argument &) {
      threw = true;
    }
    CHECK(threw);
    CHECK(t.validate(&why));
    CHECK_EQ(t.size(), size);
    CHECK(why.empty());
    why.clear();
  };
  Tree first(W == 3 ? 4 : 16);
  codes_at_every_size(first);
  first.set_margin(margin);
  refused(first, [&](Tree &t) { t.insert(odd); }, "inserted first", 0);
  Tree moved(W == 3 ? 4 : 16);
  codes_at_every_size(moved);
  moved.set_margin(margin);
  const auto h = moved.insert(plain);
  refused(moved, [&](Tree &t) { t.update(h, odd); }, "updated alone", 1);
  CHECK(moved.get(h) == plain);
  Tree sampled(W == 3 ? 4 : 16);
  codes_at_every_size(sampled);
  sampled.set_margin(margin);
  refused(sampled, [&](Tree &t) { t.insert_disjoint(std::vector<Disk>{odd}, 1); }, "sampled", 0);
  // and the ordinary shapes beside it still go in
  first.insert(plain);
  first.insert(other);
  CHECK(first.validate());
  CHECK(first.collision(plain));
}
TEST(a_shape_with_a_nan_side_is_refused_on_every_path) {
  lone_shape_with_nan_side<3>(0);
  lone_shape_with_nan_side<3>(0.5);
  lone_shape_with_nan_side<8>(0);
  lone_shape_with_nan_side<8>(0.5);
}

// split_in_two() (an overflowing leaf's split at widths other than 3)
// against the shared build loop it stands in for: on the same shapes both
// must make the same nodes, boxes, counts, shapes, ids and summaries. Centres
// on a coarse grid make ties, which the order's later keys break.
template <int W> std::string subtree_text(const bvh::detail::Core<Disk, bvh::shape_traits<Disk>, W> &core, int n) {
  std::ostringstream out;
  out << std::setprecision(17);
  bvh::detail::for_each_preorder(core.nodes, n, [&](int m) {
    const auto &node = core.nodes.node(m);
    const bvh::detail::Box &b = core.nodes.box(m);
    out << "node d" << core.nodes.info(m).depth << " c" << core.nodes.info(m).count << " [" << b.x0 << " " << b.y0 << " "
        << b.x1 << " " << b.y1 << "] k" << node.num_children;
    if (node.is_leaf()) {
      const auto v = core.leaves.shapes(node);
      const std::uint32_t *ids = core.leaves.ids(node);
      out << " coded " << node.coded();
      for (std::size_t i = 0; i < v.size(); ++i)
        out << " (" << v[i].getCenter().x << "," << v[i].getCenter().y << "," << v[i].getRadius() << " #" << ids[i] << ")";
      // The node's bytes: its summary's codes and frame, and its slot.
      unsigned char bytes[sizeof node];
      std::memcpy(bytes, &node, sizeof node);
      out << " bytes " << std::hex;
      for (unsigned char c : bytes) out << int(c) << ".";
      out << std::dec;
    }
    out << "\n";
  });
  return out.str();
}

template <int W> void check_split_in_two(unsigned seed) {
  using Core = bvh::detail::Core<Disk, bvh::shape_traits<Disk>, W>;
  std::mt19937 rng(seed);
  int took = 0, declined = 0, wrong = 0;
  for (int round = 0; round < scaled(400); ++round) {
    const int split = 1 + int(rng() % 40), depth_limit = rng() % 4 == 0 ? 1 + int(rng() % 3) : 0;
    const std::size_t m = 2 + rng() % std::size_t(2 * split + 8);
    const double grid = rng() % 2 ? 1.0 : 0.25, margin = rng() % 3 == 0 ? 0.5 : 0;
    std::vector<bvh::detail::Tagged<Disk>> shapes;
    for (std::size_t i = 0; i < m; ++i) {
      const double x = grid * double(rng() % 12), y = grid * double(rng() % (rng() % 2 ? 12 : 3));
      shapes.push_back(bvh::detail::Tagged<Disk>{Disk(Point(x, y), 0.1 + 0.1 * double(rng() % 5)), std::uint32_t(100 + i)});
    }
    const int depth = int(rng() % 3);
    Core a(bvh::shape_traits<Disk>(), split, depth_limit), b(bvh::shape_traits<Disk>(), split, depth_limit);
    a.margin = b.margin = margin;
    const int ra = a.new_node(depth, -1, 0), rb = b.new_node(depth, -1, 0);
    std::vector<bvh::detail::Tagged<Disk>> sa = shapes, sb = shapes;
    if (!bvh::detail::split_in_two(a, ra, sa)) {
      ++declined;
      continue;
    }
    ++took;
    bvh::detail::build_by_course_rule(b, rb, sb);
    const std::string ta = subtree_text(a, ra), tb = subtree_text(b, rb);
    if (ta != tb && ++wrong <= 2)
      note(seed_note(seed, round) + ": width " + std::to_string(W) + " split_in_two:\n" + ta + "the loop:\n" + tb);
  }
  note("width " + std::to_string(W) + ": " + std::to_string(took) + " splits compared, " + std::to_string(declined) + " declined");
  CHECK(took > scaled(400) / 8);
  CHECK(declined > 0);
  CHECK_EQ(wrong, 0);
}

TEST(split_in_two_builds_what_the_loop_builds) {
  check_split_in_two<8>(base_seed() + 14);
  check_split_in_two<4>(base_seed() + 15);
  check_split_in_two<2>(base_seed() + 16);
}

// The node arrays against std::vector as the model: random appends, writes
// and pops across block boundaries, then copies and moves; every block's
// first element on a cache line. The element is like a Node: trivially
// copyable, with default member values that a new element must show.
struct Cell {
  int value[3] = {0, 0, 0};
  int writes = 0;
  bool operator==(const Cell &o) const {
    return writes == o.writes && value[0] == o.value[0] && value[1] == o.value[1] && value[2] == o.value[2];
  }
};
TEST(block_vector_behaves_like_a_vector) {
  const unsigned seed = base_seed() + 7;
  note("seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  bvh::detail::BlockVector<Cell> blocks;
  std::vector<Cell> model;
  for (int step = 0; step < scaled(20000); ++step) {
    const unsigned op = rng() % 10;
    if (op < 6 || model.empty()) {
      blocks.emplace_back();
      model.emplace_back();
      CHECK(blocks.back() == Cell()); // appended elements start default
    } else if (op < 9) {
      // Half the writes go to the last element, so pops drop written ones.
      const std::size_t i = rng() % 2 ? model.size() - 1 : rng() % model.size();
      const int v = int(rng() % 1000);
      for (Cell *c : {&blocks[i], &model[i]}) c->value[c->writes++ % 3] = v;
    } else {
      blocks.pop_back();
      model.pop_back();
    }
  }
  const auto same_as_model = [&](const bvh::detail::BlockVector<Cell> &b) {
    bool same = b.size() == model.size();
    for (std::size_t i = 0; same && i < model.size(); ++i) same = b[i] == model[i];
    return same;
  };
  CHECK(same_as_model(blocks));
  for (std::size_t i = 0; i < model.size(); i += 512)
    CHECK(reinterpret_cast<std::uintptr_t>(&blocks[i]) % 64 == 0);
  bvh::detail::BlockVector<Cell> copy = blocks;
  if (!model.empty()) copy[0].writes = -1; // deep: the original keeps its own
  CHECK(same_as_model(blocks));
  copy = blocks;
  CHECK(same_as_model(copy));
  for (std::size_t i = 0; i < model.size(); i += 512)
    CHECK(reinterpret_cast<std::uintptr_t>(&copy[i]) % 64 == 0);
  // Past the end, a copy's elements are default too: it grows as the
  // original would.
  for (int i = 0; i < 600; ++i) {
    copy.emplace_back();
    CHECK(copy.back() == Cell());
    copy.pop_back();
    copy.emplace_back();
    copy.back().writes = i + 1;
  }
  const bvh::detail::BlockVector<Cell> moved = std::move(copy);
  CHECK(copy.empty());
  CHECK_EQ(moved.size(), model.size() + 600);
  CHECK(moved.bytes() >= moved.size() * sizeof(Cell));
}

// select_nth (the wide builds' selection) against the definition of
// nth_element's result, on random, sorted, reversed, organ-pipe and
// few-valued keys (ties: a strict weak order), at sizes around its
// switch to std::nth_element, every k in turn on one of them.
TEST(select_nth_gives_nth_elements_result) {
  const unsigned seed = base_seed() + 11;
  note("seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  int wrong = 0, cases = 0;
  const std::size_t sizes[] = {0, 1, 2, 599, 600, 601, 602, 1000, 4096, 20000, std::size_t(scaled(200000))};
  for (const std::size_t n : sizes)
    for (int kind = 0; kind < 5; ++kind) {
      std::vector<std::pair<int, int>> v(n); // (key, tag): compared by key only
      for (std::size_t i = 0; i < n; ++i) {
        const int key = kind == 0 ? int(rng() % 1000000) : kind == 1 ? int(i) : kind == 2 ? -int(i)
                        : kind == 3 ? std::min(int(i), int(n - i)) : int(rng() % 5);
        v[i] = {key, int(i)};
      }
      std::vector<std::pair<int, int>> sorted = v;
      std::sort(sorted.begin(), sorted.end());
      auto less = [](const std::pair<int, int> &a, const std::pair<int, int> &b) { return a.first < b.first; };
      const std::size_t picks = n <= 1000 && kind == 0 ? n : 4;
      for (std::size_t p = 0; p < picks && n > 0; ++p) {
        const std::size_t k = picks == n ? p : std::size_t(rng() % n);
        std::vector<std::pair<int, int>> w = v;
        bvh::detail::select_nth(w.begin(), w.begin() + long(k), w.end(), less);
        bool ok = w[k].first == sorted[k].first;
        for (std::size_t i = 0; i < k && ok; ++i) ok = w[i].first <= w[k].first;
        for (std::size_t i = k + 1; i < n && ok; ++i) ok = w[k].first <= w[i].first;
        std::vector<std::pair<int, int>> again = w; // a permutation of the input
        std::sort(again.begin(), again.end());
        ok = ok && again == sorted;
        if (!ok && ++wrong <= 3) note("seed " + std::to_string(seed) + ": n " + std::to_string(n) + " kind " + std::to_string(kind) + " k " + std::to_string(k));
        ++cases;
      }
    }
  CHECK(cases > 50);
  CHECK_EQ(wrong, 0);
}

// BuildAllocator (the build's items): arrays of 8 MB or more come from
// aligned_alloc, aligned to a huge page, on Linux; smaller ones, and every
// array under BVH_NO_HUGE_PAGES or elsewhere, from std::allocator. A vector
// that grows across the boundary frees each array the way it came.
TEST(build_allocator_serves_small_and_huge_arrays) {
  using Item = bvh::detail::Item<Disk, bvh::shape_traits<Disk>>;
  using Alloc = bvh::detail::BuildAllocator<Item>;
  const std::size_t huge_page = std::size_t(1) << 21;
  const std::size_t boundary = 4 * huge_page / sizeof(Item) + (4 * huge_page % sizeof(Item) != 0);
  CHECK_EQ(Alloc::huge(boundary), BVH_HUGE_PAGES == 1); // (off under BVH_NO_HUGE_PAGES: the portable build)
  CHECK(!Alloc::huge(boundary - 1));
  Alloc alloc;
  for (const std::size_t n : {std::size_t(1), boundary - 1, boundary, boundary + 12345}) {
    Item *p = alloc.allocate(n);
    CHECK(p != nullptr);
    CHECK_EQ(reinterpret_cast<std::uintptr_t>(p) % alignof(Item), std::uintptr_t(0));
#if BVH_HUGE_PAGES
    if (n >= boundary) CHECK_EQ(reinterpret_cast<std::uintptr_t>(p) % huge_page, std::uintptr_t(0));
#endif
    std::memset(static_cast<void *>(p), 0x5a, n * sizeof(Item)); // every byte is ours (ASan, valgrind)
    alloc.deallocate(p, n);
  }
  bvh::detail::Items<Disk, bvh::shape_traits<Disk>> items;
  const bvh::shape_traits<Disk> traits{};
  for (std::size_t i = 0; i < boundary + 100; ++i)
    items.push_back(bvh::detail::make_item(traits, Disk(Point(double(i), 0), 1, Color()), std::uint32_t(i)));
  bool same = true;
  for (std::size_t i = 0; i < items.size(); ++i) same = same && items[i].index == i && items[i].shape.getCenter().x == double(i);
  CHECK(same);
  bool threw = false;
  try {
    (void)alloc.allocate(std::size_t(-1) / sizeof(Item));
  } catch (const std::bad_alloc &) {
    threw = true;
  }
  CHECK(threw);
}

// A build whose items take 8 MB or more (the huge-page arrays): the course's
// tree against the literal rule, and collision() against a scan.
TEST(large_build_equals_the_literal_course_rule) {
  if (scale() < 1) return; // the literal rule is slow at this size
  const std::size_t n = (std::size_t(8) << 20) / sizeof(bvh::detail::Item<Disk, bvh::shape_traits<Disk>>) + 1000;
  Maker make(base_seed() + 13, 0.0);
  const std::vector<Disk> disks = make.scene<Disk>(int(n), 3);
  CourseBVH<Disk> tree(4, 0);
  tree.construct(disks);
  std::string why;
  CHECK(tree.validate(&why));
  if (!why.empty()) note(why);
  CHECK(report(tree) == ref_report(disks, 4, 0));
  const std::vector<Disk> probes = make.scene<Disk>(40, 3);
  int wrong = 0;
  for (const Disk &p : probes) wrong += tree.collision(p) != brute_collision(disks, p);
  CHECK_EQ(wrong, 0);
}

int main(int argc, char **argv) {
  std::cout << "seed " << base_seed() << " (set BVH_SEED to change), scale " << scale() << std::endl;
  return run_all_tests(argc, argv);
}
