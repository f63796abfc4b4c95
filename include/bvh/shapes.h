// shapes.h — the geometry the BVH stores: Point, Color, BoundingBox, Disk,
// Triangle and Quad, with the names and printing of the course's handout
// (CSCI-1200 Homework 8), so code written against the handout compiles here;
// and Shape, any one of the three, for scenes that mix them.
//
//   Triangle t(Point(0, 0), Point(10, 0), Point(0, 10), Color(255, 0, 0));
//   BoundingBox b = t.getBox();          // [<  0.0   0.0> < 10.0  10.0>]
//   std::cout << b << " " << b.getArea() << "\n";
//   Point c = t.getCenter();             // mean of the vertices
//   bool same = (t == Triangle(t));      // geometry and colour
//
// Every operation here is O(1). The exact intersection predicates between
// shapes live in intersect.h, not here.
#ifndef BVH_SHAPES_H
#define BVH_SHAPES_H

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>
#include <string>
#include <utility>
#include <variant>

// Everything here is in namespace bvh, and nothing at global scope: the
// course's unqualified names (Point, Disk, ...) are given by the top-level
// shapes.h of the course's layout, not by the library.
namespace bvh {

/// A point (or vector) in the plane.
class Point {
public:
  /// Builds the point (x, y).
  Point(double x_ = 0, double y_ = 0) : x(x_), y(y_) {}
  double x; ///< horizontal coordinate (SVG: grows to the right)
  double y; ///< vertical coordinate (SVG: grows downwards)
  /// Exact comparison of both coordinates.
  friend bool operator==(const Point &a, const Point &b) { return a.x == b.x && a.y == b.y; }
  friend bool operator!=(const Point &a, const Point &b) { return !(a == b); }
};

/// Prints `<%5.1f %5.1f>`, the course's `std::setw(5)` fixed precision-1
/// form, without touching the stream's own format flags.
inline std::ostream &operator<<(std::ostream &ostr, const Point &p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "<%5.1f %5.1f>", p.x, p.y);
  return ostr << buf;
}

/// Euclidean distance between two points.
inline double distance(const Point &a, const Point &b) { return std::hypot(a.x - b.x, a.y - b.y); }

/// An RGB colour with integer channels 0-255.
class Color {
public:
  /// Builds the colour (r, g, b); the default is white.
  Color(int r_ = 255, int g_ = 255, int b_ = 255) : r(r_), g(g_), b(b_) {}
  int r; ///< red channel
  int g; ///< green channel
  int b; ///< blue channel
  /// Six lowercase hex digits, `rrggbb`, as used in an SVG `fill:#`.
  std::string getHexString() const {
    char buf[16];
    std::snprintf(buf, sizeof buf, "%02x%02x%02x", clamp(r), clamp(g), clamp(b));
    return buf;
  }
  /// Blend: each channel becomes `channel*f + other.channel*(1-f)`, truncated.
  Color mix(const Color &other, float f) const {
    return Color(int(r * f + other.r * (1 - f)), int(g * f + other.g * (1 - f)),
                 int(b * f + other.b * (1 - f)));
  }
  friend bool operator==(const Color &a, const Color &c) { return a.r == c.r && a.g == c.g && a.b == c.b; }
  friend bool operator!=(const Color &a, const Color &c) { return !(a == c); }

private:
  static int clamp(int v) { return v < 0 ? 0 : (v > 255 ? 255 : v); }
};

/// An axis-aligned rectangle [min, max]. A default-built box is empty
/// (min = +inf, max = -inf) so that `extend` can grow it from nothing.
class BoundingBox {
public:
  /// The empty box.
  BoundingBox()
      : min_(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()),
        max_(-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()) {}
  /// The box spanned by two corners, given in any order.
  BoundingBox(const Point &a, const Point &b)
      : min_(std::min(a.x, b.x), std::min(a.y, b.y)), max_(std::max(a.x, b.x), std::max(a.y, b.y)) {}

  /// Lower-left corner (smallest x and y).
  const Point &getMin() const { return min_; }
  /// Upper-right corner (largest x and y).
  const Point &getMax() const { return max_; }
  /// True for the box that contains nothing.
  bool empty() const { return min_.x > max_.x || min_.y > max_.y; }
  /// Width (0 for an empty box).
  double dx() const { return empty() ? 0 : max_.x - min_.x; }
  /// Height (0 for an empty box).
  double dy() const { return empty() ? 0 : max_.y - min_.y; }
  /// Area (0 for an empty box).
  double getArea() const { return dx() * dy(); }
  /// True when the boxes share at least one point: touching counts.
  bool overlaps(const BoundingBox &o) const {
    return min_.x <= o.max_.x && o.min_.x <= max_.x && min_.y <= o.max_.y && o.min_.y <= max_.y;
  }
  /// True when `o` lies entirely inside this box (boundaries included).
  bool contains(const BoundingBox &o) const {
    return min_.x <= o.min_.x && min_.y <= o.min_.y && o.max_.x <= max_.x && o.max_.y <= max_.y;
  }
  /// Grows the box to include the point.
  void extend(const Point &p) {
    min_.x = std::min(min_.x, p.x);
    min_.y = std::min(min_.y, p.y);
    max_.x = std::max(max_.x, p.x);
    max_.y = std::max(max_.y, p.y);
  }
  /// Grows the box to include another box (an empty one changes nothing).
  void extend(const BoundingBox &o) {
    min_.x = std::min(min_.x, o.min_.x);
    min_.y = std::min(min_.y, o.min_.y);
    max_.x = std::max(max_.x, o.max_.x);
    max_.y = std::max(max_.y, o.max_.y);
  }
  /// Draws the box as a translucent SVG polygon filled with `color`.
  void render(std::ostream &ostr, const Color &color) const {
    if (empty()) return;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "<polygon points=\"%.3f,%.3f %.3f,%.3f %.3f,%.3f %.3f,%.3f\" "
                  "style=\"fill:#%s;fill-opacity:0.25;stroke:#%s;stroke-width:1\" />\n",
                  min_.x, min_.y, max_.x, min_.y, max_.x, max_.y, min_.x, max_.y,
                  color.getHexString().c_str(), color.getHexString().c_str());
    ostr << buf;
  }
  friend bool operator==(const BoundingBox &a, const BoundingBox &b) {
    return a.min_ == b.min_ && a.max_ == b.max_;
  }
  friend bool operator!=(const BoundingBox &a, const BoundingBox &b) { return !(a == b); }

private:
  Point min_, max_;
};

/// Prints `[<min> <max>]`, as in the course's tree listing.
inline std::ostream &operator<<(std::ostream &ostr, const BoundingBox &box) {
  return ostr << "[" << box.getMin() << " " << box.getMax() << "]";
}

/// A closed disk: every point at distance <= radius from the centre.
/// A zero radius is a single point.
class Disk {
public:
  /// Builds the disk; the default is a white point at the origin.
  Disk(const Point &center = Point(), double radius = 0, const Color &color = Color())
      : center_(center), radius_(radius), color_(color) {}
  /// Always 1: the centre is the disk's only point.
  static constexpr int numPoints() { return 1; }
  /// The centre (any index: a disk has one point).
  const Point &getPoint(int) const { return center_; }
  /// The centre.
  const Point &getCenter() const { return center_; }
  /// The radius.
  double getRadius() const { return radius_; }
  /// The fill colour.
  const Color &getColor() const { return color_; }
  /// Changes the fill colour.
  void setColor(const Color &c) { color_ = c; }
  /// The tight box [centre - r, centre + r].
  BoundingBox getBox() const {
    return BoundingBox(Point(center_.x - radius_, center_.y - radius_),
                       Point(center_.x + radius_, center_.y + radius_));
  }
  /// Same centre, radius and colour.
  friend bool operator==(const Disk &a, const Disk &b) {
    return a.center_ == b.center_ && a.radius_ == b.radius_ && a.color_ == b.color_;
  }
  friend bool operator!=(const Disk &a, const Disk &b) { return !(a == b); }

private:
  Point center_;
  double radius_;
  Color color_;
};

/// A closed polygon with N vertices (N = 3: Triangle, N = 4: Quad). The
/// vertices may come in either winding; degenerate (collinear or repeated)
/// vertices are allowed and mean a segment or a point.
template <int N> class Polygon {
public:
  /// The number of vertices.
  static constexpr int numPoints() { return N; }
  /// Vertex i, 0 <= i < N.
  const Point &getPoint(int i) const { return pts_[i]; }
  /// Mean of the vertices: the centroid the course sorts by.
  Point getCenter() const {
    double sx = 0, sy = 0;
    for (int i = 0; i < N; ++i) {
      sx += pts_[i].x;
      sy += pts_[i].y;
    }
    return Point(sx / N, sy / N);
  }
  /// The fill colour.
  const Color &getColor() const { return color_; }
  /// Changes the fill colour.
  void setColor(const Color &c) { color_ = c; }
  /// The tight box of the vertices.
  BoundingBox getBox() const {
    BoundingBox box(pts_[0], pts_[0]);
    for (int i = 1; i < N; ++i) box.extend(pts_[i]);
    return box;
  }
  /// Same vertices in the same order, and the same colour.
  friend bool operator==(const Polygon &a, const Polygon &b) {
    for (int i = 0; i < N; ++i)
      if (a.pts_[i] != b.pts_[i]) return false;
    return a.color_ == b.color_;
  }
  friend bool operator!=(const Polygon &a, const Polygon &b) { return !(a == b); }

protected:
  Polygon() = default;
  Point pts_[N];
  Color color_;
};

/// A closed triangle (its boundary and inside).
class Triangle : public Polygon<3> {
public:
  /// Builds the triangle a-b-c; the default is a white point at the origin.
  Triangle(const Point &a = Point(), const Point &b = Point(), const Point &c = Point(),
           const Color &color = Color()) {
    pts_[0] = a;
    pts_[1] = b;
    pts_[2] = c;
    color_ = color;
  }
};

/// A closed quadrilateral a-b-c-d: a simple polygon, convex or not.
class Quad : public Polygon<4> {
public:
  /// Builds the quad a-b-c-d; the default is a white point at the origin.
  Quad(const Point &a = Point(), const Point &b = Point(), const Point &c = Point(),
       const Point &d = Point(), const Color &color = Color()) {
    pts_[0] = a;
    pts_[1] = b;
    pts_[2] = c;
    pts_[3] = d;
    color_ = color;
  }
};

/// Any one shape: a Disk, a Triangle or a Quad. BVH<Shape> holds a scene
/// that mixes the three kinds (a .shapes file); every member forwards to the
/// shape held, so a Shape has the box and centre, is drawn (svg.h) and
/// intersects (intersect.h) exactly as the shape itself.
///
///   Shape s = Triangle(Point(0, 0), Point(10, 0), Point(0, 10));
///   if (const Triangle *t = s.triangle()) std::cout << t->getPoint(1);
///   s.visit([](const auto &shape) { std::cout << shape.getBox(); });
class Shape {
public:
  /// Which shape a Shape holds; also the order of Shape's alternatives.
  enum class Kind { disk, triangle, quad };
  /// A white point (a Disk of radius 0) at the origin.
  Shape() = default;
  /// Holds the disk. Implicit: a Disk is a Shape.
  Shape(const Disk &d) : shape_(d) {}
  /// Holds the triangle. Implicit: a Triangle is a Shape.
  Shape(const Triangle &t) : shape_(t) {}
  /// Holds the quad. Implicit: a Quad is a Shape.
  Shape(const Quad &q) : shape_(q) {}

  /// The kind of shape held.
  Kind kind() const { return Kind(shape_.index()); }
  /// The shape held as a K (Disk, Triangle or Quad), or nullptr when it is
  /// another kind.
  template <class K> const K *get() const { return std::get_if<K>(&shape_); }
  /// The disk held, or nullptr when it is another kind.
  const Disk *disk() const { return get<Disk>(); }
  /// The triangle held, or nullptr when it is another kind.
  const Triangle *triangle() const { return get<Triangle>(); }
  /// The quad held, or nullptr when it is another kind.
  const Quad *quad() const { return get<Quad>(); }

  /// f(shape held), as a `const Disk &`, `const Triangle &` or `const Quad &`.
  // A switch, not std::visit: the variant is never valueless (its
  // alternatives copy without throwing), and this inlines into hot loops.
  template <class F> decltype(auto) visit(F &&f) const {
    switch (shape_.index()) {
    case 0: return std::forward<F>(f)(*std::get_if<0>(&shape_));
    case 1: return std::forward<F>(f)(*std::get_if<1>(&shape_));
    default: return std::forward<F>(f)(*std::get_if<2>(&shape_));
    }
  }

  /// The held shape's number of points: 1 (a disk's centre), 3 or 4.
  int numPoints() const {
    return visit([](const auto &s) { return s.numPoints(); });
  }
  /// The held shape's point i, 0 <= i < numPoints().
  const Point &getPoint(int i) const {
    return visit([i](const auto &s) -> const Point & { return s.getPoint(i); });
  }
  /// The held shape's tight box.
  BoundingBox getBox() const {
    return visit([](const auto &s) { return s.getBox(); });
  }
  /// The held shape's centre: a disk's centre, a polygon's mean vertex.
  Point getCenter() const {
    return visit([](const auto &s) { return Point(s.getCenter()); });
  }
  /// The held shape's fill colour.
  const Color &getColor() const {
    return visit([](const auto &s) -> const Color & { return s.getColor(); });
  }
  /// Changes the held shape's fill colour.
  void setColor(const Color &c) {
    std::visit([&](auto &s) { s.setColor(c); }, shape_);
  }
  /// Same kind, and equal as shapes of that kind.
  friend bool operator==(const Shape &a, const Shape &b) { return a.shape_ == b.shape_; }
  friend bool operator!=(const Shape &a, const Shape &b) { return !(a == b); }

private:
  std::variant<Disk, Triangle, Quad> shape_;
};

} // namespace bvh


#endif // BVH_SHAPES_H
