// tests/test_editions.cpp — the two editions of BVH<T> against each other:
// the engine (include/bvh/bvh.h, bvh::BVH) and the course's edition (the
// top-level bvh.h, ::BVH), on random scenes of disks, triangles and quads (with duplicates
// and touching shapes), bulk and incremental, over split thresholds 1-8
// and depth limits 0-12. Each side is the other's reference: they must
// print the same statistics(true) report byte for byte, iterate the same
// shapes in the same order, and keep the same shapes in discard-overlap
// sampling (collision, then insert) with the same (this project's exact)
// predicates. A failure prints the case's seed and the BVH_SEED (default
// 20261207) and round that make it; BVH_TEST_SCALE scales the rounds
// (40 a kind at 1).
#include "shapes.h" // the project's shapes, under the course's global names
#include "bvh.h"    // the course's edition: ::BVH
#include <bvh/bvh.h> // the engine: bvh::BVH (the library declares nothing global)

#include "check.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <new>
#include <random>
#include <sstream>
#include <string>
#include <vector>

// Allocation faults for the edition's copies (edition_copies_survive_failed_
// allocations): operator new throws std::bad_alloc when the countdown,
// counting allocations, reaches 0 (-1: never), as in test_exceptions.cpp.
static long alloc_countdown = -1;
// (g++ sees free() on operator new's pointer once both are inlined: they are this pair)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void *operator new(std::size_t n) {
  if (alloc_countdown >= 0 && alloc_countdown-- == 0) throw std::bad_alloc();
  if (void *p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void *operator new[](std::size_t n) { return ::operator new(n); }
// (the nothrow forms, which std::stable_sort's buffer uses, never fail here)
void *operator new(std::size_t n, const std::nothrow_t &) noexcept { return std::malloc(n ? n : 1); }
void *operator new[](std::size_t n, const std::nothrow_t &) noexcept { return std::malloc(n ? n : 1); }
void operator delete(void *p, const std::nothrow_t &) noexcept { std::free(p); }
void operator delete[](void *p, const std::nothrow_t &) noexcept { std::free(p); }
void operator delete(void *p) noexcept { std::free(p); }
void operator delete[](void *p) noexcept { std::free(p); }
void operator delete(void *p, std::size_t) noexcept { std::free(p); }
void operator delete[](void *p, std::size_t) noexcept { std::free(p); }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace {

unsigned base_seed() {
  const char *s = std::getenv("BVH_SEED");
  return s ? unsigned(std::strtoul(s, nullptr, 10)) : 20261207u;
}
double scale() {
  const char *s = std::getenv("BVH_TEST_SCALE");
  const double v = s ? std::atof(s) : 1.0;
  return v > 0 ? v : 1.0;
}

// A coordinate as the course's files give them: one decimal, read as a
// float and widened.
double coordinate(std::mt19937 &rng, double lo, double hi) {
  const double v = std::uniform_real_distribution<double>(lo, hi)(rng);
  return double(float(std::round(v * 10) / 10));
}
Point around(const Point &c, double size, double angle) {
  return Point(double(float(std::round((c.x + size * std::cos(angle)) * 10) / 10)),
               double(float(std::round((c.y + size * std::sin(angle)) * 10) / 10)));
}
Disk fresh(std::mt19937 &rng, const Disk *) {
  return Disk(Point(coordinate(rng, 0, 1000), coordinate(rng, 0, 1000)), coordinate(rng, 1, 40), Color(1, 2, 3));
}
// A convex polygon of N vertices around a random centre, at increasing angles.
template <class P, int N> P polygon(std::mt19937 &rng) {
  const Point c(coordinate(rng, 0, 1000), coordinate(rng, 0, 1000));
  const double size = coordinate(rng, 3, 60), start = std::uniform_real_distribution<double>(0, 6.28)(rng);
  Point p[N];
  for (int i = 0; i < N; ++i) p[i] = around(c, size, start + 6.2831853 * i / N);
  if constexpr (N == 3) return P(p[0], p[1], p[2], Color(1, 2, 3));
  else return P(p[0], p[1], p[2], p[3], Color(1, 2, 3));
}
Triangle fresh(std::mt19937 &rng, const Triangle *) { return polygon<Triangle, 3>(rng); }
Quad fresh(std::mt19937 &rng, const Quad *) { return polygon<Quad, 4>(rng); }
// `s` moved right by its own box's width: the two boxes touch.
Disk beside(const Disk &s) { return Disk(Point(s.getCenter().x + 2 * s.getRadius(), s.getCenter().y), s.getRadius(), s.getColor()); }
Point right_of(const Point &p, double dx) { return Point(p.x + dx, p.y); }
double width(const BoundingBox &b) { return b.getMax().x - b.getMin().x; }
Triangle beside(const Triangle &s) {
  const double dx = width(s.getBox());
  return Triangle(right_of(s.getPoint(0), dx), right_of(s.getPoint(1), dx), right_of(s.getPoint(2), dx), s.getColor());
}
Quad beside(const Quad &s) {
  const double dx = width(s.getBox());
  return Quad(right_of(s.getPoint(0), dx), right_of(s.getPoint(1), dx), right_of(s.getPoint(2), dx),
              right_of(s.getPoint(3), dx), s.getColor());
}

// A scene of n shapes: a tenth duplicates of earlier ones, a tenth beside one.
template <class T> std::vector<T> scene(std::mt19937 &rng, std::size_t n) {
  std::vector<T> v;
  for (std::size_t i = 0; i < n; ++i) {
    const int what = int(rng() % 10);
    if (what == 0 && !v.empty()) v.push_back(v[rng() % v.size()]);
    else if (what == 1 && !v.empty()) v.push_back(beside(v[rng() % v.size()]));
    else v.push_back(fresh(rng, static_cast<const T *>(nullptr)));
  }
  return v;
}

template <class Tree> std::string order_of(const Tree &tree) {
  std::string s;
  char buf[200];
  for (auto it = tree.begin(); it != tree.end(); ++it) {
    const auto &b = (*it).getBox();
    std::snprintf(buf, sizeof buf, "%a %a %a %a %a %a\n", b.getMin().x, b.getMin().y, b.getMax().x, b.getMax().y,
                  (*it).getCenter().x, (*it).getCenter().y);
    s += buf;
  }
  return s;
}
template <class T> std::string report_of(const bvh::CourseBVH<T> &engine) {
  std::ostringstream out;
  engine.statistics(out, true);
  return out.str();
}
template <class T> std::string report_of(const BVH<T> &edition) { // it prints to std::cout
  std::ostringstream out;
  std::streambuf *old = std::cout.rdbuf(out.rdbuf());
  edition.statistics(true);
  std::cout.rdbuf(old);
  return out.str();
}

// One random case: a scene, parameters, and a way to build (0 bulk,
// 1 insert, 2 discard-overlap sampling). Returns false on a difference.
template <class T> bool one_case(unsigned seed, const std::string &rerun) {
  std::mt19937 rng(seed);
  const std::vector<T> shapes = scene<T>(rng, 1 + rng() % 1200);
  const int split_threshold = 1 + int(rng() % 8), depth_limit = int(rng() % 13), how = int(rng() % 3);
  bvh::CourseBVH<T> engine(split_threshold, depth_limit);
  BVH<T> edition(split_threshold, depth_limit);
  std::string kept_engine, kept_edition; // discard: which candidates each kept
  if (how == 0) {
    engine.construct(shapes);
    edition.construct(shapes);
  }
  for (std::size_t i = 0; how != 0 && i < shapes.size(); ++i) {
    const bool keep_engine = how == 1 || !engine.collision(shapes[i]);
    const bool keep_edition = how == 1 || !edition.collision(shapes[i]);
    kept_engine += keep_engine ? '1' : '0';
    kept_edition += keep_edition ? '1' : '0';
    if (keep_engine) engine.insert(shapes[i]);
    if (keep_edition) edition.insert(shapes[i]);
  }
  note("seed " + std::to_string(seed) + " (" + rerun + "): " + std::to_string(shapes.size()) + " shapes, split_threshold " +
       std::to_string(split_threshold) + ", depth_limit " + std::to_string(depth_limit) + ", " +
       (how == 0 ? "bulk" : how == 1 ? "insert" : "discard-overlap"));
  const bool same_kept = kept_engine == kept_edition;
  const bool same_report = report_of(engine) == report_of(edition);
  const bool same_order = order_of(engine) == order_of(edition);
  CHECK(same_kept);
  CHECK(same_report);
  CHECK(same_order);
  return same_kept && same_report && same_order;
}

template <class T> void run_cases(unsigned salt) {
  const int rounds = int(40 * scale());
  for (int r = 0; r < rounds; ++r)
    if (!one_case<T>(base_seed() + salt * 100003u + unsigned(r),
                     "BVH_SEED=" + std::to_string(base_seed()) + ", round " + std::to_string(r)))
      return; // (the first failure is enough)
}

} // namespace

// The edition's copy constructor and assignment, failing at their k-th
// allocation for every k: each throws std::bad_alloc and changes nothing
// (the assigned-to tree keeps its shapes), and what they had made is freed
// (the sanitizer and valgrind builds see any leak or double free).
TEST(edition_copies_survive_failed_allocations) {
  std::mt19937 rng(base_seed());
  const std::vector<Disk> shapes = scene<Disk>(rng, 100);
  BVH<Disk> tree(2, 0), other(3, 4);
  for (const Disk &d : shapes) tree.insert(d);
  other.construct(std::vector<Disk>(shapes.begin(), shapes.begin() + 50));
  const std::string tree_order = order_of(tree), other_order = order_of(other);
  int failed = 0;
  for (long k = 0;; ++k) {
    note("failing allocation " + std::to_string(k));
    bool threw = false;
    alloc_countdown = k;
    try {
      BVH<Disk> copy(tree);
      other = tree;
    } catch (const std::bad_alloc &) {
      threw = true;
    }
    alloc_countdown = -1;
    if (!threw) break;
    ++failed;
    CHECK(order_of(tree) == tree_order);
    CHECK(order_of(other) == other_order); // (whether the copy or the assignment failed)
    other.construct(std::vector<Disk>(shapes.begin(), shapes.begin() + 50)); // as before the next round
  }
  CHECK(failed > 100); // each copy allocates every node and every leaf's vector
  CHECK(order_of(other) == tree_order);
}

TEST(editions_agree_on_disks) { run_cases<Disk>(1); }
TEST(editions_agree_on_triangles) { run_cases<Triangle>(2); }
TEST(editions_agree_on_quads) { run_cases<Quad>(3); }

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
