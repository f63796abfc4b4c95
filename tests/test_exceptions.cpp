// tests/test_exceptions.cpp — issue 21: exceptions never leave a broken
// tree. SQLite-style fault injection: every mutating operation runs with
// the k-th copy (or assignment) of a shape throwing and, separately, the
// k-th allocation throwing (a test-only replacement of the global operator
// new, armed only while the operation runs), for k = 0, 1, 2, ... until the
// operation completes without meeting the fault. After every throw: the
// tree validates, size() is right, the shapes are those before (strong
// guarantee: the same multiset in the same iteration order) or as
// documented (basic), and every live handle still names its shape. Leaks
// show under ASan and valgrind, which run this same binary. Queries get a
// user intersect() that throws: they are const, so nothing may change.
//
// Two shape types: TDisk, whose copy constructor and assignment throw and
// which has no move (its moves are copies, so they throw too), and MDisk,
// a "polygon": its copy allocates (a std::vector) and may throw, its move
// is noexcept. BVH_TEST_SCALE shrinks the runs; the last case prints the
// number of injection points each operation was tested at.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <map>
#include <new>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

// make test builds this suite with g++ under -std=c++20 (the unit suites'
// C++20 build is the sanitizer build's, by clang++ and libc++ when they are
// installed): the iterator's C++20 concept, with libstdc++.
#if __cplusplus >= 202002L
static_assert(std::bidirectional_iterator<CourseBVH<Disk>::iterator>);
static_assert(std::bidirectional_iterator<BVH<Shape, bvh::shape_traits<Shape>, 8>::iterator>);
#endif
#include "check.h"
#include "scenes.h"

// ---------------------------------------------------------------------------
// The faults. Both countdowns are off (-1) outside an operation.
namespace fault {
long alloc_countdown = -1; // the allocation that throws: 0 = the next one
long copy_countdown = -1;  // the copy or assignment of a shape that throws
long intersect_countdown = -1;
bool alloc_always = false; // every allocation throws (the lazy handle table's case)
bool fired = false;

struct Injected : std::exception {
  const char *what() const noexcept override { return "injected copy failure"; }
};
struct InjectedIntersect : std::exception {
  const char *what() const noexcept override { return "injected intersect failure"; }
};

/// The test's own bookkeeping inside an operation: no fault while it lives.
struct Pause {
  long alloc = alloc_countdown, copy = copy_countdown;
  Pause() { alloc_countdown = copy_countdown = -1; }
  ~Pause() {
    alloc_countdown = alloc;
    copy_countdown = copy;
  }
};

inline void on_copy() {
  if (copy_countdown >= 0 && copy_countdown-- == 0) {
    fired = true;
    throw Injected();
  }
}
} // namespace fault

// (g++ sees free() on operator new's pointer once both are inlined: they are this pair)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void *operator new(std::size_t n) {
  if (fault::alloc_always || (fault::alloc_countdown >= 0 && fault::alloc_countdown-- == 0)) {
    fault::fired = true;
    throw std::bad_alloc();
  }
  if (void *p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void *operator new[](std::size_t n) { return ::operator new(n); }
void operator delete(void *p) noexcept { std::free(p); }
void operator delete[](void *p) noexcept { std::free(p); }
void operator delete(void *p, std::size_t) noexcept { std::free(p); }
void operator delete[](void *p, std::size_t) noexcept { std::free(p); }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace ft {

/// A disk whose copy constructor and copy assignment throw on the fault's
/// countdown; no move of its own, so moving copies (and may throw).
class TDisk : public Disk {
public:
  using Disk::Disk;
  TDisk(const TDisk &o) : Disk(o) { fault::on_copy(); }
  TDisk &operator=(const TDisk &o) {
    fault::on_copy();
    Disk::operator=(o);
    return *this;
  }
  ~TDisk() = default;
};

/// A disk with a heap payload, like a polygon's points: its copy allocates
/// and may throw (the countdown, or operator new's), its move is noexcept.
class MDisk : public Disk {
public:
  MDisk(const Point &c = Point(), double r = 0) : Disk(c, r), payload_(3, 7) {}
  MDisk(const MDisk &o) : Disk(o), payload_(o.payload_) { fault::on_copy(); }
  MDisk(MDisk &&) noexcept = default;
  MDisk &operator=(const MDisk &o) {
    fault::on_copy();
    MDisk copy(o);
    return *this = std::move(copy);
  }
  MDisk &operator=(MDisk &&) noexcept = default;
  ~MDisk() = default;

private:
  std::vector<int> payload_;
};

template <class S> bool intersect_counted(const S &a, const S &b) {
  if (fault::intersect_countdown >= 0 && fault::intersect_countdown-- == 0) {
    fault::fired = true;
    throw fault::InjectedIntersect();
  }
  return intersect(static_cast<const Disk &>(a), static_cast<const Disk &>(b));
}
bool intersect(const TDisk &a, const TDisk &b) { return intersect_counted(a, b); }
bool intersect(const MDisk &a, const MDisk &b) { return intersect_counted(a, b); }

// distance() and ray_hit(), the nearest searches' and the ray's geometry,
// on the same countdown.
inline void geometry_counted() {
  if (fault::intersect_countdown >= 0 && fault::intersect_countdown-- == 0) {
    fault::fired = true;
    throw fault::InjectedIntersect();
  }
}
double distance(const Point &p, const TDisk &d) {
  geometry_counted();
  return ::bvh::distance(p, static_cast<const Disk &>(d));
}
double distance(const Point &p, const MDisk &d) {
  geometry_counted();
  return ::bvh::distance(p, static_cast<const Disk &>(d));
}
double ray_hit(const Point &origin, const Point &dir, const TDisk &d) {
  geometry_counted();
  return ::bvh::ray_hit(origin, dir, static_cast<const Disk &>(d));
}
double ray_hit(const Point &origin, const Point &dir, const MDisk &d) {
  geometry_counted();
  return ::bvh::ray_hit(origin, dir, static_cast<const Disk &>(d));
}

} // namespace ft

namespace {

using ft::MDisk;
using ft::TDisk;

/// A disk type D whose trees are of width 8 (Tree<T>): the same faults on
/// the wide tree's own paths (its leaf splits, least-enlargement descent,
/// merges on erase).
template <class D> class Wide : public D {
public:
  using D::D;
  Wide() = default;
};
template <class T> struct width_of { static constexpr int value = bvh::detail::kCourseWidth; };
template <class D> struct width_of<Wide<D>> { static constexpr int value = 8; };
/// The tree a case runs on: the course's width 3, or 8 for Wide<D>.
template <class T> using Tree = BVH<T, bvh::shape_traits<T>, width_of<T>::value>;

template <class T> const char *type_name();
template <> const char *type_name<TDisk>() { return "TDisk"; }
template <> const char *type_name<MDisk>() { return "MDisk"; }
template <> const char *type_name<Wide<TDisk>>() { return "TDisk width 8"; }

using Key = std::tuple<double, double, double>;
template <class T> Key key(const T &s) { return Key{s.getCenter().x, s.getCenter().y, s.getRadius()}; }

/// What a test compares: the shapes in iteration order and the live
/// handles with their shapes.
template <class T> struct State {
  std::vector<Key> order;
  std::vector<std::pair<typename Tree<T>::handle, Key>> handles;
  std::vector<Key> sorted() const {
    std::vector<Key> v = order;
    std::sort(v.begin(), v.end());
    return v;
  }
};

/// A tree and the handles of its shapes (the test's own record).
template <class T> struct Subject {
  Tree<T> tree;
  std::vector<typename Tree<T>::handle> live;
  State<T> state() const {
    State<T> s;
    for (const T &x : tree) s.order.push_back(key(x));
    for (auto h : live) s.handles.push_back({h, key(tree.get(h))});
    return s;
  }
};

// Injection points per operation, reported by the last case.
std::map<std::string, long> &points() {
  static std::map<std::string, long> m;
  return m;
}

enum class Fault { copy, alloc };
enum class Guarantee { strong, basic };

/// Arms the fault: the k-th copy or allocation from now on throws.
void arm(Fault f, long k) {
  fault::fired = false;
  (f == Fault::copy ? fault::copy_countdown : fault::alloc_countdown) = k;
}
/// Disarms both; true when the fault was met.
bool disarm() {
  fault::copy_countdown = -1;
  fault::alloc_countdown = -1;
  fault::intersect_countdown = -1;
  return fault::fired;
}

/// The checks after a throw or a success.
template <class T> void check_valid(const Subject<T> &s, const std::string &where) {
  std::string why;
  const bool ok = s.tree.validate(&why);
  CHECK(ok);
  if (!ok) std::cout << "  " << where << ": " << why << std::endl;
  std::size_t n = 0;
  for (auto it = s.tree.begin(); it != s.tree.end(); ++it) ++n;
  CHECK_EQ(n, s.tree.size());
  for (auto h : s.live) {
    CHECK(s.tree.contains(h));
    if (!s.tree.contains(h)) return;
  }
}

/// Runs `op` on copies of `subject` with the k-th fault of kind `f`, k = 0,
/// 1, ... until op completes without meeting it. After a throw, strong:
/// the state is the one before; basic: `after_throw(before, now)` checks
/// it. After completion (also when a fault was met and absorbed, as a
/// failed rebalance is): `after_success(before, now)`. Returns k.
template <class T, class Op, class OnThrow, class OnSuccess>
long inject(const std::string &name, const Subject<T> &subject, Fault f, Guarantee g, Op op, OnThrow after_throw,
            OnSuccess after_success) {
  const State<T> before = subject.state();
  const long limit = 200000;
  long k = 0;
  for (;; ++k) {
    Subject<T> s = subject; // disarmed: only the operation counts
    bool threw = false;
    arm(f, k);
    try {
      op(s);
    } catch (const fault::Injected &) {
      threw = true;
    } catch (const std::bad_alloc &) {
      threw = true;
    }
    const bool met = disarm();
    CHECK(!threw || met);
    const std::string where = name + (f == Fault::copy ? " copy #" : " alloc #") + std::to_string(k);
    note(where);
    check_valid(s, where);
    if (threw) {
      if (g == Guarantee::strong) {
        const State<T> now = s.state();
        CHECK(now.order == before.order);
        CHECK(now.handles == before.handles);
        CHECK_EQ(s.tree.size(), before.order.size());
      } else {
        after_throw(before, s);
      }
    } else {
      after_success(before, s);
    }
    if (!met || k >= limit) break;
  }
  CHECK(k < limit);
  points()[std::string(type_name<T>()) + " " + name + (f == Fault::copy ? " / copy" : " / alloc")] += k;
  return k;
}
template <class T, class Op, class OnSuccess>
long inject_strong(const std::string &name, const Subject<T> &subject, Fault f, Op op, OnSuccess after_success) {
  return inject(name, subject, f, Guarantee::strong, op, [](const State<T> &, const Subject<T> &) {}, after_success);
}
/// Both faults.
template <class T, class Op, class OnSuccess>
void inject_both(const std::string &name, const Subject<T> &subject, Op op, OnSuccess after_success) {
  inject_strong(name, subject, Fault::copy, op, after_success);
  inject_strong(name, subject, Fault::alloc, op, after_success);
}

template <class T> T random_disk(std::mt19937 &rng, double spread = 1000) {
  std::uniform_real_distribution<double> c(0, spread), r(1, 12);
  return T(Point(c(rng), c(rng)), r(rng));
}

/// A tree of n random shapes, built by inserts (every shape's handle kept).
template <class T>
Subject<T> make_subject(std::mt19937 &rng, int n, int split, int depth, double margin, bool sah, bool sorted = false) {
  Subject<T> s{Tree<T>(split, depth), {}};
  if (sah) s.tree.set_build_rule(Tree<T>::BuildRule::sah);
  if (margin > 0) s.tree.set_margin(margin);
  std::vector<T> v;
  for (int i = 0; i < n; ++i) v.push_back(random_disk<T>(rng));
  if (sorted) std::sort(v.begin(), v.end(), [](const T &a, const T &b) { return a.getCenter().x < b.getCenter().x; });
  for (const T &x : v) s.live.push_back(s.tree.insert(x));
  return s;
}

/// The configurations every operation runs on: split thresholds, depth
/// limits (unlimited and small), margins, both build rules.
struct Config {
  int split, depth;
  double margin;
  bool sah;
};
std::vector<Config> configs() {
  return {{4, 0, 0, false}, {1, 0, 0, false}, {3, 3, 0, false}, {2, 0, 5, false}, {4, 0, 0, true}, {6, 2, 3, true}};
}

std::string config_name(const Config &c) {
  return "split " + std::to_string(c.split) + " depth " + std::to_string(c.depth) + " margin " +
         std::to_string(c.margin) + (c.sah ? " sah" : " course");
}

int tree_size() { return std::max(40, int(120 * scale())); }
int trials() { return std::max(2, scaled(8)); }

// ---------------------------------------------------------------------------
// insert

template <class T> void insert_case() {
  // Sorted inserts: trials() of them, and on until some insert met a fault
  // in a rebalance (a scapegoat rebuild; a wide tree's 8 children take more
  // inserts to unbalance).
  const int kSortedMax = 400;
  std::mt19937 rng(base_seed());
  long splits = 0, absorbed = 0, empty = 0;
  for (const Config &c : configs()) {
    for (int sorted = 0; sorted < 2; ++sorted) {
      note(config_name(c));
      Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah, sorted == 1);
      for (int t = 0, steps = trials();
           t < steps || (sorted && absorbed == 0 && t < kSortedMax); ++t) {
        // Sorted subjects take shapes past the right end: the lopsided
        // growth that triggers scapegoat rebuilds. Past the first steps,
        // at one height (about 500): at random heights they spread over the
        // right subtrees, and a wide tree took from 60 to over 400 inserts
        // to tip, how many depending on the standard library's random numbers.
        T shape = random_disk<T>(rng);
        const double y = shape.getCenter().y;
        if (sorted) shape = T(Point(1000 + 3.0 * t, t < steps ? y : 500 + 0.01 * y), shape.getRadius());
        Subject<T> probe = base;
        const std::size_t nodes = probe.tree.node_count();
        probe.tree.insert(shape);
        if (probe.tree.node_count() > nodes) ++splits;
        auto op = [&](Subject<T> &s) {
          const auto h = s.tree.insert(shape);
          fault::Pause bookkeeping;
          s.live.push_back(h);
        };
        auto ok = [&](const State<T> &before, const Subject<T> &s) {
          std::vector<Key> want = before.order;
          want.push_back(key(shape));
          std::sort(want.begin(), want.end());
          CHECK(s.state().sorted() == want);
          CHECK(key(s.tree.get(s.live.back())) == key(shape));
        };
        for (Fault f : {Fault::copy, Fault::alloc}) {
          // A fault met but absorbed: the insert succeeded, its rebalance
          // did not (and left the subtree as it was).
          inject_strong("insert", base, f, op, [&](const State<T> &before, const Subject<T> &s) {
            if (fault::fired) ++absorbed;
            ok(before, s);
          });
        }
        base.live.push_back(base.tree.insert(shape));
      }
    }
    // Into an empty tree.
    Subject<T> none{Tree<T>(c.split, c.depth), {}};
    if (c.margin > 0) none.tree.set_margin(c.margin);
    const T shape = random_disk<T>(rng);
    inject_both("insert", none,
                [&](Subject<T> &s) {
                  const auto h = s.tree.insert(shape);
                  fault::Pause bookkeeping;
                  s.live.push_back(h);
                },
                [&](const State<T> &, const Subject<T> &s) {
                  CHECK_EQ(s.tree.size(), 1u);
                  ++empty;
                });
  }
  // The scenes must have reached the interesting paths.
  CHECK(splits > 0);
  CHECK(absorbed > 0);
  CHECK(empty > 0);
}
TEST(insert_is_strong_TDisk) { insert_case<TDisk>(); }
TEST(insert_is_strong_MDisk) { insert_case<MDisk>(); }
TEST(insert_is_strong_TDisk_width_8) { insert_case<Wide<TDisk>>(); }

// ---------------------------------------------------------------------------
// erase(handle), erase(iterator), erase(value)

template <class T> void erase_case() {
  std::mt19937 rng(base_seed() + 1);
  long mends = 0;
  for (const Config &c : configs()) {
    note(config_name(c));
    Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    for (int t = 0; t < 2 * trials() && base.tree.size() > 1; ++t) {
      const std::size_t victim = rng() % base.live.size();
      const auto h = base.live[victim];
      const Key gone = key(base.tree.get(h));
      {
        Subject<T> probe = base;
        const std::size_t nodes = probe.tree.node_count();
        probe.tree.erase(h);
        if (probe.tree.node_count() < nodes) ++mends;
      }
      // (erase(handle) rebuilds by the build rule, which keeps no order:
      // the shapes left, as a multiset; erase(iterator) below keeps it)
      auto expect_gone = [&](const State<T> &before, const Subject<T> &s) {
        std::vector<Key> want = before.sorted();
        want.erase(std::find(want.begin(), want.end(), gone));
        CHECK(s.state().sorted() == want);
      };
      inject_both("erase(handle)", base,
                  [&](Subject<T> &s) {
                    s.tree.erase(h);
                    s.live.erase(s.live.begin() + long(victim));
                  },
                  expect_gone);
      const std::size_t rank = rng() % base.tree.size();
      Key at_rank;
      {
        auto it = base.tree.begin();
        std::advance(it, long(rank));
        at_rank = key(*it);
      }
      inject_both("erase(iterator)", base,
                  [&](Subject<T> &s) {
                    auto it = s.tree.begin();
                    std::advance(it, long(rank));
                    const auto id = it.id();
                    auto next = s.tree.erase(it);
                    s.live.erase(std::find(s.live.begin(), s.live.end(), id));
                    std::size_t r = 0;
                    for (auto i = s.tree.begin(); i != next; ++i) ++r;
                    CHECK_EQ(r, rank);
                  },
                  [&](const State<T> &before, const Subject<T> &s) {
                    std::vector<Key> want = before.order;
                    want.erase(want.begin() + long(rank));
                    CHECK(s.state().order == want);
                    (void)at_rank;
                  });
      base.tree.erase(h);
      base.live.erase(base.live.begin() + long(victim));
    }
  }
  CHECK(mends > 0);
}
TEST(erase_is_strong_TDisk) { erase_case<TDisk>(); }
TEST(erase_is_strong_MDisk) { erase_case<MDisk>(); }
TEST(erase_is_strong_TDisk_width_8) { erase_case<Wide<TDisk>>(); }

/// erase(value) is batched: each erase is strong, so after a throw some of
/// the equal shapes are gone, the others stay, and nothing else changed.
template <class T> void erase_value_case() {
  std::mt19937 rng(base_seed() + 2);
  for (const Config &c : configs()) {
    note(config_name(c));
    Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    const T dup = base.tree.get(base.live[0]);
    for (int i = 0; i < 4; ++i) base.live.push_back(base.tree.insert(dup));
    const Key k = key(dup);
    auto forget = [&](Subject<T> &s) { // the test's record: dup's handles are no longer known
      s.live.erase(std::remove_if(s.live.begin(), s.live.end(),
                                  [&](typename Tree<T>::handle h) { return !s.tree.contains(h) || key(s.tree.get(h)) == k; }),
                   s.live.end());
    };
    Subject<T> subject = base;
    forget(subject); // (handles of dup may go)
    for (Fault f : {Fault::copy, Fault::alloc}) {
      inject("erase(value)", subject, f, Guarantee::basic,
             [&](Subject<T> &s) {
               try {
                 CHECK_EQ(s.tree.erase(dup), 5u);
               } catch (...) {
                 forget(s);
                 throw;
               }
             },
             [&](const State<T> &before, const Subject<T> &s) {
               std::vector<Key> rest, now;
               for (const Key &x : before.order)
                 if (x != k) rest.push_back(x);
               for (const Key &x : s.state().order)
                 if (x != k) now.push_back(x);
               // the others, all there (erase(value)'s rebuilds keep no order)
               std::sort(rest.begin(), rest.end());
               std::sort(now.begin(), now.end());
               CHECK(now == rest);
               const std::size_t left = s.tree.size() - now.size();
               CHECK(left >= 1 && left <= 5);
             },
             [&](const State<T> &before, const Subject<T> &s) {
               CHECK_EQ(s.tree.size(), before.order.size() - 5);
             });
    }
  }
}
TEST(erase_value_is_basic_TDisk) { erase_value_case<TDisk>(); }
TEST(erase_value_is_basic_MDisk) { erase_value_case<MDisk>(); }

// ---------------------------------------------------------------------------
// update

template <class T> void update_case() {
  std::mt19937 rng(base_seed() + 3);
  long outside = 0, inside = 0;
  for (const Config &c : configs()) {
    note(config_name(c));
    Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    for (int t = 0; t < 2 * trials(); ++t) {
      const std::size_t victim = rng() % base.live.size();
      const auto h = base.live[victim];
      const T old = base.tree.get(h);
      // Small moves (inside the leaf's box, with a margin) and far ones.
      const double step = t % 2 ? 0.5 : 300;
      const T moved(Point(old.getCenter().x + step, old.getCenter().y), old.getRadius());
      {
        Subject<T> probe = base;
        State<T> want = probe.state();
        *std::find(want.order.begin(), want.order.end(), key(old)) = key(moved);
        probe.tree.update(h, moved);
        // (in place, the iteration order stays, with moved for old)
        if (probe.state().order == want.order) ++inside; else ++outside;
      }
      inject_both("update", base, [&](Subject<T> &s) { s.tree.update(h, moved); },
                  [&](const State<T> &before, const Subject<T> &s) {
                    std::vector<Key> want = before.order;
                    *std::find(want.begin(), want.end(), key(old)) = key(moved);
                    std::sort(want.begin(), want.end());
                    CHECK(s.state().sorted() == want);
                    CHECK(key(s.tree.get(h)) == key(moved));
                  });
      base.tree.update(h, moved);
    }
  }
  // The last shape of a tree.
  Subject<T> one{Tree<T>(), {}};
  one.live.push_back(one.tree.insert(T(Point(1, 1), 1)));
  const T far(Point(500, 500), 2);
  inject_both("update", one, [&](Subject<T> &s) { s.tree.update(s.live[0], far); },
              [&](const State<T> &, const Subject<T> &s) { CHECK(key(s.tree.get(s.live[0])) == key(far)); });
  CHECK(inside > 0);
  CHECK(outside > 0);
}
TEST(update_is_strong_TDisk) { update_case<TDisk>(); }
TEST(update_is_strong_MDisk) { update_case<MDisk>(); }
TEST(update_is_strong_TDisk_width_8) { update_case<Wide<TDisk>>(); }

// ---------------------------------------------------------------------------
// set_margin, copies, moves, clear

template <class T> void margin_and_copy_case() {
  std::mt19937 rng(base_seed() + 4);
  for (const Config &c : configs()) {
    note(config_name(c));
    const Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    inject_both("set_margin", base, [&](Subject<T> &s) { s.tree.set_margin(c.margin + 2); },
                [&](const State<T> &before, const Subject<T> &s) {
                  CHECK(s.state().order == before.order);
                  CHECK_EQ(s.tree.margin(), c.margin + 2);
                });
    // The copy constructor: the source is untouched, the copy (if made) equal.
    auto same = [&](const State<T> &before, const Subject<T> &s) { CHECK(s.state().order == before.order); };
    inject_both("copy constructor", base,
                [&](Subject<T> &s) {
                  Tree<T> copy(s.tree);
                  std::string why;
                  CHECK(copy.validate(&why));
                  CHECK_EQ(copy.size(), s.tree.size());
                },
                same);
    // Copy assignment over another tree: that tree is unchanged if it throws.
    const Subject<T> other = make_subject<T>(rng, tree_size() / 2, c.split + 1, 0, 0, !c.sah);
    inject_both("copy assignment", other, [&](Subject<T> &s) {
                  s.tree = base.tree;
                  fault::Pause bookkeeping;
                  s.live = base.live;
                },
                [&](const State<T> &, const Subject<T> &s) { CHECK(s.state().order == base.state().order); });
    // Moves, swap and clear allocate and copy nothing.
    static_assert(std::is_nothrow_move_constructible<Tree<T>>::value, "moves are noexcept");
    static_assert(std::is_nothrow_move_assignable<Tree<T>>::value, "moves are noexcept");
    static_assert(noexcept(std::declval<Tree<T> &>().clear()), "clear() is noexcept");
    static_assert(noexcept(std::declval<Tree<T> &>().swap(std::declval<Tree<T> &>())), "swap() is noexcept");
    for (Fault f : {Fault::copy, Fault::alloc}) {
      Subject<T> s = base, t = other;
      arm(f, 0);
      Tree<T> moved(std::move(s.tree));
      s.tree = std::move(t.tree);
      t.tree = std::move(moved);
      s.tree.swap(t.tree);
      moved.clear();
      t.tree.clear();
      CHECK(!disarm());
      CHECK(s.tree.validate() && t.tree.validate() && moved.validate());
      CHECK_EQ(s.tree.size(), base.tree.size());
      CHECK(t.tree.empty() && moved.empty());
      points()[std::string(type_name<T>()) + " move, swap, clear" + (f == Fault::copy ? " / copy" : " / alloc")] += 0;
    }
  }
}
TEST(margin_and_copies_TDisk) { margin_and_copy_case<TDisk>(); }
TEST(margin_and_copies_MDisk) { margin_and_copy_case<MDisk>(); }

// ---------------------------------------------------------------------------
// construct: basic (the tree is left empty, its parameters kept)

template <class T> void construct_case() {
  std::mt19937 rng(base_seed() + 5);
  for (const Config &c : configs()) {
    note(config_name(c));
    Subject<T> base = make_subject<T>(rng, tree_size() / 2, c.split, c.depth, c.margin, false);
    std::vector<T> elements;
    for (int i = 0; i < tree_size(); ++i) elements.push_back(random_disk<T>(rng));
    std::vector<Key> want;
    for (const T &x : elements) want.push_back(key(x));
    std::sort(want.begin(), want.end());
    for (Fault f : {Fault::copy, Fault::alloc}) {
      inject((c.sah ? "set_build_rule(sah), construct" : "construct"), base, f, Guarantee::basic,
             [&](Subject<T> &s) {
               s.live.clear(); // construct replaces every handle
               if (c.sah) s.tree.set_build_rule(Tree<T>::BuildRule::sah);
               s.tree.construct(elements);
               fault::Pause bookkeeping;
               for (std::size_t i = 0; i < elements.size(); ++i)
                 s.live.push_back(s.tree.constructed(i));
             },
             [&](const State<T> &, const Subject<T> &s) {
               CHECK(s.tree.empty());
               CHECK_EQ(s.tree.split_threshold(), c.split);
             },
             [&](const State<T> &, const Subject<T> &s) {
               CHECK(s.state().sorted() == want);
               for (std::size_t i = 0; i < elements.size(); ++i)
                 CHECK(key(s.tree.get(s.live[i])) == key(elements[i]));
             });
    }
  }
}
TEST(construct_is_basic_TDisk) { construct_case<TDisk>(); }
TEST(construct_is_basic_MDisk) { construct_case<MDisk>(); }
TEST(construct_is_basic_TDisk_width_8) { construct_case<Wide<TDisk>>(); }

// ---------------------------------------------------------------------------
// Queries with a user intersect(), distance() or ray_hit() that throws:
// nothing may change.

template <class T> void query_case() {
  std::mt19937 rng(base_seed() + 6);
  for (const Config &c : configs()) {
    note(config_name(c));
    Subject<T> s = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    for (int i = 0; i < 5; ++i) s.tree.insert(T(Point(500, 500), 30)); // overlaps for sure
    s.live.clear();
    const State<T> before = s.state();
    const T probe(Point(500, 500), 60);
    auto run = [&](const std::string &name, auto &&query) {
      long k = 0;
      for (;; ++k) {
        fault::fired = false;
        fault::intersect_countdown = k;
        bool threw = false;
        try {
          query();
        } catch (const fault::InjectedIntersect &) {
          threw = true;
        }
        const bool met = disarm();
        CHECK(threw == met);
        CHECK(s.tree.validate());
        CHECK(s.state().order == before.order);
        if (!met) break;
      }
      CHECK(k > 0);
      points()[std::string(type_name<T>()) + " " + name + " / geometry"] += k;
    };
    run("collision", [&] { (void)s.tree.collision(probe); });
    run("query(shape)", [&] { s.tree.query(probe, [](const T &) {}); });
    run("overlapping(shape)", [&] {
      for (const T &x : s.tree.overlapping(probe)) (void)x;
    });
    run("for_each_overlapping_pair", [&] { s.tree.for_each_overlapping_pair([](const T &, const T &) {}); });
    // The nearest searches, one answer and more answers (40) than their
    // inline room, and the ray.
    run("nearest", [&] { (void)s.tree.nearest(Point(480, 530)); });
    run("nearest(p, k)", [&] {
      std::vector<typename Tree<T>::neighbor> out;
      s.tree.nearest(Point(480, 530), 40, std::back_inserter(out));
    });
    run("first_hit", [&] { (void)s.tree.first_hit(Point(-10, 505), Point(1, 0)); });
  }
}
TEST(queries_with_throwing_geometry_TDisk) { query_case<TDisk>(); }
TEST(queries_with_throwing_geometry_MDisk) { query_case<MDisk>(); }

// ---------------------------------------------------------------------------
// The handle table, built on the first lookup (issue 19): with the k-th
// allocation failing, contains() and get() still answer (by a walk over
// the leaves) and the table stays unbuilt; erase(handle) on a tree without
// the table is strong for every k.

template <class T> void lazy_table_case() {
  std::mt19937 rng(base_seed() + 7);
  for (const Config &c : configs()) {
    note(config_name(c));
    const Subject<T> base = make_subject<T>(rng, tree_size(), c.split, c.depth, c.margin, c.sah);
    CHECK_EQ(base.tree.memory().handles, 0u); // (inserts only: no lookup yet)
    std::map<std::uint32_t, Key> named;       // by iteration, which needs no table
    std::vector<Key> order;
    for (auto it = base.tree.begin(); it != base.tree.end(); ++it) {
      named[it.id().id] = key(*it);
      order.push_back(key(*it));
    }
    {
      Subject<T> s = base;
      fault::alloc_always = true;
      bool right = true;
      for (auto h : s.live)
        right = right && s.tree.contains(h) && key(s.tree.get(h)) == named.at(h.id) && s.tree.find(h).id() == h;
      const bool unbuilt = s.tree.memory().handles == 0;
      fault::alloc_always = false;
      note(config_name(c) + " lookups without memory");
      CHECK(right);
      CHECK(unbuilt);
      CHECK(s.tree.validate());
      CHECK(s.tree.contains(s.live[0])); // memory again: the table is built now
      CHECK(s.tree.memory().handles > 0);
      CHECK(s.tree.validate());
    }
    const auto h = base.live[rng() % base.live.size()];
    for (long k = 0;; ++k) {
      Subject<T> s = base;
      arm(Fault::alloc, k);
      bool threw = false;
      try {
        s.tree.erase(h);
      } catch (const std::bad_alloc &) {
        threw = true;
      }
      const bool met = disarm();
      note(config_name(c) + " erase(handle) without the table, alloc #" + std::to_string(k));
      CHECK(s.tree.validate());
      std::vector<Key> now;
      for (const T &x : s.tree) now.push_back(key(x));
      std::vector<Key> want = order;
      if (!threw) { // (erase(handle)'s rebuilds keep no order: the shapes left, as a multiset)
        want.erase(std::find(want.begin(), want.end(), named.at(h.id)));
        std::sort(want.begin(), want.end());
        std::sort(now.begin(), now.end());
      }
      CHECK(now == want); // (after a throw: unchanged, in order)
      for (auto g : s.live)
        if (threw || g != h) CHECK(s.tree.contains(g) && key(s.tree.get(g)) == named.at(g.id));
      if (!met) break;
      points()[std::string(type_name<T>()) + " erase(handle), no table / alloc"] += 1;
    }
  }
}
TEST(first_handle_lookup_without_memory_TDisk) { lazy_table_case<TDisk>(); }
TEST(first_handle_lookup_without_memory_MDisk) { lazy_table_case<MDisk>(); }

// The issue's table: injection points per operation (over every
// configuration and trial of the cases above).
// ---------------------------------------------------------------------------
// parallel_for, the threads of construct() and insert_disjoint(): starting
// a thread may fail for want of memory too (the pool's room, the thread's
// own state). The threads started and the caller then do its share, every
// index once, and no thread is left running past the call (one would end
// the program: std::terminate).

TEST(parallel_for_when_a_thread_cannot_start) {
  long absorbed = 0, k = 0;
  for (;; ++k) {
    std::vector<std::atomic<int>> calls(64);
    bool threw = false;
    arm(Fault::alloc, k);
    try {
      bvh::detail::parallel_for(calls.size(), 4, [&](std::size_t i) { ++calls[i]; });
    } catch (const std::bad_alloc &) {
      threw = true;
    }
    const bool met = disarm();
    note("parallel_for alloc #" + std::to_string(k));
    CHECK(!threw); // f never throws, and a start that fails is absorbed
    for (const auto &c : calls) CHECK_EQ(c.load(), 1);
    if (met) ++absorbed;
    if (!met || k >= 100) break;
  }
  CHECK(k < 100);
  CHECK(absorbed > 0);
  points()["parallel_for / alloc"] += k;
}

TEST(zz_report_injection_points) {
  std::printf("injection points (faults met, each followed by the checks):\n");
  for (const auto &p : points()) std::printf("  %-52s %8ld\n", p.first.c_str(), p.second);
  std::fflush(stdout);
}

} // namespace

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
