// examples/wide_tree.cpp — the default tree, width 8 with 32 shapes a leaf,
// the fastest and smallest configuration measured (docs/library.txt, WIDTH),
// beside the course's ternary tree (CourseBVH): Poisson-disk sampling into both, then
// the same collision queries. Checks that both keep the same disks and
// answer alike (also a wide tree with a margin whose searches decide disks
// from codes at every size), that the wide tree validates and is smaller, and prints
// how full its nodes are. Exit status 1 if not.
#include <iostream>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h> // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(11);
  std::vector<Disk> candidates;
  for (int i = 0; i < 20000; ++i)
    candidates.push_back(Disk(Point(rng.uniform(0, 1000), rng.uniform(0, 1000)), rng.uniform(1, 4), Color(0, 0, 255)));
  // [readme:wide]
  BVH<Disk> wide;                                    // the default: width 8, split 32
  wide.insert_disjoint(candidates);                  // the loop's result, on every core
  const auto fill = wide.fill();                     // mean children / 8, shapes / 32
  // [end]
  CourseBVH<Disk> course;                           // the course's: width 3, split 4
  for (const Disk &d : candidates)
    if (!course.collision(d)) course.insert(d);
  // The same loop into a wide tree with a margin whose collision searches
  // decide disks from the leaves' codes at every size (TUNING): the same
  // answers, faster only on trees larger than the caches.
  // [readme:tuning]
  using Tree = BVH<Disk>;
  Tree tree;
  Tree::Tuning t = tree.tuning();     // a new tree has Tree::default_tuning()
  t.disk_codes_min_shapes = 0;        // decide disks from codes at every size
  tree.set_tuning(t);
  // [end]
  tree.set_margin(1);
  for (const Disk &d : candidates)
    if (!tree.collision(d)) tree.insert(d);
  bool same = wide.size() == course.size() && tree.size() == course.size();
  for (int q = 0; q < 2000; ++q) {
    const Disk probe(Point(rng.uniform(0, 1000), rng.uniform(0, 1000)), rng.uniform(1, 20), Color(0, 0, 0));
    same = same && wide.collision(probe) == course.collision(probe) && tree.collision(probe) == course.collision(probe);
  }
  const std::size_t wide_bytes = wide.memory().total(), course_bytes = course.memory().total();
  std::cout << "wide_tree: kept " << wide.size() << " of " << candidates.size() << " (ternary tree: " << course.size()
            << "), height " << wide.height() << " against " << course.height() << ", " << wide_bytes / wide.size()
            << " bytes a shape against " << course_bytes / course.size() << "; fill: children " << fill.children
            << ", leaves " << fill.shapes << "\n";
  const bool ok = same && wide.validate() && tree.validate() && wide.height() < course.height() &&
                  wide_bytes < course_bytes &&
                  fill.children > 0 && fill.children <= 1 && fill.shapes > 0;
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
