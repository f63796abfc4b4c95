// bench/instructions.cpp — `make bench-instructions`: one operation of the
// library per run, with only that operation instrumented, for
// `valgrind --tool=callgrind --instr-atstart=no`. Instruction counts repeat
// exactly for the same binary and input whatever the machine is doing, so
// they compare two versions of bvh.h where wall-clock times on a shared
// machine cannot. W1, W2 and W3 are bench.cpp's (build/bench --only W1
// --method ours); this program adds the two dynamic operations:
//   pairs   construct() of 100k disks r2-7.5, then count_overlapping_pairs()
//   churn   20k disks grown by insert(), then 50k rounds of erase(value) + insert()
// each at width 3 (the course's tree), or at width 8 as pairs8 and churn8.
// Only the operation after the set-up is counted. Prints its result so that
// two versions can be checked to agree.
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "peers.h"
#include "random_disks.h"

namespace {

template <int W> int pairs() {
  const std::vector<Disk> v = random_disks(100000, 2, 7.5, 2);
  BENCH_CG_START();
  BVH<Disk, shape_traits<Disk>, W> tree(4, 0);
  tree.construct(v);
  const std::size_t k = tree.count_overlapping_pairs();
  BENCH_CG_STOP();
  std::printf("pairs: %zu\n", k);
  return 0;
}

template <int W> int churn() {
  std::vector<Disk> live = random_disks(20000, 0.5, 2, 4);
  const std::vector<Disk> fresh = random_disks(50000, 0.5, 2, 5);
  std::mt19937_64 rng(6);
  std::vector<std::size_t> at(fresh.size());
  for (std::size_t &a : at) a = std::size_t(rng() % live.size());
  BVH<Disk, shape_traits<Disk>, W> tree(4, 0);
  for (const Disk &d : live) tree.insert(d);
  BENCH_CG_START();
  std::size_t removed = 0;
  for (std::size_t i = 0; i < fresh.size(); ++i) {
    removed += tree.erase(live[at[i]]);
    live[at[i]] = fresh[i];
    tree.insert(fresh[i]);
  }
  BENCH_CG_STOP();
  std::printf("churn: removed %zu, size %zu, height %d, sah %.6f, valid %d\n", removed, tree.size(), tree.height(),
              tree.sah_cost(), int(tree.validate()));
  return removed == fresh.size() && tree.validate() ? 0 : 1;
}

} // namespace

int main(int argc, char **argv) {
  const std::string what = argc > 1 ? argv[1] : "";
  if (what == "pairs") return pairs<3>();
  if (what == "churn") return churn<3>();
  if (what == "pairs8") return pairs<8>();
  if (what == "churn8") return churn<8>();
  std::fprintf(stderr, "usage: instructions pairs|churn|pairs8|churn8\n");
  return 2;
}
