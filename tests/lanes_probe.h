// tests/lanes_probe.h — for the suites of insert_disjoint's parallel steps
// (tests/test_disjoint.cpp, tests/test_lazy_handles.cpp; tests/lanes.cpp
// compiles both as one program): lanes_probe::insert_disjoint(tree, c,
// threads) is tree.insert_disjoint(c, threads) on a tree whose thresholds
// are lowered through set_tuning(), as a user would lower them, so that
// small trees, and the scaled-down runs under valgrind and the sanitizers,
// take every parallel path; and it counts the steps that ran (from the
// DisjointSteps it passes), so that the tests can check the lanes ran.
#ifndef BVH_TESTS_LANES_PROBE_H
#define BVH_TESTS_LANES_PROBE_H

#include <atomic>
#include <cstddef>
#include <vector>

#include <bvh/bvh.h>

// The fewest threads on which step 4 takes the lanes (Tuning::
// disjoint_lanes_threads; 0: the library's choice by the tree's shape).
// The ThreadSanitizer build sets 2, so that every tree takes the lanes on
// two threads there.
#ifndef LANES_PROBE_LANES_THREADS
#define LANES_PROBE_LANES_THREADS 0
#endif

namespace lanes_probe {
/// Laps of step 4 (the lanes), and of every step, over all calls made
/// through insert_disjoint() below.
inline std::atomic<std::size_t> &laps() {
  static std::atomic<std::size_t> n{0};
  return n;
}
inline std::atomic<std::size_t> &all_laps() {
  static std::atomic<std::size_t> n{0};
  return n;
}

/// `tree`'s thresholds lowered: lanes and step 2's sweep on every thread
/// from 128 shapes (the default: 4,096), interleaved searches and one
/// thread's batches from trees of 64 (the default: 32,768), disks decided
/// from codes at every size.
template <class Tree> Tree &lowered(Tree &tree) {
  typename Tree::Tuning t = tree.tuning();
  t.disjoint_lanes_min = 128;
  t.disjoint_sweep_min = 128;
  t.disjoint_interleave_min = 64;
  t.disk_codes_min_shapes = 0;
  t.disjoint_lanes_threads = LANES_PROBE_LANES_THREADS;
  tree.set_tuning(t);
  return tree;
}

/// tree.insert_disjoint(c, threads) with the thresholds lowered, its laps
/// counted (also when it throws).
template <class T, class Tr, int W>
std::vector<std::size_t> insert_disjoint(bvh::BVH<T, Tr, W> &tree, const std::vector<T> &c, unsigned threads = 0) {
  lowered(tree);
  bvh::DisjointSteps steps;
  struct Count {
    const bvh::DisjointSteps &steps;
    ~Count() {
      laps() += steps.laps[4];
      for (std::size_t n : steps.laps) all_laps() += n;
    }
  } count{steps};
  return tree.insert_disjoint(c, threads, &steps);
}
} // namespace lanes_probe

#endif
