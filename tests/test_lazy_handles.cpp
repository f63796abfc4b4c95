// tests/test_lazy_handles.cpp — the handle table is built on first use
// (issue 19): trees made by construct(), insert() and insert_disjoint()
// without a handle lookup hold no table (memory().handles == 0), and once a
// handle is used every id ever given out names its shape. Ids are predicted
// by a reference model of the id rule (docs/library.txt, HANDLES: a count,
// the ids given back reused last-first, all forgotten when the tree
// empties) through random inserts, erases (by handle, by iterator, by
// value), updates, insert_disjoint (serial and with lanes), copies, moves
// and rebuilds, against a brute-force map of id -> shape; validate() after
// every step. Seeds are printed on failure (BVH_SEED; BVH_TEST_SCALE
// shrinks the runs for valgrind and the sanitizers).
#include <algorithm>
#include <atomic>
#include <iterator>
#include <map>
#include <random>
#include <string>
#include <thread>
#include <vector>

// insert_disjoint's thresholds lowered (lanes from trees of 128 shapes),
// and the probe of its steps: the lanes' test checks that they ran.
#include "lanes_probe.h"

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "check.h"
#include "scenes.h"

namespace {

using Tree = CourseBVH<Disk>;
using Handle = Tree::handle;

/// The id rule, as docs/library.txt states it, and what each id names;
/// with the generations as bvh.h gives them: an erase raises its id's, and
/// once the tree is emptied (or constructed) the ids start again above
/// every generation given before.
struct Model {
  std::uint32_t count = 0;          // ids given out so far (in use or free)
  std::vector<std::uint32_t> free;  // given back, the last one reused first
  std::map<std::uint32_t, Disk> shapes;
  std::vector<std::uint32_t> generation; // by id
  std::uint32_t fresh = 0;               // the generation of new ids

  std::uint32_t next() {
    if (!free.empty()) {
      const std::uint32_t id = free.back();
      free.pop_back();
      return id;
    }
    generation.push_back(fresh);
    return count++;
  }
  void insert(const Disk &d) {
    const std::uint32_t id = next();
    shapes[id] = d;
  }
  void forget() {
    if (count != 0) fresh = std::max(fresh, *std::max_element(generation.begin(), generation.end())) + 1;
    count = 0;
    free.clear();
    generation.clear();
    shapes.clear();
  }
  void erase(std::uint32_t id) {
    shapes.erase(id);
    if (shapes.empty()) {
      forget();
    } else {
      ++generation[id];
      free.push_back(id);
    }
  }
  void construct(const std::vector<Disk> &v) {
    forget();
    for (const Disk &d : v) insert(d);
  }
  /// The id the next insert() will get.
  std::uint32_t peek() const { return free.empty() ? count : free.back(); }
  /// The handle of id (in use: its shape's; free: none's).
  Handle handle(std::uint32_t id) const { return Handle{id, generation.at(id)}; }
};

/// Without looking a handle up: size, validate, iteration's ids.
bool agrees_without_handles(const Tree &tree, const Model &m, std::string *why) {
  if (tree.size() != m.shapes.size()) return *why = "size " + std::to_string(tree.size()), false;
  if (!tree.validate(why)) return false;
  std::size_t seen = 0;
  for (auto it = tree.begin(); it != tree.end(); ++it, ++seen) {
    const auto s = m.shapes.find(it.id().id);
    if (s == m.shapes.end() || !(s->second == *it) || it.id() != m.handle(it.id().id))
      return *why = "iterator's id " + std::to_string(it.id().id) + " names another shape", false;
  }
  if (seen != m.shapes.size()) return *why = "iteration saw " + std::to_string(seen), false;
  return true;
}

/// Every id the model knows, looked up by handle; the free ones and one
/// past the count name nothing.
bool agrees(const Tree &tree, const Model &m, std::string *why) {
  if (!agrees_without_handles(tree, m, why)) return false;
  for (const auto &[id, d] : m.shapes) {
    const Handle h = m.handle(id);
    if (!tree.contains(h)) return *why = "lost handle " + std::to_string(id), false;
    if (!(tree.get(h) == d)) return *why = "get(" + std::to_string(id) + ") is another shape", false;
    if (tree.find(h).id() != h) return *why = "find(" + std::to_string(id) + ")", false;
    if (tree.contains(Handle{id, h.generation - 1}) || tree.contains(Handle{id, h.generation + 1}))
      return *why = "id " + std::to_string(id) + " of another generation names a shape", false;
  }
  for (std::uint32_t id : m.free)
    if (tree.contains(m.handle(id)) || tree.contains(Handle{id, m.handle(id).generation - 1}))
      return *why = "free id " + std::to_string(id) + " names a shape", false;
  if (tree.contains(Handle{m.count, m.fresh})) return *why = "id past the count names a shape", false;
  if (!m.shapes.empty() && tree.memory().handles == 0) return *why = "handles used but no table", false;
  return tree.validate(why);
}

/// The loop insert_disjoint must equal (`for (c) if (!collision(c))
/// insert(c)`), on the model, with a plain tree of the model's shapes for
/// the collisions.
std::vector<std::size_t> model_disjoint(Model &m, const std::vector<Disk> &c) {
  std::vector<Disk> stored;
  for (const auto &[id, d] : m.shapes) stored.push_back(d);
  Tree loop(4);
  loop.construct(stored);
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (!loop.collision(c[i])) {
      loop.insert(c[i]);
      m.insert(c[i]);
      kept.push_back(i);
    }
  return kept;
}

std::string seed_note(unsigned seed, int step) { return "BVH_SEED=" + std::to_string(seed) + " step " + std::to_string(step); }

// ---------------------------------------------------------------------------

TEST(no_table_until_a_handle_is_used) {
  const unsigned seed = base_seed() + 9100;
  note(seed_note(seed, -1));
  Maker make(seed);
  for (int round = 0; round < 3; ++round) {
    Tree tree(round + 2);
    Model m;
    std::string why;
    const std::vector<Disk> start = make.scene<Disk>(scaled(3000), 3);
    tree.construct(start);
    m.construct(start);
    CHECK_EQ(tree.memory().handles, std::size_t(0));
    for (const Disk &d : make.scene<Disk>(scaled(1000), 3)) {
      const Handle h = tree.insert(d);
      CHECK_EQ(h.id, m.peek());
      m.insert(d);
    }
    const std::vector<Disk> more = make.scene<Disk>(scaled(2000), 2);
    const std::vector<std::size_t> kept = lanes_probe::insert_disjoint(tree, more, 1 + unsigned(round));
    CHECK(kept == model_disjoint(m, more));
    // Erases by iterator and by value give ids back, still without a table.
    for (int k = 0; k < scaled(300) && tree.size() > 1; ++k) {
      auto it = tree.begin();
      std::advance(it, long(make.rng() % tree.size()));
      m.erase(it.id().id);
      tree.erase(it);
    }
    for (const Disk &d : make.scene<Disk>(scaled(200), 3)) {
      CHECK_EQ(tree.insert(d).id, m.peek());
      m.insert(d);
    }
    // Nothing const but a handle lookup builds it: queries, iteration,
    // statistics, copies.
    Disk probe;
    make.make(probe, 50);
    (void)tree.collision(probe);
    tree.query(probe, [](const Disk &) {});
    for (const Disk &s : tree.overlapping(probe)) (void)s;
    std::vector<Tree::neighbor> near;
    tree.nearest(probe.getCenter(), 5, std::back_inserter(near));
    (void)tree.sah_cost();
    (void)tree.height();
    const Tree copy = tree;
    CHECK(agrees_without_handles(tree, m, &why));
    CHECK_EQ(why, std::string());
    CHECK_EQ(tree.memory().handles, std::size_t(0));
    CHECK_EQ(copy.memory().handles, std::size_t(0));
    // The first handle lookup builds it; every id ever given names its shape.
    const Handle first = m.handle(m.shapes.begin()->first);
    CHECK(tree.get(first) == m.shapes.begin()->second);
    CHECK(tree.memory().handles >= tree.size() * 8);
    CHECK(agrees(tree, m, &why));
    CHECK_EQ(why, std::string());
    // The copy made before builds its own.
    CHECK(agrees(copy, m, &why));
    CHECK_EQ(why, std::string());
    // Emptying the tree forgets the ids and the table.
    tree.clear();
    CHECK_EQ(tree.memory().handles, std::size_t(0));
    CHECK(!tree.contains(first)); // (a lookup in an empty tree builds nothing)
    CHECK_EQ(tree.memory().handles, std::size_t(0));
    CHECK(tree.validate());
  }
}

/// Random changes; handles are looked up at random points (or, with
/// `handles_late`, only at the end), so each step runs with the table
/// built or not, and the ids must be the model's either way.
void random_changes(unsigned seed, bool handles_late, int steps) {
  note(seed_note(seed, -1) + (handles_late ? " late" : ""));
  Maker make(seed);
  std::mt19937 &rng = make.rng;
  Tree tree(int(2 + seed % 4), seed % 3 == 0 ? 6 : 0);
  if (seed % 2) tree.set_build_rule(Tree::BuildRule::sah);
  Model m;
  std::string why;
  auto pick = [&]() {
    auto it = m.shapes.begin();
    std::advance(it, long(rng() % m.shapes.size()));
    return m.handle(it->first);
  };
  bool used = false; // a handle was looked up since the tree last emptied
  for (int step = 0; step < steps; ++step) {
    note(seed_note(seed, step) + (handles_late ? " late" : ""));
    const unsigned op = unsigned(rng() % 40);
    const bool may_use = !handles_late;
    if (m.shapes.empty() || op < 12) {
      Disk d;
      make.make(d, 5);
      const Handle h = tree.insert(d);
      CHECK_EQ(h.id, m.peek());
      m.insert(d);
      CHECK(h == m.handle(h.id));
    } else if (op < 16) {
      auto it = tree.begin();
      std::advance(it, long(rng() % tree.size()));
      m.erase(it.id().id);
      tree.erase(it);
    } else if (op < 20 && may_use) {
      const Handle h = pick();
      tree.erase(h);
      m.erase(h.id);
      used = true;
    } else if (op < 26 && may_use) {
      const Handle h = pick();
      Disk to = m.shapes[h.id];
      to = Disk(Point(to.getCenter().x + make.coord(-30, 30), to.getCenter().y + make.coord(-30, 30)),
                to.getRadius(), to.getColor());
      tree.update(h, to);
      m.shapes[h.id] = to;
      used = true;
    } else if (op < 28) {
      const std::vector<Disk> c = make.scene<Disk>(int(rng() % 60), 4);
      const std::vector<std::size_t> kept = lanes_probe::insert_disjoint(tree, c, 1 + rng() % 3);
      CHECK(kept == model_disjoint(m, c));
    } else if (op < 29) {
      const std::vector<Disk> v = make.scene<Disk>(int(rng() % 200), 4);
      tree.construct(v);
      m.construct(v);
      used = false;
    } else if (op < 30) {
      // Erase by value (each disk is distinct): the id goes back.
      const Handle h = pick();
      const Disk d = m.shapes[h.id];
      CHECK_EQ(tree.erase(d), std::size_t(1));
      m.erase(h.id);
    } else if (op < 31) {
      Tree copy(tree);
      CHECK_EQ(copy.memory().handles == 0, tree.memory().handles == 0);
      tree = std::move(copy);
    } else if (op < 32) {
      Tree other(3);
      other.swap(tree);
      tree.swap(other);
    } else if (op < 33 && m.shapes.size() < 40) {
      // Down to empty: every id is forgotten.
      while (!m.shapes.empty()) {
        auto it = tree.begin();
        m.erase(it.id().id);
        tree.erase(it);
      }
      used = false;
    } else if (may_use) {
      const Handle h = pick();
      CHECK(tree.contains(h));
      CHECK(tree.get(h) == m.shapes[h.id]);
      used = true;
    }
    if (m.shapes.empty()) used = false;
    if (!handles_late && !used && tree.memory().handles != 0) {
      CHECK_EQ(std::string("a table without a handle lookup"), std::string());
      return;
    }
    if (handles_late && tree.memory().handles != 0) {
      CHECK_EQ(std::string("a table in a run without handle lookups"), std::string());
      return;
    }
    if (!agrees_without_handles(tree, m, &why)) {
      CHECK_EQ(why, std::string());
      return;
    }
    if (may_use && step % 97 == 0) {
      if (!agrees(tree, m, &why)) {
        CHECK_EQ(why, std::string());
        return;
      }
      used = !m.shapes.empty();
    }
  }
  CHECK(agrees(tree, m, &why));
  CHECK_EQ(why, std::string());
}

TEST(ids_are_the_models_with_the_table_built_on_the_way) {
  for (unsigned k = 0; k < 6; ++k) random_changes(base_seed() + 9200 + k, false, scaled(1500));
}
TEST(ids_are_the_models_with_the_table_built_at_the_end) {
  for (unsigned k = 0; k < 6; ++k) random_changes(base_seed() + 9300 + k, true, scaled(1500));
}

/// insert_disjoint's lanes (a tree of at least the lowered Tuning::disjoint_lanes_min
/// shapes, several threads) write the table from several threads when it is built, and
/// skip it when not: the ids are the loop's either way.
TEST(lanes_give_the_loops_ids_with_and_without_the_table) {
  const unsigned seed = base_seed() + 9400;
  for (int built = 0; built < 2; ++built) {
    note(seed_note(seed, built));
    Maker make(seed);
    Tree tree(4);
    Model m;
    std::string why;
    // Small disks, sparse: nearly every candidate survives, and the tree
    // is large enough for lanes.
    auto small = [&](int n) {
      std::vector<Disk> v;
      for (const Disk &d : make.scene<Disk>(n, 1)) v.push_back(Disk(d.getCenter(), d.getRadius() * 0.2, d.getColor()));
      return v;
    };
    // (Scaled down to an eighth at most: the tree stays past the lanes' minimum.)
    const std::vector<Disk> start = small(std::max(750, scaled(6000)));
    CHECK(lanes_probe::insert_disjoint(tree, start, 2) == model_disjoint(m, start));
    // Free ids in the middle, so that reused and fresh ids both go to lanes.
    for (int k = 0; k < std::max(40, scaled(300)); ++k) {
      auto it = tree.begin();
      std::advance(it, long(make.rng() % tree.size()));
      m.erase(it.id().id);
      tree.erase(it);
    }
    if (built) CHECK(agrees(tree, m, &why));
    const std::vector<Disk> c = small(std::max(1000, scaled(8000)));
    const std::size_t lanes_before = lanes_probe::laps();
    const std::vector<std::size_t> kept = lanes_probe::insert_disjoint(tree, c, 2);
    CHECK(lanes_probe::laps() > lanes_before);
    CHECK(kept == model_disjoint(m, c));
    CHECK_EQ(tree.memory().handles == 0, built == 0);
    CHECK(agrees(tree, m, &why));
    CHECK_EQ(why, std::string());
  }
}

/// Many threads look handles up at once on a tree whose table is not
/// built: one builds it, the others wait, and every answer is right
/// (ThreadSanitizer: no data race).
TEST(first_lookups_on_several_threads_at_once) {
  const unsigned seed = base_seed() + 9500;
  note(seed_note(seed, -1));
  Maker make(seed);
  for (int round = 0; round < 4; ++round) {
    Tree tree(4);
    Model m;
    const std::vector<Disk> v = make.scene<Disk>(scaled(20000), 3);
    tree.construct(v);
    m.construct(v);
    for (int k = 0; k < scaled(2000); ++k) {
      auto it = tree.begin();
      std::advance(it, long(make.rng() % tree.size()));
      m.erase(it.id().id);
      tree.erase(it);
    }
    CHECK_EQ(tree.memory().handles, std::size_t(0));
    std::atomic<int> wrong{0}, ready{0};
    std::vector<std::thread> pool;
    for (int t = 0; t < 4; ++t)
      pool.emplace_back([&, t] {
        ++ready; // (all start together, so that several meet the unbuilt table)
        while (ready.load() < 4) std::this_thread::yield();
        std::uint32_t id = std::uint32_t(t) * 997u % m.count;
        for (std::uint32_t k = 0; k < m.count; ++k, id = (id + 1) % m.count) {
          const auto s = m.shapes.find(id);
          const Handle h = m.handle(id);
          const bool in = tree.contains(h);
          if (in != (s != m.shapes.end()) || (in && !(tree.get(h) == s->second))) ++wrong;
          if (in && t % 2 && tree.find(h).id() != h) ++wrong;
        }
      });
    for (std::thread &th : pool) th.join();
    CHECK_EQ(wrong.load(), 0);
    CHECK(tree.memory().handles >= tree.size() * 8);
    CHECK(tree.validate());
  }
}

/// The report's parts add up and follow the tree's growth.
TEST(memory_report_parts) {
  Tree tree(4);
  Tree::memory_use e = tree.memory();
  CHECK_EQ(e.total(), std::size_t(0));
  Maker make(base_seed() + 9600);
  const std::vector<Disk> v = make.scene<Disk>(scaled(5000), 3);
  tree.construct(v);
  const Tree::memory_use m = tree.memory();
  CHECK_EQ(m.shapes, tree.size() * sizeof(Disk));
  CHECK_EQ(m.shape_ids, tree.size() * 4);
  CHECK(m.nodes >= tree.node_count() * 64);
  CHECK(m.build_transient >= tree.size() * sizeof(Disk));
  CHECK_EQ(m.handles, std::size_t(0));
  CHECK_EQ(m.total(), m.nodes + m.shapes + m.shape_ids + m.leaf_slack + m.pool_index + m.handles + m.free_ids + m.scratch);
  (void)tree.contains(Handle{0});
  CHECK(tree.memory().handles >= tree.size() * 8);
}

} // namespace

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
