// bench/bench.cpp — `make bench`: times our BVH against a brute-force scan,
// Boost.Geometry's R-trees, Box2D's b2DynamicTree and a uniform grid on
// discard-overlap sampling (Poisson-disk style: keep a candidate unless it
// touches one already kept) and on bulk build + probes. Writes the table to
// bench/results.txt and the scaling sweep to bench/results.svg.
//
//   make bench               full run (a few minutes on 2 cores)
//   make bench QUICK=1       reduced set, under a minute (results in build/bench-quick/)
//   make bench RUNS=7        7 runs per (workload, method); median reported
//   build/bench --help       every flag (--only, --method, --runs, --quick, ...)
//
// Every method keeps exactly the same shapes: each finds candidates by its
// own box query and decides with the same exact `intersect()` of
// intersect.h; the run compares every method's kept set (W3: the set of
// colliding probes) with ours and fails on any difference.
//
// Each (workload, method, run) runs in a forked child, so its peak RSS
// (wait4's ru_maxrss) is its own; only the index work is timed (loading is
// not, nor the child's first touch of the input pages it shares with the
// parent: touch_pages). "peak MB" is the child's whole peak, which includes the candidate
// shapes it inherited; "+MB" is that peak minus the child's RSS when it
// started, i.e. what the index itself added.
//
// Instruction counts of one workload (no fork, only the timed region is
// instrumented, via <valgrind/callgrind.h> when installed):
//   make build/bench
//   valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=build/callgrind.out
//            build/bench --only W1 --method ours          (one command line)
//   callgrind_annotate build/callgrind.out | head -40
// (--only takes a workload name from the table: W1, W2, W3, tri, quad,
// S1000 ... S1000000; --method one of ours, ours-d8, brute, boost-quad16,
// boost-rstar16, box2d, grid.)
//
// Peers are compiled in only when their headers (and for Box2D the library,
// checked by the Makefile, which passes -DBENCH_HAVE_BOX2D_LIB) are present;
// otherwise the run prints "skipped NAME: apt-get install PACKAGE". To see
// that path with the peers installed, add -DBENCH_NO_BOOST / -DBENCH_NO_BOX2D.

// insert_disjoint's step timings (bvh::DisjointSteps, include/bvh/disjoint.h):
// the serial fraction that ours-par prints (steps 1, 2 and 4 parallel, 3 and
// 0 serial), each step's wall seconds and the process's CPU seconds in it
// (all threads: the work, which a loaded machine inflates less than the
// wall time). Only the methods that print them (ours-par, ours-par1) pass
// one; the others are timed without the clock.
#include <ctime>
inline double cpu_now() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

#include <bvh/bvh.h>
#include <bvh/scene.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "peers.h"

namespace bench {

using Clock = std::chrono::steady_clock;
using Ids = std::vector<std::uint32_t>;

// ---------------------------------------------------------------------------
// Small utilities.

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The timed region of one run: starts the clock (and callgrind's
/// instrumentation, when running under it), stop() returns the seconds.
class Timer {
public:
  Timer() {
    BENCH_CG_START();
    t0_ = Clock::now();
  }
  double stop() {
    const double s = seconds_since(t0_);
    BENCH_CG_STOP();
    return s;
  }

private:
  Clock::time_point t0_;
};

/// The current resident set size in KiB (VmRSS of /proc/self/status).
long rss_now_kb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, 6, "VmRSS:") == 0) return std::atol(line.c_str() + 6);
  return 0;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : (v[m - 1] + v[m]) / 2;
}

std::string fmt(const char *format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string xml_escape(const std::string &s) {
  std::string r;
  for (char ch : s) {
    if (ch == '<') r += "&lt;";
    else if (ch == '>') r += "&gt;";
    else if (ch == '&') r += "&amp;";
    else if (ch == '"') r += "&quot;";
    else r += ch;
  }
  return r;
}

std::string count_label(long n) {
  if (n >= 1000000 && n % 1000000 == 0) return std::to_string(n / 1000000) + "M";
  if (n >= 1000 && n % 1000 == 0) return std::to_string(n / 1000) + "k";
  return std::to_string(n);
}

// ---------------------------------------------------------------------------
// The methods. Each returns the candidate indices it kept (discard) or the
// probe indices that collide (bulk), and the seconds of its index work.

struct Outcome {
  double seconds = 0;
  Ids ids;
};

// --- ours ---

/// --phases: discard_ours() also reads the clock around each collision()
/// and insert() call and prints, on stderr, the loop's time split between
/// them (less the clock's own cost, measured first). The reads add to the
/// loop's own time, so its reported seconds then overstate it a little.
bool phases = false;

/// The cost of one Clock::now(), in seconds: the mean over many reads.
double clock_cost() {
  constexpr int kReads = 1000000;
  const Clock::time_point t0 = Clock::now();
  Clock::time_point t = t0;
  for (int i = 0; i < kReads; ++i) t = Clock::now();
  return std::chrono::duration<double>(t - t0).count() / kReads;
}

template <class T, int W = bvh::course_width>
Outcome discard_ours(const std::vector<T> &c, int depth_limit, int split = bvh::course_split_threshold) {
  Outcome o;
  const double cost = phases ? clock_cost() : 0;
  Timer timer;
  BVH<T, bvh::shape_traits<T>, W> tree(split, depth_limit);
  if (!phases) {
    for (std::uint32_t i = 0; i < c.size(); ++i)
      if (!tree.collision(c[i])) {
        tree.insert(c[i]);
        o.ids.push_back(i);
      }
    o.seconds = timer.stop();
    return o;
  }
  // (The same loop with the clock read around each call; the one above,
  // which the tables time, stays free of the reads.)
  double searching = 0, inserting = 0;
  Clock::time_point t = Clock::now();
  for (std::uint32_t i = 0; i < c.size(); ++i) {
    const bool hit = tree.collision(c[i]);
    const Clock::time_point u = Clock::now();
    searching += std::chrono::duration<double>(u - t).count() - cost;
    t = u;
    if (!hit) {
      tree.insert(c[i]);
      o.ids.push_back(i);
      const Clock::time_point v = Clock::now();
      inserting += std::chrono::duration<double>(v - t).count() - cost;
      t = v;
    }
  }
  o.seconds = timer.stop();
  std::cerr << "bench: phases of the loop (width " << W << ", split " << split << "): collision() " << fmt("%.4f", searching)
            << " s for " << c.size() << " calls, insert() " << fmt("%.4f", inserting) << " s for " << o.ids.size()
            << " (the clock's " << fmt("%.1f", cost * 1e9) << " ns a read taken off), loop " << fmt("%.4f", o.seconds)
            << " s with the reads\n";
  return o;
}

/// The same loop by one call, insert_disjoint(c, 1): on one thread, the
/// loop's result, with the searches of a batch interleaved.
template <class T, int W> Outcome discard_ours_sampled(const std::vector<T> &c, int split, unsigned threads = 1) {
  Outcome o;
  Timer timer;
  BVH<T, bvh::shape_traits<T>, W> tree(split);
  const std::vector<std::size_t> kept = tree.insert_disjoint(c, threads);
  o.seconds = timer.stop();
  o.ids.assign(kept.begin(), kept.end());
  return o;
}

/// insert_disjoint() on `threads` threads (0: all cores), with the serial
/// fraction of its steps on stderr (parallel: the queries against the tree
/// and the survivors' pair tests; serial: the rest, mostly the insertions).
template <class T> Outcome discard_ours_par(const std::vector<T> &c, unsigned threads) {
  Outcome o;
  bvh::DisjointSteps steps;
  Timer timer;
  const double cpu_start = cpu_now();
  CourseBVH<T> tree(4, 0);
  const std::vector<std::size_t> kept = tree.insert_disjoint(c, threads, &steps);
  o.seconds = timer.stop();
  o.ids.assign(kept.begin(), kept.end());
  const double cpu = cpu_now() - cpu_start;
  const double *t = steps.seconds;
  const double *u = steps.cpu_seconds;
  const double serial = t[0] + t[3], parallel = t[1] + t[2] + t[4];
  if (serial + parallel > 0) {
    std::cerr << "bench: insert_disjoint(" << threads << "): steps 1 (queries) " << fmt("%.4f", t[1])
              << " s, 2 (pairs) " << fmt("%.4f", t[2]) << " s, 4 (parallel inserts) " << fmt("%.4f", t[4])
              << " s, 3 (serial inserts) " << fmt("%.4f", t[3]) << " s, other serial " << fmt("%.4f", t[0])
              << " s; serial fraction of the wall time " << fmt("%.3f", serial / (serial + parallel))
              << "; CPU seconds, all threads: steps 1 " << fmt("%.4f", u[1]) << ", 2 " << fmt("%.4f", u[2]) << ", 4 "
              << fmt("%.4f", u[4]) << ", 3 " << fmt("%.4f", u[3]) << ", other " << fmt("%.4f", u[0])
              << "; whole call: " << fmt("%.4f", o.seconds) << " s wall, " << fmt("%.4f", cpu) << " s CPU\n";
    // One line for scripts (bench/disjoint_scaling.sh): wall and CPU
    // seconds of the parallel steps (1, 2, 4) and of the serial ones (3, 0).
    std::cerr << "bench: disjoint-profile threads=" << threads << " n=" << c.size() << " parallel_wall="
              << fmt("%.4f", parallel) << " serial_wall=" << fmt("%.4f", serial) << " parallel_cpu="
              << fmt("%.4f", u[1] + u[2] + u[4]) << " serial_cpu=" << fmt("%.4f", u[0] + u[3]) << " total_wall="
              << fmt("%.4f", o.seconds) << " total_cpu=" << fmt("%.4f", cpu) << "\n";
  }
  if (serial + parallel <= 0)
    std::cerr << "bench: insert_disjoint(" << threads << "): " << fmt("%.4f", o.seconds) << " s wall, "
              << fmt("%.4f", cpu) << " s CPU\n";
  return o;
}

/// What this machine lends a parallel loop right now: a spin loop's work
/// on every core against the same work on one, in wall time (2.0 on an idle
/// 2-core machine; about 1.0 when other processes hold the cores).
double available_parallelism() {
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  auto spin = [](long n) {
    volatile long sink = 0;
    long s = 0;
    for (long i = 0; i < n; ++i) s += i ^ (s >> 3);
    sink = s;
    (void)sink;
  };
  const long total = 400000000;
  const auto t0 = Clock::now();
  spin(total);
  const double one = seconds_since(t0);
  const auto t1 = Clock::now();
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < threads; ++k) pool.emplace_back(spin, total / long(threads));
  spin(total / long(threads));
  for (std::thread &t : pool) t.join();
  const double all = seconds_since(t1);
  return all > 0 ? one / all : 0;
}

/// `threads`: construct()'s build threads (0: its default, hardware concurrency).
template <class T, int W = bvh::course_width>
Outcome bulk_ours(const std::vector<T> &base, const std::vector<T> &probes, int depth_limit, unsigned threads = 0,
                  int split = bvh::course_split_threshold) {
  Outcome o;
  Timer timer;
  BVH<T, bvh::shape_traits<T>, W> tree(split, depth_limit);
  tree.set_build_threads(threads);
  tree.construct(base);
  for (std::uint32_t i = 0; i < probes.size(); ++i)
    if (tree.collision(probes[i])) o.ids.push_back(i);
  o.seconds = timer.stop();
  return o;
}

// --- brute force: a scan of every kept box, then the exact test ---

template <class T> Outcome discard_brute(const std::vector<T> &c) {
  Outcome o;
  Timer timer;
  std::vector<BoundingBox> boxes;
  std::vector<T> kept;
  for (std::uint32_t i = 0; i < c.size(); ++i) {
    const BoundingBox b = c[i].getBox();
    bool hit = false;
    for (std::size_t k = 0; k < boxes.size(); ++k)
      if (boxes[k].overlaps(b) && intersect(kept[k], c[i])) {
        hit = true;
        break;
      }
    if (!hit) {
      boxes.push_back(b);
      kept.push_back(c[i]);
      o.ids.push_back(i);
    }
  }
  o.seconds = timer.stop();
  return o;
}

// --- uniform grid (disks only): cell = the largest diameter, so a disk can
// touch only disks whose centre lies in its own or the 8 neighbouring cells.
// Each cell is a singly linked list of kept disks (head per cell, next per
// disk): insert-only, no per-cell allocation. The practical floor. ---

Outcome discard_grid(const std::vector<Disk> &c) {
  Outcome o;
  Timer timer; // (the scan for the cell size and bounds is the grid's own work)
  double max_r = 0, x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const Disk &d : c) {
    max_r = std::max(max_r, d.getRadius());
    x0 = std::min(x0, d.getCenter().x);
    y0 = std::min(y0, d.getCenter().y);
    x1 = std::max(x1, d.getCenter().x);
    y1 = std::max(y1, d.getCenter().y);
  }
  const double cell = std::max(2 * max_r, 1e-9);
  const long nx = long((x1 - x0) / cell) + 1, ny = long((y1 - y0) / cell) + 1;
  std::vector<std::int32_t> head(std::size_t(nx * ny), -1), next;
  std::vector<Disk> kept;
  for (std::uint32_t i = 0; i < c.size(); ++i) {
    const Disk &d = c[i];
    const BoundingBox b = d.getBox();
    const long cx = long((d.getCenter().x - x0) / cell), cy = long((d.getCenter().y - y0) / cell);
    bool hit = false;
    for (long gy = std::max(0L, cy - 1); gy <= std::min(ny - 1, cy + 1) && !hit; ++gy)
      for (long gx = std::max(0L, cx - 1); gx <= std::min(nx - 1, cx + 1) && !hit; ++gx)
        for (std::int32_t k = head[std::size_t(gy * nx + gx)]; k >= 0; k = next[std::size_t(k)])
          if (kept[std::size_t(k)].getBox().overlaps(b) && intersect(kept[std::size_t(k)], d)) {
            hit = true;
            break;
          }
    if (!hit) {
      const std::size_t cellix = std::size_t(cy * nx + cx);
      next.push_back(head[cellix]);
      head[cellix] = std::int32_t(kept.size());
      kept.push_back(d);
      o.ids.push_back(i);
    }
  }
  o.seconds = timer.stop();
  return o;
}

// --- Boost.Geometry R-trees ---
#if BENCH_HAVE_BOOST


/// True when some value of `rt` whose box meets `b` (boundaries count, as
/// in ours) holds a shape of `shapes` intersecting `s`: the query iterator
/// stops at the first exact hit.
template <class Tree, class T> bool boost_hits(const Tree &rt, const BBox &b, const std::vector<T> &shapes, const T &s) {
  for (auto it = rt.qbegin(bgi::intersects(b)); it != rt.qend(); ++it)
    if (intersect(shapes[it->second], s)) return true;
  return false;
}

template <class Params, class T> Outcome discard_boost(const std::vector<T> &c) {
  Outcome o;
  Timer timer;
  bgi::rtree<BValue, Params> rt;
  for (std::uint32_t i = 0; i < c.size(); ++i) {
    const BBox b = to_boost(c[i].getBox());
    if (!boost_hits(rt, b, c, c[i])) {
      rt.insert(BValue(b, i));
      o.ids.push_back(i);
    }
  }
  o.seconds = timer.stop();
  return o;
}

/// The packing (range) constructor: Boost's bulk load.
template <class Params, class T> Outcome bulk_boost(const std::vector<T> &base, const std::vector<T> &probes) {
  Outcome o;
  Timer timer;
  std::vector<BValue> values;
  values.reserve(base.size());
  for (std::uint32_t i = 0; i < base.size(); ++i) values.emplace_back(to_boost(base[i].getBox()), i);
  const bgi::rtree<BValue, Params> rt(values.begin(), values.end());
  for (std::uint32_t i = 0; i < probes.size(); ++i)
    if (boost_hits(rt, to_boost(probes[i].getBox()), base, probes[i])) o.ids.push_back(i);
  o.seconds = timer.stop();
  return o;
}
#endif

// --- Box2D's dynamic AABB tree (float boxes, fattened by b2_aabbExtension
// = 0.1 as Box2D does; rounded outwards so no double box is ever cut) ---
#if BENCH_HAVE_BOX2D
float down(double v) {
  float f = float(v);
  return double(f) > v ? std::nextafter(f, -INFINITY) : f;
}
float up(double v) {
  float f = float(v);
  return double(f) < v ? std::nextafter(f, INFINITY) : f;
}
b2AABB to_box2d(const BoundingBox &b) {
  b2AABB a;
  a.lowerBound.Set(down(b.getMin().x), down(b.getMin().y));
  a.upperBound.Set(up(b.getMax().x), up(b.getMax().y));
  return a;
}

template <class T> struct Box2DQuery {
  const b2DynamicTree *tree;
  const std::vector<T> *shapes;
  const T *shape;
  bool hit = false;
  bool QueryCallback(int32 proxy) {
    const auto k = reinterpret_cast<std::uintptr_t>(tree->GetUserData(proxy));
    if (intersect((*shapes)[k], *shape)) {
      hit = true;
      return false; // stop the query
    }
    return true;
  }
};

template <class T> bool box2d_hits(const b2DynamicTree &tree, const std::vector<T> &shapes, const T &s) {
  Box2DQuery<T> q{&tree, &shapes, &s};
  tree.Query(&q, to_box2d(s.getBox()));
  return q.hit;
}

template <class T> Outcome discard_box2d(const std::vector<T> &c) {
  Outcome o;
  Timer timer;
  b2DynamicTree tree;
  for (std::uint32_t i = 0; i < c.size(); ++i)
    if (!box2d_hits(tree, c, c[i])) {
      tree.CreateProxy(to_box2d(c[i].getBox()), reinterpret_cast<void *>(std::uintptr_t(i)));
      o.ids.push_back(i);
    }
  o.seconds = timer.stop();
  return o;
}

/// Box2D has no bulk build (RebuildBottomUp is quadratic): one proxy at a time.
template <class T> Outcome bulk_box2d(const std::vector<T> &base, const std::vector<T> &probes) {
  Outcome o;
  Timer timer;
  b2DynamicTree tree;
  for (std::uint32_t i = 0; i < base.size(); ++i)
    tree.CreateProxy(to_box2d(base[i].getBox()), reinterpret_cast<void *>(std::uintptr_t(i)));
  for (std::uint32_t i = 0; i < probes.size(); ++i)
    if (box2d_hits(tree, base, probes[i])) o.ids.push_back(i);
  o.seconds = timer.stop();
  return o;
}
#endif

// ---------------------------------------------------------------------------
// The method table.

struct Method {
  std::string name;
  std::string label; // as shown in the table
  bool available;
  std::string missing; // why not, when unavailable
};

// ours-w8k32 is the library's default tree, BVH<T> (defaults.h); "ours"
// and its variants the course's, CourseBVH<T>.
static_assert(bvh::default_width == 8 && bvh::default_split_threshold == 32,
              "the default tree changed: rename ours-w8k32 and its labels");
static_assert(bvh::course_width == 3 && bvh::course_split_threshold == 4, "the course's tree is width 3, split 4");
std::vector<Method> all_methods() {
  return {
      {"ours", "ours course BVH(4, unlimited)", true, ""},
      {"ours-1t", "ours course BVH(4), 1 build thread", true, ""}, // bulk workloads only
      {"ours-d8", "ours course BVH(4, depth 8)", true, ""},
      {"ours-w4", "ours width 4, BVH(4)", true, ""},
      {"ours-w8", "ours width 8, BVH(4)", true, ""},
      {"ours-w8k8", "ours width 8, BVH(8)", true, ""},
      {"ours-w8k16", "ours width 8, BVH(16)", true, ""},
      {"ours-w8k32", "ours default: width 8, BVH(32)", true, ""},
      {"ours-w8k64", "ours width 8, BVH(64)", true, ""},
      {"ours-w8k32-s1", "ours w8 k32 disjoint(c,1)", true, ""}, // discard workloads only
      {"ours-w8k32-all", "ours w8 k32 disjoint(c,0)", true, ""}, // discard workloads only
      {"ours-par", "ours insert_disjoint, all", true, ""},      // discard workloads only
      {"ours-par1", "ours insert_disjoint(.., 1)", true, ""},   // discard workloads only
      {"brute", "brute force", true, ""},
      {"boost-quad16", "Boost rtree quadratic<16>", BENCH_HAVE_BOOST != 0,
       "skipped Boost.Geometry: apt-get install libboost-dev"},
      {"boost-rstar16", "Boost rtree rstar<16>", BENCH_HAVE_BOOST != 0,
       "skipped Boost.Geometry: apt-get install libboost-dev"},
      {"box2d", "Box2D b2DynamicTree", BENCH_HAVE_BOX2D != 0, "skipped Box2D: apt-get install libbox2d-dev"},
      {"grid", "uniform grid (floor)", true, ""},
  };
}

/// Runs method `m` on a discard workload; false when it does not apply.
template <class T> bool run_discard(const std::string &m, const std::vector<T> &c, Outcome &o) {
  if (m == "ours") o = discard_ours(c, 0);
  else if (m == "ours-d8") o = discard_ours(c, 8);
  else if (m == "ours-w4") o = discard_ours<T, 4>(c, 0);
  else if (m == "ours-w8") o = discard_ours<T, 8>(c, 0);
  else if (m == "ours-w8k8") o = discard_ours<T, 8>(c, 0, 8);
  else if (m == "ours-w8k16") o = discard_ours<T, 8>(c, 0, 16);
  else if (m == "ours-w8k32") o = discard_ours<T, bvh::default_width>(c, 0, bvh::default_split_threshold);
  else if (m == "ours-w8k64") o = discard_ours<T, 8>(c, 0, 64);
  else if (m == "ours-w8k32-s1") o = discard_ours_sampled<T, 8>(c, 32);
  else if (m == "ours-w8k32-all") o = discard_ours_sampled<T, 8>(c, 32, 0);
  else if (m == "ours-par") o = discard_ours_par(c, 0);
  else if (m == "ours-par1") o = discard_ours_par(c, 1);
  else if (m == "brute") o = discard_brute(c);
#if BENCH_HAVE_BOOST
  else if (m == "boost-quad16") o = discard_boost<bgi::quadratic<16>>(c);
  else if (m == "boost-rstar16") o = discard_boost<bgi::rstar<16>>(c);
#endif
#if BENCH_HAVE_BOX2D
  else if (m == "box2d") o = discard_box2d(c);
#endif
  else if (m == "grid") {
    if constexpr (std::is_same<T, Disk>::value) o = discard_grid(c);
    else return false;
  } else return false;
  return true;
}

template <class T> bool run_bulk(const std::string &m, const std::vector<T> &base, const std::vector<T> &probes, Outcome &o) {
  if (m == "ours") o = bulk_ours(base, probes, 0);
  else if (m == "ours-1t") o = bulk_ours(base, probes, 0, 1);
  else if (m == "ours-d8") o = bulk_ours(base, probes, 8);
  else if (m == "ours-w4") o = bulk_ours<T, 4>(base, probes, 0);
  else if (m == "ours-w8") o = bulk_ours<T, 8>(base, probes, 0);
  else if (m == "ours-w8k8") o = bulk_ours<T, 8>(base, probes, 0, 0, 8);
  else if (m == "ours-w8k16") o = bulk_ours<T, 8>(base, probes, 0, 0, 16);
  else if (m == "ours-w8k32") o = bulk_ours<T, bvh::default_width>(base, probes, 0, 0, bvh::default_split_threshold);
  else if (m == "ours-w8k64") o = bulk_ours<T, 8>(base, probes, 0, 0, 64);
#if BENCH_HAVE_BOOST
  else if (m == "boost-quad16") o = bulk_boost<bgi::quadratic<16>>(base, probes);
  else if (m == "boost-rstar16") o = bulk_boost<bgi::rstar<16>>(base, probes);
#endif
#if BENCH_HAVE_BOX2D
  else if (m == "box2d") o = bulk_box2d(base, probes);
#endif
  else return false;
  return true;
}

// ---------------------------------------------------------------------------
// Running one measurement in a forked child.

struct Measured {
  bool ok = false;
  std::string error;
  double seconds = 0;
  long start_kb = 0, peak_kb = 0;
  Ids ids;
};

bool write_all(int fd, const void *p, std::size_t n) {
  const char *c = static_cast<const char *>(p);
  while (n > 0) {
    const ssize_t w = ::write(fd, c, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    c += w;
    n -= std::size_t(w);
  }
  return true;
}

bool read_all(int fd, void *p, std::size_t n) {
  char *c = static_cast<char *>(p);
  while (n > 0) {
    const ssize_t r = ::read(fd, c, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    c += r;
    n -= std::size_t(r);
  }
  return true;
}

/// A workload's input arrays, which the parent has loaded (pointer, bytes).
using Inputs = std::vector<std::pair<const void *, std::size_t>>;

/// Reads one byte of every page of `inputs`. A forked child shares the
/// parent's pages of them, and its first touch of each is dear on some
/// virtual machines (on a PVM host, reading W2's 40 MB of candidates cost
/// a forked child about a fifth of a second more than the same loop in its
/// own process): the child does it before the timed work, so that every
/// method is timed on an input already in its memory, as a program's own
/// input is. (The grid's scan for its bounds used to do this for the grid
/// alone.)
unsigned touch_pages(const Inputs &inputs) {
  unsigned sum = 0;
  for (const auto &in : inputs) {
    const volatile unsigned char *p = static_cast<const unsigned char *>(in.first);
    for (std::size_t i = 0; i < in.second; i += 4096) sum += p[i];
  }
  return sum; // (volatile reads: not optimized away)
}

/// Runs `work` in a child process (or here, when `in_process`); returns its
/// seconds and ids, the child's RSS when it started and its peak RSS. The
/// child first touches `inputs` (touch_pages).
Measured measure(const std::function<Outcome()> &work, bool in_process, const Inputs &inputs = {}) {
  Measured m;
  if (in_process) {
    m.start_kb = rss_now_kb();
    Outcome o = work();
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    m.ok = true;
    m.seconds = o.seconds;
    m.ids = std::move(o.ids);
    m.peak_kb = ru.ru_maxrss;
    return m;
  }
  std::cout.flush();
  std::cerr.flush();
  int fds[2];
  if (pipe(fds) != 0) {
    m.error = std::string("pipe: ") + std::strerror(errno);
    return m;
  }
  const pid_t pid = fork();
  if (pid < 0) {
    m.error = std::string("fork: ") + std::strerror(errno);
    close(fds[0]);
    close(fds[1]);
    return m;
  }
  if (pid == 0) {
    close(fds[0]);
    (void)touch_pages(inputs);
    const long start_kb = rss_now_kb();
    const Outcome o = work();
    const std::uint64_t n = o.ids.size();
    const bool ok = write_all(fds[1], &o.seconds, sizeof o.seconds) && write_all(fds[1], &start_kb, sizeof start_kb) &&
                    write_all(fds[1], &n, sizeof n) && write_all(fds[1], o.ids.data(), n * sizeof(std::uint32_t));
    close(fds[1]);
    _exit(ok ? 0 : 3);
  }
  close(fds[1]);
  std::uint64_t n = 0;
  bool got = read_all(fds[0], &m.seconds, sizeof m.seconds) && read_all(fds[0], &m.start_kb, sizeof m.start_kb) &&
             read_all(fds[0], &n, sizeof n);
  if (got) {
    m.ids.resize(n);
    got = read_all(fds[0], m.ids.data(), n * sizeof(std::uint32_t));
  }
  close(fds[0]);
  int status = 0;
  struct rusage ru {};
  while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !got) {
    m.error = WIFSIGNALED(status) ? "child killed by signal " + std::to_string(WTERMSIG(status))
                                  : "child failed (status " + std::to_string(status) + ")";
    return m;
  }
  m.ok = true;
  m.peak_kb = ru.ru_maxrss;
  return m;
}

// ---------------------------------------------------------------------------
// Scenes: generated by bvh.out with fixed seeds, cached in the data folder.

struct Options {
  bool quick = false;
  int runs = 0; // 0: default per workload
  std::string only, method;
  bool in_process = false;
  bool fork = false; // --fork: each run in its own process even with --only
  std::string bvh = "./bvh.out";
  std::string data = "build/bench-data";
  std::string out; // default: bench, or build/bench-quick with --quick
  double sorted_budget = 60; // seconds for the sorted-by-x insertion
  long big = 0;              // --big: candidates of W1, W2 and W3 (0: 1M, or 100k with --quick)
};

struct SceneSpec {
  std::string kind; // disks, triangles, quads
  long count;
  int seed;
  std::string size; // MIN:MAX
};

std::string scene_path(const Options &opt, const SceneSpec &s) {
  return opt.data + "/" + s.kind + "_n" + std::to_string(s.count) + "_s" + std::to_string(s.seed) + "_r" + s.size +
         "." + s.kind;
}

/// Makes the scene with bvh.out unless it is already cached.
bool ensure_scene(const Options &opt, const SceneSpec &s, std::string &path) {
  path = scene_path(opt, s);
  if (std::ifstream(path).good()) return true;
  if (std::system(("mkdir -p '" + opt.data + "'").c_str()) != 0) return false;
  const std::string cmd = "'" + opt.bvh + "' --generate " + s.kind + " " + std::to_string(s.count) + " --seed " +
                          std::to_string(s.seed) + " --size " + s.size + " --overlap -o '" + path + "'";
  std::cerr << "bench: generating " << path << "\n";
  const Clock::time_point t0 = Clock::now();
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "bench: failed: " << cmd << "\n";
    return false;
  }
  std::cerr << "bench:   " << fmt("%.1f", seconds_since(t0)) << " s\n";
  return true;
}

template <class T> bool load(const Options &opt, const SceneSpec &s, std::vector<T> &out) {
  std::string path, error;
  if (!ensure_scene(opt, s, path)) return false;
  out.clear();
  if (!bvh_scene::load_scene(path, out, error)) {
    std::cerr << "bench: " << error << "\n";
    return false;
  }
  out.shrink_to_fit();
  return true;
}

// ---------------------------------------------------------------------------
// Results.

struct Row {
  std::string workload, method, label;
  std::vector<double> times;
  long start_kb = 0, peak_kb = 0;
  std::size_t kept = 0;
  std::string note; // a skipped row: why
  double med() const { return median(times); }
};

struct Report {
  std::vector<Row> rows;
  std::vector<std::string> notes;
  bool mismatch = false;
  std::ostringstream extra; // SAH and memory sections
};

std::string table(const Report &r) {
  std::ostringstream t;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-34s %-26s %10s %7s %8s %8s %8s\n", "workload", "method", "median s", "x ours",
                "peak MB", "+MB", "kept");
  t << buf << std::string(106, '-') << "\n";
  std::string last;
  std::map<std::string, double> ours;
  for (const Row &row : r.rows)
    if (row.method == "ours" && !row.times.empty()) ours[row.workload] = row.med();
  for (const Row &row : r.rows) {
    const std::string w = row.workload == last ? "" : row.workload;
    if (!last.empty() && row.workload != last) t << "\n";
    last = row.workload;
    if (!row.note.empty()) {
      std::snprintf(buf, sizeof buf, "%-34s %-26s %s\n", w.c_str(), row.label.c_str(), row.note.c_str());
    } else {
      const double m = row.med();
      const auto o = ours.find(row.workload);
      const std::string ratio = o == ours.end() || o->second <= 0 ? "-" : fmt("%.2f", m / o->second);
      std::snprintf(buf, sizeof buf, "%-34s %-26s %10.4f %7s %8.1f %8.1f %8zu\n", w.c_str(), row.label.c_str(), m,
                    ratio.c_str(), row.peak_kb / 1024.0, (row.peak_kb - row.start_kb) / 1024.0, row.kept);
    }
    t << buf;
  }
  return t.str();
}

/// The node-width goals (issue 19) of W1, W2 and W3: the fastest row of
/// ours on one thread (any width and split_threshold) against the fastest
/// peer (W1, W2: <= 0.5; W3, whose Boost trees are packed: <= 0.7) and,
/// for W1 and W2, the grid (<= 2).
std::string width_goals(const Report &r) {
  std::ostringstream t;
  std::vector<std::string> workloads;
  for (const Row &row : r.rows)
    if (std::find(workloads.begin(), workloads.end(), row.workload) == workloads.end()) workloads.push_back(row.workload);
  for (const std::string &w : workloads) {
    const bool bulk = w.compare(0, 2, "W3") == 0;
    if (!bulk && w.compare(0, 2, "W1") != 0 && w.compare(0, 2, "W2") != 0) continue;
    // ours: the loop of collision() and insert(); sampled: the same loop
    // in one call, insert_disjoint(c, 1), also on one thread.
    const Row *ours = nullptr, *sampled = nullptr, *all_cores = nullptr, *peer = nullptr, *grid = nullptr;
    for (const Row &row : r.rows) {
      if (row.workload != w || !row.note.empty() || row.times.empty()) continue;
      const std::string &m = row.method;
      const bool is_sampled = m.size() > 3 && m.compare(m.size() - 3, 3, "-s1") == 0;
      const bool is_all = m.size() > 4 && m.compare(m.size() - 4, 4, "-all") == 0;
      const bool is_ours = m.compare(0, 4, "ours") == 0 && m.compare(0, 8, "ours-par") != 0 && !is_sampled && !is_all;
      if (is_all) all_cores = &row;
      const bool is_peer = m.compare(0, 5, "boost") == 0 || m == "box2d";
      if (is_ours && (!ours || row.med() < ours->med())) ours = &row;
      if (is_sampled && (!sampled || row.med() < sampled->med())) sampled = &row;
      if (is_peer && (!peer || row.med() < peer->med())) peer = &row;
      if (m == "grid") grid = &row;
    }
    if (!ours) continue;
    t << "Goals, " << w.substr(0, 2) << " (node width, issue 19): best of ours is " << ours->label;
    const double limit = bulk ? 0.7 : 0.5;
    if (peer) {
      const double x = ours->med() / peer->med();
      t << "; / " << peer->label << " " << fmt("%.2f", x) << " (<= " << fmt("%.1f", limit) << ": "
        << (x <= limit ? "met" : "not met") << ")";
    }
    if (grid) {
      const double x = ours->med() / grid->med();
      t << "; / grid " << fmt("%.2f", x) << " (<= 2: " << (x <= 2 ? "met" : "not met") << ")";
    }
    t << "\n";
    if (sampled && grid)
      t << "  the loop in one call, " << sampled->label << ": / grid " << fmt("%.2f", sampled->med() / grid->med())
        << ", / the loop above " << fmt("%.2f", sampled->med() / ours->med()) << "\n";
    if (all_cores && sampled)
      t << "  the same call on every core, " << all_cores->label << ": / one thread "
        << fmt("%.2f", all_cores->med() / sampled->med()) << (grid ? ", / grid " + fmt("%.2f", all_cores->med() / grid->med()) : "")
        << "\n";
  }
  return t.str();
}

// ---------------------------------------------------------------------------
// The workloads.

struct Workload {
  std::string name;  // for --only
  std::string title; // table label
  SceneSpec scene;
  long take = 0;      // the first `take` shapes of the scene (sweep prefixes)
  bool bulk = false;  // construct + probes instead of discard
  SceneSpec probes{}; // bulk only
  int runs = 5;
  bool sweep = false;
};

/// --method NAME, or several: NAME,NAME,...
bool method_selected(const Options &opt, const std::string &m) {
  return opt.method.empty() || ("," + opt.method + ",").find("," + m + ",") != std::string::npos;
}

long brute_limit(const Options &opt) { return opt.quick ? 30000 : 100000; }

template <class T>
void run_workload(const Options &opt, const Workload &w, const std::vector<T> &cand, const std::vector<T> *probes,
                  Report &rep, Ids *ours_ids = nullptr) {
  const int runs = opt.runs > 0 ? opt.runs : (opt.only.empty() ? w.runs : 1);
  std::vector<Row> rows;
  std::vector<std::string> names;
  for (const Method &m : all_methods()) {
    if (!method_selected(opt, m.name)) continue;
    Row row;
    row.workload = w.title;
    row.method = m.name;
    row.label = m.label;
    if (!m.available) {
      row.note = m.missing;
    } else if (m.name == "brute" && (w.bulk || long(cand.size()) > brute_limit(opt))) {
      if (w.sweep) continue; // the sweep just has no point there
      row.note = w.bulk ? "skipped: 1M x 100k scan" : "skipped: over " + count_label(brute_limit(opt)) + " candidates";
    } else if (m.name == "ours-1t" && !w.bulk) {
      continue; // only construct() uses threads
    } else if ((m.name == "ours-par" || m.name == "ours-par1" || m.name == "ours-w8k32-s1" || m.name == "ours-w8k32-all") &&
               w.bulk) {
      continue; // insert_disjoint is a discard
    } else if (m.name == "grid" && (w.bulk || !std::is_same<T, Disk>::value)) {
      continue; // the grid is a reference for disk discards only
    }
    rows.push_back(row);
  }
  Inputs inputs{{cand.data(), cand.size() * sizeof(T)}};
  if (probes) inputs.emplace_back(probes->data(), probes->size() * sizeof(T));
  // Runs interleave the methods, so slow drift hits every method alike.
  Ids reference;
  bool have_reference = false;
  for (int r = 0; r < runs; ++r) {
    for (Row &row : rows) {
      if (!row.note.empty()) continue;
      const std::string m = row.method;
      const Measured res = measure(
          [&]() {
            Outcome o;
            if (w.bulk) run_bulk(m, cand, *probes, o);
            else run_discard(m, cand, o);
            return o;
          },
          opt.in_process, inputs);
      if (!res.ok) {
        row.note = "FAILED: " + res.error;
        rep.mismatch = true;
        continue;
      }
      row.times.push_back(res.seconds);
      row.peak_kb = std::max(row.peak_kb, res.peak_kb);
      row.start_kb = row.start_kb == 0 ? res.start_kb : std::min(row.start_kb, res.start_kb);
      row.kept = res.ids.size();
      if (!have_reference) {
        reference = res.ids;
        have_reference = true;
      } else if (res.ids != reference) {
        row.note = "MISMATCH: kept set differs from " + rows.front().method + " (" + std::to_string(res.ids.size()) +
                   " vs " + std::to_string(reference.size()) + ")";
        rep.mismatch = true;
      }
      std::cerr << "bench: " << w.name << " " << m << " run " << (r + 1) << "/" << runs << ": "
                << fmt("%.4f", res.seconds) << " s, kept " << res.ids.size() << "\n";
    }
  }
  if (ours_ids && have_reference) *ours_ids = reference;
  for (Row &row : rows) rep.rows.push_back(std::move(row));
}

// ---------------------------------------------------------------------------
// Bytes per shape by part (BVH::memory()) of the loop's tree, rebuilt from
// its kept set in order (the same inserts, so the same tree), before and
// after a handle lookup, and of construct() on the same shapes.

template <class T> void memory_parts(const std::vector<T> &kept, std::ostream &out) {
  if (kept.empty()) return;
  const double n = double(kept.size());
  auto line = [&](const std::string &what, const auto &tree) {
    const auto m = tree.memory();
    const auto f = tree.fill();
    char buf[640];
    std::snprintf(buf, sizeof buf,
                  "    %-30s nodes %5.1f  shapes %5.1f  ids %4.1f  leaf slack %5.1f  pool index %4.1f  handles %4.1f"
                  "  free ids %4.1f  scratch %4.1f  = %6.1f  (%.2fx the shapes; fill: children %.2f, leaves %.2f)\n",
                  what.c_str(), m.nodes / n, m.shapes / n, m.shape_ids / n, m.leaf_slack / n, m.pool_index / n,
                  m.handles / n, m.free_ids / n, m.scratch / n, m.total() / n, m.total() / (n * sizeof(T)), f.children,
                  f.shapes);
    out << buf;
    return m;
  };
  out << "  bytes per kept shape by part (BVH::memory(); sizeof(T) = " << sizeof(T)
      << "), and the fill factor (BVH::fill(): mean children / width, mean shapes / split_threshold):\n";
  CourseBVH<T> tree(4, 0);
  for (const T &s : kept) tree.insert(s);
  line("the loop's tree", tree);
  (void)tree.contains(typename CourseBVH<T>::handle{0});
  line("after a handle lookup", tree);
  CourseBVH<T> built(4, 0);
  built.construct(kept);
  const auto b = line("construct()", built);
  out << "    construct()'s transient build memory (its items, freed when it returns): "
      << fmt("%.1f", b.build_transient / n) << " bytes per shape\n";
  auto wide = [&](auto width, int split) {
    constexpr int W = decltype(width)::value;
    BVH<T, bvh::shape_traits<T>, W> loop(split, 0), bulk(split, 0);
    for (const T &s : kept) loop.insert(s);
    bulk.construct(kept);
    const std::string at = "width " + std::to_string(W) + ", split " + std::to_string(split);
    line("loop, " + at, loop);
    line("construct(), " + at, bulk);
  };
  wide(std::integral_constant<int, 4>(), 4);
  wide(std::integral_constant<int, 8>(), 4);
  wide(std::integral_constant<int, 8>(), 8);
  wide(std::integral_constant<int, 8>(), 16);
  wide(std::integral_constant<int, 8>(), 32);
}

// ---------------------------------------------------------------------------
// SAH quality of incremental insertion versus the bulk build, over the same
// shapes: the area sums of the course's statistics report.

struct Quality {
  double inner = 0, leaf = 0, seconds = 0;
  int height = 0;
  std::size_t nodes = 0, inserted = 0;
  bool finished = true;
};

template <class T> Quality quality_of(const CourseBVH<T> &tree) {
  Quality q;
  std::ostringstream s;
  tree.statistics(s, false);
  std::istringstream in(s.str());
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::string key = line.substr(0, colon);
    if (key == "inner node area") q.inner = std::atof(line.c_str() + colon + 1);
    if (key == "leaf node area") q.leaf = std::atof(line.c_str() + colon + 1);
  }
  q.height = tree.height();
  q.nodes = tree.node_count();
  q.inserted = tree.size();
  return q;
}

/// Builds one tree in a child: mode 0 bulk, 1 random order, 2 sorted by x.
/// The sorted order may be very slow (deep trees): it stops after `budget` s.
Quality build_quality(const std::vector<Disk> &shapes, int mode, double budget, bool in_process) {
  Quality q;
  const Measured res = measure(
      [&]() {
        CourseBVH<Disk> tree(4, 0);
        std::vector<Disk> order = shapes;
        if (mode == 1) {
          std::mt19937_64 rng(12345);
          for (std::size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[std::size_t(rng() % i)]);
        } else if (mode == 2) {
          std::stable_sort(order.begin(), order.end(),
                           [](const Disk &a, const Disk &b) { return a.getCenter().x < b.getCenter().x; });
        }
        const Clock::time_point t0 = Clock::now();
        bool finished = true;
        if (mode == 0) {
          tree.construct(order);
        } else {
          for (std::size_t i = 0; i < order.size(); ++i) {
            tree.insert(order[i]);
            if (i % 1024 == 0 && seconds_since(t0) > budget) {
              finished = false;
              break;
            }
          }
        }
        const double s = seconds_since(t0);
        const Quality qq = quality_of(tree);
        // Pass the numbers through the ids channel as raw words.
        Outcome o;
        o.seconds = s;
        const double words[6] = {qq.inner, qq.leaf, double(qq.height), double(qq.nodes), double(qq.inserted),
                                 finished ? 1.0 : 0.0};
        o.ids.resize(sizeof(words) / (sizeof(std::uint32_t)));
        std::memcpy(o.ids.data(), words, sizeof words);
        return o;
      },
      in_process);
  if (!res.ok || res.ids.size() * sizeof(std::uint32_t) != 6 * sizeof(double)) {
    q.finished = false;
    return q;
  }
  double words[6];
  std::memcpy(words, res.ids.data(), sizeof words);
  q.inner = words[0];
  q.leaf = words[1];
  q.height = int(words[2]);
  q.nodes = std::size_t(words[3]);
  q.inserted = std::size_t(words[4]);
  q.finished = words[5] != 0;
  q.seconds = res.seconds;
  return q;
}

void sah_section(const Options &opt, const std::vector<Disk> &kept, const std::string &what, std::ostream &out) {
  const char *names[3] = {"bulk construct()", "insert, random order", "insert, sorted by x"};
  Quality q[3];
  for (int mode = 0; mode < 3; ++mode) {
    std::cerr << "bench: SAH " << names[mode] << " over " << kept.size() << " disks\n";
    q[mode] = build_quality(kept, mode, opt.sorted_budget, opt.in_process);
  }
  const double bulk = q[0].inner + q[0].leaf;
  out << "SAH quality of ours, BVH(4, unlimited depth), over " << what << " (" << kept.size() << " disks):\n";
  char buf[256];
  std::snprintf(buf, sizeof buf, "  %-24s %12s %12s %12s %9s %7s %7s %9s %9s\n", "build", "inner area", "leaf area", "sum",
                "/ bulk", "height", "/ bulk", "nodes", "seconds");
  out << buf;
  for (int mode = 0; mode < 3; ++mode) {
    const double sum = q[mode].inner + q[mode].leaf;
    std::snprintf(buf, sizeof buf, "  %-24s %12.3f %12.3f %12.3f %9.3f %7d %7.2f %9zu %9.3f\n", names[mode], q[mode].inner,
                  q[mode].leaf, sum, bulk > 0 ? sum / bulk : 0.0, q[mode].height,
                  q[0].height > 0 ? double(q[mode].height) / q[0].height : 0.0, q[mode].nodes, q[mode].seconds);
    out << buf;
    if (!q[mode].finished)
      out << "    (stopped after " << fmt("%.0f", opt.sorted_budget) << " s: only " << q[mode].inserted << " of "
          << kept.size() << " inserted; the figures are for that partial tree, ratio not comparable)\n";
  }
  out << "  (areas in units of the 1000 x 1000 canvas, leaf area counted once per shape, as the course's\n"
         "   statistics print them; the insertion orders are a fixed shuffle and a stable sort by centre x;\n"
         "   goals: sum / bulk <= 1.25 in random order, <= 1.5 sorted; height O(log n): log3(n / 4) = "
      << fmt("%.1f", std::log(double(kept.size()) / 4) / std::log(3.0)) << ")\n";
}

// ---------------------------------------------------------------------------
// The command-line program's share: parsing the scene file (load_scene, the
// reader bvh.out uses) against the sampling itself, and the whole bvh.out
// run (process start, parse, sample, SVG written) timed from outside.

void cli_section(const Options &opt, const Report &rep, const Workload &w, std::ostream &out) {
  std::string path;
  if (!ensure_scene(opt, w.scene, path)) return;
  const int runs = opt.runs > 0 ? opt.runs : 3;
  std::vector<double> parse;
  for (int r = 0; r < runs; ++r) {
    const Measured m = measure(
        [&]() {
          Outcome o;
          std::vector<Disk> shapes;
          std::string error;
          const Clock::time_point t0 = Clock::now();
          if (bvh_scene::load_scene(path, shapes, error)) o.ids.push_back(std::uint32_t(shapes.size()));
          o.seconds = seconds_since(t0);
          return o;
        },
        opt.in_process);
    if (m.ok && !m.ids.empty()) parse.push_back(m.seconds);
  }
  double sample = 0;
  for (const Row &row : rep.rows)
    if (row.workload == w.title && row.method == "ours" && !row.times.empty()) sample = row.med();
  std::vector<double> whole;
  const std::string picture = opt.data + "/cli-" + w.name + ".svg";
  const std::string cmd = "'" + opt.bvh + "' -i '" + path + "' -o '" + picture + "' --incremental --discard_overlap";
  for (int r = 0; r < runs; ++r) {
    const Clock::time_point t0 = Clock::now();
    if (std::system(cmd.c_str()) != 0) {
      out << "  " << w.name << ": FAILED: " << cmd << "\n";
      return;
    }
    whole.push_back(seconds_since(t0));
  }
  if (parse.empty() || sample <= 0) return;
  char buf[256];
  std::snprintf(buf, sizeof buf, "  %-34s %10.4f %10.4f %9.2f %12.4f\n", w.title.c_str(), median(parse), sample,
                median(parse) / sample, median(whole));
  out << buf;
}

// ---------------------------------------------------------------------------
// The sweep picture: time vs candidates, log-log, one polyline per method.

void write_svg_plot(const Report &rep, const std::vector<long> &ns, const std::vector<std::string> &titles,
                    const std::string &path, const std::string &caption) {
  struct Series {
    std::string label;
    std::vector<std::pair<double, double>> pts;
  };
  std::vector<Series> series;
  for (const Method &m : all_methods()) {
    Series s;
    s.label = m.label;
    for (std::size_t i = 0; i < ns.size(); ++i)
      for (const Row &row : rep.rows)
        if (row.workload == titles[i] && row.method == m.name && row.note.empty() && !row.times.empty())
          s.pts.push_back({double(ns[i]), row.med()});
    if (!s.pts.empty()) series.push_back(s);
  }
  double ymin = 1e300, ymax = 0;
  for (const Series &s : series)
    for (const auto &p : s.pts) {
      ymin = std::min(ymin, std::max(p.second, 1e-6));
      ymax = std::max(ymax, p.second);
    }
  if (series.empty()) return;
  const double lx0 = std::floor(std::log10(double(ns.front()))), lx1 = std::ceil(std::log10(double(ns.back())));
  const double ly0 = std::floor(std::log10(ymin)), ly1 = std::max(ly0 + 1, std::ceil(std::log10(ymax)));
  const double W = 900, H = 600, L = 90, R = 250, T = 50, B = 70;
  auto X = [&](double v) { return L + (std::log10(v) - lx0) / (lx1 - lx0) * (W - L - R); };
  auto Y = [&](double v) { return H - B - (std::log10(std::max(v, 1e-6)) - ly0) / (ly1 - ly0) * (H - T - B); };
  static const char *colors[] = {"#d62728", "#ff7f0e", "#7f7f7f", "#1f77b4", "#17becf", "#2ca02c", "#9467bd"};
  std::ofstream out(path);
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" viewBox=\"0 0 %.0f %.0f\" "
                "font-family=\"sans-serif\" font-size=\"13\">\n<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
                W, H, W, H);
  out << buf;
  out << "<text x=\"" << L << "\" y=\"28\" font-size=\"15\" font-weight=\"bold\">" << xml_escape(caption)
      << "</text>\n";
  // Grid lines and tick labels at every decade (and 3x on x).
  for (double e = lx0; e <= lx1 + 1e-9; e += 1) {
    for (double f : {1.0, 3.0}) {
      const double v = f * std::pow(10.0, e);
      if (std::log10(v) > lx1 + 1e-9) continue;
      std::snprintf(buf, sizeof buf,
                    "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#%s\"/>\n"
                    "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">%s</text>\n",
                    X(v), T, X(v), H - B, f == 1 ? "ccc" : "eee", X(v), H - B + 18, count_label(long(v + 0.5)).c_str());
      out << buf;
    }
  }
  for (double e = ly0; e <= ly1 + 1e-9; e += 1) {
    const double v = std::pow(10.0, e);
    std::string label = v >= 1 ? fmt("%.0f s", v) : v >= 1e-3 ? fmt("%.0f ms", v * 1e3) : fmt("%.0f us", v * 1e6);
    std::snprintf(buf, sizeof buf,
                  "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#ccc\"/>\n"
                  "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%s</text>\n",
                  L, Y(v), W - R, Y(v), L - 8, Y(v) + 4, label.c_str());
    out << buf;
  }
  std::snprintf(buf, sizeof buf,
                "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"black\"/>\n"
                "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">candidates n (log scale)</text>\n"
                "<text transform=\"translate(22 %.1f) rotate(-90)\" text-anchor=\"middle\">median time of the index "
                "work (log scale)</text>\n",
                L, T, W - L - R, H - T - B, (L + W - R) / 2, H - 22, (T + H - B) / 2);
  out << buf;
  for (std::size_t i = 0; i < series.size(); ++i) {
    const char *c = colors[i % (sizeof colors / sizeof *colors)];
    out << "<polyline fill=\"none\" stroke=\"" << c << "\" stroke-width=\"2\" points=\"";
    for (const auto &p : series[i].pts) out << fmt("%.1f", X(p.first)) << "," << fmt("%.1f", Y(p.second)) << " ";
    out << "\"/>\n";
    for (const auto &p : series[i].pts) {
      std::snprintf(buf, sizeof buf, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>\n", X(p.first),
                    Y(p.second), c);
      out << buf;
    }
    const double ly = T + 20 + 22 * double(i);
    std::snprintf(buf, sizeof buf,
                  "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" stroke-width=\"3\"/>\n"
                  "<text x=\"%.1f\" y=\"%.1f\">%s</text>\n",
                  W - R + 15, ly, W - R + 40, ly, c, W - R + 46, ly + 4, xml_escape(series[i].label).c_str());
    out << buf;
  }
  out << "</svg>\n";
}

// ---------------------------------------------------------------------------

void usage() {
  std::cout << "usage: build/bench [--quick] [--runs N] [--only WORKLOAD] [--method NAME] [--in-process] [--fork] [--big N]\n"
               "                   [--bvh PATH] [--data DIR] [--out DIR] [--sorted-budget SECONDS]\n"
               "  --quick           reduced sizes (1M -> 100k, 100k -> 20k), 3 runs each (under a minute)\n"
               "  --runs N          runs per (workload, method); the median is reported\n"
               "                    (default 5, 3 for the 1M workloads, 1 with --only)\n"
               "  --only WORKLOAD   one workload: W1 W2 W3 tri quad S1000 ... S1000000\n"
               "                    (implies --in-process unless --fork; no files are written)\n"
               "  --method NAME     one method (or several: NAME,NAME): ours ours-1t ours-d8 ours-w4 ours-w8 ours-w8k8 ours-w8k16 ours-w8k32 ours-w8k64 ours-w8k32-s1 ours-w8k32-all ours-par ours-par1 brute boost-quad16 boost-rstar16 box2d grid\n"
               "  --big N           N candidates in W1, W2 and W3 instead of 1M (the 10M scaling point:\n"
               "                    --big 10000000 --only W2 --method ours, then boost-quad16, grid)\n"
               "  --in-process      no fork per run (for valgrind/perf); peak RSS is then cumulative\n"
               "  --fork            with --only: each run in its own process, as make bench runs it\n"
               "                    (a run's heap then starts as the parent's, whatever ran before)\n"
               "  --bvh PATH        the generator (default ./bvh.out)\n"
               "  --data DIR        cached scenes (default build/bench-data)\n"
               "  --out DIR         where results.txt and results.svg go (default bench; with --quick\n"
               "                    build/bench-quick, so a quick run never replaces the full results)\n"
               "  --sorted-budget S time cap of the sorted-by-x insertion in the SAH section (default 60)\n"
               "  --phases          the loops of collision() and insert() (ours, ours-d8, ours-w4, ours-w8,\n"
               "                    ours-w8kK) also print the time in each of the two calls, on stderr\n";
}

int main(int argc, char **argv) {
  const Clock::time_point start = Clock::now();
  Options opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "bench: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--quick") opt.quick = true;
    else if (a == "--runs") opt.runs = std::max(1, std::atoi(value().c_str()));
    else if (a == "--only") opt.only = value();
    else if (a == "--method") opt.method = value();
    else if (a == "--big") opt.big = std::atol(value().c_str());
    else if (a == "--in-process") opt.in_process = true;
    else if (a == "--fork") opt.fork = true;
    else if (a == "--bvh") opt.bvh = value();
    else if (a == "--data") opt.data = value();
    else if (a == "--out") opt.out = value();
    else if (a == "--sorted-budget") opt.sorted_budget = std::atof(value().c_str());
    else if (a == "--phases") phases = true;
    else if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else {
      std::cerr << "bench: unknown argument '" << a << "'\n";
      usage();
      return 2;
    }
  }
  if (!opt.only.empty() && !opt.fork) opt.in_process = true;
  // A quick run must not overwrite the full run's results in bench/.
  if (opt.out.empty()) opt.out = opt.quick ? "build/bench-quick" : "bench";
  if (opt.quick) {
    opt.sorted_budget = std::min(opt.sorted_budget, 5.0);
    if (opt.runs == 0) opt.runs = 3;
  }

  // Sizes. QUICK takes the same seeds with fewer shapes: with --overlap a
  // scene of n shapes is the first n lines of a larger one of the same seed.
  const long n_big = opt.big > 0 ? opt.big : (opt.quick ? 100000 : 1000000);
  const long n_probe = opt.quick ? 10000 : 100000;
  const long n_poly = opt.quick ? 20000 : 100000;
  const int big_runs = 3;
  std::vector<long> sweep_ns = {1000, 3000, 10000, 30000, 100000, 300000, 1000000};
  if (opt.quick) sweep_ns = {1000, 3000, 10000, 30000, 100000};
  const std::string big = count_label(n_big);

  Workload w1{"W1", "W1 dense-reject " + big + " disks r2-7.5", {"disks", n_big, 1, "2:7.5"}, n_big, false, {}, big_runs};
  Workload w2{"W2", "W2 insert-heavy " + big + " disks r.2-.6", {"disks", n_big, 2, "0.2:0.6"}, n_big, false, {}, big_runs};
  Workload w3{"W3",     "W3 bulk " + big + " disks + " + count_label(n_probe) + " probes", {"disks", n_big, 3, "0.2:0.6"},
              n_big,    true,
              {"disks", n_probe, 4, "0.2:0.6"},
              big_runs};
  Workload wt{"tri", "discard " + count_label(n_poly) + " triangles s1-3", {"triangles", n_poly, 5, "1:3"}, n_poly, false, {}, 5};
  Workload wq{"quad", "discard " + count_label(n_poly) + " quads s1-3", {"quads", n_poly, 6, "1:3"}, n_poly, false, {}, 5};

  auto wanted = [&](const std::string &name) { return opt.only.empty() || opt.only == name; };
  Report rep;
  for (const Method &m : all_methods())
    if (!m.available && std::find(rep.notes.begin(), rep.notes.end(), m.missing) == rep.notes.end()) {
      rep.notes.push_back(m.missing);
      std::cout << m.missing << "\n";
    }

  if (method_selected(opt, "ours-par") && !opt.method.empty()) {
    const std::string line = "available parallelism (bench's spin loop on " +
                             std::to_string(std::max(1u, std::thread::hardware_concurrency())) +
                             " threads against 1, wall time): " + fmt("%.2f", available_parallelism()) + "x";
    std::cout << line << "\n";
    rep.notes.push_back(line);
  }

  // W1 and the sweep (prefixes of W1's scene).
  std::vector<std::string> sweep_titles;
  bool any_sweep = false;
  for (long n : sweep_ns) {
    sweep_titles.push_back(n == n_big ? w1.title : "sweep " + count_label(n) + " disks r2-7.5");
    any_sweep = any_sweep || wanted("S" + std::to_string(n));
  }
  if (wanted("W1") || any_sweep) {
    std::vector<Disk> c;
    if (!load(opt, w1.scene, c)) return 1;
    if (wanted("W1") || wanted("S" + std::to_string(n_big))) run_workload(opt, w1, c, static_cast<std::vector<Disk> *>(nullptr), rep);
    for (std::size_t i = 0; i < sweep_ns.size(); ++i) {
      const long n = sweep_ns[i];
      if (n == n_big || !wanted("S" + std::to_string(n))) continue; // 1M is W1 itself
      Workload s = w1;
      s.name = "S" + std::to_string(n);
      s.title = sweep_titles[i];
      s.take = n;
      s.sweep = true;
      s.runs = n >= 1000000 ? big_runs : 5;
      const std::vector<Disk> prefix(c.begin(), c.begin() + std::min<long>(n, long(c.size())));
      run_workload(opt, s, prefix, static_cast<std::vector<Disk> *>(nullptr), rep);
    }
  }

  // W2, then the SAH and memory sections on its kept set.
  if (wanted("W2")) {
    std::vector<Disk> c;
    if (!load(opt, w2.scene, c)) return 1;
    Ids kept_ids;
    run_workload(opt, w2, c, static_cast<std::vector<Disk> *>(nullptr), rep, &kept_ids);
    std::vector<Disk> kept;
    for (std::uint32_t i : kept_ids) kept.push_back(c[i]);
    std::vector<Disk>().swap(c);
    if (opt.only.empty()) sah_section(opt, kept, "W2's kept set", rep.extra);
    {
      for (const Row &row : rep.rows)
        if (row.workload == w2.title && row.method == "ours" && !row.times.empty()) {
          const double shapes_mb = double(sizeof(Disk)) * double(row.kept) / (1024.0 * 1024.0);
          const double added_mb = (row.peak_kb - row.start_kb) / 1024.0;
          rep.extra << "\nMemory, W2, ours: peak RSS " << fmt("%.1f", row.peak_kb / 1024.0) << " MB, of which "
                    << fmt("%.1f", row.start_kb / 1024.0) << " MB were there at the start (the " << big
                    << " candidates and the program);\n  the index added " << fmt("%.1f", added_mb)
                    << " MB for " << row.kept << " kept disks of sizeof(Disk) = " << sizeof(Disk)
                    << " bytes = " << fmt("%.1f", shapes_mb) << " MB of shapes: " << fmt("%.2f", added_mb / shapes_mb)
                    << " x the bytes of the shapes (kept ids vector included, 4 bytes per kept shape).\n";
          memory_parts(kept, rep.extra);
          for (const Row &other : rep.rows)
            if (other.workload == w2.title && other.method != "ours" && other.note.empty())
              rep.extra << "  " << other.label << ": +" << fmt("%.1f", (other.peak_kb - other.start_kb) / 1024.0)
                        << " MB\n";
        }
    }
  }

  if (opt.only.empty() && opt.method.empty()) {
    rep.extra << "\nCommand line, bvh.out -i SCENE -o PICTURE.svg --incremental --discard_overlap (median of "
              << (opt.runs > 0 ? opt.runs : 3) << "): parse = load_scene() alone,\n"
              << "sampling = ours' median above, whole = the bvh.out process timed from outside (SVG included).\n"
              << "Goal: parse <= sampling.\n";
    char buf[256];
    std::snprintf(buf, sizeof buf, "  %-34s %10s %10s %9s %12s\n", "scene", "parse s", "sampling s", "parse/sam",
                  "whole s");
    rep.extra << buf;
    cli_section(opt, rep, w1, rep.extra);
    cli_section(opt, rep, w2, rep.extra);
  }

  if (wanted("W3")) {
    std::vector<Disk> base, probes;
    if (!load(opt, w3.scene, base) || !load(opt, w3.probes, probes)) return 1;
    run_workload(opt, w3, base, &probes, rep);
  }
  if (wanted("tri")) {
    std::vector<Triangle> c;
    if (!load(opt, wt.scene, c)) return 1;
    run_workload(opt, wt, c, static_cast<std::vector<Triangle> *>(nullptr), rep);
  }
  if (wanted("quad")) {
    std::vector<Quad> c;
    if (!load(opt, wq.scene, c)) return 1;
    run_workload(opt, wq, c, static_cast<std::vector<Quad> *>(nullptr), rep);
  }

  if (rep.rows.empty()) {
    std::cerr << "bench: nothing matched --only '" << opt.only << "' / --method '" << opt.method << "'\n";
    return 2;
  }

  std::ostringstream text;
  text << "bvh benchmark" << (opt.quick ? " (QUICK: reduced sizes)" : "") << ": median of "
       << (opt.runs > 0 ? std::to_string(opt.runs) + (opt.runs == 1 ? " run" : " runs")
                        : "5 runs (3 for the " + big + " workloads)")
       << (opt.in_process ? ", all in this process" : ", each run in its own process")
       << "; -std=c++17 -O2 -DNDEBUG\n";
  text << "Measured: " << BENCH_BUILD_INFO << "\n";
  text << "Scenes: bvh.out --generate ... --overlap with fixed seeds (W3's base and probes use --overlap with\n"
          "small radii, since a non-overlapping 1M scene is slow to generate). 'x ours' = median / ours' median;\n"
          "'+MB' = peak RSS minus the RSS at the child's start (the index's own memory); kept = shapes kept\n"
          "(W3: probes that collide). Box2D fattens every box by b2_aabbExtension = 0.1 (reported as is).\n"
          "The sweep is W1's scene cut to its first n candidates; its 1M point is W1.\n";
  for (const std::string &n : rep.notes) text << n << "\n";
  text << "\n" << table(rep) << "\n" << width_goals(rep) << rep.extra.str();
  if (rep.mismatch) text << "\nERROR: some method did not keep exactly the same shapes as ours (see MISMATCH/FAILED)\n";
  const double total = seconds_since(start);
  text << "\nbench: total " << fmt("%.1f", total) << " s (generation and loading included)\n";
  std::cout << "\n" << text.str();

  if (opt.only.empty() && opt.method.empty()) {
    if (std::system(("mkdir -p '" + opt.out + "'").c_str()) != 0) return 1;
    std::ofstream(opt.out + "/results.txt") << text.str();
    std::vector<long> ns;
    std::vector<std::string> titles;
    for (std::size_t i = 0; i < sweep_ns.size(); ++i) {
      ns.push_back(sweep_ns[i]);
      titles.push_back(sweep_titles[i]);
    }
    write_svg_plot(rep, ns, titles, opt.out + "/results.svg",
                   "discard-overlap sampling, disks r 2-7.5: index time vs candidates");
    std::cout << "bench: wrote " << opt.out << "/results.txt and " << opt.out << "/results.svg\n";
  }
  return rep.mismatch ? 1 : 0;
}

} // namespace bench

int main(int argc, char **argv) { return bench::main(argc, argv); }
