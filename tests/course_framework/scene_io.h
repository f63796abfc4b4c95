// scene_io.h — the stand-in framework's scene loader and picture writer,
// shared by its main.cpp and brute.cpp (test helpers, not part of what a
// student submits). Included after bvh.h, so bvh.h cannot lean on it.
//
// The loader reads each number into a float and widens it to double, as
// ../shared/README.md says the course's loader does.
#ifndef COURSE_SCENE_IO_H
#define COURSE_SCENE_IO_H

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "shapes.h"

namespace scene_io {

struct Fields {
  std::vector<Point> pts;
  std::vector<double> radius;
  std::vector<int> color;
};

[[noreturn]] inline void fail(const std::string &where, const std::string &what) {
  std::cerr << where << ": " << what << "\n";
  std::exit(1);
}

inline Fields parse_line(std::string line, const std::string &where) {
  for (char &c : line)
    if (c == '<' || c == '>' || c == '{' || c == '}') c = ' ';
  std::istringstream in(line);
  Fields f;
  std::string key;
  while (in >> key) {
    float a, b, c;
    if (key == "pt=") {
      if (!(in >> a >> b)) fail(where, "bad point");
      f.pts.push_back(Point(a, b));
    } else if (key == "radius=") {
      if (!(in >> a)) fail(where, "bad radius");
      f.radius.push_back(a);
    } else if (key == "color=") {
      if (!(in >> a >> b >> c)) fail(where, "bad color");
      f.color = {int(a), int(b), int(c)};
    } else {
      fail(where, "unknown field " + key);
    }
  }
  if (f.color.size() != 3) fail(where, "no color");
  return f;
}

inline Disk make(const Fields &f, const Disk *, const std::string &where) {
  if (f.pts.size() != 1 || f.radius.size() != 1) fail(where, "a disk needs one pt= and one radius=");
  return Disk(f.pts[0], f.radius[0], Color(f.color[0], f.color[1], f.color[2]));
}
inline Triangle make(const Fields &f, const Triangle *, const std::string &where) {
  if (f.pts.size() != 3 || !f.radius.empty()) fail(where, "a triangle needs three pt=");
  return Triangle(f.pts[0], f.pts[1], f.pts[2], Color(f.color[0], f.color[1], f.color[2]));
}
inline Quad make(const Fields &f, const Quad *, const std::string &where) {
  if (f.pts.size() != 4 || !f.radius.empty()) fail(where, "a quad needs four pt=");
  return Quad(f.pts[0], f.pts[1], f.pts[2], f.pts[3], Color(f.color[0], f.color[1], f.color[2]));
}

/// Every shape of the file, in order; exits with `file:line: why` on error.
template <class T> std::vector<T> load(const std::string &path) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot open");
  std::vector<T> shapes;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::string where = path + ":" + std::to_string(n);
    shapes.push_back(make(parse_line(line, where), static_cast<const T *>(nullptr), where));
  }
  return shapes;
}

inline void write_start(std::ostream &out) {
  out << "<html><body>\n<svg width=\"1000\" height=\"1000\" xmlns=\"http://www.w3.org/2000/svg\">\n";
}
inline void write_end(std::ostream &out) { out << "</svg>\n</body></html>\n"; }

/// One shape per line, in the same form as the project's svg.h, so that the
/// tests can compare shape sets across the two programs.
inline void write_shape(std::ostream &out, const Disk &d) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "<circle cx=\"%g\" cy=\"%g\" r=\"%g\" style=\"fill:#%s\" />\n", d.getCenter().x,
                d.getCenter().y, d.getRadius(), d.getColor().getHexString().c_str());
  out << buf;
}
template <class P> void write_shape(std::ostream &out, const P &p) {
  out << "<polygon points=\"";
  char buf[80];
  for (int i = 0; i < p.numPoints(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%g,%g", i ? " " : "", p.getPoint(i).x, p.getPoint(i).y);
    out << buf;
  }
  out << "\" style=\"fill:#" << p.getColor().getHexString() << "\" />\n";
}

} // namespace scene_io

#endif
