// tests/test_threads.cpp — construct() on several threads. A scene of
// kParallelMin shapes or more is laid out from counts alone
// (bvh::detail::Layout) and its subtrees built at once: whatever the number
// of threads, the tree must be the one-thread tree, and every node laid out
// must be used (validate() counts them). make test also runs this file
// built with -fsanitize=thread, where a data race fails it.
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "check.h"
#include "scenes.h"

namespace {

template <class Tree> std::string report(const Tree &tree) {
  std::ostringstream out;
  tree.statistics(out, true);
  return out.str();
}

/// Thread counts the scene is built on: all in the full run; 1 and 2 in the
/// scaled-down runs (the sanitizers'); under a tenth of the rounds
/// (valgrind's run) 2 alone, the threaded build checked by validate() and
/// memcheck, its equality with the one-thread tree by the other runs.
std::vector<unsigned> scaled_thread_counts() {
  if (scale() >= 1) return {1, 2, 3, 8};
  if (scale() >= 0.1) return {1, 2};
  return {2};
}

/// Builds `shapes` on each number of threads: every tree must validate and
/// print the one-thread tree's report.
template <class T, int W = 3>
void check_thread_counts(const std::vector<T> &shapes, int k, int limit, const std::vector<unsigned> &thread_counts,
                         const std::string &where) {
  std::string first;
  for (unsigned threads : thread_counts) {
    BVH<T, bvh::shape_traits<T>, W> tree(k, limit);
    tree.set_build_threads(threads);
    tree.construct(shapes);
    std::string why;
    CHECK(tree.validate(&why));
    if (!why.empty()) note(where + " " + why);
    CHECK(tree.size() == shapes.size());
    if (thread_counts.size() == 1) break; // nothing to compare the report with
    if (first.empty())
      first = report(tree);
    else
      CHECK(report(tree) == first);
  }
}

} // namespace

TEST(parallel_build_is_the_sequential_build) {
  const unsigned seed = base_seed() + 11;
  const std::size_t n = CourseBVH<Disk>::kParallelMin + 4321;
  // Scaled-down runs (valgrind, the sanitizers) check one disk scene on
  // fewer threads (scaled_thread_counts): a tree of the same size, fewer of them.
  const bool full = scale() >= 1;
  for (int round = 0; round < scaled(4); ++round) {
    const std::string where = "BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
    note(where);
    Maker make(seed + unsigned(round), round % 2 ? 5.0 : 0.0); // odd rounds: many tied centres
    const int k = 1 + round % 5, limit = round % 3 == 2 ? 7 : 0;
    check_thread_counts(make.scene<Disk>(int(n), 6), k, limit, scaled_thread_counts(), where);
    if (full) check_thread_counts(make.scene<Triangle>(int(n), 6), k, limit, scaled_thread_counts(), where);
  }
}

TEST(parallel_build_is_the_sequential_build_at_width_8) {
  // At widths other than 3 the top node's range is also halved on two
  // threads at once, from 2^16 shapes: a scene of 3 * 2^16 takes it two
  // levels down (scaled-down runs, under valgrind and the sanitizers: one).
  const unsigned seed = base_seed() + 17;
  const bool full = scale() >= 1;
  const std::size_t n = (full ? 3 : 1) * CourseBVH<Disk>::kParallelMin + 123;
  for (int round = 0; round < (full ? 2 : 1); ++round) {
    const std::string where = "BVH_SEED=" + std::to_string(seed) + " round " + std::to_string(round);
    note(where);
    Maker make(seed + unsigned(round), round % 2 ? 5.0 : 0.0);
    check_thread_counts<Disk, 8>(make.scene<Disk>(int(n), 6), round ? 16 : 32, 0, scaled_thread_counts(), where);
  }
}

TEST(small_scenes_never_use_threads_and_build_the_same) {
  // Under kParallelMin the build runs on the caller alone whatever is asked.
  Maker make(base_seed() + 13, 3.0);
  const std::vector<Disk> disks = make.scene<Disk>(scaled(5000), 6);
  check_thread_counts(disks, 4, 0, {1, 2, 0}, "small scene");
}

int main(int argc, char **argv) {
  std::cout << "seed " << base_seed() << " (set BVH_SEED to change), scale " << scale() << std::endl;
  return run_all_tests(argc, argv);
}
