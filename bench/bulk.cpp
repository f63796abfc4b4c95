// bench/bulk.cpp — `make bench-bulk` (make bench runs it too): bulk work
// against the GIS world's indexes and CGAL, on make bench's W1 and W2
// disks (1M each, the same seeds and sizes as bench.cpp's scenes):
//
//   W3  build an index over the 1M disks, then 100k probe disks of radius
//       1: how many probes touch at least one disk (exact intersect());
//   all pairs  every intersecting pair of the 1M disks, touching included.
//
// Methods: ours (BVH<Disk>, the default tree: width 8, 32 shapes a leaf;
// and CourseBVH<Disk>, the course's tree, what bvh.out runs), GEOS's
// TemplateSTRtree (node capacity 10, GEOS's default, and 16), Flatbush
// (double and float boxes, node size 16), Boost.Geometry's packed R-tree
// (rstar<16>, built from the range: STR packing), and for all pairs CGAL's
// box_self_intersection_d (cutoff 10, CGAL's default, and 1000). Each
// peer finds candidates by its own box test and decides with the same
// exact intersect() as ours; before any time is printed, every method's
// count must equal ours (exit status 1 otherwise).
//
// The peers are used when present and skipped with a notice otherwise:
// GEOS and Flatbush from ../shared/peers (PEERS, passed by the Makefile as
// -DBENCH_HAVE_GEOS / -DBENCH_HAVE_FLATBUSH with their include folders),
// Boost (libboost-dev) and CGAL (libcgal-dev) by __has_include. None of
// them is part of the library, bvh.out or the tests.
//
// Times: the median of --runs runs (default 3), each method run in turn
// within a round, in one process; the build and the probes are also shown
// apart. --quick: 100k disks and 10k probes.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/generate.h>
#include <bvh/scene.h>

#include "peers.h"
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#if defined(BENCH_HAVE_GEOS)
#include <geos/index/strtree/TemplateSTRtree.h>
#endif
#if defined(BENCH_HAVE_FLATBUSH)
#include "flatbush.h"
#endif
#if !defined(BENCH_NO_CGAL) && __has_include(<CGAL/box_intersection_d.h>)
#define BENCH_HAVE_CGAL 1
#include <CGAL/box_intersection_d.h>
#else
#define BENCH_HAVE_CGAL 0
#endif

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::vector<Disk> make_disks(long count, std::uint64_t seed, double lo, double hi) {
  std::string text, error;
  bvh_scene::generate_scene<Disk>("disks", count, seed, lo, hi, true, text);
  std::vector<Disk> out;
  if (!bvh_scene::parse_scene("generated", text.data(), text.size(), out, error)) {
    std::fprintf(stderr, "bench_bulk: %s\n", error.c_str());
    std::exit(1);
  }
  return out;
}

struct Box4 {
  double x0, y0, x1, y1;
};
[[maybe_unused]] Box4 box_of(const Disk &d) {
  const BoundingBox b = d.getBox();
  return {b.getMin().x, b.getMin().y, b.getMax().x, b.getMax().y};
}

/// One timed run: the build's seconds, the probes' (or the pairs')
/// seconds, and the count the method found.
struct Run {
  double build = 0, work = 0;
  std::size_t count = 0;
};

/// A method of one question: a name, and a run over (disks, probes).
struct Method {
  std::string name;
  std::function<Run(const std::vector<Disk> &, const std::vector<Disk> &)> run;
};

// ---- W3: build, then the probes that touch a disk.

template <class Tree> Run w3_ours(const std::vector<Disk> &disks, const std::vector<Disk> &probes, Tree tree) {
  Run r;
  Clock::time_point t = Clock::now();
  tree.construct(disks);
  r.build = seconds_since(t);
  t = Clock::now();
  for (const Disk &p : probes) r.count += tree.collision(p) ? 1 : 0;
  r.work = seconds_since(t);
  return r;
}

#if defined(BENCH_HAVE_GEOS)
using GeosTree = geos::index::strtree::TemplateSTRtree<std::uint32_t>;
/// The disks' envelopes into `tree`, then its STR packing.
void build_geos(GeosTree &tree, const std::vector<Disk> &disks) {
  for (std::size_t i = 0; i < disks.size(); ++i) {
    const Box4 b = box_of(disks[i]);
    tree.insert(geos::geom::Envelope(b.x0, b.x1, b.y0, b.y1), std::uint32_t(i));
  }
  tree.build();
}

Run w3_geos(const std::vector<Disk> &disks, const std::vector<Disk> &probes, std::size_t capacity) {
  Run r;
  Clock::time_point t = Clock::now();
  GeosTree tree(capacity, disks.size());
  build_geos(tree, disks);
  r.build = seconds_since(t);
  t = Clock::now();
  for (const Disk &p : probes) {
    const Box4 b = box_of(p);
    bool hit = false;
    tree.query(geos::geom::Envelope(b.x0, b.x1, b.y0, b.y1), [&](std::uint32_t i) {
      hit = intersect(disks[i], p);
      return !hit; // false stops the query
    });
    r.count += hit ? 1 : 0;
  }
  r.work = seconds_since(t);
  return r;
}
#endif

#if defined(BENCH_HAVE_FLATBUSH)
/// The box in Coordinate, rounded outwards (float: one step past the
/// nearest), so that no candidate is lost.
template <class Coordinate> flatbush::Box<Coordinate> outward(const Box4 &b) {
  const Coordinate down = -std::numeric_limits<Coordinate>::infinity(), up = -down;
  return {std::nextafter(Coordinate(b.x0), down), std::nextafter(Coordinate(b.y0), down),
          std::nextafter(Coordinate(b.x1), up), std::nextafter(Coordinate(b.y1), up)};
}

template <class Coordinate> Run w3_flatbush(const std::vector<Disk> &disks, const std::vector<Disk> &probes) {
  Run r;
  Clock::time_point t = Clock::now();
  flatbush::FlatbushBuilder<Coordinate> builder(disks.size());
  for (const Disk &d : disks) builder.add(outward<Coordinate>(box_of(d)));
  auto tree = builder.finish();
  r.build = seconds_since(t);
  t = Clock::now();
  for (const Disk &p : probes) {
    const Box4 b = box_of(p);
    bool hit = false;
    // (Its search has no early exit: the filter sees every candidate, and
    // keeps none in the result.)
    tree.search(outward<Coordinate>(b), [&](std::size_t i, const flatbush::Box<Coordinate> &) {
      if (!hit) hit = intersect(disks[i], p);
      return false;
    });
    r.count += hit ? 1 : 0;
  }
  r.work = seconds_since(t);
  return r;
}
#endif

#if BENCH_HAVE_BOOST
using PackedRtree = bgi::rtree<BValue, bgi::rstar<16>>;
PackedRtree boost_packed(const std::vector<Disk> &disks) {
  std::vector<BValue> values;
  values.reserve(disks.size());
  for (std::size_t i = 0; i < disks.size(); ++i) values.emplace_back(to_boost(disks[i].getBox()), std::uint32_t(i));
  return PackedRtree(values.begin(), values.end()); // the range constructor: STR packing
}
Run w3_boost(const std::vector<Disk> &disks, const std::vector<Disk> &probes) {
  Run r;
  Clock::time_point t = Clock::now();
  const PackedRtree tree = boost_packed(disks);
  r.build = seconds_since(t);
  t = Clock::now();
  for (const Disk &p : probes) {
    bool hit = false;
    for (auto it = tree.qbegin(bgi::intersects(to_boost(p.getBox()))); it != tree.qend() && !hit; ++it)
      hit = intersect(disks[it->second], p);
    r.count += hit ? 1 : 0;
  }
  r.work = seconds_since(t);
  return r;
}
#endif

// ---- All pairs: every intersecting pair once.

template <class Tree> Run pairs_ours(const std::vector<Disk> &disks, const std::vector<Disk> &, Tree tree) {
  Run r;
  Clock::time_point t = Clock::now();
  tree.construct(disks);
  r.build = seconds_since(t);
  t = Clock::now();
  r.count = tree.count_overlapping_pairs();
  r.work = seconds_since(t);
  return r;
}

#if defined(BENCH_HAVE_GEOS)
Run pairs_geos(const std::vector<Disk> &disks, const std::vector<Disk> &, std::size_t capacity) {
  Run r;
  Clock::time_point t = Clock::now();
  GeosTree tree(capacity, disks.size());
  build_geos(tree, disks);
  r.build = seconds_since(t);
  t = Clock::now();
  tree.queryPairs([&](std::uint32_t a, std::uint32_t b) {
    r.count += intersect(disks[a], disks[b]) ? 1 : 0;
    return true;
  });
  r.work = seconds_since(t);
  return r;
}
#endif

#if BENCH_HAVE_BOOST
Run pairs_boost(const std::vector<Disk> &disks, const std::vector<Disk> &) {
  Run r;
  Clock::time_point t = Clock::now();
  const PackedRtree tree = boost_packed(disks);
  r.build = seconds_since(t);
  t = Clock::now();
  for (std::size_t i = 0; i < disks.size(); ++i)
    tree.query(bgi::intersects(to_boost(disks[i].getBox())),
               boost::make_function_output_iterator([&](const BValue &v) {
                 if (v.second > i && intersect(disks[i], disks[v.second])) ++r.count;
               }));
  r.work = seconds_since(t);
  return r;
}
#endif

#if BENCH_HAVE_CGAL
Run pairs_cgal(const std::vector<Disk> &disks, const std::vector<Disk> &, std::ptrdiff_t cutoff) {
  using CgalBox = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::uint32_t>;
  Run r;
  Clock::time_point t = Clock::now();
  std::vector<CgalBox> boxes;
  boxes.reserve(disks.size());
  for (std::size_t i = 0; i < disks.size(); ++i) {
    const Box4 b = box_of(disks[i]);
    double lo[2] = {b.x0, b.y0}, hi[2] = {b.x1, b.y1};
    boxes.emplace_back(lo, hi, std::uint32_t(i));
  }
  r.build = seconds_since(t); // (no index: the boxes only)
  t = Clock::now();
  CGAL::box_self_intersection_d(
      boxes.begin(), boxes.end(),
      [&](const CgalBox &a, const CgalBox &b) { r.count += intersect(disks[a.info()], disks[b.info()]) ? 1 : 0; },
      CGAL::Box_intersection_d::Box_traits_d<CgalBox>(), cutoff, CGAL::Box_intersection_d::CLOSED);
  r.work = seconds_since(t);
  return r;
}
#endif

std::vector<Method> w3_methods() {
  std::vector<Method> m;
  m.push_back({"ours BVH<Disk> (w8 k32)", [](auto &d, auto &p) { return w3_ours(d, p, BVH<Disk>()); }});
  m.push_back({"ours CourseBVH<Disk> (w3 k4)", [](auto &d, auto &p) { return w3_ours(d, p, CourseBVH<Disk>()); }});
#if defined(BENCH_HAVE_GEOS)
  m.push_back({"GEOS TemplateSTRtree cap 10", [](auto &d, auto &p) { return w3_geos(d, p, 10); }});
  m.push_back({"GEOS TemplateSTRtree cap 16", [](auto &d, auto &p) { return w3_geos(d, p, 16); }});
#endif
#if defined(BENCH_HAVE_FLATBUSH)
  m.push_back({"Flatbush double", [](auto &d, auto &p) { return w3_flatbush<double>(d, p); }});
  m.push_back({"Flatbush float", [](auto &d, auto &p) { return w3_flatbush<float>(d, p); }});
#endif
#if BENCH_HAVE_BOOST
  m.push_back({"Boost packed rstar16", [](auto &d, auto &p) { return w3_boost(d, p); }});
#endif
  return m;
}

std::vector<Method> pairs_methods() {
  std::vector<Method> m;
  m.push_back({"ours BVH<Disk> (w8 k32)", [](auto &d, auto &p) { return pairs_ours(d, p, BVH<Disk>()); }});
  m.push_back({"ours CourseBVH<Disk> (w3 k4)", [](auto &d, auto &p) { return pairs_ours(d, p, CourseBVH<Disk>()); }});
#if defined(BENCH_HAVE_GEOS)
  m.push_back({"GEOS queryPairs cap 10", [](auto &d, auto &p) { return pairs_geos(d, p, 10); }});
  m.push_back({"GEOS queryPairs cap 16", [](auto &d, auto &p) { return pairs_geos(d, p, 16); }});
#endif
#if BENCH_HAVE_BOOST
  m.push_back({"Boost packed rstar16, query per disk", [](auto &d, auto &p) { return pairs_boost(d, p); }});
#endif
#if BENCH_HAVE_CGAL
  m.push_back({"CGAL box_intersection_d cutoff 10", [](auto &d, auto &p) { return pairs_cgal(d, p, 10); }});
  m.push_back({"CGAL box_intersection_d cutoff 1000", [](auto &d, auto &p) { return pairs_cgal(d, p, 1000); }});
#endif
  return m;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// Runs every method `runs` times (in turn within a round), checks that all
/// counts equal the first method's, and prints the table; false on a
/// disagreement.
bool measure(const std::string &title, const std::vector<Method> &methods, const std::vector<Disk> &disks,
             const std::vector<Disk> &probes, int runs) {
  std::vector<std::vector<Run>> got(methods.size());
  for (int round = 0; round < runs; ++round)
    for (std::size_t m = 0; m < methods.size(); ++m) got[m].push_back(methods[m].run(disks, probes));
  const std::size_t want = got[0][0].count;
  bool agree = true;
  for (std::size_t m = 0; m < methods.size(); ++m)
    for (const Run &r : got[m])
      if (r.count != want) {
        std::printf("MISMATCH %s: %s counts %zu, %s %zu\n", title.c_str(), methods[m].name.c_str(), r.count,
                    methods[0].name.c_str(), want);
        agree = false;
      }
  if (!agree) return false;
  std::vector<double> total(methods.size());
  double best_peer = 0;
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> t;
    for (const Run &r : got[m]) t.push_back(r.build + r.work);
    total[m] = median(t);
    if (methods[m].name.compare(0, 4, "ours") != 0 && (best_peer == 0 || total[m] < best_peer)) best_peer = total[m];
  }
  std::printf("\n%s: count %zu, medians of %d runs\n", title.c_str(), want, runs);
  std::printf("  %-40s %9s %9s %9s %12s\n", "method", "total s", "build s", "work s", "/ best peer");
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::vector<double> b, w;
    for (const Run &r : got[m]) b.push_back(r.build), w.push_back(r.work);
    char ratio[32] = "-";
    if (best_peer > 0) std::snprintf(ratio, sizeof ratio, "%.2fx", total[m] / best_peer);
    std::printf("  %-40s %9.3f %9.3f %9.3f %12s\n", methods[m].name.c_str(), total[m], median(b), median(w), ratio);
  }
  std::fflush(stdout);
  return true;
}

} // namespace

int main(int argc, char **argv) {
  int runs = 3;
  bool quick = false, with_pairs = true;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) {
      runs = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--quick") {
      quick = true;
    } else if (a == "--no-pairs") {
      with_pairs = false;
    } else if (a == "--only" && i + 1 < argc) {
      only = argv[++i];
    } else {
      std::fprintf(stderr, "usage: %s [--runs N] [--quick] [--no-pairs] [--only W1|W2]\n", argv[0]);
      return 2;
    }
  }
  std::printf("bench_bulk: %s\n", BENCH_BUILD_INFO);
#if !defined(BENCH_HAVE_GEOS)
  std::printf("skipped GEOS: not found in PEERS (default ../shared/peers; its README.md says how)\n");
#endif
#if !defined(BENCH_HAVE_FLATBUSH)
  std::printf("skipped Flatbush: not found in PEERS (default ../shared/peers; its README.md says how)\n");
#endif
#if !BENCH_HAVE_BOOST
  std::printf("skipped Boost: apt-get install libboost-dev\n");
#endif
#if !BENCH_HAVE_CGAL
  std::printf("skipped CGAL: apt-get install libcgal-dev\n");
#endif
  const long n = quick ? 100000 : 1000000, n_probes = quick ? 10000 : 100000;
  // make bench's scenes (bench.cpp: W1 seed 1, radii 2 to 7.5; W2 seed 2,
  // radii 0.2 to 0.6), and probes of radius 1 (seed 4).
  struct Scene {
    const char *name;
    std::uint64_t seed;
    double lo, hi;
  };
  const Scene scenes[] = {{"W1", 1, 2, 7.5}, {"W2", 2, 0.2, 0.6}};
  const std::vector<Disk> probes = make_disks(n_probes, 4, 1, 1);
  bool ok = true;
  for (const Scene &s : scenes) {
    if (!only.empty() && only != s.name) continue;
    const std::vector<Disk> disks = make_disks(n, s.seed, s.lo, s.hi);
    const std::string size = quick ? "100k" : "1M";
    ok = measure(std::string("W3 on ") + s.name + "'s " + size + " disks, " + (quick ? "10k" : "100k") +
                     " probes of radius 1 (probes touching a disk)",
                 w3_methods(), disks, probes, runs) &&
         ok;
    if (with_pairs)
      ok = measure(std::string("all pairs of ") + s.name + "'s " + size + " disks (intersecting pairs)", pairs_methods(),
                   disks, probes, runs) &&
           ok;
  }
  return ok ? 0 : 1;
}
