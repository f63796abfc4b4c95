// tests/test_names.cpp — the library fits beside a program's own global
// names. Including <bvh/bvh.h> (and with it shapes.h, intersect.h,
// distance.h) and <bvh/svg.h> declares nothing at global scope, so a program
// with its own Point, Color, BoundingBox, Disk, Shape, BVH, intersect and
// distance compiles: any global name bvh.h declared would clash with these.
// Then the library works through namespace bvh, and a user type with
// traits works too.
#include <bvh/bvh.h>
#include <bvh/svg.h>

// The program's own globals, as a game (raylib: Color) or a GIS has them.
struct Point { float x, y; };
struct Color { unsigned char r, g, b, a; };
struct BoundingBox { Point lo, hi; };
struct Disk { Point c; float r; };
struct Shape { int kind; };
struct Triangle {};
struct Quad {};
template <class T> struct BVH { T only; };
inline bool intersect(const Disk &a, const Disk &b) {
  const float dx = a.c.x - b.c.x, dy = a.c.y - b.c.y, reach = a.r + b.r;
  return dx * dx + dy * dy <= reach * reach;
}
inline double distance(const Point &a, const Point &b) { return double(a.x - b.x) + double(a.y - b.y); }
inline void render_start(int) {}

// A user's global type, indexed through its traits. (Inside a
// specialization of bvh::box_traits or bvh::shape_traits, names are looked
// up in namespace bvh first: the program's own clashing names need "::".)
template <> struct bvh::box_traits<::BoundingBox> {
  static bvh::bounds get(const ::BoundingBox &b) { return {b.lo.x, b.lo.y, b.hi.x, b.hi.y}; }
};
template <> struct bvh::shape_traits<::Disk> {
  static ::BoundingBox box(const ::Disk &d) { return {{d.c.x - d.r, d.c.y - d.r}, {d.c.x + d.r, d.c.y + d.r}}; }
  static ::Point center(const ::Disk &d) { return d.c; }
  static bool intersect(const ::Disk &a, const ::Disk &b) { return ::intersect(a, b); }
};

#include "check.h"

#include <random>
#include <vector>

TEST(library_through_namespace_bvh) {
  std::vector<bvh::Disk> disks;
  for (int i = 0; i < 50; ++i) disks.emplace_back(bvh::Point(20.0 * i, 10), 12, bvh::Color(0, 0, 0));
  bvh::CourseBVH<bvh::Disk> tree(4);
  tree.construct(disks);
  CHECK_EQ(tree.size(), 50u);
  CHECK(tree.validate());
  CHECK(tree.collision(bvh::Disk(bvh::Point(30, 10), 1, bvh::Color(0, 0, 0))));
  CHECK(!tree.collision(bvh::Disk(bvh::Point(30, 500), 1, bvh::Color(0, 0, 0))));
  CHECK(bvh::intersect(disks[0], disks[1])); // 20 apart, radii 12
  CHECK_EQ(bvh::distance(bvh::Point(0, 0), bvh::Point(3, 4)), 5.0);
  const bvh::Disk *near = tree.nearest(bvh::Point(41, 40));
  CHECK(near != nullptr && near->getCenter().x == 40.0);
}

TEST(own_global_type_with_traits) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coord(0, 500), radius(1, 10);
  std::vector<Disk> mine, kept;
  for (int i = 0; i < 3000; ++i) mine.push_back(Disk{{coord(rng), coord(rng)}, radius(rng)});
  bvh::CourseBVH<Disk> tree(4);
  for (const Disk &d : mine) {
    if (!tree.collision(d)) tree.insert(d);
    bool touches = false;
    for (const Disk &k : kept) touches = touches || intersect(k, d);
    if (!touches) kept.push_back(d);
  }
  CHECK_EQ(tree.size(), kept.size());
  CHECK(tree.validate());
  std::size_t seen = 0, scanned = 0;
  const BoundingBox window{{100, 100}, {200, 150}};
  tree.query(window, [&](const Disk &) { ++seen; });
  for (const Disk &d : kept)
    scanned += d.c.x - d.r <= 200 && 100 <= d.c.x + d.r && d.c.y - d.r <= 150 && 100 <= d.c.y + d.r;
  CHECK_EQ(seen, scanned);
  const BVH<int> theirs{7}; // the program's own BVH is still its own
  CHECK_EQ(theirs.only, 7);
}

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
