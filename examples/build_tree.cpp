// examples/build_tree.cpp — build a tree over disks, ask whether a disk
// collides with any of them, walk the tree (README.txt, THE LIBRARY IN TEN LINES).
// Checks every answer against a scan of the vector; exit status 1 if one
// differs. make test builds and runs it.
#include <iostream>
#include <sstream>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h> // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(12);
  std::vector<Disk> disks;
  for (int i = 0; i < 1000; ++i)
    disks.push_back(Disk(Point(rng.uniform(0, 1000), rng.uniform(0, 1000)), rng.uniform(1, 8), Color(0, 0, 0)));
  // The snippet prints to std::cout; the listing is caught here and counted.
  std::ostringstream listing;
  std::streambuf *const screen = std::cout.rdbuf(listing.rdbuf());
  // [readme:build]
  BVH<Disk> tree;          // the default: width 8, up to 32 shapes a leaf
  tree.construct(disks);   // or insert()
  bool hit = tree.collision(Disk(Point(500, 500), 10, Color(0, 0, 0)));
  for (const Disk &d : tree) std::cout << d.getBox() << "\n";
  // [end]
  std::cout.rdbuf(screen);
  bool brute = false;
  for (const Disk &d : disks) brute = brute || intersect(d, Disk(Point(500, 500), 10, Color(0, 0, 0)));
  std::size_t lines = 0;
  for (char c : listing.str()) lines += c == '\n';
  std::cout << "build_tree: " << tree.size() << " disks, " << lines << " listed, collision " << hit
            << " (scan: " << brute << "), validate " << tree.validate() << "\n";
  const bool ok = tree.size() == disks.size() && lines == disks.size() && hit == brute && tree.validate();
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
