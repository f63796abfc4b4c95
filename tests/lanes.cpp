// tests/lanes.cpp — the suites of insert_disjoint's parallel steps,
// tests/test_disjoint.cpp and tests/test_lazy_handles.cpp, compiled as one
// program (make test's build of them), as tests/units.cpp compiles six
// others: both build with insert_disjoint's thresholds lowered
// (tests/lanes_probe.h), so the trees they share compile once per build
// flavour. Each still builds alone (make build/test_disjoint; make check
// builds them so).
//
//   build/test_lanes SUITE [CASE...]    SUITE: disjoint or lazy_handles
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

#undef main

int main(int argc, char **argv) {
  static const check::Suite suites[] = {
      {"disjoint", &suite_disjoint::suite_main},
      {"lazy_handles", &suite_lazy_handles::suite_main},
  };
  return check::run_suite(argc, argv, suites);
}
