// tests/test_intersect.cpp — intersect.h against an independent, slow, exact
// reference: coordinates are scaled by a power of two to integers and every
// predicate is evaluated in integer arithmetic (__int128, or a 384-bit
// integer for full 53-bit doubles), with different formulas from the header's
// (parametric segment intersection, a vertical even-odd ray, a quadratic for
// disk-segment distance). Random pairs on small grids and built tangencies
// make touching, collinear and degenerate cases common.
//
// Environment: BVH_SEED (default 12345), BVH_TEST_SCALE (default 1, about
// 300k random pairs; 0.1 is for valgrind), COURSE_DATA (default
// ../shared/course; cases needing it pass with a "skipped:" notice if absent).
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "check.h"
#include <bvh/bvh.h>
#include <bvh/intersect.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

namespace {

__extension__ typedef __int128 i128;
__extension__ typedef unsigned __int128 u128;

// ---------------------------------------------------------------------------
// Environment.

unsigned long long base_seed() {
  const char *s = std::getenv("BVH_SEED");
  return s ? std::strtoull(s, nullptr, 10) : 12345ull;
}

double scale() {
  const char *s = std::getenv("BVH_TEST_SCALE");
  const double v = s ? std::atof(s) : 1.0;
  return v > 0 ? v : 1.0;
}

long scaled(long n) { return std::max(1L, long(double(n) * scale())); }

std::string course_dir() {
  const char *s = std::getenv("COURSE_DATA");
  return s ? s : "../shared/course";
}

/// The note of a randomized case: enough to rerun it.
std::string seed_note(const char *what);

// ---------------------------------------------------------------------------
// A fixed-width signed integer (two's complement, 6 x 64 bits): enough for
// degree-4 expressions in 62-bit inputs. Only what the reference needs.

struct Big {
  static constexpr int L = 6;
  std::uint64_t w[L];
  Big(long long x = 0) {
    w[0] = std::uint64_t(x);
    for (int i = 1; i < L; ++i) w[i] = x < 0 ? ~std::uint64_t(0) : 0;
  }
  friend Big operator+(const Big &a, const Big &b) {
    Big r;
    unsigned carry = 0;
    for (int i = 0; i < L; ++i) {
      const std::uint64_t s = a.w[i] + b.w[i];
      const unsigned c1 = s < a.w[i];
      r.w[i] = s + carry;
      carry = c1 | (r.w[i] < s);
    }
    return r;
  }
  friend Big operator-(const Big &a) {
    Big r;
    for (int i = 0; i < L; ++i) r.w[i] = ~a.w[i];
    return r + Big(1);
  }
  friend Big operator-(const Big &a, const Big &b) { return a + (-b); }
  friend Big operator*(const Big &a, const Big &b) {
    // Product mod 2^(64L): right for signed values whose product fits.
    Big r(0);
    for (int i = 0; i < L; ++i) {
      u128 carry = 0;
      for (int j = 0; i + j < L; ++j) {
        const u128 t = u128(a.w[i]) * b.w[j] + r.w[i + j] + carry;
        r.w[i + j] = std::uint64_t(t);
        carry = t >> 64;
      }
    }
    return r;
  }
};

int sgn(i128 x) { return (x > 0) - (x < 0); }
int sgn(const Big &x) {
  if (x.w[Big::L - 1] >> 63) return -1;
  for (int i = 0; i < Big::L; ++i)
    if (x.w[i]) return 1;
  return 0;
}
template <class Int> int cmp(const Int &a, const Int &b) { return sgn(a - b); }

// ---------------------------------------------------------------------------
// The reference, on integer points. Int is i128 or Big.

struct IP {
  long long x, y;
};
bool operator==(const IP &a, const IP &b) { return a.x == b.x && a.y == b.y; }

struct RShape {
  int n = 0; // 1: disk (p[0], r), 3 or 4: polygon p[0..n)
  IP p[4];
  long long r = 0;
};

template <class Int> Int icross(const IP &o, const IP &a, const IP &b) {
  return (Int(a.x) - Int(o.x)) * (Int(b.y) - Int(o.y)) - (Int(a.y) - Int(o.y)) * (Int(b.x) - Int(o.x));
}
template <class Int> Int idot(const IP &o, const IP &a, const IP &b) {
  return (Int(a.x) - Int(o.x)) * (Int(b.x) - Int(o.x)) + (Int(a.y) - Int(o.y)) * (Int(b.y) - Int(o.y));
}

/// x on the closed segment ab.
template <class Int> bool ref_on_segment(const IP &x, const IP &a, const IP &b) {
  if (a == b) return x == a;
  if (sgn(icross<Int>(a, b, x)) != 0) return false;
  const Int t = idot<Int>(a, b, x);
  return sgn(t) >= 0 && cmp(t, idot<Int>(a, b, b)) <= 0;
}

/// Closed segments p1p2 and q1q2 share a point: solve p1 + t r = q1 + u s.
template <class Int> bool ref_segments(const IP &p1, const IP &p2, const IP &q1, const IP &q2) {
  const IP o{0, 0};
  const IP r{p2.x - p1.x, p2.y - p1.y}, s{q2.x - q1.x, q2.y - q1.y}, w{q1.x - p1.x, q1.y - p1.y};
  Int den = icross<Int>(o, r, s);
  if (sgn(den) != 0) {
    Int tn = icross<Int>(o, w, s), un = icross<Int>(o, w, r);
    if (sgn(den) < 0) {
      den = -den;
      tn = -tn;
      un = -un;
    }
    return sgn(tn) >= 0 && cmp(tn, den) <= 0 && sgn(un) >= 0 && cmp(un, den) <= 0;
  }
  if (p1 == p2) return ref_on_segment<Int>(p1, q1, q2);
  if (q1 == q2) return ref_on_segment<Int>(q1, p1, p2);
  if (sgn(icross<Int>(o, w, r)) != 0) return false; // parallel, different lines
  // Collinear: overlap of the parameter intervals along r.
  const Int t0 = idot<Int>(p1, p2, q1), t1 = idot<Int>(p1, p2, q2), len = idot<Int>(p1, p2, p2);
  const Int lo = cmp(t0, t1) < 0 ? t0 : t1, hi = cmp(t0, t1) < 0 ? t1 : t0;
  return sgn(hi) >= 0 && cmp(lo, len) <= 0;
}

/// x in the closed polygon (boundary, or odd crossings of an upward ray).
template <class Int> bool ref_in_polygon(const IP &x, const RShape &s) {
  bool odd = false;
  for (int j = 0; j < s.n; ++j) {
    const IP &a = s.p[j], &b = s.p[(j + 1) % s.n];
    if (ref_on_segment<Int>(x, a, b)) return true;
    if ((a.x <= x.x) == (b.x <= x.x)) continue;
    // Height of the edge above x at x.x, times (b.x - a.x).
    const Int num = (Int(a.y) - Int(x.y)) * (Int(b.x) - Int(a.x)) + (Int(x.x) - Int(a.x)) * (Int(b.y) - Int(a.y));
    if (sgn(num) == (b.x > a.x ? 1 : -1)) odd = !odd;
  }
  return odd;
}

/// Some point a + t(b - a), t in [0, 1], within r of c: the minimum of the
/// quadratic f(t) = L t^2 - 2 D t + E over [0, 1] is <= 0.
template <class Int> bool ref_disk_segment(const IP &c, long long r, const IP &a, const IP &b) {
  const Int L = idot<Int>(a, b, b), D = idot<Int>(a, b, c);
  const Int E = idot<Int>(a, c, c) - Int(r) * Int(r);
  if (sgn(E) <= 0) return true;                              // f(0)
  if (sgn(L - Int(2) * D + E) <= 0) return true;             // f(1)
  if (sgn(D) <= 0 || cmp(D, L) >= 0) return false;           // minimum at an end
  return cmp(E * L, D * D) <= 0;                             // f(D / L) * L
}

template <class Int> bool ref_intersect(const RShape &a, const RShape &b) {
  if (a.n == 1 && b.n == 1) {
    const Int s = Int(a.r) + Int(b.r);
    return cmp(s * s, idot<Int>(a.p[0], b.p[0], b.p[0])) >= 0;
  }
  if (b.n == 1) return ref_intersect<Int>(b, a);
  if (a.n == 1) {
    if (ref_in_polygon<Int>(a.p[0], b)) return true;
    for (int j = 0; j < b.n; ++j)
      if (ref_disk_segment<Int>(a.p[0], a.r, b.p[j], b.p[(j + 1) % b.n])) return true;
    return false;
  }
  for (int i = 0; i < a.n; ++i)
    for (int j = 0; j < b.n; ++j)
      if (ref_segments<Int>(a.p[i], a.p[(i + 1) % a.n], b.p[j], b.p[(j + 1) % b.n])) return true;
  for (int i = 0; i < a.n; ++i)
    if (ref_in_polygon<Int>(a.p[i], b)) return true;
  for (int j = 0; j < b.n; ++j)
    if (ref_in_polygon<Int>(b.p[j], a)) return true;
  return false;
}

// ---------------------------------------------------------------------------
// From shapes to the reference: one power of two turns every double of the
// pair into an integer of at most `bits` bits, or the pair is not checkable.

void values(const Disk &d, std::vector<double> &v) {
  v.push_back(d.getCenter().x);
  v.push_back(d.getCenter().y);
  v.push_back(d.getRadius());
}
template <int N> void values(const Polygon<N> &p, std::vector<double> &v) {
  for (int i = 0; i < N; ++i) {
    v.push_back(p.getPoint(i).x);
    v.push_back(p.getPoint(i).y);
  }
}

bool integer_scale(const std::vector<double> &v, int bits, int &k) {
  for (k = 0; k <= 80; ++k) {
    bool ok = true;
    for (double x : v) {
      const double y = std::ldexp(x, k);
      if (std::floor(y) != y) {
        ok = false;
        break;
      }
    }
    if (!ok) continue;
    for (double x : v)
      if (std::fabs(std::ldexp(x, k)) >= std::ldexp(1.0, bits)) return false;
    return true;
  }
  return false;
}

long long to_int(double x, int k) { return (long long)std::ldexp(x, k); }

RShape to_ref(const Disk &d, int k) {
  RShape s;
  s.n = 1;
  s.p[0] = {to_int(d.getCenter().x, k), to_int(d.getCenter().y, k)};
  s.r = to_int(d.getRadius(), k);
  return s;
}
template <int N> RShape to_ref(const Polygon<N> &p, int k) {
  RShape s;
  s.n = N;
  for (int i = 0; i < N; ++i) s.p[i] = {to_int(p.getPoint(i).x, k), to_int(p.getPoint(i).y, k)};
  return s;
}

/// The reference answer: 1 or 0, or -1 when the values do not fit. Degree-4
/// disk formulas in i128 need inputs below 2^28; polygon ones below 2^60.
template <class A, class B> int reference(const A &a, const B &b, bool big) {
  std::vector<double> v;
  values(a, v);
  values(b, v);
  const bool disks = A::numPoints() == 1 || B::numPoints() == 1;
  int k;
  if (!integer_scale(v, big ? 62 : (disks ? 28 : 60), k)) return -1;
  const RShape ra = to_ref(a, k), rb = to_ref(b, k);
  return big ? ref_intersect<Big>(ra, rb) : ref_intersect<i128>(ra, rb);
}

/// The same for two shapes of a mixed scene: the reference of their kinds.
int reference(const Shape &a, const Shape &b, bool big) {
  return a.visit([&](const auto &x) { return b.visit([&](const auto &y) { return reference(x, y, big); }); });
}

// ---------------------------------------------------------------------------
// Same set, other vertex order: a rotation and maybe a reversal.

Triangle reorder(const Triangle &t, unsigned k) {
  Point p[3];
  for (int i = 0; i < 3; ++i) p[i] = t.getPoint(int((i + k) % 3));
  return (k & 4) ? Triangle(p[2], p[1], p[0]) : Triangle(p[0], p[1], p[2]);
}
Quad reorder(const Quad &q, unsigned k) {
  Point p[4];
  for (int i = 0; i < 4; ++i) p[i] = q.getPoint(int((i + k) % 4));
  return (k & 4) ? Quad(p[3], p[2], p[1], p[0]) : Quad(p[0], p[1], p[2], p[3]);
}
Disk reorder(const Disk &d, unsigned) { return d; }
Shape reorder(const Shape &s, unsigned k) {
  return s.visit([k](const auto &x) { return Shape(reorder(x, k)); });
}

/// Counts of a randomized run, for the log and for "the test saw both answers".
struct Tally {
  long pairs = 0, hits = 0, unchecked = 0;
};

/// Full-precision text of a shape, for failure messages.
std::string describe(const Point &p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "(%.17g, %.17g)", p.x, p.y);
  return buf;
}
std::string describe(const Disk &d) { return "disk " + describe(d.getCenter()) + " r=" + describe(Point(d.getRadius(), 0)); }
template <int N> std::string describe(const Polygon<N> &poly) {
  std::string s = N == 3 ? "triangle" : "quad";
  for (int i = 0; i < N; ++i) s += " " + describe(poly.getPoint(i));
  return s;
}
std::string describe(const Shape &s) {
  return s.visit([](const auto &x) { return describe(x); });
}

/// The context of the randomized case running (seed), extended with the
/// failing pair when there is one.
std::string &case_context() {
  static std::string s;
  return s;
}

std::string seed_note(const char *what) {
  case_context() = std::string(what) + " BVH_SEED=" + std::to_string(base_seed()) +
                   " BVH_TEST_SCALE=" + std::to_string(scale());
  return case_context();
}

/// Checks one pair: reference, both orders, reordered vertices.
template <class A, class B> void check_pair(const A &a, const B &b, bool big, unsigned salt, Tally &t) {
  const bool ab = intersect(a, b), ba = intersect(b, a);
  const bool reordered = intersect(reorder(a, salt), reorder(b, salt >> 3));
  const int ref = reference(a, b, big);
  if (ab != ba || reordered != ab || (ref >= 0 && ref != int(ab)))
    note(case_context() + " pair: " + describe(a) + " | " + describe(b) + " reorder " + std::to_string(salt));
  CHECK_EQ(ab, ba);
  CHECK_EQ(reordered, ab);
  if (ref < 0)
    ++t.unchecked;
  else
    CHECK_EQ(int(ab), ref);
  ++t.pairs;
  t.hits += ab;
}

// ---------------------------------------------------------------------------
// Random shapes on grids. Each pair picks a grid unit (1 or 1/8) and extent;
// each shape a centre and a size from "a point" to "the whole grid", so
// shared vertices, vertices on edges, collinear overlaps, nesting and
// degenerate shapes are all frequent. Constructions add exact tangencies.

struct Gen {
  std::mt19937_64 rng;
  double unit = 1;
  long extent = 8;

  explicit Gen(unsigned long long seed) : rng(seed) {}
  long pick(long lo, long hi) { return lo + long(rng() % std::uint64_t(hi - lo + 1)); }
  bool coin(int percent) { return long(rng() % 100) < percent; }

  void new_scene() {
    static const long extents[] = {2, 4, 8, 16, 64, 1L << 20};
    unit = coin(50) ? 1.0 : 0.125;
    extent = extents[pick(0, 5)];
  }
  long size() {
    switch (pick(0, 3)) {
    case 0: return 0;
    case 1: return pick(1, 3);
    case 2: return std::max(1L, extent / 4);
    default: return extent;
    }
  }
  // Draws happen in separate statements: argument evaluation order differs
  // between compilers, and a seed must mean the same shapes everywhere.
  Point point(long cx, long cy, long s) {
    const long x = cx + pick(-s, s), y = cy + pick(-s, s);
    return Point(x * unit, y * unit);
  }
  Point corner(long &cx, long &cy, long &s) {
    cx = pick(0, extent);
    cy = pick(0, extent);
    s = size();
    return Point(cx * unit, cy * unit);
  }

  Disk disk() {
    long cx, cy, s;
    const Point c = corner(cx, cy, s);
    return Disk(c, coin(15) ? 0.0 : pick(0, std::max(1L, s)) * unit);
  }
  Triangle triangle() {
    long cx, cy, s;
    corner(cx, cy, s);
    const Point a = point(cx, cy, s), b = point(cx, cy, s), c = point(cx, cy, s);
    return Triangle(a, b, c);
  }
  Quad quad() {
    long cx, cy, s;
    corner(cx, cy, s);
    if (coin(30)) {
      // A dart (simple, non-convex): tip, two wings, and a notch point.
      const long w = std::max(1L, s);
      const long dx = pick(-w, w), dy = pick(1, w);
      const Point tip(cx * unit, cy * unit);
      return Quad(tip, Point((cx - w) * unit, (cy + w) * unit), Point((cx + dx) * unit, (cy + dy) * unit),
                  Point((cx + w) * unit, (cy + w) * unit));
    }
    const Point a = point(cx, cy, s), b = point(cx, cy, s), c = point(cx, cy, s), e = point(cx, cy, s);
    return Quad(a, b, c, e);
  }
  void any(Disk &d) { d = disk(); }
  void any(Triangle &t) { t = triangle(); }
  void any(Quad &q) { q = quad(); }
  void any(Shape &s) {
    switch (pick(0, 2)) {
    case 0: s = disk(); break;
    case 1: s = triangle(); break;
    default: s = quad();
    }
  }

  // Pythagorean directions: (a, b) with a^2 + b^2 = c^2.
  void triple(long &a, long &b, long &c) {
    static const long t[][3] = {{3, 4, 5}, {5, 12, 13}, {8, 15, 17}, {7, 24, 25}, {20, 21, 29}, {0, 1, 1}};
    const long *p = t[pick(0, 5)];
    a = p[0];
    b = p[1];
    c = p[2];
    if (coin(50)) std::swap(a, b);
    if (coin(50)) a = -a;
    if (coin(50)) b = -b;
  }
  /// Two disks at distance exactly c*m apart with radii summing to c*m,
  /// or one grid unit more or less.
  void tangent_disks(Disk &d1, Disk &d2) {
    long a, b, c;
    triple(a, b, c);
    const long m = pick(1, 4), cx = pick(0, 16), cy = pick(0, 16);
    const long total = c * m * 8 + (coin(50) ? 0 : pick(-1, 1)); // in eighths
    const long r1 = pick(0, std::max(0L, total));
    d1 = Disk(Point(cx, cy), r1 / 8.0);
    d2 = Disk(Point(cx + a * m, cy + b * m), std::max(0L, total - r1) / 8.0);
  }
  /// A polygon with an edge A-B along a Pythagorean direction, the rest of
  /// it on one side, and a disk on the other side whose centre is exactly
  /// c*k from the edge's line: radius c*k (tangent) or one eighth off.
  template <class P> void tangent_edge(Disk &d, P &poly) {
    long a, b, c;
    triple(a, b, c);
    const long ax = pick(0, 16), ay = pick(0, 16), len = pick(0, 3), k = pick(0, 3), t = pick(-1, len + 1);
    // Along the edge: (a, b); its normal towards the disk: (-b, a).
    auto at = [&](long along, long out) { return Point(ax + a * along - b * out, ay + b * along + a * out); };
    d = Disk(at(t, k), std::max(0L, c * k * 8 + (coin(50) ? 0 : pick(-1, 1))) / 8.0);
    const long s1 = pick(0, len), h1 = pick(1, 3), s2 = pick(-1, len + 1), h2 = pick(0, 3);
    make(poly, at(0, 0), at(len, 0), at(s1, -h1), at(s2, -h2));
  }
  void make(Triangle &t, const Point &a, const Point &b, const Point &c, const Point &) { t = Triangle(a, b, c); }
  void make(Quad &q, const Point &a, const Point &b, const Point &c, const Point &e) { q = Quad(a, b, c, e); }
};

template <class A, class B> void random_pairs(Gen &g, long n, Tally &t) {
  A a;
  B b;
  for (long i = 0; i < n; ++i) {
    g.new_scene();
    g.any(a);
    g.any(b);
    check_pair(a, b, false, unsigned(g.rng()), t);
  }
}

template <class P> void tangent_pairs(Gen &g, long n, Tally &t) {
  Disk d;
  P poly;
  for (long i = 0; i < n; ++i) {
    g.tangent_edge(d, poly);
    check_pair(d, poly, false, unsigned(g.rng()), t);
  }
}

void log_tally(const char *what, const Tally &t) {
  std::cout << "  " << what << ": " << t.pairs << " pairs, " << t.hits << " intersecting, " << t.unchecked
            << " without reference" << std::endl;
}

} // namespace

// ---------------------------------------------------------------------------

TEST(random_grid_pairs_match_reference) {
  const unsigned long long seed = base_seed();
  note(seed_note("random_grid_pairs"));
  std::cout << "  seed " << seed << " (BVH_SEED), scale " << scale() << " (BVH_TEST_SCALE)" << std::endl;
  Gen g(seed);
  const long n = scaled(40000);
  Tally all;
  random_pairs<Disk, Disk>(g, n, all);
  random_pairs<Triangle, Triangle>(g, n, all);
  random_pairs<Quad, Quad>(g, n, all);
  random_pairs<Disk, Triangle>(g, n, all);
  random_pairs<Disk, Quad>(g, n, all);
  random_pairs<Triangle, Quad>(g, n, all);
  Disk d1, d2;
  for (long i = 0; i < n / 2; ++i) {
    g.tangent_disks(d1, d2);
    check_pair(d1, d2, false, unsigned(g.rng()), all);
  }
  tangent_pairs<Triangle>(g, n / 2, all);
  tangent_pairs<Quad>(g, n / 2, all);
  log_tally("grid pairs", all);
  CHECK_EQ(all.unchecked, 0L);
  // Both answers must be common, or the comparison proves little.
  CHECK(all.hits > all.pairs / 5 && all.hits < all.pairs * 4 / 5);
}

TEST(mixed_shape_pairs_match_reference) {
  // intersect(Shape, Shape) must reach the right predicate for each of the
  // nine ordered pairs of kinds: checked against the reference on random
  // mixed pairs and on tangent constructions held as Shapes.
  const unsigned long long seed = base_seed() + 5;
  note(seed_note("mixed_shape_pairs"));
  Gen g(seed);
  const long n = scaled(30000);
  Tally all;
  random_pairs<Shape, Shape>(g, n, all);
  int kinds_seen[3][3] = {};
  for (long i = 0; i < n / 4; ++i) {
    Disk d;
    Shape b;
    if (g.coin(50)) {
      Triangle t;
      g.tangent_edge(d, t);
      b = t;
    } else {
      Quad q;
      g.tangent_edge(d, q);
      b = q;
    }
    const Shape a = d;
    check_pair(a, b, false, unsigned(g.rng()), all);
    check_pair(b, a, false, unsigned(g.rng()), all);
  }
  for (long i = 0; i < 3000; ++i) {
    Shape a, b;
    g.new_scene();
    g.any(a);
    g.any(b);
    ++kinds_seen[int(a.kind())][int(b.kind())];
  }
  log_tally("mixed pairs", all);
  CHECK_EQ(all.unchecked, 0L);
  CHECK(all.hits > all.pairs / 5 && all.hits < all.pairs * 4 / 5);
  for (auto &row : kinds_seen)
    for (int c : row) CHECK(c > 100); // every ordered pair of kinds is drawn
}

namespace {

/// Discard-overlap sampling of `scene` by the tree (as bvh.out
/// --incremental --discard_overlap does it) and by an O(n^2) scan that asks
/// the exact integer reference instead of intersect.h: the kept lists
/// must be the same, in the same order.
template <class T> void discard_matches_reference(const std::vector<T> &scene, int split, int depth, Tally &t) {
  CourseBVH<T> tree(split, depth);
  std::vector<T> by_tree, by_reference;
  for (const T &s : scene)
    if (!tree.collision(s)) {
      tree.insert(s);
      by_tree.push_back(s);
    }
  for (const T &s : scene) {
    bool hit = false;
    for (const T &k : by_reference) {
      const int r = reference(k, s, false);
      CHECK(r >= 0);
      ++t.pairs;
      if (r == 1) {
        hit = true;
        ++t.hits;
        break;
      }
    }
    if (!hit) by_reference.push_back(s);
  }
  CHECK_EQ(by_tree.size(), by_reference.size());
  bool same = by_tree.size() == by_reference.size();
  for (std::size_t i = 0; same && i < by_tree.size(); ++i) same = by_tree[i] == by_reference[i];
  CHECK(same);
  CHECK(tree.validate());
}

/// One round of a grid-discard test: a scene of n shapes of kind T on the
/// round's grid, sampled by the tree with the round's parameters and by the
/// reference scan.
template <class T> void grid_discard_round(Gen &g, int round, Tally &t) {
  g.unit = round % 2 ? 1.0 : 0.5;
  g.extent = 12 + 8 * (round % 4);
  std::vector<T> scene(std::size_t(std::max(30L, long(scaled(400)))));
  for (T &s : scene) g.any(s);
  const int split = 1 + round % 5, depth = (round % 3) * 3; // depth 0: unlimited
  discard_matches_reference(scene, split, depth, t);
}

} // namespace

TEST(integer_grid_discard_survivors_match_reference) {
  // Small integer grids make touching (shared vertices, collinear edges,
  // tangent circles) the common case, where a tolerance would decide wrongly.
  const unsigned long long seed = base_seed() + 2;
  note(seed_note("integer_grid_discard"));
  Gen g(seed);
  Tally t;
  long kept_scenes = 0;
  for (int round = 0; round < scaled(24) + 3; ++round) {
    grid_discard_round<Disk>(g, round, t);
    grid_discard_round<Triangle>(g, round, t);
    grid_discard_round<Quad>(g, round, t);
    ++kept_scenes;
  }
  std::cout << "  integer-grid discard scenes: " << 3 * kept_scenes << ", reference pairs " << t.pairs
            << ", rejections " << t.hits << std::endl;
  CHECK(t.hits > 0);
}

TEST(integer_grid_mixed_discard_survivors_match_reference) {
  // The same for mixed scenes: disks, triangles and quads in one tree.
  const unsigned long long seed = base_seed() + 6;
  note(seed_note("integer_grid_mixed_discard"));
  Gen g(seed);
  Tally t;
  int scenes = 0;
  for (int round = 0; round < scaled(24) + 3; ++round) {
    grid_discard_round<Shape>(g, round, t);
    ++scenes;
  }
  std::cout << "  integer-grid mixed discard scenes: " << scenes << ", reference pairs " << t.pairs
            << ", rejections " << t.hits << std::endl;
  CHECK(t.hits > 0);
}

namespace {

/// A random double in [lo, hi): full 53-bit mantissa.
double real(Gen &g, double lo, double hi) { return lo + (hi - lo) * (double(g.rng() >> 11) * 0x1p-53); }
Point real_point(Gen &g, double lo = 8, double hi = 56) {
  const double x = real(g, lo, hi), y = real(g, lo, hi);
  return Point(x, y);
}
/// a + t (b - a), rounded: a point within rounding of the segment's line.
Point along(const Point &a, const Point &b, double t) { return Point(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)); }

Triangle near_triangle(Gen &g, const Point &a, const Point &b) {
  // Third vertex near the line ab, or a fresh point.
  const Point c = g.coin(50) ? along(a, b, real(g, -0.5, 1.5)) : real_point(g);
  return Triangle(a, b, c);
}

} // namespace

TEST(near_degenerate_doubles_match_big_reference) {
  // Full-precision doubles, built to be tangent or touching up to rounding:
  // the float filters cannot decide these and the exact path must.
  const unsigned long long seed = base_seed() + 1;
  note(seed_note("near_degenerate_doubles"));
  Gen g(seed);
  const long n = scaled(4000);
  Tally t;
  for (long i = 0; i < n; ++i) {
    const double th = real(g, 0, 6.283185307179586);
    const double r1 = real(g, 0.5, 8), r2 = real(g, 0.5, 8);
    const Point c1 = real_point(g);
    // Disk-disk, centres r1 + r2 apart up to rounding.
    const Disk d1(c1, r1), d2(Point(c1.x + (r1 + r2) * std::cos(th), c1.y + (r1 + r2) * std::sin(th)), r2);
    check_pair(d1, d2, true, unsigned(g.rng()), t);
    // Disk tangent to an edge up to rounding, and touching a vertex.
    const Point a = real_point(g), b = real_point(g);
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    const Point foot = along(a, b, real(g, -0.2, 1.2));
    const Disk de(Point(foot.x - r1 * (b.y - a.y) / len, foot.y + r1 * (b.x - a.x) / len), r1);
    const Triangle tri(a, b, Point(foot.x + (b.y - a.y), foot.y - (b.x - a.x)));
    check_pair(de, tri, true, unsigned(g.rng()), t);
    const Disk dv(Point(a.x + r2 * std::cos(th), a.y + r2 * std::sin(th)), r2);
    check_pair(dv, tri, true, unsigned(g.rng()), t);
    const double qx = real(g, -4, 4), qy = real(g, -4, 4), qt = real(g, -0.3, 1.3);
    const Quad q(a, b, Point(b.x + qx, b.y + qy), along(a, b, qt));
    check_pair(de, q, true, unsigned(g.rng()), t);
    // Polygons with a vertex on, or within rounding of, the other's edge.
    const Point on_ab = along(a, b, real(g, -0.2, 1.2)), elsewhere = real_point(g);
    const Triangle t2 = near_triangle(g, on_ab, elsewhere);
    check_pair(tri, t2, true, unsigned(g.rng()), t);
    check_pair(q, t2, true, unsigned(g.rng()), t);
    const Point q2a = along(a, b, real(g, 0, 1)), q2b = real_point(g);
    const Point q2c = along(a, b, real(g, -0.5, 1.5)), q2d = real_point(g);
    const Quad q2(q2a, q2b, q2c, q2d);
    check_pair(q, q2, true, unsigned(g.rng()), t);
  }
  log_tally("near-degenerate doubles", t);
  CHECK(t.unchecked < t.pairs / 10);
  CHECK(t.hits > t.pairs / 5 && t.hits < t.pairs * 4 / 5);
}

TEST(hand_made_cases) {
  const Quad sq(Point(0, 0), Point(1, 0), Point(1, 1), Point(0, 1));
  // Touching counts; 0.0025 apart does not.
  CHECK(intersect(sq, Quad(Point(1, 0), Point(2, 0), Point(2, 1), Point(1, 1))));         // shared edge
  CHECK(intersect(sq, Quad(Point(1, 1), Point(2, 1), Point(2, 2), Point(1, 2))));         // shared corner
  CHECK(!intersect(sq, Quad(Point(1.0025, 0), Point(2, 0), Point(2, 1), Point(1.0025, 1))));
  CHECK(intersect(sq, Triangle(Point(0.5, 1), Point(0, 2), Point(1, 2))));                // vertex on edge
  CHECK(!intersect(sq, Triangle(Point(0.5, 1.0025), Point(0, 2), Point(1, 2))));
  CHECK(intersect(sq, Triangle(Point(0.25, 0.25), Point(0.75, 0.25), Point(0.5, 0.75)))); // nested
  CHECK(intersect(Triangle(Point(-5, -5), Point(10, -5), Point(-5, 10)), sq));              // nested the other way
  const Triangle tri(Point(0, 0), Point(4, 0), Point(0, 4));
  CHECK(intersect(tri, Triangle(Point(2, 2), Point(3, 3), Point(2, 5))));                   // vertex on hypotenuse
  CHECK(!intersect(tri, Triangle(Point(2.0025, 2), Point(3, 3), Point(2, 5))));
  CHECK(intersect(tri, Triangle(Point(4, 0), Point(6, 0), Point(5, 1))));                   // shared vertex
  CHECK(intersect(tri, Triangle(Point(1, 0), Point(6, 0), Point(5, -1))));                  // collinear overlap
  CHECK(!intersect(tri, Triangle(Point(4.0025, 0), Point(6, 0), Point(5, -1))));
  // Disks: 3-4-5 tangency, inside and outside by 0.0025.
  CHECK(intersect(Disk(Point(0, 0), 2), Disk(Point(3, 4), 3)));
  CHECK(intersect(Disk(Point(0, 0), 2), Disk(Point(3, 4), 3.0025)));
  CHECK(!intersect(Disk(Point(0, 0), 2), Disk(Point(3, 4), 2.9975)));
  CHECK(intersect(Disk(Point(1, 1), 0), Disk(Point(1, 1), 0)));                            // equal points
  CHECK(!intersect(Disk(Point(1, 1), 0), Disk(Point(1, 1.0025), 0)));
  // Disk and edge / vertex tangency, nesting both ways.
  CHECK(intersect(Disk(Point(0.5, -2), 2), sq));
  CHECK(!intersect(Disk(Point(0.5, -2), 1.9975), sq));
  CHECK(intersect(Disk(Point(4, 5), 5), sq));                                              // touches (1, 1)
  CHECK(!intersect(Disk(Point(4, 5), 4.9975), sq));
  CHECK(intersect(Disk(Point(0.5, 0.5), 0.1), sq));
  CHECK(intersect(Disk(Point(0.5, 0.5), 100), sq));
  CHECK(intersect(Disk(Point(1, 0.5), 0), sq));                                            // point on edge
  CHECK(intersect(Disk(Point(4, 0), 0), tri));                                             // point on vertex
  CHECK(!intersect(Disk(Point(2.0025, 2), 0), tri));
  // Degenerate polygons: segments and points.
  const Triangle seg(Point(-1, 0.5), Point(2, 0.5), Point(0.5, 0.5));
  CHECK(intersect(seg, sq));
  CHECK(!intersect(Triangle(Point(-1, 1.0025), Point(2, 1.0025), Point(3, 1.0025)), sq));
  CHECK(intersect(Triangle(Point(-1, 1), Point(2, 1), Point(3, 1)), sq));                  // along the top edge
  CHECK(intersect(Quad(Point(0.5, 0.5), Point(0.5, 0.5), Point(0.5, 0.5), Point(0.5, 0.5)), sq));
  CHECK(!intersect(Quad(Point(1.5, 0.5), Point(1.5, 0.5), Point(1.5, 0.5), Point(1.5, 0.5)), sq));
  CHECK(intersect(Disk(Point(0.5, 3), 2.5), seg));
  CHECK(!intersect(Disk(Point(0.5, 3), 2.4975), seg));
  CHECK(intersect(Disk(Point(5, 4.5), 5), seg));                                           // 3-4-5 to the end (2, 0.5)
  CHECK(!intersect(Disk(Point(5, 4.5), 4.9975), seg));
  // Non-convex dart: tip (0,0), wings (-2,2) and (2,2), notch (0,1).
  const Quad dart(Point(0, 0), Point(-2, 2), Point(0, 1), Point(2, 2));
  CHECK(!intersect(Disk(Point(0, 1.5), 0), dart));                                         // in the notch
  CHECK(!intersect(Disk(Point(0, 1.75), 0.6), dart));                                      // ... 0.67 from the edges
  CHECK(intersect(Disk(Point(0, 1.75), 0.7), dart));
  CHECK(intersect(Disk(Point(0, 0.5), 0), dart));
  CHECK(!intersect(Triangle(Point(-0.25, 1.5), Point(0.25, 1.5), Point(0, 1.25)), dart));
  CHECK(intersect(Triangle(Point(-0.25, 1.5), Point(0.25, 1.5), Point(0, 1)), dart));       // touches the notch
  // Bow-tie, even-odd: its lobes are in, the rest of the fan a-b-c is not.
  const Quad bow(Point(0, 0), Point(2, 2), Point(2, 0), Point(0, 2));
  CHECK(intersect(Disk(Point(0.5, 1), 0), bow));
  CHECK(intersect(Disk(Point(1, 1), 0), bow));
  CHECK(!intersect(Disk(Point(1, 0.5), 0), bow));
  CHECK(!intersect(Triangle(Point(0.9, 0.2), Point(1.1, 0.2), Point(1, 0.4)), bow));
}

namespace {

template <class S> S make_shape(const Point *p, const std::vector<double> &n);
template <> Disk make_shape<Disk>(const Point *p, const std::vector<double> &n) { return Disk(p[0], n[2]); }
template <> Triangle make_shape<Triangle>(const Point *p, const std::vector<double> &) { return Triangle(p[0], p[1], p[2]); }
template <> Quad make_shape<Quad>(const Point *p, const std::vector<double> &) { return Quad(p[0], p[1], p[2], p[3]); }

/// Parses `pt= <x y> ... color= {r g b}` lines, numbers read as float.
template <class S> std::vector<S> read_shapes(const std::string &path, bool &found) {
  std::vector<S> out;
  std::ifstream in(path);
  found = bool(in);
  std::string line;
  while (std::getline(in, line)) {
    for (char &ch : line)
      if (ch == '<' || ch == '>' || ch == '{' || ch == '}') ch = ' ';
    std::istringstream is(line);
    std::string word;
    std::vector<double> nums;
    while (is >> word) {
      float f;
      std::istringstream ws(word);
      if (ws >> f && ws.eof()) nums.push_back(double(f));
    }
    // Disk: x y r c c c; triangle: 6 + 3; quad: 8 + 3.
    const int pts = S::numPoints();
    Point p[4];
    for (int i = 0; i < pts && 2 * i + 1 < int(nums.size()); ++i) p[i] = Point(nums[2 * i], nums[2 * i + 1]);
    if (nums.size() < 3) continue;
    out.push_back(make_shape<S>(p, nums));
  }
  return out;
}

/// Every pair (within one file or across two) whose boxes meet, against the
/// Big reference. Returns the number of pairs checked.
template <class A, class B> long course_pairs(const std::vector<A> &as, const std::vector<B> &bs, long &hits) {
  long n = 0;
  for (size_t i = 0; i < as.size(); ++i)
    for (size_t j = 0; j < bs.size(); ++j) {
      if (!as[i].getBox().overlaps(bs[j].getBox())) {
        CHECK(!intersect(as[i], bs[j]));
        continue;
      }
      const bool ab = intersect(as[i], bs[j]);
      CHECK_EQ(ab, intersect(bs[j], as[i]));
      CHECK_EQ(int(ab), reference(as[i], bs[j], true));
      hits += ab;
      ++n;
    }
  return n;
}

} // namespace

TEST(course_overlap_triangles_289_375_do_not_intersect) {
  const std::string path = course_dir() + "/overlap_1000.triangles";
  note("file " + path);
  bool found;
  const std::vector<Triangle> tris = read_shapes<Triangle>(path, found);
  if (!found) {
    std::cout << "  skipped: " << path << " not found (set COURSE_DATA)" << std::endl;
    return;
  }
  CHECK_EQ(tris.size(), size_t(1000));
  if (tris.size() < 375) return;
  const Triangle &a = tris[288], &b = tris[374]; // lines 289 and 375
  CHECK(a.getBox().overlaps(b.getBox()));        // close enough to need the exact test
  CHECK(!intersect(a, b));
  CHECK(!intersect(b, a));
  // Independent confirmation: float values scale to integers exactly.
  CHECK_EQ(reference(a, b, false), 0);
  CHECK_EQ(reference(a, b, true), 0);
}

TEST(course_overlap_files_match_reference) {
  const std::string dir = course_dir();
  note("dir " + dir);
  bool f1, f2, f3;
  const auto disks = read_shapes<Disk>(dir + "/overlap_1000.disks", f1);
  const auto tris = read_shapes<Triangle>(dir + "/overlap_1000.triangles", f2);
  const auto quads = read_shapes<Quad>(dir + "/overlap_1000.quads", f3);
  if (!(f1 && f2 && f3)) {
    std::cout << "  skipped: overlap_1000.* not found in " << dir << " (set COURSE_DATA)" << std::endl;
    return;
  }
  // Small scales (valgrind) check a prefix of each file, still big enough
  // for both answers to occur.
  const size_t m = size_t(std::min(1000L, std::max(150L, scaled(1000))));
  const std::vector<Disk> d(disks.begin(), disks.begin() + long(std::min(m, disks.size())));
  const std::vector<Triangle> t(tris.begin(), tris.begin() + long(std::min(m, tris.size())));
  const std::vector<Quad> q(quads.begin(), quads.begin() + long(std::min(m, quads.size())));
  long hits = 0, n = 0;
  n += course_pairs(d, d, hits);
  n += course_pairs(t, t, hits);
  n += course_pairs(q, q, hits);
  n += course_pairs(d, t, hits);
  n += course_pairs(d, q, hits);
  n += course_pairs(t, q, hits);
  std::cout << "  course pairs with meeting boxes: " << n << ", intersecting " << hits << std::endl;
  CHECK(n > 0 && hits > 0 && hits < n);
}

namespace {

/// Exact orientation of integer points (coordinates below 2^60).
int ref_orient(const Point &a, const Point &b, const Point &c, int k) {
  const IP A{to_int(a.x, k), to_int(a.y, k)}, B{to_int(b.x, k), to_int(b.y, k)}, C{to_int(c.x, k), to_int(c.y, k)};
  return sgn(icross<i128>(A, B, C));
}

int naive_orient(const Point &a, const Point &b, const Point &c) {
  const double d = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  return (d > 0) - (d < 0);
}

/// orient2d(a, b, c) and its five permutations against the reference.
/// Returns whether the naive double formula got the sign wrong.
bool check_orient(const Point &a, const Point &b, const Point &c, int k) {
  using bvh::exact::orient2d;
  const int s = ref_orient(a, b, c, k);
  CHECK_EQ(orient2d(a, b, c), s);
  CHECK_EQ(orient2d(b, c, a), s);
  CHECK_EQ(orient2d(c, a, b), s);
  CHECK_EQ(orient2d(b, a, c), -s);
  CHECK_EQ(orient2d(a, c, b), -s);
  CHECK_EQ(orient2d(c, b, a), -s);
  return naive_orient(a, b, c) != s;
}

} // namespace

TEST(orient2d_near_collinear_is_exact) {
  // The classic grid: p = (0.5 + i u, 0.5 + j u), u = 2^-53, against the
  // line through (12, 12) and (24, 24). Naive doubles get a patchwork of
  // wrong signs here; the exact answer is sign(j - i).
  const double u = std::ldexp(1.0, -53);
  const Point q(12, 12), r(24, 24);
  long wrong_naive = 0;
  // (Under a tenth of the rounds, valgrind's run, every fourth row and
  // column: 4,096 points, the patchwork still among them.)
  const int stride = scale() < 0.1 ? 4 : 1;
  for (int i = 0; i < 256; i += stride)
    for (int j = 0; j < 256; j += stride) {
      const Point p(0.5 + i * u, 0.5 + j * u);
      wrong_naive += check_orient(p, q, r, 53);
      CHECK_EQ(bvh::exact::orient2d(p, q, r), (j > i) - (j < i));
    }
  std::cout << "  naive double orientation wrong on " << wrong_naive << " of " << (256 / stride) * (256 / stride)
            << " grid points" << std::endl;
  CHECK(wrong_naive > 0); // the grid really is beyond the naive formula

  // Random full-precision points in [0.5, 64) (all multiples of 2^-53) with
  // the third one on the line through the first two, up to rounding.
  const unsigned long long seed = base_seed() + 2;
  note(seed_note("orient2d_random"));
  Gen g(seed);
  long zeros = 0;
  const long n = scaled(100000);
  for (long i = 0; i < n; ++i) {
    const Point a = real_point(g, 0.5, 64), b = real_point(g, 0.5, 64);
    Point c = along(a, b, real(g, -1, 2));
    if (c.x < 0.5 || c.y < 0.5 || c.x >= 64 || c.y >= 64) c = b;
    check_orient(a, b, c, 53);
    zeros += ref_orient(a, b, c, 53) == 0;
  }
  CHECK(zeros > 0 && zeros < n);
}

namespace {

/// The reference sign of one filtered predicate's formula, in Big.
IP big_point(const Point &p, int k) { return {to_int(p.x, k), to_int(p.y, k)}; }

} // namespace

TEST(filtered_predicates_match_reference_near_zero) {
  // Each helper of intersect.h on inputs that put its value within rounding
  // of zero: right angles, tangencies. Full doubles in [8, 56) scale by 2^53.
  using namespace bvh::exact::detail;
  const unsigned long long seed = base_seed() + 3;
  note(seed_note("filtered_predicates"));
  Gen g(seed);
  const long n = scaled(30000);
  long checked = 0;
  for (long i = 0; i < n; ++i) {
    const Point a = real_point(g), b = real_point(g);
    const double s = real(g, -0.5, 0.5), r1 = real(g, 0.5, 4), r2 = real(g, 0.5, 4), r = r1 + r2;
    // c on the perpendicular to ab at a: dot(b - a, c - a) is ~0.
    const Point c(a.x - s * (b.y - a.y), a.y + s * (b.x - a.x));
    // f at distance ~r from a, along ab.
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    const Point f(a.x + r * (b.x - a.x) / len, a.y + r * (b.y - a.y) / len);
    // The line ab passes ~rl from c.
    const double rl = std::fabs(s) * len;
    const std::vector<double> v = {a.x, a.y, b.x, b.y, c.x, c.y, f.x, f.y, r1, r2, r, rl};
    int k;
    if (!integer_scale(v, 62, k)) continue;
    ++checked;
    const IP A = big_point(a, k), B = big_point(b, k), C = big_point(c, k), F = big_point(f, k);
    const Big R(to_int(r, k)), R1(to_int(r1, k)), R2(to_int(r2, k)), RL(to_int(rl, k));
    const int dot = sgn(idot<Big>(A, B, C));
    CHECK_EQ(dot_sign(a, b, c), dot);
    CHECK_EQ(dot_sign(a, c, b), dot);
    const Big af = idot<Big>(A, F, F);
    CHECK_EQ(disk_gap(f, a, r, 0), sgn(R * R - af));
    CHECK_EQ(disk_gap(a, f, 0, r), sgn(R * R - af));
    CHECK_EQ(disk_gap(a, f, r1, r2), sgn((R1 + R2) * (R1 + R2) - af));
    const Big cr = icross<Big>(A, B, C);
    CHECK_EQ(line_gap(a, b, c, rl), sgn(RL * RL * idot<Big>(A, B, B) - cr * cr));
  }
  std::cout << "  " << checked << " of " << n << " near-zero cases checked" << std::endl;
  CHECK(checked > n / 2);
}

TEST(expansion_arithmetic_is_exact) {
  // Values whose exact result needs more than one double.
  using namespace bvh::exact::detail;
  const auto detail_exact = [](double v) { return bvh::exact::detail::exact(v); };
  const double big = std::ldexp(1.0, 60);
  CHECK_EQ((exact_sum(big, 1.0) - detail_exact(big)).sign(), 1);
  CHECK_EQ((exact_sum(big, -1.0) - detail_exact(big)).sign(), -1);
  CHECK_EQ((exact_diff(big, big)).sign(), 0);
  // (2^30 + 1)^2 - 2^60 - 2^31 - 1 == 0, and +-1 around it.
  const Expansion<2> x = exact_sum(std::ldexp(1.0, 30), 1.0);
  const auto sq = x * x;
  CHECK_EQ((sq - exact_sum(big, std::ldexp(1.0, 31)) - detail_exact(1.0)).sign(), 0);
  CHECK_EQ((sq - exact_sum(big, std::ldexp(1.0, 31))).sign(), 1);
  CHECK_EQ((sq - exact_sum(big, std::ldexp(1.0, 31)) - detail_exact(2.0)).sign(), -1);
}

int main(int argc, char **argv) { return run_all_tests(argc, argv); }
