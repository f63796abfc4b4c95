// generate.h — the random scene generator behind `bvh.out --generate`:
// random shapes of one kind (or mixed), formatted as the course's scene
// files, without overlap unless asked (each candidate is placed with a
// tree's collision test). Header-only, C++17, in namespace bvh_scene; uses
// scene.h (Random, and the reader whose numbers a placed shape must match)
// and bvh.h.
#ifndef BVH_GENERATE_H
#define BVH_GENERATE_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bvh.h"
#include "scene.h"

namespace bvh_scene {

inline double round_to(double v, double unit) { return std::round(v / unit) * unit; }

/// Formats one shape as a scene line, with the precision of the course's
/// files (one decimal for coordinates, three for radii).
inline std::string format_line(const Point &c, double radius, const Color &color) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "pt= <%5.1f %5.1f> radius= %7.3f color= {%3d %3d %3d}\n", c.x, c.y, radius,
                color.r, color.g, color.b);
  return buf;
}
inline std::string format_line(const Point *pts, int n, const Color &color) {
  std::string s;
  char buf[64];
  for (int i = 0; i < n; ++i) {
    std::snprintf(buf, sizeof buf, "pt= <%5.1f %5.1f> ", pts[i].x, pts[i].y);
    s += buf;
  }
  std::snprintf(buf, sizeof buf, "color= {%3d %3d %3d}\n", color.r, color.g, color.b);
  return s + buf;
}

/// Makes one random shape's line: centre anywhere its whole shape fits in
/// the 1000 x 1000 canvas, size uniform in [lo, hi]. Triangles have their
/// vertices at jittered thirds of a circle, quads are rotated squares; for
/// "shapes", each line is one of the three kinds, equally likely.
inline std::string random_line(const std::string &kind, Random &rng, double lo, double hi) {
  if (kind == "shapes") {
    static const char *const kinds[] = {"disks", "triangles", "quads"};
    return random_line(kinds[rng.next() % 3], rng, lo, hi);
  }
  const double size = rng.uniform(lo, hi);
  const Point c(rng.uniform(size, 1000 - size), rng.uniform(size, 1000 - size));
  const Color color(rng.channel(), rng.channel(), rng.channel());
  if (kind == "disks") return format_line(Point(round_to(c.x, 0.1), round_to(c.y, 0.1)), round_to(size, 0.001), color);
  const double pi = 3.14159265358979323846;
  const double turn = rng.uniform(0, 2 * pi);
  Point pts[4];
  const int n = kind == "triangles" ? 3 : 4;
  for (int i = 0; i < n; ++i) {
    const double angle = turn + 2 * pi * i / n + (n == 3 ? rng.uniform(-0.5, 0.5) : 0.0);
    pts[i] = Point(round_to(c.x + size * std::cos(angle), 0.1), round_to(c.y + size * std::sin(angle), 0.1));
  }
  return format_line(pts, n, color);
}

/// Adds `line` to the scene unless `no_overlap` and it touches a shape
/// already placed. The check uses the values the loader will read back.
template <class T> bool place(const std::string &line, bool no_overlap, bvh::CourseBVH<T> &placed) {
  if (!no_overlap) return true;
  LineParser in(line.data(), line.data() + line.size() - 1);
  T shape;
  std::string error;
  if (!parse_shape(in, shape, error) || placed.collision(shape)) return false;
  placed.insert(shape);
  return true;
}

/// generate_scene's default progress report: none.
struct NoGenerateProgress {
  void operator()(long /*made*/, long /*tries*/) const {}
};

/// The text of a generated scene: COUNT random lines of KIND ("disks",
/// "triangles", "quads" or "shapes"; T the matching shape type) from `seed`,
/// sizes in [lo, hi]; unless `overlap`, no two of the shapes touch. Returns
/// the number of lines made, fewer than `count` when a non-overlapping scene
/// fills up (after 1000 + 200 * count tries). `progress(made, tries)` is
/// called every 1024 tries and at the end (bvh.out's progress line).
/// max_non_overlapping() below says, before any try, when COUNT cannot fit.
template <class T, class Progress = NoGenerateProgress>
long generate_scene(const std::string &kind, long count, std::uint64_t seed, double lo, double hi, bool overlap,
                    std::string &text, Progress progress = Progress()) {
  Random rng(seed);
  // (The course's tree, so that a bvh.out of the course's width alone
  // compiles no other; only its collision answers, which are exact, matter.)
  bvh::CourseBVH<T> placed(8, bvh::CourseBVH<T>::unlimited);
  long made = 0;
  // Non-overlapping scenes fill up; give up rather than loop forever.
  const long max_tries = overlap ? count : 1000 + 200 * count;
  long tries = 0;
  for (; made < count && tries < max_tries; ++tries) {
    if ((tries & 1023) == 0) progress(made, tries);
    const std::string line = random_line(kind, rng, lo, hi);
    if (!place(line, !overlap, placed)) continue;
    text += line;
    ++made;
  }
  progress(made, tries);
  return made;
}

/// An upper bound on how many shapes of KIND, of size (circumradius) at
/// least `lo`, generate_scene can place without two touching: when COUNT is
/// larger, it provably cannot succeed, and bvh.out --generate says so at once
/// instead of trying 1000 + 200 * COUNT times.
///
/// The bound (conservative: it never refuses a scene that can exist):
///  - Every shape contains a disk of radius rho (its inscribed circle):
///    a disk its own radius; a quad (a square of circumradius R) R / sqrt 2;
///    a triangle (vertices on its circumcircle at thirds of a turn, each
///    jittered by at most 0.5 rad, so its arcs are 2pi/3 - 1, 2pi/3 and
///    2pi/3 + 1 at the extreme, where the inradius 4R sin(a/4) sin(b/4)
///    sin(c/4) of arcs a, b, c is least) 0.3775 R; "shapes" the least of the
///    three. Less 0.1 for the rounding of the written coordinates (0.1) and
///    radii (0.001) and the loader's float.
///  - Shapes that do not touch have disjoint inscribed disks, so those
///    disks' centres are at least d = 2 rho apart, and they lie in the
///    canvas shrunk by rho: a square of side s = 1000 - 2 rho (+ 0.2, the
///    rounding again).
///  - Oler's inequality (N. Oler, 1961; for any compact convex region C):
///    at most 2/sqrt(3) A(C) + P(C)/2 + 1 points of mutual distance >= 1 lie
///    in C. In units of d: N <= 2/sqrt(3) (s/d)^2 + 2 s/d + 1. (Its leading
///    term is the hexagonal packing, density pi / (2 sqrt 3); the others
///    allow for the border.)
/// Random placement jams well below this (about 55% of the hexagonal
/// density), so a COUNT under the bound may still fail, after trying.
/// Returns 1e18 (no bound) when rho is not positive (tiny sizes).
inline double max_non_overlapping(const std::string &kind, double lo) {
  const double pi = 3.14159265358979323846;
  const double third = 2 * pi / 3;
  const double triangle = 4 * std::sin((third - 1) / 4) * std::sin(third / 4) * std::sin((third + 1) / 4);
  double factor = 1; // disks
  if (kind == "quads") factor = 1 / std::sqrt(2.0);
  if (kind == "triangles" || kind == "shapes") factor = triangle;
  const double rho = factor * lo - 0.1;
  if (!(rho > 0)) return 1e18;
  const double side = 1000 - 2 * rho + 0.2;
  const double a = side / (2 * rho);
  return std::floor(2 / std::sqrt(3.0) * a * a + 2 * a + 1);
}

/// The size range bvh.out --generate uses without --size: COUNT shapes
/// cover about a fifth of the canvas (no overlap), or about twice (overlap).
inline void default_sizes(long count, bool overlap, double &lo, double &hi) {
  const double n = double(count > 0 ? count : 1);
  hi = std::min(200.0, (overlap ? 1400.0 : 420.0) / std::sqrt(n));
  lo = hi / 2;
}

} // namespace bvh_scene

#endif // BVH_GENERATE_H
