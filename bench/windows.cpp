// bench/windows.cpp — bulk window queries, the job of a map or a sprite
// layer: N boxes built in bulk, then Q window queries, each counting the
// boxes it meets (boundaries count). Three ways to hold the boxes:
//   stored   bvh::BVH<Rect>: the tree keeps the boxes in its leaves
//   ids      bvh::BVH<std::uint32_t, RectIds>: the tree keeps ids, and an
//            adaptor reads each id's box from the program's own array
//   boost    Boost.Geometry's rtree, packed (bulk-loaded) rstar<16>, of
//            (box, id) pairs (skipped with a notice when not installed)
// Every method must find the same total count before its time is printed.
// Each query's callback reads the value it is given (the stored box's
// corner, the id), as a program's would.
// Each time is the median of --runs runs (build and queries together, and
// the queries alone), in this one process, the methods taking turns.
//   build/bench_windows [--n N] [--q Q] [--runs R] [--seed S]
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <bvh/bvh.h>

#include "peers.h"

namespace {

/// A program's own box type, stored in the tree.
struct Rect {
  bvh::BoundingBox box;
  const bvh::BoundingBox &getBox() const { return box; }
  bvh::Point getCenter() const {
    return bvh::Point(0.5 * (box.getMin().x + box.getMax().x), 0.5 * (box.getMin().y + box.getMax().y));
  }
};
bool intersect(const Rect &a, const Rect &b) { return a.box.overlaps(b.box); }

/// Ids into the program's array of boxes, read through an adaptor.
struct RectIds {
  const std::vector<bvh::bounds> *boxes;
  bvh::bounds box(std::uint32_t i) const { return (*boxes)[i]; }
  bvh::Point center(std::uint32_t i) const {
    const bvh::bounds &b = (*boxes)[i];
    return {0.5 * (b.min_x + b.max_x), 0.5 * (b.min_y + b.max_y)};
  }
  bool intersect(std::uint32_t i, std::uint32_t j) const {
    const bvh::bounds &a = (*boxes)[i], &b = (*boxes)[j];
    return a.min_x <= b.max_x && b.min_x <= a.max_x && a.min_y <= b.max_y && b.min_y <= a.max_y;
  }
};

struct Scene {
  std::vector<bvh::bounds> boxes, windows;
};

Scene make_scene(std::size_t n, std::size_t q, unsigned seed) {
  std::mt19937_64 rng(seed);
  const double side = 10000;
  std::uniform_real_distribution<double> at(0, side), small(1, 10), big(50, 150);
  Scene s;
  s.boxes.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = at(rng), y = at(rng);
    s.boxes.push_back({x, y, x + small(rng), y + small(rng)});
  }
  for (std::size_t i = 0; i < q; ++i) {
    const double x = at(rng), y = at(rng);
    s.windows.push_back({x, y, x + big(rng), y + big(rng)});
  }
  return s;
}

bvh::BoundingBox to_box(const bvh::bounds &b) {
  return bvh::BoundingBox(bvh::Point(b.min_x, b.min_y), bvh::Point(b.max_x, b.max_y));
}

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Run {
  double total = 0, queries = 0;
  std::uint64_t found = 0;
  double checksum = 0; // what the callbacks read of each value found, so that they read it
  double index_mb = 0; // the tree's own bytes (memory()), 0 where not known
};

Run stored(const Scene &s) {
  const Clock::time_point t0 = Clock::now();
  std::vector<Rect> rects;
  rects.reserve(s.boxes.size());
  for (const bvh::bounds &b : s.boxes) rects.push_back(Rect{to_box(b)});
  bvh::BVH<Rect> tree;
  tree.construct(rects);
  const Clock::time_point t1 = Clock::now();
  Run r;
  for (const bvh::bounds &w : s.windows)
    tree.query(to_box(w), [&](const Rect &v) { ++r.found, r.checksum += v.box.getMin().x; });
  r.queries = since(t1);
  r.total = since(t0);
  r.index_mb = double(tree.memory().total()) / 1e6;
  return r;
}

Run ids(const Scene &s) {
  const Clock::time_point t0 = Clock::now();
  std::vector<std::uint32_t> all(s.boxes.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  bvh::BVH<std::uint32_t, RectIds> tree(bvh::default_split_threshold, 0, RectIds{&s.boxes});
  tree.construct(all);
  const Clock::time_point t1 = Clock::now();
  Run r;
  for (const bvh::bounds &w : s.windows) tree.query(to_box(w), [&](std::uint32_t i) { ++r.found, r.checksum += i; });
  r.queries = since(t1);
  r.total = since(t0);
  r.index_mb = double(tree.memory().total()) / 1e6;
  return r;
}

#if BENCH_HAVE_BOOST
Run boost_packed(const Scene &s) {
  const Clock::time_point t0 = Clock::now();
  std::vector<BValue> values;
  values.reserve(s.boxes.size());
  for (std::uint32_t i = 0; i < s.boxes.size(); ++i) values.emplace_back(to_boost(to_box(s.boxes[i])), i);
  const bgi::rtree<BValue, bgi::rstar<16>> rt(values.begin(), values.end());
  const Clock::time_point t1 = Clock::now();
  Run r;
  for (const bvh::bounds &w : s.windows)
    rt.query(bgi::intersects(to_boost(to_box(w))),
             boost::make_function_output_iterator([&](const BValue &v) { ++r.found, r.checksum += v.second; }));
  r.queries = since(t1);
  r.total = since(t0);
  return r;
}
#endif

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

} // namespace

int main(int argc, char **argv) {
  std::size_t n = 1000000, q = 100000;
  int runs = 5;
  unsigned seed = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    const long v = std::strtol(argv[i + 1], nullptr, 10);
    if (v <= 0) {
      std::fprintf(stderr, "bench_windows: %s needs a positive number, not '%s'\n", a.c_str(), argv[i + 1]);
      return 2;
    }
    if (a == "--n") n = std::size_t(v);
    else if (a == "--q") q = std::size_t(v);
    else if (a == "--runs") runs = int(v);
    else if (a == "--seed") seed = unsigned(v);
    else {
      std::fprintf(stderr, "bench_windows: unknown option '%s' (--n, --q, --runs, --seed)\n", a.c_str());
      return 2;
    }
  }
  if (argc % 2 == 0) {
    std::fprintf(stderr, "bench_windows: %s needs a value\n", argv[argc - 1]);
    return 2;
  }
  const Scene s = make_scene(n, q, seed);
  struct Method {
    const char *name;
    std::function<Run(const Scene &)> run;
  };
  std::vector<Method> methods = {{"stored  bvh::BVH<Rect> (width 8, split 32)", stored},
                                 {"ids     bvh::BVH<uint32_t, RectIds>", ids}};
#if BENCH_HAVE_BOOST
  methods.push_back({"boost   rtree rstar<16>, packed", boost_packed});
#endif
  std::printf("bench_windows: %zu boxes (sides 1-10) in a 10000 x 10000 square, %zu windows (sides 50-150); "
              "median of %d runs in one process, the methods taking turns\n",
              n, q, runs);
  std::printf("%-44s %10s %10s %8s %12s %9s\n", "method", "total s", "queries s", "x stored", "found", "index MB");
  // The methods take turns, a run each, so that the host's slower and
  // faster minutes fall on all of them alike.
  std::vector<std::vector<double>> total(methods.size()), queries(methods.size());
  std::vector<std::uint64_t> found(methods.size());
  std::vector<double> index_mb(methods.size());
  for (int r = 0; r < runs; ++r)
    for (std::size_t m = 0; m < methods.size(); ++m) {
      const Run run = methods[m].run(s);
      total[m].push_back(run.total);
      queries[m].push_back(run.queries);
      found[m] = run.found;
      index_mb[m] = run.index_mb;
    }
  const double stored_queries = median(queries[0]);
  for (std::size_t m = 0; m < methods.size(); ++m) {
    if (found[m] != found[0]) {
      std::printf("%-44s found %llu, not %llu: MISMATCH\n", methods[m].name, (unsigned long long)found[m],
                  (unsigned long long)found[0]);
      return 1;
    }
    char mb[32] = "-";
    if (index_mb[m] > 0) std::snprintf(mb, sizeof mb, "%.1f", index_mb[m]);
    std::printf("%-44s %10.4f %10.4f %8.2f %12llu %9s\n", methods[m].name, median(total[m]), median(queries[m]),
                median(queries[m]) / stored_queries, (unsigned long long)found[m], mb);
  }
#if !BENCH_HAVE_BOOST
  std::printf("skipped Boost.Geometry: apt-get install libboost-dev\n");
#endif
  return 0;
}
