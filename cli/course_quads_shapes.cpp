// cli/course_quads_shapes.cpp — bvh.out's trees of quads and of mixed scenes'
// shapes (.shapes) at the course's width 3, and --generate quads and shapes
// (cli/run.h).
#include "run.h"

namespace bvh_cli {
template int run_course_width<Quad>(const Options &, std::FILE *);
template int generate_kind<Quad>(const Options &, double, double);
template int run_course_width<Shape>(const Options &, std::FILE *);
template int generate_kind<Shape>(const Options &, double, double);
} // namespace bvh_cli
