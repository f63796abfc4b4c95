// bench/dynamic.cpp — `make bench-dynamic`: all-pairs collision against the
// peers' best ways to do it, and the tree's quality under long insert/erase
// churn. Writes its table to stdout (bench/results_dynamic.txt keeps the
// last run).
//
// Pairs: every method counts the intersecting pairs of the same disks with
// the same exact predicate (intersect.h), and the run checks they agree.
//   ours   construct() + count_overlapping_pairs() (self-traversal), the
//          course's tree (width 3, split_threshold 4), then width 8 with
//          split_threshold 16 and 32
//   Boost  packed rtree (range constructor) + one query per disk, pairs i < j
//   Box2D  CreateProxy per disk + one Query per proxy, pairs i < j (what
//          its broadphase does)
//   brute  the O(n^2) scan, small n only
// Churn: a tree grown by insert() to N disks, then rounds of erase(value) of
// a random stored disk and insert() of a new one; at checkpoints the SAH
// cost (inner + leaf area, as statistics() prints them) against a bulk
// construct() over the same disks, the height, and the time per erase.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdint>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "random_disks.h"

#if !defined(BENCH_NO_BOOST) && __has_include(<boost/geometry.hpp>)
#define HAVE_BOOST 1
#define BOOST_ALLOW_DEPRECATED_HEADERS // Boost 1.74's own includes, not ours
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#else
#define HAVE_BOOST 0
#endif
#if defined(BENCH_HAVE_BOX2D_LIB) && __has_include(<box2d/b2_dynamic_tree.h>)
#define HAVE_BOX2D 1
#include <box2d/b2_dynamic_tree.h>
#else
#define HAVE_BOX2D 0
#endif

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Median seconds of `runs` calls of f(), which returns the pair count.
template <class F> double median_time(int runs, F &&f, std::size_t &count) {
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) {
    const double start = now();
    count = f();
    t.push_back(now() - start);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

/// construct() + count_overlapping_pairs() at width W, split_threshold `split`.
template <int W = 3> std::size_t pairs_ours(const std::vector<Disk> &v, int split = 4) {
  BVH<Disk, bvh::shape_traits<Disk>, W> tree(split, CourseBVH<Disk>::unlimited);
  tree.construct(v);
  return tree.count_overlapping_pairs();
}

std::size_t pairs_brute(const std::vector<Disk> &v) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < v.size(); ++i)
    for (std::size_t j = i + 1; j < v.size(); ++j) k += intersect(v[i], v[j]);
  return k;
}

#if HAVE_BOOST
namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using BPoint = bg::model::point<double, 2, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, std::uint32_t>;
BBox boost_box(const BoundingBox &b) {
  return BBox(BPoint(b.getMin().x, b.getMin().y), BPoint(b.getMax().x, b.getMax().y));
}
std::size_t pairs_boost(const std::vector<Disk> &v) {
  std::vector<BValue> values;
  values.reserve(v.size());
  for (std::uint32_t i = 0; i < v.size(); ++i) values.emplace_back(boost_box(v[i].getBox()), i);
  const bgi::rtree<BValue, bgi::quadratic<16>> rt(values.begin(), values.end());
  std::size_t k = 0;
  for (std::uint32_t i = 0; i < v.size(); ++i)
    for (auto it = rt.qbegin(bgi::intersects(values[i].first)); it != rt.qend(); ++it)
      if (it->second > i && intersect(v[i], v[it->second])) ++k;
  return k;
}
#endif

#if HAVE_BOX2D
b2AABB box2d_box(const BoundingBox &b) { // outwards to float, so no box is cut
  b2AABB a;
  a.lowerBound.Set(std::nextafter(float(b.getMin().x), -1e30f), std::nextafter(float(b.getMin().y), -1e30f));
  a.upperBound.Set(std::nextafter(float(b.getMax().x), 1e30f), std::nextafter(float(b.getMax().y), 1e30f));
  return a;
}
struct PairQuery {
  const b2DynamicTree *tree;
  const std::vector<Disk> *v;
  std::uint32_t self;
  std::size_t k = 0;
  bool QueryCallback(int32 proxy) {
    const auto j = std::uint32_t(reinterpret_cast<std::uintptr_t>(tree->GetUserData(proxy)));
    if (j > self && intersect((*v)[self], (*v)[j])) ++k;
    return true;
  }
};
std::size_t pairs_box2d(const std::vector<Disk> &v) {
  b2DynamicTree tree;
  std::vector<int32> proxy(v.size());
  for (std::uint32_t i = 0; i < v.size(); ++i)
    proxy[i] = tree.CreateProxy(box2d_box(v[i].getBox()), reinterpret_cast<void *>(std::uintptr_t(i)));
  std::size_t k = 0;
  for (std::uint32_t i = 0; i < v.size(); ++i) {
    PairQuery q{&tree, &v, i};
    tree.Query(&q, tree.GetFatAABB(proxy[i]));
    k += q.k;
  }
  return k;
}
#endif

void pairs_row(const char *scene, const std::vector<Disk> &v, int runs) {
  std::size_t ours_count = 0, count = 0;
  const double ours = median_time(runs, [&] { return pairs_ours(v); }, ours_count);
  std::printf("%-34s %-30s %9.4f %7.2f %10zu\n", scene, "ours construct + self-traversal", ours, 1.0, ours_count);
  auto row = [&](const char *name, double t) {
    std::printf("%-34s %-30s %9.4f %7.2f %10zu%s\n", "", name, t, t / ours, count,
                count == ours_count ? "" : "   DISAGREES");
    if (count != ours_count) std::exit(1);
  };
  row("ours width 8, split 16", median_time(runs, [&] { return pairs_ours<8>(v, 16); }, count));
  row("ours width 8, split 32", median_time(runs, [&] { return pairs_ours<8>(v, 32); }, count));
#if HAVE_BOOST
  row("Boost packed rtree + queries", median_time(runs, [&] { return pairs_boost(v); }, count));
#else
  std::printf("%-34s %s\n", "", "Boost.Geometry: not installed (apt-get install libboost-dev)");
#endif
#if HAVE_BOX2D
  row("Box2D proxies + queries", median_time(runs, [&] { return pairs_box2d(v); }, count));
#else
  std::printf("%-34s %s\n", "", "Box2D: not installed (apt-get install libbox2d-dev)");
#endif
  if (v.size() <= 20000) row("brute force O(n^2)", median_time(runs, [&] { return pairs_brute(v); }, count));
}

double sah(const CourseBVH<Disk> &tree) {
  std::ostringstream out;
  tree.statistics(out, false);
  double inner = 0, leaf = 0;
  const std::string s = out.str();
  std::sscanf(s.c_str() + s.find("inner node area:") + 16, "%lf", &inner);
  std::sscanf(s.c_str() + s.find("leaf node area:") + 15, "%lf", &leaf);
  return inner + leaf;
}

void churn(std::size_t n, std::size_t ops, std::uint64_t seed) {
  std::printf("\nchurn: %zu disks r0.5-2 grown by insert(), then %zu rounds of erase(value) + insert(); "
              "BVH(4, unlimited)\n",
              n, ops);
  std::printf("%12s %10s %10s %8s %8s %8s %12s\n", "operations", "SAH", "bulk SAH", "ratio", "height",
              "bulk h", "us/erase");
  std::mt19937_64 rng(seed);
  std::vector<Disk> live = random_disks(n, 0.5, 2, seed);
  CourseBVH<Disk> tree(4, CourseBVH<Disk>::unlimited);
  for (const Disk &d : live) tree.insert(d);
  std::size_t done = 0;
  double erase_seconds = 0;
  const std::size_t step = ops / 5;
  for (int checkpoint = 0; checkpoint <= 5; ++checkpoint) {
    CourseBVH<Disk> bulk(4, CourseBVH<Disk>::unlimited);
    bulk.construct(live);
    std::printf("%12zu %10.3f %10.3f %8.3f %8d %8d %12.3f\n", done, sah(tree), sah(bulk), sah(tree) / sah(bulk),
                tree.height(), bulk.height(), done ? 1e6 * erase_seconds / double(done) : 0.0);
    if (checkpoint == 5) break;
    const std::vector<Disk> fresh = random_disks(step, 0.5, 2, rng());
    for (std::size_t i = 0; i < step; ++i) {
      const std::size_t at = std::size_t(rng() % live.size());
      const double start = now();
      const std::size_t removed = tree.erase(live[at]);
      erase_seconds += now() - start;
      if (removed != 1) {
        std::printf("erase removed %zu, not 1\n", removed);
        std::exit(1);
      }
      live[at] = fresh[i];
      tree.insert(fresh[i]);
    }
    done += step;
  }
  if (!tree.validate()) {
    std::printf("validate() failed after churn\n");
    std::exit(1);
  }
}

} // namespace

int main(int argc, char **argv) {
  const bool quick = argc > 1 && std::string(argv[1]) == "--quick";
  const int runs = quick ? 1 : 5;
  std::printf("bvh dynamic benchmark: median of %d runs in one process; g++ -O2\n\n", runs);
  std::printf("%-34s %-30s %9s %7s %10s\n", "all pairs", "method", "median s", "x ours", "pairs");
  std::printf("%s\n", std::string(94, '-').c_str());
  pairs_row("10k disks r2-7.5", random_disks(10000, 2, 7.5, 1), runs);
  pairs_row("100k disks r2-7.5", random_disks(100000, 2, 7.5, 2), runs);
  if (!quick) pairs_row("1M disks r0.2-0.6", random_disks(1000000, 0.2, 0.6, 3), 3);
  churn(quick ? 20000 : 100000, quick ? 100000 : 1000000, 4);
  return 0;
}
