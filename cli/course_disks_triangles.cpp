// cli/course_disks_triangles.cpp — bvh.out's trees of disks and triangles at
// the course's width 3, and --generate disks and triangles (cli/run.h).
#include "run.h"

namespace bvh_cli {
template int run_course_width<Disk>(const Options &, std::FILE *);
template int generate_kind<Disk>(const Options &, double, double);
template int run_course_width<Triangle>(const Options &, std::FILE *);
template int generate_kind<Triangle>(const Options &, double, double);
} // namespace bvh_cli
