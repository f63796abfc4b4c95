// tests/units.cpp — several unit suites compiled as one program (make test's
// build of them): tests/test_bvh.cpp, test_dynamic, test_moving,
// test_intersect, test_threads and test_parse, each inside a namespace of its
// own, so that the trees they share (BVH<Disk> and the rest) are compiled
// once per build flavour instead of once per suite: about 40% less code to
// compile than the six programs apart. The suites are unchanged and still
// build alone (make build/test_bvh; make check builds them so).
//
//   build/test_units SUITE [CASE...]    e.g. build/test_units bvh, or
//                                       build/test_units dynamic erase_everything_then_reuse
//
// runs one suite as its own program would (its main: the seed line, its
// cases, "N passed, M failed").
//
// The suites that replace operator new or need their own build stay
// apart: test_disjoint and test_lazy_handles (one program of their own,
// tests/lanes.cpp), test_names and test_exceptions.

// Every header a suite includes, here first, at global scope: inside the
// namespaces below each #include is then a no-op (include guards).
#include <unistd.h>

#include <algorithm>
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
#include <utility>
#include <vector>

#include <bvh/bvh.h>
#include "check.h"
#include <bvh/intersect.h>
#include <bvh/scene.h>
#include <bvh/generate.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "scenes.h"

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

#undef main

int main(int argc, char **argv) {
  static const check::Suite suites[] = {
      {"bvh", &suite_bvh::suite_main},
      {"dynamic", &suite_dynamic::suite_main},
      {"moving", &suite_moving::suite_main},
      {"intersect", &suite_intersect::suite_main},
      {"threads", &suite_threads::suite_main},
      {"parse", &suite_parse::suite_main},
  };
  return check::run_suite(argc, argv, suites);
}
