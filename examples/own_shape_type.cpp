// examples/own_shape_type.cpp — BVH<T> over a shape type of your own: a
// struct with a box, a centre and a free intersect() is all it takes.
// Poisson-disk sampling of random balls with the tree, checked against a
// brute-force scan; then every ball touching a probe, checked the same way.
//
//   g++ -std=c++17 -O2 -Iinclude examples/own_shape_type.cpp -o own_shape_type && ./own_shape_type
#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <tuple>
#include <vector>

// [readme:own_shape_type]
namespace game {
struct XY { double x, y; };
struct Extent { XY lo, hi; XY getMin() const { return lo; } XY getMax() const { return hi; } };
struct Ball { // a closed disk of radius r around (x, y)
  double x, y, r;
  Extent getBox() const { return {{x - r, y - r}, {x + r, y + r}}; }
  XY getCenter() const { return {x, y}; }
};
bool intersect(const Ball &a, const Ball &b) { // found by argument-dependent lookup
  const double dx = a.x - b.x, dy = a.y - b.y, reach = a.r + b.r;
  return dx * dx + dy * dy <= reach * reach;
}
} // namespace game
// [end]

int main(int argc, char **argv) {
  const unsigned seed = argc > 1 ? unsigned(std::atoi(argv[1])) : 7u;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(0, 1000), radius(2, 12);
  std::vector<game::Ball> candidates(20000);
  for (game::Ball &b : candidates) b = {coord(rng), coord(rng), radius(rng)};

  // [readme:own_shape_sampling]
  BVH<game::Ball> tree;
  for (const game::Ball &b : candidates)
    if (!tree.collision(b)) tree.insert(b);
  // [end]

  // The same sampling without a tree.
  std::vector<game::Ball> kept;
  for (const game::Ball &b : candidates) {
    bool touches = false;
    for (const game::Ball &k : kept) touches = touches || intersect(k, b);
    if (!touches) kept.push_back(b);
  }
  // The same balls, whatever the order (the tree iterates leaf by leaf).
  using Key = std::tuple<double, double, double>;
  std::vector<Key> from_tree, from_scan;
  for (const game::Ball &b : tree) from_tree.emplace_back(b.x, b.y, b.r);
  for (const game::Ball &b : kept) from_scan.emplace_back(b.x, b.y, b.r);
  std::sort(from_tree.begin(), from_tree.end());
  std::sort(from_scan.begin(), from_scan.end());
  int failures = 0;
  if (from_tree != from_scan) {
    std::printf("FAIL seed %u: the tree kept %zu balls, the scan %zu (or others)\n", seed, tree.size(), kept.size());
    ++failures;
  }
  // Every candidate as a probe: the tree's answer against a scan of what is kept.
  std::size_t hits = 0;
  for (const game::Ball &probe : candidates) {
    std::size_t by_tree = 0, by_scan = 0;
    tree.query(probe, [&](const game::Ball &) { ++by_tree; });
    for (const game::Ball &k : kept) by_scan += intersect(k, probe);
    hits += by_tree;
    if (by_tree != by_scan && failures++ < 5)
      std::printf("FAIL seed %u: probe (%g, %g) touches %zu kept balls, the tree found %zu\n", seed, probe.x, probe.y,
                  by_scan, by_tree);
  }
  std::string why;
  if (!tree.validate(&why)) {
    std::printf("FAIL seed %u: %s\n", seed, why.c_str());
    ++failures;
  }
  std::printf("kept %zu of %zu balls, %zu probe hits; brute force agrees: %s\n%s\n", kept.size(),
              candidates.size(), hits, failures ? "no" : "yes", failures ? "FAIL" : "ok");
  return failures ? 1 : 0;
}
