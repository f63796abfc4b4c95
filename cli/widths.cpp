// cli/widths.cpp — bvh.out's dispatch on the shape kind (the kinds' trees,
// at every width: cli/run_disks_triangles.cpp, cli/run_quads_shapes.cpp).
#include "cli.h"

namespace bvh_cli {

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
