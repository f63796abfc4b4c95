// bench/random_disks.h — n disks with centres uniform in the 1000 x 1000
// canvas and radii uniform in [rlo, rhi), the same for the same seed: the
// scenes of bench/dynamic.cpp and bench/instructions.cpp.
#ifndef BVH_BENCH_RANDOM_DISKS_H
#define BVH_BENCH_RANDOM_DISKS_H

#include <cstdint>
#include <random>
#include <vector>

#include <bvh/shapes.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

inline std::vector<Disk> random_disks(std::size_t n, double rlo, double rhi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(0, 1000), r(rlo, rhi);
  std::vector<Disk> v;
  v.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng);
    v.emplace_back(Point(x, y), r(rng), Color(0, 0, 0));
  }
  return v;
}

#endif // BVH_BENCH_RANDOM_DISKS_H
