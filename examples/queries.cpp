// examples/queries.cpp — the queries of docs/library.txt (QUERIES AND ALL PAIRS):
// shapes in a box, shapes meeting a shape, the nearest shape to a point and
// the first shape on a ray, each compared with a scan of the vector (exit
// status 1 if one differs).
#include <cmath>
#include <iostream>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/distance.h> // distance(point, shape) and ray_hit(), for the scans below
#include <bvh/scene.h>    // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(3);
  std::vector<Triangle> triangles;
  for (int i = 0; i < 2000; ++i) {
    const Point c(rng.uniform(20, 980), rng.uniform(20, 980));
    triangles.push_back(Triangle(Point(c.x - 8, c.y - 5), Point(c.x + 8, c.y - 5), Point(c.x, c.y + 9)));
  }
  const Triangle probe(Point(400, 400), Point(480, 410), Point(430, 470));
  // The snippet prints to std::cout; the lines are caught here and counted.
  std::ostringstream printed;
  std::streambuf *const screen = std::cout.rdbuf(printed.rdbuf());
  // [readme:queries]
  BVH<Triangle> tree;  tree.construct(triangles);
  // every shape whose box meets a box; return false from f to stop early
  tree.query(BoundingBox(Point(0, 0), Point(100, 100)),
             [](const Triangle &t) { std::cout << t.getBox() << "\n"; });
  // every shape that intersects a shape (exact), into a vector
  std::vector<Triangle> hits;
  tree.query_into(probe, std::back_inserter(hits));
  // the nearest shape to a point, and its distance (0 inside a shape)
  double d;  const Triangle *near = tree.nearest(Point(500, 500), &d);
  // the first shape a ray meets (ray tracing), and where: origin + t * dir
  double t;  const Triangle *first = tree.first_hit(Point(0, 500), Point(1, 0), &t);
  // [end]
  std::cout.rdbuf(screen);
  std::size_t in_box = 0;
  for (char c : printed.str()) in_box += c == '\n';
  // The same questions by scans.
  const BoundingBox box(Point(0, 0), Point(100, 100));
  std::size_t scan_box = 0, scan_hits = 0;
  double scan_d = std::numeric_limits<double>::infinity(), scan_t = std::numeric_limits<double>::infinity();
  for (const Triangle &s : triangles) {
    const BoundingBox b = s.getBox();
    scan_box += b.getMin().x <= box.getMax().x && box.getMin().x <= b.getMax().x && b.getMin().y <= box.getMax().y &&
                box.getMin().y <= b.getMax().y;
    scan_hits += intersect(s, probe);
    scan_d = std::min(scan_d, distance(Point(500, 500), s));
    scan_t = std::min(scan_t, ray_hit(Point(0, 500), Point(1, 0), s));
  }
  std::cout << "queries: in box " << in_box << " (scan " << scan_box << "), meeting the probe " << hits.size()
            << " (scan " << scan_hits << "), nearest at " << d << " (scan " << scan_d << "), first hit at t = "
            << (first ? t : -1) << " (scan " << scan_t << ")\n";
  const bool ok = in_box == scan_box && hits.size() == scan_hits && near && d == scan_d && first && t == scan_t &&
                  distance(Point(500, 500), *near) == d && scan_box > 0 && scan_hits > 0;
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}
