// examples/all_pairs.cpp — every intersecting pair of a mixed scene once
// (docs/library.txt, QUERIES AND ALL PAIRS), against the O(n^2) scan of every
// pair (exit status 1 if they differ).
#include <iostream>
#include <set>
#include <utility>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h> // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(5);
  std::vector<Shape> scene;
  for (int i = 0; i < 1500; ++i) {
    const Point c(rng.uniform(10, 990), rng.uniform(10, 990));
    const double r = rng.uniform(2, 9);
    if (i % 3 == 0) scene.push_back(Disk(c, r, Color(255, 0, 0)));
    if (i % 3 == 1) scene.push_back(Triangle(Point(c.x - r, c.y), Point(c.x + r, c.y), Point(c.x, c.y + r)));
    if (i % 3 == 2)
      scene.push_back(Quad(Point(c.x - r, c.y - r), Point(c.x + r, c.y - r), Point(c.x + r, c.y + r), Point(c.x - r, c.y + r)));
  }
  BVH<Shape> tree;
  tree.construct(scene);
  std::size_t listed = 0;
  // [readme:pairs]
  // every intersecting pair once, or just their number
  tree.for_each_overlapping_pair([&](const Shape &a, const Shape &b) { listed += intersect(a, b); });
  std::size_t k = tree.count_overlapping_pairs();
  // [end]
  std::size_t scan = 0;
  for (std::size_t i = 0; i < scene.size(); ++i)
    for (std::size_t j = i + 1; j < scene.size(); ++j) scan += intersect(scene[i], scene[j]);
  std::cout << "all_pairs: " << k << " pairs counted, " << listed << " listed (scan of every pair: " << scan << ")\n";
  const bool ok = k == scan && listed == scan && scan > 0;
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
