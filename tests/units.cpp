// tests/units.cpp — several unit suites compiled as one program (make test's
// build of them): tests/test_bvh.cpp, test_dynamic, test_moving,
// test_intersect, test_threads, test_parse, and insert_disjoint's
// test_disjoint and test_lazy_handles, each inside a namespace of its own,
// so that the trees they share (CourseBVH<Disk> and the rest) are compiled once
// per build flavour instead of once per suite. The suites are unchanged and still
// build alone (make build/test_bvh; make check builds them so).
//
//   build/test_units SUITE [CASE...]    e.g. build/test_units bvh, or
//                                       build/test_units dynamic erase_everything_then_reuse
//
// runs one suite as its own program would (its main: the seed line, its
// cases, "N passed, M failed").
//
// The suites that replace operator new or check the library beside a
// program's own global names stay apart: test_exceptions, test_names (and
// test_editions, which has the course's global BVH). tests/lanes.cpp
// builds the two insert_disjoint suites alone for ThreadSanitizer.

// Every header a suite includes, here first, at global scope: inside the
// namespaces below each #include is then a no-op (include guards).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include <bvh/bvh.h>
#include "check.h"
#include <bvh/intersect.h>
#include <bvh/scene.h>
#include <bvh/generate.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "scenes.h"
#include "lanes_probe.h"

#define main suite_main

#undef CHECK_SUITE
#define CHECK_SUITE "bvh"
namespace suite_bvh {
#include "test_bvh.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "dynamic"
namespace suite_dynamic {
#include "test_dynamic.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "moving"
namespace suite_moving {
#include "test_moving.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "intersect"
namespace suite_intersect {
#include "test_intersect.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "threads"
namespace suite_threads {
#include "test_threads.cpp"
}

#undef CHECK_SUITE
#define CHECK_SUITE "parse"
namespace suite_parse {
#include "test_parse.cpp"
}

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
      {"bvh", &suite_bvh::suite_main},
      {"dynamic", &suite_dynamic::suite_main},
      {"moving", &suite_moving::suite_main},
      {"intersect", &suite_intersect::suite_main},
      {"threads", &suite_threads::suite_main},
      {"parse", &suite_parse::suite_main},
      {"disjoint", &suite_disjoint::suite_main},
      {"lazy_handles", &suite_lazy_handles::suite_main},
  };
  return check::run_suite(argc, argv, suites);
}
