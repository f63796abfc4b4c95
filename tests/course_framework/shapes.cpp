// shapes.cpp — stand-in for the course's shapes.cpp (see shapes.h). The
// predicates are simple and inexact on purpose: a pair intersects only when
// it overlaps by more than kTolerance, so the shapes this framework keeps in
// discard-overlap sampling differ from those of the project's exact
// intersect.h, and a test can tell whose predicate a bvh.h called.
#include "shapes.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace {

const double kTolerance = 0.5;

BoundingBox box_of(const Point *pts, int n) {
  BoundingBox box(pts[0], pts[0]);
  for (int i = 1; i < n; ++i) box.extend(pts[i]);
  return box;
}

Point mean_of(const Point *pts, int n) {
  double x = 0, y = 0;
  for (int i = 0; i < n; ++i) {
    x += pts[i].x;
    y += pts[i].y;
  }
  return Point(x / n, y / n);
}

// Separating-axis test over the edge normals of both vertex sets (their
// convex hulls): apart when, on some axis, the projections overlap by no
// more than kTolerance.
bool polygons_overlap(const Point *a, int na, const Point *b, int nb) {
  const Point *sets[2] = {a, b};
  const int sizes[2] = {na, nb};
  for (int s = 0; s < 2; ++s) {
    for (int i = 0; i < sizes[s]; ++i) {
      const Point &p = sets[s][i], &q = sets[s][(i + 1) % sizes[s]];
      double nx = q.y - p.y, ny = p.x - q.x;
      const double len = std::sqrt(nx * nx + ny * ny);
      if (len == 0) continue;
      nx /= len;
      ny /= len;
      double lo[2] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
      double hi[2] = {-std::numeric_limits<double>::max(), -std::numeric_limits<double>::max()};
      for (int k = 0; k < 2; ++k)
        for (int j = 0; j < sizes[k]; ++j) {
          const double d = sets[k][j].x * nx + sets[k][j].y * ny;
          lo[k] = std::min(lo[k], d);
          hi[k] = std::max(hi[k], d);
        }
      if (std::min(hi[0], hi[1]) - std::max(lo[0], lo[1]) <= kTolerance) return false;
    }
  }
  return true;
}

} // namespace

Disk::Disk(const Point &c, double r, const Color &col)
    : center(c), radius(r), color(col), box(Point(c.x - r, c.y - r), Point(c.x + r, c.y + r)) {}

Triangle::Triangle(const Point &a, const Point &b, const Point &c, const Color &col)
    : pts{a, b, c}, center(mean_of(pts, 3)), color(col), box(box_of(pts, 3)) {}

Quad::Quad(const Point &a, const Point &b, const Point &c, const Point &d, const Color &col)
    : pts{a, b, c, d}, center(mean_of(pts, 4)), color(col), box(box_of(pts, 4)) {}

bool intersect(const Disk &a, const Disk &b) {
  return distance(a.getCenter(), b.getCenter()) + kTolerance < a.getRadius() + b.getRadius();
}

bool intersect(const Triangle &a, const Triangle &b) {
  const Point pa[3] = {a.getPoint(0), a.getPoint(1), a.getPoint(2)};
  const Point pb[3] = {b.getPoint(0), b.getPoint(1), b.getPoint(2)};
  return polygons_overlap(pa, 3, pb, 3);
}

bool intersect(const Quad &a, const Quad &b) {
  const Point pa[4] = {a.getPoint(0), a.getPoint(1), a.getPoint(2), a.getPoint(3)};
  const Point pb[4] = {b.getPoint(0), b.getPoint(1), b.getPoint(2), b.getPoint(3)};
  return polygons_overlap(pa, 4, pb, 4);
}

template <class T> bool intersect(const std::vector<T> &a, const T &b) {
  for (const T &s : a)
    if (intersect(s, b)) return true;
  return false;
}
template bool intersect(const std::vector<Disk> &, const Disk &);
template bool intersect(const std::vector<Triangle> &, const Triangle &);
template bool intersect(const std::vector<Quad> &, const Quad &);
