// tests/scenes.h — what the test programs share: the seed and scale they
// run with (BVH_SEED, BVH_TEST_SCALE), random scenes, and tree contents as
// comparable multisets.
#ifndef BVH_TESTS_SCENES_H
#define BVH_TESTS_SCENES_H

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

namespace {

unsigned base_seed() {
  const char *s = std::getenv("BVH_SEED");
  return s ? unsigned(std::strtoul(s, nullptr, 10)) : 12345u;
}

double scale() {
  const char *s = std::getenv("BVH_TEST_SCALE");
  const double v = s ? std::atof(s) : 1.0;
  return v > 0 ? v : 1.0;
}

int scaled(int n) { return std::max(1, int(n * scale())); }

// Random shapes. `grid` > 0 snaps every coordinate to multiples of it so
// that centres tie often: ties are where a sloppy build rule shows.
struct Maker {
  std::mt19937 rng;
  double grid;
  explicit Maker(unsigned seed, double grid_ = 0) : rng(seed), grid(grid_) {}
  double coord(double lo, double hi) {
    double v = std::uniform_real_distribution<double>(lo, hi)(rng);
    if (grid > 0) v = std::round(v / grid) * grid;
    return v;
  }
  Color color() { return Color(int(rng() % 256), int(rng() % 256), int(rng() % 256)); }
  Point near(const Point &c, double size) { return Point(c.x + coord(-size, size), c.y + coord(-size, size)); }
  void make(Disk &d, double size) { d = Disk(Point(coord(0, 1000), coord(0, 1000)), coord(0, size), color()); }
  void make(Triangle &t, double size) {
    const Point c(coord(0, 1000), coord(0, 1000));
    t = Triangle(near(c, size), near(c, size), near(c, size), color());
  }
  void make(Quad &q, double size) {
    // A convex quad: a jittered square around c, so it is always simple.
    const Point c(coord(0, 1000), coord(0, 1000));
    const double s = std::max(coord(1, size), 1.0);
    q = Quad(Point(c.x - s, c.y - s), Point(c.x + s, c.y - s + coord(0, s / 2)), Point(c.x + s, c.y + s),
             Point(c.x - s + coord(0, s / 2), c.y + s), color());
  }
  /// A mixed scene's shape: each of the three kinds a third of the time.
  void make(Shape &s, double size) {
    switch (rng() % 3) {
    case 0: {
      Disk d;
      make(d, size);
      s = d;
      break;
    }
    case 1: {
      Triangle t;
      make(t, size);
      s = t;
      break;
    }
    default: {
      Quad q;
      make(q, size);
      s = q;
    }
    }
  }
  template <class T> std::vector<T> scene(int n, double size) {
    std::vector<T> v(std::size_t(n > 0 ? n : 0));
    for (T &s : v) make(s, size);
    return v;
  }
};

/// The brute-force models' predicate: intersect() for one kind; for mixed
/// shapes, the pair's own predicate picked here by hand, so that the models
/// do not lean on intersect(Shape, Shape), which they are there to check.
template <class T> bool model_intersect(const T &a, const T &b) { return intersect(a, b); }
template <class A> bool model_intersect_with(const A &a, const Shape &b) {
  if (const Disk *d = b.disk()) return intersect(a, *d);
  if (const Triangle *t = b.triangle()) return intersect(a, *t);
  return intersect(a, *b.quad());
}
inline bool model_intersect(const Shape &a, const Shape &b) {
  if (const Disk *d = a.disk()) return model_intersect_with(*d, b);
  if (const Triangle *t = a.triangle()) return model_intersect_with(*t, b);
  return model_intersect_with(*a.quad(), b);
}

template <class T, class Tr, int W> std::vector<T> contents(const BVH<T, Tr, W> &tree) {
  return std::vector<T>(tree.begin(), tree.end());
}

inline int kind_of(const Disk &) { return 0; }
inline int kind_of(const Triangle &) { return 1; }
inline int kind_of(const Quad &) { return 2; }
inline int kind_of(const Shape &s) { return int(s.kind()); }

// Shapes compare by geometry and colour; a canonical order makes multisets
// comparable.
template <class T> std::string key_of(const T &s) {
  std::ostringstream o;
  o << std::setprecision(17) << kind_of(s) << s.getBox() << s.getCenter().x << "," << s.getCenter().y << "#"
    << s.getColor().getHexString();
  return o.str();
}

template <class T> bool same_multiset(std::vector<T> a, std::vector<T> b) {
  if (a.size() != b.size()) return false;
  auto by_key = [](const T &p, const T &q) { return key_of(p) < key_of(q); };
  std::sort(a.begin(), a.end(), by_key);
  std::sort(b.begin(), b.end(), by_key);
  return a == b;
}

} // namespace

#endif // BVH_TESTS_SCENES_H
