// examples/ids_into_arrays.cpp — the tree stores only 32-bit ids; the
// circles live in the program's own arrays (structure of arrays), and an
// adaptor, kept by the tree, reads them. Poisson-disk sampling by id,
// a box query, and moves by handle, checked against brute-force scans.
//
//   g++ -std=c++17 -O2 -Iinclude examples/ids_into_arrays.cpp -o ids_into_arrays && ./ids_into_arrays
#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

// [readme:ids_adaptor]
struct Circles { std::vector<double> x, y, r; }; // the program's own arrays

struct CircleIds { // how the tree reads an id: an adaptor with state
  const Circles *c;
  bvh::bounds box(std::uint32_t i) const {
    return {c->x[i] - c->r[i], c->y[i] - c->r[i], c->x[i] + c->r[i], c->y[i] + c->r[i]};
  }
  bvh::Point center(std::uint32_t i) const { return {c->x[i], c->y[i]}; }
  bool intersect(std::uint32_t i, std::uint32_t j) const {
    const double dx = c->x[i] - c->x[j], dy = c->y[i] - c->y[j], reach = c->r[i] + c->r[j];
    return dx * dx + dy * dy <= reach * reach;
  }
};
// [end]

int main() {
  Circles circles;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(0, 1000), radius(2, 8);
  for (int i = 0; i < 20000; ++i) {
    circles.x.push_back(coord(rng));
    circles.y.push_back(coord(rng));
    circles.r.push_back(radius(rng));
  }
  const CircleIds read{&circles};
  // [readme:ids_sampling]
  bvh::BVH<std::uint32_t, CircleIds> tree(bvh::default_split_threshold, 0, CircleIds{&circles});
  std::vector<bvh::BVH<std::uint32_t, CircleIds>::handle> kept;
  for (std::uint32_t i = 0; i < circles.x.size(); ++i)
    if (!tree.collision(i)) kept.push_back(tree.insert(i));
  // [end]
  int failures = 0;
  std::vector<std::uint32_t> scan;
  for (std::uint32_t i = 0; i < circles.x.size(); ++i) {
    bool touches = false;
    for (std::uint32_t k : scan) touches = touches || read.intersect(i, k);
    if (!touches) scan.push_back(i);
  }
  if (scan.size() != kept.size()) std::printf("FAIL: kept %zu, the scan %zu\n", kept.size(), scan.size()), ++failures;
  for (std::size_t k = 0; k < kept.size() && k < scan.size(); ++k)
    if (tree.get(kept[k]) != scan[k]) std::printf("FAIL: handle %zu names id %u, not %u\n", k, tree.get(kept[k]), scan[k]), ++failures;
  // A box query by ids.
  const bvh::bounds window{200, 200, 400, 300};
  std::size_t by_tree = 0, by_scan = 0;
  tree.query(window, [&](std::uint32_t) { ++by_tree; });
  for (std::uint32_t i : scan) {
    const bvh::bounds b = read.box(i);
    by_scan += b.min_x <= window.max_x && window.min_x <= b.max_x && b.min_y <= window.max_y && window.min_y <= b.max_y;
  }
  if (by_tree != by_scan) std::printf("FAIL: window found %zu, the scan %zu\n", by_tree, by_scan), ++failures;
  // Moving circles: change the arrays, then tell the tree by handle.
  for (std::size_t k = 0; k < kept.size(); k += 7) {
    const std::uint32_t i = tree.get(kept[k]);
    circles.x[i] = coord(rng);
    tree.update(kept[k], i); // the same id, at its new place
  }
  if (!tree.validate()) std::printf("FAIL: validate() after the moves\n"), ++failures;
  std::printf("kept %zu of %zu circles by id, %zu in the window; brute force agrees: %s\n%s\n", kept.size(),
              circles.x.size(), by_tree, failures ? "no" : "yes", failures ? "FAIL" : "ok");
  return failures ? 1 : 0;
}
