// distance.h — how far a point is from a shape, and where a ray first meets
// one: the per-shape measures behind BVH<T>::nearest() and first_hit().
//
//   double d = distance(Point(3, 4), disk);            // 0 inside or on it
//   double t = ray_hit(origin, direction, triangle);   // +inf when missed
//   Point hit(origin.x + t * direction.x, origin.y + t * direction.y);
//
// Whether the point lies inside or on the shape (distance 0, ray parameter 0)
// is decided exactly, by intersect.h's predicates; the positive distances and
// ray parameters are computed in double (square roots and divisions cannot be
// exact) with a relative error of a few units in the last place. Triangles
// and quads may be degenerate (segments, points) and quads non-convex: the
// boundary is the polygon's edges in order. O(1) per call.
#ifndef BVH_DISTANCE_H
#define BVH_DISTANCE_H

#include <algorithm>
#include <cmath>
#include <limits>

#include "intersect.h"

namespace bvh {

namespace distance_detail {

inline double cross(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/// Distance from p to the segment ab (a point when a == b).
inline double to_segment(const Point &p, const Point &a, const Point &b) {
  const double ex = b.x - a.x, ey = b.y - a.y;
  const double len2 = ex * ex + ey * ey;
  double t = len2 > 0 ? ((p.x - a.x) * ex + (p.y - a.y) * ey) / len2 : 0;
  t = std::min(1.0, std::max(0.0, t));
  return std::hypot(p.x - (a.x + t * ex), p.y - (a.y + t * ey));
}

/// Smallest t >= 0 with origin + t dir on the segment ab; +inf if none.
inline double ray_segment(const Point &o, const Point &dir, const Point &a, const Point &b) {
  const double inf = std::numeric_limits<double>::infinity();
  const double ex = b.x - a.x, ey = b.y - a.y, ax = a.x - o.x, ay = a.y - o.y;
  const double denom = cross(dir.x, dir.y, ex, ey);
  const double dd = dir.x * dir.x + dir.y * dir.y;
  if (denom == 0) {
    // Parallel: only a segment on the ray's own line can be met, first at
    // whichever end is nearer ahead.
    if (cross(ax, ay, dir.x, dir.y) != 0 || dd == 0) return inf;
    const double ta = (ax * dir.x + ay * dir.y) / dd, tb = ((b.x - o.x) * dir.x + (b.y - o.y) * dir.y) / dd;
    if (ta >= 0 && tb >= 0) return std::min(ta, tb);
    if (ta >= 0 || tb >= 0) return 0; // the origin lies between the ends
    return inf;
  }
  const double t = cross(ax, ay, ex, ey) / denom, s = cross(ax, ay, dir.x, dir.y) / denom;
  return t >= 0 && s >= 0 && s <= 1 ? t : inf;
}

} // namespace distance_detail

/// Distance from `p` to the disk `d` (0 when p is inside or on it).
inline double distance(const Point &p, const Disk &d) {
  if (intersect(Disk(p, 0, Color(0, 0, 0)), d)) return 0;
  return std::max(0.0, std::hypot(p.x - d.getCenter().x, p.y - d.getCenter().y) - d.getRadius());
}

namespace distance_detail {
template <class P> double polygon_distance(const Point &p, const P &poly) {
  if (intersect(Disk(p, 0, Color(0, 0, 0)), poly)) return 0;
  const int n = poly.numPoints();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) best = std::min(best, to_segment(p, poly.getPoint(i), poly.getPoint((i + 1) % n)));
  return best;
}
template <class P> double polygon_ray(const Point &origin, const Point &dir, const P &poly) {
  if (intersect(Disk(origin, 0, Color(0, 0, 0)), poly)) return 0;
  const int n = poly.numPoints();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i)
    best = std::min(best, ray_segment(origin, dir, poly.getPoint(i), poly.getPoint((i + 1) % n)));
  return best;
}
} // namespace distance_detail

/// Distance from `p` to the triangle `t` (0 inside or on it).
inline double distance(const Point &p, const Triangle &t) { return distance_detail::polygon_distance(p, t); }
/// Distance from `p` to the quad `q` (0 inside or on it).
inline double distance(const Point &p, const Quad &q) { return distance_detail::polygon_distance(p, q); }

/// The ray origin + t * dir (t >= 0) first meets the disk at the returned t;
/// 0 when the origin is inside or on it, +inf when it misses. A zero `dir`
/// meets only a disk holding the origin.
inline double ray_hit(const Point &origin, const Point &dir, const Disk &d) {
  const double inf = std::numeric_limits<double>::infinity();
  if (intersect(Disk(origin, 0, Color(0, 0, 0)), d)) return 0;
  const double ox = origin.x - d.getCenter().x, oy = origin.y - d.getCenter().y, r = d.getRadius();
  const double a = dir.x * dir.x + dir.y * dir.y, b = ox * dir.x + oy * dir.y;
  if (a == 0 || b >= 0) return inf; // standing still, or moving away from the centre
  const double c = ox * ox + oy * oy - r * r;
  // b * b - a * c, written as a r^2 - cross(o, dir)^2 (the same in exact
  // arithmetic): when the ray passes far from the centre, b * b and a * c
  // are huge and nearly equal, and their difference could round to >= 0
  // for a ray that misses by far.
  const double cross = ox * dir.y - oy * dir.x;
  const double disc = a * (r * r) - cross * cross;
  if (disc < 0) return inf;
  // The nearer root, written to avoid cancellation: c / (-b + sqrt(disc)).
  return std::max(0.0, c / (-b + std::sqrt(disc)));
}

/// The same for a triangle: the nearest crossing of an edge.
inline double ray_hit(const Point &origin, const Point &dir, const Triangle &t) {
  return distance_detail::polygon_ray(origin, dir, t);
}
/// The same for a quad (convex or not): the nearest crossing of an edge.
inline double ray_hit(const Point &origin, const Point &dir, const Quad &q) {
  return distance_detail::polygon_ray(origin, dir, q);
}

/// Distance from `p` to the shape held, whichever kind it is.
inline double distance(const Point &p, const Shape &s) {
  return s.visit([&](const auto &shape) { return distance(p, shape); });
}
/// ray_hit on the shape held, whichever kind it is.
inline double ray_hit(const Point &origin, const Point &dir, const Shape &s) {
  return s.visit([&](const auto &shape) { return ray_hit(origin, dir, shape); });
}

} // namespace bvh


#endif // BVH_DISTANCE_H
