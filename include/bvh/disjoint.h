// bvh/disjoint.h — insert_disjoint: discard-overlap sampling on several threads.
//
// Exactly the result of `for (c) if (!collides(c)) insert(c)`, in batches:
// parallel tests against the tree, a parallel sweep among survivors, a
// serial decision in input order, then the inserts (on a large tree, in
// disjoint subtrees at once: the lanes). Includes erase.h, search.h,
// parallel.h.
#ifndef BVH_DISJOINT_H
#define BVH_DISJOINT_H

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <ctime>
#include <cstring>
#include <exception>
#include <limits>
#include <utility>
#include <vector>

#include "erase.h"
#include "search.h"
#include "parallel.h"
#include "lane_alloc.h"

namespace bvh {
namespace detail {

// Discard-overlap sampling, `for (i) if (!collides(c[i])) insert c[i]`, on
// several threads with exactly that loop's result. (Placed after the
// queries because it uses them; it changes Core only through insert.h's
// insert_shape and LeafStore's ids, as BVH::insert does.) The candidates go
// in batches, each in three steps:
//  1. parallel: every candidate of the batch is tested against the tree as
//     it stood at the batch's start (collides() is const: the workers share
//     the tree, which nobody changes meanwhile). The tree only grows, so a
//     candidate that hits it is rejected by the loop too; the others are the
//     batch's survivors.
//  2. parallel when there are many survivors: every pair of survivors whose
//     boxes (rounded outwards to float, as collides()'s are) overlap, found
//     by a sweep along x, is tested by intersect(earlier, later), the
//     argument order of collides().
//  3. serial, in input order: a survivor is kept iff no earlier kept
//     survivor of the batch intersects it (step 2's pairs, or with few
//     survivors a direct box-then-intersect test);
//  4. the kept ones are inserted as the loop inserts them, with their ids
//     taken as BVH::insert takes them: on a large tree, routed through
//     its top in order and then inserted into disjoint subtrees by
//     several threads at once (insert_in_order), else one by one.
// A survivor misses the tree as it was at the batch's start, and since then
// only the batch's earlier kept survivors were added: step 3 decides what
// the loop decides, and step 4 makes the loop's insertions with its ids. (This relies on what collides() itself relies on: shapes
// that intersect have overlapping boxes.) The batch adapts: it doubles
// while few candidates survive the tree (the steps' fixed costs spread over
// more) and halves while many do (step 2's pairs grow with its square).
// The threads are started once per call (parallel_for) and wait between
// batches (Crew), so a batch never waits for a thread to start or for one
// the system has not yet woken.

} // namespace detail

/// Where a call of insert_disjoint spent its time, when one is passed to
/// it (BVH::insert_disjoint's `steps`): seconds[s] adds the wall time of
/// each lap of step s, cpu_seconds[s] the process's CPU time in it (every
/// thread's: std::clock), and laps[s] counts the laps (1 and 2: the parallel
/// steps, 3: the serial decisions and inserts, 4: the lanes' inserts, 0:
/// the rest, i.e. gathering survivors and the sweep's sort). A call
/// passed none reads no clock: reading it once a batch is a visible part
/// of a call on a virtual machine, where the clock is a system call.
/// bench/bench.cpp's serial-fraction figures come from here; the tests
/// read laps[4] to know that the lanes ran.
struct DisjointSteps {
  double seconds[5] = {0, 0, 0, 0, 0};
  double cpu_seconds[5] = {0, 0, 0, 0, 0};
  std::size_t laps[5] = {0, 0, 0, 0, 0};
};

namespace detail {

/// insert_disjoint's laps into a DisjointSteps, or nothing without one.
/// Only the driver thread laps.
struct DisjointClock {
  explicit DisjointClock(DisjointSteps *to) : steps(to) {
    if (steps) {
      last = std::chrono::steady_clock::now();
      last_cpu = std::clock();
    }
  }
  void lap(int step) {
    if (!steps) return;
    const auto now = std::chrono::steady_clock::now();
    const std::clock_t cpu = std::clock();
    steps->seconds[step] += std::chrono::duration<double>(now - last).count();
    steps->cpu_seconds[step] += double(cpu - last_cpu) / CLOCKS_PER_SEC;
    ++steps->laps[step];
    last = now;
    last_cpu = cpu;
  }
  DisjointSteps *steps;
  std::chrono::steady_clock::time_point last;
  std::clock_t last_cpu = 0;
};

/// BVH::insert's id handling around insert_shape: the next id, given back
/// if the insertion throws.
template <class T, class Tr, int W> void insert_new(Core<T, Tr, W> &core, const T &shape) {
  const std::uint32_t id = core.leaves.new_id();
  try {
    insert_shape(core, shape, id);
  } catch (...) {
    core.leaves.unnew_id(id);
    throw;
  }
}

/// The loop's step for candidate i: inserted (and i kept) unless it
/// intersects a stored shape.
template <class T, class Tr, int W>
void decide_as_the_loop(Core<T, Tr, W> &core, const std::vector<T> &candidates, std::size_t i,
                        std::vector<std::size_t> &kept) {
  if (collides(core, candidates[i])) return;
  insert_new(core, candidates[i]);
  kept.push_back(i);
}

/// A survivor of step 1 for step 2's sweep: its box rounded outwards to
/// float and its rank among the batch's survivors.
struct SweepBox {
  float lo_x, lo_y, hi_x, hi_y;
  std::uint32_t rank;
};

/// Step 3's kept survivors of a batch, as float boxes in rows of four, so
/// that one SIMD pass tests a survivor's box against four of them.
class KeptBoxes {
public:
  void clear() { size_ = 0; }
  /// Adds box b (lo x, lo y, hi x, hi y) as box size().
  void push_back(const float b[4]) {
    // The rows keep their length between batches (clear() leaves it): a
    // batch's pushes then write, without resizing four vectors every
    // fourth box. hi_y_ grows last: if a resize throws, the rows before it
    // are only longer, and the next push grows them all again.
    if (size_ + 4 > hi_y_.size()) {
      const std::size_t length = 2 * hi_y_.size() + 64;
      for (std::vector<float> *row : {&lo_x_, &lo_y_, &hi_x_, &hi_y_}) row->resize(std::max(length, row->size()));
    }
    lo_x_[size_] = b[0];
    lo_y_[size_] = b[1];
    hi_x_[size_] = b[2];
    hi_y_[size_] = b[3];
    ++size_;
  }
  /// False when exact(i) is true for some box i that meets box b (in
  /// ascending i, stopping there); else true.
  template <class Exact> BVH_ALWAYS_INLINE bool none_meets(const float b[4], Exact &&exact) const {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
    const __m128 bx0 = _mm_set1_ps(b[0]), by0 = _mm_set1_ps(b[1]), bx1 = _mm_set1_ps(b[2]), by1 = _mm_set1_ps(b[3]);
    for (std::size_t g = 0; g < size_; g += 4) {
      const __m128 meets = _mm_and_ps(
          _mm_and_ps(_mm_cmple_ps(_mm_loadu_ps(&lo_x_[g]), bx1), _mm_cmple_ps(bx0, _mm_loadu_ps(&hi_x_[g]))),
          _mm_and_ps(_mm_cmple_ps(_mm_loadu_ps(&lo_y_[g]), by1), _mm_cmple_ps(by0, _mm_loadu_ps(&hi_y_[g]))));
      unsigned bits = unsigned(_mm_movemask_ps(meets));
      if (size_ - g < 4) bits &= (1u << (size_ - g)) - 1;
      for (; bits != 0; bits &= bits - 1)
        if (exact(g + std::size_t(lowest_bit(bits)))) return false;
    }
#else
    for (std::size_t i = 0; i < size_; ++i)
      if (lo_x_[i] <= b[2] && b[0] <= hi_x_[i] && lo_y_[i] <= b[3] && b[1] <= hi_y_[i] && exact(i)) return false;
#endif
    return true;
  }

private:
  std::vector<float> lo_x_, lo_y_, hi_x_, hi_y_; // (lengths: at least size_ rounded up to 4)
  std::size_t size_ = 0;
};

/// Step 2: the pairs (earlier, later) of survivors, by rank, that
/// intersect, sorted by the later one. The sweep sorts the boxes by their
/// left side; each box then meets only the boxes after it that start before
/// its right side ends, scanned in chunks (on the crew from `crew_min`
/// survivors: below, waking it costs more than it saves).
template <class T, class Tr>
std::vector<std::pair<std::uint32_t, std::uint32_t>> surviving_pairs(const Tr &traits, const std::vector<T> &candidates,
                                                                    const std::vector<std::size_t> &survivors,
                                                                    Crew &crew, unsigned threads, std::size_t crew_min,
                                                                    DisjointClock &clock) {
  std::vector<SweepBox> boxes(survivors.size());
  for (std::size_t r = 0; r < survivors.size(); ++r) {
    float f[4];
    round_out(box_of(traits, candidates[survivors[r]]), f);
    // A NaN side sorts first; it overlaps nothing, as in collides().
    if (!(f[0] == f[0])) f[0] = -std::numeric_limits<float>::infinity();
    boxes[r] = SweepBox{f[0], f[1], f[2], f[3], std::uint32_t(r)};
  }
  // Sorted by left side: on keys of 8 bytes (the side's bits made
  // unsigned-ordered, then the rank), cheaper to compare and move than
  // the boxes.
  std::vector<std::uint64_t> keys(boxes.size());
  for (std::size_t r = 0; r < boxes.size(); ++r) {
    std::uint32_t bits;
    std::memcpy(&bits, &boxes[r].lo_x, sizeof bits);
    bits = bits >> 31 ? ~bits : bits | 0x80000000u; // (-0 before +0: equal sides, either order will do)
    keys[r] = std::uint64_t(bits) << 32 | r;
  }
  std::sort(keys.begin(), keys.end());
  {
    std::vector<SweepBox> sorted(boxes.size());
    for (std::size_t i = 0; i < keys.size(); ++i) sorted[i] = boxes[std::size_t(keys[i] & 0xffffffffu)];
    boxes.swap(sorted);
  }
  clock.lap(0);
  const std::size_t chunk = std::max<std::size_t>(1, std::min<std::size_t>(256, boxes.size() / (4 * threads)));
  const std::size_t chunks = (boxes.size() + chunk - 1) / chunk;
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> found(chunks);
  auto sweep = [&](std::size_t k) {
    const std::size_t end = std::min(boxes.size(), (k + 1) * chunk);
    for (std::size_t p = k * chunk; p < end; ++p) {
      const SweepBox &a = boxes[p];
      for (std::size_t q = p + 1; q < boxes.size() && boxes[q].lo_x <= a.hi_x; ++q) {
        const SweepBox &b = boxes[q];
        if (!(a.lo_y <= b.hi_y && b.lo_y <= a.hi_y && b.lo_x <= a.hi_x && a.lo_x <= b.hi_x)) continue;
        const std::uint32_t early = std::min(a.rank, b.rank), late = std::max(a.rank, b.rank);
        if (traits.intersect(candidates[survivors[early]], candidates[survivors[late]])) found[k].push_back({early, late});
      }
    }
  };
  if (boxes.size() >= crew_min) {
    crew.run(chunks, sweep);
    clock.lap(2);
  } else {
    for (std::size_t k = 0; k < chunks; ++k) sweep(k);
    clock.lap(0);
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (const auto &v : found) pairs.insert(pairs.end(), v.begin(), v.end());
  std::sort(pairs.begin(), pairs.end(), [](const std::pair<std::uint32_t, std::uint32_t> &a,
                                           const std::pair<std::uint32_t, std::uint32_t> &b) {
    return a.second < b.second || (a.second == b.second && a.first < b.first);
  });
  return pairs;
}

/// Step 4's share of the tree for one thread at a time: the subtree at
/// child `child_index` of top node `parent`, and the kept candidates routed
/// to it (positions in step 4's list, ascending).
struct Lane {
  int parent;
  int child_index;
  std::size_t count;                ///< the subtree's count once its routed candidates are in
  Box box;                          ///< its box then
  Box start_box;                    ///< its box before the routing
  std::vector<std::size_t> items;   ///< routed, in input order
  std::size_t done = 0;             ///< items inserted
  std::exception_ptr error;         ///< thrown by items[done]
};

/// The top of the tree for step 4: the inner nodes above depth `depth`
/// (pre-order) and, below them, the subtrees (one Lane each) that threads
/// insert into at once. Every descent from the root passes top nodes only
/// until it enters exactly one lane's subtree.
struct Frontier {
  std::vector<int> top;
  std::vector<Lane> lanes;
  std::vector<std::pair<int, std::size_t>> lane_of; ///< (subtree root, lane), by node

  template <class T, class Tr, int W> Frontier(const Core<T, Tr, W> &core, int depth) {
    const NodeStore<W> &nodes = core.nodes;
    std::vector<int> stack{core.root};
    while (!stack.empty()) {
      const int n = stack.back();
      stack.pop_back();
      const Node<W> &node = nodes.node(n);
      if (nodes.info(n).depth < depth && !node.is_leaf()) {
        top.push_back(n);
        for (int c = node.num_children - 1; c >= 0; --c) stack.push_back(node.child(c));
      } else {
        lane_of.push_back({n, lanes.size()});
        lanes.push_back(Lane{nodes.info(n).parent, nodes.info(n).child_index, nodes.info(n).count, nodes.box(n),
                             nodes.box(n), {}, 0, nullptr});
      }
    }
    std::sort(lane_of.begin(), lane_of.end());
  }
  /// The lane whose subtree root is n.
  Lane &lane(int n) { return lanes[std::lower_bound(lane_of.begin(), lane_of.end(), std::make_pair(n, std::size_t(0)))->second]; }
};

/// Step 4, serial: keep[i] inserted for each i, in order, as the loop does.
template <class T, class Tr, int W>
void insert_serially(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                     std::size_t from, std::vector<std::size_t> &kept) {
  for (std::size_t i = from; i < keep.size(); ++i) {
    insert_new(core, candidates[keep[i]]);
    kept.push_back(keep[i]);
  }
}

/// An insertion under way in insert_pipelined: where its descent is.
struct PipeCursor {
  std::size_t item;   // in keep
  Box box;            // the shape's own (at margin 0 also what it adds to boxes)
  int n;              // the node of its next step, or (at_leaf) the leaf it stepped at
  int depth;          // n's
  int prev, above;    // as in insert_below
  std::size_t prev_count;
  Box leaf_box;       // (at_leaf) the leaf's box before
  bool at_leaf;
};

/// Step 4 on one thread: keep[i] for each i >= from inserted in order, as
/// insert_new() one by one inserts them (the same tree, ids and
/// statistics), with up to kPipe insertions under way at once so that the
/// cache misses of their descents overlap. An insertion writes a node's
/// count and box (and its parent's copy of the box) when it steps there,
/// and reads the node's copies of its children's boxes; a later one steps
/// at depth D only while every earlier one under way is at depth D + 2 or
/// deeper, so it reads nothing they have yet to write and writes nothing
/// they have yet to read. A leaf split changes nothing above the leaf's
/// parent (margin 0: no box changes), and a later insertion is never that
/// deep while the split waits. Each insertion finishes at its leaf (push
/// or split, then its rebalance) only as the oldest under way, and before
/// a rebuild the later ones are rolled back (their counts and boxes) and
/// start again. Needs margin 0 and an inner root. If an insertion throws,
/// the later ones are rolled back and the exception passes on: the tree
/// then holds the candidates before it, as the loop's does.
template <class T, class Tr, int W>
void insert_pipelined(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                      std::size_t from, std::vector<std::size_t> &kept) {
  BVH_INVARIANT(core.margin == 0 && core.root >= 0 && !core.nodes.node(core.root).is_leaf(),
                "insert_pipelined() needs margin 0 and an inner root");
  constexpr int kPipe = 4; // insertions under way at most
  NodeStore<W> &nodes = core.nodes;
  const std::size_t smallest = min_rebuild(core);
  PipeCursor ring[kPipe];
  int head = 0, size = 0;
  const auto at = [&](int k) -> PipeCursor & { return ring[(head + k) % kPipe]; };
  const auto start = [&](PipeCursor &c, std::size_t item) {
    c.item = item;
    c.box = box_of(core.traits, candidates[keep[item]]);
    c.n = core.root;
    c.depth = 0;
    c.prev = c.above = -1;
    c.prev_count = 0;
    c.at_leaf = false;
  };
  const auto roll_back = [&](const PipeCursor &c) noexcept {
    undo_descent(core, c.at_leaf ? c.n : nodes.info(c.n).parent, -1, c.at_leaf ? &c.leaf_box : nullptr);
  };
  // One step, and a prefetch of what the cursor's next step reads.
  const auto step = [&](PipeCursor &c) BVH_LAMBDA_INLINE {
    if (descend_step(nodes, c.n, c.prev, c.above, c.prev_count, c.leaf_box, c.box, smallest)) {
      c.at_leaf = true;
      const Node<W> &leaf = nodes.node(c.n);
      if (leaf.leaf().has_slot()) core.leaves.prefetch_end(leaf);
      return;
    }
    ++c.depth;
    prefetch_lines(&nodes.node(c.n), sizeof(Node<W>));
    prefetch_lines(&nodes.info(c.n), sizeof(Info));
  };
  std::size_t next = from;
  while (size > 0 || next < keep.size()) {
    int shallowest = std::numeric_limits<int>::max(); // of the earlier ones under way
    for (int k = 0; k < size; ++k) {
      PipeCursor &c = at(k);
      if (c.at_leaf && k == 0) { // the oldest finishes
        const std::uint32_t id = core.leaves.new_id();
        int n;
        try {
          n = insert_at_leaf(core, core.root, c.n, c.leaf_box, c.box, candidates[keep[c.item]], id);
        } catch (...) {
          core.leaves.unnew_id(id);
          for (int j = size - 1; j >= 1; --j) roll_back(at(j));
          throw;
        }
        ++core.size;
        kept.push_back(keep[c.item]);
        const int scapegoat = insert_scapegoat(core, n, c.above, -1, size == 1);
        if (scapegoat >= 0) { // the later ones start again on the rebuilt tree
          for (int j = size - 1; j >= 1; --j) roll_back(at(j));
          rebalance(core, scapegoat, Cut::by_rule);
          for (int j = 1; j < size; ++j) start(at(j), at(j).item);
        }
        head = (head + 1) % kPipe;
        --size;
        --k;
        continue;
      }
      if (!c.at_leaf && shallowest >= c.depth + 2) step(c);
      shallowest = std::min(shallowest, c.depth);
    }
    if (next < keep.size() && size < kPipe && shallowest >= 2) {
      start(at(size), next++);
      ++size;
    }
  }
}

/// Step 4 after an insertion in a lane threw: brings the tree to what the
/// loop holds when the first candidate (in input order) whose insertion
/// throws does so, then rethrows that exception. The routed candidates
/// not inserted are taken out of the top's counts and boxes and give their
/// ids back; those of them before the first failure are inserted now, in
/// order; those inserted after it are erased again. The tree is then valid
/// and holds exactly the kept candidates before the failure, though not in
/// the loop's shape (the erases mend it their own way) and not with the
/// loop's ids. If an erase here throws too, that candidate stays.
template <class T, class Tr, int W>
[[noreturn]] void finish_failed_lanes(Core<T, Tr, W> &core, const std::vector<T> &candidates,
                                      const std::vector<std::size_t> &keep, Frontier &frontier,
                                      const std::vector<std::uint32_t> &ids, std::size_t next) {
  NodeStore<W> &nodes = core.nodes;
  std::size_t first = keep.size();
  std::exception_ptr error;
  for (const Lane &lane : frontier.lanes)
    if (lane.error && lane.items[lane.done] < first) {
      first = lane.items[lane.done];
      error = lane.error;
    }
  std::vector<std::size_t> missing, unused;
  for (const Lane &lane : frontier.lanes)
    for (std::size_t k = lane.done; k < lane.items.size(); ++k) {
      for (int a = lane.parent; a >= 0; a = nodes.info(a).parent) --nodes.info(a).count;
      --core.size;
      unused.push_back(lane.items[k]);
      if (lane.items[k] < first) missing.push_back(lane.items[k]);
    }
  for (const Lane &lane : frontier.lanes) {
    const int root = nodes.node(lane.parent).child(lane.child_index);
    nodes.set_box(root, core.fitted_box(root));
  }
  for (auto a = frontier.top.rbegin(); a != frontier.top.rend(); ++a) nodes.set_box(*a, core.fitted_box(*a));
  std::sort(unused.rbegin(), unused.rend());
  for (std::size_t i : unused) core.leaves.unnew_id(ids[i - next]);
  std::sort(missing.begin(), missing.end());
  for (std::size_t i : missing) {
    try {
      insert_new(core, candidates[keep[i]]);
    } catch (...) {
      first = i;
      error = std::current_exception();
      break;
    }
  }
  for (const Lane &lane : frontier.lanes)
    for (std::size_t k = 0; k < lane.done; ++k) {
      if (lane.items[k] < first) continue;
      const typename LeafStore<T>::Loc at = core.locate(ids[lane.items[k] - next]);
      try {
        erase_shape(core, at.leaf, at.index, Cut::in_order);
      } catch (...) {
      }
    }
  std::rethrow_exception(error);
}

/// The fewest threads worth the lanes at width W with leaves of up to
/// `split_threshold` shapes. Two lanes beat the pipeline on deep trees
/// (narrow nodes or small leaves), where each insertion's descent is long;
/// on a wide tree of large leaves, a few levels deep, one pipelined thread
/// inserts faster than two lanes, which each descend one insertion at a
/// time behind the driver's routing (docs/performance.txt, NODE WIDTH).
/// `at_least` (Tuning::disjoint_lanes_threads), when not 0, overrides it.
template <int W> constexpr unsigned disjoint_lanes_threads(int split_threshold, unsigned at_least = 0) {
  if (at_least > 0) return std::max(2u, at_least);
  return W > kCourseWidth && split_threshold >= 16 ? 3u : 2u;
}

/// Step 4's routing: keep[next], keep[next + 1], ... routed through the
/// frontier's top in order, each as its insertion would descend it (the
/// top's counts and boxes raised on the way, its lane's count and box, and
/// an id taken), until one would change the top itself (a rebuild of a
/// lopsided top node, or a split given to a top node) or all are routed.
/// Returns the end of those routed; `ids` gets their ids, `error` what a
/// routing step threw (it then stops there). A lane's subtree root keeps
/// its own count and box for the lane to raise, but the routing's later
/// choices read its box in its parent, which must already hold the
/// candidates routed to it: the routing sets the root's box to the lane's
/// (set_box, both copies), and once all are routed sets it back to the box
/// before (start_box), from which the lane grows it one insertion at a
/// time as the loop does (a split or rebuild at the subtree's root compares
/// the new box with the old one).
template <class T, class Tr, int W>
std::size_t route(Core<T, Tr, W> &core, Frontier &frontier, const std::vector<T> &candidates,
                  const std::vector<std::size_t> &keep, std::size_t next, int depth, std::vector<std::uint32_t> &ids,
                  std::exception_ptr &error) {
  NodeStore<W> &nodes = core.nodes;
  const std::size_t smallest = min_rebuild(core);
  std::size_t end = next; // candidates [next, end) are routed
  int path[32];
  for (; end < keep.size(); ++end) {
    try {
      const Box box = core.fat(box_of(core.traits, candidates[keep[end]]));
      int d = 0, n = core.root;
      while (nodes.info(n).depth < depth && !nodes.node(n).is_leaf()) {
        path[d++] = n;
        n = choose_child(nodes.node(n), box);
      }
      Lane &lane = frontier.lane(n);
      // A subtree that is one leaf and overflows would give its split
      // to its parent, a top node (splice): the loop's change of the top.
      bool top_lopsided = W != kCourseWidth && nodes.node(n).is_leaf() && d > 0 &&
                          !core.is_leaf_size(lane.count + 1, nodes.info(n).depth);
      for (int i = d - 1; i >= 0 && !top_lopsided; --i) {
        const std::size_t count = nodes.info(path[i]).count + 1;
        const std::size_t below = i == d - 1 ? lane.count + 1 : nodes.info(path[i + 1]).count + 1;
        top_lopsided = lopsided(below, count, smallest);
      }
      if (top_lopsided) break;
      ids.push_back(core.leaves.new_id());
      for (int i = 0; i < d; ++i) {
        ++nodes.info(path[i]).count;
        nodes.extend_box(path[i], box);
      }
      ++lane.count;
      lane.box.extend(box);
      nodes.set_box(n, lane.box); // (set back to start_box below)
      lane.items.push_back(end);
      ++core.size;
    } catch (...) {
      error = std::current_exception();
      break;
    }
  }
  for (const Lane &lane : frontier.lanes)
    if (!lane.items.empty()) nodes.set_box(nodes.node(lane.parent).child(lane.child_index), lane.start_box);
  return end;
}

/// Step 4's lanes, once keep[next], ..., keep[end - 1] are routed (their
/// ids ids[0], ...): each lane's candidates inserted into its subtree, in
/// order, on the crew's threads at once while the stores have room for
/// them (LaneAlloc: the allocator the lanes put in force), then the rest on
/// this thread. If an insertion threw, finish_failed_lanes().
template <class T, class Tr, int W>
void run_lanes(Core<T, Tr, W> &core, Frontier &frontier, const std::vector<T> &candidates,
               const std::vector<std::size_t> &keep, const std::vector<std::uint32_t> &ids, std::size_t next,
               std::size_t end, unsigned threads, Crew &crew, DisjointClock &clock) {
  NodeStore<W> &nodes = core.nodes;
  std::size_t largest = 0;
  for (const Lane &lane : frontier.lanes) largest = std::max(largest, lane.count);
  // Leaves hold at most split_threshold shapes, except at a depth limit.
  const std::size_t largest_leaf = core.depth_limit > 0 ? largest + 1 : std::size_t(core.split_threshold) + 1;
  LaneAlloc<T, W> alloc(nodes, core.leaves);
  // (without the room, the lanes run on this thread alone)
  const bool shareable = alloc.reserve(frontier.lanes.size(), threads, largest, largest_leaf, end - next);
  std::atomic<bool> failed{false};
  auto run_lane = [&](std::size_t k) {
    Lane &lane = frontier.lanes[k];
    typename LaneAlloc<T, W>::InLane in_lane(alloc, k);
    for (; lane.done < lane.items.size(); ++lane.done) {
      if (failed.load(std::memory_order_relaxed) || alloc.slack_used()) return;
      in_lane.begin_insertion();
      const std::size_t i = lane.items[lane.done];
      try {
        const T &shape = candidates[keep[i]];
        const int top = nodes.node(lane.parent).child(lane.child_index);
        int above;
        const int n = insert_below(core, top, box_of(core.traits, shape), shape, ids[i - next], &above);
        rebalance(core, insert_scapegoat(core, n, above, lane.parent), Cut::by_rule);
      } catch (...) {
        lane.error = std::current_exception();
        failed = true;
        return;
      }
    }
  };
  if (shareable && threads > 1) {
    alloc.put_in_force();
    crew.run(frontier.lanes.size(), run_lane);
    alloc.withdraw();
    clock.lap(4);
  }
  for (std::size_t k = 0; k < frontier.lanes.size() && !failed; ++k) run_lane(k); // what is left
  clock.lap(3);
  if (failed) finish_failed_lanes(core, candidates, keep, frontier, ids, next);
}

/// Step 4: keep[i] inserted, in order, for every i, with exactly the loop's
/// tree (insert_new one by one), on the crew's threads. A candidate's
/// descent first passes the top of the tree (Frontier), then stays in one
/// subtree below it; what it changes at the top (counts and boxes), and
/// so which subtree it enters, depends only on the candidates before it, so
/// the driver routes every candidate through the top in order ("routing"),
/// and then the threads insert each subtree's candidates into it, in
/// order, one thread per subtree at a time ("lanes"). Insertions into
/// different subtrees touch disjoint nodes, slots and ids, and their order
/// relative to one another changes nothing; allocation goes through the
/// lanes' allocator (LaneAlloc). Where the loop would change the top itself
/// (a rebuild of a lopsided top node), routing stops: the lanes catch up,
/// that candidate is inserted alone, and routing starts again from a new
/// frontier (a round). Lanes run only on a tree without margin (boxes are
/// then always their contents' union, so nothing in a subtree refits the
/// top) and large enough to be worth it.
template <class T, class Tr, int W>
void insert_in_order(Core<T, Tr, W> &core, const std::vector<T> &candidates, const std::vector<std::size_t> &keep,
                     unsigned threads, Crew &crew, DisjointClock &clock, std::vector<std::size_t> &kept) {
  const bool lanes_pay = threads >= disjoint_lanes_threads<W>(core.split_threshold, core.tuning.disjoint_lanes_threads);
  const auto inner_root = [&] { return core.margin == 0 && core.root >= 0 && !core.nodes.node(core.root).is_leaf(); };
  if (!lanes_pay && inner_root()) {
    insert_pipelined(core, candidates, keep, 0, kept);
    clock.lap(3);
    return;
  }
  int depth = 0; // the frontier's: about 16 subtrees a thread
  for (std::size_t lanes = 1; lanes < 16 * std::size_t(threads); lanes *= std::size_t(W)) ++depth;
  for (std::size_t next = 0; next < keep.size();) {
    // (a smaller tree, or a round of fewer candidates: serially)
    if (!lanes_pay || !inner_root() || core.size < core.tuning.disjoint_lanes_min || keep.size() - next < 64) {
      insert_serially(core, candidates, keep, next, kept);
      clock.lap(3);
      return;
    }
    Frontier frontier(core, depth);
    std::vector<std::uint32_t> ids;
    std::exception_ptr routing_error;
    const std::size_t end = route(core, frontier, candidates, keep, next, depth, ids, routing_error);
    clock.lap(3);
    run_lanes(core, frontier, candidates, keep, ids, next, end, threads, crew, clock);
    for (std::size_t i = next; i < end; ++i) kept.push_back(keep[i]);
    next = end;
    if (routing_error) std::rethrow_exception(routing_error);
    if (next < keep.size()) { // it changes the top
      insert_new(core, candidates[keep[next]]);
      kept.push_back(keep[next]);
      ++next;
      clock.lap(3);
    }
  }
}

/// A batch's working lists in insert_disjoint_batches, kept from one batch
/// to the next.
template <class T> struct Batch {
  std::vector<unsigned char> hit;           ///< step 1: by candidate of the batch
  std::vector<std::size_t> survivors;       ///< step 1's misses, ascending
  std::vector<std::size_t> keep;            ///< step 3's kept survivors, ascending
  std::vector<unsigned char> survivor_kept; ///< step 3: by survivor's rank
  KeptBoxes kept_boxes;                     ///< keep[i]'s box, rounded once
};

/// Step 1: the candidates [start, start + m) against the tree as it stands
/// (read only), in chunks on the crew, each chunk's searches interleaved
/// on a large tree (collides_each); b.survivors gets those that miss it.
template <class T, class Tr, int W>
void search_the_tree(const Core<T, Tr, W> &core, const std::vector<T> &candidates, std::size_t start, std::size_t m,
                     unsigned threads, Crew &crew, Batch<T> &b) {
  const bool serial = threads == 1;
  b.hit.assign(m, 0);
  const std::size_t chunk = serial ? m : std::max<std::size_t>(1, std::min<std::size_t>(128, m / (4 * threads)));
  const bool interleave = core.size >= core.tuning.disjoint_interleave_min;
  auto query = [&](std::size_t k) {
    const std::size_t end = std::min(m, (k + 1) * chunk);
    if (interleave)
      collides_each(core, candidates.data() + start + k * chunk, end - k * chunk, b.hit.data() + k * chunk);
    else
      for (std::size_t j = k * chunk; j < end; ++j) b.hit[j] = collides(core, candidates[start + j]) ? 1 : 0;
  };
  crew.run((m + chunk - 1) / chunk, query);
  b.survivors.clear();
  for (std::size_t j = 0; j < m; ++j)
    if (!b.hit[j]) b.survivors.push_back(start + j);
}

/// Steps 2 and 3: b.keep gets the survivors that intersect no earlier kept
/// one, in input order. Below `pairwise` survivors, and on one thread,
/// each is tested against the kept ones' boxes (KeptBoxes), which costs
/// the square of the survivors, with no sort and no pair list; else by
/// step 2's pairs (surviving_pairs).
template <class T, class Tr, int W>
void keep_survivors(const Core<T, Tr, W> &core, const std::vector<T> &candidates, std::size_t pairwise,
                    unsigned threads, Crew &crew, DisjointClock &clock, Batch<T> &b) {
  const std::size_t s = b.survivors.size();
  b.survivor_kept.assign(s, 0);
  b.keep.clear();
  if (s < pairwise || threads == 1) {
    clock.lap(0);
    b.kept_boxes.clear();
    for (std::size_t r = 0; r < s; ++r) {
      const T &c = candidates[b.survivors[r]];
      float box[4];
      round_out(box_of(core.traits, c), box);
      const bool free =
          b.kept_boxes.none_meets(box, [&](std::size_t i) { return core.traits.intersect(candidates[b.keep[i]], c); });
      if (!free) continue;
      b.keep.push_back(b.survivors[r]);
      b.kept_boxes.push_back(box);
    }
    return;
  }
  const auto pairs =
      surviving_pairs(core.traits, candidates, b.survivors, crew, threads, core.tuning.disjoint_sweep_min, clock);
  std::size_t p = 0;
  for (std::uint32_t r = 0; r < s; ++r) {
    bool free = true;
    for (; p < pairs.size() && pairs[p].second == r; ++p) free = free && !b.survivor_kept[pairs[p].first];
    if (!free) continue;
    b.survivor_kept[r] = 1;
    b.keep.push_back(b.survivors[r]);
  }
}

/// The batches of insert_disjoint (run by the crew's driver): steps 1 to 3
/// decide a batch, step 4 inserts what they keep.
template <class T, class Tr, int W>
void insert_disjoint_batches(Core<T, Tr, W> &core, const std::vector<T> &candidates, unsigned threads, Crew &crew,
                             std::vector<std::size_t> &kept, DisjointSteps *steps) {
  const std::size_t n = candidates.size();
  // Batch sizes: starting small (on an empty tree all of the first batch
  // survives), within [kMin, kMax]; step 2 runs from kPairwise survivors.
  // On one thread a batch is only there so that its searches can run
  // interleaved (collides_each), and steps 2 and 3 are one
  // (keep_survivors). A small batch keeps that short and the nodes its
  // searches brought in still cached when step 4 inserts.
  const bool serial = threads == 1;
  const std::size_t kSerialBatch = 128;
  const std::size_t kMin = serial ? kSerialBatch : 64 * std::size_t(threads);
  const std::size_t kMax = serial ? kSerialBatch : std::size_t(1) << 17, kPairwise = 32;
  const std::size_t target = 2048 * std::size_t(threads); // survivors a batch aims at
  std::size_t batch = kMin;
  Batch<T> b;
  DisjointClock clock(steps);
  for (std::size_t start = 0; start < n;) {
    if (serial && core.size < core.tuning.disjoint_interleave_min) { // the loop itself
      decide_as_the_loop(core, candidates, start++, kept);
      continue;
    }
    const std::size_t m = std::min(batch, n - start);
    try {
      search_the_tree(core, candidates, start, m, threads, crew, b); // 1. against the tree
      clock.lap(1);
      keep_survivors(core, candidates, kPairwise, threads, crew, clock, b); // 2. and 3. among themselves
    } catch (...) {
      if (!serial) throw;
      // One thread keeps the loop's behaviour exactly: the batch is decided
      // again as the loop decides it, one candidate at a time, so that the
      // loop's candidate throws (or, if nothing throws again, the batch
      // completes). Nothing of the batch was inserted yet.
      for (std::size_t i = start; i < start + m; ++i) decide_as_the_loop(core, candidates, i, kept);
      start += m;
      continue;
    }
    clock.lap(3);
    insert_in_order(core, candidates, b.keep, threads, crew, clock, kept); // 4. inserted, in input order
    start += m;
    const std::size_t s = b.survivors.size();
    if (2 * s < target) batch = std::min(kMax, 2 * batch);
    else if (s > 2 * target) batch = std::max(kMin, batch / 2);
  }
}

/// Inserts, in order, each candidate that intersects no stored shape and no
/// candidate inserted before it, as the loop above does, on `threads`
/// threads (0: the hardware's; 1: one thread, whose batches only let the
/// searches run interleaved). Returns the indices of those inserted,
/// ascending. If a worker or an insertion throws, the first exception is
/// rethrown and the tree holds what the loop holds after candidates [0,
/// k), with k the first candidate of the batch in progress (a throw in
/// step 1 or 2) or the first whose insertion threw (step 4; with 1 thread,
/// the candidate whose decision or insertion the loop's throw comes from);
/// after a throw in a lane, in another shape and with other ids than the
/// loop's (finish_failed_lanes).
template <class T, class Tr, int W>
std::vector<std::size_t> insert_disjoint(Core<T, Tr, W> &core, const std::vector<T> &candidates, unsigned threads,
                                         DisjointSteps *steps = nullptr) {
  std::vector<std::size_t> kept;
  threads = threads_for(threads);
  if (candidates.empty()) return kept;
  if (threads == 1) {
    Crew crew; // (no helper: the driver runs every chunk)
    insert_disjoint_batches(core, candidates, 1, crew, kept, steps);
    return kept;
  }
  // The first thread to arrive drives, the others help until it is done
  // (also when it throws). If threads cannot be started, parallel_for runs
  // the driver alone and then the helpers, which find it done.
  // The lanes reserve room for their worst case in the stores' arrays;
  // what is left of it goes back at the end, also after a throw.
  struct Shrink {
    Core<T, Tr, W> &core;
    ~Shrink() {
      core.nodes.shrink_spare();
      core.leaves.shrink_spare();
    }
  } shrink{core};
  Crew crew;
  std::atomic<bool> driving{false};
  parallel_for(threads, threads, [&](std::size_t) {
    if (driving.exchange(true)) {
      crew.help();
      return;
    }
    struct Finish {
      Crew &crew;
      ~Finish() { crew.finish(); }
    } finish{crew};
    insert_disjoint_batches(core, candidates, threads, crew, kept, steps);
  });
  return kept;
}
} // namespace detail
} // namespace bvh

#endif // BVH_DISJOINT_H
