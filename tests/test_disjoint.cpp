// tests/test_disjoint.cpp — insert_disjoint() (discard-overlap sampling on
// several threads) against the sequential loop
//   for (i) if (!tree.collision(c[i])) tree.insert(c[i]);
// at 1, 2, 3 and 8 threads, on dense, sparse, clustered and duplicated
// scenes of every shape kind, from empty and non-empty trees: the kept
// indices, the iteration order shape by shape with each shape's handle, the
// statistics report, the next handle insert() gives, and validate() must all
// be the loop's. Also: exceptions from a user's intersect() thrown inside
// the workers, and const queries from several threads at once (make test
// builds this file with -fsanitize=thread too). Seeds are printed on
// failure (BVH_SEED changes them; BVH_TEST_SCALE shrinks the runs).
#include <algorithm>
#include <atomic>
#include <iostream>
#include <iterator>
#include <limits>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <bvh/bvh.h>
// insert_disjoint's thresholds lowered, and the probe of its steps.
#include "lanes_probe.h"
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "check.h"
#include "scenes.h"

namespace {

template <class T> const char *kind_name();
template <> const char *kind_name<Disk>() { return "disks"; }
template <> const char *kind_name<Triangle>() { return "triangles"; }
template <> const char *kind_name<Quad>() { return "quads"; }
template <> const char *kind_name<Shape>() { return "mixed shapes"; }

/// Thread counts the cases compare with the loop (scaled-down runs: fewer;
/// under a tenth of the rounds, valgrind's run, where the threads take
/// turns, and AddressSanitizer's: three alone).
std::vector<unsigned> thread_counts() {
  if (scale() >= 1) return {1, 2, 3, 8};
  if (scale() >= 0.1) return {2, 3};
  return {3};
}

/// Everything of a tree the loop's tree must agree with: every shape in
/// iteration order with its handle, the statistics report with the tree,
/// and the handle the next insert() would get.
template <class T, class Tr, int W> std::string fingerprint(BVH<T, Tr, W> tree) {
  std::ostringstream out;
  for (auto it = tree.begin(); it != tree.end(); ++it) out << it.id().id << " " << key_of(*it) << "\n";
  tree.statistics(out, true);
  out << "height " << tree.height() << " nodes " << tree.node_count() << "\n";
  if (!tree.empty()) out << "next handle " << tree.insert(*tree.begin()).id << "\n";
  return out.str();
}

/// How a case's tree starts.
enum class Start { empty, constructed, inserted };

/// The tree of width W (3: the course's) over T.
template <class T, int W> using Tree = BVH<T, bvh::shape_traits<T>, W>;

template <class T, int W = 3> Tree<T, W> starting_tree(const std::vector<T> &base, Start how, int split, int depth) {
  Tree<T, W> tree(split, depth);
  if (how == Start::constructed) tree.construct(base);
  if (how == Start::inserted)
    for (const T &s : base) tree.insert(s);
  // A few holes in the handles, so that insert() reuses free ids.
  if (how != Start::empty && tree.size() > 10) {
    tree.erase(typename Tree<T, W>::handle{3});
    tree.erase(typename Tree<T, W>::handle{7});
  }
  return tree;
}

/// The loop and insert_disjoint() at every thread count agree on
/// `candidates` from the starting tree (`base`, `how`).
template <class T, int W = 3>
void check_against_loop(const std::vector<T> &base, Start how, const std::vector<T> &candidates, int split,
                        int depth, const std::string &where) {
  note(where);
  Tree<T, W> loop = starting_tree<T, W>(base, how, split, depth);
  std::vector<std::size_t> loop_kept;
  for (std::size_t i = 0; i < candidates.size(); ++i)
    if (!loop.collision(candidates[i])) {
      loop.insert(candidates[i]);
      loop_kept.push_back(i);
    }
  const std::string want = fingerprint(loop);
  for (unsigned threads : thread_counts()) {
    note(where + " threads " + std::to_string(threads));
    Tree<T, W> tree = starting_tree<T, W>(base, how, split, depth);
    const std::vector<std::size_t> kept = lanes_probe::insert_disjoint(tree, candidates, threads);
    CHECK(kept == loop_kept);
    std::string why;
    CHECK(tree.validate(&why));
    if (!why.empty()) note(where + " threads " + std::to_string(threads) + ": " + why);
    CHECK(tree.size() == loop.size());
    CHECK(fingerprint(tree) == want);
  }
}

/// Shapes of `scene` whose centre lies within 60 of one of five random
/// centres: dense clusters in empty space.
template <class T> std::vector<T> clustered(Maker &make, int n) {
  std::vector<Point> centres;
  for (int i = 0; i < 5; ++i) centres.push_back(Point(make.coord(100, 900), make.coord(100, 900)));
  std::vector<T> out;
  for (const T &s : make.scene<T>(n * 60, 12)) {
    for (const Point &c : centres) {
      const double dx = s.getCenter().x - c.x, dy = s.getCenter().y - c.y;
      if (dx * dx + dy * dy < 60 * 60) {
        out.push_back(s);
        break;
      }
    }
    if (int(out.size()) == n) break;
  }
  return out;
}

/// Every scene kind, from each kind of starting tree.
template <class T> void scenes_against_loop(unsigned seed) {
  for (int round = 0; round < scaled(6); ++round) {
    const std::string where = std::string(kind_name<T>()) + " BVH_SEED=" + std::to_string(seed) + " round " +
                              std::to_string(round);
    Maker make(seed + unsigned(round), round % 3 == 2 ? 25.0 : 0.0); // some rounds: tied coordinates
    const int split = 1 + int(make.rng() % 6);
    static const int depths[] = {CourseBVH<T>::unlimited, CourseBVH<T>::unlimited, 2, 6};
    const int depth = depths[make.rng() % 4];
    const Start how = round % 3 == 0 ? Start::empty : round % 3 == 1 ? Start::constructed : Start::inserted;
    const std::vector<T> base = make.scene<T>(scaled(400), 10);
    const int n = scaled(3000);
    // Dense: most candidates hit the tree (after the first batches).
    check_against_loop(base, how, make.scene<T>(n, 30), split, depth, where + " dense");
    // Sparse: most are kept, and survivors meet each other in a batch.
    check_against_loop(base, how, make.scene<T>(n, 2), split, depth, where + " sparse");
    // Clustered.
    check_against_loop(base, how, clustered<T>(make, n), split, depth, where + " clustered");
    // Exact duplicates, in runs and scattered.
    std::vector<T> dup;
    for (const T &s : make.scene<T>(n / 6, 5))
      for (int k = 0; k < 3; ++k) dup.push_back(s);
    const std::vector<T> runs = dup;
    std::shuffle(dup.begin(), dup.end(), make.rng);
    check_against_loop(base, how, runs, split, depth, where + " duplicates in runs");
    check_against_loop(base, how, dup, split, depth, where + " duplicates scattered");
  }
}

} // namespace

TEST(disjoint_is_the_loop_disks) { scenes_against_loop<Disk>(base_seed() + 20); }
TEST(disjoint_is_the_loop_triangles) { scenes_against_loop<Triangle>(base_seed() + 120); }
TEST(disjoint_is_the_loop_quads) { scenes_against_loop<Quad>(base_seed() + 220); }
TEST(disjoint_is_the_loop_mixed) { scenes_against_loop<Shape>(base_seed() + 320); }

// Large enough for the batches to grow and shrink: a dense scene after a
// sparse one, then a sparse one on the now full tree.
TEST(disjoint_batches_adapt_and_stay_exact) {
  const unsigned seed = base_seed() + 420;
  Maker make(seed);
  std::vector<Disk> c = make.scene<Disk>(scaled(20000), 0.5);
  const std::vector<Disk> dense = make.scene<Disk>(scaled(60000), 8);
  c.insert(c.end(), dense.begin(), dense.end());
  const std::vector<Disk> sparse = make.scene<Disk>(scaled(20000), 0.3);
  c.insert(c.end(), sparse.begin(), sparse.end());
  check_against_loop(std::vector<Disk>{}, Start::empty, c, 4, CourseBVH<Disk>::unlimited,
                     "BVH_SEED=" + std::to_string(seed) + " sparse, dense, sparse");
}

/// A size of the lanes' cases: scaled down, but never below a 32nd, so
/// that trees keep above the lowered Tuning::disjoint_lanes_min.
int lanes_scaled(int n) { return std::max(n / 32, scaled(n)); }

// A long run of rejected candidates (they fall on one big disk) grows the
// batch to its largest; then tens of thousands survive the tree at once and
// meet each other in one batch: step 2's sweep runs on every thread (here
// from 128 survivors), also in the scaled-down runs (ThreadSanitizer's).
TEST(disjoint_one_huge_batch_of_survivors) {
  const unsigned seed = base_seed() + 470;
  Maker make(seed);
  std::vector<Disk> c;
  for (int i = 0; i < lanes_scaled(60000); ++i)
    c.push_back(Disk(Point(make.coord(150, 350), make.coord(400, 600)), make.coord(0, 3)));
  for (int i = 0; i < lanes_scaled(30000); ++i) c.push_back(Disk(Point(make.coord(520, 1000), make.coord(0, 1000)), make.coord(0, 1.2)));
  check_against_loop(std::vector<Disk>{Disk(Point(250, 500), 240)}, Start::inserted, c, 4, CourseBVH<Disk>::unlimited,
                     "BVH_SEED=" + std::to_string(seed) + " one huge batch");
}

/// The lanes' candidates: sparse (most kept), then a patch sorted by x
/// (lopsided subtrees).
std::vector<Disk> lanes_candidates(Maker &make) {
  std::vector<Disk> c = make.scene<Disk>(lanes_scaled(12000), 0.5);
  std::vector<Disk> sorted = make.scene<Disk>(lanes_scaled(3000), 0.3);
  std::sort(sorted.begin(), sorted.end(),
            [](const Disk &a, const Disk &b) { return a.getCenter().x < b.getCenter().x; });
  c.insert(c.end(), sorted.begin(), sorted.end());
  return c;
}

// Trees large enough for step 4 to insert on every thread at once (the
// lanes: here from 128 shapes and 64 kept candidates a batch), at every split
// threshold, with and without a depth limit (leaves at the limit grow past
// it, through larger slots), by both build rules, from empty and from
// constructed trees, with rebuilds of lopsided nodes; scaled down no further
// than lanes_scaled, so that ThreadSanitizer's and valgrind's runs take the
// lanes too (the probe checks that they ran).
TEST(disjoint_lanes_are_the_loop) {
  const unsigned seed = base_seed() + 500;
  // (Scaled-down runs: at least the first three rounds, which take both
  // starts and the depth limit.)
  for (int round = 0; round < std::max(3, scaled(6)); ++round) {
    const std::string where = "BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
    Maker make(seed + unsigned(round));
    const int split = 1 + round % 6;
    const int depth = round % 3 == 2 ? 5 : CourseBVH<Disk>::unlimited;
    const Start how = round % 2 ? Start::constructed : Start::empty;
    const std::vector<Disk> c = lanes_candidates(make);
    const std::size_t before = lanes_probe::laps();
    check_against_loop(make.scene<Disk>(lanes_scaled(6000), 0.5), how, c, split, depth, where);
    CHECK(lanes_probe::laps() > before);
  }
  // The surface area heuristic's splits and rebuilds, and mixed shapes.
  Maker make(seed + 10);
  const std::vector<Shape> base = make.scene<Shape>(lanes_scaled(5000), 0.6), c = make.scene<Shape>(lanes_scaled(9000), 0.6);
  CourseBVH<Shape> loop(3);
  loop.set_build_rule(CourseBVH<Shape>::BuildRule::sah);
  loop.construct(base);
  for (const Shape &s : c)
    if (!loop.collision(s)) loop.insert(s);
  for (unsigned threads : {2u, 3u}) {
    note("BVH_SEED=" + std::to_string(seed + 10) + " SAH, mixed shapes, threads " + std::to_string(threads));
    CourseBVH<Shape> tree(3);
    tree.set_build_rule(CourseBVH<Shape>::BuildRule::sah);
    tree.construct(base);
    const std::size_t before = lanes_probe::laps();
    lanes_probe::insert_disjoint(tree, c, threads);
    CHECK(lanes_probe::laps() > before);
    CHECK(tree.validate());
    CHECK(fingerprint(tree) == fingerprint(loop));
  }
}

/// The lanes at widths other than 3: splices below the frontier, routing
/// stopped where a subtree that is one leaf would splice into a top node.
template <int W> void lanes_at_width(unsigned seed) {
  // (Scaled-down runs: rounds 0 and 2, split thresholds 1 and 7, the second
  // with a depth limit; round 1 starts from a constructed tree, as the odd
  // rounds of disjoint_lanes_are_the_loop do.)
  for (int round = 0; round < 3; round += scale() >= 1 ? 1 : 2) {
    const std::string where =
        "width " + std::to_string(W) + " BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
    Maker make(seed + unsigned(round));
    const int split = 1 + 3 * round; // 1, 4, 7
    const int depth = round == 2 ? 4 : CourseBVH<Disk>::unlimited;
    const std::vector<Disk> c = lanes_candidates(make);
    const std::size_t before = lanes_probe::laps();
    check_against_loop<Disk, W>(make.scene<Disk>(lanes_scaled(6000), 0.5), round == 1 ? Start::constructed : Start::empty, c,
                                split, depth, where);
    CHECK(lanes_probe::laps() > before);
  }
}
/// The loop's tree of width W: `base` constructed, then each candidate of
/// `c` that collides with nothing inserted.
template <int W>
BVH<Disk, bvh::shape_traits<Disk>, W> constructed_then_loop(const std::vector<Disk> &base, const std::vector<Disk> &c,
                                                            int split) {
  BVH<Disk, bvh::shape_traits<Disk>, W> loop(split);
  loop.construct(base);
  for (const Disk &s : c)
    if (!loop.collision(s)) loop.insert(s);
  return loop;
}

// A call given a DisjointSteps adds each step's laps and wall time to it,
// and keeps what the loop keeps, as a call given none does (which reads no
// clock).
TEST(disjoint_steps_report_their_laps) {
  const unsigned seed = base_seed() + 530;
  note("BVH_SEED=" + std::to_string(seed));
  Maker make(seed);
  const std::vector<Disk> base = make.scene<Disk>(lanes_scaled(6000), 0.5);
  const std::vector<Disk> c = lanes_candidates(make);
  const BVH<Disk, bvh::shape_traits<Disk>, 8> loop = constructed_then_loop<8>(base, c, 32);
  for (unsigned threads : {1u, 2u}) {
    for (bool timed : {false, true}) {
      note("threads " + std::to_string(threads) + (timed ? " timed" : " untimed"));
      BVH<Disk, bvh::shape_traits<Disk>, 8> tree(32);
      tree.construct(base);
      lanes_probe::lowered(tree);
      bvh::DisjointSteps steps;
      tree.insert_disjoint(c, threads, timed ? &steps : nullptr);
      std::size_t laps = 0;
      double seconds = 0;
      for (int step = 0; step < 5; ++step) {
        laps += steps.laps[step];
        seconds += steps.seconds[step];
        CHECK(steps.seconds[step] >= 0);
      }
      // Every batch laps steps 1 and 3 at least.
      CHECK((laps > 0) == timed);
      CHECK(!timed || (steps.laps[1] > 0 && steps.laps[3] > 0));
      CHECK(timed || seconds == 0);
      CHECK(tree.validate());
      CHECK(fingerprint(tree) == fingerprint(loop));
    }
  }
}

// Step 4 takes the lanes from disjoint_lanes_threads() threads: 2, or 3 on
// a wide tree of large leaves, where two threads insert by the pipeline
// instead (steps 1 and 2 still on both). Each way, the loop's tree.
template <int W> void lanes_from_threads(unsigned seed, int split, unsigned threads, bool lanes) {
  const std::string where = "BVH_SEED=" + std::to_string(seed) + " width " + std::to_string(W) + " split " +
                            std::to_string(split) + " threads " + std::to_string(threads);
  note(where);
  Maker make(seed);
  const std::vector<Disk> base = make.scene<Disk>(lanes_scaled(6000), 0.5);
  const std::vector<Disk> c = lanes_candidates(make);
  const BVH<Disk, bvh::shape_traits<Disk>, W> loop = constructed_then_loop<W>(base, c, split);
  BVH<Disk, bvh::shape_traits<Disk>, W> tree(split);
  tree.construct(base);
  const std::size_t before = lanes_probe::laps();
  lanes_probe::insert_disjoint(tree, c, threads);
  if ((lanes_probe::laps() > before) != lanes) note(where + ": lanes " + (lanes ? "expected, none ran" : "ran"));
  CHECK((lanes_probe::laps() > before) == lanes);
  CHECK(tree.validate());
  CHECK(fingerprint(tree) == fingerprint(loop));
}
// (The ThreadSanitizer build sets LANES_PROBE_LANES_THREADS to 2, which
// lanes_probe::lowered() gives every tree as Tuning::disjoint_lanes_threads:
// there the wide tree of large leaves takes the lanes on two threads too.)
TEST(disjoint_lanes_from_their_thread_count) {
  const unsigned seed = base_seed() + 535;
  const auto disjoint_lanes_threads = [](int width, int split) {
    const unsigned at_least = LANES_PROBE_LANES_THREADS;
    return width == 3 ? bvh::detail::disjoint_lanes_threads<3>(split, at_least)
                      : bvh::detail::disjoint_lanes_threads<8>(split, at_least);
  };
  if (LANES_PROBE_LANES_THREADS == 0) {
    CHECK(disjoint_lanes_threads(3, 32) == 2 && disjoint_lanes_threads(8, 8) == 2 && disjoint_lanes_threads(8, 16) == 3);
  } else {
    CHECK(disjoint_lanes_threads(3, 4) == unsigned(std::max(2, LANES_PROBE_LANES_THREADS)));
    CHECK(disjoint_lanes_threads(8, 32) == unsigned(std::max(2, LANES_PROBE_LANES_THREADS)));
  }
  // Set on a tree, Tuning::disjoint_lanes_threads overrides the choice.
  CHECK(bvh::detail::disjoint_lanes_threads<8>(32, 2) == 2 && bvh::detail::disjoint_lanes_threads<3>(4, 5) == 5);
  lanes_from_threads<3>(seed, 4, 2, 2 >= disjoint_lanes_threads(3, 4));
  lanes_from_threads<8>(seed + 1, 4, 2, 2 >= disjoint_lanes_threads(8, 4));
  lanes_from_threads<8>(seed + 2, 32, 2, 2 >= disjoint_lanes_threads(8, 32));
  lanes_from_threads<8>(seed + 3, 32, 3, 3 >= disjoint_lanes_threads(8, 32));
}

TEST(disjoint_lanes_are_the_loop_at_width_2) { lanes_at_width<2>(base_seed() + 540); }
TEST(disjoint_lanes_are_the_loop_at_width_4) { lanes_at_width<4>(base_seed() + 560); }
TEST(disjoint_lanes_are_the_loop_at_width_8) { lanes_at_width<8>(base_seed() + 580); }
// Margins x disk codes x insert_disjoint's step 4 (the lanes, which run at
// margin 0, and the serial insertions a margin takes) x handles: the kept
// indices against a scan of the stored disks (not only against the loop,
// which a wrong collision() would mislead the same way), the loop's tree
// with its handles, and those handles used afterwards (update inside and
// out of the leaf, erase, and a second call reusing the erased ids), with
// validate() throughout. `ran` counts the model steps: calls and handle
// operations.
/// fingerprint() without its printed numbers: every shape in iteration
/// order with its handle, the height and the node count.
template <class T> bool same_as_loop(const T &tree, const T &loop) {
  if (tree.size() != loop.size() || tree.height() != loop.height() || tree.node_count() != loop.node_count())
    return false;
  for (auto a = tree.begin(), b = loop.begin(); a != tree.end(); ++a, ++b)
    if (a.id() != b.id() || !(*a == *b)) return false;
  return true;
}

template <int W> void margins_lanes_handles(unsigned seed, double margin, bool codes, long &ran) {
  using T = Tree<Disk, W>;
  using Handle = typename T::handle;
  const std::string where = "BVH_SEED=" + std::to_string(seed) + " width " + std::to_string(W) + " margin " +
                            std::to_string(margin) + " codes " + (codes ? "at every size" : "never");
  note(where);
  Maker make(seed);
  const int split = W == 8 ? 8 : 4;
  typename T::Tuning tuning = T::default_tuning();
  tuning.disk_codes_min_shapes = codes ? 0 : std::numeric_limits<std::size_t>::max();
  // (at least 200 shapes and 300 candidates: the lanes' 128 and 64, also
  // in the scaled-down runs)
  const std::vector<Disk> base = make.scene<Disk>(std::max(200, lanes_scaled(600)), 0.5);
  std::vector<Disk> stored = base; // the model: what the tree stores
  // The loop's tree, and the tree insert_disjoint fills: the same start,
  // handles kept from insert(), two erased (ids to reuse).
  T loop(split), tree(split);
  std::vector<Handle> handles;
  for (T *t : {&loop, &tree}) {
    t->set_tuning(tuning);
    t->set_margin(margin);
    handles.clear();
    for (const Disk &d : base) handles.push_back(t->insert(d));
    t->erase(handles[3]);
    t->erase(handles[7]);
  }
  stored.erase(stored.begin() + 7);
  stored.erase(stored.begin() + 3);
  const auto scan = [&](const std::vector<Disk> &c) {
    std::vector<std::size_t> kept;
    for (std::size_t i = 0; i < c.size(); ++i) {
      bool hit = false;
      for (std::size_t k = 0; k < stored.size() && !hit; ++k) {
        // (centres farther apart on an axis than the radii reach: they miss)
        const double reach = (stored[k].getRadius() + c[i].getRadius()) * (1 + 1e-9) + 1e-9;
        if (std::fabs(stored[k].getCenter().x - c[i].getCenter().x) > reach ||
            std::fabs(stored[k].getCenter().y - c[i].getCenter().y) > reach)
          continue;
        hit = intersect(stored[k], c[i]);
      }
      if (!hit) {
        stored.push_back(c[i]);
        kept.push_back(i);
      }
    }
    return kept;
  };
  std::vector<std::pair<Handle, Disk>> named; // the kept ones by their handles (the loop's)
  for (int round = 0; round < 2; ++round) {
    note(where + " round " + std::to_string(round));
    // Sparse small disks (most kept: the lanes take them), then disks
    // beside stored ones, missing them by less than the margin.
    std::vector<Disk> c;
    for (const Disk &d : make.scene<Disk>(std::max(300, lanes_scaled(900)), 0.4)) c.push_back(d);
    for (int k = 0; k < std::max(60, lanes_scaled(200)); ++k) {
      const Disk &d = stored[make.rng() % stored.size()];
      const double r = make.coord(0, 1), a = make.coord(0, 6.283185307179586);
      const double reach = d.getRadius() + r + make.coord(0, 1.5 * margin + 0.2);
      c.push_back(Disk(Point(d.getCenter().x + reach * std::cos(a), d.getCenter().y + reach * std::sin(a)), r));
    }
    const std::vector<std::size_t> want = scan(c);
    std::vector<std::size_t> loop_kept;
    for (std::size_t i = 0; i < c.size(); ++i)
      if (!loop.collision(c[i])) {
        named.push_back({loop.insert(c[i]), c[i]});
        loop_kept.push_back(i);
      }
    CHECK(loop_kept == want);
    const std::size_t laps = lanes_probe::laps();
    const std::vector<std::size_t> kept = lanes_probe::insert_disjoint(tree, c, 2);
    ++ran;
    // (with a margin the lanes do not run: boxes are then no union of their
    // contents, which the lanes rely on)
    if (margin == 0) CHECK(lanes_probe::laps() > laps);
    CHECK(kept == want);
    std::string why;
    CHECK(tree.validate(&why));
    CHECK_EQ(why, std::string());
    CHECK(same_as_loop(tree, loop));
    for (const auto &[h, d] : named) CHECK(tree.contains(h) && tree.get(h) == d);
    // The handles used: a tenth moved within the margin or far, a tenth
    // erased, on both trees and the model.
    for (std::size_t k = 0; k < named.size(); k += 5) {
      Handle h = named[k].first;
      if (k % 10 == 0) {
        for (T *t : {&loop, &tree}) t->erase(h);
        stored.erase(std::find(stored.begin(), stored.end(), named[k].second));
        named[k] = named.back();
        named.pop_back();
      } else {
        const Disk &d = named[k].second;
        const double jump = k % 4 == 1 ? margin / 2 : 200;
        const Disk to(Point(d.getCenter().x + make.coord(-jump, jump), d.getCenter().y + make.coord(-jump, jump)),
                      d.getRadius(), d.getColor());
        for (T *t : {&loop, &tree}) t->update(h, to);
        *std::find(stored.begin(), stored.end(), d) = to;
        named[k].second = to;
      }
      ++ran;
    }
    CHECK(tree.validate(&why));
    CHECK_EQ(why, std::string());
    CHECK(same_as_loop(tree, loop));
  }
  CHECK(fingerprint(tree) == fingerprint(loop));
}

TEST(disjoint_margins_lanes_and_handles_crossed) {
  // (Scaled-down runs, valgrind's and the sanitizers': margins 0 and 4
  // with codes at every size, 4 of the 18 configurations.)
  long ran = 0;
  int configurations = 0;
  unsigned seed = base_seed() + 600;
  const bool all = scale() >= 1;
  for (const double margin : {0.0, 0.3, 4.0})
    for (const bool codes : {true, false}) {
      if (!all && (margin == 0.3 || !codes)) continue;
      margins_lanes_handles<3>(seed++, margin, codes, ran);
      if (all) margins_lanes_handles<4>(seed++, margin, codes, ran);
      margins_lanes_handles<8>(seed++, margin, codes, ran);
      configurations += all ? 3 : 2;
    }
  std::cout << "  " << configurations << " configurations, " << ran << " model steps" << std::endl;
}

/// The room the lanes reserve for their worst case goes back when the call
/// ends: the tree holds about what the loop's holds.
TEST(disjoint_gives_back_the_lanes_room) {
  const unsigned seed = base_seed() + 600;
  for (int depth : {CourseBVH<Disk>::unlimited, 6}) {
    note("BVH_SEED=" + std::to_string(seed) + " depth " + std::to_string(depth));
    Maker make(seed + unsigned(depth));
    const std::vector<Disk> c = make.scene<Disk>(20000, 0.5);
    CourseBVH<Disk> loop(4, depth), tree(4, depth);
    for (const Disk &d : c)
      if (!loop.collision(d)) loop.insert(d);
    const std::size_t before = lanes_probe::laps();
    lanes_probe::insert_disjoint(tree, c, 2);
    CHECK(lanes_probe::laps() > before);
    const auto got = tree.memory(), want = loop.memory();
    note("BVH_SEED=" + std::to_string(seed) + " depth " + std::to_string(depth) + ": " +
         std::to_string(got.total()) + " bytes against the loop's " + std::to_string(want.total()));
    // (A lane gives its cached nodes and slots back when it ends: kept
    // until all lanes ended, one slot of every class a leaf grew through in
    // every lane made this tree 2.2x the loop's at depth 6.)
    CHECK(got.pool_index <= 3 * want.pool_index + 4096);
    CHECK(got.total() <= want.total() * 11 / 10);
  }
}

TEST(disjoint_on_tiny_and_empty_inputs) {
  const unsigned seed = base_seed() + 520;
  Maker make(seed);
  for (int n = 0; n <= 9; ++n) {
    const std::string where = "BVH_SEED=" + std::to_string(seed) + " n " + std::to_string(n);
    check_against_loop(std::vector<Disk>{}, Start::empty, make.scene<Disk>(n, 200), 2, 0, where + " empty tree");
    check_against_loop(make.scene<Disk>(30, 20), Start::inserted, make.scene<Disk>(n, 100), 2, 3,
                       where + " non-empty tree");
    check_against_loop(std::vector<Triangle>{}, Start::empty, make.scene<Triangle>(n, 300), 1, 0,
                       where + " triangles");
  }
  // Threads 0: the hardware's.
  CourseBVH<Disk> tree;
  CHECK(lanes_probe::insert_disjoint(tree, std::vector<Disk>{}).empty());
  const std::vector<Disk> c = make.scene<Disk>(500, 20);
  CourseBVH<Disk> loop;
  std::vector<std::size_t> want;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (!loop.collision(c[i])) {
      loop.insert(c[i]);
      want.push_back(i);
    }
  CHECK(lanes_probe::insert_disjoint(tree, c) == want);
  CHECK(fingerprint(tree) == fingerprint(loop));
}

// ---------------------------------------------------------------------------
// Exceptions from the user's intersect() inside the workers.

namespace fragile {

struct Boom : std::runtime_error {
  Boom() : std::runtime_error("intersect() of the poisoned candidate") {}
};

/// A disk with its candidate index; intersect() throws Boom on any pair
/// with the poisoned index.
struct Tagged {
  Disk disk;
  int tag = -1;
  BoundingBox getBox() const { return disk.getBox(); }
  Point getCenter() const { return disk.getCenter(); }
};
inline std::atomic<int> &poison() {
  static std::atomic<int> p{-1};
  return p;
}
inline bool intersect(const Tagged &a, const Tagged &b) {
  if (a.tag == poison() || b.tag == poison()) throw Boom();
  return ::intersect(a.disk, b.disk);
}

} // namespace fragile

namespace {

/// (tag, handle) in iteration order, and validity: what is compared when
/// fragile::Tagged has no statistics of its own worth printing.
std::string fingerprint_tagged(const CourseBVH<fragile::Tagged> &tree) {
  std::ostringstream out;
  for (auto it = tree.begin(); it != tree.end(); ++it) out << it->tag << ":" << it.id().id << " ";
  out << "| height " << tree.height() << " nodes " << tree.node_count();
  return out.str();
}

} // namespace

TEST(disjoint_rethrows_intersect_and_keeps_a_prefix) {
  const unsigned seed = base_seed() + 620;
  Maker make(seed);
  for (int round = 0; round < scaled(8); ++round) {
    const std::string where = "BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
    note(where);
    std::vector<fragile::Tagged> c;
    for (const Disk &d : make.scene<Disk>(scaled(4000), round % 2 ? 2.0 : 12.0))
      c.push_back(fragile::Tagged{d, int(c.size())});
    // The loop without poison: what it keeps, and the first candidate it
    // rejects after `from` (whose decision compares it with a kept shape,
    // so the loop with the poison throws there).
    fragile::poison() = -1;
    std::vector<std::size_t> kept;
    {
      CourseBVH<fragile::Tagged> loop(3);
      for (std::size_t i = 0; i < c.size(); ++i)
        if (!loop.collision(c[i])) {
          loop.insert(c[i]);
          kept.push_back(i);
        }
    }
    const std::size_t from = std::size_t(make.rng() % c.size());
    std::size_t victim = c.size();
    for (std::size_t i = from, k = 0; i < c.size() && victim == c.size(); ++i) {
      while (k < kept.size() && kept[k] < i) ++k;
      if (k == kept.size() || kept[k] != i) victim = i;
    }
    if (victim == c.size()) continue;
    fragile::poison() = int(victim);
    for (unsigned threads : thread_counts()) {
      note(where + " threads " + std::to_string(threads) + " poisoned " + std::to_string(victim));
      CourseBVH<fragile::Tagged> tree(3);
      bool thrown = false;
      try {
        lanes_probe::insert_disjoint(tree, c, threads);
      } catch (const fragile::Boom &) {
        thrown = true;
      }
      CHECK(thrown);
      std::string why;
      CHECK(tree.validate(&why));
      // The tree is the loop's after some k <= victim candidates: the first
      // tree.size() kept ones, all before the victim.
      const std::size_t q = tree.size();
      CHECK(q <= kept.size());
      if (q > kept.size()) continue;
      CHECK(q == 0 || kept[q - 1] < victim);
      fragile::poison() = -1;
      CourseBVH<fragile::Tagged> prefix(3);
      for (std::size_t k = 0; k < q; ++k) prefix.insert(c[kept[k]]);
      CHECK(fingerprint_tagged(tree) == fingerprint_tagged(prefix));
      // One thread: exactly the loop up to the victim.
      if (threads == 1) CHECK(q == std::size_t(std::lower_bound(kept.begin(), kept.end(), victim) - kept.begin()));
      // The tree goes on as the loop would.
      const std::vector<std::size_t> rest = lanes_probe::insert_disjoint(tree, c, threads);
      for (std::size_t i = 0; i < c.size(); ++i)
        if (!prefix.collision(c[i])) prefix.insert(c[i]);
      CHECK(fingerprint_tagged(tree) == fingerprint_tagged(prefix));
      CHECK(rest.size() == kept.size() - q);
      fragile::poison() = int(victim);
    }
    fragile::poison() = -1;
  }
}

// A copy that throws inside the lanes (step 4, several threads inserting
// at once): the exception reaches the caller, and the tree is valid and
// holds exactly the candidates the loop keeps before the one whose copy
// threw (its insertion is the first copy of it).
namespace fragile {

struct CopyBoom : std::runtime_error {
  CopyBoom() : std::runtime_error("copy of the poisoned candidate") {}
};
inline std::atomic<int> &armed() {
  static std::atomic<int> a{-1};
  return a;
}
/// A disk with its candidate index whose first copy while armed() names
/// it throws CopyBoom.
struct OnceFragile {
  Disk disk;
  int tag = -1;
  OnceFragile(const Disk &d, int t) : disk(d), tag(t) {}
  OnceFragile(const OnceFragile &o) : disk(o.disk), tag(o.tag) {
    int want = tag;
    if (armed().load() == tag && armed().compare_exchange_strong(want, -1)) throw CopyBoom();
  }
  OnceFragile &operator=(const OnceFragile &) = default;
  BoundingBox getBox() const { return disk.getBox(); }
  Point getCenter() const { return disk.getCenter(); }
};
inline bool intersect(const OnceFragile &a, const OnceFragile &b) { return ::intersect(a.disk, b.disk); }

} // namespace fragile

TEST(disjoint_rethrows_a_copy_in_the_lanes_and_holds_the_prefix) {
  const unsigned seed = base_seed() + 660;
  Maker make(seed);
  std::vector<fragile::OnceFragile> c;
  // (16,000 candidates; scaled-down runs at least 2,000, more than
  // lanes_scaled gives: on 8 threads the first batch, which an empty tree
  // inserts serially, is about 500 candidates long, and the victim must come
  // after it.)
  for (const Disk &d : make.scene<Disk>(std::max(2000, scaled(16000)), 0.5)) c.push_back(fragile::OnceFragile(d, int(c.size())));
  std::vector<std::size_t> kept;
  {
    CourseBVH<fragile::OnceFragile> loop(4);
    for (std::size_t i = 0; i < c.size(); ++i)
      if (!loop.collision(c[i])) {
        loop.insert(c[i]);
        kept.push_back(i);
      }
  }
  for (int round = 0; round < 4; ++round) {
    // A kept candidate well past the first Tuning::disjoint_lanes_min kept: inserted by a lane.
    const std::size_t victim = kept[kept.size() / 2 + std::size_t(make.rng() % (kept.size() / 3))];
    for (unsigned threads : {2u, 3u, 8u}) {
      note("BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round) + " threads " +
           std::to_string(threads) + " poisoned " + std::to_string(victim));
      CourseBVH<fragile::OnceFragile> tree(4);
      const std::size_t before = lanes_probe::laps();
      fragile::armed() = int(victim);
      bool thrown = false;
      try {
        lanes_probe::insert_disjoint(tree, c, threads);
      } catch (const fragile::CopyBoom &) {
        thrown = true;
      }
      fragile::armed() = -1;
      CHECK(thrown);
      CHECK(lanes_probe::laps() > before);
      std::string why;
      CHECK(tree.validate(&why));
      if (!why.empty()) note(why);
      std::vector<int> held, want;
      for (const fragile::OnceFragile &s : tree) held.push_back(s.tag);
      for (std::size_t i : kept)
        if (i < victim) want.push_back(int(i));
      std::sort(held.begin(), held.end());
      CHECK(held == want);
      // It goes on as the loop would: the rest of the kept ones join.
      const std::vector<std::size_t> rest = lanes_probe::insert_disjoint(tree, c, threads);
      CHECK(rest.size() == kept.size() - want.size());
      CHECK(tree.validate());
    }
  }
}

// One thread's step 4 inserts several candidates at once (insert_pipelined):
// a copy that throws there must leave the loop's tree for the candidates
// before it, shape for shape and handle for handle (the later ones under
// way rolled back), and the call after it must go on as the loop does.
template <int W> void pipelined_insert_throws(unsigned seed) {
  using Tree = BVH<fragile::OnceFragile, bvh::shape_traits<fragile::OnceFragile>, W>;
  Maker make(seed);
  const int split = W == 3 ? 4 : 16;
  for (int round = 0; round < scaled(6); ++round) {
    std::vector<fragile::OnceFragile> c;
    for (const Disk &d : make.scene<Disk>(scaled(3000), round % 2 ? 0.5 : 3.0)) c.push_back(fragile::OnceFragile(d, int(c.size())));
    std::vector<std::size_t> kept;
    {
      Tree loop(split);
      for (std::size_t i = 0; i < c.size(); ++i)
        if (!loop.collision(c[i])) {
          loop.insert(c[i]);
          kept.push_back(i);
        }
    }
    if (kept.size() < 8) continue;
    // A kept candidate past the first Tuning::disjoint_interleave_min: in a batch.
    const std::size_t victim = kept[kept.size() / 2 + std::size_t(make.rng() % (kept.size() / 3))];
    note("BVH_SEED=" + std::to_string(seed) + " width " + std::to_string(W) + " round " + std::to_string(round) +
         " poisoned " + std::to_string(victim));
    Tree loop(split), tree(split);
    for (std::size_t i : kept)
      if (i < victim) loop.insert(c[i]);
    fragile::armed() = int(victim);
    bool thrown = false;
    try {
      lanes_probe::insert_disjoint(tree, c, 1);
    } catch (const fragile::CopyBoom &) {
      thrown = true;
    }
    fragile::armed() = -1;
    CHECK(thrown);
    std::string why;
    CHECK(tree.validate(&why));
    if (!why.empty()) note(why);
    const auto order = [](const Tree &t) {
      std::vector<std::pair<int, std::uint32_t>> out;
      for (auto it = t.begin(); it != t.end(); ++it) out.push_back({it->tag, it.id().id});
      return out;
    };
    CHECK(order(tree) == order(loop));
    CHECK(tree.height() == loop.height() && tree.node_count() == loop.node_count());
    const std::vector<std::size_t> rest = lanes_probe::insert_disjoint(tree, c, 1);
    for (std::size_t i = 0; i < c.size(); ++i)
      if (!loop.collision(c[i])) loop.insert(c[i]);
    CHECK(rest.size() == kept.size() - std::size_t(std::count_if(kept.begin(), kept.end(), [&](std::size_t i) { return i < victim; })));
    CHECK(order(tree) == order(loop));
    CHECK(tree.height() == loop.height() && tree.node_count() == loop.node_count());
    CHECK(tree.validate());
  }
}

TEST(disjoint_one_thread_rethrows_a_copy_and_holds_the_loops_prefix) {
  pipelined_insert_throws<3>(base_seed() + 680);
  pipelined_insert_throws<8>(base_seed() + 690);
}

// An insertion that throws gives its id back one way (LeafStore::unnew_id),
// whether insert() or insert_disjoint() threw: the ids are then as before
// the insertion, so the handles given after it, generations included, are
// the loop's. On trees emptied 0 to 2 times before (each emptying raises
// the generation of the ids given next), with the first kept candidate
// poisoned (an empty tree) or a later one (one thread: not in a lane,
// after whose throw the ids are not the loop's).
template <int W> void thrown_insert_ids_are_the_loops(unsigned seed) {
  using Tree = BVH<fragile::OnceFragile, bvh::shape_traits<fragile::OnceFragile>, W>;
  using Handle = typename Tree::handle;
  Maker make(seed);
  for (int round = 0; round < std::max(6, scaled(12)); ++round) {
    std::vector<fragile::OnceFragile> c;
    for (const Disk &d : make.scene<Disk>(std::max(40, scaled(400)), 1.0)) c.push_back(fragile::OnceFragile(d, int(c.size())));
    std::vector<std::size_t> kept;
    {
      Tree loop(4);
      for (std::size_t i = 0; i < c.size(); ++i)
        if (!loop.collision(c[i])) {
          loop.insert(c[i]);
          kept.push_back(i);
        }
    }
    const std::size_t victim = round % 2 ? kept[0] : kept[std::size_t(make.rng() % kept.size())];
    const int emptied = round % 3;
    const unsigned threads = round % 4 == 3 ? 2u : 1u; // (2: an empty tree, serial)
    note("BVH_SEED=" + std::to_string(seed) + " width " + std::to_string(W) + " round " + std::to_string(round) +
         " poisoned " + std::to_string(victim) + " emptied " + std::to_string(emptied) + " threads " +
         std::to_string(threads));
    // The same history for both: emptied, then the loop's shapes before
    // the victim.
    Tree loop(4), tree(4);
    for (Tree *t : {&loop, &tree})
      for (int e = 0; e < emptied; ++e) {
        std::vector<Handle> h;
        for (std::size_t i = 0; i < 3; ++i) h.push_back(t->insert(c[kept[i % kept.size()]]));
        for (Handle x : h) t->erase(x);
      }
    for (std::size_t i : kept)
      if (i < victim) loop.insert(c[i]);
    fragile::armed() = int(victim);
    bool loop_threw = false;
    try {
      loop.insert(c[victim]);
    } catch (const fragile::CopyBoom &) {
      loop_threw = true;
    }
    CHECK(loop_threw);
    fragile::armed() = int(victim);
    bool thrown = false;
    try {
      tree.insert_disjoint(c, threads);
    } catch (const fragile::CopyBoom &) {
      thrown = true;
    }
    fragile::armed() = -1;
    CHECK(thrown);
    CHECK(tree.validate());
    // Then both erase their earliest shape (its id goes to the free ids)
    // and insert the victim and the rest: every handle given must be the
    // loop's.
    for (Tree *t : {&loop, &tree})
      if (!t->empty()) t->erase(t->begin());
    for (std::size_t i : kept)
      if (i >= victim) {
        const Handle a = loop.insert(c[i]), b = tree.insert(c[i]);
        CHECK(a == b);
        if (a != b) {
          note("candidate " + std::to_string(i) + ": handle {" + std::to_string(b.id) + ", " + std::to_string(b.generation) +
               "}, the loop's {" + std::to_string(a.id) + ", " + std::to_string(a.generation) + "}");
          break;
        }
      }
    std::vector<std::pair<std::uint32_t, std::uint32_t>> held[2];
    for (auto it = loop.begin(); it != loop.end(); ++it) held[0].push_back({it.id().id, it.id().generation});
    for (auto it = tree.begin(); it != tree.end(); ++it) held[1].push_back({it.id().id, it.id().generation});
    CHECK(held[0] == held[1]);
    CHECK(tree.validate());
  }
}

TEST(disjoint_thrown_insert_gives_its_id_back_as_insert_does) {
  thrown_insert_ids_are_the_loops<3>(base_seed() + 700);
  thrown_insert_ids_are_the_loops<8>(base_seed() + 710);
}

// ---------------------------------------------------------------------------
// Const queries from several threads at once, on one tree that nobody
// changes: each thread's answers must be the one-thread answers (and under
// ThreadSanitizer, no data race).

TEST(const_queries_are_safe_for_concurrent_readers) {
  const unsigned seed = base_seed() + 720;
  note("BVH_SEED=" + std::to_string(seed));
  Maker make(seed);
  CourseBVH<Shape> tree(3);
  tree.construct(make.scene<Shape>(scaled(5000), 8));
  for (const Shape &s : make.scene<Shape>(scaled(2000), 4)) tree.insert(s);
  const std::vector<Shape> probes = make.scene<Shape>(scaled(3000), 10);
  auto answers = [&](std::size_t first) {
    std::ostringstream out;
    for (std::size_t k = 0; k < probes.size(); ++k) {
      const Shape &p = probes[(first + k) % probes.size()];
      std::size_t touching = 0, boxes = 0;
      tree.query(p, [&](const Shape &) { ++touching; });
      tree.query(p.getBox(), [&](const Shape &) { ++boxes; });
      std::size_t through = 0;
      for (const Shape &s : tree.overlapping(p)) through += s.getBox().getMin().x >= 0;
      std::vector<CourseBVH<Shape>::neighbor> near;
      tree.nearest(p.getCenter(), 3, std::back_inserter(near));
      out << (first + k) % probes.size() << ":" << tree.collision(p) << touching << "," << boxes << "," << through;
      for (const auto &nb : near) out << "," << nb.id.id;
      out << " ";
    }
    return out.str();
  };
  // Each thread starts at a different probe; the answers are compared after
  // rotating back.
  std::vector<std::string> alone(4), together(4);
  for (std::size_t t = 0; t < 4; ++t) alone[t] = answers(t * probes.size() / 4);
  std::vector<std::thread> pool;
  for (std::size_t t = 0; t < 4; ++t) pool.emplace_back([&, t] { together[t] = answers(t * probes.size() / 4); });
  for (std::thread &th : pool) th.join();
  for (std::size_t t = 0; t < 4; ++t) CHECK(together[t] == alone[t]);
}

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
