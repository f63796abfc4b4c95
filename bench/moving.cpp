// bench/moving.cpp — `make bench-moving` (and the end of `make bench`): the
// tree as a physics broadphase over a moving scene (W4), and k-nearest
// queries on a large static scene, against Box2D's b2DynamicTree and
// Boost.Geometry's R-trees. Writes its tables to stdout (the Makefile keeps
// the full run in bench/results_moving.txt).
//
//   make bench-moving            full run (13-17 minutes on the shared 2-core machine, 3 runs)
//   make bench-moving QUICK=1    reduced run, a few seconds (build/results_moving.txt)
//   build/bench_moving --help    every flag
//
// Flags:
//   --runs N          runs of each method; the median is reported (default 3)
//   --quick           W4: 10k disks, 20 frames; knn: 100k disks, 1k queries; 1 run
//   --only W4|knn     one of the two parts
//   --frames F        W4's frames (default 100)
//   --n N             W4's disks (default 100,000)
//   --knn-n N         the k-nearest scene's disks (default 1,000,000)
//   --queries Q       k-nearest query points (default 10,000)
//   --margins a,b,..  ours' margins in W4 (default 0,0.1,0.25,0.5,1)
//   --method NAME     only the rows whose name starts with NAME: ours, box2d,
//                     boost-rstar16, boost-quad16 (W4); ours, boost (knn)
//   --seed S          the scenes' seed (default 20261202; printed)
//
// W4 moving scene: n disks, radii uniform in [0.5, 1.5], centres uniform in
// the 1000 x 1000 square. Each frame every disk steps by a length uniform in
// [0, r] in a uniform random direction; a centre leaving the square is
// reflected back at its side (x < 0 -> -x, x > 1000 -> 2000 - x; a step is
// at most 1.5, so one reflection suffices). At every 10th frame (10, 20, ...)
// 1% of the disks (distinct, drawn at random) teleport to a uniform random
// position instead of stepping. The centres of every frame are generated
// once, before any method runs, so every method sees identical shapes.
// After the moves of a frame each method makes one overlap query per disk
// and counts the touching pairs by the exact intersect(Disk, Disk) of
// intersect.h. Every run must count the same pairs in every frame as the
// first run that found nothing wrong in itself; a method that does not (or
// whose own count is odd, or, for ours, whose validate() is false or whose
// get(h[i]) is not disk i's last position) is marked WRONG in the table, and
// the program exits 1 after printing every table. Methods:
//   ours m=M       CourseBVH<Disk>(4, 0), set_margin(M), construct(); per frame
//                  update(h[i], moved) per disk, then query(disk, f) per disk
//   Box2D          b2DynamicTree: CreateProxy per disk; per frame
//                  MoveProxy(id, box, displacement) (a teleport passes a zero
//                  displacement, as b2Body::SetTransform does), then
//                  Query(callback, box) per disk with the exact test
//   Boost rstar16 / quad16   rtree of (box, index), packed by the range
//                  constructor; per frame remove(old) + insert(new) per disk,
//                  then query(intersects(box)) per disk with the exact test
// Only the frames are timed (not the fill); time per frame is the median of
// the runs' 100-frame totals divided by the frames, split into the moves and
// the queries (two clock reads a frame). For ours the table also
// gives the tree's SAH cost (sah_cost()) after the last frame over that of a
// bulk construct() of the final disks with the same margin, and with margin
// 0, and validate().
//
// k-nearest: 1M disks of bench.cpp's W2 density (radii uniform in
// [0.2, 0.6], centres uniform in the 1000 x 1000 square: about 58% of the
// square is outside every disk, so the 1-nearest distance is often not 0),
// and 10,000 uniform query points; k = 1, 10, 100. Distances are distance()
// of distance.h: 0 inside or on the disk.
//   ours           construct() (margin 0), nearest(p, k, back_inserter(v))
//   Boost incr     packed rtree of (box, index); qbegin(nearest(p, N))
//                  yields the N nearest boxes by increasing box distance;
//                  keep the k best exact disk distances and stop at the
//                  first box farther than the k-th best (a box is never
//                  farther than its disk); N = 2k + 4, doubled and the query
//                  redone when the N boxes end before that. (N = size(),
//                  one pass, is far slower: Boost 1.74's incremental query
//                  prunes nothing until it holds N values; 100k disks,
//                  5 values taken: 1.6 ms a query against 12 us with N = 100.)
//   Boost grow     query(nearest(p, N), out) for the N nearest boxes, N as
//                  above, doubled until the farthest of them is beyond the
//                  k-th best
// Both are checked against ours for every query point (the same k distances,
// bit for bit; ids may differ only among disks at the k-th distance), and
// ours against a brute-force scan for a few points, before the timing; a
// difference stops the program with exit 1.
//
// Instruction counts (only the timed region is instrumented, via
// <valgrind/callgrind.h> when installed), e.g. one W4 method:
//   make build/bench_moving
//   valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=build/callgrind.moving
//            build/bench_moving --only W4 --method "ours m=0.25" --runs 1 --frames 10   (one line)
//   callgrind_annotate build/callgrind.moving | head -40
//
// Peers are compiled in only when their headers (and for Box2D the library,
// checked by the Makefile, which passes -DBENCH_HAVE_BOX2D_LIB) are present;
// otherwise the run prints "skipped NAME: apt-get install PACKAGE". To see
// that path with the peers installed, add -DBENCH_NO_BOOST / -DBENCH_NO_BOX2D.

#include <bvh/bvh.h>
#include <bvh/distance.h>
#include <bvh/intersect.h>
#include <bvh/shapes.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "peers.h"

namespace {

using Clock = std::chrono::steady_clock;
// The tree's width and split_threshold: the course's 3 and 4 unless the
// build says otherwise (make bench-widths builds it at width 8 too).
#ifndef BENCH_WIDTH
#define BENCH_WIDTH 3
#endif
#ifndef BENCH_SPLIT
#define BENCH_SPLIT 4
#endif
using Tree = BVH<Disk, bvh::shape_traits<Disk>, BENCH_WIDTH>;
constexpr int kSplit = BENCH_SPLIT;

/// The timed region of one run (and callgrind's instrumentation under it).
/// Seconds since `t`, which becomes now.
double lap(Clock::time_point &t) {
  const Clock::time_point now = Clock::now();
  const double s = std::chrono::duration<double>(now - t).count();
  t = now;
  return s;
}

class Timer {
public:
  Timer() {
    BENCH_CG_START();
    t0_ = Clock::now();
  }
  double stop() {
    const double s = std::chrono::duration<double>(Clock::now() - t0_).count();
    BENCH_CG_STOP();
    return s;
  }

private:
  Clock::time_point t0_;
};

/// `v` printed by `format`, or "-" when absent (v <= 0).
std::string cell(const char *format, double v) {
  if (!(v > 0)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : (v[m - 1] + v[m]) / 2;
}

/// Set by any check that fails; main() then returns 1 (after every table).
bool g_failed = false;

[[noreturn]] void fail(const std::string &why) {
  std::printf("FAILED: %s\n", why.c_str());
  std::fflush(stdout);
  std::exit(1);
}

struct Options {
  int runs = 3;
  bool quick = false;
  std::string only;   // "", "W4" or "knn"
  std::string method; // "": every method; else a prefix of the row names
  int frames = 0;     // 0: the default (100, 20 with --quick)
  long n = 0;         // W4's disks (0: 100k, 10k with --quick)
  long knn_n = 0;     // k-nearest disks (0: 1M, 100k with --quick)
  long queries = 0;   // k-nearest points (0: 10k, 1k with --quick)
  std::vector<double> margins{0, 0.1, 0.25, 0.5, 1.0};
  std::uint64_t seed = 20261202;
  bool runs_given = false;
};

bool wanted(const Options &opt, const std::string &row) {
  return opt.method.empty() || row.compare(0, opt.method.size(), opt.method) == 0;
}

// ---------------------------------------------------------------------------
// W4: the scene and its moves, generated once.

struct Scene {
  std::size_t n = 0;
  int frames = 0;
  std::vector<double> radius;              // per disk
  std::vector<std::vector<Point>> centre;  // centre[f][i]: after frame f's moves (f = 0: the start)
  std::vector<std::vector<char>> teleport; // teleport[f][i]: disk i jumped in frame f
  Disk disk(int f, std::size_t i) const { return Disk(centre[f][i], radius[i], Color(0, 0, 0)); }
  std::vector<Disk> disks(int f) const {
    std::vector<Disk> v;
    v.reserve(n);
    for (std::size_t i = 0; i < n; ++i) v.push_back(disk(f, i));
    return v;
  }
};

constexpr double kSide = 1000;

double reflect(double v) { return v < 0 ? -v : v > kSide ? 2 * kSide - v : v; }

Scene make_scene(std::size_t n, int frames, std::uint64_t seed) {
  Scene s;
  s.n = n;
  s.frames = frames;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(0, kSide), rad(0.5, 1.5), unit(0, 1), turn(0, 2 * M_PI);
  s.radius.resize(n);
  s.centre.assign(std::size_t(frames) + 1, std::vector<Point>(n));
  s.teleport.assign(std::size_t(frames) + 1, std::vector<char>(n, 0));
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng);
    s.centre[0][i] = Point(x, y);
    s.radius[i] = rad(rng);
  }
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
  for (int f = 1; f <= frames; ++f) {
    const std::vector<Point> &prev = s.centre[f - 1];
    std::vector<Point> &cur = s.centre[f];
    for (std::size_t i = 0; i < n; ++i) {
      const double len = unit(rng) * s.radius[i], a = turn(rng);
      cur[i] = Point(reflect(prev[i].x + len * std::cos(a)), reflect(prev[i].y + len * std::sin(a)));
    }
    if (f % 10 == 0) { // 1% jump: the first n/100 of a partial Fisher-Yates shuffle
      const std::size_t jumps = n / 100;
      for (std::size_t k = 0; k < jumps; ++k) {
        const std::size_t j = k + std::size_t(rng() % (n - k));
        std::swap(order[k], order[j]);
        const double x = xy(rng), y = xy(rng);
        cur[order[k]] = Point(x, y);
        s.teleport[f][order[k]] = 1;
      }
    }
  }
  return s;
}

/// One run of a method over every frame.
struct W4Run {
  double seconds = 0; // the frames only
  double moving = 0;  // of which the moves (update / MoveProxy / remove + insert); the rest is the queries
  double fill = 0;    // the initial fill (not in `seconds`)
  std::vector<std::uint64_t> pairs; // per frame
  double sah_same = 0, sah_zero = 0; // ours: SAH over a bulk build's, same margin / margin 0
  bool valid = true;                 // ours: validate() after the last frame
  std::string problem;               // the first wrong result seen ("": none)
  void flag(const std::string &why) {
    if (problem.empty()) problem = why;
  }
};

// --- ours ---

W4Run w4_ours(const Scene &s, double margin) {
  W4Run r;
  r.pairs.assign(std::size_t(s.frames), 0);
  const std::vector<Disk> start = s.disks(0);
  const auto t0 = Clock::now();
  Tree tree(kSplit, 0);
  tree.set_margin(margin);
  tree.construct(start);
  std::vector<Tree::handle> h(s.n);
  for (std::size_t i = 0; i < s.n; ++i) h[i] = tree.constructed(i); // start[i]'s handle
  r.fill = std::chrono::duration<double>(Clock::now() - t0).count();

  Timer timer;
  for (int f = 1; f <= s.frames; ++f) {
    Clock::time_point t = Clock::now();
    for (std::size_t i = 0; i < s.n; ++i) tree.update(h[i], s.disk(f, i));
    r.moving += lap(t);
    std::uint64_t hits = 0; // query() reports the disk itself too: n of them
    for (std::size_t i = 0; i < s.n; ++i) tree.query(s.disk(f, i), [&hits](const Disk &) { ++hits; });
    if (hits < s.n || (hits - s.n) % 2)
      r.flag("frame " + std::to_string(f) + ": " + std::to_string(hits) + " hits for " + std::to_string(s.n) +
             " disks, odd: a pair found from one side only");
    r.pairs[std::size_t(f - 1)] = hits < s.n ? 0 : (hits - s.n) / 2;
  }
  r.seconds = timer.stop();

  std::string why;
  r.valid = tree.validate(&why);
  if (!r.valid) r.flag("validate() after the last frame: " + why);
  const std::vector<Disk> last = s.disks(s.frames);
  for (std::size_t i = 0; i < s.n; ++i)
    if (!tree.contains(h[i]) || tree.get(h[i]) != last[i]) {
      r.flag("get(h[" + std::to_string(i) + "]) is not the disk's last position");
      break;
    }
  Tree bulk(kSplit, 0);
  bulk.set_margin(margin);
  bulk.construct(last);
  Tree bulk0(kSplit, 0);
  bulk0.construct(last);
  r.sah_same = tree.sah_cost() / bulk.sah_cost();
  r.sah_zero = tree.sah_cost() / bulk0.sah_cost();
  return r;
}

// --- Box2D ---
#if BENCH_HAVE_BOX2D
float down(double v) {
  const float f = float(v);
  return double(f) > v ? std::nextafter(f, -INFINITY) : f;
}
float up(double v) {
  const float f = float(v);
  return double(f) < v ? std::nextafter(f, INFINITY) : f;
}
/// The disk's box rounded outwards to float, so that no double box is cut.
b2AABB to_box2d(const Disk &d) {
  const BoundingBox b = d.getBox();
  b2AABB a;
  a.lowerBound.Set(down(b.getMin().x), down(b.getMin().y));
  a.upperBound.Set(up(b.getMax().x), up(b.getMax().y));
  return a;
}

struct Box2DPairs {
  const b2DynamicTree *tree;
  const std::vector<Disk> *cur;
  std::uint32_t self;
  std::uint64_t k = 0;
  bool QueryCallback(int32 proxy) {
    const auto j = std::uint32_t(reinterpret_cast<std::uintptr_t>(tree->GetUserData(proxy)));
    if (j != self && intersect((*cur)[self], (*cur)[j])) ++k;
    return true;
  }
};

W4Run w4_box2d(const Scene &s) {
  W4Run r;
  r.pairs.assign(std::size_t(s.frames), 0);
  std::vector<Disk> cur = s.disks(0);
  const auto t0 = Clock::now();
  b2DynamicTree tree;
  std::vector<int32> proxy(s.n);
  for (std::size_t i = 0; i < s.n; ++i)
    proxy[i] = tree.CreateProxy(to_box2d(cur[i]), reinterpret_cast<void *>(std::uintptr_t(i)));
  r.fill = std::chrono::duration<double>(Clock::now() - t0).count();

  Timer timer;
  for (int f = 1; f <= s.frames; ++f) {
    Clock::time_point t = Clock::now();
    const std::vector<char> &jumped = s.teleport[std::size_t(f)];
    for (std::size_t i = 0; i < s.n; ++i) {
      const Disk d = s.disk(f, i);
      b2Vec2 move(0, 0);
      if (!jumped[i])
        move.Set(float(d.getCenter().x - cur[i].getCenter().x), float(d.getCenter().y - cur[i].getCenter().y));
      tree.MoveProxy(proxy[i], to_box2d(d), move);
      cur[i] = d;
    }
    r.moving += lap(t);
    std::uint64_t k = 0;
    for (std::size_t i = 0; i < s.n; ++i) {
      Box2DPairs q{&tree, &cur, std::uint32_t(i)};
      tree.Query(&q, to_box2d(cur[i]));
      k += q.k;
    }
    if (k % 2) r.flag("frame " + std::to_string(f) + ": an odd count");
    r.pairs[std::size_t(f - 1)] = k / 2;
  }
  r.seconds = timer.stop();
  return r;
}
#endif

// --- Boost.Geometry ---
#if BENCH_HAVE_BOOST

BBox to_boost(const Disk &d) {
  return ::to_boost(d.getBox()); // (peers.h's, global: this one hides it)
}

template <class Params> W4Run w4_boost(const Scene &s) {
  W4Run r;
  r.pairs.assign(std::size_t(s.frames), 0);
  std::vector<Disk> cur = s.disks(0);
  const auto t0 = Clock::now();
  std::vector<BValue> values;
  values.reserve(s.n);
  for (std::size_t i = 0; i < s.n; ++i) values.emplace_back(to_boost(cur[i]), std::uint32_t(i));
  bgi::rtree<BValue, Params> rt(values.begin(), values.end());
  r.fill = std::chrono::duration<double>(Clock::now() - t0).count();

  Timer timer;
  for (int f = 1; f <= s.frames; ++f) {
    Clock::time_point t = Clock::now();
    for (std::size_t i = 0; i < s.n; ++i) {
      cur[i] = s.disk(f, i);
      if (rt.remove(values[i]) != 1) fail("Boost: remove() missed a value");
      values[i].first = to_boost(cur[i]);
      rt.insert(values[i]);
    }
    r.moving += lap(t);
    std::uint64_t k = 0;
    for (std::size_t i = 0; i < s.n; ++i) {
      const Disk &d = cur[i];
      rt.query(bgi::intersects(values[i].first), boost::make_function_output_iterator([&](const BValue &v) {
                 if (v.second != i && intersect(d, cur[v.second])) ++k;
               }));
    }
    if (k % 2) r.flag("frame " + std::to_string(f) + ": an odd count");
    r.pairs[std::size_t(f - 1)] = k / 2;
  }
  r.seconds = timer.stop();
  return r;
}
#endif

struct W4Row {
  std::string name;
  std::vector<W4Run> runs;
  double per_frame() const {
    std::vector<double> t;
    for (const W4Run &r : runs) t.push_back(r.seconds);
    return median(t) / double(runs.front().pairs.size());
  }
  double fill() const {
    std::vector<double> t;
    for (const W4Run &r : runs) t.push_back(r.fill);
    return median(t);
  }
  /// The moves' share of a frame, in the run of median total time.
  double moving_per_frame() const {
    std::vector<const W4Run *> by(runs.size());
    for (std::size_t i = 0; i < runs.size(); ++i) by[i] = &runs[i];
    std::sort(by.begin(), by.end(), [](const W4Run *a, const W4Run *b) { return a->seconds < b->seconds; });
    return by[by.size() / 2]->moving / double(runs.front().pairs.size());
  }
  std::string problem() const {
    for (const W4Run &r : runs)
      if (!r.problem.empty()) return r.problem;
    return "";
  }
};

void w4(const Options &opt) {
  const std::size_t n = std::size_t(opt.n > 0 ? opt.n : opt.quick ? 10000 : 100000);
  const int frames = opt.frames > 0 ? opt.frames : opt.quick ? 20 : 100;
  const auto g0 = Clock::now();
  const Scene s = make_scene(n, frames, opt.seed);
  std::printf("W4 moving scene: %zu disks r0.5-1.5 in 1000 x 1000, %d frames, seed %llu\n", n, frames,
              static_cast<unsigned long long>(opt.seed));
  std::printf("  each frame: every disk steps by U[0, r] in a random direction (reflected at the sides);\n"
              "  frames 10, 20, ...: 1%% of the disks teleport; then one overlap query per disk, exact test\n"
              "  (moves generated up front in %.2f s; %d runs, median; only the frames are timed)\n\n",
              std::chrono::duration<double>(Clock::now() - g0).count(), opt.runs);

  // The reference counts: the first run that found nothing wrong in itself.
  // Every other run must count the same pairs in every frame.
  std::vector<W4Row> rows;
  std::vector<std::uint64_t> ref;
  std::string ref_name;
  auto run = [&](const std::string &name, auto &&method) {
    if (!wanted(opt, name)) return;
    W4Row row{name, {}};
    for (int k = 0; k < opt.runs; ++k) {
      row.runs.push_back(method());
      W4Run &r = row.runs.back();
      if (ref.empty() && r.problem.empty()) {
        ref = r.pairs;
        ref_name = name;
      }
      for (int f = 0; f < frames && !ref.empty(); ++f)
        if (r.pairs[std::size_t(f)] != ref[std::size_t(f)]) {
          r.flag("frame " + std::to_string(f + 1) + ": " + std::to_string(r.pairs[std::size_t(f)]) + " pairs, " +
                 ref_name + " " + std::to_string(ref[std::size_t(f)]));
          break;
        }
    }
    std::printf("  ran %-18s %.4f s/frame%s\n", name.c_str(), row.per_frame(), row.problem().empty() ? "" : "  WRONG");
    std::fflush(stdout);
    rows.push_back(std::move(row));
  };

  for (double m : opt.margins) {
    char name[32];
    std::snprintf(name, sizeof name, "ours m=%g", m);
    run(name, [&] { return w4_ours(s, m); });
  }
#if BENCH_HAVE_BOX2D
  run("box2d", [&] { return w4_box2d(s); });
#else
  std::printf("skipped Box2D: apt-get install libbox2d-dev\n");
#endif
#if BENCH_HAVE_BOOST
  run("boost-rstar16", [&] { return w4_boost<bgi::rstar<16>>(s); });
  run("boost-quad16", [&] { return w4_boost<bgi::quadratic<16>>(s); });
#else
  std::printf("skipped Boost.Geometry: apt-get install libboost-dev\n");
#endif
  if (rows.empty()) return;

  const W4Row *box2d = nullptr;
  for (const W4Row &r : rows)
    if (r.name == "box2d") box2d = &r;
  auto mean_of = [&](const std::vector<std::uint64_t> &v) {
    double sum = 0;
    for (std::uint64_t p : v) sum += double(p);
    return sum / double(frames);
  };

  std::printf("\n%-16s %8s %9s %9s %9s %8s %11s %9s %9s %8s\n", "method", "fill s", "s/frame", "moves", "queries",
              "x Box2D", "pairs/frame", "SAH/bulk", "SAH/bulk0", "validate");
  std::printf("%s\n", std::string(108, '-').c_str());
  std::size_t wrong = 0;
  for (const W4Row &r : rows) {
    const bool ours = r.name.compare(0, 4, "ours") == 0;
    std::printf("%-16s %8.4f %9.5f %9.5f %9.5f %8s %11.1f", r.name.c_str(), r.fill(), r.per_frame(),
                r.moving_per_frame(), r.per_frame() - r.moving_per_frame(),
                cell("%.3f", box2d ? r.per_frame() / box2d->per_frame() : 0).c_str(), mean_of(r.runs.back().pairs));
    if (ours) {
      const W4Run &last = r.runs.back();
      bool valid = true;
      for (const W4Run &x : r.runs) valid = valid && x.valid;
      std::printf(" %9.4f %9.4f %8s\n", last.sah_same, last.sah_zero, valid ? "ok" : "FAILED");
    } else {
      std::printf("\n");
    }
    if (!r.problem().empty()) {
      std::printf("  WRONG: %s\n", r.problem().c_str());
      ++wrong;
    }
  }
  if (!ref.empty()) {
    const auto mm = std::minmax_element(ref.begin(), ref.end());
    std::printf("\npairs per frame: mean %.1f, min %llu, max %llu (%s); ", mean_of(ref),
                static_cast<unsigned long long>(*mm.first), static_cast<unsigned long long>(*mm.second),
                ref_name.c_str());
    if (wrong == 0)
      std::printf("identical for all %zu methods in every frame\n", rows.size());
    else
      std::printf("%zu of %zu methods WRONG (marked)\n", wrong, rows.size());
  } else {
    std::printf("\nno method ran without a problem of its own\n");
  }
  std::printf("s/frame: median over the runs of the frames' total, per frame; moves, queries: its two parts\n"
              "(in the median run; queries = s/frame - moves). SAH/bulk: sah_cost() after the last frame over\n"
              "a construct() of the final disks with the same margin; SAH/bulk0: over a margin-0 construct()\n"
              "(the margin's own cost included)\n");

  // The goals.
  const W4Row *best = nullptr;
  double worst_drift = 0;
  for (const W4Row &r : rows)
    if (r.name.compare(0, 4, "ours") == 0 && r.problem().empty()) { // only rows without a problem
      if (!best || r.per_frame() < best->per_frame()) best = &r;
      worst_drift = std::max(worst_drift, r.runs.back().sah_same);
    }
  if (best) {
    std::printf("\nGoals: ours <= 0.5 x Box2D's time per frame: ");
    if (box2d)
      std::printf("best %s %.3fx -> %s\n", best->name.c_str(), best->per_frame() / box2d->per_frame(),
                  best->per_frame() <= 0.5 * box2d->per_frame() ? "met" : "not met");
    else
      std::printf("no Box2D row\n");
    const W4Row *quad = nullptr;
    for (const W4Row &r : rows)
      if (r.name == "boost-quad16" && r.problem().empty()) quad = &r;
    std::printf("       ours <= 0.7 x Boost quadratic's time per frame (node width, issue 19): ");
    if (quad)
      std::printf("best %s %.3fx -> %s\n", best->name.c_str(), best->per_frame() / quad->per_frame(),
                  best->per_frame() <= 0.7 * quad->per_frame() ? "met" : "not met");
    else
      std::printf("no Boost quadratic row\n");
    std::printf("       SAH drift (SAH/bulk) <= 1.25 for every margin (of the rows not WRONG): worst %.4f -> %s\n",
                worst_drift,
                worst_drift <= 1.25 ? "met" : "not met");
  }
  if (wrong) {
    std::printf("FAILED: %zu W4 method%s wrong (above)\n", wrong, wrong == 1 ? "" : "s");
    g_failed = true;
  }
}

// ---------------------------------------------------------------------------
// k-nearest.

using Hit = std::pair<double, std::uint32_t>; // (exact distance, disk index)

std::vector<Disk> knn_disks(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(0, kSide), rad(0.2, 0.6);
  std::vector<Disk> v;
  v.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng), r = rad(rng);
    v.emplace_back(Point(x, y), r, Color(0, 0, 0));
  }
  return v;
}

/// ours: one query into `out` (cleared), as (distance, id) pairs.
void knn_ours(const Tree &tree, const Point &p, std::size_t k, std::vector<Tree::neighbor> &buf, std::vector<Hit> &out) {
  buf.clear();
  tree.nearest(p, k, std::back_inserter(buf));
  out.clear();
  for (const Tree::neighbor &nb : buf) out.emplace_back(nb.distance, nb.id.id);
}

#if BENCH_HAVE_BOOST
using KnnTree = bgi::rtree<BValue, bgi::rstar<16>>;

double box_distance(const BBox &b, const Point &p) {
  const double dx = std::max({b.min_corner().get<0>() - p.x, p.x - b.max_corner().get<0>(), 0.0});
  const double dy = std::max({b.min_corner().get<1>() - p.y, p.y - b.max_corner().get<1>(), 0.0});
  return std::sqrt(dx * dx + dy * dy);
}

/// A box distance, computed in floating point, may exceed its disk's
/// computed distance by rounding (both are about 1e-13 off at this scale):
/// a box counts as farther than `d` only beyond d + kSlack.
constexpr double kSlack = 1e-9;

/// Keeps the k best (distance, index) in a max-heap `best`.
void offer(std::vector<Hit> &best, std::size_t k, const Hit &h) {
  if (best.size() < k) {
    best.push_back(h);
    std::push_heap(best.begin(), best.end());
  } else if (h < best.front()) {
    std::pop_heap(best.begin(), best.end());
    best.back() = h;
    std::push_heap(best.begin(), best.end());
  }
}

void knn_boost_incr(const KnnTree &rt, const std::vector<Disk> &d, const Point &p, std::size_t k,
                    std::vector<Hit> &best) {
  for (std::size_t want = 2 * k + 4;; want *= 2) {
    best.clear();
    std::size_t seen = 0;
    bool done = false;
    for (auto it = rt.qbegin(bgi::nearest(BPoint(p.x, p.y), unsigned(want))); it != rt.qend(); ++it, ++seen) {
      if (best.size() == k && box_distance(it->first, p) > best.front().first + kSlack) {
        done = true;
        break;
      }
      offer(best, k, Hit(distance(p, d[it->second]), it->second));
    }
    if (done || seen < want) break;
  }
  std::sort_heap(best.begin(), best.end());
}

void knn_boost_grow(const KnnTree &rt, const std::vector<Disk> &d, const Point &p, std::size_t k,
                    std::vector<Hit> &best, std::vector<BValue> &found) {
  for (std::size_t want = 2 * k + 4;; want *= 2) {
    found.clear();
    rt.query(bgi::nearest(BPoint(p.x, p.y), unsigned(want)), std::back_inserter(found));
    best.clear();
    double far = 0;
    for (const BValue &v : found) {
      far = std::max(far, box_distance(v.first, p));
      offer(best, k, Hit(distance(p, d[v.second]), v.second));
    }
    if (found.size() < want || (best.size() == k && far > best.front().first + kSlack)) break;
  }
  std::sort_heap(best.begin(), best.end());
}
#endif

/// Fails unless `got` has the same k distances as `want` (exactly) and the
/// same ids but among disks at the k-th distance, where each must be at it.
void same_knn(const std::string &who, const std::vector<Disk> &d, const Point &p, std::size_t k, std::vector<Hit> want,
              std::vector<Hit> got) {
  auto where = [&] {
    char buf[96];
    std::snprintf(buf, sizeof buf, " at (%.17g, %.17g), k = %zu", p.x, p.y, k);
    return std::string(buf);
  };
  const std::size_t expect = std::min(k, d.size());
  if (want.size() != expect || got.size() != expect)
    fail(who + ": " + std::to_string(got.size()) + " neighbours against " + std::to_string(want.size()) + where());
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  const double kth = want.back().first;
  for (std::size_t j = 0; j < expect; ++j) {
    if (got[j].first != want[j].first)
      fail(who + ": neighbour " + std::to_string(j) + " at distance " + std::to_string(got[j].first) + " against " +
           std::to_string(want[j].first) + where());
    if (got[j].first < kth && got[j].second != want[j].second)
      fail(who + ": neighbour " + std::to_string(j) + " is disk " + std::to_string(got[j].second) + ", not " +
           std::to_string(want[j].second) + where());
    if (distance(p, d[got[j].second]) != got[j].first)
      fail(who + ": disk " + std::to_string(got[j].second) + " is not at its reported distance" + where());
    if (j > 0 && got[j] == got[j - 1]) fail(who + ": disk " + std::to_string(got[j].second) + " twice" + where());
  }
}

std::vector<Hit> knn_brute(const std::vector<Disk> &d, const Point &p, std::size_t k) {
  std::vector<Hit> all(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) all[i] = Hit(distance(p, d[i]), std::uint32_t(i));
  k = std::min(k, all.size());
  std::partial_sort(all.begin(), all.begin() + std::ptrdiff_t(k), all.end());
  all.resize(k);
  return all;
}

void knn(const Options &opt) {
  const std::size_t n = std::size_t(opt.knn_n > 0 ? opt.knn_n : opt.quick ? 100000 : 1000000);
  const std::size_t nq = std::size_t(opt.queries > 0 ? opt.queries : opt.quick ? 1000 : 10000);
  const std::vector<Disk> d = knn_disks(n, opt.seed + 1);
  std::vector<Point> q;
  {
    std::mt19937_64 rng(opt.seed + 2);
    std::uniform_real_distribution<double> xy(0, kSide);
    for (std::size_t i = 0; i < nq; ++i) {
      const double x = xy(rng), y = xy(rng);
      q.emplace_back(x, y);
    }
  }
  std::printf("\nk-nearest: %zu disks r0.2-0.6 in 1000 x 1000 (W2's density), %zu query points, seed %llu;\n"
              "  exact distance to the disk (0 inside); %d runs, median; only the queries are timed\n",
              n, nq, static_cast<unsigned long long>(opt.seed), opt.runs);

  const bool do_ours = wanted(opt, "ours");
  Tree tree(kSplit, 0);
  auto t0 = Clock::now();
  if (do_ours) tree.construct(d);
  const double ours_build = std::chrono::duration<double>(Clock::now() - t0).count();
#if BENCH_HAVE_BOOST
  const bool do_boost = wanted(opt, "boost");
  t0 = Clock::now();
  std::vector<BValue> values;
  if (do_boost) {
    values.reserve(n);
    for (std::size_t i = 0; i < n; ++i) values.emplace_back(to_boost(d[i]), std::uint32_t(i));
  }
  const KnnTree rt(values.begin(), values.end());
  const double boost_build = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf("  build: ours construct() %.3f s, Boost packed rstar<16> %.3f s (not timed below)\n\n", ours_build,
              boost_build);
#else
  const bool do_boost = false;
  std::printf("  build: ours construct() %.3f s\nskipped Boost.Geometry: apt-get install libboost-dev\n\n", ours_build);
#endif

  // Correctness first, untimed: ours against brute force at a few points,
  // and against each Boost variant at every point.
  const std::size_t ks[] = {1, 10, 100};
  std::vector<Tree::neighbor> buf;
  std::vector<Hit> a, b;
#if BENCH_HAVE_BOOST
  std::vector<BValue> found;
#endif
  for (std::size_t k : ks) {
    for (std::size_t i = 0; i < nq; ++i) {
      if (do_ours) {
        knn_ours(tree, q[i], k, buf, a);
        for (const Tree::neighbor &nb : buf)
          if (nb.shape != &tree.get(nb.id)) fail("ours: a neighbour's shape is not get(its id)");
        if (i < 5) same_knn("ours against brute force", d, q[i], k, knn_brute(d, q[i], k), a);
      }
#if BENCH_HAVE_BOOST
      if (do_boost) {
        knn_boost_incr(rt, d, q[i], k, b);
        if (do_ours) same_knn("Boost incr against ours", d, q[i], k, a, b);
        else if (i < 5) same_knn("Boost incr against brute force", d, q[i], k, knn_brute(d, q[i], k), b);
        std::vector<Hit> c;
        knn_boost_grow(rt, d, q[i], k, c, found);
        same_knn("Boost grow against Boost incr", d, q[i], k, b, c);
      }
#endif
    }
  }
  if (do_ours && do_boost)
    std::printf("  checked: ours and both Boost variants give the same k distances at all %zu points for\n"
                "  k = 1, 10, 100; ours matches a brute-force scan at %zu of them\n\n",
                nq, std::min<std::size_t>(5, nq));
  else
    std::printf("  checked: %s matches a brute-force scan at %zu points for k = 1, 10, 100%s\n\n",
                do_ours ? "ours" : "Boost incr", std::min<std::size_t>(5, nq),
                do_boost ? " (Boost grow: at every point)" : "");

  std::printf("%6s %14s %14s %14s %12s %10s\n", "k", "ours us/query", "Boost incr us", "Boost grow us", "ours/Boost",
              "mean k-th d");
  std::printf("%s\n", std::string(76, '-').c_str());
  double worst_ratio = 0;
  for (std::size_t k : ks) {
    double sink = 0;
    auto time = [&](auto &&one) {
      std::vector<double> t;
      for (int r = 0; r < opt.runs; ++r) {
        Timer timer;
        for (std::size_t i = 0; i < nq; ++i) sink += one(q[i]);
        t.push_back(timer.stop());
      }
      return median(t) / double(nq) * 1e6;
    };
    double ours = 0, incr = 0, grow = 0, kth_sum = 0;
    if (do_ours)
      ours = time([&](const Point &p) {
        buf.clear();
        tree.nearest(p, k, std::back_inserter(buf));
        return buf.back().distance;
      });
#if BENCH_HAVE_BOOST
    if (do_boost) {
      incr = time([&](const Point &p) {
        knn_boost_incr(rt, d, p, k, b);
        return b.back().first;
      });
      grow = time([&](const Point &p) {
        knn_boost_grow(rt, d, p, k, b, found);
        return b.back().first;
      });
    }
#endif
    kth_sum = sink / double(opt.runs * std::max(1, int(do_ours) + 2 * int(do_boost)));
    const double best_boost = do_boost ? std::min(incr, grow) : 0;
    const double ratio = do_ours && do_boost ? ours / best_boost : 0;
    worst_ratio = std::max(worst_ratio, ratio);
    std::printf("%6zu %14s %14s %14s %12s %10.4f\n", k, cell("%.3f", ours).c_str(), cell("%.3f", incr).c_str(),
                cell("%.3f", grow).c_str(), cell("%.3f", ratio).c_str(), kth_sum / double(nq));
  }
  if (do_ours && do_boost)
    std::printf("\nGoals: ours / Boost (its faster variant) <= 1.0 for every k: worst %.3f -> %s\n"
                "       the same <= 0.7 (node width, issue 19): %s\n",
                worst_ratio, worst_ratio <= 1.0 ? "met" : "not met", worst_ratio <= 0.7 ? "met" : "not met");
}

void usage() {
  std::printf("usage: build/bench_moving [--runs N] [--quick] [--only W4|knn] [--frames F] [--n N]\n"
              "                          [--knn-n N] [--queries Q] [--margins a,b,...] [--method NAME] [--seed S]\n"
              "  (see the comment at the top of bench/moving.cpp)\n");
}

} // namespace

int main(int argc, char **argv) {
  Options opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_moving: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--quick") opt.quick = true;
    else if (a == "--runs") opt.runs = std::max(1, std::atoi(value().c_str())), opt.runs_given = true;
    else if (a == "--only") opt.only = value();
    else if (a == "--method") opt.method = value();
    else if (a == "--frames") opt.frames = std::max(1, std::atoi(value().c_str()));
    else if (a == "--n") opt.n = std::atol(value().c_str());
    else if (a == "--knn-n") opt.knn_n = std::atol(value().c_str());
    else if (a == "--queries") opt.queries = std::atol(value().c_str());
    else if (a == "--seed") opt.seed = std::strtoull(value().c_str(), nullptr, 10);
    else if (a == "--margins") {
      opt.margins.clear();
      const std::string v = value();
      for (std::size_t at = 0; at <= v.size();) {
        std::size_t comma = v.find(',', at);
        if (comma == std::string::npos) comma = v.size();
        opt.margins.push_back(std::atof(v.substr(at, comma - at).c_str()));
        at = comma + 1;
      }
    } else if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else {
      std::fprintf(stderr, "bench_moving: unknown argument '%s'\n", a.c_str());
      usage();
      return 2;
    }
  }
  if (opt.only != "" && opt.only != "W4" && opt.only != "knn") {
    std::fprintf(stderr, "bench_moving: --only takes W4 or knn\n");
    return 2;
  }
  if (opt.quick && !opt.runs_given) opt.runs = 1;
  std::printf("bvh moving-scene and k-nearest benchmark; %s; g++ -O2\n\n", BENCH_BUILD_INFO);
  if (opt.only.empty() || opt.only == "W4") w4(opt);
  if (opt.only.empty() || opt.only == "knn") knn(opt);
  return g_failed ? 1 : 0;
}
