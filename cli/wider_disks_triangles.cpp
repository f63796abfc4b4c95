// cli/wider_disks_triangles.cpp — bvh.out's trees of disks and triangles at
// widths 2, 4 and 8 (cli/run.h), in a build with every width (make
// WIDTHS=all).
#include "run.h"

namespace bvh_cli {
template int run_other_width<Disk>(const Options &, std::FILE *);
template int run_other_width<Triangle>(const Options &, std::FILE *);
} // namespace bvh_cli

namespace bvh_cli {
// (Here, once for the build with every width.)
const char *widths_built_note() { return ""; }
} // namespace bvh_cli
