// tests/test_editions.cpp — the two editions test each other: the course's
// edition (the top-level bvh.h, ::BVH<T>, written for a student) and the
// engine (include/bvh/bvh.h, bvh::BVH<T> at the course's width 3) are built
// on the same random scenes and must agree byte for byte:
//  - statistics(true): the course's report and --print_tree listing;
//  - the iteration order, forwards and backwards (every shape's box and
//    colour, leaf by leaf);
//  - the shapes that discard-overlap sampling keeps (collision() then
//    insert(), the same predicates: this project's exact intersect());
//  - collision() on probes, and the contents after erases.
// Scenes: disks, triangles and quads; bulk and incremental; split
// thresholds 1 to 8 and depth limits 0 (none) to 7; coordinates on a coarse
// grid, so that centres tie, shapes touch exactly and some repeat. Each
// case prints its seed on failure (BVH_SEED, BVH_TEST_SCALE as elsewhere).
//
// Both editions are in this one program: ::BVH from "bvh.h" (with the
// top-level shapes.h giving the course's unqualified names) and bvh::BVH
// from <bvh/bvh.h>. So nothing here writes `using namespace bvh`.
#include <cstdlib>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bvh.h"
#include <bvh/bvh.h>

#include "check.h"

namespace {

unsigned base_seed() {
  const char *s = std::getenv("BVH_SEED");
  return s ? unsigned(std::strtoul(s, nullptr, 10)) : 12345u;
}

double scale() {
  const char *s = std::getenv("BVH_TEST_SCALE");
  const double v = s ? std::atof(s) : 1.0;
  return v > 0 ? v : 1.0;
}

int scaled(int n) { return std::max(1, int(n * scale())); }

// Random shapes as the course's loader makes them: each number read into a
// float, widened to double. On a grid of `step` inside [0, 1000).
struct Scenes {
  std::mt19937 rng;
  double step;
  Scenes(unsigned seed, double step_) : rng(seed), step(step_) {}
  double coord() {
    std::uniform_int_distribution<int> cell(0, int(1000 / step) - 1);
    return double(float(cell(rng) * step));
  }
  double size() { return double(float(step * std::uniform_int_distribution<int>(1, 4)(rng))); }
  Color color() {
    std::uniform_int_distribution<int> c(0, 255);
    return Color(c(rng), c(rng), c(rng));
  }
  Point near(const Point &p) { return Point(double(float(p.x + size())), double(float(p.y - size()))); }
  void make(std::vector<Disk> &out, int n) {
    for (int i = 0; i < n; ++i) out.push_back(Disk(Point(coord(), coord()), size() / 2, color()));
  }
  void make(std::vector<Triangle> &out, int n) {
    for (int i = 0; i < n; ++i) {
      const Point a(coord(), coord());
      out.push_back(Triangle(a, near(a), Point(a.x, double(float(a.y + size()))), color()));
    }
  }
  void make(std::vector<Quad> &out, int n) {
    for (int i = 0; i < n; ++i) {
      const Point a(coord(), coord());
      const double s = size();
      out.push_back(Quad(a, Point(double(float(a.x + s)), a.y), Point(double(float(a.x + s)), double(float(a.y + s))),
                         Point(a.x, double(float(a.y + s))), color()));
    }
  }
  // Some shapes twice, in a random place of the order.
  template <class T> void repeat_some(std::vector<T> &v) {
    const std::size_t n = v.size();
    for (std::size_t i = 0; i < n / 10; ++i) {
      const T copy = v[std::uniform_int_distribution<std::size_t>(0, n - 1)(rng)];
      v.insert(v.begin() + std::uniform_int_distribution<std::size_t>(0, v.size())(rng), copy);
    }
  }
};

// What statistics(true) prints to stdout.
template <class Tree> std::string report(const Tree &tree) {
  std::ostringstream out;
  std::streambuf *old = std::cout.rdbuf(out.rdbuf());
  tree.statistics(true);
  std::cout.rdbuf(old);
  return out.str();
}

template <class T> std::string describe(const T &shape) {
  std::ostringstream out;
  out << shape.getBox() << " " << shape.getColor().getHexString();
  return out.str();
}

// Every shape in iteration order, then in reverse (operator--).
template <class Tree> std::vector<std::string> order(const Tree &tree) {
  std::vector<std::string> seen;
  for (auto it = tree.begin(); it != tree.end(); ++it) seen.push_back(describe(*it));
  auto it = tree.end();
  while (it != tree.begin()) {
    --it;
    seen.push_back("back " + describe(*it));
  }
  return seen;
}

template <class Course, class Engine> bool same_trees(const Course &course, const Engine &engine, const char *what) {
  const std::string a = report(course), b = report(engine);
  if (a != b) {
    std::istringstream ia(a), ib(b);
    std::string la, lb;
    int line = 1;
    while (std::getline(ia, la) && std::getline(ib, lb) && la == lb) ++line;
    std::cout << "  " << what << ": the reports differ at line " << line << "\n    course's edition: " << la
              << "\n    engine:           " << lb << "\n";
    return false;
  }
  if (order(course) != order(engine)) {
    std::cout << "  " << what << ": the iteration orders differ\n";
    return false;
  }
  return true;
}

int cases_run = 0;

template <class T> void compare_on(unsigned seed, int n, double step, int split, int depth) {
  Scenes make(seed, step);
  std::vector<T> shapes;
  make.make(shapes, n);
  make.repeat_some(shapes);
  std::ostringstream id;
  id << "seed " << seed << ", " << shapes.size() << " shapes, step " << step << ", split_threshold " << split
     << ", depth_limit " << depth;
  note(id.str());
  ++cases_run;

  // Bulk, by the course's rule.
  ::BVH<T> course_bulk(split, depth);
  bvh::BVH<T> engine_bulk(split, depth);
  course_bulk.construct(shapes);
  engine_bulk.construct(shapes);
  CHECK(same_trees(course_bulk, engine_bulk, "construct"));

  // Incremental, every shape.
  ::BVH<T> course_inc(split, depth);
  bvh::BVH<T> engine_inc(split, depth);
  for (const T &s : shapes) {
    course_inc.insert(s);
    engine_inc.insert(s);
  }
  CHECK(same_trees(course_inc, engine_inc, "insert"));

  // Discard-overlap sampling: the same shapes kept, in the same tree.
  ::BVH<T> course_kept(split, depth);
  bvh::BVH<T> engine_kept(split, depth);
  std::size_t kept = 0, disagreements = 0;
  for (const T &s : shapes) {
    const bool a = course_kept.collision(s), b = engine_kept.collision(s);
    if (a != b) ++disagreements;
    if (!a) course_kept.insert(s);
    if (!b) engine_kept.insert(s);
    kept += !a;
  }
  CHECK_EQ(disagreements, std::size_t(0));
  CHECK(same_trees(course_kept, engine_kept, "discard-overlap"));
  CHECK(kept > 0);

  // Probes that both trees answer.
  std::vector<T> probes;
  make.make(probes, 50);
  std::size_t differ = 0;
  for (const T &p : probes) differ += course_bulk.collision(p) != engine_bulk.collision(p);
  CHECK_EQ(differ, std::size_t(0));

  // Copies print the same.
  const ::BVH<T> copy(course_inc);
  CHECK(report(copy) == report(course_inc));
}

template <class T> void compare_many(unsigned salt) {
  const int before = cases_run;
  const unsigned seed0 = base_seed() * 7919u + salt;
  std::mt19937 pick(seed0);
  const int rounds = scaled(40);
  for (int r = 0; r < rounds; ++r) {
    const int n = std::uniform_int_distribution<int>(0, 300)(pick);
    const double step = std::uniform_int_distribution<int>(0, 1)(pick) ? 25.0 : 2.5;
    const int split = std::uniform_int_distribution<int>(1, 8)(pick);
    const int depth = std::uniform_int_distribution<int>(0, 7)(pick);
    compare_on<T>(seed0 + 1000u * unsigned(r), n, step, split, depth);
  }
  std::cout << "  " << cases_run - before << " scenes, each built four ways by both editions" << std::endl;
}

} // namespace

TEST(editions_agree_on_disks) { compare_many<Disk>(1); }
TEST(editions_agree_on_triangles) { compare_many<Triangle>(2); }
TEST(editions_agree_on_quads) { compare_many<Quad>(3); }

// The handout's own scene sizes, one of each kind at a depth limit that
// prints a tree of several levels.
TEST(editions_agree_on_larger_scenes) {
  compare_on<Disk>(base_seed() + 11, scaled(3000), 2.5, 4, 6);
  compare_on<Triangle>(base_seed() + 12, scaled(3000), 2.5, 4, 0);
  compare_on<Quad>(base_seed() + 13, scaled(3000), 25.0, 2, 5);
}

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
