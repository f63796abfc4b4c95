// tests/check.h — the project's minimal test harness (no dependencies).
//
//   TEST(iterator_walks_every_shape) {
//     CHECK(tree.size() == 3);
//     CHECK_EQ(count, 3u);
//   }
//   int main(int argc, char **argv) { return run_all_tests(argc, argv); }
//
// Each TEST is one case: it passes when none of its CHECKs failed. The run
// prints `ok NAME (T s)` or `FAIL NAME` per case and ends with `N passed, M failed`;
// the exit status is non-zero when any case failed. `./test_x NAME...` runs
// only the named cases. A failing CHECK prints file:line and the expression;
// randomized cases print their seed through `note()`.
#ifndef BVH_TESTS_CHECK_H
#define BVH_TESTS_CHECK_H

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <functional>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace check {

struct Case {
  const char *name;
  void (*fn)();
  const char *suite; // CHECK_SUITE where the case was written ("" in a suite's own build)
};

inline std::vector<Case> &registry() {
  static std::vector<Case> cases;
  return cases;
}

inline int &failures_in_case() {
  static int n = 0;
  return n;
}

/// Context printed with every failure of the current case (e.g. a seed).
inline std::string &context() {
  static std::string s;
  return s;
}

/// The suite whose cases run_all_tests runs: "" (every case) in a suite's
/// own build; tests/units.cpp, which compiles several suites into one
/// program, names one.
inline const char *&selected_suite() {
  static const char *s = "";
  return s;
}

struct Registrar {
  Registrar(const char *name, void (*fn)(), const char *suite) { registry().push_back({name, fn, suite}); }
};

inline void fail(const char *file, int line, const std::string &what) {
  // Only the first few failures of a case are printed: a broken loop over a
  // million random pairs must not flood the log.
  if (++failures_in_case() <= 5) {
    std::cout << "  " << file << ":" << line << ": check failed: " << what;
    if (!context().empty()) std::cout << "  [" << context() << "]";
    std::cout << std::endl;
  }
}

template <class A, class B> std::string describe(const char *ea, const char *eb, const A &a, const B &b) {
  std::ostringstream s;
  s << ea << " == " << eb << " (" << a << " vs " << b << ")";
  return s.str();
}

} // namespace check

/// Sets the context (seed, case number...) printed with later failures.
inline void note(const std::string &s) { check::context() = s; }

// The suite a TEST belongs to: tests/units.cpp defines it before each
// suite it includes.
#ifndef CHECK_SUITE
#define CHECK_SUITE ""
#endif
#define CHECK_CAT2(a, b) a##b
#define CHECK_CAT(a, b) CHECK_CAT2(a, b)
#define TEST(name)                                                                   \
  static void test_##name();                                                         \
  static check::Registrar CHECK_CAT(registrar_, name)(#name, &test_##name, CHECK_SUITE); \
  static void test_##name()

#define CHECK(expr)                                                                  \
  do {                                                                               \
    if (!(expr)) check::fail(__FILE__, __LINE__, #expr);                             \
  } while (0)

#define CHECK_EQ(a, b)                                                               \
  do {                                                                               \
    const auto &check_a_ = (a);                                                      \
    const auto &check_b_ = (b);                                                      \
    if (!(check_a_ == check_b_))                                                     \
      check::fail(__FILE__, __LINE__, check::describe(#a, #b, check_a_, check_b_));  \
  } while (0)

/// Runs every registered case (or those named on the command line).
inline int run_all_tests(int argc, char **argv) {
  int passed = 0, failed = 0;
  for (const check::Case &c : check::registry()) {
    if (std::strcmp(c.suite, check::selected_suite()) != 0) continue;
    if (argc > 1) {
      bool wanted = false;
      for (int i = 1; i < argc; ++i) wanted = wanted || std::strcmp(argv[i], c.name) == 0;
      if (!wanted) continue;
    }
    check::failures_in_case() = 0;
    check::context().clear();
    const auto start = std::chrono::steady_clock::now();
    c.fn();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (check::failures_in_case() == 0) {
      ++passed;
      // (the time: to keep make test short, find the slow cases in its logs)
      std::cout << "ok " << c.name << " (" << std::fixed << std::setprecision(2) << seconds << " s)"
                << std::defaultfloat << std::endl;
    } else {
      ++failed;
      std::cout << "FAIL " << c.name << " (" << check::failures_in_case() << " failed checks)" << std::endl;
    }
  }
  std::cout << passed << " passed, " << failed << " failed" << std::endl;
  return failed == 0 && passed > 0 ? 0 : 1;
}

namespace check {
/// One suite of a program that compiles several (tests/units.cpp,
/// tests/lanes.cpp): its name and its own main.
struct Suite {
  const char *name;
  int (*run)(int, char **);
};
/// Such a program's main: `PROGRAM SUITE [CASE...]` runs one suite as its
/// own program would (its main sees PROGRAM [CASE...]).
template <std::size_t N> int run_suite(int argc, char **argv, const Suite (&suites)[N]) {
  for (const Suite &s : suites)
    if (argc > 1 && std::strcmp(argv[1], s.name) == 0) {
      selected_suite() = s.name;
      argv[1] = argv[0];
      return s.run(argc - 1, argv + 1);
    }
  std::cerr << "usage: " << argv[0] << " SUITE [CASE...]; the suites:";
  for (const Suite &s : suites) std::cerr << " " << s.name;
  std::cerr << "\n";
  return 2;
}
} // namespace check

/// Disks decided from their leaves' codes at every size (the library's
/// default starts at 4 MB of disks), so that the model tests check those
/// decisions on small trees: through set_tuning(), as a user would.
template <class Tree> Tree &codes_at_every_size(Tree &tree) {
  typename Tree::Tuning t = tree.tuning();
  t.disk_codes_min_shapes = 0;
  tree.set_tuning(t);
  return tree;
}

#endif // BVH_TESTS_CHECK_H
