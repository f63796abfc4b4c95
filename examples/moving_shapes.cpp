// examples/moving_shapes.cpp — the moving-shapes API of docs/library.txt (MOVING
// SHAPES): handles from insert(), update() each frame with a margin, the k
// nearest shapes to a point, and a lazy overlapping() range stopped by
// break; each answer compared with a scan of the disks (exit status 1 if one
// differs).
#include <algorithm>
#include <cmath>
#include <iostream>
#include <iterator>
#include <utility>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/distance.h> // distance(point, shape), for the scans below
#include <bvh/scene.h>    // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(11);
  std::vector<Disk> disks;
  for (int i = 0; i < 3000; ++i)
    disks.push_back(Disk(Point(rng.uniform(0, 300), rng.uniform(0, 300)), rng.uniform(0.5, 1.5)));
  const int frames = 20;
  long pairs = 0; // touching pairs in the last frame

  // [readme:moving_shapes]
  BVH<Disk> world;
  world.set_margin(0.5);             // fat leaf boxes: small moves touch no node
  std::vector<BVH<Disk>::handle> id;
  for (const Disk &d : disks) id.push_back(world.insert(d));
  for (int frame = 0; frame < frames; ++frame) {
    for (std::size_t i = 0; i < disks.size(); ++i) {
      const Point c = disks[i].getCenter();
      disks[i] = Disk(Point(c.x + rng.uniform(-1, 1), c.y + rng.uniform(-1, 1)), disks[i].getRadius());
      world.update(id[i], disks[i]);  // the handle stays valid
    }
    long met = 0;                     // the broadphase: who touches whom
    for (const Disk &d : disks) world.query(d, [&](const Disk &) { ++met; });
    pairs = (met - long(disks.size())) / 2;  // each disk meets itself once
  }
  // the 10 disks nearest to a point, nearest first (ties: smaller id first)
  std::vector<BVH<Disk>::neighbor> near;
  world.nearest(Point(150, 150), 10, std::back_inserter(near));
  // a lazy range: stop at the first disk within 5 of (150, 150)
  const Disk *found = nullptr;
  for (const Disk &d : world.overlapping(Disk(Point(150, 150), 5))) { found = &d; break; }
  // [end]

  // The same answers by scans of `disks`, which mirrors the tree.
  long scan_pairs = 0;
  for (std::size_t a = 0; a < disks.size(); ++a)
    for (std::size_t b = a + 1; b < disks.size(); ++b) scan_pairs += intersect(disks[a], disks[b]);
  std::vector<std::pair<double, std::uint32_t>> scan;
  for (std::size_t i = 0; i < disks.size(); ++i) scan.push_back({distance(Point(150, 150), disks[i]), id[i].id});
  std::sort(scan.begin(), scan.end());
  bool ok = near.size() == 10 && pairs == scan_pairs && pairs > 0;
  for (std::size_t k = 0; ok && k < near.size(); ++k)
    ok = near[k].distance == scan[k].first && near[k].id.id == scan[k].second && *near[k].shape == disks[scan[k].second];
  bool any_within = false;
  for (const Disk &d : disks) any_within = any_within || intersect(d, Disk(Point(150, 150), 5));
  ok = ok && (found != nullptr) == any_within && (!found || intersect(*found, Disk(Point(150, 150), 5)));
  for (std::size_t i = 0; ok && i < disks.size(); ++i) ok = world.get(id[i]) == disks[i];
  ok = ok && world.validate();
  std::cout << "moving shapes: " << frames << " frames of " << disks.size() << " disks, " << pairs
            << " touching pairs in the last (scan " << scan_pairs << "), nearest at "
            << near[0].distance << " (scan " << scan[0].first << "), first within 5: "
            << (found ? "yes" : "none") << "\n";
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
