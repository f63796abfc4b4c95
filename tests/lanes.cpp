// tests/lanes.cpp — the ThreadSanitizer program (build/test_lanes_tsan):
// the suites of insert_disjoint's parallel steps, tests/test_disjoint.cpp
// and tests/test_lazy_handles.cpp, and construct()'s threads,
// tests/test_threads.cpp, compiled as one program, as tests/units.cpp
// compiles them (with the others) for the default and the sanitizer
// builds. make test builds it with -DLANES_PROBE_LANES_THREADS=2
// (tests/lanes_probe.h). Each suite still builds alone (make
// build/test_disjoint; make check builds them so).
//
//   build/test_lanes_tsan SUITE [CASE...]    SUITE: disjoint, lazy_handles or threads
//
// runs one suite as its own program would.

// Every header a suite includes, here first, at global scope: inside the
// namespaces below each #include is then a no-op (include guards).
#include "lanes_probe.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <iostream>
#include <iterator>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "check.h"
#include "scenes.h"

#define main suite_main

#undef CHECK_SUITE
#define CHECK_SUITE "disjoint"
namespace suite_disjoint {
#include "test_disjoint.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "lazy_handles"
namespace suite_lazy_handles {
#include "test_lazy_handles.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "threads"
namespace suite_threads {
#include "test_threads.cpp"
}

#undef main

int main(int argc, char **argv) {
  static const check::Suite suites[] = {
      {"disjoint", &suite_disjoint::suite_main},
      {"lazy_handles", &suite_lazy_handles::suite_main},
      {"threads", &suite_threads::suite_main},
  };
  return check::run_suite(argc, argv, suites);
}
