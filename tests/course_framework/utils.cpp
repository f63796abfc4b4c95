// utils.cpp — stand-in for the course's utils.cpp (see utils.h).
#include "utils.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>

Point::Point(double x_, double y_) : x(x_), y(y_) {}

std::ostream &operator<<(std::ostream &ostr, const Point &p) {
  ostr << std::fixed << std::setprecision(1) << "<" << std::setw(5) << p.x << " " << std::setw(5) << p.y << ">";
  return ostr;
}

double distance(const Point &a, const Point &b) { return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y)); }

Color::Color(int r_, int g_, int b_) : r(r_), g(g_), b(b_) {}

std::string Color::getHexString() const {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%02x%02x%02x", r & 255, g & 255, b & 255);
  return buf;
}

void Color::mix(Color c2, float f) {
  r = int(r * f + c2.r * (1 - f));
  g = int(g * f + c2.g * (1 - f));
  b = int(b * f + c2.b * (1 - f));
}

BoundingBox::BoundingBox(Point min_, Point max_) : min(min_), max(max_) {}
double BoundingBox::dx() const { return max.x - min.x; }
double BoundingBox::dy() const { return max.y - min.y; }
double BoundingBox::getArea() const { return dx() * dy(); }

bool BoundingBox::overlaps(const BoundingBox &o) const {
  return !(o.min.x > max.x || min.x > o.max.x || o.min.y > max.y || min.y > o.max.y);
}

void BoundingBox::extend(const Point &p) {
  min.x = std::min(min.x, p.x);
  min.y = std::min(min.y, p.y);
  max.x = std::max(max.x, p.x);
  max.y = std::max(max.y, p.y);
}

void BoundingBox::extend(const BoundingBox &o) {
  extend(o.min);
  extend(o.max);
}

void BoundingBox::render(std::ostream &ostr, const Color &color) const {
  ostr << "<rect x=\"" << min.x << "\" y=\"" << min.y << "\" width=\"" << dx() << "\" height=\"" << dy()
       << "\" style=\"fill:#" << color.getHexString() << ";fill-opacity:0.25\" />\n";
}

std::ostream &operator<<(std::ostream &ostr, const BoundingBox &box) {
  return ostr << "[" << box.getMin() << " " << box.getMax() << "]";
}
