// tests/lanes_probe.h — for the suites of insert_disjoint's parallel steps
// (tests/test_disjoint.cpp, tests/test_lazy_handles.cpp; tests/lanes.cpp
// compiles both as one program): its thresholds lowered, so that small
// trees, and the scaled-down runs under valgrind and the sanitizers, take
// every parallel path; and a probe of the steps that ran. Included before
// bvh.h.
#ifndef BVH_TESTS_LANES_PROBE_H
#define BVH_TESTS_LANES_PROBE_H

#include <atomic>
#include <cstddef>

// Step 4's parallel inserts (lanes) report their laps as step 4: the lane
// tests check that they ran.
namespace lanes_probe {
inline std::atomic<std::size_t> &laps() {
  static std::atomic<std::size_t> n{0};
  return n;
}
inline std::atomic<std::size_t> &all_laps() {
  static std::atomic<std::size_t> n{0};
  return n;
}
inline void lap(int step, double) {
  ++all_laps();
  if (step == 4) ++laps();
}
/// BVH_DISJOINT_PROFILE_ON: the clock is read only while this is true.
inline bool on = true;
} // namespace lanes_probe
#define BVH_DISJOINT_PROFILE lanes_probe::lap
#define BVH_DISJOINT_PROFILE_ON lanes_probe::on
// Lanes, and step 2's sweep on every thread, from 128 shapes (bvh.h's
// default: 4,096).
#define BVH_DISJOINT_LANES_MIN 128
#define BVH_DISJOINT_SWEEP_MIN 128
// Interleaved searches, and one thread's batches, from trees of 64 shapes
// (bvh.h's default: 32,768).
#define BVH_DISJOINT_INTERLEAVE_MIN 64
#define BVH_DISK_CODES_MIN_BYTES 0 // (disks decided from codes at every size)

#endif
