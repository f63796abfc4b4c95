// bench/builders.cpp — `make bench-builders`: which way of building the tree
// is best (the handout's extra-credit question). For each scene, four
// builders over the same shapes:
//   course bulk   construct() with the course's rule
//   SAH bulk      construct() with BuildRule::sah (binned SAH, bvh.h)
//   insert random insert() one at a time, shapes in a fixed shuffled order
//   insert sorted insert() one at a time, shapes sorted by centre x
// and for each: the SAH cost (inner + leaf area as statistics() prints
// them), the height, the build time, and the time of 100,000 collision()
// probes (small disks spread over the canvas). The first table is the
// course's tree, BVH(4, unlimited) at width 3; the second builds the same
// trees at widths 2, 3, 4 and 8 (split_threshold 4, and 16 at width 8).
// The course's SAH cost charges one unit per inner node a probe enters,
// whatever its width, so it compares builders at one width; across widths
// compare the probe time. Writes the tables to stdout and a bar chart of
// the first table's SAH costs, relative to the course bulk build, to the
// SVG file named by its argument.
#include <bvh/bvh.h>
#include <bvh/scene.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

#include <chrono>
#include <fstream>
#include <random>
#include <sstream>

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double sah_cost(const std::string &stats) {
  const double inner = std::atof(stats.c_str() + stats.find("inner node area:") + 16);
  const double leaf = std::atof(stats.c_str() + stats.find("leaf node area:") + 15);
  return inner + leaf;
}

struct Row {
  std::string scene, builder;
  double sah, build_s, probe_s;
  int height;
  int width, split;
  std::size_t nodes;
  double children_fill, leaf_fill;
};

template <class T, int W = 3>
std::vector<Row> evaluate(const std::string &scene, const std::vector<T> &shapes, int split = 4) {
  using Tree = BVH<T, bvh::shape_traits<T>, W>;
  std::vector<Row> rows;
  std::vector<T> shuffled = shapes, sorted = shapes;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(7));
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const T &a, const T &b) { return a.getCenter().x < b.getCenter().x; });
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> xy(0, 1000);
  std::vector<Disk> probes;
  for (int i = 0; i < 100000; ++i) {
    const double x = xy(rng), y = xy(rng);
    probes.emplace_back(Point(x, y), 1.0, Color(0, 0, 0));
  }
  const char *names[] = {"course bulk", "SAH bulk", "insert random", "insert sorted"};
  for (int b = 0; b < 4; ++b) {
    Tree tree(split, Tree::unlimited);
    const double start = now();
    if (b == 0) tree.construct(shapes);
    if (b == 1) {
      tree.set_build_rule(Tree::BuildRule::sah);
      tree.construct(shapes);
    }
    if (b == 2)
      for (const T &s : shuffled) tree.insert(s);
    if (b == 3)
      for (const T &s : sorted) tree.insert(s);
    const double built = now() - start;
    // Probes of the scene's own kind: a probe disk's box, as a tiny shape
    // of kind T centred there (for disks, the disk itself).
    std::size_t hits = 0;
    const double probe_start = now();
    for (const Disk &p : probes) {
      if constexpr (std::is_same<T, Disk>::value) {
        hits += tree.collision(p);
      } else {
        const Point c = p.getCenter();
        bool hit = false;
        tree.query(BoundingBox(Point(c.x - 1, c.y - 1), Point(c.x + 1, c.y + 1)), [&](const T &) {
          hit = true;
          return false;
        });
        hits += hit;
      }
    }
    const double probed = now() - probe_start;
    std::ostringstream stats;
    tree.statistics(stats, false);
    const auto fill = tree.fill();
    rows.push_back({scene, names[b], sah_cost(stats.str()), built, probed, tree.height(), W, split,
                    fill.inner + fill.leaves, fill.children, fill.shapes});
    (void)hits;
  }
  return rows;
}

std::vector<Disk> random_disks(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(0, 1000);
  const double r = std::min(20.0, 300.0 / std::sqrt(double(n)));
  std::uniform_real_distribution<double> radius(r / 2, r);
  std::vector<Disk> v;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = xy(rng), y = xy(rng);
    v.emplace_back(Point(x, y), radius(rng), Color(0, 0, 0));
  }
  return v;
}

/// The same scene at every width the command line offers: widths 2, 3, 4
/// and 8 at split_threshold 4, and width 8 at 16 (the fastest in make
/// bench-widths).
template <class T> void every_width(const std::string &scene, const std::vector<T> &shapes, std::vector<Row> &rows) {
  const std::vector<Row> parts[] = {evaluate<T, 2>(scene, shapes), evaluate<T, 3>(scene, shapes),
                                    evaluate<T, 4>(scene, shapes), evaluate<T, 8>(scene, shapes),
                                    evaluate<T, 8>(scene, shapes, 16)};
  // Grouped by builder, so that each builder's widths stand together.
  for (std::size_t b = 0; b < parts[0].size(); ++b)
    for (const std::vector<Row> &part : parts) rows.push_back(part[b]);
}

template <class T>
void course_scene(const std::string &dir, const std::string &name, std::vector<Row> &rows, std::vector<Row> &wide) {
  std::vector<T> shapes;
  std::string error;
  if (!bvh_scene::load_scene(dir + "/" + name, shapes, error)) {
    std::printf("(skipped %s: %s)\n", name.c_str(), error.c_str());
    return;
  }
  for (const Row &r : evaluate(name, shapes)) rows.push_back(r);
  every_width(name, shapes, wide);
}

void chart(const std::vector<Row> &rows, const std::string &path) {
  // One group of four bars per scene: SAH cost / the course bulk build's.
  std::ofstream svg(path);
  const int groups = int(rows.size() / 4), w = std::max(600, 60 + 70 * groups), h = 330;
  const char *colours[] = {"#808080", "#d62728", "#1f77b4", "#2ca02c"};
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h << "\" viewBox=\"0 0 "
      << w << " " << h << "\" font-family=\"sans-serif\" font-size=\"10\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<text x=\"10\" y=\"13\" font-size=\"12\">SAH cost relative to the course's bulk build (lower is "
         "better), BVH(4, unlimited)</text>\n";
  const double top = 28, base = 265, scale = 100; // 1.0 = 100 px
  for (double g = 0.5; g <= 2.0; g += 0.5) {
    const double y = base - g * scale;
    svg << "<line x1=\"40\" x2=\"" << w - 10 << "\" y1=\"" << y << "\" y2=\"" << y
        << "\" stroke=\"#ddd\"/><text x=\"10\" y=\"" << y + 3 << "\">" << g << "</text>\n";
  }
  for (int gi = 0; gi < groups; ++gi) {
    const double ref = rows[std::size_t(4 * gi)].sah;
    for (int b = 0; b < 4; ++b) {
      const double v = std::min(2.2, rows[std::size_t(4 * gi + b)].sah / ref);
      const double x = 45 + 70 * gi + 15 * b;
      svg << "<rect x=\"" << x << "\" y=\"" << base - v * scale << "\" width=\"13\" height=\"" << v * scale
          << "\" fill=\"" << colours[b] << "\"/>\n";
    }
    svg << "<text x=\"" << 45 + 70 * gi << "\" y=\"" << base + 14 << "\" transform=\"rotate(30 " << 45 + 70 * gi
        << " " << base + 14 << ")\">" << rows[std::size_t(4 * gi)].scene << "</text>\n";
  }
  for (int b = 0; b < 4; ++b)
    svg << "<rect x=\"" << 45 + 130 * b << "\" y=\"" << top - 8 << "\" width=\"10\" height=\"10\" fill=\""
        << colours[b] << "\"/><text x=\"" << 58 + 130 * b << "\" y=\"" << top + 1 << "\">"
        << rows[std::size_t(b)].builder << "</text>\n";
  svg << "</svg>\n";
}

} // namespace

int main(int argc, char **argv) {
  const std::string course = argc > 1 ? argv[1] : "../shared/course";
  const std::string svg = argc > 2 ? argv[2] : "bench/builders.svg";
  const bool quick = argc > 3 && std::string(argv[3]) == "--quick";
  std::vector<Row> rows, wide;
  course_scene<Disk>(course, "5000.disks", rows, wide);
  course_scene<Triangle>(course, "5000.triangles", rows, wide);
  course_scene<Quad>(course, "5000.quads", rows, wide);
  course_scene<Triangle>(course, "overlap_1000.triangles", rows, wide);
  for (std::size_t n : {std::size_t(10000), std::size_t(100000), std::size_t(1000000)}) {
    if (quick && n > 10000) break;
    const std::string scene = std::to_string(n / 1000) + "k disks";
    const std::vector<Disk> disks = random_disks(n, n);
    for (const Row &r : evaluate(scene, disks)) rows.push_back(r);
    every_width(scene, disks, wide);
  }
  std::printf("%-24s %-14s %10s %8s %7s %10s %12s\n", "scene", "builder", "SAH", "/ course", "height", "build s",
              "100k probes s");
  std::printf("%s\n", std::string(91, '-').c_str());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row &r = rows[i];
    std::printf("%-24s %-14s %10.3f %8.3f %7d %10.4f %12.4f\n", i % 4 ? "" : r.scene.c_str(), r.builder.c_str(),
                r.sah, r.sah / rows[i - i % 4].sah, r.height, r.build_s, r.probe_s);
  }
  std::printf("\nWidths: the same builders at widths 2, 3, 4 and 8 (split_threshold 4; and width 8 at 16).\n"
              "SAH is the course's cost, comparable within a width only; fill is the mean children of an inner\n"
              "node over the width, and the mean shapes of a leaf over split_threshold.\n");
  std::printf("%-24s %-14s %5s %5s %10s %9s %6s %6s %7s %10s %12s\n", "scene", "builder", "width", "split", "SAH",
              "nodes", "fill", "leaf", "height", "build s", "100k probes s");
  std::printf("%s\n", std::string(119, '-').c_str());
  for (std::size_t i = 0; i < wide.size(); ++i) {
    const Row &r = wide[i];
    const bool first = i == 0 || wide[i - 1].scene != r.scene;
    std::printf("%-24s %-14s %5d %5d %10.3f %9zu %6.2f %6.2f %7d %10.4f %12.4f\n", first ? r.scene.c_str() : "",
                r.builder.c_str(), r.width, r.split, r.sah, r.nodes, r.children_fill, r.leaf_fill, r.height,
                r.build_s, r.probe_s);
  }
  chart(rows, svg);
  std::printf("(chart: %s)\n", svg.c_str());
  return 0;
}
