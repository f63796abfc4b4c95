// cli/kinds.cpp — bvh.out's dispatch on the scene's shape kind and on
// --width: the course's width 3 (cli/course_*.cpp), or another
// (cli/wider_*.cpp in a build with every width, cli/course_width_only.cpp
// in the default build).
#include "cli.h"

namespace bvh_cli {

template <class T> int run_kind(const Options &o, std::FILE *input) {
  return o.width == bvh::course_width ? run_course_width<T>(o, input) : run_other_width<T>(o, input);
}

int run_scene(const Options &o, std::FILE *input) {
  if (ends_with(o.input, ".disks")) return run_kind<bvh::Disk>(o, input);
  if (ends_with(o.input, ".triangles")) return run_kind<bvh::Triangle>(o, input);
  if (ends_with(o.input, ".quads")) return run_kind<bvh::Quad>(o, input);
  return run_kind<bvh::Shape>(o, input);
}

int generate_scene_file(const Options &o, double lo, double hi) {
  if (o.kind == "disks") return generate_kind<bvh::Disk>(o, lo, hi);
  if (o.kind == "triangles") return generate_kind<bvh::Triangle>(o, lo, hi);
  if (o.kind == "quads") return generate_kind<bvh::Quad>(o, lo, hi);
  return generate_kind<bvh::Shape>(o, lo, hi);
}

} // namespace bvh_cli
