// svg.h — draws a BVH and its shapes as a 1000 x 1000 SVG picture, saved as
// an .html file (as the course does) that any browser opens.
//
//   bvh::BVH<bvh::Triangle> tree(4, 2);
//   tree.construct(triangles);
//   std::string error;
//   if (!write_svg("out.html", tree, /*visualize=*/true, &error))
//     std::cerr << error << "\n";
//
// O(n) in the number of shapes and nodes. The file is written beside its
// destination under a temporary name and renamed into place only when
// complete, so a failure never leaves half a picture behind.
#ifndef BVH_SVG_H
#define BVH_SVG_H

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <ostream>
#include <string>

#include "bvh.h"
#include "shapes.h"

namespace bvh {

/// Opening of the document: XML declaration and the <svg> element. The
/// viewBox and the max-width/max-height style let a browser shrink the
/// 1000 x 1000 picture to fit a smaller window (tests/browser_check.py
/// renders it at two window sizes and finds the whole frame each time).
inline void render_start(std::ostream &ostr) {
  ostr << "<?xml version=\"1.0\" standalone=\"no\"?>\n"
          "<svg width=\"1000\" height=\"1000\" viewBox=\"0 0 1000 1000\" "
          "style=\"max-width:95vw;max-height:95vh\" version=\"1.1\" "
          "xmlns=\"http://www.w3.org/2000/svg\">\n";
}

/// A disk as a filled <circle>.
inline void render_shape(std::ostream &ostr, const Disk &d) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "<circle cx=\"%g\" cy=\"%g\" r=\"%g\" style=\"fill:#%s\" />\n", d.getCenter().x,
                d.getCenter().y, d.getRadius(), d.getColor().getHexString().c_str());
  ostr << buf;
}

/// A triangle or quad as a filled <polygon>.
template <int N> void render_shape(std::ostream &ostr, const Polygon<N> &p) {
  char buf[80];
  ostr << "<polygon points=\"";
  for (int i = 0; i < N; ++i) {
    std::snprintf(buf, sizeof buf, "%s%g,%g", i ? " " : "", p.getPoint(i).x, p.getPoint(i).y);
    ostr << buf;
  }
  ostr << "\" style=\"fill:#" << p.getColor().getHexString() << "\" />\n";
}

/// A shape of a mixed scene, drawn as its kind is.
inline void render_shape(std::ostream &ostr, const Shape &s) {
  s.visit([&](const auto &shape) { render_shape(ostr, shape); });
}

/// Closing of the document: a black frame around the canvas.
inline void render_end(std::ostream &ostr) {
  ostr << "<rect x=\"1\" y=\"1\" width=\"998\" height=\"998\" fill=\"none\" stroke=\"black\" "
          "stroke-width=\"3\" />\n"
          "</svg>\n";
}

/// The temporary name under which write_svg writes `path` (bvh.out's
/// signal handler removes it).
inline std::string partial_path(const std::string &path) { return path + ".partial"; }

/// Writes the whole picture of `tree` to `path`. With `visualize`, node
/// boxes are drawn and shapes recoloured by leaf (the tree's colours change).
/// Returns false and sets `*error` when the file cannot be written; the
/// destination is then left as it was.
template <class T, class Tr, int W>
bool write_svg(const std::string &path, bvh::BVH<T, Tr, W> &tree, bool visualize, std::string *error = nullptr) {
  const std::string temp = partial_path(path);
  {
    std::ofstream ostr(temp, std::ios::binary | std::ios::trunc);
    if (!ostr) {
      if (error) *error = path + ": cannot write: " + std::strerror(errno);
      return false;
    }
    render_start(ostr);
    if (visualize) tree.render_recolor(ostr);
    for (const T &shape : tree) render_shape(ostr, shape);
    render_end(ostr);
    ostr.flush();
    if (!ostr) {
      if (error) *error = path + ": write failed";
      ostr.close();
      std::remove(temp.c_str());
      return false;
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    if (error) *error = path + ": cannot write: " + std::strerror(errno);
    std::remove(temp.c_str());
    return false;
  }
  return true;
}

} // namespace bvh


#endif // BVH_SVG_H
