// tests/test_asserts.cpp — BVH_ASSERT: each misuse of the API that a debug
// build catches, one per run, so that tests/run.sh can check that each
// aborts with its message (and that a build with -DNDEBUG compiles the
// checks away, and that a user's own BVH_ASSERT replaces the default).
//
//   build/test_asserts CASE     CASE: one of the names in `cases` below, or
//                               `valid` (correct use only: exits 0), or
//                               `handler` (with -DBVH_TEST_THROWING_ASSERT), or
//                               `stale` (with -DNDEBUG: a stale handle's
//                               defined outcome in each call; exits 0)
#ifdef BVH_TEST_THROWING_ASSERT
#include <stdexcept>
// A user's handler: misuse throws instead of aborting.
#define BVH_ASSERT(cond, message)                                                                                     \
  ((cond) ? (void)0 : throw std::logic_error(message))
#endif

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

namespace {

std::vector<Disk> some_disks() {
  std::vector<Disk> v;
  for (int i = 0; i < 20; ++i) v.emplace_back(Point(10.0 * i, 5.0 * (i % 3)), 2.0, Color(0, 0, 0));
  return v;
}

struct Case {
  const char *name;
  void (*misuse)();
};

const Case cases[] = {
    {"deref_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       std::printf("%g\n", (*t.end()).getRadius());
     }},
    {"arrow_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       std::printf("%g\n", t.end()->getRadius());
     }},
    {"deref_singular", [] {
       CourseBVH<Disk>::iterator it;
       std::printf("%g\n", it->getRadius());
     }},
    {"increment_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       CourseBVH<Disk>::iterator it = t.end();
       ++it;
     }},
    {"decrement_begin", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       CourseBVH<Disk>::iterator it = t.begin();
       --it;
     }},
    {"decrement_end_of_empty", [] {
       CourseBVH<Disk> t;
       CourseBVH<Disk>::iterator it = t.end();
       it--;
     }},
    {"erase_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       t.erase(t.end());
     }},
    {"erase_other_trees_iterator", [] {
       CourseBVH<Disk> a, b;
       a.construct(some_disks());
       b.construct(some_disks());
       a.erase(b.begin());
     }},
    {"erase_invalidated_iterator", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       CourseBVH<Disk>::iterator last = --t.end();
       t.clear();
       t.insert(some_disks()[0]);
       t.erase(last);
     }},
    {"id_of_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       std::printf("%u\n", unsigned(t.end().id().id));
     }},
    {"get_erased_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       std::printf("%g\n", t.get(h).getRadius());
     }},
    {"find_erased_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       std::printf("%d\n", int(t.find(h) == t.end()));
     }},
    {"erase_erased_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.erase(h);
     }},
    {"update_erased_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.update(h, some_disks()[2]);
     }},
    // A stale handle whose id a later insert() reused: it names no shape,
    // although its id does.
    {"get_stale_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.insert(some_disks()[2]);
       std::printf("%g\n", t.get(h).getRadius());
     }},
    {"find_stale_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.insert(some_disks()[2]);
       std::printf("%d\n", int(t.find(h) == t.end()));
     }},
    {"erase_stale_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.insert(some_disks()[2]);
       t.erase(h);
     }},
    {"update_stale_handle", [] {
       CourseBVH<Disk> t;
       const CourseBVH<Disk>::handle h = t.insert(some_disks()[0]);
       t.insert(some_disks()[1]);
       t.erase(h);
       t.insert(some_disks()[2]);
       t.update(h, some_disks()[3]);
     }},
    {"get_handle_from_before_emptying", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       const CourseBVH<Disk>::handle h = t.constructed(0);
       t.clear();
       t.construct(some_disks()); // id 0 again, of a newer generation
       std::printf("%g\n", t.get(h).getRadius());
     }},
    {"deref_overlap_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       const Disk probe = some_disks()[0];
       std::printf("%g\n", (*t.overlapping(probe).end()).getRadius());
     }},
    {"increment_overlap_end", [] {
       CourseBVH<Disk> t;
       t.construct(some_disks());
       const Disk probe = some_disks()[0];
       auto it = t.overlapping(probe).end();
       ++it;
     }},
};

} // namespace

int main(int argc, char **argv) {
  const std::string which = argc > 1 ? argv[1] : "";
  if (which == "valid") {
    // Every operation near the edges, used correctly: no assertion fires.
    CourseBVH<Disk> t;
    if (t.begin() != t.end()) return 1;
    t.construct(some_disks());
    CourseBVH<Disk>::iterator it = t.end();
    --it;
    it = t.erase(it);
    if (it != t.end()) return 1;
    std::size_t n = 0;
    for (it = t.begin(); it != t.end();) it = t.erase(it), ++n;
    return n == 19 && t.empty() ? 0 : 1;
  }
#ifdef NDEBUG
  if (which == "stale") {
    // With the checks off, a stale handle (its id reused by a later insert)
    // or one never given changes nothing, and each call says so.
    CourseBVH<Disk> t;
    const std::vector<Disk> d = some_disks();
    const CourseBVH<Disk>::handle old = t.insert(d[0]);
    t.insert(d[1]);
    t.erase(old);
    const CourseBVH<Disk>::handle now = t.insert(d[2]);
    int wrong = 0;
    const auto expect = [&](bool ok, const char *what) {
      if (!ok) {
        std::printf("stale: %s\n", what);
        ++wrong;
      }
    };
    expect(now.id == old.id && now != old, "the id is reused, with another generation");
    for (const CourseBVH<Disk>::handle h : {old, CourseBVH<Disk>::handle{now.id, now.generation + 1}, CourseBVH<Disk>::handle{99}}) {
      expect(!t.contains(h), "contains() is false");
      expect(!t.erase(h), "erase() returns false");
      expect(!t.update(h, d[3]), "update() returns false");
      expect(t.find(h) == t.end(), "find() returns end()");
      bool threw = false;
      try {
        (void)t.get(h);
      } catch (const std::out_of_range &) {
        threw = true;
      }
      expect(threw, "get() throws std::out_of_range");
      expect(t.size() == 2 && t.contains(now) && t.get(now) == d[2], "the shape of the reused id is untouched");
      expect(t.validate(), "validate()");
    }
    return wrong == 0 ? 0 : 1;
  }
#endif
#ifdef BVH_TEST_THROWING_ASSERT
  if (which == "handler") {
    int caught = 0;
    for (const Case &c : cases) {
      try {
        c.misuse();
      } catch (const std::logic_error &e) {
        ++caught;
        std::printf("%s: %s\n", c.name, e.what());
      }
    }
    const int total = int(sizeof cases / sizeof cases[0]);
    std::printf("caught %d of %d\n", caught, total);
    return caught == total ? 0 : 1;
  }
#endif
  for (const Case &c : cases)
    if (which == c.name) {
      c.misuse();
      std::printf("%s: no assertion fired\n", c.name);
      return 0;
    }
  if (which == "list") {
    for (const Case &c : cases) std::printf("%s\n", c.name);
    return 0;
  }
  std::fprintf(stderr, "usage: test_asserts list|valid|handler|CASE\n");
  return 2;
}
