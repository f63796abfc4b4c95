// bench/edition.cpp — `make bench-edition`: the course's edition (the
// top-level bvh.h, ::BVH) beside the engine (include/bvh/bvh.h at the
// course's width 3, bvh::BVH) on the course's questions, for README.txt's
// answers; output to stdout and bench/results_edition.txt.
//
//  1. Discard-overlap sampling (collision, then insert) of 1,000 to
//     1,000,000 random disks of radius 2 to 7.5, against a scan of the
//     kept disks' boxes then the exact test (up to 100,000). Both trees
//     and the scan must keep the same number of disks.
//  2. The build rules on the course's scenes (COURSE_DATA, default
//     ../shared/course): the course's rule against the edition's SAH
//     builder (and the engine's), by the cost statistics() prints, inner
//     + leaf node area, at no depth limit.
// Medians of RUNS runs (default 3) of the wall time of each loop.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "../shapes.h" // the project's shapes under the course's names
#include "../bvh.h"    // the course's edition: ::BVH
#include <bvh/bvh.h>   // the engine: bvh::BVH
#include <bvh/scene.h> // the reader of the course's files

#include "random_disks.h"

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <class F> double median_time(int runs, F f) {
  std::vector<double> t;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(seconds_since(t0));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

template <class Tree> std::size_t sample(const std::vector<Disk> &candidates) {
  Tree tree(4, 0);
  for (const Disk &d : candidates)
    if (!tree.collision(d)) tree.insert(d);
  return tree.size();
}

std::size_t scan(const std::vector<Disk> &candidates) {
  std::vector<Disk> kept;
  for (const Disk &d : candidates) {
    const BoundingBox &b = d.getBox();
    bool hit = false;
    for (const Disk &k : kept) {
      const BoundingBox &c = k.getBox();
      if (c.getMin().x <= b.getMax().x && b.getMin().x <= c.getMax().x && c.getMin().y <= b.getMax().y &&
          b.getMin().y <= c.getMax().y && intersect(k, d)) {
        hit = true;
        break;
      }
    }
    if (!hit) kept.push_back(d);
  }
  return kept.size();
}

// inner + leaf node area, as statistics() prints them.
template <class Tree> double sah_cost(const Tree &tree) {
  std::ostringstream out;
  std::streambuf *old = std::cout.rdbuf(out.rdbuf());
  tree.statistics(false);
  std::cout.rdbuf(old);
  double inner = 0, leaf = 0;
  std::istringstream in(out.str());
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("inner node area:", 0) == 0) inner = std::atof(line.c_str() + 16);
    if (line.rfind("leaf node area:", 0) == 0) leaf = std::atof(line.c_str() + 15);
  }
  return inner + leaf;
}

template <class T> void builders_on(const std::string &folder, const std::string &name) {
  std::vector<T> shapes;
  std::string error;
  if (!bvh_scene::load_scene(folder + "/" + name, shapes, error)) {
    std::printf("  %-24s skipped: %s\n", name.c_str(), error.c_str());
    return;
  }
  const int deep = 1 << 20; // statistics() prints only with a depth limit; this one never binds
  ::BVH<T> course(4, deep), sah(4, deep);
  sah.set_build_rule(::BVH<T>::BuildRule::sah);
  course.construct(shapes);
  sah.construct(shapes);
  bvh::CourseBVH<T> engine_sah(4, deep);
  engine_sah.set_build_rule(bvh::CourseBVH<T>::BuildRule::sah);
  engine_sah.construct(shapes);
  const double c = sah_cost(course), s = sah_cost(sah), e = sah_cost(engine_sah);
  std::printf("  %-24s %8.3f %8.3f %7.3f %10.3f %7.3f\n", name.c_str(), c, s, s / c, e, e / c);
}

} // namespace

int main(int argc, char **argv) {
  int runs = 3;
  for (int i = 1; i + 1 < argc; ++i)
    if (std::string(argv[i]) == "--runs") runs = std::max(1, std::atoi(argv[i + 1]));
  const char *data = std::getenv("COURSE_DATA");
  const std::string folder = data ? data : "../shared/course";

  std::printf("Discard-overlap sampling of random disks (radius 2-7.5), split_threshold 4, no depth limit;\n"
              "median of %d runs, seconds\n\n", runs);
  std::printf("  %10s %8s %10s %10s %10s %12s\n", "candidates", "kept", "edition", "engine w3", "scan", "scan/edition");
  for (std::size_t n : {std::size_t(1000), std::size_t(10000), std::size_t(100000), std::size_t(1000000)}) {
    const std::vector<Disk> disks = random_disks(n, 2, 7.5, 20261207 + n);
    std::size_t kept_edition = 0, kept_engine = 0, kept_scan = 0;
    const double te = median_time(runs, [&] { kept_edition = sample<::BVH<Disk>>(disks); });
    const double tg = median_time(runs, [&] { kept_engine = sample<bvh::CourseBVH<Disk>>(disks); });
    double ts = 0;
    if (n <= 100000) ts = median_time(n >= 100000 ? 1 : runs, [&] { kept_scan = scan(disks); });
    if (kept_engine != kept_edition || (n <= 100000 && kept_scan != kept_edition)) {
      std::printf("MISMATCH: kept %zu (edition), %zu (engine), %zu (scan)\n", kept_edition, kept_engine, kept_scan);
      return 1;
    }
    if (n <= 100000)
      std::printf("  %10zu %8zu %10.4f %10.4f %10.4f %12.1f\n", n, kept_edition, te, tg, ts, ts / te);
    else
      std::printf("  %10zu %8zu %10.4f %10.4f %10s %12s\n", n, kept_edition, te, tg, "(not run)", "");
  }

  std::printf("\nBuild rules on the course's scenes (%s), split_threshold 4, no depth limit:\n"
              "cost = inner + leaf node area as statistics() prints them\n\n", folder.c_str());
  std::printf("  %-24s %8s %8s %7s %10s %7s\n", "scene", "course", "SAH", "/course", "engine SAH", "/course");
  builders_on<Disk>(folder, "5000.disks");
  builders_on<Triangle>(folder, "5000.triangles");
  builders_on<Quad>(folder, "5000.quads");
  builders_on<Triangle>(folder, "overlap_1000.triangles");
  builders_on<Disk>(folder, "overlap_1000.disks");
  return 0;
}
