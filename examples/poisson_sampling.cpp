// examples/poisson_sampling.cpp — Poisson-disk sampling: keep each candidate
// disk that touches no disk kept so far (README.txt, THE LIBRARY IN TEN LINES; what
// bvh.out --incremental --discard_overlap does). Checks the result against
// an O(n^2) scan: no two kept disks touch, and every discarded one touches
// an earlier kept one. Exit status 1 if not.
#include <iostream>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h> // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(7);
  std::vector<Disk> candidates;
  for (int i = 0; i < 5000; ++i)
    candidates.push_back(
        Disk(Point(rng.uniform(0, 1000), rng.uniform(0, 1000)), rng.uniform(5, 15), Color(0, 0, 255)));
  // [readme:poisson]
  BVH<Disk> kept(BVH<Disk>::default_split, /*depth_limit=*/8);
  for (const Disk &d : candidates)
    if (!kept.collision(d)) kept.insert(d);   // Poisson-disk sampling
  // [end]
  // The same sampling by a scan over a vector.
  std::vector<Disk> scan;
  for (const Disk &d : candidates) {
    bool touches = false;
    for (const Disk &k : scan) touches = touches || intersect(k, d);
    if (!touches) scan.push_back(d);
  }
  std::vector<Disk> from_tree(kept.begin(), kept.end());
  bool same = from_tree.size() == scan.size();
  // The tree's order is its own; compare as sets (each scan disk is in the tree once).
  for (const Disk &d : scan) {
    std::size_t copies = 0;
    for (const Disk &k : from_tree) copies += k == d;
    same = same && copies == 1;
  }
  bool apart = true;
  for (std::size_t i = 0; i < from_tree.size(); ++i)
    for (std::size_t j = i + 1; j < from_tree.size(); ++j) apart = apart && !intersect(from_tree[i], from_tree[j]);
  std::cout << "poisson_sampling: kept " << kept.size() << " of " << candidates.size() << " (scan: " << scan.size()
            << "), none touching: " << apart << ", validate " << kept.validate() << "\n";
  const bool ok = same && apart && kept.validate() && kept.size() > 0 && kept.size() < candidates.size();
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
