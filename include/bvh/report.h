// bvh/report.h — the course's statistics report and its picture.
//
// summarize, print_statistics (the course's exact text) and
// render_recolor. Includes core.h.
#ifndef BVH_REPORT_H
#define BVH_REPORT_H

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

#include "core.h"

namespace bvh {
namespace detail {

/// Areas are reported relative to the course's 1000 x 1000 canvas.
constexpr double kCanvasArea = 1000.0 * 1000.0;

/// What the course's report sums: node count, max depth, and the two area
/// sums of the surface area heuristic (areas in units of the canvas).
struct Summary {
  long nodes = 0;
  int max_depth = 0;
  double inner_area = 0, leaf_area = 0;
};

/// The one pass behind statistics(), sah_cost() and height(): every node in
/// pre-order, f(n, its area in canvas units) called on each.
template <class T, class Tr, int W, class F> Summary summarize(const Core<T, Tr, W> &core, F &&f) {
  Summary s;
  for_each_preorder(core.nodes, core.root, [&](int n) {
    const Info &in = core.nodes.info(n);
    const double area = in.box().area() / kCanvasArea;
    ++s.nodes;
    s.max_depth = std::max(s.max_depth, in.depth);
    if (core.nodes.node(n).is_leaf())
      s.leaf_area += area * double(in.count);
    else
      s.inner_area += area;
    f(n, area);
  });
  return s;
}
template <class T, class Tr, int W> Summary summarize(const Core<T, Tr, W> &core) {
  return summarize(core, [](int, double) {});
}

/// The course's report: with `print_tree`, one line per node in pre-order,
/// then node count, max depth and the two area sums.
template <class T, class Tr, int W> void print_statistics(const Core<T, Tr, W> &core, std::ostream &ostr, bool print_tree) {
  std::string line;
  char buf[64];
  const Summary s = summarize(core, [&](int n, double area) {
    if (!print_tree) return;
    const Info &in = core.nodes.info(n);
    const Node<W> &node = core.nodes.node(n);
    // The course's stream is not yet in fixed mode when it prints the
    // root, so the root's area shows 3 significant digits, the rest 3
    // decimals.
    std::snprintf(buf, sizeof buf, n == core.root ? "%.3g" : "%.3f", area);
    line.assign(std::size_t(3) * std::size_t(in.depth), ' ');
    line += node.is_leaf() ? "leaf area=" : "inner area=";
    line += buf;
    line += ' ';
    append_box(line, in.box());
    if (node.is_leaf()) {
      line += " elements:";
      for (const T &shape : core.leaves.shapes(node)) {
        line += ' ';
        append_box(line, box_of(core.traits, shape));
      }
    }
    line += '\n';
    ostr << line;
  });
  std::snprintf(buf, sizeof buf, "node count:      %7ld\n", s.nodes);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "max depth:       %7d\n", s.max_depth);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "inner node area: %7.3f\n", s.inner_area);
  ostr << buf;
  std::snprintf(buf, sizeof buf, "leaf node area:  %7.3f\n", s.leaf_area);
  ostr << buf;
  ostr.flush();
}

/// The course's picture: every node's box drawn translucently (root grey,
/// its children red, green and blue, deeper children blended 2/3 parent
/// and 1/3 their own primary), every shape recoloured to its leaf's colour.
/// Boxes are drawn by the shape library's BoundingBox::render; colours are
/// made with Color(r, g, b) and given to T::setColor.
template <class T, class Tr, int W> void render_recolor(Core<T, Tr, W> &core, std::ostream &ostr) {
  if (core.root < 0) return;
  struct Rgb {
    int r, g, b;
  };
  // The course's three first, then one more hue per child up to kMaxWidth.
  static const Rgb primary[kMaxWidth] = {{255, 0, 0},   {0, 255, 0},   {0, 0, 255}, {255, 255, 0},
                                         {0, 255, 255}, {255, 0, 255}, {255, 128, 0}, {128, 0, 255}};
  // Channels mixed here, as Color::mix would (the course's mix returns
  // nothing and this project's returns the mix: neither is relied on).
  auto blend = [](const Rgb &parent, const Rgb &own) {
    const float f = 2.0f / 3.0f;
    return Rgb{int(parent.r * f + own.r * (1 - f)), int(parent.g * f + own.g * (1 - f)),
               int(parent.b * f + own.b * (1 - f))};
  };
  std::vector<Rgb> rgb(core.nodes.capacity());
  rgb[std::size_t(core.root)] = Rgb{128, 128, 128};
  for_each_preorder(core.nodes, core.root, [&](int n) {
    const Info &in = core.nodes.info(n);
    Rgb &own = rgb[std::size_t(n)];
    if (in.parent >= 0)
      own = in.parent == core.root ? primary[in.child_index]
                                   : blend(rgb[std::size_t(in.parent)], primary[in.child_index]);
    const Color color(own.r, own.g, own.b);
    const Box &b = in.box();
    BoundingBox(Point(b.x0, b.y0), Point(b.x1, b.y1)).render(ostr, color);
    Node<W> &node = core.nodes.node(n);
    if (node.is_leaf())
      for (T &s : core.leaves.shapes(node)) s.setColor(color);
  });
}
} // namespace detail
} // namespace bvh

#endif // BVH_REPORT_H
