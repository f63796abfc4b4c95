// shapes.h — stand-in for the course's shapes.h, written for this project's
// tests from ../shared/spec/course-framework.md: no default constructors, no
// operator==, stored tight boxes and centres, and the intersection
// predicates declared here but defined (not inline) in shapes.cpp.
#ifndef COURSE_SHAPES_H
#define COURSE_SHAPES_H

#include <vector>

#include "utils.h"

class Disk {
public:
  Disk(const Point &center, double radius, const Color &color);
  int numPoints() const { return 1; }
  const Point &getPoint(int) const { return center; }
  const Point &getCenter() const { return center; }
  double getRadius() const { return radius; }
  const Color &getColor() const { return color; }
  const BoundingBox &getBox() const { return box; }
  void setColor(const Color &c) { color = c; }

private:
  Point center;
  double radius;
  Color color;
  BoundingBox box;
};

class Triangle {
public:
  Triangle(const Point &a, const Point &b, const Point &c, const Color &color);
  int numPoints() const { return 3; }
  const Point &getPoint(int i) const { return pts[i]; }
  const Point &getCenter() const { return center; }
  const Color &getColor() const { return color; }
  const BoundingBox &getBox() const { return box; }
  void setColor(const Color &c) { color = c; }

private:
  Point pts[3];
  Point center;
  Color color;
  BoundingBox box;
};

class Quad {
public:
  Quad(const Point &a, const Point &b, const Point &c, const Point &d, const Color &color);
  int numPoints() const { return 4; }
  const Point &getPoint(int i) const { return pts[i]; }
  const Point &getCenter() const { return center; }
  const Color &getColor() const { return color; }
  const BoundingBox &getBox() const { return box; }
  void setColor(const Color &c) { color = c; }

private:
  Point pts[4];
  Point center;
  Color color;
  BoundingBox box;
};

// Deliberately not exact (shapes.cpp): shapes must overlap by more than a
// tolerance to count, so touching and barely-overlapping pairs do not.
bool intersect(const Disk &a, const Disk &b);
bool intersect(const Triangle &a, const Triangle &b);
bool intersect(const Quad &a, const Quad &b);
// True when `b` intersects some shape of `a` (a brute-force scan).
template <class T> bool intersect(const std::vector<T> &a, const T &b);

#endif
