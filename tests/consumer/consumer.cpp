// tests/consumer/consumer.cpp — a program of another project: reads a scene
// with scene.h, samples it as bvh.out --discard_overlap does, and checks the
// sample against a scan. Prints "consumer: ok ..." and exits 0, or exits 1.
#include <iostream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h>
using namespace bvh; // the library's names (Disk, BVH, intersect), unqualified

static_assert(__cplusplus >= 201703L, "bvh::bvh asks for C++17");
// bvh::bvh puts only the folder that holds bvh/ on the include path, both
// installed and from add_subdirectory: its headers' own names ("shapes.h",
// "svg.h") stay free for the user's files.
#if __has_include("shapes.h") || __has_include(<bvh.h>)
#error "bvh::bvh exposes its headers without the bvh/ prefix"
#endif

#define BVH_STR2(x) #x
#define BVH_STR(x) BVH_STR2(x)
// The header's version is the package's (CMake's project version).
static_assert(BVH_VERSION == BVH_VERSION_MAJOR * 10000 + BVH_VERSION_MINOR * 100 + BVH_VERSION_PATCH, "BVH_VERSION");

int main(int argc, char **argv) {
#ifdef BVH_PACKAGE_VERSION
  const std::string header_version =
      BVH_STR(BVH_VERSION_MAJOR) "." BVH_STR(BVH_VERSION_MINOR) "." BVH_STR(BVH_VERSION_PATCH);
  if (header_version != BVH_PACKAGE_VERSION) {
    std::cerr << "consumer: the header says version " << header_version << ", the package " << BVH_PACKAGE_VERSION
              << "\n";
    return 1;
  }
#endif
  if (argc != 2) {
    std::cerr << "usage: consumer SCENE.disks\n";
    return 2;
  }
  std::vector<Disk> disks;
  std::string error;
  if (!bvh_scene::load_scene(argv[1], disks, error)) {
    std::cerr << "consumer: " << error << "\n";
    return 1;
  }
  BVH<Disk> tree; // the default tree: width 8, up to 32 shapes a leaf
  for (const Disk &d : disks)
    if (!tree.collision(d)) tree.insert(d);
  std::vector<Disk> scan;
  for (const Disk &d : disks) {
    bool touches = false;
    for (const Disk &k : scan) touches = touches || intersect(k, d);
    if (!touches) scan.push_back(d);
  }
  const bool ok = tree.size() == scan.size() && tree.validate() && !disks.empty();
  std::cout << "consumer: " << (ok ? "ok" : "MISMATCH") << " read " << disks.size() << ", kept " << tree.size()
            << " (scan " << scan.size() << ")\n";
  return ok ? 0 : 1;
}
