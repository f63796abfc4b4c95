// cli/course_width.cpp — the dispatch of a bvh.out built with the course's
// width 3 alone: linked instead of cli/widths.cpp and cli/run_*.cpp, it
// instantiates cli/run.h at that width only (a quarter of the trees to
// compile). make test's sanitized bvh.out is built so, its cases being at
// width 3 (the unit suites test every width, under the sanitizers too), and
// so is the CMake package test's (cmake -DBVH_CLI_COURSE_WIDTH_ONLY=ON).
#include "run.h"

namespace bvh_cli {

int run_scene(const Options &o, std::FILE *input) {
  if (o.width != 3) {
    std::cerr << "bvh.out: --width " << o.width << ": this build has the course's width 3 only\n";
    return 2;
  }
  if (ends_with(o.input, ".disks")) return run<Disk, 3>(o, input);
  if (ends_with(o.input, ".triangles")) return run<Triangle, 3>(o, input);
  if (ends_with(o.input, ".quads")) return run<Quad, 3>(o, input);
  return run<Shape, 3>(o, input);
}

int generate_scene_file(const Options &o, double lo, double hi) {
  if (o.kind == "disks") return generate_kind<Disk>(o, lo, hi);
  if (o.kind == "triangles") return generate_kind<Triangle>(o, lo, hi);
  if (o.kind == "quads") return generate_kind<Quad>(o, lo, hi);
  return generate_kind<Shape>(o, lo, hi);
}

} // namespace bvh_cli
