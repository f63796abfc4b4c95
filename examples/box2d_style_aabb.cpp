// examples/box2d_style_aabb.cpp — a game's own types, untouched: bodies
// with a Box2D-style AABB (lowerBound, upperBound), indexed by specializing
// bvh::box_traits and bvh::shape_traits, and queried with an AABB, beside
// the game's own global Vec2 and Color (the library declares nothing at
// global scope).
// Checked against a brute-force scan.
//
//   g++ -std=c++17 -O2 -Iinclude examples/box2d_style_aabb.cpp -o box2d_style_aabb && ./box2d_style_aabb
#include <bvh/bvh.h>

#include <cstdio>
#include <random>
#include <vector>

// The game's own types, as it had them before it used bvh.h.
struct Color { unsigned char r, g, b, a; }; // (raylib has one of these)
struct Vec2 { float x, y; };
struct AABB { Vec2 lowerBound, upperBound; };
struct Body {
  int id;
  AABB fat;
  Vec2 centre() const { return {0.5f * (fat.lowerBound.x + fat.upperBound.x), 0.5f * (fat.lowerBound.y + fat.upperBound.y)}; }
};
bool touch(const AABB &a, const AABB &b) {
  return a.lowerBound.x <= b.upperBound.x && b.lowerBound.x <= a.upperBound.x && a.lowerBound.y <= b.upperBound.y &&
         b.lowerBound.y <= a.upperBound.y;
}

// [readme:box2d_traits]
template <> struct bvh::box_traits<AABB> { // how the tree reads an AABB
  static bvh::bounds get(const AABB &b) { return {b.lowerBound.x, b.lowerBound.y, b.upperBound.x, b.upperBound.y}; }
};
template <> struct bvh::shape_traits<Body> { // how it reads a Body
  static const AABB &box(const Body &b) { return b.fat; }
  static Vec2 center(const Body &b) { return b.centre(); }
  static bool intersect(const Body &a, const Body &b) { return touch(a.fat, b.fat); }
};
// [end]

int main() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coord(0, 1000), size(1, 20);
  std::vector<Body> bodies;
  for (int i = 0; i < 20000; ++i) {
    const float x = coord(rng), y = coord(rng), w = size(rng), h = size(rng);
    bodies.push_back(Body{i, AABB{{x, y}, {x + w, y + h}}});
  }
  // [readme:box2d_query]
  bvh::BVH<Body> world;
  world.construct(bodies);
  const AABB view{{100, 100}, {300, 250}};
  int seen = 0;
  world.query(view, [&](const Body &) { ++seen; }); // any box type box_traits reads
  // [end]
  int failures = 0, scanned = 0;
  for (const Body &b : bodies) scanned += touch(b.fat, view);
  if (seen != scanned) std::printf("FAIL: query(AABB) found %d, the scan %d\n", seen, scanned), ++failures;
  int lazily = 0;
  for (const Body &b : world.overlapping(view)) lazily += touch(b.fat, view);
  if (lazily != scanned) std::printf("FAIL: overlapping(AABB) found %d, the scan %d\n", lazily, scanned), ++failures;
  // Bodies touching the first body, by its own intersect.
  int by_tree = 0, by_scan = 0;
  world.query(bodies[0], [&](const Body &) { ++by_tree; });
  for (const Body &b : bodies) by_scan += touch(b.fat, bodies[0].fat);
  if (by_tree != by_scan) std::printf("FAIL: query(Body) found %d, the scan %d\n", by_tree, by_scan), ++failures;
  const Color tint{255, 0, 0, 255}; // the game's own Color, beside bvh::Color
  if (!world.validate() || tint.r != 255) std::printf("FAIL: validate()\n"), ++failures;
  std::printf("%d bodies in view, %d touch body 0; brute force agrees: %s\n%s\n", seen, by_tree,
              failures ? "no" : "yes", failures ? "FAIL" : "ok");
  return failures ? 1 : 0;
}
