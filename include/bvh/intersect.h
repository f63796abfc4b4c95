// intersect.h — exact intersection tests between the closed shapes of
// shapes.h: `intersect(a, b)` for every pair of Disk, Triangle and Quad (and
// of Shape, which holds any one of them), and the exact orientation
// predicate they are built on.
//
//   #include "intersect.h"
//   Triangle t(Point(0, 0), Point(10, 0), Point(0, 10));
//   Disk d(Point(13, -4), 5);                   // 3-4-5: touches vertex (10, 0)
//   bool hit = intersect(t, d);                 // true; always == intersect(d, t)
//   int turn = bvh::exact::orient2d(a, b, c);   // sign of cross(b - a, c - a)
//
// Semantics. Every shape is a closed set. A disk is the points at distance
// <= radius from its centre (radius 0: a point). A polygon is its boundary
// plus the points it encloses an odd number of times (even-odd rule): for a
// simple triangle or quad, convex or not, that is the usual closed region;
// collinear or repeated vertices give a segment or a point; a self-crossing
// "bow-tie" quad a-b-c-d is its two lobes on either side of the crossing (NOT
// the fan a-b-c + a-c-d). Touching, however slightly, counts as intersecting.
//
// Exactness. Every answer is the exact one for the doubles the shapes hold —
// no tolerance anywhere — so intersect(a, b) == intersect(b, a). This needs
// IEEE doubles rounded to nearest-even without extended precision (any
// x86-64/ARM64 build without -ffast-math), radii >= 0, and every coordinate
// and radius either 0 or of magnitude in [2^-200, 2^200] so that nothing
// overflows or underflows; every float value, and any sane double, qualifies.
//
// Cost. O(1) per call, allocation-free. Disjoint bounding boxes answer after
// a few compares. Otherwise a polygon pair evaluates 2*N*M orientations (N, M
// vertices) and a disk-polygon pair 5 small determinants per edge, each a
// dozen flops checked against a rounding-error bound. Only when a value is
// too close to zero for its bound (touching or within ~1e-15 relative of it)
// does it fall back to exact expansion arithmetic (tens to a few thousand
// flops, on the stack).
#ifndef BVH_INTERSECT_H
#define BVH_INTERSECT_H

#include "shapes.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>

#if defined(__GNUC__)
#define BVH_EXACT_COLD __attribute__((noinline, cold))
#else
#define BVH_EXACT_COLD
#endif

#if defined(__FAST_MATH__)
#error "intersect.h needs IEEE arithmetic: do not build it with -ffast-math"
#endif
static_assert(std::numeric_limits<double>::is_iec559 && FLT_EVAL_METHOD == 0,
              "intersect.h needs IEEE doubles evaluated without extended precision");

namespace bvh {

namespace exact {

namespace detail {

// ---------------------------------------------------------------------------
// Expansion arithmetic. A value is held exactly as a sum of doubles (an
// "expansion") whose components are nonoverlapping and increasing in
// magnitude, zeros removed: its sign is then the sign of its last component.
// The error-free transforms below are exact under round-to-nearest-even.

constexpr double kEps = std::numeric_limits<double>::epsilon() / 2; // 2^-53, unit roundoff

/// s + e == a + b exactly, s = fl(a + b).
inline void two_sum(double a, double b, double &s, double &e) {
  s = a + b;
  const double bv = s - a;
  const double av = s - bv;
  e = (a - av) + (b - bv);
}

/// p + e == a * b exactly, p = fl(a * b). std::fma makes the tail one step.
inline void two_product(double a, double b, double &p, double &e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

/// Capacity N is the worst-case component count, known at compile time from
/// the formula, so no operation can overflow the array. Capacities reach 576,
/// so copies move only the n live components.
template <int N> struct Expansion {
  double v[N];
  int n = 0;
  Expansion() = default;
  Expansion(const Expansion &o) : n(o.n) { std::copy(o.v, o.v + o.n, v); }
  Expansion &operator=(const Expansion &o) {
    if (this != &o) { // (std::copy onto its own range breaks its precondition)
      n = o.n;
      std::copy(o.v, o.v + o.n, v);
    }
    return *this;
  }
  int sign() const { return n == 0 ? 0 : (v[n - 1] > 0 ? 1 : -1); }
};

inline Expansion<1> exact(double a) {
  Expansion<1> r;
  if (a != 0) r.v[r.n++] = a;
  return r;
}

/// a - b, exactly.
inline Expansion<2> exact_diff(double a, double b) {
  Expansion<2> r;
  double s, e;
  two_sum(a, -b, s, e);
  if (e != 0) r.v[r.n++] = e;
  if (s != 0) r.v[r.n++] = s;
  return r;
}

/// a + b, exactly.
inline Expansion<2> exact_sum(double a, double b) { return exact_diff(a, -b); }

/// h = e + f (h must not alias e or f). Merging by magnitude and carrying one
/// running sum keeps the result nonoverlapping; returns h's length.
inline int sum_into(const double *e, int en, const double *f, int fn, double *h) {
  int i = 0, j = 0, hn = 0;
  auto next = [&]() { return (j == fn || (i < en && std::fabs(e[i]) < std::fabs(f[j]))) ? e[i++] : f[j++]; };
  if (en + fn == 0) return 0;
  double q = next();
  while (i < en || j < fn) {
    double s, t;
    two_sum(q, next(), s, t);
    if (t != 0) h[hn++] = t;
    q = s;
  }
  if (q != 0) h[hn++] = q;
  return hn;
}

/// h = e * b (h must not alias e); returns h's length.
inline int scale_into(const double *e, int en, double b, double *h) {
  if (en == 0 || b == 0) return 0;
  int hn = 0;
  double q, t;
  two_product(e[0], b, q, t);
  if (t != 0) h[hn++] = t;
  for (int i = 1; i < en; ++i) {
    double p, pt, s, st;
    two_product(e[i], b, p, pt);
    two_sum(q, pt, s, st);
    if (st != 0) h[hn++] = st;
    two_sum(p, s, q, st);
    if (st != 0) h[hn++] = st;
  }
  if (q != 0) h[hn++] = q;
  return hn;
}

template <int A, int B> Expansion<A + B> operator+(const Expansion<A> &e, const Expansion<B> &f) {
  Expansion<A + B> r;
  r.n = sum_into(e.v, e.n, f.v, f.n, r.v);
  return r;
}

template <int A, int B> Expansion<A + B> operator-(const Expansion<A> &e, Expansion<B> f) {
  for (int i = 0; i < f.n; ++i) f.v[i] = -f.v[i];
  return e + f;
}

/// e * f as the sum of e scaled by each component of f.
template <int A, int B> Expansion<2 * A * B> operator*(const Expansion<A> &e, const Expansion<B> &f) {
  Expansion<2 * A * B> acc[2];
  double part[2 * A];
  int cur = 0;
  for (int k = 0; k < f.n; ++k) {
    const int pn = scale_into(e.v, e.n, f.v[k], part);
    acc[1 - cur].n = sum_into(acc[cur].v, acc[cur].n, part, pn, acc[1 - cur].v);
    cur = 1 - cur;
  }
  return acc[cur];
}

// Exact signs, each the fallback of a filtered predicate below. Kept out of
// line so that the filters inline into the callers' loops as a few flops.

BVH_EXACT_COLD inline int orient2d_exact(const Point &a, const Point &b, const Point &c) {
  return (exact_diff(b.x, a.x) * exact_diff(c.y, a.y) - exact_diff(b.y, a.y) * exact_diff(c.x, a.x)).sign();
}

BVH_EXACT_COLD inline int dot_exact(const Point &a, const Point &b, const Point &c) {
  return (exact_diff(b.x, a.x) * exact_diff(c.x, a.x) + exact_diff(b.y, a.y) * exact_diff(c.y, a.y)).sign();
}

BVH_EXACT_COLD inline int disk_gap_exact(const Point &p, const Point &q, double r1, double r2) {
  const Expansion<2> s = exact_sum(r1, r2), dx = exact_diff(p.x, q.x), dy = exact_diff(p.y, q.y);
  return (s * s - (dx * dx + dy * dy)).sign();
}

BVH_EXACT_COLD inline int line_gap_exact(const Point &a, const Point &b, const Point &c, double r) {
  const Expansion<2> ux = exact_diff(b.x, a.x), uy = exact_diff(b.y, a.y);
  const auto cross = ux * exact_diff(c.y, a.y) - uy * exact_diff(c.x, a.x);
  const Expansion<1> re = exact(r);
  return ((re * re) * (ux * ux + uy * uy) - cross * cross).sign();
}

// ---------------------------------------------------------------------------
// Filtered predicates. Each evaluates its formula in doubles, with a bound on
// the rounding error derived by counting roundings (each op errs by at most
// kEps relative; the constants leave slack for rounding the bound itself).
// Past the bound the double's sign is certain; inside it, go exact.

// cross or dot of two differences: <= 4 eps + O(eps^2) times |l| + |r|.
constexpr double kTwoProductsBound = 5 * kEps;
// (r1+r2)^2 - |p-q|^2: <= 5 eps + O(eps^2) times the sum of the two squares.
constexpr double kDiskGapBound = 6 * kEps;
// r^2 |u|^2 - cross^2: <= 7.1 eps r^2|u|^2 + 10.2 eps (|l| + |r|)^2.
constexpr double kLineGapBound = 12 * kEps;

/// The sign of v when |v| > bound, else 0 ("not sure"; never a certain 0).
inline int sure_sign(double v, double bound) { return (v > bound) - (v < -bound); }

/// orient2d's filter alone: 0 when the doubles cannot tell.
inline int orient2d_filtered(const Point &a, const Point &b, const Point &c) {
  const double l = (b.x - a.x) * (c.y - a.y), r = (b.y - a.y) * (c.x - a.x);
  return sure_sign(l - r, kTwoProductsBound * (std::fabs(l) + std::fabs(r)));
}

/// Sign of dot(b - a, c - a): > 0 when the angle at a is acute.
inline int dot_sign(const Point &a, const Point &b, const Point &c) {
  const double l = (b.x - a.x) * (c.x - a.x), r = (b.y - a.y) * (c.y - a.y);
  const int s = sure_sign(l + r, kTwoProductsBound * (std::fabs(l) + std::fabs(r)));
  return s != 0 ? s : dot_exact(a, b, c);
}

/// Sign of (r1 + r2)^2 - |p - q|^2: >= 0 when disks (p, r1) and (q, r2) meet.
inline int disk_gap(const Point &p, const Point &q, double r1, double r2) {
  const double s = r1 + r2, dx = p.x - q.x, dy = p.y - q.y;
  const double ss = s * s, dd = dx * dx + dy * dy;
  const int sign = sure_sign(ss - dd, kDiskGapBound * (ss + dd));
  return sign != 0 ? sign : disk_gap_exact(p, q, r1, r2);
}

/// disk_gap(p, q, r1, r2) >= 0, with the common answer (far apart) first:
/// one compare, where the sign takes two and a select.
inline bool disks_meet(const Point &p, const Point &q, double r1, double r2) {
  const double s = r1 + r2, dx = p.x - q.x, dy = p.y - q.y;
  const double ss = s * s, dd = dx * dx + dy * dy;
  const double gap = ss - dd, bound = kDiskGapBound * (ss + dd);
  if (gap < -bound) return false;
  if (gap > bound) return true;
  return disk_gap_exact(p, q, r1, r2) >= 0;
}

/// Sign of r^2 |b - a|^2 - cross(b - a, c - a)^2: >= 0 when the line through
/// a and b passes within r of c.
inline int line_gap(const Point &a, const Point &b, const Point &c, double r) {
  const double ux = b.x - a.x, uy = b.y - a.y;
  const double l = ux * (c.y - a.y), rt = uy * (c.x - a.x);
  const double cross = l - rt, t = std::fabs(l) + std::fabs(rt);
  const double reach = (r * r) * (ux * ux + uy * uy);
  const int sign = sure_sign(reach - cross * cross, kLineGapBound * (t * t + reach));
  return sign != 0 ? sign : line_gap_exact(a, b, c, r);
}

/// p in the box spanned by a and b: for p collinear with a and b, on segment ab.
inline bool in_span(const Point &p, const Point &a, const Point &b) {
  return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
         p.y <= std::max(a.y, b.y);
}

} // namespace detail

/// Sign of cross(b - a, c - a), exactly: +1 when c lies to the left of the
/// directed line a->b (counter-clockwise with y up; clockwise on an SVG
/// screen, whose y grows downwards), -1 to the right, 0 when collinear or
/// when points coincide. Exact under the conditions at the top of this file.
inline int orient2d(const Point &a, const Point &b, const Point &c) {
  const int s = detail::orient2d_filtered(a, b, c);
  return s != 0 ? s : detail::orient2d_exact(a, b, c);
}

namespace detail {

// The shape tests below evaluate every predicate they might need and combine
// the signs with & and |: on random input, data-dependent branches would
// mispredict about half the time and cost more than the arithmetic saved.

/// Copies a polygon's vertices with the first repeated at the end, so that
/// edge j is v[j] v[j+1].
template <int N> void closed_vertices(const Polygon<N> &poly, Point (&v)[N + 1]) {
  for (int i = 0; i < N; ++i) v[i] = poly.getPoint(i);
  v[N] = v[0];
}

/// Even-odd test by a ray from p towards +x, given side[j] = orient2d(v_j,
/// v_j+1, p). Exact for p off the boundary; for p on it the answer is
/// arbitrary, so callers settle boundary points first (or do not care).
template <int N> bool encloses(const Point (&v)[N + 1], const Point &p, const int *side) {
  bool odd = false;
  for (int j = 0; j < N; ++j) {
    // An edge straddling the ray's height crosses the ray iff p is to its
    // left going up, or to its right going down.
    const bool up = v[j + 1].y > v[j].y;
    odd ^= ((v[j].y > p.y) != (v[j + 1].y > p.y)) & ((side[j] > 0) == up);
  }
  return odd;
}

/// side[j][i] = orient2d(e_j, e_j+1, v_i) for every edge of one polygon and
/// vertex of another, with side[j][N] = side[j][0]. Returns true when some
/// entry is 0, i.e. some vertex is collinear with some edge.
template <int M, int N> bool side_table(const Point (&e)[M + 1], const Point (&v)[N + 1], int (&side)[M][N + 1]) {
  bool unsure = false;
  for (int j = 0; j < M; ++j)
    for (int i = 0; i < N; ++i) {
      side[j][i] = orient2d_filtered(e[j], e[j + 1], v[i]);
      unsure |= side[j][i] == 0;
    }
  bool zero = false;
  if (unsure)
    for (int j = 0; j < M; ++j)
      for (int i = 0; i < N; ++i)
        if (side[j][i] == 0) {
          side[j][i] = orient2d_exact(e[j], e[j + 1], v[i]);
          zero |= side[j][i] == 0;
        }
  for (int j = 0; j < M; ++j) side[j][N] = side[j][0];
  return zero;
}

template <int N> bool disk_meets_polygon(const Disk &d, const Polygon<N> &poly) {
  if (!d.getBox().overlaps(poly.getBox())) return false;
  const Point c = d.getCenter();
  const double r = d.getRadius();
  Point v[N + 1];
  closed_vertices(poly, v);
  int side[N];
  bool meets = false;
  for (int j = 0; j < N; ++j) {
    const Point &a = v[j], &b = v[j + 1];
    side[j] = orient2d(a, b, c);
    // The point of edge ab nearest to c is a vertex, or the foot of the
    // perpendicular when that falls strictly between a and b.
    const bool near_a = disk_gap(c, a, r, 0) >= 0;
    const bool past_a = dot_sign(a, b, c) > 0, before_b = dot_sign(b, a, c) > 0;
    const bool near_line = line_gap(a, b, c, r) >= 0;
    meets |= near_a | (past_a & before_b & near_line);
  }
  // A centre on the boundary has been found above (distance 0 <= r).
  return meets || encloses<N>(v, c, side);
}

/// P and Q meet iff their boundaries meet or one holds a vertex of the
/// other; boundaries meet iff a vertex lies on the other's edge or two edges
/// cross properly. Every orientation is computed once, in two tables.
template <int N, int M> bool polygons_meet(const Polygon<N> &P, const Polygon<M> &Q) {
  if (!P.getBox().overlaps(Q.getBox())) return false;
  Point p[N + 1], q[M + 1];
  closed_vertices(P, p);
  closed_vertices(Q, q);
  int pq[M][N + 1]; // pq[j][i]: side of p_i relative to edge q_j q_j+1
  int qp[N][M + 1]; // qp[i][j]: side of q_j relative to edge p_i p_i+1
  const bool q_collinear = side_table<M, N>(q, p, pq);
  const bool p_collinear = side_table<N, M>(p, q, qp);
  if (q_collinear | p_collinear) {
    for (int j = 0; j < M; ++j)
      for (int i = 0; i < N; ++i)
        if (pq[j][i] == 0 && in_span(p[i], q[j], q[j + 1])) return true;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < M; ++j)
        if (qp[i][j] == 0 && in_span(q[j], p[i], p[i + 1])) return true;
  }
  bool cross = false;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < M; ++j) cross |= (pq[j][i] * pq[j][i + 1] < 0) & (qp[i][j] * qp[i][j + 1] < 0);
  if (cross) return true;
  // Boundaries are disjoint: the shapes meet only if one holds the other.
  int side_p0[M], side_q0[N];
  for (int j = 0; j < M; ++j) side_p0[j] = pq[j][0];
  for (int i = 0; i < N; ++i) side_q0[i] = qp[i][0];
  return encloses<M>(q, p[0], side_p0) || encloses<N>(p, q[0], side_q0);
}

} // namespace detail
} // namespace exact

/// True when the closed disks meet (tangent disks do). (Exact, which
/// bvh.h's collision searches may rely on: see shape_traits's
/// inscribed_disks.)
#define BVH_EXACT_DISKS 1
inline bool intersect(const Disk &a, const Disk &b) {
  return exact::detail::disks_meet(a.getCenter(), b.getCenter(), a.getRadius(), b.getRadius());
}

/// True when the closed triangles meet (a shared vertex or edge point counts).
inline bool intersect(const Triangle &a, const Triangle &b) { return exact::detail::polygons_meet(a, b); }

/// True when the closed quads meet (simple, possibly non-convex; see the top).
inline bool intersect(const Quad &a, const Quad &b) { return exact::detail::polygons_meet(a, b); }

/// True when the closed disk and triangle meet.
inline bool intersect(const Disk &d, const Triangle &t) { return exact::detail::disk_meets_polygon(d, t); }

/// Same as intersect(d, t).
inline bool intersect(const Triangle &t, const Disk &d) { return intersect(d, t); }

/// True when the closed disk and quad meet.
inline bool intersect(const Disk &d, const Quad &q) { return exact::detail::disk_meets_polygon(d, q); }

/// Same as intersect(d, q).
inline bool intersect(const Quad &q, const Disk &d) { return intersect(d, q); }

/// True when the closed triangle and quad meet.
inline bool intersect(const Triangle &t, const Quad &q) { return exact::detail::polygons_meet(t, q); }

/// Same as intersect(t, q).
inline bool intersect(const Quad &q, const Triangle &t) { return intersect(t, q); }

/// Any two shapes of a mixed scene: the predicate of their two kinds.
inline bool intersect(const Shape &a, const Shape &b) {
  return a.visit([&](const auto &x) { return b.visit([&](const auto &y) { return intersect(x, y); }); });
}

} // namespace bvh


#undef BVH_EXACT_COLD

#endif // BVH_INTERSECT_H
