// utils.h — stand-in for the course's utils.h, written for this project's
// tests from the interface facts in ../shared/spec/course-framework.md:
// exactly the documented classes and members, nothing more (no empty box,
// no contains, no comparisons, no default Color). A bvh.h that needs more
// than this fails to compile here, as it would on the homework server.
#ifndef COURSE_UTILS_H
#define COURSE_UTILS_H

#include <ostream>
#include <string>

class Point {
public:
  Point(double x_ = 0, double y_ = 0);
  double x, y;
};
// <%5.1f %5.1f>; leaves the stream in fixed mode, precision 1.
std::ostream &operator<<(std::ostream &ostr, const Point &p);
double distance(const Point &a, const Point &b);

class Color {
public:
  Color(int r_, int g_, int b_);
  std::string getHexString() const;
  // Each channel becomes channel * f + c2.channel * (1 - f), truncated.
  void mix(Color c2, float f = 0.5);
  int r, g, b;
};

class BoundingBox {
public:
  // The default box is the point (0, 0): extending it keeps the origin.
  BoundingBox(Point min_ = Point(), Point max_ = Point());
  const Point &getMin() const { return min; }
  const Point &getMax() const { return max; }
  double dx() const;
  double dy() const;
  double getArea() const;
  // False only when the boxes are strictly apart on some axis.
  bool overlaps(const BoundingBox &other) const;
  void extend(const Point &p);
  void extend(const BoundingBox &other);
  // A translucent polygon, fill-opacity 0.25.
  void render(std::ostream &ostr, const Color &color) const;

private:
  Point min, max;
};
// [<min> <max>]
std::ostream &operator<<(std::ostream &ostr, const BoundingBox &box);

#endif
